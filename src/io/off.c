/* Object File Format (Geomview "OFF" manual page): read and written.
 *
 * A keyword line (OFF, COFF, NOFF, NCOFF; the counts may follow on the same
 * line), then "vertices faces edges", then one line per vertex (x y z, then
 * nx ny nz for N, then r g b [a] for C: integers 0-255 or fractions with a
 * '.') and one line per face ("n i1 ... in", anything after the indices -
 * a face colour - ignored). Comments start with '#'. The counts are checked
 * against the lines actually present; memory is reserved for at most what
 * the remaining bytes can hold, so a lying count cannot make the reader
 * allocate. */
#include "io/io.h"

#include <stdlib.h>
#include <string.h>

typedef struct off_text {
    const char *p, *end;
    uint64_t line;
} off_text;

/* Next non-empty line (comments cut) as [*s, *e); false at the end. */
static bool off_next_line(off_text *t, const char **s, const char **e)
{
    while (t->p < t->end) {
        const char *nl = memchr(t->p, '\n', (size_t)(t->end - t->p));
        const char *stop = nl ? nl : t->end;
        const char *hash = memchr(t->p, '#', (size_t)(stop - t->p));
        const char *ls = tsl_skip_blanks(t->p, hash ? hash : stop);
        const char *le = hash ? hash : stop;
        t->p = nl ? nl + 1 : t->end;
        t->line++;
        while (le > ls && tsl_is_blank(le[-1]))
            le--;
        if (ls < le) {
            *s = ls;
            *e = le;
            return true;
        }
    }
    return false;
}

/* Reads up to max numbers from the line; returns the count of tokens or
 * SIZE_MAX when one is not a number. dots[k] tells whether number k was
 * written with a '.', for colours. */
static size_t off_numbers(const char *p, const char *e, double *v, bool *dots, size_t max)
{
    size_t n = 0;
    for (;;) {
        p = tsl_skip_blanks(p, e);
        if (p == e)
            return n;
        const char *tok = p;
        double x;
        if (!tsl_scan_double(&p, e, &x) || (p < e && !tsl_is_blank(*p)))
            return SIZE_MAX;
        if (n < max) {
            v[n] = x;
            dots[n] = memchr(tok, '.', (size_t)(p - tok)) != NULL;
        }
        n++;
    }
}

static uint8_t off_colour(double v, bool fraction)
{
    if (fraction && v <= 1.0)
        v *= 255.0;
    if (!(v > 0.0))
        return 0;
    if (v >= 255.0)
        return 255;
    return (uint8_t)(v + 0.5);
}

tessel_status tsl_parse_off(const uint8_t *data, size_t size, const char *name,
                            int want_faces, tsl_builder *b, tessel_diag *diag)
{
    off_text t = {(const char *)data, (const char *)data + size, 0};
    const char *s, *e;
    if (!off_next_line(&t, &s, &e)) {
        tsl_diag_set(diag, name, t.line, 0, 0, "empty OFF file");
        return TESSEL_ERR_PARSE;
    }
    /* Keyword: [C][N]OFF or [N][C]OFF. */
    const char *k = s;
    bool has_c = false, has_n = false;
    while (k < e && (*k == 'C' || *k == 'N')) {
        if (*k == 'C')
            has_c = true;
        else
            has_n = true;
        k++;
    }
    if ((size_t)(e - k) < 3 || memcmp(k, "OFF", 3) != 0 || (k + 3 < e && !tsl_is_blank(k[3]))) {
        const char *te = s;
        while (te < e && !tsl_is_blank(*te))
            te++;
        bool variant = (size_t)(te - s) >= 3 && memcmp(te - 3, "OFF", 3) == 0;
        tsl_diag_set(diag, name, t.line, 0, 0,
                     variant ? "OFF variant '%.*s' is not supported (OFF, COFF, NOFF and "
                               "NCOFF are)"
                             : "not an OFF file: expected 'OFF', found '%.*s'",
                     (int)(te - s > 20 ? 20 : te - s), s);
        return variant ? TESSEL_ERR_UNSUPPORTED : TESSEL_ERR_PARSE;
    }
    /* Counts: on the keyword line or the next one. */
    const char *cs = tsl_skip_blanks(k + 3, e), *ce = e;
    if (cs == ce && !off_next_line(&t, &cs, &ce)) {
        tsl_diag_set(diag, name, t.line, 0, 0, "OFF file ends before its counts");
        return TESSEL_ERR_PARSE;
    }
    uint64_t nv = 0, nf = 0, ne = 0;
    const char *p = cs;
    bool ok = tsl_scan_u64(&p, ce, &nv) && tsl_scan_u64(&p, ce, &nf);
    if (ok && tsl_skip_blanks(p, ce) != ce)
        ok = tsl_scan_u64(&p, ce, &ne);
    if (!ok || tsl_skip_blanks(p, ce) != ce) {
        tsl_diag_set(diag, name, t.line, 0, 0,
                     "expected the counts 'vertices faces edges' as integers");
        return TESSEL_ERR_PARSE;
    }
    uint64_t counts_line = t.line;
    if (nv > b->max_points || (want_faces && nf > b->max_faces)) {
        tsl_diag_set(diag, name, counts_line, 0, 0,
                     "OFF announces %llu vertices and %llu faces, above the limits (%llu, "
                     "%llu)",
                     (unsigned long long)nv, (unsigned long long)nf,
                     (unsigned long long)b->max_points, (unsigned long long)b->max_faces);
        return TESSEL_ERR_LIMIT;
    }
    tessel_status st = tsl_builder_attributes(b, has_n, has_c);
    /* A vertex line takes at least 6 bytes ("0 0 0\n"): a lying count
     * cannot make us reserve more than the file could hold. */
    size_t room = (size_t)(t.end - t.p) / 6 + 1;
    if (st == TESSEL_OK)
        st = tsl_builder_reserve(b, nv < room ? (size_t)nv : room, 0);
    if (st != TESSEL_OK) {
        tsl_diag_set(diag, name, counts_line, 0, 0, "%s", tessel_status_str(st));
        return st;
    }

    size_t base = b->count;
    size_t want = 3 + (has_n ? 3 : 0);
    for (uint64_t i = 0; i < nv; i++) {
        if (!off_next_line(&t, &s, &e)) {
            tsl_diag_set(diag, name, t.line, 0, 0,
                         "OFF announces %llu vertices (line %llu), the file ends after %llu",
                         (unsigned long long)nv, (unsigned long long)counts_line,
                         (unsigned long long)i);
            return TESSEL_ERR_PARSE;
        }
        double v[10];
        bool dots[10];
        size_t n = off_numbers(s, e, v, dots, 10);
        bool count_ok = has_c ? (n == want + 3 || n == want + 4) : n == want;
        if (n == SIZE_MAX || !count_ok) {
            if (n == SIZE_MAX)
                tsl_diag_set(diag, name, t.line, 0, 0, "bad number in OFF vertex %llu",
                             (unsigned long long)i);
            else
                tsl_diag_set(diag, name, t.line, 0, 0,
                             "expected %zu%s numbers for an OFF vertex, got %zu", want,
                             has_c ? " + 3 or 4 colour" : "", n);
            return TESSEL_ERR_PARSE;
        }
        float normal[3] = {(float)v[3], (float)v[4], (float)v[5]};
        uint8_t rgb[3] = {0, 0, 0};
        if (has_c) {
            bool fraction = dots[want] || dots[want + 1] || dots[want + 2];
            for (int c = 0; c < 3; c++)
                rgb[c] = off_colour(v[want + (size_t)c], fraction);
        }
        st = tsl_builder_point(b, v, has_n ? normal : NULL, has_c ? rgb : NULL);
        if (st != TESSEL_OK) {
            tsl_diag_set(diag, name, t.line, 0, 0, "OFF vertex %llu: %s",
                         (unsigned long long)i, tessel_status_str(st));
            return st;
        }
    }
    if (!want_faces)
        return TESSEL_OK;

    uint32_t *poly = NULL;
    size_t poly_cap = 0;
    st = TESSEL_OK;
    for (uint64_t f = 0; f < nf && st == TESSEL_OK; f++) {
        if (!off_next_line(&t, &s, &e)) {
            tsl_diag_set(diag, name, t.line, 0, 0,
                         "OFF announces %llu faces (line %llu), the file ends after %llu",
                         (unsigned long long)nf, (unsigned long long)counts_line,
                         (unsigned long long)f);
            st = TESSEL_ERR_PARSE;
            break;
        }
        p = s;
        uint64_t n;
        if (!tsl_scan_u64(&p, e, &n) || (p < e && !tsl_is_blank(*p))) {
            tsl_diag_set(diag, name, t.line, 0, 0,
                         "expected a face: a vertex count and the vertex indices");
            st = TESSEL_ERR_PARSE;
            break;
        }
        for (uint64_t j = 0; j < n; j++) {
            uint64_t idx;
            const char *q = tsl_skip_blanks(p, e);
            if (q == e) {
                tsl_diag_set(diag, name, t.line, 0, 0,
                             "face announces %llu vertices, the line has %llu",
                             (unsigned long long)n, (unsigned long long)j);
                st = TESSEL_ERR_PARSE;
                break;
            }
            if (!tsl_scan_u64(&q, e, &idx) || (q < e && !tsl_is_blank(*q))) {
                tsl_diag_set(diag, name, t.line, 0, 0, "bad vertex index in face %llu",
                             (unsigned long long)f);
                st = TESSEL_ERR_PARSE;
                break;
            }
            if (idx >= nv) {
                tsl_diag_set(diag, name, t.line, 0, 0,
                             "face index %llu out of range (%llu vertices)",
                             (unsigned long long)idx, (unsigned long long)nv);
                st = TESSEL_ERR_PARSE;
                break;
            }
            p = q;
            st = tsl_grow((void **)&poly, &poly_cap, (size_t)j + 1, sizeof *poly);
            if (st != TESSEL_OK)
                break;
            poly[j] = (uint32_t)(base + idx);
        }
        if (st == TESSEL_OK)
            st = tsl_builder_polygon(b, poly, (size_t)n);
        if (st == TESSEL_ERR_LIMIT)
            tsl_diag_set(diag, name, t.line, 0, 0, "more triangles than the limit of %llu",
                         (unsigned long long)b->max_faces);
        else if (st == TESSEL_ERR_NOMEM)
            tsl_diag_set(diag, name, t.line, 0, 0, "%s", tessel_status_str(st));
    }
    free(poly);
    return st;
}

/* ---- writer ---- */

static tessel_status off_begin(FILE *fp, const tsl_vertices *v, size_t vertex_count,
                               size_t face_count, const tessel_write_params *params)
{
    bool n = tsl_writes_normals(v, params), c = tsl_writes_rgb(v, params);
    if (fprintf(fp, "%s%sOFF\n%zu %zu 0\n", c ? "C" : "", n ? "N" : "", vertex_count,
                face_count) < 0)
        return TESSEL_ERR_IO;
    return TESSEL_OK;
}

static tessel_status off_vertices(FILE *fp, const tsl_vertices *v, const uint32_t *subset,
                                  size_t n, const tessel_write_params *params)
{
    bool wn = tsl_writes_normals(v, params), wc = tsl_writes_rgb(v, params);
    char buf[256];
    for (size_t i = 0; i < n; i++) {
        size_t j = subset ? subset[i] : i;
        int len = 0;
        for (int k = 0; k < 3; k++) {
            if (k)
                buf[len++] = ' ';
            len += tsl_format_coord(buf + len, v->offset[k], v->xyz[3 * j + k]);
        }
        if (wn)
            len += snprintf(buf + len, sizeof buf - (size_t)len, " %.9g %.9g %.9g",
                            (double)v->normals[3 * j], (double)v->normals[3 * j + 1],
                            (double)v->normals[3 * j + 2]);
        if (wc)
            len += snprintf(buf + len, sizeof buf - (size_t)len, " %u %u %u 255",
                            v->rgb[3 * j], v->rgb[3 * j + 1], v->rgb[3 * j + 2]);
        buf[len++] = '\n';
        if (fwrite(buf, 1, (size_t)len, fp) != (size_t)len)
            return TESSEL_ERR_IO;
    }
    return TESSEL_OK;
}

static tessel_status off_faces(FILE *fp, const tsl_vertices *v, const uint32_t *tris,
                               const uint32_t *orig, size_t n,
                               const tessel_write_params *params)
{
    (void)v;
    (void)orig;
    (void)params;
    for (size_t t = 0; t < n; t++) {
        if (fprintf(fp, "3 %lu %lu %lu\n", (unsigned long)tris[3 * t],
                    (unsigned long)tris[3 * t + 1], (unsigned long)tris[3 * t + 2]) < 0)
            return TESSEL_ERR_IO;
    }
    return TESSEL_OK;
}

const tsl_format_writer tsl_writer_off = {TESSEL_FORMAT_OFF, off_begin, off_vertices,
                                          off_faces, NULL};
