# MPI equivalence tests (docs/mpi.md), only in an -DPSYS_MPI=ON build: 2 and
# 4 ranks on one machine (oversubscribed) against the serial run, byte for byte.
if(PSYS_MPI)
  foreach(case lj-grid lj-direct gravity-direct gravity-bh granular checkpoint errors)
    add_test(NAME mpi.${case}
      COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/cli/mpi.sh $<TARGET_FILE:psys_cli> ${PROJECT_SOURCE_DIR}
              ${MPIEXEC_EXECUTABLE} ${case})
    set_tests_properties(mpi.${case} PROPERTIES LABELS mpi TIMEOUT 900)
  endforeach()
endif()
