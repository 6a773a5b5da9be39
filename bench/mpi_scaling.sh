#!/usr/bin/env bash
# MPI strong and weak scaling of psys run (docs/mpi.md), one JSON line per run:
#   bash bench/mpi_scaling.sh build-mpi/psys [MPIEXEC] [RANKS...]
# Lennard-Jones melt (fcc, density 0.8442, T* about 1.4 by random velocities,
# cutoff 2.5σ, grid method, velocity Verlet, periodic cube) and direct
# gravity (a uniform ball). Strong: fixed N, R = 1, 2, 4. Weak: N/R fixed.
# Wall time is the median of REPS runs (REPS=3). On a 2-core machine R = 4
# is oversubscribed: report it as such. MODE=domain (default: each rank
# holds its slab's particles and ghosts) or MODE=replicated (every rank holds
# every particle) is passed as --mpi MODE. LJ_CELLS (default 20: 32,000
# atoms) sizes the strong-scaling melt; the weak one has about 8,000 atoms
# per rank. With LAMMPS=1 and Debian's lmp (built with Open MPI) on the
# PATH, LAMMPS runs the same LJ cases right after psys's (lj/cut, the melt of
# the peer in.lj (bench/README.md, "Peer programs"; $PEERS) at the same sizes, neighbour lists checked every
# step as psys does; its "Loop time" over 100 steps, start-up excluded), so
# the two codes' scaling is measured on the same machine in the same run.
set -euo pipefail
PSYS=$(realpath "$1")
MPIEXEC=${2:-mpiexec.mpich}
shift $(( $# >= 2 ? 2 : $# ))
RANKS=("$@")
[ ${#RANKS[@]} -eq 0 ] && RANKS=(1 2 4)
REPS=${REPS:-3}
STEPS=${STEPS:-100}
STEPS0=${STEPS0:-10}
MODE=${MODE:-domain}
LJ_CELLS=${LJ_CELLS:-20}
FLAGS=()
if "$MPIEXEC" --version 2>&1 | grep -qi 'open mpi\|openrte'; then
    FLAGS=(--oversubscribe)
    export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
fi
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT

# lj_scene CELLS FILE: fcc lattice of CELLS³ unit cells (4·CELLS³ atoms).
lj_scene() {
    awk -v m="$1" 'BEGIN {
        a = (4 / 0.8442) ^ (1 / 3); L = m * a; srand(1)
        printf "{\"psys\":1,\"dim\":3,\"integrator\":\"verlet\",\"dt\":0.005,\"steps\":10,"
        printf "\"box\":{\"lo\":[0,0,0],\"hi\":[%.10g,%.10g,%.10g],\"periodic\":[true,true,true]},\"particles\":[", L, L, L
        split("0 0 0 0.5 0.5 0 0.5 0 0.5 0 0.5 0.5", b, " "); n = 0
        for (i = 0; i < m; i++) for (j = 0; j < m; j++) for (k = 0; k < m; k++) for (q = 0; q < 4; q++) {
            printf "%s{\"x\":[%.10g,%.10g,%.10g],\"v\":[%.6f,%.6f,%.6f]}", (n++ ? "," : ""),
                (i + b[3*q+1]) * a, (j + b[3*q+2]) * a, (k + b[3*q+3]) * a, 4*(rand()-0.5), 4*(rand()-0.5), 4*(rand()-0.5)
        }
        printf "],\"forces\":[{\"type\":\"pair\",\"law\":\"lennard-jones\",\"epsilon\":1,\"sigma\":1,\"cutoff\":2.5,\"method\":\"grid\",\"skin\":0.3}]}\n"
    }' >"$2"
}

# ball_scene N FILE: N bodies in a unit ball, direct softened gravity.
ball_scene() {
    awk -v n="$1" 'BEGIN {
        srand(2); printf "{\"psys\":1,\"dim\":3,\"integrator\":\"verlet\",\"dt\":0.001,\"steps\":10,\"particles\":["
        for (c = 0; c < n; ) { x = 2*rand()-1; y = 2*rand()-1; z = 2*rand()-1; if (x*x+y*y+z*z > 1) continue
            printf "%s{\"x\":[%.8f,%.8f,%.8f],\"mass\":%.6f}", (c++ ? "," : ""), x, y, z, 1.0/n }
        printf "],\"forces\":[{\"type\":\"pair\",\"law\":\"gravity\",\"G\":1,\"softening\":0.01,\"method\":\"direct\"}]}\n"
    }' >"$2"
}

# med_time SCENE R STEPS: median wall seconds of REPS runs on R ranks.
med_time() {
    local scene=$1 r=$2 steps=$3 times=() t0 t1
    for _ in $(seq "$REPS"); do
        t0=$(date +%s.%N)
        if [ "$r" -eq 1 ]; then
            "$PSYS" run "$scene" --steps "$steps" --threads 1 --quiet
        else
            "$MPIEXEC" "${FLAGS[@]}" -n "$r" "$PSYS" run "$scene" --steps "$steps" --mpi "$MODE" --quiet
        fi
        t1=$(date +%s.%N)
        times+=("$(awk -v a="$t0" -v b="$t1" 'BEGIN { print b - a }')")
    done
    printf '%s\n' "${times[@]}" | sort -g | awk '{ a[NR] = $1 } END { print a[int((NR + 1) / 2)] }'
}

# run_case NAME SCENE R: wall time of STEPS steps and the time per step with
# start-up (launch, scene load and broadcast) taken out: the difference
# between runs of STEPS and STEPS0 steps.
run_case() {
    local name=$1 scene=$2 r=$3 t t0 n
    t=$(med_time "$scene" "$r" "$STEPS")
    t0=$(med_time "$scene" "$r" "$STEPS0")
    n=$(grep -o '"x":' "$scene" | wc -l)
    awk -v name="$name" -v mode="$MODE" -v n="$n" -v r="$r" -v s="$STEPS" -v s0="$STEPS0" -v t="$t" -v t0="$t0" -v c="$(nproc)" 'BEGIN {
        ps = (t - t0) / (s - s0)
        printf "{\"case\":\"%s\",\"mode\":\"%s\",\"particles\":%d,\"ranks\":%d,\"steps\":%d,\"wall_s\":%.3f,\"startup_s\":%.3f,\"ms_per_step\":%.3f,\"us_per_particle_step\":%.3f,\"cores\":%d}\n",
            name, (r > 1 ? mode : "serial"), n, r, s, t, t0 - s0 * ps, 1000 * ps, 1e6 * ps / n, c }'
}

# lammps_case NAME CELLS R: LAMMPS's LJ melt of 4·CELLS³ atoms on R ranks.
PEERS=${PEERS:-$(dirname "$0")/peers}
lammps_case() {
    local name=$1 cells=$2 r=$3 times=() t n
    for _ in $(seq "$REPS"); do
        (cd "$WORK" && OMP_NUM_THREADS=1 OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 \
            mpiexec.openmpi --oversubscribe -n "$r" lmp -in in.lj.check -var x "$(awk -v c="$cells" 'BEGIN { print c / 20 }')" \
            -var y "$(awk -v c="$cells" 'BEGIN { print c / 20 }')" -var z "$(awk -v c="$cells" 'BEGIN { print c / 20 }')" \
            -log log.lammps -screen none >/dev/null 2>&1)
        times+=("$(sed -n 's/^Loop time of \([0-9.]*\) on .*/\1/p' "$WORK/log.lammps")")
    done
    t=$(printf '%s\n' "${times[@]}" | sort -g | awk '{ a[NR] = $1 } END { print a[int((NR + 1) / 2)] }')
    n=$(sed -n 's/^Loop time of .* with \([0-9]*\) atoms.*/\1/p' "$WORK/log.lammps")
    awk -v name="$name" -v n="$n" -v r="$r" -v t="$t" -v c="$(nproc)" 'BEGIN {
        printf "{\"case\":\"lammps-%s\",\"particles\":%d,\"ranks\":%d,\"steps\":100,\"loop_s\":%.3f,\"ms_per_step\":%.3f,\"us_per_particle_step\":%.3f,\"cores\":%d}\n",
            name, n, r, t, 10 * t, 1e4 * t / n, c }'
}
with_lammps=0
if [ "${LAMMPS:-0}" = 1 ] && command -v lmp >/dev/null 2>&1 && command -v mpiexec.openmpi >/dev/null 2>&1 \
    && [ -f "$PEERS/in.lj" ]; then
    with_lammps=1
    sed 's/^neigh_modify.*/neigh_modify\tdelay 0 every 1 check yes/' "$PEERS/in.lj" >"$WORK/in.lj.check"
fi

lj_scene "$LJ_CELLS" "$WORK/ljs.json"
ball_scene 2000 "$WORK/ball2000.json"
for r in "${RANKS[@]}"; do run_case lj-strong "$WORK/ljs.json" "$r"; done
if [ "$with_lammps" = 1 ]; then
    for r in "${RANKS[@]}"; do lammps_case lj-strong "$LJ_CELLS" "$r"; done
fi
for r in "${RANKS[@]}"; do run_case gravity-strong "$WORK/ball2000.json" "$r"; done
for r in "${RANKS[@]}"; do
    case $r in 1) c=13 ;; 2) c=16 ;; 4) c=20 ;; *) c=$(awk -v r="$r" 'BEGIN { printf "%d", (2000 * r) ^ (1/3) + 0.5 }') ;; esac
    lj_scene "$c" "$WORK/ljw$r.json"   # 8788, 16384, 32000 atoms: about 8,000 per rank
    run_case lj-weak "$WORK/ljw$r.json" "$r"
    if [ "$with_lammps" = 1 ]; then lammps_case lj-weak "$c" "$r"; fi
done
