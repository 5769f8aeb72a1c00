/* Wavefront OBJ, read and written: the geometry subset of the format
 * ("Object Files (.obj)", Wavefront Advanced Visualizer manual, appendix B1):
 * v, vn and f statements.
 *
 * Reading takes two passes over the text. The first only counts: vertices,
 * normals, vertices carrying a colour ("v x y z r g b", a common
 * extension), and whether faces reference normals; that decides which
 * attributes the cloud gets and bounds every index before any is used. The
 * second parses. Faces accept the v, v/vt, v//vn and v/vt/vn forms and
 * negative (relative) indices; polygons become fans. Normals are attached to
 * vertices one to one when there are as many vn as v lines, otherwise
 * through the face references (the first reference of a vertex wins).
 * Texture coordinates, groups, materials, smoothing and curves are ignored.
 * Colours are fractions in [0, 1] unless a vertex has a component above 1,
 * which then reads as 0-255. */
#include "io/io.h"

#include <stdlib.h>
#include <string.h>

typedef struct obj_text {
    const char *p, *end;
    uint64_t line;
} obj_text;

/* Next line as [*s, *e), cut at a '#' comment; false at the end. */
static bool obj_next_line(obj_text *t, const char **s, const char **e)
{
    if (t->p >= t->end)
        return false;
    const char *nl = memchr(t->p, '\n', (size_t)(t->end - t->p));
    const char *stop = nl ? nl : t->end;
    const char *hash = memchr(t->p, '#', (size_t)(stop - t->p));
    *s = t->p;
    *e = hash ? hash : stop;
    t->p = nl ? nl + 1 : t->end;
    t->line++;
    return true;
}

/* The statement keyword of a line: "v", "vn", "f", ...; 0 for "none". */
enum { KW_OTHER, KW_V, KW_VN, KW_F };

static int keyword(const char **s, const char *e)
{
    const char *p = tsl_skip_blanks(*s, e);
    const char *k = p;
    while (p < e && !tsl_is_blank(*p))
        p++;
    size_t len = (size_t)(p - k);
    *s = p;
    if (len == 1 && k[0] == 'v')
        return KW_V;
    if (len == 2 && k[0] == 'v' && k[1] == 'n')
        return KW_VN;
    if (len == 1 && k[0] == 'f')
        return KW_F;
    return KW_OTHER;
}

static size_t count_tokens(const char *p, const char *e)
{
    size_t n = 0;
    for (;;) {
        p = tsl_skip_blanks(p, e);
        if (p == e)
            return n;
        while (p < e && !tsl_is_blank(*p))
            p++;
        n++;
    }
}

/* Reads up to max numbers; returns how many tokens the line holds, or
 * SIZE_MAX (with *bad at the token) when one is not a number. */
static size_t read_numbers(const char *p, const char *e, double *v, size_t max,
                           const char **bad)
{
    size_t n = 0;
    for (;;) {
        p = tsl_skip_blanks(p, e);
        if (p == e)
            return n;
        const char *tok = p;
        double x;
        if (!tsl_scan_double(&p, e, &x) || (p < e && !tsl_is_blank(*p))) {
            *bad = tok;
            return SIZE_MAX;
        }
        if (n < max)
            v[n] = x;
        n++;
    }
}

typedef struct obj_counts {
    size_t v, vn, v_rgb;
    bool face_normals;
} obj_counts;

static void obj_count(const char *data, size_t size, obj_counts *c)
{
    obj_text t = {data, data + size, 0};
    const char *s, *e;
    memset(c, 0, sizeof *c);
    while (obj_next_line(&t, &s, &e)) {
        int kw = keyword(&s, e);
        if (kw == KW_V) {
            c->v++;
            if (count_tokens(s, e) == 6)
                c->v_rgb++;
        } else if (kw == KW_VN) {
            c->vn++;
        } else if (kw == KW_F && !c->face_normals) {
            /* a second '/' within one vertex reference: v//vn or v/vt/vn */
            int slashes = 0;
            for (const char *q = s; q < e && !c->face_normals; q++) {
                if (*q == '/')
                    c->face_normals = ++slashes == 2;
                else if (tsl_is_blank(*q))
                    slashes = 0;
            }
        }
    }
}

static uint8_t obj_colour(double v, bool bytes)
{
    if (!bytes)
        v *= 255.0;
    if (!(v > 0.0))
        return 0;
    if (v >= 255.0)
        return 255;
    return (uint8_t)(v + 0.5);
}

/* Resolves an OBJ index (1-based, or negative relative to the n_so_far
 * elements defined before this line) against total elements. */
static bool obj_resolve(int64_t raw, size_t n_so_far, size_t total, uint32_t *out)
{
    int64_t i;
    if (raw > 0)
        i = raw - 1;
    else if (raw < 0)
        i = (int64_t)n_so_far + raw;
    else
        return false;
    if (i < 0 || (uint64_t)i >= total)
        return false;
    *out = (uint32_t)i;
    return true;
}

typedef struct obj_state {
    const char *name;
    tessel_diag *diag;
    tsl_builder *b;
    obj_counts c;
    bool normals_by_face;   /* vn attached through the f references */
    size_t v_seen, vn_seen;
    float *vn;              /* c.vn*3 */
    uint32_t *vn_of_v;      /* per vertex: its vn, TESSEL_NONE if none yet */
    uint32_t *poly;
    size_t poly_cap;
} obj_state;

static tessel_status obj_face(obj_state *o, const char *p, const char *e, uint64_t line,
                              int want_faces)
{
    size_t n = 0;
    for (;;) {
        p = tsl_skip_blanks(p, e);
        if (p == e)
            break;
        const char *tok = p;
        int64_t raw[3] = {0, 0, 0};
        bool given[3] = {false, false, false};
        bool ok = true;
        for (int part = 0; part < 3 && ok; part++) {
            if (part > 0) {
                if (p == e || *p != '/')
                    break;
                p++;
                if (part == 1 && p < e && *p == '/')
                    continue;  /* empty texture slot: v//vn */
            }
            ok = p < e && !tsl_is_blank(*p) && tsl_scan_i64(&p, e, &raw[part]);
            given[part] = ok;
        }
        if (!ok || !given[0] || (p < e && !tsl_is_blank(*p))) {
            const char *te = tok;
            while (te < e && !tsl_is_blank(*te))
                te++;
            tsl_diag_set(o->diag, o->name, line, 0, 0,
                         "bad face vertex '%.*s' (expected v, v/vt, v//vn or v/vt/vn)",
                         (int)(te - tok > 40 ? 40 : te - tok), tok);
            return TESSEL_ERR_PARSE;
        }
        uint32_t vi, ni = TESSEL_NONE;
        if (!obj_resolve(raw[0], o->v_seen, o->c.v, &vi)) {
            tsl_diag_set(o->diag, o->name, line, 0, 0,
                         "face index %lld out of range (%zu vertices%s)",
                         (long long)raw[0], raw[0] < 0 ? o->v_seen : o->c.v,
                         raw[0] < 0 ? " so far" : "");
            return TESSEL_ERR_PARSE;
        }
        if (given[2] && !obj_resolve(raw[2], o->vn_seen, o->c.vn, &ni)) {
            tsl_diag_set(o->diag, o->name, line, 0, 0,
                         "face normal index %lld out of range (%zu normals%s)",
                         (long long)raw[2], raw[2] < 0 ? o->vn_seen : o->c.vn,
                         raw[2] < 0 ? " so far" : "");
            return TESSEL_ERR_PARSE;
        }
        if (o->normals_by_face && ni != TESSEL_NONE && o->vn_of_v[vi] == TESSEL_NONE)
            o->vn_of_v[vi] = ni;
        if (want_faces) {
            tessel_status st = tsl_grow((void **)&o->poly, &o->poly_cap, n + 1,
                                        sizeof *o->poly);
            if (st != TESSEL_OK)
                return st;
            o->poly[n] = vi;
        }
        n++;
    }
    if (!want_faces)
        return TESSEL_OK;
    tessel_status st = tsl_builder_polygon(o->b, o->poly, n);
    if (st != TESSEL_OK)
        tsl_diag_set(o->diag, o->name, line, 0, 0, "face: %s", tessel_status_str(st));
    return st;
}

static tessel_status obj_parse(obj_state *o, const char *data, size_t size, int want_faces)
{
    tsl_builder *b = o->b;
    obj_text t = {data, data + size, 0};
    const char *s, *e;
    bool has_normals = o->c.vn > 0 && (o->c.vn == o->c.v || o->c.face_normals);
    bool has_rgb = o->c.v > 0 && o->c.v_rgb == o->c.v;
    o->normals_by_face = has_normals && o->c.vn != o->c.v;
    tessel_status st = tsl_builder_attributes(b, has_normals, has_rgb);
    if (st == TESSEL_OK)
        st = tsl_builder_reserve(b, o->c.v, 0);
    if (st != TESSEL_OK) {
        tsl_diag_set(o->diag, o->name, 0, 0, 0, "cannot hold %zu OBJ vertices: %s", o->c.v,
                     tessel_status_str(st));
        return st;
    }
    if (has_normals) {
        o->vn = tsl_alloc_array(o->c.vn, 3 * sizeof(float));
        if (!o->vn)
            return TESSEL_ERR_NOMEM;
    }
    if (o->normals_by_face) {
        o->vn_of_v = tsl_alloc_array(o->c.v, sizeof(uint32_t));
        if (!o->vn_of_v)
            return TESSEL_ERR_NOMEM;
        for (size_t i = 0; i < o->c.v; i++)
            o->vn_of_v[i] = TESSEL_NONE;
    }
    size_t base = b->count;
    const float zero[3] = {0, 0, 0};
    while (obj_next_line(&t, &s, &e)) {
        int kw = keyword(&s, e);
        if (kw == KW_OTHER)
            continue;
        if (kw == KW_F) {
            if (!want_faces && !o->normals_by_face)
                continue;
            st = obj_face(o, s, e, t.line, want_faces);
            if (st != TESSEL_OK)
                return st;
            continue;
        }
        double v[6];
        const char *bad = NULL;
        size_t n = read_numbers(s, e, v, 6, &bad);
        if (n == SIZE_MAX) {
            const char *te = bad;
            while (te < e && !tsl_is_blank(*te))
                te++;
            tsl_diag_set(o->diag, o->name, t.line, 0, 0, "bad number '%.*s'",
                         (int)(te - bad > 40 ? 40 : te - bad), bad);
            return TESSEL_ERR_PARSE;
        }
        if (kw == KW_VN) {
            if (n != 3) {
                tsl_diag_set(o->diag, o->name, t.line, 0, 0,
                             "expected 3 numbers after 'vn', got %zu", n);
                return TESSEL_ERR_PARSE;
            }
            if (has_normals)
                for (int k = 0; k < 3; k++)
                    o->vn[3 * o->vn_seen + k] = (float)v[k];
            o->vn_seen++;
            continue;
        }
        if (n != 3 && n != 4 && n != 6) {
            tsl_diag_set(o->diag, o->name, t.line, 0, 0,
                         "expected 3, 4 (x y z w) or 6 (x y z r g b) numbers after 'v', "
                         "got %zu",
                         n);
            return TESSEL_ERR_PARSE;
        }
        uint8_t rgb[3] = {0, 0, 0};
        if (has_rgb) {
            bool bytes = v[3] > 1.0 || v[4] > 1.0 || v[5] > 1.0;
            for (int k = 0; k < 3; k++)
                rgb[k] = obj_colour(v[3 + k], bytes);
        }
        st = tsl_builder_point(b, v, has_normals ? zero : NULL, has_rgb ? rgb : NULL);
        if (st != TESSEL_OK) {
            tsl_diag_set(o->diag, o->name, t.line, 0, 0, "vertex %zu: %s", o->v_seen + 1,
                         tessel_status_str(st));
            return st;
        }
        o->v_seen++;
    }
    /* Normals go in now that every vn is known (they may follow the v). */
    if (has_normals) {
        for (size_t i = 0; i < o->c.v; i++) {
            size_t j = o->normals_by_face ? o->vn_of_v[i] : i;
            if (j != TESSEL_NONE)
                memcpy(b->normals + 3 * (base + i), o->vn + 3 * j, 3 * sizeof(float));
        }
    }
    return TESSEL_OK;
}

tessel_status tsl_parse_obj(const uint8_t *data, size_t size, const char *name,
                            int want_faces, tsl_builder *b, tessel_diag *diag)
{
    obj_state o;
    memset(&o, 0, sizeof o);
    o.name = name;
    o.diag = diag;
    o.b = b;
    obj_count((const char *)data, size, &o.c);
    if (o.c.v > b->max_points) {
        tsl_diag_set(diag, name, 0, 0, 0, "OBJ file has %zu vertices, above the limit of %llu",
                     o.c.v, (unsigned long long)b->max_points);
        return TESSEL_ERR_LIMIT;
    }
    tessel_status st = obj_parse(&o, (const char *)data, size, want_faces);
    free(o.vn);
    free(o.vn_of_v);
    free(o.poly);
    return st;
}

/* ---- writer ---- */

static tessel_status obj_begin(FILE *fp, const tsl_vertices *v, size_t vertex_count,
                               size_t face_count, const tessel_write_params *params)
{
    (void)v;
    (void)params;
    if (fprintf(fp, "# tessel %s: %zu vertices, %zu triangles\n", TESSEL_VERSION_STRING,
                vertex_count, face_count) < 0)
        return TESSEL_ERR_IO;
    return TESSEL_OK;
}

static tessel_status obj_vertices(FILE *fp, const tsl_vertices *v, const uint32_t *subset,
                                  size_t n, const tessel_write_params *params)
{
    bool wn = tsl_writes_normals(v, params), wc = tsl_writes_rgb(v, params);
    char buf[320];
    for (size_t i = 0; i < n; i++) {
        size_t j = subset ? subset[i] : i;
        int len = 0;
        buf[len++] = 'v';
        for (int k = 0; k < 3; k++) {
            buf[len++] = ' ';
            len += tsl_format_coord(buf + len, v->offset[k], v->xyz[3 * j + k]);
        }
        /* Fractions with 6 digits read back to the same byte. */
        if (wc)
            len += snprintf(buf + len, sizeof buf - (size_t)len, " %.6g %.6g %.6g",
                            v->rgb[3 * j] / 255.0, v->rgb[3 * j + 1] / 255.0,
                            v->rgb[3 * j + 2] / 255.0);
        if (wn)
            len += snprintf(buf + len, sizeof buf - (size_t)len, "\nvn %.9g %.9g %.9g",
                            (double)v->normals[3 * j], (double)v->normals[3 * j + 1],
                            (double)v->normals[3 * j + 2]);
        buf[len++] = '\n';
        if (fwrite(buf, 1, (size_t)len, fp) != (size_t)len)
            return TESSEL_ERR_IO;
    }
    return TESSEL_OK;
}

static tessel_status obj_faces(FILE *fp, const tsl_vertices *v, const uint32_t *tris,
                               const uint32_t *orig, size_t n,
                               const tessel_write_params *params)
{
    (void)v;
    (void)orig;
    (void)params;
    for (size_t t = 0; t < n; t++) {
        if (fprintf(fp, "f %lu %lu %lu\n", (unsigned long)tris[3 * t] + 1,
                    (unsigned long)tris[3 * t + 1] + 1, (unsigned long)tris[3 * t + 2] + 1) < 0)
            return TESSEL_ERR_IO;
    }
    return TESSEL_OK;
}

const tsl_format_writer tsl_writer_obj = {TESSEL_FORMAT_OBJ, obj_begin, obj_vertices,
                                          obj_faces, NULL};
