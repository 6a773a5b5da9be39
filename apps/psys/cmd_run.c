/* psys run: load the scene, apply the flags (run_options.c), open the
 * outputs (run_outputs.c), step, and commit the files (docs/cli.md). */
#include "cli.h"
#include "render.h"
#include "run_options.h"
#include "run_outputs.h"

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

static double now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
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
 * holds (saving and loading is exact, docs/scene-format.md#saving-a-scene-back).
 * Every rank returns its
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

/* ---------------------------------------------------------------- psys run */

/* One `psys run`, from the loaded scene to the files written. */
typedef struct run_state {
    run_opts o;
    const char *source; /* the scene's name in messages */
    psys_scene *scene;
    psys_settings *set;
    psys_system *sys;
    psys_run *run;
    picture_opts pic;
    bool decomposed; /* the particles spread over the MPI ranks (psys_run_decompose) */
    run_outputs out;
    progress prog;
    psys_error err;
    int status, io_failed, pic_failed;
    long long last_written; /* the step of the last frame written */
} run_state;

#ifdef PSYS_MPI
/* Several ranks: the particles spread over them (unless --mpi replicated,
 * or the scene cannot be spread and --mpi domain was not asked for), and
 * every output left to rank 0. EXIT_OK, or an exit status (message printed). */
static int setup_mpi(run_state *s)
{
    if (!s->o.threads)
        psys_system_set_threads(s->sys, 1); /* a rank per core; --threads asks for more */
    if (!s->o.mpi || strcmp(s->o.mpi, "replicated") != 0) {
        psys_status st = psys_run_decompose(s->run, MPI_COMM_WORLD, &s->err);
        s->decomposed = st == PSYS_OK;
        if (st != PSYS_OK && (st != PSYS_ERR_UNSUPPORTED || (s->o.mpi && strcmp(s->o.mpi, "domain") == 0))) {
            cli_error("%s: --mpi domain: %s", s->source, s->err.message);
            return st == PSYS_ERR_UNSUPPORTED ? EXIT_BAD_INPUT : EXIT_RUN_FAILED;
        }
    }
    if (!s->decomposed && psys_system_set_comm(s->sys, MPI_COMM_WORLD) != PSYS_OK) {
        cli_error("%s: %s", s->source, psys_system_last_error(s->sys));
        return EXIT_RUN_FAILED;
    }
    if (mpi_rank != 0) { /* rank 0 writes every file */
        s->set->trajectory[0] = s->set->energy[0] = s->set->render[0] = '\0';
        s->o.checkpoint = s->o.plot = NULL;
        s->pic.traj = TRAJ_NONE;
        s->o.quiet = 1;
    }
    return EXIT_OK;
}
#endif

/* The scene (read by rank 0, shared with the others), the flags applied to
 * it, and the run. EXIT_OK, or an exit status (message printed). */
static int prepare(run_state *s)
{
    s->source = display_name(s->o.resume ? s->o.resume : s->o.scene);
    s->scene = mpi_rank == 0 ? load_for_run(&s->o) : NULL;
#ifdef PSYS_MPI
    if (mpi_size > 1)
        s->scene = share_scene(&s->o, s->scene);
#endif
    if (!s->scene)
        return EXIT_BAD_INPUT;
    s->set = psys_scene_settings(s->scene);
    s->sys = psys_scene_system(s->scene);
    if (run_options_apply(&s->o, s->set, psys_system_dim(s->sys), &s->pic) != 0)
        return EXIT_BAD_INPUT;
    if (!(s->run = psys_run_create(s->scene, &s->err))) {
        cli_error("%s: %s", s->source, s->err.message);
        return EXIT_BAD_INPUT;
    }
    cli_stability_warning(s->source, s->scene, s->o.quiet);
    if (s->o.threads) { /* validated by run_options_apply; results are the same for every count */
        long long nthreads = 1;
        parse_int(s->o.threads, 1, 4096, &nthreads);
        psys_system_set_threads(s->sys, (int)nthreads);
    }
#ifdef PSYS_MPI
    if (mpi_size > 1)
        return setup_mpi(s);
#endif
    return EXIT_OK;
}

/* A video is framed before the run: by a framing pass over a copy of the run,
 * unless the camera is fixed or fit=start. 1 (message printed) on failure. */
static int frame_video(run_state *s)
{
    if (!run_outputs_takes_frames(&s->out))
        return 0;
    bounds b;
    bounds_init(&b, &s->pic.cam, s->pic.width, s->pic.height);
    if (camera_needs_run_bounds(&s->pic.cam) && run_bounds(s->scene, &s->pic, &b, &s->prog, &s->err) != 0) {
        cli_error("%s: cannot frame the run: %s", s->out.render_label, s->err.message);
        return 1;
    }
    return run_outputs_frame_video(&s->out, s->sys, &b);
}

/* Every output opened, SIGINT and SIGTERM caught (the run stops at the next
 * step and keeps its files), a video framed. EXIT_OK, or an exit status
 * (message printed, nothing left behind). */
static int start(run_state *s)
{
    if (agree(run_outputs_open(&s->out, &s->o, s->set, &s->pic, psys_system_dim(s->sys))) != 0) {
        run_outputs_abort(&s->out);
        return EXIT_BAD_INPUT;
    }
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    s->prog = (progress){!s->o.quiet && isatty(STDERR_FILENO), 0, now_seconds(), 0, now_seconds()};
    if (agree(frame_video(s))) {
        run_outputs_abort(&s->out);
        return EXIT_RUN_FAILED;
    }
    s->prog.phase_start = now_seconds();
    return EXIT_OK;
}

/* Step to the end, or to a failed step, a signal or a failed write, writing
 * frames and drawing pictures on the way; the last state reached is always
 * the final frame. */
static void step_all(run_state *s)
{
    s->last_written = psys_run_step_index(s->run);
    s->io_failed |= run_outputs_write_frame(&s->out, s->sys, s->last_written);
    s->pic_failed = run_outputs_first_pictures(&s->out, s->sys);
    /* Decomposed: rank 0's system has the state only after a gather, at
     * frames, and at every step when pictures are drawn. */
    const int gather_each_step = agree(s->out.ren != NULL || s->out.still);
    const int gather_frames = agree(run_outputs_writes_frames(&s->out));
    long long gathered = psys_run_step_index(s->run);
    while (!psys_run_done(s->run) && agree(!stop_signal && !s->io_failed && !s->pic_failed)) {
        if (psys_run_step(s->run, &s->err) != PSYS_OK) {
            s->status = EXIT_RUN_FAILED;
            break;
        }
        if (s->decomposed && (gather_each_step || (gather_frames && psys_run_is_frame(s->run)))) {
            s->io_failed |= gather_state(s->run);
            gathered = psys_run_step_index(s->run);
        }
        if (psys_run_is_frame(s->run)) {
            s->last_written = psys_run_step_index(s->run);
            s->io_failed |= run_outputs_write_frame(&s->out, s->sys, s->last_written);
        }
        s->pic_failed = run_outputs_pictures(&s->out, s->sys);
        progress_update(&s->prog, s->run, "");
    }
    progress_clear(&s->prog);
    if (s->decomposed && gathered != psys_run_step_index(s->run))
        s->io_failed |= gather_state(s->run);
    if (psys_run_step_index(s->run) != s->last_written)
        s->io_failed |= run_outputs_write_frame(&s->out, s->sys, psys_run_step_index(s->run));
}

/* Say how the run ended and commit the outputs; the exit status, the same
 * on every rank. */
static int finish(run_state *s)
{
    if (s->status == EXIT_RUN_FAILED)
        cli_error("%s: %s", s->source, s->err.message);
    const psys_solver *solver = psys_run_solver(s->run);
    if (psys_solver_cg_unconverged(solver) && !s->o.quiet)
        cli_error("%s: warning: conjugate gradient stopped short of cg_tolerance in %zu steps (worst relative "
                  "residual %.3g); raise cg_max_iterations or lower dt",
                  s->source, psys_solver_cg_unconverged(solver), psys_solver_cg_worst_residual(solver));
    if (s->io_failed)
        cli_error("cannot write the output files (disk full?)");
    int rc = run_outputs_commit(&s->out, s->scene, s->run, s->sys, s->source);
    int status = s->status;
    if ((rc || s->io_failed || s->pic_failed) && status == EXIT_OK)
        status = EXIT_RUN_FAILED;
    if (stop_signal) {
        if (!s->o.quiet)
            cli_error("%s: interrupted at step %lld (t = %.17g); files hold every frame up to it", s->source,
                      psys_run_step_index(s->run), psys_system_time(s->sys));
        status = 128 + stop_signal;
    }
    return agree(status);
}

static int run_main(int argc, char **argv)
{
    run_state s;
    memset(&s, 0, sizeof s);
    if (run_options_parse(argc, argv, &s.o) != 0)
        return EXIT_BAD_INPUT;
    int status = prepare(&s);
    if (status == EXIT_OK)
        status = start(&s);
    if (status == EXIT_OK) {
        step_all(&s);
        status = finish(&s);
    }
    psys_run_destroy(s.run);
    psys_scene_destroy(s.scene);
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
