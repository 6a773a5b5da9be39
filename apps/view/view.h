/* psys view: the interactive viewer (docs/cli.md "psys view"). Built into
 * the psys executable only when SDL2 and libepoxy are found; the library
 * never sees GL: it draws through psys_draw (gl_render.c implements it). */
#ifndef PSYS_VIEW_H
#define PSYS_VIEW_H

/** `psys view [SCENE] [options]`: argv[0] is "view". Returns the exit status. */
int psys_view_main(int argc, char **argv);

#endif
