/* Mesh refinement against a point cloud: step 5 of Mederos, Velho & de
 * Figueiredo 2003, "Smooth surface reconstruction from noisy clouds",
 * section 2.5.
 *
 * Each round looks at every edge uv: its midpoint m, the normal n_m (the
 * normalised sum of u's and v's normals, each the area-weighted mean normal
 * of its star) and a = mean over the k nearest cloud points p of
 * (p - m).n_m, the offset along n_m of the least-squares closest point to
 * the cloud. When |a| > eps the edge is split at Q(m + a n_m), Q being the
 * robust projection operator of section 2.1, and so are its one or two
 * triangles (a-u-v becomes a-u-m' and a-m'-v), unless one of them is too
 * skinny (shortest / longest edge below a ratio). Then diagonals are
 * flipped wherever the other diagonal of two adjacent triangles is shorter.
 *
 * The per-edge work (neighbour search, fit, projection) runs in parallel,
 * the edges in Morton order of their midpoints; the splits and flips are
 * the mesh layer's checked edits (mesh/edit.c, split.c, flip.c), made in
 * parallel blocks with a result that does not depend on the thread count:
 * each is checked before it is kept (its new triangles must not turn by
 * more than 60 degrees from the ones they replace, nor meet any triangle
 * beyond shared vertices and edges, exactly), so the mesh stays manifold,
 * oriented and free of self-intersections. */
#include "mesh/mesh.h"
#include "smooth/smooth.h"

#include <stdlib.h>
#include <string.h>

#define NONE TESSEL_NONE
#define MAX_K 256

tessel_refine_params tessel_refine_params_default(void)
{
    tessel_refine_params p;
    memset(&p, 0, sizeof p);
    p.rounds = 2;
    p.k = 16;
    p.min_offset = 0.1;
    p.min_edge_length = 1.5;
    p.min_edge_ratio = 0.2;
    p.flip = 1;
    p.threads = 0;
    return p;
}

/* The refinement's state: the mesh under edit, and the previous round's
 * fits: edge -> index into fit_sum (3 floats per edge, the sum over its
 * midpoint's k nearest cloud points of p - m). Vertices never move, so an
 * edge that survives a round keeps its midpoint, its neighbours and this
 * sum. */
typedef struct rf {
    tsl_edit e;
    tsl_edge_map fit_of;
    float *fit_sum;
    tessel_refine_stats stats;
} rf;

typedef struct round_ctx {
    const tessel_index *index;
    const tessel_cloud *cloud;
    const tessel_projector *projector;
    double h, eps, min_len;
    uint32_t k;
    int threads;
} round_ctx;

/* How many edges ahead the fits ask for the previous round's fit: the
 * lookups land anywhere in a map of megabytes. */
#define FIT_AHEAD 8

/* Bits per axis of the cells that order the edges' neighbour searches. */
#define ORDER_BITS 6

/* Spreads the low ORDER_BITS bits of x three apart (Morton code). */
static uint32_t spread3(uint32_t x)
{
    uint32_t y = 0;
    for (int b = 0; b < ORDER_BITS; b++)
        y |= ((x >> b) & 1u) << (3 * b);
    return y;
}

/* The jobs' indices in Morton order of their midpoints' cells (a counting
 * sort over 2^(3 ORDER_BITS) cells of the mesh's box), so that consecutive
 * neighbour searches walk the same part of the kd-tree: on 10^6 points the
 * tree does not fit in cache and searches in edge order spend most of
 * their time waiting for memory. The splits follow the same order. */
static tessel_status spatial_order(const rf *r, const tsl_split_job *jobs, size_t ne,
                                   uint32_t **out)
{
    const size_t cells = (size_t)1 << (3 * ORDER_BITS);
    uint32_t *order = tsl_alloc_array(ne ? ne : 1, sizeof *order);
    uint32_t *key = tsl_alloc_array(ne ? ne : 1, sizeof *key);
    size_t *start = tsl_calloc_array(cells + 1, sizeof *start);
    if (!order || !key || !start) {
        free(order);
        free(key);
        free(start);
        return TESSEL_ERR_NOMEM;
    }
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t v = 0; v < r->e.nv; v++)
        for (int k = 0; k < 3; k++) {
            float x = r->e.xyz[3 * v + k];
            lo[k] = x < lo[k] ? x : lo[k];
            hi[k] = x > hi[k] ? x : hi[k];
        }
    double scale[3];
    for (int k = 0; k < 3; k++)
        scale[k] = hi[k] > lo[k] ? (double)((1 << ORDER_BITS) - 1) / ((double)hi[k] - lo[k]) : 0.0;
    for (size_t e = 0; e < ne; e++) {
        const float *a = r->e.xyz + 3 * (size_t)jobs[e].u, *b = r->e.xyz + 3 * (size_t)jobs[e].v;
        uint32_t m = 0;
        for (int k = 0; k < 3; k++) {
            double x = 0.5 * ((double)a[k] + b[k]) - lo[k];
            m |= spread3((uint32_t)(x * scale[k] + 0.5)) << k;
        }
        key[e] = m;
        start[m + 1]++;
    }
    for (size_t i = 0; i < cells; i++)
        start[i + 1] += start[i];
    for (size_t e = 0; e < ne; e++)
        order[start[key[e]]++] = (uint32_t)e;
    free(key);
    free(start);
    *out = order;
    return TESSEL_OK;
}

static tessel_status one_round(rf *r, const round_ctx *c, const tessel_refine_params *p,
                               bool keep_fits)
{
    /* Candidate edges: each undirected edge once (its half-edge with the
     * smaller id, or its only one). */
    size_t nh = 3 * r->e.nt, ne = 0;
    tsl_split_job *jobs = tsl_alloc_array(nh, sizeof *jobs);
    uint8_t *want = NULL, *fitted = NULL;
    float *sum = NULL;
    uint32_t *order = NULL;
    double *vn = NULL;
    tessel_status st = TESSEL_ERR_NOMEM;
    if (!jobs)
        goto done;
    for (size_t hh = 0; hh < nh; hh++) {
        uint32_t g = r->e.twin[hh];
        if (g != NONE && g < hh)
            continue;
        jobs[ne].u = tsl_he_from(&r->e, (uint32_t)hh);
        jobs[ne].v = tsl_he_to(&r->e, (uint32_t)hh);
        ne++;
    }
    want = tsl_calloc_array(ne ? ne : 1, 1);
    fitted = tsl_calloc_array(ne ? ne : 1, 1);
    sum = tsl_alloc_array(3 * (ne ? ne : 1), sizeof *sum);
    if (!want || !fitted || !sum || (st = tsl_edit_vertex_normals(&r->e, &vn)) ||
        (st = spatial_order(r, jobs, ne, &order)))
        goto done;
    size_t far = 0, unfit = 0;
    long long count = (long long)ne;
#pragma omp parallel for schedule(dynamic, 256) num_threads(tsl_threads(c->threads)) \
    reduction(+ : far, unfit)
    for (long long oo = 0; oo < count; oo++) {
        size_t ii = order[oo];
        tsl_split_job *jb = &jobs[ii];
        double pu[3], pv[3], d[3], m[3], nm[3];
        tsl_edit_point(&r->e, jb->u, pu);
        tsl_edit_point(&r->e, jb->v, pv);
        tsl_sub(pv, pu, d);
        double len = tsl_norm(d);
        if (!(len >= c->min_len))
            continue;
        for (int k = 0; k < 3; k++) {
            m[k] = 0.5 * (pu[k] + pv[k]);
            nm[k] = vn[3 * (size_t)jb->u + k] + vn[3 * (size_t)jb->v + k];
        }
        if (!tsl_normalize(nm))
            continue;
        float *ws = sum + 3 * ii;
        if (r->fit_sum && oo + FIT_AHEAD < count) {
            const tsl_split_job *ahead = &jobs[order[oo + FIT_AHEAD]];
            tsl_edge_map_prefetch(&r->fit_of, ahead->u, ahead->v);
        }
        uint32_t known = r->fit_sum ? tsl_edge_map_get(&r->fit_of, jb->u, jb->v) : NONE;
        if (known != NONE) {
            memcpy(ws, r->fit_sum + 3 * (size_t)known, 3 * sizeof *ws);
        } else {
            uint32_t idx[MAX_K];
            float q[3] = {(float)m[0], (float)m[1], (float)m[2]};
            size_t got = tessel_index_knn(c->index, q, c->k, idx, NULL);
            if (got != c->k)
                continue;
            double w[3] = {0.0, 0.0, 0.0};
            for (size_t s = 0; s < got; s++)
                for (int k = 0; k < 3; k++)
                    w[k] += (double)c->cloud->xyz[3 * (size_t)idx[s] + k] - m[k];
            for (int k = 0; k < 3; k++)
                ws[k] = (float)w[k];
        }
        fitted[ii] = 1;
        double a = (ws[0] * nm[0] + ws[1] * nm[1] + ws[2] * nm[2]) / (double)c->k;
        if (!(fabs(a) > c->eps))
            continue;
        far++;
        float target[3] = {(float)(m[0] + a * nm[0]), (float)(m[1] + a * nm[1]),
                           (float)(m[2] + a * nm[2])};
        if (tessel_project(c->projector, target, jb->pos, NULL, NULL) != TESSEL_OK) {
            unfit++;
            continue;
        }
        want[ii] = 1;
    }
    r->stats.far_edges += far;
    r->stats.unfit += unfit;
    /* Keep this round's fits for the next round (the edges of the mesh
     * before any split or flip; most of them survive). */
    tsl_edge_map_free(&r->fit_of);
    free(r->fit_sum);
    r->fit_sum = NULL;
    if (keep_fits) {
        size_t nf = 0;
        for (size_t e = 0; e < ne; e++)
            nf += fitted[e];
        if ((st = tsl_edge_map_init(&r->fit_of, nf)))
            goto done;
#pragma omp parallel for schedule(static) num_threads(tsl_threads(c->threads))
        for (long long e = 0; e < count; e++)
            if (fitted[e])
                tsl_edge_map_put_shared(&r->fit_of, jobs[e].u, jobs[e].v, (uint32_t)e);
        r->fit_of.count = nf;
        r->fit_sum = sum;
        sum = NULL;
    }
    /* Each edge once, in the Morton order of the fits (a split reads and
     * writes the mesh, its edge map and its grid around the edge, so
     * neighbouring splits in a row find them in cache), in parallel. */
    size_t nw = 0;
    for (size_t oo = 0; oo < ne; oo++)
        if (want[order[oo]])
            order[nw++] = order[oo];
    st = tsl_edit_splits(&r->e, jobs, order, nw, p->min_edge_ratio, c->threads);
    if (st)
        goto done;
    if (p->flip)
        st = tsl_edit_flips(&r->e, c->threads);
done:
    free(jobs);
    free(want);
    free(fitted);
    free(sum);
    free(order);
    free(vn);
    return st;
}

static tessel_status check_params(const tessel_refine_params *p)
{
    if (p->rounds > 20 || p->k < 1 || p->k > MAX_K || !(p->min_offset >= 0.0) ||
        !isfinite(p->min_offset) || !(p->min_edge_length >= 0.0) || !isfinite(p->min_edge_length) ||
        !(p->min_edge_ratio >= 0.0 && p->min_edge_ratio <= 1.0))
        return TESSEL_ERR_INVALID_ARG;
    return TESSEL_OK;
}

tessel_status tessel_refine(tessel_mesh *mesh, const tessel_cloud *cloud,
                            const tessel_projector *projector, const tessel_refine_params *params,
                            const tessel_callbacks *callbacks, tessel_refine_stats *stats)
{
    if (stats)
        memset(stats, 0, sizeof *stats);
    if (!mesh || !cloud || (mesh->vertex_count && !mesh->xyz) ||
        (mesh->triangle_count && !mesh->triangles) || (cloud->count && !cloud->xyz))
        return TESSEL_ERR_INVALID_ARG;
    tessel_refine_params p = params ? *params : tessel_refine_params_default();
    tessel_status st = check_params(&p);
    if (st)
        return st;
    for (int c = 0; c < 3; c++)
        if (mesh->offset[c] != cloud->offset[c])
            return TESSEL_ERR_INVALID_ARG;
    if (mesh->vertex_count >= UINT32_MAX / 2 || mesh->triangle_count >= UINT32_MAX / 8)
        return TESSEL_ERR_LIMIT;
    if (p.rounds == 0 || mesh->triangle_count == 0)
        return TESSEL_OK;
    if (cloud->count < 3)
        return TESSEL_ERR_TOO_FEW_POINTS;

    rf r;
    memset(&r, 0, sizeof r);
    tessel_projector *own = NULL;
    tessel_index *own_index = NULL;
    tsl_edit *e = &r.e;
    if ((st = tsl_edit_init(e)))
        goto done;
    e->nv = mesh->vertex_count;
    e->nt = mesh->triangle_count;
    e->cap_v = e->nv + 16;
    e->cap_t = e->nt + 16;
    e->xyz = e->xyz_own = tsl_alloc_array(3 * e->cap_v, sizeof *e->xyz_own);
    e->rgb = mesh->rgb ? tsl_alloc_array(3 * e->cap_v, 1) : NULL;
    e->tri = tsl_alloc_array(3 * e->cap_t, sizeof *e->tri);
    e->twin = tsl_alloc_array(3 * e->cap_t, sizeof *e->twin);
    e->box = tsl_alloc_array(6 * e->cap_t, sizeof *e->box);
    st = TESSEL_ERR_NOMEM;
    if (!e->xyz_own || !e->tri || !e->twin || !e->box || (mesh->rgb && !e->rgb))
        goto done;
    memcpy(e->xyz_own, mesh->xyz, 3 * e->nv * sizeof *e->xyz_own);
    if (e->rgb)
        memcpy(e->rgb, mesh->rgb, 3 * e->nv);
    memcpy(e->tri, mesh->triangles, 3 * e->nt * sizeof *e->tri);
    if ((st = tsl_edit_topology(e, p.threads)))
        goto done;
    if (!projector) {
        if ((st = tessel_projector_create(&own, cloud, NULL)))
            goto done;
        projector = own;
    }
    /* The projector's kd-tree when it is over this cloud, else our own. */
    const tessel_index *index = tsl_projector_index(projector, cloud->xyz, cloud->count);
    if (!index) {
        if ((st = tessel_index_build(&own_index, cloud->xyz, cloud->count)))
            goto done;
        index = own_index;
    }
    round_ctx c;
    c.index = index;
    c.cloud = cloud;
    c.projector = projector;
    c.h = tessel_projector_spacing(projector);
    c.eps = p.min_offset * c.h;
    c.min_len = p.min_edge_length * c.h;
    c.k = p.k < cloud->count ? p.k : (uint32_t)cloud->count;
    c.threads = p.threads;
    for (uint32_t round = 0; round < p.rounds; round++) {
        if ((st = tsl_progress(callbacks, "refine", (double)round / p.rounds)))
            goto done;
        if ((st = tsl_edit_grid(e)) || (st = one_round(&r, &c, &p, round + 1 < p.rounds)))
            goto done;
    }
    for (size_t h = 0; h < 3 * e->nt; h++)
        r.stats.border_edges += e->twin[h] == NONE;
    /* Commit into the caller's mesh. */
    {
        tessel_mesh out;
        if ((st = tessel_mesh_alloc(&out, e->nv, e->nt, mesh->normals != NULL, e->rgb != NULL)))
            goto done;
        memcpy(out.xyz, e->xyz, 3 * e->nv * sizeof *out.xyz);
        memcpy(out.triangles, e->tri, 3 * e->nt * sizeof *out.triangles);
        if (e->rgb)
            memcpy(out.rgb, e->rgb, 3 * e->nv);
        if (out.normals) {
            double *vn;
            if ((st = tsl_edit_vertex_normals(e, &vn))) {
                tessel_mesh_free(&out);
                goto done;
            }
            for (size_t v = 0; v < 3 * e->nv; v++)
                out.normals[v] = (float)vn[v];
            free(vn);
        }
        for (int k = 0; k < 3; k++)
            out.offset[k] = mesh->offset[k];
        tessel_mesh_free(mesh);
        *mesh = out;
    }
    st = tsl_progress(callbacks, "refine", 1.0);
done:
    r.stats.splits = e->counts.splits;
    r.stats.flips = e->counts.flips;
    r.stats.skipped_skinny = e->counts.skipped_skinny;
    r.stats.skipped_invalid = e->counts.skipped_invalid;
    if (stats)
        *stats = r.stats;
    tessel_index_destroy(own_index);
    tessel_projector_destroy(own);
    tsl_edit_free(e);
    tsl_edge_map_free(&r.fit_of);
    free(r.fit_sum);
    return st;
}
