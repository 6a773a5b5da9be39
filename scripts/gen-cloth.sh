#!/usr/bin/env bash
# Writes a cloth scene to standard output: an N×N sheet of particles lying flat
# in the x-z plane (y = 0), pinned at the two corners of its z = 0 edge, with
# structural, shear and bend springs, gravity and a little air drag.
#
#   scripts/gen-cloth.sh [N] > examples/cloth-small.json     (N defaults to 12)
#
# Particle (i, j), with i along x and j along z, is number j*N + i and has the
# id "cloth[i,j]"; springs refer to particles by number (0-based index).
# Springs: structural (i,j)-(i+1,j) and (i,j)-(i,j+1); shear along both
# diagonals of every cell; bend (i,j)-(i+2,j) and (i,j)-(i,j+2), weaker.
# Rest lengths are left out, so each spring rests at its initial length.
# Settings below are environment variables so variants need no editing:
#   SPACING (m), MASS (kg per particle), KS, KD (structural and shear),
#   BEND (fraction of KS and KD for bend springs), DRAG, DT, DURATION, EVERY.
set -euo pipefail
N=${1:-12}
case "$N" in
  '' | *[!0-9]*) echo "gen-cloth.sh: N must be a whole number >= 3 (got $N)" >&2; exit 2 ;;
esac
if [ "$N" -lt 3 ]; then
  echo "gen-cloth.sh: N must be a whole number >= 3 (got $N)" >&2
  exit 2
fi
awk -v n="$N" \
    -v h="${SPACING:-0.1}" -v m="${MASS:-0.01}" \
    -v ks="${KS:-1000}" -v kd="${KD:-0.05}" -v bend="${BEND:-0.2}" \
    -v drag="${DRAG:-0.002}" -v dt="${DT:-0.001}" -v dur="${DURATION:-3.0}" \
    -v every="${EVERY:-20}" '
function num(x) { return sprintf("%.10g", x) }
function spring(a, b, k, d) {
  printf "%s    {\"type\": \"spring\", \"a\": %d, \"b\": %d, \"ks\": %s, \"kd\": %s}", sep, a, b, num(k), num(d)
  sep = ",\n"
}
BEGIN {
  printf "{\n  \"psys\": 1,\n  \"dim\": 3,\n  \"integrator\": \"rk4\",\n"
  printf "  \"dt\": %s,\n  \"duration\": %s,\n  \"particles\": [\n", num(dt), num(dur)
  for (j = 0; j < n; j++)
    for (i = 0; i < n; i++) {
      pin = (j == 0 && (i == 0 || i == n - 1)) ? ", \"fixed\": true" : ""
      printf "    {\"id\": \"cloth[%d,%d]\", \"x\": [%s, 0, %s], \"mass\": %s%s}%s\n", \
             i, j, num(i * h), num(j * h), num(m), pin, (j * n + i < n * n - 1) ? "," : ""
    }
  printf "  ],\n  \"forces\": [\n"
  printf "    {\"type\": \"gravity\", \"g\": [0, -9.81, 0]},\n"
  printf "    {\"type\": \"drag\", \"kd\": %s},\n", num(drag)
  sep = ""
  for (j = 0; j < n; j++)
    for (i = 0; i < n; i++) {
      p = j * n + i
      if (i + 1 < n) spring(p, p + 1, ks, kd)                       # structural
      if (j + 1 < n) spring(p, p + n, ks, kd)
      if (i + 1 < n && j + 1 < n) spring(p, p + n + 1, ks, kd)      # shear
      if (i > 0 && j + 1 < n) spring(p, p + n - 1, ks, kd)
      if (i + 2 < n) spring(p, p + 2, bend * ks, bend * kd)         # bend
      if (j + 2 < n) spring(p, p + 2 * n, bend * ks, bend * kd)
    }
  printf "\n  ],\n"
  printf "  \"output\": {\"every\": %d, \"trajectory\": \"cloth.csv\", \"energy\": \"cloth-energy.csv\"}\n}\n", every
}'
