/* Trajectory and energy CSV (docs/cli.md#output-files): %.17g so readers
 * recover the exact doubles. */
#include "mpi/mpi.h"

#include <stdio.h>

int psys_csv_write_trajectory_header(FILE *fp, int dim)
{
    return fputs(dim == 2 ? "step,t,i,x,y,vx,vy\n" : "step,t,i,x,y,z,vx,vy,vz\n", fp) < 0 ? -1 : 0;
}

int psys_csv_write_trajectory_frame(FILE *fp, const psys_system *sys, long long step)
{
    int d = sys->dim;
    for (size_t i = 0; i < sys->n; i++) {
        const double *x = sys->x + i * d, *v = sys->v + i * d;
        int rc = d == 2 ? fprintf(fp, "%lld,%.17g,%zu,%.17g,%.17g,%.17g,%.17g\n", step, sys->t, i, x[0], x[1], v[0], v[1])
                        : fprintf(fp, "%lld,%.17g,%zu,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n", step, sys->t, i, x[0],
                                  x[1], x[2], v[0], v[1], v[2]);
        if (rc < 0)
            return -1;
    }
    return 0;
}

int psys_csv_write_energy_header(FILE *fp)
{
    return fputs("step,t,kinetic,potential,total\n", fp) < 0 ? -1 : 0;
}

int psys_csv_write_energy_frame(FILE *fp, const psys_system *sys, long long step)
{
    double ke = psys_system_kinetic_energy(sys), pe = psys_system_potential_energy(sys);
    return fprintf(fp, "%lld,%.17g,%.17g,%.17g,%.17g\n", step, sys->t, ke, pe, ke + pe) < 0 ? -1 : 0;
}
