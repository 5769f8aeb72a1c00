/* The smoothing, clustering and representatives (src/smooth/), private
 * to the library: the entry points the refinement and the noisy-cloud
 * pipeline share. Not installed. */
#ifndef TESSEL_SMOOTH_H
#define TESSEL_SMOOTH_H

#include "core/core.h"

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

#endif /* TESSEL_SMOOTH_H */
