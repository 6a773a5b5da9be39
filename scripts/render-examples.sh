#!/usr/bin/env bash
# Regenerates the pictures of the examples shown in README.md: one PNG per
# examples/NAME.json, drawn by psys itself (psys run --render), plus the
# energy plot of the cloth (psys run --plot).
#
#   scripts/render-examples.sh PSYS_BINARY [OUTDIR]     (OUTDIR defaults to docs/images)
#
# Each picture is 480x360 and shows the last frame of a run of the example,
# shortened below where an earlier moment shows more. The example's own
# output files go to a temporary directory.
set -euo pipefail

if [ $# -lt 1 ] || [ $# -gt 2 ]; then
  echo "usage: scripts/render-examples.sh PSYS_BINARY [OUTDIR]" >&2
  exit 2
fi
psys=$(cd "$(dirname "$1")" && pwd)/$(basename "$1")
root=$(cd "$(dirname "$0")/.." && pwd)
outdir=${2:-$root/docs/images}
mkdir -p "$outdir"
outdir=$(cd "$outdir" && pwd)
if [ ! -x "$psys" ]; then
  echo "render-examples.sh: $psys is not an executable (build first: make build)" >&2
  exit 2
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"   # the scenes write their own CSV files: keep them out of the tree

# Extra flags per example: a moment that shows more than the last frame.
flags_for() {
  case "$1" in
    bouncing-balls) echo "--duration 1" ;;     # balls in the air, one on the slope
    cloth-small) echo "--duration 2.5" ;;      # swinging back, the free edge rippling
    double-pendulum) echo "--duration 3" ;;
    driven-pendulum) echo "--duration 15" ;;   # the swing built up by resonance
    worm) echo "--camera center=5.15:0.35,extent=1.3" ;;  # close up: it crawled 4.5 m in 10 s
    *) echo "" ;;
  esac
}

n=0
for scene in "$root"/examples/*.json; do
  name=$(basename "$scene" .json)
  # shellcheck disable=SC2046  # flags_for prints words to split
  "$psys" run "$scene" --quiet --size 480x360 --render "$outdir/$name.png" $(flags_for "$name")
  echo "$outdir/$name.png"
  n=$((n + 1))
done
"$psys" run "$root/examples/cloth-small.json" --quiet --size 480x360 --plot "$outdir/cloth-small-energy.png"
echo "$outdir/cloth-small-energy.png"
echo "render-examples.sh: $n examples and 1 plot drawn into $outdir" >&2
