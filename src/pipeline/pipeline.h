/* The noisy-cloud pipeline (src/pipeline/), private to the library.
 * Not installed. */
#ifndef TESSEL_PIPELINE_H
#define TESSEL_PIPELINE_H

#include "front/front.h"
#include "mesh/mesh.h"

/* ---- the noisy-cloud pipeline (src/pipeline/) ---- */

/* How many components of m are stray pieces: at most STRAY_FRACTION (1%)
 * of its triangles each, counted only when there are at most STRAY_MAX (8)
 * of them (else 0: a scene of many small pieces is what was sampled).
 * *pieces (when not NULL): the other components. The pipeline's repair
 * sends the front again around stray pieces. */
tessel_status tsl_stray_pieces(const tessel_mesh *m, size_t *strays, size_t *pieces);

/* tessel_reconstruct_smooth with the tiles of its advancing front over the
 * representatives run by runner (NULL: this process's threads). */
tessel_status tsl_reconstruct_smooth_with(const tessel_cloud *cloud,
                                          const tessel_smooth_recon_params *params,
                                          const tsl_af_tile_runner *runner,
                                          const tessel_callbacks *callbacks, tessel_mesh *mesh,
                                          tessel_smooth_recon_stats *stats);

#endif /* TESSEL_PIPELINE_H */
