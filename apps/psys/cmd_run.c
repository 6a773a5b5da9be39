/* psys run: load, override, step, write frames, checkpoint (DESIGN §3, §3a). */
#include "cli.h"

#include <math.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

static volatile sig_atomic_t stop_signal = 0;

static void on_signal(int sig) { stop_signal = sig; }

typedef struct run_opts {
    const char *scene;
    const char *dt, *steps, *duration, *integrator, *every, *out, *energy, *render, *threads;
    const char *checkpoint, *resume;
    int quiet;
} run_opts;

static double now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* "--name VALUE" or "--name=VALUE"; returns 1 if argv[*i] is this option. */
static int take(int argc, char **argv, int *i, const char *name, const char **val, int *bad)
{
    size_t n = strlen(name);
    if (strncmp(argv[*i], name, n) != 0)
        return 0;
    if (argv[*i][n] == '=') {
        *val = argv[*i] + n + 1;
        return 1;
    }
    if (argv[*i][n] != '\0')
        return 0;
    if (*i + 1 >= argc) {
        cli_error("%s needs a value (see psys --help)", name);
        *bad = 1;
        return 1;
    }
    *val = argv[++*i];
    return 1;
}

static int parse_args(int argc, char **argv, run_opts *o)
{
    memset(o, 0, sizeof *o);
    for (int i = 1; i < argc; i++) {
        int bad = 0;
        const char *a = argv[i];
        if (take(argc, argv, &i, "--dt", &o->dt, &bad) || take(argc, argv, &i, "--steps", &o->steps, &bad)
            || take(argc, argv, &i, "--duration", &o->duration, &bad)
            || take(argc, argv, &i, "--integrator", &o->integrator, &bad)
            || take(argc, argv, &i, "--every", &o->every, &bad) || take(argc, argv, &i, "--out", &o->out, &bad)
            || take(argc, argv, &i, "--energy", &o->energy, &bad)
            || take(argc, argv, &i, "--render", &o->render, &bad)
            || take(argc, argv, &i, "--threads", &o->threads, &bad)
            || take(argc, argv, &i, "--checkpoint", &o->checkpoint, &bad)
            || take(argc, argv, &i, "--resume", &o->resume, &bad)) {
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

/* Apply command-line overrides to the scene's settings (flags win). */
static int apply_flags(const run_opts *o, psys_settings *set)
{
    long long n;
    double x;
    if (o->integrator) {
        if (!psys_solver_exists(o->integrator)) {
            char known[256] = "";
            for (size_t i = 0; psys_solver_name_at(i); i++)
                snprintf(known + strlen(known), sizeof known - strlen(known), "%s%s", i ? ", " : "",
                         psys_solver_name_at(i));
            cli_error("--integrator: unknown integrator (got %s; known: %s)", o->integrator, known);
            return -1;
        }
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
    const char *traj_label = o->out ? "--out" : "output.trajectory";
    if (set->trajectory[0]) {
        const char *ext = extension(set->trajectory);
        if (strcmp(ext, ".vtk") == 0 || strcmp(ext, ".vtp") == 0 || strcmp(ext, ".xyz") == 0) {
            cli_error("%s %s: the %s format is not available in this version of psys yet (use .csv)", traj_label,
                      set->trajectory, ext);
            return -1;
        }
        if (strcmp(ext, ".csv") != 0) {
            cli_error("%s %s: unknown trajectory format (got \"%s\"; use .csv)", traj_label, set->trajectory, ext);
            return -1;
        }
    }
    if (set->render[0]) {
        cli_error("%s %s: rendering is not available in this version of psys yet", o->render ? "--render" : "output.render",
                  set->render);
        return -1;
    }
    return 0;
}

/* Progress on a terminal only, and only once a run has taken 2 s. */
typedef struct progress {
    int enabled, shown;
    double start, last;
} progress;

static void progress_update(progress *p, const psys_run *run)
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
    double eta = f > 0 ? (t - p->start) * (1 - f) / f : 0;
    fprintf(stderr, "\r[%s] %3d%%  step %lld  eta %.0f s ", bar, (int)(f * 100), psys_run_step_index(run), eta);
    fflush(stderr);
}

static void progress_clear(progress *p)
{
    if (p->shown)
        fprintf(stderr, "\r%60s\r", "");
}

typedef struct outputs {
    outfile traj, energy;
} outputs;

static int write_frame(outputs *out, const psys_system *sys, long long step)
{
    if (out->traj.fp && psys_csv_write_trajectory_frame(out->traj.fp, sys, step) != 0)
        return -1;
    if (out->energy.fp && psys_csv_write_energy_frame(out->energy.fp, sys, step) != 0)
        return -1;
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

/* Two outputs written to one file would silently clobber each other. */
static int same_path(const char *a, const char *b) { return a && b && a[0] && strcmp(a, b) == 0; }

static const char *display_name(const char *path) { return strcmp(path, "-") == 0 ? "<stdin>" : path; }

int cmd_run(int argc, char **argv)
{
    run_opts o;
    if (parse_args(argc, argv, &o) != 0)
        return EXIT_BAD_INPUT;
    psys_error err;
    psys_scene *scene = NULL;
    if (o.scene) {
        if (!(scene = psys_scene_load_file(o.scene, &err))) {
            cli_error("%s: %s", display_name(o.scene), err.message);
            return EXIT_BAD_INPUT;
        }
    }
    const char *source = o.scene ? display_name(o.scene) : NULL;
    if (o.resume) {
        /* The checkpoint holds the complete system; SCENE, if given, was only validated. */
        psys_scene_destroy(scene);
        if (!(scene = psys_scene_load_file(o.resume, &err))) {
            cli_error("%s: %s", display_name(o.resume), err.message);
            return EXIT_BAD_INPUT;
        }
        source = display_name(o.resume);
        if (!psys_scene_resume_state(scene)->present) {
            cli_error("%s: checkpoint: required key missing (not a checkpoint written by --checkpoint)", source);
            psys_scene_destroy(scene);
            return EXIT_BAD_INPUT;
        }
        /* A resumed run writes only the outputs asked for now: reusing the
         * paths stored in the checkpoint would overwrite the first run's files. */
        psys_settings *rset = psys_scene_settings(scene);
        rset->trajectory[0] = rset->energy[0] = rset->render[0] = '\0';
    }
    psys_settings *set = psys_scene_settings(scene);
    if (apply_flags(&o, set) != 0) {
        psys_scene_destroy(scene);
        return EXIT_BAD_INPUT;
    }
    psys_run *run = psys_run_create(scene, &err);
    if (!run) {
        cli_error("%s: %s", source, err.message);
        psys_scene_destroy(scene);
        return EXIT_BAD_INPUT;
    }
    psys_system *sys = psys_scene_system(scene);
    outputs out;
    outfile ck;
    memset(&out, 0, sizeof out);
    memset(&ck, 0, sizeof ck);
    const char *traj_label = o.out ? "--out" : "output.trajectory";
    const char *energy_label = o.energy ? "--energy" : "output.energy";
    int clash = same_path(set->trajectory, set->energy) || same_path(set->trajectory, o.checkpoint)
                || same_path(set->energy, o.checkpoint);
    if (clash)
        cli_error("%s: the trajectory, energy and checkpoint files must be different files",
                  same_path(set->energy, o.checkpoint) ? set->energy : set->trajectory);
    if (clash || (set->trajectory[0] && outfile_open(&out.traj, set->trajectory, traj_label) != 0)
        || (set->energy[0] && outfile_open(&out.energy, set->energy, energy_label) != 0)
        || (o.checkpoint && outfile_open(&ck, o.checkpoint, "--checkpoint") != 0)) {
        outfile_abort(&out.traj);
        outfile_abort(&out.energy);
        outfile_abort(&ck);
        psys_run_destroy(run);
        psys_scene_destroy(scene);
        return EXIT_BAD_INPUT;
    }
    if (out.traj.fp)
        psys_csv_write_trajectory_header(out.traj.fp, psys_system_dim(sys));
    if (out.energy.fp)
        psys_csv_write_energy_header(out.energy.fp);

    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);

    progress prog = {!o.quiet && isatty(STDERR_FILENO), 0, now_seconds(), 0};
    int status = EXIT_OK, io_failed = 0;
    long long last_written = psys_run_step_index(run);
    io_failed |= write_frame(&out, sys, last_written);
    while (!psys_run_done(run) && !stop_signal && !io_failed) {
        if (psys_run_step(run, &err) != PSYS_OK) {
            status = EXIT_RUN_FAILED;
            break;
        }
        if (psys_run_is_frame(run)) {
            last_written = psys_run_step_index(run);
            io_failed |= write_frame(&out, sys, last_written);
        }
        progress_update(&prog, run);
    }
    progress_clear(&prog);
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
    int rc = outfile_commit(&out.traj);
    rc |= outfile_commit(&out.energy);
    if (o.checkpoint)
        rc |= write_checkpoint(&ck, scene, run);
    if ((rc || io_failed) && status == EXIT_OK)
        status = EXIT_RUN_FAILED;
    if (stop_signal) {
        if (!o.quiet)
            cli_error("%s: interrupted at step %lld (t = %.17g); files hold every frame up to it", source,
                      psys_run_step_index(run), psys_system_time(sys));
        status = 128 + stop_signal;
    }
    psys_run_destroy(run);
    psys_scene_destroy(scene);
    return status;
}
