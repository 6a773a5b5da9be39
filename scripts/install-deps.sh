#!/usr/bin/env bash
# Installs the Debian 12 packages psys needs to build and test, when missing.
# As root it runs apt-get; otherwise it prints the exact command to run.
set -euo pipefail
# libcairo2-dev and fonts-dejavu-core: pictures and plots (psys run --render,
# --plot, psys plot); ffmpeg: --render out.mp4 (and better GIFs; optional at
# run time, the MP4 tests are skipped without it); libxml2-utils: xmllint,
# which the VTK XML tests use to parse the files back; clang and
# libclang-rt-14-dev: libFuzzer for the fuzz targets (fuzz/, docs/trust.md).
# The viewer (psys view, apps/view/): libsdl2-dev, libepoxy-dev (OpenGL 3.3
# core), libstb-dev (stb_truetype for its text), libgl1-mesa-dri (software
# GL); its tests run it under xvfb (+ xauth) and drive it with xdotool,
# x11-utils (xwininfo), imagemagick (import: X screenshots) and jq (reads
# the saved scene). python3: tests/tools/md_links.py, the docs' link check.
# mpich and libmpich-dev: the MPI build (make test-mpi, docs/mpi.md;
# Open MPI's libopenmpi-dev works too).
# lammps: Debian 12's LAMMPS (command `lmp`), for tests/cli/lammps.sh, which
# runs a Lennard-Jones melt in LAMMPS and in psys (psys import lammps) and
# compares their energies (skipped without it), and bench/lj_vs_lammps.sh.
# valgrind, libbullet-dev and g++: bench/results.py's callgrind step and
# bench/stiff_cloth.sh (Bullet's side), which the test bench.results_quick
# runs at tiny sizes.
PKGS=(cmake ninja-build pkg-config gcc make libc6-dev libcjson-dev libcairo2-dev fonts-dejavu-core ffmpeg libxml2-utils
      clang libclang-rt-14-dev
      libsdl2-dev libepoxy-dev libstb-dev libgl1-mesa-dri xvfb xauth xdotool x11-utils imagemagick jq
      lammps mpich libmpich-dev python3 valgrind libbullet-dev g++)
missing=()
for p in "${PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0
cmd="apt-get -o DPkg::Lock::Timeout=600 install -y --no-install-recommends ${missing[*]}"
if [ "$(id -u)" -ne 0 ]; then
  echo "psys needs these Debian packages: ${missing[*]}" >&2
  echo "run as root:  apt-get update && $cmd" >&2
  exit 1
fi
echo "installing: ${missing[*]}" >&2
apt-get update -q >&2
$cmd >&2
