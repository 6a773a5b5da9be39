/* The force types scenes know. Adding a force type: its psys_force_class
 * (force_*.c), its psys__force_io (json_*.c), and one line here. */
#include "io/io.h"

const psys__force_io *const psys__force_types[] = {
    &psys__gravity_io,
    &psys__drag_io,
    &psys__spring_io,
    &psys__mouse_io,
    &psys__behavior_io,
    &psys__pair_io,
    NULL,
};
