# MPI equivalence (docs/mpi.md; issue 10 point 4): under mpiexec with R = 2
# and 4 ranks (oversubscribed on one machine), the trajectory CSV of every
# explicit solver is byte-identical to the serial run's; checkpoints written
# by R ranks resume on R' ranks bit-identically.
#
#   bash tests/cli/mpi.sh PSYS SRC MPIEXEC CASE
# CASE: a scene name in tests/mpi/ (every explicit solver, R = 2 and 4),
# or "checkpoint", or "errors" (bad input and unwritable output under mpiexec).
# shellcheck disable=SC2034  # RC is read by the helpers in lib.sh
. "$(dirname "$0")/lib.sh"

MPIEXEC=$3
CASE=$4
MPIFLAGS=()
# Open MPI refuses more ranks than cores and running as root unless told.
if "$MPIEXEC" --version 2>&1 | grep -qi 'open mpi\|openrte'; then
    MPIFLAGS=(--oversubscribe)
    export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
fi

# mpirun R ARGS...: psys ARGS on R ranks (at most 120 s).
mpirun() {
    local r=$1
    shift
    timeout 120 "$MPIEXEC" "${MPIFLAGS[@]}" -n "$r" "$PSYS" "$@" </dev/null
}

SOLVERS=(euler midpoint rk4 symplectic-euler verlet rk45)

case "$CASE" in
checkpoint)
    scene=$SRC/tests/mpi/lj-grid.json
    for solver in verlet rk45 rk4; do
        "$PSYS" run "$scene" --integrator "$solver" --steps 30 --every 5 --out one.csv --quiet >/dev/null 2>err.txt
        [ $? -eq 0 ] || { fail "$solver: serial run failed: $(cat err.txt)"; continue; }
        mpirun 2 run "$scene" --integrator "$solver" --steps 12 --every 5 --out a.csv --checkpoint ck.json \
            --quiet >/dev/null 2>err.txt
        [ $? -eq 0 ] || { fail "$solver: 2-rank run with --checkpoint failed: $(cat err.txt)"; continue; }
        ok
        for r in 1 4; do
            if [ "$r" = 1 ]; then
                "$PSYS" run --resume ck.json --steps 18 --every 5 --out b$r.csv --quiet >/dev/null 2>err.txt
            else
                mpirun "$r" run --resume ck.json --steps 18 --every 5 --out b$r.csv --quiet >/dev/null 2>err.txt
            fi
            [ $? -eq 0 ] || { fail "$solver: resume on $r rank(s) failed: $(cat err.txt)"; continue; }
            # The one-go rows after step 12 against the resumed rows (frame 12 is written again first).
            if cmp -s <(awk -F, 'NR > 1 && $1 > 12' one.csv) <(awk -F, 'NR > 1 && $1 > 12' b$r.csv); then
                ok
            else
                fail "$solver: checkpoint of 2 ranks resumed on $r rank(s) differs from the one-go serial run"
            fi
        done
    done
    ;;
errors)
    scene=$SRC/tests/mpi/granular.json
    mpirun 2 run "$SRC/tests/mpi/no-such-scene.json" --out x.csv >out.txt 2>err.txt
    RC=$?
    [ "$RC" -eq 2 ] && ok || fail "missing scene under mpiexec: exit $RC, want 2"
    [ "$(grep -c 'no-such-scene' err.txt)" -eq 1 ] && ok || fail "missing scene: want one message (rank 0), got: $(cat err.txt)"
    [ ! -e x.csv ] && ok || fail "missing scene: x.csv was created"
    mpirun 2 run "$scene" --out /nonexistent-dir/x.csv >out.txt 2>err.txt
    RC=$?
    [ "$RC" -eq 2 ] && ok || fail "unwritable output under mpiexec: exit $RC, want 2"
    mpirun 4 run "$scene" --steps 5 --out t.csv --energy e.csv --quiet >out.txt 2>err.txt
    RC=$?
    [ "$RC" -eq 0 ] && ok || fail "4 ranks, trajectory and energy: exit $RC: $(cat err.txt)"
    "$PSYS" run "$scene" --steps 5 --out ts.csv --energy es.csv --quiet
    cmp -s t.csv ts.csv && cmp -s e.csv es.csv && ok || fail "4 ranks: trajectory or energy CSV differs from serial"
    ls ./*.tmp* .*.tmp* >/dev/null 2>&1 && fail "temporary files left behind" || ok
    ;;
*)
    scene=$SRC/tests/mpi/$CASE.json
    [ -f "$scene" ] || { fail "no scene $scene"; finish; }
    for solver in "${SOLVERS[@]}"; do
        "$PSYS" run "$scene" --integrator "$solver" --every 4 --out serial.csv --quiet >/dev/null 2>err.txt
        [ $? -eq 0 ] || { fail "$CASE $solver: serial run failed: $(cat err.txt)"; continue; }
        for r in 2 4; do
            mpirun "$r" run "$scene" --integrator "$solver" --every 4 --out r$r.csv --quiet >/dev/null 2>err.txt
            RC=$?
            if [ "$RC" -ne 0 ]; then
                fail "$CASE $solver: $r ranks: exit $RC: $(cat err.txt)"
            elif cmp -s serial.csv r$r.csv; then
                ok
            else
                fail "$CASE $solver: $r ranks: trajectory differs from the serial run ($(cmp serial.csv r$r.csv | head -1))"
            fi
        done
    done
    ;;
esac
finish
