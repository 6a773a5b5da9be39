#!/usr/bin/env bash
# Stiff cloth: psys implicit-euler and rk4 against Bullet's soft-body cloth,
# in one run (issue 7; bench/README.md explains the case and keeps results).
#
#   bash bench/stiff_cloth.sh [BUILD_DIR]
#
# The cloth of the peer bullet_cloth.cpp (bench/README.md, "Peer programs"): N×N nodes (N=100 unless
# set; smaller only to check that the script runs), 2 m × 2 m,
# 1 kg, hanging from two corners of one edge, 1 s simulated. Needs
# libbullet-dev (apt-get install libbullet-dev) and PEERS (the folder of
# the peer programs) holding bullet_cloth.cpp; psys's side is build/stiff_cloth.
#
# Steps: (1) Bullet (float64) at piterations 8..32: the fewest reaching mean
# link strain <= 2%; (2) psys implicit-euler at dt = 1/60 and a sweep of
# larger dt: the largest that stays finite with mean structural strain <= 2%;
# (3) psys rk4: the largest stable dt of a sweep; (4) the chosen Bullet and
# psys runs again, interleaved REPS times; medians and ratios.
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD=${1:-build}
PEERS=${PEERS:-bench/peers}
REPS=${REPS:-3}
KS=${KS:-100}          # structural stiffness (N/m): the softest giving <= 2% mean strain
KD=${KD:-0.1}          # structural damping (N s/m); bend springs get ks/10, kd/10
TOL=${TOL:-1e-2}       # cg_tolerance
N=${N:-100}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT

if [ ! -f /usr/include/bullet/btBulletDynamicsCommon.h ]; then
    echo "stiff_cloth.sh: needs libbullet-dev (apt-get install libbullet-dev)" >&2
    exit 1
fi
if [ ! -f "$PEERS/bullet_cloth.cpp" ]; then
    echo "stiff_cloth.sh: $PEERS/bullet_cloth.cpp not found (set PEERS)" >&2
    exit 1
fi
cmake --build "$BUILD" --target stiff_cloth >/dev/null
g++ -O2 "$PEERS/bullet_cloth.cpp" $(pkg-config --cflags --libs bullet-float64) -o "$out/bullet_cloth64"

# bullet ITER: one JSON line from bullet_cloth's RESULT line (240 steps = 1 s).
bullet() {
    "$out/bullet_cloth64" $N 240 "$1" | awk -v it="$1" '/^RESULT/ {
        for (i = 1; i <= NF; i++) { split($i, kv, "="); v[kv[1]] = kv[2] }
        printf "{\"case\": \"stiff-cloth\", \"solver\": \"bullet\", \"piterations\": %d, \"wall_s\": %.4f, \"ms_per_step\": %s, \"mean_strain\": %s, \"max_strain\": %s}\n",
            it, 240 * v["ms_per_step"] / 1000, v["ms_per_step"], v["mean_strain"], v["max_strain"] }'
}
psys() { "$BUILD/stiff_cloth" "$1" "$2" "$KS" "$KD" $N "$TOL" || true; }
field() { sed -n "s/.*\"$1\": \([^,}]*\).*/\1/p"; }
ok() { # ok LINE: finite and mean strain <= 2%
    [ "$(echo "$1" | field finite)" != false ] && awk -v s="$(echo "$1" | field mean_strain)" 'BEGIN{exit !(s != "nan" && s <= 0.02)}'
}

echo "# 1. Bullet (float64), 240 steps of 1/240 s"
best_it=
for it in 8 16 20 24 28 32; do
    line=$(bullet $it); echo "$line"
    if [ -z "$best_it" ] && ok "$line"; then best_it=$it; fi
done
echo "# 2. psys implicit-euler (ks=$KS, kd=$KD, cg_tolerance=$TOL)"
best_dt=
for dt in 0.016666666666666666 0.033333333333333333 0.05 0.066666666666666667 0.083333333333333333 0.1 0.125 0.2; do
    line=$(psys implicit-euler $dt); echo "$line"
    if ok "$line"; then best_dt=$dt; else break; fi
done
echo "# 3. psys rk4: largest stable dt"
rk_dt=
for dt in 0.001 0.0007 0.0005 0.0004 0.0003 0.0002 0.00015 0.0001; do
    line=$(psys rk4 $dt); echo "$line"
    if [ "$(echo "$line" | field finite)" = true ]; then rk_dt=$dt; break; fi
done
echo "# 4. interleaved: bullet piterations=${best_it:-none}, implicit-euler dt=1/60 and dt=${best_dt:-none}, rk4 dt=${rk_dt:-none}"
: > "$out/b"; : > "$out/i60"; : > "$out/ibig"
for r in $(seq "$REPS"); do
    [ -n "$best_it" ] && bullet "$best_it" | tee -a "$out/b"
    psys implicit-euler 0.016666666666666666 | tee -a "$out/i60"
    [ -n "$best_dt" ] && psys implicit-euler "$best_dt" | tee -a "$out/ibig"
done
median() { field wall_s < "$1" | sort -g | awk '{a[NR] = $1} END {if (NR) print a[int((NR + 1) / 2)]}'; }
b=$(median "$out/b"); i60=$(median "$out/i60"); ibig=$(median "$out/ibig")
echo "# medians of $REPS: bullet ${b:-?} s, implicit-euler dt=1/60 ${i60:-?} s, implicit-euler dt=${best_dt:-?} ${ibig:-?} s"
if [ -n "$b" ] && [ -n "$i60" ]; then
    awk -v b="$b" -v a="$i60" -v c="${ibig:-0}" 'BEGIN {
        printf "{\"case\": \"stiff-cloth-ratio\", \"implicit_dt60_over_bullet\": %.3f, \"implicit_largest_dt_over_bullet\": %.3f}\n", a / b, c / b }'
fi
