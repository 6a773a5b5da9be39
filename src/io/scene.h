/* The scene object shared by the loader, the saver and runs. */
#ifndef PSYS_SCENE_H
#define PSYS_SCENE_H

#include "mpi/mpi.h"

struct psys_scene {
    psys_system *sys;
    psys_settings settings;
    psys_resume_state resume;
};

#endif
