/*
 * tessel — surface reconstruction from 3D point clouds.
 *
 * The whole public API. Conventions:
 *  - Every function that can fail returns a tessel_status (TESSEL_OK == 0).
 *    Functions that parse input also fill an optional tessel_diag naming the
 *    file and the line or byte offset of the problem.
 *  - Arrays are plain pointers with their shape documented ("count*3 floats").
 *    Structs returned to the caller own their arrays; free them with the
 *    matching *_free() function. Freeing a zeroed struct or NULL is a no-op.
 *  - Lengths in params structs are multiples of the cloud's mean spacing
 *    (mean distance from a point to its nearest neighbour) unless the field
 *    says otherwise.
 *  - The library never prints and never exits. Progress and log messages go
 *    through tessel_callbacks; a non-zero return from progress cancels.
 *  - No mutable global state: every function is reentrant. Threaded stages
 *    use OpenMP and give bit-identical results for any thread count.
 */
#ifndef TESSEL_H
#define TESSEL_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define TESSEL_VERSION_MAJOR 0
#define TESSEL_VERSION_MINOR 1
#define TESSEL_VERSION_PATCH 0
#define TESSEL_VERSION_STRING "0.1.0"

#if defined(_WIN32) && defined(TESSEL_SHARED_BUILD)
#define TESSEL_API __declspec(dllexport)
#elif defined(__GNUC__)
#define TESSEL_API __attribute__((visibility("default")))
#else
#define TESSEL_API
#endif

/* ------------------------------------------------------------------------ */
/* Status codes                                                              */
/* ------------------------------------------------------------------------ */

/* X-macro table: one place defines the enum and its strings. */
#define TESSEL_STATUS_LIST(X)                                                  \
    X(TESSEL_OK, "ok")                                                         \
    X(TESSEL_ERR_INVALID_ARG, "invalid argument")                              \
    X(TESSEL_ERR_NOMEM, "out of memory")                                       \
    X(TESSEL_ERR_IO, "input/output error")                                     \
    X(TESSEL_ERR_PARSE, "malformed input")                                     \
    X(TESSEL_ERR_UNSUPPORTED, "unsupported format or feature")                 \
    X(TESSEL_ERR_LIMIT, "size limit exceeded")                                 \
    X(TESSEL_ERR_TOO_FEW_POINTS, "not enough points")                          \
    X(TESSEL_ERR_CANCELLED, "cancelled")                                       \
    X(TESSEL_ERR_INTERNAL, "internal error")

typedef enum tessel_status {
#define TESSEL_X_ENUM(name, str) name,
    TESSEL_STATUS_LIST(TESSEL_X_ENUM)
#undef TESSEL_X_ENUM
    TESSEL_STATUS_COUNT
} tessel_status;

/* A static, human-readable string for a status ("unknown status" if out of
 * range). Never NULL. */
TESSEL_API const char *tessel_status_str(tessel_status status);

/* Library version as "MAJOR.MINOR.PATCH". */
TESSEL_API const char *tessel_version(void);

/* Where and why parsing or writing failed. Filled by functions that take a
 * tessel_diag* (which may be NULL). Fixed-size buffers: no allocation. */
typedef struct tessel_diag {
    char file[512];      /* path or the name given to a parser; "" if none */
    uint64_t line;       /* 1-based line number for text input; 0 if n/a */
    uint64_t offset;     /* byte offset for binary input; meaningful if has_offset */
    int has_offset;      /* 1 when offset is set */
    char message[512];   /* what is wrong, e.g. "expected 3 coordinates, got 2" */
} tessel_diag;

/* ------------------------------------------------------------------------ */
/* Callbacks                                                                 */
/* ------------------------------------------------------------------------ */

typedef enum tessel_log_level {
    TESSEL_LOG_DEBUG = 0,
    TESSEL_LOG_INFO = 1,
    TESSEL_LOG_WARNING = 2
} tessel_log_level;

/* One record for progress and logging; every member may be NULL.
 * progress: stage is a short static name ("read", "normals", "greedy"...),
 *   fraction in [0,1]. Called at most a few hundred times per stage, never
 *   from inside an OpenMP parallel region. Return non-zero to cancel: the
 *   running function then returns TESSEL_ERR_CANCELLED.
 * log: one message per call, never from a hot loop. */
typedef struct tessel_callbacks {
    int (*progress)(void *user_data, const char *stage, double fraction);
    void (*log)(void *user_data, tessel_log_level level, const char *message);
    void *user_data;
} tessel_callbacks;

/* Marks an absent index (missing grid cell, no neighbour). */
#define TESSEL_NONE UINT32_MAX

/* ------------------------------------------------------------------------ */
/* Point clouds and meshes                                                   */
/* ------------------------------------------------------------------------ */

/* A point cloud. World coordinates of point i are offset + xyz[3i..3i+2]:
 * float positions in a local frame, a double offset so georeferenced data
 * (UTM, ECEF) keep their precision. Readers choose the offset (see
 * docs/formats.md): per axis, the integer part of the points' median when
 * that exceeds 4096 in magnitude, else 0, so a few stray points far from
 * the bulk cannot make the bulk's floats coarse. */
typedef struct tessel_cloud {
    size_t count;        /* number of points */
    float *xyz;          /* count*3 floats, local coordinates */
    float *normals;      /* count*3 floats (unit length) or NULL */
    uint8_t *rgb;        /* count*3 bytes or NULL */
    double offset[3];    /* added to xyz to get world coordinates */

    /* Organized clouds (depth cameras, PCD width x height, PLY
     * "comment organized W H"): width*height grid cells in row-major order;
     * grid[cell] is the index of the point at that cell or TESSEL_NONE where
     * the scanner returned nothing (NaN in the file). grid is NULL and
     * width == height == 0 for unorganized clouds. */
    uint32_t width, height;
    uint32_t *grid;

    /* Scanner position in world coordinates (PCD VIEWPOINT, PLY
     * "comment viewpoint X Y Z"), valid when has_viewpoint is 1. */
    double viewpoint[3];
    int has_viewpoint;

    /* Points the reader dropped because a coordinate was NaN, infinite or
     * beyond 1e15 in magnitude. */
    size_t dropped_nonfinite;
} tessel_cloud;

/* A triangle mesh. Vertex i is at offset + xyz[3i..3i+2]. Triangles are
 * counter-clockwise seen from outside (right-hand rule gives the normal). */
typedef struct tessel_mesh {
    size_t vertex_count;
    float *xyz;            /* vertex_count*3 floats */
    float *normals;        /* vertex_count*3 floats or NULL */
    uint8_t *rgb;          /* vertex_count*3 bytes or NULL */
    double offset[3];
    size_t triangle_count;
    uint32_t *triangles;   /* triangle_count*3 vertex indices */
} tessel_mesh;

/* Allocates a cloud of count points (xyz zeroed; normals / colours only when
 * asked). On failure *cloud is left zeroed. */
TESSEL_API tessel_status tessel_cloud_alloc(tessel_cloud *cloud, size_t count,
                                            int with_normals, int with_rgb);
/* Frees the arrays and zeroes the struct. NULL and zeroed structs are fine. */
TESSEL_API void tessel_cloud_free(tessel_cloud *cloud);
/* Deep copy. */
TESSEL_API tessel_status tessel_cloud_copy(tessel_cloud *dst, const tessel_cloud *src);

TESSEL_API tessel_status tessel_mesh_alloc(tessel_mesh *mesh, size_t vertex_count,
                                           size_t triangle_count, int with_normals,
                                           int with_rgb);
TESSEL_API void tessel_mesh_free(tessel_mesh *mesh);

/* World coordinates to a local frame exactly as the readers store them
 * (docs/formats.md, "the offset rule"): chooses the per-axis offset from
 * count*3 doubles (world) and writes count*3 floats to xyz (the caller
 * sizes it), so that offset + xyz is what a reader of the same points gives.
 * For programs and bindings that hold double coordinates (python/).
 * TESSEL_ERR_INVALID_ARG, nothing written, when a coordinate is NaN,
 * infinite or beyond 1e15 in magnitude; TESSEL_ERR_NOMEM. */
TESSEL_API tessel_status tessel_world_to_local(const double *world, size_t count, float *xyz,
                                               double offset[3]);

/* ------------------------------------------------------------------------ */
/* File formats                                                              */
/* ------------------------------------------------------------------------ */

typedef enum tessel_format {
    TESSEL_FORMAT_AUTO = 0, /* from the file name's extension, then content */
    TESSEL_FORMAT_PLY,
    TESSEL_FORMAT_XYZ,      /* .xyz .pts .txt .asc: whitespace separated */
    TESSEL_FORMAT_CSV,      /* .csv: comma separated */
    TESSEL_FORMAT_OBJ,
    TESSEL_FORMAT_OFF,
    TESSEL_FORMAT_STL,      /* write only: binary STL */
    TESSEL_FORMAT_PCD,      /* read only: ascii and binary (uncompressed) */
    TESSEL_FORMAT_LAS       /* read only: LAS 1.0-1.4, point formats 0-10 */
} tessel_format;

/* Short lower-case name ("ply", "xyz", ...). */
TESSEL_API const char *tessel_format_name(tessel_format format);
/* Format from a path's extension (case-insensitive); AUTO if unknown. */
TESSEL_API tessel_format tessel_format_from_path(const char *path);

/* Limits that protect readers against hostile headers. Defaults are large
 * enough for real scans (2^31 points) and small enough that a lying header
 * cannot make the reader allocate more than the data can fill. */
typedef struct tessel_read_params {
    tessel_format format;    /* AUTO by default */
    uint64_t max_points;     /* default 2^31 - 1 (with bbox: of the points kept) */
    uint64_t max_faces;      /* default 2^31 - 1 */
    /* LAS and LAZ input only: keep the points inside this box, world
     * coordinates {xmin, ymin, zmin, xmax, ymax, zmax}, bounds included; the
     * array must outlive the call. A COPC file decodes only the chunks whose
     * octree node meets the box. NULL (default): every point. With another
     * format: TESSEL_ERR_UNSUPPORTED; min > max or a NaN:
     * TESSEL_ERR_INVALID_ARG. */
    const double *bbox;
} tessel_read_params;
TESSEL_API tessel_read_params tessel_read_params_default(void);

typedef struct tessel_write_params {
    tessel_format format;    /* AUTO: from the extension */
    int ascii;               /* PLY only: 1 writes ascii; default 0 (binary LE) */
    int write_normals;       /* write normals when present; default 1 */
    int write_rgb;           /* write colours when present; default 1 */
} tessel_write_params;
TESSEL_API tessel_write_params tessel_write_params_default(void);

/* Parse a cloud from memory. `name` is used in diagnostics only (may be
 * NULL). For mesh formats the vertices are read and faces skipped. With
 * format AUTO, the extension of `name` decides when it is known, else the
 * content (PLY, OFF, PCD, LAS magic; else OBJ if it has "v " lines; else
 * XYZ/CSV). On error *cloud is zeroed. */
TESSEL_API tessel_status tessel_cloud_parse(tessel_cloud *cloud, const void *data,
                                            size_t size, const char *name,
                                            const tessel_read_params *params,
                                            tessel_diag *diag);
/* Read a cloud from a file (params may be NULL for defaults). */
TESSEL_API tessel_status tessel_cloud_read(tessel_cloud *cloud, const char *path,
                                           const tessel_read_params *params,
                                           tessel_diag *diag);
/* Parse / read a mesh (PLY, OBJ, OFF). Polygons with more than three
 * vertices are split into fans. A point format gives a mesh with no
 * triangles. */
TESSEL_API tessel_status tessel_mesh_parse(tessel_mesh *mesh, const void *data,
                                           size_t size, const char *name,
                                           const tessel_read_params *params,
                                           tessel_diag *diag);
TESSEL_API tessel_status tessel_mesh_read(tessel_mesh *mesh, const char *path,
                                          const tessel_read_params *params,
                                          tessel_diag *diag);

/* Writers go to a temporary file in the destination's folder and rename it
 * over the destination only once everything was written: a failed write
 * never leaves a partial file. params may be NULL. */
TESSEL_API tessel_status tessel_cloud_write(const tessel_cloud *cloud, const char *path,
                                            const tessel_write_params *params,
                                            tessel_diag *diag);
TESSEL_API tessel_status tessel_mesh_write(const tessel_mesh *mesh, const char *path,
                                           const tessel_write_params *params,
                                           tessel_diag *diag);

/* Where a reconstruction sends its triangles as soon as they are final.
 * emit receives count triangles (count*3 indices into the input cloud) and
 * returns TESSEL_OK to continue; any other status aborts the caller, which
 * returns that status. */
typedef struct tessel_triangle_sink {
    tessel_status (*emit)(void *user_data, const uint32_t *triangles, size_t count);
    void *user_data;
} tessel_triangle_sink;

/* Streaming mesh writer: the vertices are the given cloud's points, the
 * triangles arrive in batches and are spooled to a temporary file, so memory
 * stays flat however many triangles come. close() writes the final file
 * (vertices not used by any triangle are dropped when compact is set) and
 * renames it into place; abort() removes every temporary. Formats: PLY, OBJ,
 * OFF, STL. */
typedef struct tessel_mesh_writer tessel_mesh_writer;

TESSEL_API tessel_status tessel_mesh_writer_open(tessel_mesh_writer **writer,
                                                 const char *path,
                                                 const tessel_cloud *vertices,
                                                 const tessel_write_params *params,
                                                 int compact, tessel_diag *diag);
TESSEL_API tessel_status tessel_mesh_writer_add(tessel_mesh_writer *writer,
                                                const uint32_t *triangles, size_t count);
/* Finishes the file; the writer is freed whatever the result. */
TESSEL_API tessel_status tessel_mesh_writer_close(tessel_mesh_writer *writer,
                                                  tessel_diag *diag);
/* Discards everything; the destination is left untouched. NULL is fine. */
TESSEL_API void tessel_mesh_writer_abort(tessel_mesh_writer *writer);
/* A sink that feeds tessel_mesh_writer_add. */
TESSEL_API tessel_triangle_sink tessel_mesh_writer_sink(tessel_mesh_writer *writer);

/* ------------------------------------------------------------------------ */
/* Neighbour search                                                          */
/* ------------------------------------------------------------------------ */

/* An exact spatial index (kd-tree) over count points. It keeps a pointer to
 * xyz: the array must outlive the index and stay unchanged. Queries are
 * thread-safe and never allocate. */
typedef struct tessel_index tessel_index;

TESSEL_API tessel_status tessel_index_build(tessel_index **index, const float *xyz,
                                            size_t count);
TESSEL_API void tessel_index_destroy(tessel_index *index);

/* The k nearest points to q (k <= count), sorted by squared distance, ties
 * by increasing index; a point equal to q is included. Writes min(k, count)
 * entries to idx and dist2 (dist2 may be NULL) and returns that number. */
TESSEL_API size_t tessel_index_knn(const tessel_index *index, const float q[3],
                                   size_t k, uint32_t *idx, float *dist2);

/* All points with squared distance <= radius^2 from q, sorted like knn.
 * Writes at most cap of them (the nearest) and returns how many there are
 * in all (which may exceed cap). dist2 may be NULL. A query point with a NaN
 * or infinite coordinate finds nothing (returns 0), in knn too. */
TESSEL_API size_t tessel_index_radius(const tessel_index *index, const float q[3],
                                      float radius, uint32_t *idx, float *dist2,
                                      size_t cap);

/* knn for every query point, threaded: idx and dist2 (may be NULL) have
 * query_count*k slots; rows of points with fewer than k neighbours are
 * padded with TESSEL_NONE / INFINITY. threads: 0 = OpenMP default (honours
 * OMP_NUM_THREADS). */
TESSEL_API tessel_status tessel_index_knn_batch(const tessel_index *index,
                                                const float *queries, size_t query_count,
                                                size_t k, uint32_t *idx, float *dist2,
                                                int threads);

/* ------------------------------------------------------------------------ */
/* Cloud statistics and clean-up                                             */
/* ------------------------------------------------------------------------ */

typedef struct tessel_stats_params {
    size_t sample_size;        /* spacing is measured on at most this many
                                  points (evenly strided); default 100000 */
    uint32_t outlier_k;        /* neighbours for the density test, 1..256;
                                  default 8 */
    double outlier_factor;     /* a point is an isolated outlier when its mean
                                  distance to its outlier_k neighbours exceeds
                                  this many times the cloud's median of that
                                  quantity; default 5 */
    int threads;               /* 0 = OpenMP default */
} tessel_stats_params;
TESSEL_API tessel_stats_params tessel_stats_params_default(void);

typedef struct tessel_cloud_stats {
    double bbox_min[3], bbox_max[3]; /* world coordinates */
    double diagonal;                 /* bounding-box diagonal */
    double mean_spacing;             /* mean nearest-neighbour distance
                                        (excluding exact duplicates, and
                                        isolated points whose distance is
                                        over 32 times the median) */
    double median_spacing;
    size_t exact_duplicates;         /* points equal to an earlier point */
    size_t outliers;                 /* isolated points by local density */
} tessel_cloud_stats;

TESSEL_API tessel_status tessel_cloud_stats_compute(const tessel_cloud *cloud,
                                                    const tessel_stats_params *params,
                                                    tessel_cloud_stats *stats);

/* Mean nearest-neighbour spacing of a cloud (sampled like the stats, far
 * outliers left out: mean_spacing). The unit of every "multiple of the
 * spacing" parameter. */
TESSEL_API tessel_status tessel_cloud_spacing(const tessel_cloud *cloud, double *spacing);

/* The noise of a cloud, estimated from the cloud alone (docs/noise.md):
 * heights above local planes fitted over balls of growing size (Mitra,
 * Nguyen & Guibas 2004), the smallest ball well above the noise giving
 * sigma, corrected for the ball's cut through the noisy slab and for the
 * curvature. */
typedef struct tessel_noise_estimate {
    double sigma;           /* standard deviation of the points' distances
                               from the surface, world units */
    double surface_spacing; /* 1 / sqrt(points per unit area of the
                               surface), world units (for a uniform random
                               sample about twice the mean nearest-neighbour
                               distance of the clean cloud) */
    double noise_ratio;     /* sigma / surface_spacing */
    size_t samples;         /* seed points the medians were taken over */
} tessel_noise_estimate;

/* Estimates the noise of cloud into *out. threads: 0 = OpenMP default; the
 * result does not depend on it. Clouds of more than 2^18 points are
 * estimated on a subsample of that size. TESSEL_ERR_TOO_FEW_POINTS under
 * 32 points. */
TESSEL_API tessel_status tessel_cloud_noise(const tessel_cloud *cloud, int threads,
                                            tessel_noise_estimate *out);

/* Merges points closer than tolerance (absolute length; 0 merges exact
 * duplicates only) into the first of them, in input order, keeping normals
 * and colours of the kept point. Writes the number removed to *removed
 * (may be NULL). Order of the kept points is preserved. */
TESSEL_API tessel_status tessel_cloud_merge_duplicates(tessel_cloud *cloud,
                                                       double tolerance,
                                                       size_t *removed);

/* ------------------------------------------------------------------------ */
/* Normals                                                                   */
/* ------------------------------------------------------------------------ */

typedef struct tessel_normals_params {
    uint32_t k;          /* neighbours for the PCA plane; default 16 (3..256) */
    int orient;          /* 1: consistent orientation by a minimum spanning
                            tree over the k-NN graph (Hoppe et al. 1992),
                            outward on closed surfaces; 0: PCA sign as is.
                            Default 1. */
    int threads;         /* 0 = OpenMP default */
} tessel_normals_params;
TESSEL_API tessel_normals_params tessel_normals_params_default(void);

/* Estimates unit normals for every point. cloud->normals is replaced by a
 * new array (any previous one is freed), so pointers to the old normals
 * must not be kept across the call. */
TESSEL_API tessel_status tessel_normals_estimate(tessel_cloud *cloud,
                                                 const tessel_normals_params *params,
                                                 const tessel_callbacks *callbacks);
/* Orientation details (src/normals/): each component of the k-NN graph is
 * seeded at its highest point with n.z > 0; a cloud with a viewpoint (one
 * scan, has_viewpoint) instead has every normal turned towards the
 * viewpoint. On failure or cancellation cloud->normals is left as it was.
 * Non-finite coordinates give TESSEL_ERR_INVALID_ARG, fewer than 3 points
 * TESSEL_ERR_TOO_FEW_POINTS. Progress stage: "normals". */

/* ------------------------------------------------------------------------ */
/* Mesh check (src/check/)                                                  */
/* ------------------------------------------------------------------------ */

typedef struct tessel_check_params {
    int self_intersections;      /* 1: test every nearby triangle pair exactly
                                    (bounding-box culling + robust orientation
                                    predicates); default 1 */
    const tessel_cloud *input;   /* optional: the cloud the mesh was made from */
    const tessel_mesh *reference;/* optional: the true surface */
    double tau;                  /* F-score threshold, absolute length; 0 means
                                    1% of the reference's bounding-box diagonal
                                    (as meshcheck); default 0 */
    uint32_t samples;            /* surface samples per mesh for Chamfer /
                                    Hausdorff / F-score; default 200000 */
    int threads;                 /* 0 = OpenMP default */
} tessel_check_params;
TESSEL_API tessel_check_params tessel_check_params_default(void);

typedef struct tessel_mesh_report {
    /* Definitions follow the evaluator meshcheck (docs/check.md). A
     * triangle is degenerate when it repeats an index or its three corners
     * are exactly collinear. Topology ignores triangles with a repeated
     * index; zero-area ones take part. */
    size_t vertices, triangles;
    size_t unreferenced_vertices;   /* used by no triangle */
    size_t components;              /* edge-connected triangle components */
    size_t edges;                   /* distinct undirected edges */
    size_t boundary_edges;          /* edges with one triangle */
    size_t boundary_loops;          /* connected components of the graph of
                                       boundary edges */
    size_t nonmanifold_edges;       /* edges with more than two triangles */
    size_t nonmanifold_vertices;    /* vertices whose link (the opposite
                                       edges of their triangles) is not one
                                       path or one cycle */
    size_t orientation_conflicts;   /* edges with two triangles that run it in
                                       the same direction */
    int oriented;                   /* 1 when orientation_conflicts == 0 */
    int orientable;                 /* 1 when flipping whole triangles could
                                       make every two-triangle edge
                                       consistent (a flipped triangle is
                                       orientable but not oriented) */
    size_t self_intersections;      /* pairs of non-degenerate triangles that
                                       meet anywhere if they share no vertex,
                                       beyond the shared vertex or edge
                                       otherwise (bit-identical vertices
                                       count as shared); decided exactly.
                                       SIZE_MAX when not run */
    size_t self_intersecting_triangles; /* triangles in such a pair;
                                       SIZE_MAX when not run */
    size_t duplicate_triangles;     /* same vertex set as an earlier one */
    size_t degenerate_triangles;    /* repeated index or zero area */
    long euler;                     /* V - E + F, V counting vertices of the
                                       triangles without repeated index */
    long genus;                     /* sum over components of (2 - chi)/2,
                                       given for closed (no boundary),
                                       manifold, orientable meshes; -1
                                       otherwise */
    /* Over non-degenerate triangles (NaN when there are none): */
    double min_angle_deg;           /* smallest angle of any triangle */
    double max_angle_deg;           /* largest angle of any triangle */
    double mean_min_angle_deg;      /* mean of each triangle's smallest angle */
    double area;                    /* total area, world units squared */
    double bbox_diagonal;           /* of the vertices used by triangles (all
                                       vertices if there are no triangles) */
    /* With params->input (NaN / 0 otherwise): */
    size_t input_points;
    size_t input_as_vertices;       /* input points within 1e-9 of the
                                       input's bbox diagonal of a mesh vertex
                                       used by a triangle */
    double input_distance_mean, input_distance_rms, input_distance_max;
                                    /* input point to mesh surface, world
                                       units */
    double input_bbox_diagonal;
    /* With params->reference (NaN otherwise); both surfaces are sampled
     * uniformly by area, params->samples points each, fixed seeds: */
    double accuracy;                /* mean distance mesh samples -> reference */
    double completeness;            /* mean distance reference samples -> mesh */
    double chamfer;                 /* (accuracy + completeness) / 2 */
    double hausdorff;               /* largest sample distance either way */
    double precision, recall, fscore; /* percent of mesh samples within tau
                                       of the reference, of reference samples
                                       within tau of the mesh, and their
                                       harmonic mean */
    double tau;                     /* absolute threshold used */
    double reference_bbox_diagonal;
    double normal_consistency;      /* mean |cos| of the angle between the
                                       mesh's normal at each of its samples
                                       and the reference's at the nearest
                                       point (1: parallel everywhere) */
    double normal_consistency_ref;  /* the same from the reference's samples */
} tessel_mesh_report;

/* Measures a mesh (params may be NULL for defaults). Returns TESSEL_OK
 * even when the mesh is not valid: the report says what is wrong. Fails with
 * TESSEL_ERR_INVALID_ARG when a triangle index is out of range, a vertex used
 * by a triangle is not finite, or the reference has no non-degenerate
 * triangle; TESSEL_ERR_LIMIT beyond 2^32-1 vertices or 2^31-1 triangles.
 * Distances are computed in the mesh's local frame (other offsets are
 * converted). Deterministic for any thread count.
 * tessel_mesh_report_valid() is true for a mesh with at least one triangle
 * that is manifold (boundaries allowed), consistently oriented, and has no
 * self-intersection (when they were checked), duplicate or degenerate
 * triangle. */
TESSEL_API tessel_status tessel_mesh_check(const tessel_mesh *mesh,
                                           const tessel_check_params *params,
                                           tessel_mesh_report *report);
TESSEL_API int tessel_mesh_report_valid(const tessel_mesh_report *report);

/* ------------------------------------------------------------------------ */
/* Sampling a mesh (src/sample/)                                            */
/* ------------------------------------------------------------------------ */

typedef struct tessel_sample_params {
    double noise;     /* standard deviation of isotropic Gaussian noise added
                         to each point, world units; default 0 (none) */
    double noise_rel; /* the same as a fraction of the mesh's bounding-box
                         diagonal, used when noise is 0; default 0 */
    uint64_t seed;    /* default 1; the same seed gives the same points for
                         any thread count */
    int normals;      /* 1 (default): each point gets its triangle's unit
                         normal; 0: none */
    int threads;      /* 0 = OpenMP default */
} tessel_sample_params;
TESSEL_API tessel_sample_params tessel_sample_params_default(void);

/* Draws count points uniformly distributed over the mesh's area (each
 * triangle with probability proportional to its area, uniformly inside
 * it), plus the noise of params, into *out (allocated; in the mesh's local
 * frame: same offset). Degenerate triangles get no point.
 * TESSEL_ERR_TOO_FEW_POINTS when the mesh has no area; INVALID_ARG for a
 * triangle index out of range or a negative noise; LIMIT for count >=
 * 2^32 - 1. Progress stage: "sample". */
TESSEL_API tessel_status tessel_mesh_sample(const tessel_mesh *mesh, size_t count,
                                            const tessel_sample_params *params,
                                            const tessel_callbacks *callbacks,
                                            tessel_cloud *out);

/* ------------------------------------------------------------------------ */
/* Rendering (src/render/)                                                  */
/* ------------------------------------------------------------------------ */

/* A software rasterizer for looking at results: orthographic views fitted
 * to the mesh, z-buffer, flat shading with a headlight. Front faces (whose
 * counter-clockwise side faces the viewer) and back faces get different
 * colours, so flipped triangles show; boundary edges (edges of exactly one
 * triangle) are drawn on top in their own colour, so holes show. A cloud
 * is rendered as a mesh with no triangles: its points become splats,
 * coloured by their rgb when present, otherwise shaded by their normals or,
 * without normals, by depth. */
typedef enum tessel_view {
    TESSEL_VIEW_FRONT = 0, /* directions: see the table below */
    TESSEL_VIEW_BACK,
    TESSEL_VIEW_LEFT,
    TESSEL_VIEW_RIGHT,
    TESSEL_VIEW_TOP,
    TESSEL_VIEW_ISO,       /* from the front-right-top diagonal */
    TESSEL_VIEW_ALL        /* 2x2 contact sheet: front, right, top, iso */
} tessel_view;
/* Views with up = +Y (z_up 0): front looks from +Z towards -Z, back from
 * -Z, right from +X, left from -X, top from +Y (image up = -Z), iso from
 * (+1,+1,+1). With z_up 1 the roles of Y and Z swap: front looks from -Y,
 * top from +Z, iso from (+1,-1,+1). */

/* Parses "front", "back", "left", "right", "top", "iso", "all"; returns -1
 * for anything else. */
TESSEL_API int tessel_view_from_name(const char *name);

typedef struct tessel_render_params {
    tessel_view view;          /* default TESSEL_VIEW_ISO */
    uint32_t width, height;    /* image size in pixels (the whole sheet for
                                  VIEW_ALL); 1..16384 each; default 1024 x 768 */
    int z_up;                  /* 1: +Z is up (terrain, LAS); 0: +Y is up
                                  (most scanned models); default 0 */
    int edges;                 /* 1: draw every triangle edge; default 0 */
    int points;                /* 1: draw the vertices of a mesh as splats
                                  too (a mesh without triangles always is);
                                  default 0 */
    int boundary;              /* 1: draw boundary edges; default 1 */
    uint32_t point_size;       /* splat width in pixels, 0 = automatic (from
                                  the point count and image size); default 0 */
    uint8_t background[3];     /* default 38 38 46 (dark grey) */
    uint8_t front_color[3];    /* lit front faces; default 214 208 196 */
    uint8_t back_color[3];     /* lit back faces; default 70 120 235 (blue) */
    uint8_t boundary_color[3]; /* default 255 0 0 (red) */
    uint8_t edge_color[3];     /* triangle edges; default 20 20 20 */
    uint8_t point_color[3];    /* splats without rgb; default 250 200 60 */
    int threads;               /* 0 = OpenMP default */
} tessel_render_params;
TESSEL_API tessel_render_params tessel_render_params_default(void);

/* Renders mesh into rgb, which the caller sizes width*height*3 bytes (rows
 * top to bottom, RGB8). A mesh with nothing to draw gives an image of the
 * background colour. Triangle indices must be < vertex_count
 * (TESSEL_ERR_INVALID_ARG otherwise). Memory beyond the image: a float
 * depth buffer, 21 bytes per vertex and 20 per triangle (projected
 * coordinates, row ranges, boundary edge search). Deterministic for any
 * thread count. */
TESSEL_API tessel_status tessel_render(const tessel_mesh *mesh,
                                       const tessel_render_params *params,
                                       uint8_t *rgb);

/* ------------------------------------------------------------------------ */
/* Greedy projection reconstruction (src/greedy/)                           */
/* ------------------------------------------------------------------------ */

/* Gopi & Krishnan 2002, "A fast and efficient projection-based approach for
 * surface reconstruction" (GP3): an interpolating mesh grown breadth-first
 * from seed points. Each reference point R gathers the points within
 * mu * m of it (m: its shortest edge, or nearest neighbour), projects them
 * on its tangent plane, orders them by angle, drops the ones hidden by the
 * mesh boundary and joins consecutive ones (sections 3-4). Unlike the paper
 * (and PCL's GreedyProjectionTriangulation), every triangle is accepted
 * only if it keeps the mesh manifold, consistently oriented and free of
 * self-intersections, decided with exact predicates. See docs/greedy.md. */
typedef enum tessel_greedy_plane {
    TESSEL_GREEDY_PLANE_PCA = 0, /* section 4.1: the average normal of the
                                    triangles already at R; the PCA plane of
                                    its neighbourhood for a seed */
    TESSEL_GREEDY_PLANE_AXIS     /* section 6.1: the coordinate plane nearest
                                    to that estimate */
} tessel_greedy_plane;

typedef struct tessel_greedy_params {
    double mu;             /* radius of the sphere of influence as a multiple
                              of m (section 4.1); the one essential
                              parameter. Default 2 (the paper and PCL use
                              2.5-3; docs/greedy.md), range [1.2, 10]; used
                              when mu_from_sampling is 0 */
    int mu_from_sampling;  /* 1 (default): mu from the spread of the nearest
                              distances (their coefficient of variation c
                              over a sample of the cloud): 2 on even
                              samples (c <= 0.15), 3 on uniformly random
                              ones (c >= 0.45, where points come in close
                              pairs and a sphere of twice the nearest
                              distance misses neighbours), linear between;
                              0: mu as given */
    double max_angle;      /* alpha, degrees: consecutive neighbours of R that
                              are farther apart than this (seen from R) are
                              not joined and R stays a boundary point
                              (section 4.2). Default 120, range [60, 175] */
    double min_angle;      /* beta, degrees: neighbours that would make a
                              triangle with a smaller angle at R are dropped
                              when that traps no other point (section 4.1,
                              "angle criterion"); 0 disables it. Default 0,
                              range [0, 45]. The fans keep only R's Delaunay
                              neighbours, so it seldom helps and can make the
                              smallest angles smaller */
    tessel_greedy_plane plane; /* default TESSEL_GREEDY_PLANE_PCA */
    double max_spacing;    /* m is capped at this multiple of the cloud's mean
                              spacing: it bounds the sphere of influence (and
                              every edge) in sparse regions; a point with no
                              other point within mu * max_spacing mean
                              spacings is isolated. Default 4, range
                              [1, 1000] */
    uint32_t max_hole;     /* once the front has stopped, boundary loops of
                              at most this many edges are closed by ear
                              clipping, provided no new edge is longer than
                              2 * mu times the loop's mean edge (gaps the
                              sampling left, not openings of the surface)
                              and every triangle keeps the mesh valid. Not
                              in the paper; 0 disables it. Default 16,
                              range [0, 1000] */
    const uint32_t *existing; /* optional triangles that already exist
                              (existing_count*3 indices into the cloud,
                              counter-clockwise seen from outside, forming
                              a manifold, consistently oriented mesh), e.g.
                              a neighbouring tile's: the front starts from
                              their boundary and they are not sent to the
                              sink again. Default NULL */
    size_t existing_count;
    const uint8_t *frozen; /* with existing triangles, optional, one byte
                              per point: a point marked non-zero takes no
                              new triangle and its fan among the existing
                              ones may be partial (its other triangles lie
                              outside this cloud: a neighbouring part
                              already written, as in the out-of-core
                              sweep). Default NULL */
    int orient_check;      /* 1: hold every triangle until the end, find
                              regions meshed the wrong way round (the
                              front can step across a place where two
                              sheets touch, a hand on a thigh, and carry
                              the wrong side onto a whole limb; on a noisy
                              scan it folds over itself), rebuild them
                              the right way round, then send all to the
                              sink. The side comes from the viewpoint or
                              the input normals when the cloud has them
                              (normals only when oriented: their signs
                              agree across most edges), else from rays
                              (closed surfaces).
                              Memory then holds the mesh, about 24 bytes
                              per point more. Not with existing
                              triangles. 0: stream triangles as they are
                              final. Not in the paper; docs/greedy.md.
                              Default 1 */
    int flip;              /* 1: hold every triangle until the end, then flip
                              the diagonal of two triangles wherever the
                              two angles facing it add up to more than 180
                              degrees (the Delaunay rule; tessel_refine's
                              flips use the shorter diagonal), each flip
                              kept only if the mesh stays valid. Joining
                              R's neighbours in angle order makes many
                              slivers where two parts of the front meet;
                              this removes most (bunny.ply: 10% of the
                              triangles with an angle over 150 degrees ->
                              0.02%). Vertices stay the
                              input points. Not with existing triangles. 0:
                              the paper's triangles. Not in the paper;
                              docs/greedy.md. Default 1 */
    size_t tile_points;    /* with the mesh held (orient_check or flip):
                              more points than this are cut into tiles of
                              at most this many, meshed in parallel, and
                              the seams closed by a front over the points
                              near the cuts from the tiles' triangles
                              (docs/greedy.md, "Tiles"); the result
                              depends on this, not on the thread count.
                              Default 262144; 0: one front */
    int threads;           /* 0 = OpenMP default (honours OMP_NUM_THREADS) */
} tessel_greedy_params;
TESSEL_API tessel_greedy_params tessel_greedy_params_default(void);

/* What a reconstruction did. Every input point is counted exactly once:
 * points_in == points_used + left_duplicate + left_isolated +
 * left_closed_in + left_untriangulated. */
typedef struct tessel_recon_summary {
    size_t points_in;
    size_t points_used;          /* vertices of at least one triangle */
    size_t left_duplicate;       /* same coordinates as a kept point */
    size_t left_isolated;        /* no other point near enough (see
                                    max_spacing) */
    size_t left_closed_in;       /* inside the surface already built: its
                                    neighbours were all or mostly completed
                                    before it was reached (typically noise
                                    off the surface, or a point passed
                                    over), or the point lies on one of
                                    its triangles (a point much closer to
                                    a neighbour than the spacing, passed
                                    over by the front) */
    size_t left_untriangulated;  /* had free neighbours, but every triangle
                                    through it would have broken the mesh's
                                    validity */
    size_t triangles;            /* triangles sent to the sink (existing ones
                                    not included) */
    size_t components;           /* connected pieces of the output */
    size_t boundary_edges;       /* edges with one triangle */
    size_t seeds;                /* fronts started from a free point */
    size_t holes_closed;         /* boundary loops closed (see max_hole) */
    size_t rejected_intersecting;/* candidate triangles refused because they
                                    would have intersected the mesh or lain
                                    on it as a second layer */
    size_t peak_held_triangles;  /* most triangles held in memory at once
                                    (all of them with orient_check or
                                    flip) */
    size_t reoriented;           /* triangles of regions found the wrong
                                    way round and rebuilt (see
                                    orient_check) */
    size_t flips;                /* diagonals flipped (see flip) */
    double spacing;              /* mean spacing used, world units */
    double mu;                   /* mu used (see mu_from_sampling) */
    size_t tiles;                /* tiles of the first pass (0: one front) */
    size_t slabs;                /* out of core: slabs meshed in turn (0: in
                                    core) */
    double seconds;              /* wall-clock time of the call */
} tessel_recon_summary;

/* Reconstructs cloud and sends the triangles to sink in batches as soon as
 * no later triangle can touch them (streaming: memory holds the points and
 * a band of triangles behind the front, not the mesh) when
 * params->orient_check and params->flip are 0, else all at the end (the
 * default). Triangles index the
 * cloud's points and are counter-clockwise seen from outside on closed
 * surfaces (from the side of the input normals or viewpoint, when the cloud
 * has them, on open ones). The output is edge- and vertex-manifold,
 * consistently oriented, without self-intersecting, duplicate or degenerate
 * triangles, and the same for the same input and params. params and summary
 * may be NULL; the cloud must have fewer than 2^32 - 1 points and finite
 * coordinates. The front runs on one thread; the orientation check and the
 * diagonal flips after it run in parallel (OpenMP), with the same result
 * for any thread count. */
TESSEL_API tessel_status tessel_reconstruct_greedy(const tessel_cloud *cloud,
                                                   const tessel_greedy_params *params,
                                                   const tessel_callbacks *callbacks,
                                                   const tessel_triangle_sink *sink,
                                                   tessel_recon_summary *summary);

/* The same into a mesh: its vertices are the cloud points used by a
 * triangle, in input order, with their normals and colours; the offset is
 * the cloud's. On error *mesh is zeroed. */
TESSEL_API tessel_status tessel_reconstruct_greedy_mesh(const tessel_cloud *cloud,
                                                        const tessel_greedy_params *params,
                                                        const tessel_callbacks *callbacks,
                                                        tessel_mesh *mesh,
                                                        tessel_recon_summary *summary);

/* Out of core: clouds larger than memory. The file is read three times in
 * chunks (never whole): once to count the points and cut the cloud into
 * slabs along its longest axis (quantiles of a sample), once to sort the
 * points into one scratch file per slab, once to write the output's
 * vertices. The slabs are meshed in turn by greedy projection (tiles in
 * parallel within a slab), a band of triangles carried across each cut so
 * the seams close as in core; finished triangles go to a scratch file.
 * Memory: about 450 bytes per point of a slab, so the slabs hold
 * memory / 450 points each. Differences from the in-core result: no
 * orientation check by rays (orient_check), and the cuts fall elsewhere;
 * docs/outofcore.md. */
typedef struct tessel_outofcore_params {
    uint64_t memory;     /* bytes the reconstruction may use; 0 (default):
                            half the machine's physical memory */
    const char *scratch; /* folder for the scratch files (a hidden folder is
                            made there and removed on success, failure and
                            cancellation); NULL (default): the output's
                            folder */
} tessel_outofcore_params;
TESSEL_API tessel_outofcore_params tessel_outofcore_params_default(void);

/* Reads the cloud at in (PLY, XYZ/CSV, LAS/LAZ; read_params may be NULL)
 * and writes the greedy projection mesh of its points to out (PLY, OBJ or
 * OFF; write_params may be NULL) within op->memory. The output's vertices
 * are the used points in input order, as tessel_reconstruct_greedy_mesh
 * gives them. The summary counts the points, the triangles and the slabs
 * (in tiles); components and boundary edges are left 0 (tessel_check
 * measures them). Errors name the file in diag; the output appears whole
 * or not at all. */
TESSEL_API tessel_status tessel_reconstruct_greedy_file(
    const char *in, const char *out, const tessel_read_params *read_params,
    const tessel_greedy_params *params, const tessel_write_params *write_params,
    const tessel_outofcore_params *op, const tessel_callbacks *callbacks,
    tessel_recon_summary *summary, tessel_diag *diag);

/* ------------------------------------------------------------------------ */
/* Fixed-plane reconstruction for height fields, range scans and organized   */
/* grids (src/fixed_plane/)                                                 */
/* ------------------------------------------------------------------------ */

/* Gopi & Krishnan 2002, "A fast and efficient projection-based approach for
 * surface reconstruction", section 5: when the data are a height field
 * (terrain, aerial LIDAR) or come from a scanner with one centre of
 * projection, the projection plane is fixed and the dexel array is
 * two-dimensional. One representative per dexel (section 5.1): among the
 * dexel's points whose depth (height, range) lies in the middle half of the
 * dexel's depths, the one nearest the dexel's centre; an empty dexel next to
 * a dexel with spare points takes the nearest of them. Neighbours only from
 * adjacent dexels, a sphere of influence slightly above the noise level and
 * no visibility or angle tests. See docs/fixed_plane.md. */
typedef enum tessel_fixed_plane_mode {
    TESSEL_FIXED_PLANE_HEIGHT = 0, /* dexels on a plane (terrain, aerial LIDAR) */
    TESSEL_FIXED_PLANE_RANGE,      /* (theta, phi) dexels around a centre of
                                      projection (terrestrial scanners) */
    TESSEL_FIXED_PLANE_GRID        /* the organized cloud's own grid (depth
                                      cameras, PCD width x height) */
} tessel_fixed_plane_mode;

/* Edge test. Two representatives a and b of adjacent dexels (or grid
 * cells) are joined only when
 *     |a - b|^2 <= s^2 / cos^2(max_angle) + margin^2,
 * where s is the length the edge would have on a surface facing the
 * projection direction: in height mode the distance of a and b in the
 * plane; in range and grid modes r * |unit(a - V) - unit(b - V)|, r the
 * distance from the viewpoint V to the nearer of a and b (so |a - b| / r,
 * the edge's length relative to its range, is compared with the angular
 * step divided by cos(max_angle)). margin = noise_factor * noise: the
 * sphere of influence reaches slightly beyond the noise (section 5.1).
 * Depth discontinuities (steps, an object in front of a wall) fail the test
 * and stay open. A triangle is made when its three edges pass and it is not
 * flipped or degenerate seen along the projection direction. */
typedef struct tessel_fixed_plane_params {
    tessel_fixed_plane_mode mode; /* default TESSEL_FIXED_PLANE_HEIGHT */
    int axis;                  /* height mode: -1 (default) projects onto the
                                  cloud's plane of least variance (normal
                                  signed so that its z is >= 0: "up" for
                                  terrain); 0, 1, 2 onto the plane normal to
                                  +x, +y, +z */
    uint32_t columns, rows;    /* height and range modes: dexel array size
                                  (range: columns in phi, rows in theta);
                                  both 0 (default) derives it from cell */
    double cell;               /* height mode: dexel edge, world units; range
                                  mode: dexel angular size, radians; 0
                                  (default): chosen so that occupied dexels
                                  hold points_per_dexel points on average.
                                  Ignored when columns and rows are set */
    double points_per_dexel;   /* target of the automatic cell; default 3
                                  (>= 1; larger simplifies more) */
    double viewpoint[3];       /* range and grid modes: centre of projection,
                                  world coordinates, used when use_viewpoint
                                  is 1 */
    int use_viewpoint;         /* 0 (default): the cloud's viewpoint; grid
                                  mode falls back to the world origin (the
                                  sensor frame of depth cameras), range mode
                                  fails with TESSEL_ERR_INVALID_ARG */
    double max_angle;          /* degrees, (0, 90): steepest edge, measured
                                  from the plane facing the projection
                                  direction, that is still joined; default
                                  80 */
    double noise;              /* noise along the projection direction (height
                                  or range), standard deviation, world units;
                                  0 (default): estimated from the data (robust
                                  residual of each representative against the
                                  plane through three neighbours) */
    double noise_factor;       /* margin = noise_factor * noise; default 6
                                  (>= 0): the depth difference of two
                                  neighbours has deviation 1.4 noise, so 6
                                  keeps all but ~2e-5 of the true edges */
    int threads;               /* 0 = OpenMP default (honours OMP_NUM_THREADS) */
} tessel_fixed_plane_params;
TESSEL_API tessel_fixed_plane_params tessel_fixed_plane_params_default(void);

/* What a fixed-plane reconstruction did. */
typedef struct tessel_fixed_plane_stats {
    tessel_fixed_plane_mode mode;
    size_t points_in;          /* cloud->count */
    size_t representatives;    /* dexels (grid cells) holding a point */
    size_t dexels_filled;      /* of which empty dexels that took a spare
                                  point of a neighbouring dexel (height and
                                  range: a one-dexel sampling gap is not a
                                  hole) */
    uint32_t columns, rows;    /* dexel array (grid) size as stored; range
                                  mode stores phi along the rows instead of
                                  the columns when the input runs in theta
                                  (scanner profiles) */
    int wrap_columns, wrap_rows; /* 1 when the last column (row) is joined to
                                  the first: a full 360 degree scan */
    double cell[2];            /* dexel size along columns and rows: world
                                  units (height), radians (range); 0 (grid) */
    double axis[3];            /* height: plane normal; range: the pole of the
                                  (theta, phi) frame; grid: 0 */
    double viewpoint[3];       /* range and grid: centre of projection used,
                                  world coordinates */
    double noise;              /* noise used, world units */
    int noise_estimated;       /* 1 when noise was estimated from the data */
    double margin;             /* noise_factor * noise, world units */
    size_t cells;              /* 2x2 dexel blocks considered */
    size_t cells_missing;      /* blocks with fewer than 3 representatives */
    size_t cells_open;         /* blocks where the edge test rejected at least
                                  one triangle: discontinuities */
    size_t triangles_folded;   /* rejected as flipped or degenerate */
    size_t triangles_nonmanifold; /* removed so that every vertex's triangles
                                  form a single fan */
    int poles_closed;          /* range and grid: 360-degree scans whose
                                  first or last theta line is a small ring
                                  round the pole get it closed (0..2) */
    size_t triangles;          /* triangles emitted */
    double seconds;            /* wall-clock time of the whole call */
    double seconds_dexels;     /* of which bucketing and representatives */
} tessel_fixed_plane_stats;

/* Reconstructs a surface from a height field, a range scan or an organized
 * grid (params->mode) and sends the triangles to sink in batches, in
 * dexel-row order. Triangles index cloud's points (one representative per
 * dexel; other points are unused) and are counter-clockwise seen from the
 * +normal side of the plane (height: "up" for terrain) or from the
 * viewpoint (range, grid). The output is edge- and vertex-manifold and
 * consistently oriented. Grid mode needs an organized cloud (cloud->grid)
 * and fails with TESSEL_ERR_INVALID_ARG, logging why, on an unorganized
 * one; range mode needs a viewpoint. When more triangles face away from
 * the viewpoint (height: the plane's normal) than are made, a warning is
 * logged: the input is not what the mode assumes (a wrong viewpoint, a grid
 * that is not the camera's image, no height field), and the mesh may cross
 * itself. params and stats may be NULL; the cloud must have fewer than 2^32
 * points. */
TESSEL_API tessel_status tessel_reconstruct_fixed_plane(const tessel_cloud *cloud,
                                                        const tessel_fixed_plane_params *params,
                                                        const tessel_callbacks *callbacks,
                                                        const tessel_triangle_sink *sink,
                                                        tessel_fixed_plane_stats *stats);

/* The same into a mesh: its vertices are the cloud points used by a
 * triangle, in input order, with their normals and colours; the offset is
 * the cloud's, so world coordinates are unchanged. On error *mesh is
 * zeroed. */
TESSEL_API tessel_status tessel_reconstruct_fixed_plane_mesh(
    const tessel_cloud *cloud, const tessel_fixed_plane_params *params,
    const tessel_callbacks *callbacks, tessel_mesh *mesh, tessel_fixed_plane_stats *stats);

/* Denoising a scan from one position along its rays, before the range or
 * grid mode meshes it (src/fixed_plane/denoise.c): each point moves along
 * the line from the viewpoint onto a robust plane through its neighbours,
 * so a noisy scan comes out smooth and its depth steps stay steps. */
typedef struct tessel_ray_denoise_params {
    uint32_t k;          /* neighbours of each plane; 0 (default): enough to
                            cover about 3 noise sigmas, 16..64 */
    uint32_t passes;     /* each from the last one's positions; default 2
                            (1..10) */
    double noise;        /* noise sigma, world units; 0 (default): the
                            cloud's own estimate (tessel_cloud_noise) */
    double viewpoint[3]; /* world coordinates, used when use_viewpoint */
    int use_viewpoint;   /* 0 (default): the cloud's viewpoint, which it must
                            then have */
    int threads;         /* 0 = OpenMP default; the result does not depend on
                            it */
} tessel_ray_denoise_params;
TESSEL_API tessel_ray_denoise_params tessel_ray_denoise_params_default(void);

typedef struct tessel_ray_denoise_stats {
    double noise;        /* sigma used, world units */
    uint32_t k;          /* neighbours used */
    double rms_move;     /* RMS distance the points moved, world units */
} tessel_ray_denoise_stats;

/* Moves the points of cloud (in place) along their rays from the
 * viewpoint (params or the cloud's) onto planes fitted robustly to their
 * neighbours, by at most three noise sigmas. INVALID_ARG without a
 * viewpoint; TOO_FEW_POINTS under 16 points. stats may be NULL. */
TESSEL_API tessel_status tessel_denoise_along_rays(tessel_cloud *cloud,
                                                   const tessel_ray_denoise_params *params,
                                                   tessel_ray_denoise_stats *stats);

/* ------------------------------------------------------------------------ */
/* Noisy clouds: robust smoothing, clustering, reduction (src/smooth/,      */
/* src/smooth/cluster.c, src/smooth/simplify.c)                                            */
/* ------------------------------------------------------------------------ */

/* Mederos, Velho & de Figueiredo 2003, "Smooth surface reconstruction from
 * noisy clouds", steps 1-3 (sections 2.1-2.3). Pipeline:
 *   tessel_smooth()   noisy cloud -> smoothed cloud with normals
 *   tessel_cluster()  smoothed cloud -> BSP clusters
 *   tessel_representatives()  clusters -> one point per cluster
 * or tessel_simplify() for the last two in one call. See docs/smooth.md. */

/* The robust projection operator Q (section 2.1): a point p moves to
 * p + t n, where the plane through p + t n with unit normal n minimises
 *   sum over the neighbours q of rho(h_q) w(|q - p|),
 *   h_q = n.(q - p - t n), rho(x) = 1 - exp(-x^2 / (2 sigma_rho^2)),
 *   w(x) = exp(-x^2 / (2 sigma_w^2)),
 * found by iteratively reweighted least squares (weighted PCA for n,
 * weighted mean height for t) from the Gaussian-weighted PCA plane. Beyond
 * the paper (quadric = 1, the default): p is then lifted from the plane by
 * the height of a quadric fitted over it with the same weights. The
 * neighbours of p are its k nearest cloud points within 3 sigma_w (farther
 * ones would weigh less than 1.1%), p itself included when it is a cloud
 * point. */
typedef struct tessel_smooth_params {
    uint32_t k;               /* at most this many neighbours; default 30
                                 (3..256) */
    double sigma_rho;         /* scale of the robust error norm, multiple of
                                 the spacing h: heights beyond ~2 sigma_rho
                                 count as outliers; default 2 (> 0; the
                                 paper uses 1-2.5) */
    double sigma_w;           /* scale of the Gaussian distance weight,
                                 multiple of h; default 3 (> 0; the paper
                                 uses 1.5-3) */
    uint32_t passes;          /* smoothing passes, each on the previous
                                 pass's output (a pass after the first
                                 takes one IRLS step from the previous
                                 pass's normal); default 2 (1..100;
                                 ignored by projections) */
    uint32_t max_iterations;  /* IRLS iteration cap per point; default 20
                                 (1..1000) */
    double tolerance;         /* IRLS stops when the plane's offset moves
                                 less than tolerance*h and its normal turns
                                 less than tolerance radians; default 1e-2
                                 (> 0) */
    uint32_t min_neighbors;   /* a fit needs at least this many neighbours
                                 (the point itself included); with fewer
                                 the point stays put and is counted as
                                 unfit; default 6 (3..k) */
    double spacing;           /* h in world units; 0 (default) estimates it
                                 with tessel_cloud_spacing() */
    int threads;              /* 0 = OpenMP default (honours
                                 OMP_NUM_THREADS) */
    int quadric;              /* 1 (default): beyond the paper, Q(p) is
                                 lifted from the robust plane onto a
                                 weighted quadric height field fitted over
                                 it (less shrinkage on curved parts);
                                 0: the paper's plane; other values are
                                 invalid */
    double sigma_rho_later;   /* sigma_rho of the passes after the first,
                                 multiple of h: the first pass has removed
                                 most of the noise, so a tighter norm
                                 rejects more; default 1 (> 0). Those
                                 passes reuse the first pass's neighbours
                                 (at their new positions) */
    int aggregate;            /* 1: beyond the paper, after each pass a
                                 point moves to the weighted mean of its
                                 projections onto the surfaces fitted at
                                 its neighbours (within ~1.5 h) and at
                                 itself, and its normal to their mean
                                 normal: less of each point's own noise
                                 stays where the surface curves within a
                                 few h (thin parts; docs/smooth.md,
                                 section E), for about half again the
                                 time and 76 bytes per point. 0 (default):
                                 off; other values are invalid */
    int exclude_self;         /* 1: the point being moved, and any exact
                                 copy of it, is left out of its own fit
                                 (the paper's neighbourhood N(p) read as
                                 the points around p), so its own noise
                                 does not pull the fitted surface toward
                                 it. Helps where the noise is about a
                                 spacing or more and the surface is flat
                                 over the neighbourhood; costs where the
                                 noise is small or the surface curves
                                 within a few spacings, where the point
                                 itself pulls the fit back onto the
                                 surface (docs/smooth.md, section F).
                                 0 (default): it enters its fit with the
                                 largest weight; the noisy pipeline's
                                 cluster sizes are calibrated with 0.
                                 Projections of other points are the same
                                 either way; other values are invalid */
} tessel_smooth_params;
TESSEL_API tessel_smooth_params tessel_smooth_params_default(void);

typedef struct tessel_smooth_stats {
    double spacing;           /* h used, world units */
    size_t unfit;             /* points left in place because their fit had
                                 too few neighbours or a degenerate
                                 (collinear) neighbourhood, summed over
                                 passes */
    size_t unconverged;       /* fits that reached max_iterations, summed
                                 over passes (their last plane is used) */
    double mean_iterations;   /* IRLS iterations per fitted point, over all
                                 passes */
    double rms_displacement;  /* RMS distance from each input point to its
                                 output position, world units */
    double max_displacement;  /* largest such distance */
} tessel_smooth_stats;

/* Robust smoothing (section 2.1): writes to *out a new cloud with every
 * point moved to Q(p), computed from the previous pass's positions only, and
 * normals set to the fitted planes' normals n*. Sign of n*: agreeing with
 * the normal of the nearest cloud point when the cloud has normals, else
 * facing the cloud's viewpoint when it has one, else arbitrary (orient
 * them later if needed). Unfit points keep their position; their normal is
 * the smallest-eigenvalue direction of their neighbours' unweighted
 * covariance. Colours, offset, viewpoint and grid are copied. params and
 * stats may be NULL. Needs at least 3 points and a non-zero spacing
 * (TESSEL_ERR_TOO_FEW_POINTS) and finite coordinates (else
 * TESSEL_ERR_INVALID_ARG, also from the projector and clustering). On
 * error *out is zeroed. */
TESSEL_API tessel_status tessel_smooth(const tessel_cloud *cloud, tessel_cloud *out,
                                       const tessel_smooth_params *params,
                                       const tessel_callbacks *callbacks,
                                       tessel_smooth_stats *stats);

/* The operator Q over a fixed cloud, for projecting arbitrary points (the
 * representatives here, edge midpoints in refinement). Keeps a pointer to
 * cloud->xyz, which must outlive it unchanged. With params->spacing 0 the
 * spacing is estimated from the cloud. tessel_projector_spacing() returns
 * the h in use (world units). */
typedef struct tessel_projector tessel_projector;
TESSEL_API tessel_status tessel_projector_create(tessel_projector **projector,
                                                 const tessel_cloud *cloud,
                                                 const tessel_smooth_params *params);
TESSEL_API void tessel_projector_destroy(tessel_projector *projector);
TESSEL_API double tessel_projector_spacing(const tessel_projector *projector);

/* Projects q (local coordinates of the projector's cloud) to out = Q(q) and
 * writes the fitted unit normal to normal (may be NULL; sign as in
 * tessel_smooth). Returns TESSEL_OK, or TESSEL_ERR_TOO_FEW_POINTS when q has
 * no robust fit (out = q; normal from the plain covariance of its k nearest
 * points). *iterations (may be NULL) receives the IRLS iterations used, 0
 * when unfit. For a cloud point the result is bit for bit the one
 * tessel_smooth computes. Thread-safe; never allocates. */
TESSEL_API tessel_status tessel_project(const tessel_projector *projector, const float q[3],
                                        float out[3], float normal[3],
                                        uint32_t *iterations);

/* BSP clustering (section 2.2). A node (a set of points) is split in two
 * when it holds more than n_min points and its flatness
 * sigma = l1 / (l1 + l2 + l3) (covariance eigenvalues l1 <= l2 <= l3)
 * exceeds sigma_max; the points are then classified by the side of the
 * node's regression plane (through the centroid, spanned by the two
 * largest eigenvectors) they lie on, as in the paper. A node wider than
 * max_diameter is split too, whatever its size and flatness, by the plane
 * through its centroid across its largest eigenvector: this keeps clusters
 * local, so that flat regions do not become one huge cluster with one
 * representative, and stops regression-plane splits of curved caps from
 * leaving ring-shaped clusters whose centroid lies off the ring. Leaves are
 * the clusters. */
typedef struct tessel_cluster_params {
    double sigma_max;         /* flatness tolerance; default 0.01
                                 (0..1/3; 1/3 disables the flatness test) */
    uint32_t n_min;           /* nodes with at most this many points are not
                                 split for flatness; default 10 (>= 1) */
    double max_diameter;      /* multiple of the spacing h: every point of
                                 a cluster lies within max_diameter/2 of
                                 its centroid; default 8 (> 0; INFINITY
                                 disables) */
    double spacing;           /* h in world units; 0 (default) estimates it */
    int threads;              /* 0 = OpenMP default */
} tessel_cluster_params;
TESSEL_API tessel_cluster_params tessel_cluster_params_default(void);

/* Clusters of a cloud: every point is in exactly one cluster. Cluster c
 * holds the points order[offsets[c] .. offsets[c+1]), in increasing index
 * order; clusters are numbered in depth-first order of the BSP tree. */
typedef struct tessel_clusters {
    size_t point_count;       /* points clustered */
    size_t count;             /* number of clusters */
    uint32_t *labels;         /* point_count: cluster of each point */
    uint32_t *order;          /* point_count point indices grouped by cluster */
    size_t *offsets;          /* count + 1 entries; offsets[count] ==
                                 point_count */
    double spacing;           /* h used, world units */
} tessel_clusters;

/* Clusters the cloud (normally the output of tessel_smooth). params may be
 * NULL. On error *clusters is zeroed. */
TESSEL_API tessel_status tessel_cluster(const tessel_cloud *cloud,
                                        const tessel_cluster_params *params,
                                        const tessel_callbacks *callbacks,
                                        tessel_clusters *clusters);
/* Frees the arrays and zeroes the struct; NULL and zeroed structs are fine. */
TESSEL_API void tessel_clusters_free(tessel_clusters *clusters);

typedef struct tessel_simplify_params {
    tessel_cluster_params cluster;    /* defaults as above */
    tessel_smooth_params projection;  /* the operator Q projecting centroids
                                         (passes is ignored); defaults as
                                         above except k = 16 and
                                         sigma_w = 1.5, for an already
                                         smooth cloud */
    int keep_unfit;                   /* 1: a cluster whose centroid has no
                                         robust fit keeps its centroid as
                                         representative; 0 (default): it gets
                                         none (isolated outliers) */
} tessel_simplify_params;
TESSEL_API tessel_simplify_params tessel_simplify_params_default(void);

typedef struct tessel_simplify_stats {
    double spacing;           /* h used, world units */
    size_t clusters;          /* clusters found */
    size_t representatives;   /* points written */
    size_t unfit;             /* clusters whose centroid had no robust fit */
} tessel_simplify_stats;

/* Reduction (section 2.3): one representative per cluster, Q(c) for the
 * cluster's centroid c, projected onto `cloud` (the cloud that was
 * clustered). *out gets the representatives in cluster order, normals set
 * to the fitted planes' normals (sign as in tessel_smooth), colours (when
 * the cloud has them) the cluster's mean. params and stats may be NULL; a
 * spacing of 0 in params uses clusters->spacing. On error *out is zeroed. */
TESSEL_API tessel_status tessel_representatives(const tessel_cloud *cloud,
                                                const tessel_clusters *clusters,
                                                const tessel_simplify_params *params,
                                                const tessel_callbacks *callbacks,
                                                tessel_cloud *out,
                                                tessel_simplify_stats *stats);

/* tessel_cluster() then tessel_representatives() in one call (the spacing
 * is estimated once when both params leave it 0). */
TESSEL_API tessel_status tessel_simplify(const tessel_cloud *cloud, tessel_cloud *out,
                                         const tessel_simplify_params *params,
                                         const tessel_callbacks *callbacks,
                                         tessel_simplify_stats *stats);

/* ------------------------------------------------------------------------ */
/* Noisy clouds: advancing front and refinement (src/front/,      */
/* src/refine/)                                                             */
/* ------------------------------------------------------------------------ */

/* Steps 4 and 5 of Mederos, Velho & de Figueiredo 2003 (sections 2.4, 2.5)
 * and the whole pipeline. See docs/advancing_front.md. */

/* Advancing-front triangulation (section 2.4, Algorithms 1 and 2). From a
 * seed triangle, every border edge uv takes as third vertex the point q
 * among the k nearest neighbours of u and v with the largest angle uqv
 * among those that satisfy (i) the new triangle turns at most theta from
 * the triangle across uv, theta widening by eps2 up to 90 + eps2 degrees
 * until some point qualifies, (ii) the surface stays valid, (iii) both new
 * edges are shorter than eps1 * min(d_u, d_v), (iv) the angles at u and v
 * are below phi. d_x is the local spacing at x: the mean distance to its 4
 * nearest distinct neighbours (the paper uses the nearest one, which makes
 * (iii) reject everything around the close pairs representatives of
 * clusters form). An edge with no such point stays a border edge; when the
 * fronts stop, the narrow holes they left are closed (max_hole_radius). */
typedef struct tessel_front_params {
    uint32_t k;              /* neighbours of each end of an edge searched
                                for its third vertex; default 16 (3..64) */
    double theta_deg;        /* theta, degrees: initial half-width of the
                                dihedral band [180 - theta, 180 + theta];
                                default 30 (0..90) */
    double theta_step_deg;   /* eps2, degrees: theta grows by this; default
                                15 (> 0) */
    double max_edge_ratio;   /* eps1: new edges shorter than this times the
                                smaller local spacing d of the edge's ends;
                                default 3 (> 1) */
    double max_angle_deg;    /* phi, degrees: the new triangle's angles at
                                the edge's ends stay below this; default 140
                                (60..180) */
    double normal_angle_deg; /* a triangle reaching a new point stays within
                                this many degrees of the surface normal at
                                each of its vertices (the points' normals,
                                sign ignored, when given, else the normal of
                                the plane fitted to their k nearest
                                neighbours), oriented as the surface took
                                it: no fold-backs on noisy points (triangles
                                that only close border edges get 100);
                                default 60 (0..180; 180 disables) */
    double max_hole_radius;  /* when the fronts stop, a border loop is
                                closed if its area over half its perimeter
                                (the radius of a round hole, half the width
                                of a slit) is at most this many times the
                                mean local spacing d of its vertices (up to
                                twice that when points the front passed by
                                lie in it): holes the front left, not holes
                                of the sampled surface, which enclose empty
                                space, nor loops round a tube (a limb the
                                front did not cross), whose triangles stand
                                across them. Closing
                                tries the least-area and the least-bending
                                triangulations of the loop, then, if the
                                borders cross, the same after removing the
                                triangles along it, then ear clipping; every
                                triangle is checked like the front's.
                                Default 2.5 (>= 0; 0 disables) */
    int orient;              /* 1 (default): every closed component faces
                                outward (positive volume); open components
                                agree with the points' normals when they have
                                them, else face away from their centroid
                                (right for nearly closed surfaces, arbitrary
                                for flat ones). 0: as grown (still
                                consistent within each component). */
    size_t tile_points;      /* more points than this are cut into tiles of
                                at most this many (recursive median cuts),
                                whose fronts run in parallel; a front over
                                all points then closes the seams, starting
                                from the tiles' triangles less those within
                                half a mean spacing of a cut. The result depends
                                on this, not on the thread count. Default
                                65536 (0: one front; else >= 256) */
    int threads;             /* for the neighbour search and the tiles; 0 =
                                OpenMP default (honours OMP_NUM_THREADS).
                                The result does not depend on the thread
                                count. */
} tessel_front_params;
TESSEL_API tessel_front_params tessel_front_params_default(void);

typedef struct tessel_front_stats {
    size_t triangles;        /* triangles in the mesh */
    size_t seeds;            /* seed triangles (fronts started) */
    size_t bridges;          /* joins and splits of border loops */
    size_t hole_triangles;   /* triangles added by closing holes */
    size_t eroded_triangles; /* triangles removed around holes whose borders
                                crossed, before closing them */
    size_t border_edges;     /* edges with one triangle in the result */
    size_t unused_points;    /* points on no triangle (isolated points,
                                exact duplicates, points no front reached,
                                points left behind by the front as it passed
                                them slightly off the surface) */
    size_t flipped_components; /* components reversed by orient */
} tessel_front_stats;

/* Triangulates the points (normally the representatives of
 * tessel_simplify). The mesh's vertices are the points, in order (vertex i
 * is point i; normals, colours and offset copied), so points on no triangle
 * are unreferenced vertices. The result is manifold (every edge on one or
 * two triangles, every vertex on a single fan, after every step),
 * consistently oriented and free of self-intersections (decided with exact
 * predicates). Normals are not needed; when present they replace the fitted
 * normals of normal_angle_deg and choose the orientation of open
 * components. params and stats may be NULL. Needs 3 points
 * (TESSEL_ERR_TOO_FEW_POINTS); at most 2^29 (TESSEL_ERR_LIMIT). On error
 * *mesh is zeroed. */
TESSEL_API tessel_status tessel_advancing_front(const tessel_cloud *points,
                                                const tessel_front_params *params,
                                                const tessel_callbacks *callbacks,
                                                tessel_mesh *mesh,
                                                tessel_front_stats *stats);

/* Refinement (section 2.5). For every edge uv of the mesh (in each round),
 * with midpoint m and normal n_m the normalised sum of the vertex normals of
 * u and v (area-weighted normals of their stars), the offset
 * a = mean over the k nearest cloud points p of (p - m).n_m measures how far
 * the edge is from the cloud. When |a| > eps the edge is split at
 * Q(m + a n_m), the robust projection onto the cloud, and so are its one or
 * two triangles, unless one of them is too skinny. Then diagonals are
 * flipped wherever the other diagonal of the two triangles is shorter. Every
 * split and flip keeps the mesh manifold, oriented and free of
 * self-intersections (checked exactly; an operation that would break it is
 * skipped). */
typedef struct tessel_refine_params {
    uint32_t rounds;          /* refinement rounds; default 2 (the paper
                                 shows two; 0..20) */
    uint32_t k;               /* cloud neighbours of the midpoint for a;
                                 default 16 (1..256) */
    double min_offset;        /* eps, multiple of the cloud's spacing h:
                                 edges with |a| <= eps stay; default 0.1
                                 (>= 0) */
    double min_edge_length;   /* multiple of h: shorter edges are not split
                                 (below the sampling there is nothing to
                                 fit); default 1.5 (>= 0) */
    double min_edge_ratio;    /* a triangle whose shortest edge is below
                                 this fraction of its longest is not divided;
                                 default 0.2 (0..1) */
    int flip;                 /* 1 (default): flip diagonals after each
                                 round; 0: splits only */
    int threads;              /* 0 = OpenMP default (honours
                                 OMP_NUM_THREADS); the result does not depend
                                 on it */
} tessel_refine_params;
TESSEL_API tessel_refine_params tessel_refine_params_default(void);

typedef struct tessel_refine_stats {
    size_t splits;            /* edges split, all rounds */
    size_t flips;             /* diagonals flipped */
    size_t far_edges;         /* edges whose |a| exceeded eps */
    size_t skipped_skinny;    /* splits skipped for a too skinny triangle */
    size_t skipped_invalid;   /* splits or flips skipped because they would
                                 fold the mesh or make it self-intersect */
    size_t unfit;             /* splits skipped because Q had no fit there */
    size_t border_edges;      /* edges with one triangle in the result */
} tessel_refine_stats;

/* Refines mesh in place against cloud (normally the smoothed cloud, in the
 * same local frame: equal offsets). projector is Q over that cloud (from
 * tessel_projector_create); NULL makes one with default parameters. New
 * vertices are appended after the existing ones (normals, when the mesh has
 * them, set from the stars at the end for every vertex; colours averaged
 * from the edge's ends). params and stats may be NULL. The mesh must be
 * manifold and consistently oriented (as tessel_advancing_front makes it):
 * TESSEL_ERR_INVALID_ARG otherwise; TESSEL_ERR_LIMIT when the result would
 * pass 2^32 / 3 triangles. On error the mesh is left as it was. */
TESSEL_API tessel_status tessel_refine(tessel_mesh *mesh, const tessel_cloud *cloud,
                                       const tessel_projector *projector,
                                       const tessel_refine_params *params,
                                       const tessel_callbacks *callbacks,
                                       tessel_refine_stats *stats);

/* The whole pipeline (src/pipeline/): smooth -> cluster -> reduce
 * -> triangulate -> refine, for noisy clouds without normals. The spacing h
 * is estimated once (unless a stage's params give one) and used by every
 * stage. */
typedef struct tessel_smooth_recon_params {
    tessel_smooth_params smooth;     /* step 1 (its k, sigmas and iteration
                                        limits also define the projection
                                        operator of step 5); defaults as
                                        tessel_smooth_params_default() but
                                        passes 1, as in the paper */
    tessel_simplify_params simplify; /* steps 2-3 */
    tessel_front_params front;       /* step 4 */
    tessel_refine_params refine;     /* step 5 (rounds 0: the triangulation
                                        of the representatives as is) */
    int auto_cluster_size;           /* 1 (default): simplify.cluster
                                        .max_diameter is chosen from the
                                        noise the smoothing removed (RMS
                                        displacement r, in h): 11 r within
                                        [3, 8] h, so that representatives
                                        stay farther apart than the noise
                                        left can confuse, yet follow thin
                                        parts of clean clouds; 0: as given */
    double noise_ratio_max;          /* the noise is measured first
                                        (tessel_cloud_noise); when it is
                                        more than this many surface spacings,
                                        the cloud is thinned (a subsample by
                                        a hash of the point index) until it
                                        is this many: the stages work at the
                                        noise they are tuned for, in time
                                        linear in the points, and detail
                                        finer than the noise cannot be
                                        recovered anyway. Default 1.0; 0: no
                                        measurement, no thinning */
    double noise, noise_ratio;       /* the cloud's noise when it was
                                        measured already (tessel_cloud_noise's
                                        sigma and noise_ratio, or
                                        tessel_choose_method's noise and
                                        noise_ratio): used instead of measuring
                                        again when both are above 0. Default
                                        0: measured */
    int threads;                     /* every stage's thread count when not
                                        0; 0 (default) leaves each stage's */
} tessel_smooth_recon_params;
TESSEL_API tessel_smooth_recon_params tessel_smooth_recon_params_default(void);

typedef struct tessel_smooth_recon_stats {
    double spacing;                  /* h, world units */
    double cluster_diameter;         /* max_diameter used, multiple of h */
    size_t points;                   /* input points */
    double noise;                    /* measured noise, world units (0 when
                                        not measured) */
    double noise_ratio;              /* the same in surface spacings */
    size_t points_used;              /* points after thinning */
    int fitted;                      /* 1: the points were moved onto
                                        quadrics fitted to their neighbours
                                        in the whole cloud first (noise
                                        above one surface spacing) */
    size_t representatives;          /* points triangulated */
    size_t vertices, triangles;      /* in the result */
    size_t border_edges;             /* edges with one triangle */
    size_t reoriented;               /* triangles of the representatives'
                                        mesh turned outward: regions the
                                        front carried inside out across a
                                        place where two sheets touch
                                        (src/mesh/orient.c); only for clouds
                                        without normals or viewpoint */
    /* Wall-clock seconds per stage (as the paper's Table 1) and in all. */
    double seconds_noise, seconds_spacing, seconds_smooth, seconds_simplify, seconds_front,
        seconds_refine, seconds_total;
    tessel_smooth_stats smooth;
    tessel_simplify_stats simplify;
    tessel_front_stats front;
    tessel_refine_stats refine;
} tessel_smooth_recon_stats;

/* Reconstructs a surface from a noisy cloud. *mesh gets the refined mesh:
 * vertices are representatives and refinement points (not input points),
 * every one on a triangle, with unit normals from their stars (outward on
 * closed components; on open ones they follow the input's normals or
 * viewpoint when it has them) and mean colours when the cloud has them.
 * Manifold, consistently oriented, no self-intersection. params and stats
 * may be NULL. On error *mesh is zeroed. */
TESSEL_API tessel_status tessel_reconstruct_smooth(const tessel_cloud *cloud,
                                                   const tessel_smooth_recon_params *params,
                                                   const tessel_callbacks *callbacks,
                                                   tessel_mesh *mesh,
                                                   tessel_smooth_recon_stats *stats);

/* ------------------------------------------------------------------------ */
/* One entry point for every method (src/reconstruct/)                      */
/* ------------------------------------------------------------------------ */

typedef enum tessel_method {
    TESSEL_METHOD_AUTO = 0,    /* chosen from the cloud: tessel_choose_method */
    TESSEL_METHOD_GREEDY,      /* greedy projection: interpolates clean clouds */
    TESSEL_METHOD_SMOOTH,      /* the noisy-cloud pipeline: approximates */
    TESSEL_METHOD_FIXED_PLANE  /* height, range or grid mode (fixed.mode) */
} tessel_method;
TESSEL_API const char *tessel_method_name(tessel_method method);

typedef struct tessel_reconstruct_params {
    tessel_method method;               /* default AUTO */
    double clean_below;                 /* AUTO: noise below this many surface
                                           spacings (tessel_cloud_noise) is
                                           clean and goes to greedy
                                           projection, the rest to the
                                           smooth method; default 0.3 */
    tessel_greedy_params greedy;        /* defaults of each method */
    tessel_smooth_recon_params smooth;
    tessel_fixed_plane_params fixed;    /* mode: default RANGE (what AUTO picks
                                           for organized scans with a viewpoint) */
    int denoise;                        /* 1 (default): the range and grid
                                           modes mesh a noisy scan (noise of
                                           clean_below or more) denoised along
                                           its rays (tessel_denoise_along_rays,
                                           on a copy); 0: as it is */
    int threads;                        /* every method's when not 0 */
} tessel_reconstruct_params;
TESSEL_API tessel_reconstruct_params tessel_reconstruct_params_default(void);

/* Which method and why. */
typedef struct tessel_method_choice {
    tessel_method method;          /* never AUTO */
    tessel_fixed_plane_mode mode;  /* for FIXED_PLANE */
    const char *reason;            /* a static string */
    int measured;                  /* 1: the noise was measured */
    double noise, noise_ratio;     /* then: world units, surface spacings */
    double seconds;                /* spent measuring */
} tessel_method_choice;

/* The method tessel_reconstruct would run on cloud with params (NULL:
 * defaults): params->method when it is not AUTO; else the range mode for
 * an organized cloud with a viewpoint; else greedy projection when the
 * noise is below params->clean_below surface spacings (or cannot be
 * measured), the smooth method above. */
TESSEL_API tessel_status tessel_choose_method(const tessel_cloud *cloud,
                                              const tessel_reconstruct_params *params,
                                              tessel_method_choice *choice);

typedef struct tessel_reconstruct_summary {
    tessel_method_choice choice;
    size_t vertices, triangles;
    size_t boundary_edges;     /* greedy and smooth; 0 for the fixed plane */
    size_t components;         /* greedy; 0 otherwise */
    double seconds;            /* choice and reconstruction */
    tessel_recon_summary greedy;        /* the method's own figures */
    tessel_smooth_recon_stats smooth;
    tessel_fixed_plane_stats fixed;
    int denoised;                       /* 1: the scan was denoised first */
    tessel_ray_denoise_stats denoise;
} tessel_reconstruct_summary;

/* Reconstructs a mesh from cloud with the method params ask for or the one
 * tessel_choose_method picks (params NULL: AUTO). *mesh gets the result (as
 * the method's own _mesh call gives it); summary (may be NULL) says which
 * method ran and why, and its figures. On error *mesh is zeroed. */
TESSEL_API tessel_status tessel_reconstruct(const tessel_cloud *cloud,
                                            const tessel_reconstruct_params *params,
                                            const tessel_callbacks *callbacks, tessel_mesh *mesh,
                                            tessel_reconstruct_summary *summary);

#ifdef __cplusplus
}
#endif

#endif /* TESSEL_H */
