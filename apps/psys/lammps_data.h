/* Reader of LAMMPS data files (read_data / write_data format) for
 * `psys import lammps`: atom_style atomic, an orthogonal box, Masses,
 * lj/cut Pair Coeffs or PairIJ Coeffs, Atoms and Velocities. */
#ifndef PSYS_LAMMPS_DATA_H
#define PSYS_LAMMPS_DATA_H

#include <stdbool.h>
#include <stddef.h>

/** What was read. Atoms are sorted by id. */
typedef struct lmp_data {
    size_t natoms;        /**< from the header ("N atoms") */
    int ntypes;           /**< from the header ("N atom types") */
    double lo[3], hi[3];  /**< box bounds */
    double *mass;         /**< per type, index 1..ntypes */
    bool have_coeffs;     /**< a Pair Coeffs or PairIJ Coeffs section was read */
    double epsilon, sigma;/**< the (common) lj/cut coefficients when have_coeffs */
    bool have_cutoff;     /**< the coefficient lines gave a (common) cutoff too */
    double cutoff;        /**< that cutoff */
    long long *id;        /**< atom ids, increasing */
    int *type;            /**< atom types */
    double *x;            /**< positions, natoms × 3 */
    double *v;            /**< velocities, natoms × 3 (zero without a Velocities section) */
    bool have_velocities; /**< a Velocities section was read */
} lmp_data;

/** Read path ("-": standard input). With any_coeffs, the Pair Coeffs of
 *  different types need not agree (the caller overrides them). On failure
 *  returns -1 with "line N: problem (got TEXT)" (or "problem" when no line
 *  is to blame) in msg; d is then empty. */
int lmp_data_read(const char *path, bool any_coeffs, lmp_data *d, char *msg, size_t cap);
/** Free what lmp_data_read allocated. */
void lmp_data_free(lmp_data *d);

#endif
