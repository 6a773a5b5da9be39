# The fused derivative (src/fast/fused.c): the same bits as the generic one.
psys_c_test(test_fused derivative_same_bits runs_same_bits chooses_path planes_same_bits chain_same_bits chain_timed shuffled_same_physics
  state_order_same_bits
  state_order_cache
  avx512_switch
  holds_back_where_large
  sweeps_find_nonfinite)
# The determinism checks again with the fused derivative forced (it then
# also runs small spring sets on several threads), and with it off (the
# generic path, which systems with pair forces, mouse springs and the like
# take): the committed hashes of the examples and the thread-count
# runs. And both again with the compiler's run loops instead of the
# AVX-512 ones where the CPU has AVX-512 (PSYS_SPRING_PLAIN=1; elsewhere
# the same runs again).
foreach(variant "fused:PSYS_FUSED=1" "generic:PSYS_FUSED=0" "plain_spring:PSYS_FUSED=1,PSYS_SPRING_PLAIN=1"
        "plain_spring_generic:PSYS_FUSED=0,PSYS_SPRING_PLAIN=1")
  string(REPLACE ":" ";" parts "${variant}")
  list(GET parts 0 name)
  list(GET parts 1 env)
  string(REPLACE "," ";" env "${env}")
  add_test(NAME cli.determinism.${name}
    COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/cli/determinism.sh $<TARGET_FILE:psys_cli> ${PROJECT_SOURCE_DIR})
  set_tests_properties(cli.determinism.${name} PROPERTIES ENVIRONMENT "${env}")
  foreach(case thread_counts thread_counts_parallel_paths round_trip_runs)
    add_test(NAME test_determinism.${name}.${case} COMMAND test_determinism ${case})
    set_tests_properties(test_determinism.${name}.${case} PROPERTIES ENVIRONMENT "${env}")
  endforeach()
endforeach()
# And with every rk4 and midpoint step swept through memory at once (the
# chain, src/fast/fused.c), forced for every system it can take.
add_test(NAME cli.determinism.chain
  COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/cli/determinism.sh $<TARGET_FILE:psys_cli> ${PROJECT_SOURCE_DIR})
set_tests_properties(cli.determinism.chain PROPERTIES ENVIRONMENT "PSYS_FUSED=1;PSYS_CHAIN=1")
foreach(case thread_counts thread_counts_parallel_paths round_trip_runs)
  add_test(NAME test_determinism.chain.${case} COMMAND test_determinism ${case})
  set_tests_properties(test_determinism.chain.${case} PROPERTIES ENVIRONMENT "PSYS_FUSED=1;PSYS_CHAIN=1")
endforeach()
# The fused tests with the compiler's run loops (PSYS_SPRING_PLAIN=1).
foreach(case derivative_same_bits runs_same_bits planes_same_bits chain_same_bits sweeps_find_nonfinite)
  add_test(NAME test_fused.plain_spring.${case} COMMAND test_fused ${case})
  set_tests_properties(test_fused.plain_spring.${case} PROPERTIES ENVIRONMENT "PSYS_SPRING_PLAIN=1")
endforeach()
