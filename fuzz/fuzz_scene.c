/* libFuzzer target: the scene loader and saver (docs/trust.md).
 *
 * bytes -> psys_scene_load_string -> (rejected: an error code and a message)
 *       -> psys_scene_to_string = text1 -> load text1 -> save = text2
 * and then: text2 == text1 (the round trip is a fixed point), both systems
 * have the same particles (count, dimension, positions, velocities, masses
 * bit for bit), springs and force objects, and a few steps of a run on each
 * give bit-identical states (docs/scene-format.md#saving-a-scene-back:
 * loading that file gives the same system and results to the last bit).
 *
 * Inputs that ask for huge structures (a 10^4 × 10^4 cloth in 60 bytes) are
 * skipped: they are valid scenes that only cost time and memory here; the
 * hostile-size tests (tests/cli/hostile.sh) cover the limits. Allocations of
 * more than 256 MiB fail (ASan's max_allocation_size_mb with
 * allocator_may_return_null, set below) and must end in a clean
 * PSYS_ERR_NOMEM, never a crash.
 *
 * Built two ways: with -fsanitize=fuzzer (clang) as a libFuzzer target, and
 * with replay_main.c as a plain program that replays the corpus and the
 * regression inputs in every build (ctest fuzz.replay.*). */
#include "psys/psys.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
/* The loader's allocation-free JSON check (src/io/json_check.c, internal). */
int psys__json_check(const char *text, size_t len, int max_depth, size_t *where);

/* ASan defaults for the libFuzzer build (ignored without ASan). */
const char *__asan_default_options(void);
const char *__asan_default_options(void) { return "allocator_may_return_null=1:max_allocation_size_mb=256"; }

#define FUZZ_CHECK(cond, ...)                                                 \
    do {                                                                      \
        if (!(cond)) {                                                        \
            fprintf(stderr, "fuzz_scene: check failed: %s: ", #cond);       \
            fprintf(stderr, __VA_ARGS__);                                     \
            fputc('\n', stderr);                                              \
            abort();                                                          \
        }                                                                     \
    } while (0)

/* Most structure particles an input may ask for here, and the most
 * particles a system may have to be stepped. Larger structures take the
 * same code paths; each one costs milliseconds under the sanitizers (the
 * scene is saved and loaded twice), which would cut the executions per
 * second tenfold. */
enum { MAX_STRUCTURE_PARTICLES = 2000, MAX_STEPPED_PARTICLES = 256, MAX_IMPLICIT_PARTICLES = 24, STEPS = 3 };

static double count_of(const cJSON *it)
{
    if (cJSON_IsNumber(it))
        return fabs(it->valuedouble);
    double prod = 1;
    if (cJSON_IsArray(it))
        for (const cJSON *c = it->child; c; c = c->next)
            prod *= cJSON_IsNumber(c) ? fabs(c->valuedouble) : 1;
    return prod;
}

/* True if the text holds 64 or more characters in a row that cJSON copies
 * into a number ("0123456789+-.eE"). */
static int long_number(const char *text, size_t len)
{
    size_t run = 0;
    for (size_t i = 0; i < len; i++) {
        run = text[i] && strchr("0123456789+-.eE", text[i]) ? run + 1 : 0;
        if (run >= 64)
            return 1;
    }
    return 0;
}

/* True if the structures of the scene would add too many particles. Also
 * checks that psys__json_check, which the loader consults when cJSON fails
 * to say whether it ran out of memory, agrees with cJSON on every text. */
static int too_big(const char *text, size_t len)
{
    const char *end = NULL;
    cJSON *root = cJSON_ParseWithLengthOpts(text, len, &end, false);
    if (!memchr(text, '\0', len)) {
        size_t at;
        int chk = psys__json_check(text, len, CJSON_NESTING_LIMIT, &at);
        if (!root)
            FUZZ_CHECK(chk != 0, "cJSON refuses a text psys__json_check calls valid");
        size_t rest = root ? len - (size_t)(end - text) : 0;
        while (rest && (unsigned char)end[rest - 1] <= 32)
            rest--;
        /* Numbers longer than 63 characters: cJSON 1.7.15 as released refuses
         * them, Debian's patched one reads them; the check refuses them (the
         * safe side: never "out of memory" for a text cJSON refuses). */
        if (root && rest == 0 && !long_number(text, len))
            FUZZ_CHECK(chk == 0, "psys__json_check refuses a text cJSON accepts (at offset %zu)", at);
    }
    if (!root)
        return 0;
    double total = 0;
    const cJSON *arr = cJSON_GetObjectItemCaseSensitive(root, "structures");
    if (cJSON_IsArray(arr))
        for (const cJSON *s = arr->child; s; s = s->next) {
            total += count_of(cJSON_GetObjectItemCaseSensitive(s, "count"));
            total += count_of(cJSON_GetObjectItemCaseSensitive(s, "size"));
        }
    cJSON_Delete(root);
    return !(total <= MAX_STRUCTURE_PARTICLES);
}

static void same_system(const psys_system *a, const psys_system *b)
{
    size_t n = psys_system_count(a);
    int d = psys_system_dim(a);
    FUZZ_CHECK(psys_system_dim(b) == d, "dim %d != %d", psys_system_dim(b), d);
    FUZZ_CHECK(psys_system_count(b) == n, "particles %zu != %zu", psys_system_count(b), n);
    FUZZ_CHECK(psys_system_spring_count(b) == psys_system_spring_count(a), "springs %zu != %zu",
               psys_system_spring_count(b), psys_system_spring_count(a));
    FUZZ_CHECK(psys_system_force_count(b) == psys_system_force_count(a), "forces %zu != %zu",
               psys_system_force_count(b), psys_system_force_count(a));
    if (n == 0)
        return;
    FUZZ_CHECK(memcmp(psys_system_positions(a), psys_system_positions(b), n * (size_t)d * sizeof(double)) == 0,
               "positions differ");
    FUZZ_CHECK(memcmp(psys_system_velocities(a), psys_system_velocities(b), n * (size_t)d * sizeof(double)) == 0,
               "velocities differ");
    FUZZ_CHECK(memcmp(psys_system_masses(a), psys_system_masses(b), n * sizeof(double)) == 0, "masses differ");
    for (size_t i = 0; i < n; i++) {
        const char *ia = psys_system_particle_id(a, i), *ib = psys_system_particle_id(b, i);
        FUZZ_CHECK((!ia && !ib) || (ia && ib && strcmp(ia, ib) == 0), "particle %zu: ids differ", i);
        FUZZ_CHECK(psys_system_is_fixed(a, i) == psys_system_is_fixed(b, i), "particle %zu: fixed differs", i);
        FUZZ_CHECK(psys_system_is_controlled(a, i) == psys_system_is_controlled(b, i),
                   "particle %zu: controlled differs", i);
    }
}

/* A few steps of a run of each scene: the same status and bit-identical states. */
static void same_run(psys_scene *a, psys_scene *b)
{
    psys_error ea, eb;
    /* Bound implicit-euler's work per step (a solve may take 1000 iterations,
     * and collisions re-run steps): the same code runs, capped or not. */
    if (psys_scene_settings(a)->cg_max_iterations > 20)
        psys_scene_settings(a)->cg_max_iterations = psys_scene_settings(b)->cg_max_iterations = 20;
    psys_run *ra = psys_run_create(a, &ea);
    psys_run *rb = psys_run_create(b, &eb);
    FUZZ_CHECK(!ra == !rb, "run_create: %s / %s", ra ? "ok" : ea.message, rb ? "ok" : eb.message);
    if (!ra) {
        FUZZ_CHECK(ea.code != PSYS_OK && ea.message[0], "run_create failed without a message");
        FUZZ_CHECK(ea.code == eb.code, "run_create: codes %d != %d", (int)ea.code, (int)eb.code);
        return;
    }
    for (int k = 0; k < STEPS && !psys_run_done(ra); k++) {
        FUZZ_CHECK(!psys_run_done(rb), "one run ended before the other");
        psys_status sa = psys_run_step(ra, &ea), sb = psys_run_step(rb, &eb);
        FUZZ_CHECK(sa == sb, "step %d: status %d != %d", k, (int)sa, (int)sb);
        if (sa != PSYS_OK) {
            FUZZ_CHECK(ea.message[0] != '\0', "step failed without a message");
            break;
        }
        FUZZ_CHECK(psys_run_step_index(ra) == psys_run_step_index(rb), "step index differs");
        double ta = psys_system_time(psys_scene_system(a)), tb = psys_system_time(psys_scene_system(b));
        FUZZ_CHECK(memcmp(&ta, &tb, sizeof ta) == 0, "time %.17g != %.17g", ta, tb);
        same_system(psys_scene_system(a), psys_scene_system(b));
    }
    psys_run_destroy(ra);
    psys_run_destroy(rb);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const char *text = (const char *)data;
    if (too_big(text, size))
        return 0;
    psys_error err;
    psys_scene *s1 = psys_scene_load_string(text, size, &err);
    if (!s1) {
        FUZZ_CHECK(err.code != PSYS_OK, "rejected with code ok");
        FUZZ_CHECK(err.message[0] != '\0', "rejected without a message");
        FUZZ_CHECK(memchr(err.message, '\n', strlen(err.message)) == NULL, "message has a newline: %s", err.message);
        return 0;
    }
    const psys_resume_state *rs1 = psys_scene_resume_state(s1);
    char *t1 = psys_scene_to_string(s1, rs1->present ? rs1 : NULL, &err);
    if (!t1) {
        /* Only a scene too large to print may fail to save (no callbacks here). */
        FUZZ_CHECK(err.code == PSYS_ERR_NOMEM && err.message[0], "save failed: %s", err.message);
        psys_scene_destroy(s1);
        return 0;
    }
    psys_scene *s2 = psys_scene_load_string(t1, strlen(t1), &err);
    FUZZ_CHECK(s2 != NULL, "the saved scene does not load: %s\n--- saved scene:\n%.2000s", err.message, t1);
    const psys_resume_state *rs2 = psys_scene_resume_state(s2);
    FUZZ_CHECK(rs1->present == rs2->present, "checkpoint presence differs");
    char *t2 = psys_scene_to_string(s2, rs2->present ? rs2 : NULL, &err);
    FUZZ_CHECK(t2 != NULL, "the reloaded scene does not save: %s", err.message);
    FUZZ_CHECK(strcmp(t1, t2) == 0, "save -> load -> save changed the text\n--- first:\n%.2000s\n--- second:\n%.2000s",
               t1, t2);
    same_system(psys_scene_system(s1), psys_scene_system(s2));
    /* implicit-euler steps cost far more than explicit ones under the
     * sanitizers (a multigrid solve per step; with planes, collisions re-run
     * steps a hundred times): small systems without planes for it (24
     * particles: still two multigrid levels); its stepping is tested by the
     * suite, the sanitizer build and the allocation-failure sweep. */
    const psys_system *sys1 = psys_scene_system(s1);
    bool implicit = strcmp(psys_scene_settings(s1)->integrator, "implicit-euler") == 0;
    size_t max_stepped = !implicit ? MAX_STEPPED_PARTICLES : psys_system_plane_count(sys1) ? 0 : MAX_IMPLICIT_PARTICLES;
    if (psys_system_count(sys1) <= max_stepped)
        same_run(s1, s2);
    free(t1);
    free(t2);
    psys_scene_destroy(s1);
    psys_scene_destroy(s2);
    return 0;
}
