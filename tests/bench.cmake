# Benchmark programs (bench/; programs, not tests of speed): each runs a
# tiny case, so that they keep building and running. spring_ceiling also
# checks its fused loops against its plain one and exits 1 if they disagree
# (its exit status decides; a pass expression would hide it); 300 steps, so
# that the springs by the anchors move the heights it compares (at 5 steps a
# kind of spring left out went unseen).
add_test(NAME bench.spring_ceiling COMMAND $<TARGET_FILE:spring_ceiling> 16 300)
add_test(NAME bench.pair_bench_lj_threads COMMAND $<TARGET_FILE:pair_bench> lj-threads --cells 4 --reps 2 --steps 3)
set_tests_properties(bench.pair_bench_lj_threads PROPERTIES PASS_REGULAR_EXPRESSION "\"case\":\"lj-threads-summary\",\"atoms\":256,")
