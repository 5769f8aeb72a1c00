/* Orientation check by ray parity, for meshes of closed objects (beyond
 * Mederos, Velho & de Figueiredo 2003; used by the smooth pipeline and by
 * the greedy projection, src/greedy/held.c).
 *
 * The advancing front carries a component's orientation from triangle to
 * triangle (section 2.4). Where two sheets touch closer than the
 * representatives' spacing (a hand against a thigh) it can step from one
 * onto the other as if they were one sheet, and mesh the whole limb behind
 * the step inside out. Locally the flipped limb is flawless; only a global
 * test sees it. A ray from a triangle's centroid towards the side its
 * normal points to crosses a closed surface an odd number of times exactly
 * when the normal points inward. Every triangle votes so; the votes are
 * averaged over a few rings of neighbours (a ray through a hole
 * miscounts); a
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
/* Averaging rounds over edge neighbours. */
#define SMOOTH_ROUNDS 12
/* Smaller inward regions are left alone: too few rays to trust. */
#define MIN_REGION 32
/* Rays cast at most: larger meshes cast from a hashed sample of their
 * triangles, and the averaging carries the votes to the rest; a region
 * about to turn is judged again on the rays of all its triangles. */
#define RAY_BUDGET 65536
/* A second ray goes along the next axis when the normal is at least this
 * much along it (closer to the surface, a ray runs along it). */
#define SECOND_RAY 0.25
/* Normals whose signs disagree across more than 1 / UNSIGNED_SHARE of the
 * mesh's edges carry no side (unoriented normals: half of them). Oriented
 * ones, even from noisy points, disagree across a few percent: 0-6.4% on
 * the data files with tessel's normals. */
#define UNSIGNED_SHARE 5

/* A ray of the sample: from a triangle's centroid along the axis nearest
 * its normal (or the next one: second), towards the side the normal
 * points to (dir +1 or -1). Any direction on that side gives the parity
 * of a closed surface; two that disagree show a hole on the way (noisy
 * clouds: elephant.pd.n05.ply's smooth mesh 14 -> 0 boundary edges). Along
 * an axis, the rays' feet
 * (their other two coordinates) go in a 2D grid, and each triangle finds
 * the few rays that can cross it there. The mesh needs no index of its own
 * (10^7 points: a 3D grid of every triangle took 1.5 s for 65,536 rays). */
typedef struct ray {
    double o[3];
    uint32_t tri, crossings;
    int axis, dir, second;
} ray;

/* The rays along one axis k, by the cell of their foot (u, v) = the
 * coordinates (k + 1) % 3 and (k + 2) % 3: a uniform grid over the feet's
 * box, CSR. */
typedef struct ray_feet {
    double lo[2], inv_cell;
    int n[2];
    uint32_t *start, *items;
    double *uv; /* the feet in the order of items */
} ray_feet;

/* Largest grid side of the feet (the cells follow their count). */
#define FEET_SIDE 4096

static void tri_points(const float *xyz, const uint32_t *v, double p[3][3])
{
    for (int i = 0; i < 3; i++)
        tsl_load(xyz + 3 * (size_t)v[i], p[i]);
}

static int clampi(double x, int n)
{
    return x < 0.0 ? 0 : x >= (double)n ? n - 1 : (int)x;
}

static tessel_status feet_build(ray_feet *f, const ray *rays, const uint32_t *ids, size_t m,
                                int k)
{
    int ku = (k + 1) % 3, kv = (k + 2) % 3;
    double hi[2] = {-INFINITY, -INFINITY};
    f->lo[0] = f->lo[1] = INFINITY;
    for (size_t i = 0; i < m; i++) {
        const double *o = rays[ids[i]].o;
        f->lo[0] = fmin(f->lo[0], o[ku]);
        f->lo[1] = fmin(f->lo[1], o[kv]);
        hi[0] = fmax(hi[0], o[ku]);
        hi[1] = fmax(hi[1], o[kv]);
    }
    /* About one foot a cell over the box. */
    double w = hi[0] - f->lo[0], h = hi[1] - f->lo[1];
    double cell = sqrt(fmax(w * h, fmax(w, h) * fmax(w, h) / (double)FEET_SIDE) / (double)m);
    if (!(cell > 0.0))
        cell = 1.0;
    f->inv_cell = 1.0 / cell;
    f->n[0] = clampi(w * f->inv_cell + 1.0, FEET_SIDE) + 1;
    f->n[1] = clampi(h * f->inv_cell + 1.0, FEET_SIDE) + 1;
    size_t cells = (size_t)f->n[0] * (size_t)f->n[1];
    f->start = tsl_calloc_array(cells + 1, sizeof *f->start);
    f->items = tsl_alloc_array(m + 1, sizeof *f->items);
    f->uv = tsl_alloc_array(2 * m + 1, sizeof *f->uv);
    if (!f->start || !f->items || !f->uv)
        return TESSEL_ERR_NOMEM;
    size_t *cell_of = tsl_alloc_array(m + 1, sizeof *cell_of);
    if (!cell_of)
        return TESSEL_ERR_NOMEM;
    for (size_t i = 0; i < m; i++) {
        const double *o = rays[ids[i]].o;
        cell_of[i] = (size_t)clampi((o[kv] - f->lo[1]) * f->inv_cell, f->n[1]) * (size_t)f->n[0] +
                     (size_t)clampi((o[ku] - f->lo[0]) * f->inv_cell, f->n[0]);
        f->start[cell_of[i] + 1]++;
    }
    for (size_t c = 0; c < cells; c++)
        f->start[c + 1] += f->start[c];
    for (size_t i = 0; i < m; i++)
        f->items[f->start[cell_of[i]]++] = ids[i];
    for (size_t i = 0; i < m; i++) {
        f->uv[2 * i] = rays[f->items[i]].o[ku];
        f->uv[2 * i + 1] = rays[f->items[i]].o[kv];
    }
    /* The fill advanced every start to the next cell's; shift back. */
    memmove(f->start + 1, f->start, cells * sizeof *f->start);
    f->start[0] = 0;
    free(cell_of);
    return TESSEL_OK;
}

/* Side of point q of the directed line a -> b, as tsl_orient2d, with q
 * moved by (e, e^2) for an infinitesimal e when it lies on the line
 * (simulation of simplicity): a foot on an edge shared by two triangles
 * lies in exactly one of them, and a ray through a vertex crosses once. */
static int side(const double a[2], const double b[2], const double q[2], double *o)
{
    *o = tsl_orient2d(a, b, q);
    if (*o != 0.0)
        return *o > 0.0 ? 1 : -1;
    if (a[1] != b[1])
        return a[1] > b[1] ? 1 : -1;
    return b[0] > a[0] ? 1 : b[0] < a[0] ? -1 : 0;
}

/* Counts on rays r of the feet f (axis k) that triangle x (points p) crosses
 * ahead of their origin. */
static void cross_rays(const ray_feet *f, ray *rays, int k, uint32_t x, const double p[3][3])
{
    int ku = (k + 1) % 3, kv = (k + 2) % 3;
    double a[3][2], lo[2], hi[2];
    for (int i = 0; i < 3; i++) {
        a[i][0] = p[i][ku];
        a[i][1] = p[i][kv];
    }
    for (int j = 0; j < 2; j++) {
        lo[j] = a[0][j] < a[1][j] ? a[0][j] : a[1][j];
        lo[j] = a[2][j] < lo[j] ? a[2][j] : lo[j];
        hi[j] = a[0][j] > a[1][j] ? a[0][j] : a[1][j];
        hi[j] = a[2][j] > hi[j] ? a[2][j] : hi[j];
    }
    double area = NAN; /* when a foot is in the box */
    int c0[2], c1[2];
    for (int j = 0; j < 2; j++) {
        double u0 = (lo[j] - f->lo[j]) * f->inv_cell, u1 = (hi[j] - f->lo[j]) * f->inv_cell;
        if (u1 < 0.0 || u0 >= (double)f->n[j])
            return;
        c0[j] = clampi(u0, f->n[j]);
        c1[j] = clampi(u1, f->n[j]);
    }
    for (int cv = c0[1]; cv <= c1[1]; cv++)
        for (int cu = c0[0]; cu <= c1[0]; cu++) {
            size_t c = (size_t)cv * (size_t)f->n[0] + (size_t)cu;
            for (uint32_t e = f->start[c]; e < f->start[c + 1]; e++) {
                const double *q = f->uv + 2 * (size_t)e;
                if (q[0] < lo[0] || q[0] > hi[0] || q[1] < lo[1] || q[1] > hi[1])
                    continue;
                ray *r = &rays[f->items[e]];
                if (r->tri == x)
                    continue;
                if (isnan(area))
                    area = tsl_orient2d(a[0], a[1], a[2]);
                if (area == 0.0) /* edge-on: the rays along k graze it */
                    return;
                double w[3];
                int s0 = side(a[1], a[2], q, &w[0]);
                if (side(a[2], a[0], q, &w[1]) != s0 || side(a[0], a[1], q, &w[2]) != s0)
                    continue;
                /* The crossing's coordinate along k, barycentric. */
                double h = (w[0] * p[0][k] + w[1] * p[1][k] + w[2] * p[2][k]) / area;
                if ((h - r->o[k]) * (double)r->dir > 0.0) {
#pragma omp atomic
                    r->crossings++;
                }
            }
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

/* Raw votes (+1 out, -1 in, 0 none) into raw[t] of the triangles t that
 * cast rays: those with from[t] (all when from is NULL) whose place
 * mix(t) is a multiple of stride. Every triangle of the mesh is tested
 * against every ray. */
static tessel_status cast(const float *xyz, const uint32_t *tri, size_t nt, const uint8_t *from,
                          uint32_t stride, int threads, float *raw)
{
    size_t nr = 0;
    for (size_t t = 0; t < nt; t++)
        nr += (!from || from[t]) && mix((uint32_t)t) % stride == 0;
    ray *rays = tsl_alloc_array(2 * nr + 1, sizeof *rays);
    uint32_t *ids = tsl_alloc_array(2 * nr + 1, sizeof *ids);
    ray_feet feet[3];
    memset(feet, 0, sizeof feet);
    size_t along[3] = {0, 0, 0};
    tessel_status st = rays && ids ? TESSEL_OK : TESSEL_ERR_NOMEM;
    nr = 0;
    for (size_t t = 0; st == TESSEL_OK && t < nt; t++) {
        double p[3][3], u[3], w[3], d[3];
        if ((from && !from[t]) || mix((uint32_t)t) % stride)
            continue;
        tri_points(xyz, tri + 3 * t, p);
        tsl_sub(p[1], p[0], u);
        tsl_sub(p[2], p[0], w);
        tsl_cross(u, w, d);
        if (!tsl_normalize(d))
            continue; /* degenerate: no vote */
        int k = fabs(d[0]) >= fabs(d[1]) ? (fabs(d[0]) >= fabs(d[2]) ? 0 : 2)
                                         : (fabs(d[1]) >= fabs(d[2]) ? 1 : 2);
        int k2 = (k + 1) % 3, k3 = (k + 2) % 3;
        if (fabs(d[k3]) > fabs(d[k2]))
            k2 = k3;
        for (int j = 0; j < 2; j++) {
            int a = j ? k2 : k;
            if (j && !(fabs(d[a]) > SECOND_RAY))
                break;
            ray *r = &rays[nr++];
            for (int i = 0; i < 3; i++)
                r->o[i] = (p[0][i] + p[1][i] + p[2][i]) / 3.0;
            r->tri = (uint32_t)t;
            r->crossings = 0;
            r->axis = a;
            r->dir = d[a] > 0.0 ? 1 : -1;
            r->second = j;
            along[a]++;
        }
    }
    for (int k = 0; k < 3 && st == TESSEL_OK; k++) {
        size_t m = 0;
        for (size_t i = 0; i < nr; i++)
            if (rays[i].axis == k)
                ids[m++] = (uint32_t)i;
        if (m)
            st = feet_build(&feet[k], rays, ids, m, k);
    }
    if (st == TESSEL_OK) {
        ptrdiff_t n = (ptrdiff_t)nt;
#pragma omp parallel for schedule(dynamic, 4096) num_threads(tsl_threads(threads))
        for (ptrdiff_t t = 0; t < n; t++) {
            double p[3][3];
            tri_points(xyz, tri + 3 * t, p);
            for (int k = 0; k < 3; k++)
                if (along[k])
                    cross_rays(&feet[k], rays, k, (uint32_t)t, p);
        }
        /* A second ray that disagrees withdraws the vote. */
        for (size_t i = 0; i < nr; i++) {
            float v = rays[i].crossings % 2 ? -1.0f : 1.0f;
            raw[rays[i].tri] = rays[i].second && raw[rays[i].tri] != v ? 0.0f : v;
        }
    }
    for (int k = 0; k < 3; k++) {
        free(feet[k].start);
        free(feet[k].items);
        free(feet[k].uv);
    }
    free(rays);
    free(ids);
    return st;
}

/* From the raw votes (+1 out, -1 in, 0 none): the votes averaged over
 * SMOOTH_ROUNDS rings of edge neighbours, the connected regions voting in
 * marked for flipping when they hold at least MIN_REGION triangles, more
 * inward raw votes than outward (with recount, the points: more inward
 * votes cast again from all their triangles) and (unless whole) less than
 * half of their component, and their rims marked for dropping (see the
 * header). */
static tessel_status mark_regions(const uint32_t *tri, size_t nt, size_t nv, const float *raw,
                                  bool whole, const float *recount, int threads, uint8_t *mark,
                                  size_t *flipped)
{
    if (nt >= UINT32_MAX) /* triangle ids are uint32_t, NONE the largest */
        return TESSEL_ERR_LIMIT;
    /* Averages of votes none of which is inward are not inward: then no
     * region turns, and the neighbours and rounds over the whole mesh are
     * not needed (a clean 10^7-point sample: no inward vote, 1.6 s). */
    bool inward = false;
    for (size_t t = 0; t < nt && !inward; t++)
        inward = raw[t] < 0.0f;
    if (!inward)
        return TESSEL_OK;
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
    if (any && recount) {
        /* From a sample of rays a region can rest on one triangle's vote,
         * and a flap of the mesh folded over that triangle (at a crease,
         * before the repair) makes both its rays cross an odd number of
         * times: a 10^6 sample of knot2.gt.ply turned 57 good triangles
         * so. Every triangle of the regions votes again. */
        size_t m = 0;
        for (size_t t = 0; t < nt; t++) {
            in[t] = label[t] != NONE && size[label[t]] >= MIN_REGION && sum[label[t]] < 0.0;
            m += in[t];
        }
        free(vote);
        vote = tsl_calloc_array(nt, sizeof *vote);
        if (!vote) {
            st = TESSEL_ERR_NOMEM;
            goto done;
        }
        st = cast(recount, tri, nt, in, (uint32_t)((m + RAY_BUDGET - 1) / RAY_BUDGET), threads,
                  vote);
        if (st)
            goto done;
        memset(sum, 0, ((size_t)nset + 1) * sizeof *sum);
        for (size_t t = 0; t < nt; t++)
            if (in[t])
                sum[label[t]] += vote[t];
        any = false;
        for (uint32_t l = 0; l < nset; l++)
            any |= size[l] >= MIN_REGION && sum[l] < 0.0;
    }
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
    uint32_t stride = (uint32_t)((nt + RAY_BUDGET - 1) / RAY_BUDGET);
    float *raw = tsl_calloc_array(nt, sizeof *raw);
    tessel_status st = raw ? cast(xyz, tri, nt, NULL, stride, threads, raw) : TESSEL_ERR_NOMEM;
    if (st == TESSEL_OK)
        st = mark_regions(tri, nt, nv, raw, false, stride > 1 ? xyz : NULL, threads, mark,
                          flipped);
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
    tessel_status st = mark_regions(tri, nt, nv, raw, true, NULL, threads, mark, flipped);
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
