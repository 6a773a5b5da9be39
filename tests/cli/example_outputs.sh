# Every example's whole run, byte for byte: the trajectory and energy CSVs of
#   psys run examples/NAME.json --out T.csv --energy E.csv
# with the scene's own settings, and again with --integrator verlet and
# midpoint (a run that blows up counts with its exit status), hash to the values in tests/example_outputs.sha256. A change of
# code that is meant to keep results (a refactoring, a faster path) must
# pass this unchanged.
#
# Regenerating (only for a change of results that is meant; say why in the
# commit message):
#   bash tests/cli/example_outputs.sh build/psys . --regenerate
. "$(dirname "$0")/lib.sh"

HASHES=$SRC/tests/example_outputs.sha256
REGENERATE=0
[ "${3:-}" = "--regenerate" ] && REGENERATE=1
VARIANTS="scene verlet midpoint"

# outputs_hash SCENE VARIANT: sha256 of the trajectory and energy CSVs together.
outputs_hash() {
    local flags=()
    [ "$2" = scene ] || flags=(--integrator "$2")
    rm -f t.csv e.csv
    "$PSYS" run "$1" "${flags[@]}" --out t.csv --energy e.csv --quiet >out.txt 2>err.txt </dev/null
    RC=$?
    # A run that stops (an explicit solver blowing up) is compared too: its
    # exit status and the frames it wrote up to the last good state.
    { echo "rc=$RC"; cat t.csv e.csv 2>/dev/null; } | sha256sum | cut -d' ' -f1
}

if [ "$REGENERATE" -eq 1 ]; then
    {
        echo "# sha256 of the trajectory CSV followed by the energy CSV of"
        echo "#   psys run examples/NAME.json [--integrator I] --out T.csv --energy E.csv"
        echo "# (VARIANT scene: the scene's own settings). Checked by tests/cli/example_outputs.sh."
        echo "# Regenerate only when results are meant to change, and say why in the commit message."
        for f in "$SRC"/examples/*.json; do
            name=$(basename "$f" .json)
            for v in $VARIANTS; do
                h=$(outputs_hash "$f" "$v")
                echo "$h  $name $v"
            done
        done
    } >"$WORK/hashes.new" || exit 1
    cp "$WORK/hashes.new" "$HASHES"
    echo "wrote $HASHES"
    exit 0
fi

if [ ! -f "$HASHES" ]; then
    fail "no $HASHES (bash tests/cli/example_outputs.sh build/psys . --regenerate)"
fi
for f in "$SRC"/examples/*.json; do
    name=$(basename "$f" .json)
    for v in $VARIANTS; do
        want=$(awk -v n="$name" -v v="$v" '$2 == n && $3 == v { print $1 }' "$HASHES")
        got=$(outputs_hash "$f" "$v")
        if [ -z "$want" ]; then
            fail "examples/$name.json ($v) has no committed hash in tests/example_outputs.sha256"
        elif [ "$got" != "$want" ]; then
            fail "examples/$name.json ($v): the outputs changed (sha256 $got, committed $want; rc $RC $(head -c 200 err.txt))"
        else
            ok
        fi
    done
done
finish
