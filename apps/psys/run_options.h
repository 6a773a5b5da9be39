/* The options of `psys run` (docs/cli.md): the flags as given (run_opts),
 * then checked and applied to a scene's settings, with the picture settings
 * they imply (picture_opts). */
#ifndef PSYS_RUN_OPTIONS_H
#define PSYS_RUN_OPTIONS_H

#include "cli.h"
#include "render.h"

/** The flags of `psys run`, as given; NULL when absent. */
typedef struct run_opts {
    const char *scene;
    const char *dt, *steps, *duration, *integrator, *every, *out, *energy, *render, *threads;
    const char *checkpoint, *resume;
    const char *size, *fps, *camera, *radius, *plot;
    const char *mpi; /* --mpi: auto, domain or replicated */
    int quiet;
} run_opts;

/** Trajectory formats, by the --out extension. */
typedef enum traj_format { TRAJ_NONE, TRAJ_CSV, TRAJ_XYZ, TRAJ_VTP, TRAJ_VTK } traj_format;

/** Rendering and plotting settings after the flags were checked. */
typedef struct picture_opts {
    int width, height;  /* --size, default 800x600 */
    double fps;         /* --fps, default 30 */
    camera_spec cam;    /* --camera */
    sink_kind kind;     /* of the render path */
    traj_format traj;   /* of the trajectory path */
} picture_opts;

/** Read argv[1..] into o; -1 (message printed) on an unknown or repeated
 *  argument, a missing value, no scene, or both --steps and --duration. */
int run_options_parse(int argc, char **argv, run_opts *o);

/** Apply o to a dim-D scene's settings (flags win over the scene) and check
 *  the picture options into pic; -1 (message printed) on a bad value. */
int run_options_apply(const run_opts *o, psys_settings *set, int dim, picture_opts *pic);

/** How messages name the picture path: the flag, or the scene key it came from. */
const char *run_options_render_label(const run_opts *o);

#endif
