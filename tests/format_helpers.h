/* Helpers shared by the format tests (test_xyz.c, test_obj_off.c,
 * test_pcd.c, test_las.c): run a parser on an exact-size heap copy (so
 * AddressSanitizer sees any read past the end), write through a format
 * writer into memory, re-run a parser on every prefix of a valid input, and
 * load the bad files of tests/data/bad. */
#ifndef TESSEL_FORMAT_HELPERS_H
#define TESSEL_FORMAT_HELPERS_H

#include "io/io.h"
#include "test.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Parses data[0..size) as a cloud (want_faces 0) or a mesh. On error the
 * outputs are zeroed and diag holds the message. */
static inline tessel_status fmt_parse_cloud(tsl_parse_fn fn, const void *data, size_t size,
                                     tessel_cloud *cloud, tessel_diag *diag)
{
    uint8_t *copy = malloc(size ? size : 1);
    if (!copy)
        return TESSEL_ERR_NOMEM;
    if (size)
        memcpy(copy, data, size);
    tsl_builder b;
    tsl_builder_init(&b, NULL);
    memset(diag, 0, sizeof *diag);
    memset(cloud, 0, sizeof *cloud);
    tessel_status st = fn(copy, size, "mem", 0, &b, diag);
    if (st == TESSEL_OK)
        st = tsl_builder_finish_cloud(&b, cloud);
    tsl_builder_free(&b);
    free(copy);
    return st;
}

static inline tessel_status fmt_parse_mesh(tsl_parse_fn fn, const void *data, size_t size,
                                    tessel_mesh *mesh, tessel_diag *diag)
{
    uint8_t *copy = malloc(size ? size : 1);
    if (!copy)
        return TESSEL_ERR_NOMEM;
    if (size)
        memcpy(copy, data, size);
    tsl_builder b;
    tsl_builder_init(&b, NULL);
    memset(diag, 0, sizeof *diag);
    memset(mesh, 0, sizeof *mesh);
    tessel_status st = fn(copy, size, "mem", 1, &b, diag);
    if (st == TESSEL_OK)
        st = tsl_builder_finish_mesh(&b, mesh);
    tsl_builder_free(&b);
    free(copy);
    return st;
}

static inline tessel_status fmt_parse_text(tsl_parse_fn fn, const char *text, tessel_cloud *cloud,
                                    tessel_diag *diag)
{
    return fmt_parse_cloud(fn, text, strlen(text), cloud, diag);
}

/* Writes vertices (and n_tris triangles, indices into v) with a format
 * writer into a heap buffer; *size gets its length. NULL on failure. */
static inline char *fmt_write(const tsl_format_writer *w, const tsl_vertices *v,
                       const uint32_t *tris, size_t n_tris,
                       const tessel_write_params *params, size_t *size)
{
    char *buf = NULL;
    FILE *fp = open_memstream(&buf, size);
    if (!fp)
        return NULL;
    tessel_status st = TESSEL_OK;
    if (w->begin)
        st = w->begin(fp, v, v->count, n_tris, params);
    if (st == TESSEL_OK && w->vertices)
        st = w->vertices(fp, v, NULL, v->count, params);
    if (st == TESSEL_OK && w->faces && n_tris)
        st = w->faces(fp, v, tris, tris, n_tris, params);
    if (st == TESSEL_OK && w->end)
        st = w->end(fp, params);
    fclose(fp);
    if (st != TESSEL_OK) {
        free(buf);
        return NULL;
    }
    return buf;
}

/* Runs the parser (as cloud and as mesh) on every proper prefix of a valid
 * input: each must either succeed or fail with a message, never crash or
 * read past the end. Returns the number of prefixes that failed without a
 * message. */
static inline size_t fmt_every_prefix(tsl_parse_fn fn, const void *data, size_t size)
{
    size_t silent = 0;
    for (size_t len = 0; len < size; len++) {
        tessel_diag d;
        tessel_cloud c;
        tessel_status st = fmt_parse_cloud(fn, data, len, &c, &d);
        if (st != TESSEL_OK && d.message[0] == 0)
            silent++;
        tessel_cloud_free(&c);
        tessel_mesh m;
        st = fmt_parse_mesh(fn, data, len, &m, &d);
        if (st != TESSEL_OK && d.message[0] == 0)
            silent++;
        tessel_mesh_free(&m);
    }
    return silent;
}

/* Reads tests/data/bad/<name> into a heap buffer. */
static inline uint8_t *fmt_load_bad(const char *name, size_t *size)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/bad/%s", TESSEL_TEST_DATA, name);
    FILE *fp = fopen(path, "rb");
    if (!fp)
        return NULL;
    fseek(fp, 0, SEEK_END);
    long n = ftell(fp);
    fseek(fp, 0, SEEK_SET);
    uint8_t *buf = malloc(n > 0 ? (size_t)n : 1);
    if (buf && n > 0 && fread(buf, 1, (size_t)n, fp) != (size_t)n) {
        free(buf);
        buf = NULL;
    }
    fclose(fp);
    *size = n > 0 ? (size_t)n : 0;
    return buf;
}

/* Parses a bad file and checks status, message substring and position
 * (line for text, byte offset for binary; 0 / UINT64_MAX: not checked). */
static inline void fmt_check_bad(tsl_parse_fn fn, const char *file, int want_faces,
                          tessel_status expect, const char *substring, uint64_t line,
                          uint64_t offset)
{
    size_t size = 0;
    uint8_t *data = fmt_load_bad(file, &size);
    CHECK_MSG(data != NULL, "missing %s", file);
    if (!data)
        return;
    tessel_diag d;
    tessel_status st;
    if (want_faces) {
        tessel_mesh m;
        st = fmt_parse_mesh(fn, data, size, &m, &d);
        tessel_mesh_free(&m);
    } else {
        tessel_cloud c;
        st = fmt_parse_cloud(fn, data, size, &c, &d);
        tessel_cloud_free(&c);
    }
    CHECK_MSG(st == expect, "%s: status %s, expected %s (%s)", file, tessel_status_str(st),
              tessel_status_str(expect), d.message);
    CHECK_MSG(strstr(d.message, substring) != NULL, "%s: message '%s' lacks '%s'", file,
              d.message, substring);
    if (line)
        CHECK_MSG(d.line == line, "%s: line %llu, expected %llu (%s)", file,
                  (unsigned long long)d.line, (unsigned long long)line, d.message);
    if (offset != UINT64_MAX)
        CHECK_MSG(d.has_offset && d.offset == offset, "%s: offset %llu, expected %llu (%s)",
                  file, (unsigned long long)d.offset, (unsigned long long)offset, d.message);
    free(data);
}

/* A small deterministic generator (xorshift64*). */
static uint64_t fmt_rng_state = 88172645463325252ull;
static inline double fmt_rand(void)
{
    fmt_rng_state ^= fmt_rng_state >> 12;
    fmt_rng_state ^= fmt_rng_state << 25;
    fmt_rng_state ^= fmt_rng_state >> 27;
    return (double)((fmt_rng_state * 2685821657736338717ull) >> 11) / 9007199254740992.0;
}

/* Float bits equal (so -0 != 0 and NaN == NaN with the same payload). */
static inline int fmt_same_floats(const float *a, const float *b, size_t n)
{
    return memcmp(a, b, n * sizeof(float)) == 0;
}

#endif
