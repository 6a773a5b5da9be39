#!/usr/bin/env bash
# LJ melt, psys against LAMMPS in the same run (interleaved; benchmarks are programs,
# not tests: bench/README.md).
#
#   bench/lj_vs_lammps.sh [BUILD_DIR] [REPS] [THREADS] [SCALE]
#
# SCALE 1 (default): 32,000 atoms; 2: 256,000 (LAMMPS's -var x/y/z 2).
# psys: BUILD_DIR/pair_bench lj-melt (32,000 × SCALE³ atoms, 100 velocity-Verlet steps,
# dt 0.005, cutoff 2.5, skin 0.3; see bench/pair_bench.c). LAMMPS:
# the peer in.lj in $PEERS (bench/README.md, "Peer programs"; the same system; its neighbour lists are rebuilt
# every 20 steps without a check, psys's whenever needed), and the same
# input with LAMMPS checking displacements every step ("check yes", what psys
# does; case lammps-lj-melt-check). Prints one JSON line per run and a summary
# line with the medians and their ratios. Without `lmp` on the PATH (Debian:
# apt-get install lammps) only psys runs.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
build=${1:-$here/../build}
reps=${2:-3}
threads=${3:-1}
scale=${4:-1}
cells=$((20 * scale))
atoms=$((4 * cells * cells * cells))
peers=${PEERS:-$here/peers}
bench="$build/pair_bench"
[ -x "$bench" ] || { echo "lj_vs_lammps: $bench not built" >&2; exit 2; }
have_lmp=0
if command -v lmp >/dev/null 2>&1 && [ -f "$peers/in.lj" ]; then have_lmp=1; fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
psys_s=()
lmp_s=()
lmpc_s=()
if [ "$have_lmp" = 1 ]; then
    sed 's/^neigh_modify.*/neigh_modify\tdelay 0 every 1 check yes/' "$peers/in.lj" >"$work/in.lj.check"
fi
lmp_run() { # input, case name; appends the loop time to the array named by $3
    (cd "$work" && OMP_NUM_THREADS=1 lmp -in "$1" -var x "$scale" -var y "$scale" -var z "$scale" \
        -log log.lammps -screen none >/dev/null 2>&1)
    local t b
    t=$(sed -n 's/^Loop time of \([0-9.]*\) on .*/\1/p' "$work/log.lammps")
    b=$(sed -n 's/^Neighbor list builds = \([0-9]*\).*/\1/p' "$work/log.lammps")
    echo "{\"case\":\"$2\",\"atoms\":$atoms,\"steps\":100,\"ranks\":1,\"seconds\":$t,\"ns_per_atom_step\":$(awk -v t="$t" -v a="$atoms" 'BEGIN{printf "%.1f", t*1e9/(a*100)}'),\"list_builds\":$b}"
    eval "$3+=(\"\$t\")"
}
for ((r = 0; r < reps; r++)); do
    line=$("$bench" lj-melt --cells "$cells" --steps 100 --threads "$threads")
    echo "$line"
    psys_s+=("$(sed -n 's/.*"seconds":\([0-9.]*\).*/\1/p' <<<"$line")")
    if [ "$have_lmp" = 1 ]; then
        lmp_run "$peers/in.lj" lammps-lj-melt lmp_s
        lmp_run "$work/in.lj.check" lammps-lj-melt-check lmpc_s
    fi
done
median() { printf '%s\n' "$@" | sort -g | awk '{a[NR]=$1} END{print a[int((NR+1)/2)]}'; }
mp=$(median "${psys_s[@]}")
if [ "$have_lmp" = 1 ]; then
    ml=$(median "${lmp_s[@]}")
    mc=$(median "${lmpc_s[@]}")
    awk -v p="$mp" -v l="$ml" -v c="$mc" -v th="$threads" 'BEGIN{printf "{\"case\":\"lj-melt-vs-lammps\",\"atoms\":'"$atoms"',\"psys_threads\":%d,\"psys_seconds\":%s,\"lammps_seconds\":%s,\"lammps_check_seconds\":%s,\"psys_over_lammps\":%.3f,\"psys_over_lammps_check\":%.3f}\n", th, p, l, c, p/l, p/c}'
else
    echo "{\"case\":\"lj-melt-vs-lammps\",\"psys_threads\":$threads,\"psys_seconds\":$mp,\"lammps\":\"not installed\"}"
fi
