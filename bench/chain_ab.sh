#!/bin/sh
# The chain sweep (all rk4 stages in one pass over the particles,
# src/spring_fused.c) against stage by stage (PSYS_CHAIN=0), interleaved in
# one run: `psys bench CASE` (rk4) on 1 and 2 threads, each side's median
# ns per particle-step and their ratio. Usage:
# bench/chain_ab.sh [BUILD_DIR] [ROUNDS] [CASES] (defaults: build, 5,
# "rope-1000000 cloth-1024 cloth-256 cloth-100"). Same bits either way, so
# only the time differs; compare the ratios, the host's load shows in both.
set -eu
BUILD=${1:-build}
ROUNDS=${2:-5}
CASES=${3:-"rope-1000000 cloth-1024 cloth-256 cloth-100"}
export OMP_WAIT_POLICY=PASSIVE
TMP=${TMPDIR:-/tmp}/psys-chain-ab
median() { sort -n | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
ns() { sed -n 's/.*"integrator":"rk4".*"ns_per_particle_step":\([0-9.]*\).*/\1/p'; }
for C in $CASES; do
  for T in 1 2; do
    : > "$TMP.on"; : > "$TMP.off"
    for r in $(seq "$ROUNDS"); do
      PSYS_CHAIN=0 "$BUILD/psys" bench "$C" --integrator rk4 --reps 3 --threads "$T" | ns >> "$TMP.off"
      PSYS_CHAIN=1 "$BUILD/psys" bench "$C" --integrator rk4 --reps 3 --threads "$T" | ns >> "$TMP.on"
    done
    OFF=$(median < "$TMP.off"); ON=$(median < "$TMP.on")
    printf '%s rk4, %s thread(s): stage by stage %s ns, chain %s ns per particle-step; chain/stages = %s\n' \
      "$C" "$T" "$OFF" "$ON" "$(echo "$ON $OFF" | awk '{printf "%.3f", $1/$2}')"
  done
done
