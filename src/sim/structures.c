/* Structures (notes §5 "Structures", docs/scene-format.md#structures):
 * builders of mass-and-spring
 * chains, cloth sheets, beams, blocks and wheels, for the C API and the
 * scene's "structures" array (io/json_structures.c).
 *
 * Conventions (docs/scene-format.md, "Structures"):
 *   - particles are appended after the system's existing ones; grid particle
 *     (i,j,k) is first + i + nx·(j + ny·k) (i fastest); a chain's particle i is
 *     first + i; a wheel's rim particle i is first + i and its hub first + count;
 *   - with a structure id, particles are named "id[i]", "id[i,j]", "id[i,j,k]"
 *     and "id[hub]"; every id of the form "id[..." is reserved for the
 *     structure, so an existing particle named that way is an error;
 *   - springs are appended to the system's spring set stencil by stencil in
 *     the order of the tables below, each in grid order of its first particle,
 *     all at rest (rest length = initial distance);
 *   - everything is validated, including the particle limit, before anything
 *     is allocated; a build that fails midway (out of memory) is undone. */
#include "sim/sim.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define TWO_PI 6.28318530717958647692

/* A validation problem, shared by the C API (which prints `got` from C
 * values) and the scene loader (which names the JSON path and value). */
typedef psys__problem problem;

static psys_status bad(problem *pb, const char *key, long index, const char *got, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 5, 6)))
#endif
    ;

static psys_status bad(problem *pb, const char *key, long index, const char *got, const char *fmt, ...)
{
    va_list ap;
    pb->key = key;
    pb->index = index;
    va_start(ap, fmt);
    vsnprintf(pb->what, sizeof pb->what, fmt, ap);
    va_end(ap);
    snprintf(pb->got, sizeof pb->got, "%s", got ? got : "");
    return PSYS_ERR_INVALID;
}

static psys_status nomem(problem *pb)
{
    pb->key = NULL;
    pb->index = -1;
    snprintf(pb->what, sizeof pb->what, "out of memory");
    pb->got[0] = '\0';
    return PSYS_ERR_NOMEM;
}

static void fmt_num(char *out, size_t cap, double x) { snprintf(out, cap, "%g", x); }

static void fmt_vec(char *out, size_t cap, const double *v, int n)
{
    size_t at = 0;
    at += (size_t)snprintf(out, cap, "[");
    for (int k = 0; k < n && at < cap; k++)
        at += (size_t)snprintf(out + at, cap - at, "%s%g", k ? ", " : "", v[k]);
    if (at < cap)
        snprintf(out + at, cap - at, "]");
}

static void fmt_sizes(char *out, size_t cap, const size_t *n, int nd)
{
    size_t at = 0;
    at += (size_t)snprintf(out, cap, "[");
    for (int k = 0; k < nd && at < cap; k++)
        at += (size_t)snprintf(out + at, cap - at, "%s%zu", k ? ", " : "", n[k]);
    if (at < cap)
        snprintf(out + at, cap - at, "]");
}

static bool finite_vec(const double *v, int n)
{
    for (int k = 0; k < n; k++)
        if (!isfinite(v[k]))
            return false;
    return true;
}

/* ---- checks shared by every builder ---- */

static psys_status check_id(const psys_system *sys, const char *id, problem *pb)
{
    if (!id)
        return PSYS_OK;
    if (!id[0])
        return bad(pb, "id", -1, "\"\"", "must be a non-empty string");
    size_t len = strlen(id);
    for (size_t i = 0; i < sys->n; i++) {
        const char *o = sys->ids[i];
        if (o && strncmp(o, id, len) == 0 && o[len] == '[') {
            char got[120];
            snprintf(got, sizeof got, "\"%.100s\"", id);
            return bad(pb, "id", -1, got, "already in use by particle \"%.120s\"", o);
        }
    }
    return PSYS_OK;
}

static psys_status check_material(double mass, double ks, double kd, problem *pb)
{
    char got[40];
    if (!isfinite(mass) || !(mass > 0)) {
        fmt_num(got, sizeof got, mass);
        return bad(pb, "mass", -1, got, "must be > 0");
    }
    if (!isfinite(ks) || ks < 0) {
        fmt_num(got, sizeof got, ks);
        return bad(pb, "ks", -1, got, "must be >= 0");
    }
    if (!isfinite(kd) || kd < 0) {
        fmt_num(got, sizeof got, kd);
        return bad(pb, "kd", -1, got, "must be >= 0");
    }
    return PSYS_OK;
}

/* `count` new particles must keep the system within PSYS_MAX_PARTICLES. */
static bool fits(const psys_system *sys, size_t count)
{
    return sys->n <= PSYS_MAX_PARTICLES && count <= PSYS_MAX_PARTICLES - sys->n;
}

/* Where a build failed after particles or springs were added: undo it. */
static void undo(psys_system *sys, size_t n0, size_t s0)
{
    if (sys->springs)
        psys__springs_truncate(sys->springs, s0);
    psys__system_truncate(sys, n0);
}

/* Buffer for particle ids "id[...]" (NULL when the structure has no id). */
static char *id_buffer(const char *id, problem *pb, bool *oom)
{
    *oom = false;
    if (!id)
        return NULL;
    char *buf = malloc(strlen(id) + 80);
    if (!buf) {
        *oom = true;
        nomem(pb);
    }
    return buf;
}

/* ---- lattices: cloth, beam, block ---- */

typedef struct stencil {
    int off[3];
    double ks, kd;
} stencil;

typedef struct lattice {
    const char *id;
    int nd;                /* grid dimensions: 2 (planar) or 3 */
    size_t n[3];           /* n[2] = 1 for planar grids */
    double origin[3], axes[3][3], spacing, mass, ks, kd;
    const size_t *pin;     /* pin_count × nd coordinates */
    size_t pin_count;
    size_t nst;
    stencil st[16];
} lattice;

static psys_status lattice_check(const psys_system *sys, const lattice *L, problem *pb)
{
    int dim = sys->dim;
    char got[120];
    psys_status st;
    if ((st = check_id(sys, L->id, pb)) != PSYS_OK || (st = check_material(L->mass, L->ks, L->kd, pb)) != PSYS_OK)
        return st;
    for (size_t s = 0; s < L->nst; s++)
        if (!isfinite(L->st[s].ks) || L->st[s].ks < 0 || !isfinite(L->st[s].kd) || L->st[s].kd < 0)
            return bad(pb, "ks", -1, "", "every spring's ks and kd must be finite and >= 0");
    fmt_sizes(got, sizeof got, L->n, L->nd);
    for (int d = 0; d < L->nd; d++)
        if (L->n[d] < 2)
            return bad(pb, "size", -1, got, "must be an array of %d integers >= 2", L->nd);
    /* Particle count without overflow: each factor is checked before multiplying. */
    size_t total = 1;
    for (int d = 0; d < L->nd; d++) {
        if (L->n[d] > PSYS_MAX_PARTICLES || total > PSYS_MAX_PARTICLES / L->n[d] || !fits(sys, total * L->n[d]))
            return bad(pb, "size", -1, got, "would exceed the limit of %u particles per scene", PSYS_MAX_PARTICLES);
        total *= L->n[d];
    }
    if (!isfinite(L->spacing) || !(L->spacing > 0)) {
        fmt_num(got, sizeof got, L->spacing);
        return bad(pb, "spacing", -1, got, "must be > 0");
    }
    if (!finite_vec(L->origin, dim)) {
        fmt_vec(got, sizeof got, L->origin, dim);
        return bad(pb, "origin", -1, got, "must be %d finite numbers", dim);
    }
    /* Axes: finite, and independent, so that no two particles coincide. */
    const double(*a)[3] = L->axes;
    bool ok = true;
    for (int d = 0; d < L->nd; d++)
        ok = ok && finite_vec(a[d], dim);
    if (ok && L->nd == 2) {
        double n1 = 0, n2 = 0, dot = 0;
        for (int k = 0; k < dim; k++) {
            n1 += a[0][k] * a[0][k];
            n2 += a[1][k] * a[1][k];
            dot += a[0][k] * a[1][k];
        }
        /* |a1 × a2|² = |a1|²|a2|² - (a1·a2)², relative to |a1|²|a2|² */
        ok = n1 > 0 && n2 > 0 && n1 * n2 - dot * dot > 1e-12 * n1 * n2;
    } else if (ok) {
        double det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
                     - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
                     + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
        double n[3];
        for (int d = 0; d < 3; d++)
            n[d] = sqrt(a[d][0] * a[d][0] + a[d][1] * a[d][1] + a[d][2] * a[d][2]);
        ok = n[0] > 0 && n[1] > 0 && n[2] > 0 && fabs(det) > 1e-6 * n[0] * n[1] * n[2];
    }
    if (!ok) {
        size_t at = (size_t)snprintf(got, sizeof got, "[");
        for (int d = 0; d < L->nd && at < sizeof got; d++) {
            at += (size_t)snprintf(got + at, sizeof got - at, "%s", d ? ", " : "");
            if (at < sizeof got) {
                fmt_vec(got + at, sizeof got - at, a[d], dim);
                at += strlen(got + at);
            }
        }
        if (at < sizeof got)
            snprintf(got + at, sizeof got - at, "]");
        return bad(pb, "axes", -1, got, L->nd == 2 ? "must be two non-zero, non-parallel vectors"
                                                   : "must be three linearly independent vectors");
    }
    for (size_t m = 0; m < L->pin_count; m++) {
        const size_t *c = L->pin + m * (size_t)L->nd;
        bool inside = true;
        for (int d = 0; d < L->nd; d++)
            inside = inside && c[d] < L->n[d];
        if (!inside) {
            size_t at = (size_t)snprintf(got, sizeof got, "[");
            for (int d = 0; d < L->nd && at < sizeof got; d++)
                at += (size_t)snprintf(got + at, sizeof got - at, "%s%lld", d ? ", " : "",
                                       c[d] == SIZE_MAX ? -1LL : (long long)c[d]);
            if (at < sizeof got)
                snprintf(got + at, sizeof got - at, "]");
            if (L->nd == 2)
                return bad(pb, "pin", (long)m, got, "must be grid coordinates [i, j] with 0 <= i < %zu, 0 <= j < %zu",
                           L->n[0], L->n[1]);
            return bad(pb, "pin", (long)m, got,
                       "must be grid coordinates [i, j, k] with 0 <= i < %zu, 0 <= j < %zu, 0 <= k < %zu", L->n[0],
                       L->n[1], L->n[2]);
        }
    }
    return PSYS_OK;
}

/* i + o for a grid coordinate known to stay inside the grid. */
static size_t shift(size_t i, int o) { return o < 0 ? i - (size_t)(-o) : i + (size_t)o; }

static psys_status lattice_add(psys_system *sys, const lattice *L, size_t *first, problem *pb)
{
    psys_status st = lattice_check(sys, L, pb);
    if (st != PSYS_OK)
        return st;
    int dim = sys->dim;
    size_t nx = L->n[0], ny = L->n[1], nz = L->n[2], total = nx * ny * nz;
    size_t n0 = sys->n, s0 = psys_system_spring_count(sys);
    bool oom;
    char *name = id_buffer(L->id, pb, &oom);
    if (oom)
        return PSYS_ERR_NOMEM;
    if (psys__system_reserve(sys, n0 + total) != PSYS_OK) {
        free(name);
        return nomem(pb);
    }
    for (size_t k = 0; k < nz; k++)
        for (size_t j = 0; j < ny; j++)
            for (size_t i = 0; i < nx; i++) {
                /* x = origin + (i·h)·a1 + (j·h)·a2 [+ (k·h)·a3], summed in that order */
                double c[3] = {(double)i * L->spacing, (double)j * L->spacing, (double)k * L->spacing}, x[3];
                for (int q = 0; q < dim; q++) {
                    x[q] = L->origin[q];
                    for (int d = 0; d < L->nd; d++)
                        x[q] += c[d] * L->axes[d][q];
                }
                if (name) {
                    if (L->nd == 2)
                        sprintf(name, "%s[%zu,%zu]", L->id, i, j);
                    else
                        sprintf(name, "%s[%zu,%zu,%zu]", L->id, i, j, k);
                }
                if (psys__system_add_particle_unique(sys, x, NULL, L->mass, name, NULL) != PSYS_OK) {
                    free(name);
                    undo(sys, n0, s0);
                    return nomem(pb);
                }
            }
    free(name);
    for (size_t m = 0; m < L->pin_count; m++) {
        const size_t *c = L->pin + m * (size_t)L->nd;
        psys_system_set_fixed(sys, n0 + c[0] + nx * (c[1] + ny * (L->nd == 3 ? c[2] : 0)), true);
    }
    for (size_t s = 0; s < L->nst; s++) {
        const int *o = L->st[s].off;
        /* a = (i,j,k), b = a + off; loop only where b is inside the grid */
        size_t lo[3], hi[3];
        for (int d = 0; d < 3; d++) {
            size_t ao = (size_t)(o[d] < 0 ? -o[d] : o[d]);
            if (L->n[d] <= ao)
                goto next;
            lo[d] = o[d] < 0 ? ao : 0;
            hi[d] = o[d] > 0 ? L->n[d] - ao : L->n[d];
        }
        for (size_t k = lo[2]; k < hi[2]; k++)
            for (size_t j = lo[1]; j < hi[1]; j++)
                for (size_t i = lo[0]; i < hi[0]; i++) {
                    size_t a = n0 + i + nx * (j + ny * k);
                    size_t b = n0 + shift(i, o[0]) + nx * (shift(j, o[1]) + ny * shift(k, o[2]));
                    if (psys_system_add_spring(sys, a, b, L->st[s].ks, L->st[s].kd, -1) != PSYS_OK) {
                        undo(sys, n0, s0);
                        return nomem(pb);
                    }
                }
    next:;
    }
    if (first)
        *first = n0;
    return PSYS_OK;
}

static void lattice_cloth(const psys_cloth_def *def, lattice *L)
{
    memset(L, 0, sizeof *L);
    L->id = def->id;
    L->nd = 2;
    L->n[0] = def->nx;
    L->n[1] = def->ny;
    L->n[2] = 1;
    memcpy(L->origin, def->origin, sizeof L->origin);
    memcpy(L->axes, def->axes, sizeof def->axes);
    L->spacing = def->spacing;
    L->mass = def->mass;
    L->ks = def->ks;
    L->kd = def->kd;
    L->pin = def->pin;
    L->pin_count = def->pin_count;
    double sks = def->shear_ks < 0 ? def->ks : def->shear_ks, skd = def->shear_kd < 0 ? def->kd : def->shear_kd;
    double bks = def->bend_ks < 0 ? def->ks : def->bend_ks, bkd = def->bend_kd < 0 ? def->kd : def->bend_kd;
    L->st[L->nst++] = (stencil){{1, 0, 0}, def->ks, def->kd};
    L->st[L->nst++] = (stencil){{0, 1, 0}, def->ks, def->kd};
    if (def->shear) {
        L->st[L->nst++] = (stencil){{1, 1, 0}, sks, skd};
        L->st[L->nst++] = (stencil){{-1, 1, 0}, sks, skd};
    }
    if (def->bend) {
        L->st[L->nst++] = (stencil){{2, 0, 0}, bks, bkd};
        L->st[L->nst++] = (stencil){{0, 2, 0}, bks, bkd};
    }
}

static void lattice_block(const psys_block_def *def, lattice *L)
{
    static const int offs[13][3] = {
        {1, 0, 0},  {0, 1, 0},  {0, 0, 1},                                        /* edges */
        {1, 1, 0},  {-1, 1, 0}, {1, 0, 1}, {-1, 0, 1}, {0, 1, 1}, {0, -1, 1},     /* face diagonals */
        {1, 1, 1},  {-1, 1, 1}, {1, -1, 1}, {-1, -1, 1},                          /* body diagonals */
    };
    memset(L, 0, sizeof *L);
    L->id = def->id;
    L->nd = 3;
    L->n[0] = def->nx;
    L->n[1] = def->ny;
    L->n[2] = def->nz;
    memcpy(L->origin, def->origin, sizeof L->origin);
    memcpy(L->axes, def->axes, sizeof def->axes);
    L->spacing = def->spacing;
    L->mass = def->mass;
    L->ks = def->ks;
    L->kd = def->kd;
    L->pin = def->pin;
    L->pin_count = def->pin_count;
    for (int s = 0; s < 13; s++) {
        memcpy(L->st[s].off, offs[s], sizeof offs[s]);
        L->st[s].ks = def->ks;
        L->st[s].kd = def->kd;
    }
    L->nst = 13;
}

/* ---- chains and wheels ---- */

static psys_status chain_add(psys_system *sys, const psys_chain_def *def, size_t *first, problem *pb)
{
    int dim = sys->dim;
    char got[120];
    psys_status st;
    if ((st = check_id(sys, def->id, pb)) != PSYS_OK
        || (st = check_material(def->mass, def->ks, def->kd, pb)) != PSYS_OK)
        return st;
    if (def->count < 2) {
        snprintf(got, sizeof got, "%zu", def->count);
        return bad(pb, "count", -1, got, "must be an integer >= 2");
    }
    if (def->count > PSYS_MAX_PARTICLES || !fits(sys, def->count)) {
        snprintf(got, sizeof got, "%zu", def->count);
        return bad(pb, "count", -1, got, "would exceed the limit of %u particles per scene", PSYS_MAX_PARTICLES);
    }
    if (!finite_vec(def->from, dim)) {
        fmt_vec(got, sizeof got, def->from, dim);
        return bad(pb, "from", -1, got, "must be %d finite numbers", dim);
    }
    if (!finite_vec(def->to, dim)) {
        fmt_vec(got, sizeof got, def->to, dim);
        return bad(pb, "to", -1, got, "must be %d finite numbers", dim);
    }
    bool same = true;
    for (int q = 0; q < dim; q++)
        same = same && def->from[q] == def->to[q];
    if (same) {
        fmt_vec(got, sizeof got, def->to, dim);
        return bad(pb, "to", -1, got, "must differ from \"from\"");
    }
    for (size_t m = 0; m < def->pin_count; m++)
        if (def->pin[m] >= def->count) {
            snprintf(got, sizeof got, "%lld", def->pin[m] == SIZE_MAX ? -1LL : (long long)def->pin[m]);
            return bad(pb, "pin", (long)m, got, "must be a particle index from 0 to %zu", def->count - 1);
        }
    double amp = def->muscle_amplitude;
    if (!isfinite(amp) || amp < 0 || amp > 1) {
        fmt_num(got, sizeof got, amp);
        return bad(pb, "muscle", -1, got, "amplitude must be from 0 to 1");
    }
    if (!isfinite(def->muscle_omega) || !isfinite(def->muscle_phase) || !isfinite(def->muscle_phase_step))
        return bad(pb, "muscle", -1, "", "omega, phase and phase_step must be finite");

    size_t n0 = sys->n, s0 = psys_system_spring_count(sys), n = def->count;
    bool oom;
    char *name = id_buffer(def->id, pb, &oom);
    if (oom)
        return PSYS_ERR_NOMEM;
    if (psys__system_reserve(sys, n0 + n) != PSYS_OK) {
        free(name);
        return nomem(pb);
    }
    for (size_t i = 0; i < n; i++) {
        /* x = (1 - t)·from + t·to with t = i/(count-1): exact at both ends */
        double t = (double)i / (double)(n - 1), x[3];
        for (int q = 0; q < dim; q++)
            x[q] = (1.0 - t) * def->from[q] + t * def->to[q];
        if (name)
            sprintf(name, "%s[%zu]", def->id, i);
        if (psys__system_add_particle_unique(sys, x, NULL, def->mass, name, NULL) != PSYS_OK) {
            free(name);
            undo(sys, n0, s0);
            return nomem(pb);
        }
    }
    free(name);
    for (size_t m = 0; m < def->pin_count; m++)
        psys_system_set_fixed(sys, n0 + def->pin[m], true);
    for (size_t i = 0; i + 1 < n; i++)
        if (psys_system_add_spring(sys, n0 + i, n0 + i + 1, def->ks, def->kd, -1) != PSYS_OK
            || (amp > 0
                && psys_system_set_spring_muscle(sys, s0 + i, amp, def->muscle_omega,
                                                 def->muscle_phase + (double)i * def->muscle_phase_step)
                       != PSYS_OK)) {
            undo(sys, n0, s0);
            return nomem(pb);
        }
    if (first)
        *first = n0;
    return PSYS_OK;
}

/* Right-handed basis (u, w) of the plane normal to axis, as the circle
 * controller builds it: u = e_x made orthogonal to the axis (e_y when the
 * axis is nearly along x), w = axis × u. In 2-D u = e_x, w = e_y. */
static void wheel_basis(int dim, const double *axis, double *u, double *w)
{
    memset(u, 0, 3 * sizeof *u);
    memset(w, 0, 3 * sizeof *w);
    if (dim == 2) {
        u[0] = 1;
        w[1] = 1;
        return;
    }
    double len = sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]), a[3], e[3] = {1, 0, 0};
    for (int k = 0; k < 3; k++)
        a[k] = axis[k] / len;
    if (fabs(a[0]) > 0.9) {
        e[0] = 0;
        e[1] = 1;
    }
    double ea = e[0] * a[0] + e[1] * a[1] + e[2] * a[2];
    for (int k = 0; k < 3; k++)
        u[k] = e[k] - ea * a[k];
    double ul = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
    for (int k = 0; k < 3; k++)
        u[k] /= ul;
    w[0] = a[1] * u[2] - a[2] * u[1];
    w[1] = a[2] * u[0] - a[0] * u[2];
    w[2] = a[0] * u[1] - a[1] * u[0];
}

static psys_status wheel_add(psys_system *sys, const psys_wheel_def *def, size_t *first, problem *pb)
{
    int dim = sys->dim;
    char got[120];
    psys_status st;
    if ((st = check_id(sys, def->id, pb)) != PSYS_OK
        || (st = check_material(def->mass, def->ks, def->kd, pb)) != PSYS_OK)
        return st;
    size_t n = def->count;
    if (n < 3) {
        snprintf(got, sizeof got, "%zu", n);
        return bad(pb, "count", -1, got, "must be an integer >= 3");
    }
    if (n > PSYS_MAX_PARTICLES - 1 || !fits(sys, n + (def->hub ? 1 : 0))) {
        snprintf(got, sizeof got, "%zu", n);
        return bad(pb, "count", -1, got, "would exceed the limit of %u particles per scene", PSYS_MAX_PARTICLES);
    }
    if (!finite_vec(def->center, dim)) {
        fmt_vec(got, sizeof got, def->center, dim);
        return bad(pb, "center", -1, got, "must be %d finite numbers", dim);
    }
    if (!isfinite(def->radius) || !(def->radius > 0)) {
        fmt_num(got, sizeof got, def->radius);
        return bad(pb, "radius", -1, got, "must be > 0");
    }
    if (dim == 3 && (!finite_vec(def->axis, 3) || !(def->axis[0] != 0 || def->axis[1] != 0 || def->axis[2] != 0))) {
        fmt_vec(got, sizeof got, def->axis, 3);
        return bad(pb, "axis", -1, got, "must be a non-zero vector");
    }
    for (size_t m = 0; m < def->pin_count; m++)
        if (def->pin[m] >= n) {
            snprintf(got, sizeof got, "%lld", def->pin[m] == SIZE_MAX ? -1LL : (long long)def->pin[m]);
            return bad(pb, "pin", (long)m, got, "must be a rim index from 0 to %zu or \"hub\"", n - 1);
        }
    if (def->pin_hub && !def->hub)
        return bad(pb, "pin_hub", -1, "true", "needs a hub (hub is false)");

    size_t n0 = sys->n, s0 = psys_system_spring_count(sys), hub = n0 + n;
    bool oom;
    char *name = id_buffer(def->id, pb, &oom);
    if (oom)
        return PSYS_ERR_NOMEM;
    if (psys__system_reserve(sys, n0 + n + 1) != PSYS_OK) {
        free(name);
        return nomem(pb);
    }
    double u[3], w[3];
    wheel_basis(dim, def->axis, u, w);
    for (size_t i = 0; i <= n; i++) {
        double x[3];
        if (i == n && !def->hub)
            break;
        if (i < n) {
            /* x = c + (R cos θ)·u + (R sin θ)·w, θ = 2π i / count */
            double th = TWO_PI * (double)i / (double)n, cr = def->radius * cos(th), sr = def->radius * sin(th);
            for (int q = 0; q < dim; q++)
                x[q] = def->center[q] + cr * u[q] + sr * w[q];
            if (name)
                sprintf(name, "%s[%zu]", def->id, i);
        } else {
            memcpy(x, def->center, sizeof x);
            if (name)
                sprintf(name, "%s[hub]", def->id);
        }
        if (psys__system_add_particle_unique(sys, x, NULL, def->mass, name, NULL) != PSYS_OK) {
            free(name);
            undo(sys, n0, s0);
            return nomem(pb);
        }
    }
    free(name);
    for (size_t m = 0; m < def->pin_count; m++)
        psys_system_set_fixed(sys, n0 + def->pin[m], true);
    if (def->pin_hub)
        psys_system_set_fixed(sys, hub, true);
    /* rim (i, i+1), spokes (i, hub), bracing (i, i+2) without duplicates:
     * n bracing springs for n >= 5, 2 for n = 4, none for n = 3 */
    size_t nbrace = !def->brace ? 0 : n >= 5 ? n : n == 4 ? 2 : 0;
    bool ok = true;
    for (size_t i = 0; ok && i < n; i++)
        ok = psys_system_add_spring(sys, n0 + i, n0 + (i + 1) % n, def->ks, def->kd, -1) == PSYS_OK;
    for (size_t i = 0; ok && def->hub && i < n; i++)
        ok = psys_system_add_spring(sys, n0 + i, hub, def->ks, def->kd, -1) == PSYS_OK;
    for (size_t i = 0; ok && i < nbrace; i++)
        ok = psys_system_add_spring(sys, n0 + i, n0 + (i + 2) % n, def->ks, def->kd, -1) == PSYS_OK;
    if (!ok) {
        undo(sys, n0, s0);
        return nomem(pb);
    }
    if (first)
        *first = n0;
    return PSYS_OK;
}

/* ---- C API ---- */

psys_chain_def psys_chain_def_default(void)
{
    psys_chain_def d;
    memset(&d, 0, sizeof d);
    d.to[0] = 1;
    d.count = 2;
    d.mass = 1;
    d.ks = 1;
    return d;
}

psys_cloth_def psys_cloth_def_default(void)
{
    psys_cloth_def d;
    memset(&d, 0, sizeof d);
    d.nx = d.ny = 2;
    d.spacing = 1;
    d.mass = 1;
    d.ks = 1;
    d.shear = d.bend = true;
    d.shear_ks = d.shear_kd = d.bend_ks = d.bend_kd = -1;
    d.axes[0][0] = 1;
    d.axes[1][1] = 1;
    return d;
}

psys_beam_def psys_beam_def_default(void)
{
    psys_beam_def d;
    memset(&d, 0, sizeof d);
    d.nx = d.ny = 2;
    d.spacing = 1;
    d.mass = 1;
    d.ks = 1;
    d.axes[0][0] = 1;
    d.axes[1][1] = 1;
    return d;
}

psys_block_def psys_block_def_default(void)
{
    psys_block_def d;
    memset(&d, 0, sizeof d);
    d.nx = d.ny = d.nz = 2;
    d.spacing = 1;
    d.mass = 1;
    d.ks = 1;
    d.axes[0][0] = 1;
    d.axes[1][1] = 1;
    d.axes[2][2] = 1;
    return d;
}

psys_wheel_def psys_wheel_def_default(void)
{
    psys_wheel_def d;
    memset(&d, 0, sizeof d);
    d.radius = 1;
    d.count = 8;
    d.mass = 1;
    d.ks = 1;
    d.axis[2] = 1;
    d.hub = d.brace = true;
    return d;
}

/* "cloth \"sheet\": size: must be ... (got [1, 5])" into the system's error. */
static psys_status report(psys_system *sys, const char *kind, const char *id, psys_status st, const problem *pb)
{
    if (st == PSYS_OK)
        return PSYS_OK;
    char who[160], key[64] = "";
    if (id)
        snprintf(who, sizeof who, "%s \"%.100s\"", kind, id);
    else
        snprintf(who, sizeof who, "%s", kind);
    if (!pb->key)
        return psys__fail(&sys->err, st, "%s: out of memory", who);
    if (pb->index >= 0)
        snprintf(key, sizeof key, "%s[%ld]", pb->key, pb->index);
    else
        snprintf(key, sizeof key, "%s", pb->key);
    if (pb->got[0])
        return psys__fail(&sys->err, st, "%s: %s: %s (got %s)", who, key, pb->what, pb->got);
    return psys__fail(&sys->err, st, "%s: %s: %s", who, key, pb->what);
}

psys_status psys_system_add_chain(psys_system *sys, const psys_chain_def *def, size_t *first_index)
{
    problem pb;
    if (!def)
        return psys__fail(&sys->err, PSYS_ERR_INVALID, "chain: no definition");
    if (def->pin_count && !def->pin)
        return psys__fail(&sys->err, PSYS_ERR_INVALID, "chain: pin is NULL but pin_count is %zu", def->pin_count);
    return report(sys, "chain", def->id, chain_add(sys, def, first_index, &pb), &pb);
}

psys_status psys_system_add_cloth(psys_system *sys, const psys_cloth_def *def, size_t *first_index)
{
    problem pb;
    lattice L;
    if (!def)
        return psys__fail(&sys->err, PSYS_ERR_INVALID, "cloth: no definition");
    if (def->pin_count && !def->pin)
        return psys__fail(&sys->err, PSYS_ERR_INVALID, "cloth: pin is NULL but pin_count is %zu", def->pin_count);
    lattice_cloth(def, &L);
    return report(sys, "cloth", def->id, lattice_add(sys, &L, first_index, &pb), &pb);
}

psys_status psys_system_add_beam(psys_system *sys, const psys_beam_def *def, size_t *first_index)
{
    problem pb;
    lattice L;
    if (!def)
        return psys__fail(&sys->err, PSYS_ERR_INVALID, "beam: no definition");
    if (def->pin_count && !def->pin)
        return psys__fail(&sys->err, PSYS_ERR_INVALID, "beam: pin is NULL but pin_count is %zu", def->pin_count);
    /* a beam is a cloth with shear springs of the same constants and no bend springs */
    psys_cloth_def c = psys_cloth_def_default();
    c.id = def->id;
    memcpy(c.origin, def->origin, sizeof c.origin);
    c.nx = def->nx;
    c.ny = def->ny;
    c.spacing = def->spacing;
    c.mass = def->mass;
    c.ks = def->ks;
    c.kd = def->kd;
    c.bend = false;
    memcpy(c.axes, def->axes, sizeof c.axes);
    c.pin = def->pin;
    c.pin_count = def->pin_count;
    lattice_cloth(&c, &L);
    return report(sys, "beam", def->id, lattice_add(sys, &L, first_index, &pb), &pb);
}

psys_status psys_system_add_block(psys_system *sys, const psys_block_def *def, size_t *first_index)
{
    problem pb;
    lattice L;
    if (!def)
        return psys__fail(&sys->err, PSYS_ERR_INVALID, "block: no definition");
    if (sys->dim != 3)
        return psys__fail(&sys->err, PSYS_ERR_INVALID, "block: needs a 3-D system (dim is %d)", sys->dim);
    if (def->pin_count && !def->pin)
        return psys__fail(&sys->err, PSYS_ERR_INVALID, "block: pin is NULL but pin_count is %zu", def->pin_count);
    lattice_block(def, &L);
    return report(sys, "block", def->id, lattice_add(sys, &L, first_index, &pb), &pb);
}

psys_status psys_system_add_wheel(psys_system *sys, const psys_wheel_def *def, size_t *first_index)
{
    problem pb;
    if (!def)
        return psys__fail(&sys->err, PSYS_ERR_INVALID, "wheel: no definition");
    if (def->pin_count && !def->pin)
        return psys__fail(&sys->err, PSYS_ERR_INVALID, "wheel: pin is NULL but pin_count is %zu", def->pin_count);
    return report(sys, "wheel", def->id, wheel_add(sys, def, first_index, &pb), &pb);
}

/* The builders for the scene loader, which reports problems itself. */
psys_status psys__chain_build(psys_system *sys, const psys_chain_def *def, psys__problem *pb)
{
    return chain_add(sys, def, NULL, pb);
}

psys_status psys__cloth_build(psys_system *sys, const psys_cloth_def *def, psys__problem *pb)
{
    lattice L;
    lattice_cloth(def, &L);
    return lattice_add(sys, &L, NULL, pb);
}

psys_status psys__block_build(psys_system *sys, const psys_block_def *def, psys__problem *pb)
{
    lattice L;
    lattice_block(def, &L);
    return lattice_add(sys, &L, NULL, pb);
}

psys_status psys__wheel_build(psys_system *sys, const psys_wheel_def *def, psys__problem *pb)
{
    return wheel_add(sys, def, NULL, pb);
}
