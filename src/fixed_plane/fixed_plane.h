/* Fixed-plane reconstruction (src/fixed_plane/), private to the library:
 * the dexel array and what the folder's files share (fixed_plane.c the
 * whole reconstruction, dexels.c the frames and the representatives,
 * link.c the edge test and the block codes, manifold.c vertex
 * manifoldness and the filled dexels' overlaps). Not installed. */
#ifndef TESSEL_FIXED_PLANE_H
#define TESSEL_FIXED_PLANE_H

#include "core/core.h"

#define FP_PI 3.14159265358979323846
/* Rows per parallel block (progress is reported between blocks). */
#define FP_BLOCK_ROWS 64u

/* Points sampled for the frame (PCA), the automatic cell and the noise. */
#define FP_SAMPLE 65536u
/* Triangles per sink call. */
#define FP_BATCH 16384u
/* Rows per parallel block (progress is reported between blocks). */
#define FP_BLOCK_ROWS 64u

enum { FP_PLANE = 0, FP_RAY = 1 };

typedef struct fp_ctx {
    const float *xyz;
    uint32_t w, h;           /* array columns, rows */
    const uint32_t *idx;     /* w*h point indices or TESSEL_NONE */
    int wrap_c, wrap_r;      /* last column (row) adjacent to the first */
    uint32_t cw, ch;         /* blocks per row, block rows */
    int kind;                /* FP_PLANE or FP_RAY */
    float dir[3];            /* FP_PLANE: unit normal of the plane */
    float vp[3];             /* FP_RAY: viewpoint in the local frame */
    float reach2;            /* 1 / cos^2(max_angle) */
    float margin2;
    int orient;              /* sign of the facing test for (A, B, D) order */
    int threads;
} fp_ctx;

/* One array entry with what the edge test needs. */
typedef struct fp_vrec {
    float p[3];
    float d[3];              /* FP_RAY: unit direction from the viewpoint */
    float w;                 /* FP_PLANE: height; FP_RAY: range */
    uint32_t ok;             /* a usable point */
} fp_vrec;

/* Block codes: bit 0 the diagonal (0: A-D, 1: B-C), bit 1 triangle t0,
 * bit 2 triangle t1, with corners A (r, c), B (r, c+1), C (r+1, c),
 * D (r+1, c+1) and, counter-clockwise in (column, row):
 *   diagonal A-D: t0 = (A, B, D), t1 = (A, D, C)
 *   diagonal B-C: t0 = (A, B, C), t1 = (B, D, C). */
enum { FP_DIAG_BC = 1, FP_T0 = 2, FP_T1 = 4 };

typedef struct fp_counts {
    size_t missing, open, folded;
} fp_counts;

/* The block codes are the hot loop (every point, every mode). Rows are
 * held as structures of arrays and the common case - four points, the
 * shorter diagonal passing, both triangles facing the right way by a clear
 * margin - is computed for a whole row in loops without branches, which
 * the compiler vectorizes; the other blocks go through fp_block(). */
typedef struct fp_soa {
    float *px, *py, *pz, *dx, *dy, *dz, *w;
    int32_t *ok;
} fp_soa;

/* Scratch of one thread: two rows (w + 1 entries: with wrapped columns,
 * entry w repeats entry 0) and the per-row edge tests. */
typedef struct fp_scratch {
    fp_soa row[2];
    int32_t *hk[2], *vk;
    float *len2;             /* lengths fp_soa_edges() writes, unused here */
    void *mem;
} fp_scratch;

/* Corners of the triangles: [diag][t] -> three corner numbers. */
static const int fp_tri_corners[2][2][3] = {
    {{0, 1, 3}, {0, 3, 2}},
    {{0, 1, 2}, {1, 3, 2}},
};

/* The 2D frame of the dexels: each point maps to (s, t) and a depth;
 * height: in-plane coordinates and height; range: (phi, theta) about the
 * pole and the range. */
typedef struct fp_frame {
    int kind;
    double e[3][3];          /* rows: first axis, second axis, normal / pole */
    double vp[3];            /* range: viewpoint, local frame */
    double phi0;             /* range: phi measured from here */
    int transpose;           /* range: (s, t) = (theta, phi) instead of
                                (phi, theta): see tsl_fp_scan_order() */
} fp_frame;

/* A point in the dexel frame: first its map (s, t) and depth; once the
 * array is sized, its dexel and its position (u, v) inside it (0..65535
 * each way), computed once for the bucketing, the representatives and the
 * filling. The depth stays in place. */
typedef union fp_mapped {
    struct {
        float s, t, depth;
    } st;
    struct {
        uint32_t id;   /* dexel, TESSEL_NONE for an unmapped point */
        uint16_t u, v;
        float depth;
    } dx;
} fp_mapped;

typedef struct fp_dexels {
    uint32_t w, h;
    int wrap_c, wrap_r;      /* range: phi runs along columns or rows */
    double cell[2];
    float lo[2];             /* corner of dexel (0, 0) */
    uint32_t *rep;
    size_t reps, filled;
    uint32_t *filled_slots;  /* the filled dexels, in raster order */
} fp_dexels;

void tsl_fp_row(const fp_ctx *x, uint32_t r, fp_vrec *out);

/* The sphere-of-influence test of tessel.h; both entries valid. Writes the
 * squared length. */
int tsl_fp_edge(const fp_ctx *x, const fp_vrec *a, const fp_vrec *b, float *len2);

/* The same, first in float: when |s| exceeds 1e-5 of the sum of the
 * magnitudes of its terms (float rounding is below 1e-6 of it), the float
 * sign is the exact one; only near-degenerate triangles take the double
 * path. */
int tsl_fp_facing(const fp_ctx *x, const fp_vrec *a, const fp_vrec *b,
                            const fp_vrec *c);

tessel_status tsl_fp_scratch_alloc(fp_scratch *sc, uint32_t w);

/* Codes of block rows [r0, r1), loading each array row once. */
void tsl_fp_codes_rows(const fp_ctx *x, uint32_t r0, uint32_t r1, uint8_t *codes,
                          fp_scratch *sc, fp_counts *cnt);

tessel_status tsl_fp_make_manifold(const fp_ctx *x, uint8_t *codes, size_t *removed);

/* The triangles of the blocks round each filled dexel that use its point
 * are dropped when they overlap another triangle in projection or meet it
 * in space beyond shared vertices and edges. */
void tsl_fp_untangle(const fp_ctx *x, uint8_t *codes, const uint32_t *slots, size_t n,
                        size_t *dropped);

/* Height frame: the plane normal to an axis, or of least variance. */
void tsl_fp_height_frame(const tessel_cloud *cloud, int axis, fp_frame *f);

/* Range frame. The pole is the axis (z, x or y) for which the sample's
 * points spread most evenly over equal-angle (theta, phi) cells: the
 * scanner's own axis for a terrestrial scan (its samples are equal-angle
 * about the vertical), an axis across the view for a camera (whose view
 * axis as pole would crowd the data into tiny dexels round it). Evenness
 * is the coefficient of variation of the counts of occupied cells; z wins
 * unless another axis is clearly more even. phi starts after the widest
 * empty sector, so a partial scan does not straddle the cut. */
void tsl_fp_range_frame(const tessel_cloud *cloud, const double vp[3], fp_frame *f,
                           double *gap);

/* Range: which way the input runs. A scanner delivers its points profile
 * by profile; when consecutive points mostly step in theta, the array is
 * stored with theta along its rows (s = theta, t = phi), so that bucketing
 * writes and reads memory nearly in order instead of jumping a whole row per
 * point (2-3x faster at 10^8 points). The dexels are the same either way;
 * only rules that go in raster order (filling, fan fixes) may pick
 * differently among ties. */
void tsl_fp_scan_order(const tessel_cloud *cloud, fp_frame *f);

/* Buckets the mapped points into the w x h dexels (a stable counting sort
 * of point indices) and picks each dexel's representative. */
tessel_status tsl_fp_bucket(const fp_mapped *map, size_t n, fp_dexels *dx, int nt,
                               const tessel_callbacks *cb);

/* Turns every map entry (s, t) into its dexel and position (see
 * fp_mapped). */
void tsl_fp_assign(fp_mapped *map, size_t n, const fp_dexels *dx, int nt);

/* Chooses the array size: given, from a cell size, or so that occupied
 * dexels hold points_per_dexel points on average (the occupied area is
 * measured on a coarse probe grid filled with a sample). */
tessel_status tsl_fp_size(const fp_mapped *map, size_t n, const fp_frame *f,
                             const float lo[2], const float hi[2],
                             const tessel_fixed_plane_params *p, size_t valid, int full_axis,
                             fp_dexels *dx);

/* Maps every point once: map[i] = (s, t, depth), s = NaN for a point
 * that cannot be mapped; returns the number mapped and their
 * bounding box (parallel min/max are exact: no dependence on the thread
 * count). */
size_t tsl_fp_map_all(const tessel_cloud *cloud, const fp_frame *f, fp_mapped *map,
                         float lo[2], float hi[2], int nt);

#endif /* TESSEL_FIXED_PLANE_H */
