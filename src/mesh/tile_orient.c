/* Tiles meshed apart and oriented against each other before their seams
 * are closed: the tiles' components agree or disagree across the cuts by
 * the normals of their nearest triangles there (mesh.h,
 * tsl_orient_tiles). Used by the advancing front's tiles and greedy
 * projection's. */
#include "mesh/mesh.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* The sine of the shallowest angle between surface and cut that widens a
 * triangle's search (tsl_orient_tiles). */
#define SHALLOW_SIN 0.25

static double dmin(double a, double b) { return a < b ? a : b; }
static double dmax(double a, double b) { return a > b ? a : b; }

static void turn(uint32_t v[3])
{
    uint32_t tmp = v[1];
    v[1] = v[2];
    v[2] = tmp;
}

/* Agreement between two tile components: the sum of the dot products of
 * nearby triangles' normals across cuts. */
typedef struct tile_pair {
    uint32_t a, b; /* component ids, a < b */
    double w;
} tile_pair;

static int cmp_pair_ids(const void *pa, const void *pb)
{
    const tile_pair *x = pa, *y = pb;
    if (x->a != y->a)
        return x->a < y->a ? -1 : 1;
    return x->b < y->b ? -1 : (x->b > y->b);
}

static int cmp_pair_weight(const void *pa, const void *pb)
{
    const tile_pair *x = pa, *y = pb;
    double u = fabs(x->w), v = fabs(y->w);
    if (u != v)
        return u > v ? -1 : 1;
    return cmp_pair_ids(pa, pb);
}

/* Root of component c and, in *flip, whether c is reversed against it. */
static uint32_t parity_root(const uint32_t *up, const uint8_t *rel, uint32_t c, uint8_t *flip)
{
    *flip = 0;
    while (up[c] != c) {
        *flip ^= rel[c];
        c = up[c];
    }
    return c;
}

/* Parities of the components (rel to up, see parity_root) from their
 * pairs, strongest first, leaving out dropped components. */
static void spanning_parity(const tile_pair *pairs, size_t np, size_t ncomp, const uint8_t *drop,
                            uint32_t *up, uint8_t *rel)
{
    for (size_t c = 0; c < ncomp; c++) {
        up[c] = (uint32_t)c;
        rel[c] = 0;
    }
    for (size_t i = 0; i < np; i++) {
        if (drop[pairs[i].a] || drop[pairs[i].b])
            continue;
        uint8_t fa, fb;
        uint32_t ra = parity_root(up, rel, pairs[i].a, &fa);
        uint32_t rb = parity_root(up, rel, pairs[i].b, &fb);
        if (ra == rb)
            continue;
        uint32_t keep = ra < rb ? ra : rb, under = ra < rb ? rb : ra;
        up[under] = keep;
        rel[under] = (uint8_t)(fa ^ fb ^ (pairs[i].w < 0.0));
    }
}

tessel_status tsl_orient_tiles(uint32_t *tri, const uint32_t *comp, size_t count,
                                  size_t ncomp, const float *xyz, const float *dcut,
                                  const uint8_t *cut_axis, double near, double radius, size_t small,
                                  int threads, uint8_t *drop)
{
    size_t nl = 0;
    for (size_t t = 0; t < count; t++) {
        const uint32_t *v = tri + 3 * t;
        nl += dcut[v[0]] < near || dcut[v[1]] < near || dcut[v[2]] < near;
    }
    uint32_t *list = tsl_alloc_array(nl + 1, sizeof *list);
    double *geo = tsl_alloc_array(7 * nl + 1, sizeof *geo); /* centroid, normal, radius */
    tile_pair *pairs = tsl_alloc_array(nl + 1, sizeof *pairs);
    uint32_t *best_of = tsl_alloc_array(nl + 1, sizeof *best_of);
    uint32_t *up = tsl_alloc_array(ncomp + 1, sizeof *up);
    uint8_t *rel = tsl_calloc_array(ncomp + 1, sizeof *rel);
    size_t *size = tsl_calloc_array(ncomp + 1, sizeof *size);
    double *total = tsl_alloc_array(ncomp + 1, sizeof *total);
    double *agree = tsl_alloc_array(ncomp + 1, sizeof *agree);
    tsl_trigrid grid;
    memset(&grid, 0, sizeof grid);
    tessel_status st = TESSEL_ERR_NOMEM;
    if (!list || !geo || !pairs || !best_of || !up || !rel || !size || !total || !agree)
        goto done;
    memset(drop, 0, ncomp);
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    nl = 0;
    for (size_t t = 0; t < count; t++) {
        const uint32_t *v = tri + 3 * t;
        if (!(dcut[v[0]] < near || dcut[v[1]] < near || dcut[v[2]] < near))
            continue;
        double p[3][3], *g = geo + 7 * nl;
        for (int i = 0; i < 3; i++)
            tsl_load(xyz + 3 * (size_t)v[i], p[i]);
        tsl_tri_normal(p[0], p[1], p[2], g + 3);
        uint32_t nearest = v[0];
        for (int i = 1; i < 3; i++)
            if (dcut[v[i]] < dcut[nearest])
                nearest = v[i];
        double along = g[3 + cut_axis[nearest]];
        g[6] = radius / dmax(sqrt(dmax(0.0, 1.0 - along * along)), SHALLOW_SIN);
        for (int c = 0; c < 3; c++) {
            g[c] = (p[0][c] + p[1][c] + p[2][c]) / 3.0;
            lo[c] = dmin(lo[c], g[c]);
            hi[c] = dmax(hi[c], g[c]);
        }
        list[nl++] = (uint32_t)t;
    }
    /* Cells of half the radius: a query meets a few cells (with cells of a
     * spacing, tens of thousands at the widest: most of the time went to
     * the empty ones). */
    if ((st = tsl_trigrid_init(&grid, lo, hi, 0.5 * radius)))
        goto done;
    for (size_t i = 0; i < nl; i++)
        if ((st = tsl_trigrid_insert(&grid, (uint32_t)i, geo + 7 * i, geo + 7 * i)))
            goto done;
    /* Each triangle's partner: the nearest centroid of another component,
     * along the surface (in parallel, each query with its own result). */
    bool nomem = false;
    ptrdiff_t count_l = (ptrdiff_t)nl;
#pragma omp parallel num_threads(tsl_threads(threads)) reduction(|| : nomem)
    {
        tsl_trigrid_hits hits;
        memset(&hits, 0, sizeof hits);
#pragma omp for schedule(dynamic, 1024)
        for (ptrdiff_t ii = 0; ii < count_l; ii++) {
            size_t i = (size_t)ii;
            const double *g = geo + 7 * i;
            double blo[3], bhi[3];
            for (int c = 0; c < 3; c++) {
                blo[c] = g[c] - g[6];
                bhi[c] = g[c] + g[6];
            }
            best_of[i] = TESSEL_NONE;
            if (nomem || tsl_trigrid_hits_begin(&hits) ||
                tsl_trigrid_collect(&grid, blo, bhi, &hits)) {
                nomem = true;
                continue;
            }
            double best = g[6] * g[6];
            for (size_t f = 0; f < hits.count; f++) {
                uint32_t j = hits.found[f];
                if (comp[list[j]] == comp[list[i]])
                    continue;
                double d[3], h;
                tsl_sub(geo + 7 * (size_t)j, g, d);
                double d2 = tsl_dot(d, d);
                /* Only along the surface: the other side of a thin part
                 * lies off the tangent plane and faces the other way. */
                h = tsl_dot(d, g + 3);
                if (4.0 * h * h > d2)
                    continue;
                if (d2 < best || (d2 == best && j < best_of[i])) {
                    best = d2;
                    best_of[i] = j;
                }
            }
        }
        tsl_trigrid_hits_free(&hits);
    }
    if (nomem) {
        st = TESSEL_ERR_NOMEM;
        goto done;
    }
    size_t np = 0;
    for (size_t i = 0; i < nl; i++) {
        uint32_t j = best_of[i];
        if (j == TESSEL_NONE)
            continue;
        uint32_t ca = comp[list[i]], cb = comp[list[j]];
        pairs[np].a = ca < cb ? ca : cb;
        pairs[np].b = ca < cb ? cb : ca;
        pairs[np].w = tsl_dot(geo + 7 * i + 3, geo + 7 * (size_t)j + 3);
        np++;
    }
    qsort(pairs, np, sizeof *pairs, cmp_pair_ids);
    size_t merged = 0;
    for (size_t i = 0; i < np; i++) {
        if (merged && pairs[merged - 1].a == pairs[i].a && pairs[merged - 1].b == pairs[i].b)
            pairs[merged - 1].w += pairs[i].w;
        else
            pairs[merged++] = pairs[i];
    }
    qsort(pairs, merged, sizeof *pairs, cmp_pair_weight);
    /* A component whose pairs disagree with the forest by more than a
     * quarter of their weight is dropped too (its neighbours across the
     * cuts contradict each other: a fold, another sheet), and the forest
     * is built again without it. */
    for (int round = 0; round < 2; round++) {
        spanning_parity(pairs, merged, ncomp, drop, up, rel);
        if (round == 1)
            break;
        memset(total, 0, ncomp * sizeof *total);
        memset(agree, 0, ncomp * sizeof *agree);
        for (size_t i = 0; i < merged; i++) {
            if (drop[pairs[i].a] || drop[pairs[i].b])
                continue;
            uint8_t fa, fb;
            parity_root(up, rel, pairs[i].a, &fa);
            parity_root(up, rel, pairs[i].b, &fb);
            double w = fa == fb ? pairs[i].w : -pairs[i].w;
            total[pairs[i].a] += fabs(w);
            total[pairs[i].b] += fabs(w);
            agree[pairs[i].a] += w;
            agree[pairs[i].b] += w;
        }
        for (size_t c = 0; c < ncomp; c++)
            if (agree[c] < 0.5 * total[c])
                drop[c] = 1;
    }
    /* Small pieces at a cut (a tile's corner of the surface, the tip of a
     * thin part) relay the orientation between their neighbours, then are
     * left to the front that closes the seams, which joins them better. */
    for (size_t t = 0; t < count; t++)
        size[comp[t]]++;
    for (size_t t = 0; t < count; t++) {
        const uint32_t *v = tri + 3 * t;
        if ((dcut[v[0]] < near || dcut[v[1]] < near || dcut[v[2]] < near) &&
            size[comp[t]] < small)
            drop[comp[t]] = 1;
    }
    for (size_t t = 0; t < count; t++) {
        uint8_t f;
        parity_root(up, rel, comp[t], &f);
        if (f)
            turn(tri + 3 * t);
    }
    st = TESSEL_OK;
done:
    tsl_trigrid_free(&grid);
    free(list);
    free(geo);
    free(pairs);
    free(best_of);
    free(up);
    free(rel);
    free(size);
    free(total);
    free(agree);
    return st;
}

