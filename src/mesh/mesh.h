/* The mesh layer, private to the library: what the reconstruction
 * methods share (a triangle hash grid, vertex corners, fans and
 * components, checked flips and splits, the orientation check by ray
 * parity). The methods build on it and not on each other. Not
 * installed. */
#ifndef TESSEL_MESH_H
#define TESSEL_MESH_H

#include "core/core.h"

/* ---- triangle hash grid (mesh/trigrid.c), the advancing front's and the
 * checked edits' index of the triangles near a new one ----
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

/* ---- topology (mesh/topology.c) ---- */

/* The corners of each vertex: corner[start[v] .. start[v + 1]) are the
 * corners i (triangle i / 3, position i % 3) of tri[0 .. 3 nt) at vertex
 * v < nv, in increasing order. Both arrays are allocated; the caller frees
 * them. */
tessel_status tsl_vertex_corners(const uint32_t *tri, size_t nt, size_t nv, uint32_t **start,
                                 uint32_t **corner);

/* Connected components by shared vertices: root[v] (nv entries, filled)
 * is the smallest vertex of v's component (v itself for a vertex on no
 * triangle). Triangles whose first vertex is TESSEL_NONE (removed) are
 * skipped. Joined on `threads` threads (0: all), the same for any. */
void tsl_vertex_components(const uint32_t *tri, size_t nt, size_t nv, int threads,
                           uint32_t *root);
/* sum[v] (nv entries) = the sum of mix(w) over v's outgoing edges v -> w
 * less the sum over its incoming ones (tsl_mix64, a bijection, wrapping):
 * 0 exactly when v's fan is closed, if every vertex has a single fan. */
void tsl_open_fans(const uint32_t *tri, size_t nt, size_t nv, int threads, uint64_t *sum);
/* The connected components of a mesh (by shared vertices, which for
 * single fans is by edges, as tessel_mesh_check counts them) numbered
 * 0 .. *ncomp in the order of their first triangle: comp[t] for each of
 * the nt triangles (none removed). */
tessel_status tsl_triangle_components(const uint32_t *tri, size_t nt, size_t nv, int threads,
                                      uint32_t *comp, size_t *ncomp);

/* ---- tiles oriented against each other (mesh/tile_orient.c) ----
 * Orients the tiles' components (comp[t] for triangle t of tri[0 .. count),
 * ncomp of them, over the points xyz, dcut[v] each point's distance to the
 * nearest cut) against each other: a pair of components facing each other
 * across a cut agree or disagree by the normals of their nearest triangles
 * there (triangles with a vertex within near of a cut, nearest centroid of
 * another component within radius, along the surface); the strongest
 * agreements are taken first (a maximum spanning forest), so a weak or
 * wrong one cannot override them. Reversed components get their triangles
 * turned. drop[c] (ncomp bytes) is set for components to leave to the
 * front that closes the seams: those whose pairs contradict the forest,
 * and those under `small` triangles at a cut. cut_axis[v]: the axis the cut nearest
 * point v runs across; a triangle whose plane meets its nearest cut at an
 * angle theta searches radius / sin(theta) (at most 4 radius): a gap of a
 * given width along the axis is that much wider along a surface that
 * meets the cut at a shallow angle. */
tessel_status tsl_orient_tiles(uint32_t *tri, const uint32_t *comp, size_t count, size_t ncomp,
                               const float *xyz, const float *dcut, const uint8_t *cut_axis,
                               double near, double radius, size_t small, int threads,
                               uint8_t *drop);

/* ---- checked local edits (mesh/edit.c, flip.c, split.c) ---- */

/* Open-addressing map from an undirected edge to one of its half-edges,
 * with backward-shift deletion. A slot holds key and value together: a
 * lookup that misses the cache costs one line, not two. */
typedef struct tsl_edge_slot {
    uint64_t key; /* (min << 32 | max) + 1; 0 = empty */
    uint32_t val;
} tsl_edge_slot;

typedef struct tsl_edge_map {
    tsl_edge_slot *slot;
    size_t slots, count;
} tsl_edge_map;

/* An empty map with room for `expected` edges without growing. */
tessel_status tsl_edge_map_init(tsl_edge_map *m, size_t expected);
void tsl_edge_map_free(tsl_edge_map *m);
/* Sets the half-edge of {a, b}, adding the edge if new. */
tessel_status tsl_edge_map_put(tsl_edge_map *m, uint32_t a, uint32_t b, uint32_t he);
/* tsl_edge_map_put for several threads filling a map at once: the map was
 * sized for every key (no growth), each key is put once, and nobody reads
 * it until all are in. The caller sets m->count after. */
void tsl_edge_map_put_shared(tsl_edge_map *m, uint32_t a, uint32_t b, uint32_t he);
void tsl_edge_map_del(tsl_edge_map *m, uint32_t a, uint32_t b);

static inline uint64_t tsl_edge_key(uint32_t a, uint32_t b)
{
    uint64_t lo = a < b ? a : b, hi = a < b ? b : a;
    return (lo << 32 | hi) + 1;
}

static inline size_t tsl_edge_map_slot(const tsl_edge_map *m, uint64_t key)
{
    uint64_t h = key * 0x9E3779B97F4A7C15ULL;
    return (size_t)(h ^ (h >> 31)) & (m->slots - 1);
}

/* The half-edge of {a, b}, or TESSEL_NONE. */
static inline uint32_t tsl_edge_map_get(const tsl_edge_map *m, uint32_t a, uint32_t b)
{
    uint64_t key = tsl_edge_key(a, b);
    for (size_t s = tsl_edge_map_slot(m, key); m->slot[s].key; s = (s + 1) & (m->slots - 1))
        if (m->slot[s].key == key)
            return m->slot[s].val;
    return TESSEL_NONE;
}

/* Asks for the line of {a, b}'s home slot ahead of a tsl_edge_map_get. */
static inline void tsl_edge_map_prefetch(const tsl_edge_map *m, uint32_t a, uint32_t b)
{
    __builtin_prefetch(&m->slot[tsl_edge_map_slot(m, tsl_edge_key(a, b))]);
}

/* What the edits did. */
typedef struct tsl_edit_counts {
    size_t splits, flips;
    size_t skipped_skinny;  /* splits refused for a too skinny triangle */
    size_t skipped_invalid; /* edits refused by the checks */
} tsl_edit_counts;

/* A mesh under checked edits. The caller fills the vertices, the
 * triangles and their capacities (cap_v, cap_t; the edits grow xyz_own,
 * rgb, tri, twin and box beyond them), after tsl_edit_init. */
typedef struct tsl_edit {
    const float *xyz; /* the vertices: xyz_own, or the caller's points when
                         only flipping (tsl_flip_diagonals never splits) */
    float *xyz_own;   /* a copy that splits grow */
    uint8_t *rgb;     /* NULL when the mesh has no colours */
    size_t nv, cap_v;
    uint32_t *tri;  /* 3 per triangle */
    uint32_t *twin; /* per half-edge 3t+i (tri[3t+i] -> tri[3t+(i+1)%3]) */
    float *box;     /* per triangle: lo[3], hi[3] of its current corners */
    size_t nt, cap_t;
    tsl_edge_map edges;
    tsl_trigrid grid;
    double cos_turn;
    bool delaunay; /* the flip rule: see flip_edge */
    /* Flips only: fixed[t] (NULL: none) keeps triangle t's edges, and no
     * new diagonal may be longer than sqrt(max_edge2) (0: any). */
    const uint8_t *fixed;
    double max_edge2;
    tsl_edit_counts counts;
    double lo[3], hi[3]; /* the triangles' box when the grid was built */
    struct tsl_edit_worker *serial; /* the checks and edits outside parallel phases */
    /* pinched[v]: vertex v (v < npinched) has more than one fan; NULL when
     * none has. tsl_edit_edge_exists sees one fan only, so their flips go to
     * the serial tail, which asks the edge map. */
    uint8_t *pinched;
    size_t npinched;
} tsl_edit;

/* An empty editable mesh (no vertices, no triangles). */
tessel_status tsl_edit_init(tsl_edit *e);
/* Frees everything e holds (tri too: set it to NULL first when it is the
 * caller's). */
void tsl_edit_free(tsl_edit *e);
/* Twins (in parallel) and the edge map (each edge at its half-edge of
 * smaller id), and e->pinched for vertices with more than one fan;
 * INVALID_ARG for a non-manifold or inconsistently oriented mesh or a
 * triangle with a repeated or bad vertex. */
tessel_status tsl_edit_topology(tsl_edit *e, int threads);
/* A fresh triangle grid, with cells two mean edges wide, over the
 * triangles' boxes (a point no triangle uses must not stretch the cells). */
tessel_status tsl_edit_grid(tsl_edit *e);
/* Flips, pass after pass, every diagonal the rule asks for (e->delaunay:
 * the opposite angles add up to more than pi; else the other diagonal is
 * shorter) and the checks allow, in parallel; the result depends on the
 * mesh only, not on the thread count. Needs the topology and the grid. */
tessel_status tsl_edit_flips(tsl_edit *e, int threads);

/* A split: the edge {u, v} at a new vertex at pos. */
typedef struct tsl_split_job {
    uint32_t u, v;
    float pos[3];
} tsl_split_job;

/* The splits jobs[want[0 .. n)], in that order, each checked, in parallel
 * blocks; a split whose triangles have their shortest edge under min_ratio
 * times their longest is not made. The result depends on the mesh only,
 * not on the thread count. */
tessel_status tsl_edit_splits(tsl_edit *e, const tsl_split_job *jobs, const uint32_t *want,
                              size_t n, double min_ratio, int threads);
/* Area-weighted unit vertex normals, 3 * e->nv doubles (allocated). */
tessel_status tsl_edit_vertex_normals(const tsl_edit *e, double **out);

static inline void tsl_edit_point(const tsl_edit *e, uint32_t v, double out[3])
{
    tsl_load(e->xyz + 3 * (size_t)v, out);
}
/* The ends of half-edge h. */
static inline uint32_t tsl_he_from(const tsl_edit *e, uint32_t h) { return e->tri[h]; }
static inline uint32_t tsl_he_to(const tsl_edit *e, uint32_t h)
{
    return e->tri[h - h % 3 + (h % 3 + 1) % 3];
}

/* Flips, in place, the diagonal of every pair of triangles whose angles
 * opposite it add up to more than pi (the Delaunay rule, which raises the
 * pair's smallest angle), pass after pass, with the checks of the edits
 * (mesh/edit.c): each flip kept only if the new edge is not there
 * already, neither new triangle turns more than 60 degrees from the pair's
 * normal and neither meets the mesh beyond shared vertices and edges
 * (exact). tri (nt triangles over the points xyz, nv of them) must be
 * manifold and consistently oriented; the triangles keep their slots.
 * threads: 0 = OpenMP default; the result is the same for any count.
 * *flips: the diagonals flipped.
 *
 * fixed (NULL: none): triangles t with fixed[t] keep their edges; the
 * checks see them, and their vertices may have several fans (a part of a
 * larger mesh, cut around the triangles to flip). New diagonals are then
 * no longer than the longest edge L of the triangles not fixed, so a flip
 * stays within L of each vertex of its pair: a part that holds every
 * triangle meeting the balls of radius L around theirs holds every
 * triangle a flip could meet. */
tessel_status tsl_flip_diagonals(const float *xyz, size_t nv, uint32_t *tri, size_t nt,
                                 const uint8_t *fixed, int threads, size_t *flips);
/* The square of the longest edge of the nt triangles tri over xyz, less
 * those t with skip[t] (skip NULL: none). */
double tsl_longest_edge2(const float *xyz, const uint32_t *tri, size_t nt, const uint8_t *skip);

/* Removes the triangles (tri[3 i ..], *count of them, consistently
 * oriented, over n vertices) at every vertex with more than one fan, until
 * none is left, keeping the rest in order; only vertices flagged in touched
 * (cleared on return) can have one (mesh/topology.c). With gone, *gone
 * receives the removed triangles (*ngone of them, in order; the caller
 * frees it). */
tessel_status tsl_single_fans(size_t n, uint32_t *tri, size_t *count, uint8_t *touched,
                              uint32_t **gone, size_t *ngone);

/* ---- orientation check by ray parity (src/mesh/orient.c) ----
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
