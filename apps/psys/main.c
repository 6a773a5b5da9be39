/* psys: the command-line program (docs/cli.md). */
#include "cli.h"

#include <stdlib.h>
#include <string.h>

#ifdef PSYS_HAVE_VIEW
#include "../view/view.h"
#endif

static const char usage[] =
    "usage:\n"
    "  psys run SCENE [--dt H] [--steps N | --duration T] [--integrator NAME]\n"
    "                 [--every K] [--out FILE] [--energy FILE.csv] [--plot FILE.png]\n"
    "                 [--render FILE] [--size WxH] [--fps F] [--camera SPEC] [--radius R]\n"
    "                 [--threads N] [--checkpoint FILE] [--resume FILE] [--mpi MODE] [--quiet]\n"
    "  psys check SCENE [--save FILE]   validate, print a summary, optionally write it back\n"
    "  psys plot FILE.csv --y COLUMNS [--x COLUMN] [--particle I] [--size WxH]\n"
    "                 [--title TEXT] --out FILE.png   plot columns of a psys CSV file\n"
    "  psys view [SCENE] [--save FILE] [--integrator NAME] [--dt H] [--paused]\n"
    "                 [--size WxH] [--controls | --no-controls] [--frames N] [--screenshot FILE.png]\n"
    "                                   interactive viewer and editor (empty 2-D scene if none)\n"
    "  psys bench [CASE] [--integrator NAME] [--threads N] [--reps N] [--seconds S] [--steps N] [--bandwidth GBS]\n"
    "                                   benchmark cases (cloth-100, cloth-256, cloth-1024, rope-1000000,\n"
    "                                   lj-melt, nbody-4096; cloth-N[-shuffled|-floor], N in 2..4096),\n"
    "                                   JSON lines\n"
    "  psys import lammps FILE.data --out SCENE.json [--cutoff RC] [--skin S] [--shift]\n"
    "                 [--epsilon E --sigma S] [--dt H] [--steps N] [--integrator NAME]\n"
    "                                   scene from a LAMMPS data file (write_data; atom_style atomic)\n"
    "  psys --help | --version\n"
    "\n"
    "SCENE is a JSON scene file (docs/scene-format.md), or - for standard input.\n"
    "Flags override the scene's values. Integrators: euler, midpoint, rk4,\n"
    "symplectic-euler, verlet, rk45, implicit-euler.\n"
    "\n"
    "run options:\n"
    "  --dt H            step size (first step for rk45)\n"
    "  --steps N         take N steps\n"
    "  --duration T      simulate T seconds (the last step is shortened to end at T)\n"
    "  --integrator NAME solver to use\n"
    "  --every K         write every K-th step (the first and last states always)\n"
    "  --out FILE        trajectory: .csv (step,t,i,x,y[,z],vx,vy[,vz]), .vtp or .vtk\n"
    "                    (NAME_000000.vtp... one per frame + NAME.pvd for ParaView), .xyz\n"
    "  --energy FILE.csv energy CSV: step,t,kinetic,potential,total\n"
    "  --plot FILE.png   plot of kinetic, potential and total energy against time\n"
    "  --render FILE     pictures: out.png (last frame), frames/%04d.png, out.gif, out.mp4\n"
    "  --size WxH        picture and plot size in pixels (default 800x600)\n"
    "  --fps F           frames per simulated second for --render (default 30)\n"
    "  --camera SPEC     view, comma-separated: ortho|perspective, az=DEG, el=DEG, fov=DEG,\n"
    "                    up=x|y|z, center=X:Y[:Z], extent=L, zoom=F, fit=run|start\n"
    "  --radius R        particle radius in pictures (scene units; default from the scene)\n"
    "  --threads N       worker threads (results never depend on N)\n"
    "  --checkpoint FILE write the complete state at the end (or on SIGINT/SIGTERM)\n"
    "  --resume FILE     continue from a checkpoint; --steps/--duration count from it\n"
    "  --mpi MODE        under mpiexec (MPI builds): domain (each rank holds the particles\n"
    "                    of its box of space and ghosts), replicated (every rank holds every\n"
    "                    particle), auto (domain where the scene allows it; default)\n"
    "  --quiet, -q       no progress bar, no interruption notice and no warnings\n"
    "\n"
    "view options (keys and mouse: H in the viewer, docs/cli.md):\n"
    "  --save FILE       where Ctrl+S saves (default: SCENE, or untitled.json)\n"
    "  --integrator NAME, --dt H   solver and step to start with (keys 1-7, [ and ])\n"
    "  --paused          start paused (Space runs)\n"
    "  --size WxH        window size (default 960x720)\n"
    "  --controls, --no-controls   show or hide the list of controls at the start\n"
    "                    (default: shown for an empty scene)\n"
    "  --frames N        quit after drawing N frames\n"
    "  --screenshot FILE.png   write the last frame drawn (after --frames N, default 1)\n"
    "                    as PNG, print each particle's pixel, and quit\n"
    "\n";
/* the rest apart: one literal would pass the 4,095 characters C99 promises */
static const char usage_end[] =
    "Results below 2.2e-308 are flushed to zero on x86-64; PSYS_FLUSH_SUBNORMALS=0 in the\n"
    "environment keeps them (docs/cli.md, Floating point).\n"
    "\n"
    "Exit status: 0 success; 1 the run failed (files keep every frame up to the last\n"
    "good state); 2 bad usage or bad scene (no file is created or touched);\n"
    "128+signal when interrupted by SIGINT or SIGTERM.\n";

int main(int argc, char **argv)
{
    /* Before any thread exists, so every thread inherits it: subnormal
     * results flushed to zero (docs/cli.md, "Floating point") */
    const char *flush = getenv("PSYS_FLUSH_SUBNORMALS");
    psys_fpu_flush_subnormals(!(flush && flush[0] == '0'));
    if (argc < 2) {
        fputs(usage, stderr);
        fputs(usage_end, stderr);
        return EXIT_BAD_INPUT;
    }
    const char *cmd = argv[1];
    /* psys --help, and psys COMMAND --help (the viewer prints its own) */
    static const char *const helped[] = {"run", "check", "bench", "plot", "import"};
    bool sub_help = false;
    const bool help_arg = argc > 2 && (strcmp(argv[2], "--help") == 0 || strcmp(argv[2], "-h") == 0);
    for (size_t i = 0; i < sizeof helped / sizeof helped[0] && help_arg; i++)
        sub_help = sub_help || strcmp(cmd, helped[i]) == 0;
    if (strcmp(cmd, "--help") == 0 || strcmp(cmd, "-h") == 0 || strcmp(cmd, "help") == 0 || sub_help) {
        fputs(usage, stdout);
        fputs(usage_end, stdout);
        return EXIT_OK;
    }
    if (strcmp(cmd, "--version") == 0) {
        if (argc > 2) {
            cli_error("--version takes no arguments (got %s)", argv[2]);
            return EXIT_BAD_INPUT;
        }
        printf("psys %s\n", PSYS_VERSION_STRING);
        return EXIT_OK;
    }
    if (strcmp(cmd, "run") == 0)
        return cmd_run(argc - 1, argv + 1);
    if (strcmp(cmd, "check") == 0)
        return cmd_check(argc - 1, argv + 1);
    if (strcmp(cmd, "bench") == 0)
        return cmd_bench(argc - 1, argv + 1);
    if (strcmp(cmd, "plot") == 0)
        return cmd_plot(argc - 1, argv + 1);
    if (strcmp(cmd, "import") == 0)
        return cmd_import(argc - 1, argv + 1);
    if (strcmp(cmd, "view") == 0) {
#ifdef PSYS_HAVE_VIEW
        return psys_view_main(argc - 1, argv + 1);
#else
        cli_error("view: this psys was built without the viewer (it needs SDL2 and libepoxy: "
                  "apt-get install libsdl2-dev libepoxy-dev libstb-dev, then rebuild)");
        return EXIT_BAD_INPUT;
#endif
    }
    cli_error("unknown command \"%s\" (see psys --help)", cmd);
    return EXIT_BAD_INPUT;
}
