#!/bin/sh
# psys bench cloth-N (rk4, 1 thread, and 2 threads for the largest N) and the
# plain-C reference, the peer ref_cloth.c in $PEERS (bench/README.md, "Peer
# programs"; gcc -O3 -march=native),
# interleaved in one run; prints each side's median ns per particle-step and
# their ratio per size. Usage: bench/cloth_vs_ref.sh [BUILD_DIR] [ROUNDS] [SIZES]
# (defaults: build, 3, "100 256 1024"); BENCH_SECONDS (default 0.4) is each
# repetition's length on both sides. Needs gcc; the host's load shows in
# both sides alike, so compare the ratios, not the absolute times. Both
# sides flush subnormal results to zero (ref_cloth with FTZ=1), or neither
# with PSYS_FLUSH_SUBNORMALS=0.
set -eu
BUILD=${1:-build}
ROUNDS=${2:-3}
SIZES=${3:-"100 256 1024"}
SECS=${BENCH_SECONDS:-0.4}
LARGEST=$(printf '%s\n' $SIZES | sort -n | tail -1)
HERE=$(cd "$(dirname "$0")" && pwd)
REF_SRC=${REF_SRC:-$HERE/peers/ref_cloth.c}
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
REF="$WORK/ref_cloth"
gcc -O3 -march=native "$REF_SRC" -lm -o "$REF"
export OMP_WAIT_POLICY=PASSIVE
# like with like: psys flushes subnormal results to zero unless
# PSYS_FLUSH_SUBNORMALS=0 (docs/cli.md), and ref_cloth does with FTZ=1
REF_ENV="env FTZ=1"
[ "${PSYS_FLUSH_SUBNORMALS:-1}" = 0 ] && REF_ENV=env
echo "# subnormals: $([ "$REF_ENV" = env ] && echo kept || echo flushed) on both sides"
BW=$("$BUILD/psys" bench cloth-100 --steps 1 --reps 1 | sed 's/.*"bandwidth_gbs":\([0-9.]*\).*/\1/')
echo "# STREAM triad, 1 thread: $BW GB/s"
median() { sort -n | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
for N in $SIZES; do
  : > "$WORK/p1"; : > "$WORK/p2"; : > "$WORK/r"
  for r in $(seq "$ROUNDS"); do
    "$BUILD/psys" bench cloth-$N --reps 3 --seconds "$SECS" --bandwidth "$BW" --threads 1 | tee -a "$WORK/log" \
      | sed 's/.*"ns_per_particle_step":\([0-9.]*\).*/\1/' >> "$WORK/p1"
    $REF_ENV "$REF" "$N" 3 "$SECS" | grep RESULT | sed 's/.*ns_per_particle_step=\([0-9.]*\).*/\1/' >> "$WORK/r"
    if [ "$N" -eq "$LARGEST" ]; then
      "$BUILD/psys" bench cloth-$N --reps 3 --seconds "$SECS" --bandwidth "$BW" --threads 2 | tee -a "$WORK/log" \
        | sed 's/.*"ns_per_particle_step":\([0-9.]*\).*/\1/' >> "$WORK/p2"
    fi
  done
  P1=$(median < "$WORK/p1"); R=$(median < "$WORK/r")
  FLOOR=$(tail -n "$((ROUNDS * (N == LARGEST ? 2 : 1)))" "$WORK/log" | head -1 | sed 's/.*"floor_ns_per_particle_step":\([0-9.]*\).*/\1/')
  printf 'cloth-%s rk4: psys %s ns, ref_cloth %s ns per particle-step; psys/ref = %s; floor %s ns: psys %sx, ref %sx\n' \
    "$N" "$P1" "$R" "$(echo "$P1 $R" | awk '{printf "%.3f", $1/$2}')" "$FLOOR" \
    "$(echo "$P1 $FLOOR" | awk '{printf "%.2f", $1/$2}')" "$(echo "$R $FLOOR" | awk '{printf "%.2f", $1/$2}')"
  if [ -s "$WORK/p2" ]; then
    P2=$(median < "$WORK/p2")
    printf 'cloth-%s rk4, 2 threads: %s ns per particle-step; speed-up over 1 thread %s\n' "$N" "$P2" \
      "$(echo "$P1 $P2" | awk '{printf "%.2f", $1/$2}')"
  fi
done
