/* The mesh layer, private to the library: what every reconstruction
 * method shares (a triangle hash grid, vertex corners and fans, checked
 * diagonal flips, the orientation check). The methods build on it and not
 * on each other. Not installed. */
#ifndef TESSEL_MESH_H
#define TESSEL_MESH_H

#include "core/core.h"

/* ---- triangle hash grid and exact triangle tests (src/advancing_front.c),
 * shared by the advancing front and the refinement (src/refine.c) ----
 * A uniform grid hashed on cell coordinates; a triangle is listed in every
 * cell its bounding box meets. Insert-only: a caller that replaces
 * triangles inserts the new ones and skips stale ids it gets back, so a
 * query returns a superset of the triangles whose boxes meet the box. */

/* A query's result with its own scratch, so that several threads can
 * query one grid at once: tsl_trigrid_hits_begin starts a result, and each
 * tsl_trigrid_collect adds the ids listed in the cells of a grid that meet
 * [lo, hi] (the grid only read), each id once per result, into
 * found[0 .. count). The ids seen are kept in a small hash set stamped
 * with the result's number (a query finds tens of triangles; a stamp per
 * triangle id would be a cache miss each on large meshes). */
typedef struct tsl_trigrid_hits {
    uint64_t *seen; /* slots: result number << 32 | id */
    size_t seen_cap; /* a power of two, at least twice count */
    uint32_t now;
    uint32_t *found;
    size_t count, found_cap;
} tsl_trigrid_hits;

typedef struct tsl_trigrid {
    double origin[3], inv_cell;
    uint64_t *keys;          /* slots: cell key + 1 (0 = empty) */
    uint32_t *heads;         /* slots: first entry of the cell */
    size_t slots, used;
    uint32_t *ent_tri, *ent_next;
    size_t entries, ent_cap;
    size_t id_end;           /* one past the largest id inserted */
    tsl_trigrid_hits hits;   /* tsl_trigrid_query's result */
} tsl_trigrid;

/* cell: edge length of a cell (> 0); [lo, hi]: the box that will hold the
 * triangles (used to keep cell coordinates in range). */
tessel_status tsl_trigrid_init(tsl_trigrid *g, const double lo[3], const double hi[3],
                               double cell);
/* An empty grid with the cells of like (same origin and cell). */
tessel_status tsl_trigrid_init_like(tsl_trigrid *g, const tsl_trigrid *like);
/* Room for this many entries (triangle-cell pairs) and cells, so that
 * inserting them neither copies the entries nor rehashes the cells. */
tessel_status tsl_trigrid_reserve(tsl_trigrid *g, size_t entries, size_t cells);
tessel_status tsl_trigrid_insert(tsl_trigrid *g, uint32_t tri, const double lo[3],
                                 const double hi[3]);
/* Triangle ids whose cells meet the box [lo, hi], each once, into
 * g->hits.found[0 .. g->hits.count). Not thread-safe (scratch in g). */
tessel_status tsl_trigrid_query(tsl_trigrid *g, const double lo[3], const double hi[3]);
/* Empties g, keeping its memory. */
void tsl_trigrid_clear(tsl_trigrid *g);
void tsl_trigrid_free(tsl_trigrid *g);
/* Whether the cells of box [lo, hi] are among those of [olo, ohi] (a
 * triangle listed for the latter needs no listing for the former). */
bool tsl_trigrid_covers(const tsl_trigrid *g, const double olo[3], const double ohi[3],
                        const double lo[3], const double hi[3]);
tessel_status tsl_trigrid_hits_begin(tsl_trigrid_hits *h);
tessel_status tsl_trigrid_collect(const tsl_trigrid *g, const double lo[3], const double hi[3],
                                  tsl_trigrid_hits *h);
void tsl_trigrid_hits_free(tsl_trigrid_hits *h);

/* The corners of each vertex: corner[start[v] .. start[v + 1]) are the
 * corners i (triangle i / 3, position i % 3) of tri[0 .. 3 nt) at vertex
 * v < nv, in increasing order. Both arrays are allocated; the caller frees
 * them. */
tessel_status tsl_vertex_corners(const uint32_t *tri, size_t nt, size_t nv, uint32_t **start,
                                 uint32_t **corner);

/* Connected components by shared vertices: root[v] (nv entries, filled)
 * is the smallest vertex of v's component (v itself for a vertex on no
 * triangle). Triangles whose first vertex is TESSEL_NONE (removed) are
 * skipped. */
void tsl_vertex_components(const uint32_t *tri, size_t nt, size_t nv, uint32_t *root);

/* Flips, in place, the diagonal of every pair of triangles whose angles
 * opposite it add up to more than pi (the Delaunay rule, which raises the
 * pair's smallest angle), pass after pass, with the refinement's checks
 * (src/refine.c): each flip kept only if the new edge is not there
 * already, neither new triangle turns more than 60 degrees from the pair's
 * normal and neither meets the mesh beyond shared vertices and edges
 * (exact). tri (nt triangles over the points xyz, nv of them) must be
 * manifold and consistently oriented; the triangles keep their slots.
 * threads: 0 = OpenMP default; the result is the same for any count.
 * *flips: the diagonals flipped. */
tessel_status tsl_flip_diagonals(const float *xyz, size_t nv, uint32_t *tri, size_t nt,
                                 int threads, size_t *flips);

/* Removes the triangles (tri[3 i ..], *count of them, consistently
 * oriented, over n vertices) at every vertex with more than one fan, until
 * none is left, keeping the rest in order; only vertices flagged in touched
 * (cleared on return) can have one (src/advancing_front.c). */
tessel_status tsl_single_fans(size_t n, uint32_t *tri, size_t *count, uint8_t *touched);

/* ---- orientation check by ray parity (src/orient.c) ----
 * For the triangles tri[0 .. nt) over xyz (nv points): mark[t] = 1 for a
 * triangle of a connected region whose rays say it faces into a closed
 * surface while most of its component faces out (flip it), 2 for such a
 * triangle on the region's rim (drop it: flipped, it would clash with its
 * neighbours), 0 otherwise. *flipped: triangles marked 1 or 2. Results
 * are the same for any thread count. */
tessel_status tsl_orient_check(const float *xyz, size_t nv, const uint32_t *tri, size_t nt,
                               int threads, uint8_t *mark, size_t *flipped);
/* The same where the points' side is known: each triangle votes out when
 * it agrees with the sum of its vertices' normals (normals, one per point)
 * or, normals NULL, faces viewpoint (in xyz's frame), and a region voting
 * in is flipped however much of its component it holds. */
tessel_status tsl_orient_check_toward(const float *xyz, size_t nv, const uint32_t *tri,
                                      size_t nt, const float *normals,
                                      const double *viewpoint, int threads, uint8_t *mark,
                                      size_t *flipped);
/* Whether the points' normals (one per point) are oriented: their signs
 * agree across most of the mesh's edges. Unoriented normals decide no
 * side, and the ray check applies. */
bool tsl_normals_signed(const float *normals, const uint32_t *tri, size_t nt);
/* The check's verdict applied: the triangles marked 1 turned, those
 * marked 2 left out, the rest copied; out may be tri. Returns how many
 * triangles out holds. */
size_t tsl_orient_apply(const uint32_t *tri, size_t nt, const uint8_t *mark, uint32_t *out);

#endif /* TESSEL_MESH_H */
