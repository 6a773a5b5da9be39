/* Allocation-failure injection (docs/trust.md#allocation-failure-injection,
 * docs/semantics.md#library-rules: "every allocation failure is handled").
 *
 * This program is linked with -Wl,--wrap=malloc,--wrap=calloc,--wrap=realloc,
 * --wrap=strdup,--wrap=free against the static libpsys.a and the CLI's code,
 * so every allocation they make goes through the counter below; cJSON (a
 * shared library) is routed through it with cJSON_InitHooks. A scenario is
 * run once to count its allocations (T) and record its results, then again
 * for every N = 1..T with exactly the N-th allocation failing. Each run must
 *   - fail cleanly: an error code (PSYS_ERR_NOMEM from the library; exit
 *     status 1 or 2 with a "psys: ..." message from the CLI), or succeed
 *     with exactly the results of the reference run (a failure that was
 *     absorbed, e.g. by a fallback);
 *   - free everything: the allocations still live after the scenario has
 *     cleaned up are leaks (reported with their allocation number and size;
 *     LeakSanitizer then reports them with stacks in the sanitizer build);
 *   - leave no half-written file: every output file is either untouched (its
 *     sentinel content) or identical to the reference run's, or, when the
 *     run failed while simulating (exit 1: every frame up to the last good
 *     state is kept, docs/semantics.md#failed-and-interrupted-runs), whole frames of it / a scene that loads; and
 *     no temporary file (*.psys-tmp-*) is left.
 *
 *   test_alloc lib SCENE   load, run 5 steps writing CSV frames, save with a
 *                          checkpoint, load that, save again (library calls)
 *   test_alloc cli SCENE   psys run SCENE --steps 5 --out/--energy/--checkpoint,
 *                          psys run --resume CK --steps 3 --out, and
 *                          psys check SCENE --save (the CLI's commands)
 *
 * Run single-threaded (OMP_NUM_THREADS=1): the counter is not thread-safe.
 * Debugging a failure at allocation N: TEST_ALLOC_ONLY=N runs only that
 * case, and TEST_ALLOC_TRAP=K makes allocation K abort() (under gdb, the
 * backtrace names who allocated the leaked or mishandled block);
 * TEST_ALLOC_VERBOSE=1 prints the CLI's message for every failure. */
#include "cli.h"
#include "psys/psys.h"

#include <cjson/cJSON.h>
#include <dirent.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* ------------------------------------------------------------------ */
/* The counting allocator                                              */
/* ------------------------------------------------------------------ */

void *__real_malloc(size_t n);
void *__real_calloc(size_t n, size_t size);
void *__real_realloc(void *p, size_t n);
void __real_free(void *p);
void *__wrap_malloc(size_t n);
void *__wrap_calloc(size_t n, size_t size);
void *__wrap_realloc(void *p, size_t n);
void __wrap_free(void *p);
char *__wrap_strdup(const char *s);

/* volatile: the compiler takes malloc for the C library's, which touches no
 * global of ours, and could move stores to these across calls to it. */
static volatile int armed;   /* count and track allocations */
static long alloc_count;     /* allocations so far while armed */
static long fail_at;         /* allocation number that fails (0: none) */
static long injected;        /* failures injected so far */
static long trap_at;         /* debugging: abort() at this allocation (env TEST_ALLOC_TRAP) */
static long only_n;          /* debugging: sweep only this N (env TEST_ALLOC_ONLY) */
static int verbose;          /* print every failure's message (env TEST_ALLOC_VERBOSE) */

/* Live allocations made while armed: open addressing, linear probing,
 * deletion by backward shift (no tombstones). */
enum { TABLE_BITS = 21, TABLE_SIZE = 1 << TABLE_BITS };
typedef struct live {
    void *p;
    size_t size;
    long seq;
} live;
static live table[TABLE_SIZE];
static size_t nlive;

static size_t slot_of(const void *p)
{
    uint64_t h = (uint64_t)(uintptr_t)p * 0x9E3779B97F4A7C15ull;
    return (size_t)(h >> (64 - TABLE_BITS));
}

static void track(void *p, size_t size, long seq)
{
    if (!p)
        return;
    if (nlive >= TABLE_SIZE / 2) {
        fprintf(stderr, "test_alloc: too many live allocations to track\n");
        abort();
    }
    size_t i = slot_of(p);
    while (table[i].p)
        i = (i + 1) & (TABLE_SIZE - 1);
    table[i].p = p;
    table[i].size = size;
    table[i].seq = seq;
    nlive++;
}

static void untrack(void *p)
{
    if (!p || nlive == 0)
        return;
    size_t i = slot_of(p);
    while (table[i].p && table[i].p != p)
        i = (i + 1) & (TABLE_SIZE - 1);
    if (!table[i].p)
        return; /* not ours (allocated by libc, or before arming) */
    table[i].p = NULL;
    nlive--;
    /* backward-shift the entries of the probe run after the hole */
    size_t hole = i;
    for (size_t j = (i + 1) & (TABLE_SIZE - 1); table[j].p; j = (j + 1) & (TABLE_SIZE - 1)) {
        size_t home = slot_of(table[j].p);
        /* move j into the hole unless its home lies cyclically in (hole, j] */
        bool stays = hole <= j ? (hole < home && home <= j) : (hole < home || home <= j);
        if (!stays) {
            table[hole] = table[j];
            table[j].p = NULL;
            hole = j;
        }
    }
}

/* True if this allocation is the one to fail. */
static bool should_fail(long *seq)
{
    *seq = 0;
    if (!armed)
        return false;
    *seq = ++alloc_count;
    if (alloc_count == trap_at && (fail_at == only_n || !only_n))
        abort(); /* run under gdb to see who allocates */
    if (alloc_count == fail_at) {
        injected++;
        return true;
    }
    return false;
}

void *__wrap_malloc(size_t n)
{
    long seq;
    if (should_fail(&seq))
        return NULL;
    void *p = __real_malloc(n);
    if (armed)
        track(p, n, seq);
    return p;
}

void *__wrap_calloc(size_t n, size_t size)
{
    long seq;
    if (should_fail(&seq))
        return NULL;
    void *p = __real_calloc(n, size);
    if (armed)
        track(p, n * size, seq);
    return p;
}

void *__wrap_realloc(void *p, size_t n)
{
    long seq;
    if (should_fail(&seq))
        return NULL; /* p stays valid, as with a real failure */
    void *q = __real_realloc(p, n);
    if (q) {
        untrack(p);
        if (armed)
            track(q, n, seq);
    }
    return q;
}

char *__wrap_strdup(const char *s)
{
    size_t len = strlen(s) + 1;
    char *d = __wrap_malloc(len);
    if (d)
        memcpy(d, s, len);
    return d;
}

void __wrap_free(void *p)
{
    untrack(p);
    __real_free(p);
}

/* Report and forget live allocations (LeakSanitizer then sees them as leaks). */
static size_t report_leaks(const char *what, long n)
{
    size_t count = nlive, shown = 0;
    if (!count)
        return 0;
    for (size_t i = 0; i < TABLE_SIZE && nlive; i++)
        if (table[i].p) {
            if (shown++ < 5)
                fprintf(stderr, "  leak: allocation #%ld (%zu bytes) not freed\n", table[i].seq, table[i].size);
            table[i].p = NULL;
            nlive--;
        }
    fprintf(stderr, "FAIL: %s, allocation %ld failing: %zu allocation(s) leaked\n", what, n, count);
    return count;
}

static void arm(long n)
{
    alloc_count = 0;
    injected = 0;
    fail_at = n;
    armed = 1;
}

static void disarm(void) { armed = 0; }

/* ------------------------------------------------------------------ */
/* Helpers                                                             */
/* ------------------------------------------------------------------ */

static int failures;

#define FAILF(...)                                                                       \
    do {                                                                                 \
        fprintf(stderr, "FAIL: " __VA_ARGS__);                                           \
        fputc('\n', stderr);                                                             \
        failures++;                                                                      \
    } while (0)

/* Whole file into a malloc'ed string (disarmed); NULL if it does not exist. */
static char *slurp(const char *path)
{
    FILE *fp = fopen(path, "rb");
    if (!fp)
        return NULL;
    size_t cap = 4096, len = 0;
    char *buf = malloc(cap);
    while (buf) {
        len += fread(buf + len, 1, cap - len - 1, fp);
        if (len < cap - 1)
            break;
        char *nb = realloc(buf, cap * 2);
        if (!nb) {
            free(buf);
            buf = NULL;
            break;
        }
        buf = nb;
        cap *= 2;
    }
    fclose(fp);
    if (buf)
        buf[len] = '\0';
    return buf;
}

static bool same_text(const char *a, const char *b) { return a && b && strcmp(a, b) == 0; }

/* ------------------------------------------------------------------ */
/* Library scenario                                                    */
/* ------------------------------------------------------------------ */

typedef struct lib_result {
    psys_status status;     /* PSYS_OK or the first error */
    char message[512];
    char *saved;            /* the scene saved with its checkpoint (malloc'ed, disarmed copy) */
    char *frames;           /* CSV frames written */
} lib_result;

static FILE *csv_fp;

/* Copy a string made while armed into a disarmed allocation. */
static char *keep(const char *s)
{
    if (!s)
        return NULL;
    int was = armed;
    armed = 0;
    size_t len = strlen(s) + 1;
    char *d = malloc(len);
    if (d)
        memcpy(d, s, len);
    armed = was;
    return d;
}

static void lib_scenario(const char *path, lib_result *r)
{
    psys_error err;
    memset(r, 0, sizeof *r);
    rewind(csv_fp);
    if (ftruncate(fileno(csv_fp), 0) != 0)
        abort();
    psys_scene *scene = psys_scene_load_file(path, &err);
    psys_scene *again = NULL;
    psys_run *run = NULL;
    char *t1 = NULL, *t2 = NULL;
    if (!scene)
        goto fail;
    psys_settings *set = psys_scene_settings(scene);
    set->use_steps = true;
    set->steps = 5;
    set->every = 1;
    if (!(run = psys_run_create(scene, &err)))
        goto fail;
    psys_system *sys = psys_scene_system(scene);
    psys_csv_write_trajectory_header(csv_fp, psys_system_dim(sys));
    psys_csv_write_trajectory_frame(csv_fp, sys, psys_run_step_index(run));
    while (!psys_run_done(run)) {
        if (psys_run_step(run, &err) != PSYS_OK)
            goto fail;
        psys_csv_write_trajectory_frame(csv_fp, sys, psys_run_step_index(run));
        psys_csv_write_energy_frame(csv_fp, sys, psys_run_step_index(run));
    }
    psys_resume_state rs = psys_run_resume_state(run);
    if (!(t1 = psys_scene_to_string(scene, &rs, &err)))
        goto fail;
    if (!(again = psys_scene_load_string(t1, strlen(t1), &err)))
        goto fail;
    if (!(t2 = psys_scene_to_string(again, psys_scene_resume_state(again), &err)))
        goto fail;
    if (strcmp(t1, t2) != 0) {
        err.code = PSYS_ERR_INVALID;
        snprintf(err.message, sizeof err.message, "save -> load -> save changed the scene");
        goto fail;
    }
    r->status = PSYS_OK;
    r->saved = keep(t1);
    goto done;
fail:
    r->status = err.code;
    snprintf(r->message, sizeof r->message, "%s", err.message);
done:
    free(t1);
    free(t2);
    psys_scene_destroy(again);
    psys_run_destroy(run);
    psys_scene_destroy(scene);
    fflush(csv_fp);
}

static char *csv_contents(void)
{
    long len = ftell(csv_fp);
    char *buf = malloc((size_t)len + 1);
    if (!buf)
        abort();
    rewind(csv_fp);
    size_t got = fread(buf, 1, (size_t)len, csv_fp);
    buf[got] = '\0';
    return buf;
}

static int sweep_lib(const char *path)
{
    csv_fp = tmpfile();
    if (!csv_fp) {
        FAILF("tmpfile");
        return 1;
    }
    lib_result ref;
    arm(0);
    lib_scenario(path, &ref);
    disarm();
    long total = alloc_count;
    if (ref.status != PSYS_OK) {
        FAILF("%s: reference run failed: %s", path, ref.message);
        return 1;
    }
    if (report_leaks("reference run", 0))
        failures++;
    char *ref_csv = csv_contents();
    long absorbed = 0;
    for (long n = only_n ? only_n : 1; n <= total + 1; n++) {
        lib_result r;
        arm(n);
        lib_scenario(path, &r);
        disarm();
        char *got_csv = csv_contents();
        if (injected == 0) {
            if (n <= total)
                FAILF("%s: allocation %ld of %ld never happened (allocations are not repeatable)", path, n, total);
        } else if (r.status == PSYS_OK) {
            absorbed++;
            if (!same_text(r.saved, ref.saved) || strcmp(got_csv, ref_csv) != 0)
                FAILF("%s: allocation %ld failing: reported success with different results", path, n);
        } else {
            if (r.status != PSYS_ERR_NOMEM)
                FAILF("%s: allocation %ld failing: status \"%s\", expected \"%s\" (message: %s)", path, n,
                      psys_status_name(r.status), psys_status_name(PSYS_ERR_NOMEM), r.message);
            if (!r.message[0])
                FAILF("%s: allocation %ld failing: no message", path, n);
            if (strncmp(ref_csv, got_csv, strlen(got_csv)) != 0)
                FAILF("%s: allocation %ld failing: the frames written differ from the reference run's", path, n);
        }
        if (report_leaks(path, n))
            failures++;
        free(r.saved);
        free(got_csv);
        if (failures > 100000) {
            fprintf(stderr, "test_alloc: too many failures, stopping\n");
            break;
        }
        if (injected == 0 || only_n)
            break;
    }
    printf("%s: library: %ld allocations, each failed once: %ld clean errors, %ld absorbed\n", path, total,
           total - absorbed, absorbed);
    free(ref.saved);
    free(ref_csv);
    fclose(csv_fp);
    return failures ? 1 : 0;
}

/* ------------------------------------------------------------------ */
/* CLI scenario                                                        */
/* ------------------------------------------------------------------ */

static char msgbuf[16384];

/* Run a CLI command with stdout and stderr in memory; message gets stderr. */
static int run_cli(int (*cmd)(int, char **), int argc, char **argv, long fail_n, char *message, size_t cap)
{
    FILE *mem_err = fmemopen(msgbuf, sizeof msgbuf, "w");
    FILE *mem_out = fopen("/dev/null", "w");
    if (!mem_err || !mem_out)
        abort();
    FILE *real_err = stderr, *real_out = stdout;
    stderr = mem_err;
    stdout = mem_out;
    arm(fail_n);
    int rc = cmd(argc, argv);
    disarm();
    fflush(mem_err);
    long said = ftell(mem_err);
    stderr = real_err;
    stdout = real_out;
    fclose(mem_err);
    fclose(mem_out);
    snprintf(message, cap, "%.*s", (int)(said < 0 ? 0 : said), msgbuf);
    return rc;
}

static const char *const sentinel = "sentinel: must survive a run that cannot start\n";

static void write_file(const char *path, const char *text)
{
    FILE *fp = fopen(path, "w");
    if (!fp || fputs(text, fp) < 0 || fclose(fp) != 0)
        abort();
}

static bool tmp_files_left(void)
{
    DIR *d = opendir(".");
    bool found = false;
    if (!d)
        return false;
    for (struct dirent *e; (e = readdir(d));)
        if (strstr(e->d_name, ".psys-tmp-")) {
            found = true;
            remove(e->d_name);
        }
    closedir(d);
    return found;
}

typedef struct cli_case {
    const char *name;
    int (*cmd)(int, char **);
    char *argv[16];
    const char *outputs[4]; /* files the command writes, NULL-terminated */
    const char *kinds;      /* per output: 'T' trajectory CSV, 'R' rows CSV, 'S' scene JSON */
} cli_case;

static size_t scene_particles; /* particles of the scene (frames of the trajectory) */

/* A run that fails while simulating (exit 1) keeps every frame up to the last
 * good state (docs/semantics.md#failed-and-interrupted-runs): a valid partial file is whole lines of the
 * reference file (whole frames for a trajectory); a scene file loads. */
static bool valid_partial(char kind, const char *got, const char *ref)
{
    if (!got || !ref)
        return false;
    if (kind == 'S') {
        psys_error err;
        psys_scene *s = psys_scene_load_string(got, strlen(got), &err);
        psys_scene_destroy(s);
        return s != NULL;
    }
    size_t len = strlen(got);
    if (len == 0 || got[len - 1] != '\n' || strncmp(ref, got, len) != 0)
        return false;
    size_t lines = 0;
    for (const char *c = got; *c; c++)
        lines += *c == '\n';
    return kind != 'T' || (lines >= 1 + scene_particles && (lines - 1) % scene_particles == 0);
}

static int sweep_cli_case(cli_case *c)
{
    int argc = 0;
    while (c->argv[argc])
        argc++;
    char message[sizeof msgbuf];
    char *ref[4] = {NULL, NULL, NULL, NULL};
    for (int k = 0; c->outputs[k]; k++)
        write_file(c->outputs[k], sentinel);
    int rc = run_cli(c->cmd, argc, c->argv, 0, message, sizeof message);
    long total = alloc_count;
    if (rc != 0) {
        FAILF("%s: reference run failed with status %d: %s", c->name, rc, message);
        return 1;
    }
    if (report_leaks(c->name, 0))
        failures++;
    for (int k = 0; c->outputs[k]; k++)
        if (!(ref[k] = slurp(c->outputs[k])) || same_text(ref[k], sentinel))
            FAILF("%s: reference run did not write %s", c->name, c->outputs[k]);
    long absorbed = 0;
    for (long n = only_n ? only_n : 1; n <= total + 1; n++) {
        for (int k = 0; c->outputs[k]; k++)
            write_file(c->outputs[k], sentinel);
        rc = run_cli(c->cmd, argc, c->argv, n, message, sizeof message);
        if (injected == 0) {
            if (n <= total)
                FAILF("%s: allocation %ld of %ld never happened", c->name, n, total);
        } else if (rc == 0) {
            absorbed++;
            if (verbose)
                fprintf(stderr, "%s: allocation %ld failing: absorbed (success)\n", c->name, n);
        } else {
            if (rc != EXIT_RUN_FAILED && rc != EXIT_BAD_INPUT)
                FAILF("%s: allocation %ld failing: exit status %d", c->name, n, rc);
            if (strncmp(message, "psys: ", 6) != 0)
                FAILF("%s: allocation %ld failing: exit status %d without a message", c->name, n, rc);
            if (verbose)
                fprintf(stderr, "%s: allocation %ld failing: exit %d: %s", c->name, n, rc, message);
        }
        for (int k = 0; c->outputs[k]; k++) {
            char *got = slurp(c->outputs[k]);
            bool untouched = same_text(got, sentinel), complete = same_text(got, ref[k]);
            if (rc == 0 && !complete)
                FAILF("%s: allocation %ld failing: success but %s differs from the reference run's", c->name, n,
                      c->outputs[k]);
            else if (rc == EXIT_BAD_INPUT && !untouched)
                FAILF("%s: allocation %ld failing: exit 2 but %s was changed", c->name, n, c->outputs[k]);
            else if (!untouched && !complete && !(rc == EXIT_RUN_FAILED && valid_partial(c->kinds[k], got, ref[k])))
                FAILF("%s: allocation %ld failing (exit %d): %s is half-written", c->name, n, rc, c->outputs[k]);
            free(got);
        }
        if (tmp_files_left())
            FAILF("%s: allocation %ld failing: temporary files left behind", c->name, n);
        if (report_leaks(c->name, n))
            failures++;
        if (failures > 100000) {
            fprintf(stderr, "test_alloc: too many failures, stopping\n");
            break;
        }
        if (injected == 0 || only_n)
            break;
    }
    printf("%s: %ld allocations, each failed once: %ld clean errors, %ld absorbed\n", c->name, total,
           total - absorbed, absorbed);
    for (int k = 0; k < 4; k++)
        free(ref[k]);
    return failures ? 1 : 0;
}

static int sweep_cli(const char *path)
{
    char dir[] = "/tmp/psys-alloc.XXXXXX";
    char *scene = realpath(path, NULL);
    if (!scene || !mkdtemp(dir) || chdir(dir) != 0) {
        FAILF("cannot set up a temporary directory for %s", path);
        free(scene);
        return 1;
    }
    psys_error err;
    psys_scene *loaded = psys_scene_load_file(scene, &err);
    if (!loaded) {
        FAILF("%s: %s", path, err.message);
        free(scene);
        return 1;
    }
    scene_particles = psys_system_count(psys_scene_system(loaded));
    psys_scene_destroy(loaded);
    /* a checkpoint to resume from, written by an ordinary run */
    char message[sizeof msgbuf];
    char *mk[] = {"run", scene, "--steps", "2", "--checkpoint", "ck-ref.json", "--quiet", NULL};
    if (run_cli(cmd_run, 7, mk, 0, message, sizeof message) != 0)
        FAILF("%s: cannot write a checkpoint: %s", path, message);
    cli_case cases[] = {
        {"psys run --out --energy --checkpoint", cmd_run,
         {"run", scene, "--steps", "5", "--every", "2", "--out", "traj.csv", "--energy", "energy.csv",
          "--checkpoint", "ck.json", "--quiet", NULL},
         {"traj.csv", "energy.csv", "ck.json", NULL}, "TRS"},
        {"psys run --resume", cmd_run,
         {"run", "--resume", "ck-ref.json", "--steps", "3", "--out", "resumed.csv", "--quiet", NULL},
         {"resumed.csv", NULL}, "T"},
        {"psys check --save", cmd_check, {"check", scene, "--save", "saved.json", NULL}, {"saved.json", NULL}, "S"},
    };
    int rc = 0;
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        printf("%s: ", path);
        fflush(stdout);
        rc |= sweep_cli_case(&cases[k]);
    }
    /* clean up the directory */
    const char *files[] = {"traj.csv", "energy.csv", "ck.json", "ck-ref.json", "resumed.csv", "saved.json"};
    for (size_t k = 0; k < sizeof files / sizeof files[0]; k++)
        remove(files[k]);
    if (chdir("/") == 0)
        rmdir(dir);
    free(scene);
    return rc;
}

int main(int argc, char **argv)
{
    if (argc != 3 || (strcmp(argv[1], "lib") != 0 && strcmp(argv[1], "cli") != 0)) {
        fprintf(stderr, "usage: %s lib|cli SCENE\n", argv[0]);
        return 2;
    }
    if (getenv("TEST_ALLOC_TRAP"))
        trap_at = atol(getenv("TEST_ALLOC_TRAP"));
    if (getenv("TEST_ALLOC_ONLY"))
        only_n = atol(getenv("TEST_ALLOC_ONLY"));
    verbose = getenv("TEST_ALLOC_VERBOSE") != NULL;
    cJSON_Hooks hooks = {__wrap_malloc, __wrap_free};
    cJSON_InitHooks(&hooks);
    int rc = strcmp(argv[1], "lib") == 0 ? sweep_lib(argv[2]) : sweep_cli(argv[2]);
    if (rc || failures)
        fprintf(stderr, "%s %s: %d failure(s)\n", argv[1], argv[2], failures);
    return rc || failures ? 1 : 0;
}
