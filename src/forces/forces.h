/* The forces layer: what the built-in force types expose to the layers
 * above (data accessors for drawing, scenes and MPI; the spring set). */
#ifndef PSYS_FORCES_H
#define PSYS_FORCES_H

#include "core/core.h"

/** Gravity object's acceleration (forces/gravity.c). */
const double *psys__gravity_g(const void *data);
/** Drag object's coefficient (forces/drag.c). */
double psys__drag_kd(const void *data);
/** A mouse spring's particle, constants, fixed target (dim numbers) and
 *  scripted path (*nframes frames of 1 + dim numbers; 0: none) (forces/mouse.c). */
void psys__mouse_get(const void *data, size_t *particle, double *ks, double *kd, const double **target,
                     const double **frames, size_t *nframes);
/** A pair force's definition, defaults resolved (forces/pair.c). */
const psys_pair_def *psys__pair_def(const void *data);
/** A behaviour's definition as added, defaults resolved (forces/behavior.c). */
const psys_behavior_def *psys__behavior_def(const void *data);
/** Built-in behaviour function i in table order (false past the end): its
 *  function, name, particle count and the NULL-terminated keys of its
 *  parameters in scenes (any out pointer may be NULL; forces/behavior.c). */
bool psys__behavior_builtin(size_t i, psys_behavior_function *f, const char **name, int *nparticles,
                            const char *const **keys);
/** A pair force's particles were replaced (not just moved): rebuild its lists
 *  and forget its cached forces at the next evaluation (forces/pair.c). */
void psys__pair_invalidate(void *data);

/* ---- spring set internals (forces/spring.c) ---- */
/** The damped spring law's magnitude over |l|: with len2 = |l|², dot = l̇·l,
 *  [ks(|l| - r) + kd dot/|l|] / |l|, and 0 for a spring of zero length (no
 *  direction, no force); the force on the first end is -mag·l. The one
 *  expression of every spring loop (serial and across MPI ranks), so they
 *  give the same bits. */
static inline double psys__spring_mag(double ks, double kd, double rest, double len2, double dot)
{
    double L = sqrt(len2), inv = 1.0 / L;
    double mag = (ks * (L - rest) + kd * dot * inv) * inv;
    return len2 == 0 ? 0.0 : mag;
}

/** Create an empty spring set of the system owner (whose thread count it uses). */
void *psys__springs_create(const psys_system *owner);
/** Append one spring. */
psys_status psys__springs_add(void *set, size_t a, size_t b, double ks, double kd, double rest);
/** Number of springs. */
size_t psys__springs_count(const void *set);
/** Read spring k. */
void psys__springs_get(const void *set, size_t k, size_t *a, size_t *b, double *ks, double *kd, double *rest);
/** Give spring k a muscle (amplitude 0 removes it); arguments already validated. */
psys_status psys__springs_set_muscle(void *set, size_t k, double amplitude, double omega, double phase);
/** True if spring k has a muscle; its parameters into the out pointers (may be NULL). */
bool psys__springs_muscle(const void *set, size_t k, double *amplitude, double *omega, double *phase);
/** Rest length of spring k at time t (muscles included). */
double psys__springs_rest_at(const void *set, size_t k, double t);
/** Drop springs n.. (and their muscles); never allocates. */
void psys__springs_truncate(void *set, size_t n);
/** Build the spring set's evaluation plan if the set changed (allocates;
 *  PSYS_ERR_NOMEM on failure). Called before evaluating forces. */
psys_status psys__springs_prepare(void *set);
/** The order in which each particle's force receives its spring forces
 *  (builds the plan): row i of rowptr (np + 1) and ent (2·count) lists
 *  particle i's contributions, 2k for spring k's lower-index end (-F) and
 *  2k + 1 for its higher one (+F); seq[e] (2·count) is entry e's place in
 *  the loop's whole sequence of additions. */
psys_status psys__springs_order(void *set, size_t np, size_t *rowptr, uint32_t *ent, uint64_t *seq);
/** How MPI ranks read a bonded class's terms (psys_force_class.terms,
 *  mpi/bonded.c): a spring set's springs, or one behaviour. */
typedef enum psys__terms_kind { PSYS__TERMS_SPRINGS, PSYS__TERMS_BEHAVIOR } psys__terms_kind;
struct psys__force_terms {
    psys__terms_kind kind;
};
/** Copy of behaviour force data (forces/behavior.c; free() frees it). */
void *psys__behavior_clone(const void *data);
/** A behaviour's particles (count, then each index). */
int psys__behavior_count(const void *data);
size_t psys__behavior_particle(const void *data, int i);
/** The force a behaviour adds to each of its particles, out[i·d + c], from
 *  their positions and velocities gathered in its order (x, v: count·d). */
void psys__behavior_forces(const void *data, const double *x, const double *v, double *out);

/* ---- periodic box and pair forces (forces/box.c, forces/pair.c) ---- */
/** Wrap free particles into the box on periodic axes (after accepted steps). */
void psys__box_wrap(psys_system *s);
/** Check pair force data (of class psys_pair_class or psys_pair_user_class)
 *  against box; on failure write a message into msg. */
psys_status psys__pair_check_box(const void *pair, const psys__box *box, char *msg, size_t cap);

/** Grid force evaluations of pair force object i whose rows ran four or
 *  eight at a time (the AVX2 / AVX-512 loops; 0 where they do not run)
 *  into *grouped; PSYS_ERR_INVALID if i is not a pair force. */
psys_status psys__system_pair_grouped(const psys_system *sys, size_t i, size_t *grouped);

#endif
