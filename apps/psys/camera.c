/* Camera for headless pictures: the --camera option, framing and projection
 * (docs/cli.md "Camera"). Pure geometry: no cairo here. */
#include "render.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

static const double DEG = 3.14159265358979323846 / 180.0;
/* Room around the framed bounds: 5% of the picture on each side. */
static const double MARGIN = 1.1;
/* Automatic framing keeps 7% of the height free at the top (time stamp,
 * strain bar) and 5% at the bottom (legend). */
static const double FIT_TOP = 0.07, FIT_BOTTOM = 0.05;

void camera_spec_default(camera_spec *s, int dim)
{
    memset(s, 0, sizeof *s);
    s->dim = dim;
    s->perspective = dim == 3;
    s->az = dim == 3 ? 30 : 0;
    s->el = dim == 3 ? 20 : 0;
    s->fov = 35;
    s->up = 1;
    s->zoom = 1;
}

static int num(const char *s, double *out)
{
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (end == s || *end || errno || !isfinite(v) || strpbrk(s, "xX") || isspace((unsigned char)*s)) /* decimal only */
        return -1;
    *out = v;
    return 0;
}

/* One item of the spec, a NUL-terminated word. */
static int parse_item(char *item, camera_spec *s, char *why, size_t cap)
{
    char *eq = strchr(item, '=');
    const char *val = eq ? eq + 1 : NULL;
    if (eq)
        *eq = '\0';
    const char *key = item;
    double v;
    if (!eq && (strcmp(key, "ortho") == 0 || strcmp(key, "orthographic") == 0)) {
        s->perspective = false;
        return 0;
    }
    if (!eq && (strcmp(key, "perspective") == 0 || strcmp(key, "persp") == 0)) {
        if (s->dim != 3) {
            snprintf(why, cap, "%s is only for 3-D scenes", key);
            return -1;
        }
        s->perspective = true;
        return 0;
    }
    bool only3 = strcmp(key, "az") == 0 || strcmp(key, "el") == 0 || strcmp(key, "fov") == 0
                 || strcmp(key, "up") == 0;
    bool known = only3 || strcmp(key, "center") == 0 || strcmp(key, "extent") == 0 || strcmp(key, "zoom") == 0
                 || strcmp(key, "fit") == 0;
    if (!known || !eq) {
        snprintf(why, cap,
                 "unknown item \"%s\" (known: ortho, perspective, az=DEG, el=DEG, fov=DEG, up=x|y|z, "
                 "center=X:Y[:Z], extent=L, zoom=F, fit=run|start)",
                 key);
        return -1;
    }
    if (only3 && s->dim != 3) {
        snprintf(why, cap, "%s= is only for 3-D scenes", key);
        return -1;
    }
    if (strcmp(key, "az") == 0) {
        if (num(val, &v) != 0) {
            snprintf(why, cap, "az= must be a number of degrees (got %s)", val);
            return -1;
        }
        s->az = v;
    } else if (strcmp(key, "el") == 0) {
        if (num(val, &v) != 0 || v < -90 || v > 90) {
            snprintf(why, cap, "el= must be a number of degrees from -90 to 90 (got %s)", val);
            return -1;
        }
        s->el = v;
    } else if (strcmp(key, "fov") == 0) {
        if (num(val, &v) != 0 || v < 1 || v > 170) {
            snprintf(why, cap, "fov= must be a number of degrees from 1 to 170 (got %s)", val);
            return -1;
        }
        s->fov = v;
    } else if (strcmp(key, "up") == 0) {
        if (strcmp(val, "x") != 0 && strcmp(val, "y") != 0 && strcmp(val, "z") != 0) {
            snprintf(why, cap, "up= must be x, y or z (got %s)", val);
            return -1;
        }
        s->up = val[0] - 'x';
    } else if (strcmp(key, "center") == 0) {
        char buf[256];
        snprintf(buf, sizeof buf, "%s", val);
        int k = 0;
        bool bad = strlen(val) >= sizeof buf;
        for (char *p = buf, *tok; !bad && (tok = strsep(&p, ":")) != NULL; k++)
            bad = k >= s->dim || num(tok, &s->center[k]) != 0;
        if (bad || k != s->dim) {
            snprintf(why, cap, "center= must be %d numbers separated by colons, e.g. %s (got %s)", s->dim,
                     s->dim == 3 ? "0:1.5:0" : "0:1.5", val);
            return -1;
        }
        s->has_center = true;
    } else if (strcmp(key, "extent") == 0) {
        if (num(val, &v) != 0 || !(v > 0)) {
            snprintf(why, cap, "extent= must be a number > 0 (got %s)", val);
            return -1;
        }
        s->extent = v;
    } else if (strcmp(key, "zoom") == 0) {
        if (num(val, &v) != 0 || !(v > 0) || v > 1e6) {
            snprintf(why, cap, "zoom= must be a number > 0 and at most 1e6 (got %s)", val);
            return -1;
        }
        s->zoom = v;
    } else { /* fit */
        if (strcmp(val, "run") != 0 && strcmp(val, "start") != 0) {
            snprintf(why, cap, "fit= must be run or start (got %s)", val);
            return -1;
        }
        s->fit_start = strcmp(val, "start") == 0;
    }
    return 0;
}

int camera_spec_parse(const char *text, camera_spec *s, char *why, size_t cap)
{
    size_t len = strlen(text);
    if (len == 0 || len > 1000) {
        snprintf(why, cap, "must be a comma-separated list such as \"perspective,az=30,el=20\" (got \"%s\")",
                 len ? "..." : "");
        return -1;
    }
    char *copy = malloc(len + 1);
    if (!copy) {
        snprintf(why, cap, "out of memory");
        return -1;
    }
    memcpy(copy, text, len + 1);
    int rc = 0;
    for (char *p = copy, *item; rc == 0 && (item = strsep(&p, ",")) != NULL;) {
        if (!*item) {
            snprintf(why, cap, "empty item in \"%s\"", text);
            rc = -1;
        } else {
            rc = parse_item(item, s, why, cap);
        }
    }
    free(copy);
    return rc;
}

bool camera_needs_bounds(const camera_spec *s) { return !(s->has_center && s->extent > 0); }

bool camera_needs_run_bounds(const camera_spec *s) { return camera_needs_bounds(s) && !s->fit_start; }

static double dot(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* The view's right, up and forward (into the picture) axes for spec. */
static void orient(const camera_spec *s, double r[3], double u[3], double f[3])
{
    if (s->dim == 2) {
        r[0] = 1, r[1] = 0, r[2] = 0;
        u[0] = 0, u[1] = 1, u[2] = 0;
        f[0] = 0, f[1] = 0, f[2] = -1;
        return;
    }
    /* Basis (e1, e2 = up, e3), a cyclic permutation of (x, y, z) so it stays right-handed. */
    double e[3][3] = {{0}};
    for (int i = 0; i < 3; i++)
        e[i][(s->up + 2 + i) % 3] = 1;
    double az = s->az * DEG, el = s->el * DEG;
    for (int k = 0; k < 3; k++) {
        /* From the center toward the eye: d = cos(el) sin(az) e1 + sin(el) e2 + cos(el) cos(az) e3. */
        double d = cos(el) * sin(az) * e[0][k] + sin(el) * e[1][k] + cos(el) * cos(az) * e[2][k];
        f[k] = -d;
        r[k] = cos(az) * e[0][k] - sin(az) * e[2][k];
    }
    /* u = r × f */
    u[0] = r[1] * f[2] - r[2] * f[1];
    u[1] = r[2] * f[0] - r[0] * f[2];
    u[2] = r[0] * f[1] - r[1] * f[0];
}

void bounds_init(bounds *b, const camera_spec *spec, int width, int height)
{
    memset(b, 0, sizeof *b);
    b->dim = spec->dim;
    orient(spec, b->axis[0], b->axis[1], b->axis[2]);
    double tv = tan(0.5 * spec->fov * DEG);
    b->ky = MARGIN / (tv * (1 - FIT_TOP - FIT_BOTTOM));
    b->kx = MARGIN / (tv * width / height);
}

void bounds_add_system(bounds *b, const psys_system *sys)
{
    size_t n = psys_system_count(sys);
    int d = psys_system_dim(sys);
    const double *x = psys_system_positions(sys);
    for (size_t i = 0; i < n; i++) {
        const double *p = x + i * (size_t)d;
        double v[3];
        for (int a = 0; a < 3; a++)
            v[a] = b->axis[a][0] * p[0] + b->axis[a][1] * p[1] + (d == 3 ? b->axis[a][2] * p[2] : 0.0);
        if (!isfinite(v[0]) || !isfinite(v[1]) || !isfinite(v[2]))
            continue;
        double am[4] = {b->kx * v[0] - v[2], -b->kx * v[0] - v[2], b->ky * v[1] - v[2], -b->ky * v[1] - v[2]};
        for (int a = 0; a < 3; a++) {
            if (!b->any || v[a] < b->lo[a])
                b->lo[a] = v[a];
            if (!b->any || v[a] > b->hi[a])
                b->hi[a] = v[a];
        }
        for (int a = 0; a < 4; a++)
            if (!b->any || am[a] > b->amax[a])
                b->amax[a] = am[a];
        b->any = true;
    }
}

void camera_view(const camera *cam, const double *p, double v[3])
{
    double q[3] = {p[0] - cam->c[0], p[1] - cam->c[1], p[2] - cam->c[2]};
    v[0] = dot(q, cam->r);
    v[1] = dot(q, cam->u);
    v[2] = dot(q, cam->f);
}

double camera_near(const camera *cam) { return cam->perspective ? 1e-3 * cam->dist : -INFINITY; }

bool camera_pixel(const camera *cam, const double v[3], double *px, double *py, double *ppu)
{
    double k = cam->scale;
    if (cam->perspective) {
        double depth = cam->dist + v[2];
        if (!(depth >= camera_near(cam)))
            return false;
        k = cam->scale / depth;
    }
    *px = 0.5 * cam->width + v[0] * k;
    *py = cam->cy - v[1] * k;
    if (ppu)
        *ppu = k;
    return true;
}

void camera_setup(camera *cam, const camera_spec *s, int width, int height, const bounds *b)
{
    memset(cam, 0, sizeof *cam);
    cam->width = width;
    cam->height = height;
    cam->perspective = s->perspective && s->dim == 3;
    orient(s, cam->r, cam->u, cam->f);
    /* The bounds along the view axes; the center in view coordinates. */
    double lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0}, cv[3];
    if (b && b->any) {
        memcpy(lo, b->lo, sizeof lo);
        memcpy(hi, b->hi, sizeof hi);
    }
    bool fit = b && b->any && b->kx > 0;
    if (s->has_center) {
        double c[3] = {s->center[0], s->center[1], s->dim == 3 ? s->center[2] : 0.0};
        for (int a = 0; a < 3; a++)
            cv[a] = dot(c, a == 0 ? cam->r : a == 1 ? cam->u : cam->f);
    } else {
        for (int a = 0; a < 3; a++)
            cv[a] = 0.5 * (lo[a] + hi[a]);
        if (cam->perspective && fit) {
            /* The center that balances left against right and top against bottom in perspective. */
            cv[0] = (b->amax[0] - b->amax[1]) / (2 * b->kx);
            cv[1] = (b->amax[2] - b->amax[3]) / (2 * b->ky);
        }
    }
    for (int k = 0; k < 3; k++)
        cam->c[k] = cv[0] * cam->r[k] + cv[1] * cam->u[k] + cv[2] * cam->f[k];
    if (s->dim == 2)
        cam->c[2] = 0;
    double size = 0;
    for (int a = 0; a < 3; a++)
        size = fmax(size, hi[a] - lo[a]);
    /* Automatic framing fits a band of the picture clear of the overlays. */
    bool auto_fit = !(s->extent > 0);
    double band = auto_fit ? 1 - FIT_TOP - FIT_BOTTOM : 1.0;
    cam->cy = height * (auto_fit ? FIT_TOP + 0.5 * band : 0.5);
    double aspect = (double)width / (height * band);
    double tv = tan(0.5 * s->fov * DEG) * band, th = tan(0.5 * s->fov * DEG) * width / height;
    double E = s->extent;
    double D = 0;
    if (!(E > 0)) {
        /* Fit the 8 corners of the view-aligned box. */
        double hx = 0, hy = 0, need = 0, zmin = 0;
        for (int m = 0; m < 8; m++) {
            double v[3] = {(m & 1 ? hi[0] : lo[0]) - cv[0], (m & 2 ? hi[1] : lo[1]) - cv[1],
                           (m & 4 ? hi[2] : lo[2]) - cv[2]};
            hx = fmax(hx, fabs(v[0]));
            hy = fmax(hy, fabs(v[1]));
            double dm = fmax(MARGIN * fabs(v[0]) / th, MARGIN * fabs(v[1]) / tv) - v[2];
            need = m == 0 ? dm : fmax(need, dm);
            zmin = m == 0 ? v[2] : fmin(zmin, v[2]);
        }
        if (cam->perspective && fit) {
            /* Exact for the points seen: D >= margin·|x - cx|/tan - (z - cz) for every point. */
            need = fmax(fmax(b->amax[0] - b->kx * cv[0], b->amax[1] + b->kx * cv[0]),
                        fmax(b->amax[2] - b->ky * cv[1], b->amax[3] + b->ky * cv[1]))
                   + cv[2];
        }
        if (cam->perspective) {
            D = fmax(need, -zmin + 0.05 * size);
            if (!(D > 1e-12 * fmax(1.0, size)))
                D = 1.0 / tv; /* nothing to frame: a view 2 units high */
            E = 2 * D * tv;
        } else {
            E = MARGIN * fmax(2 * hy, 2 * hx / aspect);
            if (!(E > 1e-12 * fmax(1.0, fabs(cv[0]) + fabs(cv[1]))))
                E = 2.0;
        }
    } else if (cam->perspective) {
        D = 0.5 * E / tan(0.5 * s->fov * DEG);
    }
    /* E is the height of the band fitted (the whole picture for an explicit extent). */
    cam->extent = E / band / s->zoom;
    if (cam->perspective) {
        cam->dist = D;
        cam->scale = 0.5 * height / tan(0.5 * s->fov * DEG) * s->zoom;
    } else {
        cam->scale = height * band / E * s->zoom;
    }
}

int parse_size(const char *s, int *w, int *h)
{
    char *end;
    errno = 0;
    long a = strtol(s, &end, 10);
    if (end == s || (*end != 'x' && *end != 'X') || errno || a < 16 || a > 8192 || s[0] < '0' || s[0] > '9')
        return -1;
    const char *t = end + 1;
    long b = strtol(t, &end, 10);
    if (end == t || *end || errno || b < 16 || b > 8192 || t[0] < '0' || t[0] > '9')
        return -1;
    *w = (int)a;
    *h = (int)b;
    return 0;
}
