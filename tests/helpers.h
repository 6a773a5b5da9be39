/* Helpers shared by the C test files: building systems and solvers, loading
 * and saving scenes, and a reproducible random sequence. Everything is
 * static (inline) rather than in a linked helpers.c
 * because CHECK counts into check.h's per-file check_failures; inline keeps
 * the helpers a file does not use from warning. */
#ifndef PSYS_TESTS_HELPERS_H
#define PSYS_TESTS_HELPERS_H

#include "check.h"

#include <psys/psys.h>

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ------------------------------------------------------------------ */
/* systems and solvers                                                  */
/* ------------------------------------------------------------------ */

/* Tests cannot go on without a system, so a failure ends the test. */
static inline psys_system *make_system(int dim)
{
    psys_error err;
    psys_system *sys = psys_system_create(dim, &err);
    if (!sys) {
        fprintf(stderr, "psys_system_create: %s\n", err.message);
        exit(1);
    }
    return sys;
}

static inline size_t add_particle(psys_system *sys, const double *x, const double *v, double m)
{
    size_t i = (size_t)-1;
    psys_status st = psys_system_add_particle(sys, x, v, m, NULL, &i);
    CHECK(st == PSYS_OK);
    return i;
}

/* A solver on any ODE (custom ones included); a failure ends the test. */
static inline psys_solver *make_ode_solver(const char *name, const psys_ode *ode)
{
    psys_error err;
    psys_solver *s = psys_solver_create(name, ode, &err);
    if (!s) {
        fprintf(stderr, "psys_solver_create(%s): %s\n", name, err.message);
        exit(1);
    }
    return s;
}

/* The system's own solver, with its fast paths (psys_system_solver_create). */
static inline psys_solver *make_solver(const char *name, psys_system *sys)
{
    psys_error err;
    psys_solver *s = psys_system_solver_create(sys, name, &err);
    if (!s) {
        fprintf(stderr, "psys_system_solver_create(%s): %s\n", name, err.message);
        exit(1);
    }
    return s;
}

/* ------------------------------------------------------------------ */
/* scenes                                                               */
/* ------------------------------------------------------------------ */

/* A scene that must load; a failure ends the test. */
static inline psys_scene *load_scene(const char *text)
{
    psys_error err;
    psys_scene *sc = psys_scene_load_string(text, strlen(text), &err);
    if (!sc) {
        fprintf(stderr, "scene failed to load: %s\n", err.message);
        CHECK(sc != NULL);
        exit(1);
    }
    return sc;
}

/* The message a bad scene is rejected with ("" if it loaded). */
static inline const char *load_error(const char *text)
{
    static psys_error err; /* the message outlives the call */
    psys_scene *sc = psys_scene_load_string(text, strlen(text), &err);
    CHECK(sc == NULL);
    if (sc) {
        psys_scene_destroy(sc);
        return "";
    }
    CHECK(err.code == PSYS_ERR_INVALID);
    return err.message;
}

/* Loading must fail with exactly `want`. */
static inline void expect_error(const char *text, const char *want)
{
    psys_error err;
    psys_scene *sc = psys_scene_load_string(text, strlen(text), &err);
    CHECK(sc == NULL);
    if (sc) {
        fprintf(stderr, "  scene loaded but should fail with: %s\n", want);
        psys_scene_destroy(sc);
        return;
    }
    CHECK(err.code == PSYS_ERR_INVALID);
    CHECK_STR(err.message, want);
}

/* The scene as text (free it), NULL on failure. */
static inline char *save_scene(psys_scene *sc)
{
    psys_error err;
    char *text = psys_scene_to_string(sc, NULL, &err);
    if (!text)
        fprintf(stderr, "psys_scene_to_string: %s\n", err.message);
    CHECK(text != NULL);
    return text;
}

/* ------------------------------------------------------------------ */
/* random numbers                                                       */
/* ------------------------------------------------------------------ */

/* The same sequence on every machine (xorshift64*), so a failing case
 * reproduces; urand_seed restarts it. */
static uint64_t urand_state = 0x9E3779B97F4A7C15ull;

static inline void urand_seed(uint64_t seed) { urand_state = seed; }

/* Uniform in [lo, hi). */
static inline double urand(double lo, double hi)
{
    urand_state ^= urand_state >> 12;
    urand_state ^= urand_state << 25;
    urand_state ^= urand_state >> 27;
    uint64_t r = urand_state * 2685821657736338717ull;
    return lo + (hi - lo) * ((double)(r >> 11) * (1.0 / 9007199254740992.0));
}

#endif
