/* Decomposition and migration: the grid of ranks (cuts from global
 * histograms of the owned particles), which rank owns a position and which
 * ranks need it as a ghost, and the redistribution that moves particles
 * to their boxes' ranks and rebuilds the halo plan. */
#include "mpi/domain.h"

#include <float.h>
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

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
void psys__domain_choose_parts(psys__domain *D, const double *len)
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

/* Local arrays for m particles (0 on success). */
int psys__domain_reserve_local(psys__domain *D, size_t m)
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

/* ---- migration ---- */

static int by_gid(const void *a, const void *b)
{
    size_t ga = ((const struct rec_key *)a)->gid, gb = ((const struct rec_key *)b)->gid;
    return ga < gb ? -1 : ga > gb;
}

/* Room for m charges in s (the local system's charges are written directly). */
int psys__domain_reserve_charges(psys_system *s, size_t m)
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
         && GROW_BUF(D->order, D->order_cap, m ? m : 1) && psys__domain_reserve_local(D, m) == 0
         && psys__system_reserve(s, m) == PSYS_OK && (!D->charges || psys__domain_reserve_charges(s, m) == 0);
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
        ok = psys__domain_make_solver(D) == 0;
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
int psys__domain_redistribute(psys__domain *D)
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
            if (psys__domain_halo_exchange(D, D->ysave) != 0)
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
