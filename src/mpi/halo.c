/* The local ODE of a rank: its local system's, with the ghosts' entries
 * filled in by the halo exchange before every evaluation and every rank's
 * largest displacements gathered to tell when the ghosts may be incomplete;
 * and the solver stepping it. */
#include "mpi/domain.h"

#include <float.h>
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---- the local ODE: the local system's, with ghosts filled in first ---- */

/* Owners send their particles' x and v to the ranks holding them as ghosts. */
int psys__domain_halo_exchange(psys__domain *D, double *y)
{
    const size_t d = (size_t)D->dim, nd = D->nloc * d, rl = 2 * d;
    int nreq = 0;
    for (int r = 0; r < D->size; r++)
        if (D->rcount[r] > 0
            && MPI_Irecv(D->rbuf + D->roff[r] * rl, (int)((size_t)D->rcount[r] * rl), MPI_DOUBLE, r, HALO_TAG, D->comm,
                         &D->req[nreq++])
                   != MPI_SUCCESS)
            return -1;
    for (int r = 0; r < D->size; r++) {
        if (D->scount[r] == 0)
            continue;
        double *b = D->sbuf + D->soff[r] * rl;
        for (size_t t = D->soff[r]; t < D->soff[r + 1]; t++, b += rl) {
            size_t i = D->sidx[t];
            memcpy(b, y + i * d, d * sizeof(double));
            memcpy(b + d, y + nd + i * d, d * sizeof(double));
        }
        if (MPI_Isend(D->sbuf + D->soff[r] * rl, (int)((size_t)D->scount[r] * rl), MPI_DOUBLE, r, HALO_TAG, D->comm,
                      &D->req[nreq++])
            != MPI_SUCCESS)
            return -1;
    }
    if (nreq && MPI_Waitall(nreq, D->req, D->stat) != MPI_SUCCESS)
        return -1;
    const double *b = D->rbuf;
    for (size_t t = 0; t < D->roff[D->size]; t++, b += rl) {
        size_t i = D->ridx[t];
        memcpy(y + i * d, b, d * sizeof(double));
        memcpy(y + nd + i * d, b + d, d * sizeof(double));
    }
    return 0;
}

/* The two largest displacements of owned particles since the redistribution
 * into top[0] >= top[1] (minimum image on periodic axes; NaN positions are
 * left to the solver's finite check). */
static void owned_displacements(const psys__domain *D, const double *x, double top[2])
{
    const int d = D->dim;
    const psys__box *box = &D->local->box;
    bool per[3];
    double half[3];
    for (int k = 0; k < 3; k++) {
        per[k] = box->on && box->periodic[k];
        half[k] = 0.5 * box->len[k];
    }
    double m1 = 0, m2 = 0;
    for (size_t i = 0; i < D->nloc; i++) {
        if (!D->own[i])
            continue;
        double r2 = 0;
        for (int k = 0; k < d; k++) {
            double dx = x[i * d + k] - D->xref[i * d + k];
            if (per[k]) { /* positions are wrapped after every step: |dx| < 1.5 boxes */
                if (dx > half[k])
                    dx -= box->len[k];
                else if (dx < -half[k])
                    dx += box->len[k];
            }
            r2 += dx * dx;
        }
        if (r2 > m1) {
            m2 = m1;
            m1 = r2;
        } else if (r2 > m2) {
            m2 = r2;
        }
    }
    top[0] = sqrt(m1);
    top[1] = sqrt(m2);
}

static void dd_get_state(void *ctx, double *y)
{
    psys__domain *D = ctx;
    D->inner.get_state(D->inner.ctx, y);
}
static void dd_set_state(void *ctx, const double *y)
{
    psys__domain *D = ctx;
    D->inner.set_state(D->inner.ctx, y);
}
static double dd_get_time(void *ctx)
{
    psys__domain *D = ctx;
    return D->inner.get_time(D->inner.ctx);
}
static void dd_set_time(void *ctx, double t)
{
    psys__domain *D = ctx;
    D->inner.set_time(D->inner.ctx, t);
}

/* The ghosts' entries of y are overwritten with their owners' values (y is
 * a solver's trial state in its own buffer, never the current state; the
 * solvers then carry the owners' values on, since ghosts' derivatives are
 * 0). Ghosts' state is their owners' business. */
static psys_status dd_derivative(void *ctx, double t, const double *y, double *ydot)
{
    psys__domain *D = ctx;
    const size_t d = (size_t)D->dim, nd = D->nloc * d;
    double *yw = (double *)y; /* the solver's buffer, not a const object */
    int failed = psys__domain_halo_exchange(D, yw) != 0;
    if (D->bonds && psys__bonds_evaluate(D->bonds, D->comm, t, yw, D->nloc) != 0)
        failed = 1;
    double in[3] = {0, 0, 0};
    if (isfinite(D->delta))
        owned_displacements(D, yw, in);
    psys_status st = failed ? PSYS_ERR_INVALID : D->inner.derivative(D->inner.ctx, t, yw, ydot);
    in[2] = st != PSYS_OK ? 1.0 : 0.0;
    /* every rank's two largest displacements and failure flag */
    if (MPI_Allgather(in, 3, MPI_DOUBLE, D->gath, 3, MPI_DOUBLE, D->comm) != MPI_SUCCESS)
        return psys__fail(&D->err, PSYS_ERR_INVALID, "MPI exchange of the state failed");
    double m1 = 0, m2 = 0, bad = 0;
    for (int r = 0; r < D->size; r++) {
        for (int k = 0; k < 2; k++) {
            double v = D->gath[3 * r + k];
            if (v > m1) {
                m2 = m1;
                m1 = v;
            } else if (v > m2) {
                m2 = v;
            }
        }
        bad = fmax(bad, D->gath[3 * r + 2]);
    }
    D->dmax = m1 + m2; /* no pair can have closed its gap by more */
    if (bad != 0)
        return psys__fail(&D->err, PSYS_ERR_INVALID, "a force evaluation failed on %s",
                          st != PSYS_OK ? "this rank" : "another rank");
    if (!(D->dmax < D->skin)) {
        D->stale = true; /* the ghosts may miss a pair: redistribute and take the step again */
        return psys__fail(&D->err, PSYS_ERR_INVALID, "particles moved too far for the ghosts");
    }
    for (size_t i = 0; i < D->nloc; i++)
        if (!D->own[i])
            for (size_t k = 0; k < d; k++)
                ydot[i * d + k] = ydot[nd + i * d + k] = 0.0;
    return PSYS_OK;
}

static void dd_project(void *ctx, double t, double *y)
{
    psys__domain *D = ctx;
    D->inner.project(D->inner.ctx, t, y); /* the owned controlled particles; ghosts come with the halo */
}

static void dd_reduce_sum(void *ctx, double *values, int count)
{
    psys__domain *D = ctx;
    if (count >= 2) /* the second value counts components: only owned ones are this rank's */
        values[1] = (double)(2 * D->nown * (size_t)D->dim);
    MPI_Allreduce(MPI_IN_PLACE, values, count, MPI_DOUBLE, MPI_SUM, D->comm);
}

/* The solver of the local ODE: created at the first decomposition, pointed
 * at the new local particles after each migration. */
int psys__domain_make_solver(psys__domain *D)
{
    D->inner = psys_system_ode(D->local);
    psys_ode o;
    memset(&o, 0, sizeof o);
    o.size = D->inner.size;
    o.npos = D->inner.npos;
    o.ctx = D;
    o.get_state = dd_get_state;
    o.set_state = dd_set_state;
    o.get_time = dd_get_time;
    o.set_time = dd_set_time;
    o.derivative = dd_derivative;
    o.reduce_sum = dd_reduce_sum;
    if (D->inner.project)
        o.project = dd_project;
    o.block = D->dim;
    if (D->solver) /* after a migration: the same solver, its settings and next step size */
        return psys__solver_rebind(D->solver, &o) == PSYS_OK ? 0 : -1;
    psys_error e;
    psys_solver *s = psys_solver_create(D->integrator, &o, &e);
    if (!s)
        return -1;
    psys_solver_set_tolerance(s, D->tol);
    psys_solver_set_cg(s, D->cg_tol, D->cg_maxit);
    if (D->h_next > 0)
        psys_solver_set_next_step(s, D->h_next);
    D->solver = s;
    return 0;
}
