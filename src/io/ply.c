/* PLY (Turk 1994, "The PLY polygon file format"; the layout of Paul
 * Bourke's description): reader and writer.
 *
 * Reader: ascii, binary_little_endian and binary_big_endian; every scalar
 * type under both its old and its sized name; x/y/z of any type, optional
 * nx/ny/nz, colours as red/green/blue (also r/g/b and diffuse_*) in uchar,
 * ushort (>> 8) or float (0..1); faces from the "vertex_indices" or
 * "vertex_index" list, polygons split into fans; every other property and
 * element skipped, lists included. "comment organized W H" and
 * "comment viewpoint X Y Z" restore what tessel's writer stores.
 *
 * Hostile input: before anything is allocated, the bytes every announced
 * record needs at least (binary: its fixed part; ascii: two characters per
 * value) are checked against the bytes that follow the header; list counts
 * are checked against the bytes left; every read is bounds-checked; errors
 * give the line (ascii) or byte offset (binary).
 *
 * Writer: binary little-endian by default, ascii on request; coordinates as
 * float when the offset is 0 and as double (offset + xyz) otherwise, so a
 * file reads back to the same floats and offset; faces as a uchar count and
 * int indices. */
#include "io/io.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum ply_type { T_NONE = 0, T_I8, T_U8, T_I16, T_U16, T_I32, T_U32, T_F32, T_F64 };
static const unsigned type_size[] = {0, 1, 1, 2, 2, 4, 4, 4, 8};

enum ply_format { F_NONE = 0, F_ASCII, F_LE, F_BE };

enum ply_role { R_NONE = -1, R_X, R_Y, R_Z, R_NX, R_NY, R_NZ, R_R, R_G, R_B, R_COUNT };

/* Header sanity caps: real files have a handful of each. */
enum { MAX_ELEMENTS = 1024, MAX_PROPERTIES = 4096 };

typedef struct ply_prop {
    const char *name;
    size_t name_len;
    uint8_t type;        /* scalar type, or the item type of a list */
    uint8_t count_type;  /* list count type; T_NONE for scalars */
    int8_t role;         /* vertex role or R_NONE */
    uint8_t face_list;   /* the face element's index list */
    size_t offset;       /* byte offset in fixed-size binary records */
} ply_prop;

typedef struct ply_elem {
    const char *name;
    size_t name_len;
    uint64_t count;
    uint64_t line;       /* header line, for messages */
    ply_prop *props;
    size_t nprops, cap;
    size_t min_bytes;    /* least bytes one record takes */
    int fixed;           /* binary record size is min_bytes (no lists) */
    int is_vertex, is_face;
} ply_elem;

typedef struct ply_reader {
    const uint8_t *data;
    size_t size, pos;
    const char *name;
    tessel_diag *diag;
    int format;
    ply_elem *elems;
    size_t nelems;
    uint64_t line;            /* ascii: current line */
    uint64_t vertex_count;
    const ply_elem *vertex;
    int role_prop[R_COUNT];   /* property index of each vertex role or -1 */
    int has_normals, has_rgb;
    uint32_t *poly;           /* face index scratch */
    size_t poly_cap;
} ply_reader;

/* ---- small helpers ---- */

static bool tok_is(const char *s, size_t n, const char *word)
{
    return strlen(word) == n && memcmp(s, word, n) == 0;
}

static int parse_type(const char *s, size_t n)
{
    static const struct {
        const char *name;
        int type;
    } names[] = {
        {"char", T_I8},    {"int8", T_I8},     {"uchar", T_U8},   {"uint8", T_U8},
        {"short", T_I16},  {"int16", T_I16},   {"ushort", T_U16}, {"uint16", T_U16},
        {"int", T_I32},    {"int32", T_I32},   {"uint", T_U32},   {"uint32", T_U32},
        {"float", T_F32},  {"float32", T_F32}, {"double", T_F64}, {"float64", T_F64},
    };
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++)
        if (tok_is(s, n, names[i].name))
            return names[i].type;
    return T_NONE;
}

static int vertex_role(const char *s, size_t n)
{
    static const struct {
        const char *name;
        int role;
    } names[] = {
        {"x", R_X},           {"y", R_Y},          {"z", R_Z},
        {"nx", R_NX},         {"ny", R_NY},        {"nz", R_NZ},
        {"normal_x", R_NX},   {"normal_y", R_NY},  {"normal_z", R_NZ},
        {"red", R_R},         {"green", R_G},      {"blue", R_B},
        {"r", R_R},           {"g", R_G},          {"b", R_B},
        {"diffuse_red", R_R}, {"diffuse_green", R_G}, {"diffuse_blue", R_B},
    };
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++)
        if (tok_is(s, n, names[i].name))
            return names[i].role;
    return R_NONE;
}

/* Loads in the file's byte order; compilers turn these into plain or
 * byte-swapped loads. */
static inline uint16_t load16(const uint8_t *p, int big)
{
    return big ? (uint16_t)(p[0] << 8 | p[1]) : (uint16_t)(p[1] << 8 | p[0]);
}
static inline uint32_t load32(const uint8_t *p, int big)
{
    return big ? (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3]
               : (uint32_t)p[3] << 24 | (uint32_t)p[2] << 16 | (uint32_t)p[1] << 8 | p[0];
}
static inline uint64_t load64(const uint8_t *p, int big)
{
    uint64_t a = load32(p, big), b = load32(p + 4, big);
    return big ? a << 32 | b : b << 32 | a;
}

static inline double decode(const uint8_t *p, int type, int big)
{
    switch (type) {
    case T_I8: return (double)(int8_t)p[0];
    case T_U8: return (double)p[0];
    case T_I16: return (double)(int16_t)load16(p, big);
    case T_U16: return (double)load16(p, big);
    case T_I32: return (double)(int32_t)load32(p, big);
    case T_U32: return (double)load32(p, big);
    case T_F32: {
        uint32_t u = load32(p, big);
        float f;
        memcpy(&f, &u, sizeof f);
        return (double)f;
    }
    default: {
        uint64_t u = load64(p, big);
        double d;
        memcpy(&d, &u, sizeof d);
        return d;
    }
    }
}

/* A colour channel: 8-bit types as they are, 16-bit scaled down, floats
 * from [0, 1]; everything clamped to 0..255. */
static uint8_t color_u8(int type, double v)
{
    if (type == T_U16 || type == T_I16)
        v = floor(v / 256.0);
    else if (type == T_F32 || type == T_F64)
        v = floor(v * 255.0 + 0.5);
    if (!(v > 0.0))
        return 0;
    if (v >= 255.0)
        return 255;
    return (uint8_t)v;
}

static tessel_status fail_line(ply_reader *r, uint64_t line, tessel_status st,
                               const char *fmt, ...) TSL_PRINTF(4, 5);
static tessel_status fail_line(ply_reader *r, uint64_t line, tessel_status st,
                               const char *fmt, ...)
{
    char msg[400];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    tsl_diag_set(r->diag, r->name, line, 0, 0, "%s", msg);
    return st;
}

static tessel_status fail_at(ply_reader *r, size_t offset, tessel_status st,
                             const char *fmt, ...) TSL_PRINTF(4, 5);
static tessel_status fail_at(ply_reader *r, size_t offset, tessel_status st,
                             const char *fmt, ...)
{
    char msg[400];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    tsl_diag_set(r->diag, r->name, 0, 1, offset, "%s", msg);
    return st;
}

/* Data errors: line for ascii, byte offset for binary. */
static tessel_status fail_data(ply_reader *r, tessel_status st, const char *fmt, ...)
    TSL_PRINTF(3, 4);
static tessel_status fail_data(ply_reader *r, tessel_status st, const char *fmt, ...)
{
    char msg[400];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (r->format == F_ASCII)
        tsl_diag_set(r->diag, r->name, r->line, 0, 0, "%s", msg);
    else
        tsl_diag_set(r->diag, r->name, 0, 1, r->pos, "%s", msg);
    return st;
}

/* Builder failures carry no position of their own. */
static tessel_status fail_builder(ply_reader *r, tessel_status st)
{
    if (st == TESSEL_ERR_LIMIT)
        return fail_data(r, st, "more points or faces than the read limits allow");
    return fail_data(r, st, "%s", tessel_status_str(st));
}

/* ---- header ---- */

/* Splits one header line into at most 8 blank-separated tokens. */
typedef struct line_tokens {
    const char *s[8];
    size_t n[8];
    size_t count;
} line_tokens;

static void tokenize(const char *s, const char *end, line_tokens *t)
{
    t->count = 0;
    while (s < end && t->count < 8) {
        while (s < end && (*s == ' ' || *s == '\t'))
            s++;
        if (s >= end)
            break;
        const char *b = s;
        while (s < end && *s != ' ' && *s != '\t')
            s++;
        t->s[t->count] = b;
        t->n[t->count] = (size_t)(s - b);
        t->count++;
    }
}

static bool tok_u64(const line_tokens *t, size_t i, uint64_t *out)
{
    const char *p = t->s[i];
    return tsl_scan_u64(&p, t->s[i] + t->n[i], out) && p == t->s[i] + t->n[i];
}

static bool tok_double(const line_tokens *t, size_t i, double *out)
{
    const char *p = t->s[i];
    return tsl_scan_double(&p, t->s[i] + t->n[i], out) && p == t->s[i] + t->n[i];
}

static tessel_status add_prop(ply_reader *r, ply_elem *e, const ply_prop *p, uint64_t line)
{
    if (e->nprops == MAX_PROPERTIES)
        return fail_line(r, line, TESSEL_ERR_LIMIT, "more than %d properties in element '%.*s'",
                         MAX_PROPERTIES, (int)e->name_len, e->name);
    if (e->nprops == e->cap) {
        void *ptr = e->props;
        if (tsl_grow(&ptr, &e->cap, e->nprops + 1, sizeof(ply_prop)) != TESSEL_OK)
            return TESSEL_ERR_NOMEM;
        e->props = ptr;
    }
    e->props[e->nprops++] = *p;
    return TESSEL_OK;
}

static tessel_status parse_header(ply_reader *r, tsl_builder *b, bool *organized,
                                  uint64_t *org_w, uint64_t *org_h, uint64_t *org_line)
{
    const char *text = (const char *)r->data;
    size_t pos = 0, cap = 0;
    uint64_t line = 0;
    bool ended = false;
    *organized = false;
    while (pos < r->size) {
        const char *nl = memchr(text + pos, '\n', r->size - pos);
        if (!nl)
            break;
        const char *s = text + pos, *e = nl;
        if (e > s && e[-1] == '\r')
            e--;
        line++;
        pos = (size_t)(nl - text) + 1;
        line_tokens t;
        tokenize(s, e, &t);
        if (line == 1) {
            if (t.count != 1 || !tok_is(t.s[0], t.n[0], "ply"))
                return fail_line(r, 1, TESSEL_ERR_PARSE, "not a PLY file (no 'ply' first line)");
            continue;
        }
        if (t.count == 0)
            continue;
        if (tok_is(t.s[0], t.n[0], "end_header")) {
            ended = true;
            break;
        }
        if (tok_is(t.s[0], t.n[0], "format")) {
            if (t.count < 2)
                return fail_line(r, line, TESSEL_ERR_PARSE, "format line without a format");
            if (tok_is(t.s[1], t.n[1], "ascii"))
                r->format = F_ASCII;
            else if (tok_is(t.s[1], t.n[1], "binary_little_endian"))
                r->format = F_LE;
            else if (tok_is(t.s[1], t.n[1], "binary_big_endian"))
                r->format = F_BE;
            else
                return fail_line(r, line, TESSEL_ERR_UNSUPPORTED, "unknown PLY format '%.*s'",
                                 (int)(t.n[1] > 64 ? 64 : t.n[1]), t.s[1]);
        } else if (tok_is(t.s[0], t.n[0], "comment")) {
            if (t.count >= 4 && tok_is(t.s[1], t.n[1], "organized")) {
                if (!tok_u64(&t, 2, org_w) || !tok_u64(&t, 3, org_h))
                    return fail_line(r, line, TESSEL_ERR_PARSE,
                                     "bad 'comment organized W H' line");
                *organized = true;
                *org_line = line;
            } else if (t.count >= 5 && tok_is(t.s[1], t.n[1], "viewpoint")) {
                double v[3];
                if (!tok_double(&t, 2, &v[0]) || !tok_double(&t, 3, &v[1]) ||
                    !tok_double(&t, 4, &v[2]) || !isfinite(v[0]) || !isfinite(v[1]) ||
                    !isfinite(v[2]))
                    return fail_line(r, line, TESSEL_ERR_PARSE,
                                     "bad 'comment viewpoint X Y Z' line");
                memcpy(b->viewpoint, v, sizeof v);
                b->has_viewpoint = 1;
            }
        } else if (tok_is(t.s[0], t.n[0], "obj_info")) {
            /* free text */
        } else if (tok_is(t.s[0], t.n[0], "element")) {
            if (t.count < 3)
                return fail_line(r, line, TESSEL_ERR_PARSE, "element line needs a name and a count");
            uint64_t count;
            if (!tok_u64(&t, 2, &count))
                return fail_line(r, line, TESSEL_ERR_PARSE, "bad count '%.*s' for element '%.*s'",
                                 (int)(t.n[2] > 32 ? 32 : t.n[2]), t.s[2],
                                 (int)(t.n[1] > 64 ? 64 : t.n[1]), t.s[1]);
            if (r->nelems == MAX_ELEMENTS)
                return fail_line(r, line, TESSEL_ERR_LIMIT, "more than %d elements",
                                 MAX_ELEMENTS);
            if (r->nelems == cap) {
                void *ptr = r->elems;
                if (tsl_grow(&ptr, &cap, r->nelems + 1, sizeof(ply_elem)) != TESSEL_OK)
                    return TESSEL_ERR_NOMEM;
                r->elems = ptr;
            }
            ply_elem *el = &r->elems[r->nelems++];
            memset(el, 0, sizeof *el);
            el->name = t.s[1];
            el->name_len = t.n[1];
            el->count = count;
            el->line = line;
            el->is_vertex = tok_is(t.s[1], t.n[1], "vertex");
            el->is_face = tok_is(t.s[1], t.n[1], "face");
        } else if (tok_is(t.s[0], t.n[0], "property")) {
            if (r->nelems == 0)
                return fail_line(r, line, TESSEL_ERR_PARSE, "property before any element");
            ply_elem *el = &r->elems[r->nelems - 1];
            ply_prop p;
            memset(&p, 0, sizeof p);
            p.role = R_NONE;
            if (t.count >= 2 && tok_is(t.s[1], t.n[1], "list")) {
                if (t.count < 5)
                    return fail_line(r, line, TESSEL_ERR_PARSE,
                                     "list property needs a count type, an item type and a name");
                p.count_type = (uint8_t)parse_type(t.s[2], t.n[2]);
                p.type = (uint8_t)parse_type(t.s[3], t.n[3]);
                size_t bad = p.count_type == T_NONE ? 2 : 3;
                if (p.count_type == T_NONE || p.type == T_NONE)
                    return fail_line(r, line, TESSEL_ERR_PARSE, "unknown property type '%.*s'",
                                     (int)(t.n[bad] > 32 ? 32 : t.n[bad]), t.s[bad]);
                if (p.count_type == T_F32 || p.count_type == T_F64)
                    return fail_line(r, line, TESSEL_ERR_PARSE,
                                     "list count type must be an integer type");
                p.name = t.s[4];
                p.name_len = t.n[4];
                p.face_list = el->is_face && (tok_is(p.name, p.name_len, "vertex_indices") ||
                                              tok_is(p.name, p.name_len, "vertex_index"));
            } else {
                if (t.count < 3)
                    return fail_line(r, line, TESSEL_ERR_PARSE, "property needs a type and a name");
                p.type = (uint8_t)parse_type(t.s[1], t.n[1]);
                if (p.type == T_NONE)
                    return fail_line(r, line, TESSEL_ERR_PARSE, "unknown property type '%.*s'",
                                     (int)(t.n[1] > 32 ? 32 : t.n[1]), t.s[1]);
                p.name = t.s[2];
                p.name_len = t.n[2];
                if (el->is_vertex)
                    p.role = (int8_t)vertex_role(p.name, p.name_len);
            }
            tessel_status st = add_prop(r, el, &p, line);
            if (st != TESSEL_OK)
                return st;
        } else if (t.s[0][0] == '-' || t.s[0][0] == '+' || t.s[0][0] == '.' ||
                   (t.s[0][0] >= '0' && t.s[0][0] <= '9')) {
            return fail_line(r, line, TESSEL_ERR_PARSE,
                             "header has no end_header line (line %llu looks like data)",
                             (unsigned long long)line);
        } else {
            return fail_line(r, line, TESSEL_ERR_PARSE, "unknown header keyword '%.*s'",
                             (int)(t.n[0] > 32 ? 32 : t.n[0]), t.s[0]);
        }
    }
    if (!ended)
        return fail_line(r, line ? line : 1, TESSEL_ERR_PARSE,
                         "header has no end_header line");
    if (r->format == F_NONE)
        return fail_line(r, line, TESSEL_ERR_PARSE, "header has no format line");
    r->pos = pos;
    r->line = line + 1;
    return TESSEL_OK;
}

/* Checks the vertex layout, the announced counts against the limits and
 * the bytes that follow, and sizes the builder. */
static tessel_status check_layout(ply_reader *r, tsl_builder *b, int want_faces,
                                  bool organized, uint64_t w, uint64_t h, uint64_t org_line,
                                  bool reserve)
{
    for (int k = 0; k < R_COUNT; k++)
        r->role_prop[k] = -1;
    uint64_t faces = 0;
    for (size_t i = 0; i < r->nelems; i++) {
        ply_elem *e = &r->elems[i];
        if (e->is_vertex) {
            if (r->vertex)
                return fail_line(r, e->line, TESSEL_ERR_PARSE, "second vertex element");
            r->vertex = e;
            r->vertex_count = e->count;
            for (size_t k = 0; k < e->nprops; k++) {
                const ply_prop *p = &e->props[k];
                if (p->role == R_NONE || r->role_prop[p->role] >= 0)
                    continue;
                if (p->count_type != T_NONE)
                    continue; /* a list named x: not a coordinate */
                r->role_prop[p->role] = (int)k;
            }
        }
        if (e->is_face)
            faces += e->count;
        /* Least bytes per record. */
        size_t min = 0, off = 0;
        e->fixed = 1;
        for (size_t k = 0; k < e->nprops; k++) {
            ply_prop *p = &e->props[k];
            p->offset = off;
            if (r->format == F_ASCII) {
                min += 2;
            } else if (p->count_type != T_NONE) {
                min += type_size[p->count_type];
                e->fixed = 0;
            } else {
                min += type_size[p->type];
                off += type_size[p->type];
            }
        }
        e->min_bytes = min;
    }
    if (!r->vertex)
        return fail_line(r, 1, TESSEL_ERR_PARSE, "no vertex element");
    static const char *const axis[3] = {"x", "y", "z"};
    for (int k = 0; k < 3; k++)
        if (r->role_prop[k] < 0)
            return fail_line(r, r->vertex->line, TESSEL_ERR_PARSE,
                             "vertex element has no '%s' property", axis[k]);
    r->has_normals = r->role_prop[R_NX] >= 0 && r->role_prop[R_NY] >= 0 &&
                     r->role_prop[R_NZ] >= 0;
    r->has_rgb = r->role_prop[R_R] >= 0 && r->role_prop[R_G] >= 0 && r->role_prop[R_B] >= 0;
    if (r->vertex_count > b->max_points)
        return fail_line(r, r->vertex->line, TESSEL_ERR_LIMIT,
                         "header announces %llu vertices, more than the limit of %llu",
                         (unsigned long long)r->vertex_count,
                         (unsigned long long)b->max_points);
    if (want_faces && faces > b->max_faces)
        return fail_line(r, 1, TESSEL_ERR_LIMIT,
                         "header announces %llu faces, more than the limit of %llu",
                         (unsigned long long)faces, (unsigned long long)b->max_faces);
    if (organized) {
        if (w == 0 || h == 0 || w > UINT32_MAX || h > UINT32_MAX ||
            w * h != r->vertex_count) /* w, h < 2^32: no overflow */
            return fail_line(r, org_line, TESSEL_ERR_PARSE,
                             "comment organized %llu %llu does not match the %llu vertices",
                             (unsigned long long)w, (unsigned long long)h,
                             (unsigned long long)r->vertex_count);
        b->width = (uint32_t)w;
        b->height = (uint32_t)h;
    }
    /* Every announced record must fit in what follows the header: a lying
     * count fails here, before any allocation. (ascii: the last value may
     * lack its separator.) */
    size_t avail = r->size - r->pos;
    uint64_t need = 0;
    for (size_t i = 0; i < r->nelems; i++) {
        const ply_elem *e = &r->elems[i];
        if (e->min_bytes == 0)
            continue;
        if (e->count > (UINT64_MAX - need) / e->min_bytes) {
            need = UINT64_MAX;
            break;
        }
        need += e->count * e->min_bytes;
    }
    uint64_t slack = r->format == F_ASCII ? 1 : 0;
    if (need > (uint64_t)avail + slack) {
        const ply_elem *e = r->vertex;
        char what[96];
        snprintf(what, sizeof what, "%llu vertices", (unsigned long long)e->count);
        for (size_t i = 0; i < r->nelems; i++)
            if (r->elems[i].count && r->elems[i].min_bytes &&
                r->elems[i].count > (uint64_t)avail / r->elems[i].min_bytes) {
                e = &r->elems[i];
                if (e == r->vertex)
                    break;
                snprintf(what, sizeof what, "%llu '%.*s' records",
                         (unsigned long long)e->count, (int)(e->name_len > 32 ? 32 : e->name_len),
                         e->name);
                break;
            }
        if (r->format == F_ASCII)
            return fail_line(r, r->line, TESSEL_ERR_PARSE,
                             "header announces %s but only %llu bytes of data follow "
                             "(truncated file or wrong count)",
                             what, (unsigned long long)avail);
        return fail_at(r, r->pos, TESSEL_ERR_PARSE,
                       "header announces %s needing %s%llu bytes but only %llu bytes follow "
                       "(truncated file or wrong count)",
                       what, need == UINT64_MAX ? "more than " : "",
                       (unsigned long long)(need == UINT64_MAX ? UINT64_MAX : need),
                       (unsigned long long)avail);
    }
    tessel_status st = tsl_builder_attributes(b, r->has_normals, r->has_rgb);
    if (st == TESSEL_OK && reserve)
        st = tsl_builder_reserve(b, (size_t)r->vertex_count,
                                 want_faces ? (size_t)faces : 0);
    if (st != TESSEL_OK)
        return fail_line(r, r->vertex->line, st, "cannot hold %llu vertices: %s",
                         (unsigned long long)r->vertex_count, tessel_status_str(st));
    return TESSEL_OK;
}

/* ---- vertex and face records ---- */

static tessel_status emit_vertex(ply_reader *r, tsl_builder *b, const double *val)
{
    double xyz[3] = {val[R_X], val[R_Y], val[R_Z]};
    float n[3];
    uint8_t c[3];
    if (r->has_normals)
        for (int k = 0; k < 3; k++)
            n[k] = (float)val[R_NX + k];
    if (r->has_rgb)
        for (int k = 0; k < 3; k++)
            c[k] = color_u8(r->vertex->props[r->role_prop[R_R + k]].type, val[R_R + k]);
    tessel_status st = tsl_builder_point(b, xyz, r->has_normals ? n : NULL,
                                         r->has_rgb ? c : NULL);
    return st == TESSEL_OK ? st : fail_builder(r, st);
}

static tessel_status poly_room(ply_reader *r, size_t n)
{
    if (n <= r->poly_cap)
        return TESSEL_OK;
    void *p = r->poly;
    tessel_status st = tsl_grow(&p, &r->poly_cap, n, sizeof(uint32_t));
    r->poly = p;
    return st;
}

/* Checks a face index value and stores it. */
static tessel_status face_index(ply_reader *r, uint64_t face, double v, size_t k)
{
    if (!(v >= 0.0) || v != floor(v) || v >= (double)r->vertex_count) {
        if (v != v)
            return fail_data(r, TESSEL_ERR_PARSE, "face %llu: vertex index is not a number",
                             (unsigned long long)face);
        return fail_data(r, TESSEL_ERR_PARSE,
                         "face %llu: vertex index %.0f out of range (%llu vertices)",
                         (unsigned long long)face, v, (unsigned long long)r->vertex_count);
    }
    r->poly[k] = (uint32_t)v;
    return TESSEL_OK;
}

/* left: bytes after the count. */
static tessel_status check_list_count(ply_reader *r, const ply_elem *e, uint64_t rec,
                                      double count, size_t item_bytes, size_t left,
                                      size_t *out)
{
    if (count < 0)
        return fail_data(r, TESSEL_ERR_PARSE, "%.*s %llu: negative list count %.0f",
                         (int)(e->name_len > 32 ? 32 : e->name_len), e->name,
                         (unsigned long long)rec, count);
    if (count != floor(count))
        return fail_data(r, TESSEL_ERR_PARSE, "%.*s %llu: list count %g is not an integer",
                         (int)(e->name_len > 32 ? 32 : e->name_len), e->name,
                         (unsigned long long)rec, count);
    if (count > (double)(left / item_bytes) + 1.0)
        return fail_data(r, TESSEL_ERR_PARSE,
                         "%.*s %llu: list of %.0f items but only %llu bytes left",
                         (int)(e->name_len > 32 ? 32 : e->name_len), e->name,
                         (unsigned long long)rec, count, (unsigned long long)left);
    *out = (size_t)count;
    return TESSEL_OK;
}

/* ---- binary ---- */

static tessel_status truncated(ply_reader *r, const ply_elem *e, uint64_t rec)
{
    return fail_data(r, TESSEL_ERR_PARSE, "data truncated in element '%.*s', record %llu of %llu",
                     (int)(e->name_len > 32 ? 32 : e->name_len), e->name,
                     (unsigned long long)rec, (unsigned long long)e->count);
}

/* count fixed-size vertex records of e from p on, all inside the data
 * (checked by the caller). */
static tessel_status fixed_vertices(ply_reader *r, tsl_builder *b, const ply_elem *e,
                                    const uint8_t *p, uint64_t count)
{
    const int big = r->format == F_BE;
    const ply_prop *px = &e->props[r->role_prop[R_X]], *py = &e->props[r->role_prop[R_Y]],
                   *pz = &e->props[r->role_prop[R_Z]];
    if (!r->has_normals && !r->has_rgb && px->type == py->type && px->type == pz->type &&
        (px->type == T_F32 || px->type == T_F64)) {
        /* The common case, x y z only, without the per-role loop. */
        const size_t ox = px->offset, oy = py->offset, oz = pz->offset;
        const int type = px->type;
        for (uint64_t i = 0; i < count; i++, p += e->min_bytes) {
            double xyz[3] = {decode(p + ox, type, big), decode(p + oy, type, big),
                             decode(p + oz, type, big)};
            tessel_status st = tsl_builder_point(b, xyz, NULL, NULL);
            if (st != TESSEL_OK)
                return fail_builder(r, st);
        }
        return TESSEL_OK;
    }
    double val[R_COUNT] = {0};
    int roles[R_COUNT], nroles = 0;
    for (int k = 0; k < R_COUNT; k++)
        if (r->role_prop[k] >= 0)
            roles[nroles++] = k;
    for (uint64_t i = 0; i < count; i++, p += e->min_bytes) {
        for (int k = 0; k < nroles; k++) {
            const ply_prop *pp = &e->props[r->role_prop[roles[k]]];
            val[roles[k]] = decode(p + pp->offset, pp->type, big);
        }
        tessel_status st = emit_vertex(r, b, val);
        if (st != TESSEL_OK)
            return st;
    }
    return TESSEL_OK;
}

static tessel_status binary_element(ply_reader *r, tsl_builder *b, const ply_elem *e,
                                    int want_faces)
{
    const int big = r->format == F_BE;
    const bool vertex = e == r->vertex;
    const bool faces = e->is_face && want_faces;
    double val[R_COUNT] = {0};
    /* The header check counted lists at their least size; a list element
     * before this one may have used more, so fixed records are checked
     * against what is really left. */
    if (e->fixed && e->min_bytes && e->count > (r->size - r->pos) / e->min_bytes)
        return truncated(r, e, (r->size - r->pos) / e->min_bytes);
    if (e->fixed && !vertex) {
        r->pos += (size_t)e->count * e->min_bytes;
        return TESSEL_OK;
    }
    if (e->fixed) {
        tessel_status st = fixed_vertices(r, b, e, r->data + r->pos, e->count);
        r->pos += (size_t)e->count * e->min_bytes;
        return st;
    }
    for (uint64_t i = 0; i < e->count; i++) {
        for (size_t k = 0; k < e->nprops; k++) {
            const ply_prop *p = &e->props[k];
            if (p->count_type == T_NONE) {
                size_t n = type_size[p->type];
                if (r->size - r->pos < n)
                    return truncated(r, e, i);
                if (vertex && p->role != R_NONE && r->role_prop[p->role] == (int)k)
                    val[p->role] = decode(r->data + r->pos, p->type, big);
                r->pos += n;
                continue;
            }
            size_t cn = type_size[p->count_type], in = type_size[p->type];
            if (r->size - r->pos < cn)
                return truncated(r, e, i);
            double cv = decode(r->data + r->pos, p->count_type, big);
            size_t count;
            tessel_status st = check_list_count(r, e, i, cv, in, r->size - r->pos - cn, &count);
            if (st != TESSEL_OK)
                return st;
            r->pos += cn;
            if ((r->size - r->pos) / in < count)
                return truncated(r, e, i);
            if (faces && p->face_list) {
                if ((st = poly_room(r, count)) != TESSEL_OK)
                    return st;
                for (size_t j = 0; j < count; j++) {
                    double v = decode(r->data + r->pos, p->type, big);
                    if ((st = face_index(r, i, v, j)) != TESSEL_OK)
                        return st;
                    r->pos += in;
                }
                if ((st = tsl_builder_polygon(b, r->poly, count)) != TESSEL_OK)
                    return fail_builder(r, st);
            } else {
                r->pos += count * in;
            }
        }
        if (vertex) {
            tessel_status st = emit_vertex(r, b, val);
            if (st != TESSEL_OK)
                return st;
        }
    }
    return TESSEL_OK;
}

/* ---- ascii ---- */

static bool is_space(uint8_t c)
{
    return tsl_is_blank((char)c) || c == '\n' || c == '\v' || c == '\f';
}

/* Reads the next value as a double; false with a diagnostic at the end of
 * the data or on a malformed number. */
static tessel_status ascii_value(ply_reader *r, const ply_elem *e, uint64_t rec, double *out)
{
    while (r->pos < r->size && is_space(r->data[r->pos])) {
        if (r->data[r->pos] == '\n')
            r->line++;
        r->pos++;
    }
    if (r->pos >= r->size)
        return fail_data(r, TESSEL_ERR_PARSE,
                         "file ends in element '%.*s', record %llu of %llu",
                         (int)(e->name_len > 32 ? 32 : e->name_len), e->name,
                         (unsigned long long)rec, (unsigned long long)e->count);
    const char *s = (const char *)r->data + r->pos;
    const char *end = (const char *)r->data + r->size;
    const char *p = s;
    if (!tsl_scan_double(&p, end, out) || (p < end && !is_space((uint8_t)*p))) {
        const char *q = s;
        while (q < end && !is_space((uint8_t)*q) && q - s < 32)
            q++;
        return fail_data(r, TESSEL_ERR_PARSE, "bad number '%.*s' in element '%.*s', record %llu",
                         (int)(q - s), s, (int)(e->name_len > 32 ? 32 : e->name_len), e->name,
                         (unsigned long long)rec);
    }
    r->pos += (size_t)(p - s);
    return TESSEL_OK;
}

static tessel_status ascii_element(ply_reader *r, tsl_builder *b, const ply_elem *e,
                                   int want_faces)
{
    const bool vertex = e == r->vertex;
    const bool faces = e->is_face && want_faces;
    double val[R_COUNT] = {0};
    tessel_status st;
    for (uint64_t i = 0; i < e->count; i++) {
        for (size_t k = 0; k < e->nprops; k++) {
            const ply_prop *p = &e->props[k];
            double v;
            if ((st = ascii_value(r, e, i, &v)) != TESSEL_OK)
                return st;
            if (p->count_type == T_NONE) {
                if (vertex && p->role != R_NONE && r->role_prop[p->role] == (int)k)
                    val[p->role] = v;
                continue;
            }
            size_t count;
            if ((st = check_list_count(r, e, i, v, 2, r->size - r->pos, &count)) != TESSEL_OK)
                return st;
            bool keep = faces && p->face_list;
            if (keep && (st = poly_room(r, count)) != TESSEL_OK)
                return st;
            for (size_t j = 0; j < count; j++) {
                if ((st = ascii_value(r, e, i, &v)) != TESSEL_OK)
                    return st;
                if (keep && (st = face_index(r, i, v, j)) != TESSEL_OK)
                    return st;
            }
            if (keep && (st = tsl_builder_polygon(b, r->poly, count)) != TESSEL_OK)
                return fail_builder(r, st);
        }
        if (vertex && (st = emit_vertex(r, b, val)) != TESSEL_OK)
            return st;
    }
    return TESSEL_OK;
}

/* The header read and checked (check_layout; the builder's room made when
 * reserve), r set up for the data; *organized: a grid was announced. */
static tessel_status open_reader(ply_reader *r, const uint8_t *data, size_t size,
                                 const char *name, int want_faces, bool reserve, tsl_builder *b,
                                 bool *organized, tessel_diag *diag)
{
    memset(r, 0, sizeof *r);
    r->data = data;
    r->size = size;
    r->name = name;
    r->diag = diag;
    uint64_t w = 0, h = 0, org_line = 0;
    tessel_status st = parse_header(r, b, organized, &w, &h, &org_line);
    return st ? st : check_layout(r, b, want_faces, *organized, w, h, org_line, reserve);
}

static void close_reader(ply_reader *r)
{
    for (size_t i = 0; i < r->nelems; i++)
        free(r->elems[i].props);
    free(r->elems);
    free(r->poly);
}

tessel_status tsl_parse_ply(const uint8_t *data, size_t size, const char *name,
                            int want_faces, tsl_builder *b, tessel_diag *diag)
{
    ply_reader r;
    bool organized;
    tessel_status st = open_reader(&r, data, size, name, want_faces, true, b, &organized, diag);
    /* Elements in file order; stop once nothing wanted is left. */
    bool vertex_done = false, faces_left = false;
    for (size_t i = 0; st == TESSEL_OK && i < r.nelems; i++) {
        faces_left = false;
        for (size_t j = i; j < r.nelems; j++)
            faces_left |= r.elems[j].is_face && want_faces;
        if (vertex_done && !faces_left)
            break;
        const ply_elem *e = &r.elems[i];
        if (e->count == 0)
            continue;
        if (e->nprops == 0)
            continue; /* no data at all */
        st = r.format == F_ASCII ? ascii_element(&r, b, e, want_faces)
                                 : binary_element(&r, b, e, want_faces);
        if (&r.elems[i] == r.vertex)
            vertex_done = true;
    }
    close_reader(&r);
    return st;
}

/* The byte where the vertex records start when they can be read in parts:
 * a binary file whose vertex records and every record before them have a
 * fixed size, without the organized grid or viewpoint a whole read keeps;
 * 0 otherwise. */
static size_t vertex_start(const ply_reader *r, const tsl_builder *b, bool organized)
{
    if (r->format == F_ASCII || organized || b->has_viewpoint || !r->vertex->fixed)
        return 0;
    size_t at = r->pos;
    for (const ply_elem *e = r->elems; e != r->vertex; e++) {
        if (!e->fixed)
            return 0;
        at += (size_t)e->count * e->min_bytes;
    }
    return at;
}

tessel_status tsl_parse_ply_part(const uint8_t *data, size_t size, const char *name, size_t part,
                                 size_t parts, tsl_builder *b, bool *whole, tessel_diag *diag)
{
    ply_reader r;
    bool organized;
    *whole = false;
    tessel_status st = open_reader(&r, data, size, name, 0, false, b, &organized, diag);
    size_t at = st == TESSEL_OK ? vertex_start(&r, b, organized) : 0;
    if (st == TESSEL_OK && at == 0)
        *whole = true;
    if (st == TESSEL_OK && at) {
        /* check_layout found every record inside the data. */
        const ply_elem *e = r.vertex;
        uint64_t first = e->count * part / parts, last = e->count * (part + 1) / parts;
        st = tsl_builder_reserve(b, (size_t)(last - first), 0);
        if (st != TESSEL_OK)
            st = fail_line(&r, e->line, st, "cannot hold %llu vertices: %s",
                           (unsigned long long)(last - first), tessel_status_str(st));
        else
            st = fixed_vertices(&r, b, e, data + at + (size_t)first * e->min_bytes,
                                last - first);
    }
    close_reader(&r);
    return st;
}

/* ---- writer ---- */

/* Output buffer for binary records. */
enum { WBUF = 1 << 16 };

static bool ply_double(const tsl_vertices *v)
{
    return v->offset[0] != 0.0 || v->offset[1] != 0.0 || v->offset[2] != 0.0;
}

static void put_u32le(uint8_t *p, uint32_t u)
{
    p[0] = (uint8_t)u;
    p[1] = (uint8_t)(u >> 8);
    p[2] = (uint8_t)(u >> 16);
    p[3] = (uint8_t)(u >> 24);
}
static void put_f32le(uint8_t *p, float f)
{
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    put_u32le(p, u);
}
static void put_f64le(uint8_t *p, double d)
{
    uint64_t u;
    memcpy(&u, &d, sizeof u);
    put_u32le(p, (uint32_t)u);
    put_u32le(p + 4, (uint32_t)(u >> 32));
}

static tessel_status header(FILE *fp, const tsl_vertices *v, size_t vertex_count,
                            size_t face_count, const tessel_write_params *params,
                            const char *extra_comments)
{
    const char *t = ply_double(v) ? "double" : "float";
    int ok = fprintf(fp, "ply\nformat %s 1.0\ncomment written by tessel %s\n%s",
                     params->ascii ? "ascii" : "binary_little_endian", TESSEL_VERSION_STRING,
                     extra_comments ? extra_comments : "") >= 0;
    ok = ok && fprintf(fp, "element vertex %llu\nproperty %s x\nproperty %s y\nproperty %s z\n",
                       (unsigned long long)vertex_count, t, t, t) >= 0;
    if (tsl_writes_normals(v, params))
        ok = ok && fputs("property float nx\nproperty float ny\nproperty float nz\n", fp) >= 0;
    if (tsl_writes_rgb(v, params))
        ok = ok &&
             fputs("property uchar red\nproperty uchar green\nproperty uchar blue\n", fp) >= 0;
    if (face_count)
        ok = ok && fprintf(fp, "element face %llu\nproperty list uchar %s vertex_indices\n",
                           (unsigned long long)face_count,
                           v->count > INT32_MAX ? "uint" : "int") >= 0;
    ok = ok && fputs("end_header\n", fp) >= 0;
    return ok ? TESSEL_OK : TESSEL_ERR_IO;
}

static tessel_status ply_begin(FILE *fp, const tsl_vertices *v, size_t vertex_count,
                               size_t face_count, const tessel_write_params *params)
{
    return header(fp, v, vertex_count, face_count, params, NULL);
}

/* One vertex: j < v->count, or a missing organized cell when j is
 * TESSEL_NONE (NaN coordinates, zero attributes). */
static size_t binary_vertex(uint8_t *out, const tsl_vertices *v, uint32_t j, bool dbl,
                            bool wn, bool wc)
{
    size_t n = 0;
    for (int k = 0; k < 3; k++) {
        float f = j == TESSEL_NONE ? NAN : v->xyz[3 * (size_t)j + k];
        if (dbl) {
            put_f64le(out + n, v->offset[k] + (double)f);
            n += 8;
        } else {
            put_f32le(out + n, f);
            n += 4;
        }
    }
    if (wn)
        for (int k = 0; k < 3; k++, n += 4)
            put_f32le(out + n, j == TESSEL_NONE ? 0.0f : v->normals[3 * (size_t)j + k]);
    if (wc)
        for (int k = 0; k < 3; k++)
            out[n++] = j == TESSEL_NONE ? 0 : v->rgb[3 * (size_t)j + k];
    return n;
}

static int ascii_vertex(char *out, const tsl_vertices *v, uint32_t j, bool wn, bool wc)
{
    int len = 0;
    for (int k = 0; k < 3; k++) {
        if (k)
            out[len++] = ' ';
        float f = j == TESSEL_NONE ? NAN : v->xyz[3 * (size_t)j + k];
        len += tsl_format_coord(out + len, j == TESSEL_NONE ? 0.0 : v->offset[k], f);
    }
    if (wn)
        for (int k = 0; k < 3; k++) {
            out[len++] = ' ';
            float f = j == TESSEL_NONE ? 0.0f : v->normals[3 * (size_t)j + k];
            len += tsl_format_coord(out + len, 0.0, f);
        }
    if (wc)
        len += snprintf(out + len, 16, " %u %u %u", j == TESSEL_NONE ? 0u : v->rgb[3 * (size_t)j],
                        j == TESSEL_NONE ? 0u : v->rgb[3 * (size_t)j + 1],
                        j == TESSEL_NONE ? 0u : v->rgb[3 * (size_t)j + 2]);
    out[len++] = '\n';
    return len;
}

/* Writes n vertices: index i is subset[i] (NULL: i; TESSEL_NONE: a missing
 * cell). */
static tessel_status write_vertices(FILE *fp, const tsl_vertices *v, const uint32_t *subset,
                                    size_t n, const tessel_write_params *params)
{
    bool wn = tsl_writes_normals(v, params), wc = tsl_writes_rgb(v, params), dbl = ply_double(v);
    if (params->ascii) {
        char line[256];
        for (size_t i = 0; i < n; i++) {
            int len = ascii_vertex(line, v, subset ? subset[i] : (uint32_t)i, wn, wc);
            if (fwrite(line, 1, (size_t)len, fp) != (size_t)len)
                return TESSEL_ERR_IO;
        }
        return TESSEL_OK;
    }
    uint8_t buf[WBUF];
    size_t used = 0;
    for (size_t i = 0; i < n; i++) {
        if (used + 64 > WBUF) {
            if (fwrite(buf, 1, used, fp) != used)
                return TESSEL_ERR_IO;
            used = 0;
        }
        used += binary_vertex(buf + used, v, subset ? subset[i] : (uint32_t)i, dbl, wn, wc);
    }
    if (used && fwrite(buf, 1, used, fp) != used)
        return TESSEL_ERR_IO;
    return TESSEL_OK;
}

static tessel_status ply_faces(FILE *fp, const tsl_vertices *v, const uint32_t *tris,
                               const uint32_t *orig, size_t n,
                               const tessel_write_params *params)
{
    (void)v;
    (void)orig;
    if (params->ascii) {
        for (size_t t = 0; t < n; t++)
            if (fprintf(fp, "3 %lu %lu %lu\n", (unsigned long)tris[3 * t],
                        (unsigned long)tris[3 * t + 1], (unsigned long)tris[3 * t + 2]) < 0)
                return TESSEL_ERR_IO;
        return TESSEL_OK;
    }
    uint8_t buf[WBUF];
    size_t used = 0;
    for (size_t t = 0; t < n; t++) {
        if (used + 13 > WBUF) {
            if (fwrite(buf, 1, used, fp) != used)
                return TESSEL_ERR_IO;
            used = 0;
        }
        buf[used] = 3;
        for (int k = 0; k < 3; k++)
            put_u32le(buf + used + 1 + 4 * k, tris[3 * t + k]);
        used += 13;
    }
    if (used && fwrite(buf, 1, used, fp) != used)
        return TESSEL_ERR_IO;
    return TESSEL_OK;
}

const tsl_format_writer tsl_writer_ply = {TESSEL_FORMAT_PLY, ply_begin, write_vertices,
                                          ply_faces, NULL};

tessel_status tsl_ply_write_cloud(FILE *fp, const tessel_cloud *cloud,
                                  const tessel_write_params *params)
{
    tsl_vertices v;
    v.count = cloud->count;
    v.xyz = cloud->xyz;
    v.normals = cloud->normals;
    v.rgb = cloud->rgb;
    memcpy(v.offset, cloud->offset, sizeof v.offset);
    char comments[256] = "";
    size_t len = 0;
    size_t cells = (size_t)cloud->width * cloud->height;
    bool organized = cloud->grid && cells > 0;
    if (organized) {
        for (size_t c = 0; c < cells; c++)
            if (cloud->grid[c] != TESSEL_NONE && cloud->grid[c] >= cloud->count)
                return TESSEL_ERR_INVALID_ARG;
        len += (size_t)snprintf(comments, sizeof comments, "comment organized %lu %lu\n",
                                (unsigned long)cloud->width, (unsigned long)cloud->height);
    }
    if (cloud->has_viewpoint) {
        char c[3][40];
        for (int k = 0; k < 3; k++)
            tsl_format_coord(c[k], cloud->viewpoint[k], 0.0f);
        snprintf(comments + len, sizeof comments - len, "comment viewpoint %s %s %s\n", c[0],
                 c[1], c[2]);
    }
    size_t n = organized ? cells : cloud->count;
    tessel_status st = header(fp, &v, n, 0, params, comments);
    if (st != TESSEL_OK || !organized)
        return st == TESSEL_OK ? write_vertices(fp, &v, NULL, n, params) : st;
    return write_vertices(fp, &v, cloud->grid, n, params);
}
