/* Determinism and guard rails at the library level (docs/trust.md):
 * the same scene gives bit-identical states run after run in one process
 * (no hidden global state), for every thread count, and after a save/load
 * round trip; psys_system_stiffest_omega gives the documented estimate. */
#include "check.h"
#include "psys/psys.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Springs, a muscle, a behaviour, controllers, a mouse path, a plane and
 * pair forces (grid neighbour lists, Barnes-Hut, direct): everything that
 * keeps internal state or could be evaluated in parallel. */
static const char scene_text[] =
    "{\"psys\": 1, \"dim\": 3, \"dt\": 0.001, \"steps\": 60,\n"
    " \"particles\": [{\"id\": \"p\", \"x\": [0, 0, 1], \"fixed\": true},\n"
    "   {\"id\": \"b\", \"x\": [0.3, 0, 1], \"v\": [0, 0.5, 0], \"mass\": 0.5},\n"
    "   {\"id\": \"c\", \"x\": [0.3, 0.1, 0.9], \"mass\": 2},\n"
    "   {\"id\": \"m\", \"x\": [0.5, 0, 1], \"control\": {\"type\": \"circle\", \"center\": [0.5, 0, 0.9],"
    " \"radius\": 0.1, \"omega\": 3}},\n"
    "   {\"x\": [0.1, 0.1, 0.1]}, {\"x\": [0.2, 0.12, 0.1]}, {\"x\": [0.15, 0.2, 0.1], \"v\": [0.3, 0, 0]},\n"
    "   {\"x\": [0.05, 0.3, 0.12]}, {\"x\": [0.25, 0.25, 0.1]}, {\"x\": [0.3, 0.3, 0.3]}],\n"
    " \"structures\": [{\"type\": \"cloth\", \"id\": \"s\", \"origin\": [1, 0, 1], \"size\": [6, 5],"
    " \"spacing\": 0.05, \"mass\": 0.01, \"ks\": 200, \"kd\": 0.05, \"pin\": [[0, 0], [5, 0]]}],\n"
    " \"forces\": [{\"type\": \"gravity\", \"g\": [0, 0, -9.81]}, {\"type\": \"drag\", \"kd\": 0.05},\n"
    "   {\"type\": \"spring\", \"a\": \"p\", \"b\": \"b\", \"ks\": 100, \"kd\": 0.5,"
    " \"muscle\": {\"amplitude\": 0.2, \"omega\": 7}},\n"
    "   {\"type\": \"spring\", \"a\": \"b\", \"b\": \"c\", \"ks\": 50},\n"
    "   {\"type\": \"behavior\", \"function\": \"distance\", \"particles\": [\"c\", \"m\"], \"r\": 0.3, \"ks\": 5},\n"
    "   {\"type\": \"mouse-spring\", \"particle\": \"c\", \"ks\": 10, \"kd\": 1,"
    " \"path\": [[0, 0.3, 0.1, 0.9], [0.05, 0.4, 0.1, 0.9]]},\n"
    "   {\"type\": \"pair\", \"law\": \"lennard-jones\", \"epsilon\": 0.01, \"sigma\": 0.05, \"cutoff\": 0.15,"
    " \"method\": \"grid\"},\n"
    "   {\"type\": \"pair\", \"law\": \"gravity\", \"G\": 0.01, \"softening\": 0.01, \"method\": \"barnes-hut\","
    " \"theta\": 0.5}],\n"
    " \"planes\": [{\"point\": [0, 0, 0], \"normal\": [0, 0, 1], \"restitution\": 0.5, \"friction\": 0.2}]}\n";

typedef struct state {
    size_t n;
    int dim;
    double t;
    double *x, *v;
} state;

/* Load text, set threads (0: leave), run it to the end; the final state. */
static int run_scene(const char *text, const char *integrator, int threads, state *out)
{
    psys_error err;
    memset(out, 0, sizeof *out);
    psys_scene *scene = psys_scene_load_string(text, strlen(text), &err);
    if (!scene) {
        fprintf(stderr, "load: %s\n", err.message);
        return -1;
    }
    psys_settings *set = psys_scene_settings(scene);
    if (integrator)
        snprintf(set->integrator, sizeof set->integrator, "%s", integrator);
    psys_system *sys = psys_scene_system(scene);
    if (threads > 0)
        psys_system_set_threads(sys, threads);
    psys_run *run = psys_run_create(scene, &err);
    if (!run) {
        fprintf(stderr, "run: %s\n", err.message);
        psys_scene_destroy(scene);
        return -1;
    }
    int rc = 0;
    while (!psys_run_done(run) && rc == 0)
        if (psys_run_step(run, &err) != PSYS_OK) {
            fprintf(stderr, "step: %s\n", err.message);
            rc = -1;
        }
    out->n = psys_system_count(sys);
    out->dim = psys_system_dim(sys);
    out->t = psys_system_time(sys);
    size_t nd = out->n * (size_t)out->dim;
    out->x = malloc(nd * sizeof(double));
    out->v = malloc(nd * sizeof(double));
    if (!out->x || !out->v)
        abort();
    memcpy(out->x, psys_system_positions(sys), nd * sizeof(double));
    memcpy(out->v, psys_system_velocities(sys), nd * sizeof(double));
    psys_run_destroy(run);
    psys_scene_destroy(scene);
    return rc;
}

static bool same_state(const state *a, const state *b)
{
    size_t nd = a->n * (size_t)a->dim;
    if (!a->x || !b->x)
        return false;
    return a->n == b->n && a->dim == b->dim && memcmp(&a->t, &b->t, sizeof a->t) == 0
           && memcmp(a->x, b->x, nd * sizeof(double)) == 0 && memcmp(a->v, b->v, nd * sizeof(double)) == 0;
}

static void free_state(state *s)
{
    free(s->x);
    free(s->v);
}

static const char *const integrators[] = {"euler", "midpoint", "rk4", "symplectic-euler", "verlet", "rk45",
                                          "implicit-euler"};

/* The same scene twice in one process, with another run in between. */
static void repeat_runs(void)
{
    for (size_t k = 0; k < sizeof integrators / sizeof integrators[0]; k++) {
        state a, b, other;
        CHECK(run_scene(scene_text, integrators[k], 0, &a) == 0);
        CHECK(run_scene(scene_text, integrators[(k + 1) % 7], 0, &other) == 0);
        CHECK(run_scene(scene_text, integrators[k], 0, &b) == 0);
        if (!same_state(&a, &b))
            fprintf(stderr, "%s: the second run differs\n", integrators[k]);
        CHECK(same_state(&a, &b));
        CHECK(a.n > 30);
        free_state(&a);
        free_state(&b);
        free_state(&other);
    }
}

/* 1, 2, 3, 4 and 8 threads: bit-identical. */
static void thread_counts(void)
{
    for (size_t k = 0; k < sizeof integrators / sizeof integrators[0]; k++) {
        state ref;
        CHECK(run_scene(scene_text, integrators[k], 1, &ref) == 0);
        for (int threads = 2; threads <= 8; threads = threads == 4 ? 8 : threads + 1) {
            state s;
            CHECK(run_scene(scene_text, integrators[k], threads, &s) == 0);
            if (!same_state(&ref, &s))
                fprintf(stderr, "%s: %d threads differ from 1\n", integrators[k], threads);
            CHECK(same_state(&ref, &s));
            free_state(&s);
        }
        free_state(&ref);
    }
}

/* A cloth and a muscle chain big enough for the parallel paths: springs
 * split among threads (>= 20,000 springs) and the solver's and derivative's
 * elementwise passes (>= 65,536 numbers); with drag and gravity. The chain's
 * muscles pull on every one of its particles from the first step (the
 * cloth's springs start at rest and act only near its pins at first). */
static const char big_cloth_text[] =
    "{\"psys\": 1, \"dim\": 3, \"dt\": 0.0005, \"steps\": 12,\n"
    " \"structures\": [{\"type\": \"cloth\", \"id\": \"s\", \"origin\": [0, 0, 1], \"size\": [160, 150],"
    " \"spacing\": 0.01, \"mass\": 0.0001, \"ks\": 40, \"kd\": 0.001, \"pin\": [[0, 0], [159, 0]]},\n"
    "   {\"type\": \"chain\", \"id\": \"c\", \"from\": [0, 0, 2], \"to\": [60, 0, 2], \"count\": 6000,"
    " \"mass\": 0.001, \"ks\": 5, \"kd\": 0.01, \"pin\": [0],"
    " \"muscle\": {\"amplitude\": 0.3, \"omega\": 40, \"phase_step\": 0.1}}],\n"
    " \"forces\": [{\"type\": \"gravity\", \"g\": [0, 0, -9.81]}, {\"type\": \"drag\", \"kd\": 0.0001},\n"
    "   {\"type\": \"spring\", \"a\": \"s[3,3]\", \"b\": \"s[5,4]\", \"ks\": 1,"
    " \"muscle\": {\"amplitude\": 0.2, \"omega\": 7}}]}\n";

/* The big scene on 1, 2 and 3 threads: bit-identical, every explicit solver. */
static void thread_counts_parallel_paths(void)
{
    for (size_t k = 0; k + 1 < sizeof integrators / sizeof integrators[0]; k++) {
        state ref;
        CHECK(run_scene(big_cloth_text, integrators[k], 1, &ref) == 0);
        CHECK(ref.n == 30000);
        for (int threads = 2; threads <= 3; threads++) {
            state s;
            CHECK(run_scene(big_cloth_text, integrators[k], threads, &s) == 0);
            if (!same_state(&ref, &s))
                fprintf(stderr, "%s: big cloth, %d threads differ from 1\n", integrators[k], threads);
            CHECK(same_state(&ref, &s));
            free_state(&s);
        }
        free_state(&ref);
    }
}

/* Saved and loaded again, the scene runs to the same bits. */
static void round_trip_runs(void)
{
    psys_error err;
    psys_scene *scene = psys_scene_load_string(scene_text, strlen(scene_text), &err);
    CHECK(scene != NULL);
    if (!scene)
        return;
    char *saved = psys_scene_to_string(scene, NULL, &err);
    CHECK(saved != NULL);
    psys_scene_destroy(scene);
    if (!saved)
        return;
    for (size_t k = 0; k < sizeof integrators / sizeof integrators[0]; k++) {
        state a, b;
        CHECK(run_scene(scene_text, integrators[k], 0, &a) == 0);
        CHECK(run_scene(saved, integrators[k], 0, &b) == 0);
        CHECK(same_state(&a, &b));
        free_state(&a);
        free_state(&b);
    }
    free(saved);
}

/* psys_system_stiffest_omega: max over springs of sqrt(2 ks (1/m_a + 1/m_b)),
 * fixed and controlled particles counting as infinitely heavy. */
static void stiffest_omega(void)
{
    psys_system *sys = psys_system_create(2, NULL);
    CHECK(sys != NULL);
    if (!sys)
        return;
    CHECK(psys_system_stiffest_omega(sys) == 0.0);
    double x[2] = {0, 0};
    for (int i = 0; i < 5; i++) {
        x[0] = i;
        CHECK(psys_system_add_particle(sys, x, NULL, i == 2 ? 4.0 : 1.0, NULL, NULL) == PSYS_OK);
    }
    CHECK(psys_system_add_spring(sys, 0, 1, 100, 0, -1) == PSYS_OK);   /* 2·100·2 = 400 */
    CHECK_NEAR(psys_system_stiffest_omega(sys), 20.0, 1e-12);
    CHECK(psys_system_add_spring(sys, 1, 2, 300, 0, -1) == PSYS_OK);   /* 2·300·1.25 = 750 */
    CHECK_NEAR(psys_system_stiffest_omega(sys), sqrt(750.0), 1e-12);
    CHECK(psys_system_set_fixed(sys, 1, true) == PSYS_OK);              /* now 2·300·0.25 and 2·100·1 */
    CHECK_NEAR(psys_system_stiffest_omega(sys), sqrt(200.0), 1e-12);
    double c[2] = {3, 1};
    CHECK(psys_system_control_circle(sys, 3, c, 1, 1, 0, NULL) == PSYS_OK);
    CHECK(psys_system_add_spring(sys, 1, 3, 1e9, 0, -1) == PSYS_OK);   /* fixed to controlled: moves nothing */
    CHECK_NEAR(psys_system_stiffest_omega(sys), sqrt(200.0), 1e-12);
    CHECK(psys_system_add_spring(sys, 3, 4, 1e4, 0, -1) == PSYS_OK);   /* controlled to free: 2·1e4·1 */
    CHECK_NEAR(psys_system_stiffest_omega(sys), sqrt(2e4), 1e-9);
    CHECK(psys_system_stiffest_omega(NULL) == 0.0);
    psys_system_destroy(sys);
}

static const check_case cases[] = {{"repeat_runs", repeat_runs},
                                   {"thread_counts", thread_counts},
                                   {"thread_counts_parallel_paths", thread_counts_parallel_paths},
                                   {"round_trip_runs", round_trip_runs},
                                   {"stiffest_omega", stiffest_omega},
                                   {NULL, NULL}};

int main(int argc, char **argv) { return check_main(argc, argv, cases); }
