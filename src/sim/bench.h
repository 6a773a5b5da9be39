/* What only the in-tree benchmarks and tests read (the psys bench command,
 * the programs in bench/ and tests/): psys__system_timing_settled
 * (fast/fast.h) and psys__system_pair_grouped (forces/forces.h). Not part
 * of the C API, whose users get the same bits whichever code path ran. */
#ifndef PSYS_BENCH_H
#define PSYS_BENCH_H

#include "sim/sim.h"

#endif
