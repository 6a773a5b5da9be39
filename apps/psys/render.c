/* The cairo implementation of psys_draw: one anti-aliased picture of a
 * system per call (docs/cli.md "What a picture shows"). psys_system_draw
 * hands over planes, springs and particles; they are gathered, projected
 * through the camera, ordered far to near in 3-D, and painted with a time
 * stamp and, where they help, a legend and a strain colour bar. */
#include "render.h"

#include <cairo.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* fontconfig (behind cairo's text) keeps allocations it never frees; under
 * AddressSanitizer, LeakSanitizer must not blame psys for them. */
#if defined(__SANITIZE_ADDRESS__)
#define PSYS_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define PSYS_ASAN 1
#endif
#endif
#ifdef PSYS_ASAN
const char *__lsan_default_suppressions(void);
const char *__lsan_default_suppressions(void) { return "leak:libfontconfig\n"; }
const char *__lsan_default_options(void);
const char *__lsan_default_options(void) { return "print_suppressions=0"; }
#endif

/* Strain at which a spring's colour is fully red (stretched) or blue (compressed). */
#define STRAIN_FULL 0.05

typedef struct r_particle {
    double px, py, depth, rad;
    unsigned flags;
} r_particle;

typedef struct r_spring {
    double x0, y0, x1, y1, depth, strain;
    int link; /* a behaviour-function link, not a spring */
} r_spring;

typedef struct r_guide {
    double p[3], n[3], radius; /* plane (radius < 0) or sphere */
} r_guide;

typedef struct r_plane {
    double p[3], n[3];
} r_plane;

struct renderer {
    int width, height;
    camera cam;
    double radius;
    cairo_surface_t *surface;
    cairo_t *cr;
    int dim;
    double t;
    r_particle *parts;
    size_t nparts, parts_cap;
    r_spring *springs;
    size_t nsprings, springs_cap;
    r_plane *planes;
    size_t nplanes, planes_cap;
    r_guide *guides;
    size_t nguides, guides_cap;
    size_t nlinks;
    bool oom;
    unsigned kinds; /* particle flags seen: bit 0 free, then PSYS_PARTICLE_* << 1 */
};

static bool grow(void **p, size_t *cap, size_t need, size_t elem)
{
    if (need <= *cap)
        return true;
    size_t nc = *cap ? *cap : 64;
    while (nc < need)
        nc *= 2;
    if (nc > SIZE_MAX / elem)
        return false;
    void *q = realloc(*p, nc * elem);
    if (!q)
        return false;
    *p = q;
    *cap = nc;
    return true;
}

renderer *renderer_create(int width, int height, const camera *cam, double radius)
{
    renderer *r = calloc(1, sizeof *r);
    if (!r)
        return NULL;
    r->width = width;
    r->height = height;
    r->cam = *cam;
    r->radius = radius;
    r->surface = cairo_image_surface_create(CAIRO_FORMAT_ARGB32, width, height);
    if (cairo_surface_status(r->surface) != CAIRO_STATUS_SUCCESS) {
        cairo_surface_destroy(r->surface);
        free(r);
        return NULL;
    }
    r->cr = cairo_create(r->surface);
    if (cairo_status(r->cr) != CAIRO_STATUS_SUCCESS) {
        renderer_destroy(r);
        return NULL;
    }
    return r;
}

void renderer_destroy(renderer *r)
{
    if (!r)
        return;
    if (r->cr)
        cairo_destroy(r->cr);
    cairo_surface_destroy(r->surface);
    free(r->parts);
    free(r->springs);
    free(r->planes);
    free(r->guides);
    free(r);
}

/* World point (dim numbers) as 3 numbers. */
static void to3(const renderer *r, const double *x, double p[3])
{
    p[0] = x[0];
    p[1] = x[1];
    p[2] = r->dim == 3 ? x[2] : 0.0;
}

/* ---------------------------------------------------------------- callbacks */

static void cb_begin(void *ctx, int dim, double t)
{
    renderer *r = ctx;
    r->dim = dim;
    r->t = t;
    r->nparts = r->nsprings = r->nplanes = r->nguides = r->nlinks = 0;
    r->kinds = 0;
}

static void cb_plane(void *ctx, const double *point, const double *normal)
{
    renderer *r = ctx;
    if (!grow((void **)&r->planes, &r->planes_cap, r->nplanes + 1, sizeof *r->planes)) {
        r->oom = true;
        return;
    }
    r_plane *pl = &r->planes[r->nplanes++];
    to3(r, point, pl->p);
    to3(r, normal, pl->n);
}

/* The near plane in view coordinates (a little inside camera_near, so
 * clipped points pass camera_pixel despite rounding). */
static double view_near(const renderer *r)
{
    return r->cam.perspective ? 1.01 * camera_near(&r->cam) - r->cam.dist : -INFINITY;
}

/* Clip the view-space segment a-b to depth >= near; false if nothing is left. */
static bool clip_near(double a[3], double b[3], double near)
{
    bool ina = a[2] >= near, inb = b[2] >= near;
    if (ina && inb)
        return true;
    if (!ina && !inb)
        return false;
    double *out = ina ? b : a, *in = ina ? a : b;
    double s = (near - in[2]) / (out[2] - in[2]);
    for (int k = 0; k < 3; k++)
        out[k] = in[k] + s * (out[k] - in[k]);
    out[2] = near;
    return true;
}

static void cb_guide(void *ctx, const double *point, const double *normal, double radius)
{
    renderer *r = ctx;
    if (!grow((void **)&r->guides, &r->guides_cap, r->nguides + 1, sizeof *r->guides)) {
        r->oom = true;
        return;
    }
    r_guide *g = &r->guides[r->nguides++];
    to3(r, point, g->p);
    if (normal)
        to3(r, normal, g->n);
    else
        g->n[0] = g->n[1] = g->n[2] = 0;
    g->radius = normal ? -1.0 : radius;
}

static void add_segment(renderer *r, const double *a, const double *b, double strain, int link)
{
    double pa[3], pb[3], va[3], vb[3];
    to3(r, a, pa);
    to3(r, b, pb);
    camera_view(&r->cam, pa, va);
    camera_view(&r->cam, pb, vb);
    if (r->cam.perspective) {
        if (!clip_near(va, vb, view_near(r)))
            return;
    }
    r_spring s;
    if (!camera_pixel(&r->cam, va, &s.x0, &s.y0, NULL) || !camera_pixel(&r->cam, vb, &s.x1, &s.y1, NULL))
        return;
    if (!isfinite(s.x0 + s.y0 + s.x1 + s.y1))
        return;
    s.depth = 0.5 * (va[2] + vb[2]);
    s.strain = strain;
    s.link = link;
    if (!grow((void **)&r->springs, &r->springs_cap, r->nsprings + 1, sizeof *r->springs)) {
        r->oom = true;
        return;
    }
    r->springs[r->nsprings++] = s;
    r->nlinks += link != 0;
}

static void cb_spring(void *ctx, const double *a, const double *b, double strain)
{
    add_segment(ctx, a, b, strain, 0);
}

static void cb_link(void *ctx, const double *a, const double *b) { add_segment(ctx, a, b, 0.0, 1); }

static void cb_particle(void *ctx, size_t i, const double *x, double radius, unsigned flags)
{
    (void)i;
    renderer *r = ctx;
    r->kinds |= flags ? (flags << 1) : 1u;
    double p[3], v[3], ppu;
    to3(r, x, p);
    camera_view(&r->cam, p, v);
    r_particle q;
    if (!camera_pixel(&r->cam, v, &q.px, &q.py, &ppu))
        return;
    q.rad = fmax(1.5, radius * ppu);
    if (!isfinite(q.px + q.py + q.rad) || q.px < -q.rad - 1 || q.py < -q.rad - 1 || q.px > r->width + q.rad + 1
        || q.py > r->height + q.rad + 1)
        return;
    q.depth = v[2];
    q.flags = flags;
    if (!grow((void **)&r->parts, &r->parts_cap, r->nparts + 1, sizeof *r->parts)) {
        r->oom = true;
        return;
    }
    r->parts[r->nparts++] = q;
}

/* ---------------------------------------------------------------- painting */

static double ui_scale(const renderer *r) { return fmax(0.6, r->height / 600.0); }

static void set_rgb(cairo_t *cr, int r, int g, int b) { cairo_set_source_rgb(cr, r / 255.0, g / 255.0, b / 255.0); }

/* Spring colours are drawn in 2·STRAIN_LEVELS + 1 steps from -STRAIN_FULL to +STRAIN_FULL. */
#define STRAIN_LEVELS 16

/* 0 .. 2·STRAIN_LEVELS: the colour step of a strain (by the colour's own curve, so steps look even). */
static int strain_level(double strain)
{
    double v = strain / STRAIN_FULL;
    if (!isfinite(v))
        v = 0;
    v = v > 1 ? 1 : v < -1 ? -1 : v;
    double a = sqrt(fabs(v)); /* strain_rgb's blend */
    int k = (int)lround(a * STRAIN_LEVELS);
    return STRAIN_LEVELS + (v < 0 ? -k : k);
}

/* Spring colour: grey at rest, toward red when stretched, blue when compressed
 * (square root, so small strains of stiff springs still show). */
static void strain_rgb(double strain, double rgb[3])
{
    static const double grey[3] = {0.60, 0.60, 0.60}, red[3] = {0.84, 0.15, 0.16}, blue[3] = {0.12, 0.40, 0.80};
    double v = strain / STRAIN_FULL;
    if (!isfinite(v))
        v = 0;
    v = v > 1 ? 1 : v < -1 ? -1 : v;
    double a = sqrt(fabs(v));
    const double *to = v >= 0 ? red : blue;
    for (int k = 0; k < 3; k++)
        rgb[k] = grey[k] + a * (to[k] - grey[k]);
}

static void paint_plane_2d(renderer *r, const r_plane *pl)
{
    cairo_t *cr = r->cr;
    double v0[3], v1[3], v2[3], p1[3], p2[3];
    double t[3] = {-pl->n[1], pl->n[0], 0};
    for (int k = 0; k < 3; k++) {
        p1[k] = pl->p[k] + t[k];
        p2[k] = pl->p[k] + pl->n[k];
    }
    camera_view(&r->cam, pl->p, v0);
    camera_view(&r->cam, p1, v1);
    camera_view(&r->cam, p2, v2);
    double x0, y0, x1, y1, x2, y2;
    if (!camera_pixel(&r->cam, v0, &x0, &y0, NULL) || !camera_pixel(&r->cam, v1, &x1, &y1, NULL)
        || !camera_pixel(&r->cam, v2, &x2, &y2, NULL))
        return;
    double tx = x1 - x0, ty = y1 - y0, nx = x2 - x0, ny = y2 - y0;
    double tl = hypot(tx, ty), nl = hypot(nx, ny);
    if (!(tl > 0) || !(nl > 0) || !isfinite(x0 + y0))
        return;
    tx /= tl;
    ty /= tl;
    nx /= nl;
    ny /= nl;
    /* Move the anchor to the point of the line nearest the picture's centre, so
     * the big polygon stays within numbers cairo handles exactly. */
    double cx = 0.5 * r->width, cy = 0.5 * r->height;
    double s = (cx - x0) * tx + (cy - y0) * ty;
    x0 += s * tx;
    y0 += s * ty;
    double L = 4.0 * (r->width + r->height);
    cairo_move_to(cr, x0 - L * tx, y0 - L * ty);
    cairo_line_to(cr, x0 + L * tx, y0 + L * ty);
    cairo_line_to(cr, x0 + L * tx - L * nx, y0 + L * ty - L * ny);
    cairo_line_to(cr, x0 - L * tx - L * nx, y0 - L * ty - L * ny);
    cairo_close_path(cr);
    cairo_set_source_rgba(cr, 0.55, 0.53, 0.50, 0.22);
    cairo_fill(cr);
    cairo_move_to(cr, x0 - L * tx, y0 - L * ty);
    cairo_line_to(cr, x0 + L * tx, y0 + L * ty);
    set_rgb(cr, 90, 88, 84);
    cairo_set_line_width(cr, 1.5 * ui_scale(r));
    cairo_stroke(cr);
}

/* A view-space polygon clipped to the near plane (Sutherland–Hodgman), traced as a path. */
static void trace_polygon(renderer *r, double (*v)[3], int n)
{
    double near = view_near(r);
    double out[16][3];
    int m = 0;
    for (int i = 0; i < n && m < 14; i++) {
        const double *a = v[i], *b = v[(i + 1) % n];
        bool ina = a[2] >= near, inb = b[2] >= near;
        if (ina)
            memcpy(out[m++], a, sizeof out[0]);
        if (ina != inb) {
            double s = (near - a[2]) / (b[2] - a[2]);
            for (int k = 0; k < 3; k++)
                out[m][k] = a[k] + s * (b[k] - a[k]);
            out[m++][2] = near;
        }
    }
    for (int i = 0; i < m; i++) {
        double px, py;
        if (!camera_pixel(&r->cam, out[i], &px, &py, NULL))
            continue;
        if (i == 0)
            cairo_move_to(r->cr, px, py);
        else
            cairo_line_to(r->cr, px, py);
    }
    if (m)
        cairo_close_path(r->cr);
}

static void paint_plane_3d(renderer *r, const r_plane *pl)
{
    cairo_t *cr = r->cr;
    const double *n = pl->n;
    /* Patch centred where the view's centre projects onto the plane, 1.5 views wide. */
    double d = (r->cam.c[0] - pl->p[0]) * n[0] + (r->cam.c[1] - pl->p[1]) * n[1] + (r->cam.c[2] - pl->p[2]) * n[2];
    double pc[3], t1[3], t2[3];
    for (int k = 0; k < 3; k++)
        pc[k] = r->cam.c[k] - d * n[k];
    double rn = r->cam.r[0] * n[0] + r->cam.r[1] * n[1] + r->cam.r[2] * n[2];
    for (int k = 0; k < 3; k++)
        t1[k] = r->cam.r[k] - rn * n[k];
    double l = sqrt(t1[0] * t1[0] + t1[1] * t1[1] + t1[2] * t1[2]);
    if (l < 1e-6) {
        double un = r->cam.u[0] * n[0] + r->cam.u[1] * n[1] + r->cam.u[2] * n[2];
        for (int k = 0; k < 3; k++)
            t1[k] = r->cam.u[k] - un * n[k];
        l = sqrt(t1[0] * t1[0] + t1[1] * t1[1] + t1[2] * t1[2]);
    }
    if (!(l > 0))
        return;
    for (int k = 0; k < 3; k++)
        t1[k] /= l;
    t2[0] = n[1] * t1[2] - n[2] * t1[1];
    t2[1] = n[2] * t1[0] - n[0] * t1[2];
    t2[2] = n[0] * t1[1] - n[1] * t1[0];
    double S = 0.75 * r->cam.extent;
    const int cells = 8;
    double quad[4][3];
    static const int sg[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
    for (int c = 0; c < 4; c++) {
        double p[3];
        for (int k = 0; k < 3; k++)
            p[k] = pc[k] + S * (sg[c][0] * t1[k] + sg[c][1] * t2[k]);
        camera_view(&r->cam, p, quad[c]);
    }
    trace_polygon(r, quad, 4);
    cairo_set_source_rgba(cr, 0.55, 0.53, 0.50, 0.18);
    cairo_fill(cr);
    double near = view_near(r);
    cairo_set_line_width(cr, 0.8 * ui_scale(r));
    cairo_set_source_rgba(cr, 0.35, 0.34, 0.32, 0.45);
    for (int dir = 0; dir < 2; dir++)
        for (int i = 0; i <= cells; i++) {
            double s = -S + 2 * S * i / cells, a[3], b[3], va[3], vb[3];
            for (int k = 0; k < 3; k++) {
                const double *ta = dir ? t2 : t1, *tb = dir ? t1 : t2;
                a[k] = pc[k] + s * ta[k] - S * tb[k];
                b[k] = pc[k] + s * ta[k] + S * tb[k];
            }
            camera_view(&r->cam, a, va);
            camera_view(&r->cam, b, vb);
            double x0, y0, x1, y1;
            if (!clip_near(va, vb, near) || !camera_pixel(&r->cam, va, &x0, &y0, NULL)
                || !camera_pixel(&r->cam, vb, &x1, &y1, NULL))
                continue;
            cairo_move_to(cr, x0, y0);
            cairo_line_to(cr, x1, y1);
        }
    cairo_stroke(cr);
}

/* A behaviour's guide, dashed: a line (2-D plane) or a circle (sphere seen about its center). */
static void paint_guide(renderer *r, const r_guide *g)
{
    cairo_t *cr = r->cr;
    double ui = ui_scale(r);
    double dash[2] = {6 * ui, 4 * ui};
    double v[3], px, py, ppu;
    camera_view(&r->cam, g->p, v);
    if (!camera_pixel(&r->cam, v, &px, &py, &ppu) || !isfinite(px + py))
        return;
    if (g->radius >= 0) {
        double rad = g->radius * ppu;
        if (!(rad > 0.5) || rad > 1e5)
            return;
        cairo_new_sub_path(cr);
        cairo_arc(cr, px, py, rad, 0, 2 * 3.14159265358979323846);
    } else {
        if (r->dim != 2)
            return;
        double t[3] = {-g->n[1], g->n[0], 0}, q[3], vq[3], qx, qy;
        for (int k = 0; k < 3; k++)
            q[k] = g->p[k] + t[k];
        camera_view(&r->cam, q, vq);
        if (!camera_pixel(&r->cam, vq, &qx, &qy, NULL))
            return;
        double tx = qx - px, ty = qy - py, tl = hypot(tx, ty);
        if (!(tl > 0))
            return;
        tx /= tl;
        ty /= tl;
        double s = (0.5 * r->width - px) * tx + (0.5 * r->height - py) * ty, L = 2.0 * (r->width + r->height);
        px += s * tx;
        py += s * ty;
        cairo_move_to(cr, px - L * tx, py - L * ty);
        cairo_line_to(cr, px + L * tx, py + L * ty);
    }
    cairo_save(cr);
    cairo_set_dash(cr, dash, 2, 0);
    cairo_set_line_width(cr, 1.0 * ui);
    cairo_set_source_rgba(cr, 0.16, 0.42, 0.36, 0.7);
    cairo_stroke(cr);
    cairo_restore(cr);
}

static int far_first(const void *a, const void *b)
{
    double da = ((const r_particle *)a)->depth, db = ((const r_particle *)b)->depth;
    return da > db ? -1 : da < db ? 1 : 0;
}

static int far_first_spring(const void *a, const void *b)
{
    double da = ((const r_spring *)a)->depth, db = ((const r_spring *)b)->depth;
    return da > db ? -1 : da < db ? 1 : 0;
}

/* Particle shapes: free = disc, fixed = square, controlled = diamond. */
static void trace_marker(cairo_t *cr, double x, double y, double rad, unsigned flags)
{
    if (flags & PSYS_PARTICLE_FIXED) {
        double h = 0.9 * rad;
        cairo_rectangle(cr, x - h, y - h, 2 * h, 2 * h);
    } else if (flags & PSYS_PARTICLE_CONTROLLED) {
        double h = 1.2 * rad;
        cairo_move_to(cr, x, y - h);
        cairo_line_to(cr, x + h, y);
        cairo_line_to(cr, x, y + h);
        cairo_line_to(cr, x - h, y);
        cairo_close_path(cr);
    } else {
        cairo_new_sub_path(cr);
        cairo_arc(cr, x, y, rad, 0, 2 * 3.14159265358979323846);
    }
}

static void marker_colours(unsigned flags, double fill[3], double edge[3])
{
    static const double free_f[3] = {0.24, 0.44, 0.72}, free_e[3] = {0.10, 0.20, 0.36};
    static const double fix_f[3] = {0.22, 0.22, 0.22}, fix_e[3] = {0.0, 0.0, 0.0};
    static const double ctl_f[3] = {0.95, 0.55, 0.10}, ctl_e[3] = {0.50, 0.25, 0.0};
    const double *f = free_f, *e = free_e;
    if (flags & PSYS_PARTICLE_FIXED) {
        f = fix_f;
        e = fix_e;
    } else if (flags & PSYS_PARTICLE_CONTROLLED) {
        f = ctl_f;
        e = ctl_e;
    }
    memcpy(fill, f, 3 * sizeof *fill);
    memcpy(edge, e, 3 * sizeof *edge);
}

/* Markers wider than this many pixels are traced as the half-plane their
 * disc's edge bounds near the picture: cairo's arcs take time and memory
 * growing with the radius, and its coordinates end near ±8·10⁶ (a huge
 * --radius hung a run); at 8192² the edge is then off by under 17 pixels
 * at the corners, 0.13 at 800×600. */
#define MARKER_MAX_PX 1e6

static void trace_huge_marker(cairo_t *cr, double x, double y, double rad)
{
    cairo_surface_t *t = cairo_get_target(cr);
    double w = cairo_image_surface_get_width(t), h = cairo_image_surface_get_height(t);
    double mx = 0.5 * w, my = 0.5 * h, ux = mx - x, uy = my - y, d = hypot(ux, uy);
    if (!(d > 0)) {
        ux = 1;
        uy = 0;
    } else {
        ux /= d;
        uy /= d;
    }
    /* inside: (p − m)·u ≤ s, with s = rad − d measured from the centre m */
    double s = rad - d, L = 4.0 * (w + h);
    s = fmax(-L, fmin(s, L)); /* beyond ±L the picture is all in or all out */
    double ex = mx + s * ux, ey = my + s * uy;
    cairo_move_to(cr, ex - L * uy, ey + L * ux);
    cairo_line_to(cr, ex + L * uy, ey - L * ux);
    cairo_line_to(cr, ex + L * uy - 2 * L * ux, ey - L * ux - 2 * L * uy);
    cairo_line_to(cr, ex - L * uy - 2 * L * ux, ey + L * ux - 2 * L * uy);
    cairo_close_path(cr);
}

static void paint_marker(cairo_t *cr, double x, double y, double rad, unsigned flags, double lw)
{
    double fill[3], edge[3];
    marker_colours(flags, fill, edge);
    if (rad > MARKER_MAX_PX)
        trace_huge_marker(cr, x, y, rad);
    else
        trace_marker(cr, x, y, rad, flags);
    cairo_set_source_rgb(cr, fill[0], fill[1], fill[2]);
    if (rad >= 2.5) {
        cairo_fill_preserve(cr);
        cairo_set_source_rgb(cr, edge[0], edge[1], edge[2]);
        cairo_set_line_width(cr, lw);
        cairo_stroke(cr);
    } else {
        cairo_fill(cr);
    }
}

static void paint_text(cairo_t *cr, double x, double y, double size, const char *text)
{
    cairo_select_font_face(cr, "DejaVu Sans", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
    cairo_set_font_size(cr, size);
    cairo_move_to(cr, x, y);
    cairo_show_text(cr, text);
}

static void paint_overlays(renderer *r)
{
    cairo_t *cr = r->cr;
    double ui = ui_scale(r), fs = 14 * ui;
    char buf[64];
    double t = r->t;
    if (fabs(t) < 5e-13)
        t = 0; /* no "-0.000" */
    snprintf(buf, sizeof buf, "t = %.3f s", t);
    set_rgb(cr, 30, 30, 30);
    paint_text(cr, 10 * ui, 10 * ui + fs, fs, buf);

    double small = 11 * ui;
    if (r->nsprings > r->nlinks) {
        /* Strain colour bar on the time stamp's line, top right: "spring strain -5% [bar] +5%". */
        cairo_set_font_size(cr, small);
        cairo_text_extents_t te;
        double base = 10 * ui + fs, w = 70 * ui, h = 0.7 * small;
        double x = r->width - 10 * ui;
        cairo_text_extents(cr, "+5%", &te);
        x -= te.x_advance;
        set_rgb(cr, 60, 60, 60);
        cairo_move_to(cr, x, base);
        cairo_show_text(cr, "+5%");
        x -= 4 * ui + w;
        cairo_pattern_t *pat = cairo_pattern_create_linear(x, 0, x + w, 0);
        for (int i = 0; i <= 20; i++) {
            double rgb[3];
            strain_rgb(STRAIN_FULL * (i / 10.0 - 1), rgb);
            cairo_pattern_add_color_stop_rgb(pat, i / 20.0, rgb[0], rgb[1], rgb[2]);
        }
        cairo_rectangle(cr, x, base - h, w, h);
        cairo_set_source(cr, pat);
        cairo_fill(cr);
        cairo_pattern_destroy(pat);
        set_rgb(cr, 60, 60, 60);
        const char *left = "spring strain  -5%";
        cairo_text_extents(cr, left, &te);
        x -= 4 * ui + te.x_advance;
        cairo_move_to(cr, x, base);
        cairo_show_text(cr, left);
    }
    if (r->kinds & ~1u) {
        /* Legend of particle kinds, bottom left, only when more than free particles appear. */
        static const unsigned kinds[3] = {0, PSYS_PARTICLE_FIXED, PSYS_PARTICLE_CONTROLLED};
        static const char *const names[3] = {"free", "fixed", "controlled"};
        double x = 12 * ui, y = r->height - 12 * ui;
        cairo_set_font_size(cr, small);
        for (int i = 0; i < 3; i++) {
            unsigned bit = kinds[i] ? kinds[i] << 1 : 1u;
            if (!(r->kinds & bit))
                continue;
            paint_marker(cr, x + 5 * ui, y - 0.35 * small, 4.5 * ui, kinds[i], 1.0);
            set_rgb(cr, 60, 60, 60);
            cairo_move_to(cr, x + 14 * ui, y);
            cairo_show_text(cr, names[i]);
            cairo_text_extents_t te;
            cairo_text_extents(cr, names[i], &te);
            x += 14 * ui + te.x_advance + 14 * ui;
        }
    }
}

static void paint(renderer *r)
{
    cairo_t *cr = r->cr;
    cairo_save(cr);
    set_rgb(cr, 250, 250, 247);
    cairo_paint(cr);
    cairo_set_line_cap(cr, CAIRO_LINE_CAP_ROUND);
    cairo_set_line_join(cr, CAIRO_LINE_JOIN_ROUND);
    for (size_t k = 0; k < r->nplanes; k++) {
        if (r->dim == 2)
            paint_plane_2d(r, &r->planes[k]);
        else
            paint_plane_3d(r, &r->planes[k]);
    }
    for (size_t k = 0; k < r->nguides; k++)
        paint_guide(r, &r->guides[k]);
    double ppu_c = r->cam.perspective ? r->cam.scale / r->cam.dist : r->cam.scale;
    double lw = fmin(3.0 * ui_scale(r), fmax(0.8, 0.3 * r->radius * ppu_c));
    if (r->dim == 3) {
        qsort(r->springs, r->nsprings, sizeof *r->springs, far_first_spring);
        qsort(r->parts, r->nparts, sizeof *r->parts, far_first);
    }
    cairo_set_line_width(cr, lw);
    /* Springs in STRAIN_LEVELS colours, one stroke per colour (a stroke per
     * spring costs several times more), the most strained on top; then the
     * behaviour links. Butt caps: the particles cover the ends. */
    cairo_set_line_cap(cr, CAIRO_LINE_CAP_BUTT);
    for (int level = 0; level <= 2 * STRAIN_LEVELS; level++) {
        int order = level % 2 ? STRAIN_LEVELS - (level + 1) / 2 : STRAIN_LEVELS + level / 2; /* 0, -1, +1, ... */
        bool any = false;
        for (size_t k = 0; k < r->nsprings; k++) {
            const r_spring *s = &r->springs[k];
            if (s->link || strain_level(s->strain) != order)
                continue;
            cairo_move_to(cr, s->x0, s->y0);
            cairo_line_to(cr, s->x1, s->y1);
            any = true;
        }
        if (!any)
            continue;
        double rgb[3];
        double a = (double)(order - STRAIN_LEVELS) / STRAIN_LEVELS;
        strain_rgb(STRAIN_FULL * a * fabs(a), rgb);
        cairo_set_source_rgb(cr, rgb[0], rgb[1], rgb[2]);
        cairo_stroke(cr);
    }
    if (r->nlinks) {
        for (size_t k = 0; k < r->nsprings; k++) {
            const r_spring *s = &r->springs[k];
            if (s->link) {
                cairo_move_to(cr, s->x0, s->y0);
                cairo_line_to(cr, s->x1, s->y1);
            }
        }
        cairo_set_source_rgb(cr, 0.16, 0.42, 0.36); /* dark teal */
        cairo_set_line_width(cr, 1.6 * lw);
        cairo_set_line_cap(cr, CAIRO_LINE_CAP_ROUND);
        cairo_stroke(cr);
    }
    cairo_set_line_cap(cr, CAIRO_LINE_CAP_ROUND);
    double edge = fmax(0.75, 0.6 * ui_scale(r));
    for (size_t i = 0; i < r->nparts; i++) {
        const r_particle *q = &r->parts[i];
        paint_marker(cr, q->px, q->py, q->rad, q->flags, edge);
    }
    paint_overlays(r);
    cairo_restore(cr);
    cairo_surface_flush(r->surface);
}

int renderer_draw(renderer *r, const psys_system *sys)
{
    psys_draw d;
    memset(&d, 0, sizeof d);
    d.ctx = r;
    d.radius = r->radius;
    d.begin = cb_begin;
    d.plane = cb_plane;
    d.spring = cb_spring;
    d.particle = cb_particle;
    d.link = cb_link;
    d.guide = cb_guide;
    r->oom = false;
    psys_system_draw(sys, &d);
    if (r->oom)
        return -1;
    paint(r);
    return cairo_status(r->cr) == CAIRO_STATUS_SUCCESS ? 0 : -1;
}

const unsigned char *renderer_pixels(renderer *r, int *stride)
{
    cairo_surface_flush(r->surface);
    *stride = cairo_image_surface_get_stride(r->surface);
    return cairo_image_surface_get_data(r->surface);
}

static cairo_status_t write_fp(void *closure, const unsigned char *data, unsigned int length)
{
    return fwrite(data, 1, length, (FILE *)closure) == length ? CAIRO_STATUS_SUCCESS : CAIRO_STATUS_WRITE_ERROR;
}

int renderer_write_png(renderer *r, FILE *fp)
{
    return cairo_surface_write_to_png_stream(r->surface, write_fp, fp) == CAIRO_STATUS_SUCCESS ? 0 : -1;
}

double render_auto_radius(const psys_system *sys, const camera *cam)
{
    double limit = cam->extent / 45.0;
    double shortest = INFINITY;
    size_t ns = psys_system_spring_count(sys);
    for (size_t k = 0; k < ns; k++) {
        double rest;
        if (psys_system_spring(sys, k, NULL, NULL, NULL, NULL, &rest) == PSYS_OK && rest > 0 && rest < shortest)
            shortest = rest;
    }
    double r = isfinite(shortest) ? fmin(0.15 * shortest, limit) : limit;
    return r > 0 && isfinite(r) ? r : 1.0;
}
