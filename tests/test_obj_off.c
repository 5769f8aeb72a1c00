/* OBJ and OFF readers and writers, and the binary STL writer: face forms,
 * relative indices, polygons as fans, normals and colours, format
 * variants, errors with their line, exact round trips, every prefix of a
 * valid file, CRLF line ends in every text format, and the STL byte layout
 * checked field by field. */
#include "format_helpers.h"

#include <math.h>
#include <unistd.h>

static tessel_status parse_mesh(tsl_parse_fn fn, const char *text, tessel_mesh *m,
                                tessel_diag *d)
{
    return fmt_parse_mesh(fn, text, strlen(text), m, d);
}

static int tri_is(const tessel_mesh *m, size_t t, uint32_t a, uint32_t b, uint32_t c)
{
    return t < m->triangle_count && m->triangles[3 * t] == a &&
           m->triangles[3 * t + 1] == b && m->triangles[3 * t + 2] == c;
}

static void test_obj_read(void)
{
    tessel_mesh m;
    tessel_diag d;
    const char *quad = "# a quad and a triangle\n"
                       "mtllib x.mtl\no thing\ng part\nusemtl red\ns off\n"
                       "v 0 0 0\nv 1 0 0\r\nv 1 1 0 1.0\nv 0 1 0\n"
                       "vt 0 0\nvt 1 0\n"
                       "vn 0 0 1\n"
                       "f 1/1/1 2/2/1 3/1/1 4/2/1 # trailing comment\n"
                       "f -4//-1 -2//-1 -1//-1\n"
                       "f 1/1 2/2 3/1\n"
                       "l 1 2\n";
    CHECK_MSG(parse_mesh(tsl_parse_obj, quad, &m, &d) == TESSEL_OK, "%s", d.message);
    CHECK(m.vertex_count == 4 && m.triangle_count == 4 && !m.rgb);
    CHECK(tri_is(&m, 0, 0, 1, 2) && tri_is(&m, 1, 0, 2, 3) && tri_is(&m, 2, 0, 2, 3) &&
          tri_is(&m, 3, 0, 1, 2));
    /* One vn for four v: attached through the face references. */
    CHECK(m.normals != NULL);
    if (m.normals)
        for (int i = 0; i < 4; i++)
            CHECK(m.normals[3 * i + 2] == 1);
    CHECK(m.xyz[6] == 1 && m.xyz[7] == 1);
    tessel_mesh_free(&m);

    /* As many vn as v: attached in order, even when they come later. */
    const char *ordered = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 1 0 0\nvn 0 1 0\nvn 0 0 1\nf 1 2 3\n";
    CHECK(parse_mesh(tsl_parse_obj, ordered, &m, &d) == TESSEL_OK);
    CHECK(m.normals && m.normals[0] == 1 && m.normals[4] == 1 && m.normals[8] == 1);
    tessel_mesh_free(&m);

    /* Colours: fractions, and 0-255 when a component exceeds 1. */
    const char *colours = "v 0 0 0 1 0.5 0\nv 1 0 0 0 128 255\nv 0 1 0 0 0 0\nf 1 2 3\n";
    CHECK(parse_mesh(tsl_parse_obj, colours, &m, &d) == TESSEL_OK);
    CHECK(m.rgb && m.rgb[0] == 255 && m.rgb[1] == 128 && m.rgb[2] == 0);
    CHECK(m.rgb && m.rgb[3] == 0 && m.rgb[4] == 128 && m.rgb[5] == 255);
    tessel_mesh_free(&m);

    /* A pentagon becomes a fan of three triangles; cloud reads skip faces. */
    const char *penta = "v 0 0 0\nv 1 0 0\nv 2 1 0\nv 1 2 0\nv 0 1 0\nf 1 2 3 4 5\n";
    CHECK(parse_mesh(tsl_parse_obj, penta, &m, &d) == TESSEL_OK);
    CHECK(m.triangle_count == 3 && tri_is(&m, 2, 0, 3, 4));
    tessel_mesh_free(&m);
    tessel_cloud c;
    CHECK(fmt_parse_text(tsl_parse_obj, penta, &c, &d) == TESSEL_OK && c.count == 5);
    tessel_cloud_free(&c);

    /* Errors. */
    struct {
        const char *text, *message;
        uint64_t line;
    } bad[] = {
        {"v 0 0\n", "expected 3, 4 (x y z w) or 6 (x y z r g b) numbers after 'v', got 2", 1},
        {"v 0 0 0\nv 0 0 zero\n", "bad number 'zero'", 2},
        {"v 0 0 0\nvn 0 1\n", "expected 3 numbers after 'vn', got 2", 2},
        {"v 0 0 0\nf 1 1 0\n", "face index 0 out of range", 2},
        {"v 0 0 0\nf 1 1 a\n", "bad face vertex 'a'", 2},
        {"v 0 0 0\nf 1 1 1/\n", "bad face vertex '1/'", 2},
        {"v 0 0 0\nvn 0 0 1\nf 1//2 1//1 1//1\n", "face normal index 2 out of range (1 normals)",
         3},
        {"v 0 0 0\nvn 0 0 1\nf 1//-2 1 1\n", "face normal index -2 out of range (1 normals so far)",
         3},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        tessel_status st = parse_mesh(tsl_parse_obj, bad[i].text, &m, &d);
        CHECK_MSG(st == TESSEL_ERR_PARSE && strstr(d.message, bad[i].message) &&
                      d.line == bad[i].line,
                  "case %zu: %s line %llu '%s'", i, tessel_status_str(st),
                  (unsigned long long)d.line, d.message);
        CHECK(m.vertex_count == 0 && m.xyz == NULL);
    }
    fmt_check_bad(tsl_parse_obj, "obj_index_range.obj", 1, TESSEL_ERR_PARSE,
                  "face index 4 out of range (3 vertices)", 6, UINT64_MAX);
    fmt_check_bad(tsl_parse_obj, "obj_relative_index.obj", 1, TESSEL_ERR_PARSE,
                  "face index -4 out of range (3 vertices so far)", 5, UINT64_MAX);
    CHECK(fmt_every_prefix(tsl_parse_obj, quad, strlen(quad)) == 0);
}

static void test_off_read(void)
{
    tessel_mesh m;
    tessel_diag d;
    const char *off = "OFF 5 2 0 # counts on the keyword line\n"
                      "# a comment line\n\n"
                      "0 0 0\n1 0 0\n1 1 0\n0 1 0\n  2 2 2  \n"
                      "4 0 1 2 3 255 0 0\n"
                      "3 4 3 2 0.5 0.5 0.5 1\n";
    CHECK_MSG(parse_mesh(tsl_parse_off, off, &m, &d) == TESSEL_OK, "%s", d.message);
    CHECK(m.vertex_count == 5 && m.triangle_count == 3 && !m.normals && !m.rgb);
    CHECK(tri_is(&m, 0, 0, 1, 2) && tri_is(&m, 1, 0, 2, 3) && tri_is(&m, 2, 4, 3, 2));
    CHECK(m.xyz[12] == 2);
    tessel_mesh_free(&m);
    CHECK(fmt_every_prefix(tsl_parse_off, off, strlen(off)) == 0);

    const char *coff = "COFF\n3 1 3\n0 0 0 255 0 0 255\n1 0 0 0.0 1.0 0.5 1.0\n"
                       "0 1 0 0 0 7\n3 0 1 2\n";
    CHECK_MSG(parse_mesh(tsl_parse_off, coff, &m, &d) == TESSEL_OK, "%s", d.message);
    CHECK(m.rgb && m.rgb[0] == 255 && m.rgb[3] == 0 && m.rgb[4] == 255 && m.rgb[5] == 128 &&
          m.rgb[8] == 7);
    tessel_mesh_free(&m);

    const char *ncoff = "NCOFF\n3 1 0\n0 0 0 0 0 1 10 20 30\n1 0 0 0 0 1 10 20 30\n"
                        "0 1 0 0 0 1 10 20 30\n3 0 1 2\n";
    CHECK_MSG(parse_mesh(tsl_parse_off, ncoff, &m, &d) == TESSEL_OK, "%s", d.message);
    CHECK(m.normals && m.rgb && m.normals[8] == 1 && m.rgb[7] == 20);
    tessel_mesh_free(&m);

    struct {
        const char *text, *message;
        tessel_status st;
        uint64_t line;
    } bad[] = {
        {"", "empty OFF file", TESSEL_ERR_PARSE, 0},
        {"ply\n", "not an OFF file", TESSEL_ERR_PARSE, 1},
        {"4OFF\n1 0 0\n0 0 0 0\n", "OFF variant '4OFF' is not supported",
         TESSEL_ERR_UNSUPPORTED, 1},
        {"OFF\n3 x 0\n", "expected the counts", TESSEL_ERR_PARSE, 2},
        {"OFF\n1 0 0\n0 0\n", "expected 3 numbers for an OFF vertex, got 2", TESSEL_ERR_PARSE,
         3},
        {"COFF\n1 0 0\n0 0 0\n", "expected 3 + 3 or 4 colour numbers", TESSEL_ERR_PARSE, 3},
        {"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1\n", "face announces 3 vertices, the line has 2",
         TESSEL_ERR_PARSE, 6},
        {"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 -2\n", "bad vertex index", TESSEL_ERR_PARSE,
         6},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        tessel_status st = parse_mesh(tsl_parse_off, bad[i].text, &m, &d);
        CHECK_MSG(st == bad[i].st && strstr(d.message, bad[i].message) &&
                      d.line == bad[i].line,
                  "case %zu: %s line %llu '%s'", i, tessel_status_str(st),
                  (unsigned long long)d.line, d.message);
    }
    fmt_check_bad(tsl_parse_off, "off_truncated.off", 1, TESSEL_ERR_PARSE,
                  "OFF announces 2 faces (line 3), the file ends after 1", 8, UINT64_MAX);
    fmt_check_bad(tsl_parse_off, "off_lying_count.off", 0, TESSEL_ERR_PARSE,
                  "OFF announces 8 vertices (line 2), the file ends after 4", 6, UINT64_MAX);
    fmt_check_bad(tsl_parse_off, "off_index_range.off", 1, TESSEL_ERR_PARSE,
                  "face index 3 out of range (3 vertices)", 6, UINT64_MAX);

    /* Face limit. */
    tsl_builder b;
    tessel_read_params rp = tessel_read_params_default();
    rp.max_faces = 1;
    tsl_builder_init(&b, &rp);
    CHECK(tsl_parse_off((const uint8_t *)off, strlen(off), "m", 1, &b, &d) ==
          TESSEL_ERR_LIMIT);
    tsl_builder_free(&b);
}

/* A random mesh built through the builder (so its offset and floats are
 * what a reader would produce): a strip of triangles over a grid. */
static tessel_mesh random_mesh(double offset, int normals, int rgb, size_t side)
{
    tsl_builder b;
    tsl_builder_init(&b, NULL);
    tsl_builder_attributes(&b, normals, rgb);
    for (size_t j = 0; j < side; j++)
        for (size_t i = 0; i < side; i++) {
            double p[3] = {offset + (double)i + fmt_rand() * 0.3,
                           2 * offset + (double)j + fmt_rand() * 0.3, fmt_rand() * 10};
            float n[3] = {(float)(fmt_rand() - 0.5), (float)(fmt_rand() - 0.5), 1.0f};
            uint8_t c[3] = {(uint8_t)(fmt_rand() * 256), (uint8_t)(fmt_rand() * 256),
                            (uint8_t)(fmt_rand() * 256)};
            tsl_builder_point(&b, p, n, c);
        }
    for (size_t j = 0; j + 1 < side; j++)
        for (size_t i = 0; i + 1 < side; i++) {
            uint32_t a = (uint32_t)(j * side + i);
            uint32_t q[4] = {a, a + 1, a + 1 + (uint32_t)side, a + (uint32_t)side};
            tsl_builder_polygon(&b, q, 4);
        }
    tessel_mesh m;
    tsl_builder_finish_mesh(&b, &m);
    tsl_builder_free(&b);
    return m;
}

static void round_trip(const tsl_format_writer *w, tsl_parse_fn fn, double offset,
                       int normals, int rgb, const char *what)
{
    tessel_mesh src = random_mesh(offset, normals, rgb, 12);
    tsl_vertices v = {src.vertex_count, src.xyz, src.normals, src.rgb,
                      {src.offset[0], src.offset[1], src.offset[2]}};
    tessel_write_params wp = tessel_write_params_default();
    size_t size;
    char *text = fmt_write(w, &v, src.triangles, src.triangle_count, &wp, &size);
    CHECK(text != NULL);
    tessel_mesh back;
    tessel_diag d;
    CHECK_MSG(fmt_parse_mesh(fn, text, size, &back, &d) == TESSEL_OK, "%s: %s", what,
              d.message);
    CHECK_MSG(back.vertex_count == src.vertex_count &&
                  back.triangle_count == src.triangle_count,
              "%s: counts", what);
    if (back.vertex_count == src.vertex_count && back.triangle_count == src.triangle_count) {
        CHECK_MSG(memcmp(back.offset, src.offset, sizeof src.offset) == 0, "%s: offset",
                  what);
        CHECK_MSG(fmt_same_floats(back.xyz, src.xyz, 3 * src.vertex_count), "%s: xyz", what);
        CHECK_MSG(memcmp(back.triangles, src.triangles,
                         3 * src.triangle_count * sizeof(uint32_t)) == 0,
                  "%s: triangles", what);
        CHECK_MSG((back.normals != NULL) == (normals != 0), "%s: normals presence", what);
        if (normals && back.normals)
            CHECK_MSG(fmt_same_floats(back.normals, src.normals, 3 * src.vertex_count),
                      "%s: normals", what);
        CHECK_MSG((back.rgb != NULL) == (rgb != 0), "%s: rgb presence", what);
        if (rgb && back.rgb)
            CHECK_MSG(memcmp(back.rgb, src.rgb, 3 * src.vertex_count) == 0, "%s: rgb", what);
    }
    /* every prefix of the first 60 lines */
    size_t cut = 0;
    for (int lines = 0; cut < size && lines < 60; cut++)
        lines += text[cut] == '\n';
    CHECK_MSG(fmt_every_prefix(fn, text, cut) == 0, "%s: prefixes", what);
    free(text);
    tessel_mesh_free(&back);
    tessel_mesh_free(&src);
}

static void test_round_trips(void)
{
    for (int k = 0; k < 4; k++) {
        int normals = k & 1, rgb = k >> 1;
        round_trip(&tsl_writer_obj, tsl_parse_obj, 0, normals, rgb, "obj");
        round_trip(&tsl_writer_obj, tsl_parse_obj, 512000.0, normals, rgb, "obj utm");
        round_trip(&tsl_writer_off, tsl_parse_off, 0, normals, rgb, "off");
        round_trip(&tsl_writer_off, tsl_parse_off, 512000.0, normals, rgb, "off utm");
    }
}

static float get_f32(const uint8_t *p)
{
    uint32_t u = (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) |
                 ((uint32_t)p[3] << 24);
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

static void test_stl(void)
{
    tessel_mesh m = random_mesh(300000.0, 0, 0, 6);
    /* Make one triangle degenerate: its normal must be zero. */
    m.triangles[3 * 4 + 2] = m.triangles[3 * 4 + 1];
    tsl_vertices v = {m.vertex_count, m.xyz, NULL, NULL, {m.offset[0], m.offset[1], m.offset[2]}};
    size_t size;
    char *bytes = fmt_write(&tsl_writer_stl, &v, m.triangles, m.triangle_count, NULL, &size);
    CHECK(bytes != NULL);
    CHECK(size == 84 + 50 * m.triangle_count);
    if (!bytes || size != 84 + 50 * m.triangle_count) {
        free(bytes);
        tessel_mesh_free(&m);
        return;
    }
    const uint8_t *b = (const uint8_t *)bytes;
    CHECK(memcmp(b, "solid", 5) != 0);
    uint32_t n = (uint32_t)b[80] | ((uint32_t)b[81] << 8) | ((uint32_t)b[82] << 16) |
                 ((uint32_t)b[83] << 24);
    CHECK(n == m.triangle_count);
    size_t bad_xyz = 0, bad_normal = 0;
    for (size_t t = 0; t < m.triangle_count; t++) {
        const uint8_t *r = b + 84 + 50 * t;
        double p[3][3];
        for (int c = 0; c < 3; c++)
            for (int k = 0; k < 3; k++) {
                double local = m.xyz[3 * m.triangles[3 * t + c] + k];
                p[c][k] = local;
                if (get_f32(r + 12 + 12 * c + 4 * k) != (float)(m.offset[k] + local))
                    bad_xyz++;
            }
        double e1[3], e2[3], nrm[3];
        for (int k = 0; k < 3; k++) {
            e1[k] = p[1][k] - p[0][k];
            e2[k] = p[2][k] - p[0][k];
        }
        nrm[0] = e1[1] * e2[2] - e1[2] * e2[1];
        nrm[1] = e1[2] * e2[0] - e1[0] * e2[2];
        nrm[2] = e1[0] * e2[1] - e1[1] * e2[0];
        double len = sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]);
        for (int k = 0; k < 3; k++) {
            double want = len > 0 ? nrm[k] / len : 0.0;
            if (fabs(get_f32(r + 4 * k) - want) > 1e-6)
                bad_normal++;
        }
        if (r[48] != 0 || r[49] != 0)
            bad_xyz++;
    }
    CHECK_MSG(bad_xyz == 0, "%zu STL coordinates differ", bad_xyz);
    CHECK_MSG(bad_normal == 0, "%zu STL normal components differ", bad_normal);
    CHECK(get_f32(b + 84 + 50 * 4) == 0 && get_f32(b + 84 + 50 * 4 + 8) == 0);
    /* Grid triangles are counter-clockwise seen from +z: normals point up. */
    CHECK(get_f32(b + 84 + 8) > 0);
    free(bytes);
    tessel_mesh_free(&m);
}


static bool same_world_triangles(const tessel_mesh *a, const tessel_mesh *b)
{
    if (a->triangle_count != b->triangle_count)
        return false;
    for (size_t i = 0; i < 3 * a->triangle_count; i++)
        for (int k = 0; k < 3; k++)
            if (a->offset[k] + a->xyz[3 * a->triangles[i] + k] !=
                b->offset[k] + b->xyz[3 * b->triangles[i] + k])
                return false;
    return true;
}

/* Through the public API: files written and read back for OBJ and OFF,
 * STL refused on read, and the streaming writer (with compaction) for all
 * three formats. */
static void test_public_api(void)
{
    char dir[] = "/tmp/tessel_fmt_XXXXXX";
    CHECK(mkdtemp(dir) != NULL);
    tessel_mesh src = random_mesh(4.3e6, 1, 1, 9);
    static const char *const exts[] = {"obj", "off", "stl"};
    for (int e = 0; e < 3; e++) {
        char path[256];
        snprintf(path, sizeof path, "%s/mesh.%s", dir, exts[e]);
        tessel_diag d;
        CHECK_MSG(tessel_mesh_write(&src, path, NULL, &d) == TESSEL_OK, "%s", d.message);
        tessel_mesh back;
        tessel_status st = tessel_mesh_read(&back, path, NULL, &d);
        if (e == 2) {
            CHECK(st == TESSEL_ERR_UNSUPPORTED);
            FILE *fp = fopen(path, "rb");
            long size = -1;
            if (fp) {
                fseek(fp, 0, SEEK_END);
                size = ftell(fp);
                fclose(fp);
            }
            CHECK(size == (long)(84 + 50 * src.triangle_count));
        } else {
            CHECK_MSG(st == TESSEL_OK, "%s: %s", path, d.message);
            CHECK(back.vertex_count == src.vertex_count &&
                  fmt_same_floats(back.xyz, src.xyz, 3 * src.vertex_count) &&
                  memcmp(back.offset, src.offset, sizeof src.offset) == 0);
            CHECK(back.normals && back.rgb && same_world_triangles(&src, &back));
            /* A cloud read of a mesh file gets the vertices. */
            tessel_cloud c;
            CHECK(tessel_cloud_read(&c, path, NULL, &d) == TESSEL_OK &&
                  c.count == src.vertex_count);
            tessel_cloud_free(&c);
        }
        tessel_mesh_free(&back);
        unlink(path);

        /* Streaming: only the odd triangles, so some vertices are unused
         * and compaction renumbers the rest. */
        tessel_cloud cloud = {0};
        cloud.count = src.vertex_count;
        cloud.xyz = src.xyz;
        cloud.normals = src.normals;
        cloud.rgb = src.rgb;
        memcpy(cloud.offset, src.offset, sizeof cloud.offset);
        tessel_mesh_writer *w;
        CHECK_MSG(tessel_mesh_writer_open(&w, path, &cloud, NULL, 1, &d) == TESSEL_OK, "%s",
                  d.message);
        size_t kept = 0;
        tessel_mesh odd = src;
        odd.triangles = malloc(src.triangle_count * 3 * sizeof(uint32_t));
        for (size_t t = 1; t < src.triangle_count; t += 2) {
            CHECK(tessel_mesh_writer_add(w, src.triangles + 3 * t, 1) == TESSEL_OK);
            memcpy(odd.triangles + 3 * kept++, src.triangles + 3 * t, 3 * sizeof(uint32_t));
        }
        odd.triangle_count = kept;
        CHECK_MSG(tessel_mesh_writer_close(w, &d) == TESSEL_OK, "%s", d.message);
        if (e < 2) {
            CHECK(tessel_mesh_read(&back, path, NULL, &d) == TESSEL_OK);
            CHECK(back.vertex_count < src.vertex_count && back.triangle_count == kept);
            CHECK(same_world_triangles(&odd, &back));
            tessel_mesh_free(&back);
        }
        free(odd.triangles);
        unlink(path);
    }
    tessel_mesh_free(&src);
    rmdir(dir);
}

/* CRLF line ends and a CR between tokens read as blanks in every text
 * format (one definition of a blank in src/io/io.h): the same meshes and
 * clouds as with LF. */
static void test_crlf(void)
{
    static const struct {
        tsl_parse_fn fn;
        const char *text;
    } cases[] = {
        {tsl_parse_obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4\r3\n"},
        {tsl_parse_off, "OFF\n4 2 0\n0 0 0\n1 0\r0\n0 1 0\n1 1 0\n3 0 1 2\n3 1 3 2\n"},
        {tsl_parse_xyz, "0 0 0\n1 0\r0\n0 1 0\n1 1 0\n"},
        {tsl_parse_pcd, "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
                        "WIDTH 4\nHEIGHT 1\nPOINTS 4\nDATA ascii\n0 0 0\n1 0\r0\n0 1 0\n"
                        "1 1 0\n"},
    };
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        const char *lf = cases[c].text;
        char crlf[512];
        size_t n = 0;
        for (const char *q = lf; *q && n + 2 < sizeof crlf; q++) {
            if (*q == '\n')
                crlf[n++] = '\r';
            crlf[n++] = *q;
        }
        crlf[n] = 0;
        tessel_mesh a, b;
        tessel_diag d;
        tessel_status sa = parse_mesh(cases[c].fn, lf, &a, &d);
        CHECK_MSG(sa == TESSEL_OK, "case %zu LF: %s", c, d.message);
        tessel_status sb = parse_mesh(cases[c].fn, crlf, &b, &d);
        CHECK_MSG(sb == TESSEL_OK, "case %zu CRLF: %s", c, d.message);
        if (sa == TESSEL_OK && sb == TESSEL_OK) {
            CHECK(a.vertex_count == 4 && b.vertex_count == 4);
            CHECK(a.triangle_count == b.triangle_count);
            CHECK(fmt_same_floats(a.xyz, b.xyz, 3 * a.vertex_count));
            CHECK(a.triangle_count == 0 ||
                  !memcmp(a.triangles, b.triangles, 3 * a.triangle_count * sizeof *a.triangles));
            CHECK(a.xyz[3 * 1] == 1 && a.xyz[3 * 1 + 2] == 0);
        }
        if (sa == TESSEL_OK)
            tessel_mesh_free(&a);
        if (sb == TESSEL_OK)
            tessel_mesh_free(&b);
    }
}

int main(void)
{
    test_obj_read();
    test_off_read();
    test_round_trips();
    test_stl();
    test_public_api();
    test_crlf();
    return TEST_SUMMARY();
}
