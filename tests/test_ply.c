/* PLY reader and writer: every scalar type in all three encodings, colours,
 * normals, skipped properties and elements, faces and fans, organized clouds
 * and viewpoints, exact round trips, every prefix of valid files (no crash,
 * OK or an error), and the bad files of tests/data/bad with their expected
 * messages and positions. */
#include "io/io.h"
#include "test.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* ---- a tiny PLY generator: header text + values in any encoding ---- */

enum { ENC_ASCII, ENC_LE, ENC_BE };
static const char *const enc_name[] = {"ascii", "binary_little_endian", "binary_big_endian"};

typedef struct gbuf {
    uint8_t *d;
    size_t n, cap;
} gbuf;

static void g_bytes(gbuf *g, const void *p, size_t n)
{
    if (g->n + n + 1 > g->cap) {
        g->cap = (g->n + n + 1) * 2;
        g->d = realloc(g->d, g->cap);
    }
    memcpy(g->d + g->n, p, n);
    g->n += n;
    g->d[g->n] = 0;
}

static void g_str(gbuf *g, const char *s) { g_bytes(g, s, strlen(s)); }

/* One value of a PLY type name ("uchar", "float32", ...). */
static void g_val(gbuf *g, int enc, const char *type, double v)
{
    if (enc == ENC_ASCII) {
        char b[64];
        snprintf(b, sizeof b, "%.17g ", v);
        g_str(g, b);
        return;
    }
    uint8_t b[8];
    size_t n;
    uint64_t u;
    if (!strcmp(type, "char") || !strcmp(type, "int8")) {
        n = 1;
        u = (uint8_t)(int8_t)v;
    } else if (!strcmp(type, "uchar") || !strcmp(type, "uint8")) {
        n = 1;
        u = (uint8_t)v;
    } else if (!strcmp(type, "short") || !strcmp(type, "int16")) {
        n = 2;
        u = (uint16_t)(int16_t)v;
    } else if (!strcmp(type, "ushort") || !strcmp(type, "uint16")) {
        n = 2;
        u = (uint16_t)v;
    } else if (!strcmp(type, "int") || !strcmp(type, "int32")) {
        n = 4;
        u = (uint32_t)(int32_t)v;
    } else if (!strcmp(type, "uint") || !strcmp(type, "uint32")) {
        n = 4;
        u = (uint32_t)v;
    } else if (!strcmp(type, "float") || !strcmp(type, "float32")) {
        n = 4;
        float f = (float)v;
        uint32_t x;
        memcpy(&x, &f, 4);
        u = x;
    } else {
        n = 8;
        memcpy(&u, &v, 8);
    }
    for (size_t i = 0; i < n; i++) {
        size_t shift = enc == ENC_LE ? i : n - 1 - i;
        b[i] = (uint8_t)(u >> (8 * shift));
    }
    g_bytes(g, b, n);
}

static void g_eol(gbuf *g, int enc)
{
    if (enc == ENC_ASCII)
        g_str(g, "\n");
}

static tessel_status parse_cloud(const gbuf *g, tessel_cloud *c, tessel_diag *d)
{
    tessel_read_params rp = tessel_read_params_default();
    rp.format = TESSEL_FORMAT_PLY;
    return tessel_cloud_parse(c, g->d, g->n, "gen.ply", &rp, d);
}

static tessel_status parse_mesh(const gbuf *g, tessel_mesh *m, tessel_diag *d)
{
    tessel_read_params rp = tessel_read_params_default();
    rp.format = TESSEL_FORMAT_PLY;
    return tessel_mesh_parse(m, g->d, g->n, "gen.ply", &rp, d);
}

/* ---- every scalar type for x, y, z ---- */

static void test_scalar_types(void)
{
    static const char *const types[] = {"char",  "int8",   "uchar",  "uint8",
                                         "short", "int16",  "ushort", "uint16",
                                         "int",   "int32",  "uint",   "uint32",
                                         "float", "float32", "double", "float64"};
    const int nt = (int)(sizeof types / sizeof types[0]);
    for (int enc = 0; enc < 3; enc++) {
        for (int t = 0; t < nt; t++) {
            const char *tx = types[t], *ty = types[(t + 5) % nt], *tz = types[(t + 11) % nt];
            gbuf g = {0};
            char h[512];
            snprintf(h, sizeof h,
                     "ply\nformat %s 1.0\nelement vertex 4\nproperty %s x\nproperty %s y\n"
                     "property %s z\nend_header\n",
                     enc_name[enc], tx, ty, tz);
            g_str(&g, h);
            for (int i = 0; i < 4; i++) {
                g_val(&g, enc, tx, 10 * i + 1);
                g_val(&g, enc, ty, 10 * i + 2);
                g_val(&g, enc, tz, 127 - i);
                g_eol(&g, enc);
            }
            tessel_cloud c;
            tessel_diag d;
            tessel_status st = parse_cloud(&g, &c, &d);
            CHECK_MSG(st == TESSEL_OK, "%s %s/%s/%s: %s", enc_name[enc], tx, ty, tz, d.message);
            bool ok = st == TESSEL_OK && c.count == 4;
            for (int i = 0; ok && i < 4; i++)
                ok = c.xyz[3 * i] == 10 * i + 1 && c.xyz[3 * i + 1] == 10 * i + 2 &&
                     c.xyz[3 * i + 2] == 127 - i;
            CHECK_MSG(ok, "%s %s/%s/%s values", enc_name[enc], tx, ty, tz);
            CHECK(!c.normals && !c.rgb);
            tessel_cloud_free(&c);
            free(g.d);
        }
    }
    /* Signed types keep their sign. */
    for (int enc = 0; enc < 3; enc++) {
        gbuf g = {0};
        char h[256];
        snprintf(h, sizeof h,
                 "ply\nformat %s 1.0\nelement vertex 1\nproperty char x\nproperty short y\n"
                 "property int z\nend_header\n",
                 enc_name[enc]);
        g_str(&g, h);
        g_val(&g, enc, "char", -100);
        g_val(&g, enc, "short", -30000);
        g_val(&g, enc, "int", -2000);
        g_eol(&g, enc);
        tessel_cloud c;
        CHECK(parse_cloud(&g, &c, NULL) == TESSEL_OK);
        CHECK(c.count == 1 && c.offset[0] + c.xyz[0] == -100 &&
              c.offset[1] + c.xyz[1] == -30000 && c.offset[2] + c.xyz[2] == -2000);
        /* A lone point is its own median: beyond 4096 the offset is its
         * floor (local coordinate in [0, 1)), within it 0. */
        CHECK(c.offset[0] == 0 && c.offset[1] == -30000 && c.offset[2] == 0);
        tessel_cloud_free(&c);
        free(g.d);
    }
}

/* ---- colours, normals, skipped properties and elements ---- */

static void test_attributes(void)
{
    static const struct {
        const char *names[3];
        const char *type;
        double in;
        uint8_t expect;
    } colors[] = {
        {{"red", "green", "blue"}, "uchar", 200, 200},
        {{"r", "g", "b"}, "uint8", 17, 17},
        {{"diffuse_red", "diffuse_green", "diffuse_blue"}, "uchar", 255, 255},
        {{"red", "green", "blue"}, "float", 0.5, 128},
        {{"red", "green", "blue"}, "double", 1.0, 255},
        {{"red", "green", "blue"}, "float", 2.0, 255},
        {{"red", "green", "blue"}, "ushort", 65535, 255},
        {{"red", "green", "blue"}, "ushort", 0x1234, 0x12},
    };
    for (int enc = 0; enc < 3; enc++) {
        for (size_t k = 0; k < sizeof colors / sizeof colors[0]; k++) {
            gbuf g = {0};
            char h[1024];
            /* an unknown element with a list before the vertices, unknown
             * scalar and list properties among them, and one after. */
            snprintf(h, sizeof h,
                     "ply\nformat %s 1.0\ncomment any text\nobj_info more text\n"
                     "element camera 2\nproperty list uchar float params\nproperty int id\n"
                     "element vertex 2\nproperty double x\nproperty float intensity\n"
                     "property float y\nproperty list int short junk\nproperty float z\n"
                     "property float nx\nproperty float ny\nproperty float nz\n"
                     "property %s %s\nproperty %s %s\nproperty %s %s\nproperty uchar alpha\n"
                     "element material 1\nproperty list ushort uchar name\n"
                     "end_header\n",
                     enc_name[enc], colors[k].type, colors[k].names[0], colors[k].type,
                     colors[k].names[1], colors[k].type, colors[k].names[2]);
            g_str(&g, h);
            for (int cam = 0; cam < 2; cam++) {
                g_val(&g, enc, "uchar", 3);
                for (int j = 0; j < 3; j++)
                    g_val(&g, enc, "float", j * 0.5);
                g_val(&g, enc, "int", cam);
                g_eol(&g, enc);
            }
            for (int i = 0; i < 2; i++) {
                g_val(&g, enc, "double", 1.25 + i);
                g_val(&g, enc, "float", 99);
                g_val(&g, enc, "float", -2.5);
                g_val(&g, enc, "int", i + 1); /* list of i+1 shorts */
                for (int j = 0; j <= i; j++)
                    g_val(&g, enc, "short", -7);
                g_val(&g, enc, "float", 3.75);
                g_val(&g, enc, "float", 0);
                g_val(&g, enc, "float", i ? -1 : 1);
                g_val(&g, enc, "float", 0);
                for (int j = 0; j < 3; j++)
                    g_val(&g, enc, colors[k].type, colors[k].in);
                g_val(&g, enc, "uchar", 255);
                g_eol(&g, enc);
            }
            g_val(&g, enc, "ushort", 2);
            g_val(&g, enc, "uchar", 65);
            g_val(&g, enc, "uchar", 66);
            g_eol(&g, enc);
            for (int as_mesh = 0; as_mesh < 2; as_mesh++) {
                tessel_cloud c;
                tessel_mesh m;
                tessel_diag d;
                tessel_status st = as_mesh ? parse_mesh(&g, &m, &d) : parse_cloud(&g, &c, &d);
                CHECK_MSG(st == TESSEL_OK, "%s colour %zu: %s", enc_name[enc], k, d.message);
                if (st != TESSEL_OK)
                    continue;
                const float *xyz = as_mesh ? m.xyz : c.xyz;
                const float *n = as_mesh ? m.normals : c.normals;
                const uint8_t *rgb = as_mesh ? m.rgb : c.rgb;
                size_t count = as_mesh ? m.vertex_count : c.count;
                CHECK(count == 2 && n && rgb);
                if (count == 2 && n && rgb) {
                    CHECK(xyz[0] == 1.25f && xyz[1] == -2.5f && xyz[2] == 3.75f);
                    CHECK(xyz[3] == 2.25f);
                    CHECK(n[0] == 0 && n[1] == 1 && n[2] == 0 && n[4] == -1);
                    CHECK_MSG(rgb[0] == colors[k].expect && rgb[5] == colors[k].expect,
                              "%s colour %zu: got %u want %u", enc_name[enc], k, rgb[0],
                              colors[k].expect);
                }
                if (as_mesh)
                    tessel_mesh_free(&m);
                else
                    tessel_cloud_free(&c);
            }
            free(g.d);
        }
    }
    /* Normals under their long names; only two colour channels: no colour. */
    gbuf g = {0};
    g_str(&g, "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
              "property float z\nproperty float normal_x\nproperty float normal_y\n"
              "property float normal_z\nproperty uchar red\nproperty uchar green\n"
              "end_header\n1 2 3 0 1 0 9 9\n");
    tessel_cloud c;
    CHECK(parse_cloud(&g, &c, NULL) == TESSEL_OK);
    CHECK(c.count == 1 && c.normals && c.normals[1] == 1.0f && !c.rgb);
    tessel_cloud_free(&c);
    free(g.d);
}

/* ---- faces ---- */

static void test_faces(void)
{
    static const char *const count_types[] = {"uchar", "int", "ushort", "char"};
    static const char *const index_types[] = {"int", "uint", "ushort", "uchar"};
    for (int enc = 0; enc < 3; enc++) {
        for (int t = 0; t < 4; t++) {
            gbuf g = {0};
            char h[512];
            snprintf(h, sizeof h,
                     "ply\nformat %s 1.0\nelement vertex 5\nproperty float x\nproperty float y\n"
                     "property float z\nelement face 3\nproperty uchar flags\n"
                     "property list %s %s %s\nproperty list uchar float texcoord\n"
                     "end_header\n",
                     enc_name[enc], count_types[t], index_types[t],
                     t == 1 ? "vertex_index" : "vertex_indices");
            g_str(&g, h);
            for (int i = 0; i < 5; i++) {
                g_val(&g, enc, "float", i);
                g_val(&g, enc, "float", i * i);
                g_val(&g, enc, "float", 0);
                g_eol(&g, enc);
            }
            /* a triangle, a quad, a pentagon -> 1 + 2 + 3 triangles */
            static const int faces[3][6] = {{3, 0, 1, 2}, {4, 0, 1, 2, 3}, {5, 4, 3, 2, 1, 0}};
            for (int f = 0; f < 3; f++) {
                g_val(&g, enc, "uchar", 1);
                g_val(&g, enc, count_types[t], faces[f][0]);
                for (int j = 1; j <= faces[f][0]; j++)
                    g_val(&g, enc, index_types[t], faces[f][j]);
                g_val(&g, enc, "uchar", 2);
                g_val(&g, enc, "float", 0.5);
                g_val(&g, enc, "float", 0.25);
                g_eol(&g, enc);
            }
            tessel_mesh m;
            tessel_diag d;
            tessel_status st = parse_mesh(&g, &m, &d);
            CHECK_MSG(st == TESSEL_OK, "%s faces %d: %s", enc_name[enc], t, d.message);
            static const uint32_t want[6][3] = {{0, 1, 2}, {0, 1, 2}, {0, 2, 3},
                                                {4, 3, 2}, {4, 2, 1}, {4, 1, 0}};
            bool ok = st == TESSEL_OK && m.vertex_count == 5 && m.triangle_count == 6;
            for (int i = 0; ok && i < 6; i++)
                for (int k = 0; k < 3; k++)
                    ok = ok && m.triangles[3 * i + k] == want[i][k];
            CHECK_MSG(ok, "%s faces %d: fans", enc_name[enc], t);
            tessel_mesh_free(&m);
            /* A cloud read skips the faces. */
            tessel_cloud c;
            CHECK(parse_cloud(&g, &c, NULL) == TESSEL_OK && c.count == 5);
            tessel_cloud_free(&c);
            free(g.d);
        }
    }
    /* A NaN vertex is dropped with the faces that use it; others renumbered. */
    gbuf g = {0};
    g_str(&g, "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
              "property float z\nelement face 2\nproperty list uchar int vertex_indices\n"
              "end_header\n0 0 0\nnan 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 2 3\n");
    tessel_mesh m;
    CHECK(parse_mesh(&g, &m, NULL) == TESSEL_OK);
    CHECK(m.vertex_count == 3 && m.triangle_count == 1);
    CHECK(m.triangle_count == 1 && m.triangles[0] == 0 && m.triangles[1] == 1 &&
          m.triangles[2] == 2);
    tessel_mesh_free(&m);
    tessel_cloud c;
    CHECK(parse_cloud(&g, &c, NULL) == TESSEL_OK && c.count == 3 && c.dropped_nonfinite == 1);
    tessel_cloud_free(&c);
    free(g.d);
}

/* ---- writer and exact round trips ---- */

static uint64_t rng_state = 0x9e3779b97f4a7c15ull;
static double rnd(void)
{
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 7;
    rng_state ^= rng_state << 17;
    return (double)(rng_state >> 11) / 9007199254740992.0;
}

static char tmpdir[256];

static void path_in(char *buf, size_t n, const char *name)
{
    snprintf(buf, n, "%s/%s", tmpdir, name);
}

static bool same_cloud(const tessel_cloud *a, const tessel_cloud *b)
{
    if (a->count != b->count || !!a->normals != !!b->normals || !!a->rgb != !!b->rgb)
        return false;
    if (memcmp(a->offset, b->offset, sizeof a->offset) != 0)
        return false;
    if (a->count && memcmp(a->xyz, b->xyz, a->count * 12) != 0)
        return false;
    if (a->normals && memcmp(a->normals, b->normals, a->count * 12) != 0)
        return false;
    if (a->rgb && memcmp(a->rgb, b->rgb, a->count * 3) != 0)
        return false;
    return true;
}

/* Reads a file back as a cloud. */
static tessel_status reread(const char *path, tessel_cloud *c)
{
    tessel_diag d;
    tessel_status st = tessel_cloud_read(c, path, NULL, &d);
    if (st != TESSEL_OK)
        fprintf(stderr, "reread %s: %s\n", path, d.message);
    return st;
}

/* Whether offset is what the reader's rule gives for n <= 8192 points: 0
 * when the floor of their lower median lies in [-4096, 4096], that floor
 * otherwise. Checked by counting, not sorting: at most (n-1)/2 floors lie
 * below the median's floor and more than (n-1)/2 at or below it. */
static bool offset_is_median_floor(const double *world, size_t n, int axis, double offset)
{
    double lo = offset != 0 ? offset : -4096, hi = offset != 0 ? offset : 4096;
    size_t below = 0, upto = 0;
    for (size_t i = 0; i < n; i++) {
        below += floor(world[3 * i + axis]) < lo;
        upto += floor(world[3 * i + axis]) <= hi;
    }
    return offset == floor(offset) && below <= (n - 1) / 2 && upto > (n - 1) / 2;
}

static void test_round_trips(void)
{
    char path[512];
    path_in(path, sizeof path, "rt.ply");
    static double world[3000 * 3];
    /* ordinary, UTM, UTM with stray points (a scanner's origin, -1e5) */
    for (int georef = 0; georef < 3; georef++) {
        /* Build the cloud the way a reader would: through the builder. */
        tsl_builder b;
        tsl_builder_init(&b, NULL);
        CHECK(tsl_builder_attributes(&b, 1, 1) == TESSEL_OK);
        for (int i = 0; i < 3000; i++) {
            double *p = world + 3 * i;
            p[0] = (rnd() - 0.5) * 50;
            p[1] = (rnd() - 0.5) * 50;
            p[2] = rnd() * 10;
            if (georef) {
                p[0] = 500000.0 + rnd() * 1000.0;
                p[1] = 5400000.0 + rnd() * 1000.0;
                p[2] = 200.0 + rnd() * 30.0;
            }
            if (i == 7)
                p[1] = georef ? 5400000.0 : -4096.0; /* integer edge cases */
            if (georef == 2 && i % 500 == 11)
                p[0] = p[1] = p[2] = i % 1000 == 11 ? 0.0 : -1e5;
            float n[3] = {(float)rnd(), (float)rnd(), (float)-rnd()};
            uint8_t rgb[3] = {(uint8_t)i, (uint8_t)(i * 7), (uint8_t)(255 - i)};
            CHECK(tsl_builder_point(&b, p, n, rgb) == TESSEL_OK);
        }
        tessel_cloud c0;
        CHECK(tsl_builder_finish_cloud(&b, &c0) == TESSEL_OK);
        /* Offsets from the bulk's median: the strays change nothing. */
        for (int k = 0; k < 3; k++)
            CHECK_MSG(offset_is_median_floor(world, 3000, k, c0.offset[k]) &&
                          (georef && k < 2 ? c0.offset[k] > 0 : c0.offset[k] == 0),
                      "georef %d axis %d: offset %.17g", georef, k, c0.offset[k]);
        if (georef == 2)
            CHECK(c0.offset[0] > 500000.0 && c0.offset[0] < 501000.0 &&
                  c0.offset[1] > 5400000.0 && c0.offset[1] < 5401000.0);
        for (int ascii = 0; ascii < 2; ascii++) {
            tessel_write_params wp = tessel_write_params_default();
            wp.ascii = ascii;
            tessel_diag d;
            CHECK(tessel_cloud_write(&c0, path, &wp, &d) == TESSEL_OK);
            tessel_cloud c1, c2;
            CHECK(reread(path, &c1) == TESSEL_OK);
            CHECK_MSG(same_cloud(&c0, &c1), "round trip georef=%d ascii=%d", georef, ascii);
            /* and once more: a fixed point */
            CHECK(tessel_cloud_write(&c1, path, &wp, &d) == TESSEL_OK);
            CHECK(reread(path, &c2) == TESSEL_OK);
            CHECK(same_cloud(&c1, &c2));
            tessel_cloud_free(&c1);
            tessel_cloud_free(&c2);
        }
        /* Without normals and colours when asked. */
        tessel_write_params wp = tessel_write_params_default();
        wp.write_normals = 0;
        wp.write_rgb = 0;
        CHECK(tessel_cloud_write(&c0, path, &wp, NULL) == TESSEL_OK);
        tessel_cloud c3;
        CHECK(reread(path, &c3) == TESSEL_OK);
        CHECK(c3.count == c0.count && !c3.normals && !c3.rgb &&
              memcmp(c3.xyz, c0.xyz, c0.count * 12) == 0);
        tessel_cloud_free(&c3);
        tessel_cloud_free(&c0);
    }
    /* Binary header: float without offset, double with. */
    tessel_cloud c;
    CHECK(tessel_cloud_alloc(&c, 2, 0, 0) == TESSEL_OK);
    c.xyz[3] = 1.5f;
    CHECK(tessel_cloud_write(&c, path, NULL, NULL) == TESSEL_OK);
    uint8_t *data;
    size_t size;
    CHECK(tsl_read_file(path, &data, &size, NULL) == TESSEL_OK);
    CHECK(strstr((char *)data, "format binary_little_endian 1.0\n") != NULL);
    CHECK(strstr((char *)data, "property float x\n") != NULL);
    const char *eh = strstr((char *)data, "end_header\n");
    CHECK(eh && size == (size_t)(eh + 11 - (char *)data) + 24);
    free(data);
    c.offset[2] = 1000000.0;
    CHECK(tessel_cloud_write(&c, path, NULL, NULL) == TESSEL_OK);
    CHECK(tsl_read_file(path, &data, &size, NULL) == TESSEL_OK);
    CHECK(strstr((char *)data, "property double x\n") != NULL);
    free(data);
    tessel_cloud_free(&c);
}

static void test_mesh_round_trip(void)
{
    char path[512];
    path_in(path, sizeof path, "mesh.ply");
    tessel_mesh m;
    CHECK(tessel_mesh_alloc(&m, 300, 400, 0, 1) == TESSEL_OK);
    for (size_t i = 0; i < 900; i++)
        m.xyz[i] = (float)(rnd() * 100);
    for (size_t i = 0; i < 900; i++)
        m.rgb[i] = (uint8_t)i;
    for (size_t i = 0; i < 1200; i++)
        m.triangles[i] = (uint32_t)(rnd() * 300);
    for (int ascii = 0; ascii < 2; ascii++) {
        tessel_write_params wp = tessel_write_params_default();
        wp.ascii = ascii;
        CHECK(tessel_mesh_write(&m, path, &wp, NULL) == TESSEL_OK);
        tessel_mesh r;
        tessel_diag d;
        CHECK(tessel_mesh_read(&r, path, NULL, &d) == TESSEL_OK);
        CHECK(r.vertex_count == 300 && r.triangle_count == 400 && !r.normals && r.rgb);
        CHECK(r.vertex_count == 300 && memcmp(r.xyz, m.xyz, 900 * 4) == 0 &&
              memcmp(r.rgb, m.rgb, 900) == 0);
        CHECK(r.triangle_count == 400 && memcmp(r.triangles, m.triangles, 1200 * 4) == 0);
        tessel_mesh_free(&r);
    }
    tessel_mesh_free(&m);
}

static void test_organized(void)
{
    char path[512];
    path_in(path, sizeof path, "org.ply");
    /* 4 x 3 grid, cells 1 and 6 missing. */
    tsl_builder b;
    tsl_builder_init(&b, NULL);
    CHECK(tsl_builder_attributes(&b, 0, 1) == TESSEL_OK);
    for (int cell = 0; cell < 12; cell++) {
        double p[3] = {cell % 4, cell / 4, (cell == 1 || cell == 6) ? NAN : 1.0 + cell};
        uint8_t rgb[3] = {(uint8_t)cell, 0, 0};
        CHECK(tsl_builder_point(&b, p, NULL, rgb) == TESSEL_OK);
    }
    b.width = 4;
    b.height = 3;
    b.viewpoint[0] = 0.25;
    b.viewpoint[1] = -1e6 / 3.0;
    b.viewpoint[2] = 12.5;
    b.has_viewpoint = 1;
    tessel_cloud c0;
    CHECK(tsl_builder_finish_cloud(&b, &c0) == TESSEL_OK);
    CHECK(c0.count == 10 && c0.dropped_nonfinite == 2 && c0.grid && c0.width == 4);
    for (int ascii = 0; ascii < 2; ascii++) {
        tessel_write_params wp = tessel_write_params_default();
        wp.ascii = ascii;
        CHECK(tessel_cloud_write(&c0, path, &wp, NULL) == TESSEL_OK);
        uint8_t *data;
        size_t size;
        CHECK(tsl_read_file(path, &data, &size, NULL) == TESSEL_OK);
        CHECK(strstr((char *)data, "comment organized 4 3\n") != NULL);
        CHECK(strstr((char *)data, "comment viewpoint ") != NULL);
        CHECK(strstr((char *)data, "element vertex 12\n") != NULL);
        free(data);
        tessel_cloud c1;
        CHECK(reread(path, &c1) == TESSEL_OK);
        CHECK(same_cloud(&c0, &c1));
        CHECK(c1.width == 4 && c1.height == 3 && c1.grid &&
              memcmp(c1.grid, c0.grid, 12 * sizeof(uint32_t)) == 0);
        CHECK(c1.grid && c1.grid[1] == TESSEL_NONE && c1.grid[6] == TESSEL_NONE &&
              c1.grid[7] == 5);
        CHECK(c1.has_viewpoint && c1.viewpoint[0] == 0.25 && c1.viewpoint[1] == -1e6 / 3.0 &&
              c1.viewpoint[2] == 12.5);
        CHECK(c1.dropped_nonfinite == 2);
        tessel_cloud_free(&c1);
    }
    tessel_cloud_free(&c0);
}

/* ---- every prefix of valid files ---- */

static void prefixes(const uint8_t *data, size_t size, const char *what)
{
    size_t ok = 0;
    tessel_read_params rp = tessel_read_params_default();
    rp.format = TESSEL_FORMAT_PLY;
    uint8_t *buf = malloc(size ? size : 1);
    for (size_t n = 0; n <= size; n++) {
        /* an exact-size copy: ASan catches any read past the prefix */
        memcpy(buf, data, n);
        uint8_t *copy = malloc(n ? n : 1);
        memcpy(copy, buf, n);
        tessel_cloud c;
        tessel_mesh m;
        tessel_diag d;
        tessel_status sc = tessel_cloud_parse(&c, copy, n, what, &rp, &d);
        if (sc == TESSEL_OK) {
            ok++;
            tessel_cloud_free(&c);
        } else if (!d.message[0]) {
            CHECK_MSG(0, "%s prefix %zu: error without message", what, n);
        }
        tessel_status sm = tessel_mesh_parse(&m, copy, n, what, &rp, &d);
        if (sm == TESSEL_OK) {
            for (size_t i = 0; i < 3 * m.triangle_count; i++)
                if (m.triangles[i] >= m.vertex_count) {
                    CHECK_MSG(0, "%s prefix %zu: bad index", what, n);
                    break;
                }
            tessel_mesh_free(&m);
        }
        free(copy);
    }
    free(buf);
    /* The full file parses. */
    CHECK_MSG(ok >= 1, "%s: full file did not parse", what);
}

static void test_prefixes(void)
{
    for (int enc = 0; enc < 3; enc++) {
        gbuf g = {0};
        char h[512];
        snprintf(h, sizeof h,
                 "ply\r\nformat %s 1.0\r\ncomment organized 2 2\r\nelement vertex 4\r\n"
                 "property float x\r\nproperty double y\r\nproperty short z\r\n"
                 "property list uchar int extra\r\nproperty uchar red\r\nproperty uchar green\r\n"
                 "property uchar blue\r\nelement face 2\r\nproperty list uchar uint "
                 "vertex_indices\r\nend_header\r\n",
                 enc_name[enc]);
        g_str(&g, h);
        for (int i = 0; i < 4; i++) {
            g_val(&g, enc, "float", i * 0.5);
            g_val(&g, enc, "double", -i);
            g_val(&g, enc, "short", 3 * i);
            g_val(&g, enc, "uchar", 2);
            g_val(&g, enc, "int", 7);
            g_val(&g, enc, "int", 8);
            for (int k = 0; k < 3; k++)
                g_val(&g, enc, "uchar", 40 * i + k);
            g_eol(&g, enc);
        }
        g_val(&g, enc, "uchar", 3);
        for (int k = 0; k < 3; k++)
            g_val(&g, enc, "uint", k);
        g_eol(&g, enc);
        g_val(&g, enc, "uchar", 4);
        for (int k = 0; k < 4; k++)
            g_val(&g, enc, "uint", 3 - k);
        g_eol(&g, enc);
        tessel_mesh m;
        tessel_diag d;
        CHECK_MSG(parse_mesh(&g, &m, &d) == TESSEL_OK, "%s: %s", enc_name[enc], d.message);
        CHECK(m.vertex_count == 4 && m.triangle_count == 3 && m.rgb && m.rgb[9] == 120);
        tessel_mesh_free(&m);
        prefixes(g.d, g.n, enc_name[enc]);
        free(g.d);
    }
    /* A file from the writer. */
    char path[512];
    path_in(path, sizeof path, "prefix.ply");
    tessel_mesh m;
    CHECK(tessel_mesh_alloc(&m, 20, 10, 1, 1) == TESSEL_OK);
    for (size_t i = 0; i < 60; i++)
        m.xyz[i] = (float)i;
    for (size_t i = 0; i < 30; i++)
        m.triangles[i] = (uint32_t)(i % 20);
    m.offset[0] = 700000;
    for (int ascii = 0; ascii < 2; ascii++) {
        tessel_write_params wp = tessel_write_params_default();
        wp.ascii = ascii;
        CHECK(tessel_mesh_write(&m, path, &wp, NULL) == TESSEL_OK);
        uint8_t *data;
        size_t size;
        CHECK(tsl_read_file(path, &data, &size, NULL) == TESSEL_OK);
        prefixes(data, size, ascii ? "written ascii" : "written binary");
        free(data);
    }
    tessel_mesh_free(&m);
}

/* ---- bad files ---- */

static void test_bad_files(void)
{
    static const struct {
        const char *file;
        int mesh;              /* read as a mesh */
        tessel_status status;
        const char *message;   /* expected substring */
        uint64_t line;         /* expected line, 0 = none */
        int64_t offset;        /* expected byte offset, -1 = none */
    } cases[] = {
        {"ply_lying_count.ply", 0, TESSEL_ERR_PARSE,
         "file ends in element 'vertex', record 3 of 5", 11, -1},
        {"ply_truncated_binary.ply", 0, TESSEL_ERR_PARSE,
         "header announces 4 vertices needing 48 bytes but only 30 bytes follow", 0, 115},
        {"ply_truncated_faces.ply", 1, TESSEL_ERR_PARSE,
         "data truncated in element 'face', record 1 of 2", 0, 219},
        /* A list element used more than its least size, so the fixed
         * records after it no longer fit (found by fuzz_ply). */
        {"ply_list_then_fixed.ply", 0, TESSEL_ERR_PARSE,
         "data truncated in element 'vertex', record 2 of 3", 0, 223},
        {"ply_bad_number.ply", 0, TESSEL_ERR_PARSE, "bad number 'abc' in element 'vertex'", 9,
         -1},
        {"ply_index_out_of_range.ply", 1, TESSEL_ERR_PARSE,
         "face 1: vertex index 7 out of range (3 vertices)", 14, -1},
        {"ply_negative_index.ply", 1, TESSEL_ERR_PARSE,
         "face 0: vertex index -1 out of range", 13, -1},
        {"ply_negative_list_count.ply", 1, TESSEL_ERR_PARSE, "face 0: negative list count -3",
         0, 204},
        {"ply_absurd_count.ply", 0, TESSEL_ERR_LIMIT,
         "header announces 1000000000000000 vertices, more than the limit", 3, -1},
        {"ply_absurd_element.ply", 0, TESSEL_ERR_PARSE,
         "header announces 1000000000000000 'edge' records", 0, 184},
        {"ply_no_end_header.ply", 0, TESSEL_ERR_PARSE, "header has no end_header line", 7, -1},
        {"ply_unknown_format.ply", 0, TESSEL_ERR_UNSUPPORTED,
         "unknown PLY format 'binary_middle_endian'", 2, -1},
        {"ply_unknown_type.ply", 0, TESSEL_ERR_PARSE, "unknown property type 'float128'", 4, -1},
        {"ply_no_x.ply", 0, TESSEL_ERR_PARSE, "vertex element has no 'x' property", 3, -1},
        {"ply_organized_mismatch.ply", 0, TESSEL_ERR_PARSE,
         "comment organized 2 3 does not match the 4 vertices", 3, -1},
        {"ply_not_ply.ply", 0, TESSEL_ERR_PARSE, "not a PLY file", 1, -1},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char path[512];
        snprintf(path, sizeof path, "%s/bad/%s", TESSEL_TEST_DATA, cases[i].file);
        tessel_diag d;
        tessel_cloud c;
        tessel_mesh m;
        tessel_status st = cases[i].mesh ? tessel_mesh_read(&m, path, NULL, &d)
                                         : tessel_cloud_read(&c, path, NULL, &d);
        CHECK_MSG(st == cases[i].status, "%s: status %s (%s)", cases[i].file,
                  tessel_status_str(st), d.message);
        CHECK_MSG(strstr(d.message, cases[i].message) != NULL, "%s: message '%s'",
                  cases[i].file, d.message);
        CHECK_MSG(strcmp(d.file, path) == 0, "%s: file '%s'", cases[i].file, d.file);
        CHECK_MSG(d.line == cases[i].line, "%s: line %llu", cases[i].file,
                  (unsigned long long)d.line);
        if (cases[i].offset >= 0)
            CHECK_MSG(d.has_offset && d.offset == (uint64_t)cases[i].offset,
                      "%s: offset %d/%llu", cases[i].file, d.has_offset,
                      (unsigned long long)d.offset);
        else
            CHECK_MSG(!d.has_offset, "%s: unexpected offset", cases[i].file);
        if (st == TESSEL_OK) {
            if (cases[i].mesh)
                tessel_mesh_free(&m);
            else
                tessel_cloud_free(&c);
        }
    }
    /* Face errors do not matter to a cloud read, which skips faces. */
    char path[512];
    snprintf(path, sizeof path, "%s/bad/ply_index_out_of_range.ply", TESSEL_TEST_DATA);
    tessel_cloud c;
    CHECK(tessel_cloud_read(&c, path, NULL, NULL) == TESSEL_OK && c.count == 3);
    tessel_cloud_free(&c);
}

static void test_limits(void)
{
    gbuf g = {0};
    g_str(&g, "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
              "property float z\nelement face 2\nproperty list uchar int vertex_indices\n"
              "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n4 0 1 2 0\n");
    tessel_read_params rp = tessel_read_params_default();
    rp.max_points = 2;
    tessel_diag d;
    tessel_cloud c;
    CHECK(tessel_cloud_parse(&c, g.d, g.n, NULL, &rp, &d) == TESSEL_ERR_LIMIT);
    CHECK(strstr(d.message, "more than the limit of 2") != NULL);
    rp = tessel_read_params_default();
    rp.max_faces = 2; /* 2 faces announced, 3 triangles after the fan */
    tessel_mesh m;
    CHECK(tessel_mesh_parse(&m, g.d, g.n, NULL, &rp, &d) == TESSEL_ERR_LIMIT);
    rp.max_faces = 3;
    CHECK(tessel_mesh_parse(&m, g.d, g.n, NULL, &rp, &d) == TESSEL_OK && m.triangle_count == 3);
    tessel_mesh_free(&m);
    /* A list count larger than the bytes left. */
    gbuf h = {0};
    g_str(&h, "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\n"
              "property float y\nproperty float z\nproperty list uint int junk\nend_header\n");
    g_val(&h, ENC_LE, "float", 1);
    g_val(&h, ENC_LE, "float", 2);
    g_val(&h, ENC_LE, "float", 3);
    g_val(&h, ENC_LE, "uint", 4000000000.0);
    g_val(&h, ENC_LE, "int", 1);
    CHECK(tessel_cloud_parse(&c, h.d, h.n, "x.ply", NULL, &d) == TESSEL_ERR_PARSE);
    CHECK(strstr(d.message, "list of 4000000000 items but only 4 bytes left") != NULL);
    free(h.d);
    free(g.d);
}

int main(void)
{
    snprintf(tmpdir, sizeof tmpdir, "/tmp/tessel_test_ply_XXXXXX");
    if (!mkdtemp(tmpdir)) {
        perror("mkdtemp");
        return 1;
    }
    test_scalar_types();
    test_attributes();
    test_faces();
    test_round_trips();
    test_mesh_round_trip();
    test_organized();
    test_prefixes();
    test_bad_files();
    test_limits();
    const char *names[] = {"rt.ply", "mesh.ply", "org.ply", "prefix.ply"};
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++) {
        char p[512];
        path_in(p, sizeof p, names[i]);
        unlink(p);
    }
    rmdir(tmpdir);
    return TEST_SUMMARY();
}
