/* Minimal test harness: each test file defines cases in a table and CTest
 * runs one case per test (the case name is argv[1]). */
#ifndef PSYS_TESTS_CHECK_H
#define PSYS_TESTS_CHECK_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int check_failures = 0;

#define CHECK(cond)                                                                      \
    do {                                                                                 \
        if (!(cond)) {                                                                   \
            fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, __LINE__, #cond);     \
            check_failures++;                                                            \
        }                                                                                \
    } while (0)

/* |a - b| <= tol, printing both values on failure. */
#define CHECK_NEAR(a, b, tol)                                                            \
    do {                                                                                 \
        double check_a_ = (a), check_b_ = (b), check_t_ = (tol);                         \
        if (!(fabs(check_a_ - check_b_) <= check_t_)) {                                  \
            fprintf(stderr, "%s:%d: CHECK_NEAR failed: %s = %.17g, %s = %.17g, |diff| = %.3g > %.3g\n", \
                    __FILE__, __LINE__, #a, check_a_, #b, check_b_, fabs(check_a_ - check_b_), check_t_); \
            check_failures++;                                                            \
        }                                                                                \
    } while (0)

#define CHECK_STR(a, b)                                                                  \
    do {                                                                                 \
        const char *check_sa_ = (a), *check_sb_ = (b);                                   \
        if (!check_sa_ || !check_sb_ || strcmp(check_sa_, check_sb_) != 0) {             \
            fprintf(stderr, "%s:%d: CHECK_STR failed:\n  got:      %s\n  expected: %s\n", \
                    __FILE__, __LINE__, check_sa_ ? check_sa_ : "(null)",                 \
                    check_sb_ ? check_sb_ : "(null)");                                   \
            check_failures++;                                                            \
        }                                                                                \
    } while (0)

typedef struct check_case {
    const char *name;
    void (*fn)(void);
} check_case;

/* Run the case named argv[1], or every case when none is named. */
static int check_main(int argc, char **argv, const check_case *cases)
{
    int ran = 0;
    for (const check_case *c = cases; c->name; c++) {
        if (argc > 1 && strcmp(argv[1], c->name) != 0)
            continue;
        c->fn();
        ran++;
        fprintf(stderr, "%s: %s\n", c->name, check_failures ? "FAILED" : "ok");
    }
    if (!ran) {
        fprintf(stderr, "no test case named %s\n", argc > 1 ? argv[1] : "(none)");
        return 1;
    }
    return check_failures ? 1 : 0;
}

#endif
