/* Plain-text point lists: XYZ, CSV and Leica PTS, read and written.
 *
 * There is no standard for these files, only habits; the reader accepts the
 * common ones and refuses what it cannot read unambiguously:
 *  - values separated by blanks, ',' or ';'; blank lines and comment lines
 *    ('#' or '//') skipped;
 *  - without column names, 3 numbers per line are x y z and 6 are x y z
 *    nx ny nz; every line must have as many numbers as the first. Six
 *    columns whose last three are all integers in 0-255 and not unit
 *    vectors (some longer than 1.5) are x y z r g b, the other common habit:
 *    no normal looks like that;
 *  - a line of column names before the first point ("x,y,z,nx,ny,nz")
 *    maps the columns by name: x y z, nx ny nz (or normal_x ...), r g b (or
 *    red green blue); other columns are skipped. A comment naming columns
 *    (CloudCompare's "//X,Y,Z,R,G,B") counts too when the first point has
 *    that many values;
 *  - Leica PTS: a line holding one integer (the point count of the scan that
 *    follows) and lines of "x y z intensity [r g b]"; a file may hold
 *    several such blocks. Intensity is dropped, colour kept.
 * Colours are 0-255 integers, or fractions in [0, 1] written with a '.'.
 * The writer prints coordinates with tsl_format_coord (exact round trip),
 * comma separated with a header line for CSV; colour columns are announced
 * by a header ("# x y z r g b" in XYZ) so the file reads back as written. */
#include "io/io.h"

#include <stdlib.h>
#include <string.h>

enum { XYZ_MAX_COLUMNS = 64 };

enum xyz_role {
    COL_SKIP = -1,
    COL_X, COL_Y, COL_Z, COL_NX, COL_NY, COL_NZ, COL_R, COL_G, COL_B, COL_ROLES
};

typedef struct xyz_layout {
    size_t columns;
    signed char role[XYZ_MAX_COLUMNS];
    int has_normals, has_rgb;
    int named;          /* from a header line */
    uint64_t defined_at;  /* line that fixed the layout */
} xyz_layout;

static bool is_sep(char c) { return c == ',' || c == ';'; }

/* Skips blanks, then at most one ',' or ';' and the blanks after it. */
static const char *skip_separator(const char *p, const char *end)
{
    p = tsl_skip_blanks(p, end);
    if (p < end && is_sep(*p))
        p = tsl_skip_blanks(p + 1, end);
    return p;
}

/* End of the token starting at p. */
static const char *token_end(const char *p, const char *end)
{
    while (p < end && !tsl_is_blank(*p) && !is_sep(*p))
        p++;
    return p;
}

/* Parses one number token at *p; false when the token is not exactly a
 * number ("nan" and "inf" are numbers: the builder drops such points). */
static bool scan_value(const char **p, const char *end, double *v)
{
    const char *q = *p;
    if (!tsl_scan_double(&q, end, v) || (q < end && !tsl_is_blank(*q) && !is_sep(*q)))
        return false;
    *p = q;
    return true;
}

/* Number of tokens from p to the end of the line. */
static size_t count_fields(const char *p, const char *end)
{
    size_t n = 0;
    p = skip_separator(p, end);
    while (p < end) {
        const char *e = token_end(p, end);
        if (e == p)  /* an empty field between two separators */
            e = p + 1;
        n++;
        p = skip_separator(e, end);
    }
    return n;
}

static bool name_is(const char *s, size_t len, const char *word)
{
    if (strlen(word) != len)
        return false;
    for (size_t i = 0; i < len; i++) {
        char c = s[i] >= 'A' && s[i] <= 'Z' ? (char)(s[i] + 32) : s[i];
        if (c != word[i])
            return false;
    }
    return true;
}

static int role_of_name(const char *s, size_t len)
{
    static const char *const names[][3] = {
        {"x", NULL, NULL},      {"y", NULL, NULL},       {"z", NULL, NULL},
        {"nx", "normal_x", "normalx"}, {"ny", "normal_y", "normaly"},
        {"nz", "normal_z", "normalz"}, {"r", "red", NULL}, {"g", "green", NULL},
        {"b", "blue", NULL}};
    for (int r = 0; r < COL_ROLES; r++)
        for (int k = 0; k < 3 && names[r][k]; k++)
            if (name_is(s, len, names[r][k]))
                return r;
    return COL_SKIP;
}

/* Tries to read [p, end) as a line of column names. True when every token
 * is a name (starts with a letter or '_') and x, y and z are among them. */
static bool parse_header(const char *p, const char *end, xyz_layout *lay)
{
    xyz_layout l;
    memset(&l, 0, sizeof l);
    int seen[COL_ROLES] = {0};
    p = skip_separator(p, end);
    while (p < end) {
        const char *e = token_end(p, end);
        /* spreadsheets quote their column names: "x","y","z" */
        const char *ns = p, *ne = e;
        if (ne - ns >= 2 && *ns == '"' && ne[-1] == '"') {
            ns++;
            ne--;
        }
        char c = (char)(*ns | 0x20);
        if (ne == ns || !((c >= 'a' && c <= 'z') || *ns == '_') ||
            l.columns == XYZ_MAX_COLUMNS)
            return false;
        int r = role_of_name(ns, (size_t)(ne - ns));
        if (r != COL_SKIP && seen[r])
            r = COL_SKIP;  /* a repeated name: the first one counts */
        if (r != COL_SKIP)
            seen[r] = 1;
        l.role[l.columns++] = (signed char)r;
        p = skip_separator(e, end);
    }
    if (!seen[COL_X] || !seen[COL_Y] || !seen[COL_Z])
        return false;
    l.has_normals = seen[COL_NX] && seen[COL_NY] && seen[COL_NZ];
    l.has_rgb = seen[COL_R] && seen[COL_G] && seen[COL_B];
    for (size_t i = 0; i < l.columns; i++) {
        int r = l.role[i];
        if ((r >= COL_NX && r <= COL_NZ && !l.has_normals) ||
            (r >= COL_R && !l.has_rgb))
            l.role[i] = COL_SKIP;
    }
    l.named = 1;
    *lay = l;
    return true;
}

/* Layout of an unnamed line: 3 or 6 numbers (PTS: 3, 4 or 7). */
static bool layout_from_count(size_t n, int pts, xyz_layout *lay)
{
    memset(lay, 0, sizeof *lay);
    for (int k = 0; k < 3; k++)
        lay->role[k] = (signed char)k;
    lay->columns = n;
    if (n == 3)
        return true;
    if (!pts && n == 6) {
        for (int k = 3; k < 6; k++)
            lay->role[k] = (signed char)k;
        lay->has_normals = 1;
        return true;
    }
    if (pts && (n == 4 || n == 7)) {
        lay->role[3] = COL_SKIP;  /* intensity */
        for (size_t k = 4; k < n; k++)
            lay->role[k] = (signed char)(COL_R + (int)(k - 4));
        lay->has_rgb = n == 7;
        return true;
    }
    return false;
}

/* A colour value: integers are 0-255, numbers with a '.' in [0, 1] are
 * fractions. Out of range values are clamped. */
static uint8_t colour_byte(double v, const char *tok, const char *tok_end)
{
    if (memchr(tok, '.', (size_t)(tok_end - tok)) && v <= 1.0)
        v *= 255.0;
    if (!(v > 0.0))
        return 0;
    if (v >= 255.0)
        return 255;
    return (uint8_t)(v + 0.5);
}

typedef struct line_iter {
    const char *p, *end;
    uint64_t line;
} line_iter;

/* Next line as [*s, *e) (terminator excluded); false at the end. */
static bool next_line(line_iter *it, const char **s, const char **e)
{
    if (it->p >= it->end)
        return false;
    const char *nl = memchr(it->p, '\n', (size_t)(it->end - it->p));
    *s = it->p;
    *e = nl ? nl : it->end;
    it->p = nl ? nl + 1 : it->end;
    it->line++;
    return true;
}

/* Trims blanks; returns 0 for a blank line, 1 for a comment (with *body
 * after the marker), 2 for content. */
static int classify(const char **s, const char *e, const char **body)
{
    const char *p = *s;
    while (p < e && tsl_is_blank(*p))
        p++;
    *s = p;
    if (p == e)
        return 0;
    if (*p == '#') {
        *body = p + 1;
        return 1;
    }
    if (*p == '/' && p + 1 < e && p[1] == '/') {
        *body = p + 2;
        return 1;
    }
    return 2;
}

/* One line holding a single unsigned integer (a PTS block count). */
static bool single_integer(const char *s, const char *e, uint64_t *n)
{
    const char *p = s;
    if (!tsl_scan_u64(&p, e, n))
        return false;
    while (p < e && tsl_is_blank(*p))
        p++;
    return p == e;
}

/* The unnamed 6-column file turned out to hold colours, not normals: move
 * the values over (the builder keeps its arrays at b->cap points). */
static tessel_status normals_to_colours(tsl_builder *b)
{
    uint8_t *rgb = tsl_alloc_array(b->cap ? b->cap : 1, 3);
    if (!rgb)
        return TESSEL_ERR_NOMEM;
    for (size_t i = 0; i < 3 * b->count; i++)
        rgb[i] = (uint8_t)b->normals[i];
    free(b->normals);
    free(b->rgb);
    b->normals = NULL;
    b->has_normals = 0;
    b->rgb = rgb;
    b->has_rgb = 1;
    return TESSEL_OK;
}

/* Sink mode (streaming) cannot take back a chunk that went out: whether
 * the columns 4-6 of an unnamed 6-column file are normals or colours is
 * decided from the first chunk, and a later line that would have decided
 * otherwise (the whole-file rule above) fails the read rather than give a
 * cloud that differs from what tessel_cloud_read gives. Naming the columns
 * lifts the doubt. */
static tessel_status sink_colours(tessel_diag *diag, const char *name, uint64_t line,
                                  const tsl_builder *b, int were_colours)
{
    tsl_diag_set(diag, name, line, 0, 0,
                 "columns 4-6 were read as %s from the first %zu points (a chunked read "
                 "decides from the first chunk), but the whole file reads as %s: name the "
                 "columns in a first line such as '# x y z %s'",
                 were_colours ? "colours" : "normals", b->chunk,
                 were_colours ? "normals" : "colours", were_colours ? "nx ny nz" : "r g b");
    return TESSEL_ERR_UNSUPPORTED;
}

tessel_status tsl_parse_xyz(const uint8_t *data, size_t size, const char *name,
                            int want_faces, tsl_builder *b, tessel_diag *diag)
{
    (void)want_faces;
    line_iter it = {(const char *)data, (const char *)data + size, 0};
    const char *s, *e, *body;
    xyz_layout lay, comment_header;
    int have_layout = 0, have_comment_header = 0, pts = 0;
    /* PTS block bookkeeping: points expected / seen in the current block. */
    uint64_t block_expected = 0, block_seen = 0, block_line = 0;
    /* For unnamed 6-column files: could columns 4-6 be colours? */
    bool colour_like = true, long_vector = false;
    /* In sink mode that is decided when the first chunk goes out (-1: not
     * yet, 0: normals, 1: colours); see sink_colours. */
    int decided = -1;
    tessel_status st;

    while (next_line(&it, &s, &e)) {
        int kind = classify(&s, e, &body);
        if (kind == 0)
            continue;
        if (kind == 1) {
            /* A comment naming the columns before the first point is a
             * header if the first point has as many values as it names. */
            if (!have_layout && !have_comment_header &&
                parse_header(body, e, &comment_header)) {
                have_comment_header = 1;
                comment_header.defined_at = it.line;
            }
            continue;
        }
        uint64_t count;
        if ((pts || !have_layout) && single_integer(s, e, &count)) {
            /* A PTS block count; the previous block must be complete. */
            if (pts && block_seen != block_expected) {
                tsl_diag_set(diag, name, block_line, 0, 0,
                             "PTS block announces %llu points but has %llu",
                             (unsigned long long)block_expected,
                             (unsigned long long)block_seen);
                return TESSEL_ERR_PARSE;
            }
            pts = 1;
            block_expected = count;
            block_seen = 0;
            block_line = it.line;
            continue;
        }
        if (!have_layout) {
            if (!pts && parse_header(s, e, &lay)) {
                have_layout = 1;
                lay.defined_at = it.line;
                continue;
            }
            size_t n = count_fields(s, e);
            if (have_comment_header && n == comment_header.columns) {
                lay = comment_header;
            } else if (!layout_from_count(n, pts, &lay)) {
                tsl_diag_set(diag, name, it.line, 0, 0,
                             pts ? "expected 3, 4 or 7 numbers in a PTS file, got %zu"
                                 : "expected 3 or 6 numbers, got %zu",
                             n);
                return TESSEL_ERR_PARSE;
            } else {
                lay.defined_at = it.line;
            }
            have_layout = 1;
        }
        if (tsl_builder_pushed(b) == 0) {
            st = tsl_builder_attributes(b, lay.has_normals, lay.has_rgb);
            /* Lines are about as long as this one: reserve for that,
             * bounded by the size of the file (never by a header) and
             * capped, as comments could fill the rest. */
            size_t guess = size / ((size_t)(e - s) + 1) + 16;
            if (guess > ((size_t)1 << 22))
                guess = (size_t)1 << 22;
            if (guess > b->max_points)
                guess = (size_t)b->max_points;
            if (st == TESSEL_OK)
                st = tsl_builder_reserve(b, guess, 0);
            if (st != TESSEL_OK) {
                tsl_diag_set(diag, name, it.line, 0, 0, "%s", tessel_status_str(st));
                return st;
            }
        }

        double v[COL_ROLES] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
        uint8_t rgb[3] = {0, 0, 0};
        const char *p = s;
        size_t col = 0;
        while (p < e && col < lay.columns) {
            int r = lay.role[col];
            const char *tok = p;
            if (r == COL_SKIP) {
                p = token_end(p, e);
            } else if (!scan_value(&p, e, &v[r])) {
                const char *te = token_end(tok, e);
                tsl_diag_set(diag, name, it.line, 0, 0, "bad number '%.*s' in column %zu",
                             (int)(te - tok > 40 ? 40 : te - tok), tok, col + 1);
                return TESSEL_ERR_PARSE;
            } else if (r >= COL_R) {
                rgb[r - COL_R] = colour_byte(v[r], tok, p);
            }
            col++;
            p = skip_separator(p, e);
        }
        if (col != lay.columns || p != e) {
            size_t got = col + count_fields(p, e);
            if (lay.named)
                tsl_diag_set(diag, name, it.line, 0, 0,
                             "expected %zu values (the columns named on line %llu), got %zu",
                             lay.columns, (unsigned long long)lay.defined_at, got);
            else
                tsl_diag_set(diag, name, it.line, 0, 0,
                             "expected %zu numbers (like line %llu), got %zu", lay.columns,
                             (unsigned long long)lay.defined_at, got);
            return TESSEL_ERR_PARSE;
        }
        bool ambiguous = lay.has_normals && !lay.named;
        if (ambiguous && decided < 0 && tsl_builder_full(b)) {
            /* This point flushes the first chunk: decide now. */
            decided = colour_like && long_vector;
            if (decided && (st = normals_to_colours(b)) != TESSEL_OK) {
                tsl_diag_set(diag, name, it.line, 0, 0, "%s", tessel_status_str(st));
                return st;
            }
        }
        if (ambiguous && colour_like) {
            double len2 = 0;
            for (int k = COL_NX; k <= COL_NZ; k++) {
                colour_like = colour_like && v[k] >= 0 && v[k] <= 255 && v[k] == floor(v[k]);
                len2 += v[k] * v[k];
            }
            long_vector = long_vector || len2 > 2.25;
        }
        float normal[3] = {(float)v[COL_NX], (float)v[COL_NY], (float)v[COL_NZ]};
        if (decided == 1) {
            if (!colour_like)
                return sink_colours(diag, name, it.line, b, 1);
            for (int k = 0; k < 3; k++)
                rgb[k] = (uint8_t)normal[k]; /* as normals_to_colours */
            st = tsl_builder_point(b, v, NULL, rgb);
        } else {
            st = tsl_builder_point(b, v, lay.has_normals ? normal : NULL,
                                   lay.has_rgb ? rgb : NULL);
        }
        if (st != TESSEL_OK) {
            tsl_diag_set(diag, name, it.line, 0, 0, "point %llu: %s",
                         (unsigned long long)tsl_builder_pushed(b) + 1, tessel_status_str(st));
            return st;
        }
        block_seen++;
    }
    if (pts && block_seen != block_expected) {
        tsl_diag_set(diag, name, block_line, 0, 0,
                     "PTS block announces %llu points but has %llu",
                     (unsigned long long)block_expected, (unsigned long long)block_seen);
        return TESSEL_ERR_PARSE;
    }
    if (decided == 0 && colour_like && long_vector)
        return sink_colours(diag, name, it.line, b, 0);
    if (decided < 0 && have_layout && lay.has_normals && !lay.named && colour_like &&
        long_vector) {
        st = normals_to_colours(b);
        if (st != TESSEL_OK) {
            tsl_diag_set(diag, name, it.line, 0, 0, "%s", tessel_status_str(st));
            return st;
        }
    }
    return TESSEL_OK;
}

/* ---- writer ---- */

static bool xyz_csv(const tessel_write_params *params)
{
    return params && params->format == TESSEL_FORMAT_CSV;
}

static tessel_status xyz_begin(FILE *fp, const tsl_vertices *v, size_t vertex_count,
                               size_t face_count, const tessel_write_params *params)
{
    (void)vertex_count;
    (void)face_count;
    bool csv = xyz_csv(params);
    bool n = tsl_writes_normals(v, params), c = tsl_writes_rgb(v, params);
    /* XYZ stays bare for 3 and 6 columns, which read back by their count;
     * colours need the names. CSV always names its columns. */
    if (!csv && !c)
        return TESSEL_OK;
    const char *sep = csv ? "," : " ";
    if (fprintf(fp, "%sx%sy%sz", csv ? "" : "# ", sep, sep) < 0 ||
        (n && fprintf(fp, "%snx%sny%snz", sep, sep, sep) < 0) ||
        (c && fprintf(fp, "%sr%sg%sb", sep, sep, sep) < 0) || fputc('\n', fp) == EOF)
        return TESSEL_ERR_IO;
    return TESSEL_OK;
}

static tessel_status xyz_vertices(FILE *fp, const tsl_vertices *v, const uint32_t *subset,
                                  size_t n, const tessel_write_params *params)
{
    char sep = xyz_csv(params) ? ',' : ' ';
    bool wn = tsl_writes_normals(v, params), wc = tsl_writes_rgb(v, params);
    char buf[256];
    for (size_t i = 0; i < n; i++) {
        size_t j = subset ? subset[i] : i;
        int len = 0;
        for (int k = 0; k < 3; k++) {
            if (k)
                buf[len++] = sep;
            len += tsl_format_coord(buf + len, v->offset[k], v->xyz[3 * j + k]);
        }
        if (wn)
            len += snprintf(buf + len, sizeof buf - (size_t)len, "%c%.9g%c%.9g%c%.9g", sep,
                            (double)v->normals[3 * j], sep, (double)v->normals[3 * j + 1],
                            sep, (double)v->normals[3 * j + 2]);
        if (wc)
            len += snprintf(buf + len, sizeof buf - (size_t)len, "%c%u%c%u%c%u", sep,
                            v->rgb[3 * j], sep, v->rgb[3 * j + 1], sep, v->rgb[3 * j + 2]);
        buf[len++] = '\n';
        if (fwrite(buf, 1, (size_t)len, fp) != (size_t)len)
            return TESSEL_ERR_IO;
    }
    return TESSEL_OK;
}

const tsl_format_writer tsl_writer_xyz = {TESSEL_FORMAT_XYZ, xyz_begin, xyz_vertices, NULL,
                                          NULL};
