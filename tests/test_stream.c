/* The chunked reader (src/io/stream.c): for PLY binary and ascii, XYZ, CSV,
 * PCD, LAS and LAZ (tests/data/laz/, with and without a bounding box) and
 * clouds written here, streaming in chunks of 1, 7 and 1000 points gives
 * exactly tessel_cloud_read's points (the streamed double world coordinate
 * rounds to its float through tsl_local_coord and its offset), normals,
 * colours and counts, and no chunk exceeds its size; errors give the same
 * status and diagnostic; non-finite points are dropped and counted; the
 * callback cancels; a FIFO is read whole and streamed; XYZ's unnamed
 * 6-column files are decided from the first chunk, or fail when the rest
 * of the file would decide otherwise. */
#include "io/io.h"
#include "io/stream.h"
#include "test.h"

#include <dirent.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

static char tmpdir[256];

static void path_in(char *buf, size_t n, const char *name)
{
    snprintf(buf, n, "%s/%s", tmpdir, name);
}

static void write_text(const char *path, const char *text)
{
    FILE *fp = fopen(path, "wb");
    if (fp) {
        fputs(text, fp);
        fclose(fp);
    }
}

/* What the callback saw. */
typedef struct got {
    size_t chunk;             /* the chunk size asked for */
    size_t n, cap;
    double *xyz;
    float *normals;
    uint8_t *rgb;
    size_t calls, biggest;
    int inconsistent;         /* normals / rgb present in some chunks only */
    int has_normals, has_rgb;
    size_t cancel_after;      /* > 0: return TESSEL_ERR_CANCELLED on that call */
} got;

static tessel_status take(void *user, const double *xyz, const float *normals,
                          const uint8_t *rgb, size_t count)
{
    got *g = user;
    if (g->calls == 0) {
        g->has_normals = normals != NULL;
        g->has_rgb = rgb != NULL;
    } else if (g->has_normals != (normals != NULL) || g->has_rgb != (rgb != NULL)) {
        g->inconsistent = 1;
    }
    g->calls++;
    if (count > g->biggest)
        g->biggest = count;
    if (g->cancel_after && g->calls == g->cancel_after)
        return TESSEL_ERR_CANCELLED;
    if (g->n + count > g->cap) {
        size_t cap = (g->n + count) * 2;
        double *x = realloc(g->xyz, 3 * cap * sizeof *x);
        float *nn = realloc(g->normals, 3 * cap * sizeof *nn);
        uint8_t *c = realloc(g->rgb, 3 * cap);
        if (x)
            g->xyz = x;
        if (nn)
            g->normals = nn;
        if (c)
            g->rgb = c;
        if (!x || !nn || !c)
            return TESSEL_ERR_NOMEM;
        g->cap = cap;
    }
    memcpy(g->xyz + 3 * g->n, xyz, 3 * count * sizeof *xyz);
    if (normals)
        memcpy(g->normals + 3 * g->n, normals, 3 * count * sizeof *normals);
    if (rgb)
        memcpy(g->rgb + 3 * g->n, rgb, 3 * count);
    g->n += count;
    return TESSEL_OK;
}

static void got_free(got *g)
{
    free(g->xyz);
    free(g->normals);
    free(g->rgb);
}

static bool same_diag(const tessel_diag *a, const tessel_diag *b)
{
    return !strcmp(a->file, b->file) && a->line == b->line && a->has_offset == b->has_offset &&
           (!a->has_offset || a->offset == b->offset) && !strcmp(a->message, b->message);
}

/* Streams path in chunks of `chunk` and compares with tessel_cloud_read.
 * Returns the status both gave (or -1 when they differ). */
static int compare(const char *path, const tessel_read_params *params, size_t chunk,
                   bool diag_must_match)
{
    tessel_cloud c;
    tessel_diag d1, d2;
    tessel_status st1 = tessel_cloud_read(&c, path, params, &d1);
    got g;
    memset(&g, 0, sizeof g);
    g.chunk = chunk;
    tsl_stream_info info;
    tessel_status st2 = tsl_cloud_stream(path, params, chunk, take, &g, &info, &d2);
    CHECK_MSG(st1 == st2, "%s chunk %zu: read %s, stream %s (%s)", path, chunk,
              tessel_status_str(st1), tessel_status_str(st2), d2.message);
    CHECK_MSG(g.biggest <= chunk && !g.inconsistent, "%s chunk %zu: biggest %zu", path, chunk,
              g.biggest);
    if (st1 != st2 || st1 != TESSEL_OK) {
        CHECK_MSG(!diag_must_match || same_diag(&d1, &d2),
                  "%s chunk %zu: diag '%s' / '%s' vs '%s' / '%s'", path, chunk, d1.file,
                  d1.message, d2.file, d2.message);
        CHECK(st2 == TESSEL_OK || !strcmp(d2.file, path));
        got_free(&g);
        if (st1 == TESSEL_OK)
            tessel_cloud_free(&c);
        return st1 == st2 ? (int)st1 : -1;
    }
    CHECK_MSG(info.points == c.count && g.n == c.count, "%s chunk %zu: %llu / %zu points, read %zu",
              path, chunk, (unsigned long long)info.points, g.n, c.count);
    CHECK(info.dropped == c.dropped_nonfinite);
    CHECK(info.has_normals == (c.normals != NULL) && info.has_rgb == (c.rgb != NULL));
    CHECK(g.calls == 0 || (g.has_normals == info.has_normals && g.has_rgb == info.has_rgb));
    size_t bad_xyz = 0, bad_attr = 0, n = g.n < c.count ? g.n : c.count;
    for (size_t i = 0; i < n; i++) {
        for (int k = 0; k < 3; k++) {
            size_t j = 3 * i + (size_t)k;
            float f = tsl_local_coord(g.xyz[j], c.offset[k]);
            bad_xyz += memcmp(&f, &c.xyz[j], sizeof f) != 0;
            if (c.normals && g.has_normals)
                bad_attr += memcmp(&g.normals[j], &c.normals[j], sizeof(float)) != 0;
            if (c.rgb && g.has_rgb)
                bad_attr += g.rgb[j] != c.rgb[j];
        }
    }
    CHECK_MSG(bad_xyz == 0 && bad_attr == 0, "%s chunk %zu: %zu coordinates, %zu attributes differ",
              path, chunk, bad_xyz, bad_attr);
    got_free(&g);
    tessel_cloud_free(&c);
    return TESSEL_OK;
}

static void compare_chunks(const char *path, const tessel_read_params *params)
{
    static const size_t chunks[] = {1, 7, 1000};
    for (size_t i = 0; i < sizeof chunks / sizeof chunks[0]; i++)
        compare(path, params, chunks[i], true);
}

/* A cloud far from the origin (offsets chosen), with normals and colours. */
static tessel_cloud make_cloud(size_t n)
{
    tessel_cloud c;
    memset(&c, 0, sizeof c);
    c.count = n;
    c.xyz = malloc(3 * n * sizeof *c.xyz);
    c.normals = malloc(3 * n * sizeof *c.normals);
    c.rgb = malloc(3 * n);
    c.offset[0] = 500000;
    c.offset[1] = 4649000;
    c.offset[2] = 0;
    uint64_t s = 0x9e3779b97f4a7c15u;
    for (size_t i = 0; i < 3 * n; i++) {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        double u = (double)(s >> 11) / 9007199254740992.0;
        c.xyz[i] = (float)(u * 300.0 - 50.0);
        c.normals[i] = (float)(u * 2.0 - 1.0);
        c.rgb[i] = (uint8_t)(s >> 3);
    }
    return c;
}

static void test_written_formats(void)
{
    tessel_cloud c = make_cloud(2500);
    struct {
        const char *name;
        tessel_format format;
        int ascii, normals, rgb;
    } cases[] = {
        {"bin.ply", TESSEL_FORMAT_PLY, 0, 1, 1},   {"ascii.ply", TESSEL_FORMAT_PLY, 1, 1, 1},
        {"xyzonly.ply", TESSEL_FORMAT_PLY, 0, 0, 0}, {"all.xyz", TESSEL_FORMAT_XYZ, 0, 1, 1},
        {"six.xyz", TESSEL_FORMAT_XYZ, 0, 1, 0},   {"plain.xyz", TESSEL_FORMAT_XYZ, 0, 0, 0},
        {"all.csv", TESSEL_FORMAT_CSV, 0, 1, 1},   {"rgb.csv", TESSEL_FORMAT_CSV, 0, 0, 1},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char path[512];
        path_in(path, sizeof path, cases[i].name);
        tessel_write_params wp = tessel_write_params_default();
        wp.format = cases[i].format;
        wp.ascii = cases[i].ascii;
        wp.write_normals = cases[i].normals;
        wp.write_rgb = cases[i].rgb;
        tessel_diag d;
        CHECK(tessel_cloud_write(&c, path, &wp, &d) == TESSEL_OK);
        compare_chunks(path, NULL);
        /* The format given, not taken from the name. */
        tessel_read_params rp = tessel_read_params_default();
        rp.format = cases[i].format;
        compare(path, &rp, 333, true);
        unlink(path);
    }

    /* A truncated binary PLY fails as the whole-file read fails. */
    char path[512];
    path_in(path, sizeof path, "cut.ply");
    CHECK(tessel_cloud_write(&c, path, NULL, NULL) == TESSEL_OK);
    struct stat sb;
    CHECK(stat(path, &sb) == 0 && truncate(path, sb.st_size - 10) == 0);
    CHECK(compare(path, NULL, 7, true) == TESSEL_ERR_PARSE);

    /* The callback cancels: the status comes back, the read stops. */
    CHECK(tessel_cloud_write(&c, path, NULL, NULL) == TESSEL_OK);
    got g;
    memset(&g, 0, sizeof g);
    g.cancel_after = 3;
    tsl_stream_info info;
    tessel_diag d;
    CHECK(tsl_cloud_stream(path, NULL, 100, take, &g, &info, &d) == TESSEL_ERR_CANCELLED);
    CHECK(g.calls == 3 && g.n == 200);
    CHECK(!strcmp(d.file, path) && strstr(d.message, "cancelled"));

    /* The limit counts every point read, as in the whole-file read. */
    tessel_read_params rp = tessel_read_params_default();
    rp.max_points = 2499;
    CHECK(compare(path, &rp, 100, true) == TESSEL_ERR_LIMIT);
    rp.max_points = 2500;
    CHECK(compare(path, &rp, 100, true) == TESSEL_OK);
    got_free(&g);

    /* Arguments. */
    CHECK(tsl_cloud_stream(path, NULL, 0, take, &g, &info, &d) == TESSEL_ERR_INVALID_ARG);
    CHECK(tsl_cloud_stream(path, NULL, 10, NULL, &g, &info, &d) == TESSEL_ERR_INVALID_ARG);
    unlink(path);
    path_in(path, sizeof path, "missing.ply");
    CHECK(compare(path, NULL, 10, true) == TESSEL_ERR_IO);
    CHECK(compare(tmpdir, NULL, 10, true) == TESSEL_ERR_IO); /* a folder */
    tessel_cloud_free(&c);
}

static void test_nonfinite(void)
{
    char path[512];
    path_in(path, sizeof path, "nan.xyz");
    write_text(path, "1 2 3\nnan 0 0\n4 5 6\n7 inf 9\n1e300 0 0\n10 11 12\n");
    for (size_t chunk = 1; chunk <= 4; chunk++)
        compare(path, NULL, chunk, true);
    got g;
    memset(&g, 0, sizeof g);
    tsl_stream_info info;
    CHECK(tsl_cloud_stream(path, NULL, 2, take, &g, &info, NULL) == TESSEL_OK);
    CHECK(info.points == 3 && info.dropped == 3 && g.n == 3);
    CHECK(g.n == 3 && g.xyz[0] == 1 && g.xyz[3] == 4 && g.xyz[6] == 10);
    got_free(&g);
    unlink(path);

    /* Only non-finite points, and none at all. */
    write_text(path, "nan nan nan\n");
    compare_chunks(path, NULL);
    write_text(path, "");
    compare_chunks(path, NULL);
    /* A file of exactly one page, ending without a newline. */
    FILE *fp = fopen(path, "wb");
    long page = sysconf(_SC_PAGESIZE);
    for (long i = 0; fp && i < page / 8; i++)
        fputs(i + 1 < page / 8 ? "1 2 333\n" : "1 2 3333", fp);
    if (fp)
        fclose(fp);
    struct stat sb;
    CHECK(stat(path, &sb) == 0 && sb.st_size == page);
    compare_chunks(path, NULL);
    unlink(path);
}

/* Unnamed 6 columns: the whole-file rule reads integers 0-255 with some
 * long vectors as colours. */
static void test_xyz_six_columns(void)
{
    char path[512];
    path_in(path, sizeof path, "six.xyz");
    char text[4096];
    size_t len = 0;
    for (int i = 0; i < 20; i++)
        len += (size_t)snprintf(text + len, sizeof text - len, "%d 1 2 %d 7 200\n", i,
                                (i * 37) % 256);
    write_text(path, text);
    compare_chunks(path, NULL); /* colours in every chunking */

    /* Colour-like for 10 lines, then a fraction: normals for the whole
     * file; a chunk of 7 already went out as colours. */
    snprintf(text + len, sizeof text - len, "1 2 3 0.5 0 0\n");
    write_text(path, text);
    CHECK(compare(path, NULL, 1000, true) == TESSEL_OK);
    got g;
    memset(&g, 0, sizeof g);
    tsl_stream_info info;
    tessel_diag d;
    CHECK(tsl_cloud_stream(path, NULL, 7, take, &g, &info, &d) == TESSEL_ERR_UNSUPPORTED);
    CHECK(!strcmp(d.file, path) && d.line == 21 && strstr(d.message, "name the columns"));
    got_free(&g);

    /* Short integer vectors first (normals so far), a long one later:
     * colours for the whole file. */
    len = 0;
    for (int i = 0; i < 10; i++)
        len += (size_t)snprintf(text + len, sizeof text - len, "%d 1 2 0 0 1\n", i);
    snprintf(text + len, sizeof text - len, "1 2 3 0 9 0\n");
    write_text(path, text);
    CHECK(compare(path, NULL, 1000, true) == TESSEL_OK);
    memset(&g, 0, sizeof g);
    CHECK(tsl_cloud_stream(path, NULL, 7, take, &g, &info, &d) == TESSEL_ERR_UNSUPPORTED);
    CHECK(!strcmp(d.file, path) && strstr(d.message, "r g b"));
    got_free(&g);
    unlink(path);
}

static void test_pcd(void)
{
    char path[512];
    path_in(path, sizeof path, "small.pcd");
    char text[8192];
    size_t len = (size_t)snprintf(text, sizeof text,
                                  "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z normal_x normal_y "
                                  "normal_z\nSIZE 4 4 4 4 4 4\nTYPE F F F F F F\nCOUNT 1 1 1 "
                                  "1 1 1\nWIDTH 30\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\n"
                                  "POINTS 30\nDATA ascii\n");
    for (int i = 0; i < 30; i++)
        len += (size_t)snprintf(text + len, sizeof text - len, "%d.25 %d 3e2 0 %s 1\n", i,
                                -i, i == 4 ? "nan" : "0.5");
    write_text(path, text);
    compare_chunks(path, NULL);
    /* Organized (HEIGHT > 1) with a missing cell: streamed unorganized. */
    memcpy(strstr(text, "WIDTH 30\nHEIGHT 1"), "WIDTH 10\nHEIGHT 3", 17);
    char *nan = strstr(text, "4.25 -4 3e2");
    if (nan)
        memcpy(nan, "nan  -4 3e2", 11);
    write_text(path, text);
    compare_chunks(path, NULL);
    unlink(path);
}

static void test_las_laz(void)
{
    char dir[512];
    snprintf(dir, sizeof dir, "%s/laz", TESSEL_TEST_DATA);
    DIR *dp = opendir(dir);
    CHECK(dp != NULL);
    struct dirent *e;
    size_t files = 0;
    while (dp && (e = readdir(dp))) {
        size_t l = strlen(e->d_name);
        if (l < 5 || (strcmp(e->d_name + l - 4, ".las") && strcmp(e->d_name + l - 4, ".laz")))
            continue;
        char path[1024];
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        compare_chunks(path, NULL);
        files++;
        /* A box around the middle of the cloud (the header's bounds). */
        tessel_cloud c;
        if (tessel_cloud_read(&c, path, NULL, NULL) != TESSEL_OK || c.count == 0)
            continue;
        double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (size_t i = 0; i < c.count; i++)
            for (int k = 0; k < 3; k++) {
                double w = c.offset[k] + c.xyz[3 * i + k];
                lo[k] = w < lo[k] ? w : lo[k];
                hi[k] = w > hi[k] ? w : hi[k];
            }
        double box[6];
        for (int k = 0; k < 3; k++) {
            box[k] = lo[k] + 0.25 * (hi[k] - lo[k]);
            box[k + 3] = lo[k] + 0.75 * (hi[k] - lo[k]);
        }
        tessel_read_params rp = tessel_read_params_default();
        rp.bbox = box;
        compare(path, &rp, 7, true);
        compare(path, &rp, 1000, true);
        /* The limit: status as the whole-file read (its message counts the
         * points in the box first, the stream meets the limit later). */
        rp.bbox = NULL;
        rp.max_points = c.count > 1 ? c.count - 1 : 0;
        CHECK(compare(path, &rp, 7, !strstr(path, "copc")) == TESSEL_ERR_LIMIT);
        tessel_cloud_free(&c);
    }
    if (dp)
        closedir(dp);
    CHECK(files >= 30);

    /* The malformed LAS files fail alike. */
    snprintf(dir, sizeof dir, "%s/bad", TESSEL_TEST_DATA);
    dp = opendir(dir);
    while (dp && (e = readdir(dp))) {
        if (strncmp(e->d_name, "las_", 4))
            continue;
        char path[1024];
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        CHECK_MSG(compare(path, NULL, 7, true) > TESSEL_OK, "%s", path);
    }
    if (dp)
        closedir(dp);
}

/* A LAS file of more records than a window of the colour pre-pass, with
 * 8-bit colours but for one 16-bit value near the end: every colour is
 * shifted down, as in the whole-file read. Built from simple.las. */
static void test_las_windows(void)
{
    char src[1024], path[512];
    snprintf(src, sizeof src, "%s/laz/simple.las", TESSEL_TEST_DATA);
    path_in(path, sizeof path, "big.las");
    uint8_t *data;
    size_t size;
    if (tsl_read_file(src, &data, &size, NULL) != TESSEL_OK) {
        CHECK(0);
        return;
    }
    tsl_las_header h;
    size_t n;
    CHECK(tsl_las_check(data, size, src, &h, &n, NULL) == TESSEL_OK);
    CHECK(h.format == 3 && h.minor < 4 && n > 0);
    const uint32_t count = 150000;
    FILE *fp = fopen(path, "wb");
    uint8_t head[4096];
    CHECK(h.point_offset <= sizeof head);
    memcpy(head, data, h.point_offset);
    for (int k = 0; k < 4; k++)
        head[107 + k] = (uint8_t)(count >> (8 * k));
    if (fp)
        fwrite(head, 1, h.point_offset, fp);
    for (uint32_t i = 0; fp && i < count; i++) {
        uint8_t rec[64];
        memcpy(rec, data + h.point_offset + (i % n) * h.record_length, h.record_length);
        for (int k = 0; k < 3; k++) {
            unsigned v = i == count - 100 ? 0x1234u : (i * 7 + (unsigned)k) % 256;
            rec[28 + 2 * k] = (uint8_t)v;
            rec[29 + 2 * k] = (uint8_t)(v >> 8);
        }
        if (i % 9999 == 5) /* a stray point far from the rest */
            rec[3] = 0x7f, rec[11] = 0x7f;
        fwrite(rec, 1, h.record_length, fp);
    }
    if (fp)
        fclose(fp);
    free(data);
    compare(path, NULL, 7, true);
    compare(path, NULL, 100000, true);
    unlink(path);
}

/* A FIFO cannot be mapped: it is read whole, then streamed. */
static void test_fifo(void)
{
    char path[512];
    path_in(path, sizeof path, "fifo.xyz");
    if (mkfifo(path, 0600) != 0) {
        CHECK(0);
        return;
    }
    const char *text = "1 2 3\n4 5 6\n7 8 9\n";
    pid_t pid = fork();
    if (pid == 0) {
        FILE *fp = fopen(path, "wb");
        if (fp) {
            fputs(text, fp);
            fclose(fp);
        }
        _exit(0);
    }
    got g;
    memset(&g, 0, sizeof g);
    tsl_stream_info info;
    CHECK(tsl_cloud_stream(path, NULL, 2, take, &g, &info, NULL) == TESSEL_OK);
    CHECK(info.points == 3 && g.calls == 2 && g.n == 3 && g.xyz[8] == 9);
    got_free(&g);
    int status;
    waitpid(pid, &status, 0);
    unlink(path);
}

int main(void)
{
    snprintf(tmpdir, sizeof tmpdir, "/tmp/tessel_test_stream_XXXXXX");
    if (!mkdtemp(tmpdir)) {
        perror("mkdtemp");
        return 1;
    }
    test_written_formats();
    test_nonfinite();
    test_xyz_six_columns();
    test_pcd();
    test_las_laz();
    test_las_windows();
    test_fifo();
    CHECK(rmdir(tmpdir) == 0);
    return TEST_SUMMARY();
}
