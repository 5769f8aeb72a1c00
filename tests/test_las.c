/* LAS reader: files built here in memory for every version (1.0-1.4) and
 * point data record format (0-10), with VLRs, extra bytes, 8- and 16-bit
 * colour, EVLRs, zero points and georeferenced coordinates; every header
 * lie we know of; every prefix of a valid file. */
#include "format_helpers.h"

#include <math.h>

static const uint16_t min_len[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};
static const uint8_t rgb_at[11] = {0, 0, 20, 28, 0, 28, 0, 30, 30, 0, 30};

typedef struct las_spec {
    int minor, format;
    size_t n;
    size_t extra;          /* extra bytes per record */
    int vlrs;              /* VLRs of 10 payload bytes each */
    int evlrs;             /* 1.4: EVLRs of 16 payload bytes after the points */
    double scale[3], offset[3];
    const int32_t *X;      /* n*3 */
    const uint16_t *rgb;   /* n*3 or NULL */
    int legacy_count_too;  /* 1.4 formats 0-5: also fill the legacy count */
} las_spec;

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
static void put64(uint8_t *p, uint64_t v)
{
    for (int k = 0; k < 8; k++)
        p[k] = (uint8_t)(v >> (8 * k));
}
static void putf64(uint8_t *p, double d)
{
    uint64_t u;
    memcpy(&u, &d, sizeof u);
    put64(p, u);
}

static size_t header_size(int minor) { return minor >= 4 ? 375 : minor == 3 ? 235 : 227; }

/* Builds a LAS file as the specification lays it out. */
static uint8_t *make_las(const las_spec *s, size_t *size)
{
    size_t hs = header_size(s->minor);
    size_t vlr_bytes = (size_t)s->vlrs * (54 + 10) + (s->minor == 0 ? 2 : 0);
    size_t rec = min_len[s->format] + s->extra;
    size_t point_offset = hs + vlr_bytes;
    size_t evlr_bytes = (size_t)s->evlrs * (60 + 16);
    *size = point_offset + s->n * rec + evlr_bytes;
    uint8_t *d = calloc(*size, 1);
    memcpy(d, "LASF", 4);
    d[24] = 1;
    d[25] = (uint8_t)s->minor;
    memcpy(d + 26, "tessel test", 11);
    put16(d + 94, (unsigned)hs);
    put32(d + 96, (uint32_t)point_offset);
    put32(d + 100, (uint32_t)s->vlrs);
    d[104] = (uint8_t)s->format;
    put16(d + 105, (unsigned)rec);
    if (s->format < 6 && (s->minor < 4 || s->legacy_count_too))
        put32(d + 107, (uint32_t)s->n);
    double lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
    for (size_t i = 0; i < s->n; i++)
        for (int k = 0; k < 3; k++) {
            double w = s->X[3 * i + k] * s->scale[k] + s->offset[k];
            if (i == 0 || w < lo[k])
                lo[k] = w;
            if (i == 0 || w > hi[k])
                hi[k] = w;
        }
    for (int k = 0; k < 3; k++) {
        putf64(d + 131 + 8 * k, s->scale[k]);
        putf64(d + 155 + 8 * k, s->offset[k]);
        putf64(d + 179 + 16 * k, hi[k]);
        putf64(d + 187 + 16 * k, lo[k]);
    }
    if (s->minor >= 4) {
        put64(d + 235, s->evlrs ? point_offset + s->n * rec : 0);
        put32(d + 243, (uint32_t)s->evlrs);
        put64(d + 247, s->n);
    }
    uint8_t *p = d + hs;
    for (int v = 0; v < s->vlrs; v++, p += 64) {
        memcpy(p + 2, "tessel", 6);
        put16(p + 18, 1000 + (unsigned)v);
        put16(p + 20, 10);
        memset(p + 54, 0xAB, 10);
    }
    if (s->minor == 0) {
        p[0] = 0xDD;
        p[1] = 0xCC;
    }
    for (size_t i = 0; i < s->n; i++) {
        uint8_t *r = d + point_offset + i * rec;
        /* Everything but X, Y, Z and RGB is noise the reader must skip. */
        for (size_t k = 12; k < rec; k++)
            r[k] = (uint8_t)(fmt_rand() * 256);
        for (int k = 0; k < 3; k++)
            put32(r + 4 * k, (uint32_t)s->X[3 * i + k]);
        if (rgb_at[s->format] && s->rgb)
            for (int k = 0; k < 3; k++)
                put16(r + rgb_at[s->format] + 2 * k, s->rgb[3 * i + k]);
    }
    p = d + point_offset + s->n * rec;
    for (int v = 0; v < s->evlrs; v++, p += 76) {
        memcpy(p + 2, "tessel", 6);
        put64(p + 20, 16);
    }
    return d;
}

static tessel_status parse(const uint8_t *data, size_t size, tessel_cloud *c, tessel_diag *d)
{
    return fmt_parse_cloud(tsl_parse_las, data, size, c, d);
}

/* Random points in a box; colours 16-bit (wide) or 8-bit. */
static void fill(size_t n, int32_t *X, uint16_t *rgb, int32_t range, int wide)
{
    for (size_t i = 0; i < 3 * n; i++) {
        X[i] = (int32_t)((fmt_rand() - 0.5) * 2.0 * range);
        rgb[i] = (uint16_t)(fmt_rand() * (wide ? 65536 : 256));
    }
}

static void check_points(const las_spec *s, const tessel_cloud *c, double tol,
                         const char *what)
{
    CHECK_MSG(c->count == s->n, "%s: %zu points, expected %zu", what, c->count, s->n);
    if (c->count != s->n)
        return;
    double worst = 0;
    for (size_t i = 0; i < s->n; i++)
        for (int k = 0; k < 3; k++) {
            double want = s->X[3 * i + k] * s->scale[k] + s->offset[k];
            double got = c->offset[k] + c->xyz[3 * i + k];
            if (fabs(got - want) > worst)
                worst = fabs(got - want);
        }
    CHECK_MSG(worst <= tol, "%s: worst coordinate error %g > %g", what, worst, tol);
    int has_rgb = rgb_at[s->format] != 0;
    CHECK_MSG((c->rgb != NULL) == has_rgb, "%s: colour presence", what);
    if (has_rgb && c->rgb && s->rgb) {
        int wide = 0;
        for (size_t i = 0; i < 3 * s->n; i++)
            wide |= s->rgb[i] > 255;
        size_t bad = 0;
        for (size_t i = 0; i < 3 * s->n; i++)
            bad += c->rgb[i] != (uint8_t)(wide ? s->rgb[i] >> 8 : s->rgb[i]);
        CHECK_MSG(bad == 0, "%s: %zu colour values differ", what, bad);
    }
    CHECK(c->normals == NULL && c->grid == NULL);
}

static void test_versions_and_formats(void)
{
    enum { N = 64 };
    int32_t X[3 * N];
    uint16_t rgb[3 * N];
    /* The formats each version introduced. */
    static const int max_format[5] = {1, 1, 3, 5, 10};
    for (int minor = 0; minor <= 4; minor++) {
        for (int format = 0; format <= max_format[minor]; format++) {
            for (int variant = 0; variant < 2; variant++) {
                fill(N, X, rgb, 100000, variant);
                las_spec s = {minor, format, N, variant ? 7 : 0, variant ? 2 : 0,
                              minor == 4 && variant, {0.01, 0.01, 0.001},
                              {1000, -2000, 5}, X, rgb, variant};
                size_t size;
                uint8_t *data = make_las(&s, &size);
                tessel_cloud c;
                tessel_diag d;
                char what[64];
                snprintf(what, sizeof what, "LAS 1.%d format %d variant %d", minor, format,
                         variant);
                tessel_status st = parse(data, size, &c, &d);
                CHECK_MSG(st == TESSEL_OK, "%s: %s", what, d.message);
                /* |world| <= 3000: floats are exact to ~2.5e-4 there */
                check_points(&s, &c, 5e-4, what);
                tessel_cloud_free(&c);
                free(data);
            }
        }
    }
}

static void test_colour_and_counts(void)
{
    enum { N = 20 };
    int32_t X[3 * N];
    uint16_t rgb[3 * N];
    fill(N, X, rgb, 1000, 0);
    /* 8-bit values stored in the 16-bit fields are kept as they are. */
    las_spec s = {2, 3, N, 0, 0, 0, {0.01, 0.01, 0.01}, {0, 0, 0}, X, rgb, 0};
    size_t size;
    uint8_t *data = make_las(&s, &size);
    tessel_cloud c;
    tessel_diag d;
    CHECK(parse(data, size, &c, &d) == TESSEL_OK);
    check_points(&s, &c, 1e-4, "8-bit colour");
    tessel_cloud_free(&c);
    free(data);
    /* One value above 255 switches the whole file to >> 8. */
    rgb[7] = 300;
    data = make_las(&s, &size);
    CHECK(parse(data, size, &c, &d) == TESSEL_OK);
    check_points(&s, &c, 1e-4, "16-bit colour");
    CHECK(c.count == N && c.rgb[7] == 1);
    tessel_cloud_free(&c);
    free(data);

    /* Zero points. */
    las_spec z = {2, 1, 0, 0, 1, 0, {0.01, 0.01, 0.01}, {0, 0, 0}, X, rgb, 0};
    data = make_las(&z, &size);
    CHECK(parse(data, size, &c, &d) == TESSEL_OK && c.count == 0);
    tessel_cloud_free(&c);
    free(data);

    /* 1.4, format 1: the 64-bit count is used when the legacy one is 0 and
     * must win when both are present. */
    las_spec l = {4, 1, N, 0, 0, 0, {0.01, 0.01, 0.01}, {0, 0, 0}, X, rgb, 0};
    data = make_las(&l, &size);
    CHECK(parse(data, size, &c, &d) == TESSEL_OK && c.count == N);
    tessel_cloud_free(&c);
    put32(data + 107, 5); /* stale legacy count */
    CHECK(parse(data, size, &c, &d) == TESSEL_OK && c.count == N);
    tessel_cloud_free(&c);
    free(data);
}

static void test_georeferenced(void)
{
    /* UTM coordinates with millimetre scale over a 2 km tile: every point
     * must come back within 1 mm (it would be ~6 cm with plain floats). */
    enum { N = 2000 };
    int32_t *X = malloc(3 * N * sizeof(int32_t));
    uint16_t *rgb = malloc(3 * N * sizeof(uint16_t));
    fill(N, X, rgb, 1000000, 1);
    las_spec s = {4, 7, N, 0, 1, 0, {0.001, 0.001, 0.001}, {637000, 5120000, 300}, X, rgb,
                  0};
    size_t size;
    uint8_t *data = make_las(&s, &size);
    tessel_cloud c;
    tessel_diag d;
    CHECK(parse(data, size, &c, &d) == TESSEL_OK);
    CHECK(c.offset[0] > 600000 && c.offset[1] > 5000000);
    check_points(&s, &c, 1e-3, "UTM");
    tessel_cloud_free(&c);
    free(data);
    free(X);
    free(rgb);
}

static void test_lies(void)
{
    enum { N = 10 };
    int32_t X[3 * N];
    uint16_t rgb[3 * N];
    fill(N, X, rgb, 1000, 1);
    las_spec s = {4, 6, N, 2, 2, 2, {0.01, 0.01, 0.01}, {0, 0, 0}, X, rgb, 0};
    size_t size;
    uint8_t *base = make_las(&s, &size);
    uint8_t *data = malloc(size);
    tessel_cloud c;
    tessel_diag d;
    CHECK(parse(base, size, &c, &d) == TESSEL_OK && c.count == N);
    tessel_cloud_free(&c);
    size_t point_offset = 375 + 2 * 64;

#define MUTATE(stmt, expect, substring, off)                                     \
    do {                                                                         \
        memcpy(data, base, size);                                                \
        stmt;                                                                    \
        tessel_status st_ = parse(data, size, &c, &d);                           \
        CHECK_MSG(st_ == (expect), "%s: got %s (%s)", #stmt, tessel_status_str(st_), \
                  d.message);                                                    \
        CHECK_MSG(strstr(d.message, substring) != NULL, "%s: message '%s'", #stmt, \
                  d.message);                                                    \
        CHECK_MSG(d.has_offset && d.offset == (uint64_t)(off), "%s: offset %llu", #stmt, \
                  (unsigned long long)d.offset);                                 \
        tessel_cloud_free(&c);                                                   \
    } while (0)

    MUTATE(data[3] = 'Z', TESSEL_ERR_PARSE, "LASF", 0);
    MUTATE(data[24] = 2, TESSEL_ERR_UNSUPPORTED, "version 2.4", 24);
    MUTATE(data[25] = 5, TESSEL_ERR_UNSUPPORTED, "version 1.5", 24);
    MUTATE(put16(data + 94, 300), TESSEL_ERR_PARSE, "header size 300", 94);
    MUTATE(put32(data + 96, (uint32_t)size + 1), TESSEL_ERR_PARSE, "offset to point data",
           96);
    MUTATE(put32(data + 96, 100), TESSEL_ERR_PARSE, "offset to point data", 96);
    MUTATE(data[104] = 0x86, TESSEL_ERR_UNSUPPORTED, "LAZ compressed", 104);
    MUTATE(data[104] = 11, TESSEL_ERR_UNSUPPORTED, "record format 11", 104);
    MUTATE(put16(data + 105, 29), TESSEL_ERR_PARSE, "shorter than the 30 bytes", 105);
    MUTATE(putf64(data + 139, 0.0), TESSEL_ERR_PARSE, "Y scale factor", 139);
    MUTATE(putf64(data + 171, NAN), TESSEL_ERR_PARSE, "Z scale factor", 147);
    MUTATE(put64(data + 247, (uint64_t)1 << 40), TESSEL_ERR_PARSE,
           "announces 1099511627776 points", point_offset);
    MUTATE(put64(data + 247, N + 1), TESSEL_ERR_PARSE, "extended VLR", 235);
    /* A VLR longer than the room before the points. */
    MUTATE(put16(data + 375 + 64 + 20, 11), TESSEL_ERR_PARSE, "record 2 of 2",
           375 + 64);
    /* An EVLR running past the end of the file. */
    MUTATE(put64(data + size - 76 + 20, 17), TESSEL_ERR_PARSE, "extended VLR 2 of 2",
           size - 76);
    MUTATE(put32(data + 243, 3), TESSEL_ERR_PARSE, "extended VLR 3 of 3", size);
    MUTATE(put64(data + 235, size + 10), TESSEL_ERR_PARSE, "extended VLRs at byte", 235);
#undef MUTATE

    /* A garbage VLR count with no room for any VLR (as PDAL's
     * garbage_nVariableLength.las) is read correctly: the point data offset
     * is consistent and the VLRs carry nothing we need. */
    las_spec g = {2, 0, N, 0, 0, 0, {0.01, 0.01, 0.01}, {0, 0, 0}, X, rgb, 0};
    size_t gsize;
    uint8_t *gdata = make_las(&g, &gsize);
    put32(gdata + 100, 1069128089u);
    CHECK(parse(gdata, gsize, &c, &d) == TESSEL_OK);
    check_points(&g, &c, 1e-4, "garbage VLR count");
    tessel_cloud_free(&c);
    free(gdata);

    /* The point limit. */
    tsl_builder b;
    tessel_read_params rp = tessel_read_params_default();
    rp.max_points = N - 1;
    tsl_builder_init(&b, &rp);
    CHECK(tsl_parse_las(base, size, "m", 0, &b, &d) == TESSEL_ERR_LIMIT);
    CHECK(strstr(d.message, "limit") != NULL);
    tsl_builder_free(&b);

    /* Every prefix fails cleanly (the file is only complete at its end). */
    CHECK(fmt_every_prefix(tsl_parse_las, base, size) == 0);
    free(data);
    free(base);
}

static void test_bad_files(void)
{
    fmt_check_bad(tsl_parse_las, "las_bad_signature.las", 0, TESSEL_ERR_PARSE,
                  "missing \"LASF\" signature", 0, 0);
    fmt_check_bad(tsl_parse_las, "las_truncated.las", 0, TESSEL_ERR_PARSE,
                  "announces 10 points of 20 bytes from byte 227, but only 110 bytes follow",
                  0, 227);
    fmt_check_bad(tsl_parse_las, "las_lying_vlr.las", 0, TESSEL_ERR_PARSE,
                  "record 2 of 2 (60000 bytes) runs past the point data", 0, 291);
    fmt_check_bad(tsl_parse_las, "las_laz.las", 0, TESSEL_ERR_UNSUPPORTED, "LAZ compressed",
                  0, 104);
    fmt_check_bad(tsl_parse_las, "las_absurd_count.las", 0, TESSEL_ERR_PARSE,
                  "announces 4294967280 points", 0, 227);
}


/* The public entry point recognises LAS by its signature. */
static void test_public_api(void)
{
    enum { N = 5 };
    int32_t X[3 * N];
    uint16_t rgb[3 * N];
    fill(N, X, rgb, 1000, 1);
    las_spec s = {3, 5, N, 0, 1, 0, {0.01, 0.01, 0.01}, {0, 0, 0}, X, rgb, 0};
    size_t size;
    uint8_t *data = make_las(&s, &size);
    tessel_cloud c;
    tessel_diag d;
    CHECK(tessel_cloud_parse(&c, data, size, NULL, NULL, &d) == TESSEL_OK);
    check_points(&s, &c, 1e-4, "sniffed");
    tessel_cloud_free(&c);
    tessel_mesh m;
    CHECK(tessel_mesh_parse(&m, data, size, "x.las", NULL, &d) == TESSEL_OK &&
          m.vertex_count == N && m.triangle_count == 0);
    tessel_mesh_free(&m);
    free(data);
}

int main(void)
{
    test_versions_and_formats();
    test_colour_and_counts();
    test_georeferenced();
    test_lies();
    test_bad_files();
    test_public_api();
    return TEST_SUMMARY();
}
