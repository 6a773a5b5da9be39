# The interactive viewer (psys view, apps/view/) under a private Xvfb:
# cli/view.sh drives a construction session with xdotool and checks the
# saved scene; cli/view_screenshot.sh checks that example scenes draw. They
# exit 77 (reported as skipped, with the reason) only where no X server can
# be started. Leak detection is off for them under ASan (mesa leaks).
if(TARGET psys_view)
  foreach(t view view_screenshot)
    psys_cli_test(${t})
    set_tests_properties(cli.${t} PROPERTIES
      ENVIRONMENT "PSYS_PNG_PROBE=$<TARGET_FILE:png_probe>;ASAN_OPTIONS=detect_leaks=0"
      SKIP_RETURN_CODE 77
      TIMEOUT 300)
  endforeach()
endif()
