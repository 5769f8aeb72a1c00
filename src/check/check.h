/* The mesh checker (src/check/), private to the library: what its two
 * files share (check.c topology and validity, surface.c the bounding
 * volume hierarchy and what uses it: self-intersections, distances,
 * sampling, F-score). Not installed. */
#ifndef TESSEL_CHECK_H
#define TESSEL_CHECK_H

#include "core/core.h"

enum { KIND_OK = 0, KIND_REPEATED = 1, KIND_ZERO_AREA = 2 };

/* Seeds of the evaluator's two sample sets (mesh side, reference side). */
#define SEED_MESH_SAMPLES 0x5eed0001ULL
#define SEED_REF_SAMPLES 0x5eed0002ULL

#define BVH_LEAF 4
#define BVH_STACK 96

/* Nodes in depth-first order: an inner node's left child follows it. Boxes
 * are floats rounded outwards (32-byte-ish nodes keep traversals in cache);
 * every primitive box fed in is itself a rounded-out float box. */
typedef struct bvh_node {
    float lo[3], hi[3];
    uint32_t start, end; /* leaf positions [start, end) below this node */
    uint32_t right;      /* right child; 0 for a leaf (the root is never one) */
} bvh_node;

typedef struct bvh {
    bvh_node *nodes;
    uint32_t *order; /* primitive id at each leaf position */
    float *box;      /* box of the primitive at each leaf position, 6 floats */
    size_t node_count;
} bvh;

/* Usable triangles of a mesh for distances and sampling: non-degenerate,
 * with a finite non-zero normal; coordinates in the checked mesh's local
 * frame; cumulative areas in order; a hierarchy over their boxes. */
typedef struct surface {
    size_t count;
    double *tri;  /* count*9 */
    double *cum;  /* count, running sum of areas */
    uint8_t *sliver; /* count, 1: measured as its three edges */
    double slack; /* absolute rounding allowance of a distance, 1e-9 of the
                     largest coordinate */
    bvh tree;
} surface;

void tsl_check_surface_free(surface *s);

/* shift: added to m's local coordinates to bring them into the frame of the
 * checked mesh. kind: per-triangle classification of m. */
tessel_status tsl_check_surface_build(surface *s, const tessel_mesh *m, const uint8_t *kind,
                                   const double shift[3]);

/* Checks indices and coordinates, classifies every triangle. */
tessel_status tsl_check_classify(const tessel_mesh *m, uint8_t **kind_out, int threads);

/* Bounding-box diagonal of the vertices referenced by a triangle (all
 * vertices when there are no triangles). */
double tsl_check_bbox_diagonal(const tessel_mesh *m);

/* Counts intersecting pairs of non-degenerate triangles and the triangles
 * in at least one such pair. */
tessel_status tsl_check_self_intersections(const tessel_mesh *m, const uint8_t *kind, int threads,
                                        size_t *pairs_out, size_t *faces_out);

/* --input: input points that are mesh vertices, distances to the mesh. */
tessel_status tsl_check_input_figures(const tessel_mesh *m, const surface *s,
                                   const tessel_cloud *cloud, int threads,
                                   tessel_mesh_report *r);

/* --reference: Chamfer, Hausdorff, precision / recall / F-score. */
tessel_status tsl_check_reference_figures(const tessel_mesh *m, const surface *out,
                                       const tessel_check_params *p, int threads,
                                       tessel_mesh_report *r);

#endif /* TESSEL_CHECK_H */
