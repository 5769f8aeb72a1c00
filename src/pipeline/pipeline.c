/* The noisy-cloud pipeline of Mederos, Velho & de Figueiredo 2003, "Smooth
 * surface reconstruction from noisy clouds", section 2, in one call:
 * robust smoothing (2.1, smooth/), BSP clustering (2.2, smooth/cluster.c),
 * one representative per cluster (2.3, smooth/simplify.c), advancing-front
 * triangulation of the representatives (2.4, front/) and refinement
 * against the smoothed cloud (2.5, refine/).
 *
 * The spacing h is estimated once and handed to every stage, and the
 * projection operator Q of steps 3 and 5 is the smoothing's own. The
 * representatives' normals are passed to the triangulation only when their
 * sign means something (the input had normals or a viewpoint, which the
 * smoothing orients by); otherwise the triangulation fits its own and
 * closed components are turned outward by their volume. When the front
 * leaves small holes (where two parts of the surface come close, such as
 * the elephant's trunk curled against its face, the representatives are
 * too sparse for it to pass between them), or stray pieces (a thin part
 * cut off and closed at both ends), it runs again with extra
 * representatives around them: points of the smoothed cloud, projected by
 * Q, 0.4 to 0.7 mean edges apart; first anew, then from the mesh less its
 * triangles around the holes left (so the rest stays as it was); a result
 * is kept when it has fewer components, or fewer border edges and stray
 * pieces (see `defects`). Points no triangle uses are
 * dropped before refinement, and the result's normals are those of the
 * vertices' stars. Each stage is timed, as in the paper's Table 1. */
#include "front/front.h"
#include "pipeline/pipeline.h"
#include "smooth/smooth.h"

#include <stdlib.h>
#include <string.h>

/* Automatic cluster diameter (multiples of h): this many times the RMS
 * displacement of the smoothing (in h), within [MIN, MAX]. Measured on the
 * data sets of the project: clean Poisson-disk samples move by 0.1-0.3 h
 * (curvature) and triangulate best from clusters 3 h wide; samples with
 * noise of the order of h move by about 0.7 h and need 8 h. */
#define AUTO_DIAMETER_PER_NOISE 11.0
#define AUTO_DIAMETER_MIN 3.0
#define AUTO_DIAMETER_MAX 8.0
/* Attempts at the holes the front leaves: the spacing of the extra
 * representatives around a hole, as a fraction of its mean border edge,
 * and how far beyond its ball (in mean border edges) the front's triangles
 * are cleared for the front to go again (INFINITY: all of them, the front
 * runs anew). The first phase runs the whole front again while each
 * attempt improves on the last (a front on 10^5 representatives costs
 * about 0.2 s); the second clears around the holes left, until two
 * attempts in a row fail. Measured on the data sets of the project (noisy
 * bunny, elephant, man; the elephant with the front's seeds taken from
 * eight starting points). */
static const double global_repairs[][2] = {
    {0.7, INFINITY}, {0.5, INFINITY}, {0.6, INFINITY}, {0.4, INFINITY}};
static const double local_repairs[][2] = {{0.7, 1.0}, {0.7, 2.0}, {0.4, 4.0}, {0.5, 4.0},
                                          {0.6, 2.0}, {0.7, 4.0}, {0.5, 8.0}};
#define COUNT(a) (sizeof (a) / sizeof *(a))

tessel_smooth_recon_params tessel_smooth_recon_params_default(void)
{
    tessel_smooth_recon_params p;
    memset(&p, 0, sizeof p);
    p.smooth = tessel_smooth_params_default();
    /* One pass, as in the paper (section 4): every pass of the plane-fit
     * operator pulls curved surfaces inward by about sigma_w^2 / R. */
    p.smooth.passes = 1;
    p.simplify = tessel_simplify_params_default();
    p.front = tessel_front_params_default();
    p.refine = tessel_refine_params_default();
    p.auto_cluster_size = 1;
    p.noise_ratio_max = 1.0;
    p.threads = 0;
    return p;
}

/* The hash of a point index at or below which a fraction of the points
 * falls (all of them from 1 up). */
static uint64_t hash_limit(double fraction)
{
    return fraction < 1.0 ? (uint64_t)(fraction * 0x1.0p64) : UINT64_MAX;
}

/* The points of c whose index hashes at most hash_limit(keep) (a fraction), with their
 * normals and colours, into *out (no organized grid: it would have holes
 * everywhere); the viewpoint and the offset stay. */
static tessel_status thin_cloud(const tessel_cloud *c, double keep, tessel_cloud *out)
{
    uint64_t limit = hash_limit(keep);
    size_t n = 0;
    for (size_t i = 0; i < c->count; i++)
        n += tsl_mix64(i) <= limit;
    tessel_status st = tessel_cloud_alloc(out, n, c->normals != NULL, c->rgb != NULL);
    if (st)
        return st;
    memcpy(out->offset, c->offset, sizeof out->offset);
    memcpy(out->viewpoint, c->viewpoint, sizeof out->viewpoint);
    out->has_viewpoint = c->has_viewpoint;
    for (size_t i = 0, j = 0; i < c->count; i++) {
        if (tsl_mix64(i) > limit)
            continue;
        memcpy(out->xyz + 3 * j, c->xyz + 3 * i, 3 * sizeof *out->xyz);
        if (c->normals)
            memcpy(out->normals + 3 * j, c->normals + 3 * i, 3 * sizeof *out->normals);
        if (c->rgb)
            memcpy(out->rgb + 3 * j, c->rgb + 3 * i, 3);
        j++;
    }
    return TESSEL_OK;
}

/* The points of thinned (a hash subsample of cloud, whose noise is sigma,
 * ratio surface spacings) moved onto the surface that the whole cloud
 * gives: quadric height fields (tsl_height_fit, trimmed at 3 residual
 * sigmas) are fitted around centres about one sigma apart (the hash
 * subsample at a ratio of 1), each to its k nearest points of cloud, and
 * every thinned point moves by the offsets of the quadrics of its BLEND
 * nearest centres, weighted by exp(-(tangent distance / sigma)^2) so that
 * neighbouring patches join without steps. The points thinning drops
 * still average the noise away, by about sqrt(k / 6), instead of being
 * lost. k = FIT_SPAN ratio^2, the points of a disc of radius 1.7 sigmas
 * (FIT_SPAN = pi 1.7^2): wide enough for a tangent frame above the noise,
 * narrow enough for thin parts (the elephant at noise 1% of the diagonal,
 * 10^5 points: F-score 97.1 with discs of 2.3 sigmas, 97.9 with 1.7, one
 * fit per point). Above FIT_POINTS the neighbours come from a hash
 * subsample of the cloud, so the time is linear in the centres; below
 * FIT_MIN (a ratio of 1.9) a quadric would follow the noise: the points
 * stay, *fitted 0. Each point reads shared data and writes itself only:
 * the same cloud for any thread count. */
#define FIT_SPAN 9.0
#define FIT_POINTS 256.0
#define FIT_MIN 32.0
#define FIT_THIN 2.0
#define BLEND 4
#define FIT_MOVE_MAX 8.0

/* The points of cloud whose index hashes at most limit (all for
 * UINT64_MAX), their coordinates into a new array of *m. */
static float *hash_subset(const tessel_cloud *cloud, uint64_t limit, size_t *m)
{
    size_t n = 0;
    for (size_t i = 0; i < cloud->count; i++)
        n += tsl_mix64(i) <= limit;
    float *xyz = tsl_alloc_array(n ? n : 1, 3 * sizeof *xyz);
    if (xyz)
        for (size_t i = 0, j = 0; i < cloud->count; i++)
            if (tsl_mix64(i) <= limit)
                memcpy(xyz + 3 * j++, cloud->xyz + 3 * i, 3 * sizeof *xyz);
    *m = n;
    return xyz;
}

static tessel_status fit_thinned(const tessel_cloud *cloud, double sigma, double ratio,
                                 tessel_cloud *thinned, int threads, int *fitted)
{
    *fitted = 0;
    double inv_s2 = 1.0 / (sigma * sigma), span = FIT_SPAN * ratio * ratio;
    if (!(inv_s2 < INFINITY) || span < FIT_MIN)
        return TESSEL_OK;
    size_t k_fit = span < FIT_POINTS ? (size_t)span : (size_t)FIT_POINTS, m = 0, nc = 0;
    int nt = tsl_threads(threads);
    float *xyz = hash_subset(cloud, hash_limit(FIT_POINTS / span), &m);
    float *cxyz = hash_subset(cloud, hash_limit(1.0 / (ratio * ratio)), &nc);
    tsl_height *fit = tsl_alloc_array(nc ? nc : 1, sizeof *fit);
    uint32_t *order = tsl_alloc_array(nc ? nc : 1, sizeof *order);
    uint32_t *idx = tsl_alloc_array((size_t)nt * k_fit, sizeof *idx);
    float *dist = tsl_alloc_array((size_t)nt * k_fit, sizeof *dist);
    double *work = tsl_alloc_array((size_t)nt * k_fit, 4 * sizeof *work);
    tessel_index *ix = NULL, *cx = NULL;
    tessel_status st = TESSEL_OK;
    if (!xyz || !cxyz || !fit || !order || !idx || !dist || !work)
        st = TESSEL_ERR_NOMEM;
    if (!st && m >= k_fit && nc && !(st = tessel_index_build(&ix, xyz, m)) &&
        !(st = tessel_index_build(&cx, cxyz, nc))) {
        /* The centres in the order of their tree, which is near in space:
         * consecutive queries then read the same part of the cloud's tree
         * (in the cloud's order, a random one for a uniform sample, each
         * query waited on memory). Each fit goes to its centre's slot. */
        tsl_index_order(cx, order);
#pragma omp parallel num_threads(nt)
        {
            int t = omp_get_thread_num();
            uint32_t *id = idx + (size_t)t * k_fit;
            float *d2 = dist + (size_t)t * k_fit;
            double *wk = work + (size_t)t * 4 * k_fit;
#pragma omp for schedule(dynamic, 64)
            for (size_t j = 0; j < nc; j++) {
                size_t c = order[j];
                const float *q = cxyz + 3 * c;
                size_t k = tessel_index_knn(ix, q, k_fit, id, d2);
                if (k < k_fit || !tsl_height_fit(xyz, q, id, k, (double)d2[k - 1], wk, &fit[c]))
                    fit[c].inliers = 0; /* no fit here */
            }
#pragma omp for schedule(dynamic, 256)
            for (size_t i = 0; i < thinned->count; i++) {
                float *q = thinned->xyz + 3 * i;
                uint32_t c[BLEND];
                size_t nb = tessel_index_knn(cx, q, BLEND, c, NULL);
                double w_sum = 0.0, move[3] = {0.0, 0.0, 0.0};
                for (size_t j = 0; j < nb; j++) {
                    const tsl_height *h = &fit[c[j]];
                    if (!h->inliers)
                        continue;
                    const float *o = cxyz + 3 * (size_t)c[j];
                    double d[3] = {(double)q[0] - o[0], (double)q[1] - o[1], (double)q[2] - o[2]};
                    double along = tsl_dot(d, h->normal);
                    double w = exp(-(tsl_dot(d, d) - along * along) * inv_s2);
                    double off = tsl_height_offset(h, d);
                    for (int a = 0; a < 3; a++)
                        move[a] += w * off * h->normal[a];
                    w_sum += w;
                }
                /* A point the quadrics would carry beyond FIT_MOVE_MAX sigmas
                 * is not where they hold (an edge, a degenerate fit): it
                 * stays. */
                if (!(w_sum > 0.0) || tsl_dot(move, move) > FIT_MOVE_MAX * FIT_MOVE_MAX *
                                                                 w_sum * w_sum * sigma * sigma)
                    continue;
                float moved[3];
                for (int a = 0; a < 3; a++)
                    moved[a] = (float)(q[a] + move[a] / w_sum);
                memcpy(q, moved, sizeof moved);
            }
        }
        *fitted = 1;
    }
    tessel_index_destroy(cx);
    tessel_index_destroy(ix);
    free(work);
    free(dist);
    free(idx);
    free(fit);
    free(order);
    free(cxyz);
    free(xyz);
    return st;
}

/* The noise measured (s->noise, s->noise_ratio) and, above
 * params->noise_ratio_max surface spacings, the thinned cloud in *thinned
 * (*use points to it, else to cloud). */
static tessel_status measure_noise(const tessel_cloud *cloud, const tessel_smooth_recon_params *p,
                                   tessel_smooth_recon_stats *s, tessel_cloud *thinned,
                                   const tessel_cloud **use)
{
    *use = cloud;
    s->points_used = cloud->count;
    if (!(p->noise_ratio_max > 0.0))
        return TESSEL_OK;
    double t0 = tsl_seconds();
    tessel_noise_estimate e = {.sigma = p->noise, .noise_ratio = p->noise_ratio};
    tessel_status st = TESSEL_OK;
    if (!(p->noise > 0.0 && p->noise_ratio > 0.0))
        st = tessel_cloud_noise(cloud, p->threads ? p->threads : p->smooth.threads, &e);
    if (st == TESSEL_ERR_TOO_FEW_POINTS)
        return TESSEL_OK; /* too small to say: the stages decide */
    if (st)
        return st;
    s->noise = e.sigma;
    s->noise_ratio = e.noise_ratio;
    if (e.noise_ratio > p->noise_ratio_max) {
        /* Density scales with the kept fraction, the spacing with its root.
         * Points that will be fitted may stay up to FIT_THIN times denser
         * (finer detail where the noise is high), but at most 1 / FIT_THIN^2
         * of them (the stages' time: where the noise is low, one spacing of
         * it is detail enough). */
        double target = p->noise_ratio_max;
        if (FIT_SPAN * e.noise_ratio * e.noise_ratio >= FIT_MIN)
            target = fmin(FIT_THIN * target, fmax(target, e.noise_ratio / FIT_THIN));
        double keep = target / e.noise_ratio;
        if ((st = thin_cloud(cloud, keep * keep, thinned)) ||
            (st = fit_thinned(cloud, e.sigma, e.noise_ratio, thinned,
                              p->threads ? p->threads : p->smooth.threads, &s->fitted)))
            return st;
        *use = thinned;
        s->points_used = thinned->count;
    }
    s->seconds_noise = tsl_seconds() - t0;
    return TESSEL_OK;
}

/* Drops vertices no triangle uses (keeping order). */
static tessel_status compact(tessel_mesh *m)
{
    uint32_t *map = tsl_alloc_array(m->vertex_count ? m->vertex_count : 1, sizeof *map);
    if (!map)
        return TESSEL_ERR_NOMEM;
    for (size_t v = 0; v < m->vertex_count; v++)
        map[v] = TESSEL_NONE;
    for (size_t i = 0; i < 3 * m->triangle_count; i++)
        map[m->triangles[i]] = 0;
    size_t n = 0;
    for (size_t v = 0; v < m->vertex_count; v++) {
        if (map[v] == TESSEL_NONE)
            continue;
        map[v] = (uint32_t)n;
        memmove(m->xyz + 3 * n, m->xyz + 3 * v, 3 * sizeof *m->xyz);
        if (m->normals)
            memmove(m->normals + 3 * n, m->normals + 3 * v, 3 * sizeof *m->normals);
        if (m->rgb)
            memmove(m->rgb + 3 * n, m->rgb + 3 * v, 3);
        n++;
    }
    for (size_t i = 0; i < 3 * m->triangle_count; i++)
        m->triangles[i] = map[m->triangles[i]];
    m->vertex_count = n;
    free(map);
    return TESSEL_OK;
}

/* Unit vertex normals from the area-weighted normals of their stars. */
static tessel_status star_normals(tessel_mesh *m)
{
    if (!m->normals) {
        m->normals = tsl_alloc_array(3 * (m->vertex_count ? m->vertex_count : 1),
                                     sizeof *m->normals);
        if (!m->normals)
            return TESSEL_ERR_NOMEM;
    }
    double *acc = tsl_calloc_array(3 * (m->vertex_count ? m->vertex_count : 1), sizeof *acc);
    if (!acc)
        return TESSEL_ERR_NOMEM;
    for (size_t t = 0; t < m->triangle_count; t++) {
        const uint32_t *v = m->triangles + 3 * t;
        double a[3], b[3], c[3], u[3], w[3], n[3];
        tsl_load(m->xyz + 3 * (size_t)v[0], a);
        tsl_load(m->xyz + 3 * (size_t)v[1], b);
        tsl_load(m->xyz + 3 * (size_t)v[2], c);
        tsl_sub(b, a, u);
        tsl_sub(c, a, w);
        tsl_cross(u, w, n);
        for (int i = 0; i < 3; i++)
            for (int k = 0; k < 3; k++)
                acc[3 * (size_t)v[i] + k] += n[k];
    }
    for (size_t v = 0; v < m->vertex_count; v++) {
        double *n = acc + 3 * v;
        if (!tsl_normalize(n)) {
            n[0] = n[1] = 0.0;
            n[2] = 1.0;
        }
        for (int k = 0; k < 3; k++)
            m->normals[3 * v + k] = (float)n[k];
    }
    free(acc);
    return TESSEL_OK;
}

/* ------------------------------------------------------------------------ */
/* Denser representatives where the front left holes                       */
/* ------------------------------------------------------------------------ */

/* Border components (edge-connected border edges) of at most this many
 * edges get extra representatives; longer ones are borders of the sampled
 * surface. */
#define HOLE_MAX_EDGES 128
/* A component with at most this fraction of the mesh's triangles is a
 * stray piece (a thin part the front cut off and closed on both sides,
 * the elephant's curled trunk tip): it gets extra representatives like a
 * hole, and counts as STRAY_WEIGHT border edges when attempts are
 * compared. Only when there are at most STRAY_MAX of them: a scene of many
 * small pieces (a room scan) is what was sampled. */
#define STRAY_FRACTION 0.01
#define STRAY_WEIGHT 16
#define STRAY_MAX 8

/* The triangles' components (by shared vertices): comp[v] is the root
 * vertex of v's component (for vertices on a triangle) and tris[root] its
 * triangle count. */
static tessel_status components(const tessel_mesh *m, uint32_t **comp, size_t **tris)
{
    size_t nv = m->vertex_count, nt = m->triangle_count;
    uint32_t *parent = tsl_alloc_array(nv + 1, sizeof *parent);
    size_t *count = tsl_calloc_array(nv + 1, sizeof *count);
    if (!parent || !count) {
        free(parent);
        free(count);
        return TESSEL_ERR_NOMEM;
    }
    tsl_vertex_components(m->triangles, nt, nv, 1, parent);
    for (size_t t = 0; t < nt; t++)
        count[parent[m->triangles[3 * t]]]++;
    *comp = parent;
    *tris = count;
    return TESSEL_OK;
}

/* Whether a component of `count` triangles is small enough to be a stray
 * piece of a mesh of nt triangles. */
static bool is_stray(size_t count, size_t nt)
{
    return count && (double)count <= STRAY_FRACTION * (double)nt;
}

tessel_status tsl_stray_pieces(const tessel_mesh *m, size_t *strays, size_t *pieces)
{
    uint32_t *comp;
    size_t *tris, n = 0, all = 0;
    tessel_status st = components(m, &comp, &tris);
    if (st)
        return st;
    for (size_t v = 0; v < m->vertex_count; v++) {
        n += is_stray(tris[v], m->triangle_count);
        all += tris[v] > 0;
    }
    *strays = n <= STRAY_MAX ? n : 0;
    if (pieces)
        *pieces = all - *strays;
    free(comp);
    free(tris);
    return TESSEL_OK;
}

/* What the repairs try to bring down: first the components that are not
 * stray pieces (a front that cuts a thin part in two closes both ends, and
 * leaves no border edge to show it), then the border edges and
 * STRAY_WEIGHT for each stray piece. */
typedef struct defects {
    size_t count, pieces;
} defects;

/* Whether d is better than e (see defects). The components count only
 * while there are few (at most STRAY_MAX): in a scene of many pieces (a
 * room scan) an attempt that joins some of them is no better for that. */
static bool better(const defects *d, const defects *e)
{
    if (d->pieces <= STRAY_MAX && e->pieces <= STRAY_MAX && d->pieces != e->pieces)
        return d->pieces < e->pieces;
    return d->count < e->count;
}

static tessel_status defects_of(const tessel_mesh *m, const tessel_front_stats *fs, defects *d)
{
    size_t strays;
    tessel_status st = tsl_stray_pieces(m, &strays, &d->pieces);
    d->count = fs->border_edges + STRAY_WEIGHT * strays;
    return st;
}

/* Sets clear[] for the representatives of index ix within radius of q. */
static tessel_status mark_clear(const tessel_index *ix, const float q[3], double radius,
                                uint8_t *clear)
{
    size_t found = tessel_index_radius(ix, q, (float)radius, NULL, NULL, 0);
    uint32_t *ids = tsl_alloc_array(found + 1, sizeof *ids);
    if (!ids)
        return TESSEL_ERR_NOMEM;
    found = tessel_index_radius(ix, q, (float)radius, ids, NULL, found);
    for (size_t i = 0; i < found; i++)
        clear[ids[i]] = 1;
    free(ids);
    return TESSEL_OK;
}

/* A place the front goes again: a ball and the mean edge there. */
typedef struct site {
    double c[3], reach, mean;
} site;

typedef struct site_list {
    site *s;
    size_t n, cap;
} site_list;

static tessel_status site_add(site_list *l, const double c[3], double reach, double mean)
{
    if (tsl_grow((void **)&l->s, &l->cap, l->n + 1, sizeof *l->s))
        return TESSEL_ERR_NOMEM;
    site *x = &l->s[l->n++];
    memcpy(x->c, c, sizeof x->c);
    x->reach = reach;
    x->mean = mean;
    return TESSEL_OK;
}

/* The small holes of m: its border components (edge-connected border
 * edges) of at most HOLE_MAX_EDGES edges, each as the ball round its
 * vertices' centroid through the farthest. */
static tessel_status hole_sites(const tessel_mesh *m, site_list *out)
{
    size_t nt = m->triangle_count, nv = m->vertex_count;
    uint64_t *keys = tsl_alloc_array(3 * nt + 1, sizeof *keys);
    uint32_t *parent = tsl_alloc_array(nv + 1, sizeof *parent);
    uint32_t *bnext = tsl_alloc_array(nv + 1, sizeof *bnext);
    size_t *edges = tsl_calloc_array(nv + 1, sizeof *edges);
    double *len = tsl_calloc_array(nv + 1, sizeof *len);
    double *reach = tsl_calloc_array(nv + 1, sizeof *reach);
    double *cen = tsl_calloc_array(3 * (nv + 1), sizeof *cen);
    tessel_status st = TESSEL_ERR_NOMEM;
    if (!keys || !parent || !bnext || !edges || !len || !reach || !cen)
        goto done;
    for (size_t t = 0; t < nt; t++)
        for (int i = 0; i < 3; i++)
            keys[3 * t + i] = (uint64_t)m->triangles[3 * t + i] << 32 |
                              m->triangles[3 * t + (i + 1) % 3];
    qsort(keys, 3 * nt, sizeof *keys, tsl_cmp_u64);
    for (size_t v = 0; v < nv; v++) {
        parent[v] = (uint32_t)v;
        bnext[v] = TESSEL_NONE;
    }
    for (size_t e = 0; e < 3 * nt; e++) {
        uint32_t a = (uint32_t)(keys[e] >> 32), b = (uint32_t)keys[e];
        uint64_t twin = (uint64_t)b << 32 | a;
        if (bsearch(&twin, keys, 3 * nt, sizeof *keys, tsl_cmp_u64))
            continue;
        bnext[a] = b;
        uint32_t ra = tsl_uf_find(parent, a), rb = tsl_uf_find(parent, b);
        if (ra != rb)
            parent[ra] = rb;
    }
    for (size_t v = 0; v < nv; v++) {
        if (bnext[v] == TESSEL_NONE)
            continue;
        uint32_t r = tsl_uf_find(parent, (uint32_t)v);
        double a[3], b[3], d[3];
        tsl_load(m->xyz + 3 * v, a);
        tsl_load(m->xyz + 3 * (size_t)bnext[v], b);
        tsl_sub(b, a, d);
        edges[r]++;
        len[r] += tsl_norm(d);
        for (int k = 0; k < 3; k++)
            cen[3 * (size_t)r + k] += a[k];
    }
    for (size_t v = 0; v < nv; v++)
        for (int k = 0; k < 3 && edges[v]; k++)
            cen[3 * v + k] /= (double)edges[v];
    for (size_t v = 0; v < nv; v++) {
        if (bnext[v] == TESSEL_NONE)
            continue;
        uint32_t r = tsl_uf_find(parent, (uint32_t)v);
        double a[3], d[3];
        tsl_load(m->xyz + 3 * v, a);
        tsl_sub(a, cen + 3 * (size_t)r, d);
        double l = tsl_norm(d);
        reach[r] = l > reach[r] ? l : reach[r];
    }
    st = TESSEL_OK;
    for (size_t r = 0; r < nv && !st; r++)
        if (edges[r] && edges[r] <= HOLE_MAX_EDGES)
            st = site_add(out, cen + 3 * r, reach[r], len[r] / (double)edges[r]);
done:
    free(keys);
    free(parent);
    free(bnext);
    free(edges);
    free(len);
    free(reach);
    free(cen);
    return st;
}

/* The stray pieces of m (see STRAY_FRACTION), each as the ball round its
 * vertices' centroid through the farthest. */
static tessel_status stray_sites(const tessel_mesh *m, site_list *out)
{
    size_t nv = m->vertex_count, nt = m->triangle_count, strays;
    tessel_status st = tsl_stray_pieces(m, &strays, NULL);
    if (st || !strays)
        return st;
    uint32_t *comp;
    size_t *tris;
    if ((st = components(m, &comp, &tris)))
        return st;
    double *cen = tsl_calloc_array(3 * (nv + 1), sizeof *cen);
    double *reach = tsl_calloc_array(nv + 1, sizeof *reach);
    double *len = tsl_calloc_array(nv + 1, sizeof *len);
    size_t *verts = tsl_calloc_array(nv + 1, sizeof *verts);
    uint8_t *on = tsl_calloc_array(nv + 1, sizeof *on);
    st = TESSEL_ERR_NOMEM;
    if (!cen || !reach || !len || !verts || !on)
        goto done;
    for (size_t t = 0; t < nt; t++) {
        const uint32_t *c = m->triangles + 3 * t;
        uint32_t r = comp[c[0]];
        if (!is_stray(tris[r], nt))
            continue;
        for (int i = 0; i < 3; i++) {
            double a[3], b[3], d[3];
            tsl_load(m->xyz + 3 * (size_t)c[i], a);
            tsl_load(m->xyz + 3 * (size_t)c[(i + 1) % 3], b);
            tsl_sub(b, a, d);
            len[r] += tsl_norm(d);
            on[c[i]] = 1;
        }
    }
    for (size_t v = 0; v < nv; v++)
        if (on[v]) {
            verts[comp[v]]++;
            for (int k = 0; k < 3; k++)
                cen[3 * (size_t)comp[v] + k] += m->xyz[3 * v + k];
        }
    for (size_t v = 0; v < nv; v++)
        for (int k = 0; k < 3 && verts[v]; k++)
            cen[3 * v + k] /= (double)verts[v];
    for (size_t v = 0; v < nv; v++)
        if (on[v]) {
            double a[3], d[3];
            tsl_load(m->xyz + 3 * v, a);
            tsl_sub(a, cen + 3 * (size_t)comp[v], d);
            double l = tsl_norm(d);
            reach[comp[v]] = l > reach[comp[v]] ? l : reach[comp[v]];
        }
    st = TESSEL_OK;
    for (size_t r = 0; r < nv && !st; r++)
        if (verts[r])
            st = site_add(out, cen + 3 * r, reach[r], len[r] / (3.0 * (double)tris[r]));
done:
    free(comp);
    free(tris);
    free(cen);
    free(reach);
    free(len);
    free(verts);
    free(on);
    return st;
}

/* The points densify_holes adds around one site. */
typedef struct site_extra {
    float *xyz, *nrm; /* 3 floats per point */
    size_t n, cap_xyz, cap_nrm;
} site_extra;

/* The points of the smoothed cloud (kd-tree cix) within a mean edge of
 * site x's ball, projected by Q, each at least fraction times the site's
 * mean edge from every representative (kd-tree rix; normals rnormals,
 * which orient the new normals, or NULL) and from the points added
 * before it, into *out. */
static tessel_status site_points(const site *x, const tessel_index *cix, const tessel_index *rix,
                                 const float *smoothed, const tessel_projector *projector,
                                 const float *rnormals, double fraction, site_extra *out)
{
    double radius = x->reach + x->mean, gap2 = (fraction * x->mean) * (fraction * x->mean);
    float q[3] = {(float)x->c[0], (float)x->c[1], (float)x->c[2]};
    size_t found = tessel_index_radius(cix, q, (float)radius, NULL, NULL, 0);
    uint32_t *near = tsl_alloc_array(found + 1, sizeof *near);
    if (!near)
        return TESSEL_ERR_NOMEM;
    found = tessel_index_radius(cix, q, (float)radius, near, NULL, found);
    tessel_status st = TESSEL_OK;
    for (size_t i = 0; i < found && !st; i++) {
        const float *p = smoothed + 3 * (size_t)near[i];
        uint32_t j;
        float d2;
        if (tessel_index_knn(rix, p, 1, &j, &d2) == 1 && (double)d2 < gap2)
            continue;
        bool close = false;
        for (size_t e = 0; e < out->n && !close; e++) {
            double dx = out->xyz[3 * e] - p[0], dy = out->xyz[3 * e + 1] - p[1],
                   dz = out->xyz[3 * e + 2] - p[2];
            close = dx * dx + dy * dy + dz * dz < gap2;
        }
        if (close)
            continue;
        float at[3], nrm[3];
        if (tessel_project(projector, p, at, nrm, NULL) != TESSEL_OK)
            continue;
        if ((st = tsl_grow((void **)&out->xyz, &out->cap_xyz, out->n + 1, 3 * sizeof *out->xyz)) ||
            (st = tsl_grow((void **)&out->nrm, &out->cap_nrm, out->n + 1, 3 * sizeof *out->nrm)))
            break;
        /* Oriented like the nearest representative's normal when the
         * representatives have oriented normals. */
        if (rnormals && tessel_index_knn(rix, at, 1, &j, &d2) == 1) {
            const float *rn = rnormals + 3 * (size_t)j;
            if (rn[0] * nrm[0] + rn[1] * nrm[1] + rn[2] * nrm[2] < 0.0f)
                for (int k = 0; k < 3; k++)
                    nrm[k] = -nrm[k];
        }
        memcpy(out->xyz + 3 * out->n, at, sizeof at);
        memcpy(out->nrm + 3 * out->n, nrm, sizeof nrm);
        out->n++;
    }
    free(near);
    return st;
}

/* Adds to reps points of the smoothed cloud around the small holes and the
 * stray pieces of mesh (hole_sites, stray_sites; site_points, the sites in
 * parallel, the points in site order whatever the thread count).
 * reps->normals or else *lines grow with them. *added tells how many;
 * clear[v] (when clear is not NULL) is set for the representatives within
 * `clearing` mean edges of the ball of each site. */
static tessel_status densify_holes(const tessel_mesh *m, const tessel_cloud *smoothed,
                                   const tessel_projector *projector, double fraction,
                                   double clearing, int threads, tessel_cloud *reps,
                                   float **lines, uint8_t *clear, size_t *added)
{
    *added = 0;
    site_list sites = {NULL, 0, 0};
    site_extra *ex = NULL;
    /* The smoothed cloud's kd-tree is the projector's (made over it). */
    const tessel_index *cix = tsl_projector_index(projector, smoothed->xyz, smoothed->count);
    tessel_index *rix = NULL;
    tessel_status st = TESSEL_ERR_INVALID_ARG;
    if (!cix || (st = hole_sites(m, &sites)) || (st = stray_sites(m, &sites)) || !sites.n ||
        (st = tessel_index_build(&rix, reps->xyz, reps->count)))
        goto done;
    if (!(ex = tsl_calloc_array(sites.n, sizeof *ex))) {
        st = TESSEL_ERR_NOMEM;
        goto done;
    }
    long long count = (long long)sites.n;
    int failed = 0;
#pragma omp parallel for schedule(dynamic, 1) num_threads(tsl_threads(threads)) \
    reduction(| : failed)
    for (long long x = 0; x < count; x++)
        failed |= site_points(&sites.s[x], cix, rix, smoothed->xyz, projector, reps->normals,
                              fraction, &ex[x]) != TESSEL_OK;
    if (failed) {
        st = TESSEL_ERR_NOMEM; /* site_points' only failure */
        goto done;
    }
    size_t n_extra = 0;
    for (size_t x = 0; x < sites.n && !st; x++) {
        n_extra += ex[x].n;
        const double *c = sites.s[x].c;
        float q[3] = {(float)c[0], (float)c[1], (float)c[2]};
        if (clear)
            st = mark_clear(rix, q, sites.s[x].reach + clearing * sites.s[x].mean, clear);
    }
    if (st || !n_extra)
        goto done;
    size_t was = 3 * reps->count * sizeof(float), now = was + 3 * n_extra * sizeof(float);
    float **nn = reps->normals ? &reps->normals : *lines ? lines : NULL;
    if ((st = tsl_resize((void **)&reps->xyz, was, now)) ||
        (nn && (st = tsl_resize((void **)nn, was, now))))
        goto done;
    for (size_t x = 0, at = reps->count; x < sites.n; at += ex[x].n, x++) {
        if (!ex[x].n)
            continue; /* its arrays are NULL, which memcpy may not take */
        memcpy(reps->xyz + 3 * at, ex[x].xyz, 3 * ex[x].n * sizeof *reps->xyz);
        if (nn)
            memcpy(*nn + 3 * at, ex[x].nrm, 3 * ex[x].n * sizeof **nn);
    }
    reps->count += n_extra;
    *added = n_extra;
done:
    for (size_t x = 0; ex && x < sites.n; x++) {
        free(ex[x].xyz);
        free(ex[x].nrm);
    }
    free(ex);
    free(sites.s);
    tessel_index_destroy(rix);
    return st;
}

/* The small holes and stray pieces of the front's mesh (over reps) again,
 * for each (fraction, clearing) of repairs[0 .. count) in turn until none
 * is left or max_failed attempts in a row fail: extra representatives
 * around them and the front from the mesh less its triangles there. An
 * attempt that leaves fewer components other than stray pieces, or as
 * many and fewer defects (border edges, STRAY_WEIGHT for a stray piece),
 * replaces *mesh and keeps its extra representatives in
 * reps; the next starts from it. */
static tessel_status repair_holes(const double (*repairs)[2], size_t count, int max_failed,
                                  tessel_mesh *mesh, const tessel_cloud *smoothed,
                                  const tessel_projector *projector,
                                  const tessel_front_params *front,
                                  const tessel_callbacks *callbacks, tessel_cloud *reps,
                                  float **lines, tessel_front_stats *stats)
{
    uint8_t *clear = NULL;
    uint32_t *start = NULL;
    int failed = 0;
    defects have;
    tessel_status st = defects_of(mesh, stats, &have);
    for (size_t f = 0; f < count && have.count && !st && failed < max_failed; f++) {
        size_t base = reps->count, nt = mesh->triangle_count, added = 0;
        free(clear);
        free(start);
        clear = tsl_calloc_array(base, sizeof *clear);
        start = tsl_alloc_array(3 * nt + 1, sizeof *start);
        if (!clear || !start) {
            st = TESSEL_ERR_NOMEM;
            break;
        }
        bool all = isinf(repairs[f][1]);
        if ((st = densify_holes(mesh, smoothed, projector, repairs[f][0], repairs[f][1],
                                front->threads, reps, lines, all ? NULL : clear, &added)) ||
            !added)
            continue;
        size_t kept = 0;
        for (size_t t = 0; t < nt && !all; t++) {
            const uint32_t *v = mesh->triangles + 3 * t;
            if (clear[v[0]] || clear[v[1]] || clear[v[2]])
                continue;
            memcpy(start + 3 * kept++, v, 3 * sizeof *v);
        }
        tessel_mesh other;
        tessel_front_stats fs;
        if ((st = tsl_advancing_front_from(reps, *lines, front, start, kept, callbacks, &other,
                                           &fs)))
            break;
        defects left;
        if ((st = defects_of(&other, &fs, &left))) {
            tessel_mesh_free(&other);
            break;
        }
        if (better(&left, &have)) {
            have = left;
            tessel_mesh_free(mesh);
            *mesh = other;
            *stats = fs;
            failed = 0;
        } else {
            tessel_mesh_free(&other);
            reps->count = base;
            failed++;
        }
    }
    free(clear);
    free(start);
    return st;
}

/* Regions the front meshed inside out (src/mesh/orient.c) flipped, their rims
 * dropped, and the front again from the rest to close the seams (the
 * caller's hole repair follows for what it leaves open). */
static tessel_status repair_orientation(tessel_mesh *mesh, const tessel_cloud *reps,
                                        const float *lines, const tessel_front_params *front,
                                        const tessel_callbacks *callbacks,
                                        tessel_front_stats *stats, size_t *turned)
{
    size_t nt = mesh->triangle_count, flipped = 0;
    uint8_t *mark = tsl_alloc_array(nt + 1, sizeof *mark);
    uint32_t *start = NULL;
    tessel_status st = TESSEL_ERR_NOMEM;
    if (!mark)
        goto done;
    if ((st = tsl_orient_check(reps->xyz, reps->count, mesh->triangles, nt, front->threads, mark,
                               &flipped)) ||
        !flipped)
        goto done;
    if (!(start = tsl_alloc_array(3 * nt, sizeof *start))) {
        st = TESSEL_ERR_NOMEM;
        goto done;
    }
    size_t kept = tsl_orient_apply(mesh->triangles, nt, mark, start);
    tessel_mesh other;
    tessel_front_stats fs;
    if ((st = tsl_advancing_front_from(reps, lines, front, start, kept, callbacks, &other, &fs)))
        goto done;
    tessel_mesh_free(mesh);
    *mesh = other;
    *stats = fs;
    *turned = flipped;
done:
    free(mark);
    free(start);
    return st;
}

tessel_status tessel_reconstruct_smooth(const tessel_cloud *cloud,
                                        const tessel_smooth_recon_params *params,
                                        const tessel_callbacks *callbacks, tessel_mesh *mesh,
                                        tessel_smooth_recon_stats *stats)
{
    return tsl_reconstruct_smooth_with(cloud, params, NULL, callbacks, mesh, stats);
}

tessel_status tsl_reconstruct_smooth_with(const tessel_cloud *cloud,
                                          const tessel_smooth_recon_params *params,
                                          const tsl_af_tile_runner *runner,
                                          const tessel_callbacks *callbacks, tessel_mesh *mesh,
                                          tessel_smooth_recon_stats *stats)
{
    if (!mesh)
        return TESSEL_ERR_INVALID_ARG;
    memset(mesh, 0, sizeof *mesh);
    if (stats)
        memset(stats, 0, sizeof *stats);
    if (!cloud || (cloud->count && !cloud->xyz))
        return TESSEL_ERR_INVALID_ARG;
    tessel_smooth_recon_params p = params ? *params : tessel_smooth_recon_params_default();
    if (!(p.noise >= 0.0 && p.noise < INFINITY && p.noise_ratio >= 0.0 &&
          p.noise_ratio < INFINITY))
        return TESSEL_ERR_INVALID_ARG;
    if (p.threads) {
        p.smooth.threads = p.simplify.cluster.threads = p.simplify.projection.threads =
            p.front.threads = p.refine.threads = p.threads;
    }
    tessel_smooth_recon_stats s;
    memset(&s, 0, sizeof s);
    s.points = cloud->count;
    if (cloud->count < 3)
        return TESSEL_ERR_TOO_FEW_POINTS;

    tessel_cloud smoothed = {0}, reps = {0}, thinned = {0};
    tessel_projector *projector = NULL;
    tessel_status st;
    double t_all = tsl_seconds();
    const tessel_cloud *input = cloud;
    if ((st = measure_noise(cloud, &p, &s, &thinned, &input)))
        goto fail;
    cloud = input;
    if (cloud->count < 3) {
        st = TESSEL_ERR_TOO_FEW_POINTS;
        goto fail;
    }
    double t = tsl_seconds();

    /* h once for every stage: the smoothing measures it (on the grid it
     * builds for its neighbours) unless it is given. */
    if ((st = tsl_smooth_timed(cloud, &smoothed, &p.smooth, callbacks, &s.smooth, true,
                               &s.seconds_spacing)))
        goto fail;
    double h = s.smooth.spacing;
    s.spacing = h;
    p.smooth.spacing = h;
    if (!(p.simplify.cluster.spacing > 0.0))
        p.simplify.cluster.spacing = h;
    if (!(p.simplify.projection.spacing > 0.0))
        p.simplify.projection.spacing = h;
    s.seconds_smooth = tsl_seconds() - t - s.seconds_spacing;

    /* Representatives far enough apart for the noise left (see the
     * params): on clean input small clusters follow thin parts; on noisy
     * input closer representatives would make the triangulation trip over
     * their residual noise. */
    if (p.auto_cluster_size) {
        double noise = s.smooth.rms_displacement / h;
        double d = AUTO_DIAMETER_PER_NOISE * noise;
        p.simplify.cluster.max_diameter = d < AUTO_DIAMETER_MIN   ? AUTO_DIAMETER_MIN
                                          : d > AUTO_DIAMETER_MAX ? AUTO_DIAMETER_MAX
                                                                  : d;
    }
    s.cluster_diameter = p.simplify.cluster.max_diameter;

    t = tsl_seconds();
    {
        /* One kd-tree over the smoothed cloud serves the representatives'
         * projector here, the refinement's and the hole step's. */
        tessel_smooth_params q = p.smooth;
        q.spacing = h;
        tessel_projector *rp = NULL;
        tessel_clusters cl = {0};
        if (!(st = tessel_projector_create(&projector, &smoothed, &q)) &&
            !(st = tessel_cluster(&smoothed, &p.simplify.cluster, callbacks, &cl)) &&
            !(st = tsl_projector_create_on(
                  &rp, &smoothed, &p.simplify.projection,
                  tsl_projector_index(projector, smoothed.xyz, smoothed.count))))
            st = tsl_representatives_with(&smoothed, &cl, &p.simplify, rp, callbacks, &reps,
                                          &s.simplify);
        tessel_projector_destroy(rp);
        tessel_clusters_free(&cl);
        if (st)
            goto fail;
    }
    s.seconds_simplify = tsl_seconds() - t;
    s.representatives = reps.count;
    if (reps.count < 3) {
        st = TESSEL_ERR_TOO_FEW_POINTS;
        goto fail;
    }
    /* Normals whose sign is arbitrary would orient open components at
     * random: then they serve only as second normal lines of the
     * triangulation's normal cone (next to the planes it fits to the
     * representatives, which are poor at tips and narrow parts). */
    float *lines = NULL;
    if (!cloud->normals && !cloud->has_viewpoint) {
        lines = reps.normals;
        reps.normals = NULL;
    }

    t = tsl_seconds();
    st = tsl_advancing_front_lines_with(&reps, lines, &p.front, runner, callbacks, mesh,
                                        &s.front);
    /* Holes left: the front again around them with extra representatives,
     * the rest of the mesh kept (but near tile cuts; every result is
     * valid). In a scene of many pieces (a room scan) most borders are the
     * scan's own, and every attempt costs a front over the whole cloud:
     * there the whole front does not run again, the local attempts stop at
     * the first that fails, and they run only when the normals are oriented
     * (the input had normals or a viewpoint). room_small.grid with its
     * viewpoint, at four positions, kept the first attempt every time (F
     * 93.64 instead of 93.31); without it, at four positions and as 2 x 2
     * and 3 x 3 copies side by side, no attempt was ever kept (the first
     * left 23-33% more border edges), and they took a third of the run. */
    size_t strays, pieces = 0;
    if (!st)
        st = tsl_stray_pieces(mesh, &strays, &pieces);
    bool scene = pieces > STRAY_MAX, local = !scene || !lines;
    int max_failed = scene ? 1 : 2;
    if (!st && !scene)
        st = repair_holes(global_repairs, COUNT(global_repairs), 1, mesh, &smoothed, projector,
                          &p.front, callbacks, &reps, &lines, &s.front);
    if (!st && local)
        st = repair_holes(local_repairs, COUNT(local_repairs), max_failed, mesh, &smoothed,
                          projector, &p.front, callbacks, &reps, &lines, &s.front);
    if (!st && lines)
        st = repair_orientation(mesh, &reps, lines, &p.front, callbacks, &s.front,
                                &s.reoriented);
    if (!st && local && s.reoriented)
        st = repair_holes(local_repairs, COUNT(local_repairs), max_failed, mesh, &smoothed,
                          projector, &p.front, callbacks, &reps, &lines, &s.front);
    free(lines);
    if (st)
        goto fail;
    if ((st = compact(mesh)))
        goto fail;
    s.seconds_front = tsl_seconds() - t;

    t = tsl_seconds();
    if (p.refine.rounds > 0 &&
        (st = tessel_refine(mesh, &smoothed, projector, &p.refine, callbacks, &s.refine)))
        goto fail;
    if ((st = star_normals(mesh)))
        goto fail;
    s.seconds_refine = tsl_seconds() - t;

    s.vertices = mesh->vertex_count;
    s.triangles = mesh->triangle_count;
    /* Refinement splits border edges too. */
    s.border_edges = p.refine.rounds > 0 ? s.refine.border_edges : s.front.border_edges;
    s.seconds_total = tsl_seconds() - t_all;
    tessel_projector_destroy(projector);
    tessel_cloud_free(&smoothed);
    tessel_cloud_free(&reps);
    tessel_cloud_free(&thinned);
    if (stats)
        *stats = s;
    return TESSEL_OK;
fail:
    tessel_projector_destroy(projector);
    tessel_cloud_free(&smoothed);
    tessel_cloud_free(&reps);
    tessel_cloud_free(&thinned);
    tessel_mesh_free(mesh);
    if (stats)
        *stats = s;
    return st;
}
