/* The force types scenes know. Adding a force type: one file defining its
 * psys_force_class and psys__force_io, and one line here. */
#include "internal.h"

const psys__force_io *const psys__force_types[] = {
    &psys__gravity_io,
    &psys__drag_io,
    &psys__spring_io,
    &psys__mouse_io,
    &psys__behavior_io,
    &psys__pair_io,
    NULL,
};
