/* psys import: turn another program's state into a psys scene.
 *
 *   psys import lammps FILE.data --out SCENE.json [--cutoff RC] [--skin S] [--shift]
 *               [--epsilon E --sigma S] [--dt H] [--steps N] [--integrator NAME]
 *
 * A LAMMPS data file (write_data, atom_style atomic, pair_style lj/cut, an
 * orthogonal box) becomes a 3-D scene with a periodic box, one particle per
 * atom in increasing order of atom id, and one lennard-jones pair force
 * (method grid). The scene is built through the library and written by its
 * saver, so it loads back to exactly the numbers read. docs/cli.md. */
#include "cli.h"
#include "lammps_data.h"

#include <stdlib.h>
#include <string.h>

typedef struct import_opts {
    const char *format, *input, *out;
    const char *cutoff, *skin, *epsilon, *sigma, *dt, *steps, *integrator;
    int shift;
} import_opts;


static const char import_usage[] = "usage: psys import lammps FILE.data --out SCENE.json [options]; see psys --help";

static int parse_args(int argc, char **argv, import_opts *o)
{
    memset(o, 0, sizeof *o);
    for (int i = 1; i < argc; i++) {
        int bad = 0;
        const char *a = argv[i];
        if (cli_take(argc, argv, &i, "--out", &o->out, &bad) || cli_take(argc, argv, &i, "--cutoff", &o->cutoff, &bad)
            || cli_take(argc, argv, &i, "--skin", &o->skin, &bad) || cli_take(argc, argv, &i, "--epsilon", &o->epsilon, &bad)
            || cli_take(argc, argv, &i, "--sigma", &o->sigma, &bad) || cli_take(argc, argv, &i, "--dt", &o->dt, &bad)
            || cli_take(argc, argv, &i, "--steps", &o->steps, &bad)
            || cli_take(argc, argv, &i, "--integrator", &o->integrator, &bad)) {
            if (bad)
                return -1;
        } else if (strcmp(a, "--shift") == 0) {
            o->shift = 1;
        } else if (a[0] == '-' && a[1] != '\0') {
            cli_error("import: unknown option %s (see psys --help)", a);
            return -1;
        } else if (!o->format) {
            o->format = a;
        } else if (!o->input) {
            o->input = a;
        } else {
            cli_error("import: more than one input file given (%s and %s)", o->input, a);
            return -1;
        }
    }
    if (!o->format) {
        cli_error("import: no format given (%s)", import_usage);
        return -1;
    }
    if (strcmp(o->format, "lammps") != 0) {
        cli_error("import: unknown format (got %s; known: lammps)", o->format);
        return -1;
    }
    if (!o->input) {
        cli_error("import: no input file given (%s)", import_usage);
        return -1;
    }
    if (!o->out) {
        cli_error("import: no --out file given (%s)", import_usage);
        return -1;
    }
    if (!o->out[0]) {
        cli_error("--out: path must not be empty");
        return -1;
    }
    if (!o->epsilon != !o->sigma) {
        cli_error("import: give --epsilon and --sigma together");
        return -1;
    }
    return 0;
}

/* Checked option values. */
typedef struct import_values {
    double cutoff, skin, epsilon, sigma, dt;
    long long steps;
    const char *integrator;
} import_values;

static int check_values(const import_opts *o, import_values *v)
{
    v->cutoff = 0;
    v->skin = 0.3;  /* LAMMPS's default neighbor skin in lj units */
    v->dt = 0.005;  /* LAMMPS's default timestep in lj units */
    v->steps = 100; /* in.lj's run */
    v->integrator = "verlet";
    if (o->cutoff && parse_positive(o->cutoff, &v->cutoff) != 0) {
        cli_error("--cutoff: must be a finite number > 0 (got %s)", o->cutoff);
        return -1;
    }
    if (o->skin && parse_nonneg(o->skin, &v->skin) != 0) {
        cli_error("--skin: must be a finite number >= 0 (got %s)", o->skin);
        return -1;
    }
    if (o->epsilon && parse_nonneg(o->epsilon, &v->epsilon) != 0) {
        cli_error("--epsilon: must be a finite number >= 0 (got %s)", o->epsilon);
        return -1;
    }
    if (o->sigma && parse_positive(o->sigma, &v->sigma) != 0) {
        cli_error("--sigma: must be a finite number > 0 (got %s)", o->sigma);
        return -1;
    }
    if (o->dt && parse_positive(o->dt, &v->dt) != 0) {
        cli_error("--dt: must be a finite number > 0 (got %s)", o->dt);
        return -1;
    }
    if (o->steps && parse_int(o->steps, 0, 1000000000000000LL, &v->steps) != 0) {
        cli_error("--steps: must be an integer from 0 to 1e15 (got %s)", o->steps);
        return -1;
    }
    if (o->integrator) {
        if (cli_check_integrator(o->integrator) != 0)
            return -1;
        v->integrator = o->integrator;
    }
    return 0;
}

/* The scene of data d with the options v; NULL (message printed) on failure. */
static psys_scene *build_scene(const char *name, const lmp_data *d, const import_opts *o, const import_values *v)
{
    static const char base[] = "{\"psys\": 1, \"dim\": 3}";
    psys_error err;
    psys_scene *scene = psys_scene_load_string(base, sizeof base - 1, &err);
    if (!scene) {
        cli_error("%s: %s", name, err.message);
        return NULL;
    }
    psys_settings *set = psys_scene_settings(scene);
    snprintf(set->integrator, sizeof set->integrator, "%s", v->integrator);
    set->dt = v->dt;
    set->use_steps = true;
    set->steps = v->steps;
    psys_system *sys = psys_scene_system(scene);
    for (size_t i = 0; i < d->natoms; i++) {
        if (psys_system_add_particle(sys, d->x + 3 * i, d->v + 3 * i, d->mass[d->type[i]], NULL, NULL) != PSYS_OK) {
            cli_error("%s: atom %lld: %s", name, d->id[i], psys_system_last_error(sys));
            psys_scene_destroy(scene);
            return NULL;
        }
    }
    psys_pair_def pd = psys_pair_def_default();
    pd.law = PSYS_PAIR_LENNARD_JONES;
    pd.method = PSYS_PAIR_GRID;
    pd.epsilon = o->epsilon ? v->epsilon : d->epsilon;
    pd.sigma = o->sigma ? v->sigma : d->sigma;
    pd.cutoff = o->cutoff ? v->cutoff : d->have_cutoff && !o->sigma ? d->cutoff : 2.5 * pd.sigma;
    pd.shift = o->shift != 0;
    pd.skin = v->skin;
    if (psys_system_add_pair(sys, &pd, NULL) != PSYS_OK) {
        cli_error("%s: %s", name, psys_system_last_error(sys));
        psys_scene_destroy(scene);
        return NULL;
    }
    const bool periodic[3] = {true, true, true};
    if (psys_system_set_box(sys, d->lo, d->hi, periodic) != PSYS_OK) {
        cli_error("%s: %s (use a smaller --cutoff or a larger box)", name, psys_system_last_error(sys));
        psys_scene_destroy(scene);
        return NULL;
    }
    /* read_data maps atoms outside a periodic box back into it; so does this. */
    psys_system_wrap_positions(sys);
    return scene;
}

int cmd_import(int argc, char **argv)
{
    import_opts o;
    import_values v;
    if (parse_args(argc, argv, &o) != 0 || check_values(&o, &v) != 0)
        return EXIT_BAD_INPUT;
    const char *name = strcmp(o.input, "-") == 0 ? "<stdin>" : o.input;
    if (strcmp(o.input, "-") != 0 && strcmp(o.out, "-") != 0 && cli_same_file(o.input, o.out)) {
        cli_error("%s: --out would replace the data file it reads", o.out);
        return EXIT_BAD_INPUT;
    }
    lmp_data d;
    char msg[700];
    if (lmp_data_read(o.input, o.epsilon != NULL, &d, msg, sizeof msg) != 0) {
        cli_error("%s: %s", name, msg);
        return EXIT_BAD_INPUT;
    }
    if (!d.have_coeffs && !o.epsilon) {
        cli_error("%s: no Pair Coeffs section (written by write_data ... nocoeff, or before pair_coeff): give "
                  "--epsilon and --sigma",
                  name);
        lmp_data_free(&d);
        return EXIT_BAD_INPUT;
    }
    psys_scene *scene = build_scene(name, &d, &o, &v);
    lmp_data_free(&d);
    if (!scene)
        return EXIT_BAD_INPUT;
    psys_error err;
    char *text = psys_scene_to_string(scene, NULL, &err);
    psys_scene_destroy(scene);
    if (!text) {
        cli_error("%s: %s", name, err.message);
        return EXIT_RUN_FAILED;
    }
    int status = EXIT_OK;
    if (strcmp(o.out, "-") == 0) {
        if (puts(text) < 0 || fflush(stdout) != 0) {
            cli_error("--out -: cannot write to standard output");
            status = EXIT_RUN_FAILED;
        }
    } else {
        outfile f;
        if (outfile_open(&f, o.out, "--out") != 0) {
            status = EXIT_BAD_INPUT;
        } else {
            fputs(text, f.fp);
            fputc('\n', f.fp);
            if (outfile_commit(&f) != 0)
                status = EXIT_RUN_FAILED;
        }
    }
    free(text);
    return status;
}
