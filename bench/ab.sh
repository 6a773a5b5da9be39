#!/bin/sh
# Two builds of psys against each other, interleaved in one run: cloth-100 and
# cloth-1024 rk4 (1 thread), lj-melt (verlet, 1 thread) and the stiff cloth
# (build/stiff_cloth implicit-euler at dt = 1/60). Prints each side's median
# and the ratio NEW/OLD per case (time per step: below 1 is faster). This
# host drifts 10-25 % over minutes, so only ratios from one interleaved run
# mean anything.
#
#   sh bench/ab.sh OLD_BUILD NEW_BUILD [ROUNDS]     (ROUNDS default 5)
#
# BENCH_SECONDS (default 0.4) is each repetition's length; CASES picks some of the cases.
set -eu
OLD=$1
NEW=$2
ROUNDS=${3:-5}
SECS=${BENCH_SECONDS:-0.4}
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
export OMP_WAIT_POLICY=PASSIVE
median() { sort -n | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
ns() { sed 's/.*"ns_per_particle_step":\([0-9.]*\).*/\1/'; }
stiff() { "$1/stiff_cloth" implicit-euler 0.016666666666666666 | sed 's/.*"ms_per_step": *\([0-9.]*\).*/\1/'; }
CASES=${CASES:-"cloth-100 cloth-1024 lj-melt stiff-cloth"}
for r in $(seq "$ROUNDS"); do
  for c in $CASES; do
    for side in old new; do
      b=$OLD; [ "$side" = new ] && b=$NEW
      if [ "$c" = stiff-cloth ]; then
        stiff "$b" >> "$WORK/$c.$side"
      else
        "$b/psys" bench "$c" --threads 1 --reps 3 --seconds "$SECS" | ns >> "$WORK/$c.$side"
      fi
    done
  done
done
printf '%-12s %12s %12s %8s   (%s rounds; ns per particle-step, stiff-cloth ms per step)\n' case old new new/old "$ROUNDS"
for c in $CASES; do
  o=$(median < "$WORK/$c.old"); n=$(median < "$WORK/$c.new")
  printf '%-12s %12s %12s %8s\n' "$c" "$o" "$n" "$(echo "$n $o" | awk '{printf "%.3f", $1/$2}')"
done
