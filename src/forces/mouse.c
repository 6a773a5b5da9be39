/* Mouse spring (notes §5): a damped zero-length spring from a particle to a
 * movable target, f = -ks (x - p) - kd (v - ṗ). Dragging through a spring,
 * not by setting positions, keeps fast mouse motion stable. The target is
 * either set by the caller (the viewer) or follows a keyframed path (scenes). */
#include "forces/forces.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct mouse {
    size_t particle;
    double ks, kd;
    double target[3], target_v[3];
    psys__controller path; /* kind KEYFRAMES when nframes > 0 */
} mouse;

static void mouse_destroy(void *data)
{
    mouse *m = data;
    if (m)
        psys__controller_free(&m->path);
    free(m);
}

/* Target position and velocity at time t. */
static void mouse_target(const mouse *m, int d, double t, double *p, double *pv)
{
    if (m->path.nframes) {
        psys__controller_eval(&m->path, d, t, p, pv);
    } else {
        memcpy(p, m->target, sizeof(double) * (size_t)d);
        memcpy(pv, m->target_v, sizeof(double) * (size_t)d);
    }
}

static void mouse_apply(void *data, const psys_force_eval *e, double *f)
{
    const mouse *m = data;
    int d = e->dim;
    double p[3], pv[3];
    mouse_target(m, d, e->t, p, pv);
    size_t i = m->particle;
    for (int c = 0; c < d; c++)
        f[i * d + c] += -m->ks * (e->x[i * d + c] - p[c]) - m->kd * (e->v[i * d + c] - pv[c]);
}

static double mouse_energy(void *data, const psys_force_eval *e)
{
    const mouse *m = data;
    int d = e->dim;
    double p[3], pv[3], u = 0;
    mouse_target(m, d, e->t, p, pv);
    for (int c = 0; c < d; c++) {
        double l = e->x[m->particle * d + c] - p[c];
        u += l * l;
    }
    return 0.5 * m->ks * u;
}

static void mouse_jacobian(void *data, const psys_force_eval *e, psys_jacobian *J)
{
    const mouse *m = data;
    int d = e->dim;
    double kx[9] = {0}, kv[9] = {0};
    for (int c = 0; c < d; c++) {
        kx[c * d + c] = -m->ks;
        kv[c * d + c] = -m->kd;
    }
    psys_jacobian_add(J, m->particle, m->particle, kx, kv);
}

/* A one-particle term (damped: not velocity-free); MPI ranks do not split it. */
const psys_force_class psys_mouse_spring_class = {.name = "mouse-spring",
                                                  .apply = mouse_apply,
                                                  .energy = mouse_energy,
                                                  .jacobian = mouse_jacobian,
                                                  .destroy = mouse_destroy,
                                                  .traits = PSYS_FORCE_BONDED};

void psys__mouse_get(const void *data, size_t *particle, double *ks, double *kd, const double **target,
                     const double **frames, size_t *nframes)
{
    const mouse *m = data;
    *particle = m->particle;
    *ks = m->ks;
    *kd = m->kd;
    *target = m->target;
    *frames = m->path.frames;
    *nframes = m->path.nframes;
}

psys_status psys_system_add_mouse_spring(psys_system *sys, size_t i, const double *target, double ks, double kd,
                                         size_t *handle)
{
    if (i >= sys->n)
        return psys__fail(&sys->err, PSYS_ERR_INVALID, "no particle %zu", i);
    if (!(ks >= 0) || !(kd >= 0) || !isfinite(ks) || !isfinite(kd))
        return psys__fail(&sys->err, PSYS_ERR_INVALID, "mouse spring ks and kd must be finite and >= 0");
    for (int c = 0; c < sys->dim; c++)
        if (!target || !isfinite(target[c]))
            return psys__fail(&sys->err, PSYS_ERR_INVALID, "mouse spring target must be finite");
    mouse *m = calloc(1, sizeof *m);
    if (!m)
        return psys__fail(&sys->err, PSYS_ERR_NOMEM, "out of memory adding a mouse spring");
    m->particle = i;
    m->ks = ks;
    m->kd = kd;
    memcpy(m->target, target, sizeof(double) * (size_t)sys->dim);
    m->path.kind = PSYS__CONTROL_KEYFRAMES;
    psys_status st = psys_system_add_force(sys, &psys_mouse_spring_class, m);
    if (st == PSYS_OK && handle)
        *handle = sys->nforces - 1;
    return st;
}

static mouse *get_mouse(psys_system *sys, size_t handle)
{
    if (handle >= sys->nforces || sys->forces[handle].cls != &psys_mouse_spring_class) {
        psys__fail(&sys->err, PSYS_ERR_INVALID, "force %zu is not a mouse spring", handle);
        return NULL;
    }
    return sys->forces[handle].data;
}

psys_status psys_system_mouse_set_target(psys_system *sys, size_t handle, const double *target,
                                         const double *target_velocity)
{
    mouse *m = get_mouse(sys, handle);
    if (!m)
        return PSYS_ERR_INVALID;
    for (int c = 0; c < sys->dim; c++)
        if (!target || !isfinite(target[c]) || (target_velocity && !isfinite(target_velocity[c])))
            return psys__fail(&sys->err, PSYS_ERR_INVALID, "mouse spring target must be finite");
    memcpy(m->target, target, sizeof(double) * (size_t)sys->dim);
    for (int c = 0; c < sys->dim; c++)
        m->target_v[c] = target_velocity ? target_velocity[c] : 0.0;
    /* A target set by hand takes over from a scripted path. */
    psys__controller_free(&m->path);
    m->path.frames = NULL;
    m->path.nframes = 0;
    return PSYS_OK;
}

psys_status psys_system_mouse_set_path(psys_system *sys, size_t handle, const double *frames, size_t count)
{
    mouse *m = get_mouse(sys, handle);
    if (!m)
        return PSYS_ERR_INVALID;
    size_t stride = 1 + (size_t)sys->dim;
    if (!frames || count == 0)
        return psys__fail(&sys->err, PSYS_ERR_INVALID, "mouse spring path needs at least one frame");
    for (size_t k = 0; k < count; k++) {
        for (size_t c = 0; c < stride; c++)
            if (!isfinite(frames[k * stride + c]))
                return psys__fail(&sys->err, PSYS_ERR_INVALID, "mouse spring path frame %zu is not finite", k);
        if (k > 0 && !(frames[k * stride] > frames[(k - 1) * stride]))
            return psys__fail(&sys->err, PSYS_ERR_INVALID, "mouse spring path times must increase (frame %zu)", k);
    }
    double *copy = psys__calloc(count * stride, sizeof(double));
    if (!copy)
        return psys__fail(&sys->err, PSYS_ERR_NOMEM, "out of memory setting a mouse path");
    memcpy(copy, frames, count * stride * sizeof(double));
    free(m->path.frames);
    m->path.frames = copy;
    m->path.nframes = count;
    return PSYS_OK;
}

psys_status psys_system_remove_force(psys_system *sys, size_t i)
{
    if (i >= sys->nforces)
        return psys__fail(&sys->err, PSYS_ERR_INVALID, "no force %zu", i);
    psys__force f = sys->forces[i];
    if (f.data == sys->springs)
        sys->springs = NULL;
    memmove(sys->forces + i, sys->forces + i + 1, (sys->nforces - i - 1) * sizeof *sys->forces);
    sys->nforces--;
    if (f.cls->destroy)
        f.cls->destroy(f.data);
    return PSYS_OK;
}
