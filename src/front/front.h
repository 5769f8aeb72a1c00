/* The advancing front (src/front/), private to the library: the entry
 * points the noisy-cloud pipeline calls beside tessel_advancing_front,
 * then the state the front's files share. Not installed. */
#ifndef TESSEL_FRONT_H
#define TESSEL_FRONT_H

#include "mesh/mesh.h"

#include <math.h>

/* tessel_advancing_front with a second set of unit normal lines (count*3
 * floats, sign not meaningful; NULL: none): a new triangle's normal may
 * agree with either line at each vertex (src/front/; the
 * pipeline passes the robust fit's normals of the representatives). */
tessel_status tsl_advancing_front_lines(const tessel_cloud *points, const float *lines,
                                        const tessel_front_params *params,
                                        const tessel_callbacks *callbacks, tessel_mesh *mesh,
                                        tessel_front_stats *stats);

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

/* The tiles of a front to run (tsl_af_run_tiles): tile k's points are
 * ids[range[k] .. range[k + 1]) of s (tile_of and local: each point's tile
 * and place in it), its starting triangles start[3 sfrom[k] ..
 * 3 sfrom[k + 1]) in local ids; each tile's front goes to tiles[k]. */
typedef struct af af;
typedef struct tsl_af_tiles_job {
    const af *s;
    const tessel_front_params *p;
    size_t count;
    const size_t *range;
    const uint32_t *ids, *tile_of, *local, *start;
    const size_t *sfrom;
    const tessel_callbacks *cb;
    af *tiles;
} tsl_af_tiles_job;

/* Who runs the tiles: NULL, this process's threads; the MPI runner
 * (src/mpi/) spreads them over processes. A tile's front depends on the
 * tile alone, so any runner gives the same mesh. */
typedef struct tsl_af_tile_runner {
    tessel_status (*run)(void *ctx, const tsl_af_tiles_job *job);
    void *ctx;
} tsl_af_tile_runner;

/* tsl_advancing_front_lines with its tiles run by runner. */
tessel_status tsl_advancing_front_lines_with(const tessel_cloud *points, const float *lines,
                                             const tessel_front_params *params,
                                             const tsl_af_tile_runner *runner,
                                             const tessel_callbacks *callbacks,
                                             tessel_mesh *mesh, tessel_front_stats *stats);

/* Tile k of job into job->tiles[k]: its inputs (tsl_af_tile_inputs), then
 * its front (tsl_af_tile_run). */
tessel_status tsl_af_tile(const tsl_af_tiles_job *job, size_t k, const tessel_callbacks *cb);
/* Tile k's inputs into t: its points (and normals and lines), normal
 * lines, nearest distances, duplicate flags and neighbours (those in the
 * tile, in local ids). */
tessel_status tsl_af_tile_inputs(const tsl_af_tiles_job *job, size_t k, af *t);
/* The room for a tile's inputs (m points, k neighbours each, p's derived
 * parameters), for a process that receives them. */
tessel_status tsl_af_tile_alloc(af *t, size_t m, uint32_t k, const tessel_front_params *p,
                                bool normals, bool lines);
/* A tile's front from its inputs: the mesh with cells of `cell`, the
 * starting triangles, the fronts. */
tessel_status tsl_af_tile_run(af *t, double cell, const uint32_t *start, size_t nstart,
                              const tessel_callbacks *cb);

/* ---- private to src/front/: the front's state and what its files share
 * (front.c the front itself, validity.c the checks of a new triangle,
 * holes.c the hole filling, tiles.c the tiles and their seams) ---- */

#define NONE TESSEL_NONE
#define MAX_K 64
/* Holes with more edges are never closed; up to DP_HOLE_EDGES they get a
 * minimum-area triangulation first. */
#define MAX_HOLE_EDGES 4096
#define DP_HOLE_EDGES 128
/* Up to this many edges, a hole whose optimal triangulation meets the mesh
 * gets one built from triangles the mesh allows (a check per diagonal). */
#define CHECKED_HOLE_EDGES 48
/* A loop of more than TINY_HOLE_EDGES edges and at least one spacing in
 * radius whose triangles stand across it, their normals on average more
 * than acos(TUBE_COS) = 60 degrees from the loop's own (its vector area),
 * runs round a tube rather than through a sheet: it is not a hole. */
#define TUBE_COS 0.5
/* d_x, the local spacing of (iii): mean distance to this many nearest
 * distinct neighbours. */
#define SPACING_NEIGHBOURS 4

enum { EDGE_ACTIVE = 0, EDGE_DEAD = 1, EDGE_CLOSED = 2 };
/* A dead edge is reconsidered when its neighbourhood changes, this often. */
#define MAX_RETRIES 3
/* retries value of border edges made by tsl_af_erode(): never revived. */
#define ERODED 255
/* Triangles that only close border edges (ears, holes) cannot make the
 * front grow over itself, so they get looser limits: the sharpest fold
 * along a shared edge, and the largest angle to the vertices' normals. */
#define CLOSING_FOLD_DEG 150.0
#define CLOSING_NORMAL_DEG 100.0
/* Holes of at most this many edges are closed by any valid ears (the
 * surface stays manifold and free of self-intersections; folds up to
 * LAST_FOLD_DEG). */
#define TINY_HOLE_EDGES 6
#define LAST_FOLD_DEG 175.0

/* How a candidate triangle (b, a, t) on border edge a->b is attached. */
enum {
    PLAN_FREE,     /* t is a new vertex */
    PLAN_EAR_A,    /* t precedes a on the loop: closes t->a */
    PLAN_EAR_B,    /* t follows b on the loop: closes b->t */
    PLAN_HOLE,     /* both: the loop t, a, b is filled */
    PLAN_BRIDGE_R, /* t elsewhere on a border; second triangle (r, t, a) */
    PLAN_BRIDGE_P  /* same; second triangle (b, t, p) */
};

typedef struct af_edge {
    uint32_t from, to;   /* border half-edge; its triangle lies on the left */
    uint32_t prev, next; /* neighbours along the border loop */
    uint32_t tri;        /* the triangle it belongs to */
    uint8_t state;
    uint8_t retries;
    uint16_t unfilled;   /* length of the loop a hole filling left it on */
    uint32_t mark;       /* hole-filling pass that last visited it */
} af_edge;

typedef struct af_cand {
    uint32_t t;
    int level;     /* smallest widening of theta that admits it */
    double cos_t;  /* cosine of the angle at t (smaller = larger angle) */
} af_cand;

/* Per triangle: unit normal and bounding box. */
typedef struct af_tinfo {
    float n[3];
    float lo[3], hi[3];
} af_tinfo;

struct af {
    /* input */
    const float *xyz;
    const float *pnormals; /* may be NULL */
    size_t n;
    uint32_t k;
    uint32_t *knn;   /* n*k neighbours, self excluded, nearest first */
    float *nnd;      /* distance to the nearest point at a distance > 0 */
    uint8_t *dup;    /* exact duplicate of a point with a smaller index */
    uint32_t *seen;  /* candidate already looked at in this search */
    uint32_t seen_now;
    float *star;     /* n*3 sums of the normals of each vertex's triangles */
    uint8_t *eroded; /* on a loop that tsl_af_erode() already enlarged */
    float *ln;       /* n*3 unit surface normal lines (sign not meaningful) */
    int8_t *vsign;   /* orientation of ln taken by the surface, 0 if unused */
    const float *lines; /* n*3 second normal lines (caller's), may be NULL */
    int8_t *vsign2;  /* orientation of lines taken by the surface */
    /* derived parameters */
    double cos_phi, theta0, theta_step, theta_max, cos_theta_max, eps1, cos_normal;
    double cos_closing_fold, cos_closing_normal, cos_last_fold;
    double *cos_level; /* cosines of theta0, theta0 + eps2, ..., then -2 */
    double max_hole_radius;
    uint32_t pass;       /* hole-filling pass, for edge marks */
    uint32_t *scratch_u; /* hole filling: corners */
    double *scratch_d;
    size_t scratch_cap;
    /* mesh */
    uint32_t *tri;   /* 3 per triangle */
    af_tinfo *ti;    /* per triangle: normal and box */
    uint32_t *cnext; /* per corner: next corner at the same vertex */
    size_t nt, cap_t;
    uint32_t *vhead; /* per point: first corner, NONE if unused */
    uint32_t *vin, *vout; /* per point: border edge ending / starting there */
    af_edge *e;
    size_t ne, cap_e;
    /* Edges made since the last hole-filling pass, in id order: only
     * their loops can get another verdict (tsl_af_fill_holes). */
    uint32_t *fresh;
    size_t n_fresh, cap_fresh;
    uint32_t *queue; /* ring buffer of edge ids */
    size_t q_head, q_count, q_cap;
    tsl_trigrid grid;
    double cell;     /* grid cell: 3 mean spacings of the whole point set */
    float *own;      /* a tile's copies of its points, normals and lines */
    double max_edge; /* longest edge so far, for seed orientation searches */
    size_t used;     /* points on some triangle */
    size_t deleted;  /* triangles removed by tsl_af_erode() (vertices NONE) */
    tessel_front_stats stats;
};

/* Plain minimum / maximum of finite numbers (fmin/fmax handle NaN and are
 * function calls). */
static inline double dmin(double a, double b) { return a < b ? a : b; }
static inline double dmax(double a, double b) { return a > b ? a : b; }

/* A triangle about to be added: vertex ids, coordinates, unit normal,
 * longest edge. */
typedef struct af_tri {
    uint32_t v[3];
    double p[3][3];
    double n[3];
    double maxlen;
    double centroid[3], radius; /* bounding sphere */
    double cos_fold; /* sharpest fold allowed along an edge it shares */
    bool exact_only; /* skip the projection test: only validity counts */
} af_tri;

typedef struct af_plan {
    int kind;
    uint32_t t;  /* third vertex */
    uint32_t w;  /* r or p for bridges */
} af_plan;

static inline void point(const af *s, uint32_t i, double out[3])
{
    tsl_load(s->xyz + 3 * (size_t)i, out);
}

static inline bool is_free(const af *s, uint32_t v) { return s->vhead[v] == NONE; }
static inline bool is_interior(const af *s, uint32_t v)
{
    return s->vhead[v] != NONE && s->vout[v] == NONE;
}

static inline void link_edges(af *s, uint32_t x, uint32_t y)
{
    s->e[x].next = y;
    s->e[y].prev = x;
}

/* Unit normal of triangle (x, y, z) into n; returns twice its area. */
/* 1 when the undirected edge {x, y} is on some triangle. */
bool tsl_af_edge_exists(const af *s, uint32_t x, uint32_t y);

void tsl_af_tri_box(const double *p[3], double lo[3], double hi[3]);

tessel_status tsl_af_add_triangle(af *s, uint32_t x, uint32_t y, uint32_t z, uint32_t *id);

tessel_status tsl_af_new_edge(af *s, uint32_t from, uint32_t to, uint32_t tri, uint32_t *id);

/* Fills x from ids; false when the triangle is degenerate. */
bool tsl_af_make_tri(const af *s, uint32_t a, uint32_t b, uint32_t c, af_tri *x);

/* Largest angle of x, as its cosine (smaller = wider). */
double tsl_af_min_cos_angle(const af_tri *x);

/* The triangle's normal lies within the normal cone around each vertex's
 * surface normal, oriented as the surface took it (either way for a vertex
 * not yet on the surface). This keeps the front from folding back over
 * itself where noise lets folds pass the dihedral test (i). With a second
 * set of lines (the pipeline's: the normals of the robust fit at each
 * representative, local where the plane of its k nearest representatives
 * spans a tip or a narrow part), agreeing with either line is enough. */
bool tsl_af_normals_agree(const af *s, const af_tri *x, double cos_limit);

/* *ok: x may be added to the mesh (together with `other`, a triangle added
 * in the same step, or NULL). */
tessel_status tsl_af_check_triangle(af *s, const af_tri *x, const af_tri *other, bool *ok);

/* Combinatorial case of triangle (b, a, t) on border edge id; false when it
 * would break the manifold (t interior, or an edge it needs already
 * exists). */
bool tsl_af_classify(const af *s, uint32_t id, uint32_t t, int *kind);

tessel_status tsl_af_commit(af *s, uint32_t id, const af_plan *plan);

void tsl_af_flip_triangle(uint32_t v[3]);

void tsl_af_free(af *s);

/* Removes the triangle on border edge id when its third vertex z is
 * interior: the border then runs through z (the hole grows by one edge) and
 * every vertex keeps a single fan. The two new border edges are left to the
 * hole filling (dead, not queued for the front). */
tessel_status tsl_af_erode(af *s, uint32_t id, bool *done);

/* Closes the small holes among the border loops (small_hole), each loop in
 * the order of its lowest edge id. A loop is looked at only when it has an
 * edge made since the last pass: every change of a loop makes an edge, a
 * closed edge stays closed, and the verdict on an unchanged loop cannot
 * change (its geometry is the same, a filling that failed is not tried
 * again, and points inside it only stop being free). Looking at every loop
 * at every pass made this quadratic in a scene of thousands of pieces,
 * where the fronts stop once per piece. */
tessel_status tsl_af_fill_holes(af *s);

tessel_status tsl_af_run_fronts(af *s, const tessel_callbacks *cb);

/* Derived parameters (angles as cosines, limits) from p. */
void tsl_af_params(af *s, const tessel_front_params *p);

/* The empty mesh over s's points (neighbours prepared), with a triangle
 * grid of the given cell size. */
tessel_status tsl_af_alloc_mesh(af *s, double cell);

/* Fronts in tiles of at most p->tile_points points, run by runner (NULL:
 * this process's threads), each from the triangles of start[0 .. nstart)
 * with all three corners in it; their triangles, less the seams, become
 * s's starting mesh. */
tessel_status tsl_af_run_tiles(af *s, const tessel_front_params *p, double mean_nn,
                               const uint32_t *start, size_t nstart,
                               const tsl_af_tile_runner *runner, const tessel_callbacks *cb);

/* Places the starting triangles in s (see tsl_advancing_front_from). */
tessel_status tsl_af_place_start(af *s, const uint32_t *start, size_t count);

#endif /* TESSEL_FRONT_H */
