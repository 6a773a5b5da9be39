/* png_probe: facts about a PNG for the rendering tests (tests/cli/render.sh).
 *
 *   png_probe FILE.png [X Y]...
 *
 * prints
 *   size W H
 *   background R G B        the most frequent colour
 *   nonbackground N         pixels differing from it by more than 24 in some channel
 *   pixel X Y R G B         for each X Y asked for
 * and exits 1 (with a message) when FILE is not a PNG cairo can read. */
#include <cairo.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void rgb(const unsigned char *p, int *r, int *g, int *b)
{
    /* cairo ARGB32: premultiplied B, G, R, A in memory (little endian) */
    int a = p[3];
    *b = a ? p[0] * 255 / a : 0;
    *g = a ? p[1] * 255 / a : 0;
    *r = a ? p[2] * 255 / a : 0;
}

int main(int argc, char **argv)
{
    if (argc < 2 || argc % 2 != 0) {
        fprintf(stderr, "usage: png_probe FILE.png [X Y]...\n");
        return 2;
    }
    cairo_surface_t *s = cairo_image_surface_create_from_png(argv[1]);
    if (cairo_surface_status(s) != CAIRO_STATUS_SUCCESS) {
        fprintf(stderr, "png_probe: %s: %s\n", argv[1], cairo_status_to_string(cairo_surface_status(s)));
        cairo_surface_destroy(s);
        return 1;
    }
    cairo_surface_flush(s);
    int w = cairo_image_surface_get_width(s), h = cairo_image_surface_get_height(s);
    int stride = cairo_image_surface_get_stride(s);
    const unsigned char *data = cairo_image_surface_get_data(s);
    /* The most frequent colour (a histogram of all 2^24 colours). */
    unsigned *hist = calloc(1u << 24, sizeof *hist);
    if (!hist) {
        fprintf(stderr, "png_probe: out of memory\n");
        return 1;
    }
    int opaque = cairo_image_surface_get_format(s) == CAIRO_FORMAT_RGB24;
    unsigned best = 0, bestn = 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            const unsigned char *p = data + (size_t)y * stride + 4 * (size_t)x;
            int r, g, b;
            if (opaque) {
                b = p[0], g = p[1], r = p[2];
            } else {
                rgb(p, &r, &g, &b);
            }
            unsigned c = (unsigned)r << 16 | (unsigned)g << 8 | (unsigned)b;
            if (++hist[c] > bestn) {
                bestn = hist[c];
                best = c;
            }
        }
    int br = best >> 16 & 255, bg = best >> 8 & 255, bb = best & 255;
    long nonbg = 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            const unsigned char *p = data + (size_t)y * stride + 4 * (size_t)x;
            int r, g, b;
            if (opaque) {
                b = p[0], g = p[1], r = p[2];
            } else {
                rgb(p, &r, &g, &b);
            }
            if (abs(r - br) > 24 || abs(g - bg) > 24 || abs(b - bb) > 24)
                nonbg++;
        }
    printf("size %d %d\nbackground %d %d %d\nnonbackground %ld\n", w, h, br, bg, bb, nonbg);
    for (int i = 2; i + 1 < argc; i += 2) {
        int x = atoi(argv[i]), y = atoi(argv[i + 1]);
        if (x < 0 || y < 0 || x >= w || y >= h) {
            printf("pixel %d %d outside\n", x, y);
            continue;
        }
        const unsigned char *p = data + (size_t)y * stride + 4 * (size_t)x;
        int r, g, b;
        if (opaque) {
            b = p[0], g = p[1], r = p[2];
        } else {
            rgb(p, &r, &g, &b);
        }
        printf("pixel %d %d %d %d %d\n", x, y, r, g, b);
    }
    free(hist);
    cairo_surface_destroy(s);
    return 0;
}
