/* Headless pictures for the psys CLI (docs/cli.md "Rendering"): camera and
 * framing (camera.c), the cairo implementation of psys_draw (render.c),
 * where frames go (sink.c: PNG, PNG sequences, GIF, MP4 through ffmpeg),
 * a small GIF encoder for machines without ffmpeg (gif.c) and line plots
 * (plot.c). The library never sees cairo: it draws through psys_draw. */
#ifndef PSYS_RENDER_H
#define PSYS_RENDER_H

#include "psys/psys.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdio.h>

/* ---------------------------------------------------------------- camera.c */

/** What --camera asked for (camera_spec_default, then camera_spec_parse). */
typedef struct camera_spec {
    int dim;            /* 2 or 3 */
    bool perspective;   /* 3-D default: true */
    double az, el, fov; /* degrees: azimuth about the up axis, elevation, vertical field of view */
    int up;             /* up axis: 0 x, 1 y (default), 2 z */
    bool has_center;    /* center= given */
    double center[3];   /* look-at point */
    double extent;      /* visible height at the center, scene units; <= 0 automatic */
    double zoom;        /* > 0, multiplies the picture scale (default 1) */
    bool fit_start;     /* fit=start: frame the initial state only */
} camera_spec;

/** Defaults for a dim-D scene: 2-D orthographic x right, y up; 3-D perspective, az 30, el 20, fov 35. */
void camera_spec_default(camera_spec *spec, int dim);
/** Parse a --camera value over spec; -1 with the reason in why (no "--camera: " prefix). */
int camera_spec_parse(const char *text, camera_spec *spec, char *why, size_t cap);
/** True when framing needs the bounds of the whole run (a framing pass): no
 *  center and extent given and not fit=start. */
bool camera_needs_run_bounds(const camera_spec *spec);
/** True when framing needs any bounds at all (center or extent left automatic). */
bool camera_needs_bounds(const camera_spec *spec);

/** Bounds gathered over frames, along the camera's axes (right, up,
 *  forward), so framing fits what the picture shows, not a world box. */
typedef struct bounds {
    bool any;
    int dim;
    double axis[3][3]; /* right, up, forward of the camera spec */
    double lo[3], hi[3];
    /* Perspective fit: kx = margin/tan(half horizontal fov), ky the same
     * vertically; amax = the largest kx·x - z, -kx·x - z, ky·y - z, -ky·y - z
     * over all points, which give the eye distance exactly for any center. */
    double kx, ky, amax[4];
} bounds;

/** Empty bounds along the axes of spec's view, for width×height pictures. */
void bounds_init(bounds *b, const camera_spec *spec, int width, int height);
/** Extend b by the current particle positions of sys. */
void bounds_add_system(bounds *b, const psys_system *sys);

/** A camera ready to project: world point -> pixel. */
typedef struct camera {
    int width, height;
    bool perspective;
    double c[3];        /* look-at point */
    double r[3], u[3], f[3]; /* right, up, forward (into the picture), orthonormal */
    double dist;        /* perspective: distance of the eye from c */
    double scale;       /* orthographic: pixels per scene unit; perspective: focal length in pixels */
    double extent;      /* visible height at c, in scene units */
    double cy;          /* pixel row of the view's center */
} camera;

/** Set up cam for a width×height picture from spec and the bounds to frame. */
void camera_setup(camera *cam, const camera_spec *spec, int width, int height, const bounds *b);
/** View coordinates of world point p (3 numbers): x right, y up, z depth (into the picture). */
void camera_view(const camera *cam, const double *p, double v[3]);
/** Nearest view depth drawn (perspective); points closer are clipped. */
double camera_near(const camera *cam);
/** Pixel position of a view point; false if it is behind the near plane. *ppu gets pixels per scene unit there. */
bool camera_pixel(const camera *cam, const double v[3], double *px, double *py, double *ppu);

/* ---------------------------------------------------------------- render.c */

/** A cairo picture of a system: implements psys_draw. */
typedef struct renderer renderer;

/** A renderer for width×height pictures seen through cam; radius is the
 *  particle radius in scene units (see psys_draw.radius). NULL if out of memory. */
renderer *renderer_create(int width, int height, const camera *cam, double radius);
void renderer_destroy(renderer *r);
/** Draw the current state of sys (background, planes, springs, particles, time stamp). -1 if out of memory. */
int renderer_draw(renderer *r, const psys_system *sys);
/** Pixels of the last picture: premultiplied BGRA rows (cairo ARGB32), stride bytes apart. */
const unsigned char *renderer_pixels(renderer *r, int *stride);
/** Write the last picture as PNG to fp; -1 on failure. */
int renderer_write_png(renderer *r, FILE *fp);
/** A particle radius that suits the scene: 0.15 of the shortest spring, at most 1/45 of the view. */
double render_auto_radius(const psys_system *sys, const camera *cam);

/* ---------------------------------------------------------------- sink.c */

/** Where --render pictures go, chosen by the path. */
typedef enum sink_kind {
    SINK_PNG,     /* out.png: the last frame */
    SINK_PATTERN, /* frames/%04d.png: one PNG per frame */
    SINK_GIF,     /* out.gif (ffmpeg, or the built-in encoder without it) */
    SINK_MP4      /* out.mp4 (H.264 through ffmpeg) */
} sink_kind;

/** The kind of path; -1 with the reason in why when it is not one psys writes. */
int sink_kind_of(const char *path, sink_kind *kind, char *why, size_t cap);
/** The ffmpeg program to run ($PSYS_FFMPEG, else "ffmpeg" on PATH) if it exists, else NULL. */
const char *sink_find_ffmpeg(void);

typedef struct sink sink;

/** Prepare the output (temporary files, checks; ffmpeg starts with the first
 *  frame). label names the option in messages. NULL after printing a message. */
sink *sink_open(const char *path, const char *label, int width, int height, double fps);
/** True for sinks that take every frame (all but the single PNG). */
bool sink_takes_frames(const sink *s);
/** Add the renderer's current picture as the next frame; -1 (message printed) on failure. */
int sink_frame(sink *s, renderer *r);
/** Finish: the single PNG is written from r's current picture; video is
 *  completed; files are renamed into place. -1 (message printed) on failure.
 *  Frees s. */
int sink_close(sink *s, renderer *r);
/** Give up: stop ffmpeg, remove temporary files. Frees s (NULL is fine). */
void sink_abort(sink *s);
/** Frames written so far. */
long long sink_frames(const sink *s);

/* ---------------------------------------------------------------- gif.c */

/** A minimal GIF89a encoder (fixed 256-colour palette, LZW), looping forever. */
typedef struct gif_writer gif_writer;
gif_writer *gif_begin(FILE *fp, int width, int height);
/** Add a frame of BGRA pixels (opaque) shown for delay_cs hundredths of a second. */
int gif_frame(gif_writer *g, const unsigned char *bgra, int stride, int delay_cs);
/** Write the trailer and free g; -1 if any write failed. */
int gif_end(gif_writer *g);

/* ---------------------------------------------------------------- plot.c */

/** One line of a plot. */
typedef struct plot_series {
    const char *label;
    const double *x, *y;
    size_t n;
} plot_series;

/** Labels and size of a plot. */
typedef struct plot_spec {
    int width, height;
    const char *title, *xlabel, *ylabel;
} plot_spec;

/** Draw the series (non-finite points break a line) with axes, ticks,
 *  labels and a legend, and write it as PNG to fp; -1 on failure. */
int plot_write_png(FILE *fp, const plot_spec *spec, const plot_series *series, size_t count);

/* ---------------------------------------------------------------- shared */

/** Parse "WxH" (each 16 to 8192); -1 if it is not one. */
int parse_size(const char *s, int *w, int *h);

#endif
