/* PCD reader: ascii and binary data, every field type, skipped fields with
 * COUNT > 1, normals, packed rgb (float and uint32, binary and text),
 * organized clouds with NaN cells, VIEWPOINT, .6 headers; lying headers
 * with their line or byte offset; every prefix of valid files. */
#include "format_helpers.h"

#include <math.h>

static tessel_status parse(const void *data, size_t size, tessel_cloud *c, tessel_diag *d)
{
    return fmt_parse_cloud(tsl_parse_pcd, data, size, c, d);
}

/* Appends value bytes little-endian whatever the host. */
static void put_le(uint8_t **p, const void *value, size_t size)
{
    const uint16_t one = 1;
    int little = *(const uint8_t *)&one == 1;
    const uint8_t *v = value;
    for (size_t k = 0; k < size; k++)
        (*p)[k] = little ? v[k] : v[size - 1 - k];
    *p += size;
}

static void test_ascii(void)
{
    /* rgb as PCL >= 1.8 writes it (uint32 text) and as older versions did
     * (the float whose bits are the colour). */
    float legacy;
    uint32_t bits = 0x00102030u;
    memcpy(&legacy, &bits, sizeof legacy);
    char text[1024];
    snprintf(text, sizeof text,
             "# .PCD v0.7 - Point Cloud Data file format\n"
             "VERSION 0.7\n"
             "FIELDS x y z rgb\n"
             "SIZE 4 4 4 4\n"
             "TYPE F F F F\n"
             "COUNT 1 1 1 1\n"
             "WIDTH 3\n"
             "HEIGHT 1\n"
             "VIEWPOINT 1 2 3 1 0 0 0\n"
             "POINTS 3\n"
             "DATA ascii\n"
             "0.5 1.5 -2 16711680\n"
             "1 2 3 %.9g\n"
             "nan 0 0 255\n",
             (double)legacy);
    tessel_cloud c;
    tessel_diag d;
    CHECK_MSG(parse(text, strlen(text), &c, &d) == TESSEL_OK, "%s", d.message);
    CHECK(c.count == 2 && c.dropped_nonfinite == 1 && c.rgb && !c.normals && !c.grid);
    if (c.count == 2 && c.rgb) {
        CHECK(c.xyz[0] == 0.5f && c.xyz[1] == 1.5f && c.xyz[2] == -2);
        CHECK(c.rgb[0] == 255 && c.rgb[1] == 0 && c.rgb[2] == 0);
        CHECK(c.rgb[3] == 0x10 && c.rgb[4] == 0x20 && c.rgb[5] == 0x30);
    }
    CHECK(c.has_viewpoint && c.viewpoint[0] == 1 && c.viewpoint[1] == 2 &&
          c.viewpoint[2] == 3);
    tessel_cloud_free(&c);

    /* A .6 header: no VIEWPOINT, no COUNT; normals; an unknown field. */
    const char *v6 = "VERSION .6\nFIELDS x y z normal_x normal_y normal_z curvature\n"
                     "SIZE 4 4 4 4 4 4 4\nTYPE F F F F F F F\nWIDTH 2\nHEIGHT 1\n"
                     "POINTS 2\nDATA ascii\n1 2 3 0 0 1 0.1\n4 5 6 0 1 0 0.2\n";
    CHECK_MSG(parse(v6, strlen(v6), &c, &d) == TESSEL_OK, "%s", d.message);
    CHECK(c.count == 2 && c.normals && !c.rgb && !c.has_viewpoint);
    if (c.count == 2 && c.normals)
        CHECK(c.normals[2] == 1 && c.normals[4] == 1 && c.xyz[5] == 6);
    tessel_cloud_free(&c);

    /* COUNT > 1 fields are skipped in text too. */
    const char *multi = "FIELDS hist x y z\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 3 1 1 1\n"
                        "WIDTH 1\nPOINTS 1\nDATA ascii\n9 9 9 7 8 9\n";
    CHECK_MSG(parse(multi, strlen(multi), &c, &d) == TESSEL_OK, "%s", d.message);
    CHECK(c.count == 1 && c.xyz[0] == 7 && c.xyz[2] == 9);
    tessel_cloud_free(&c);
}

/* One binary file with every field type and skipped fields in between. */
static void test_binary_types(void)
{
    const char *header = "VERSION 0.7\n"
                         "FIELDS pad x y z a normal_x normal_y normal_z rgba fpfh\n"
                         "SIZE 1 8 2 4 1 4 4 4 4 4\n"
                         "TYPE U F I I I F F F U F\n"
                         "COUNT 3 1 1 1 1 1 1 1 1 33\n"
                         "WIDTH 4\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 4\nDATA binary\n";
    size_t rec = 3 + 8 + 2 + 4 + 1 + 12 + 4 + 33 * 4;
    size_t hl = strlen(header);
    size_t size = hl + 4 * rec;
    uint8_t *data = calloc(size, 1);
    memcpy(data, header, hl);
    uint8_t *p = data + hl;
    for (int i = 0; i < 4; i++) {
        uint8_t pad[3] = {0xFF, 0xFF, 0xFF};
        put_le(&p, pad, 3);
        double x = -1.25 * i;
        int16_t y = (int16_t)(-300 * i);
        int32_t z = 100000 * i;
        int8_t a = -5;
        float n[3] = {0, (float)(i == 1), (float)(i != 1)};
        uint32_t rgba = 0xFF000000u | (uint32_t)(i * 0x010203);
        put_le(&p, &x, 8);
        put_le(&p, &y, 2);
        put_le(&p, &z, 4);
        put_le(&p, &a, 1);
        for (int k = 0; k < 3; k++)
            put_le(&p, &n[k], 4);
        put_le(&p, &rgba, 4);
        for (int k = 0; k < 33; k++) {
            float f = (float)k;
            put_le(&p, &f, 4);
        }
    }
    CHECK(p == data + size);
    tessel_cloud c;
    tessel_diag d;
    CHECK_MSG(parse(data, size, &c, &d) == TESSEL_OK, "%s", d.message);
    CHECK(c.count == 4 && c.normals && c.rgb && c.has_viewpoint);
    if (c.count == 4 && c.normals && c.rgb) {
        for (int i = 0; i < 4; i++) {
            CHECK(c.offset[0] + c.xyz[3 * i] == -1.25 * i);
            CHECK(c.offset[1] + c.xyz[3 * i + 1] == -300.0 * i);
            CHECK(c.offset[2] + c.xyz[3 * i + 2] == 100000.0 * i);
            CHECK(c.normals[3 * i + 1] == (float)(i == 1));
            CHECK(c.rgb[3 * i] == i && c.rgb[3 * i + 1] == 2 * i && c.rgb[3 * i + 2] == 3 * i);
        }
    }
    tessel_cloud_free(&c);
    /* Every prefix fails cleanly (the cut binary data is always short). */
    CHECK(fmt_every_prefix(tsl_parse_pcd, data, size) == 0);
    /* Trailing bytes after the announced records are ignored. */
    uint8_t *longer = calloc(size + 5, 1);
    memcpy(longer, data, size);
    CHECK(parse(longer, size + 5, &c, &d) == TESSEL_OK && c.count == 4);
    tessel_cloud_free(&c);
    free(longer);
    free(data);

    /* Integer types: I1 I4 I8 U1 U2 U4 U8 on x, y, z across three files. */
    static const struct {
        const char *type;
        unsigned size;
        int64_t value;
    } ints[] = {{"I", 1, -128}, {"I", 2, -32768}, {"I", 4, -2000000000},
                {"I", 8, -4000000000LL}, {"U", 1, 255}, {"U", 2, 65535},
                {"U", 4, 4000000000LL}, {"U", 8, 5000000000LL}};
    for (size_t t = 0; t < sizeof ints / sizeof ints[0]; t++) {
        char h[256];
        unsigned sz = ints[t].size;
        snprintf(h, sizeof h,
                 "FIELDS x y z\nSIZE %u %u %u\nTYPE %s %s %s\nWIDTH 1\nPOINTS 1\nDATA "
                 "binary\n",
                 sz, sz, sz, ints[t].type, ints[t].type, ints[t].type);
        size_t l = strlen(h);
        uint8_t buf[300];
        memcpy(buf, h, l);
        uint8_t *q = buf + l;
        for (int k = 0; k < 3; k++) {
            int64_t v = k == 0 ? ints[t].value : k;
            uint64_t u;
            memcpy(&u, &v, sizeof u);
            for (unsigned b = 0; b < sz; b++)
                *q++ = (uint8_t)(u >> (8 * b));
        }
        CHECK_MSG(parse(buf, (size_t)(q - buf), &c, &d) == TESSEL_OK, "%s", d.message);
        CHECK_MSG(c.count == 1 && c.offset[0] + c.xyz[0] == (double)ints[t].value &&
                      c.xyz[1] == 1 && c.xyz[2] == 2,
                  "type %s%u", ints[t].type, sz);
        tessel_cloud_free(&c);
    }
}

static void test_organized(void)
{
    /* 3 x 2 grid, cell (1, 0) missing (NaN), binary. */
    const char *header = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 3\n"
                         "HEIGHT 2\nVIEWPOINT 0.5 0 -1 1 0 0 0\nPOINTS 6\nDATA binary\n";
    size_t hl = strlen(header), size = hl + 6 * 12;
    uint8_t *data = malloc(size);
    memcpy(data, header, hl);
    uint8_t *p = data + hl;
    for (int i = 0; i < 6; i++) {
        float v[3] = {(float)(i % 3), (float)(i / 3), 1.0f};
        if (i == 1)
            v[0] = v[1] = v[2] = NAN;
        for (int k = 0; k < 3; k++)
            put_le(&p, &v[k], 4);
    }
    tessel_cloud c;
    tessel_diag d;
    CHECK_MSG(parse(data, size, &c, &d) == TESSEL_OK, "%s", d.message);
    CHECK(c.width == 3 && c.height == 2 && c.grid && c.count == 5 &&
          c.dropped_nonfinite == 1);
    if (c.grid && c.count == 5) {
        CHECK(c.grid[0] == 0 && c.grid[1] == TESSEL_NONE && c.grid[2] == 1 &&
              c.grid[5] == 4);
        CHECK(c.xyz[3 * c.grid[5]] == 2 && c.xyz[3 * c.grid[5] + 1] == 1);
    }
    CHECK(c.has_viewpoint && c.viewpoint[0] == 0.5 && c.viewpoint[2] == -1);
    tessel_cloud_free(&c);
    free(data);

    /* The same in ascii, with PCL's "nan" for the missing cell. */
    const char *text = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 2\nHEIGHT 2\n"
                       "POINTS 4\nDATA ascii\n0 0 1\nnan nan nan\n0 1 1\n1 1 1\n";
    CHECK_MSG(parse(text, strlen(text), &c, &d) == TESSEL_OK, "%s", d.message);
    CHECK(c.count == 3 && c.grid && c.grid[1] == TESSEL_NONE && c.grid[3] == 2);
    tessel_cloud_free(&c);
    CHECK(fmt_every_prefix(tsl_parse_pcd, text, strlen(text)) == 0);
}

static void expect_error(const char *text, tessel_status expect, const char *substring,
                         uint64_t line)
{
    tessel_cloud c;
    tessel_diag d;
    tessel_status st = parse(text, strlen(text), &c, &d);
    CHECK_MSG(st == expect && strstr(d.message, substring) && (!line || d.line == line),
              "got %s line %llu '%s', expected '%s' line %llu", tessel_status_str(st),
              (unsigned long long)d.line, d.message, substring, (unsigned long long)line);
    tessel_cloud_free(&c);
}

static void test_errors(void)
{
    expect_error("FIELDS x y z\nSIZE 4 4\n", TESSEL_ERR_PARSE,
                 "SIZE has 2 entries but FIELDS names 3", 2);
    expect_error("FIELDS x y z\nSIZE 4 2 4\nTYPE F F F\nWIDTH 1\nDATA ascii\n1 2 3\n",
                 TESSEL_ERR_PARSE, "field 'y' has TYPE F with SIZE 2", 5);
    expect_error("FIELDS x y z\nSIZE 4 4 4\nTYPE F F D\n", TESSEL_ERR_PARSE,
                 "TYPE must be F, I or U", 3);
    expect_error("FIELDS a b c\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nDATA ascii\n1 2 3\n",
                 TESSEL_ERR_PARSE, "no x, y and z", 5);
    expect_error("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\n", TESSEL_ERR_PARSE,
                 "no DATA line", 4);
    expect_error("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 2\nDATA ascii\n1 2 3\n",
                 TESSEL_ERR_PARSE, "ends after 1 points, POINTS announced 2", 6);
    expect_error("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nDATA ascii\n1 2 3\n4 5 6\n",
                 TESSEL_ERR_PARSE, "more lines than the 1 POINTS", 7);
    expect_error("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nDATA ascii\n1 2\n",
                 TESSEL_ERR_PARSE, "expected 3 values", 6);
    expect_error("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nDATA ascii\n1 b 3\n",
                 TESSEL_ERR_PARSE, "bad value 'b' for field 'y'", 6);
    expect_error("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nBOGUS 3\n", TESSEL_ERR_PARSE,
                 "unknown keyword 'BOGUS'", 5);
    expect_error("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nVIEWPOINT 1 2 3\n",
                 TESSEL_ERR_PARSE, "VIEWPOINT needs 7 numbers", 5);
    expect_error("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 2 1 1\nWIDTH 1\nDATA ascii\n",
                 TESSEL_ERR_PARSE, "field 'x' must be a single", 6);
    expect_error("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 4294967296\nHEIGHT 2\n"
                 "DATA ascii\n",
                 TESSEL_ERR_LIMIT, "too large", 4);

    fmt_check_bad(tsl_parse_pcd, "pcd_lying_points.pcd", 0, TESSEL_ERR_PARSE,
                  "POINTS 5 does not match WIDTH 3 x HEIGHT 1", 9, UINT64_MAX);
    fmt_check_bad(tsl_parse_pcd, "pcd_compressed.pcd", 0, TESSEL_ERR_UNSUPPORTED,
                  "binary_compressed data is not supported", 10, UINT64_MAX);
    /* header of 140 bytes, 4 records of 12 announced, 30 bytes present */
    fmt_check_bad(tsl_parse_pcd, "pcd_truncated_binary.pcd", 0, TESSEL_ERR_PARSE,
                  "4 points of 12 bytes announced from byte 140, only 30 bytes follow", 0,
                  140 + 24);
    fmt_check_bad(tsl_parse_pcd, "pcd_size_type.pcd", 0, TESSEL_ERR_PARSE,
                  "field 'z' has TYPE F with SIZE 2", 10, UINT64_MAX);

    /* The point limit applies before anything is read. */
    tsl_builder b;
    tessel_read_params rp = tessel_read_params_default();
    rp.max_points = 1;
    tsl_builder_init(&b, &rp);
    const char *text = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 2\nDATA ascii\n1 2 3\n"
                       "4 5 6\n";
    tessel_diag d;
    CHECK(tsl_parse_pcd((const uint8_t *)text, strlen(text), "m", 0, &b, &d) ==
          TESSEL_ERR_LIMIT);
    tsl_builder_free(&b);
}


/* The public entry point recognises PCD by its header. */
static void test_public_api(void)
{
    const char *text = "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n"
                       "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nDATA ascii\n1 2 3\n";
    tessel_cloud c;
    tessel_diag d;
    CHECK_MSG(tessel_cloud_parse(&c, text, strlen(text), NULL, NULL, &d) == TESSEL_OK, "%s",
              d.message);
    CHECK(c.count == 1 && c.xyz[2] == 3);
    tessel_cloud_free(&c);
}

int main(void)
{
    test_ascii();
    test_binary_types();
    test_organized();
    test_errors();
    test_public_api();
    return TEST_SUMMARY();
}
