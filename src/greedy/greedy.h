/* Private declarations of the greedy projection reconstruction (Gopi &
 * Krishnan 2002), shared by its six files:
 *   greedy.c  reference points, seeds, the main loop, the API
 *   store.c   dexel array, triangle pool, fans, retirement, set-up
 *   guard.c   exact intersection tests, the free-cone certificate
 *   held.c    with the whole mesh held: regions meshed inside out found
 *             and rebuilt, diagonal flips (mesh/flip.c)
 *   tiles.c   the first pass in tiles, in parallel, and the seams
 *   slabs.c   out of core: slabs meshed in turn, a band carried between
 * Not installed. */
#ifndef TESSEL_GREEDY_H
#define TESSEL_GREEDY_H

#include "mesh/mesh.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---- point states (section 4: free, fringe, boundary, completed) ---- */
enum {
    ST_FREE = 0,     /* no triangle */
    ST_FRINGE = 1,   /* has triangles, not yet a reference point */
    ST_BOUNDARY = 2, /* was a reference point, fan still open */
    ST_DONE = 3,     /* fan closed: completed */
    ST_DEAD = 4,     /* left out (duplicate, isolated, ...) */
    ST_MASK = 7,
    ST_QUEUED = 8,   /* in the breadth-first queue */
    ST_VISITS = 16,  /* bits 4-5: times processed as a reference point */
    ST_WHY = 64      /* bits 6-7 of a left-out point: its fate less
                        FATE_DUPLICATE */
};

/* What became of a point (tsl_gp_pass's fate[]): used, or why it was left
 * out (the summary's left_* counts). */
enum { FATE_USED = 0, FATE_DUPLICATE, FATE_ISOLATED, FATE_CLOSED_IN, FATE_UNTRIANGULATED };
/* A point a front that only grows (tsl_gp_grow) did not reach: not an
 * outcome, only a mark for the caller's next pass. */
#define FATE_UNREACHED (FATE_UNTRIANGULATED + 1)

#define NONE TESSEL_NONE
/* Boundary points are looked at again when a neighbour changes their fan,
 * at most this many times in all. */
#define MAX_VISITS 3
/* A reference point whose free sector holds no candidate at all tries
 * again with a sphere of influence GROW times larger, at most GROW_STEPS
 * times and never beyond rho_cap (uneven sampling: the next row of points
 * lies beyond mu * m). */
#define GROW 1.5
#define GROW_STEPS 2
/* A seed needs this many candidates (a surface around it, not a splinter). */
#define SEED_MIN 4
/* A seed within this fraction of a held triangle's longest edge of its
 * plane, over the triangle, is taken as passed over (greedy.c, covered). */
#define COVER_HEIGHT 0.25
/* A seed whose box holds more than this many completed points per live one
 * is taken as passed over too (greedy.c, seed). On 60,000 random points of
 * the bunny, the elephant and the knot it removed every island but one of
 * the elephant's; on the data files it removed splinters of 1 to 7
 * triangles (room_small.grid, 11 -> 4 components; F within 0.01). With 1,
 * man.ply also lost a 43-triangle patch of real surface. */
#define SEED_DONE_RATIO 2
/* A fan triangle whose projection on R's plane is smaller than this
 * fraction of its area (steeper than 70.5 degrees) is refused (greedy.c,
 * try_fan): section 4.1 orders candidates by their projection, which only
 * holds while triangles stay within 90 degrees of the plane. A sliver
 * standing across a crease (the first triangle of a seed beside a facet
 * edge) sets its points' planes across the surface and turns the front
 * inside out beyond the crease: knot2 at 10^7 points, a pentagonal torus
 * at 5x10^4-10^6 (docs/greedy.md, "Creases"). */
#define STEEP_COS (1.0 / 3.0)
/* A front's triangle may not lie on a held one as a second layer: facing
 * within acos(LAYER_COS) of the same way, within LAYER_HEIGHT of its
 * longest edge off its plane, overlapping it (guard.c,
 * second_layer). On uniformly random samples such layers lie within 0.025
 * of the edge; the nearby triangles of scans (curved, slits) mostly
 * farther: at 0.05 man.ply's boundary grew by a tenth, at 0.03 it does
 * not (docs/greedy.md, "Second layers"). */
#define LAYER_HEIGHT 0.03
#define LAYER_COS 0.8
/* Longest edge of a short triangle (ell), in mu times the mean spacing;
 * it is also the cell edge of the short-triangle grid (the guard's index).
 * The longest edges of even samples stay under 2.8 spacings (mu 2: ell 4),
 * of uniformly random ones 99.99% under 7.7 (mu 3: ell 6). On random 10^6
 * samples of the bunny, elephant and knot, against 3 spacings for both:
 * 4.5-5.1 -> 4.1-4.3 s (2 threads); within the noise on an even 10^6
 * sphere. */
#define ELL_MU 2.0
/* Triangles per batch sent to the sink. */
#define OUT_BATCH 8192

typedef struct gp_tri {
    uint32_t v[3];    /* counter-clockwise seen from outside */
    uint32_t next[3]; /* next held triangle in the list of v[k]; next[0] is
                         the free-list link of an unused slot */
} gp_tri;

enum { TF_ALIVE = 1, TF_LONG = 2, TF_EXISTING = 4 };

/* A point of the box around R. */
typedef struct gp_box {
    uint32_t idx;
    float dinf;      /* L-infinity distance to R */
    double rel[3];   /* position relative to R */
} gp_box;

/* A candidate neighbour of R in R's projection frame. */
typedef struct gp_cand {
    uint32_t idx;
    uint8_t kept;    /* survives the pruning */
    double x, y;     /* projection on R's plane (R at the origin) */
    double key;      /* pseudo-angle, [0, 4), from the start of the sector */
    double d2;       /* squared 3D distance to R */
    double rel[3];
} gp_cand;

/* Cached box of a held triangle near R (for the guard). */
typedef struct gp_gtri {
    uint32_t t;
    float lo[3], hi[3];
    int fan;          /* made by the current reference point R = v[0] */
    double p1[2], p2[2]; /* then: projections of v[1], v[2] on R's plane */
} gp_gtri;

/* R's free sector in its projection: new triangles lie in the cone from
 * e's direction counter-clockwise to s's, the mesh around R in the rest.
 * The projection is linear, so triangles whose images are disjoint (or meet
 * only in the images of shared vertices and edges) do not meet in space:
 * held triangles that provably stay out of the cone need no exact test. */
typedef struct gp_cone {
    int on;           /* 0: no certificate (a seed: every triangle is tested) */
    int convex;       /* the free sector is under 180 degrees */
    uint32_t R, e, s;
    double e2[2], s2[2], bis[2];
    double eu[2], su[2];  /* unit directions of e2, s2 */
    double eps;       /* margin for the rounding of projections */
} gp_cone;

/* A hashed grid of cells, each the head of a list whose links live
 * elsewhere: open addressing on the cell key + 1 (0 marks an empty slot).
 * Used for the long and the short triangles (store.c keeps it). */
/* A cell's key (+ 1; 0 = empty slot) and the head of its list, together:
 * a lookup reads one cache line, not one in each of two arrays. */
typedef struct gp_slot {
    uint64_t key;
    uint32_t head;
} gp_slot;

typedef struct gp_cells {
    gp_slot *slot;
    size_t slots, used;
} gp_cells;

typedef struct gp {
    /* input and parameters */
    const tessel_cloud *cloud;
    size_t n;
    double mu, cos_alpha, beta, max_spacing;
    bool mu_from_sampling; /* mu chosen in tsl_gp_init */
    uint32_t max_hole;
    int plane_axis;
    bool grow_only;       /* no new seed: only from the existing triangles */
    const tessel_callbacks *cb;
    const char *stage;    /* progress label */
    const tessel_triangle_sink *sink;

    /* points in dexel order */
    float *xyz;
    uint32_t *orig;       /* dexel order -> input index */
    uint8_t *state;
    uint32_t *head;       /* first held triangle at the point */
    uint32_t *ls, *le;    /* ends of the point's fan: its link path runs
                             ls -> ... -> le counter-clockwise */
    uint32_t *label;      /* component label (union-find), NONE if unused */
    float *maxe;          /* longest edge ever at the point (0: none) */

    /* dexel array: columns over axes au, av; depth along ad */
    int ad, au, av;
    double glo[3];
    double cell, inv_cell;
    uint32_t nu, nv;
    uint32_t *col;        /* nu*nv+1 column starts */

    /* lengths (world units) */
    double spacing;       /* mean nearest-neighbour distance */
    double m_cap;         /* cap on m */
    double rho_cap;       /* largest sphere of influence, mu * m_cap, grown
                             or not */
    double m_floor;       /* floor on m (near-duplicates) */
    double ell;           /* long-triangle threshold (max edge, ELL_MU) */
    double delta;         /* guard margin: ell / sqrt(3) */

    /* retirement blocks */
    double inv_block;
    uint32_t bn[3];
    uint32_t *blive;      /* live points in the block */
    uint8_t *bdead;       /* dead blocks among the 27 around it */
    float *bmaxl;         /* longest edge of the short triangles whose first
                             vertex is in the block (never lowered) */

    /* triangle pool */
    gp_tri *tri;
    uint8_t *tflag;
    uint32_t *tblock;     /* retirement block of the triangle's first vertex */
    uint32_t *tstamp;     /* long triangles: stamp of the last guard
                             collection that looked at them */
    size_t tcap, tused, talive;
    uint32_t tfree;
    size_t created_since_sweep, alive_after_sweep;
    /* long triangles: hashed grid of cell edge 1 / lg_inv, every triangle
     * listed in the cells its box overlaps */
    double lg_inv;
    gp_cells lg;          /* heads: entries of lt_tri / lt_next */
    uint32_t *lt_tri, *lt_next; /* entries */
    size_t lt_cap, lt_used;
    uint32_t lt_free;
    /* short triangles: hashed grid of cell edge 1 / sg_inv, each triangle
     * listed once, in the cell of its centroid (the guard's index) */
    double sg_inv;
    gp_cells sg;          /* heads: triangles, linked by tsg_next */
    uint32_t *tsg_next;   /* per triangle: next in its cell */
    float *tbox;          /* per triangle: float box, lo[3] then hi[3] (read
                             by the guard's collection without touching the
                             vertices) */

    /* breadth-first queue (ring) and seeds */
    uint32_t *queue;
    size_t qhead, qcount;
    uint32_t *seed_order; /* dexel indices by increasing depth */
    size_t seed_cursor;

    /* components: union-find over labels */
    uint32_t *uf;
    size_t uf_count, uf_cap;

    /* output batch */
    uint32_t *out;
    size_t out_count;

    /* per-reference scratch */
    gp_box *box;          /* the scanned box: live points */
    size_t box_count, box_cap;
    gp_box *boxd;         /* and completed points with triangles */
    size_t boxd_count, boxd_cap;
    gp_cand *cand;
    size_t cand_count, cand_cap;
    uint32_t *seq;
    size_t seq_count, seq_cap;
    double (*far)[2];     /* projections of the free points beyond rho that a
                             triangle to a boundary neighbour may reach */
    size_t far_count, far_cap;
    uint32_t *hide;       /* visibility: candidates that may be hidden */
    size_t hide_cap;
    gp_gtri *gt;
    size_t gt_count, gt_cap;
    uint32_t stamp;       /* of the guard's collection */
    double fan_eps;       /* rounding margin of the fan certificate */
    int empty_gap;        /* the last fill found no candidate between R's
                             boundary neighbours */
    gp_cone cone;         /* of the current reference point */
    int guard_pending;    /* the collection for guard_R / guard_f is due
                             (made at the first guard test: a reference
                             point whose walk stops on geometry or topology
                             alone needs none) */
    uint32_t guard_R;
    const struct gp_frame *guard_f;
    uint32_t *pmark;      /* per point: marks of the guard's collection */
    double *hn;           /* hole closing: fan normals of the loop, 3 each */
    size_t hn_cap;

    tessel_recon_summary sum;
    size_t processed;
} gp;

typedef struct gp_frame {
    double n[3], u[3], v[3];
    double rho;        /* radius of the sphere of influence */
    double reach;      /* every new triangle lies within reach of R */
    double delta;      /* guard margin here (<= g->delta) */
    double flo[3], fhi[3]; /* box (relative to R) holding every triangle the
                              guard will be asked about */
} gp_frame;

/* ---- small helpers ---- */

static inline int sgn(double x) { return (x > 0.0) - (x < 0.0); }
/* fmin/fmax for finite values, inlined (the libm calls were 4% of the run). */
static inline double dmin(double a, double b) { return a < b ? a : b; }
static inline double dmax(double a, double b) { return a > b ? a : b; }

static inline void pos(const gp *g, uint32_t i, double out[3])
{
    const float *p = g->xyz + 3 * (size_t)i;
    out[0] = p[0];
    out[1] = p[1];
    out[2] = p[2];
}

/* The next float below / above a finite x (nextafterf, inlined: the libm
 * calls were 0.7% of the run). */
static inline float tsl_float_down(float x)
{
    uint32_t u;
    memcpy(&u, &x, sizeof u);
    if ((u & 0x7fffffffu) == 0)
        u = 0x80000001u; /* -0 and +0: the negative subnormal */
    else
        u = (u & 0x80000000u) ? u + 1 : u - 1;
    memcpy(&x, &u, sizeof u);
    return x;
}

static inline float tsl_float_up(float x) { return -tsl_float_down(-x); }

static inline int st(const gp *g, uint32_t i) { return g->state[i] & ST_MASK; }
static inline int is_live(const gp *g, uint32_t i)
{
    int s = st(g, i);
    return s == ST_FREE || s == ST_FRINGE || s == ST_BOUNDARY;
}

/* Pseudo-angle of (x, y) in [0, 4): monotone in atan2 taken in [0, 2pi)
 * (the paper's quadrant + sin^2 ordering does the same job). */
static inline double pseudo_angle(double x, double y)
{
    double p = fabs(y) / (fabs(x) + fabs(y));
    if (x >= 0.0)
        return y >= 0.0 ? p : 4.0 - p;
    return y >= 0.0 ? 2.0 - p : 2.0 + p;
}

static inline double wrap4(double k) { return k < 0.0 ? k + 4.0 : (k >= 4.0 ? k - 4.0 : k); }

static inline tessel_status grow(void **p, size_t *cap, size_t need, size_t size)
{
    if (need <= *cap)
        return TESSEL_OK;
    return tsl_grow(p, cap, need, size);
}

static inline uint32_t grid_coord(double x, double lo, double inv, uint32_t count)
{
    double c = (x - lo) * inv;
    if (!(c > 0.0))
        return 0;
    if (c >= (double)(count - 1))
        return count - 1;
    return (uint32_t)c;
}

static inline size_t block_of(const gp *g, const float p[3])
{
    uint32_t b[3];
    for (int k = 0; k < 3; k++)
        b[k] = grid_coord(p[k], g->glo[k], g->inv_block, g->bn[k]);
    return ((size_t)b[2] * g->bn[1] + b[1]) * g->bn[0] + b[0];
}

static inline int tri_pos(const gp_tri *t, uint32_t v)
{
    return t->v[0] == v ? 0 : (t->v[1] == v ? 1 : 2);
}

static inline uint64_t lg_key(uint32_t x, uint32_t y, uint32_t z)
{
    return ((uint64_t)x << 42) | ((uint64_t)y << 21) | (uint64_t)z;
}

/* Slot of the cell with this key: its own, or the empty one it would take
 * (the table must have slots). */
static inline size_t cells_find(const gp_cells *c, uint64_t key)
{
    size_t mask = c->slots - 1;
    /* Full 64-bit mix: a bare multiply leaves the low bits blind to x (the
     * top field): cells differing in x collided, long probe runs on scans. */
    uint64_t k = key ^ (key >> 31);
    k *= 0x9E3779B97F4A7C15ull;
    k ^= k >> 29;
    k *= 0xBF58476D1CE4E5B9ull;
    k ^= k >> 32;
    size_t h = (size_t)k & mask;
    while (c->slot[h].key && c->slot[h].key != key + 1)
        h = (h + 1) & mask;
    return h;
}

static inline uint32_t sg_coord(const gp *g, double x, int k)
{
    double a = (x - g->glo[k]) * g->sg_inv;
    return a > 0.0 ? (a < 2097151.0 ? (uint32_t)a : 2097151u) : 0u;
}

static inline double cross2(double ax, double ay, double bx, double by)
{
    return ax * by - ay * bx;
}

static inline void project_point(const gp *g, uint32_t R, const gp_frame *f, uint32_t i,
                                 double xy[2])
{
    const float *p = g->xyz + 3 * (size_t)i, *r = g->xyz + 3 * (size_t)R;
    double d[3] = {(double)p[0] - r[0], (double)p[1] - r[1], (double)p[2] - r[2]};
    xy[0] = tsl_dot(d, f->u);
    xy[1] = tsl_dot(d, f->v);
}

/* ---- fans ----
 * The triangles at a point with an open fan have link path ls -> ... -> le:
 * triangle (p, x, y) contributes the link edge x -> y. A new link segment
 * a -> ... -> b (from one or two new triangles) keeps a single fan when it
 * is prepended (b == ls), appended (a == le), or closes the fan (both, with
 * at least three triangles in all), or when the point had no triangle. */
enum { LINK_FAIL = 0, LINK_NEW, LINK_PREPEND, LINK_APPEND, LINK_CLOSE };

/* ---- greedy.c ---- */

/* One pass of the front over the cloud (params already checked), its
 * progress reported as `stage`; summary->seconds is left 0. fate (NULL, or
 * one entry per point) receives each point's FATE_*. */
tessel_status tsl_gp_pass(const tessel_cloud *cloud, const tessel_greedy_params *params,
                          const char *stage, const tessel_callbacks *callbacks,
                          const tessel_triangle_sink *sink, uint8_t *fate,
                          tessel_recon_summary *summary);
/* The same from params.existing without a seed of its own: points the
 * front cannot reach from them get FATE_UNREACHED. */
tessel_status tsl_gp_grow(const tessel_cloud *cloud, const tessel_greedy_params *params,
                          const char *stage, const tessel_callbacks *callbacks,
                          const tessel_triangle_sink *sink, uint8_t *fate,
                          tessel_recon_summary *summary);

/* A sink that appends the triangles to a growing array. */
typedef struct gp_collect {
    uint32_t *tris;
    size_t count, cap;
} gp_collect;
tessel_status tsl_gp_collect_emit(void *user, const uint32_t *tris, size_t count);

/* ---- local.c ---- */

/* The cells (of half the radius) within radius of a point flagged in
 * seed: a superset of the ball around each, up to about 1.9 radii. */
typedef struct tsl_gp_near {
    double lo[3], cell;
    size_t dim[3];
    uint8_t *near; /* per cell; NULL without a seed */
} tsl_gp_near;
tessel_status tsl_gp_near_build(const float *xyz, size_t n, const uint8_t *seed, double radius,
                                tsl_gp_near *g);
/* Whether the box [lo, hi] meets one of the cells. */
bool tsl_gp_near_box(const tsl_gp_near *g, const double lo[3], const double hi[3]);
void tsl_gp_near_free(tsl_gp_near *g);

/* Flags in sel (n entries) every point within radius of a point flagged
 * in seed, and some points farther (the cells of tsl_gp_near), the points
 * looked at on `threads` threads. */
tessel_status tsl_gp_select_near(const float *xyz, size_t n, const uint8_t *seed, double radius,
                                 int threads, uint8_t *sel);

/* Leaves out of sel the points a front left out (fate[i] not FATE_USED)
 * but those within reach of a cut (dcut, NULL: none): such a point lies
 * among triangles, or beside them, and the triangles may lie beyond the
 * selection, where a local front cannot see them and would lay a second
 * sheet over them from the point. */
void tsl_gp_select_meshed(size_t n, const uint8_t *fate, const float *dcut, double reach,
                          uint8_t *sel);

/* The points ids[0 .. m) of cloud as a cloud of their own (positions,
 * normals, viewpoint and offset). */
tessel_status tsl_gp_subcloud(const tessel_cloud *cloud, const uint32_t *ids, size_t m,
                             tessel_cloud *out);

/* A front over the points ids[0 .. m) of cloud (at least 3, else nothing),
 * resumed from inside (ninside triangles in indices into ids), the points
 * flagged in frozen (by index into ids) taking no new triangle; grow_only:
 * no seed of its own (tsl_gp_grow). Its triangles are appended to more in
 * the cloud's indices and their vertices flagged in made, the points'
 * fate[] rewritten, its summary in sum. */
tessel_status tsl_gp_front_over(const tessel_cloud *cloud, const uint32_t *ids, size_t m,
                                const uint32_t *inside, size_t ninside, const uint8_t *frozen,
                                const tessel_greedy_params *params, bool grow_only,
                                const char *stage, const tessel_callbacks *callbacks,
                                gp_collect *more, uint8_t *fate, uint8_t *made,
                                tessel_recon_summary *sum);

/* tsl_gp_front_over's front on the points' own cloud lc (at least 3
 * points): inside and frozen by index into lc, the triangles appended to
 * more in lc's indices, each point's fate in fate[0 .. lc->count). What
 * another process runs for a seam's group (src/mpi/). */
tessel_status tsl_gp_front_local(const tessel_cloud *lc, const uint32_t *inside, size_t ninside,
                                 const uint8_t *frozen, const tessel_greedy_params *params,
                                 bool grow_only, const char *stage,
                                 const tessel_callbacks *callbacks, gp_collect *more,
                                 uint8_t *fate, tessel_recon_summary *sum);
/* A local front's results back in the cloud's indices: more's triangles
 * (from indices into ids) and their vertices flagged in made, fate[ids[j]]
 * = lfate[j]. */
void tsl_gp_front_back(const uint32_t *ids, size_t m, const uint8_t *lfate, gp_collect *more,
                       uint8_t *fate, uint8_t *made);

/* A front over the points flagged in sel only (params checked; mu as
 * given), from the triangles of all among them (points with a triangle
 * beyond are frozen); its triangles appended to all and their vertices
 * flagged in made, the selected points' fate[] rewritten, its seeds,
 * holes and refusals added to summary. */
tessel_status tsl_gp_local_pass(const tessel_cloud *cloud, const uint8_t *sel,
                                const tessel_greedy_params *params, const char *stage,
                                const tessel_callbacks *callbacks, gp_collect *all,
                                uint8_t *fate, uint8_t *made, tessel_recon_summary *summary);

/* ---- tiles.c ---- */

/* The tiles of a tiled pass to mesh: parts[k] and sums[k] for every
 * k < count, each tile by tsl_gp_tile_mesh. */
typedef struct tsl_gp_tiles_job {
    const tessel_cloud *cloud;
    const tessel_greedy_params *params; /* tile_points 0 */
    const tsl_tiles *cut;
    size_t count;
    const tessel_callbacks *callbacks;
    gp_collect *parts;
    tessel_recon_summary *sums;
    uint8_t *fate; /* per point of cloud: each tile writes its own points' */
} tsl_gp_tiles_job;

/* One group of a level of seams (tiles.c): its points (the cloud's
 * indices), the triangles among them that resume its front (indices into
 * ids), and what its front gives: new triangles in the cloud's indices,
 * its summary and status. */
typedef struct gp_seam_group {
    const uint32_t *ids;
    size_t m;
    uint32_t *inside;
    size_t ninside, cap_inside;
    gp_collect more;
    tessel_recon_summary sum;
    tessel_status st;
} gp_seam_group;

/* The groups of one level of seams, whose fronts do not meet: each a front
 * over its points (tsl_gp_front_over, growing from inside only) with the
 * seams' params; frozen by the cloud's index (taking no new triangle);
 * fate and made written at each group's points. */
typedef struct tsl_gp_seams_job {
    const tessel_cloud *cloud;
    const tessel_greedy_params *params;
    gp_seam_group *groups;
    size_t count;
    const uint8_t *frozen;
    uint8_t *fate, *made;
    const tessel_callbacks *callbacks; /* progress, on the calling thread */
} tsl_gp_seams_job;

/* Group i of job on the calling thread: its more, sum and st. */
void tsl_gp_seam_group_run(const tsl_gp_seams_job *job, size_t i, const tessel_callbacks *cb);

/* Who meshes the tiles and the seams' groups: NULL, this process's
 * threads; the MPI runner (src/mpi/) spreads them over processes and
 * shares the results. A tile's triangles depend on the tile alone, a
 * group's on the group alone, so any runner gives the same mesh. */
typedef struct tsl_gp_tile_runner {
    tessel_status (*run)(void *ctx, const tsl_gp_tiles_job *job);
    tessel_status (*seams)(void *ctx, const tsl_gp_seams_job *job); /* NULL: the threads */
    void *ctx;
} tsl_gp_tile_runner;

/* The cloud's points in space order (cells of a few spacings in Morton
 * order; the same for any thread count) into *sorted (positions, normals,
 * offset, viewpoint), with (*perm)[i] the caller's index of point i. */
tessel_status tsl_gp_space_order(const tessel_cloud *cloud, int threads, tessel_cloud *sorted,
                                 uint32_t **perm);

/* Tile k of job on the calling thread: job->parts[k] (triangles in the
 * cloud's indices) and job->sums[k]. */
tessel_status tsl_gp_tile_mesh(const tsl_gp_tiles_job *job, size_t k,
                               const tessel_callbacks *cb);
/* A tile's mesh from its own points (sub, in the tile's order): the
 * triangles into out (in sub's indices), each point's FATE_* into fate,
 * the counts into sum. What tsl_gp_tile_mesh runs, for a process that
 * holds the tile's points alone (src/mpi/). */
tessel_status tsl_gp_tile_mesh_cloud(const tessel_cloud *sub, const tessel_greedy_params *params,
                                     const tessel_callbacks *cb, gp_collect *out, uint8_t *fate,
                                     tessel_recon_summary *sum);

/* The first pass in tiles of at most params->tile_points points, meshed
 * by runner, then the seams closed by a local pass over the points near
 * the cuts; the triangles into *all (held), every point's FATE_* into
 * fate, the vertices of the triangles that close the seams (not flipped
 * yet) flagged in dirty. The summary's counts of the mesh (points used, left
 * out, boundary, components) are left to the caller. */
tessel_status tsl_gp_tiled_pass(const tessel_cloud *cloud, const tessel_greedy_params *params,
                                const tsl_gp_tile_runner *runner,
                                const tessel_callbacks *callbacks, gp_collect *all,
                                uint8_t *fate, uint8_t *dirty, tessel_recon_summary *summary);

/* ---- slabs.c ---- */

/* What an out-of-core sweep carries from one slab to the next: the band
 * below the next cut (points with their global ids, frozen where written
 * triangles use them, and the triangles not yet written, in the band's
 * numbering). */
typedef struct tsl_gp_slabs {
    const tsl_gp_tile_runner *runner; /* who meshes a slab's tiles (NULL: threads) */
    int axis;                         /* the axis the slabs are cut along */
    double cut, reach;                /* the band's cut and the band's reach */
    size_t np, nt;
    float *xyz, *normals;
    uint32_t *gid, *tri;
    uint8_t *frozen;
} tsl_gp_slabs;

void tsl_gp_slabs_init(tsl_gp_slabs *s, int axis, const tsl_gp_tile_runner *runner);
void tsl_gp_slabs_free(tsl_gp_slabs *s);
/* One slab: the points of slab (global ids gid) between cut and next_cut
 * along s->axis (INFINITY for the last slab) meshed and joined to the band;
 * the triangles no later slab can change go to out in global ids. */
tessel_status tsl_gp_slabs_step(tsl_gp_slabs *s, const tessel_cloud *slab, const uint32_t *gid,
                                double cut, double next_cut, const tessel_greedy_params *params,
                                const tessel_callbacks *callbacks,
                                const tessel_triangle_sink *out, tessel_recon_summary *summary);

/* ---- holes.c ---- */

/* The count of a held mesh, kept from one hole repair to the next. */
typedef struct gp_count {
    uint32_t *comp;   /* per point on the mesh: its component */
    uint32_t *size;   /* per component: its triangles */
    uint64_t *used;   /* a bit per point: on the mesh */
    uint64_t *open;   /* per point: tsl_open_fans of the mesh */
    size_t ncomp;
    uint32_t most;    /* the largest component's triangles */
    size_t local;     /* repairs counted around what they changed */
} gp_count;
void tsl_gp_count_free(gp_count *c);
/* Drops the pieces of fewer than 64 triangles from a mesh that has one of
 * 64 times as many: fragments the fronts leave where they meet beside the
 * surface (a seam, a repaired hole), a few triangles each, which would
 * count as components of their own; their points count as closed in (their
 * neighbours are on the mesh). Then the summary's counts of what is left
 * (points used, left out by fate[], boundary edges, components,
 * triangles), kept in c. */
tessel_status tsl_gp_drop_specks_and_count(size_t n, gp_collect *all, uint8_t *fate, int threads,
                                           gp_count *c, tessel_recon_summary *summary);
/* Small holes the front could not close (its ear clipping finds every ear
 * refused, mostly where the triangles beside the hole fold over each
 * other): the boundary loops of at most max_hole edges, the triangles at
 * their vertices and `rings` rings beyond are dropped and a front over
 * the points within 6 spheres of influence of them runs again from the
 * triangles there. The caller tries with 0, 1 and 2 rings while holes are
 * left (*holes: there were small loops): a fold can lie a ring or two
 * away from the hole, and the front then remakes it. A repair that
 * changes the number of components (two sheets closer than the sampling
 * joined through a hole, a piece cut off) or leaves more boundary edges is
 * undone. summary and c hold the count before and after; the vertices of
 * the new triangles are flagged in dirty (also when undone). */
tessel_status tsl_gp_reopen_holes(const tessel_cloud *cloud, const tessel_greedy_params *params,
                                  const tessel_callbacks *callbacks, gp_collect *all,
                                  uint8_t *fate, uint8_t *dirty, gp_count *c,
                                  tessel_recon_summary *summary, int rings, bool *holes);

/* ---- held.c ---- */

/* The pass with every triangle held; then, when check, regions meshed
 * inside out found by ray parity (src/mesh/orient.c) and rebuilt by a second
 * pass; then, when params->flip, the diagonal flips; then all sent to
 * sink, each point i named perm[i] (perm NULL: i). */
tessel_status tsl_gp_held(const tessel_cloud *cloud, const tessel_greedy_params *params,
                          bool check, const tsl_gp_tile_runner *runner,
                          const tessel_callbacks *callbacks, const uint32_t *perm,
                          const tessel_triangle_sink *sink, tessel_recon_summary *summary);

/* tessel_reconstruct_greedy with the tiles meshed by runner (NULL: this
 * process's threads). */
tessel_status tsl_reconstruct_greedy_with(const tessel_cloud *cloud,
                                          const tessel_greedy_params *params,
                                          const tsl_gp_tile_runner *runner,
                                          const tessel_callbacks *callbacks,
                                          const tessel_triangle_sink *sink,
                                          tessel_recon_summary *summary);

/* tessel_reconstruct_greedy_file (src/outofcore/outofcore.c) with each
 * slab's tiles meshed by runner (NULL: this process's threads). */
tessel_status tsl_reconstruct_greedy_file_with(
    const char *in, const char *out, const tessel_read_params *read_params,
    const tessel_greedy_params *params, const tessel_write_params *write_params,
    const tessel_outofcore_params *op, const tsl_gp_tile_runner *runner,
    const tessel_callbacks *callbacks, tessel_recon_summary *summary, tessel_diag *diag);

/* ---- store.c ---- */

/* Set-up (dexel array, spacing, duplicates, blocks, seed order) and
 * release. */
tessel_status tsl_gp_init(gp *g);
void tsl_gp_free(gp *g);
/* Imports params->existing (TESSEL_ERR_INVALID_ARG if not a manifold,
 * consistently oriented mesh). */
tessel_status tsl_gp_import_existing(gp *g, const uint32_t *tris, size_t count,
                                     const uint8_t *frozen);
/* Points other than R, not dead, in the box of half-size half around R:
 * live ones into g->box, completed ones with triangles into g->boxd. */
tessel_status tsl_gp_scan_box(gp *g, uint32_t R, double half);
/* Distance from point i to its nearest point (live ones only if
 * live_only) with boxes doubling from start up to limit; INFINITY if none. */
tessel_status tsl_gp_nearest(gp *g, uint32_t i, int live_only, double start, double limit,
                             double *dist);
/* The guard margin around R when every new triangle lies in the box of
 * half-size core around it: longest held short triangle edge nearby over
 * sqrt(3) (a short triangle meeting a box inside that one has its centroid
 * within this margin of it), at most g->delta. */
double tsl_gp_local_delta(const gp *g, uint32_t R, double core);
/* Point i is no longer live (completed or left out). */
void tsl_gp_point_settled(gp *g, uint32_t i);
tessel_status tsl_gp_flush_out(gp *g);
/* Retires held triangles nothing can reach any more (all: every one). */
tessel_status tsl_gp_sweep(gp *g, int all);
/* Some held triangle uses the directed edge x -> y. */
int tsl_gp_edge_exists(const gp *g, uint32_t x, uint32_t y);
/* Float bounding box of triangle v of the points xyz. */
static inline void tsl_tri_box(const float *xyz, const uint32_t v[3], float lo[3], float hi[3])
{
    const float *a = xyz + 3 * (size_t)v[0], *b = xyz + 3 * (size_t)v[1],
                *c = xyz + 3 * (size_t)v[2];
    for (int k = 0; k < 3; k++) {
        float l = a[k], h = a[k];
        l = b[k] < l ? b[k] : l;
        h = b[k] > h ? b[k] : h;
        l = c[k] < l ? c[k] : l;
        h = c[k] > h ? c[k] : h;
        lo[k] = l;
        hi[k] = h;
    }
}
/* The same for the front's points (inlined: called per collected triangle). */
static inline void tsl_gp_tri_box(const gp *g, const uint32_t v[3], float lo[3], float hi[3])
{
    tsl_tri_box(g->xyz, v, lo, hi);
}
/* Cells of the long-triangle grid that the box [lo, hi] overlaps. */
void tsl_gp_lg_cells(const gp *g, const float lo[3], const float hi[3], uint32_t c0[3],
                     uint32_t c1[3]);
/* Adds triangle (a, b, c) (fans are updated by the caller). */
tessel_status tsl_gp_tri_add(gp *g, uint32_t a, uint32_t b, uint32_t c, int existing,
                             uint32_t *out);
/* Whether the link segment a -> ... -> b (edges edges) keeps p's fan single,
 * and how (LINK_*); then applying it. */
int tsl_gp_link_check(const gp *g, uint32_t p, uint32_t a, uint32_t b, int edges);
void tsl_gp_link_apply(gp *g, uint32_t p, uint32_t a, uint32_t b, int how, int is_ref);

/* ---- guard.c ---- */

/* Exact: a, b, c collinear. */
int tsl_gp_collinear3(const double a[3], const double b[3], const double c[3]);
/* Collects into g->gt the held triangles that a new triangle inside the box
 * [f->flo, f->fhi] around R (within f->reach of R) could meet; use_cone:
 * skip those the free-cone certificate rules out (R must have a fan). */
tessel_status tsl_gp_guard_collect(gp *g, uint32_t R, const gp_frame *f, int use_cone);
/* The same in two steps: the cone (which try_fan needs at once) now, the
 * collection when tsl_gp_guard_ready is first called before a guard test
 * (f must stay valid until then; no triangle may be added in between). */
void tsl_gp_guard_defer(gp *g, uint32_t R, const gp_frame *f, int use_cone);
tessel_status tsl_gp_guard_ready(gp *g);
/* New triangle v meets no collected triangle beyond shared vertices/edges
 * and, with layers, lies on none as a second layer (see LAYER_HEIGHT).
 * q1, q2: projections of v[1], v[2] on the plane of R = v[0] when v is one
 * of R's fan triangles (else NULL). */
int tsl_gp_guard_ok(gp *g, const uint32_t v[3], const double q1[2], const double q2[2],
                    int layers);

#endif /* TESSEL_GREEDY_H */
