/* The CLI's own behaviour: exit codes, error lines that name the file and
 * the place for every bad file, --json, convert round trips through every
 * writable format, normals, and no partial output on failure. */
#include "test.h"
#include "tessel.h"

#include <dirent.h>
#include <signal.h>
#include <math.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

static char tmpdir[256];

/* Runs the CLI with args; stdout and stderr go to files in tmpdir.
 * Returns the exit code (or -1 if it did not exit normally). */
static int run(const char *args)
{
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "%s %s >%s/out.txt 2>%s/err.txt", TESSEL_CLI, args, tmpdir,
             tmpdir);
    int st = system(cmd);
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

static char *slurp(const char *name)
{
    static char buf[65536];
    char path[512];
    snprintf(path, sizeof path, "%s/%s", tmpdir, name);
    FILE *f = fopen(path, "rb");
    size_t n = f ? fread(buf, 1, sizeof buf - 1, f) : 0;
    if (f)
        fclose(f);
    buf[n] = '\0';
    return buf;
}

/* Files in tmpdir other than the captured out/err: must be none after a
 * failed write (no temporaries, no partial output). */
static int stray_files(void)
{
    int n = 0;
    DIR *d = opendir(tmpdir);
    struct dirent *e;
    while (d && (e = readdir(d)) != NULL) {
        if (strcmp(e->d_name, ".") && strcmp(e->d_name, "..") &&
            strcmp(e->d_name, "out.txt") && strcmp(e->d_name, "err.txt") &&
            strncmp(e->d_name, "keep_", 5))
            n++;
    }
    if (d)
        closedir(d);
    return n;
}

static void test_usage(void)
{
    CHECK(run("--help") == 0 && strstr(slurp("out.txt"), "reconstruct"));
    CHECK(run("") == 1);
    CHECK(run("frobnicate") == 1 && strstr(slurp("err.txt"), "unknown command"));
    CHECK(run("info") == 1);
    CHECK(run("info --bogus x.ply") == 1 && strstr(slurp("err.txt"), "unknown option"));
    CHECK(run("info --threads many x.ply") == 1);
    CHECK(run("convert only_one.ply") == 1);
    CHECK(run("convert --help") == 0 && strstr(slurp("out.txt"), "usage: tessel convert"));
    CHECK(run("info /nonexistent/cloud.ply") == 2);
    CHECK(strstr(slurp("err.txt"), "tessel: error: /nonexistent/cloud.ply: ") != NULL);
}

/* Every bad file gives exit 2 and one line "tessel: error: FILE: line N: ..."
 * or "...: byte N: ...". */
static void test_bad_files(void)
{
    char dir[512];
    snprintf(dir, sizeof dir, "%s/bad", TESSEL_TEST_DATA);
    DIR *d = opendir(dir);
    CHECK(d != NULL);
    int count = 0;
    struct dirent *e;
    while (d && (e = readdir(d)) != NULL) {
        if (e->d_name[0] == '.')
            continue;
        char args[1024], prefix[1024];
        snprintf(args, sizeof args, "info %s/%s", dir, e->d_name);
        int code = run(args);
        const char *err = slurp("err.txt");
        snprintf(prefix, sizeof prefix, "tessel: error: %s/%s: ", dir, e->d_name);
        bool named = strncmp(err, prefix, strlen(prefix)) == 0;
        const char *place = err + (named ? strlen(prefix) : 0);
        bool located = strncmp(place, "line ", 5) == 0 || strncmp(place, "byte ", 5) == 0;
        CHECK_MSG(code == 2 && named && located, "%s: exit %d, stderr '%s'", e->d_name, code,
                  err);
        count++;
    }
    if (d)
        closedir(d);
    CHECK(count >= 20);
}

/* A small cloud with normals written by the library, then converted by the
 * CLI through each writable format and back: the same floats come back. */
static void test_convert_round_trip(void)
{
    tessel_cloud c;
    CHECK(tessel_cloud_alloc(&c, 200, 1, 0) == TESSEL_OK);
    for (size_t i = 0; i < c.count; i++) {
        double t = (double)i * 0.37;
        c.xyz[3 * i] = (float)cos(t) * 1.25f;
        c.xyz[3 * i + 1] = (float)sin(t) / 3.0f;
        c.xyz[3 * i + 2] = (float)(t * 1e-3);
        c.normals[3 * i + 2] = 1.0f;
    }
    char src[512];
    snprintf(src, sizeof src, "%s/keep_src.ply", tmpdir);
    CHECK(tessel_cloud_write(&c, src, NULL, NULL) == TESSEL_OK);
    const char *exts[] = {"xyz", "csv", "obj", "off", "ply"};
    for (size_t k = 0; k < sizeof exts / sizeof exts[0]; k++) {
        char args[2048], mid[512], back[512];
        snprintf(mid, sizeof mid, "%s/keep_mid.%s", tmpdir, exts[k]);
        snprintf(back, sizeof back, "%s/keep_back.ply", tmpdir);
        snprintf(args, sizeof args, "convert %s %s --quiet", src, mid);
        CHECK_MSG(run(args) == 0, "convert to %s: %s", exts[k], slurp("err.txt"));
        snprintf(args, sizeof args, "convert %s %s --quiet", mid, back);
        CHECK_MSG(run(args) == 0, "convert from %s: %s", exts[k], slurp("err.txt"));
        tessel_cloud r;
        CHECK(tessel_cloud_read(&r, back, NULL, NULL) == TESSEL_OK);
        bool same = r.count == c.count &&
                    memcmp(r.xyz, c.xyz, c.count * 3 * sizeof(float)) == 0;
        CHECK_MSG(same, "round trip through %s changed the points", exts[k]);
        tessel_cloud_free(&r);
        unlink(mid);
        unlink(back);
    }
    /* STL holds triangles only: a cloud is refused with a clear message and
     * no file. */
    char args[1024];
    snprintf(args, sizeof args, "convert %s %s/x.stl", src, tmpdir);
    CHECK(run(args) == 3 && strstr(slurp("err.txt"), "triangles only") && stray_files() == 0);
    /* Output errors: exit 3, nothing left behind. */
    snprintf(args, sizeof args, "convert %s /nonexistent/dir/out.ply", src);
    CHECK(run(args) == 3 && strstr(slurp("err.txt"), "/nonexistent/dir/out.ply"));
    snprintf(args, sizeof args, "convert %s %s/out.las", src, tmpdir);
    CHECK(run(args) == 1 && stray_files() == 0);
    snprintf(args, sizeof args, "convert %s %s/out.unknownext", src, tmpdir);
    CHECK(run(args) == 1 && stray_files() == 0);
    /* --json summary on stdout. */
    snprintf(args, sizeof args, "info %s --json", src);
    CHECK(run(args) == 0 && strstr(slurp("out.txt"), "\"points\": 200") &&
          strstr(slurp("out.txt"), "\"normals\": true"));
    tessel_cloud_free(&c);
    unlink(src);
}

/* tessel normals on a sphere: unit normals pointing outward. */
static void test_normals(void)
{
    tessel_cloud c;
    const size_t n = 2000;
    CHECK(tessel_cloud_alloc(&c, n, 0, 0) == TESSEL_OK);
    const double golden = 2.399963229728653;
    for (size_t i = 0; i < n; i++) {
        double z = 1.0 - 2.0 * ((double)i + 0.5) / (double)n, r = sqrt(1 - z * z);
        c.xyz[3 * i] = (float)(r * cos(golden * (double)i));
        c.xyz[3 * i + 1] = (float)(r * sin(golden * (double)i));
        c.xyz[3 * i + 2] = (float)z;
    }
    char in[512], out[512], args[2048];
    snprintf(in, sizeof in, "%s/keep_sphere.ply", tmpdir);
    snprintf(out, sizeof out, "%s/keep_sphere_n.ply", tmpdir);
    CHECK(tessel_cloud_write(&c, in, NULL, NULL) == TESSEL_OK);
    snprintf(args, sizeof args, "normals %s %s -k 12 --threads 2 --json", in, out);
    CHECK(run(args) == 0 && strstr(slurp("out.txt"), "\"oriented\": true"));
    tessel_cloud r;
    CHECK(tessel_cloud_read(&r, out, NULL, NULL) == TESSEL_OK);
    size_t outward = 0;
    for (size_t i = 0; r.normals && i < r.count; i++) {
        const float *p = r.xyz + 3 * i, *m = r.normals + 3 * i;
        if (p[0] * m[0] + p[1] * m[1] + p[2] * m[2] > 0.95f)
            outward++;
    }
    CHECK_MSG(r.normals && outward == n, "%zu of %zu normals outward", outward, n);
    tessel_cloud_free(&r);
    tessel_cloud_free(&c);
    snprintf(args, sizeof args, "normals %s %s -k 2", in, out);
    CHECK(run(args) == 1);
    unlink(in);
    unlink(out);
}

/* RMS of |p| - 1 over a cloud read from path (-1 when unreadable). */
static double sphere_rms_of(const char *path)
{
    tessel_cloud r;
    if (tessel_cloud_read(&r, path, NULL, NULL) != TESSEL_OK)
        return -1.0;
    double s = 0;
    for (size_t i = 0; i < r.count; i++) {
        const float *p = r.xyz + 3 * i;
        double d = sqrt((double)p[0] * p[0] + (double)p[1] * p[1] + (double)p[2] * p[2]) - 1.0;
        s += d * d;
    }
    s = sqrt(s / (double)r.count);
    tessel_cloud_free(&r);
    return s;
}

/* tessel smooth on a noisy sphere (radial noise of about the spacing):
 * the output is closer to the sphere, --aggregate closer still, with each
 * point out of its own fit (--exclude-self) still closer than the input,
 * and the summary reports the options. */
static void test_smooth(void)
{
    tessel_cloud c;
    const size_t n = 2000;
    CHECK(tessel_cloud_alloc(&c, n, 0, 0) == TESSEL_OK);
    const double golden = 2.399963229728653;
    uint64_t state = 7;
    for (size_t i = 0; i < n; i++) {
        double z = 1.0 - 2.0 * ((double)i + 0.5) / (double)n, r = sqrt(1 - z * z);
        state = state * 6364136223846793005ull + 1442695040888963407ull;
        double u = (double)(state >> 11) * 0x1.0p-53; /* [0, 1): noise +-0.08 */
        double s = 1.0 + 0.16 * (u - 0.5);
        c.xyz[3 * i] = (float)(s * r * cos(golden * (double)i));
        c.xyz[3 * i + 1] = (float)(s * r * sin(golden * (double)i));
        c.xyz[3 * i + 2] = (float)(s * z);
    }
    char in[512], out[512], args[2048];
    snprintf(in, sizeof in, "%s/noisy_sphere.ply", tmpdir);
    snprintf(out, sizeof out, "%s/noisy_sphere_s.ply", tmpdir);
    CHECK(tessel_cloud_write(&c, in, NULL, NULL) == TESSEL_OK);
    double before = sphere_rms_of(in);
    snprintf(args, sizeof args, "smooth %s %s --json", in, out);
    CHECK(run(args) == 0 && strstr(slurp("out.txt"), "\"aggregate\": 0") &&
          strstr(slurp("out.txt"), "\"exclude_self\": 0"));
    double plain = sphere_rms_of(out);
    snprintf(args, sizeof args, "smooth %s %s --aggregate --json", in, out);
    CHECK(run(args) == 0 && strstr(slurp("out.txt"), "\"aggregate\": 1"));
    double agg = sphere_rms_of(out);
    snprintf(args, sizeof args, "smooth %s %s --exclude-self --json", in, out);
    CHECK(run(args) == 0 && strstr(slurp("out.txt"), "\"exclude_self\": 1"));
    double excl = sphere_rms_of(out);
    CHECK_MSG(plain > 0 && plain < before / 2 && agg > 0 && agg < plain && excl > 0 &&
                  excl < before / 2 && excl != plain,
              "rms %g -> %g, aggregated %g, each point out of its own fit %g", before, plain,
              agg, excl);
    snprintf(args, sizeof args, "smooth %s %s --passes 0", in, out);
    CHECK(run(args) == 1);
    tessel_cloud_free(&c);
    unlink(in);
    unlink(out);
}

/* Points the reader drops (NaN, infinite, beyond 1e15) are said: a warning
 * when enough are left (none with --quiet), and counted in the error when
 * too few are. */
static void test_dropped_points(void)
{
    char path[512], args[1200];
    snprintf(path, sizeof path, "%s/keep_dropped.xyz", tmpdir);
    FILE *f = fopen(path, "w");
    CHECK(f != NULL);
    if (!f)
        return;
    fprintf(f, "nan 0 0\n0 inf 0\n0 0 1e30\n");
    for (int i = 0; i < 20; i++)
        for (int j = 0; j < 20; j++)
            fprintf(f, "%d %d %g\n", i, j, 0.01 * ((i * 7 + j * 3) % 5));
    fclose(f);
    snprintf(args, sizeof args, "reconstruct %s %s/keep_out.ply", path, tmpdir);
    CHECK(run(args) == 0);
    CHECK(strstr(slurp("err.txt"), "3 of 403 points dropped: a coordinate NaN") != NULL);
    snprintf(args, sizeof args, "reconstruct %s %s/keep_out.ply --quiet", path, tmpdir);
    CHECK(run(args) == 0 && strstr(slurp("err.txt"), "dropped") == NULL);

    f = fopen(path, "w");
    CHECK(f != NULL);
    if (!f)
        return;
    fprintf(f, "nan 0 0\n0 inf 0\n1 1 1\n2 0 0\n");
    fclose(f);
    snprintf(args, sizeof args, "smooth %s %s/keep_out.ply --quiet", path, tmpdir);
    CHECK(run(args) == 2);
    CHECK(strstr(slurp("err.txt"), "2 points (2 more dropped: a coordinate NaN") != NULL);
    remove(path);
    snprintf(path, sizeof path, "%s/keep_out.ply", tmpdir);
    remove(path);
}

/* tessel sample: N points with the noise asked for, written with normals;
 * a cloud (no triangles), a bad N and a bad option are refused. */
static void test_sample(void)
{
    tessel_mesh m;
    CHECK(tessel_mesh_alloc(&m, 4, 2, 0, 0) == TESSEL_OK);
    const float v[12] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
    const uint32_t t[6] = {0, 1, 2, 0, 2, 3};
    memcpy(m.xyz, v, sizeof v);
    memcpy(m.triangles, t, sizeof t);
    char in[512], out[512], args[2048];
    snprintf(in, sizeof in, "%s/keep_square.ply", tmpdir);
    snprintf(out, sizeof out, "%s/keep_square_s.ply", tmpdir);
    CHECK(tessel_mesh_write(&m, in, NULL, NULL) == TESSEL_OK);
    tessel_mesh_free(&m);
    snprintf(args, sizeof args, "sample %s 2e4 %s --noise 0.01 --seed 3 --json", in, out);
    CHECK(run(args) == 0 && strstr(slurp("out.txt"), "\"points\": 20000"));
    tessel_cloud c;
    CHECK(tessel_cloud_read(&c, out, NULL, NULL) == TESSEL_OK);
    double s2 = 0.0;
    size_t inside = 0;
    for (size_t i = 0; i < c.count; i++) {
        const float *p = c.xyz + 3 * i;
        s2 += (double)p[2] * p[2];
        inside += p[0] > -0.05f && p[0] < 1.05f && p[1] > -0.05f && p[1] < 1.05f;
    }
    CHECK(c.count == 20000 && c.normals != NULL && inside == c.count);
    CHECK_MSG(fabs(sqrt(s2 / (double)c.count) - 0.01) < 0.0005, "noise %g",
              sqrt(s2 / (double)c.count));
    tessel_cloud_free(&c);
    /* A point cloud has nothing to sample: an input error naming it. */
    snprintf(args, sizeof args, "sample %s 10 %s/never.ply", out, tmpdir);
    CHECK(run(args) == 2 && strstr(slurp("err.txt"), "no triangles"));
    snprintf(args, sizeof args, "sample %s 1.5 %s/never.ply", in, tmpdir);
    CHECK(run(args) == 1 && strstr(slurp("err.txt"), "whole number"));
    snprintf(args, sizeof args, "sample %s 10 %s/never.ply --noise -1", in, tmpdir);
    CHECK(run(args) == 1);
    CHECK(stray_files() == 0);
    unlink(in);
    unlink(out);
}

/* tessel reconstruct without --method: the summary says which method the
 * cloud got and why; an unknown method is a usage error. */
static void test_reconstruct_auto(void)
{
    tessel_cloud c;
    const size_t n = 20000;
    CHECK(tessel_cloud_alloc(&c, n, 0, 0) == TESSEL_OK);
    const double golden = 2.399963229728653;
    for (size_t i = 0; i < n; i++) {
        double z = 1.0 - 2.0 * ((double)i + 0.5) / (double)n, r = sqrt(1 - z * z);
        c.xyz[3 * i] = (float)(r * cos(golden * (double)i));
        c.xyz[3 * i + 1] = (float)(r * sin(golden * (double)i));
        c.xyz[3 * i + 2] = (float)z;
    }
    char in[512], out[512], args[2048];
    snprintf(in, sizeof in, "%s/keep_auto.ply", tmpdir);
    snprintf(out, sizeof out, "%s/keep_auto_out.ply", tmpdir);
    CHECK(tessel_cloud_write(&c, in, NULL, NULL) == TESSEL_OK);
    snprintf(args, sizeof args, "reconstruct %s %s --json", in, out);
    CHECK(run(args) == 0);
    const char *o = slurp("out.txt");
    CHECK_MSG(strstr(o, "\"method\": \"greedy\"") && strstr(o, "\"chosen_by\": \"auto\"") &&
                  strstr(o, "clean"),
              "clean sphere: %s", o);
    /* Radial noise of about one spacing: the smooth method. */
    uint64_t x = 12345;
    for (size_t i = 0; i < n; i++) {
        x = x * 6364136223846793005ULL + 1442695040888963407ULL;
        double u = (double)(x >> 11) * 0x1.0p-53 - 0.5;
        for (int k = 0; k < 3; k++)
            c.xyz[3 * i + k] *= (float)(1.0 + 0.05 * u);
    }
    CHECK(tessel_cloud_write(&c, in, NULL, NULL) == TESSEL_OK);
    CHECK(run(args) == 0);
    o = slurp("out.txt");
    CHECK_MSG(strstr(o, "\"method\": \"smooth\"") && strstr(o, "noisy"), "noisy sphere: %s", o);
    snprintf(args, sizeof args, "reconstruct %s %s", in, out);
    CHECK(run(args) == 0 && strstr(slurp("err.txt"), "method smooth (auto)"));
    snprintf(args, sizeof args, "reconstruct %s %s --method magic", in, out);
    CHECK(run(args) == 1 && strstr(slurp("err.txt"), "auto, greedy or smooth"));
    tessel_cloud_free(&c);
    unlink(in);
    unlink(out);
}

/* SIGINT during a reconstruction: the process exits with 130 and leaves
 * no temporary or partial output; SIGTERM the same with 143; SIGINT out of
 * core (--memory 1M: slabs of 1,000 points) leaves no scratch file. */
static void test_interrupt(void)
{
    tessel_cloud c;
    const size_t n = 600000;
    CHECK(tessel_cloud_alloc(&c, n, 0, 0) == TESSEL_OK);
    const double golden = 2.399963229728653;
    for (size_t i = 0; i < n; i++) {
        double z = 1.0 - 2.0 * ((double)i + 0.5) / (double)n, r = sqrt(1 - z * z);
        c.xyz[3 * i] = (float)(r * cos(golden * (double)i));
        c.xyz[3 * i + 1] = (float)(r * sin(golden * (double)i));
        c.xyz[3 * i + 2] = (float)z;
    }
    char in[512], out[512];
    snprintf(in, sizeof in, "%s/keep_big.ply", tmpdir);
    snprintf(out, sizeof out, "%s/interrupted.ply", tmpdir);
    CHECK(tessel_cloud_write(&c, in, NULL, NULL) == TESSEL_OK);
    tessel_cloud_free(&c);
    const int sigs[3] = {SIGINT, SIGTERM, SIGINT};
    for (int k = 0; k < 3; k++) {
        pid_t pid = fork();
        if (pid == 0) {
            if (!freopen("/dev/null", "w", stdout) || !freopen("/dev/null", "w", stderr))
                _exit(99);
            execl(TESSEL_CLI, TESSEL_CLI, "reconstruct", in, out, "--method", "greedy",
                  k == 2 ? "--memory" : (char *)NULL, "1M", (char *)NULL);
            _exit(98);
        }
        CHECK(pid > 0);
        /* Interrupt once the output's temporary exists: mid-reconstruction. */
        struct timespec pause = {0, 5000000};
        for (int t = 0; t < 2000 && stray_files() == 0; t++)
            nanosleep(&pause, NULL);
        CHECK(stray_files() > 0);
        kill(pid, sigs[k]);
        int status = 0;
        waitpid(pid, &status, 0);
        CHECK_MSG(WIFEXITED(status) && WEXITSTATUS(status) == 128 + sigs[k],
                  "signal %d: exit status %d", sigs[k], WIFEXITED(status) ? WEXITSTATUS(status) : -1);
        CHECK_MSG(stray_files() == 0, "signal %d: %d files left", sigs[k], stray_files());
    }
    /* Its messages into a pipe nobody reads any more: it finishes, and
     * leaves its output and nothing else. */
    int fd[2];
    CHECK(pipe(fd) == 0);
    pid_t pid = fork();
    if (pid == 0) {
        close(fd[0]);
        if (!freopen("/dev/null", "w", stdout) || dup2(fd[1], 2) < 0)
            _exit(99);
        execl(TESSEL_CLI, TESSEL_CLI, "reconstruct", in, out, "--method", "greedy", (char *)NULL);
        _exit(98);
    }
    close(fd[0]);
    close(fd[1]);
    int status = 0;
    waitpid(pid, &status, 0);
    CHECK_MSG(WIFEXITED(status) && WEXITSTATUS(status) == 0, "closed pipe: status %d", status);
    CHECK(access(out, F_OK) == 0 && stray_files() == 1); /* the output only */
    unlink(out);
    unlink(in);
}

int main(void)
{
    snprintf(tmpdir, sizeof tmpdir, "/tmp/tessel_test_cli_XXXXXX");
    if (!mkdtemp(tmpdir)) {
        perror("mkdtemp");
        return 1;
    }
    test_usage();
    test_bad_files();
    test_convert_round_trip();
    test_normals();
    test_smooth();
    test_dropped_points();
    test_sample();
    test_reconstruct_auto();
    test_interrupt();
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf %s", tmpdir);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", tmpdir);
    return TEST_SUMMARY();
}
