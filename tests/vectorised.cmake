# The spring loops vectorise (the compiler's vectorisation report, GCC on
# x86-64 Linux; skipped elsewhere): cli/vectorised.sh compiles the sources
# holding the marked loops with the library's release flags.
if(CMAKE_C_COMPILER_ID STREQUAL "GNU")
  set(PSYS_VEC_FLAGS -O3 ${PSYS_FLAGS} -std=c11 -fno-trapping-math)
  if(OpenMP_C_FOUND)
    list(APPEND PSYS_VEC_FLAGS ${OpenMP_C_FLAGS} -DPSYS_HAVE_OPENMP)
  endif()
  add_test(NAME cli.vectorised
    COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/cli/vectorised.sh ${CMAKE_C_COMPILER} ${PROJECT_SOURCE_DIR} ${PSYS_VEC_FLAGS})
  set_tests_properties(cli.vectorised PROPERTIES SKIP_RETURN_CODE 77)
endif()
