/* XYZ / CSV / PTS reader and writer: layouts, separators, comments, column
 * names, Leica PTS blocks, errors with their line, exact round trips and
 * every prefix of a valid file. */
#include "format_helpers.h"

#include <math.h>
#include <unistd.h>

static tessel_status parse(const char *text, tessel_cloud *c, tessel_diag *d)
{
    return fmt_parse_text(tsl_parse_xyz, text, c, d);
}

static void test_basic(void)
{
    tessel_cloud c;
    tessel_diag d;
    CHECK(parse("1 2 3\n4.5\t5 -6e1\n", &c, &d) == TESSEL_OK);
    CHECK(c.count == 2 && !c.normals && !c.rgb && !c.grid);
    CHECK(c.xyz[0] == 1 && c.xyz[1] == 2 && c.xyz[2] == 3);
    CHECK(c.xyz[3] == 4.5f && c.xyz[4] == 5 && c.xyz[5] == -60);
    CHECK(c.offset[0] == 0 && c.offset[1] == 0 && c.offset[2] == 0);
    tessel_cloud_free(&c);

    /* Separators, comments, blank lines, CRLF, no final newline. */
    CHECK(parse("# header comment\r\n// another\r\n\r\n1,2,3,0,0,1\r\n  4;5;6;0;1;0\r\n"
                "7, 8 ,9 , 1,0,0", &c, &d) == TESSEL_OK);
    CHECK_MSG(c.count == 3 && c.normals != NULL, "%s", d.message);
    if (c.count == 3 && c.normals) {
        CHECK(c.xyz[6] == 7 && c.xyz[7] == 8 && c.xyz[8] == 9);
        CHECK(c.normals[2] == 1 && c.normals[4] == 1 && c.normals[6] == 1);
    }
    tessel_cloud_free(&c);

    /* Six integer columns with colour values are x y z r g b... */
    CHECK(parse("1 2 3 255 0 0\n4 5 6 0 128 64\n7 8 9 0 0 1\n", &c, &d) == TESSEL_OK);
    CHECK(c.count == 3 && !c.normals && c.rgb);
    if (c.rgb)
        CHECK(c.rgb[0] == 255 && c.rgb[4] == 128 && c.rgb[5] == 64 && c.rgb[8] == 1);
    tessel_cloud_free(&c);
    /* ...but unit-length integer vectors stay normals. */
    CHECK(parse("1 2 3 0 0 1\n4 5 6 1 0 0\n", &c, &d) == TESSEL_OK);
    CHECK(c.count == 2 && c.normals && !c.rgb);
    tessel_cloud_free(&c);
    /* Quoted CSV column names. */
    CHECK(parse("\"x\",\"y\",\"z\"\n1,2,3\n", &c, &d) == TESSEL_OK && c.count == 1);
    tessel_cloud_free(&c);

    /* Empty input and comment-only input give an empty cloud. */
    CHECK(parse("", &c, &d) == TESSEL_OK && c.count == 0);
    tessel_cloud_free(&c);
    CHECK(parse("# nothing\n\n", &c, &d) == TESSEL_OK && c.count == 0);
    tessel_cloud_free(&c);

    /* Non-finite points are dropped and counted. */
    CHECK(parse("1 2 3\nnan 0 0\n0 inf 0\n4 5 6\n", &c, &d) == TESSEL_OK);
    CHECK(c.count == 2 && c.dropped_nonfinite == 2 && c.xyz[3] == 4);
    tessel_cloud_free(&c);

    /* Large coordinates get an offset; the world value is kept. */
    CHECK(parse("500000.125 4100000.5 12.25\n500010.5 4100020.75 13\n", &c, &d) ==
          TESSEL_OK);
    CHECK(c.offset[0] != 0 && c.offset[1] != 0 && c.offset[2] == 0);
    CHECK(c.offset[0] + c.xyz[0] == 500000.125 && c.offset[1] + c.xyz[4] == 4100020.75);
    tessel_cloud_free(&c);
}

static void test_named_columns(void)
{
    tessel_cloud c;
    tessel_diag d;
    /* CSV header, columns reordered and an unknown one skipped. */
    CHECK(parse("intensity,Z,Y,X,red,green,blue\n7,3,2,1,255,128,0\n9,6,5,4,0.5,1.0,0\n", &c,
                &d) == TESSEL_OK);
    CHECK_MSG(c.count == 2 && c.rgb && !c.normals, "%s", d.message);
    if (c.count == 2 && c.rgb) {
        CHECK(c.xyz[0] == 1 && c.xyz[1] == 2 && c.xyz[2] == 3);
        CHECK(c.rgb[0] == 255 && c.rgb[1] == 128 && c.rgb[2] == 0);
        CHECK(c.rgb[3] == 128 && c.rgb[4] == 255 && c.rgb[5] == 0); /* fractions */
    }
    tessel_cloud_free(&c);

    /* CloudCompare's comment header. */
    CHECK(parse("//X,Y,Z,R,G,B\n1,2,3,10,20,30\n", &c, &d) == TESSEL_OK);
    CHECK(c.count == 1 && c.rgb && c.rgb[2] == 30 && !c.normals);
    tessel_cloud_free(&c);

    /* A comment header that does not match the data is just a comment. */
    CHECK(parse("# x y z r g b\n1 2 3\n", &c, &d) == TESSEL_OK);
    CHECK(c.count == 1 && !c.rgb);
    tessel_cloud_free(&c);

    /* normal_x names */
    CHECK(parse("x y z normal_x normal_y normal_z\n0 0 0 0 0 1\n", &c, &d) == TESSEL_OK);
    CHECK(c.count == 1 && c.normals && c.normals[2] == 1);
    tessel_cloud_free(&c);

    /* A header then a line of the wrong width. */
    CHECK(parse("x,y,z\n1,2,3\n1,2\n", &c, &d) == TESSEL_ERR_PARSE);
    CHECK(d.line == 3 && strstr(d.message, "expected 3 values") != NULL);
}

static void test_pts(void)
{
    tessel_cloud c;
    tessel_diag d;
    CHECK(parse("2\n1 2 3 -1200 255 0 0\n4 5 6 300 0 0 255\n1\n7 8 9 5 1 2 3\n", &c, &d) ==
          TESSEL_OK);
    CHECK_MSG(c.count == 3 && c.rgb, "%s", d.message);
    if (c.count == 3 && c.rgb) {
        CHECK(c.xyz[3] == 4 && c.rgb[0] == 255 && c.rgb[5] == 255 && c.rgb[8] == 3);
        CHECK(c.xyz[6] == 7);
    }
    tessel_cloud_free(&c);
    /* x y z intensity: no colour */
    CHECK(parse("1\n1 2 3 -5\n", &c, &d) == TESSEL_OK && c.count == 1 && !c.rgb);
    tessel_cloud_free(&c);
    /* lying block count, in the middle and at the end */
    CHECK(parse("3\n1 2 3 0\n2\n4 5 6 0\n7 8 9 0\n", &c, &d) == TESSEL_ERR_PARSE);
    CHECK(d.line == 1 && strstr(d.message, "announces 3 points but has 1"));
    CHECK(parse("1\n1 2 3 0\n2\n4 5 6 0\n", &c, &d) == TESSEL_ERR_PARSE);
    CHECK(d.line == 3 && strstr(d.message, "announces 2 points but has 1"));
    CHECK(parse("1\n1 2 3 0 1\n", &c, &d) == TESSEL_ERR_PARSE);
    CHECK(strstr(d.message, "expected 3, 4 or 7 numbers") != NULL);
}

static void test_errors(void)
{
    tessel_cloud c;
    tessel_diag d;
    CHECK(parse("1 2 3\n4 5 6 7\n", &c, &d) == TESSEL_ERR_PARSE);
    CHECK(d.line == 2 && strstr(d.message, "expected 3 numbers (like line 1), got 4"));
    CHECK(c.count == 0 && c.xyz == NULL);
    CHECK(parse("1 2\n", &c, &d) == TESSEL_ERR_PARSE);
    CHECK(strstr(d.message, "expected 3 or 6 numbers, got 2") != NULL);
    CHECK(parse("1 2 3\n1 2 3abc\n", &c, &d) == TESSEL_ERR_PARSE);
    CHECK(d.line == 2 && strstr(d.message, "bad number '3abc' in column 3"));
    CHECK(parse("1,,3\n", &c, &d) == TESSEL_ERR_PARSE);
    CHECK(strstr(d.message, "bad number '' in column 2") != NULL);
    CHECK(parse("5\n", &c, &d) == TESSEL_ERR_PARSE); /* a PTS count and no points */

    fmt_check_bad(tsl_parse_xyz, "xyz_bad_number.xyz", 0, TESSEL_ERR_PARSE,
                  "bad number 'x8' in column 2", 4, UINT64_MAX);
    fmt_check_bad(tsl_parse_xyz, "xyz_columns.xyz", 0, TESSEL_ERR_PARSE,
                  "expected 3 or 6 numbers, got 4", 3, UINT64_MAX);
    fmt_check_bad(tsl_parse_xyz, "xyz_pts_count.pts", 0, TESSEL_ERR_PARSE,
                  "PTS block announces 3 points but has 2", 1, UINT64_MAX);

    /* The point limit */
    tsl_builder b;
    tessel_read_params rp = tessel_read_params_default();
    rp.max_points = 2;
    tsl_builder_init(&b, &rp);
    const char *text = "1 2 3\n4 5 6\n7 8 9\n";
    CHECK(tsl_parse_xyz((const uint8_t *)text, strlen(text), "m", 0, &b, &d) ==
          TESSEL_ERR_LIMIT);
    CHECK(d.line == 3);
    tsl_builder_free(&b);
}

/* Writes a random cloud (with the given offset) and reads it back: the
 * floats, offset, normals and colours must be identical. */
static void round_trip(tessel_format format, double offset, int normals, int rgb)
{
    size_t n = 500;
    /* Build the source cloud through the builder so it has a valid offset
     * and rounding, as any cloud read from a file. */
    tsl_builder b;
    tsl_builder_init(&b, NULL);
    tsl_builder_attributes(&b, normals, rgb);
    for (size_t i = 0; i < n; i++) {
        double p[3];
        for (int k = 0; k < 3; k++)
            p[k] = offset * (k + 1) + (fmt_rand() - 0.5) * 200.0;
        float nn[3];
        double len = 0;
        for (int k = 0; k < 3; k++) {
            nn[k] = (float)(fmt_rand() - 0.5);
            len += nn[k] * nn[k];
        }
        for (int k = 0; k < 3; k++)
            nn[k] = (float)(nn[k] / sqrt(len));
        uint8_t cc[3] = {(uint8_t)(fmt_rand() * 256), (uint8_t)(fmt_rand() * 256),
                         (uint8_t)(fmt_rand() * 256)};
        tsl_builder_point(&b, p, nn, cc);
    }
    tessel_cloud src;
    CHECK(tsl_builder_finish_cloud(&b, &src) == TESSEL_OK);
    tsl_builder_free(&b);
    if (offset > 10000)
        CHECK(src.offset[0] != 0 && src.offset[2] != 0);

    tsl_vertices v = {src.count, src.xyz, src.normals, src.rgb,
                      {src.offset[0], src.offset[1], src.offset[2]}};
    tessel_write_params wp = tessel_write_params_default();
    wp.format = format;
    size_t size;
    char *text = fmt_write(&tsl_writer_xyz, &v, NULL, 0, &wp, &size);
    CHECK(text != NULL);
    if (format == TESSEL_FORMAT_CSV)
        CHECK(strncmp(text, "x,y,z", 5) == 0);
    tessel_cloud back;
    tessel_diag d;
    CHECK_MSG(fmt_parse_cloud(tsl_parse_xyz, text, size, &back, &d) == TESSEL_OK, "%s",
              d.message);
    CHECK(back.count == src.count);
    CHECK(memcmp(back.offset, src.offset, sizeof src.offset) == 0);
    if (back.count == src.count) {
        CHECK(fmt_same_floats(back.xyz, src.xyz, 3 * n));
        CHECK((back.normals != NULL) == (normals != 0));
        if (normals && back.normals)
            CHECK(fmt_same_floats(back.normals, src.normals, 3 * n));
        CHECK((back.rgb != NULL) == (rgb != 0));
        if (rgb && back.rgb)
            CHECK(memcmp(back.rgb, src.rgb, 3 * n) == 0);
    }
    /* Every prefix of a (short) written file parses or fails cleanly. */
    size_t cut = size < 3000 ? size : 3000;
    while (cut > 0 && text[cut - 1] != '\n')
        cut--;
    CHECK(fmt_every_prefix(tsl_parse_xyz, text, cut) == 0);
    free(text);
    tessel_cloud_free(&back);
    tessel_cloud_free(&src);
}

static void test_round_trips(void)
{
    for (int f = 0; f < 2; f++) {
        tessel_format fmt = f ? TESSEL_FORMAT_CSV : TESSEL_FORMAT_XYZ;
        round_trip(fmt, 0.0, 0, 0);
        round_trip(fmt, 0.0, 1, 0);
        round_trip(fmt, 0.0, 1, 1);
        round_trip(fmt, 0.0, 0, 1);
        round_trip(fmt, 637000.0, 1, 1); /* UTM-like */
        round_trip(fmt, 6.4e6, 0, 0);    /* ECEF-like */
    }
    /* Writing with write_normals = 0 drops them, and the rest still reads. */
    float xyz[3] = {1, 2, 3}, nrm[3] = {0, 0, 1};
    tsl_vertices v = {1, xyz, nrm, NULL, {0, 0, 0}};
    tessel_write_params wp = tessel_write_params_default();
    wp.write_normals = 0;
    size_t size;
    char *text = fmt_write(&tsl_writer_xyz, &v, NULL, 0, &wp, &size);
    CHECK(text && strcmp(text, "1 2 3\n") == 0);
    free(text);
}

static void test_prefixes(void)
{
    const char *text = "// x y z\n# c\n1,2,3\n\n4;5;6\n7 8 9\n";
    CHECK(fmt_every_prefix(tsl_parse_xyz, text, strlen(text)) == 0);
    const char *pts = "2\n1 2 3 4 5 6 7\n1 2 3 4 5 6 7\n";
    CHECK(fmt_every_prefix(tsl_parse_xyz, pts, strlen(pts)) == 0);
    const char *csv = "X,Y,Z,Nx,Ny,Nz\n1,2,3,0,0,1\n4,5,6,1,0,0\n";
    CHECK(fmt_every_prefix(tsl_parse_xyz, csv, strlen(csv)) == 0);
}


/* Through the public API: .xyz, .csv and .txt files written and read back
 * (format from the extension), and content sniffing on a nameless buffer. */
static void test_public_api(void)
{
    char dir[] = "/tmp/tessel_xyz_XXXXXX";
    CHECK(mkdtemp(dir) != NULL);
    tessel_cloud src;
    const char *text = "x,y,z,nx,ny,nz,r,g,b\n"
                       "637001.25,5120000.5,301.125,0,0,1,1,2,3\n"
                       "637002.5,5120001.75,302.5,0,1,0,4,5,6\n";
    tessel_diag d;
    CHECK(tessel_cloud_parse(&src, text, strlen(text), NULL, NULL, &d) == TESSEL_OK);
    CHECK(src.count == 2 && src.normals && src.rgb && src.offset[0] > 0);
    static const char *const exts[] = {"xyz", "csv", "txt"};
    for (int e = 0; e < 3; e++) {
        char path[256];
        snprintf(path, sizeof path, "%s/cloud.%s", dir, exts[e]);
        CHECK_MSG(tessel_cloud_write(&src, path, NULL, &d) == TESSEL_OK, "%s", d.message);
        tessel_cloud back;
        CHECK_MSG(tessel_cloud_read(&back, path, NULL, &d) == TESSEL_OK, "%s", d.message);
        CHECK(back.count == 2 && fmt_same_floats(back.xyz, src.xyz, 6) &&
              memcmp(back.offset, src.offset, sizeof src.offset) == 0);
        CHECK(back.normals && fmt_same_floats(back.normals, src.normals, 6));
        CHECK(back.rgb && memcmp(back.rgb, src.rgb, 6) == 0);
        if (e == 1) {
            FILE *fp = fopen(path, "r");
            char line[128] = "";
            CHECK(fp && fgets(line, sizeof line, fp));
            CHECK(strcmp(line, "x,y,z,nx,ny,nz,r,g,b\n") == 0);
            CHECK(fp && fgets(line, sizeof line, fp));
            CHECK(strcmp(line, "637001.25,5120000.5,301.125,0,0,1,1,2,3\n") == 0);
            if (fp)
                fclose(fp);
        }
        tessel_cloud_free(&back);
        unlink(path);
    }
    tessel_cloud_free(&src);
    rmdir(dir);
}

int main(void)
{
    test_basic();
    test_named_columns();
    test_pts();
    test_errors();
    test_round_trips();
    test_prefixes();
    test_public_api();
    return TEST_SUMMARY();
}
