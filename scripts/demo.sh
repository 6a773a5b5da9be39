#!/usr/bin/env bash
# The demo behind `make demo`: runs examples/cloth-small.json end to end (a
# 12×12 cloth pinned at two corners, falling and swinging under gravity),
# renders it to a video and plots its energy, and prints a short summary of
# what it wrote.
#
#   scripts/demo.sh PSYS_BINARY [OUTDIR]      (OUTDIR defaults to ./out)
#
# Writes OUTDIR/cloth.csv (trajectory), OUTDIR/cloth-energy.csv (energy),
# OUTDIR/cloth.mp4 (video, 800x600 at 30 frames per simulated second; an
# animated OUTDIR/cloth.gif instead when ffmpeg is not installed) and
# OUTDIR/cloth-energy.png (kinetic, potential and total energy against time).
set -euo pipefail

if [ $# -lt 1 ] || [ $# -gt 2 ]; then
  echo "usage: scripts/demo.sh PSYS_BINARY [OUTDIR]" >&2
  exit 2
fi
psys=$1
outdir=${2:-out}
root=$(cd "$(dirname "$0")/.." && pwd)
scene=$root/examples/cloth-small.json
if [ ! -x "$psys" ]; then
  echo "demo.sh: $psys is not an executable (build first: make build)" >&2
  exit 2
fi

mkdir -p "$outdir"
traj=$outdir/cloth.csv
energy=$outdir/cloth-energy.csv
plot=$outdir/cloth-energy.png
if command -v ffmpeg >/dev/null 2>&1; then
  video=$outdir/cloth.mp4
else
  video=$outdir/cloth.gif   # psys's own GIF encoder: no ffmpeg needed
fi

echo "psys demo: $("$psys" --version)"
echo "scene:     examples/cloth-small.json"
# psys check prints "key: value" lines; keep the ones worth showing.
"$psys" check "$scene" | awk -F': ' '
  $1 == "particles" { p = $2 } $1 == "fixed" { f = $2 } $1 == "springs" { s = $2 }
  $1 == "integrator" { i = $2 } $1 == "dt" { dt = $2 } $1 == "steps" { n = $2 }
  $1 == "duration" { d = $2 }
  END { printf "system:    %s particles (%s pinned), %s springs\n", p, f, s
        printf "solver:    %s, dt = %s s, %s steps, %s s simulated\n", i, dt, n, d }'

start=$(date +%s.%N)
"$psys" run "$scene" --out "$traj" --energy "$energy" --render "$video" --plot "$plot"
end=$(date +%s.%N)

awk -F, -v secs="$(awk -v a="$start" -v b="$end" 'BEGIN { printf "%.2f", b - a }')" \
    -v traj="$traj" -v energy="$energy" -v video="$video" -v plot="$plot" '
  NR == 1 { next }
  NR == 2 { e0 = $5 }
  { frames++; t = $2; ke = $3; pe = $4; e = $5 }
  END {
    printf "run:       %.2f s wall clock, %d frames written (t = 0 to %g s)\n", secs, frames, t
    printf "energy:    total %.6f J at t = 0, %.6f J at the end (kinetic %.6f, potential %.6f)\n", e0, e, ke, pe
    printf "           the difference is what drag and spring damping dissipated\n"
    printf "files:     %s (step,t,i,x,y,z,vx,vy,vz)\n", traj
    printf "           %s (step,t,kinetic,potential,total)\n", energy
    printf "           %s (91 frames: 3 s at 30 frames per second)\n", video
    printf "           %s (energy against time)\n", plot
  }' "$energy"
# Lowest point of the sheet in the last frame: how far it has fallen.
awk -F, 'NR > 1 { if ($1 != step) { step = $1; low = $5 } else if ($5 < low) low = $5 }
         END { printf "cloth:     lowest point %.3f m below the pins in the last frame\n", -low }' "$traj"
