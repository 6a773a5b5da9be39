/* The files `psys run` writes (docs/cli.md): trajectory (CSV, XYZ, or VTP/VTK
 * frames with a .pvd series), energy CSV, checkpoint, energy plot and the
 * picture or video. All are opened before the first step and written under
 * temporary names, so a run that cannot start leaves nothing behind and a
 * file appears only once complete. */
#ifndef PSYS_RUN_OUTPUTS_H
#define PSYS_RUN_OUTPUTS_H

#include "run_options.h"

/** Picture frames are taken at simulated times t0 + k/fps: after each step,
 *  every k whose time has been reached (the state of the nearest step at or
 *  after it) is due. Steps longer than 1/fps repeat a state, so a video
 *  keeps time. */
typedef struct frame_clock {
    double t0, fps;
    long long next;
} frame_clock;

/** How many frames are due by time t (and mark them taken). */
long long frames_due(frame_clock *c, double t);

/** Energies sampled at the trajectory frames, for the --plot picture. */
typedef struct energy_series {
    double *t, *ke, *pe, *total;
    size_t n, cap;
    long long stride, skip; /* after thinning, keep every stride-th sample */
    int oom;
} energy_series;

/** Every output of one run; zeroed by run_outputs_open. */
typedef struct run_outputs {
    const picture_opts *pic;
    const psys_settings *set;
    traj_format fmt;
    outfile traj;             /* CSV or XYZ: the trajectory; VTP/VTK: the .pvd series */
    char *stem;               /* VTP/VTK: the path without its extension; frames are stem_NNNNNN.ext */
    const char *label;        /* --out or output.trajectory */
    long long vtk_frames;
    outfile energy;
    int checkpoint_on;
    outfile checkpoint;
    int plot_on;
    outfile plot_file;
    energy_series plot;
    sink *snk;                /* the picture or video, NULL without one */
    const char *render_label; /* --render or output.render */
    renderer *ren;            /* a video's renderer, once framed */
    frame_clock clock;
    bool still;               /* a single PNG, framed and drawn at the end */
    bounds still_bounds;      /* the states it is framed by */
} run_outputs;

/** Open every output that o and set ask for, checking that no two are one
 *  file and none replaces the scene or checkpoint read, and write the
 *  headers; -1 (message printed) on failure, after which run_outputs_abort
 *  removes what was opened. pic and set must outlive out. */
int run_outputs_open(run_outputs *out, const run_opts *o, const psys_settings *set, const picture_opts *pic,
                     int dim);
/** Close and delete every output, and free out. */
void run_outputs_abort(run_outputs *out);

/** Whether the picture is a video or frame sequence (drawn during the run). */
bool run_outputs_takes_frames(const run_outputs *out);
/** The video's renderer, framing b; 1 (message printed) when out of memory. */
int run_outputs_frame_video(run_outputs *out, const psys_system *sys, const bounds *b);
/** The pictures of the initial state; 1 (message printed) on failure. */
int run_outputs_first_pictures(run_outputs *out, const psys_system *sys);
/** The pictures due after a step; 1 (message printed) on failure. */
int run_outputs_pictures(run_outputs *out, const psys_system *sys);

/** Whether a trajectory frame, energy row or plot sample is written at frames. */
bool run_outputs_writes_frames(const run_outputs *out);
/** The trajectory frame, energy row and plot sample of sys at step; -1 on failure. */
int run_outputs_write_frame(run_outputs *out, const psys_system *sys, long long step);

/** Finish and rename every output into place: the trajectory, the energy
 *  file, the checkpoint of run, the plot (titled after source) and the
 *  picture; frees out. Nonzero (message printed) when any failed. */
int run_outputs_commit(run_outputs *out, const psys_scene *scene, const psys_run *run, const psys_system *sys,
                       const char *source);

#endif
