/* Shared pieces of the psys command-line program. */
#ifndef PSYS_CLI_H
#define PSYS_CLI_H

#include "psys/psys.h"

#include <stdio.h>

/** Exit statuses of docs/cli.md#exit-status. */
enum { EXIT_OK = 0, EXIT_RUN_FAILED = 1, EXIT_BAD_INPUT = 2 };

/** Nonzero: cli_error prints nothing (MPI ranks other than 0). */
extern int cli_silent;
/** Print "psys: " + message + newline to standard error. */
void cli_error(const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 1, 2)))
#endif
    ;

/** An output file written under a temporary name and renamed when complete. */
typedef struct outfile {
    char *path;  /* final name */
    char *tmp;   /* temporary name in the same directory */
    FILE *fp;
} outfile;

/** Create the temporary file for path; on failure prints a message and returns -1. */
int outfile_open(outfile *o, const char *path, const char *what);
/** Flush, close and rename into place; returns -1 (message printed) on failure. */
int outfile_commit(outfile *o);
/** Close and delete the temporary file (no-op if not open). */
void outfile_abort(outfile *o);
/** Whether paths a and b (either may be NULL) name the same regular file,
 *  existing or not: the same name after resolving links and the directory
 *  ("./x" and "x"), or one file under two names (hard links). Devices and
 *  pipes (/dev/null twice) are not the same file. */
bool cli_same_file(const char *a, const char *b);

/** Warn on stderr (unless quiet) when an explicit fixed-step solver's dt
 *  exceeds 2/omega_max of the stiffest spring (psys_system_stiffest_omega);
 *  not for implicit-euler or rk45. */
void cli_stability_warning(const char *source, psys_scene *scene, int quiet);

/** Parse a strictly positive finite double; returns -1 if s is not one. */
int parse_positive(const char *s, double *out);
/** strtod for decimal numbers only: hexadecimal ("0x10") and leading space
 *  leave *end at s (not a number), as in JSON. */
double cli_strtod(const char *s, char **end);
/* Read all of fp into a NUL-terminated buffer, its length into *len; NULL on failure. */
char *cli_read_all(FILE *fp, size_t *len);
/** Parse a non-negative finite double. */
int parse_nonneg(const char *s, double *out);
/** Parse an integer in [min, max]. */
int parse_int(const char *s, long long min, long long max, long long *out);

int cmd_run(int argc, char **argv);
/** Parse and apply `psys run` options to set only (no scene, no files): EXIT_OK or EXIT_BAD_INPUT. */
int cmd_run_parse(int argc, char **argv, psys_settings *set);
int cmd_check(int argc, char **argv);
int cmd_bench(int argc, char **argv);
int cmd_plot(int argc, char **argv);
int cmd_import(int argc, char **argv);

/* "--name VALUE" or "--name=VALUE" at argv[*i]: 1 if it is this option (*val
 * set, *i advanced past a separate value; *bad set, with a message, when the
 * value is missing), 0 if not. */
int cli_take(int argc, char **argv, int *i, const char *name, const char **val, int *bad);

/* 0 if name is a known solver; else -1, having printed the --integrator error. */
int cli_check_integrator(const char *name);

#endif
