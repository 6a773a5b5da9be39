/* Pieces of the interactive viewer (psys view), one concept per file:
 *   view_main.c   options, the window, the event loop and the fixed-rate clock
 *   view_camera.c 2-D pan/zoom and 3-D orbit cameras, projection and picking
 *   model.c       the editable system: stepping, construction edits, undo,
 *                 mouse springs, gravity, saving
 *   gl_render.c   the OpenGL 3.3 core implementation of psys_draw
 *   hud.c         text (stb_truetype atlas), the HUD and the controls panel */
#ifndef PSYS_VIEW_INTERNAL_H
#define PSYS_VIEW_INTERNAL_H

#include "psys/psys.h"

#include <stdbool.h>
#include <stddef.h>

/* ------------------------------------------------------------ view_camera.c */

/** A camera: 2-D orthographic (x right, y up) or 3-D perspective orbiting
 *  `center` (y up). Window pixels have y down, origin top left. */
typedef struct vw_camera {
    int dim;
    int width, height;   /* window size in pixels */
    double center[3];    /* 2-D: view center; 3-D: orbit center (look-at point) */
    double ppu;          /* 2-D: pixels per scene unit */
    double az, el;       /* 3-D: azimuth, elevation (radians) */
    double dist;         /* 3-D: eye distance from center */
    double fov;          /* 3-D: vertical field of view (radians) */
    /* derived by vw_camera_update */
    double eye[3], r[3], u[3], f[3]; /* eye, right, up, forward (into the screen) */
    double focal;        /* 3-D: pixels per unit at unit depth */
    double near_z, far_z;
    float view_proj[16]; /* column-major, for GL */
    float proj22, proj32; /* perspective matrix entries for depth (unused in 2-D) */
} vw_camera;

void vw_camera_init(vw_camera *c, int dim, int width, int height);
void vw_camera_resize(vw_camera *c, int width, int height);
/** Recompute the derived members (call after changing any of the others). */
void vw_camera_update(vw_camera *c);
/** Window pixel of world point p (dim numbers); *depth gets the view depth
 *  (0 in 2-D). False if p is behind the eye. */
bool vw_camera_project(const vw_camera *c, const double *p, double *sx, double *sy, double *depth);
/** The point under window pixel (sx, sy) on the view plane through `through`
 *  (3-D; NULL = the orbit center); dim numbers into out. */
void vw_camera_unproject(const vw_camera *c, double sx, double sy, const double *through, double *out);
/** Pixels per scene unit at world point p. */
double vw_camera_ppu_at(const vw_camera *c, const double *p);
/** Frame the box lo..hi (dim numbers each) with a margin. */
void vw_camera_frame(vw_camera *c, const double *lo, const double *hi);
/** Zoom by factor (> 1 closer) keeping the point under (sx, sy) in place (2-D). */
void vw_camera_zoom(vw_camera *c, double factor, double sx, double sy);
/** Pan by a pixel offset (the scene follows the mouse). */
void vw_camera_pan(vw_camera *c, double dx, double dy);
/** Orbit by a pixel offset (3-D). */
void vw_camera_orbit(vw_camera *c, double dx, double dy);

/* ------------------------------------------------------------------ model.c */

/** What a construction edit uses for new particles, springs and grabs. */
typedef struct vw_params {
    double mass;        /* new particles */
    double ks, kd;      /* new springs */
} vw_params;

typedef struct vw_model {
    psys_scene *scene;     /* the editable document: system + settings */
    psys_system *sys;      /* the scene's system */
    psys_solver *solver;
    int dim;
    char *initial;         /* the loaded document, for R */
    char *gravity_stash;   /* gravity entries removed by the last G (JSON array) */
    char **undo;           /* snapshots before each edit (oldest first) */
    size_t nundo;
    vw_params params;
    double radius;         /* particle radius for drawing, scene units */
    /* the mouse spring (a force object of sys while grabbing) */
    bool grabbing;
    bool grab_kinematic;   /* a fixed particle: moved directly */
    size_t grab_particle, grab_handle;
    double grab_target[3];
    double grab_ks, grab_kd;
    bool failed;           /* the state became non-finite: paused until R/undo */
    long long steps;
    char message[512];     /* last error from model calls */
} vw_model;

/** Load path (NULL: an empty 2-D scene). -1 with the reason in m->message. */
int vw_model_open(vw_model *m, const char *path);
void vw_model_close(vw_model *m);
/** Rebuild the solver (after changing the integrator or the ODE's size). */
int vw_model_reset_solver(vw_model *m);
/** Advance by at most h (one solver step); *taken gets the step length. */
psys_status vw_model_step(vw_model *m, double h, double *taken);

/* Construction edits: each records an undo snapshot first; -1 (reason in
 * m->message) leaves the system as it was. */
int vw_model_add_particle(vw_model *m, const double *x, size_t *index);
int vw_model_add_spring(vw_model *m, size_t a, size_t b);
/** A new particle at x joined to particle a by a spring (one undo step). */
int vw_model_add_connected(vw_model *m, size_t a, const double *x);
int vw_model_toggle_pin(vw_model *m, size_t i);
/** Circle motor around i's current position (axis: 3-D circle normal, or NULL);
 *  on a motor, releases it. */
int vw_model_toggle_motor(vw_model *m, size_t i, double radius, const double *axis);
int vw_model_delete_particle(vw_model *m, size_t i);
int vw_model_delete_spring(vw_model *m, size_t k);
/** Undo the last edit; 0 done, 1 nothing to undo, -1 failed. */
int vw_model_undo(vw_model *m);
/** Back to the loaded state (undoable). */
int vw_model_reset(vw_model *m);
/** Gravity on/off (not an undo step). */
int vw_model_toggle_gravity(vw_model *m);
bool vw_model_has_gravity(const vw_model *m);
/** Use solver number k (0-based registry order). */
int vw_model_set_integrator(vw_model *m, size_t k);
int vw_model_set_dt(vw_model *m, double dt);
/** Write the current system as a scene (atomically). */
int vw_model_save(vw_model *m, const char *path);

/* Mouse spring */
int vw_model_grab(vw_model *m, size_t i, const double *target);
void vw_model_grab_move(vw_model *m, const double *target);
void vw_model_release(vw_model *m);

/** Particles that are fixed, controlled. */
void vw_model_counts(const vw_model *m, size_t *fixed, size_t *controlled);

/* ------------------------------------------------------------- gl_render.c */

typedef struct vw_renderer vw_renderer;

/** Highlights drawn over the system. */
typedef struct vw_overlay {
    long hover_particle;   /* -1 none */
    long hover_spring;     /* -1 none */
    long source_particle;  /* connection drag source, -1 none */
    bool line;             /* a rubber band from line_a to line_b (connect / mouse spring) */
    double line_a[3], line_b[3];
} vw_overlay;

vw_renderer *vw_renderer_create(char *why, size_t cap);
void vw_renderer_destroy(vw_renderer *r);
/** Draw the system (clears the frame). */
void vw_renderer_draw(vw_renderer *r, const psys_system *sys, const vw_camera *cam, double radius,
                      const vw_overlay *ov);
/** Draw 2-D overlay geometry in window pixels: a filled rectangle. */
void vw_renderer_rect(vw_renderer *r, const vw_camera *cam, float x0, float y0, float x1, float y1,
                      const float rgba[4]);
/** Read the frame just drawn (RGB rows top to bottom); malloc'd, NULL on failure. */
unsigned char *vw_renderer_read_pixels(const vw_camera *cam);

/* ------------------------------------------------------------------ hud.c */

typedef struct vw_text vw_text;

/** Load the font (NULL path: DejaVu Sans); NULL with the reason in why. */
vw_text *vw_text_create(const char *font_path, float pixel_height, char *why, size_t cap);
void vw_text_destroy(vw_text *t);
/** Queue text at window pixel (x, baseline y); returns the x after it. */
float vw_text_add(vw_text *t, float x, float y, const char *s, const float rgba[4]);
/** Width of s in pixels. */
float vw_text_width(const vw_text *t, const char *s);
float vw_text_line_height(const vw_text *t);
/** Distance from the top of a line to its baseline. */
float vw_text_ascent(const vw_text *t);
/** Draw and clear the queued text. */
void vw_text_flush(vw_text *t, const vw_camera *cam);

#endif
