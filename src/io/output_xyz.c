/* Extended XYZ trajectories for OVITO and ASE (docs/cli.md "XYZ"): frames
 * concatenated in one file, each with the particle count, a key=value comment
 * line (Properties=, Time=, step=) and a row per particle. */
#include "mpi/mpi.h"

#include <stdio.h>

int psys_xyz_write_frame(FILE *fp, const psys_system *sys, long long step)
{
    int d = sys->dim;
    if (fprintf(fp,
                "%zu\nProperties=species:S:1:pos:R:3:velo:R:3:mass:R:1:id:I:1:flags:I:1 Time=%.17g step=%lld "
                "pbc=\"F F F\"\n",
                sys->n, sys->t, step) < 0)
        return -1;
    for (size_t i = 0; i < sys->n; i++) {
        const double *x = sys->x + i * (size_t)d, *v = sys->v + i * (size_t)d;
        double z = d == 3 ? x[2] : 0.0, vz = d == 3 ? v[2] : 0.0;
        if (fprintf(fp, "X %.17g %.17g %.17g %.17g %.17g %.17g %.17g %zu %u\n", x[0], x[1], z, v[0], v[1], vz,
                    sys->mass[i], i, (unsigned)(sys->flags[i] & PSYS_PARTICLE_NOT_FREE)) < 0)
            return -1;
    }
    return 0;
}
