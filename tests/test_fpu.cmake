# The floating-point mode for subnormal results (src/base/fpu.c): flushing on and
# off, subnormal inputs kept, inherited by new threads, never changed by the
# library itself.
psys_c_test(test_fpu flush_toggles inputs_keep_value new_threads_inherit library_leaves_mode)
find_package(Threads REQUIRED)
target_link_libraries(test_fpu PRIVATE Threads::Threads)
