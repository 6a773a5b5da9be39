# The psys program flushes subnormal results to zero (docs/cli.md,
# "Floating point"), on every thread: each thread starts with the mode of
# the program's first thread. PSYS_FLUSH_SUBNORMALS=0 keeps them.
#   - one particle under drag, one euler step: v = 1e-306 − 0.999·1e-306,
#     about 1e-309, below the smallest normal double: 0, or kept;
#   - 40,000 such particles (the solver's and drag's loops then run on
#     every thread): every v is 0 on 1 and on 2 threads, the files the same
#     bytes; with subnormals kept, none is 0.
#   - psys bench says which mode it timed.
# shellcheck disable=SC2034  # RC is read by the helpers in lib.sh
. "$(dirname "$0")/lib.sh"

cat >one.json <<'EOF'
{"psys": 1, "dim": 2, "dt": 1, "steps": 1, "integrator": "euler",
 "particles": [{"x": [0, 0], "v": [1e-306, 0]}],
 "forces": [{"type": "drag", "kd": 0.999}]}
EOF
# vx_of FILE: the vx column of the last frame's rows (step,t,i,x,y,vx,vy)
vx_of() { awk -F, 'NR > 1 && $1 == 1 { print $6 }' "$1"; }

psys run one.json --out flushed.csv --quiet
expect_rc 0 "one particle (stderr: $(cat err.txt))"
check "the subnormal velocity flushed to 0 (got $(vx_of flushed.csv))" test "$(vx_of flushed.csv)" = 0
PSYS_FLUSH_SUBNORMALS=0 psys run one.json --out kept.csv --quiet
expect_rc 0 "one particle, subnormals kept (stderr: $(cat err.txt))"
check "the subnormal velocity kept (got $(vx_of kept.csv))" \
    awk -v v="$(vx_of kept.csv)" 'BEGIN { exit !(v + 0 != 0 && v + 0 < 2.2250738585072014e-308) }'

awk 'BEGIN {
    printf "{\"psys\": 1, \"dim\": 2, \"dt\": 1, \"steps\": 1, \"integrator\": \"euler\", \"particles\": ["
    for (i = 0; i < 40000; i++)
        printf "%s{\"x\": [%d, 0], \"v\": [1e-306, 0]}", (i ? "," : ""), i
    print "], \"forces\": [{\"type\": \"drag\", \"kd\": 0.999}]}"
}' >many.json
for t in 1 2; do
    psys run many.json --threads "$t" --out "many$t.csv" --quiet
    expect_rc 0 "40,000 particles, $t thread(s) (stderr: $(cat err.txt))"
    check "$t thread(s): every velocity flushed to 0" \
        test "$(vx_of "many$t.csv" | grep -cvx 0)" = 0
    PSYS_FLUSH_SUBNORMALS=0 psys run many.json --threads "$t" --out "kept$t.csv" --quiet
    expect_rc 0 "40,000 particles, $t thread(s), subnormals kept (stderr: $(cat err.txt))"
    check "$t thread(s), subnormals kept: no velocity 0" test "$(vx_of "kept$t.csv" | grep -cx 0)" = 0
done
check "flushed: the same bytes on 1 and 2 threads" cmp -s many1.csv many2.csv
check "kept: the same bytes on 1 and 2 threads" cmp -s kept1.csv kept2.csv

psys bench cloth-8 --steps 1 --reps 1 --bandwidth 10
check "bench reports flushing" grep -q '"flush_subnormals":true' out.txt
PSYS_FLUSH_SUBNORMALS=0 psys bench cloth-8 --steps 1 --reps 1 --bandwidth 10
check "bench reports subnormals kept" grep -q '"flush_subnormals":false' out.txt
finish
