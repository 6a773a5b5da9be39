/* Line plots with cairo: axes with round-number ticks, grid, labels, legend
 * (psys run --plot, psys plot; docs/cli.md "Plots"). */
#include "render.h"

#include <cairo.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

static const double palette[][3] = {
    {0.12, 0.47, 0.71}, {0.84, 0.15, 0.16}, {0.17, 0.63, 0.17}, {1.00, 0.50, 0.05}, {0.58, 0.40, 0.74},
    {0.55, 0.34, 0.29}, {0.89, 0.47, 0.76}, {0.50, 0.50, 0.50}, {0.74, 0.74, 0.13}, {0.09, 0.75, 0.81},
};
#define NPAL (sizeof palette / sizeof *palette)
#define LEGEND_MAX 12

/* A round step (1, 2 or 5 × 10^k) giving about `want` intervals over span. */
static double nice_step(double span, int want)
{
    double raw = span / want, p = pow(10, floor(log10(raw))), m = raw / p;
    return (m < 1.5 ? 1 : m < 3.5 ? 2 : m < 7.5 ? 5 : 10) * p;
}

/* Tick label with just enough digits for the step. */
static void tick_label(char *buf, size_t cap, double v, double step)
{
    if (fabs(v) < 1e-9 * step)
        v = 0;
    double mag = fmax(fabs(v), step);
    int prec = (int)(floor(log10(mag)) - floor(log10(step))) + 1;
    prec = prec < 1 ? 1 : prec > 15 ? 15 : prec;
    snprintf(buf, cap, "%.*g", prec, v);
}

static void range_of(const plot_series *s, size_t count, bool y, double *lo, double *hi)
{
    *lo = INFINITY;
    *hi = -INFINITY;
    for (size_t k = 0; k < count; k++)
        for (size_t i = 0; i < s[k].n; i++) {
            double xv = s[k].x[i], yv = s[k].y[i];
            if (!isfinite(xv) || !isfinite(yv))
                continue;
            double v = y ? yv : xv;
            if (v < *lo)
                *lo = v;
            if (v > *hi)
                *hi = v;
        }
    if (!(*lo <= *hi)) {
        *lo = 0;
        *hi = 1;
    } else if (*hi - *lo <= 1e-12 * fmax(fabs(*lo), fabs(*hi))) {
        double d = fabs(*lo) > 0 ? 0.05 * fabs(*lo) : 1.0;
        *lo -= d;
        *hi += d;
    }
}

static void centred(cairo_t *cr, double x, double y, const char *text)
{
    cairo_text_extents_t te;
    cairo_text_extents(cr, text, &te);
    cairo_move_to(cr, x - te.width / 2 - te.x_bearing, y);
    cairo_show_text(cr, text);
}

static cairo_status_t write_fp(void *closure, const unsigned char *data, unsigned int length)
{
    return fwrite(data, 1, length, (FILE *)closure) == length ? CAIRO_STATUS_SUCCESS : CAIRO_STATUS_WRITE_ERROR;
}

/* Trace one series, thinning runs of points that fall in the same pixel
 * column to their first, lowest, highest and last points. */
static void trace_series(cairo_t *cr, const plot_series *s, double x0, double xs, double y0, double ys,
                         double xlo, double ylo)
{
    bool pen = false;
    long col = 0;
    double cmin = 0, cmax = 0, last_y = 0, cx = 0;
    bool have_col = false;
#define PX(v) (x0 + ((v) - xlo) * xs)
#define PY(v) (y0 - ((v) - ylo) * ys)
    for (size_t i = 0; i < s->n; i++) {
        double xv = s->x[i], yv = s->y[i];
        if (!isfinite(xv) || !isfinite(yv)) {
            if (have_col) {
                cairo_line_to(cr, cx, PY(cmin));
                cairo_line_to(cr, cx, PY(cmax));
                cairo_line_to(cr, cx, PY(last_y));
            }
            have_col = pen = false;
            continue;
        }
        double px = PX(xv);
        long c = lround(floor(px));
        if (have_col && c == col) {
            cmin = fmin(cmin, yv);
            cmax = fmax(cmax, yv);
            last_y = yv;
            continue;
        }
        if (have_col) {
            cairo_line_to(cr, cx, PY(cmin));
            cairo_line_to(cr, cx, PY(cmax));
            cairo_line_to(cr, cx, PY(last_y));
        }
        if (!pen) {
            cairo_move_to(cr, px, PY(yv));
            pen = true;
        } else {
            cairo_line_to(cr, px, PY(yv));
        }
        have_col = true;
        col = c;
        cx = px;
        cmin = cmax = last_y = yv;
    }
    if (have_col) {
        cairo_line_to(cr, cx, PY(cmin));
        cairo_line_to(cr, cx, PY(cmax));
        cairo_line_to(cr, cx, PY(last_y));
    }
#undef PX
#undef PY
}

int plot_write_png(FILE *fp, const plot_spec *spec, const plot_series *s, size_t count)
{
    int W = spec->width, H = spec->height;
    cairo_surface_t *surf = cairo_image_surface_create(CAIRO_FORMAT_ARGB32, W, H);
    if (cairo_surface_status(surf) != CAIRO_STATUS_SUCCESS) {
        cairo_surface_destroy(surf);
        return -1;
    }
    cairo_t *cr = cairo_create(surf);
    double ui = fmax(0.6, fmin(W / 800.0, H / 600.0));
    double fs = 12 * ui;
    cairo_select_font_face(cr, "DejaVu Sans", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
    cairo_set_source_rgb(cr, 1, 1, 1);
    cairo_paint(cr);

    double xlo, xhi, ylo, yhi;
    range_of(s, count, false, &xlo, &xhi);
    range_of(s, count, true, &ylo, &yhi);
    double pad = 0.05 * (yhi - ylo);
    ylo -= pad;
    yhi += pad;
    double xstep = nice_step(xhi - xlo, 7), ystep = nice_step(yhi - ylo, 6);

    /* Room for the y tick labels: measure the widest. */
    cairo_set_font_size(cr, fs);
    double wlab = 0;
    char buf[64];
    for (long k0 = lround(ceil(ylo / ystep)), k = k0; k - k0 < 100 && (double)k * ystep <= yhi + 1e-9 * ystep; k++) {
        double v = (double)k * ystep;
        cairo_text_extents_t te;
        tick_label(buf, sizeof buf, v, ystep);
        cairo_text_extents(cr, buf, &te);
        wlab = fmax(wlab, te.x_advance);
    }
    double left = 18 * ui + 1.4 * fs + wlab, right = W - 20 * ui;
    double top = (spec->title && *spec->title ? 38 : 18) * ui, bottom = H - (22 * ui + 2.6 * fs);
    if (right - left < 20 || bottom - top < 20) {
        left = 0;
        right = W;
        top = 0;
        bottom = H;
    }
    double xs = (right - left) / (xhi - xlo), ys = (bottom - top) / (yhi - ylo);

    /* Grid and ticks. */
    cairo_set_line_width(cr, 1);
    for (long k0 = lround(ceil(xlo / xstep)), k = k0; k - k0 < 100 && (double)k * xstep <= xhi + 1e-9 * xstep; k++) {
        double v = (double)k * xstep;
        double px = floor(left + (v - xlo) * xs) + 0.5;
        cairo_set_source_rgb(cr, 0.90, 0.90, 0.90);
        cairo_move_to(cr, px, top);
        cairo_line_to(cr, px, bottom);
        cairo_stroke(cr);
        cairo_set_source_rgb(cr, 0.2, 0.2, 0.2);
        tick_label(buf, sizeof buf, v, xstep);
        centred(cr, px, bottom + 6 * ui + fs, buf);
    }
    for (long k0 = lround(ceil(ylo / ystep)), k = k0; k - k0 < 100 && (double)k * ystep <= yhi + 1e-9 * ystep; k++) {
        double v = (double)k * ystep;
        double py = floor(bottom - (v - ylo) * ys) + 0.5;
        cairo_set_source_rgb(cr, 0.90, 0.90, 0.90);
        cairo_move_to(cr, left, py);
        cairo_line_to(cr, right, py);
        cairo_stroke(cr);
        cairo_set_source_rgb(cr, 0.2, 0.2, 0.2);
        tick_label(buf, sizeof buf, v, ystep);
        cairo_text_extents_t te;
        cairo_text_extents(cr, buf, &te);
        cairo_move_to(cr, left - 6 * ui - te.x_advance, py + 0.35 * fs);
        cairo_show_text(cr, buf);
    }
    cairo_set_source_rgb(cr, 0.15, 0.15, 0.15);
    cairo_rectangle(cr, floor(left) + 0.5, floor(top) + 0.5, floor(right) - floor(left), floor(bottom) - floor(top));
    cairo_stroke(cr);

    /* Labels and title. */
    if (spec->xlabel)
        centred(cr, 0.5 * (left + right), H - 10 * ui, spec->xlabel);
    if (spec->ylabel) {
        cairo_save(cr);
        cairo_translate(cr, 8 * ui + fs, 0.5 * (top + bottom));
        cairo_rotate(cr, -0.5 * 3.14159265358979323846);
        centred(cr, 0, 0, spec->ylabel);
        cairo_restore(cr);
    }
    if (spec->title && *spec->title) {
        cairo_set_font_size(cr, 1.2 * fs);
        centred(cr, 0.5 * (left + right), top - 12 * ui, spec->title);
        cairo_set_font_size(cr, fs);
    }

    /* Lines, clipped to the plot area. */
    cairo_save(cr);
    cairo_rectangle(cr, left, top, right - left, bottom - top);
    cairo_clip(cr);
    cairo_set_line_width(cr, 1.6 * ui);
    cairo_set_line_join(cr, CAIRO_LINE_JOIN_ROUND);
    for (size_t k = 0; k < count; k++) {
        const double *c = palette[k % NPAL];
        cairo_set_source_rgb(cr, c[0], c[1], c[2]);
        trace_series(cr, &s[k], left, xs, bottom, ys, xlo, ylo);
        cairo_stroke(cr);
    }
    cairo_restore(cr);

    /* Legend, top right inside the plot. */
    size_t shown = count > LEGEND_MAX ? LEGEND_MAX : count;
    if (count > 0) {
        double wmax = 0;
        for (size_t k = 0; k < shown; k++) {
            cairo_text_extents_t te;
            cairo_text_extents(cr, s[k].label ? s[k].label : "", &te);
            wmax = fmax(wmax, te.x_advance);
        }
        char more[64] = "";
        if (count > shown) {
            snprintf(more, sizeof more, "and %zu more", count - shown);
            cairo_text_extents_t te;
            cairo_text_extents(cr, more, &te);
            wmax = fmax(wmax, te.x_advance - 28 * ui);
        }
        double rows = (double)shown + (count > shown), lh = 1.5 * fs;
        double bw = wmax + 44 * ui, bh = rows * lh + 10 * ui;
        double bx = right - bw - 8 * ui, by = top + 8 * ui;
        cairo_rectangle(cr, bx, by, bw, bh);
        cairo_set_source_rgba(cr, 1, 1, 1, 0.85);
        cairo_fill_preserve(cr);
        cairo_set_source_rgb(cr, 0.75, 0.75, 0.75);
        cairo_set_line_width(cr, 1);
        cairo_stroke(cr);
        for (size_t k = 0; k < shown; k++) {
            double y = by + 5 * ui + (k + 0.5) * lh;
            const double *c = palette[k % NPAL];
            cairo_set_source_rgb(cr, c[0], c[1], c[2]);
            cairo_set_line_width(cr, 2.5 * ui);
            cairo_move_to(cr, bx + 8 * ui, y);
            cairo_line_to(cr, bx + 30 * ui, y);
            cairo_stroke(cr);
            cairo_set_source_rgb(cr, 0.1, 0.1, 0.1);
            cairo_move_to(cr, bx + 36 * ui, y + 0.35 * fs);
            cairo_show_text(cr, s[k].label ? s[k].label : "");
        }
        if (count > shown) {
            cairo_set_source_rgb(cr, 0.3, 0.3, 0.3);
            cairo_move_to(cr, bx + 8 * ui, by + 5 * ui + (shown + 0.5) * lh + 0.35 * fs);
            cairo_show_text(cr, more);
        }
    }

    int rc = cairo_status(cr) == CAIRO_STATUS_SUCCESS ? 0 : -1;
    cairo_destroy(cr);
    cairo_surface_flush(surf);
    if (rc == 0 && cairo_surface_write_to_png_stream(surf, write_fp, fp) != CAIRO_STATUS_SUCCESS)
        rc = -1;
    cairo_surface_destroy(surf);
    return rc;
}
