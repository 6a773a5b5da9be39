# Allocation-failure injection (tests/test_alloc.c, docs/trust.md): every
# allocation of loading, running and saving representative scenes, and of the
# CLI's run/resume/check commands, is made to fail in turn; each failure must
# end in an error with a message, free everything and leave no half-written
# file. Needs the static libpsys.a (the allocator is swapped in with ld --wrap).
get_target_property(PSYS_LIB_TYPE psys TYPE)
if(PSYS_LIB_TYPE STREQUAL "STATIC_LIBRARY" AND CMAKE_C_COMPILER_ID MATCHES "GNU|Clang")
  add_executable(test_alloc test_alloc.c)
  target_compile_options(test_alloc PRIVATE ${PSYS_FLAGS})
  target_link_libraries(test_alloc PRIVATE psys_cli_parts psys cjson m)
  target_link_options(test_alloc PRIVATE
    -Wl,--wrap=malloc,--wrap=calloc,--wrap=realloc,--wrap=strdup,--wrap=free)
  # Representative scenes: springs and gravity, controllers (oscillate,
  # circle, keyframes), behaviours, mouse springs, planes, every structure
  # (small: the sweep costs the square of a scene's allocation count, and
  # examples/hanging-cloth.json alone makes 144000), muscles, pair forces,
  # checkpoints, implicit-euler and rk45.
  set(PSYS_ALLOC_SCENES
    examples/double-pendulum.json
    examples/driven-pendulum.json
    examples/motor-mechanism.json
    examples/bouncing-balls.json
    examples/rope-bridge.json
    examples/worm.json
    fuzz/corpus/scene/features-2d.json
    fuzz/corpus/scene/structures-small-3d.json
    fuzz/corpus/scene/beam-2d.json
    fuzz/corpus/scene/checkpoint-3d.json
    fuzz/corpus/scene/pair-2d.json)
  foreach(scene ${PSYS_ALLOC_SCENES})
    get_filename_component(scene_name ${scene} NAME_WE)
    foreach(mode lib cli)
      add_test(NAME alloc.${mode}.${scene_name} COMMAND test_alloc ${mode} ${PROJECT_SOURCE_DIR}/${scene})
      set_tests_properties(alloc.${mode}.${scene_name} PROPERTIES ENVIRONMENT "OMP_NUM_THREADS=1")
    endforeach()
  endforeach()
endif()
