#!/usr/bin/env bash
# The spring loops vectorise, by the compiler's own report: the sources
# holding loops marked "vectorised (tests/cli/vectorised.sh)" are compiled
# with the library's optimisation flags and -fopt-info-vec-optimized, and
# GCC must report each marked loop vectorised at every width the build
# makes of it: 16-byte vectors (the default x86-64 build), 32 (the AVX2
# clone) and 64 (the AVX-512 clone). Other compilers and machines: skipped
# (exit 77).
#
#   tests/cli/vectorised.sh CC SOURCE_DIR [FLAG...]
set -euo pipefail
cc=$1
src=$2
shift 2
macros=$("$cc" -dM -E -x c /dev/null)
if ! grep -q '__GNUC__' <<<"$macros" || grep -q '__clang__' <<<"$macros" || ! grep -q '__x86_64__' <<<"$macros" ||
    [ "$(uname -s)" != Linux ]; then
    echo "vectorised: not GCC on x86-64 Linux (no target clones): skipped"
    exit 77
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$src"
marker='vectorised (tests/cli/vectorised.sh)'
shopt -s nullglob
# src/ and its folders (src/fast/: the fused spring path)
sources=(src/*.c src/*.h src/*/*.c src/*/*.h)
mapfile -t marked < <(grep -n -F "$marker" "${sources[@]}" | cut -d: -f1,2)
[ "${#marked[@]}" -ge 5 ] || { echo "vectorised: expected at least 5 marked loops, found ${#marked[@]}"; exit 1; }
# the translation units that compile them (a header's loops: its includers)
units=$(for m in "${marked[@]}"; do
    f=${m%%:*}
    case $f in
    *.h) grep -l "#include \"${f#src/}\"" src/*.c src/*/*.c ;;
    *) echo "$f" ;;
    esac
done | sort -u)
report="$work/report"
: >"$report"
for u in $units; do
    "$cc" "$@" -Iinclude -Isrc -fopt-info-vec-optimized="$work/one" -c "$u" -o "$work/unit.o"
    cat "$work/one" >>"$report"
done
fail=0
for m in "${marked[@]}"; do
    for w in 16 32 64; do
        if ! grep -q -E "^$m:[0-9]+: optimized: loop vectorized using $w byte vectors" "$report"; then
            echo "vectorised: the loop at $m was not vectorised with $w-byte vectors"
            fail=1
        fi
    done
done
[ "$fail" = 0 ] || { echo "report:"; grep -F -f <(printf '%s:\n' "${marked[@]}") "$report" || true; exit 1; }
echo "vectorised: ${#marked[@]} marked loops vectorised with 16-, 32- and 64-byte vectors"
