/* PCD reader: the Point Cloud Library's own format, header versions .6 and
 * .7 (PCL documentation, "The PCD (Point Cloud Data) file format").
 *
 * A text header (FIELDS / SIZE / TYPE / COUNT / WIDTH / HEIGHT / VIEWPOINT /
 * POINTS / DATA) describes fixed-size records that follow either as text
 * lines (DATA ascii) or packed little-endian records (DATA binary). We take
 * x y z, normal_x normal_y normal_z and rgb / rgba (a packed 0x00RRGGBB
 * stored in a float or uint32) and skip every other field, whatever its
 * COUNT. HEIGHT > 1 means an organized grid: every record is pushed, NaN
 * ones included, so the builder can map grid cells to the kept points.
 * VIEWPOINT's translation is the scanner position. binary_compressed (LZF,
 * fields stored column by column) is refused with a clear message. Every
 * announced count is checked against the bytes or lines actually there
 * before anything is allocated. */
#include "io/io.h"

#include <stdlib.h>
#include <string.h>

enum { PCD_MAX_FIELDS = 256 };

enum pcd_role { ROLE_X, ROLE_Y, ROLE_Z, ROLE_NX, ROLE_NY, ROLE_NZ, ROLE_RGB, ROLE_COUNT };

typedef struct pcd_field {
    const char *name;
    size_t name_len;
    unsigned size;       /* bytes per element */
    char type;           /* 'F', 'I' or 'U' */
    uint32_t count;      /* elements */
    size_t offset;       /* byte offset in a binary record */
    size_t token;        /* index of its first token on an ascii line */
} pcd_field;

typedef struct pcd_header {
    pcd_field fields[PCD_MAX_FIELDS];
    size_t field_count;
    int have_fields, have_size, have_type, have_count, have_width, have_height,
        have_points;
    uint64_t width, height, points;
    uint64_t points_line, width_line;
    int role[ROLE_COUNT];  /* field index or -1 */
    double viewpoint[3];
    int has_viewpoint;
    int binary;
    size_t record_size;     /* bytes per binary record */
    size_t tokens;          /* values per ascii line */
    size_t data_start;      /* byte offset of the data */
    uint64_t data_line;     /* line number of the first data line */
} pcd_header;

/* A line of the input without its terminator. */
typedef struct pcd_line {
    const char *p, *end;
} pcd_line;

/* Next whitespace-delimited token of the line; false at its end. */
static bool next_token(pcd_line *l, const char **tok, size_t *len)
{
    const char *p = tsl_skip_blanks(l->p, l->end);
    if (p == l->end)
        return false;
    const char *q = p;
    while (q < l->end && !tsl_is_blank(*q))
        q++;
    *tok = p;
    *len = (size_t)(q - p);
    l->p = q;
    return true;
}

static bool token_is(const char *tok, size_t len, const char *word)
{
    return strlen(word) == len && memcmp(tok, word, len) == 0;
}

static size_t count_tokens(pcd_line l)
{
    size_t n = 0;
    const char *t;
    size_t len;
    while (next_token(&l, &t, &len))
        n++;
    return n;
}

/* Parses a whole token as an unsigned integer. */
static bool token_u64(const char *tok, size_t len, uint64_t *out)
{
    const char *p = tok;
    return tsl_scan_u64(&p, tok + len, out) && p == tok + len;
}

/* Parses a whole token as a double (PCL writes "nan" for missing values,
 * which the scanner accepts). */
static bool token_double(const char *tok, size_t len, double *out)
{
    const char *p = tok;
    return tsl_scan_double(&p, tok + len, out) && p == tok + len;
}

static tessel_status header_error(tessel_diag *diag, const char *name, uint64_t line,
                                  const char *what, const char *tok, size_t len)
{
    tsl_diag_set(diag, name, line, 0, 0, "PCD header: %s '%.*s'", what,
                 (int)(len > 64 ? 64 : len), tok);
    return TESSEL_ERR_PARSE;
}

/* Reads one per-field list (SIZE / TYPE / COUNT) after FIELDS. */
static tessel_status parse_field_list(pcd_header *h, pcd_line l, const char *key,
                                      uint64_t line, const char *name, tessel_diag *diag)
{
    if (!h->have_fields) {
        tsl_diag_set(diag, name, line, 0, 0, "PCD header: %s before FIELDS", key);
        return TESSEL_ERR_PARSE;
    }
    size_t n = count_tokens(l);
    if (n != h->field_count) {
        tsl_diag_set(diag, name, line, 0, 0,
                     "PCD header: %s has %zu entries but FIELDS names %zu", key, n,
                     h->field_count);
        return TESSEL_ERR_PARSE;
    }
    const char *tok;
    size_t len;
    for (size_t i = 0; next_token(&l, &tok, &len); i++) {
        pcd_field *f = &h->fields[i];
        uint64_t v = 0;
        if (key[0] == 'T') {
            if (len != 1 || (tok[0] != 'F' && tok[0] != 'I' && tok[0] != 'U'))
                return header_error(diag, name, line, "TYPE must be F, I or U, not", tok, len);
            f->type = tok[0];
        } else if (!token_u64(tok, len, &v) || v == 0 || v > UINT32_MAX) {
            return header_error(diag, name, line,
                                key[0] == 'S' ? "bad SIZE" : "bad COUNT", tok, len);
        } else if (key[0] == 'S') {
            f->size = (unsigned)v;
        } else {
            f->count = (uint32_t)v;
        }
    }
    return TESSEL_OK;
}

static int role_of(const char *s, size_t len)
{
    static const char *const names[] = {"x", "y", "z", "normal_x", "normal_y", "normal_z"};
    for (int r = 0; r < 6; r++)
        if (token_is(s, len, names[r]))
            return r;
    if (token_is(s, len, "rgb") || token_is(s, len, "rgba"))
        return ROLE_RGB;
    return -1;
}

/* Checks the header once DATA was seen and lays out the records. */
static tessel_status finish_header(pcd_header *h, uint64_t data_line, const char *name,
                                   tessel_diag *diag)
{
    if (!h->have_fields || !h->have_size || !h->have_type) {
        tsl_diag_set(diag, name, data_line, 0, 0,
                     "PCD header: FIELDS, SIZE and TYPE are required before DATA");
        return TESSEL_ERR_PARSE;
    }
    if (!h->have_width && !h->have_points) {
        tsl_diag_set(diag, name, data_line, 0, 0,
                     "PCD header: neither WIDTH nor POINTS given before DATA");
        return TESSEL_ERR_PARSE;
    }
    if (!h->have_width) {
        h->width = h->points;
        h->height = 1;
    }
    if (!h->have_height)
        h->height = 1;
    if (h->width > UINT32_MAX || h->height > UINT32_MAX ||
        (h->height != 0 && h->width > UINT64_MAX / h->height)) {
        tsl_diag_set(diag, name, h->width_line, 0, 0,
                     "PCD header: WIDTH %llu x HEIGHT %llu is too large",
                     (unsigned long long)h->width, (unsigned long long)h->height);
        return TESSEL_ERR_LIMIT;
    }
    if (!h->have_points) {
        h->points = h->width * h->height;
    } else if (h->points != h->width * h->height) {
        tsl_diag_set(diag, name, h->points_line, 0, 0,
                     "PCD header: POINTS %llu does not match WIDTH %llu x HEIGHT %llu",
                     (unsigned long long)h->points, (unsigned long long)h->width,
                     (unsigned long long)h->height);
        return TESSEL_ERR_PARSE;
    }
    for (int r = 0; r < ROLE_COUNT; r++)
        h->role[r] = -1;
    size_t offset = 0, token = 0;
    for (size_t i = 0; i < h->field_count; i++) {
        pcd_field *f = &h->fields[i];
        if (!h->have_count)
            f->count = 1;
        bool ok = f->type == 'F' ? (f->size == 4 || f->size == 8)
                                 : (f->size == 1 || f->size == 2 || f->size == 4 ||
                                    f->size == 8);
        if (!ok) {
            tsl_diag_set(diag, name, data_line, 0, 0,
                         "PCD header: field '%.*s' has TYPE %c with SIZE %u (F takes 4 or "
                         "8, I and U take 1, 2, 4 or 8)",
                         (int)f->name_len, f->name, f->type, f->size);
            return TESSEL_ERR_PARSE;
        }
        f->offset = offset;
        f->token = token;
        size_t bytes;
        if (!tsl_mul_size(f->size, f->count, &bytes) || !tsl_add_size(offset, bytes, &offset) ||
            !tsl_add_size(token, f->count, &token)) {
            tsl_diag_set(diag, name, data_line, 0, 0, "PCD header: records are too large");
            return TESSEL_ERR_LIMIT;
        }
        int r = role_of(f->name, f->name_len);
        if (r < 0 || h->role[r] >= 0)
            continue;  /* other fields and repeats are skipped */
        if (f->count != 1 || (r == ROLE_RGB && f->size != 4)) {
            tsl_diag_set(diag, name, data_line, 0, 0,
                         "PCD header: field '%.*s' must be a single %s value (COUNT %u, "
                         "SIZE %u)",
                         (int)f->name_len, f->name, r == ROLE_RGB ? "4-byte" : "scalar",
                         f->count, f->size);
            return TESSEL_ERR_PARSE;
        }
        h->role[r] = (int)i;
    }
    h->record_size = offset;
    h->tokens = token;
    if (h->role[ROLE_X] < 0 || h->role[ROLE_Y] < 0 || h->role[ROLE_Z] < 0) {
        tsl_diag_set(diag, name, data_line, 0, 0, "PCD file has no x, y and z fields");
        return TESSEL_ERR_PARSE;
    }
    return TESSEL_OK;
}

static tessel_status parse_header(const uint8_t *data, size_t size, const char *name,
                                  pcd_header *h, tessel_diag *diag)
{
    const char *p = (const char *)data, *end = p + size;
    uint64_t line = 0;
    while (p < end) {
        line++;
        const char *nl = memchr(p, '\n', (size_t)(end - p));
        pcd_line l = {p, nl ? nl : end};
        p = nl ? nl + 1 : end;
        const char *key;
        size_t klen;
        if (!next_token(&l, &key, &klen) || key[0] == '#')
            continue;
        tessel_status st = TESSEL_OK;
        const char *tok;
        size_t len;
        if (token_is(key, klen, "VERSION")) {
            continue;
        } else if (token_is(key, klen, "FIELDS") || token_is(key, klen, "COLUMNS")) {
            if (h->have_fields)
                return header_error(diag, name, line, "repeated keyword", key, klen);
            while (next_token(&l, &tok, &len)) {
                if (h->field_count == PCD_MAX_FIELDS) {
                    tsl_diag_set(diag, name, line, 0, 0,
                                 "PCD header: more than %d fields", PCD_MAX_FIELDS);
                    return TESSEL_ERR_LIMIT;
                }
                h->fields[h->field_count].name = tok;
                h->fields[h->field_count].name_len = len;
                h->field_count++;
            }
            if (h->field_count == 0) {
                tsl_diag_set(diag, name, line, 0, 0, "PCD header: FIELDS names no field");
                return TESSEL_ERR_PARSE;
            }
            h->have_fields = 1;
        } else if (token_is(key, klen, "SIZE")) {
            st = parse_field_list(h, l, "SIZE", line, name, diag);
            h->have_size = 1;
        } else if (token_is(key, klen, "TYPE")) {
            st = parse_field_list(h, l, "TYPE", line, name, diag);
            h->have_type = 1;
        } else if (token_is(key, klen, "COUNT")) {
            st = parse_field_list(h, l, "COUNT", line, name, diag);
            h->have_count = 1;
        } else if (token_is(key, klen, "WIDTH") || token_is(key, klen, "HEIGHT") ||
                   token_is(key, klen, "POINTS")) {
            uint64_t v;
            if (!next_token(&l, &tok, &len) || !token_u64(tok, len, &v) ||
                count_tokens(l) != 0)
                return header_error(diag, name, line, "expected one integer after", key,
                                    klen);
            if (key[0] == 'W') {
                h->width = v;
                h->have_width = 1;
                h->width_line = line;
            } else if (key[0] == 'H') {
                h->height = v;
                h->have_height = 1;
            } else {
                h->points = v;
                h->have_points = 1;
                h->points_line = line;
            }
        } else if (token_is(key, klen, "VIEWPOINT")) {
            double v[7];
            int k = 0;
            while (k < 7 && next_token(&l, &tok, &len) && token_double(tok, len, &v[k]) &&
                   isfinite(v[k]))
                k++;
            if (k != 7 || count_tokens(l) != 0) {
                tsl_diag_set(diag, name, line, 0, 0,
                             "PCD header: VIEWPOINT needs 7 numbers (tx ty tz qw qx qy qz)");
                return TESSEL_ERR_PARSE;
            }
            memcpy(h->viewpoint, v, sizeof h->viewpoint);
            h->has_viewpoint = 1;
        } else if (token_is(key, klen, "DATA")) {
            if (!next_token(&l, &tok, &len))
                return header_error(diag, name, line, "DATA needs a kind", key, 0);
            if (token_is(tok, len, "binary_compressed")) {
                tsl_diag_set(diag, name, line, 0, 0,
                             "PCD binary_compressed data is not supported; save the cloud "
                             "as binary or ascii (pcl_convert_pcd_ascii_binary)");
                return TESSEL_ERR_UNSUPPORTED;
            }
            if (token_is(tok, len, "binary"))
                h->binary = 1;
            else if (!token_is(tok, len, "ascii"))
                return header_error(diag, name, line, "unknown DATA kind", tok, len);
            h->data_start = (size_t)(p - (const char *)data);
            h->data_line = line + 1;
            return finish_header(h, line, name, diag);
        } else {
            return header_error(diag, name, line, "unknown keyword", key, klen);
        }
        if (st != TESSEL_OK)
            return st;
    }
    tsl_diag_set(diag, name, line, 0, 0, "PCD header has no DATA line");
    return TESSEL_ERR_PARSE;
}

/* One binary element of a field as a double (little-endian). */
static double binary_value(const uint8_t *p, const pcd_field *f)
{
    uint64_t u = 0;
    for (unsigned k = 0; k < f->size; k++)
        u |= (uint64_t)p[k] << (8 * k);
    if (f->type == 'F') {
        if (f->size == 4) {
            uint32_t u32 = (uint32_t)u;
            float v;
            memcpy(&v, &u32, sizeof v);
            return v;
        }
        double v;
        memcpy(&v, &u, sizeof v);
        return v;
    }
    if (f->type == 'U')
        return (double)u;
    /* sign-extend */
    unsigned shift = 64 - 8 * f->size;
    int64_t s;
    uint64_t shifted = u << shift;
    memcpy(&s, &shifted, sizeof s);
    return (double)(s >> shift);
}

static void unpack_rgb(uint32_t packed, uint8_t rgb[3])
{
    rgb[0] = (uint8_t)(packed >> 16);
    rgb[1] = (uint8_t)(packed >> 8);
    rgb[2] = (uint8_t)packed;
}

static tessel_status push_point(tsl_builder *b, const pcd_header *h, const double v[6],
                                const uint8_t rgb[3])
{
    float normal[3] = {(float)v[3], (float)v[4], (float)v[5]};
    int has_n = h->role[ROLE_NX] >= 0 && h->role[ROLE_NY] >= 0 && h->role[ROLE_NZ] >= 0;
    return tsl_builder_point(b, v, has_n ? normal : NULL, h->role[ROLE_RGB] >= 0 ? rgb : NULL);
}

static tessel_status read_binary(const uint8_t *data, size_t size, const char *name,
                                 const pcd_header *h, tsl_builder *b, tessel_diag *diag)
{
    size_t available = size - h->data_start;
    size_t n = (size_t)h->points;
    if (h->record_size == 0 || h->points > available / h->record_size) {
        size_t whole = h->record_size ? available / h->record_size : 0;
        tsl_diag_set(diag, name, 0, 1, h->data_start + whole * h->record_size,
                     "PCD binary data truncated: %llu points of %zu bytes announced from "
                     "byte %zu, only %zu bytes follow (%zu whole points)",
                     (unsigned long long)h->points, h->record_size, h->data_start,
                     available, whole);
        return TESSEL_ERR_PARSE;
    }
    tessel_status st = tsl_builder_reserve(b, n, 0);
    if (st != TESSEL_OK) {
        tsl_diag_set(diag, name, h->points_line, 0, 0, "cannot hold %zu PCD points: %s", n,
                     tessel_status_str(st));
        return st;
    }
    const uint8_t *rec = data + h->data_start;
    for (size_t i = 0; i < n; i++, rec += h->record_size) {
        double v[6] = {0, 0, 0, 0, 0, 0};
        for (int r = 0; r < ROLE_RGB; r++)
            if (h->role[r] >= 0)
                v[r] = binary_value(rec + h->fields[h->role[r]].offset, &h->fields[h->role[r]]);
        uint8_t rgb[3] = {0, 0, 0};
        if (h->role[ROLE_RGB] >= 0) {
            const uint8_t *c = rec + h->fields[h->role[ROLE_RGB]].offset;
            unpack_rgb((uint32_t)c[0] | ((uint32_t)c[1] << 8) | ((uint32_t)c[2] << 16) |
                           ((uint32_t)c[3] << 24),
                       rgb);
        }
        st = push_point(b, h, v, rgb);
        if (st != TESSEL_OK) {
            tsl_diag_set(diag, name, 0, 1, (uint64_t)(rec - data), "PCD point %zu: %s", i,
                         tessel_status_str(st));
            return st;
        }
    }
    return TESSEL_OK;
}

/* rgb in ascii: PCL writes the packed bits as an unsigned integer (since
 * 1.8) even for TYPE F; older files print the float whose bits they are. */
static bool ascii_rgb(const char *tok, size_t len, const pcd_field *f, uint8_t rgb[3])
{
    uint64_t u;
    if (token_u64(tok, len, &u)) {
        if (u > UINT32_MAX)
            return false;
        unpack_rgb((uint32_t)u, rgb);
        return true;
    }
    double d;
    if (!token_double(tok, len, &d))
        return false;
    if (f->type != 'F') {
        if (d < 0 && d >= INT32_MIN && d == floor(d)) {  /* I4 written signed */
            int32_t s = (int32_t)d;
            uint32_t bits;
            memcpy(&bits, &s, sizeof bits);
            unpack_rgb(bits, rgb);
            return true;
        }
        return false;
    }
    float fl = (float)d;
    uint32_t bits;
    memcpy(&bits, &fl, sizeof bits);
    unpack_rgb(bits, rgb);
    return true;
}

static tessel_status read_ascii(const uint8_t *data, size_t size, const char *name,
                                const pcd_header *h, tsl_builder *b, tessel_diag *diag)
{
    const char *p = (const char *)data + h->data_start, *end = (const char *)data + size;
    /* Each value takes at least one character and one separator: a bound on
     * the points the remaining bytes can hold, so a lying POINTS cannot make
     * us over-allocate. */
    size_t room = ((size_t)(end - p) + 1) / (2 * h->tokens);
    size_t n = (size_t)h->points;
    tessel_status st = tsl_builder_reserve(b, n < room ? n : room, 0);
    if (st != TESSEL_OK) {
        tsl_diag_set(diag, name, h->points_line, 0, 0, "cannot hold %zu PCD points: %s", n,
                     tessel_status_str(st));
        return st;
    }
    /* Which role, if any, each token of a line feeds. */
    int token_role[ROLE_COUNT];
    for (int r = 0; r < ROLE_COUNT; r++)
        token_role[r] = h->role[r] >= 0 ? (int)h->fields[h->role[r]].token : -1;

    uint64_t line = h->data_line - 1;
    size_t done = 0;
    while (p < end) {
        line++;
        const char *nl = memchr(p, '\n', (size_t)(end - p));
        pcd_line l = {p, nl ? nl : end};
        p = nl ? nl + 1 : end;
        const char *tok;
        size_t len;
        pcd_line probe = l;
        if (!next_token(&probe, &tok, &len) || tok[0] == '#')
            continue;
        if (done == n) {
            tsl_diag_set(diag, name, line, 0, 0,
                         "PCD data has more lines than the %zu POINTS announced", n);
            return TESSEL_ERR_PARSE;
        }
        double v[6] = {0, 0, 0, 0, 0, 0};
        uint8_t rgb[3] = {0, 0, 0};
        size_t t = 0;
        while (next_token(&l, &tok, &len)) {
            if (t < h->tokens) {
                for (int r = 0; r < ROLE_COUNT; r++) {
                    if (token_role[r] != (int)t)
                        continue;
                    bool ok = r == ROLE_RGB
                                  ? ascii_rgb(tok, len, &h->fields[h->role[r]], rgb)
                                  : token_double(tok, len, &v[r]);
                    if (!ok) {
                        tsl_diag_set(diag, name, line, 0, 0,
                                     "PCD data: bad value '%.*s' for field '%.*s'",
                                     (int)(len > 64 ? 64 : len), tok,
                                     (int)h->fields[h->role[r]].name_len,
                                     h->fields[h->role[r]].name);
                        return TESSEL_ERR_PARSE;
                    }
                }
            }
            t++;
        }
        if (t != h->tokens) {
            tsl_diag_set(diag, name, line, 0, 0,
                         "PCD data: expected %zu values (from FIELDS and COUNT), got %zu",
                         h->tokens, t);
            return TESSEL_ERR_PARSE;
        }
        st = push_point(b, h, v, rgb);
        if (st != TESSEL_OK) {
            tsl_diag_set(diag, name, line, 0, 0, "PCD point %zu: %s", done,
                         tessel_status_str(st));
            return st;
        }
        done++;
    }
    if (done != n) {
        tsl_diag_set(diag, name, line, 0, 0,
                     "PCD data ends after %zu points, POINTS announced %zu", done, n);
        return TESSEL_ERR_PARSE;
    }
    return TESSEL_OK;
}

tessel_status tsl_parse_pcd(const uint8_t *data, size_t size, const char *name,
                            int want_faces, tsl_builder *b, tessel_diag *diag)
{
    (void)want_faces;
    pcd_header *h = tsl_calloc_array(1, sizeof *h);
    if (!h)
        return TESSEL_ERR_NOMEM;
    tessel_status st = parse_header(data, size, name, h, diag);
    if (st == TESSEL_OK && h->points > b->max_points) {
        tsl_diag_set(diag, name, h->points_line, 0, 0,
                     "PCD file has %llu points, above the limit of %llu",
                     (unsigned long long)h->points, (unsigned long long)b->max_points);
        st = TESSEL_ERR_LIMIT;
    }
    if (st == TESSEL_OK) {
        int has_n = h->role[ROLE_NX] >= 0 && h->role[ROLE_NY] >= 0 && h->role[ROLE_NZ] >= 0;
        st = tsl_builder_attributes(b, has_n, h->role[ROLE_RGB] >= 0);
        if (h->height > 1) {
            b->width = (uint32_t)h->width;
            b->height = (uint32_t)h->height;
        }
        if (h->has_viewpoint) {
            memcpy(b->viewpoint, h->viewpoint, sizeof b->viewpoint);
            b->has_viewpoint = 1;
        }
    }
    if (st == TESSEL_OK)
        st = h->binary ? read_binary(data, size, name, h, b, diag)
                       : read_ascii(data, size, name, h, b, diag);
    free(h);
    return st;
}
