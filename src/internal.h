/* Private declarations shared by the library's stages: diagnostics, checked
 * size arithmetic, small vector helpers, progress. Not installed. */
#ifndef TESSEL_INTERNAL_H
#define TESSEL_INTERNAL_H

#include "tessel.h"

#include <math.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#if defined(__GNUC__)
#define TSL_PRINTF(a, b) __attribute__((format(printf, a, b)))
#else
#define TSL_PRINTF(a, b)
#endif

/* Fills diag (if not NULL): file name, line (0 = none), byte offset
 * (has_offset = 0: none) and a printf-style message. */
void tsl_diag_set(tessel_diag *diag, const char *file, uint64_t line, int has_offset,
                  uint64_t offset, const char *fmt, ...) TSL_PRINTF(6, 7);

/* a*b and a+b into *out; false on overflow. */
static inline bool tsl_mul_size(size_t a, size_t b, size_t *out)
{
    if (a != 0 && b > SIZE_MAX / a)
        return false;
    *out = a * b;
    return true;
}
static inline bool tsl_add_size(size_t a, size_t b, size_t *out)
{
    if (b > SIZE_MAX - a)
        return false;
    *out = a + b;
    return true;
}

/* malloc(count*size) with overflow check; NULL on overflow or failure. */
void *tsl_alloc_array(size_t count, size_t size);
/* calloc-like, zeroed. */
void *tsl_calloc_array(size_t count, size_t size);
/* Grows *ptr (holding *cap elements of size bytes) to at least need
 * elements, doubling. Returns TESSEL_ERR_NOMEM on failure (ptr unchanged). */
tessel_status tsl_grow(void **ptr, size_t *cap, size_t need, size_t size);
/* realloc of *ptr (old_bytes in use) to new_bytes, keeping the contents;
 * large blocks get the huge-page advice of tsl_alloc_array. Returns
 * TESSEL_ERR_NOMEM on failure (*ptr unchanged). */
tessel_status tsl_resize(void **ptr, size_t old_bytes, size_t new_bytes);
/* Monotonic wall-clock seconds, for the stage times of the stats. */
double tsl_seconds(void);

/* Progress helper: calls the callback if set; returns TESSEL_ERR_CANCELLED
 * when it asks to stop. */
tessel_status tsl_progress(const tessel_callbacks *cb, const char *stage, double fraction);
void tsl_log(const tessel_callbacks *cb, tessel_log_level level, const char *fmt, ...)
    TSL_PRINTF(3, 4);

/* Sets the OpenMP thread count for the next parallel region from a params
 * field (0 = leave the OpenMP default, which honours OMP_NUM_THREADS). */
int tsl_threads(int requested);

/* ---- small vector math on double[3] ---- */
static inline double tsl_dot(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static inline void tsl_sub(const double a[3], const double b[3], double out[3])
{
    out[0] = a[0] - b[0];
    out[1] = a[1] - b[1];
    out[2] = a[2] - b[2];
}
static inline void tsl_cross(const double a[3], const double b[3], double out[3])
{
    double x = a[1] * b[2] - a[2] * b[1];
    double y = a[2] * b[0] - a[0] * b[2];
    double z = a[0] * b[1] - a[1] * b[0];
    out[0] = x;
    out[1] = y;
    out[2] = z;
}
static inline double tsl_norm(const double a[3]) { return sqrt(tsl_dot(a, a)); }
static inline bool tsl_normalize(double a[3])
{
    double n = tsl_norm(a);
    if (!(n > 0.0))
        return false;
    a[0] /= n;
    a[1] /= n;
    a[2] /= n;
    return true;
}
static inline void tsl_load(const float *p, double out[3])
{
    out[0] = p[0];
    out[1] = p[1];
    out[2] = p[2];
}

/* Union-find: the root of x, halving the path to it. */
static inline uint32_t tsl_uf_find(uint32_t *parent, uint32_t x)
{
    while (parent[x] != x) {
        parent[x] = parent[parent[x]];
        x = parent[x];
    }
    return x;
}

/* qsort comparison of uint32_t values, ascending. */
int tsl_cmp_u32(const void *a, const void *b);

/* Eigen-decomposition of a symmetric 3x3 matrix (row-major a[9]).
 * Eigenvalues ascending in w[3]; column i of v (v[3*r+i]) is the unit
 * eigenvector of w[i]. Jacobi rotations: accurate for near-degenerate
 * covariances, which is where normals are decided. */
void tsl_eigen_sym3(const double a[9], double w[3], double v[9]);

/* The same for a covariance m = {a00, a01, a02, a11, a12, a22} (symmetric,
 * positive semi-definite) without rotations, several times cheaper:
 * tsl_sym3_values gives the eigenvalues ascending in l[3], the smallest as
 * the smallest root of the characteristic cubic by Newton's method from 0
 * (below every root, where Newton rises monotonically to it; cheaper than
 * the trigonometric closed form, whose acos and cos cost more than the
 * whole iteration), the other two from the deflated quadratic; false when
 * the trace is not positive. tsl_sym3_vector gives a unit vector of the
 * null space of m - l I, the longest cross product of two of its rows;
 * false when all vanish. That vector is accurate only for an eigenvalue l
 * well apart from the other two: callers take tsl_eigen_sym3 when the gap
 * is under 1e-4 of the largest eigenvalue. */
bool tsl_sym3_values(const double m[6], double l[3]);
bool tsl_sym3_vector(const double m[6], double l, double v[3]);

/* ---- robust orientation predicates (src/predicates.c, Shewchuk 1997) ----
 * The SIGN of the result is exact (filtered double evaluation, exact
 * expansion arithmetic when the filter cannot decide); the magnitude is an
 * approximation. Exact for any inputs whose products neither overflow nor
 * underflow, which covers every float coordinate.
 * tsl_orient2d: > 0 when a, b, c turn counter-clockwise, < 0 clockwise, 0
 *   when collinear (twice the signed area of abc).
 * tsl_orient3d: > 0 when d lies below the plane through a, b, c, "below"
 *   meaning a, b, c appear counter-clockwise seen from above; < 0 above; 0
 *   when coplanar (det[a-d; b-d; c-d], six times the signed volume). */
double tsl_orient2d(const double a[2], const double b[2], const double c[2]);
double tsl_orient3d(const double a[3], const double b[3], const double c[3],
                    const double d[3]);

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

/* Exactly collinear vertices (zero area). */
bool tsl_triangle_degenerate(const double *p[3]);
/* Two non-degenerate triangles with vertex ids ia, ib and coordinates pa,
 * pb intersect in more than their shared vertex or edge (exact, closed
 * triangles). Triangles with three shared ids count as intersecting. */
bool tsl_triangles_intersect(const uint32_t ia[3], const double *pa[3], const uint32_t ib[3],
                             const double *pb[3]);

/* tessel_advancing_front with a second set of unit normal lines (count*3
 * floats, sign not meaningful; NULL: none): a new triangle's normal may
 * agree with either line at each vertex (src/advancing_front.c; the
 * pipeline passes the robust fit's normals of the representatives). */
tessel_status tsl_advancing_front_lines(const tessel_cloud *points, const float *lines,
                                        const tessel_front_params *params,
                                        const tessel_callbacks *callbacks, tessel_mesh *mesh,
                                        tessel_front_stats *stats);

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

/* tsl_advancing_front_lines from a starting mesh: start_count triangles
 * (3 ids into points each, consistently oriented, no two crossing, as a
 * front's output less some triangles). Triangles at vertices the removal
 * left with two fans are dropped; the fronts start from the borders of the
 * rest and cover the points they do not use. With more points than
 * params->tile_points, each tile starts from the triangles inside it, and
 * those across or along a cut are made again by the front that joins the
 * tiles. */
tessel_status tsl_advancing_front_from(const tessel_cloud *points, const float *lines,
                                       const tessel_front_params *params,
                                       const uint32_t *start, size_t start_count,
                                       const tessel_callbacks *callbacks, tessel_mesh *mesh,
                                       tessel_front_stats *stats);

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

/* ---- the projector's own index (src/smooth.c), shared by the stages
 * that search the same cloud ---- */

/* The kd-tree over the projector's cloud, when that cloud's coordinates
 * are `xyz` with `count` points (the same array the projector was made
 * from); else NULL. */
const tessel_index *tsl_projector_index(const tessel_projector *projector, const float *xyz,
                                        size_t count);

/* tessel_smooth, also reporting the seconds spent measuring the spacing
 * when params->spacing is 0 (the noisy pipeline's first column). With
 * grid_order the output's points come in the order of the smoothing's grid
 * (cells in Morton order, nearby points near in memory) instead of the
 * input's: the noisy pipeline, which needs no point of the smoothed cloud
 * by its input index, works on it faster so. */
tessel_status tsl_smooth_timed(const tessel_cloud *cloud, tessel_cloud *out,
                               const tessel_smooth_params *params,
                               const tessel_callbacks *callbacks, tessel_smooth_stats *stats,
                               bool grid_order, double *seconds_spacing);
/* tessel_projector_create on the kd-tree `index` of cloud->xyz (built by
 * the caller, borrowed: it must outlive the projector), or on its own
 * kd-tree when index is NULL. */
tessel_status tsl_projector_create_on(tessel_projector **projector, const tessel_cloud *cloud,
                                     const tessel_smooth_params *params,
                                     const tessel_index *index);

/* tessel_representatives with a projector over `cloud` made by the caller
 * (tessel_projector_create with the projection parameters of params). */
tessel_status tsl_representatives_with(const tessel_cloud *cloud,
                                       const tessel_clusters *clusters,
                                       const tessel_simplify_params *params,
                                       const tessel_projector *projector,
                                       const tessel_callbacks *callbacks, tessel_cloud *out,
                                       tessel_simplify_stats *stats);

/* ---- the noisy-cloud pipeline (src/smooth_pipeline.c) ---- */

/* How many components of m are stray pieces: at most STRAY_FRACTION (1%)
 * of its triangles each, counted only when there are at most STRAY_MAX (8)
 * of them (else 0: a scene of many small pieces is what was sampled).
 * *pieces (when not NULL): the other components. The pipeline's repair
 * sends the front again around stray pieces. */
tessel_status tsl_stray_pieces(const tessel_mesh *m, size_t *strays, size_t *pieces);

/* ---- neighbour search (src/kdtree.c) ---- */

/* Writes the index's count point indices in its storage order (leaf by
 * leaf). Self-queries issued in this order find the tree in cache: 1.7x
 * the queries/s of random order on 10^6 points. */
void tsl_index_order(const tessel_index *index, uint32_t *order);

#endif /* TESSEL_INTERNAL_H */
