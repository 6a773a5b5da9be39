/* Grid method of pair forces, the internals its files share: pair/grid.c
 * (storage, cells, the build), pair/scan.c (particle-by-particle scans and
 * the list sorts), pair/cells.c (the AVX-512 cell-by-cell fill) and
 * pair/moved.c (the skin check, the moved particles). The small inline
 * helpers live here so that every file inlines them as before.
 *
 * The method: cell lists (spatial buckets) and Verlet neighbour lists with
 * a skin.
 *
 * A build sorts the particles into cells at least (cutoff + skin)/2 wide
 * (counting sort, so each cell lists its particles in increasing index) and
 * gives every particle the list of partners within cutoff + skin (all of
 * them, or only those of higher index: pair/pair.h), sorted by index (the force
 * sum is then the direct method's, bit for bit). A particle scans the cells
 * within two cells of its own whose nearest point is within cutoff + skin of
 * it. The lists stay valid until the two largest displacements since the
 * build add up to the skin (no pair can have closed its gap by more), the
 * particle count, the box or the kind of list wanted changes; then they are
 * rebuilt. Periodic axes:
 * the cells tile the box exactly and wrap around; distances use the minimum
 * image. Free axes: the cells span the particles' bounding box. The number
 * of cells is capped at about twice the number of particles (cells grow
 * wider for sparse or far-flung clouds), so storage is O(n) and a build
 * O(n) at bounded density.
 *
 * Lists are written in one pass: particles are cut into chunks of
 * CHUNK consecutive indices, each chunk writes into its own region of the
 * list array, sized from the previous build's neighbours per particle; a
 * region that overflows makes the build resize the regions and run again
 * (this, and a growing system, are the only times the array grows). With
 * AVX-512, full lists are filled cell by cell instead (fill_by_cells, pair/cells.c):
 * each particle gets a slot as long as the last build's longest list plus
 * eight (or 1.2 times its mean plus twelve, if more), and a longer list
 * makes the build run again with slots that fit it. */
#ifndef PSYS_PAIR_GRID_H
#define PSYS_PAIR_GRID_H

#include "pair/pair.h"

/* Particles per chunk of the one-pass list fill; the longest list the
 * sorts' scratch holds (sort_indices' tmp, the cell fill's lists). */
#define CHUNK 128
#define SORT_MAX 512

#if (defined(__GNUC__) || defined(__clang__)) && defined(__x86_64__)
#include <immintrin.h>
#define PSYS_SCAN_AVX512 1
#endif

/* Coordinate of x on axis k relative to the cell origin, wrapped on periodic axes. */
static inline double cell_rel(const pair_grid *g, const pair_image *m, int k, double x)
{
    double t = x - g->cell_lo[k];
    if (m->per[k] && !(t >= 0 && t < m->len[k]))
        t -= m->len[k] * floor(t / m->len[k]);
    return t;
}

/* Cells around a particle's own, per axis: offsets -2..2 (pruned by the
 * particle's distance to them), or, on a periodic axis of fewer than five
 * cells, each cell once (offsets 0..n-1, not pruned). */
typedef struct stencil {
    int n[3];
    int off[3][5];
    bool prune[3];
} stencil;

/* Cell index v on axis k (possibly one box out) wrapped into the grid on a
 * periodic axis, with *sh the shift at which that cell's image lies (its
 * particles' coordinates + *sh); -1 outside a free axis. */
static inline int wrap_cell(const pair_grid *g, const pair_image *m, int k, int v, double *sh)
{
    const int nk = g->ncell[k];
    *sh = 0;
    if (m->per[k]) {
        if (v < 0) {
            *sh = -m->len[k];
            return v + nk;
        }
        if (v >= nk) {
            *sh = m->len[k];
            return v - nk;
        }
        return v;
    }
    return v < 0 || v >= nk ? -1 : v;
}

/* Coordinate k of particle i as the builds see it: wrapped into the box on
 * periodic axes (lo + t), the position itself on free axes. */
static inline double build_coord(const pair_grid *g, const pair_image *m, int k, double x)
{
    return m->per[k] ? g->cell_lo[k] + cell_rel(g, m, k, x) : x;
}

/* ---- pair/grid.c ---- */
/** Sort the particles into cells and fill their lists for positions e->x
 *  (psys__pair_grid_update calls it when the lists no longer hold). False if
 *  storage could not grow. */
bool psys__pair_grid_build(pair_force *p, const psys_force_eval *e, const pair_image *m, bool half);

/* ---- pair/scan.c ---- */
/** Whether the AVX-512 scans and sorts run here (once per build). */
bool psys__pair_scan_has_avx512(const psys_system *sys);
/** Sort a list of indices in place (tmp: SORT_MAX entries of scratch). */
void psys__pair_sort_indices(uint32_t *a, size_t n, uint32_t *tmp);
/** Fill every chunk's lists (2 or 3 dimensions; h: half lists); true if none overflowed its region. */
bool psys__pair_fill_2(pair_force *p, const stencil *sc, const pair_image *m, const double *x, size_t n,
                       size_t nchunks, double rl2, int nt, bool sort);
bool psys__pair_fill_3(pair_force *p, const stencil *sc, const pair_image *m, const double *x, size_t n,
                       size_t nchunks, double rl2, int nt, bool sort);
bool psys__pair_fill_2h(pair_force *p, const stencil *sc, const pair_image *m, const double *x, size_t n,
                        size_t nchunks, double rl2, int nt, bool sort);
bool psys__pair_fill_3h(pair_force *p, const stencil *sc, const pair_image *m, const double *x, size_t n,
                        size_t nchunks, double rl2, int nt, bool sort);
#ifdef PSYS_SCAN_AVX512
/** a[0..n) sorted into dst (n <= 128); false, touching nothing, if longer. */
__attribute__((target("avx512f"))) bool psys__pair_sort_avx512_to(const uint32_t *a, size_t n, uint32_t *dst);

/* ---- pair/cells.c ---- */
/** Full lists cell by cell into slots of room entries: the longest list, or
 *  SIZE_MAX if some list is too long for the scratch (or storage could not grow). */
size_t psys__pair_fill_by_cells(pair_force *p, const stencil *sc, const pair_image *m, size_t n, size_t room,
                                double rl2, double scale, int nt, int d);
#endif

#endif
