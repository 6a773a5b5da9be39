/* MPI: the system's force evaluation spread over the ranks of a communicator
 * (docs/mpi.md). Compiled only with -DPSYS_MPI=ON.
 *
 * Replicated state, partitioned force work: every rank holds every
 * particle and integrates the same way. At each evaluation the particles are
 * split into R slabs along one axis (the longest axis of the periodic box, or
 * of the particles' bounding box), cut so the slabs hold about equal numbers
 * of particles; a particle belongs to the rank of its slab (the owner rule).
 * Pair forces (the O(n²) or O(n·neighbours) work) are computed by each rank
 * only for the rows it owns, in exactly the serial summation order; the other
 * force objects (springs, behaviour functions, gravity, drag, mouse springs)
 * are cheap and run on every rank. The owners' rows of the force array are
 * then combined with one MPI_Allgatherv, so every rank ends with the force
 * array a serial evaluation gives, bit for bit, and every solver proceeds
 * identically everywhere. */
#include "core/core.h"
#include "psys/psys_mpi.h"

#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define BINS_PER_RANK 64

struct psys__dist {
    MPI_Comm comm;
    int rank, size;
    size_t cap;             /* particles the buffers hold */
    int *owner;             /* cap: rank owning particle i */
    unsigned char *mark;    /* cap: 1 where this rank owns i */
    size_t *perm;           /* cap: particles grouped by owner, ascending within a rank */
    double *send, *recv;    /* cap·dim */
    int *counts, *displs;   /* size: doubles per rank */
    size_t *cursor;         /* size */
    size_t *hist;           /* size·BINS_PER_RANK */
    bool active;            /* inside an evaluation whose rows are split */
    size_t owned;
};

void psys__dist_free(psys__dist *d)
{
    if (!d)
        return;
    if (d->comm != MPI_COMM_NULL)
        MPI_Comm_free(&d->comm);
    free(d->owner);
    free(d->mark);
    free(d->perm);
    free(d->send);
    free(d->recv);
    free(d->counts);
    free(d->displs);
    free(d->cursor);
    free(d->hist);
    free(d);
}

psys_status psys_system_set_comm(psys_system *s, MPI_Comm comm)
{
    psys__dist_free(s->dist);
    s->dist = NULL;
    if (comm == MPI_COMM_NULL)
        return PSYS_OK;
    int size = 1;
    if (MPI_Comm_size(comm, &size) != MPI_SUCCESS)
        return psys__fail(&s->err, PSYS_ERR_INVALID, "MPI_Comm_size failed on the communicator");
    if (size <= 1)
        return PSYS_OK;
    psys__dist *d = calloc(1, sizeof *d);
    if (!d)
        return psys__fail(&s->err, PSYS_ERR_NOMEM, "out of memory for the MPI decomposition");
    d->comm = MPI_COMM_NULL;
    d->size = size;
    d->counts = psys__calloc((size_t)size, sizeof(int));
    d->displs = psys__calloc((size_t)size, sizeof(int));
    d->cursor = psys__calloc((size_t)size, sizeof(size_t));
    d->hist = psys__calloc((size_t)size * BINS_PER_RANK, sizeof(size_t));
    if (!d->counts || !d->displs || !d->cursor || !d->hist) {
        psys__dist_free(d);
        return psys__fail(&s->err, PSYS_ERR_NOMEM, "out of memory for the MPI decomposition");
    }
    if (MPI_Comm_dup(comm, &d->comm) != MPI_SUCCESS || MPI_Comm_rank(d->comm, &d->rank) != MPI_SUCCESS) {
        psys__dist_free(d);
        return psys__fail(&s->err, PSYS_ERR_INVALID, "cannot duplicate the MPI communicator");
    }
    s->dist = d;
    return PSYS_OK;
}

int psys_system_comm_size(const psys_system *s) { return s->dist ? s->dist->size : 1; }

size_t psys_system_comm_owned(const psys_system *s) { return s->dist ? s->dist->owned : 0; }

const unsigned char *psys__dist_mark(const psys_system *s)
{
    if (s->own_mark)
        return s->own_mark;
    return s->dist && s->dist->active ? s->dist->mark : NULL;
}

/* Buffers for n particles. Collective: every rank reaches this at the same
 * evaluation (the same n), and all agree whether every rank succeeded. */
static bool dist_reserve(psys__dist *d, size_t n, int dim)
{
    if (n <= d->cap)
        return true;
    size_t cap = d->cap ? d->cap : 64;
    while (cap < n)
        cap *= 2;
    int ok = 1;
    void *p;
#define GROW(field, count, type)                                  \
    if (ok && (p = psys__realloc(d->field, (count), sizeof(type)))) \
        d->field = p;                                             \
    else                                                          \
        ok = 0;
    GROW(owner, cap, int)
    GROW(mark, cap, unsigned char)
    GROW(perm, cap, size_t)
    GROW(send, cap * (size_t)dim, double)
    GROW(recv, cap * (size_t)dim, double)
#undef GROW
    if (ok)
        d->cap = cap;
    int all = 0;
    if (MPI_Allreduce(&ok, &all, 1, MPI_INT, MPI_MIN, d->comm) != MPI_SUCCESS)
        all = 0;
    return all == 1;
}

/* Owners of the particles at positions x: equal-count slabs along one axis,
 * cut at the edges of a histogram of BINS_PER_RANK·R bins. The same on every
 * rank (all hold the same x), so nothing needs to be exchanged. */
static void partition(psys__dist *d, const psys_system *s, const double *x, size_t n)
{
    const int dim = s->dim, R = d->size;
    double lo[3] = {0, 0, 0}, len[3] = {0, 0, 0};
    if (s->box.on) {
        for (int k = 0; k < dim; k++) {
            lo[k] = s->box.lo[k];
            len[k] = s->box.len[k];
        }
    } else {
        double mn[3] = {INFINITY, INFINITY, INFINITY}, mx[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (size_t i = 0; i < n; i++)
            for (int k = 0; k < dim; k++) {
                double v = x[i * dim + k];
                if (v < mn[k])
                    mn[k] = v;
                if (v > mx[k])
                    mx[k] = v;
            }
        for (int k = 0; k < dim; k++) {
            lo[k] = mn[k];
            len[k] = mx[k] - mn[k];
        }
    }
    int axis = 0;
    for (int k = 1; k < dim; k++)
        if (len[k] > len[axis])
            axis = k;
    double L = isfinite(len[axis]) && len[axis] > 0 ? len[axis] : 1.0, x0 = isfinite(lo[axis]) ? lo[axis] : 0.0;
    const size_t nb = (size_t)R * BINS_PER_RANK;
    memset(d->hist, 0, nb * sizeof *d->hist);
    /* Bin of each particle (clamped; NaN to bin 0), kept in owner[] for now. */
    for (size_t i = 0; i < n; i++) {
        double q = (x[i * dim + axis] - x0) / L * (double)nb;
        size_t b = !(q >= 0) ? 0 : q >= (double)nb ? nb - 1 : (size_t)q;
        d->owner[i] = (int)b;
        d->hist[b]++;
    }
    /* Cut: bin b goes to the rank r with r·n/R <= (particles in bins before b) < (r+1)·n/R. */
    size_t before = 0;
    for (size_t b = 0; b < nb; b++) {
        size_t c = d->hist[b];
        size_t r = n ? before * (size_t)R / n : 0;
        d->hist[b] = r < (size_t)R ? r : (size_t)R - 1;
        before += c;
    }
    for (int r = 0; r < R; r++)
        d->cursor[r] = 0;
    for (size_t i = 0; i < n; i++) {
        int r = (int)d->hist[d->owner[i]];
        d->owner[i] = r;
        d->mark[i] = r == d->rank;
        d->cursor[r]++;
    }
    size_t at = 0;
    for (int r = 0; r < R; r++) {
        d->counts[r] = (int)(d->cursor[r] * (size_t)dim);
        d->displs[r] = (int)(at * (size_t)dim);
        size_t c = d->cursor[r];
        d->cursor[r] = at;
        at += c;
    }
    for (size_t i = 0; i < n; i++)
        d->perm[d->cursor[d->owner[i]]++] = i;
    d->owned = (size_t)d->counts[d->rank] / (size_t)dim;
}

bool psys__dist_begin(const psys_system *s, const double *x)
{
    psys__dist *d = s->dist;
    d->active = false;
    size_t n = s->n;
    if (n < 2 || n > (size_t)INT_MAX / 3 || !dist_reserve(d, n, s->dim))
        return false; /* every rank evaluates every row: the same result, no exchange */
    partition(d, s, x, n);
    d->active = true;
    return true;
}

psys_status psys__dist_finish(const psys_system *s, double *f)
{
    psys__dist *d = s->dist;
    if (!d->active)
        return PSYS_OK;
    d->active = false;
    const size_t dim = (size_t)s->dim;
    const size_t first = (size_t)d->displs[d->rank] / dim, own = d->owned;
    for (size_t t = 0; t < own; t++)
        memcpy(d->send + t * dim, f + d->perm[first + t] * dim, dim * sizeof(double));
    if (MPI_Allgatherv(d->send, d->counts[d->rank], MPI_DOUBLE, d->recv, d->counts, d->displs, MPI_DOUBLE, d->comm)
        != MPI_SUCCESS)
        return PSYS_ERR_INVALID;
    for (size_t t = 0; t < s->n; t++)
        memcpy(f + d->perm[t] * dim, d->recv + t * dim, dim * sizeof(double));
    return PSYS_OK;
}
