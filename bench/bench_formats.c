/* Reader throughput for LAS, LAZ and XYZ on files in memory (so the disk
 * does not enter the figure): points/s and bytes/point through the public
 * tessel_cloud_parse, median of three runs. Data: n points of a
 * fixed-seed torus (bench_data.h) moved to UTM-like coordinates (offset
 * 637000, 5120000, 300) so the double-offset path is exercised.
 *  - LAS 1.2, point format 3 (34 bytes, RGB), scale 0.001;
 *  - XYZ text "x y z" with 3 decimals, and the same with normals.
 * For comparison, the XYZ text is also parsed by a plain strtod loop (no
 * checks, no builder): the cost of the C library alone.
 *
 * LAZ: the one-chunk test files tests/data/laz/simple.laz (point format 3,
 * LAS 1.2) and gen_fmt7_plain.laz (the same 1,065 points as LAS 1.4 format 7,
 * layered) are made into files of at least N points by repeating their chunk
 * (1,065 points a chunk) under a new chunk table, then decoded: the decoder
 * alone (tsl_laz_decode_all, points/s on one thread in CPU time and on two in
 * wall time) and the whole public read (decoding, then the builder).
 *
 * Any FILE.laz argument is also timed as it is (decoder alone, one and two
 * threads): real files with their own chunks.
 *
 * Usage: bench_formats [N [LAZ_DIR]] [FILE.laz...]   (default 1000000 points,
 * the source tree's tests/data/laz) */
#include "tessel.h"

#include "bench_data.h"
#include "io/laz.h"
#include "io/laz_coder.h"

#define UTM_X 637000.0
#define UTM_Y 5120000.0
#define UTM_Z 300.0
#define SCALE 0.001

static void put16(uint8_t *p, unsigned v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}
static void put32(uint8_t *p, uint32_t v)
{
    for (int k = 0; k < 4; k++)
        p[k] = (uint8_t)(v >> (8 * k));
}
static void putf64(uint8_t *p, double d)
{
    uint64_t u;
    memcpy(&u, &d, sizeof u);
    for (int k = 0; k < 8; k++)
        p[k] = (uint8_t)(u >> (8 * k));
}

/* World coordinate k of point i (torus scaled to a 200 m wide tile). */
static double world(const float *xyz, size_t i, int k)
{
    static const double base[3] = {UTM_X, UTM_Y, UTM_Z};
    return base[k] + 100.0 * xyz[3 * i + k];
}

static uint8_t *make_las(const float *xyz, size_t n, size_t *size)
{
    const size_t hs = 227, rec = 34;
    *size = hs + n * rec;
    uint8_t *d = calloc(*size, 1);
    if (!d)
        return NULL;
    memcpy(d, "LASF", 4);
    d[24] = 1;
    d[25] = 2;
    put16(d + 94, (unsigned)hs);
    put32(d + 96, (uint32_t)hs);
    d[104] = 3;
    put16(d + 105, (unsigned)rec);
    put32(d + 107, (uint32_t)n);
    static const double base[3] = {UTM_X, UTM_Y, UTM_Z};
    for (int k = 0; k < 3; k++) {
        putf64(d + 131 + 8 * k, SCALE);
        putf64(d + 155 + 8 * k, base[k]);
    }
    for (size_t i = 0; i < n; i++) {
        uint8_t *r = d + hs + i * rec;
        for (int k = 0; k < 3; k++)
            put32(r + 4 * k, (uint32_t)(int32_t)lround((world(xyz, i, k) - base[k]) / SCALE));
        for (int k = 0; k < 3; k++)
            put16(r + 28 + 2 * k, (unsigned)(i * (k + 1) * 97) & 0xFFFF);
    }
    return d;
}

static char *make_xyz(const float *xyz, size_t n, int normals, size_t *size)
{
    size_t cap = n * (normals ? 80 : 48) + 1;
    char *t = malloc(cap);
    if (!t)
        return NULL;
    size_t len = 0;
    for (size_t i = 0; i < n; i++) {
        len += (size_t)snprintf(t + len, cap - len, "%.3f %.3f %.3f", world(xyz, i, 0),
                                world(xyz, i, 1), world(xyz, i, 2));
        if (normals)
            len += (size_t)snprintf(t + len, cap - len, " %.6f %.6f %.6f", 0.0, 0.6, 0.8);
        t[len++] = '\n';
    }
    *size = len;
    return t;
}

/* Seconds for one parse; checks the count. */
static double time_parse(const void *data, size_t size, const char *name, size_t n)
{
    tessel_cloud c;
    tessel_diag d;
    double t0 = bench_now();
    tessel_status st = tessel_cloud_parse(&c, data, size, name, NULL, &d);
    double t = bench_now() - t0;
    if (st != TESSEL_OK || c.count != n) {
        fprintf(stderr, "bench_formats: %s: %s (%s)\n", name, tessel_status_str(st),
                d.message);
        exit(1);
    }
    tessel_cloud_free(&c);
    return t;
}

static void report(const char *what, size_t n, size_t bytes, double a, double b, double c)
{
    double t = bench_median3(a, b, c);
    printf("%-28s %10zu points %7.1f MB %6.1f bytes/point %8.3f s %8.2f Mpoints/s\n", what,
           n, bytes / 1e6, (double)bytes / (double)n, t, n / t / 1e6);
}

/* ---- LAZ: a large file from the chunk of a small one ---- */

/* The range encoder that LAZ's decoder undoes (Said's FastAC as LASzip has
 * it), only as much as a chunk table needs: an integer compressor's symbols,
 * bits and raw bits. */
typedef struct enc {
    uint8_t *out;
    size_t n, cap;
    uint32_t base, length;
} enc;

static void enc_byte(enc *e, uint32_t b)
{
    if (e->n == e->cap) {
        e->cap = e->cap ? 2 * e->cap : 256;
        e->out = realloc(e->out, e->cap);
    }
    e->out[e->n++] = (uint8_t)b;
}

static void enc_carry(enc *e)
{
    for (size_t i = e->n; i-- > 0;) {
        if (e->out[i] != 0xFF) {
            e->out[i]++;
            return;
        }
        e->out[i] = 0;
    }
}

static void enc_renorm(enc *e)
{
    do {
        enc_byte(e, e->base >> 24);
        e->base <<= 8;
    } while ((e->length <<= 8) < LAZ_MIN_LENGTH);
}

static void enc_symbol(enc *e, laz_model *m, uint32_t sym)
{
    uint32_t x, init = e->base;
    if (sym == m->last_symbol) {
        x = m->dist[sym] * (e->length >> LAZ_DM_SHIFT);
        e->base += x;
        e->length -= x;
    } else {
        x = m->dist[sym] * (e->length >>= LAZ_DM_SHIFT);
        e->base += x;
        e->length = m->dist[sym + 1] * e->length - x;
    }
    if (init > e->base)
        enc_carry(e);
    if (e->length < LAZ_MIN_LENGTH)
        enc_renorm(e);
    ++m->count[sym];
    if (--m->until_update == 0)
        laz_model_update(m);
}

static void enc_bit(enc *e, laz_bitmodel *m, uint32_t bit)
{
    uint32_t x = m->bit_0_prob * (e->length >> LAZ_BM_SHIFT);
    if (bit == 0) {
        e->length = x;
        ++m->bit_0_count;
    } else {
        uint32_t init = e->base;
        e->base += x;
        e->length -= x;
        if (init > e->base)
            enc_carry(e);
    }
    if (e->length < LAZ_MIN_LENGTH)
        enc_renorm(e);
    if (--m->until_update == 0)
        laz_bitmodel_update(m);
}

static void enc_bits(enc *e, uint32_t bits, uint32_t sym)
{
    if (bits > 19) {
        enc_bits(e, 16, sym & 0xFFFF);
        sym >>= 16;
        bits -= 16;
    }
    uint32_t init = e->base;
    e->base += sym * (e->length >>= bits);
    if (init > e->base)
        enc_carry(e);
    if (e->length < LAZ_MIN_LENGTH)
        enc_renorm(e);
}

static void enc_done(enc *e)
{
    uint32_t init = e->base;
    int another = 1;
    if (e->length > 2 * LAZ_MIN_LENGTH) {
        e->base += LAZ_MIN_LENGTH;
        e->length = LAZ_MIN_LENGTH >> 1;
    } else {
        e->base += LAZ_MIN_LENGTH >> 1;
        e->length = LAZ_MIN_LENGTH >> 9;
        another = 0;
    }
    if (init > e->base)
        enc_carry(e);
    enc_renorm(e);
    enc_byte(e, 0);
    enc_byte(e, 0);
    if (another)
        enc_byte(e, 0);
}

/* real as a corrector from pred (32-bit integer compressor, bits_high 8). */
static void enc_int(enc *e, laz_ic *ic, int32_t pred, int32_t real, uint32_t ctx)
{
    int64_t c = (int64_t)real - pred;
    uint64_t c1 = c <= 0 ? (uint64_t)-c : (uint64_t)c - 1;
    uint32_t k = 0;
    while (c1) {
        c1 >>= 1;
        k++;
    }
    enc_symbol(e, &ic->mbits[ctx], k);
    if (k == 0) {
        enc_bit(e, &ic->corr0, (uint32_t)c);
        return;
    }
    uint32_t v = (uint32_t)(c < 0 ? c + (int64_t)((1u << k) - 1) : c - 1);
    laz_model *m = &ic->corr[k - 1];
    if (!ic->corr_ready[k - 1]) {
        if (!m->dist)
            laz_model_alloc(m, 1u << (k <= 8 ? k : 8));
        laz_model_init(m);
        ic->corr_ready[k - 1] = 1;
    }
    if (k <= 8) {
        enc_symbol(e, m, v);
    } else {
        enc_symbol(e, m, v >> (k - 8));
        enc_bits(e, k - 8, v & ((1u << (k - 8)) - 1));
    }
}

static uint8_t *load_file(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    uint8_t *b = malloc(n > 0 ? (size_t)n : 1);
    if (b && fread(b, 1, (size_t)n, f) != (size_t)n) {
        free(b);
        b = NULL;
    }
    fclose(f);
    *size = (size_t)n;
    return b;
}

/* A LAZ file of copies of the one chunk of src (at least `want` points):
 * header and VLRs as they are (counts, chunk size and EVLRs adjusted), the
 * chunk repeated, a chunk table of equal sizes. */
static uint8_t *repeat_laz(const uint8_t *src, size_t size, size_t want, size_t *out_size,
                           size_t *out_n)
{
    tsl_las_header h;
    tessel_diag d;
    if (tsl_las_header_parse(src, size, size, "src", &h, &d) != TESSEL_OK || !h.compressed)
        return NULL;
    size_t vlen;
    const uint8_t *vlr = tsl_las_find_vlr(src, &h, "laszip encoded", 22204, &vlen);
    if (!vlr)
        return NULL;
    size_t po = h.point_offset, pts = (size_t)h.count;
    uint64_t table = 0;
    for (int k = 0; k < 8; k++)
        table |= (uint64_t)src[po + k] << (8 * k);
    if (table >= size || pts == 0)
        return NULL;
    size_t chunk = (size_t)table - (po + 8), copies = (want + pts - 1) / pts;
    size_t n = copies * pts;
    enc e = {NULL, 0, 0, 0, 0xFFFFFFFFu};
    laz_ic ic;
    laz_ic_alloc(&ic, 32, 2, 8, 0);
    laz_ic_init(&ic);
    for (size_t i = 0; i < copies; i++)
        enc_int(&e, &ic, i ? (int32_t)chunk : 0, (int32_t)chunk, 1);
    enc_done(&e);
    laz_ic_free(&ic);
    size_t total = po + 8 + copies * chunk + 8 + e.n;
    uint8_t *out = malloc(total);
    memcpy(out, src, po);
    uint64_t tpos = po + 8 + (uint64_t)copies * chunk;
    for (int k = 0; k < 8; k++)
        out[po + k] = (uint8_t)(tpos >> (8 * k));
    for (size_t i = 0; i < copies; i++)
        memcpy(out + po + 8 + i * chunk, src + po + 8, chunk);
    uint8_t *t = out + tpos;
    put32(t, 0);
    put32(t + 4, (uint32_t)copies);
    memcpy(t + 8, e.out, e.n);
    free(e.out);
    put32(out + (vlr - src) + 12, (uint32_t)pts); /* chunk size */
    put32(out + 107, h.format < 6 && n <= UINT32_MAX ? (uint32_t)n : 0);
    if (h.minor >= 4) {
        for (int k = 0; k < 8; k++) {
            out[247 + k] = (uint8_t)((uint64_t)n >> (8 * k));
            out[235 + k] = 0; /* no EVLRs */
        }
        put32(out + 243, 0);
    }
    *out_size = total;
    *out_n = n;
    return out;
}

/* Seconds to decode every point of a LAZ file in memory on `threads`
 * threads (CPU time for one thread, wall time otherwise). */
static double time_laz_decode(const uint8_t *data, size_t size, uint8_t *records, int threads)
{
    tsl_laz *z;
    tessel_diag d;
    if (tsl_laz_open_memory(&z, data, size, "b.laz", &d) != TESSEL_OK) {
        fprintf(stderr, "bench_formats: %s\n", d.message);
        exit(1);
    }
    double t0 = bench_clock(threads == 1);
    tessel_status st = tsl_laz_decode_all(z, records, threads, &d);
    double t = bench_clock(threads == 1) - t0;
    tsl_laz_close(z);
    if (st != TESSEL_OK) {
        fprintf(stderr, "bench_formats: %s\n", d.message);
        exit(1);
    }
    return t;
}

/* A LAZ file as it is: the decoder alone on one and two threads. */
static void bench_laz_file(const char *path)
{
    size_t size;
    uint8_t *data = load_file(path, &size);
    tsl_laz *z;
    tessel_diag d;
    if (!data || tsl_laz_open_memory(&z, data, size, path, &d) != TESSEL_OK) {
        fprintf(stderr, "bench_formats: %s: %s\n", path, data ? d.message : "cannot read");
        free(data);
        return;
    }
    const tsl_laz_info *info = tsl_laz_get_info(z);
    size_t n = (size_t)info->header.count;
    uint8_t *records = malloc(n * info->header.record_length + 1);
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    char label[96];
    for (int threads = 1; threads <= 2; threads++) {
        snprintf(label, sizeof label, "%.40s format %u, %d thr", base, info->header.format,
                 threads);
        report(label, n, size, time_laz_decode(data, size, records, threads),
               time_laz_decode(data, size, records, threads),
               time_laz_decode(data, size, records, threads));
    }
    free(records);
    tsl_laz_close(z);
    free(data);
}

static void bench_laz(const char *dir, const char *file, const char *what, size_t want)
{
    char path[2048];
    snprintf(path, sizeof path, "%s/%s", dir, file);
    size_t size, big_size, n;
    uint8_t *src = load_file(path, &size);
    uint8_t *big = src ? repeat_laz(src, size, want, &big_size, &n) : NULL;
    if (!big) {
        fprintf(stderr, "bench_formats: %s: not found or not a one-chunk LAZ file\n", path);
        free(src);
        return;
    }
    uint8_t *records = malloc(n * 64);
    char label[96];
    for (int threads = 1; threads <= 2; threads++) {
        snprintf(label, sizeof label, "%s decode, %d thread%s", what, threads,
                 threads > 1 ? "s" : "");
        report(label, n, big_size, time_laz_decode(big, big_size, records, threads),
               time_laz_decode(big, big_size, records, threads),
               time_laz_decode(big, big_size, records, threads));
    }
    snprintf(label, sizeof label, "%s read (public)", what);
    report(label, n, big_size, time_parse(big, big_size, "b.laz", n),
           time_parse(big, big_size, "b.laz", n), time_parse(big, big_size, "b.laz", n));
    free(records);
    free(big);
    free(src);
}

/* The floor for text: strtod on every number, nothing else. */
static double time_strtod(const char *text, size_t n, double *checksum)
{
    double t0 = bench_now();
    const char *p = text;
    double sum = 0;
    for (size_t i = 0; i < 3 * n; i++) {
        char *end;
        sum += strtod(p, &end);
        p = end;
    }
    *checksum = sum;
    return bench_now() - t0;
}


static bool is_laz_path(const char *a)
{
    size_t len = strlen(a);
    return len > 4 && strcmp(a + len - 4, ".laz") == 0;
}

int main(int argc, char **argv)
{
    /* N and LAZ_DIR are the arguments that are not .laz files */
    const char *plain[2] = {NULL, NULL};
    int n_plain = 0;
    for (int i = 1; i < argc; i++)
        if (!is_laz_path(argv[i]) && n_plain < 2)
            plain[n_plain++] = argv[i];
    size_t n = plain[0] ? (size_t)strtoull(plain[0], NULL, 10) : 1000000;
    if (n == 0) {
        fprintf(stderr, "usage: bench_formats [N [LAZ_DIR]] [FILE.laz...]\n");
        return 1;
    }
    float *xyz = bench_torus(n, 42);
    size_t las_size, xyz_size, xyzn_size;
    uint8_t *las = make_las(xyz, n, &las_size);
    char *txt = make_xyz(xyz, n, 0, &xyz_size);
    char *txtn = make_xyz(xyz, n, 1, &xyzn_size);
    if (!xyz || !las || !txt || !txtn) {
        fprintf(stderr, "bench_formats: out of memory\n");
        return 1;
    }
    printf("tessel %s, reader throughput (median of 3, in memory)\n", tessel_version());
    report("LAS 1.2 format 3", n, las_size, time_parse(las, las_size, "b.las", n),
           time_parse(las, las_size, "b.las", n), time_parse(las, las_size, "b.las", n));
    report("XYZ x y z", n, xyz_size, time_parse(txt, xyz_size, "b.xyz", n),
           time_parse(txt, xyz_size, "b.xyz", n), time_parse(txt, xyz_size, "b.xyz", n));
    report("XYZ x y z nx ny nz", n, xyzn_size, time_parse(txtn, xyzn_size, "b.xyz", n),
           time_parse(txtn, xyzn_size, "b.xyz", n), time_parse(txtn, xyzn_size, "b.xyz", n));
    double s1, s2, s3;
    report("strtod loop (x y z, floor)", n, xyz_size, time_strtod(txt, n, &s1),
           time_strtod(txt, n, &s2), time_strtod(txt, n, &s3));
    printf("(strtod checksum %.6g)\n", s1 + s2 + s3);
    /* the source tree's test files, unless a folder is given */
    char dir[2048];
    if (plain[1]) {
        snprintf(dir, sizeof dir, "%s", plain[1]);
    } else {
        snprintf(dir, sizeof dir, "%s", __FILE__);
        char *slash = strrchr(dir, '/');
        snprintf(slash ? slash + 1 : dir, sizeof dir - (size_t)(slash ? slash + 1 - dir : 0),
                 "../tests/data/laz");
    }
    bench_laz(dir, "simple.laz", "LAZ 1.2 format 3", n);
    bench_laz(dir, "gen_fmt7_plain.laz", "LAZ 1.4 format 7", n);
    for (int i = 1; i < argc; i++)
        if (is_laz_path(argv[i]))
            bench_laz_file(argv[i]);
    free(xyz);
    free(las);
    free(txt);
    free(txtn);
    return 0;
}
