# The drawing interface, bounds and the VTP/VTK/PVD/XYZ frame writers (src/sim/draw.c, src/io/output_vtk.c, src/io/output_xyz.c).
psys_c_test(test_draw draw_order_and_values draw_null_callbacks draw_radius_clamped draw_behaviours bounds vtp_frame pvd_escapes xyz_frame)
