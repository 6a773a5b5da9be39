/* MPI domain decomposition (docs/mpi.md "Domain decomposition"): the
 * particles of a run spread over the ranks of a communicator, each rank
 * holding only the particles of its box of space ("owned") and ghost copies
 * of the particles near its box. Compiled only with -DPSYS_MPI=ON.
 *
 * Decomposition. A grid of px·py·pz = R boxes: R's prime factors go, largest
 * first, to the axis whose parts are longest (the box's extent, else the
 * particles'), so 4 ranks cut a cube 2×2×1 and 8 ranks 2×2×2. The cuts are
 * levels (one per cut axis): the space is cut along the first axis into px
 * parts holding about n/px particles each, each of those along the next axis
 * into py parts, and so on, from global histograms of 64 bins per part
 * (MPI_Allreduce), cuts at bin edges. A rank's ghosts are the other ranks'
 * particles whose every coordinate is within delta of its box (delta = the
 * longest pair-force range + skin; every particle when a law has no cutoff:
 * the all-gather exchange for direct and Barnes–Hut gravity and Coulomb).
 * Before every force evaluation each rank sends its owned particles'
 * positions and velocities to the ranks that hold them as ghosts
 * (point-to-point, halo exchange); both sides derive the lists from the same
 * positions and cuts.
 *
 * Migration. At a redistribution every rank sends each particle it owns to
 * the rank of the box it is now in, and copies to the ranks that need it as
 * a ghost (MPI_Alltoallv); the grid is re-cut first. Every evaluation
 * gathers each rank's two largest displacements since then; the ghosts hold
 * while the two largest of all add up to less than the skin (no pair can
 * have closed its gap by more). Between steps a redistribution happens when
 * the next step could break that (judged from the last step's growth); if
 * an evaluation inside a step finds it broken anyway, that step is
 * abandoned on every rank, the particles redistributed and the step taken
 * again. Ghost sets are therefore always complete: every pair closer than
 * the pair range with one owned end has its other end on the rank.
 *
 * Same answers. The local system holds its particles in increasing global
 * index and computes pair-force rows only for the owned particles (the
 * own_mark of pair.h's methods), each row the serial sum over the same
 * partners in the same order (pairs beyond the cutoff add exactly nothing);
 * gravity and drag are per particle. So every owned particle's force, and
 * every explicit solver's update of it, is bit-identical to the serial run.
 * rk45's error norm is a sum over the whole state: here it is summed per rank
 * and combined with MPI_Allreduce, so rk45 trajectories equal the serial ones
 * to rounding (not bit for bit).
 *
 * The library keeps no global state: everything lives in the psys__domain
 * of one run. */
#include "mpi/bonded.h"
#include "solvers/solver.h"
#include "psys/psys_mpi.h"

#include <float.h>
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define DOMAIN_BINS 64  /* histogram bins per part for the cuts */
#define HALO_TAG 7301

/* One particle on the move: global index, mass, inverse mass, charge,
 * flags, then x and v. */
#define REC_HEAD 5
#define REC_LEN(d) (REC_HEAD + 2 * (size_t)(d))

/* A received record's global index and where it lies, for sorting. */
struct rec_key {
    size_t gid, at;
};

struct psys__domain {
    MPI_Comm comm;
    int rank, size, dim;
    psys_system *local;
    psys_solver *solver;
    char integrator[32];
    double tol, cg_tol, h_next; /* for creating the solver */
    int cg_maxit;
    bool charges;    /* the system has charges: ghosts carry them */
    /* the grid of ranks: levels of cuts along the axes with more than one part */
    int parts[3];    /* ranks along each axis (product: size) */
    int nlev, lev_axis[3], lev_cells[3]; /* level L cuts axis lev_axis[L] in each of lev_cells[L] cells */
    bool periodic[3];
    bool fixed_range;/* the box gives the histograms' ranges */
    double lo[3], len[3]; /* histogram range along each axis */
    double delta;    /* ghost range: < 0 none, INFINITY every particle */
    double pair_delta; /* the pair forces' part of it (< 0: none) */
    psys__bonds *bonds;/* springs and behaviours (mpi_bonded.c), NULL = none */
    double bond_ext; /* the longest bonded term along any axis at the last redistribution */
    bool all_ghosts; /* every particle a ghost from now on */
    /* controlled particles: every controller of the system (by increasing
     * particle), and room for the local system's, which are copies of those
     * of its owned particles (the keyframes stay here) */
    psys__controller *gctrl;
    size_t ngctrl, ctrl_cap;
    /* planes: the collision code's collectives (psys__advance) */
    psys__collide_hooks hooks;
    int who_rank;     /* the rank owning the particle of the current contact event */
    double skin;     /* displacements of two particles may add up to less than this */
    int *bin_part[3];      /* level L: lev_cells[L]·parts·DOMAIN_BINS, the part each bin goes to */
    uint64_t *hist;        /* size·DOMAIN_BINS (the largest level's histogram) */
    double *reg_lo, *reg_hi; /* size·3: each rank's box (lo == hi on an axis: empty; ±inf: unbounded) */
    /* local particles, in increasing global index */
    size_t cap, nloc, nown;
    size_t *gid;
    unsigned char *own;
    int *lowner;     /* the rank owning each local particle */
    double *xref;    /* cap·dim: positions at the last redistribution */
    double *ysave;   /* 2·cap·dim: the state before a step */
    /* halo plan: local indices sent to / received from each rank */
    int *scount, *rcount;     /* size: particles */
    size_t *soff, *roff;      /* size + 1 */
    size_t *sidx, *ridx;
    size_t scap;
    double *sbuf, *rbuf;
    size_t sbuf_cap, rbuf_cap;
    MPI_Request *req;         /* 2·size */
    MPI_Status *stat;         /* 2·size (MPI_STATUSES_IGNORE trips GCC's -Wstringop-overflow) */
    /* migration buffers */
    int *mcount, *mdispl, *rmcount, *rmdispl; /* size each, in doubles */
    double *msend, *mrecv;
    size_t msend_cap, mrecv_cap;
    struct rec_key *order;    /* sort of received records */
    size_t order_cap;
    /* step state */
    psys_ode inner;           /* the local system's ODE */
    double dmax;              /* the two largest displacements since the redistribution added, all ranks,
                                 at the last evaluation */
    double dmax_step;         /* dmax at the start of the last step */
    double *gath;             /* 3·size: every rank's two largest displacements and failure flag */
    bool stale;               /* an evaluation found the ghosts could be incomplete */
    size_t bad;               /* global index of the first non-finite particle of a failed step */
    size_t redistributions;
    void *grown;              /* GROW_BUF's result before it is stored */
    psys_error err;
};

psys_system *psys__domain_local(const psys__domain *D) { return D->local; }
psys_solver *psys__domain_solver(const psys__domain *D) { return D->solver; }
size_t psys__domain_bad_particle(const psys__domain *D) { return D->bad; }

void psys__domain_free(psys__domain *D)
{
    if (!D)
        return;
    psys_solver_destroy(D->solver);
    if (D->local)
        D->local->nctrl = 0; /* its controllers' keyframes are gctrl's */
    psys_system_destroy(D->local);
    for (size_t k = 0; k < D->ngctrl; k++)
        psys__controller_free(&D->gctrl[k]);
    free(D->gctrl);
    psys__bonds_free(D->bonds);
    if (D->comm != MPI_COMM_NULL)
        MPI_Comm_free(&D->comm);
    for (int L = 0; L < 3; L++)
        free(D->bin_part[L]);
    free(D->hist);
    free(D->reg_lo);
    free(D->reg_hi);
    free(D->gid);
    free(D->own);
    free(D->lowner);
    free(D->xref);
    free(D->ysave);
    free(D->scount);
    free(D->rcount);
    free(D->soff);
    free(D->roff);
    free(D->sidx);
    free(D->ridx);
    free(D->sbuf);
    free(D->rbuf);
    free(D->req);
    free(D->gath);
    free(D->stat);
    free(D->mcount);
    free(D->mdispl);
    free(D->rmcount);
    free(D->rmdispl);
    free(D->msend);
    free(D->mrecv);
    free(D->order);
    free(D);
}

/* ---- geometry of the grid of ranks ---- */

/* Coordinate along axis k, into [lo, lo + len) on a periodic axis. */
static double axis_coord(const psys__domain *D, int k, double q)
{
    if (!D->periodic[k])
        return q;
    double u = (q - D->lo[k]) / D->len[k];
    return D->lo[k] + (u - floor(u)) * D->len[k];
}

/* Histogram bin of coordinate q along axis k (clamped; NaN to bin 0). */
static size_t bin_of(const psys__domain *D, int k, double q)
{
    const size_t nb = (size_t)D->parts[k] * DOMAIN_BINS;
    double u = (axis_coord(D, k, q) - D->lo[k]) / D->len[k] * (double)nb;
    return !(u >= 0) ? 0 : u >= (double)nb ? nb - 1 : (size_t)u;
}

/* The cell of position x after the first `levels` levels of cuts; with all
 * levels, the rank owning that position. */
static int cell_of(const psys__domain *D, const double *x, int levels)
{
    int c = 0;
    for (int L = 0; L < levels; L++) {
        const int k = D->lev_axis[L], P = D->parts[k];
        const size_t nb = (size_t)P * DOMAIN_BINS;
        c = c * P + D->bin_part[L][(size_t)c * nb + bin_of(D, k, x[k])];
    }
    return c;
}

static int owner_of(const psys__domain *D, const double *x) { return cell_of(D, x, D->nlev); }

/* Does rank r need a particle at x as a ghost? Every axis of r's box within
 * delta of x (a superset of the particles within delta of the box). */
static bool needed_by(const psys__domain *D, const double *x, int r)
{
    if (D->delta < 0)
        return false;
    for (int k = 0; k < D->dim; k++)
        if (!(D->reg_lo[3 * r + k] < D->reg_hi[3 * r + k]))
            return false; /* an empty box owns nothing and needs nothing */
    if (isinf(D->delta))
        return true;
    for (int k = 0; k < D->dim; k++) {
        double a = D->reg_lo[3 * r + k], b = D->reg_hi[3 * r + k], q = x[k], dist;
        if (isinf(a) && isinf(b))
            continue; /* the whole axis */
        if (D->periodic[k]) {
            double c = axis_coord(D, k, q), L = D->len[k], up = a - c, down = c - b;
            up -= floor(up / L) * L;     /* from c up to the box's start, in [0, L) */
            down -= floor(down / L) * L; /* from the box's end up to c */
            dist = c >= a && c < b ? 0 : fmin(up, down);
        } else {
            dist = q < a ? a - q : q >= b ? q - b : 0;
        }
        if (!(dist < D->delta))
            return false;
    }
    return true;
}

/* Re-cut the grid from global histograms of the owned particles: level by
 * level, each cell of the previous levels is cut along the next axis into
 * parts holding about equal numbers of particles (cuts at bin edges). */
static int cut_grid(psys__domain *D)
{
    const int d = D->dim;
    const psys_system *s = D->local;
    if (!D->fixed_range) {
        double mm[6]; /* {min, -max} per axis */
        for (int k = 0; k < 6; k++)
            mm[k] = INFINITY;
        for (size_t i = 0; i < D->nloc; i++) {
            if (!D->own[i])
                continue;
            for (int k = 0; k < d; k++) {
                double q = s->x[i * d + k];
                if (q < mm[2 * k])
                    mm[2 * k] = q;
                if (-q < mm[2 * k + 1])
                    mm[2 * k + 1] = -q;
            }
        }
        if (MPI_Allreduce(MPI_IN_PLACE, mm, 6, MPI_DOUBLE, MPI_MIN, D->comm) != MPI_SUCCESS)
            return -1;
        for (int k = 0; k < d; k++) {
            double lo = mm[2 * k], hi = -mm[2 * k + 1];
            D->lo[k] = isfinite(lo) ? lo : 0.0;
            D->len[k] = isfinite(hi) && isfinite(lo) && hi > lo ? (hi - lo) * (1 + 1e-12) : 1.0;
        }
    }
    for (int r = 0; r < D->size; r++)
        for (int k = 0; k < 3; k++) {
            D->reg_lo[3 * r + k] = -INFINITY;
            D->reg_hi[3 * r + k] = INFINITY;
        }
    int stride = D->size; /* ranks sharing one index at the current level */
    for (int L = 0; L < D->nlev; L++) {
        const int k = D->lev_axis[L], P = D->parts[k], C = D->lev_cells[L];
        const size_t nb = (size_t)P * DOMAIN_BINS, nh = (size_t)C * nb;
        memset(D->hist, 0, nh * sizeof *D->hist);
        for (size_t i = 0; i < D->nloc; i++)
            if (D->own[i]) {
                const double *x = s->x + i * d;
                D->hist[(size_t)cell_of(D, x, L) * nb + bin_of(D, k, x[k])]++;
            }
        if (MPI_Allreduce(MPI_IN_PLACE, D->hist, (int)nh, MPI_UINT64_T, MPI_SUM, D->comm) != MPI_SUCCESS)
            return -1;
        stride /= P;
        const double w = D->len[k] / (double)nb;
        for (int c = 0; c < C; c++) {
            const uint64_t *h = D->hist + (size_t)c * nb;
            int *part = D->bin_part[L] + (size_t)c * nb;
            uint64_t total = 0, before = 0;
            for (size_t b = 0; b < nb; b++)
                total += h[b];
            /* bin b goes to part q with q·n/P <= (particles in bins before b) < (q+1)·n/P */
            for (size_t b = 0; b < nb; b++) {
                uint64_t q = total ? before * (uint64_t)P / total : 0;
                part[b] = (int)(q < (uint64_t)P ? q : (uint64_t)P - 1);
                before += h[b];
            }
            for (int q = 0; q < P; q++) {
                size_t b0 = nb, b1 = 0;
                for (size_t b = 0; b < nb; b++)
                    if (part[b] == q) {
                        if (b0 == nb)
                            b0 = b;
                        b1 = b + 1;
                    }
                double lo = 0, hi = 0; /* empty */
                if (b0 < nb) {
                    lo = D->lo[k] + (double)b0 * w;
                    hi = b1 == nb ? D->lo[k] + D->len[k] : D->lo[k] + (double)b1 * w;
                    if (!D->periodic[k]) { /* clamped bins: the end parts reach to infinity */
                        if (b0 == 0)
                            lo = -INFINITY;
                        if (b1 == nb)
                            hi = INFINITY;
                    }
                }
                /* every rank of cell c, part q at this level */
                const int first = (c * P + q) * stride;
                for (int r = first; r < first + stride; r++) {
                    D->reg_lo[3 * r + k] = lo;
                    D->reg_hi[3 * r + k] = hi;
                }
            }
        }
    }
    return 0;
}

/* Ranks per axis: each prime factor of R, largest first, to the axis whose
 * parts are longest (so the boxes stay near cubes). */
static void choose_parts(psys__domain *D, const double *len)
{
    for (int k = 0; k < 3; k++)
        D->parts[k] = 1;
    int R = D->size, f = 2;
    int primes[64], np = 0;
    while (R > 1 && np < 64) {
        if (R % f == 0) {
            primes[np++] = f;
            R /= f;
        } else {
            f++;
        }
    }
    for (int t = np - 1; t >= 0; t--) {
        int best = 0;
        for (int k = 1; k < D->dim; k++)
            if (len[k] / D->parts[k] > len[best] / D->parts[best])
                best = k;
        D->parts[best] *= primes[t];
    }
    D->nlev = 0;
    int cells = 1;
    for (int k = 0; k < D->dim; k++)
        if (D->parts[k] > 1) {
            D->lev_axis[D->nlev] = k;
            D->lev_cells[D->nlev] = cells;
            cells *= D->parts[k];
            D->nlev++;
        }
}

/* ---- storage ---- */

/* D->field grown to hold want elements; false (and the buffer kept) on failure. */
#define GROW_BUF(field, cap, want) \
    ((D->grown = psys__grow((field), &(cap), (want), sizeof *(field))) != NULL && ((field) = D->grown, true))

/* Local arrays for m particles (0 on success). */
static int reserve_local(psys__domain *D, size_t m)
{
    if (m <= D->cap)
        return 0;
    size_t cap = D->cap ? D->cap : 64;
    while (cap < m)
        cap *= 2;
    const size_t d = (size_t)D->dim;
    void *p;
#define GROW(field, count)                                             \
    if (!(p = psys__realloc(D->field, (count), sizeof *D->field)))    \
        return -1;                                                     \
    D->field = p;
    GROW(gid, cap)
    GROW(own, cap)
    GROW(lowner, cap)
    GROW(xref, cap * d)
    GROW(ysave, 2 * cap * d)
    GROW(ridx, cap)
#undef GROW
    D->cap = cap;
    return 0;
}

/* ---- the local ODE: the local system's, with ghosts filled in first ---- */

/* Owners send their particles' x and v to the ranks holding them as ghosts. */
static int halo_exchange(psys__domain *D, double *y)
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
    int failed = halo_exchange(D, yw) != 0;
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
static int make_solver(psys__domain *D)
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

/* ---- migration ---- */

static int by_gid(const void *a, const void *b)
{
    size_t ga = ((const struct rec_key *)a)->gid, gb = ((const struct rec_key *)b)->gid;
    return ga < gb ? -1 : ga > gb;
}

/* Room for m charges in s (the local system's charges are written directly). */
static int reserve_charges(psys_system *s, size_t m)
{
    if (m <= s->charge_cap)
        return 0;
    double *p = psys__realloc(s->charge, m, sizeof(double));
    if (!p)
        return -1;
    s->charge = p;
    s->charge_cap = m;
    return 0;
}

/* Collective: re-cut the grid, move every owned particle to its box's rank
 * with ghost copies to the ranks that need it, rebuild the local system,
 * the halo plan and the bonded terms. 0 on success on every rank, 1 when
 * some rank lacks a particle of one of its bonded terms, -1 on failure. */
static int redistribute_once(psys__domain *D)
{
    const int d = D->dim, R = D->size;
    const size_t rl = REC_LEN(d);
    psys_system *s = D->local;
    int ok = cut_grid(D) == 0;
    /* records to send: counted, then packed by destination */
    for (int r = 0; r < R; r++)
        D->mcount[r] = 0;
    size_t nsend = 0;
    for (int pass = 0; pass < 2 && ok; pass++) {
        if (pass == 1) {
            size_t at = 0;
            for (int r = 0; r < R; r++) {
                D->mdispl[r] = (int)at;
                at += (size_t)D->mcount[r];
                D->mcount[r] = 0;
            }
            if (at > (size_t)INT_MAX || !GROW_BUF(D->msend, D->msend_cap, at ? at : 1)) {
                ok = 0;
                break;
            }
        }
        for (size_t i = 0; i < D->nloc; i++) {
            if (!D->own[i])
                continue;
            const double *q = s->x + i * d;
            int o = owner_of(D, q);
            for (int r = 0; r < R; r++) {
                if (r != o && !needed_by(D, q, r))
                    continue;
                if (pass == 1) {
                    double *rec = D->msend + (size_t)D->mdispl[r] + (size_t)D->mcount[r];
                    rec[0] = (double)D->gid[i];
                    rec[1] = s->mass[i];
                    rec[2] = s->inv_mass[i];
                    rec[3] = D->charges && i < s->ncharge ? s->charge[i] : 0.0;
                    rec[4] = (double)s->flags[i] + (r == o ? 256.0 : 0.0);
                    memcpy(rec + REC_HEAD, s->x + i * d, (size_t)d * sizeof(double));
                    memcpy(rec + REC_HEAD + d, s->v + i * d, (size_t)d * sizeof(double));
                }
                if ((size_t)D->mcount[r] + rl > (size_t)INT_MAX)
                    ok = 0;
                D->mcount[r] += (int)rl;
                nsend++;
            }
        }
    }
    int all = 0;
    MPI_Allreduce(&ok, &all, 1, MPI_INT, MPI_MIN, D->comm);
    if (!all)
        return -1;
    if (MPI_Alltoall(D->mcount, 1, MPI_INT, D->rmcount, 1, MPI_INT, D->comm) != MPI_SUCCESS)
        return -1;
    size_t at = 0;
    for (int r = 0; r < R; r++) {
        D->rmdispl[r] = (int)at;
        at += (size_t)D->rmcount[r];
    }
    const size_t m = at / rl;
    ok = at <= (size_t)INT_MAX && GROW_BUF(D->mrecv, D->mrecv_cap, at ? at : 1)
         && GROW_BUF(D->order, D->order_cap, m ? m : 1) && reserve_local(D, m) == 0
         && psys__system_reserve(s, m) == PSYS_OK && (!D->charges || reserve_charges(s, m) == 0);
    MPI_Allreduce(&ok, &all, 1, MPI_INT, MPI_MIN, D->comm);
    if (!all)
        return -1;
    if (MPI_Alltoallv(D->msend, D->mcount, D->mdispl, MPI_DOUBLE, D->mrecv, D->rmcount, D->rmdispl, MPI_DOUBLE,
                      D->comm)
        != MPI_SUCCESS)
        return -1;
    /* the new local particles in increasing global index */
    for (size_t t = 0; t < m; t++) {
        D->order[t].gid = (size_t)D->mrecv[t * rl];
        D->order[t].at = t;
    }
    qsort(D->order, m, sizeof *D->order, by_gid);
    D->nown = 0;
    for (size_t t = 0; t < m; t++) {
        const double *rec = D->mrecv + D->order[t].at * rl;
        int fl = (int)rec[4];
        D->gid[t] = (size_t)rec[0];
        D->own[t] = (fl & 256) != 0;
        D->nown += D->own[t];
        s->mass[t] = rec[1];
        s->inv_mass[t] = rec[2];
        s->flags[t] = (unsigned char)(fl & 255);
        s->ids[t] = NULL;
        if (D->charges)
            s->charge[t] = rec[3];
        memcpy(s->x + t * d, rec + REC_HEAD, (size_t)d * sizeof(double));
        memcpy(s->v + t * d, rec + REC_HEAD + d, (size_t)d * sizeof(double));
        memset(s->f + t * d, 0, (size_t)d * sizeof(double));
        memcpy(D->xref + t * d, rec + REC_HEAD, (size_t)d * sizeof(double));
    }
    s->n = m;
    s->epoch++; /* new particles and masses */
    if (D->charges)
        s->ncharge = m;
    D->nloc = m;
    s->own_mark = D->own;
    /* the controllers of the owned particles */
    size_t nc = 0;
    for (size_t t = 0; t < m && D->ngctrl; t++)
        nc += D->own[t] && (s->flags[t] & PSYS_PARTICLE_CONTROLLED);
    s->nctrl = 0;
    const int cok = nc == 0 || GROW_BUF(s->ctrl, D->ctrl_cap, nc);
    for (size_t t = 0; t < m && cok && D->ngctrl; t++) {
        if (!D->own[t] || !(s->flags[t] & PSYS_PARTICLE_CONTROLLED))
            continue;
        size_t lo = 0, hi = D->ngctrl; /* gctrl by increasing particle */
        while (lo < hi) {
            size_t mid = lo + (hi - lo) / 2;
            if (D->gctrl[mid].particle < D->gid[t])
                lo = mid + 1;
            else
                hi = mid;
        }
        if (lo < D->ngctrl && D->gctrl[lo].particle == D->gid[t]) {
            s->ctrl[s->nctrl] = D->gctrl[lo];
            s->ctrl[s->nctrl++].particle = t;
        }
    }
    for (size_t k = 0; k < s->nforces; k++)
        if (s->forces[k].cls == &psys_pair_class)
            psys__pair_invalidate(s->forces[k].data);
    /* halo plan: what this rank sends (its owned particles other ranks need)
     * and where what it receives goes (its ghosts, grouped by owner); both
     * sides compute them from the same positions and cuts */
    for (int r = 0; r < R; r++)
        D->scount[r] = D->rcount[r] = 0;
    size_t ns = 0;
    for (size_t i = 0; i < m; i++) {
        const double *q = s->x + i * d;
        if (D->own[i]) {
            D->lowner[i] = D->rank;
            for (int r = 0; r < R; r++)
                if (r != D->rank && needed_by(D, q, r)) {
                    D->scount[r]++;
                    ns++;
                }
        } else {
            D->lowner[i] = owner_of(D, q);
            D->rcount[D->lowner[i]]++;
        }
    }
    ok = cok && GROW_BUF(D->sidx, D->scap, ns ? ns : 1)
         && GROW_BUF(D->sbuf, D->sbuf_cap, (ns ? ns : 1) * 2 * (size_t)d)
         && GROW_BUF(D->rbuf, D->rbuf_cap, (m - D->nown + 1) * 2 * (size_t)d);
    if (ok) {
        D->soff[0] = D->roff[0] = 0;
        for (int r = 0; r < R; r++) {
            D->soff[r + 1] = D->soff[r] + (size_t)D->scount[r];
            D->roff[r + 1] = D->roff[r] + (size_t)D->rcount[r];
        }
        for (int r = 0; r < R; r++)
            D->scount[r] = D->rcount[r] = 0;
        for (size_t i = 0; i < m; i++) {
            const double *q = s->x + i * d;
            if (D->own[i]) {
                for (int r = 0; r < R; r++)
                    if (r != D->rank && needed_by(D, q, r))
                        D->sidx[D->soff[r] + (size_t)D->scount[r]++] = i;
            } else {
                int o = owner_of(D, q);
                D->ridx[D->roff[o] + (size_t)D->rcount[o]++] = i;
            }
        }
        ok = make_solver(D) == 0;
    }
    int complete = 1; /* every bonded term with an owned particle has all its particles here */
    if (ok && D->bonds) {
        int b = psys__bonds_localize(D->bonds, m, D->gid, D->own, D->lowner, D->rank, R);
        ok = b >= 0;
        complete = b != 0;
    }
    int flags[2] = {ok, complete}, both[2] = {0, 0};
    MPI_Allreduce(flags, both, 2, MPI_INT, MPI_MIN, D->comm);
    D->dmax = D->dmax_step = 0;
    D->stale = false;
    D->redistributions++;
    return !both[0] ? -1 : !both[1] ? 1 : 0;
}

/* The ghost range: the pair forces' and the longest bonded term's (with a
 * margin for rounding in the boxes' edges), or every particle. */
static void set_delta(psys__domain *D)
{
    double del = D->pair_delta;
    if (D->bonds) {
        double scale = 0;
        for (int k = 0; k < D->dim; k++)
            scale = fmax(scale, fabs(D->lo[k]) + D->len[k]);
        double b = D->bond_ext + 1e-6 * D->bond_ext + 1e-9 * scale + DBL_MIN;
        del = b > del || b != b ? b : del;
    }
    D->delta = D->all_ghosts || !(del == del) ? INFINITY : del;
}

/* Collective: redistribute_once with the ghost range brought up to date;
 * if a bonded term still lacks a particle somewhere, every particle becomes
 * a ghost. 0 on success on every rank. */
static int redistribute(psys__domain *D)
{
    if (D->bonds) {
        /* the terms' current extent (before the first redistribution, the
         * whole system's, from psys__domain_create) */
        double ext = D->bond_ext;
        if (D->redistributions > 0) {
            const size_t nd = D->nloc * (size_t)D->dim;
            if (nd) { /* the ghosts' current positions first */
                memcpy(D->ysave, D->local->x, nd * sizeof(double));
                memcpy(D->ysave + nd, D->local->v, nd * sizeof(double));
            }
            if (halo_exchange(D, D->ysave) != 0)
                return -1;
            ext = psys__bonds_extent(D->bonds, D->ysave);
        }
        if (MPI_Allreduce(&ext, &D->bond_ext, 1, MPI_DOUBLE, MPI_MAX, D->comm) != MPI_SUCCESS)
            return -1;
    }
    set_delta(D);
    int r = redistribute_once(D);
    if (r == 1) {
        D->all_ghosts = true;
        set_delta(D);
        r = redistribute_once(D);
    }
    return r == 0 ? 0 : -1;
}

/* ---- stepping ---- */

/* Every rank's earliest contact event; the lexicographic minimum of
 * (fraction, plane, particle), as the serial search finds it. */
static bool dd_earliest(void *ctx, double *alpha, size_t *plane, size_t *gid)
{
    psys__domain *D = ctx;
    double in[3] = {*alpha, (double)*plane, *gid == SIZE_MAX ? -1.0 : (double)*gid};
    if (MPI_Allgather(in, 3, MPI_DOUBLE, D->gath, 3, MPI_DOUBLE, D->comm) != MPI_SUCCESS)
        return false; /* MPI errors abort by default */
    int best = -1;
    for (int r = 0; r < D->size; r++) {
        const double *c = D->gath + 3 * r, *b = best < 0 ? NULL : D->gath + 3 * best;
        if (c[2] < 0)
            continue;
        if (!b || c[0] < b[0] || (c[0] == b[0] && (c[1] < b[1] || (c[1] == b[1] && c[2] < b[2]))))
            best = r;
    }
    D->who_rank = best < 0 ? 0 : best;
    if (best < 0) {
        *alpha = 2; /* no event anywhere */
        *gid = SIZE_MAX;
        return false;
    }
    *alpha = D->gath[3 * best];
    *plane = (size_t)D->gath[3 * best + 1];
    *gid = (size_t)D->gath[3 * best + 2];
    return best == D->rank;
}

static double dd_share(void *ctx, double value)
{
    psys__domain *D = ctx;
    MPI_Bcast(&value, 1, MPI_DOUBLE, D->who_rank, D->comm);
    return value;
}

static void save_state(psys__domain *D)
{
    const size_t nd = D->nloc * (size_t)D->dim;
    if (nd) {
        memcpy(D->ysave, D->local->x, nd * sizeof(double));
        memcpy(D->ysave + nd, D->local->v, nd * sizeof(double));
    }
}

static void restore_state(psys__domain *D, double t)
{
    const size_t nd = D->nloc * (size_t)D->dim;
    if (nd) {
        memcpy(D->local->x, D->ysave, nd * sizeof(double));
        memcpy(D->local->v, D->ysave + nd, nd * sizeof(double));
    }
    D->local->t = t;
}

psys_status psys__domain_advance(psys__domain *D, double h_max, double *h_taken)
{
    psys_system *s = D->local;
    if (h_taken)
        *h_taken = 0;
    /* Between steps: redistribute when the next step could use up the skin,
     * judged from how much the largest displacement grew in the last step
     * (a wrong guess costs a retried step, never a wrong force). */
    if (isfinite(D->delta) && D->delta >= 0) {
        double grew = D->dmax > D->dmax_step ? D->dmax - D->dmax_step : 0.0;
        if (!(D->dmax + 1.25 * grew < D->skin) && redistribute(D) != 0)
            return psys__fail(&D->err, PSYS_ERR_NOMEM, "out of memory moving particles between MPI ranks");
        D->dmax_step = D->dmax;
    }
    const double t0 = s->t;
    save_state(D);
    psys_status st = PSYS_OK;
    double h = 0;
    for (int attempt = 0;; attempt++) {
        psys_solver_set_threads(D->solver, psys_system_effective_threads(s));
        if (s->nplanes) { /* contact events: the serial collision code with collectives */
            D->hooks.own = D->own;
            D->hooks.gid = D->gid;
            st = psys__advance(s, D->solver, h_max, &h, &D->hooks);
        } else {
            st = psys_solver_step(D->solver, h_max, &h);
        }
        if (!D->stale) /* the same on every rank (an all-reduced decision) */
            break;
        restore_state(D, t0);
        if (attempt == 1) /* not even a fresh decomposition holds for one step: every particle a ghost */
            D->all_ghosts = true;
        if (redistribute(D) != 0)
            return psys__fail(&D->err, PSYS_ERR_NOMEM, "out of memory moving particles between MPI ranks");
        save_state(D);
    }
    /* every rank the same outcome: the worst status, the first bad particle */
    D->bad = SIZE_MAX;
    double bad = INFINITY;
    if (st == PSYS_ERR_NONFINITE) {
        size_t c = psys_solver_bad_component(D->solver), nd = D->nloc * (size_t)D->dim;
        size_t i = (c < nd ? c : c - nd) / (size_t)D->dim;
        /* position components come before velocity components */
        bad = (c < nd ? 0.0 : 9007199254740992.0) + (i < D->nloc ? (double)D->gid[i] : 0.0);
    }
    double in[2] = {(double)st, -bad}, out[2];
    if (MPI_Allreduce(in, out, 2, MPI_DOUBLE, MPI_MAX, D->comm) != MPI_SUCCESS)
        return psys__fail(&D->err, PSYS_ERR_INVALID, "MPI exchange of the step's outcome failed");
    psys_status all = (psys_status)(int)out[0];
    if (all != PSYS_OK) {
        restore_state(D, t0); /* the last good state everywhere */
        if (all == PSYS_ERR_NONFINITE && isfinite(out[1])) {
            double b = -out[1];
            D->bad = (size_t)(b >= 9007199254740992.0 ? b - 9007199254740992.0 : b);
        }
        if (st == PSYS_OK)
            psys__fail(&D->err, all, "the step failed on another MPI rank");
        else
            psys__fail(&D->err, all, "%s", psys_solver_last_error(D->solver));
        return all;
    }
    psys__box_wrap(s);
    if (h_taken)
        *h_taken = h;
    return PSYS_OK;
}

const char *psys__domain_last_error(const psys__domain *D) { return D->err.message; }

/* ---- creation ---- */

static int by_particle(const void *a, const void *b)
{
    size_t x = ((const psys__controller *)a)->particle, y = ((const psys__controller *)b)->particle;
    return x < y ? -1 : x > y;
}

/* Whether every rank can apply its own copy of force class c to the
 * particles it owns. */
static bool per_particle(const psys_force_class *c)
{
    return (c->traits & PSYS_FORCE_PER_PARTICLE) && c->clone && c->destroy;
}

/* Why the scene cannot be decomposed (NULL: it can); range and skin of its pair forces. */
static const char *unsupported(const psys_system *g, const char *integrator, double *delta, double *skin)
{
    if (strcmp(integrator, "implicit-euler") == 0)
        return "implicit-euler solves for the whole system at once";
    double range = -1, sk = 0;
    for (size_t k = 0; k < g->nforces; k++) {
        const psys_force_class *c = g->forces[k].cls;
        if (per_particle(c) || psys__bonds_takes(c))
            continue;
        /* pair forces: their ranges set the ghosts' */
        if (c != &psys_pair_class)
            return c == &psys_mouse_spring_class ? "the scene has mouse springs"
                                                 : "the scene has a force type other than pair, bonded terms the "
                                                   "ranks can split (spring, behaviour) and per-particle forces the "
                                                   "ranks can copy (gravity, drag)";
        psys_pair_def def;
        psys_system_pair(g, k, &def);
        double r = def.law == PSYS_PAIR_LENNARD_JONES ? def.cutoff
                   : def.law == PSYS_PAIR_SOFT_REPULSION ? def.radius
                                                         : INFINITY;
        /* the ghosts' skin: twice the lists' (or 0.2 of the range), so
         * particles migrate about half as often as the lists are rebuilt
         * (each migration also rebuilds them and empties the force cache);
         * the extra ghosts cost only their halo messages */
        double s = 2 * (def.method == PSYS_PAIR_GRID && def.skin > 0 ? def.skin : 0.1 * r);
        if (!(r > range))
            r = range;
        range = r;
        if (s > sk)
            sk = s;
    }
    *delta = range < 0 ? -1 : range + sk;
    *skin = sk;
    return NULL;
}

psys_status psys__domain_create(psys_system *g, const char *integrator, double tol, double cg_tol, int cg_maxit,
                                double h_next, MPI_Comm comm, psys__domain **out, psys_error *err)
{
    *out = NULL;
    double delta = -1, skin = 0;
    const char *why = unsupported(g, integrator, &delta, &skin);
    if (why)
        return psys__fail(err, PSYS_ERR_UNSUPPORTED, "cannot decompose the domain: %s", why);
    psys__domain *D = calloc(1, sizeof *D);
    if (!D)
        return psys__fail(err, PSYS_ERR_NOMEM, "out of memory for the MPI decomposition");
    D->comm = MPI_COMM_NULL;
    if (MPI_Comm_dup(comm, &D->comm) != MPI_SUCCESS || MPI_Comm_rank(D->comm, &D->rank) != MPI_SUCCESS
        || MPI_Comm_size(D->comm, &D->size) != MPI_SUCCESS) {
        psys__domain_free(D);
        return psys__fail(err, PSYS_ERR_INVALID, "cannot duplicate the MPI communicator");
    }
    const int d = g->dim, R = D->size;
    D->dim = d;
    snprintf(D->integrator, sizeof D->integrator, "%s", integrator);
    D->tol = tol;
    D->cg_tol = cg_tol;
    D->cg_maxit = cg_maxit;
    D->h_next = h_next;
    D->pair_delta = D->delta = delta;
    D->skin = isfinite(delta) && delta >= 0 ? skin : INFINITY;
    D->charges = g->ncharge > 0;
    const size_t nb = (size_t)R * DOMAIN_BINS;
    for (int L = 0; L < 3; L++)
        D->bin_part[L] = psys__calloc(nb, sizeof(int)); /* cells·parts = at most R at every level */
    D->hist = psys__calloc(nb, sizeof(uint64_t));
    D->reg_lo = psys__calloc(3 * (size_t)R, sizeof(double));
    D->reg_hi = psys__calloc(3 * (size_t)R, sizeof(double));
    D->scount = psys__calloc((size_t)R, sizeof(int));
    D->rcount = psys__calloc((size_t)R, sizeof(int));
    D->soff = psys__calloc((size_t)R + 1, sizeof(size_t));
    D->roff = psys__calloc((size_t)R + 1, sizeof(size_t));
    D->req = psys__calloc(2 * (size_t)R, sizeof(MPI_Request));
    D->stat = psys__calloc(2 * (size_t)R, sizeof(MPI_Status));
    D->gath = psys__calloc(3 * (size_t)R, sizeof(double));
    D->mcount = psys__calloc((size_t)R, sizeof(int));
    D->mdispl = psys__calloc((size_t)R, sizeof(int));
    D->rmcount = psys__calloc((size_t)R, sizeof(int));
    D->rmdispl = psys__calloc((size_t)R, sizeof(int));
    psys_error e;
    D->local = psys_system_create(d, &e);
    int ok = D->bin_part[0] && D->bin_part[1] && D->bin_part[2] && D->hist && D->reg_lo && D->reg_hi && D->scount && D->rcount && D->soff && D->roff
             && D->req && D->stat && D->gath && D->mcount && D->mdispl && D->rmcount && D->rmdispl && D->local;
    /* the local system: the same box, threads and force objects in the same order */
    psys_system *s = D->local;
    if (ok && g->nctrl) { /* every controller, by increasing particle (keyframes copied) */
        ok = (D->gctrl = psys__calloc(g->nctrl, sizeof *D->gctrl)) != NULL;
        if (ok) {
            memcpy(D->gctrl, g->ctrl, g->nctrl * sizeof *D->gctrl);
            qsort(D->gctrl, g->nctrl, sizeof *D->gctrl, by_particle);
            for (size_t k = 0; k < g->nctrl; k++) {
                const double *src = D->gctrl[k].frames;
                D->gctrl[k].frames = NULL;
                D->ngctrl++;
                size_t len = D->gctrl[k].nframes * (size_t)(1 + d);
                if (len && ok && (ok = (D->gctrl[k].frames = psys__calloc(len, sizeof(double))) != NULL))
                    memcpy(D->gctrl[k].frames, src, len * sizeof(double));
            }
        }
    }
    if (ok) {
        ok = psys__bonds_create(g, &D->bonds) == PSYS_OK;
        if (D->bonds)
            D->bond_ext = psys__bonds_extent_all(D->bonds, g->x);
    }
    if (ok) {
        s->threads = g->threads;
        s->box = g->box;
        s->t = g->t;
        D->hooks.ctx = D;
        D->hooks.earliest = dd_earliest;
        D->hooks.share = dd_share;
        for (size_t k = 0; k < g->nplanes && ok; k++) {
            psys_plane_def def;
            ok = psys_system_plane(g, k, &def) == PSYS_OK && psys_system_add_plane(s, &def) == PSYS_OK;
        }
        for (size_t k = 0; k < g->nforces && ok; k++) {
            const psys_force_class *c = g->forces[k].cls;
            psys_status st;
            if (per_particle(c)) {
                void *copy = c->clone(g->forces[k].data);
                st = copy ? psys_system_add_force(s, c, copy) : PSYS_ERR_NOMEM; /* frees copy on failure */
            } else if (psys__bonds_takes(c)) {
                st = psys__bonds_add_force(D->bonds, s, k);
            } else {
                psys_pair_def def;
                psys_system_pair(g, k, &def);
                st = psys_system_add_pair(s, &def, NULL);
            }
            ok = st == PSYS_OK;
        }
    }
    /* Every rank starts with every particle (all loaded the scene) and takes
     * a contiguous block of indices as its own; the first redistribution
     * then cuts the grid and moves the particles to their boxes. */
    const size_t n = g->n;
    if (ok)
        ok = reserve_local(D, n ? n : 1) == 0 && psys__system_reserve(s, n ? n : 1) == PSYS_OK
             && (!D->charges || reserve_charges(s, n ? n : 1) == 0);
    if (ok) {
        memcpy(s->x, g->x, n * (size_t)d * sizeof(double));
        memcpy(s->v, g->v, n * (size_t)d * sizeof(double));
        memcpy(s->mass, g->mass, n * sizeof(double));
        memcpy(s->inv_mass, g->inv_mass, n * sizeof(double));
        memcpy(s->flags, g->flags, n);
        for (size_t i = 0; i < n; i++) {
            s->ids[i] = NULL;
            D->gid[i] = i;
            D->own[i] = (unsigned char)((unsigned long long)i * (unsigned long long)R / (n ? n : 1) == (unsigned long long)D->rank);
            D->nown += D->own[i];
            if (D->charges)
                s->charge[i] = i < g->ncharge ? g->charge[i] : 0.0;
        }
        s->n = n;
        s->epoch++;
        if (D->charges)
            s->ncharge = n;
        D->nloc = n;
        s->own_mark = D->own;
        /* the grid of ranks from the box's extent, else the particles' */
        double len[3] = {1, 1, 1};
        for (int k = 0; k < d; k++) {
            if (g->box.on) {
                D->lo[k] = g->box.lo[k];
                len[k] = g->box.len[k];
            } else {
                double mn = INFINITY, mx = -INFINITY;
                for (size_t i = 0; i < n; i++) {
                    double q = g->x[i * d + k];
                    mn = q < mn ? q : mn;
                    mx = q > mx ? q : mx;
                }
                D->lo[k] = isfinite(mn) ? mn : 0.0;
                len[k] = mx - mn;
            }
            if (!(len[k] > 0) || !isfinite(len[k]))
                len[k] = 1.0;
            D->len[k] = len[k];
            D->periodic[k] = g->box.on && g->box.periodic[k];
        }
        D->fixed_range = g->box.on;
        choose_parts(D, len);
    }
    int all = 0;
    MPI_Allreduce(&ok, &all, 1, MPI_INT, MPI_MIN, D->comm);
    if (!all || redistribute(D) != 0) {
        psys__domain_free(D);
        return psys__fail(err, PSYS_ERR_NOMEM, "out of memory for the MPI decomposition");
    }
    *out = D;
    psys__ok(err);
    return PSYS_OK;
}

size_t psys__domain_owned(const psys__domain *D) { return D->nown; }
void psys__domain_parts(const psys__domain *D, int parts[3])
{
    for (int k = 0; k < 3; k++)
        parts[k] = D->parts[k];
}
size_t psys__domain_ghosts(const psys__domain *D) { return D->nloc - D->nown; }
size_t psys__domain_redistributions(const psys__domain *D) { return D->redistributions; }
size_t psys__domain_bond_terms(const psys__domain *D) { return psys__bonds_owned_terms(D->bonds); }
size_t psys__domain_bond_sent(const psys__domain *D) { return psys__bonds_sent(D->bonds); }

/* Collective: rank 0's system g gets every particle's state and the clock. */
psys_status psys__domain_gather(psys__domain *D, psys_system *g)
{
    /* the migration buffers serve as scratch (no allocation once they are large enough) */
    const size_t d = (size_t)D->dim, rl = 1 + 2 * d;
    const psys_system *s = D->local;
    const size_t want = D->rank == 0 ? g->n * rl : 0;
    int ok = D->nown * rl <= (size_t)INT_MAX && want <= (size_t)INT_MAX
             && GROW_BUF(D->msend, D->msend_cap, D->nown * rl + 1)
             && GROW_BUF(D->mrecv, D->mrecv_cap, want + 1);
    int all = 0;
    MPI_Allreduce(&ok, &all, 1, MPI_INT, MPI_MIN, D->comm);
    if (!all)
        return psys__fail(&D->err, PSYS_ERR_NOMEM, "out of memory gathering the particles on rank 0");
    int mine = (int)(D->nown * rl);
    double *b = D->msend;
    for (size_t i = 0; i < D->nloc; i++) {
        if (!D->own[i])
            continue;
        b[0] = (double)D->gid[i];
        memcpy(b + 1, s->x + i * d, d * sizeof(double));
        memcpy(b + 1 + d, s->v + i * d, d * sizeof(double));
        b += rl;
    }
    if (MPI_Gather(&mine, 1, MPI_INT, D->rmcount, 1, MPI_INT, 0, D->comm) != MPI_SUCCESS)
        return psys__fail(&D->err, PSYS_ERR_INVALID, "MPI gather of the particles failed");
    if (D->rank == 0) {
        int at = 0;
        for (int r = 0; r < D->size; r++) {
            D->rmdispl[r] = at;
            at += D->rmcount[r];
        }
    }
    if (MPI_Gatherv(D->msend, mine, MPI_DOUBLE, D->mrecv, D->rmcount, D->rmdispl, MPI_DOUBLE, 0, D->comm)
        != MPI_SUCCESS)
        return psys__fail(&D->err, PSYS_ERR_INVALID, "MPI gather of the particles failed");
    if (D->rank == 0) {
        for (size_t t = 0; t < g->n; t++) {
            const double *r = D->mrecv + t * rl;
            size_t i = (size_t)r[0];
            if (i < g->n) {
                memcpy(g->x + i * d, r + 1, d * sizeof(double));
                memcpy(g->v + i * d, r + 1 + d, d * sizeof(double));
            }
        }
        g->t = s->t;
    }
    return PSYS_OK;
}
