/* The domain of an MPI run (overview: mpi/domain.h): its creation from
 * the scene every rank loaded, a step taken on every rank with a retry
 * when the ghosts could be incomplete, contact events across ranks, and
 * the gathering of the particles on rank 0. */
#include "mpi/domain.h"

#include <float.h>
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

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
        if (!(D->dmax + 1.25 * grew < D->skin) && psys__domain_redistribute(D) != 0)
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
        if (psys__domain_redistribute(D) != 0)
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
        ok = psys__domain_reserve_local(D, n ? n : 1) == 0 && psys__system_reserve(s, n ? n : 1) == PSYS_OK
             && (!D->charges || psys__domain_reserve_charges(s, n ? n : 1) == 0);
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
        psys__domain_choose_parts(D, len);
    }
    int all = 0;
    MPI_Allreduce(&ok, &all, 1, MPI_INT, MPI_MIN, D->comm);
    if (!all || psys__domain_redistribute(D) != 0) {
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
