/* State that only the in-tree benchmarks and tests read (the psys bench
 * command, the programs in bench/ and tests/): not part of the C API,
 * whose users get the same bits whichever code path ran. */
#ifndef PSYS_BENCH_H
#define PSYS_BENCH_H

#include "psys/psys.h"

/** Whether the steps timed to choose between equivalent code paths are
 *  over: for rk4 and midpoint on springs that reach far, the first six
 *  steps after the springs, particle count or threads change time every
 *  stage in one sweep against stage by stage. The results are the same
 *  bits either way; benchmarks step until this holds. */
bool psys__system_timing_settled(const psys_system *sys);

/** Grid force evaluations of pair force object i whose rows ran four or
 *  eight at a time (the AVX2 / AVX-512 loops; 0 where they do not run)
 *  into *grouped; PSYS_ERR_INVALID if i is not a pair force. */
psys_status psys__system_pair_grouped(const psys_system *sys, size_t i, size_t *grouped);

#endif
