# Scene round trip (docs/scene-format.md "Saving a scene back", docs/cli.md
# "psys check"):
#   psys check S --save A;  psys check A --save B   ->  A and B byte-identical,
#   and running S and running A give byte-identical results (to the last bit).
# Also: check prints "key: value" lines with at least dim, particles,
# springs, forces, integrator, dt, steps and energy.
. "$(dirname "$0")/lib.sh"

# A 2-D scene with ids (one needing JSON escapes), particles without ids
# referred to by index, a fixed particle, springs with and without rest
# lengths (default: the initial distance), gravity and drag interleaved with
# springs, numbers that need all 17 digits, -0 and a tiny velocity.
cat >s2.json <<'EOF'
{"psys": 1, "dim": 2, "integrator": "verlet", "dt": 0.005, "steps": 60,
 "particles": [{"id": "pivot", "x": [0, 0], "fixed": true},
   {"id": "bob \"one\" \u00fc", "x": [0.1, -0.33333333333333331], "v": [1e-300, -0.0], "mass": 0.7},
   {"x": [1.2345678901234567, -2.5e-7], "v": [0.5, 0.25], "mass": 3},
   {"id": "c", "x": [0.30000000000000004, 1]}],
 "forces": [{"type": "spring", "a": "pivot", "b": 1, "ks": 40, "kd": 0.25},
   {"type": "gravity", "g": [0, -9.81]},
   {"type": "spring", "a": "bob \"one\" \u00fc", "b": "c", "ks": 12.5, "rest": 0.9},
   {"type": "drag", "kd": 0.05},
   {"type": "spring", "a": 2, "b": 3, "ks": 7.000000000000001}],
 "output": {"every": 5}}
EOF

# A 3-D scene: adaptive rk45 with a duration and a tolerance, a chain of
# springs with default rest lengths hanging from a fixed particle.
cat >s3.json <<'EOF'
{"psys": 1, "dim": 3, "integrator": "rk45", "dt": 0.01, "duration": 0.37, "tolerance": 1e-8,
 "particles": [{"id": "top", "x": [0, 0, 2], "fixed": true},
   {"id": "m1", "x": [0.3, 0.1, 1.7], "mass": 0.2},
   {"id": "m2", "x": [0.6, -0.1, 1.45], "v": [0, 0.3, 0], "mass": 0.2},
   {"x": [0.9, 0, 1.2], "mass": 0.45}],
 "forces": [{"type": "gravity", "g": [0, 0, -9.81]},
   {"type": "spring", "a": "top", "b": "m1", "ks": 300, "kd": 0.8},
   {"type": "spring", "a": "m1", "b": "m2", "ks": 300, "kd": 0.8},
   {"type": "spring", "a": "m2", "b": 3, "ks": 300, "kd": 0.8, "rest": 0.2},
   {"type": "drag", "kd": 0.02}]}
EOF

# A 3-D scene with nothing but defaults (dim 3, rk4, dt 0.001, duration 1).
printf '{"psys": 1, "particles": [{"x": [1, 2, 3]}]}\n' >s0.json

# roundtrip NAME N DIM: the checks for sNAME.json with N particles.
roundtrip() {
    local s=$1 n=$2 dim=$3
    psys check "$s.json" --save "$s-A.json"
    expect_rc 0 "check $s --save"
    cp out.txt "$s-check-S.txt"
    expect_exists "$s-A.json" "check $s --save writes the file"
    psys check "$s-A.json" --save "$s-B.json"
    expect_rc 0 "check $s-A --save"
    cp out.txt "$s-check-A.txt"
    expect_same "$s-A.json" "$s-B.json" "$s: saving a saved scene gives the same bytes"
    # the summaries agree (apart from the scene's name)
    grep -v '^scene: ' "$s-check-S.txt" >"$s-sum-S.txt"
    grep -v '^scene: ' "$s-check-A.txt" >"$s-sum-A.txt"
    expect_same "$s-sum-S.txt" "$s-sum-A.txt" "$s: check prints the same summary for the scene and its saved form"
    # --save - writes the same text to standard output
    psys check "$s.json" --save -
    expect_rc 0 "check $s --save -"
    expect_same "$s-A.json" out.txt "$s: --save - writes the saved scene to stdout"
    # same results to the last bit
    psys run "$s.json" --out "$s-S.csv" --energy "$s-S-e.csv"
    expect_rc 0 "run $s"
    psys run "$s-A.json" --out "$s-A.csv" --energy "$s-A-e.csv"
    expect_rc 0 "run $s-A"
    expect_trajectory "$s-S.csv" "$n" "$dim" "$s trajectory"
    expect_same "$s-S.csv" "$s-A.csv" "$s: the saved scene gives a byte-identical trajectory"
    expect_same "$s-S-e.csv" "$s-A-e.csv" "$s: the saved scene gives byte-identical energies"
    # and with every integrator forced by flag
    for integ in euler midpoint rk4 symplectic-euler verlet rk45; do
        psys run "$s.json" --integrator "$integ" --steps 20 --out "$s-S-$integ.csv"
        psys run "$s-A.json" --integrator "$integ" --steps 20 --out "$s-A-$integ.csv"
        expect_same "$s-S-$integ.csv" "$s-A-$integ.csv" "$s: saved scene, --integrator $integ, same trajectory"
    done
}

roundtrip s2 4 2
roundtrip s3 4 3
roundtrip s0 1 3

# check's summary: "key: value" lines with the required keys.
sumval() { sed -n "s/^$1: //p" "$2"; }
for key in dim particles springs forces integrator dt steps energy; do
    check "check prints a \"$key: value\" line" grep -Eq "^$key: [^ ]" s2-check-S.txt
done
check "every line of check's output is \"key: value\"" \
    awk '!/^[a-z][a-z_ -]*: ./ { print "not key: value: " $0; bad = 1 } END { exit bad }' s2-check-S.txt
expect_eq 2 "$(sumval dim s2-check-S.txt)" "check s2: dim"
expect_eq 4 "$(sumval particles s2-check-S.txt)" "check s2: particles"
expect_eq 3 "$(sumval springs s2-check-S.txt)" "check s2: springs"
check "check s2: forces is a count >= 3 (got $(sumval forces s2-check-S.txt))" \
    awk -v f="$(sumval forces s2-check-S.txt)" 'BEGIN { exit !(f ~ /^[0-9]+$/ && f >= 3) }'
expect_eq verlet "$(sumval integrator s2-check-S.txt)" "check s2: integrator"
expect_near "$(sumval dt s2-check-S.txt)" 0.005 1e-15 "check s2: dt"
expect_eq 60 "$(sumval steps s2-check-S.txt)" "check s2: steps"
# energy = the total of frame 0 of the energy CSV
expect_eq "$(awk -F, 'NR == 2 { print $5 }' s2-S-e.csv)" "$(sumval energy s2-check-S.txt)" "check s2: energy is the frame-0 total"

expect_eq 3 "$(sumval dim s3-check-S.txt)" "check s3: dim"
expect_eq 4 "$(sumval particles s3-check-S.txt)" "check s3: particles"
expect_eq 3 "$(sumval springs s3-check-S.txt)" "check s3: springs"
expect_eq rk45 "$(sumval integrator s3-check-S.txt)" "check s3: integrator"
check "check s3: steps is given (got $(sumval steps s3-check-S.txt))" test -n "$(sumval steps s3-check-S.txt)"
expect_eq "$(awk -F, 'NR == 2 { print $5 }' s3-S-e.csv)" "$(sumval energy s3-check-S.txt)" "check s3: energy is the frame-0 total"

expect_eq 3 "$(sumval dim s0-check-S.txt)" "check s0: default dim 3"
expect_eq 0 "$(sumval springs s0-check-S.txt)" "check s0: no springs"
expect_eq rk4 "$(sumval integrator s0-check-S.txt)" "check s0: default integrator rk4"
expect_near "$(sumval dt s0-check-S.txt)" 0.001 1e-15 "check s0: default dt 0.001"
expect_eq 1000 "$(sumval steps s0-check-S.txt)" "check s0: default duration 1 = 1000 steps"
expect_eq 0 "$(sumval energy s0-check-S.txt)" "check s0: energy of a particle at rest with no forces"

# The saved scene keeps what was given: ids, fixed, default rest lengths made
# explicit (so they no longer depend on positions), the output block.
check "s2-A keeps the escaped id" grep -qF '"bob \"one\" ü"' s2-A.json
check "s2-A keeps the fixed particle" grep -q '"fixed":[[:space:]]*true' s2-A.json
check "s2-A keeps output.every" grep -q '"every":[[:space:]]*5' s2-A.json
check "s2-A writes the default rest length" test "$(grep -c '"rest"' s2-A.json)" -eq 3

# An existing --save file is replaced.
sentinel replaced.json
psys check s2.json --save replaced.json
expect_rc 0 "check --save over an existing file"
expect_same s2-A.json replaced.json "check --save replaces an existing file"

expect_no_tmp "whole test"
finish
