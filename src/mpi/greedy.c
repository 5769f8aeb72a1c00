/* Greedy projection over MPI (include/tessel_mpi.h, docs/mpi.md): process 0
 * meshes as one process does (src/greedy/tiles.c) with a runner that sends
 * each tile's points to process k mod size, which meshes the tile
 * (tsl_gp_tile_mesh_cloud) and sends back its triangles in the tile's
 * numbering. The seams' groups of each level go out and come back the same
 * way; process 0 then checks the orientation and flips the diagonals
 * alone: the same bytes for any number of processes. Out of core
 * (src/outofcore/) the same runner meshes each slab's tiles and seams. */
#include "greedy/greedy.h"
#include "mpi/mpi.h"
#include "tessel_mpi.h"

#include <stdlib.h>
#include <string.h>

/* ---- process 0 ---- */

/* One of process 0's own tiles. */
static tessel_status mesh_one(const void *job, size_t k)
{
    return tsl_gp_tile_mesh((const tsl_gp_tiles_job *)job, k, NULL);
}

/* Every other process's tiles, point by point in the tile's order, to it. */
static tessel_status send_tiles(const ranks *r, const tsl_gp_tiles_job *job)
{
    const tsl_tiles *cut = job->cut;
    size_t most = 0;
    for (size_t k = 0; k < job->count; k++)
        most = cut->start[k + 1] - cut->start[k] > most ? cut->start[k + 1] - cut->start[k] : most;
    float *buf = tsl_alloc_array(3 * most + 1, sizeof *buf);
    tessel_status st = tsl_mpi_agree(r->comm, buf ? TESSEL_OK : TESSEL_ERR_NOMEM);
    for (size_t k = 0; st == TESSEL_OK && k < job->count; k++) {
        if (tsl_mpi_owner(r, k) == 0)
            continue;
        const uint32_t *ids = cut->ids + cut->start[k];
        size_t m = cut->start[k + 1] - cut->start[k];
        for (int block = 0; block < 1 + (job->cloud->normals != NULL); block++) {
            const float *src = block ? job->cloud->normals : job->cloud->xyz;
            for (size_t i = 0; i < m; i++)
                memcpy(buf + 3 * i, src + 3 * (size_t)ids[i], 3 * sizeof *buf);
            tsl_mpi_move(r->comm, 0, tsl_mpi_owner(r, k), buf, 3 * m, MPI_FLOAT, sizeof *buf);
        }
    }
    free(buf);
    return st;
}

/* The other processes' tiles back: triangles (mapped from the tile's
 * order to the cloud's), summaries and fates. */
static tessel_status receive_tiles(const ranks *r, const tsl_gp_tiles_job *job)
{
    size_t nt = job->count;
    const tsl_tiles *cut = job->cut;
    uint64_t *counts = tsl_calloc_array(nt, sizeof *counts);
    if (tsl_mpi_agree(r->comm, counts ? TESSEL_OK : TESSEL_ERR_NOMEM) != TESSEL_OK) {
        free(counts);
        return TESSEL_ERR_NOMEM;
    }
    tsl_mpi_sum_counts(r, counts, nt);
    size_t most = 0;
    tessel_status mine = TESSEL_OK;
    for (size_t k = 0; k < nt && mine == TESSEL_OK; k++) {
        gp_collect *c = &job->parts[k];
        most = cut->start[k + 1] - cut->start[k] > most ? cut->start[k + 1] - cut->start[k] : most;
        if (tsl_mpi_owner(r, k) == 0 || !counts[k])
            continue;
        c->tris = tsl_alloc_array((size_t)counts[k], 3 * sizeof *c->tris);
        c->count = c->cap = c->tris ? (size_t)counts[k] : 0;
        mine = c->tris ? TESSEL_OK : TESSEL_ERR_NOMEM;
    }
    free(counts);
    uint8_t *fate = mine == TESSEL_OK ? tsl_alloc_array(most + 1, 1) : NULL;
    if ((mine = tsl_mpi_agree(r->comm, fate ? TESSEL_OK : TESSEL_ERR_NOMEM)) != TESSEL_OK) {
        free(fate);
        return mine;
    }
    for (size_t k = 0; k < nt; k++) {
        int from = tsl_mpi_owner(r, k);
        if (from == 0)
            continue;
        gp_collect *c = &job->parts[k];
        const uint32_t *ids = cut->ids + cut->start[k];
        size_t m = cut->start[k + 1] - cut->start[k];
        tsl_mpi_move(r->comm, from, 0, c->tris, 3 * c->count, MPI_UINT32_T, sizeof *c->tris);
        for (size_t i = 0; i < 3 * c->count; i++)
            c->tris[i] = ids[c->tris[i]];
        tsl_mpi_move(r->comm, from, 0, &job->sums[k], sizeof job->sums[k], MPI_BYTE, 1);
        tsl_mpi_move(r->comm, from, 0, fate, m, MPI_BYTE, 1);
        for (size_t i = 0; i < m; i++)
            job->fate[ids[i]] = fate[i];
    }
    free(fate);
    return TESSEL_OK;
}

/* Process 0's runner: the other processes' tiles sent to them, its own
 * meshed, theirs received; it then goes on alone (seams, orientation,
 * flips, output). */
static tessel_status run_ranks(void *ctx, const tsl_gp_tiles_job *job)
{
    const ranks *r = ctx;
    tessel_status st = tsl_progress(job->callbacks, "greedy", 0.0);
    const tessel_cloud *c = job->cloud;
    tiles_head h = {.status = (int32_t)st, .kind = TILES_GREEDY, .normals = c->normals != NULL,
                    .has_viewpoint = c->has_viewpoint, .count = job->count};
    memcpy(h.offset, c->offset, sizeof h.offset);
    memcpy(h.viewpoint, c->viewpoint, sizeof h.viewpoint);
    tsl_mpi_head(r, h);
    if (st != TESSEL_OK)
        return st;
    /* The tiles' parameters (tile_points 0, no existing triangles). */
    tessel_greedy_params tp = *job->params;
    MPI_Bcast(&tp, (int)sizeof tp, MPI_BYTE, 0, r->comm);
    uint64_t *start;
    if ((st = tsl_mpi_bcast_sizes(r, job->count, job->cut->start, &start)) != TESSEL_OK)
        return st;
    free(start);
    if ((st = send_tiles(r, job)) != TESSEL_OK)
        return st;
    st = tsl_mpi_each_mine(r, job->count, mesh_one, job);
    if ((st = tsl_mpi_agree(r->comm, st)) != TESSEL_OK)
        return st;
    if ((st = receive_tiles(r, job)) != TESSEL_OK)
        return st;
    return tsl_progress(job->callbacks, "greedy", 0.5);
}

/* ---- the other processes ---- */

/* A process's own tiles (or seam groups): their points as received, what
 * their fronts give. */
typedef struct own_tiles {
    size_t count;        /* tiles of this process */
    size_t *k;           /* their numbers */
    size_t *points;      /* their points' counts */
    tessel_cloud *cloud; /* their points, in the tile's order */
    gp_collect *parts;
    tessel_recon_summary *sums;
    uint8_t **fate;
} own_tiles;

static void own_free(own_tiles *o)
{
    for (size_t j = 0; j < o->count; j++) {
        if (o->cloud)
            tessel_cloud_free(&o->cloud[j]);
        if (o->parts)
            free(o->parts[j].tris);
        if (o->fate)
            free(o->fate[j]);
    }
    free(o->k);
    free(o->points);
    free(o->cloud);
    free(o->parts);
    free(o->sums);
    free(o->fate);
    memset(o, 0, sizeof *o);
}

/* Room for count own tiles. */
static tessel_status own_room(own_tiles *o, size_t count)
{
    o->count = count;
    o->k = tsl_calloc_array(count + 1, sizeof *o->k);
    o->points = tsl_calloc_array(count + 1, sizeof *o->points);
    o->cloud = tsl_calloc_array(count + 1, sizeof *o->cloud);
    o->parts = tsl_calloc_array(count + 1, sizeof *o->parts);
    o->sums = tsl_calloc_array(count + 1, sizeof *o->sums);
    o->fate = tsl_calloc_array(count + 1, sizeof *o->fate);
    return o->k && o->points && o->cloud && o->parts && o->sums && o->fate ? TESSEL_OK
                                                                           : TESSEL_ERR_NOMEM;
}

/* Own tile j is tile k of h, of m points: room for its points and fates. */
static tessel_status own_tile(own_tiles *o, size_t j, size_t k, size_t m, const tiles_head *h)
{
    tessel_cloud *c = &o->cloud[j];
    o->k[j] = k;
    o->points[j] = m;
    if (tessel_cloud_alloc(c, m, h->normals, 0) != TESSEL_OK ||
        !(o->fate[j] = tsl_alloc_array(m + 1, 1)))
        return TESSEL_ERR_NOMEM;
    memcpy(c->offset, h->offset, sizeof c->offset);
    memcpy(c->viewpoint, h->viewpoint, sizeof c->viewpoint);
    c->has_viewpoint = h->has_viewpoint;
    return TESSEL_OK;
}

/* Room for this process's tiles of h (starts: their point ranges). */
static tessel_status own_alloc(const ranks *r, const tiles_head *h, const uint64_t *start,
                               own_tiles *o)
{
    size_t nt = (size_t)h->count;
    tessel_status st =
        own_room(o, nt / (size_t)r->size + (nt % (size_t)r->size > (size_t)r->rank));
    for (size_t j = 0; st == TESSEL_OK && j < o->count; j++) {
        size_t k = (size_t)r->rank + j * (size_t)r->size;
        st = own_tile(o, j, k, (size_t)(start[k + 1] - start[k]), h);
    }
    return st;
}

/* The own tiles' results to process 0 (the other side of receive_tiles
 * and receive_groups): the triangle counts of all nt summed, then each
 * tile's triangles, summary and fates. */
static tessel_status own_return(const ranks *r, const own_tiles *o, size_t nt)
{
    uint64_t *counts = tsl_calloc_array(nt + 1, sizeof *counts);
    tessel_status st = tsl_mpi_agree(r->comm, counts ? TESSEL_OK : TESSEL_ERR_NOMEM);
    if (st == TESSEL_OK) {
        for (size_t j = 0; j < o->count; j++)
            counts[o->k[j]] = o->parts[j].count;
        tsl_mpi_sum_counts(r, counts, nt);
        st = tsl_mpi_agree(r->comm, TESSEL_OK); /* process 0's room */
    }
    for (size_t j = 0; st == TESSEL_OK && j < o->count; j++) {
        tsl_mpi_move(r->comm, r->rank, 0, o->parts[j].tris, 3 * o->parts[j].count,
                     MPI_UINT32_T, sizeof(uint32_t));
        tsl_mpi_move(r->comm, r->rank, 0, &o->sums[j], sizeof o->sums[j], MPI_BYTE, 1);
        tsl_mpi_move(r->comm, r->rank, 0, o->fate[j], o->points[j], MPI_BYTE, 1);
    }
    free(counts);
    return st;
}

/* Own tile j: its mesh; its points are freed once meshed. */
typedef struct own_ctx {
    own_tiles *o;
    tessel_greedy_params params; /* tile_points 0 */
} own_ctx;

static tessel_status mesh_own(const void *ctx, size_t j)
{
    const own_ctx *c = ctx;
    own_tiles *o = c->o;
    tessel_status st = tsl_gp_tile_mesh_cloud(&o->cloud[j], &c->params, NULL, &o->parts[j],
                                              o->fate[j], &o->sums[j]);
    tessel_cloud_free(&o->cloud[j]);
    return st;
}

/* A process other than 0: receives its tiles, meshes them, sends them back
 * (the other side of run_ranks). */
tessel_status tsl_mpi_serve_greedy(const ranks *r, const tiles_head *head)
{
    tiles_head h = *head;
    tessel_greedy_params params;
    MPI_Bcast(&params, (int)sizeof params, MPI_BYTE, 0, r->comm);
    params.existing = NULL; /* process 0's pointer: tiles have none */
    params.frozen = NULL;
    uint64_t *start = NULL;
    own_tiles o = {0};
    tessel_status st = tsl_mpi_bcast_sizes(r, (size_t)h.count, NULL, &start);
    if (st != TESSEL_OK)
        return st;
    st = tsl_mpi_agree(r->comm, own_alloc(r, &h, start, &o)); /* send_tiles' agreement */
    for (size_t j = 0; st == TESSEL_OK && j < o.count; j++) {
        size_t m = o.cloud[j].count;
        tsl_mpi_move(r->comm, 0, r->rank, o.cloud[j].xyz, 3 * m, MPI_FLOAT, sizeof(float));
        if (h.normals)
            tsl_mpi_move(r->comm, 0, r->rank, o.cloud[j].normals, 3 * m, MPI_FLOAT,
                       sizeof(float));
    }
    if (st == TESSEL_OK) {
        own_ctx c = {&o, params};
        c.params.tile_points = 0;
        st = tsl_mpi_agree(r->comm, tsl_mpi_each(r, o.count, mesh_own, &c));
    }
    if (st == TESSEL_OK)
        st = own_return(r, &o, (size_t)h.count);
    free(start);
    own_free(&o);
    return st;
}

/* ---- the seams: each level's groups as the tiles ---- */

/* Sizes of a level's groups for all: its points and its triangles that
 * resume the front, in turn (process 0 passes the job, the others NULL). */
static tessel_status bcast_group_sizes(const ranks *r, size_t count, const tsl_gp_seams_job *job,
                                       uint64_t **sizes)
{
    size_t *from = NULL;
    if (job) {
        from = tsl_alloc_array(2 * count + 1, sizeof *from);
        for (size_t i = 0; from && i < count; i++) {
            from[2 * i] = job->groups[i].m;
            from[2 * i + 1] = job->groups[i].ninside;
        }
        if (from)
            from[2 * count] = 0;
    }
    tessel_status st = tsl_mpi_agree(r->comm, !job || from ? TESSEL_OK : TESSEL_ERR_NOMEM);
    if (st == TESSEL_OK)
        st = tsl_mpi_bcast_sizes(r, 2 * count, from, sizes);
    free(from);
    return st;
}

/* Whether group i goes to another process: its own, and a front to run
 * (tsl_gp_front_over makes nothing of fewer than 3 points). */
static bool remote_group(const ranks *r, const uint64_t *sizes, size_t i)
{
    return tsl_mpi_owner(r, i) != 0 && sizes[2 * i] >= 3;
}

static tessel_status seam_one(const void *job, size_t i)
{
    const tsl_gp_seams_job *j = job;
    tsl_gp_seam_group_run(j, i, NULL);
    return j->groups[i].st;
}

/* The other processes' groups out: points (and normals), the triangles
 * that resume the front, the frozen flags. */
static tessel_status send_groups(const ranks *r, const tsl_gp_seams_job *job,
                                 const uint64_t *sizes)
{
    size_t most = 0;
    for (size_t i = 0; i < job->count; i++)
        most = job->groups[i].m > most ? job->groups[i].m : most;
    float *buf = tsl_alloc_array(3 * most + 1, sizeof *buf);
    uint8_t *fr = tsl_alloc_array(most + 1, 1);
    tessel_status st = tsl_mpi_agree(r->comm, buf && fr ? TESSEL_OK : TESSEL_ERR_NOMEM);
    const tessel_cloud *c = job->cloud;
    for (size_t i = 0; st == TESSEL_OK && i < job->count; i++) {
        if (!remote_group(r, sizes, i))
            continue;
        const gp_seam_group *g = &job->groups[i];
        int to = tsl_mpi_owner(r, i);
        for (int block = 0; block < 1 + (c->normals != NULL); block++) {
            const float *src = block ? c->normals : c->xyz;
            for (size_t j = 0; j < g->m; j++)
                memcpy(buf + 3 * j, src + 3 * (size_t)g->ids[j], 3 * sizeof *buf);
            tsl_mpi_move(r->comm, 0, to, buf, 3 * g->m, MPI_FLOAT, sizeof *buf);
        }
        tsl_mpi_move(r->comm, 0, to, g->inside, 3 * g->ninside, MPI_UINT32_T, sizeof *g->inside);
        for (size_t j = 0; j < g->m; j++)
            fr[j] = job->frozen[g->ids[j]];
        tsl_mpi_move(r->comm, 0, to, fr, g->m, MPI_BYTE, 1);
    }
    free(buf);
    free(fr);
    return st;
}

/* The other processes' groups back: triangles, summaries and fates, put
 * in the cloud's indices as a front over the whole cloud leaves them. */
static tessel_status receive_groups(const ranks *r, const tsl_gp_seams_job *job,
                                    const uint64_t *sizes)
{
    size_t ng = job->count, most = 0;
    uint64_t *counts = tsl_calloc_array(ng + 1, sizeof *counts);
    tessel_status st = tsl_mpi_agree(r->comm, counts ? TESSEL_OK : TESSEL_ERR_NOMEM);
    if (st != TESSEL_OK) {
        free(counts);
        return st;
    }
    tsl_mpi_sum_counts(r, counts, ng);
    tessel_status mine = TESSEL_OK;
    for (size_t i = 0; i < ng && mine == TESSEL_OK; i++) {
        gp_seam_group *g = &job->groups[i];
        most = g->m > most ? g->m : most;
        if (!remote_group(r, sizes, i) || !counts[i])
            continue;
        if (tsl_grow((void **)&g->more.tris, &g->more.cap, (size_t)counts[i],
                     3 * sizeof *g->more.tris))
            mine = TESSEL_ERR_NOMEM;
        g->more.count = (size_t)counts[i];
    }
    free(counts);
    uint8_t *fate = mine == TESSEL_OK ? tsl_alloc_array(most + 1, 1) : NULL;
    if ((st = tsl_mpi_agree(r->comm, fate ? TESSEL_OK : TESSEL_ERR_NOMEM)) != TESSEL_OK) {
        free(fate);
        return st;
    }
    for (size_t i = 0; i < ng; i++) {
        if (!remote_group(r, sizes, i))
            continue;
        gp_seam_group *g = &job->groups[i];
        int from = tsl_mpi_owner(r, i);
        tsl_mpi_move(r->comm, from, 0, g->more.tris, 3 * g->more.count, MPI_UINT32_T,
                     sizeof *g->more.tris);
        tsl_mpi_move(r->comm, from, 0, &g->sum, sizeof g->sum, MPI_BYTE, 1);
        tsl_mpi_move(r->comm, from, 0, fate, g->m, MPI_BYTE, 1);
        tsl_gp_front_back(g->ids, g->m, fate, &g->more, job->fate, job->made);
    }
    free(fate);
    return TESSEL_OK;
}

/* Process 0's runner of a level's groups: group i by process i mod size,
 * as the tiles. */
static tessel_status run_seams(void *ctx, const tsl_gp_seams_job *job)
{
    const ranks *r = ctx;
    const tessel_cloud *c = job->cloud;
    tiles_head h = {.status = TESSEL_OK, .kind = TILES_SEAMS, .normals = c->normals != NULL,
                    .has_viewpoint = c->has_viewpoint, .count = job->count};
    memcpy(h.offset, c->offset, sizeof h.offset);
    memcpy(h.viewpoint, c->viewpoint, sizeof h.viewpoint);
    tsl_mpi_head(r, h);
    tessel_greedy_params sp = *job->params;
    MPI_Bcast(&sp, (int)sizeof sp, MPI_BYTE, 0, r->comm);
    uint64_t *sizes = NULL;
    tessel_status st = bcast_group_sizes(r, job->count, job, &sizes);
    if (st == TESSEL_OK)
        st = send_groups(r, job, sizes);
    if (st == TESSEL_OK)
        st = tsl_mpi_agree(r->comm, tsl_mpi_each_mine(r, job->count, seam_one, job));
    if (st == TESSEL_OK)
        st = receive_groups(r, job, sizes);
    free(sizes);
    return st;
}

/* A process's own groups of a level: as own tiles, with the triangles that
 * resume each front and its frozen flags. */
typedef struct own_groups {
    own_tiles t;
    uint32_t **inside;
    uint8_t **frozen;
} own_groups;

static void groups_free(own_groups *o)
{
    for (size_t j = 0; j < o->t.count; j++) {
        if (o->inside)
            free(o->inside[j]);
        if (o->frozen)
            free(o->frozen[j]);
    }
    free(o->inside);
    free(o->frozen);
    own_free(&o->t);
    memset(o, 0, sizeof *o);
}

static tessel_status groups_alloc(const ranks *r, const tiles_head *h, const uint64_t *sizes,
                                  own_groups *o)
{
    size_t ng = (size_t)h->count, count = 0;
    for (size_t i = 0; i < ng; i++)
        count += tsl_mpi_owner(r, i) == r->rank && remote_group(r, sizes, i);
    tessel_status st = own_room(&o->t, count);
    o->inside = tsl_calloc_array(count + 1, sizeof *o->inside);
    o->frozen = tsl_calloc_array(count + 1, sizeof *o->frozen);
    if (!o->inside || !o->frozen)
        st = TESSEL_ERR_NOMEM;
    for (size_t i = 0, j = 0; st == TESSEL_OK && i < ng; i++) {
        if (tsl_mpi_owner(r, i) != r->rank || !remote_group(r, sizes, i))
            continue;
        size_t m = (size_t)sizes[2 * i], ni = (size_t)sizes[2 * i + 1];
        st = own_tile(&o->t, j, i, m, h);
        if (st == TESSEL_OK &&
            (!(o->inside[j] = tsl_alloc_array(3 * ni + 1, sizeof **o->inside)) ||
             !(o->frozen[j] = tsl_alloc_array(m, 1))))
            st = TESSEL_ERR_NOMEM;
        j++;
    }
    return st;
}

/* Own group j: its front; its points are freed once it has run. */
typedef struct groups_ctx {
    own_groups *o;
    const tessel_greedy_params *params;
    const uint64_t *sizes;
} groups_ctx;

static tessel_status group_run(const void *ctx, size_t j)
{
    const groups_ctx *c = ctx;
    own_groups *o = c->o;
    own_tiles *t = &o->t;
    size_t ni = (size_t)c->sizes[2 * t->k[j] + 1];
    tessel_status st = tsl_gp_front_local(&t->cloud[j], o->inside[j], ni, o->frozen[j], c->params,
                                          true, "greedy: seams", NULL, &t->parts[j], t->fate[j],
                                          &t->sums[j]);
    tessel_cloud_free(&t->cloud[j]);
    return st;
}

/* A process other than 0: its groups of a level in, their fronts run, the
 * results out (the other side of run_seams). */
tessel_status tsl_mpi_serve_seams(const ranks *r, const tiles_head *head)
{
    tessel_greedy_params params;
    MPI_Bcast(&params, (int)sizeof params, MPI_BYTE, 0, r->comm);
    params.existing = NULL; /* process 0's pointers */
    params.frozen = NULL;
    size_t ng = (size_t)head->count;
    uint64_t *sizes = NULL;
    own_groups o = {0};
    tessel_status st = bcast_group_sizes(r, ng, NULL, &sizes);
    if (st == TESSEL_OK) /* send_groups' agreement */
        st = tsl_mpi_agree(r->comm, groups_alloc(r, head, sizes, &o));
    for (size_t j = 0; st == TESSEL_OK && j < o.t.count; j++) {
        size_t m = o.t.points[j], ni = (size_t)sizes[2 * o.t.k[j] + 1];
        tsl_mpi_move(r->comm, 0, r->rank, o.t.cloud[j].xyz, 3 * m, MPI_FLOAT, sizeof(float));
        if (head->normals)
            tsl_mpi_move(r->comm, 0, r->rank, o.t.cloud[j].normals, 3 * m, MPI_FLOAT,
                         sizeof(float));
        tsl_mpi_move(r->comm, 0, r->rank, o.inside[j], 3 * ni, MPI_UINT32_T, sizeof(uint32_t));
        tsl_mpi_move(r->comm, 0, r->rank, o.frozen[j], m, MPI_BYTE, 1);
    }
    if (st == TESSEL_OK) {
        groups_ctx c = {&o, &params, sizes};
        st = tsl_mpi_agree(r->comm, tsl_mpi_each(r, o.t.count, group_run, &c));
    }
    if (st == TESSEL_OK)
        st = own_return(r, &o.t, ng);
    free(sizes);
    groups_free(&o);
    return st;
}

tessel_status tessel_mpi_reconstruct_greedy(MPI_Comm comm, const tessel_cloud *cloud,
                                            const tessel_greedy_params *params,
                                            const tessel_callbacks *callbacks,
                                            const tessel_triangle_sink *sink,
                                            tessel_recon_summary *summary)
{
    tessel_greedy_params p = params ? *params : tessel_greedy_params_default();
    ranks r = tsl_mpi_ranks(comm, p.threads);
    if (r.rank != 0)
        return tsl_mpi_final(&r, tsl_mpi_serve(&r));
    tsl_gp_tile_runner runner = {run_ranks, run_seams, &r};
    /* After the tiles the processes beside process 0 on its machine wait
     * without a core: it takes their threads for the seams, the orientation
     * check and the flips (the mesh does not depend on it). */
    p.threads = r.last_threads;
    tessel_status st = tsl_reconstruct_greedy_with(cloud, &p, &runner, callbacks, sink, summary);
    return tsl_mpi_done(&r, st);
}

tessel_status tessel_mpi_reconstruct_greedy_file(
    MPI_Comm comm, const char *in, const char *out, const tessel_read_params *read_params,
    const tessel_greedy_params *params, const tessel_write_params *write_params,
    const tessel_outofcore_params *op, const tessel_callbacks *callbacks,
    tessel_recon_summary *summary, tessel_diag *diag)
{
    tessel_greedy_params p = params ? *params : tessel_greedy_params_default();
    ranks r = tsl_mpi_ranks(comm, p.threads);
    if (r.rank != 0) {
        if (summary)
            memset(summary, 0, sizeof *summary);
        if (diag)
            memset(diag, 0, sizeof *diag);
        return tsl_mpi_final(&r, tsl_mpi_serve(&r));
    }
    tsl_gp_tile_runner runner = {run_ranks, run_seams, &r};
    /* Between the slabs' tiles the others wait without a core, as in
     * tessel_mpi_reconstruct_greedy. */
    p.threads = r.last_threads;
    tessel_status st = tsl_reconstruct_greedy_file_with(in, out, read_params, &p, write_params, op,
                                                        &runner, callbacks, summary, diag);
    return tsl_mpi_done(&r, st);
}
