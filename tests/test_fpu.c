/* psys_fpu_flush_subnormals and psys_fpu_flushes_subnormals (src/base/fpu.c):
 * results below the smallest normal double become 0 with flushing on and
 * stay subnormal with it off; subnormal inputs keep their value either way
 * (flush to zero, not denormals are zero); threads created afterwards
 * inherit the mode; the library never changes it by itself. Where the CPU
 * has no such mode the call says so (false) and nothing changes. */
#include "check.h"

#include <psys/psys.h>

#include <pthread.h>

/* A result of 1e-310: below DBL_MIN (2.2e-308), so subnormal unless flushed. */
static double tiny_product(void)
{
    volatile double a = 1e-300, b = 1e-10;
    return a * b;
}

/* Whether the mode can be switched here: switches it on if so. */
static bool flushing_on(void)
{
    bool have = psys_fpu_flush_subnormals(true);
    CHECK(psys_fpu_flushes_subnormals() == have);
    return have;
}

static void flush_toggles(void)
{
    const bool was = psys_fpu_flushes_subnormals();
    const bool have = flushing_on();
    double r = tiny_product();
    if (have) {
        CHECK(r == 0.0 && !signbit(r));
    } else {
        CHECK(fpclassify(r) == FP_SUBNORMAL);
    }
    CHECK(psys_fpu_flush_subnormals(false) == have);
    CHECK(!psys_fpu_flushes_subnormals());
    r = tiny_product();
    CHECK(fpclassify(r) == FP_SUBNORMAL);
    CHECK_NEAR(r / 1e-310, 1.0, 1e-3);
    psys_fpu_flush_subnormals(was);
}

static void inputs_keep_value(void)
{
    const bool have = flushing_on();
    volatile double s = 1e-310; /* a subnormal input, as a scene's value */
    CHECK(fpclassify(s) == FP_SUBNORMAL);
    CHECK(s > 0.0);        /* compared as what it is: no DAZ */
    CHECK(s + 1.0 == 1.0); /* a normal result from it */
    volatile double half = s * 0.5;
    CHECK(have ? half == 0.0 : fpclassify(half) == FP_SUBNORMAL);
    psys_fpu_flush_subnormals(false);
}

static void *thread_product(void *out)
{
    *(double *)out = tiny_product();
    return NULL;
}

static void new_threads_inherit(void)
{
    for (int on = 1; on >= 0; on--) {
        const bool have = psys_fpu_flush_subnormals(on != 0);
        pthread_t t;
        double r = -1;
        CHECK(pthread_create(&t, NULL, thread_product, &r) == 0);
        CHECK(pthread_join(t, NULL) == 0);
        if (have && on)
            CHECK(r == 0.0);
        else
            CHECK(fpclassify(r) == FP_SUBNORMAL);
    }
}

/* A hanging spring stepped by rk4 with the mode on and then off: the
 * mode is as the caller left it after every step. */
static void library_leaves_mode(void)
{
    const double g[2] = {0, -9.81}, x0[2] = {0, 0}, x1[2] = {1, 0}, v[2] = {0, 0};
    for (int on = 1; on >= 0; on--) {
        const bool have = psys_fpu_flush_subnormals(on != 0);
        psys_system *s = psys_system_create(2, NULL);
        CHECK(psys_system_add_particle(s, x0, v, 1.0, NULL, NULL) == PSYS_OK);
        CHECK(psys_system_add_particle(s, x1, v, 1.0, NULL, NULL) == PSYS_OK);
        CHECK(psys_system_set_fixed(s, 0, true) == PSYS_OK);
        CHECK(psys_system_add_gravity(s, g) == PSYS_OK);
        CHECK(psys_system_add_spring(s, 0, 1, 100.0, 0.5, 1.0) == PSYS_OK);
        psys_solver *sv = psys_system_solver_create(s, "rk4", NULL);
        CHECK(sv != NULL);
        for (int k = 0; k < 20; k++) {
            double taken;
            CHECK(psys_solver_step(sv, 1e-3, &taken) == PSYS_OK);
            CHECK(psys_fpu_flushes_subnormals() == (have && on));
        }
        psys_solver_destroy(sv);
        psys_system_destroy(s);
    }
}

static const check_case cases[] = {
    {"flush_toggles", flush_toggles},
    {"inputs_keep_value", inputs_keep_value},
    {"new_threads_inherit", new_threads_inherit},
    {"library_leaves_mode", library_leaves_mode},
    {NULL, NULL},
};

int main(int argc, char **argv) { return check_main(argc, argv, cases); }
