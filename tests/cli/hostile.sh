# Hostile sizes (docs/trust.md): inputs that ask for huge amounts of memory
# or time are refused with a clear message before any large allocation, and
# big but legitimate inputs load in linear time; nothing crashes or
# overflows the stack.
# shellcheck disable=SC2034  # RC is read by the helpers in lib.sh
. "$(dirname "$0")/lib.sh"

# Memory cap for the runs below where the build allows one (ASan reserves
# terabytes of address space and cannot run under ulimit -v).
LIMIT_KB=1000000
CAP=0
(ulimit -v $LIMIT_KB && "$PSYS" --version) >/dev/null 2>&1 && CAP=1
capped() { (if [ "$CAP" = 1 ]; then ulimit -v $LIMIT_KB; fi && exec "$@"); }

# refused LABEL MESSAGE-REGEX SCENE-TEXT: psys check exits 2 with the message, fast.
refused() {
    local label=$1 re=$2
    printf '%s' "$3" >hostile.json
    local t0 t1
    t0=$(date +%s%N)
    capped "$PSYS" check hostile.json >out.txt 2>err.txt </dev/null
    RC=$?
    t1=$(date +%s%N)
    expect_rc 2 "$label"
    expect_stderr_re "psys: hostile\\.json: $re" "$label"
    check "$label: refused in under 5 s ($(((t1 - t0) / 1000000)) ms)" test $(((t1 - t0) / 1000000)) -lt 5000
}

LIMIT=50000000
refused "chain of 1e15 particles" "structures\\[0\\]\\.count: would exceed the limit of $LIMIT particles per scene.*" \
    '{"psys": 1, "dim": 2, "structures": [{"type": "chain", "from": [0, 0], "to": [1, 0], "count": 1e15, "mass": 1, "ks": 1}]}'
refused "chain of 2^64 particles" "structures\\[0\\]\\.count: .*" \
    '{"psys": 1, "dim": 2, "structures": [{"type": "chain", "from": [0, 0], "to": [1, 0], "count": 18446744073709551616, "mass": 1, "ks": 1}]}'
refused "cloth of 1e8 x 1e8" "structures\\[0\\]\\.size: would exceed the limit of $LIMIT particles per scene.*" \
    '{"psys": 1, "dim": 3, "structures": [{"type": "cloth", "origin": [0, 0, 0], "size": [100000000, 100000000], "spacing": 1, "mass": 1, "ks": 1}]}'
refused "cloth whose size product overflows 64 bits" "structures\\[0\\]\\.size: would exceed the limit of $LIMIT particles per scene.*" \
    '{"psys": 1, "dim": 3, "structures": [{"type": "cloth", "origin": [0, 0, 0], "size": [4294967296, 4294967296], "spacing": 1, "mass": 1, "ks": 1}]}'
refused "block of 1e6^3" "structures\\[0\\]\\.size: would exceed the limit of $LIMIT particles per scene.*" \
    '{"psys": 1, "dim": 3, "structures": [{"type": "block", "origin": [0, 0, 0], "size": [1000000, 1000000, 1000000], "spacing": 1, "mass": 1, "ks": 1}]}'
refused "wheel of 1e12 rim particles" "structures\\[0\\]\\.count: would exceed the limit of $LIMIT particles per scene.*" \
    '{"psys": 1, "dim": 2, "structures": [{"type": "wheel", "center": [0, 0], "radius": 1, "count": 1000000000000, "mass": 1, "ks": 1}]}'
refused "two chains just over the limit together" "structures\\[1\\]\\.count: would exceed the limit of $LIMIT particles per scene.*" \
    '{"psys": 1, "dim": 2, "structures": [{"type": "chain", "from": [0, 0], "to": [1, 0], "count": 2, "mass": 1, "ks": 1},
       {"type": "chain", "from": [0, 0], "to": [1, 0], "count": 49999999, "mass": 1, "ks": 1}]}'
refused "steps of 1e16" "steps: must be an integer from 0 to 1e15 \\(got 1e\\+16\\)" \
    '{"psys": 1, "steps": 1e16}'
refused "every of 1e300" "output\\.every: must be an integer from 1 to 1e15 \\(got 1e\\+300\\)" \
    '{"psys": 1, "output": {"every": 1e300}}'

# Deep nesting: cJSON stops at 1000 levels; the message says so, no stack overflow.
python_free_nest() { # nest OPEN CLOSE N: OPEN×N CLOSE×N without a huge bash string
    awk -v o="$1" -v c="$2" -v n="$3" 'BEGIN { for (i = 0; i < n; i++) printf "%s", o; for (i = 0; i < n; i++) printf "%s", c; print "" }'
}
refused "100000 nested arrays" "line 1, column 1001: JSON nested too deeply \\(more than 1000 levels of arrays and objects\\)" \
    "$(python_free_nest '[' ']' 100000)"
refused "100000 nested objects" "line 1, column 6001: JSON nested too deeply \\(more than 1000 levels of arrays and objects\\)" \
    "$(python_free_nest '{"a": ' '}' 100000)"
refused "nesting in a value" "line 1, column 1017: JSON nested too deeply .*" \
    "{\"psys\": 1, \"x\": $(python_free_nest '[' ']' 5000)}"
refused "999 nested arrays as a particle position" "particles\\[0\\]\\.x: must be an array of 2 numbers \\(dim is 2\\) \\(got \\[\\[\\[.*\\.\\.\\.\\)" \
    "{\"psys\": 1, \"dim\": 2, \"particles\": [{\"x\": $(python_free_nest '[' ']' 997)}]}"
printf '{"psys": 1, "dt": 1e-300, "duration": 1e300}' >hostile.json
psys run hostile.json --out never.csv
expect_rc 2 "duration/dt over 1e15 steps"
expect_stderr "psys: hostile.json: duration/dt asks for more than 1e15 steps" "duration/dt over 1e15 steps"
expect_absent never.csv "duration/dt over 1e15 steps: nothing written"
refused "duration/dt over 1e15 steps (psys check agrees with psys run)" "duration/dt asks for more than 1e15 steps" \
    '{"psys": 1, "dt": 1e-300, "duration": 1e300}'

# A big legitimate file: 100000 named particles and 99999 springs naming them
# load in linear time (ids are hashed; a linear search made this quadratic).
N=100000
awk -v n="$N" 'BEGIN {
    printf "{\"psys\": 1, \"dim\": 2, \"steps\": 1, \"particles\": ["
    for (i = 0; i < n; i++) printf "%s{\"id\": \"p%d\", \"x\": [%d, 0]}", i ? ", " : "", i, i
    printf "], \"forces\": ["
    for (i = 0; i + 1 < n; i++) printf "%s{\"type\": \"spring\", \"a\": \"p%d\", \"b\": \"p%d\", \"ks\": 1}", i ? ", " : "", i, i + 1
    printf "]}\n" }' >big.json
t0=$(date +%s%N)
psys check big.json
t1=$(date +%s%N)
expect_rc 0 "$N named particles and springs: psys check"
expect_eq "particles: $N" "$(grep '^particles:' out.txt)" "$N named particles loaded"
expect_eq "springs: $((N - 1))" "$(grep '^springs:' out.txt)" "$((N - 1)) springs loaded"
check "$N named particles load in under 30 s ($(((t1 - t0) / 1000000)) ms)" test $(((t1 - t0) / 1000000)) -lt 30000
psys run big.json --steps 2 --out big.csv --quiet
expect_rc 0 "$N particles: a short run"
expect_eq $((3 * N + 1)) "$(wc -l <big.csv)" "$N particles: every row written"

# A run of 1e15 steps with --out allocates nothing up front: under the
# memory cap it starts at once, writes frames as it goes, and a SIGINT ends
# it cleanly with complete files.
cat >forever.json <<'EOF'
{"psys": 1, "dim": 2, "dt": 0.001, "steps": 1000000000000000,
 "particles": [{"x": [0, 0], "fixed": true}, {"x": [1, 0], "v": [0, 1]}],
 "forces": [{"type": "spring", "a": 0, "b": 1, "ks": 10}]}
EOF
(
    if [ "$CAP" = 1 ]; then ulimit -v $LIMIT_KB; fi
    exec "$PSYS" run forever.json --every 100000 --out forever.csv --energy forever-e.csv --checkpoint forever-ck.json
) >out.txt 2>err.txt </dev/null &
pid=$! # psys itself (exec), so that it gets the signal
wait_caught "$pid" INT && sleep 1
kill -INT "$pid" 2>/dev/null
wait "$pid"
RC=$?
expect_rc 130 "1e15 steps with --out, interrupted"
expect_trajectory forever.csv 2 2 "1e15 steps: the trajectory is complete"
expect_energy forever-e.csv "1e15 steps: the energy file is complete"
expect_exists forever-ck.json "1e15 steps: checkpoint written"
psys run forever.json --steps 1000000000000001
expect_rc 2 "--steps above 1e15 refused"
psys run forever.json --every 1000000000000000 --steps 3 --out e.csv
expect_rc 0 "--every 1e15"
expect_eq "0 3" "$(csv_steps_line e.csv)" "--every 1e15: first and last frames"

expect_no_tmp "whole test"
finish
