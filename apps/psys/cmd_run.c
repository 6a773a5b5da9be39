/* psys run: load, override, step, write frames, render, plot, checkpoint
 * (DESIGN §3, §3a; docs/cli.md). */
#include "cli.h"
#include "render.h"

#include <math.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#ifdef PSYS_MPI
#include "psys/psys_mpi.h"
#endif

static volatile sig_atomic_t stop_signal = 0;

static void on_signal(int sig) { stop_signal = sig; }

/* MPI (docs/mpi.md): this process's rank and the number of ranks; 0 and 1
 * in a build without MPI or when run without mpiexec. Rank 0 reads the scene
 * and writes every file; all ranks step the same replicated system. */
static int mpi_rank = 0, mpi_size = 1;

/* Rank 0's v on every rank: decisions only rank 0 can make (its files, its
 * signals) taken by all. A collective with several ranks, v itself otherwise. */
static int agree(int v)
{
#ifdef PSYS_MPI
    if (mpi_size > 1)
        MPI_Bcast(&v, 1, MPI_INT, 0, MPI_COMM_WORLD);
#else
    (void)mpi_size;
#endif
    return v;
}

typedef struct run_opts {
    const char *scene;
    const char *dt, *steps, *duration, *integrator, *every, *out, *energy, *render, *threads;
    const char *checkpoint, *resume;
    const char *size, *fps, *camera, *radius, *plot;
    const char *mpi; /* --mpi: auto, domain or replicated */
    int quiet;
} run_opts;

/* Trajectory formats, by the --out extension. */
typedef enum traj_format { TRAJ_NONE, TRAJ_CSV, TRAJ_XYZ, TRAJ_VTP, TRAJ_VTK } traj_format;

/* Rendering and plotting settings after the flags were checked. */
typedef struct picture_opts {
    int width, height;  /* --size, default 800x600 */
    double fps;         /* --fps, default 30 */
    camera_spec cam;    /* --camera */
    sink_kind kind;     /* of the render path */
    traj_format traj;   /* of the trajectory path */
} picture_opts;

static double now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}


static int parse_args(int argc, char **argv, run_opts *o)
{
    memset(o, 0, sizeof *o);
    for (int i = 1; i < argc; i++) {
        int bad = 0;
        const char *a = argv[i];
        if (cli_take(argc, argv, &i, "--dt", &o->dt, &bad) || cli_take(argc, argv, &i, "--steps", &o->steps, &bad)
            || cli_take(argc, argv, &i, "--duration", &o->duration, &bad)
            || cli_take(argc, argv, &i, "--integrator", &o->integrator, &bad)
            || cli_take(argc, argv, &i, "--every", &o->every, &bad) || cli_take(argc, argv, &i, "--out", &o->out, &bad)
            || cli_take(argc, argv, &i, "--energy", &o->energy, &bad)
            || cli_take(argc, argv, &i, "--render", &o->render, &bad)
            || cli_take(argc, argv, &i, "--threads", &o->threads, &bad)
            || cli_take(argc, argv, &i, "--checkpoint", &o->checkpoint, &bad)
            || cli_take(argc, argv, &i, "--resume", &o->resume, &bad)
            || cli_take(argc, argv, &i, "--size", &o->size, &bad) || cli_take(argc, argv, &i, "--fps", &o->fps, &bad)
            || cli_take(argc, argv, &i, "--camera", &o->camera, &bad)
            || cli_take(argc, argv, &i, "--radius", &o->radius, &bad)
            || cli_take(argc, argv, &i, "--plot", &o->plot, &bad)
            || cli_take(argc, argv, &i, "--mpi", &o->mpi, &bad)) {
            if (bad)
                return -1;
        } else if (strcmp(a, "--quiet") == 0 || strcmp(a, "-q") == 0) {
            o->quiet = 1;
        } else if (a[0] == '-' && a[1] != '\0') {
            cli_error("run: unknown option %s (see psys --help)", a);
            return -1;
        } else if (!o->scene) {
            o->scene = a;
        } else {
            cli_error("run: more than one scene given (%s and %s)", o->scene, a);
            return -1;
        }
    }
    if (!o->scene && !o->resume) {
        cli_error("run: no scene given (usage: psys run SCENE [options]; see psys --help)");
        return -1;
    }
    if (o->steps && o->duration) {
        cli_error("run: give either --steps or --duration, not both");
        return -1;
    }
    return 0;
}

static const char *extension(const char *path)
{
    const char *slash = strrchr(path, '/');
    const char *dot = strrchr(slash ? slash : path, '.');
    return dot ? dot : "";
}

/* Apply command-line overrides to the scene's settings (flags win) and check
 * the picture options for a dim-D scene into pic. */
static int apply_flags(const run_opts *o, psys_settings *set, int dim, picture_opts *pic)
{
    long long n;
    double x;
    if (o->integrator) {
        if (cli_check_integrator(o->integrator) != 0)
            return -1;
        snprintf(set->integrator, sizeof set->integrator, "%s", o->integrator);
    }
    if (o->dt) {
        if (parse_positive(o->dt, &x) != 0) {
            cli_error("--dt: must be a finite number > 0 (got %s)", o->dt);
            return -1;
        }
        set->dt = x;
    }
    if (o->steps) {
        if (parse_int(o->steps, 0, 1000000000000000LL, &n) != 0) {
            cli_error("--steps: must be an integer >= 0 (got %s)", o->steps);
            return -1;
        }
        set->steps = n;
        set->use_steps = true;
    }
    if (o->duration) {
        if (parse_nonneg(o->duration, &x) != 0) {
            cli_error("--duration: must be a finite number >= 0 (got %s)", o->duration);
            return -1;
        }
        set->duration = x;
        set->use_steps = false;
    }
    if (o->every) {
        if (parse_int(o->every, 1, 1000000000000000LL, &n) != 0) {
            cli_error("--every: must be an integer >= 1 (got %s)", o->every);
            return -1;
        }
        set->every = n;
    }
    if (o->threads && parse_int(o->threads, 1, 4096, &n) != 0) {
        cli_error("--threads: must be an integer from 1 to 4096 (got %s)", o->threads);
        return -1;
    }
    if (o->mpi && strcmp(o->mpi, "auto") != 0 && strcmp(o->mpi, "domain") != 0 && strcmp(o->mpi, "replicated") != 0) {
        cli_error("--mpi: must be auto, domain or replicated (got %s)", o->mpi);
        return -1;
    }
#define COPY_PATH(flag, field)                                                        \
    if (flag) {                                                                       \
        if (strlen(flag) >= sizeof set->field || !(flag)[0]) {                       \
            cli_error("--%s: path must be 1 to %zu characters", #field, sizeof set->field - 1); \
            return -1;                                                                \
        }                                                                             \
        memcpy(set->field, flag, strlen(flag) + 1);                                   \
    }
    COPY_PATH(o->out, trajectory)
    COPY_PATH(o->energy, energy)
    COPY_PATH(o->render, render)
#undef COPY_PATH
    if (o->plot && !o->plot[0]) {
        cli_error("--plot: path must not be empty");
        return -1;
    }
    pic->traj = TRAJ_NONE;
    const char *traj_label = o->out ? "--out" : "output.trajectory";
    if (set->trajectory[0]) {
        const char *ext = extension(set->trajectory);
        if (strcmp(ext, ".csv") == 0)
            pic->traj = TRAJ_CSV;
        else if (strcmp(ext, ".xyz") == 0)
            pic->traj = TRAJ_XYZ;
        else if (strcmp(ext, ".vtp") == 0)
            pic->traj = TRAJ_VTP;
        else if (strcmp(ext, ".vtk") == 0)
            pic->traj = TRAJ_VTK;
        else {
            cli_error("%s %s: unknown trajectory format (got \"%s\"; use .csv, .vtp, .vtk or .xyz)", traj_label,
                      set->trajectory, ext);
            return -1;
        }
    }
    /* Pictures. */
    const char *render_label = o->render ? "--render" : "output.render";
    bool rendering = set->render[0] != '\0';
    pic->width = 800;
    pic->height = 600;
    pic->fps = 30;
    camera_spec_default(&pic->cam, dim);
    if (o->size) {
        if (parse_size(o->size, &pic->width, &pic->height) != 0) {
            cli_error("--size: must be WIDTHxHEIGHT, each from 16 to 8192 (got %s)", o->size);
            return -1;
        }
        if (!rendering && !o->plot) {
            cli_error("--size: only with --render or --plot (or output.render)");
            return -1;
        }
    }
    if (o->fps) {
        if (parse_positive(o->fps, &x) != 0 || x > 1000) {
            cli_error("--fps: must be a number > 0 and at most 1000 (got %s)", o->fps);
            return -1;
        }
        pic->fps = x;
    }
    if (o->camera) {
        char why[512];
        if (camera_spec_parse(o->camera, &pic->cam, why, sizeof why) != 0) {
            cli_error("--camera: %s", why);
            return -1;
        }
    }
    if (o->radius) {
        if (parse_positive(o->radius, &x) != 0) {
            cli_error("--radius: must be a finite number > 0 (got %s)", o->radius);
            return -1;
        }
        set->render_radius = x;
    }
    const char *lone = o->fps ? "--fps" : o->camera ? "--camera" : o->radius ? "--radius" : NULL;
    if (lone && !rendering) {
        cli_error("%s: only with --render (or output.render)", lone);
        return -1;
    }
    if (rendering) {
        char why[512];
        if (sink_kind_of(set->render, &pic->kind, why, sizeof why) != 0) {
            cli_error("%s %s: %s", render_label, set->render, why);
            return -1;
        }
        if (pic->kind == SINK_MP4 && (pic->width % 2 || pic->height % 2)) {
            cli_error("--size: .mp4 (H.264, yuv420p) needs an even width and height (got %dx%d)", pic->width,
                      pic->height);
            return -1;
        }
    }
    if (o->plot && strcmp(extension(o->plot), ".png") != 0) {
        cli_error("--plot %s: the energy plot is a PNG (got \"%s\"; use a name ending in .png)", o->plot,
                  extension(o->plot));
        return -1;
    }
    return 0;
}

/* ---------------------------------------------------------------- progress */

/* Progress on a terminal only, and only once a run has taken 2 s. */
typedef struct progress {
    int enabled, shown;
    double start, last, phase_start;
} progress;

static void progress_update(progress *p, const psys_run *run, const char *label)
{
    if (!p->enabled)
        return;
    double t = now_seconds();
    if (t - p->start < 2.0 || t - p->last < 0.1)
        return;
    p->last = t;
    p->shown = 1;
    double f = psys_run_progress(run);
    int filled = (int)(f * 30);
    char bar[31];
    for (int i = 0; i < 30; i++)
        bar[i] = i < filled ? '#' : '.';
    bar[30] = '\0';
    double eta = f > 0 ? (t - p->phase_start) * (1 - f) / f : 0;
    fprintf(stderr, "\r[%s] %3d%%  step %lld  eta %.0f s%s ", bar, (int)(f * 100), psys_run_step_index(run), eta,
            label);
    fflush(stderr);
}

static void progress_clear(progress *p)
{
    if (p->shown)
        fprintf(stderr, "\r%72s\r", "");
    p->shown = 0;
}

/* ---------------------------------------------------------------- frames for pictures */

/* Picture frames are taken at simulated times t0 + k/fps: after each step,
 * every k whose time has been reached (the state of the nearest step at or
 * after it) is due. Steps longer than 1/fps repeat a state, so a video
 * keeps time. */
typedef struct frame_clock {
    double t0, fps;
    long long next;
} frame_clock;

static long long frames_due(frame_clock *c, double t)
{
    long long n = 0;
    while (c->t0 + (double)c->next / c->fps <= t + 1e-9 / c->fps) {
        c->next++;
        n++;
    }
    return n;
}

/* ---------------------------------------------------------------- energy plot */

typedef struct energy_series {
    double *t, *ke, *pe, *total;
    size_t n, cap;
    long long stride, skip; /* after thinning, keep every stride-th sample */
    int oom;
} energy_series;

#define ENERGY_MAX_SAMPLES (1u << 20)

static void energy_add(energy_series *e, const psys_system *sys)
{
    if (e->oom)
        return;
    if (e->stride > 1 && (e->skip++ % e->stride) != 0)
        return;
    if (e->n == ENERGY_MAX_SAMPLES) { /* keep every other sample from now on */
        size_t k = 0;
        for (size_t i = 0; i < e->n; i += 2, k++) {
            e->t[k] = e->t[i];
            e->ke[k] = e->ke[i];
            e->pe[k] = e->pe[i];
            e->total[k] = e->total[i];
        }
        e->n = k;
        e->stride = e->stride ? 2 * e->stride : 2;
        e->skip = 1;
    }
    if (e->n == e->cap) {
        size_t nc = e->cap ? 2 * e->cap : 1024;
        double *arr[4] = {e->t, e->ke, e->pe, e->total};
        for (int j = 0; j < 4; j++) {
            double *q = realloc(arr[j], nc * sizeof *q);
            if (!q) {
                e->oom = 1;
                return;
            }
            arr[j] = q;
            switch (j) {
            case 0: e->t = q; break;
            case 1: e->ke = q; break;
            case 2: e->pe = q; break;
            default: e->total = q; break;
            }
        }
        e->cap = nc;
    }
    double ke = psys_system_kinetic_energy(sys), pe = psys_system_potential_energy(sys);
    e->t[e->n] = psys_system_time(sys);
    e->ke[e->n] = ke;
    e->pe[e->n] = pe;
    e->total[e->n] = ke + pe;
    e->n++;
}

static void energy_free(energy_series *e)
{
    free(e->t);
    free(e->ke);
    free(e->pe);
    free(e->total);
    memset(e, 0, sizeof *e);
}

static int energy_plot(energy_series *e, outfile *o, const picture_opts *pic, const char *source)
{
    if (e->oom) {
        cli_error("--plot %s: out of memory", o->path ? o->path : "");
        outfile_abort(o);
        return -1;
    }
    plot_series s[3] = {{"kinetic", e->t, e->ke, e->n}, {"potential", e->t, e->pe, e->n},
                        {"total", e->t, e->total, e->n}};
    char title[300];
    const char *base = strrchr(source, '/') ? strrchr(source, '/') + 1 : source;
    snprintf(title, sizeof title, "%s: energy", base);
    plot_spec spec = {pic->width, pic->height, title, "t (s)", "energy (J)"};
    if (plot_write_png(o->fp, &spec, s, 3) != 0) {
        cli_error("--plot: cannot draw or write the plot");
        outfile_abort(o);
        return -1;
    }
    return outfile_commit(o);
}

/* ---------------------------------------------------------------- outputs */

typedef struct outputs {
    traj_format fmt;
    outfile traj;       /* CSV or XYZ: the trajectory; VTP/VTK: the .pvd series */
    char *stem;         /* VTP/VTK: the path without its extension; frames are stem_NNNNNN.ext */
    const char *label;  /* --out or output.trajectory */
    long long vtk_frames;
    outfile energy;
    int plot_on;
    energy_series plot;
} outputs;

/* One VTP/VTK frame file, written under a temporary name and renamed. */
static int write_vtk_frame(outputs *out, const psys_system *sys, long long step)
{
    size_t len = strlen(out->stem) + 40;
    char *name = malloc(len);
    if (!name)
        return -1;
    const char *ext = out->fmt == TRAJ_VTP ? "vtp" : "vtk";
    snprintf(name, len, "%s_%06lld.%s", out->stem, out->vtk_frames, ext);
    outfile o;
    int rc = outfile_open(&o, name, out->label);
    if (rc == 0) {
        rc = (out->fmt == TRAJ_VTP ? psys_vtp_write_frame(o.fp, sys, step) : psys_vtk_write_frame(o.fp, sys, step));
        if (rc != 0)
            outfile_abort(&o);
        else
            rc = outfile_commit(&o);
    }
    if (rc == 0) {
        const char *slash = strrchr(name, '/');
        rc = psys_pvd_write_entry(out->traj.fp, psys_system_time(sys), slash ? slash + 1 : name);
        out->vtk_frames++;
    }
    free(name);
    return rc;
}

static int write_frame(outputs *out, const psys_system *sys, long long step)
{
    if (out->traj.fp) {
        int rc = 0;
        switch (out->fmt) {
        case TRAJ_CSV: rc = psys_csv_write_trajectory_frame(out->traj.fp, sys, step); break;
        case TRAJ_XYZ: rc = psys_xyz_write_frame(out->traj.fp, sys, step); break;
        case TRAJ_VTP:
        case TRAJ_VTK: rc = write_vtk_frame(out, sys, step); break;
        case TRAJ_NONE: break;
        }
        if (rc != 0)
            return -1;
    }
    if (out->energy.fp && psys_csv_write_energy_frame(out->energy.fp, sys, step) != 0)
        return -1;
    if (out->plot_on)
        energy_add(&out->plot, sys);
    return 0;
}

/* The checkpoint file was opened (as a temporary) before the run started,
 * so an unwritable path is a start-up error, not a surprise at the end. */
static int write_checkpoint(outfile *o, const psys_scene *scene, const psys_run *run)
{
    psys_error err;
    psys_resume_state rs = psys_run_resume_state(run);
    char *text = psys_scene_to_string(scene, &rs, &err);
    if (!text) {
        cli_error("--checkpoint %s: %s", o->path, err.message);
        outfile_abort(o);
        return -1;
    }
    fputs(text, o->fp);
    fputc('\n', o->fp);
    free(text);
    return outfile_commit(o);
}

static const char *display_name(const char *path) { return strcmp(path, "-") == 0 ? "<stdin>" : path; }

/* ---------------------------------------------------------------- framing */

/* Bounds of every picture frame of the run, from a copy of the scene run
 * ahead (the same steps: saving and loading a scene is exact). Stops early at
 * a failure or a signal. Returns 0, or -1 with the reason in err if the scene
 * could not be copied (out of memory). */
static int run_bounds(psys_scene *scene, const picture_opts *pic, bounds *b, progress *prog, psys_error *err)
{
    const psys_resume_state *rs = psys_scene_resume_state(scene);
    char *text = psys_scene_to_string(scene, rs->present ? rs : NULL, err);
    if (!text)
        return -1;
    psys_scene *copy = psys_scene_load_string(text, strlen(text), err);
    free(text);
    if (!copy)
        return -1;
    psys_run *run = psys_run_create(copy, err);
    if (!run) {
        psys_scene_destroy(copy);
        return -1;
    }
    psys_system *sys = psys_scene_system(copy);
    frame_clock fc = {psys_system_time(sys), pic->fps, 0};
    frames_due(&fc, psys_system_time(sys));
    bounds_add_system(b, sys);
    prog->phase_start = now_seconds();
    psys_error step_err;
    while (!psys_run_done(run) && !stop_signal) {
        if (psys_run_step(run, &step_err) != PSYS_OK)
            break;
        if (frames_due(&fc, psys_system_time(sys)) > 0)
            bounds_add_system(b, sys);
        progress_update(prog, run, "  (framing)");
    }
    progress_clear(prog);
    psys_run_destroy(run);
    psys_scene_destroy(copy);
    return 0;
}

/* A renderer for the picture options, framing b (or sys's current state when b is NULL or empty). */
static renderer *make_renderer(const picture_opts *pic, const psys_settings *set, const psys_system *sys,
                               const bounds *b)
{
    bounds now;
    if (!b || !b->any) {
        bounds_init(&now, &pic->cam, pic->width, pic->height);
        bounds_add_system(&now, sys);
        b = &now;
    }
    camera cam;
    camera_setup(&cam, &pic->cam, pic->width, pic->height, b);
    double radius = set->render_radius > 0 ? set->render_radius : render_auto_radius(sys, &cam);
    return renderer_create(pic->width, pic->height, &cam, radius);
}

/* Draw the current state once and hand it to the sink as the next k frames;
 * 1 (message printed) on failure. */
static int draw_frames(renderer *ren, sink *snk, const psys_system *sys, long long k, const char *label)
{
    if (k <= 0)
        return 0;
    if (renderer_draw(ren, sys) != 0) {
        cli_error("%s: out of memory drawing a frame", label);
        return 1;
    }
    for (; k > 0; k--)
        if (sink_frame(snk, ren) != 0)
            return 1;
    return 0;
}

/* The scene of the run (SCENE, or the checkpoint of --resume); NULL after
 * printing why not. */
static psys_scene *load_for_run(const run_opts *o)
{
    psys_error err;
    psys_scene *scene = NULL;
    if (o->scene) {
        if (!(scene = psys_scene_load_file(o->scene, &err))) {
            cli_error("%s: %s", display_name(o->scene), err.message);
            return NULL;
        }
    }
    if (o->resume) {
        /* The checkpoint holds the complete system; SCENE, if given, was only validated. */
        psys_scene_destroy(scene);
        if (!(scene = psys_scene_load_file(o->resume, &err))) {
            cli_error("%s: %s", display_name(o->resume), err.message);
            return NULL;
        }
        if (!psys_scene_resume_state(scene)->present) {
            cli_error("%s: checkpoint: required key missing (not a checkpoint written by --checkpoint)",
                      display_name(o->resume));
            psys_scene_destroy(scene);
            return NULL;
        }
        /* A resumed run writes only the outputs asked for now: reusing the
         * paths stored in the checkpoint would overwrite the first run's files. */
        psys_settings *rset = psys_scene_settings(scene);
        rset->trajectory[0] = rset->energy[0] = rset->render[0] = '\0';
    }
    return scene;
}

#ifdef PSYS_MPI
/* The scene file's own text when rank 0's scene is exactly what it loads
 * to (a plain scene file, read again: structures stay unexpanded, so the
 * text is short and quick to parse); NULL otherwise. On success *scene is
 * replaced by the scene parsed from that text, so every rank parses the
 * same bytes. */
static char *scene_file_text(const run_opts *o, psys_scene **scene, long long *len)
{
    if (o->resume || !o->scene || strcmp(o->scene, "-") == 0)
        return NULL;
    FILE *fp = fopen(o->scene, "rb");
    size_t n = 0;
    char *text = fp ? cli_read_all(fp, &n) : NULL;
    if (fp)
        fclose(fp);
    psys_error err;
    psys_scene *again = text ? psys_scene_load_string(text, n, &err) : NULL;
    if (!again) { /* the file changed or vanished: pass the loaded scene instead */
        free(text);
        return NULL;
    }
    psys_scene_destroy(*scene);
    *scene = again;
    *len = (long long)n;
    return text;
}

/* Rank 0's scene (NULL: it failed) to every rank: the scene file's text, or
 * for a checkpoint or standard input the exact scene text a checkpoint
 * holds (saving and loading is exact, DESIGN §2). Every rank returns its
 * scene, or NULL when any rank has none. */
static psys_scene *share_scene(const run_opts *o, psys_scene *scene)
{
    psys_error err;
    char *text = NULL;
    long long len = -1;
    if (mpi_rank == 0 && scene && !(text = scene_file_text(o, &scene, &len))) {
        const psys_resume_state *rs = psys_scene_resume_state(scene);
        if (!(text = psys_scene_to_string(scene, rs->present ? rs : NULL, &err)))
            cli_error("cannot pass the scene to the other MPI ranks: %s", err.message);
        else
            len = (long long)strlen(text);
    }
    MPI_Bcast(&len, 1, MPI_LONG_LONG, 0, MPI_COMM_WORLD);
    int ok = len >= 0;
    if (ok && mpi_rank != 0 && !(text = malloc((size_t)len + 1)))
        ok = 0;
    int all = 0;
    MPI_Allreduce(&ok, &all, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
    if (all) {
        for (long long at = 0; at < len; at += 1 << 30) {
            long long chunk = len - at < (1 << 30) ? len - at : (1 << 30);
            MPI_Bcast(text + at, (int)chunk, MPI_CHAR, 0, MPI_COMM_WORLD);
        }
        text[len] = '\0';
        if (mpi_rank != 0 && !(scene = psys_scene_load_string(text, (size_t)len, &err)))
            ok = 0;
        MPI_Allreduce(&ok, &all, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
    }
    free(text);
    if (!all) {
        if (len >= 0)
            cli_error("the other MPI ranks could not take the scene (out of memory?)");
        psys_scene_destroy(scene);
        return NULL;
    }
    return scene;
}
#endif

/* ---------------------------------------------------------------- psys run */

/* Parse-only entry point (fuzz/fuzz_cli.c): the options of `psys run` checked
 * and applied to set as cmd_run does (for a 3-D scene), with no scene loaded
 * and no file touched. */
int cmd_run_parse(int argc, char **argv, psys_settings *set)
{
    run_opts o;
    picture_opts pic;
    return parse_args(argc, argv, &o) != 0 || apply_flags(&o, set, 3, &pic) != 0 ? EXIT_BAD_INPUT : EXIT_OK;
}

/* Open every output before the first step; on failure nothing is left behind. */
static int open_outputs(const run_opts *o, const psys_settings *set, const picture_opts *pic, outputs *out,
                        outfile *ck, outfile *plot, sink **snk)
{
    out->fmt = pic->traj;
    out->label = o->out ? "--out" : "output.trajectory";
    const char *traj_path = set->trajectory[0] ? set->trajectory : NULL;
    char *pvd = NULL;
    if (out->fmt == TRAJ_VTP || out->fmt == TRAJ_VTK) {
        size_t stem_len = strlen(set->trajectory) - 4;
        out->stem = malloc(stem_len + 1);
        pvd = malloc(stem_len + 5);
        if (!out->stem || !pvd) {
            free(pvd);
            cli_error("out of memory");
            return -1;
        }
        memcpy(out->stem, set->trajectory, stem_len);
        out->stem[stem_len] = '\0';
        snprintf(pvd, stem_len + 5, "%s.pvd", out->stem);
        traj_path = pvd;
    }
    const char *render_path = set->render[0] && pic->kind != SINK_PATTERN ? set->render : NULL;
    /* Two outputs written to one file would silently clobber each other,
     * and an output naming the scene read would replace it (a checkpoint
     * may: it is a scene, and `--resume ck.json --checkpoint ck.json` goes
     * on in place). */
    const char *paths[5] = {traj_path, set->energy[0] ? set->energy : NULL, o->checkpoint, render_path, o->plot};
    static const char *const what[5] = {"the trajectory", "the energy file", "the checkpoint", "the picture",
                                        "the plot"};
    const char *inputs[2] = {o->scene && strcmp(o->scene, "-") != 0 ? o->scene : NULL, o->resume};
    for (int i = 0; i < 5; i++) {
        for (int j = i + 1; j < 5; j++)
            if (cli_same_file(paths[i], paths[j])) {
                cli_error("%s: the trajectory, energy, checkpoint, render and plot files must be different files",
                          paths[i]);
                free(pvd);
                return -1;
            }
        for (int k = 0; k < 2 && i != 2; k++)
            if (cli_same_file(paths[i], inputs[k])) {
                cli_error("%s: %s would replace the %s it reads", paths[i], what[i], k ? "checkpoint" : "scene");
                free(pvd);
                return -1;
            }
    }
    const char *energy_label = o->energy ? "--energy" : "output.energy";
    int bad = (traj_path && outfile_open(&out->traj, traj_path, out->label) != 0)
              || (set->energy[0] && outfile_open(&out->energy, set->energy, energy_label) != 0)
              || (o->checkpoint && outfile_open(ck, o->checkpoint, "--checkpoint") != 0)
              || (o->plot && outfile_open(plot, o->plot, "--plot") != 0);
    free(pvd);
    if (!bad && set->render[0]
        && !(*snk = sink_open(set->render, o->render ? "--render" : "output.render", pic->width, pic->height,
                              pic->fps)))
        bad = 1;
    return bad ? -1 : 0;
}

static void abort_outputs(outputs *out, outfile *ck, outfile *plot, sink *snk)
{
    outfile_abort(&out->traj);
    outfile_abort(&out->energy);
    outfile_abort(ck);
    outfile_abort(plot);
    sink_abort(snk);
    free(out->stem);
    out->stem = NULL;
    energy_free(&out->plot);
}

/* Rank 0's system gets the decomposed run's state (collective); 1 on failure. */
static int gather_state(psys_run *run)
{
#ifdef PSYS_MPI
    psys_error e;
    if (psys_run_gather(run, &e) != PSYS_OK) {
        cli_error("%s", e.message);
        return 1;
    }
#else
    (void)run;
#endif
    return 0;
}

static int run_main(int argc, char **argv)
{
    run_opts o;
    if (parse_args(argc, argv, &o) != 0)
        return EXIT_BAD_INPUT;
    const char *source = display_name(o.resume ? o.resume : o.scene);
    psys_scene *scene = mpi_rank == 0 ? load_for_run(&o) : NULL;
#ifdef PSYS_MPI
    if (mpi_size > 1)
        scene = share_scene(&o, scene);
#endif
    if (!scene)
        return EXIT_BAD_INPUT;
    psys_error err;
    psys_settings *set = psys_scene_settings(scene);
    psys_system *sys = psys_scene_system(scene);
    picture_opts pic;
    if (apply_flags(&o, set, psys_system_dim(sys), &pic) != 0) {
        psys_scene_destroy(scene);
        return EXIT_BAD_INPUT;
    }
    psys_run *run = psys_run_create(scene, &err);
    if (!run) {
        cli_error("%s: %s", source, err.message);
        psys_scene_destroy(scene);
        return EXIT_BAD_INPUT;
    }
    cli_stability_warning(source, scene, o.quiet);
    if (o.threads) { /* validated by apply_flags; results are the same for every count */
        long long nthreads = 1;
        parse_int(o.threads, 1, 4096, &nthreads);
        psys_system_set_threads(sys, (int)nthreads);
    }
    bool decomposed = false; /* the particles spread over the MPI ranks (psys_run_decompose) */
#ifdef PSYS_MPI
    if (mpi_size > 1) {
        if (!o.threads)
            psys_system_set_threads(sys, 1); /* a rank per core; --threads asks for more */
        if (!o.mpi || strcmp(o.mpi, "replicated") != 0) {
            psys_status st = psys_run_decompose(run, MPI_COMM_WORLD, &err);
            decomposed = st == PSYS_OK;
            if (st != PSYS_OK && (st != PSYS_ERR_UNSUPPORTED || (o.mpi && strcmp(o.mpi, "domain") == 0))) {
                cli_error("%s: --mpi domain: %s", source, err.message);
                psys_run_destroy(run);
                psys_scene_destroy(scene);
                return st == PSYS_ERR_UNSUPPORTED ? EXIT_BAD_INPUT : EXIT_RUN_FAILED;
            }
        }
        if (!decomposed && psys_system_set_comm(sys, MPI_COMM_WORLD) != PSYS_OK) {
            cli_error("%s: %s", source, psys_system_last_error(sys));
            psys_run_destroy(run);
            psys_scene_destroy(scene);
            return EXIT_RUN_FAILED;
        }
        if (mpi_rank != 0) { /* rank 0 writes every file */
            set->trajectory[0] = set->energy[0] = set->render[0] = '\0';
            o.checkpoint = o.plot = NULL;
            pic.traj = TRAJ_NONE;
            o.quiet = 1;
        }
    }
#endif
    outputs out;
    outfile ck, plot_out;
    sink *snk = NULL;
    memset(&out, 0, sizeof out);
    memset(&ck, 0, sizeof ck);
    memset(&plot_out, 0, sizeof plot_out);
    if (agree(open_outputs(&o, set, &pic, &out, &ck, &plot_out, &snk)) != 0) {
        abort_outputs(&out, &ck, &plot_out, snk);
        psys_run_destroy(run);
        psys_scene_destroy(scene);
        return EXIT_BAD_INPUT;
    }
    out.plot_on = o.plot != NULL;
    if (out.fmt == TRAJ_CSV)
        psys_csv_write_trajectory_header(out.traj.fp, psys_system_dim(sys));
    if (out.fmt == TRAJ_VTP || out.fmt == TRAJ_VTK)
        psys_pvd_write_header(out.traj.fp);
    if (out.energy.fp)
        psys_csv_write_energy_header(out.energy.fp);

    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);

    progress prog = {!o.quiet && isatty(STDERR_FILENO), 0, now_seconds(), 0, now_seconds()};
    int status = EXIT_OK, io_failed = 0;

    /* Pictures: frame the run (a framing pass, unless the camera is fixed or
     * fit=start), then draw frames at t0 + k/fps as the run passes them. The
     * single PNG is framed and drawn at the end. */
    renderer *ren = NULL;
    frame_clock fc = {psys_system_time(sys), pic.fps, 0};
    int framing_failed = 0;
    if (snk && sink_takes_frames(snk)) {
        bounds b;
        bounds_init(&b, &pic.cam, pic.width, pic.height);
        bool framed = !camera_needs_run_bounds(&pic.cam) || run_bounds(scene, &pic, &b, &prog, &err) == 0;
        if (!framed)
            cli_error("%s: cannot frame the run: %s", o.render ? "--render" : "output.render", err.message);
        else if (!(ren = make_renderer(&pic, set, sys, &b)))
            cli_error("%s: out of memory for a %dx%d picture", o.render ? "--render" : "output.render", pic.width,
                      pic.height);
        framing_failed = !ren;
    }
    if (agree(framing_failed)) {
        abort_outputs(&out, &ck, &plot_out, snk);
        psys_run_destroy(run);
        psys_scene_destroy(scene);
        return EXIT_RUN_FAILED;
    }
    prog.phase_start = now_seconds();

    /* The single PNG is framed at the end: by the initial state (fit=start)
     * or by the frames a video would have shown, gathered on the way. */
    bounds still_bounds;
    bool still = snk && !sink_takes_frames(snk);
    bounds_init(&still_bounds, &pic.cam, pic.width, pic.height);
    if (still) {
        bounds_add_system(&still_bounds, sys);
        frames_due(&fc, psys_system_time(sys));
    }
    int pic_failed = 0;
    long long last_written = psys_run_step_index(run);
    io_failed |= write_frame(&out, sys, last_written);
    const char *render_label = o.render ? "--render" : "output.render";
    if (ren)
        pic_failed = draw_frames(ren, snk, sys, frames_due(&fc, psys_system_time(sys)), render_label);
    /* Decomposed: rank 0's system has the state only after a gather, at
     * frames, and at every step when pictures are drawn. */
    const int gather_each_step = agree(ren != NULL || still);
    const int gather_frames = agree(out.traj.fp != NULL || out.energy.fp != NULL || out.plot_on);
    long long gathered = psys_run_step_index(run);
    while (!psys_run_done(run) && agree(!stop_signal && !io_failed && !pic_failed)) {
        if (psys_run_step(run, &err) != PSYS_OK) {
            status = EXIT_RUN_FAILED;
            break;
        }
        if (decomposed && (gather_each_step || (gather_frames && psys_run_is_frame(run)))) {
            io_failed |= gather_state(run);
            gathered = psys_run_step_index(run);
        }
        if (psys_run_is_frame(run)) {
            last_written = psys_run_step_index(run);
            io_failed |= write_frame(&out, sys, last_written);
        }
        if (still && !pic.cam.fit_start && frames_due(&fc, psys_system_time(sys)) > 0)
            bounds_add_system(&still_bounds, sys);
        if (ren)
            pic_failed = draw_frames(ren, snk, sys, frames_due(&fc, psys_system_time(sys)), render_label);
        progress_update(&prog, run, "");
    }
    progress_clear(&prog);
    if (decomposed && gathered != psys_run_step_index(run))
        io_failed |= gather_state(run);
    /* The last good state is always the final frame (interrupted or failed runs too). */
    if (psys_run_step_index(run) != last_written)
        io_failed |= write_frame(&out, sys, psys_run_step_index(run));
    if (status == EXIT_RUN_FAILED)
        cli_error("%s: %s", source, err.message);
    const psys_solver *solver = psys_run_solver(run);
    if (psys_solver_cg_unconverged(solver) && !o.quiet)
        cli_error("%s: warning: conjugate gradient stopped short of cg_tolerance in %zu steps (worst relative "
                  "residual %.3g); raise cg_max_iterations or lower dt",
                  source, psys_solver_cg_unconverged(solver), psys_solver_cg_worst_residual(solver));
    if (io_failed)
        cli_error("cannot write the output files (disk full?)");
    if (out.fmt == TRAJ_VTP || out.fmt == TRAJ_VTK)
        psys_pvd_write_footer(out.traj.fp);
    int rc = outfile_commit(&out.traj);
    rc |= outfile_commit(&out.energy);
    if (o.checkpoint)
        rc |= write_checkpoint(&ck, scene, run);
    if (o.plot)
        rc |= energy_plot(&out.plot, &plot_out, &pic, source);
    if (snk) {
        if (!sink_takes_frames(snk)) {
            /* The last frame. */
            if (!pic.cam.fit_start)
                bounds_add_system(&still_bounds, sys);
            ren = make_renderer(&pic, set, sys, &still_bounds);
            if (!ren || renderer_draw(ren, sys) != 0) {
                cli_error("%s: out of memory for a %dx%d picture", render_label, pic.width, pic.height);
                sink_abort(snk);
                rc = -1;
            } else {
                rc |= sink_close(snk, ren);
            }
        } else {
            rc |= sink_close(snk, ren);
        }
    }
    renderer_destroy(ren);
    free(out.stem);
    energy_free(&out.plot);
    if ((rc || io_failed || pic_failed) && status == EXIT_OK)
        status = EXIT_RUN_FAILED;
    if (stop_signal) {
        if (!o.quiet)
            cli_error("%s: interrupted at step %lld (t = %.17g); files hold every frame up to it", source,
                      psys_run_step_index(run), psys_system_time(sys));
        status = 128 + stop_signal;
    }
    status = agree(status);
    psys_run_destroy(run);
    psys_scene_destroy(scene);
    return status;
}

/* `psys run`; in an MPI build also under `mpiexec -n R psys run ...`
 * (docs/mpi.md). Run without mpiexec it is one rank: the serial run. */
int cmd_run(int argc, char **argv)
{
#ifdef PSYS_MPI
    int inited = 0;
    MPI_Initialized(&inited);
    if (!inited)
        MPI_Init(NULL, NULL);
    MPI_Comm_rank(MPI_COMM_WORLD, &mpi_rank);
    MPI_Comm_size(MPI_COMM_WORLD, &mpi_size);
    cli_silent = mpi_rank != 0;
    int status = run_main(argc, argv);
    if (!inited)
        MPI_Finalize();
    return status;
#else
    return run_main(argc, argv);
#endif
}
