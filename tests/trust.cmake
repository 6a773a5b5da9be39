# Trust (docs/trust.md): determinism across runs, thread counts and
# checkpoint splits, with committed hashes of the examples' final states
# (tests/determinism.sha256); numerical guard rails; hostile sizes. The
# allocation-failure sweep is tests/test_alloc.cmake, fuzzing fuzz/.
psys_c_test(test_determinism repeat_runs thread_counts thread_counts_parallel_paths round_trip_runs stiffest_omega)
psys_cli_test(determinism)
psys_cli_test(example_outputs)
psys_cli_test(guardrails)
psys_cli_test(hostile)
