/* Greedy projection of a cloud larger than memory
 * (tessel_reconstruct_greedy_file, docs/outofcore.md). The file is read in
 * chunks three times: to count the points and place the cuts between slabs
 * (quantiles of a reservoir sample along the longest axis), to sort the
 * points into one scratch file per slab, and to write the output's
 * vertices. In between the slabs are meshed in turn (greedy/slabs.c), each
 * from its scratch file, and the finished triangles spooled to another.
 * Everything scratch lives in one hidden folder, removed however the call
 * ends. */
#include "greedy/greedy.h"
#include "io/io.h"
#include "io/stream.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* Memory per point of a slab: the slab's greedy pass held in core peaks
 * near 370 bytes per point (tiles, flips); the front that joins it to the
 * band holds a second copy of the points and the triangles. */
#define BYTES_PER_POINT 450
/* Points per chunk of a read. */
#define CHUNK_POINTS ((size_t)1 << 20)
/* The sample that places the cuts. */
#define SAMPLE_POINTS ((size_t)1 << 18)
/* Buffer of each slab file while the points are sorted. */
#define SLAB_BUFFER ((size_t)1 << 16)
/* Triangles per read of the spool when the output is written. */
#define TRI_BATCH ((size_t)1 << 16)

tessel_outofcore_params tessel_outofcore_params_default(void)
{
    tessel_outofcore_params p;
    p.memory = 0;
    p.scratch = NULL;
    return p;
}

static uint64_t physical_memory(void)
{
    long pages = sysconf(_SC_PHYS_PAGES), size = sysconf(_SC_PAGESIZE);
    return pages > 0 && size > 0 ? (uint64_t)pages * (uint64_t)size : (uint64_t)4 << 30;
}

/* ---- scratch folder ---- */

typedef struct scratch {
    char *dir;
    size_t slabs;
    FILE **slab;
    FILE *tris;
} scratch;

static char *scratch_file(const scratch *s, const char *name, size_t k)
{
    size_t len = strlen(s->dir) + 32;
    char *p = malloc(len);
    if (p)
        snprintf(p, len, "%s/%s-%06zu", s->dir, name, k);
    return p;
}

/* Makes the hidden folder in folder (NULL: the output's). */
static tessel_status scratch_open(scratch *s, const char *folder, const char *out,
                                  tessel_diag *diag)
{
    memset(s, 0, sizeof *s);
    char base[4096];
    if (folder) {
        snprintf(base, sizeof base, "%s", folder);
    } else {
        const char *slash = strrchr(out, '/');
        if (!slash)
            snprintf(base, sizeof base, ".");
        else
            snprintf(base, sizeof base, "%.*s", (int)(slash - out + (slash == out)), out);
    }
    size_t len = strlen(base) + 32;
    if (!(s->dir = malloc(len)))
        return TESSEL_ERR_NOMEM;
    snprintf(s->dir, len, "%s/.tessel-scratch-XXXXXX", base);
    if (!mkdtemp(s->dir)) {
        int err = errno;
        tsl_diag_set(diag, base, 0, 0, 0, "cannot make a scratch folder: %s", strerror(err));
        free(s->dir);
        s->dir = NULL;
        return TESSEL_ERR_IO;
    }
    return TESSEL_OK;
}

static void scratch_close(scratch *s)
{
    for (size_t k = 0; s->slab && k < s->slabs; k++) {
        if (s->slab[k])
            fclose(s->slab[k]);
        char *p = s->dir ? scratch_file(s, "slab", k) : NULL;
        if (p)
            unlink(p);
        free(p);
    }
    free(s->slab);
    if (s->tris)
        fclose(s->tris);
    if (s->dir) {
        char *p = scratch_file(s, "triangles", 0);
        if (p)
            unlink(p);
        free(p);
        rmdir(s->dir);
        free(s->dir);
    }
    memset(s, 0, sizeof *s);
}

/* ---- the first read: count, offset, sample, cuts ---- */

typedef struct survey {
    const tessel_callbacks *cb;
    uint64_t n;
    double offset[3];
    float *sample; /* 3 * SAMPLE_POINTS, local coordinates */
    size_t ns;
    uint64_t rng;
} survey;

static uint64_t splitmix(uint64_t *x)
{
    uint64_t z = (*x += 0x9e3779b97f4a7c15u);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9u;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebu;
    return z ^ (z >> 31);
}

static tessel_status survey_chunk(void *user, const double *xyz, const float *normals,
                                  const uint8_t *rgb, size_t count)
{
    (void)normals;
    (void)rgb;
    survey *s = user;
    /* The offset follows the first chunk (tsl_choose_offset's rule there):
     * every later point is stored against it. */
    if (s->n == 0 && count) {
        tessel_status st = tsl_choose_offset(xyz, count, s->offset);
        if (st)
            return st;
    }
    for (size_t i = 0; i < count; i++, s->n++) {
        /* Reservoir sampling (Vitter's algorithm R), a fixed seed. */
        size_t slot = s->n < SAMPLE_POINTS ? (size_t)s->n
                                           : (size_t)(splitmix(&s->rng) % (s->n + 1));
        if (slot >= SAMPLE_POINTS)
            continue;
        for (int k = 0; k < 3; k++)
            s->sample[3 * slot + (size_t)k] = tsl_local_coord(xyz[3 * i + (size_t)k], s->offset[k]);
        if (s->ns <= slot)
            s->ns = slot + 1;
    }
    return tsl_progress(s->cb, "out of core: reading", 0.0);
}

static int cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return x < y ? -1 : x > y;
}

/* The sweep axis (the longest extent of the sample between its 0.1% and
 * 99.9% quantiles, as greedy picks its depth axis) and the slabs - 1 cuts
 * along it at the sample's quantiles. */
static tessel_status place_cuts(const survey *s, size_t slabs, int *axis, float *cuts)
{
    size_t ns = s->ns;
    float *c = tsl_alloc_array(ns + 1, sizeof *c);
    if (!c)
        return TESSEL_ERR_NOMEM;
    double best = -1.0;
    *axis = 0;
    for (int k = 0; k < 3; k++) {
        for (size_t i = 0; i < ns; i++)
            c[i] = s->sample[3 * i + (size_t)k];
        qsort(c, ns, sizeof *c, cmp_float);
        double ext = (double)c[ns - 1 - ns / 1000] - (double)c[ns / 1000];
        if (ext > best) {
            best = ext;
            *axis = k;
        }
    }
    for (size_t i = 0; i < ns; i++)
        c[i] = s->sample[3 * i + (size_t)*axis];
    qsort(c, ns, sizeof *c, cmp_float);
    for (size_t j = 1; j < slabs; j++)
        cuts[j - 1] = c[j * ns / slabs];
    free(c);
    return TESSEL_OK;
}

/* ---- the second read: points into slab files ---- */

typedef struct sorter {
    const tessel_callbacks *cb;
    scratch *sc;
    const float *cuts;
    size_t ncuts;
    int axis, normals;
    double offset[3];
    uint64_t n, total;
} sorter;

static size_t slab_of(const float *cuts, size_t ncuts, float x)
{
    size_t lo = 0, hi = ncuts; /* the number of cuts <= x */
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (cuts[mid] <= x)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

static tessel_status sort_chunk(void *user, const double *xyz, const float *normals,
                                const uint8_t *rgb, size_t count)
{
    (void)rgb;
    sorter *s = user;
    for (size_t i = 0; i < count; i++, s->n++) {
        float rec[7];
        uint32_t gid = (uint32_t)s->n;
        for (int k = 0; k < 3; k++)
            rec[1 + k] = tsl_local_coord(xyz[3 * i + (size_t)k], s->offset[k]);
        memcpy(rec, &gid, sizeof gid);
        size_t fields = 4;
        if (s->normals) {
            memcpy(rec + 4, normals + 3 * i, 3 * sizeof *rec);
            fields = 7;
        }
        FILE *f = s->sc->slab[slab_of(s->cuts, s->ncuts, rec[1 + s->axis])];
        if (fwrite(rec, sizeof *rec, fields, f) != fields)
            return TESSEL_ERR_IO;
    }
    return tsl_progress(s->cb, "out of core: sorting",
                        s->total ? (double)s->n / (double)s->total : 0.0);
}

/* ---- the slabs ---- */

typedef struct spool {
    FILE *fp;
    uint64_t *used; /* one bit per point */
    uint64_t triangles;
} spool;

static tessel_status spool_emit(void *user, const uint32_t *tris, size_t count)
{
    spool *s = user;
    for (size_t i = 0; i < 3 * count; i++)
        s->used[tris[i] >> 6] |= (uint64_t)1 << (tris[i] & 63);
    s->triangles += count;
    return fwrite(tris, 3 * sizeof *tris, count, s->fp) == count ? TESSEL_OK : TESSEL_ERR_IO;
}

/* Slab k back from its file (which is removed: its disk space is needed
 * no more). */
static tessel_status load_slab(scratch *sc, size_t k, int normals, double offset[3],
                               tessel_cloud *cloud, uint32_t **gid, tessel_diag *diag)
{
    char *path = scratch_file(sc, "slab", k);
    if (!path)
        return TESSEL_ERR_NOMEM;
    size_t fields = normals ? 7 : 4;
    FILE *f = fopen(path, "rb");
    struct stat stt;
    tessel_status st = TESSEL_OK;
    if (!f || fstat(fileno(f), &stt) != 0) {
        int err = errno;
        tsl_diag_set(diag, path, 0, 0, 0, "cannot read a scratch file: %s", strerror(err));
        st = TESSEL_ERR_IO;
    }
    size_t n = st ? 0 : (size_t)stt.st_size / (fields * sizeof(float));
    float *rec = st ? NULL : tsl_alloc_array(fields * n + 1, sizeof *rec);
    *gid = st ? NULL : tsl_alloc_array(n + 1, sizeof **gid);
    if (!st && (!rec || !*gid || tessel_cloud_alloc(cloud, n, normals, 0)))
        st = TESSEL_ERR_NOMEM;
    if (!st && fread(rec, fields * sizeof *rec, n, f) != n) {
        tsl_diag_set(diag, path, 0, 0, 0, "scratch file cut short");
        st = TESSEL_ERR_IO;
    }
    for (size_t i = 0; !st && i < n; i++) {
        const float *r = rec + fields * i;
        memcpy(*gid + i, r, sizeof **gid);
        memcpy(cloud->xyz + 3 * i, r + 1, 3 * sizeof *r);
        if (normals)
            memcpy(cloud->normals + 3 * i, r + 4, 3 * sizeof *r);
    }
    if (!st)
        memcpy(cloud->offset, offset, sizeof cloud->offset);
    if (f)
        fclose(f);
    unlink(path);
    free(path);
    free(rec);
    return st;
}

/* ---- the third read: the output ---- */

typedef struct writer {
    const tessel_callbacks *cb;
    const tsl_format_writer *w;
    const tessel_write_params *params;
    FILE *fp;
    const uint64_t *used;
    double offset[3];
    uint64_t n, total;
    float *xyz, *normals;
    uint8_t *rgb;
} writer;

static tessel_status write_chunk(void *user, const double *xyz, const float *normals,
                                 const uint8_t *rgb, size_t count)
{
    writer *o = user;
    size_t m = 0;
    for (size_t i = 0; i < count; i++, o->n++) {
        if (!(o->used[o->n >> 6] >> (o->n & 63) & 1))
            continue;
        for (int k = 0; k < 3; k++)
            o->xyz[3 * m + (size_t)k] = tsl_local_coord(xyz[3 * i + (size_t)k], o->offset[k]);
        if (normals && o->normals)
            memcpy(o->normals + 3 * m, normals + 3 * i, 3 * sizeof *normals);
        if (rgb && o->rgb)
            memcpy(o->rgb + 3 * m, rgb + 3 * i, 3);
        m++;
    }
    tsl_vertices v = {m, o->xyz, normals ? o->normals : NULL, rgb ? o->rgb : NULL, {0, 0, 0}};
    memcpy(v.offset, o->offset, sizeof v.offset);
    tessel_status st = m ? o->w->vertices(o->fp, &v, NULL, m, o->params) : TESSEL_OK;
    return st ? st
              : tsl_progress(o->cb, "out of core: writing",
                             0.5 * (double)o->n / (double)(o->total ? o->total : 1));
}

/* Rank of each point among the used ones: rank[w] counts the used points
 * before word w of the bitmap. */
static uint32_t out_index(const uint64_t *used, const uint32_t *rank, uint32_t g)
{
    uint64_t below = used[g >> 6] & (((uint64_t)1 << (g & 63)) - 1);
    return rank[g >> 6] + (uint32_t)__builtin_popcountll(below);
}

static tessel_status write_output(const char *in, const char *out,
                                  const tessel_read_params *rp, const tessel_write_params *wp,
                                  const tessel_callbacks *cb, scratch *sc, const spool *sp,
                                  uint64_t n, const double offset[3], int has_normals,
                                  int has_rgb, tessel_diag *diag)
{
    tessel_write_params eff;
    const tsl_format_writer *w;
    tessel_status st = tsl_write_setup(out, wp, &eff, &w, diag);
    if (st)
        return st;
    size_t words = (size_t)(n + 63) / 64;
    uint32_t *rank = tsl_alloc_array(words + 1, sizeof *rank);
    uint32_t *batch = tsl_alloc_array(3 * TRI_BATCH, sizeof *batch);
    writer o = {cb, w, &eff, NULL, sp->used, {0, 0, 0}, 0, n, NULL, NULL, NULL};
    memcpy(o.offset, offset, sizeof o.offset);
    o.xyz = tsl_alloc_array(3 * CHUNK_POINTS, sizeof *o.xyz);
    o.normals = has_normals ? tsl_alloc_array(3 * CHUNK_POINTS, sizeof *o.normals) : NULL;
    o.rgb = has_rgb ? tsl_alloc_array(3 * CHUNK_POINTS, 1) : NULL;
    if (!rank || !batch || !o.xyz || (has_normals && !o.normals) || (has_rgb && !o.rgb)) {
        st = TESSEL_ERR_NOMEM;
        goto done;
    }
    uint32_t used = 0;
    for (size_t i = 0; i < words; i++) {
        rank[i] = used;
        used += (uint32_t)__builtin_popcountll(sp->used[i]);
    }
    tsl_outfile file;
    if ((st = tsl_outfile_open(&file, out, diag)))
        goto done;
    o.fp = file.fp;
    /* The header only looks at which arrays there are. */
    tsl_vertices head = {used, o.xyz, o.normals, o.rgb, {0, 0, 0}};
    memcpy(head.offset, offset, sizeof head.offset);
    st = w->begin(file.fp, &head, used, (size_t)sp->triangles, &eff);
    tsl_stream_info info;
    if (!st)
        st = tsl_cloud_stream(in, rp, CHUNK_POINTS, write_chunk, &o, &info, diag);
    if (!st && fseeko(sc->tris, 0, SEEK_SET) != 0)
        st = TESSEL_ERR_IO;
    for (uint64_t t = 0; !st && t < sp->triangles;) {
        size_t m = sp->triangles - t < TRI_BATCH ? (size_t)(sp->triangles - t) : TRI_BATCH;
        if (fread(batch, 3 * sizeof *batch, m, sc->tris) != m) {
            st = TESSEL_ERR_IO;
            break;
        }
        for (size_t i = 0; i < 3 * m; i++)
            batch[i] = out_index(sp->used, rank, batch[i]);
        st = w->faces(file.fp, &head, batch, NULL, m, &eff);
        t += m;
        if (!st)
            st = tsl_progress(cb, "out of core: writing",
                              0.5 + 0.5 * (double)t / (double)sp->triangles);
    }
    if (!st && w->end)
        st = w->end(file.fp, &eff);
    if (st == TESSEL_ERR_CANCELLED) {
        tsl_outfile_abort(&file);
        goto done;
    }
    st = tsl_write_finish(&file, st, out, diag);
done:
    free(rank);
    free(batch);
    free(o.xyz);
    free(o.normals);
    free(o.rgb);
    return st;
}

/* ---- the whole ---- */

/* Progress of the slab being meshed within the whole sweep (never
 * backwards: each stage inside a slab counts from 0 again), and the
 * caller's cancellation heard inside a slab. */
typedef struct slab_progress {
    const tessel_callbacks *user;
    size_t k, slabs;
    double shown;
} slab_progress;

static int slab_progress_fn(void *data, const char *stage, double fraction)
{
    (void)stage;
    slab_progress *p = data;
    double f = ((double)p->k + (fraction > 0.0 && fraction < 1.0 ? fraction : 0.0)) /
               (double)p->slabs;
    if (f > p->shown)
        p->shown = f;
    return tsl_progress(p->user, "out of core: meshing", p->shown) != TESSEL_OK;
}

static tessel_status sweep(scratch *sc, const float *cuts, size_t slabs, int axis, int normals,
                           double offset[3], const tessel_greedy_params *params,
                           const tsl_gp_tile_runner *runner, const tessel_callbacks *cb,
                           spool *sp, tessel_recon_summary *sum, tessel_diag *diag)
{
    tsl_gp_slabs band;
    tsl_gp_slabs_init(&band, axis, runner);
    tessel_triangle_sink sink = {spool_emit, sp};
    slab_progress prog = {cb, 0, slabs, 0.0};
    tessel_callbacks inner = {slab_progress_fn, cb ? cb->log : NULL, &prog};
    tessel_status st = TESSEL_OK;
    for (size_t k = 0; k < slabs && !st; k++) {
        prog.k = k;
        tessel_cloud slab;
        memset(&slab, 0, sizeof slab);
        uint32_t *gid = NULL;
        st = load_slab(sc, k, normals, offset, &slab, &gid, diag);
        double cut = k ? (double)cuts[k - 1] : -INFINITY;
        double next = k + 1 < slabs ? (double)cuts[k] : INFINITY;
        if (!st)
            st = tsl_gp_slabs_step(&band, &slab, gid, cut, next, params, &inner, &sink, sum);
        tessel_cloud_free(&slab);
        free(gid);
    }
    tsl_gp_slabs_free(&band);
    return st;
}

tessel_status tessel_reconstruct_greedy_file(const char *in, const char *out,
                                             const tessel_read_params *read_params,
                                             const tessel_greedy_params *params,
                                             const tessel_write_params *write_params,
                                             const tessel_outofcore_params *op,
                                             const tessel_callbacks *callbacks,
                                             tessel_recon_summary *summary, tessel_diag *diag)
{
    return tsl_reconstruct_greedy_file_with(in, out, read_params, params, write_params, op, NULL,
                                            callbacks, summary, diag);
}

tessel_status tsl_reconstruct_greedy_file_with(
    const char *in, const char *out, const tessel_read_params *read_params,
    const tessel_greedy_params *params, const tessel_write_params *write_params,
    const tessel_outofcore_params *op, const tsl_gp_tile_runner *runner,
    const tessel_callbacks *callbacks, tessel_recon_summary *summary, tessel_diag *diag)
{
    double t0 = tsl_seconds();
    tessel_recon_summary sum;
    memset(&sum, 0, sizeof sum);
    if (summary)
        memset(summary, 0, sizeof *summary);
    if (diag)
        memset(diag, 0, sizeof *diag);
    if (!in || !out)
        return TESSEL_ERR_INVALID_ARG;
    tessel_greedy_params p = params ? *params : tessel_greedy_params_default();
    tessel_outofcore_params o = op ? *op : tessel_outofcore_params_default();
    uint64_t memory = o.memory ? o.memory : physical_memory() / 2;
    if (p.existing_count || p.frozen)
        return TESSEL_ERR_INVALID_ARG;
    /* The output's format first: a file it cannot write should not cost a
     * sweep. */
    tessel_write_params eff;
    const tsl_format_writer *w;
    tessel_status valid = tsl_write_setup(out, write_params, &eff, &w, diag);
    if (valid)
        return valid;
    if (!w->vertices || !w->begin) {
        tsl_diag_set(diag, out, 0, 0, 0, "out of core, meshes are written as PLY, OBJ or OFF");
        return TESSEL_ERR_UNSUPPORTED;
    }
    scratch sc;
    memset(&sc, 0, sizeof sc);
    survey sv = {callbacks, 0, {0, 0, 0}, NULL, 0, 0x7e55e1u};
    float *cuts = NULL;
    spool sp = {NULL, NULL, 0};
    tsl_stream_info info;
    tessel_status st = TESSEL_ERR_NOMEM;
    if (!(sv.sample = tsl_alloc_array(3 * SAMPLE_POINTS, sizeof *sv.sample)))
        goto done;
    if ((st = tsl_cloud_stream(in, read_params, CHUNK_POINTS, survey_chunk, &sv, &info, diag)))
        goto done;
    if (sv.n < 3) {
        tsl_diag_set(diag, in, 0, 0, 0, "%llu points: a mesh needs at least 3",
                     (unsigned long long)sv.n);
        st = TESSEL_ERR_TOO_FEW_POINTS;
        goto done;
    }
    if (sv.n >= UINT32_MAX) {
        st = TESSEL_ERR_LIMIT;
        goto done;
    }
    /* Memory the sweep holds whatever the slabs: the bitmap, the ranks,
     * the chunks of the reads. */
    uint64_t fixed = sv.n / 8 + sv.n / 16 + CHUNK_POINTS * 64 + ((uint64_t)64 << 20);
    uint64_t per_slab = memory > fixed ? (memory - fixed) / BYTES_PER_POINT : 0;
    if (per_slab < 1000)
        per_slab = 1000;
    size_t slabs = (size_t)((sv.n + per_slab - 1) / per_slab);
    int axis = 0;
    if (!(cuts = tsl_alloc_array(slabs, sizeof *cuts)) ||
        (st = place_cuts(&sv, slabs, &axis, cuts)))
        goto done;
    st = TESSEL_ERR_NOMEM;
    if (!(sp.used = tsl_calloc_array((size_t)(sv.n + 63) / 64, sizeof *sp.used)))
        goto done;
    if ((st = scratch_open(&sc, o.scratch, out, diag)))
        goto done;
    if (!(sc.slab = tsl_calloc_array(slabs, sizeof *sc.slab))) {
        st = TESSEL_ERR_NOMEM;
        goto done;
    }
    sc.slabs = slabs;
    for (size_t k = 0; k < slabs; k++) {
        char *path = scratch_file(&sc, "slab", k);
        if (!path || !(sc.slab[k] = fopen(path, "wb"))) {
            int err = errno;
            tsl_diag_set(diag, path ? path : sc.dir, 0, 0, 0, "cannot write a scratch file: %s",
                         strerror(err));
            free(path);
            st = TESSEL_ERR_IO;
            goto done;
        }
        setvbuf(sc.slab[k], NULL, _IOFBF, SLAB_BUFFER);
        free(path);
    }
    sorter so = {callbacks, &sc, cuts, slabs - 1, axis, info.has_normals, {0, 0, 0}, 0, sv.n};
    memcpy(so.offset, sv.offset, sizeof so.offset);
    if ((st = tsl_cloud_stream(in, read_params, CHUNK_POINTS, sort_chunk, &so, &info, diag)))
        goto done;
    if (so.n != sv.n) {
        tsl_diag_set(diag, in, 0, 0, 0, "the file changed while it was read");
        st = TESSEL_ERR_IO;
        goto done;
    }
    for (size_t k = 0; k < slabs; k++) {
        int bad = fclose(sc.slab[k]) != 0;
        sc.slab[k] = NULL;
        if (bad) {
            tsl_diag_set(diag, sc.dir, 0, 0, 0, "cannot write a scratch file: %s",
                         strerror(errno));
            st = TESSEL_ERR_IO;
            goto done;
        }
    }
    char *tpath = scratch_file(&sc, "triangles", 0);
    sc.tris = tpath ? fopen(tpath, "w+b") : NULL;
    free(tpath);
    if (!sc.tris) {
        tsl_diag_set(diag, sc.dir, 0, 0, 0, "cannot write a scratch file: %s", strerror(errno));
        st = TESSEL_ERR_IO;
        goto done;
    }
    sp.fp = sc.tris;
    if ((st = sweep(&sc, cuts, slabs, axis, info.has_normals, sv.offset, &p, runner, callbacks,
                    &sp, &sum, diag)))
        goto done;
    if (fflush(sc.tris) != 0) {
        tsl_diag_set(diag, sc.dir, 0, 0, 0, "cannot write a scratch file: %s", strerror(errno));
        st = TESSEL_ERR_IO;
        goto done;
    }
    st = write_output(in, out, read_params, write_params, callbacks, &sc, &sp, sv.n, sv.offset,
                      info.has_normals, info.has_rgb, diag);
    if (!st) {
        sum.points_in = (size_t)sv.n;
        sum.points_used = 0;
        for (size_t i = 0; i < (size_t)(sv.n + 63) / 64; i++)
            sum.points_used += (size_t)__builtin_popcountll(sp.used[i]);
        sum.triangles = (size_t)sp.triangles;
        sum.slabs = slabs;
        sum.seconds = tsl_seconds() - t0;
        if (summary)
            *summary = sum;
    }
done:
    if (st && diag && !diag->message[0])
        tsl_diag_set(diag, in, 0, 0, 0, "%s", tessel_status_str(st));
    scratch_close(&sc);
    free(sv.sample);
    free(cuts);
    free(sp.used);
    return st;
}
