/* psys check: validate a scene, print a summary, optionally save it back. */
#include "cli.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

int cmd_check(int argc, char **argv)
{
    const char *scene_path = NULL, *save = NULL;
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--save") == 0) {
            if (i + 1 >= argc) {
                cli_error("--save needs a value (see psys --help)");
                return EXIT_BAD_INPUT;
            }
            save = argv[++i];
        } else if (strncmp(argv[i], "--save=", 7) == 0) {
            save = argv[i] + 7;
        } else if (argv[i][0] == '-' && argv[i][1] != '\0') {
            cli_error("check: unknown option %s (see psys --help)", argv[i]);
            return EXIT_BAD_INPUT;
        } else if (!scene_path) {
            scene_path = argv[i];
        } else {
            cli_error("check: more than one scene given (%s and %s)", scene_path, argv[i]);
            return EXIT_BAD_INPUT;
        }
    }
    if (!scene_path) {
        cli_error("check: no scene given (usage: psys check SCENE [--save FILE])");
        return EXIT_BAD_INPUT;
    }
    if (save && !save[0]) {
        cli_error("--save: path must not be empty");
        return EXIT_BAD_INPUT;
    }
    const char *name = strcmp(scene_path, "-") == 0 ? "<stdin>" : scene_path;
    psys_error err;
    psys_scene *scene = psys_scene_load_file(scene_path, &err);
    if (!scene) {
        cli_error("%s: %s", name, err.message);
        return EXIT_BAD_INPUT;
    }
    /* A scene psys run would refuse (src/io/run.c counts the steps the same way). */
    const psys_settings *cs = psys_scene_settings(scene);
    if (!cs->use_steps && strcmp(cs->integrator, "rk45") != 0) {
        double q = cs->duration / cs->dt;
        if (!(ceil(q - 1e-9 * q) <= 1e15)) { /* NaN too: inf - inf */
            cli_error("%s: duration/dt asks for more than 1e15 steps", name);
            psys_scene_destroy(scene);
            return EXIT_BAD_INPUT;
        }
    }
    /* Open the --save file first: a path that cannot be written is bad usage,
     * reported before anything is printed. */
    outfile saved;
    memset(&saved, 0, sizeof saved);
    if (save && strcmp(save, "-") != 0 && outfile_open(&saved, save, "--save") != 0) {
        psys_scene_destroy(scene);
        return EXIT_BAD_INPUT;
    }
    psys_system *sys = psys_scene_system(scene);
    const psys_settings *set = psys_scene_settings(scene);
    size_t fixed = 0;
    for (size_t i = 0; i < psys_system_count(sys); i++)
        fixed += psys_system_is_fixed(sys, i);
    double ke = psys_system_kinetic_energy(sys), pe = psys_system_potential_energy(sys);
    /* With --save - the scene goes to standard output, so the summary moves to stderr. */
    FILE *info = save && strcmp(save, "-") == 0 ? stderr : stdout;
    fprintf(info, "scene: %s\n", name);
    fprintf(info, "dim: %d\n", psys_system_dim(sys));
    fprintf(info, "particles: %zu\n", psys_system_count(sys));
    fprintf(info, "fixed: %zu\n", fixed);
    fprintf(info, "springs: %zu\n", psys_system_spring_count(sys));
    fprintf(info, "forces: %zu\n", psys_system_force_count(sys));
    fprintf(info, "integrator: %s\n", set->integrator);
    fprintf(info, "dt: %.17g\n", set->dt);
    if (set->use_steps) {
        fprintf(info, "steps: %lld\n", set->steps);
        if (strcmp(set->integrator, "rk45") == 0)
            fprintf(info, "duration: adaptive\n");
        else
            fprintf(info, "duration: %.17g\n", (double)set->steps * set->dt);
    } else {
        if (strcmp(set->integrator, "rk45") == 0) {
            fprintf(info, "steps: adaptive\n");
        } else {
            double q = set->duration / set->dt; /* at most 1e15 steps: checked above */
            fprintf(info, "steps: %.0f\n", ceil(q - 1e-9 * q));
        }
        fprintf(info, "duration: %.17g\n", set->duration);
    }
    fprintf(info, "kinetic: %.17g\n", ke);
    fprintf(info, "potential: %.17g\n", pe);
    fprintf(info, "energy: %.17g\n", ke + pe);
    int status = EXIT_OK;
    if (save) {
        const psys_resume_state *rs = psys_scene_resume_state(scene);
        char *text = psys_scene_to_string(scene, rs->present ? rs : NULL, &err);
        if (!text) {
            cli_error("--save %s: %s", save, err.message);
            outfile_abort(&saved);
            status = EXIT_RUN_FAILED;
        } else if (strcmp(save, "-") == 0) {
            puts(text);
        } else {
            fputs(text, saved.fp);
            fputc('\n', saved.fp);
            if (outfile_commit(&saved) != 0)
                status = EXIT_RUN_FAILED;
        }
        free(text);
    }
    psys_scene_destroy(scene);
    return status;
}
