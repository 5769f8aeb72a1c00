/* The noisy-cloud pipeline (src/pipeline/), private to the library.
 * Not installed. */
#ifndef TESSEL_PIPELINE_H
#define TESSEL_PIPELINE_H

#include "mesh/mesh.h"

/* ---- the noisy-cloud pipeline (src/pipeline/) ---- */

/* How many components of m are stray pieces: at most STRAY_FRACTION (1%)
 * of its triangles each, counted only when there are at most STRAY_MAX (8)
 * of them (else 0: a scene of many small pieces is what was sampled).
 * *pieces (when not NULL): the other components. The pipeline's repair
 * sends the front again around stray pieces. */
tessel_status tsl_stray_pieces(const tessel_mesh *m, size_t *strays, size_t *pieces);

#endif /* TESSEL_PIPELINE_H */
