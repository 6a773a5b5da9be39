/* libFuzzer target: the `psys run` command-line parser (docs/trust.md).
 *
 * The input is the argument list, one argument per line ("\n" separated,
 * at most 64), given to cmd_run_parse: the options of `psys run` parsed and
 * applied to default settings exactly as `psys run` does, without loading a
 * scene or touching a file. Checks: an accepted command line leaves sane
 * settings (dt > 0 and finite, every >= 1, steps >= 0, paths terminated); a
 * rejected one returns EXIT_BAD_INPUT having printed "psys: ..." lines.
 *
 * Messages go to standard error; the harness points stderr at a memory
 * buffer around each call (sanitizer reports go to file descriptor 2 and
 * are not affected). Built as a libFuzzer target and, with replay_main.c,
 * as a replay program for the regression corpus in every build. */
#include "cli.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#define FUZZ_CHECK(cond, ...)                                                 \
    do {                                                                      \
        if (!(cond)) {                                                        \
            fprintf(real_stderr, "fuzz_cli: check failed: %s: ", #cond);      \
            fprintf(real_stderr, __VA_ARGS__);                                \
            fputc('\n', real_stderr);                                         \
            abort();                                                          \
        }                                                                     \
    } while (0)

enum { MAX_ARGS = 64 };

static char msgbuf[8192];
static char cmd_name[] = "run";

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size > 65536)
        return 0;
    FILE *real_stderr = stderr;
    char *text = malloc(size + 1);
    if (!text)
        return 0;
    memcpy(text, data, size);
    text[size] = '\0';
    char *argv[MAX_ARGS + 2];
    int argc = 0;
    argv[argc++] = cmd_name;
    for (char *p = text; argc <= MAX_ARGS;) {
        argv[argc++] = p;
        char *nl = strchr(p, '\n');
        if (!nl)
            break;
        *nl = '\0';
        p = nl + 1;
    }
    argv[argc] = NULL;

    FILE *mem = fmemopen(msgbuf, sizeof msgbuf, "w");
    FUZZ_CHECK(mem != NULL, "fmemopen failed");
    psys_settings set = psys_settings_default();
    stderr = mem;
    int rc = cmd_run_parse(argc, argv, &set);
    fflush(mem);
    long said = ftell(mem);
    stderr = real_stderr;
    fclose(mem);

    if (rc == EXIT_OK) {
        FUZZ_CHECK(isfinite(set.dt) && set.dt > 0, "accepted dt %g", set.dt);
        FUZZ_CHECK(set.every >= 1, "accepted every %lld", set.every);
        FUZZ_CHECK(!set.use_steps || set.steps >= 0, "accepted steps %lld", set.steps);
        FUZZ_CHECK(set.use_steps || (isfinite(set.duration) && set.duration >= 0), "accepted duration %g",
                   set.duration);
        FUZZ_CHECK(memchr(set.trajectory, '\0', sizeof set.trajectory) != NULL, "trajectory path not terminated");
        FUZZ_CHECK(memchr(set.energy, '\0', sizeof set.energy) != NULL, "energy path not terminated");
        FUZZ_CHECK(psys_solver_exists(set.integrator), "accepted integrator %s", set.integrator);
    } else {
        FUZZ_CHECK(rc == EXIT_BAD_INPUT, "exit status %d", rc);
        FUZZ_CHECK(said > 6 && strncmp(msgbuf, "psys: ", 6) == 0, "rejected without a message");
    }
    free(text);
    return 0;
}
