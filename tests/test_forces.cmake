psys_c_test(test_forces spring_force_eq1 spring_runs_shared_parameters spring_damping_along_l spring_rest_length spring_invalid_arguments spring_zero_length gravity_and_drag custom_force_class jacobian_2d jacobian_3d)
# The spring tests again with the compiler's run loops where the CPU has
# AVX-512 (PSYS_SPRING_PLAIN=1: forces/spring.c's loops without run_forces_512).
foreach(case spring_force_eq1 spring_runs_shared_parameters spring_zero_length)
  add_test(NAME test_forces.plain_spring.${case} COMMAND test_forces ${case})
  set_tests_properties(test_forces.plain_spring.${case} PROPERTIES ENVIRONMENT "PSYS_SPRING_PLAIN=1")
endforeach()
