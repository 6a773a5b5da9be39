# Force traits: a force type defined outside the library gets the paths its
# traits promise (verlet's velocity-free shortcut, the fused derivative) and
# the built-in gravity's bits; without traits, the generic paths, same bits.
psys_c_test(test_traits verlet_shortcut fused_path same_bits)
