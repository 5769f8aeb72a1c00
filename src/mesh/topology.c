/* Mesh topology shared by the methods: the corners of each vertex, the
 * removal of triangles that leave a vertex with more than one fan, and
 * connected components by shared vertices. */
#include "mesh/mesh.h"

#include <stdlib.h>
#include <string.h>

tessel_status tsl_vertex_corners(const uint32_t *tri, size_t nt, size_t nv, uint32_t **start,
                                 uint32_t **corner)
{
    uint32_t *s = tsl_calloc_array(nv + 1, sizeof *s);
    uint32_t *c = tsl_alloc_array(3 * nt + 1, sizeof *c);
    if (!s || !c) {
        free(s);
        free(c);
        return TESSEL_ERR_NOMEM;
    }
    for (size_t i = 0; i < 3 * nt; i++)
        s[tri[i] + 1]++;
    for (size_t v = 0; v < nv; v++)
        s[v + 1] += s[v];
    for (size_t i = 0; i < 3 * nt; i++)
        c[s[tri[i]]++] = (uint32_t)i;
    /* The fill advanced every start to the next vertex's; shift back. */
    memmove(s + 1, s, nv * sizeof *s);
    s[0] = 0;
    *start = s;
    *corner = c;
    return TESSEL_OK;
}

tessel_status tsl_single_fans(size_t n, uint32_t *tri, size_t *count, uint8_t *touched)
{
    size_t nt = *count;
    uint32_t *start = NULL, *corner = NULL;
    uint8_t *alive = tsl_alloc_array(nt, sizeof *alive);
    uint32_t *todo = tsl_alloc_array(n, sizeof *todo);
    uint32_t *later = tsl_alloc_array(n, sizeof *later);
    if (!alive || !todo || !later || tsl_vertex_corners(tri, nt, n, &start, &corner)) {
        free(alive);
        free(todo);
        free(later);
        return TESSEL_ERR_NOMEM;
    }
    memset(alive, 1, nt);
    size_t ntodo = 0;
    for (size_t v = 0; v < n; v++)
        if (touched[v])
            todo[ntodo++] = (uint32_t)v;
    while (ntodo) {
        /* Each round judges its vertices on the triangles alive when it
         * starts, then drops: dropping at one vertex as soon as it is seen
         * would change what the next one sees, and more pieces get cut off
         * (man.ply, greedy's repair: 24 components against 17). */
        size_t nbad = 0;
        for (size_t q = 0; q < ntodo; q++) {
            uint32_t v = todo[q];
            touched[v] = 0;
            unsigned border = 0;
            for (uint32_t a = start[v]; a < start[v + 1]; a++) {
                uint32_t c = corner[a], t = c / 3;
                if (!alive[t])
                    continue;
                uint32_t after = tri[3 * t + (c + 1) % 3];
                bool twin = false;
                for (uint32_t b = start[v]; b < start[v + 1] && !twin; b++) {
                    uint32_t d = corner[b], u = d / 3;
                    twin = alive[u] && tri[3 * u + (d + 2) % 3] == after;
                }
                border += !twin;
            }
            if (border > 1)
                todo[nbad++] = v;
        }
        size_t next = 0;
        for (size_t q = 0; q < nbad; q++) {
            uint32_t v = todo[q];
            for (uint32_t a = start[v]; a < start[v + 1]; a++) {
                uint32_t t = corner[a] / 3;
                if (!alive[t])
                    continue;
                alive[t] = 0;
                for (int i = 0; i < 3; i++) {
                    uint32_t w = tri[3 * t + i];
                    if (!touched[w]) {
                        touched[w] = 1;
                        later[next++] = w;
                    }
                }
            }
        }
        uint32_t *swap = todo;
        todo = later;
        later = swap;
        ntodo = next;
    }
    size_t kept = 0;
    for (size_t t = 0; t < nt; t++)
        if (alive[t]) {
            memmove(tri + 3 * kept, tri + 3 * t, 3 * sizeof *tri);
            kept++;
        }
    *count = kept;
    free(start);
    free(corner);
    free(alive);
    free(todo);
    free(later);
    return TESSEL_OK;
}

void tsl_vertex_components(const uint32_t *tri, size_t nt, size_t nv, uint32_t *root)
{
    for (size_t v = 0; v < nv; v++)
        root[v] = (uint32_t)v;
    for (size_t t = 0; t < nt; t++) {
        const uint32_t *c = tri + 3 * t;
        if (c[0] == TESSEL_NONE)
            continue;
        tsl_uf_unite(root, c[0], c[1]);
        tsl_uf_unite(root, c[0], c[2]);
    }
    for (size_t v = 0; v < nv; v++)
        root[v] = tsl_uf_find(root, (uint32_t)v);
}

tessel_status tsl_triangle_components(const uint32_t *tri, size_t nt, size_t nv, uint32_t *comp,
                                      size_t *ncomp)
{
    uint32_t *root = tsl_alloc_array(nv + 1, sizeof *root);
    uint32_t *label = tsl_alloc_array(nv + 1, sizeof *label);
    *ncomp = 0;
    if (!root || !label) {
        free(root);
        free(label);
        return TESSEL_ERR_NOMEM;
    }
    tsl_vertex_components(tri, nt, nv, root);
    for (size_t v = 0; v < nv; v++)
        label[v] = TESSEL_NONE;
    for (size_t t = 0; t < nt; t++) {
        uint32_t r = root[tri[3 * t]];
        if (label[r] == TESSEL_NONE)
            label[r] = (uint32_t)(*ncomp)++;
        comp[t] = label[r];
    }
    free(root);
    free(label);
    return TESSEL_OK;
}

void tsl_open_fans(const uint32_t *tri, size_t nt, size_t nv, uint64_t *sum)
{
    memset(sum, 0, nv * sizeof *sum);
    for (size_t t = 0; t < nt; t++)
        for (int k = 0; k < 3; k++) {
            uint32_t a = tri[3 * t + (size_t)k], b = tri[3 * t + (size_t)(k + 1) % 3];
            sum[a] += tsl_mix64(b);
            sum[b] -= tsl_mix64(a);
        }
}

tessel_status tsl_mesh_counts(const uint32_t *tri, size_t nt, size_t nv, uint8_t *used,
                              size_t *boundary, size_t *components)
{
    uint64_t *sum = tsl_alloc_array(nv + 1, sizeof *sum);
    uint32_t *root = tsl_alloc_array(nv + 1, sizeof *root);
    if (!sum || !root) {
        free(sum);
        free(root);
        return TESSEL_ERR_NOMEM;
    }
    tsl_open_fans(tri, nt, nv, sum);
    tsl_vertex_components(tri, nt, nv, root);
    memset(used, 0, nv);
    for (size_t i = 0; i < 3 * nt; i++)
        used[tri[i]] = 1;
    *boundary = *components = 0;
    for (size_t v = 0; v < nv; v++) {
        *boundary += sum[v] != 0;
        *components += used[v] && root[v] == v;
    }
    free(sum);
    free(root);
    return TESSEL_OK;
}
