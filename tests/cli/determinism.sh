# Determinism (docs/trust.md; docs/semantics.md "Library rules", "Resuming"):
#   1. the same scene gives byte-identical output from run to run and for
#      --threads 1, 2 and 4;
#   2. a run split at ANY step into a --checkpoint run and a --resume run
#      gives the rows of the one-go run bit for bit, for every integrator,
#      with controllers, muscles, mouse paths, collisions and pair forces;
#   3. a run interrupted by SIGINT/SIGTERM and resumed from the checkpoint
#      it wrote continues bit-identically, and rk45 taking its own steps
#      (frames far apart, bounces cutting steps) resumes at the state written;
#   4. the final states of examples/*.json match the committed hashes in
#      tests/determinism.sha256 (so a change of results anywhere is seen).
#
# Regenerating the hashes (only for a change of results that is meant, and
# say why in the commit message):
#   bash tests/cli/determinism.sh build/psys . --regenerate
# shellcheck disable=SC2034  # RC is read by the helpers in lib.sh
. "$(dirname "$0")/lib.sh"

HASHES=$SRC/tests/determinism.sha256
HASH_STEPS=200
REGENERATE=0
[ "${3:-}" = "--regenerate" ] && REGENERATE=1

# ---------------------------------------------------------------- 4. committed hashes of examples

# final_hash SCENE: sha256 of the trajectory of a HASH_STEPS-step run, frames 0 and HASH_STEPS.
final_hash() {
    "$PSYS" run "$1" --steps "$HASH_STEPS" --every "$HASH_STEPS" --out final.csv --quiet >out.txt 2>err.txt </dev/null
    RC=$?
    if [ "$RC" -ne 0 ]; then
        echo "error"
        return
    fi
    sha256sum final.csv | cut -d' ' -f1
}

if [ "$REGENERATE" -eq 1 ]; then
    {
        echo "# sha256 of the trajectory CSV of  psys run examples/NAME.json --steps $HASH_STEPS --every $HASH_STEPS --out F.csv"
        echo "# (frames 0 and $HASH_STEPS, %.17g numbers). Checked by tests/cli/determinism.sh in every build"
        echo "# (Release, ASan+UBSan, any thread count). Regenerate with"
        echo "#   bash tests/cli/determinism.sh build/psys . --regenerate"
        echo "# only when results are meant to change, and say why in the commit message."
        for f in "$SRC"/examples/*.json; do
            name=$(basename "$f" .json)
            h=$(final_hash "$f")
            [ "$h" = error ] && { echo "determinism.sh: $name does not run: $(cat err.txt)" >&2; exit 1; }
            echo "$h  $name"
        done
    } >"$WORK/hashes.new" || exit 1
    cp "$WORK/hashes.new" "$HASHES"
    echo "wrote $HASHES"
    exit 0
fi

if [ ! -f "$HASHES" ]; then
    fail "no $HASHES (bash tests/cli/determinism.sh build/psys . --regenerate)"
else
    for f in "$SRC"/examples/*.json; do
        name=$(basename "$f" .json)
        want=$(awk -v n="$name" '$2 == n { print $1 }' "$HASHES")
        got=$(final_hash "$f")
        if [ -z "$want" ]; then
            fail "examples/$name.json has no committed hash in tests/determinism.sha256 (regenerate: see the file's header)"
        elif [ "$got" != "$want" ]; then
            fail "examples/$name.json: the final state changed (sha256 $got, committed $want; rc $RC $(head -c 200 err.txt)).
      If the change is meant, regenerate tests/determinism.sha256 (see its header) and justify it in the commit."
        else
            ok
        fi
    done
fi

# ---------------------------------------------------------------- 1. runs and thread counts

for f in "$SRC"/examples/*.json; do
    name=$(basename "$f" .json)
    for threads in 1 2 4 1; do
        "$PSYS" run "$f" --steps 60 --every 7 --threads "$threads" --out "t$threads.csv" --energy "e$threads.csv" \
            --quiet >out.txt 2>err.txt </dev/null
        RC=$?
        expect_rc 0 "$name --threads $threads"
        if [ "$threads" = 1 ] && [ -f ref.csv ]; then
            expect_same ref.csv t1.csv "$name: a second run is byte-identical"
            expect_same ref-e.csv e1.csv "$name: a second run's energies are byte-identical"
        elif [ "$threads" = 1 ]; then
            mv t1.csv ref.csv
            mv e1.csv ref-e.csv
        else
            expect_same ref.csv "t$threads.csv" "$name: --threads $threads gives the --threads 1 trajectory"
            expect_same ref-e.csv "e$threads.csv" "$name: --threads $threads gives the --threads 1 energies"
        fi
    done
    rm -f ref.csv ref-e.csv t*.csv e*.csv
done

# ---------------------------------------------------------------- 2. checkpoint/resume split at every step

# 2-D: a pivot, springs (one a muscle), a behaviour, gravity, drag, a circle
# motor, a keyframed particle, a scripted mouse drag, a ball that hits a
# friction plane (rollback) within the run, and one that rests on a plane.
cat >split2.json <<'EOF'
{"psys": 1, "dim": 2, "dt": 0.01, "steps": 1000,
 "particles": [{"id": "p", "x": [0, 1], "fixed": true},
               {"id": "b", "x": [1, 1], "v": [0, 0.5], "mass": 0.5},
               {"id": "c", "x": [1, 2], "mass": 2},
               {"id": "m", "x": [3, 1], "control": {"type": "circle", "center": [3, 1.5], "radius": 0.5, "omega": 3, "phase": -1.5707963}},
               {"id": "k", "x": [2, 2], "control": {"type": "keyframes", "frames": [[0, 2, 2], [0.05, 2.1, 2], [0.2, 2.1, 2.3]]}},
               {"id": "ball", "x": [5, 0.05], "v": [1, -2], "mass": 0.2},
               {"id": "rest", "x": [6, 0], "mass": 0.1}],
 "forces": [{"type": "gravity", "g": [0, -9.81]}, {"type": "drag", "kd": 0.1},
            {"type": "spring", "a": "p", "b": "b", "ks": 100, "kd": 0.5,
             "muscle": {"amplitude": 0.2, "omega": 7, "phase": 0.3}},
            {"type": "spring", "a": "b", "b": "c", "ks": 50, "rest": 0.8},
            {"type": "spring", "a": "c", "b": "m", "ks": 20, "kd": 0.2},
            {"type": "spring", "a": "c", "b": "k", "ks": 10},
            {"type": "behavior", "function": "distance", "particles": ["b", "m"], "r": 2, "ks": 5, "kd": 0.1},
            {"type": "mouse-spring", "particle": "c", "ks": 10, "kd": 1, "path": [[0, 1, 2], [0.1, 1.2, 2.1], [1, 1.5, 2]]}],
 "planes": [{"point": [0, 0], "normal": [0, 1], "restitution": 0.5, "friction": 0.3}]}
EOF

# 3-D: pair forces (Lennard-Jones on a grid with neighbour lists, Coulomb,
# Barnes-Hut gravity): neighbour lists must not make a resumed run differ.
cat >split3.json <<'EOF'
{"psys": 1, "dim": 3, "dt": 0.0005, "steps": 1000,
 "particles": [{"x": [0, 0, 0], "charge": 1}, {"x": [0.11, 0, 0], "charge": -1}, {"x": [0, 0.12, 0.01]},
               {"x": [0.1, 0.1, 0.1], "v": [-1, 0, 0]}, {"x": [0.2, 0, 0]}, {"x": [0.2, 0.2, 0]},
               {"x": [0, 0.2, 0.1]}, {"x": [0.3, 0.1, 0], "v": [0, 2, 0]}],
 "forces": [{"type": "pair", "law": "lennard-jones", "epsilon": 1, "sigma": 0.1, "cutoff": 0.25, "method": "grid"},
            {"type": "pair", "law": "coulomb", "k": 0.1, "method": "direct"},
            {"type": "pair", "law": "gravity", "G": 1, "softening": 0.01, "method": "barnes-hut", "theta": 0.5}]}
EOF

TOTAL=16
rows_after() { awk -F, -v s="$2" 'NR > 1 && $1 + 0 > s + 0' "$1"; }

# split_sweep SCENE INTEGRATOR: every split point A = 1..TOTAL-1.
split_sweep() {
    local scene=$1 integ=$2 tag="$1 $2" a
    psys run "$scene" --integrator "$integ" --steps "$TOTAL" --out full.csv --energy full-e.csv --quiet
    expect_rc 0 "$tag: one-go run"
    for ((a = 1; a < TOTAL; a++)); do
        psys run "$scene" --integrator "$integ" --steps "$a" --checkpoint ck.json --quiet
        expect_rc 0 "$tag: $a steps with --checkpoint"
        psys run --resume ck.json --steps $((TOTAL - a)) --out part.csv --energy part-e.csv --quiet
        expect_rc 0 "$tag: resume after $a steps"
        rows_after full.csv "$a" >want.csv
        rows_after part.csv "$a" >got.csv
        rows_after full-e.csv "$a" >want-e.csv
        rows_after part-e.csv "$a" >got-e.csv
        if [ ! -s got.csv ]; then
            fail "$tag: resume after $a steps wrote no rows after step $a"
        fi
        expect_same want.csv got.csv "$tag: split at step $a: resumed rows = one-go rows"
        expect_same want-e.csv got-e.csv "$tag: split at step $a: resumed energies = one-go energies"
    done
}

for integ in euler midpoint rk4 symplectic-euler verlet rk45 implicit-euler; do
    split_sweep split2.json "$integ"
done
if "$PSYS" check split3.json >/dev/null 2>&1; then
    for integ in rk4 verlet rk45; do
        split_sweep split3.json "$integ"
    done
else
    echo "note: pair forces not available in this build: $("$PSYS" check split3.json 2>&1 | head -n 1)"
fi

# ---------------------------------------------------------------- 3. interrupted, then resumed

cat >long.json <<'EOF'
{"psys": 1, "dim": 2, "dt": 0.0001, "steps": 1000000000000,
 "particles": [{"id": "p", "x": [0, 0], "fixed": true},
               {"id": "b", "x": [1, 0], "v": [0, 0.5], "mass": 0.5},
               {"x": [1, 1], "mass": 2},
               {"id": "m", "x": [2, 0], "control": {"type": "circle", "center": [2, 0.5], "radius": 0.5, "omega": 3}}],
 "forces": [{"type": "gravity", "g": [0, -9.81]}, {"type": "drag", "kd": 0.1},
            {"type": "spring", "a": "p", "b": "b", "ks": 100, "kd": 0.5},
            {"type": "spring", "a": 1, "b": 2, "ks": 50, "rest": 0.8},
            {"type": "spring", "a": 2, "b": "m", "ks": 10}],
 "planes": [{"point": [0, -1.5], "normal": [0, 1], "restitution": 0.7}]}
EOF

# interrupt_resume SIGNAL INTEGRATOR: interrupt a run (it writes its
# checkpoint), resume it for 40 steps, and compare with one uninterrupted
# run of (interrupted step + 40) steps. Frames every 10^6 steps in all three
# runs (rk45 lands on frame times, so they must be the same times).
interrupt_resume() {
    local sig=$1 integ=$2 tag="$1 $2" code last
    [ "$sig" = INT ] && code=130 || code=143
    rm -f ck.json int.csv resumed.csv go.csv
    "$PSYS" run long.json --integrator "$integ" --every 1000000 --out int.csv --checkpoint ck.json --quiet \
        >out.txt 2>err.txt </dev/null &
    local pid=$!
    wait_caught "$pid" "$sig" && sleep 0.4
    kill -"$sig" "$pid" 2>/dev/null
    wait "$pid"
    RC=$?
    expect_rc "$code" "$tag: interrupted run's exit status"
    expect_exists ck.json "$tag: checkpoint written on the signal"
    last=$(tail -n 1 int.csv | cut -d, -f1)
    check "$tag: the run got somewhere (step $last)" test "${last:-0}" -gt 0
    psys run --resume ck.json --steps 40 --every 1000000 --out resumed.csv --quiet
    expect_rc 0 "$tag: resume"
    expect_eq "$(tail -n 4 int.csv)" "$(sed -n 2,5p resumed.csv)" "$tag: the resumed run starts at the interrupted state"
    psys run long.json --integrator "$integ" --steps $((last + 40)) --every 1000000 --out go.csv --quiet
    expect_rc 0 "$tag: uninterrupted run of $((last + 40)) steps"
    expect_eq "$(tail -n 4 go.csv)" "$(tail -n 4 resumed.csv)" \
        "$tag: interrupted at step $last and resumed for 40 steps = $((last + 40)) steps in one go (bit for bit)"
}

for integ in rk4 rk45 verlet; do
    interrupt_resume INT "$integ"
done
interrupt_resume TERM implicit-euler

# rk45 with frames far apart takes its own step sizes, and its steps 217,
# 224, 227 and 229 of long.json end in bounces on the plane (partial steps):
# a checkpoint after any of steps 200..240 resumes at the state written.
for ((a = 200; a <= 240; a++)); do
    psys run long.json --integrator rk45 --steps "$a" --every 1000000 --out int.csv --checkpoint ck.json --quiet
    expect_rc 0 "rk45 $a steps with --checkpoint"
    psys run --resume ck.json --steps 1 --every 1000000 --out resumed.csv --quiet
    expect_rc 0 "rk45 resume after $a steps"
    expect_eq "$(tail -n 4 int.csv)" "$(sed -n 2,5p resumed.csv)" "rk45 split at step $a: the resumed run starts at the state written"
done

expect_no_tmp "whole test"
finish
