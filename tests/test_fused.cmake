# The fused derivative (src/spring_fused.c): the same bits as the generic one.
psys_c_test(test_fused derivative_same_bits runs_same_bits chooses_path)
# The determinism checks again with the fused derivative forced (it then
# also runs small spring sets on several threads), and with it off (the
# generic path, which systems with planes, pair forces, mouse springs and
# the like take): the committed hashes of the examples and the thread-count
# runs.
add_test(NAME cli.determinism.fused
  COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/cli/determinism.sh $<TARGET_FILE:psys_cli> ${PROJECT_SOURCE_DIR})
foreach(case thread_counts thread_counts_parallel_paths round_trip_runs)
  add_test(NAME test_determinism.fused.${case} COMMAND test_determinism ${case})
endforeach()
set_tests_properties(cli.determinism.fused test_determinism.fused.thread_counts
  test_determinism.fused.thread_counts_parallel_paths test_determinism.fused.round_trip_runs
  PROPERTIES ENVIRONMENT "PSYS_FUSED=1")
add_test(NAME cli.determinism.generic
  COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/cli/determinism.sh $<TARGET_FILE:psys_cli> ${PROJECT_SOURCE_DIR})
foreach(case thread_counts thread_counts_parallel_paths round_trip_runs)
  add_test(NAME test_determinism.generic.${case} COMMAND test_determinism ${case})
endforeach()
set_tests_properties(cli.determinism.generic test_determinism.generic.thread_counts
  test_determinism.generic.thread_counts_parallel_paths test_determinism.generic.round_trip_runs
  PROPERTIES ENVIRONMENT "PSYS_FUSED=0")
