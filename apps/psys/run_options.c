/* psys run's flags: parsed, checked, and applied over the scene's settings
 * (docs/cli.md). Checks run in a fixed order, so a command line with several
 * bad flags always gets the same message. */
#include "run_options.h"

#include <string.h>

int run_options_parse(int argc, char **argv, run_opts *o)
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

const char *run_options_render_label(const run_opts *o) { return o->render ? "--render" : "output.render"; }

static const char *extension(const char *path)
{
    const char *slash = strrchr(path, '/');
    const char *dot = strrchr(slash ? slash : path, '.');
    return dot ? dot : "";
}

/* The solver and stepping flags, and the values only checked here (--threads
 * and --mpi are used once the run exists). */
static int apply_stepping(const run_opts *o, psys_settings *set)
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
    return 0;
}

/* flag over the settings' fixed-size path field; -1 (message printed) when
 * it is empty or does not fit. */
static int copy_path(const char *flag, char *field, size_t cap, const char *name)
{
    if (!flag)
        return 0;
    if (strlen(flag) >= cap || !flag[0]) {
        cli_error("--%s: path must be 1 to %zu characters", name, cap - 1);
        return -1;
    }
    memcpy(field, flag, strlen(flag) + 1);
    return 0;
}

/* The output paths, and the trajectory's format from its extension. */
static int apply_paths(const run_opts *o, psys_settings *set, picture_opts *pic)
{
    if (copy_path(o->out, set->trajectory, sizeof set->trajectory, "trajectory") != 0
        || copy_path(o->energy, set->energy, sizeof set->energy, "energy") != 0
        || copy_path(o->render, set->render, sizeof set->render, "render") != 0)
        return -1;
    if (o->plot && !o->plot[0]) {
        cli_error("--plot: path must not be empty");
        return -1;
    }
    pic->traj = TRAJ_NONE;
    if (!set->trajectory[0])
        return 0;
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
        cli_error("%s %s: unknown trajectory format (got \"%s\"; use .csv, .vtp, .vtk or .xyz)",
                  o->out ? "--out" : "output.trajectory", set->trajectory, ext);
        return -1;
    }
    return 0;
}

/* --size, --fps, --camera and --radius, each only where a picture uses it. */
static int apply_picture(const run_opts *o, psys_settings *set, int dim, picture_opts *pic)
{
    bool rendering = set->render[0] != '\0';
    double x;
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
    return 0;
}

/* The picture's kind from its name (and what that kind needs of the size),
 * and the plot's name. */
static int check_picture_paths(const run_opts *o, const psys_settings *set, picture_opts *pic)
{
    if (set->render[0]) {
        char why[512];
        if (sink_kind_of(set->render, &pic->kind, why, sizeof why) != 0) {
            cli_error("%s %s: %s", run_options_render_label(o), set->render, why);
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

int run_options_apply(const run_opts *o, psys_settings *set, int dim, picture_opts *pic)
{
    if (apply_stepping(o, set) != 0 || apply_paths(o, set, pic) != 0 || apply_picture(o, set, dim, pic) != 0
        || check_picture_paths(o, set, pic) != 0)
        return -1;
    return 0;
}

/* Parse-only entry point (fuzz/fuzz_cli.c): the options of `psys run` checked
 * and applied to set as cmd_run does (for a 3-D scene), with no scene loaded
 * and no file touched. */
int cmd_run_parse(int argc, char **argv, psys_settings *set)
{
    run_opts o;
    picture_opts pic;
    return run_options_parse(argc, argv, &o) != 0 || run_options_apply(&o, set, 3, &pic) != 0 ? EXIT_BAD_INPUT
                                                                                              : EXIT_OK;
}
