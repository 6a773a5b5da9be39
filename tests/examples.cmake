# Example scenes (tests/cli/examples.sh): every examples/*.json passes
# `psys check` and a short `psys run`; the cloth generator reproduces its
# scene; the physics the docs quote holds; `make demo`'s script works; the
# JSON scenes shown in README.md and docs/ are valid.
file(GLOB PSYS_EXAMPLE_SCENES CONFIGURE_DEPENDS ${PROJECT_SOURCE_DIR}/examples/*.json)
set(PSYS_EXAMPLES_SH ${CMAKE_CURRENT_SOURCE_DIR}/cli/examples.sh)
foreach(scene ${PSYS_EXAMPLE_SCENES})
  get_filename_component(scene_name ${scene} NAME_WE)
  add_test(NAME examples.${scene_name}
    COMMAND bash ${PSYS_EXAMPLES_SH} $<TARGET_FILE:psys_cli> ${PROJECT_SOURCE_DIR} ${scene})
endforeach()
foreach(mode generator claims demo docs)
  add_test(NAME examples.${mode}
    COMMAND bash ${PSYS_EXAMPLES_SH} $<TARGET_FILE:psys_cli> ${PROJECT_SOURCE_DIR} --${mode})
endforeach()
