# Docs stay true (python3 comes from scripts/install-deps.sh):
# - docs.links: every link between the project's Markdown files names a
#   file and a heading that exist (tests/tools/md_links.py);
# - docs.bench_results: bench/README.md's Results are what bench/results.py
#   prints from the raw outputs kept in bench/results/ (and it still reads them);
# - docs.api_programs: below.
find_program(PSYS_PYTHON3 python3)
if(PSYS_PYTHON3)
  add_test(NAME docs.links COMMAND ${PSYS_PYTHON3} ${CMAKE_CURRENT_SOURCE_DIR}/tools/md_links.py ${PROJECT_SOURCE_DIR})
  # docs.api_programs: the complete programs of docs/api.md, built with the
  # command lines it shows against this build's libpsys.a, print what it
  # quotes (not under the sanitizers, whose library needs their flags; the
  # lines name -fopenmp, so only where OpenMP is on).
  if(NOT PSYS_SANITIZE AND PSYS_OPENMP AND OpenMP_C_FOUND)
    add_test(NAME docs.api_programs
      COMMAND ${PSYS_PYTHON3} ${CMAKE_CURRENT_SOURCE_DIR}/tools/api_programs.py ${PROJECT_SOURCE_DIR} ${CMAKE_BINARY_DIR})
  endif()
  add_test(NAME docs.bench_results
    COMMAND ${PSYS_PYTHON3} ${PROJECT_SOURCE_DIR}/bench/results.py --replay
            --logs ${PROJECT_SOURCE_DIR}/bench/results/2026-12-06-68895a1 --check ${PROJECT_SOURCE_DIR}/bench/README.md)
else()
  message(WARNING "python3 not found: the docs.* tests are not built (scripts/install-deps.sh installs it)")
endif()
