# The layers point one way (docs/architecture.md): tests/tools/layers.py reads
# the includes of src/ and, from the library's compiled objects (nm), which
# file uses which file's functions and variables; it fails on a use against
# the layer order, on cJSON outside src/io/, and on a cycle of more than
# four files, naming the files.
find_program(PSYS_NM nm)
if(PSYS_NM)
  add_test(NAME layers
    COMMAND python3 ${CMAKE_CURRENT_SOURCE_DIR}/tools/layers.py ${PROJECT_SOURCE_DIR}/src
            --objects "$<TARGET_OBJECTS:psys>")
endif()
