# Docs stay true: every link between the project's Markdown files names a
# file and a heading that exist (tests/tools/md_links.py; python3 comes
# from scripts/install-deps.sh).
find_program(PSYS_PYTHON3 python3)
if(PSYS_PYTHON3)
  add_test(NAME docs.links COMMAND ${PSYS_PYTHON3} ${CMAKE_CURRENT_SOURCE_DIR}/tools/md_links.py ${PROJECT_SOURCE_DIR})
else()
  message(WARNING "python3 not found: the docs.links test is not built (scripts/install-deps.sh installs it)")
endif()
