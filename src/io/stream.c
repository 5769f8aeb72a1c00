/* Chunked reading of a cloud file, for out-of-core work (src/outofcore/).
 *
 * The per-format parsers take the whole file as one buffer. Rather than
 * write a second, incremental parser per format, a regular file is mapped
 * read-only (MAP_PRIVATE) and parsed by those very parsers, through a
 * builder in sink mode (src/io/builder.c): every chunk_points points it
 * drops the non-finite ones, hands the rest to the caller and starts over
 * in the same arrays. Now and then the whole mapping is released with
 * MADV_DONTNEED: the pages were never written, so nothing is lost, and a
 * page the parser touches again faults back from the page cache. The call
 * walks the whole mapping, so it is made once RELEASE_POINTS points went
 * out, not after every chunk (chunks of 7 points spent minutes in it).
 * Resident memory is thus the builder's chunk plus the file bytes of at
 * most max(chunk, RELEASE_POINTS) points, whatever the file's size; the
 * page cache is the kernel's to reclaim. Sharing the parsers is what makes
 * the points, their order and every error message tessel_cloud_read's.
 *
 * Where a whole-file rule looks at all points before deciding, streaming
 * must decide up front:
 *  - LAS/LAZ colours are shifted down from 16 bits when any value exceeds
 *    255: a first pass looks for such a value (stopping at the first, so it
 *    is short for 16-bit files, a whole extra pass for 8-bit ones; for LAZ
 *    an extra decode) before the points are emitted a window at a time;
 *  - LAZ is decoded a LASzip chunk at a time (tsl_laz_read_chunk) on one
 *    thread, not all at once in parallel: memory is one decoded chunk;
 *  - XYZ's unnamed 6 columns (normals or colours?) are decided from the
 *    first chunk, and a file the whole-file rule would read otherwise fails
 *    with a message (src/io/xyz.c).
 * Limits (max_points) are met after the points below them went out.
 * Pipes and other non-regular files cannot be mapped: they are read whole
 * (tsl_read_file) and streamed from memory, so memory is O(file) there. */
#define _DEFAULT_SOURCE /* madvise and MAP_ANONYMOUS are not POSIX */

#include "io/stream.h"

#include "io/io.h"
#include "io/laz.h"

#include <errno.h>
#include <fcntl.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

/* Points delivered between releases of the mapping. */
#define RELEASE_POINTS ((uint64_t)1 << 16)
/* LAS records per window of the colour pre-pass, released after each. */
#define LAS_WINDOW ((size_t)1 << 16)

/* The file's bytes: mapped (map != NULL) or read whole (owned). */
typedef struct input {
    const uint8_t *data;
    size_t size;
    void *map;       /* the reservation, span bytes: the file, then zeros */
    size_t span;
    uint8_t *owned;  /* tsl_read_file's buffer */
} input;

typedef struct stream {
    tsl_chunk_fn fn;
    void *user;
    tsl_stream_info *info;
    const input *in;
    tessel_status fn_status;  /* what fn returned when it stopped the read */
    uint64_t unreleased;      /* points delivered since the last release */
} stream;

/* Lets go of every page of the mapping read so far. */
static void release_input(const input *in)
{
    if (in->map)
        (void)madvise(in->map, in->span, MADV_DONTNEED);
}

static void close_input(input *in)
{
    if (in->map)
        munmap(in->map, in->span);
    free(in->owned);
    memset(in, 0, sizeof *in);
}

/* Maps the regular file fd of size bytes. The text parsers, like
 * tsl_read_file's callers, may rely on a NUL after the data: a zero page
 * is reserved first and the file mapped over its start, so data[size] is
 * 0 even when size is a multiple of the page size. */
static tessel_status map_input(int fd, size_t size, const char *path, input *in,
                               tessel_diag *diag)
{
    size_t page = (size_t)sysconf(_SC_PAGESIZE);
    if (size > SIZE_MAX - 2 * page) {
        tsl_diag_set(diag, path, 0, 0, 0, "file too large for this machine");
        return TESSEL_ERR_LIMIT;
    }
    size_t span = (size / page + 1) * page;
    void *base = mmap(NULL, span, PROT_READ, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (base == MAP_FAILED) {
        tsl_diag_set(diag, path, 0, 0, 0, "cannot map %zu bytes: %s", size, strerror(errno));
        return TESSEL_ERR_NOMEM;
    }
    if (mmap(base, size, PROT_READ, MAP_PRIVATE | MAP_FIXED, fd, 0) == MAP_FAILED) {
        int err = errno;
        munmap(base, span);
        errno = err;
        return TESSEL_ERR_IO;
    }
    /* Parsers read front to back (LAZ jumps once to its chunk table). */
    (void)madvise(base, size, MADV_SEQUENTIAL);
    in->map = base;
    in->span = span;
    in->data = base;
    in->size = size;
    return TESSEL_OK;
}

/* Maps path when it is a regular file, else reads it whole. Errors name
 * the path as tsl_read_file's do (it reports the ones it meets itself). */
static tessel_status open_input(const char *path, input *in, tessel_diag *diag)
{
    memset(in, 0, sizeof *in);
    struct stat sb;
    /* stat, not open, first: opening a FIFO blocks until its writer comes,
     * and tsl_read_file would open it a second time. */
    int fd = -1;
    if (path && *path && stat(path, &sb) == 0 && S_ISREG(sb.st_mode) && sb.st_size > 0)
        fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd >= 0) {
        tessel_status st = TESSEL_OK;
        int tried = 0, err = 0;
        if (fstat(fd, &sb) == 0 && S_ISREG(sb.st_mode) && sb.st_size > 0) {
            tried = 1;
            if ((uint64_t)sb.st_size >= SIZE_MAX) {
                tsl_diag_set(diag, path, 0, 0, 0, "file too large for this machine");
                st = TESSEL_ERR_LIMIT;
            } else {
                st = map_input(fd, (size_t)sb.st_size, path, in, diag);
                err = errno;
            }
        }
        close(fd);
        if (tried && st != TESSEL_ERR_IO)
            return st;
        /* A file system that cannot map falls back to reading whole. */
        if (tried && err != ENODEV && err != EACCES && err != EINVAL) {
            tsl_diag_set(diag, path, 0, 0, 0, "cannot map: %s", strerror(err));
            return TESSEL_ERR_IO;
        }
    }
    /* Not mappable (pipes, devices, empty or /proc-like files that report
     * no size, missing files: tsl_read_file says why). */
    uint8_t *data;
    size_t size;
    tessel_status st = tsl_read_file(path, &data, &size, diag);
    if (st != TESSEL_OK)
        return st;
    in->owned = data;
    in->data = data;
    in->size = size;
    return TESSEL_OK;
}

/* The builder's sink: one chunk of finite points to the caller. */
static tessel_status deliver(void *user, const tsl_builder *b)
{
    stream *s = user;
    tessel_status st = TESSEL_OK;
    s->info->has_normals = b->has_normals;
    s->info->has_rgb = b->has_rgb;
    if (b->count) {
        s->info->points += b->count;
        st = s->fn(s->user, b->xyz, b->has_normals ? b->normals : NULL,
                   b->has_rgb ? b->rgb : NULL, b->count);
        if (st != TESSEL_OK)
            s->fn_status = st;
    }
    s->unreleased += b->count;
    if (s->unreleased >= RELEASE_POINTS) {
        release_input(s->in);
        s->unreleased = 0;
    }
    return st;
}

/* LAZ: a LASzip chunk at a time, decoded into one chunk's records, in two
 * passes when the colour shift must be found first. The reader works on
 * the mapping, so its errors are tessel_cloud_read's. */
static tessel_status stream_laz(const input *in, const char *name, tsl_builder *b,
                                tessel_diag *diag)
{
    tsl_laz *z;
    tessel_status st = tsl_laz_open_memory(&z, in->data, in->size, name, diag);
    if (st != TESSEL_OK)
        return st;
    const tsl_laz_info *info = tsl_laz_get_info(z);
    const tsl_las_header *h = &info->header;
    uint8_t *select = NULL, *records = NULL;
    uint64_t n;
    st = tsl_laz_select(z, b, &select, &n, diag);
    size_t most = info->max_chunk_points ? info->max_chunk_points : 1;
    if (st == TESSEL_OK && !(records = tsl_alloc_array(most, h->record_length))) {
        tsl_diag_set(diag, name, 0, 0, 0, "cannot hold a LAZ chunk of %zu points", most);
        st = TESSEL_ERR_NOMEM;
    }
    int shift = 0;
    for (size_t k = 0; st == TESSEL_OK && !shift && tsl_las_has_rgb(h) &&
                       k < info->chunk_count; k++) {
        if (select && !select[k])
            continue;
        if ((st = tsl_laz_read_chunk(z, k, records, diag)) == TESSEL_OK) {
            shift = tsl_las_rgb_shift(records, tsl_laz_chunk_points(z, k), h);
            release_input(in);
        }
    }
    /* Points before chunk k, for the byte offsets in messages, which
     * count as if the records were stored uncompressed (as tsl_laz_parse). */
    uint64_t before = 0;
    for (size_t k = 0; st == TESSEL_OK && k < info->chunk_count; k++) {
        if (select && !select[k])
            continue;
        size_t pts = tsl_laz_chunk_points(z, k);
        st = tsl_laz_read_chunk(z, k, records, diag);
        if (st == TESSEL_OK)
            st = tsl_las_emit(records, pts, h, shift, name,
                              h->point_offset + before * h->record_length, b, diag);
        before += pts;
    }
    free(records);
    free(select);
    tsl_laz_close(z);
    return st;
}

/* LAS: the checks of tsl_parse_las, then its emission a window of records
 * at a time with the colour shift of the whole file. */
static tessel_status stream_las(const input *in, const char *name, tsl_builder *b,
                                tessel_diag *diag)
{
    tsl_las_header h;
    size_t n;
    tessel_status st = tsl_las_check(in->data, in->size, name, &h, &n, diag);
    if (st != TESSEL_OK)
        return st;
    if (h.compressed)
        return stream_laz(in, name, b, diag);
    const uint8_t *rec = in->data + h.point_offset;
    size_t rl = h.record_length;
    int shift = 0;
    for (size_t i = 0; !shift && tsl_las_has_rgb(&h) && i < n; i += LAS_WINDOW) {
        shift = tsl_las_rgb_shift(rec + i * rl, n - i < LAS_WINDOW ? n - i : LAS_WINDOW, &h);
        release_input(in);
    }
    for (size_t i = 0; st == TESSEL_OK && i < n; i += LAS_WINDOW) {
        size_t m = n - i < LAS_WINDOW ? n - i : LAS_WINDOW;
        st = tsl_las_emit(rec + i * rl, m, &h, shift, name, h.point_offset + i * rl, b, diag);
    }
    return st;
}

tessel_status tsl_cloud_stream(const char *path, const tessel_read_params *params,
                               size_t chunk_points, tsl_chunk_fn fn, void *user,
                               tsl_stream_info *info, tessel_diag *diag)
{
    if (diag)
        memset(diag, 0, sizeof *diag);
    if (!fn || !info || chunk_points == 0)
        return TESSEL_ERR_INVALID_ARG;
    memset(info, 0, sizeof *info);
    tessel_read_params def = tessel_read_params_default();
    if (!params)
        params = &def;
    input in;
    tessel_status st = open_input(path, &in, diag);
    if (st != TESSEL_OK)
        return st;
    tsl_builder b;
    memset(&b, 0, sizeof b);
    tsl_parse_fn parse;
    st = tsl_read_setup(in.data, in.size, path, params, &b, &parse, diag);
    stream s = {fn, user, info, &in, TESSEL_OK, 0};
    if (st == TESSEL_OK) {
        /* No point indices are kept here: tsl_builder_init's uint32 cap
         * does not apply, params' limit does. */
        b.max_points = params->max_points;
        tsl_builder_sink(&b, chunk_points, deliver, &s);
        st = parse == tsl_parse_las ? stream_las(&in, path, &b, diag)
                                    : parse(in.data, in.size, path, 0, &b, diag);
        if (st == TESSEL_OK)
            st = tsl_builder_flush(&b); /* the last chunk, maybe short */
        info->dropped = b.dropped;
    }
    if (st != TESSEL_OK && s.fn_status == st) {
        /* The parser reported where it was; what stopped it was fn. */
        tsl_diag_set(diag, path, 0, 0, 0, "read stopped by its consumer after %llu points: %s",
                     (unsigned long long)info->points, tessel_status_str(st));
    } else if (st != TESSEL_OK && diag && !diag->message[0]) {
        tsl_diag_set(diag, path, 0, 0, 0, "%s", tessel_status_str(st));
    }
    tsl_builder_free(&b);
    close_input(&in);
    return st;
}

/* ---- reading in parts ---- */

/* LAS and LAZ part: records n * part / parts up to n * (part + 1) / parts
 * (LAZ: the LASzip chunks whose first point falls there), with the colour
 * shift agreed by every part. */
typedef struct part_job {
    size_t part, parts;
    tsl_any_fn any;
    void *ctx;
} part_job;

/* The colour shift of records[0 .. n) agreed with the other parts; every
 * part calls any once, a failed one too (after its failure, with 0). */
static int agreed_shift(const part_job *j, const tsl_las_header *h, const uint8_t *records,
                        size_t n, tessel_status st)
{
    if (!tsl_las_has_rgb(h))
        return 0;
    int mine = st == TESSEL_OK && tsl_las_rgb_shift(records, n, h);
    return j->any(j->ctx, mine) ? 8 : 0;
}

static tessel_status part_laz(const uint8_t *data, size_t size, const char *name,
                              const part_job *j, tsl_builder *b, tessel_diag *diag)
{
    tsl_laz *z;
    tessel_status st = tsl_laz_open_memory(&z, data, size, name, diag);
    if (st != TESSEL_OK)
        return st;
    const tsl_laz_info *info = tsl_laz_get_info(z);
    const tsl_las_header *h = &info->header;
    uint8_t *select = NULL, *records = NULL;
    uint64_t n = 0, first = 0, last = 0, mine = 0, before = 0;
    size_t k0 = info->chunk_count, k1 = 0;
    st = tsl_laz_select(z, b, &select, &n, diag);
    if (st == TESSEL_OK) {
        first = n * j->part / j->parts;
        last = n * (j->part + 1) / j->parts;
        /* This part's chunks: those starting in [first, last). */
        uint64_t at = 0;
        for (size_t k = 0; k < info->chunk_count; k++) {
            uint64_t pts = tsl_laz_chunk_points(z, k);
            if (select && !select[k])
                continue;
            if (at >= first && at < last) {
                if (!mine)
                    before = at; /* for messages, as stream_laz counts */
                k0 = k < k0 ? k : k0;
                k1 = k + 1;
                mine += pts;
            }
            at += pts;
        }
        if (mine && !(records = tsl_alloc_array((size_t)mine, h->record_length))) {
            tsl_diag_set(diag, name, 0, 0, 0, "cannot hold %llu decoded LAZ points",
                         (unsigned long long)mine);
            st = TESSEL_ERR_NOMEM;
        }
    }
    /* This part's chunks, on the threads (a process of a parallel read has
     * its machine's share of cores). */
    uint8_t *take = st == TESSEL_OK ? tsl_calloc_array(info->chunk_count + 1, 1) : NULL;
    if (st == TESSEL_OK && !take) {
        tsl_diag_set(diag, name, 0, 0, 0, "out of memory for %zu LAZ chunks", info->chunk_count);
        st = TESSEL_ERR_NOMEM;
    }
    for (size_t k = k0; take && k < k1; k++)
        take[k] = !select || select[k];
    if (st == TESSEL_OK && mine)
        st = tsl_laz_decode_chunks(z, take, records, 0, diag);
    free(take);
    size_t got = st == TESSEL_OK ? (size_t)mine : 0;
    int shift = agreed_shift(j, h, records, got, st);
    if (st == TESSEL_OK)
        st = tsl_las_emit(records, got, h, shift, name,
                          h->point_offset + before * h->record_length, b, diag);
    free(records);
    free(select);
    tsl_laz_close(z);
    return st;
}

static tessel_status part_las(const uint8_t *data, size_t size, const char *name,
                              const part_job *j, tsl_builder *b, tessel_diag *diag)
{
    tsl_las_header h;
    size_t n;
    tessel_status st = tsl_las_check(data, size, name, &h, &n, diag);
    if (st != TESSEL_OK)
        return st;
    if (h.compressed)
        return part_laz(data, size, name, j, b, diag);
    size_t first = (size_t)((uint64_t)n * j->part / j->parts),
           last = (size_t)((uint64_t)n * (j->part + 1) / j->parts);
    size_t rl = h.record_length;
    const uint8_t *rec = data + h.point_offset + first * rl;
    int shift = agreed_shift(j, &h, rec, last - first, TESSEL_OK);
    return tsl_las_emit(rec, last - first, &h, shift, name, h.point_offset + first * rl, b, diag);
}

tessel_status tsl_cloud_parse_part(const uint8_t *data, size_t size, const char *name,
                                   const tessel_read_params *params, size_t part, size_t parts,
                                   tsl_any_fn any, void *ctx, tsl_builder *b, bool *whole,
                                   tessel_diag *diag)
{
    if (diag)
        memset(diag, 0, sizeof *diag);
    memset(b, 0, sizeof *b);
    *whole = false;
    if (!any || parts == 0 || part >= parts)
        return TESSEL_ERR_INVALID_ARG;
    tsl_parse_fn parse;
    tessel_status st = tsl_read_setup(data, size, name, params, b, &parse, diag);
    part_job j = {part, parts, any, ctx};
    if (st == TESSEL_OK && parse == tsl_parse_las)
        st = part_las(data, size, name, &j, b, diag);
    else if (st == TESSEL_OK && parse == tsl_parse_ply)
        st = tsl_parse_ply_part(data, size, name, part, parts, b, whole, diag);
    else if (st == TESSEL_OK)
        *whole = true;
    if (st == TESSEL_OK)
        b->dropped = tsl_builder_keep_finite(b);
    else if (diag && !diag->message[0])
        tsl_diag_set(diag, name, 0, 0, 0, "%s", tessel_status_str(st));
    return st;
}

tessel_status tsl_cloud_read_part(const char *path, const tessel_read_params *params,
                                  size_t part, size_t parts, tsl_any_fn any, void *ctx,
                                  tsl_builder *b, bool *whole, tessel_diag *diag)
{
    if (diag)
        memset(diag, 0, sizeof *diag);
    memset(b, 0, sizeof *b);
    *whole = false;
    input in;
    tessel_status st = open_input(path, &in, diag);
    if (st != TESSEL_OK)
        return st;
    st = tsl_cloud_parse_part(in.data, in.size, path, params, part, parts, any, ctx, b, whole,
                              diag);
    close_input(&in);
    return st;
}
