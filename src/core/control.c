/* Controlled particles (notes §5): circle motors, oscillators, keyframed
 * paths and C callbacks. Their state is imposed, never integrated; velocities
 * are the exact time derivatives of the paths
 * (docs/notes-errata.md#5-controlled-particles-position-and-velocity-at-every-stage). */
#include "core/core.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void psys__controller_eval(const psys__controller *c, int dim, double t, double *x, double *v)
{
    switch (c->kind) {
    case PSYS__CONTROL_CIRCLE: {
        double a = c->omega * t + c->phase, ca = cos(a), sa = sin(a);
        for (int k = 0; k < dim; k++) {
            x[k] = c->center[k] + c->radius * (ca * c->u[k] + sa * c->w[k]);
            v[k] = c->radius * c->omega * (-sa * c->u[k] + ca * c->w[k]);
        }
        break;
    }
    case PSYS__CONTROL_OSCILLATE: {
        double a = c->omega * t + c->phase;
        double s = c->amplitude * sin(a), ds = c->amplitude * c->omega * cos(a);
        for (int k = 0; k < dim; k++) {
            x[k] = c->center[k] + s * c->u[k];
            v[k] = ds * c->u[k];
        }
        break;
    }
    case PSYS__CONTROL_KEYFRAMES: {
        const size_t stride = 1 + (size_t)dim;
        const double *f = c->frames;
        size_t n = c->nframes;
        /* Each knot starts the piece to its right: [t_k, t_k+1) uses segment k. */
        if (t < f[0] || n == 1) {
            memcpy(x, f + 1, sizeof(double) * (size_t)dim);
            memset(v, 0, sizeof(double) * (size_t)dim);
            break;
        }
        if (t >= f[(n - 1) * stride]) {
            memcpy(x, f + (n - 1) * stride + 1, sizeof(double) * (size_t)dim);
            memset(v, 0, sizeof(double) * (size_t)dim);
            break;
        }
        /* Segment k with t_k <= t < t_{k+1} (binary search: paths can be long). */
        size_t lo = 0, hi = n - 1;
        while (hi - lo > 1) {
            size_t mid = (lo + hi) / 2;
            if (f[mid * stride] <= t)
                lo = mid;
            else
                hi = mid;
        }
        const double *a = f + lo * stride, *b = f + hi * stride;
        double span = b[0] - a[0], s = (t - a[0]) / span;
        for (int k = 0; k < dim; k++) {
            x[k] = a[1 + k] + s * (b[1 + k] - a[1 + k]);
            v[k] = (b[1 + k] - a[1 + k]) / span;
        }
        break;
    }
    case PSYS__CONTROL_CALLBACK:
        c->fn(c->ctx, t, x, v);
        break;
    }
}

void psys__controller_free(psys__controller *c) { free(c->frames); }

size_t psys__controller_find(const psys_system *sys, size_t i)
{
    for (size_t k = 0; k < sys->nctrl; k++)
        if (sys->ctrl[k].particle == i)
            return k;
    return sys->nctrl;
}

bool psys_system_is_controlled(const psys_system *sys, size_t i)
{
    return i < sys->n && (sys->flags[i] & PSYS_PARTICLE_CONTROLLED);
}

void psys_system_apply_controllers(psys_system *sys, double t)
{
    int d = sys->dim;
    for (size_t k = 0; k < sys->nctrl; k++) {
        size_t i = sys->ctrl[k].particle;
        psys__controller_eval(&sys->ctrl[k], d, t, sys->x + i * d, sys->v + i * d);
    }
}

/* Install c (ownership of c->frames passes to the system, also on failure). */
static psys_status install(psys_system *sys, psys__controller *c)
{
    size_t i = c->particle;
    if (i >= sys->n) {
        psys__controller_free(c);
        return psys__fail(&sys->err, PSYS_ERR_INVALID, "no particle %zu", i);
    }
    if (sys->flags[i] & PSYS_PARTICLE_FIXED) {
        psys__controller_free(c);
        return psys__fail(&sys->err, PSYS_ERR_INVALID, "particle %zu is fixed and cannot also be controlled", i);
    }
    size_t k = psys__controller_find(sys, i);
    if (k < sys->nctrl) {
        psys__controller_free(&sys->ctrl[k]);
    } else {
        if (sys->nctrl == sys->ctrl_cap) {
            size_t cap = sys->ctrl_cap ? 2 * sys->ctrl_cap : 8;
            psys__controller *p = psys__realloc(sys->ctrl, cap, sizeof *p);
            if (!p) {
                psys__controller_free(c);
                return psys__fail(&sys->err, PSYS_ERR_NOMEM, "out of memory adding a controller");
            }
            sys->ctrl = p;
            sys->ctrl_cap = cap;
        }
        k = sys->nctrl++;
    }
    sys->ctrl[k] = *c;
    sys->flags[i] |= PSYS_PARTICLE_CONTROLLED;
    sys->inv_mass[i] = 0.0; /* the solver must not accelerate it */
    sys->epoch++;
    int d = sys->dim;
    psys__controller_eval(c, d, sys->t, sys->x + i * d, sys->v + i * d);
    return PSYS_OK;
}

static bool finite_vec(const double *a, int n)
{
    for (int k = 0; k < n; k++)
        if (!isfinite(a[k]))
            return false;
    return true;
}

static double norm(const double *a, int n)
{
    double s = 0;
    for (int k = 0; k < n; k++)
        s += a[k] * a[k];
    return sqrt(s);
}

psys_status psys_system_control_circle(psys_system *sys, size_t i, const double *center, double radius,
                                       double omega, double phase, const double *axis)
{
    int d = sys->dim;
    psys__controller c;
    memset(&c, 0, sizeof c);
    c.particle = i;
    c.kind = PSYS__CONTROL_CIRCLE;
    if (!center || !finite_vec(center, d) || !isfinite(radius) || radius < 0 || !isfinite(omega)
        || !isfinite(phase))
        return psys__fail(&sys->err, PSYS_ERR_INVALID, "circle: center, radius >= 0, omega and phase must be finite");
    memcpy(c.center, center, sizeof(double) * (size_t)d);
    c.radius = radius;
    c.omega = omega;
    c.phase = phase;
    if (d == 2) {
        c.u[0] = 1;
        c.w[1] = 1;
        c.given[2] = 1;
    } else {
        double a[3] = {0, 0, 1};
        memcpy(c.given, a, sizeof a);
        if (axis) {
            memcpy(c.given, axis, sizeof c.given);
            double len = finite_vec(axis, 3) ? norm(axis, 3) : 0;
            if (!(len > 0))
                return psys__fail(&sys->err, PSYS_ERR_INVALID, "circle: axis must be a finite nonzero vector");
            for (int k = 0; k < 3; k++)
                a[k] = axis[k] / len;
        }
        /* u: e_x made orthogonal to the axis (e_y if the axis is along x); w = axis × u. */
        double e[3] = {1, 0, 0};
        if (fabs(a[0]) > 0.9) {
            e[0] = 0;
            e[1] = 1;
        }
        double ea = e[0] * a[0] + e[1] * a[1] + e[2] * a[2];
        for (int k = 0; k < 3; k++)
            c.u[k] = e[k] - ea * a[k];
        double ul = norm(c.u, 3);
        for (int k = 0; k < 3; k++)
            c.u[k] /= ul;
        c.w[0] = a[1] * c.u[2] - a[2] * c.u[1];
        c.w[1] = a[2] * c.u[0] - a[0] * c.u[2];
        c.w[2] = a[0] * c.u[1] - a[1] * c.u[0];
    }
    return install(sys, &c);
}

psys_status psys_system_control_oscillate(psys_system *sys, size_t i, const double *center,
                                          const double *direction, double amplitude, double omega, double phase)
{
    int d = sys->dim;
    psys__controller c;
    memset(&c, 0, sizeof c);
    c.particle = i;
    c.kind = PSYS__CONTROL_OSCILLATE;
    double len = direction && finite_vec(direction, d) ? norm(direction, d) : 0;
    if (!center || !finite_vec(center, d) || !(len > 0) || !isfinite(amplitude) || !isfinite(omega)
        || !isfinite(phase))
        return psys__fail(&sys->err, PSYS_ERR_INVALID,
                          "oscillate: center, a nonzero direction, amplitude, omega and phase must be finite");
    memcpy(c.center, center, sizeof(double) * (size_t)d);
    for (int k = 0; k < d; k++) {
        c.u[k] = direction[k] / len;
        c.given[k] = direction[k];
    }
    c.amplitude = amplitude;
    c.omega = omega;
    c.phase = phase;
    return install(sys, &c);
}

psys_status psys_system_control_keyframes(psys_system *sys, size_t i, const double *frames, size_t count)
{
    size_t stride = 1 + (size_t)sys->dim;
    if (!frames || count == 0)
        return psys__fail(&sys->err, PSYS_ERR_INVALID, "keyframes: at least one frame is needed");
    for (size_t k = 0; k < count; k++) {
        if (!finite_vec(frames + k * stride, (int)stride))
            return psys__fail(&sys->err, PSYS_ERR_INVALID, "keyframes: frame %zu is not finite", k);
        if (k > 0 && !(frames[k * stride] > frames[(k - 1) * stride]))
            return psys__fail(&sys->err, PSYS_ERR_INVALID, "keyframes: times must increase strictly (frame %zu)", k);
    }
    psys__controller c;
    memset(&c, 0, sizeof c);
    c.particle = i;
    c.kind = PSYS__CONTROL_KEYFRAMES;
    if (!(c.frames = psys__calloc(count * stride, sizeof(double))))
        return psys__fail(&sys->err, PSYS_ERR_NOMEM, "out of memory adding keyframes");
    memcpy(c.frames, frames, count * stride * sizeof(double));
    c.nframes = count;
    return install(sys, &c);
}

psys_status psys_system_control_callback(psys_system *sys, size_t i, psys_controller_fn fn, void *ctx)
{
    if (!fn)
        return psys__fail(&sys->err, PSYS_ERR_INVALID, "callback controller needs a function");
    psys__controller c;
    memset(&c, 0, sizeof c);
    c.particle = i;
    c.kind = PSYS__CONTROL_CALLBACK;
    c.fn = fn;
    c.ctx = ctx;
    return install(sys, &c);
}

psys_status psys_system_release(psys_system *sys, size_t i)
{
    size_t k = psys__controller_find(sys, i);
    if (k == sys->nctrl)
        return psys__fail(&sys->err, PSYS_ERR_INVALID, "particle %zu has no controller", i);
    psys__controller_free(&sys->ctrl[k]);
    sys->ctrl[k] = sys->ctrl[--sys->nctrl];
    sys->flags[i] &= (unsigned char)~PSYS_PARTICLE_CONTROLLED;
    sys->inv_mass[i] = 1.0 / sys->mass[i];
    sys->epoch++;
    return PSYS_OK;
}
