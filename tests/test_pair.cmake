psys_c_test(test_pair
  gravity_hand_values coulomb_hand_values lennard_jones_hand_values soft_repulsion_hand_values
  user_law_hand_values user_law_grid_equals_direct newton_third_law lj_cluster_energy sort_lists
  grid_equals_direct_2d grid_equals_direct_3d grid_equals_direct_periodic_2d grid_equals_direct_periodic_3d grid_equals_direct_dense grid_equals_direct_lattice grid_lists_keep_radius
  grid_rebuild_criterion grid_rebuild_criterion_all_moved grid_cache_matches_direct grid_partial_matches_direct grid_partial_keeps_unchanged_rows grid_partial_sparse_groups grid_groups_any_numbering cutoff_boundary_groups minimum_image minimum_image_far minimum_image_far_groups wrapping box_validation
  thread_determinism_grid thread_determinism_direct_bh barnes_hut_error_2d barnes_hut_error_3d kepler_orbit_closes figure_eight_returns jacobians_match_differences
  particles_added_later scene_round_trip checkpoint_resume_bit_exact scene_bad_input)
# Threads sleep rather than spin between parallel regions: ctest runs tests
# side by side on few cores, where spinning threads starve each other.
# The grid tests again with the portable candidate scan of the list builds
# (pair/scan.c uses an AVX-512 one where the CPU has it): the same bits.
foreach(case sort_lists grid_equals_direct_3d grid_equals_direct_periodic_3d grid_equals_direct_dense grid_cache_matches_direct thread_determinism_grid
             checkpoint_resume_bit_exact grid_lists_keep_radius)
  add_test(NAME test_pair.plain_scan.${case} COMMAND test_pair ${case})
endforeach()
# And with the row kernel (pair/group.c runs the grid's forces four rows at
# a time where the CPU has AVX2): the same bits.
foreach(case grid_equals_direct_2d grid_equals_direct_3d grid_equals_direct_periodic_3d grid_equals_direct_lattice grid_partial_matches_direct
             grid_partial_keeps_unchanged_rows grid_cache_matches_direct minimum_image_far_groups thread_determinism_grid)
  add_test(NAME test_pair.rows.${case} COMMAND test_pair ${case})
endforeach()
# And four rows at a time where the CPU would take eight (AVX-512): the same bits.
foreach(case grid_equals_direct_2d grid_equals_direct_3d grid_equals_direct_periodic_3d grid_equals_direct_lattice grid_partial_matches_direct
             grid_partial_keeps_unchanged_rows grid_partial_sparse_groups grid_groups_any_numbering cutoff_boundary_groups grid_cache_matches_direct minimum_image_far_groups thread_determinism_grid)
  add_test(NAME test_pair.group4.${case} COMMAND test_pair ${case})
endforeach()
# And with the AVX-512 build's window in double precision (it takes single
# precision where coordinates are small against the list radius): the same bits.
foreach(case grid_equals_direct_dense grid_equals_direct_lattice grid_lists_keep_radius thread_determinism_grid)
  add_test(NAME test_pair.double_window.${case} COMMAND test_pair ${case})
endforeach()
get_property(psys_pair_tests DIRECTORY PROPERTY TESTS)
foreach(t ${psys_pair_tests})
  if(t MATCHES "^test_pair\\.plain_scan\\.")
    set_tests_properties(${t} PROPERTIES ENVIRONMENT "OMP_WAIT_POLICY=PASSIVE;PSYS_SCAN_PLAIN=1")
  elseif(t MATCHES "^test_pair\\.double_window\\.")
    set_tests_properties(${t} PROPERTIES ENVIRONMENT "OMP_WAIT_POLICY=PASSIVE;PSYS_WINDOW_DOUBLE=1")
  elseif(t MATCHES "^test_pair\\.group4\\.")
    set_tests_properties(${t} PROPERTIES ENVIRONMENT "OMP_WAIT_POLICY=PASSIVE;PSYS_GROUP8_OFF=1")
  elseif(t MATCHES "^test_pair\\.rows\\.")
    set_tests_properties(${t} PROPERTIES ENVIRONMENT "OMP_WAIT_POLICY=PASSIVE;PSYS_GROUP_OFF=1")
  elseif(t MATCHES "^test_pair\\.")
    set_tests_properties(${t} PROPERTIES ENVIRONMENT "OMP_WAIT_POLICY=PASSIVE")
  endif()
endforeach()
