/* Orientation check by ray parity, for meshes of closed objects (beyond
 * Mederos, Velho & de Figueiredo 2003; used by the smooth pipeline and by
 * the greedy projection, src/greedy/held.c).
 *
 * The advancing front carries a component's orientation from triangle to
 * triangle (section 2.4). Where two sheets touch closer than the
 * representatives' spacing (a hand against a thigh) it can step from one
 * onto the other as if they were one sheet, and mesh the whole limb behind
 * the step inside out. Locally the flipped limb is flawless; only a global
 * test sees it. A ray from a triangle's centroid along its normal crosses a
 * closed surface an odd number of times exactly when the normal points
 * inward. Every triangle votes so; the votes are averaged over a few rings
 * of neighbours (a ray through a hole or along an edge miscounts); a
 * connected region voting inward is marked for flipping when it holds
 * fewer than half of its component's triangles, the component's own
 * orientation being the front's business (orient_components). The
 * triangles along the region's edge are marked for removal: once the region
 * is flipped they would meet their neighbours with clashing orientations,
 * and the front fills the seam again from the mesh around it.
 *
 * When the points come with normals or a viewpoint (a scan), the side of
 * every triangle is known without rays, open surfaces included: it votes
 * by agreeing with its vertices' normals or facing the viewpoint, and any
 * region voting away is flipped, a whole component too
 * (tsl_orient_check_toward). The greedy front on a noisy range scan folds
 * over itself and carries the wrong side across the folds: on
 * room_small.grid.ply half the area faced away from the scanner. */
#include "mesh/mesh.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define NONE TESSEL_NONE
/* Grid cells at most (the cell grows to stay under). */
#define MAX_CELLS (1u << 22)
/* Averaging rounds over edge neighbours. */
#define SMOOTH_ROUNDS 12
/* Smaller inward regions are left alone: too few rays to trust. */
#define MIN_REGION 32
/* Rays cast at most: larger meshes cast from a hashed sample of their
 * triangles (a ray crosses the whole grid, some hundred cells at 10^6
 * triangles), and the averaging carries the votes to the rest. */
#define RAY_BUDGET 65536
/* Normals whose signs disagree across more than 1 / UNSIGNED_SHARE of the
 * mesh's edges carry no side (unoriented normals: half of them). Oriented
 * ones, even from noisy points, disagree across a few percent: 0-6.4% on
 * the data files with tessel's normals. */
#define UNSIGNED_SHARE 5

/* A uniform grid over the mesh's box; each cell lists the triangles whose
 * boxes meet it (CSR). */
typedef struct ray_grid {
    double lo[3], cell;
    int n[3];
    uint32_t *start, *items;
} ray_grid;

static void tri_points(const float *xyz, const uint32_t *v, double p[3][3])
{
    for (int i = 0; i < 3; i++)
        tsl_load(xyz + 3 * (size_t)v[i], p[i]);
}

static int clampi(double x, int n)
{
    return x < 0.0 ? 0 : x >= (double)n ? n - 1 : (int)x;
}

static void cell_range(const ray_grid *g, const double p[3][3], int lo[3], int hi[3])
{
    for (int k = 0; k < 3; k++) {
        double a = fmin(p[0][k], fmin(p[1][k], p[2][k]));
        double b = fmax(p[0][k], fmax(p[1][k], p[2][k]));
        lo[k] = clampi((a - g->lo[k]) / g->cell, g->n[k]);
        hi[k] = clampi((b - g->lo[k]) / g->cell, g->n[k]);
    }
}

static size_t cell_id(const ray_grid *g, int x, int y, int z)
{
    return ((size_t)z * (size_t)g->n[1] + (size_t)y) * (size_t)g->n[0] + (size_t)x;
}

/* The box is the triangles': points no triangle uses (an outlier far
 * away) would only stretch the grid. Threaded; the items of a cell come
 * in any order, which changes no count. */
static tessel_status grid_build(ray_grid *g, const float *xyz, const uint32_t *tri, size_t nt,
                                int threads)
{
    double hi[3], len = 0.0;
    for (int k = 0; k < 3; k++) {
        g->lo[k] = INFINITY;
        hi[k] = -INFINITY;
    }
    ptrdiff_t n = (ptrdiff_t)nt;
    /* The edge lengths summed in order, so that the cell is the same for
     * any thread count. */
    double *edge = tsl_alloc_array(nt ? nt : 1, sizeof *edge);
    if (!edge)
        return TESSEL_ERR_NOMEM;
    double lo0 = INFINITY, lo1 = INFINITY, lo2 = INFINITY;
    double hi0 = -INFINITY, hi1 = -INFINITY, hi2 = -INFINITY;
#pragma omp parallel for schedule(static) num_threads(tsl_threads(threads)) \
    reduction(min : lo0, lo1, lo2) reduction(max : hi0, hi1, hi2)
    for (ptrdiff_t t = 0; t < n; t++) {
        double p[3][3], d[3];
        tri_points(xyz, tri + 3 * t, p);
        for (int i = 0; i < 3; i++) {
            lo0 = fmin(lo0, p[i][0]);
            lo1 = fmin(lo1, p[i][1]);
            lo2 = fmin(lo2, p[i][2]);
            hi0 = fmax(hi0, p[i][0]);
            hi1 = fmax(hi1, p[i][1]);
            hi2 = fmax(hi2, p[i][2]);
        }
        tsl_sub(p[1], p[0], d);
        edge[t] = tsl_norm(d);
    }
    for (size_t t = 0; t < nt; t++)
        len += edge[t];
    free(edge);
    g->lo[0] = lo0, g->lo[1] = lo1, g->lo[2] = lo2;
    hi[0] = hi0, hi[1] = hi1, hi[2] = hi2;
    /* One mean edge a cell. A ray's cost is its triangle tests, and most of
     * them are in the first cells, among the triangles around its origin;
     * smaller cells hold fewer of them, for more (cheap) empty cells on
     * the way out. Against two mean edges, the check took 0.12 s instead
     * of 0.18 s on man.ply and 0.31 s instead of 0.51 s on
     * elephant.pd.n05.ply (one core); below one edge it gained nothing. The
     * cell changes no count: a crossing counts in the cell where it lies. */
    double ext[3], top = 0.0;
    for (int k = 0; k < 3; k++) {
        ext[k] = hi[k] - g->lo[k];
        top = fmax(top, ext[k]);
    }
    g->cell = len / (double)nt;
    if (!(g->cell > 0.0))
        g->cell = top > 0.0 ? top : 1.0;
    for (;;) {
        double cells = 1.0;
        for (int k = 0; k < 3; k++)
            cells *= floor(ext[k] / g->cell) + 1.0;
        if (cells <= MAX_CELLS)
            break;
        g->cell *= 1.25;
    }
    size_t total = 1;
    for (int k = 0; k < 3; k++) {
        g->n[k] = (int)(ext[k] / g->cell) + 1;
        total *= (size_t)g->n[k];
    }
    g->start = tsl_calloc_array(total + 1, sizeof *g->start);
    if (!g->start)
        return TESSEL_ERR_NOMEM;
    size_t entries = 0;
    for (int pass = 0; pass < 2; pass++) {
#pragma omp parallel for schedule(static) num_threads(tsl_threads(threads))
        for (ptrdiff_t t = 0; t < n; t++) {
            double p[3][3];
            int a[3], b[3];
            tri_points(xyz, tri + 3 * t, p);
            cell_range(g, p, a, b);
            for (int z = a[2]; z <= b[2]; z++)
                for (int y = a[1]; y <= b[1]; y++)
                    for (int x = a[0]; x <= b[0]; x++) {
                        size_t c = cell_id(g, x, y, z), at;
                        if (pass == 0) {
#pragma omp atomic
                            g->start[c + 1]++;
                            continue;
                        }
#pragma omp atomic capture
                        at = g->start[c]++;
                        g->items[at] = (uint32_t)t;
                    }
        }
        if (pass == 0) {
            for (size_t c = 0; c < total; c++)
                g->start[c + 1] += g->start[c];
            entries = g->start[total];
            if (entries > UINT32_MAX ||
                !(g->items = tsl_alloc_array(entries ? entries : 1, sizeof *g->items)))
                return TESSEL_ERR_NOMEM;
        }
    }
    /* The fill advanced every start to the next cell's; shift back. */
    memmove(g->start + 1, g->start, total * sizeof *g->start);
    g->start[0] = 0;
    return TESSEL_OK;
}

/* Parameter t > 0 where the ray o + t d meets the closed triangle p, or -1
 * (Moeller and Trumbore). */
static double ray_hit(const double o[3], const double d[3], const double p[3][3])
{
    double e1[3], e2[3], q[3], s[3], r[3];
    tsl_sub(p[1], p[0], e1);
    tsl_sub(p[2], p[0], e2);
    tsl_cross(d, e2, q);
    double det = tsl_dot(e1, q);
    if (det == 0.0)
        return -1.0;
    double inv = 1.0 / det;
    tsl_sub(o, p[0], s);
    double u = tsl_dot(s, q) * inv;
    if (u < 0.0 || u > 1.0)
        return -1.0;
    tsl_cross(s, e1, r);
    double v = tsl_dot(d, r) * inv;
    if (v < 0.0 || u + v > 1.0)
        return -1.0;
    return tsl_dot(e2, r) * inv;
}

/* Crossings of the ray from triangle t's centroid along its normal with
 * the other triangles (3D DDA through the grid, Amanatides and Woo; a
 * crossing counts in the cell where it lies, so once). -1 for a degenerate
 * triangle. */
static int crossings(const ray_grid *g, const float *xyz, const uint32_t *tri, uint32_t t)
{
    double p[3][3], o[3], d[3], u[3], w[3];
    tri_points(xyz, tri + 3 * (size_t)t, p);
    tsl_sub(p[1], p[0], u);
    tsl_sub(p[2], p[0], w);
    tsl_cross(u, w, d);
    if (!tsl_normalize(d))
        return -1;
    for (int k = 0; k < 3; k++)
        o[k] = (p[0][k] + p[1][k] + p[2][k]) / 3.0;
    int c[3], step[3];
    double tmax[3], tdelta[3];
    for (int k = 0; k < 3; k++) {
        double x = (o[k] - g->lo[k]) / g->cell;
        c[k] = clampi(x, g->n[k]);
        if (d[k] > 0.0) {
            step[k] = 1;
            tdelta[k] = g->cell / d[k];
            tmax[k] = ((double)(c[k] + 1) - x) * tdelta[k];
        } else if (d[k] < 0.0) {
            step[k] = -1;
            tdelta[k] = -g->cell / d[k];
            tmax[k] = (x - (double)c[k]) * tdelta[k];
        } else {
            step[k] = 0;
            tdelta[k] = tmax[k] = INFINITY;
        }
    }
    int count = 0;
    double tin = 0.0;
    for (;;) {
        int k = tmax[0] < tmax[1] ? (tmax[0] < tmax[2] ? 0 : 2) : (tmax[1] < tmax[2] ? 1 : 2);
        double tout = tmax[k];
        size_t id = cell_id(g, c[0], c[1], c[2]);
        for (uint32_t e = g->start[id]; e < g->start[id + 1]; e++) {
            uint32_t x = g->items[e];
            if (x == t)
                continue;
            double q[3][3];
            tri_points(xyz, tri + 3 * (size_t)x, q);
            double h = ray_hit(o, d, q);
            if (h > 0.0 && h >= tin && h < tout)
                count++;
        }
        c[k] += step[k];
        if (c[k] < 0 || c[k] >= g->n[k])
            return count;
        tin = tout;
        tmax[k] += tdelta[k];
    }
}

/* A triangle's place in the ray sample (Wellons' lowbias32 mix): spread
 * over the mesh whatever order the front made the triangles in. */
static uint32_t mix(uint32_t x)
{
    x ^= x >> 16;
    x *= 0x7feb352dU;
    x ^= x >> 15;
    x *= 0x846ca68bU;
    x ^= x >> 16;
    return x;
}

/* nb[3 t + i]: the triangle across t's edge i (from its vertex i to
 * i + 1), NONE on a border: the first triangle other than t, in the
 * order of a's corners, that has b too. Vertex by vertex (each writes only
 * the edges leaving it), from its corners' other two vertices, so that a
 * triangle is read once per vertex instead of once per edge there. */
static tessel_status neighbours(const uint32_t *tri, size_t nt, size_t nv, int threads,
                                uint32_t *nb)
{
    uint32_t *first, *corner;
    if (tsl_vertex_corners(tri, nt, nv, &first, &corner))
        return TESSEL_ERR_NOMEM;
    ptrdiff_t count = (ptrdiff_t)nv;
    bool nomem = false;
#pragma omp parallel num_threads(tsl_threads(threads)) reduction(|| : nomem)
    {
        size_t cap = 0;
        uint32_t *other = NULL; /* per corner at a: its next and previous vertex */
#pragma omp for schedule(dynamic, 1024)
        for (ptrdiff_t a = 0; a < count; a++) {
            uint32_t c0 = first[a], deg = first[a + 1] - c0;
            if (nomem || deg == 0)
                continue;
            if (2 * (size_t)deg > cap) {
                free(other);
                cap = 2 * (size_t)deg;
                if (!(other = tsl_alloc_array(cap, sizeof *other))) {
                    nomem = true;
                    cap = 0;
                    continue;
                }
            }
            for (uint32_t k = 0; k < deg; k++) {
                uint32_t c = corner[c0 + k], t3 = c - c % 3;
                other[2 * k] = tri[t3 + (c % 3 + 1) % 3];
                other[2 * k + 1] = tri[t3 + (c % 3 + 2) % 3];
            }
            for (uint32_t k = 0; k < deg; k++) {
                uint32_t c = corner[c0 + k], b = other[2 * k], found = NONE;
                for (uint32_t j = 0; j < deg && found == NONE; j++)
                    if (corner[c0 + j] / 3 != c / 3 &&
                        (b == (uint32_t)a || other[2 * j] == b || other[2 * j + 1] == b))
                        found = corner[c0 + j] / 3;
                nb[c] = found;
            }
        }
        free(other);
    }
    free(first);
    free(corner);
    return nomem ? TESSEL_ERR_NOMEM : TESSEL_OK;
}

/* Labels the connected sets of triangles t with in[t] (edge neighbours),
 * label[t] = the set's number, NONE outside; returns the count of sets.
 * queue: nt entries of scratch. */
static uint32_t label_sets(const uint32_t *nb, size_t nt, const uint8_t *in, uint32_t *label,
                           uint32_t *queue)
{
    uint32_t sets = 0;
    for (size_t t = 0; t < nt; t++)
        label[t] = NONE;
    for (size_t t = 0; t < nt; t++) {
        if (!in[t] || label[t] != NONE)
            continue;
        size_t head = 0, tail = 0;
        queue[tail++] = (uint32_t)t;
        label[t] = sets;
        while (head < tail) {
            uint32_t x = queue[head++];
            for (int i = 0; i < 3; i++) {
                uint32_t y = nb[3 * (size_t)x + (size_t)i];
                if (y != NONE && in[y] && label[y] == NONE) {
                    label[y] = sets;
                    queue[tail++] = y;
                }
            }
        }
        sets++;
    }
    return sets;
}

/* From the raw votes (+1 out, -1 in, 0 none): the votes averaged over
 * SMOOTH_ROUNDS rings of edge neighbours, the connected regions voting in
 * marked for flipping when they hold at least MIN_REGION triangles, more
 * inward raw votes than outward and (unless whole) less than half of
 * their component, and their rims marked for dropping (see the header). */
static tessel_status mark_regions(const uint32_t *tri, size_t nt, size_t nv, const float *raw,
                                  bool whole, int threads, uint8_t *mark, size_t *flipped)
{
    if (nt >= UINT32_MAX) /* triangle ids are uint32_t, NONE the largest */
        return TESSEL_ERR_LIMIT;
    /* Each array only while needed (10^7 points: 49 -> 33 bytes per
     * triangle at the peak, which is the whole reconstruction's). */
    uint32_t *nb = tsl_alloc_array(3 * nt, sizeof *nb), *label = NULL, *comp = NULL, *queue = NULL;
    float *vote = NULL, *next = NULL;
    uint8_t *in = NULL;
    size_t *size = NULL, *csize = NULL;
    double *sum = NULL;
    tessel_status st = nb ? neighbours(tri, nt, nv, threads, nb) : TESSEL_ERR_NOMEM;
    if (st)
        goto done;
    vote = tsl_alloc_array(nt, sizeof *vote);
    next = tsl_alloc_array(nt, sizeof *next);
    if (!vote || !next) {
        st = TESSEL_ERR_NOMEM;
        goto done;
    }
    ptrdiff_t n = (ptrdiff_t)nt;
    memcpy(vote, raw, nt * sizeof *vote);
    for (int r = 0; r < SMOOTH_ROUNDS; r++) {
#pragma omp parallel for schedule(static) num_threads(tsl_threads(threads))
        for (ptrdiff_t t = 0; t < n; t++) {
            float s = vote[t];
            int k = 1;
            for (int i = 0; i < 3; i++) {
                uint32_t y = nb[3 * (size_t)t + (size_t)i];
                if (y != NONE) {
                    s += vote[y];
                    k++;
                }
            }
            next[t] = s / (float)k;
        }
        float *tmp = vote;
        vote = next;
        next = tmp;
    }
    free(next);
    next = NULL;
    label = tsl_alloc_array(nt, sizeof *label);
    queue = tsl_alloc_array(nt, sizeof *queue);
    in = tsl_alloc_array(nt, sizeof *in);
    if (!label || !queue || !in) {
        st = TESSEL_ERR_NOMEM;
        goto done;
    }
    for (size_t t = 0; t < nt; t++)
        in[t] = vote[t] < 0.0f;
    uint32_t nset = label_sets(nb, nt, in, label, queue);
    size = tsl_calloc_array((size_t)nset + 1, sizeof *size);
    sum = tsl_calloc_array((size_t)nset + 1, sizeof *sum);
    if (!size || !sum) {
        st = TESSEL_ERR_NOMEM;
        goto done;
    }
    for (size_t t = 0; t < nt; t++)
        if (label[t] != NONE) {
            size[label[t]]++;
            sum[label[t]] += raw[t];
        }
    bool any = false;
    for (uint32_t l = 0; l < nset; l++)
        any |= size[l] >= MIN_REGION && sum[l] < 0.0;
    /* The components' sizes only when a region may turn (mostly none: the
     * labelling is a serial walk over the whole mesh). */
    if (any && !whole) {
        for (size_t t = 0; t < nt; t++)
            in[t] = 1;
        if (!(comp = tsl_alloc_array(nt, sizeof *comp))) {
            st = TESSEL_ERR_NOMEM;
            goto done;
        }
        uint32_t ncomp = label_sets(nb, nt, in, comp, queue);
        if (!(csize = tsl_calloc_array((size_t)ncomp + 1, sizeof *csize))) {
            st = TESSEL_ERR_NOMEM;
            goto done;
        }
        for (size_t t = 0; t < nt; t++)
            csize[comp[t]]++;
    }
    for (size_t t = 0; any && t < nt; t++) {
        uint32_t l = label[t];
        if (l != NONE && size[l] >= MIN_REGION && sum[l] < 0.0 &&
            (whole || 2 * size[l] < csize[comp[t]]))
            mark[t] = 1;
    }
    /* The region's rim: triangles with a neighbour that stays as it is. */
    for (size_t t = 0; t < nt; t++) {
        if (mark[t] != 1)
            continue;
        (*flipped)++;
        for (int i = 0; i < 3; i++) {
            uint32_t y = nb[3 * t + (size_t)i];
            if (y != NONE && mark[y] == 0)
                mark[t] = 2;
        }
    }
    st = TESSEL_OK;
done:
    free(nb);
    free(label);
    free(comp);
    free(queue);
    free(vote);
    free(next);
    free(in);
    free(size);
    free(csize);
    free(sum);
    return st;
}

tessel_status tsl_orient_check(const float *xyz, size_t nv, const uint32_t *tri, size_t nt,
                               int threads, uint8_t *mark, size_t *flipped)
{
    *flipped = 0;
    memset(mark, 0, nt);
    if (nt < 2 * MIN_REGION)
        return TESSEL_OK;
    if (nt > UINT32_MAX)
        return TESSEL_ERR_LIMIT;
    ray_grid g = {0};
    float *raw = tsl_alloc_array(nt, sizeof *raw);
    tessel_status st = raw ? grid_build(&g, xyz, tri, nt, threads) : TESSEL_ERR_NOMEM;
    if (st == TESSEL_OK) {
        ptrdiff_t n = (ptrdiff_t)nt;
        uint32_t stride = (uint32_t)((nt + RAY_BUDGET - 1) / RAY_BUDGET);
#pragma omp parallel for schedule(dynamic, 256) num_threads(tsl_threads(threads))
        for (ptrdiff_t t = 0; t < n; t++) {
            int c = mix((uint32_t)t) % stride ? -1 : crossings(&g, xyz, tri, (uint32_t)t);
            raw[t] = c < 0 ? 0.0f : c % 2 ? -1.0f : 1.0f;
        }
    }
    free(g.start);
    free(g.items);
    if (st == TESSEL_OK)
        st = mark_regions(tri, nt, nv, raw, false, threads, mark, flipped);
    free(raw);
    return st;
}

bool tsl_normals_signed(const float *normals, const uint32_t *tri, size_t nt)
{
    size_t opposite = 0;
    for (size_t t = 0; t < nt; t++)
        for (int i = 0; i < 3; i++) {
            const float *a = normals + 3 * (size_t)tri[3 * t + (size_t)i];
            const float *b = normals + 3 * (size_t)tri[3 * t + (size_t)(i + 1) % 3];
            opposite += a[0] * b[0] + a[1] * b[1] + a[2] * b[2] < 0.0f;
        }
    return opposite * UNSIGNED_SHARE < 3 * nt;
}

tessel_status tsl_orient_check_toward(const float *xyz, size_t nv, const uint32_t *tri,
                                      size_t nt, const float *normals,
                                      const double *viewpoint, int threads, uint8_t *mark,
                                      size_t *flipped)
{
    *flipped = 0;
    memset(mark, 0, nt);
    if (nt < 2 * MIN_REGION)
        return TESSEL_OK;
    if (nt > UINT32_MAX)
        return TESSEL_ERR_LIMIT;
    float *raw = tsl_alloc_array(nt, sizeof *raw);
    if (!raw)
        return TESSEL_ERR_NOMEM;
    ptrdiff_t n = (ptrdiff_t)nt;
#pragma omp parallel for schedule(static) num_threads(tsl_threads(threads))
    for (ptrdiff_t t = 0; t < n; t++) {
        const uint32_t *v = tri + 3 * (size_t)t;
        double p[3][3], u[3], w[3], nn[3], ref[3] = {0.0, 0.0, 0.0};
        tri_points(xyz, v, p);
        tsl_sub(p[1], p[0], u);
        tsl_sub(p[2], p[0], w);
        tsl_cross(u, w, nn);
        for (int i = 0; i < 3; i++)
            for (int k = 0; k < 3; k++)
                ref[k] += normals ? (double)normals[3 * (size_t)v[i] + (size_t)k]
                                  : viewpoint[k] - p[i][k];
        double d = tsl_dot(nn, ref);
        raw[t] = d > 0.0 ? 1.0f : d < 0.0 ? -1.0f : 0.0f;
    }
    tessel_status st = mark_regions(tri, nt, nv, raw, true, threads, mark, flipped);
    free(raw);
    return st;
}

size_t tsl_orient_apply(const uint32_t *tri, size_t nt, const uint8_t *mark, uint32_t *out)
{
    size_t kept = 0;
    for (size_t t = 0; t < nt; t++) {
        if (mark[t] == 2)
            continue;
        /* Read before writing: out[kept] may be tri[t] or before it. */
        uint32_t a = tri[3 * t], b = tri[3 * t + 1], c = tri[3 * t + 2];
        uint32_t *w = out + 3 * kept++;
        w[0] = a;
        w[1] = mark[t] ? c : b;
        w[2] = mark[t] ? b : c;
    }
    return kept;
}
