# Rendering, plots and trajectory formats (docs/cli.md): tests/cli/render.sh
# (pictures, frame sequences, GIF, MP4, runs that cannot start), plot.sh
# (--plot and psys plot) and formats.sh (VTP/VTK + PVD, extended XYZ parsed
# back). png_probe reads PNGs back with cairo for the picture checks.
add_executable(png_probe tools/png_probe.c)
target_compile_options(png_probe PRIVATE ${PSYS_FLAGS})
target_link_libraries(png_probe PRIVATE PkgConfig::CAIRO)
foreach(t render plot formats)
  psys_cli_test(${t})
  set_tests_properties(cli.${t} PROPERTIES ENVIRONMENT "PSYS_PNG_PROBE=$<TARGET_FILE:png_probe>")
endforeach()
