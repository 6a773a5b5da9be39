#!/usr/bin/env bash
# Runs a psys libFuzzer target (docs/trust.md).
#
#   bash fuzz/fuzz.sh smoke TARGET BUILD_DIR
#       a short fixed-seed run (ctest fuzz.smoke.TARGET): 20000 executions,
#       -seed=1, from the seed corpus, new inputs kept in a fresh scratch
#       directory under BUILD_DIR (the source tree is never written).
#   bash fuzz/fuzz.sh long TARGET BUILD_DIR SECONDS [LIBFUZZER FLAGS...]
#       a long run (`make fuzz`): the corpus grows in BUILD_DIR/fuzz-corpus/TARGET
#       and is kept between runs; crashes go to BUILD_DIR/fuzz-artifacts/TARGET/.
#
# TARGET is scene (the scene loader: load -> save -> load -> save round trip,
# a few steps) or cli (the `psys run` option parser). The fuzzer binaries are
# BUILD_DIR/fuzz-build/fuzz/fuzz_TARGET (built by the normal build when clang
# has libFuzzer). A crash: minimise it, add it to fuzz/regress/TARGET/ (ctest
# fuzz.replay.TARGET replays it in every build), fix the bug.
set -euo pipefail
mode=${1:?usage: fuzz.sh smoke|long TARGET BUILD_DIR [SECONDS]}
target=${2:?target: scene or cli}
build=$(cd "${3:?build directory}" && pwd)
src=$(cd "$(dirname "$0")/.." && pwd)
fuzzer=$build/fuzz-build/fuzz/fuzz_$target
if [ ! -x "$fuzzer" ]; then
    echo "fuzz.sh: $fuzzer not built (needs clang with libFuzzer: apt-get install clang libclang-rt-14-dev)" >&2
    exit 1
fi
case $target in
scene) seeds=("$src/fuzz/corpus/scene" "$src/fuzz/regress/scene" "$src/examples")
    opts=(-dict="$src/fuzz/scene.dict" -max_len=16384) ;;
cli) seeds=("$src/fuzz/corpus/cli" "$src/fuzz/regress/cli")
    opts=(-dict="$src/fuzz/cli.dict" -max_len=1024) ;;
*) echo "fuzz.sh: unknown target $target (scene or cli)" >&2; exit 2 ;;
esac
artifacts=$build/fuzz-artifacts/$target
mkdir -p "$artifacts"
opts+=(-artifact_prefix="$artifacts/" -timeout=20 -rss_limit_mb=3072 -print_final_stats=1)

report_crash() {
    echo "fuzz.sh: fuzz_$target found a failure; the input is in $artifacts/." >&2
    echo "  reproduce:  $fuzzer $artifacts/<crash-file>" >&2
    echo "  minimise:   $fuzzer -minimize_crash=1 -runs=100000 $artifacts/<crash-file>" >&2
    echo "  keep it:    cp <minimised> $src/fuzz/regress/$target/<short-name> (replayed by ctest fuzz.replay.$target)" >&2
}

case $mode in
smoke)
    work=$build/fuzz-smoke/$target
    rm -rf "$work"
    mkdir -p "$work"
    if ! "$fuzzer" "${opts[@]}" -runs=20000 -seed=1 "$work" "${seeds[@]}"; then
        report_crash
        exit 1
    fi
    ;;
long)
    seconds=${4:?seconds}
    shift 4
    corpus=$build/fuzz-corpus/$target
    mkdir -p "$corpus"
    if ! "$fuzzer" "${opts[@]}" -max_total_time="$seconds" "$@" "$corpus" "${seeds[@]}"; then
        report_crash
        exit 1
    fi
    ;;
*) echo "fuzz.sh: unknown mode $mode (smoke or long)" >&2; exit 2 ;;
esac
