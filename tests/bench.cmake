# Benchmark programs (bench/; programs, not tests of speed): each runs a
# tiny case, so that they keep building and running. spring_ceiling also
# checks its fused loops against its plain one and exits 1 if they disagree
# (its exit status decides; a pass expression would hide it); 300 steps, so
# that the springs by the anchors move the heights it compares (at 5 steps a
# kind of spring left out went unseen).
add_test(NAME bench.spring_ceiling COMMAND $<TARGET_FILE:spring_ceiling> 16 300)
add_test(NAME bench.pair_bench_lj_threads COMMAND $<TARGET_FILE:pair_bench> lj-threads --cells 4 --reps 2 --steps 3)
set_tests_properties(bench.pair_bench_lj_threads PROPERTIES PASS_REGULAR_EXPRESSION "\"case\":\"lj-threads-summary\",\"atoms\":256,")

# bench/results.py --quick: every step of the one command behind
# bench/README.md's Results (the peer scripts, psys bench, spring_ceiling,
# pair_bench, callgrind) at tiny sizes, so that a change to what a program
# or script prints fails here, not in the next benchmark run. Its figures
# mean nothing. A step whose tool (lmp, valgrind, libbullet-dev: all from
# scripts/install-deps.sh) or peer source ($PEERS: bench/README.md, "Peer programs")
# is missing is left out and named in the output; one that fails, fails the
# test. Not under the sanitizers (valgrind cannot run ASan binaries).
find_program(PSYS_PYTHON3 python3)
if(PSYS_PYTHON3 AND NOT PSYS_SANITIZE)
  add_test(NAME bench.results_quick
    COMMAND ${PSYS_PYTHON3} ${PROJECT_SOURCE_DIR}/bench/results.py ${CMAKE_BINARY_DIR} --quick
            --logs ${CMAKE_CURRENT_BINARY_DIR}/results-quick)
  set_tests_properties(bench.results_quick PROPERTIES TIMEOUT 900)
endif()
