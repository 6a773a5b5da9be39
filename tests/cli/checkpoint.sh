# Checkpoint and resume (docs/semantics.md "Resuming"): running A+B steps in one go, and A
# steps with --checkpoint followed by `--resume CK --steps B`, gives
# byte-identical trajectory (and energy) rows, for every integrator. The
# resumed run's first frame is the checkpoint state (step A); step and t
# continue; --steps counts from the checkpoint.
. "$(dirname "$0")/lib.sh"

A=12
B=18
TOTAL=$((A + B))

# 2-D: fixed pivot, free particles with and without ids, springs (one with a
# default rest length), gravity, drag; energies nonzero.
cat >scene2.json <<'EOF'
{"psys": 1, "dim": 2, "dt": 0.01, "steps": 1000,
 "particles": [{"id": "p", "x": [0, 0], "fixed": true},
               {"id": "b", "x": [1, 0], "v": [0, 0.5], "mass": 0.5},
               {"x": [1, 1], "mass": 2}],
 "forces": [{"type": "gravity", "g": [0, -9.81]}, {"type": "drag", "kd": 0.1},
            {"type": "spring", "a": "p", "b": "b", "ks": 100, "kd": 0.5},
            {"type": "spring", "a": 1, "b": 2, "ks": 50, "rest": 0.8}]}
EOF

# 3-D: a small stiff chain.
cat >scene3.json <<'EOF'
{"psys": 1, "dim": 3, "dt": 0.004, "duration": 5,
 "particles": [{"id": "top", "x": [0, 0, 0], "fixed": true},
               {"x": [0.2, 0, -0.05], "v": [0, 0.4, 0], "mass": 0.1},
               {"x": [0.4, 0.05, -0.1], "mass": 0.1},
               {"x": [0.6, 0, -0.1], "mass": 0.3}],
 "forces": [{"type": "gravity", "g": [0, 0, -9.81]},
            {"type": "spring", "a": 0, "b": 1, "ks": 800, "kd": 1},
            {"type": "spring", "a": 1, "b": 2, "ks": 800, "kd": 1},
            {"type": "spring", "a": 2, "b": 3, "ks": 800, "kd": 1}]}
EOF

# 3-D: a 30 × 30 sheet whose particles are numbered out of order (cell c is
# particle 397·c mod 900), over 4,096 springs: the spring set takes an
# internal order (src/forces/spring.c), which the resumed run must find again.
{
    printf '{"psys": 1, "dim": 3, "dt": 0.0005, "steps": 1000,\n "particles": ['
    for ((q = 0; q < 900; q++)); do
        c=$(( (q * 433) % 900 )) # 433 = 397⁻¹ mod 900: particle q sits at cell c
        sep=","; [ "$q" -eq 0 ] && sep=""
        fixed=""; { [ "$c" -eq 0 ] || [ "$c" -eq 29 ]; } && fixed=', "fixed": true'
        printf '%s\n  {"x": [%s, 0, %s], "mass": 0.01%s}' "$sep" "$((c % 30)).0" "$((c / 30)).0" "$fixed"
    done
    printf '],\n "forces": [{"type": "gravity", "g": [0, 0, -9.81]}'
    for ((r = 0; r < 30; r++)); do
        for ((col = 0; col < 30; col++)); do
            c=$((r * 30 + col))
            for t in "1 0 1" "0 1 1" "1 1 1.4142135623730951" "-1 1 1.4142135623730951" "2 0 2" "0 2 2"; do
                set -- $t
                c2=$(( (r + $2) * 30 + col + $1 ))
                if [ $((col + $1)) -ge 0 ] && [ $((col + $1)) -lt 30 ] && [ $((r + $2)) -lt 30 ]; then
                    printf ',\n  {"type": "spring", "a": %d, "b": %d, "ks": 50, "kd": 0.2, "rest": %s}' \
                        $(( (c * 397) % 900 )) $(( (c2 * 397) % 900 )) "$3"
                fi
            done
        done
    done
    printf ']}\n'
} >scene4.json

# 2-D: a Lennard-Jones gas of 36 particles in a periodic box (a pair force on
# a grid with neighbour lists). implicit-euler's multigrid preconditioner
# groups the particles by their strong couplings, which change from step to
# step here: it must be the one the state gives, not one kept from an
# earlier step, or the resumed run differs in the last digits.
awk 'BEGIN {
    printf "{\"psys\": 1, \"dim\": 2, \"dt\": 0.005, \"steps\": 1000,\n"
    printf " \"box\": {\"lo\": [0, 0], \"hi\": [7, 7], \"periodic\": [true, true]},\n \"particles\": ["
    for (q = 0; q < 36; q++)
        printf "%s\n  {\"x\": [%.2f, %.2f], \"v\": [%.1f, %.1f]}", (q ? "," : ""), q % 6 + 0.1 + (q % 7) / 100,
            int(q / 6) + 0.2 + (q % 5) / 100, ((q * 37 + 11) % 41 - 20) / 10, ((q * 53 + 7) % 43 - 21) / 10
    printf "],\n \"forces\": [{\"type\": \"pair\", \"law\": \"lennard-jones\", \"epsilon\": 1, \"sigma\": 1,"
    printf " \"cutoff\": 2.5, \"method\": \"grid\", \"skin\": 0.3}]}\n"
}' >scene5.json

# rows_from FILE STEP: the data rows with step >= STEP.
rows_from() { awk -F, -v s="$2" 'NR > 1 && $1 + 0 >= s + 0' "$1"; }
# rows_after FILE STEP: the data rows with step > STEP.
rows_after() { awk -F, -v s="$2" 'NR > 1 && $1 + 0 > s + 0' "$1"; }
# rows_to FILE STEP: the data rows with step <= STEP.
rows_to() { awk -F, -v s="$2" 'NR > 1 && $1 + 0 <= s + 0' "$1"; }

# split_test SCENE N DIM INTEGRATOR EVERY
split_test() {
    local scene=$1 n=$2 dim=$3 integ=$4 every=$5
    local tag="$scene $integ every $every"
    local base="${scene%.json}-$integ-$every"
    rm -f "$base"-*
    psys run "$scene" --integrator "$integ" --every "$every" --steps "$TOTAL" \
        --out "$base-full.csv" --energy "$base-full-e.csv"
    expect_rc 0 "$tag: run $TOTAL steps"
    expect_trajectory "$base-full.csv" "$n" "$dim" "$tag: full trajectory"
    psys run "$scene" --integrator "$integ" --every "$every" --steps "$A" \
        --out "$base-part1.csv" --energy "$base-part1-e.csv" --checkpoint "$base-ck.json"
    expect_rc 0 "$tag: run $A steps with --checkpoint"
    expect_exists "$base-ck.json" "$tag: --checkpoint"
    psys run "$scene" --resume "$base-ck.json" --steps "$B" --every "$every" \
        --out "$base-part2.csv" --energy "$base-part2-e.csv"
    expect_rc 0 "$tag: --resume --steps $B"
    expect_trajectory "$base-part2.csv" "$n" "$dim" "$tag: resumed trajectory"
    expect_eq "$(head -n 1 "$base-full.csv")" "$(head -n 1 "$base-part2.csv")" "$tag: resumed header"

    # the resumed run starts with the checkpoint state, at step A
    expect_eq "$A" "$(awk -F, 'NR == 2 { print $1 }' "$base-part2.csv")" "$tag: resumed run's first frame is step $A"
    expect_eq "$(tail -n 1 "$base-part1.csv")" "$(awk -F, -v n="$n" 'NR == n + 1' "$base-part2.csv")" \
        "$tag: resumed run's first frame is the last frame of the checkpointed run"
    expect_eq "$TOTAL" "$(tail -n 1 "$base-part2.csv" | cut -d, -f1)" "$tag: --steps $B counts from the checkpoint"

    if [ "$integ" = rk45 ]; then
        # rk45's frames lie on output times; step A (the checkpoint) need not
        # be one of them in the one-go run. Every later row must match.
        rows_after "$base-full.csv" "$A" >"$base-want.csv"
        rows_after "$base-part2.csv" "$A" >"$base-got.csv"
        rows_after "$base-full-e.csv" "$A" >"$base-want-e.csv"
        rows_after "$base-part2-e.csv" "$A" >"$base-got-e.csv"
    else
        rows_from "$base-full.csv" "$A" >"$base-want.csv"
        rows_from "$base-part2.csv" "$A" >"$base-got.csv"
        rows_from "$base-full-e.csv" "$A" >"$base-want-e.csv"
        rows_from "$base-part2-e.csv" "$A" >"$base-got-e.csv"
        # and the checkpointed run's rows are the first rows of the one-go run
        rows_to "$base-full.csv" "$A" >"$base-want1.csv"
        tail -n +2 "$base-part1.csv" >"$base-got1.csv"
        expect_same "$base-want1.csv" "$base-got1.csv" "$tag: first $A steps match the one-go run"
    fi
    check "$tag: resumed run has rows to compare" test -s "$base-got.csv"
    expect_same "$base-want.csv" "$base-got.csv" "$tag: resumed trajectory rows = one-go rows (bit for bit)"
    expect_same "$base-want-e.csv" "$base-got-e.csv" "$tag: resumed energy rows = one-go rows (bit for bit)"
}

for integ in rk4 verlet symplectic-euler euler midpoint rk45; do
    split_test scene2.json 3 2 "$integ" 1
    split_test scene2.json 3 2 "$integ" 4 # 4 divides A = 12
    split_test scene3.json 4 3 "$integ" 3 # 3 divides A = 12
done
for integ in rk4 verlet; do
    split_test scene4.json 900 3 "$integ" 6
done
if "$PSYS" check scene5.json >/dev/null 2>&1; then
    for integ in implicit-euler rk4; do
        split_test scene5.json 36 2 "$integ" 1
    done
else
    echo "note: pair forces not available in this build: $("$PSYS" check scene5.json 2>&1 | head -n 1)"
fi

# A checkpoint of a checkpoint: A, then 7, then 11 steps = A + 18 steps in one go.
for integ in rk4 rk45 verlet; do
    psys run scene2.json --integrator "$integ" --steps "$TOTAL" --out chain-full.csv
    psys run scene2.json --integrator "$integ" --steps "$A" --checkpoint chain-ck1.json
    expect_rc 0 "chain $integ: first part"
    psys run --resume chain-ck1.json --steps 7 --checkpoint chain-ck2.json --out chain-2.csv
    expect_rc 0 "chain $integ: resume without SCENE, with a new checkpoint"
    psys run scene2.json --resume chain-ck2.json --steps 11 --out chain-3.csv
    expect_rc 0 "chain $integ: resume the resumed run"
    expect_eq "$TOTAL" "$(tail -n 1 chain-3.csv | cut -d, -f1)" "chain $integ: ends at step $TOTAL"
    rows_after chain-full.csv $((A + 7)) >chain-want.csv
    rows_after chain-3.csv $((A + 7)) >chain-got.csv
    expect_same chain-want.csv chain-got.csv "chain $integ: twice-resumed rows = one-go rows"
    expect_eq "$(grep "^$((A + 7))," chain-2.csv)" "$(grep "^$((A + 7))," chain-3.csv)" \
        "chain $integ: second checkpoint's state starts the third run"
done

# --checkpoint holds t: the resumed t column continues the one-go t column
# exactly (fixed step: t = step * dt, printed %.17g).
expect_eq "$(grep '^20,' scene2-rk4-1-full.csv | head -n 1 | cut -d, -f2)" \
    "$(grep '^20,' scene2-rk4-1-part2.csv | head -n 1 | cut -d, -f2)" "t continues after --resume"

# --duration after --resume counts from the checkpoint: 0.18 s at dt 0.01 from
# t = 0.12 is 18 steps, ending at t = 0.12 + 0.18.
psys run scene2.json --resume scene2-rk4-1-ck.json --duration 0.18 --out dur.csv
expect_rc 0 "--resume --duration"
expect_eq "$TOTAL" "$(tail -n 1 dur.csv | cut -d, -f1)" "--resume --duration 0.18 takes 18 steps"
tck=$(awk -F, 'NR == 2 { print $2 }' scene2-rk4-1-part2.csv)
expect_eq "$(awk -v t="$tck" 'BEGIN { printf "%.17g", t + 0.18 }')" "$(tail -n 1 dur.csv | cut -d, -f2)" \
    "--resume --duration 0.18 ends at t = t_checkpoint + 0.18"

expect_no_tmp "whole test"
finish
