# MPI equivalence tests (docs/mpi.md), only in an -DPSYS_MPI=ON build: 2 and
# 4 ranks on one machine (oversubscribed) against the serial run, byte for byte.
if(PSYS_MPI)
  foreach(case lj-grid lj-direct gravity-direct gravity-bh granular lj-melt gas2d cloth cloth-shuffled polymer arm crank hail checkpoint errors)
    add_test(NAME mpi.${case}
      COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/cli/mpi.sh $<TARGET_FILE:psys_cli> ${PROJECT_SOURCE_DIR}
              ${MPIEXEC_EXECUTABLE} ${case})
    set_tests_properties(mpi.${case} PROPERTIES LABELS mpi TIMEOUT 900)
  endforeach()
endif()

# The library API under mpiexec: psys_system_set_comm, the owner split, forces
# bit-identical to the serial ones (tests/test_mpi.c).
if(PSYS_MPI)
  add_executable(test_mpi test_mpi.c)
  target_compile_options(test_mpi PRIVATE ${PSYS_FLAGS})
  target_link_libraries(test_mpi PRIVATE psys MPI::MPI_C m)
  set(PSYS_MPIEXEC_FLAGS "")
  execute_process(COMMAND ${MPIEXEC_EXECUTABLE} --version OUTPUT_VARIABLE psys_mpiexec_version ERROR_QUIET)
  if(psys_mpiexec_version MATCHES "Open MPI|OpenRTE")
    set(PSYS_MPIEXEC_FLAGS --oversubscribe)
  endif()
  foreach(r 1 2 3 4)
    add_test(NAME mpi.api.${r} COMMAND ${MPIEXEC_EXECUTABLE} ${PSYS_MPIEXEC_FLAGS} -n ${r} $<TARGET_FILE:test_mpi>
             ${CMAKE_CURRENT_SOURCE_DIR}/mpi/lj-melt.json ${CMAKE_CURRENT_SOURCE_DIR}/mpi/cloth.json
             ${CMAKE_CURRENT_SOURCE_DIR}/mpi/polymer.json ${CMAKE_CURRENT_SOURCE_DIR}/mpi/arm.json
             ${CMAKE_CURRENT_SOURCE_DIR}/mpi/crank.json ${CMAKE_CURRENT_SOURCE_DIR}/mpi/hail.json)
    set_tests_properties(mpi.api.${r} PROPERTIES LABELS mpi TIMEOUT 300
      ENVIRONMENT "OMPI_ALLOW_RUN_AS_ROOT=1;OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1")
  endforeach()
endif()
