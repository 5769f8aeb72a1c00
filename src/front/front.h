/* The advancing front (src/front/), private to the library: the entry
 * points the noisy-cloud pipeline calls beside tessel_advancing_front.
 * Not installed. */
#ifndef TESSEL_FRONT_H
#define TESSEL_FRONT_H

#include "mesh/mesh.h"

/* tessel_advancing_front with a second set of unit normal lines (count*3
 * floats, sign not meaningful; NULL: none): a new triangle's normal may
 * agree with either line at each vertex (src/advancing_front.c; the
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

#endif /* TESSEL_FRONT_H */
