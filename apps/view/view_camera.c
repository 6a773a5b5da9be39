/* Viewer cameras: 2-D orthographic pan/zoom, 3-D perspective orbit (y up),
 * projection to window pixels and back onto a view plane (picking). */
#include "view_internal.h"

#include <math.h>
#include <string.h>

static const double PI = 3.14159265358979323846;

static double dot3(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static void norm3(double *a)
{
    double n = sqrt(dot3(a, a));
    if (n > 0)
        for (int k = 0; k < 3; k++)
            a[k] /= n;
}

void vw_camera_init(vw_camera *c, int dim, int width, int height)
{
    memset(c, 0, sizeof *c);
    c->dim = dim;
    c->width = width > 0 ? width : 1;
    c->height = height > 0 ? height : 1;
    c->ppu = c->height / 4.0; /* 4 scene units high */
    c->az = 30 * PI / 180;
    c->el = 20 * PI / 180;
    c->fov = 35 * PI / 180;
    c->dist = 5;
    vw_camera_update(c);
}

void vw_camera_resize(vw_camera *c, int width, int height)
{
    c->width = width > 0 ? width : 1;
    c->height = height > 0 ? height : 1;
    vw_camera_update(c);
}

void vw_camera_update(vw_camera *c)
{
    float *m = c->view_proj;
    memset(m, 0, 16 * sizeof *m);
    double w = c->width, h = c->height;
    if (c->dim == 2) {
        /* clip = ((x - cx)·ppu·2/w, (y - cy)·ppu·2/h, 0, 1) */
        double sx = 2 * c->ppu / w, sy = 2 * c->ppu / h;
        m[0] = (float)sx;
        m[5] = (float)sy;
        m[10] = 1.0f;
        m[12] = (float)(-c->center[0] * sx);
        m[13] = (float)(-c->center[1] * sy);
        m[15] = 1.0f;
        c->r[0] = 1, c->u[1] = 1, c->f[2] = -1;
        return;
    }
    double ce = cos(c->el), se = sin(c->el);
    double offs[3] = {ce * sin(c->az), se, ce * cos(c->az)};
    for (int k = 0; k < 3; k++) {
        c->eye[k] = c->center[k] + c->dist * offs[k];
        c->f[k] = -offs[k];
    }
    norm3(c->f);
    double up[3] = {0, 1, 0};
    /* r = f × up, u = r × f */
    c->r[0] = c->f[1] * up[2] - c->f[2] * up[1];
    c->r[1] = c->f[2] * up[0] - c->f[0] * up[2];
    c->r[2] = c->f[0] * up[1] - c->f[1] * up[0];
    norm3(c->r);
    c->u[0] = c->r[1] * c->f[2] - c->r[2] * c->f[1];
    c->u[1] = c->r[2] * c->f[0] - c->r[0] * c->f[2];
    c->u[2] = c->r[0] * c->f[1] - c->r[1] * c->f[0];
    double t = tan(c->fov / 2);
    c->focal = (h / 2) / t;
    c->near_z = c->dist * 0.01;
    c->far_z = c->dist * 100 + 100;
    /* view: rows r, u, -f; translation -R·eye. proj: standard perspective. */
    double V[16] = {0};
    for (int k = 0; k < 3; k++) {
        V[k * 4 + 0] = c->r[k];
        V[k * 4 + 1] = c->u[k];
        V[k * 4 + 2] = -c->f[k];
    }
    V[12] = -dot3(c->r, c->eye);
    V[13] = -dot3(c->u, c->eye);
    V[14] = dot3(c->f, c->eye);
    V[15] = 1;
    double fy = 1 / t, fx = fy * h / w, n = c->near_z, fz = c->far_z;
    double P[16] = {0};
    P[0] = fx;
    P[5] = fy;
    P[10] = (fz + n) / (n - fz);
    P[11] = -1;
    P[14] = 2 * fz * n / (n - fz);
    c->proj22 = (float)P[10];
    c->proj32 = (float)P[14];
    for (int col = 0; col < 4; col++)
        for (int row = 0; row < 4; row++) {
            double s = 0;
            for (int k = 0; k < 4; k++)
                s += P[k * 4 + row] * V[col * 4 + k];
            m[col * 4 + row] = (float)s;
        }
}

bool vw_camera_project(const vw_camera *c, const double *p, double *sx, double *sy, double *depth)
{
    if (c->dim == 2) {
        *sx = c->width / 2.0 + (p[0] - c->center[0]) * c->ppu;
        *sy = c->height / 2.0 - (p[1] - c->center[1]) * c->ppu;
        if (depth)
            *depth = 0;
        return true;
    }
    double v[3] = {p[0] - c->eye[0], p[1] - c->eye[1], p[2] - c->eye[2]};
    double z = dot3(v, c->f);
    if (depth)
        *depth = z;
    if (!(z > c->near_z))
        return false;
    *sx = c->width / 2.0 + c->focal * dot3(v, c->r) / z;
    *sy = c->height / 2.0 - c->focal * dot3(v, c->u) / z;
    return true;
}

void vw_camera_unproject(const vw_camera *c, double sx, double sy, const double *through, double *out)
{
    if (c->dim == 2) {
        out[0] = c->center[0] + (sx - c->width / 2.0) / c->ppu;
        out[1] = c->center[1] - (sy - c->height / 2.0) / c->ppu;
        return;
    }
    const double *q = through ? through : c->center;
    double v[3] = {q[0] - c->eye[0], q[1] - c->eye[1], q[2] - c->eye[2]};
    double z = dot3(v, c->f);
    if (!(z > c->near_z))
        z = c->dist;
    double vx = (sx - c->width / 2.0) * z / c->focal, vy = -(sy - c->height / 2.0) * z / c->focal;
    for (int k = 0; k < 3; k++)
        out[k] = c->eye[k] + c->f[k] * z + c->r[k] * vx + c->u[k] * vy;
}

double vw_camera_ppu_at(const vw_camera *c, const double *p)
{
    if (c->dim == 2)
        return c->ppu;
    double v[3] = {p[0] - c->eye[0], p[1] - c->eye[1], p[2] - c->eye[2]};
    double z = dot3(v, c->f);
    return z > c->near_z ? c->focal / z : c->focal / c->near_z;
}

void vw_camera_frame(vw_camera *c, const double *lo, const double *hi)
{
    if (c->dim == 2) {
        double dx = hi[0] - lo[0], dy = hi[1] - lo[1];
        c->center[0] = (lo[0] + hi[0]) / 2;
        c->center[1] = (lo[1] + hi[1]) / 2;
        double sx = dx > 0 ? c->width / (dx * 1.25) : INFINITY;
        double sy = dy > 0 ? c->height / (dy * 1.25) : INFINITY;
        double s = fmin(sx, sy);
        if (isfinite(s) && s > 0)
            c->ppu = s;
        vw_camera_update(c);
        return;
    }
    double r2 = 0;
    for (int k = 0; k < 3; k++) {
        c->center[k] = (lo[k] + hi[k]) / 2;
        r2 += (hi[k] - lo[k]) * (hi[k] - lo[k]) / 4;
    }
    double R = sqrt(r2);
    if (!(R > 0))
        R = 1;
    double half = c->fov / 2;
    if (c->width < c->height)
        half = atan(tan(half) * c->width / c->height);
    c->dist = R / sin(half) * 1.05;
    vw_camera_update(c);
}

void vw_camera_zoom(vw_camera *c, double factor, double sx, double sy)
{
    if (!(factor > 0))
        return;
    if (c->dim == 2) {
        double before[2], after[2];
        vw_camera_unproject(c, sx, sy, NULL, before);
        c->ppu *= factor;
        if (c->ppu < 1e-9)
            c->ppu = 1e-9;
        if (c->ppu > 1e12)
            c->ppu = 1e12;
        vw_camera_update(c);
        vw_camera_unproject(c, sx, sy, NULL, after);
        c->center[0] += before[0] - after[0];
        c->center[1] += before[1] - after[1];
    } else {
        c->dist /= factor;
        if (c->dist < 1e-6)
            c->dist = 1e-6;
    }
    vw_camera_update(c);
}

void vw_camera_pan(vw_camera *c, double dx, double dy)
{
    if (c->dim == 2) {
        c->center[0] -= dx / c->ppu;
        c->center[1] += dy / c->ppu;
    } else {
        double s = c->dist / c->focal; /* scene units per pixel at the center */
        for (int k = 0; k < 3; k++)
            c->center[k] += (-dx * c->r[k] + dy * c->u[k]) * s;
    }
    vw_camera_update(c);
}

void vw_camera_orbit(vw_camera *c, double dx, double dy)
{
    if (c->dim != 3)
        return;
    c->az -= dx * 0.006;
    c->el += dy * 0.006;
    double lim = 89 * PI / 180;
    if (c->el > lim)
        c->el = lim;
    if (c->el < -lim)
        c->el = -lim;
    vw_camera_update(c);
}
