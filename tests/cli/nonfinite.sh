# A run whose state becomes non-finite (docs/cli.md "Exit status" 1,
# docs/semantics.md "Failed and interrupted runs"): exit 1; the message names the step, the time and a particle; the
# output files are complete (header + whole frames, every frame up to the last
# good state), renamed into place, and their last frame is finite and is the
# step before the failing one.
. "$(dirname "$0")/lib.sh"

# Particle 1 ("wild") under a huge drag: with dt 0.1 the explicit update
# multiplies its velocity by about -1e9 per step, so it overflows after a few
# dozen steps. Particle 0 is at rest (its drag force stays exactly 0) and
# particle 2 has no id; neither ever becomes non-finite.
cat >drag.json <<'EOF'
{"psys": 1, "dim": 2, "dt": 0.1, "steps": 1000,
 "particles": [{"id": "calm", "x": [0, 0]}, {"id": "wild", "x": [1, 2], "v": [1, -1]}, {"x": [5, 5]}],
 "forces": [{"type": "drag", "kd": 1e10}]}
EOF

# blowup_test SCENE N DIM INTEGRATOR EVERY PARTICLE-TEXT
#   PARTICLE-TEXT: how the message must name the particle that blew up.
blowup_test() {
    local scene=$1 n=$2 dim=$3 integ=$4 every=$5 who=$6
    local tag="$scene $integ every $every"
    rm -f out.csv en.csv
    sentinel out.csv
    sentinel en.csv
    # --quiet: no dt stability warning before the message (tests/cli/guardrails.sh)
    psys run "$scene" --integrator "$integ" --every "$every" --out out.csv --energy en.csv --quiet
    expect_rc 1 "$tag: exit status"
    expect_stdout_empty "$tag"
    expect_trajectory out.csv "$n" "$dim" "$tag: the trajectory is complete, whole frames, last frame finite"
    expect_energy en.csv "$tag: the energy file is complete"
    expect_no_tmp "$tag"
    local last t
    last=$(tail -n 1 out.csv | cut -d, -f1)
    t=$(tail -n 1 out.csv | cut -d, -f2)
    check "$tag: the run stopped early (last frame $last)" test "$last" -lt 1000
    # frames: 0, every K, and the last good step
    local want
    want=$(awk -v k="$every" -v l="$last" 'BEGIN { for (s = 0; s < l; s += k) printf "%d ", s; printf "%d", l }')
    expect_eq "$want" "$(csv_steps_line out.csv)" "$tag: frames 0, every $every, and the last good step"
    expect_eq "$want" "$(awk -F, 'NR > 1 { print $1 }' en.csv | tr '\n' ' ' | sed 's/ $//')" \
        "$tag: energy rows for the same frames"
    # the message: one line naming the failing step (last good + 1), the time
    # it was stepping from (the last good state's t, as in the CSV) and the particle.
    check "$tag: one line on stderr (got: $(head -c 400 err.txt))" test "$(wc -l <err.txt)" -eq 1
    check "$tag: message starts \"psys: $scene: \" (got: $(head -c 400 err.txt))" grep -q "^psys: $scene: " err.txt
    expect_stderr_has "step $((last + 1))" "$tag: message names the failing step"
    expect_stderr_has "t = $t" "$tag: message names the time"
    expect_stderr_has "$who" "$tag: message names the particle"
    check "$tag: message says the state became non-finite" grep -q 'non-finite' err.txt
}

for integ in euler midpoint rk4 symplectic-euler verlet; do
    blowup_test drag.json 3 2 "$integ" 1 'particle 1 ("wild")'
    blowup_test drag.json 3 2 "$integ" 7 'particle 1 ("wild")'
done

# 3-D, the exploding particle without an id.
cat >drag3.json <<'EOF'
{"psys": 1, "dim": 3, "dt": 0.1, "steps": 1000, "integrator": "euler",
 "particles": [{"x": [0, 0, 0]}, {"id": "still", "x": [1, 1, 1], "fixed": true}, {"x": [1, 2, 3], "v": [0, 0, 1]}],
 "forces": [{"type": "drag", "kd": 1e10}]}
EOF
blowup_test drag3.json 3 3 euler 5 'particle 2'

# A very stiff spring tied to a fixed anchor, explicit Euler, big dt. The
# particle that blows up is the free one, "bob" (index 1); the fixed anchor's
# state is prescribed and never becomes non-finite, so it must not be named.
cat >spring.json <<'EOF'
{"psys": 1, "dim": 2, "dt": 0.1, "integrator": "euler", "steps": 1000,
 "particles": [{"id": "anchor", "x": [0, 0], "fixed": true}, {"id": "bob", "x": [1.5, 0]}],
 "forces": [{"type": "spring", "a": "anchor", "b": "bob", "ks": 1e6, "rest": 1}]}
EOF
blowup_test spring.json 2 2 euler 1 'particle 1 ("bob")'
check "spring.json: the fixed anchor is not named (got: $(head -c 400 err.txt))" \
    sh -c '! grep -q "anchor" err.txt'

# Huge initial velocities with RK4: positions overflow.
cat >fast.json <<'EOF'
{"psys": 1, "dim": 2, "dt": 1e300, "steps": 50, "integrator": "rk4",
 "particles": [{"id": "slow", "x": [0, 0]}, {"id": "rocket", "x": [0, 0], "v": [1e10, 0]}]}
EOF
blowup_test fast.json 2 2 rk4 1 'particle 1 ("rocket")'

# --checkpoint on a failed run: if written, it holds the last good state
# and resumes from it (it must not hold a non-finite state).
rm -f ck.json
psys run drag.json --integrator euler --out fail.csv --checkpoint ck.json
expect_rc 1 "failed run with --checkpoint"
if [ -f ck.json ]; then
    check "failed run's checkpoint has no non-finite numbers" sh -c '! grep -Eiq "nan|inf|null" ck.json'
    psys check ck.json
    expect_rc 0 "failed run's checkpoint loads"
fi

# The run failed; the scene from standard input is named <stdin>.
psys_in drag.json run - --integrator euler --out stdin.csv
expect_rc 1 "run - (non-finite)"
check "run - names <stdin> (got: $(head -c 400 err.txt))" grep -q '^psys: <stdin>: ' err.txt
expect_same fail.csv stdin.csv "run - writes the same partial trajectory"

expect_no_tmp "whole test"
finish
