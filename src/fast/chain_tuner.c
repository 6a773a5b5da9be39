/* Whether a step takes the chain (chain.c) or goes stage by stage: by the
 * springs' reach, and beyond a reach where neither was faster on every host,
 * by timing each system's first steps both ways. Apart from the chain
 * because it is a policy on a wall clock, not a loop; both give the same
 * bits. */
#include "fast/fused.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <time.h>

/* By default the chain runs when the springs reach at most this many
 * particles (ropes, chains, strips of a few dozen columns): there the
 * stages' span stays in L2 and the sweep was faster than stage by stage
 * on one thread and on two (bench/README.md; figures in bench/HISTORY.md).
 * Cloths (bend springs two rows long: reach 712 at 100 columns, 1,024 at
 * 256) reach further: see chain_timed.
 * PSYS_CHAIN=1 runs it whenever it can (tests), 0 never. */
#define CHAIN_AUTO_REACH 600

/* Beyond that reach the two were measured either way round on different
 * hosts (the chain slower on an Intel host, faster on an AMD one:
 * bench/README.md; figures in bench/HISTORY.md), so there
 * each system's first steps time both, alternating, CHAIN_TRIALS steps of
 * each, and the mode whose fastest step was faster stays. A step's time
 * runs from the solver asking whether the chain takes it to the next
 * step's asking; the fastest of several leaves out a first step's set-up
 * and the caller's work between steps. The same bits either way. */
#define CHAIN_TRIALS 3

/* Seconds on a clock that does not jump where there is one (POSIX). */
static double chain_clock(void)
{
    struct timespec ts;
#ifdef CLOCK_MONOTONIC
    clock_gettime(CLOCK_MONOTONIC, &ts);
#else
    timespec_get(&ts, TIME_UTC);
#endif
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* The mode of the step the solver is asking about (1: the chain), by
 * timing: at each asking, the step before it is timed. */
static int chain_timed(psys_system *sys, springs *s)
{
    const int T = psys_system_effective_threads(sys);
    const double now = chain_clock();
    if (!s->chain.keyed || s->chain.plan != s->plan_version || s->chain.n != sys->n || s->chain.T != T) {
        s->chain.keyed = true;
        s->chain.plan = s->plan_version;
        s->chain.n = sys->n;
        s->chain.T = T;
        s->chain.pick = -1;
        s->chain.mode = -1;
        s->chain.steps = 0;
        s->chain.best[0] = s->chain.best[1] = INFINITY;
    }
    if (s->chain.pick < 0 && s->chain.mode >= 0) {
        const double dt = now - s->chain.t;
        if (dt >= 0 && dt < s->chain.best[s->chain.mode])
            s->chain.best[s->chain.mode] = dt;
        if (++s->chain.steps == 2 * CHAIN_TRIALS)
            s->chain.pick = s->chain.best[1] < s->chain.best[0];
    }
    s->chain.mode = s->chain.pick >= 0 ? s->chain.pick : s->chain.steps % 2 == 0;
    s->chain.t = now;
    return s->chain.mode;
}

/* Whether the chain takes sys for `stages` stages; fz gets its forces.
 * ask: the solver asks before a step (the timed choice advances); else the
 * step itself, which follows the answer given. */
bool psys__chain_takes(psys_system *sys, int stages, fused *fz, bool ask)
{
    if (stages < 2 || stages > CHAIN_MAX_STAGES || sys->nctrl || !psys__fused_takes(sys, fz))
        return false;
    springs *s = sys->springs;
    if (sys->sw.chain == '0' || s->nm != 0)
        return false;
    if (sys->sw.chain == '1')
        return true;
    /* the plan's reach (an allocation failure: no, and the stage path reports it) */
    if (psys__springs_prepare_rings(s, sys->n, 1) != PSYS_OK)
        return false;
    if (chain_reach(s) <= CHAIN_AUTO_REACH)
        return true;
    return ask ? chain_timed(sys, s) == 1 : s->chain.mode == 1;
}

bool psys__fused_chain_eligible(psys_system *sys, int stages)
{
    fused fz;
    return psys__chain_takes(sys, stages, &fz, true);
}

int psys__fused_chain_pick(const psys_system *sys)
{
    const springs *s = sys->springs;
    return s && s->chain.keyed ? s->chain.pick : -1;
}

bool psys__system_timing_settled(const psys_system *sys)
{
    const springs *s = sys->springs;
    /* timing started (a mode under way) and not yet decided */
    return !s || !s->chain.keyed || s->chain.pick >= 0 || s->chain.mode < 0;
}
