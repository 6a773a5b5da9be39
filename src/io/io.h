/* The scene format's declarations (cJSON), shared by the io files only:
 * io/scene_load.c, io/scene_save.c, json_*.c. The layers below know nothing of
 * JSON; the io files build systems through the C API and the accessors of
 * internal.h, and read them back the same way. */
#ifndef PSYS_IO_H
#define PSYS_IO_H

#include "mpi/mpi.h"

struct cJSON;

/** JSON syntax check that allocates nothing (io/json_check.c): 0 valid, 1 syntax
 *  error, 2 arrays/objects nested deeper than max_depth; *where (may be NULL)
 *  gets the offset where it stopped. Accepts no more than cJSON does. */
int psys__json_check(const char *text, size_t len, int max_depth, size_t *where);

/* ---- scene-format handlers per force type (one json_*.c file each) ---- */
/** A scene being parsed (io/scene_load.c). */
typedef struct psys__parse psys__parse;
/** A scene being read: the system it builds and where failures go. */
struct psys__parse {
    psys_system *sys;
    psys_error *err;
};

/** How one force type is read from and written to scenes. */
typedef struct psys__force_io {
    const char *type;                       /* JSON "type" */
    const psys_force_class *cls;            /* NULL if the type has no class of its own */
    /** Parse obj (path names it in messages) into sys. */
    psys_status (*parse)(psys__parse *p, const struct cJSON *obj, const char *path);
    /** Append JSON objects describing force object data to the array arr. */
    psys_status (*save)(const psys_system *sys, const void *data, struct cJSON *arr);
} psys__force_io;

/** Scene form of gravity (io/json_gravity.c). */
extern const psys__force_io psys__gravity_io;
/** Scene form of drag (io/json_drag.c). */
extern const psys__force_io psys__drag_io;
/** Scene form of springs (io/json_spring.c). */
extern const psys__force_io psys__spring_io;
/** Scene form of mouse springs (io/json_mouse.c). */
extern const psys__force_io psys__mouse_io;
/** Scene form of built-in behaviours (io/json_behavior.c). */
extern const psys__force_io psys__behavior_io;
/** Scene form of built-in pair forces (io/json_pair.c). */
extern const psys__force_io psys__pair_io;

/** All force types known to scenes, NULL-terminated (io/json_registry.c). */
extern const psys__force_io *const psys__force_types[];

/** Parse the scene's top-level "box" (io/json_box.c; io/scene_load.c calls it before particles and forces). */
psys_status psys__parse_box(psys__parse *p, const struct cJSON *root);
/** Add the system's box, if any, to the scene object root; false on out of memory (io/json_box.c). */
bool psys__save_box(const psys_system *sys, struct cJSON *root);

/* ---- helpers for force parsers (io/json_read.c) ---- */
/** The system being built. */
psys_system *psys__parse_system(psys__parse *p);
/** Fail with "PATH: what (got VALUE)" where VALUE is item printed. */
psys_status psys__parse_fail(psys__parse *p, const char *path, const struct cJSON *item, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 4, 5)))
#endif
    ;
/** Reject keys of obj not in the NULL-terminated list allowed. */
psys_status psys__parse_keys(psys__parse *p, const struct cJSON *obj, const char *path, const char *const *allowed);
/** out = path + "." + key (or key at the top level), truncated to cap. */
void psys__key_path(char *out, size_t cap, const char *path, const char *key);
/** Read an integer at key, exact and >= min; *present (may be NULL) says
 *  whether it was there (if not, *out is left as it was). */
psys_status psys__parse_integer(psys__parse *p, const struct cJSON *obj, const char *path, const char *key,
                                long long min, long long *out, bool *present);
/** Read an optional boolean at key (left as it was when absent). */
psys_status psys__parse_bool(psys__parse *p, const struct cJSON *obj, const char *path, const char *key, bool *out);
/** Read an optional non-empty string at key into out (cap bytes; left as it was when absent). */
psys_status psys__parse_string(psys__parse *p, const struct cJSON *obj, const char *path, const char *key,
                               char *out, size_t cap);
/** Read a finite number at key; if absent use def (required if !has_def). min is an
 *  inclusive lower bound unless min_exclusive. */
psys_status psys__parse_number(psys__parse *p, const struct cJSON *obj, const char *path, const char *key,
                               bool has_def, double def, double min, bool min_exclusive, double *out);
/** Read a dim-vector at key (required if def is NULL, else defaults to def). */
psys_status psys__parse_vec(psys__parse *p, const struct cJSON *obj, const char *path, const char *key,
                            const double *def, double *out);
/** Read a dim-vector from the array item it (kp names it in messages). */
psys_status psys__parse_vec_item(psys__parse *p, const struct cJSON *it, const char *kp, int dim, double *out);
/** Read a particle reference (id string or index) at key. */
psys_status psys__parse_ref(psys__parse *p, const struct cJSON *obj, const char *path, const char *key, size_t *out);
/** Read a particle reference from item itself (an array element); path names it. */
psys_status psys__parse_ref_item(psys__parse *p, const struct cJSON *item, const char *path, size_t *out);
/** Parse a JSON array of frames [[t, x...], ...] (t strictly increasing) at
 *  item; *frames is malloc'ed count × (1 + dim). */
psys_status psys__parse_frames(psys__parse *p, const struct cJSON *item, const char *path, double **frames,
                               size_t *count);

/* ---- helpers for force savers (io/json_write.c) ---- */
/** JSON array of frames (exact numbers). */
struct cJSON *psys__frames_json(const double *frames, size_t count, int dim);
/** Add to arr a JSON reference to particle i (its id, else its index). */
struct cJSON *psys__ref_json(const psys_system *sys, size_t i);
/** A JSON number that reads back as exactly x. */
struct cJSON *psys__num_json(double x);
/** Add key: x (exact) to obj; NULL on failure. */
struct cJSON *psys__add_num(struct cJSON *obj, const char *key, double x);
/** A JSON array of dim numbers (exact). */
struct cJSON *psys__vec_json(const double *v, int dim);

/* ---- shared parts of the scene format ---- */
/** Read the optional "muscle" object of obj into out = {amplitude, omega,
 *  phase, phase_step} (phase_step only accepted when with_step; io/json_spring.c). */
psys_status psys__parse_muscle(psys__parse *p, const struct cJSON *obj, const char *path, bool with_step,
                               bool *present, double out[4]);
/** Parse one element of the scene's "structures" array (io/json_structures.c). */
psys_status psys__parse_structure(psys__parse *p, const struct cJSON *obj, const char *path);

#endif
