/* The public I/O entry points: format names and detection, read and write
 * parameters, reading from memory or files through the per-format parsers
 * and the shared builder, writing through the per-format writers and an
 * atomic output file, and the streaming mesh writer. */
#include "io/io.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

const char *tessel_format_name(tessel_format format)
{
    switch (format) {
    case TESSEL_FORMAT_AUTO: return "auto";
    case TESSEL_FORMAT_PLY: return "ply";
    case TESSEL_FORMAT_XYZ: return "xyz";
    case TESSEL_FORMAT_CSV: return "csv";
    case TESSEL_FORMAT_OBJ: return "obj";
    case TESSEL_FORMAT_OFF: return "off";
    case TESSEL_FORMAT_STL: return "stl";
    case TESSEL_FORMAT_PCD: return "pcd";
    case TESSEL_FORMAT_LAS: return "las";
    }
    return "unknown";
}

static bool ext_is(const char *ext, const char *want)
{
    for (; *ext && *want; ext++, want++) {
        char c = *ext;
        if (c >= 'A' && c <= 'Z')
            c = (char)(c - 'A' + 'a');
        if (c != *want)
            return false;
    }
    return *ext == 0 && *want == 0;
}

tessel_format tessel_format_from_path(const char *path)
{
    if (!path)
        return TESSEL_FORMAT_AUTO;
    const char *slash = strrchr(path, '/');
    const char *base = slash ? slash + 1 : path;
    const char *dot = strrchr(base, '.');
    if (!dot || dot == base)
        return TESSEL_FORMAT_AUTO;
    const char *ext = dot + 1;
    static const struct {
        const char *ext;
        tessel_format format;
    } table[] = {
        {"ply", TESSEL_FORMAT_PLY}, {"xyz", TESSEL_FORMAT_XYZ}, {"pts", TESSEL_FORMAT_XYZ},
        {"txt", TESSEL_FORMAT_XYZ}, {"asc", TESSEL_FORMAT_XYZ}, {"csv", TESSEL_FORMAT_CSV},
        {"obj", TESSEL_FORMAT_OBJ}, {"off", TESSEL_FORMAT_OFF}, {"stl", TESSEL_FORMAT_STL},
        {"pcd", TESSEL_FORMAT_PCD}, {"las", TESSEL_FORMAT_LAS},
    };
    for (size_t i = 0; i < sizeof table / sizeof table[0]; i++)
        if (ext_is(ext, table[i].ext))
            return table[i].format;
    return TESSEL_FORMAT_AUTO;
}

tessel_read_params tessel_read_params_default(void)
{
    tessel_read_params p;
    p.format = TESSEL_FORMAT_AUTO;
    p.max_points = ((uint64_t)1 << 31) - 1;
    p.max_faces = ((uint64_t)1 << 31) - 1;
    p.bbox = NULL;
    return p;
}

tessel_write_params tessel_write_params_default(void)
{
    tessel_write_params p;
    p.format = TESSEL_FORMAT_AUTO;
    p.ascii = 0;
    p.write_normals = 1;
    p.write_rgb = 1;
    return p;
}

/* ---- reading ---- */

static tsl_parse_fn parser_for(tessel_format format)
{
    switch (format) {
    case TESSEL_FORMAT_PLY: return tsl_parse_ply;
    case TESSEL_FORMAT_XYZ:
    case TESSEL_FORMAT_CSV: return tsl_parse_xyz;
    case TESSEL_FORMAT_OBJ: return tsl_parse_obj;
    case TESSEL_FORMAT_OFF: return tsl_parse_off;
    case TESSEL_FORMAT_PCD: return tsl_parse_pcd;
    case TESSEL_FORMAT_LAS: return tsl_parse_las;
    default: return NULL;
    }
}

static bool starts_with(const uint8_t *d, size_t n, const char *s)
{
    size_t k = strlen(s);
    return n >= k && memcmp(d, s, k) == 0;
}

/* Content sniffing, in the order tessel.h documents: PLY, OFF, PCD and LAS
 * by their first bytes; OBJ when a line starts with "v "; else XYZ (whose
 * reader also takes comma-separated values). */
static tessel_format sniff(const uint8_t *d, size_t n)
{
    if (starts_with(d, n, "ply\n") || starts_with(d, n, "ply\r\n"))
        return TESSEL_FORMAT_PLY;
    if (starts_with(d, n, "LASF"))
        return TESSEL_FORMAT_LAS;
    /* OFF and its variants: [ST][C][N][4][n]OFF as the first token. */
    size_t t = 0;
    while (t < n && t < 8 && d[t] != ' ' && d[t] != '\t' && d[t] != '\r' && d[t] != '\n')
        t++;
    if (t >= 3 && t < 8 && memcmp(d + t - 3, "OFF", 3) == 0)
        return TESSEL_FORMAT_OFF;
    if (starts_with(d, n, "# .PCD") || starts_with(d, n, "VERSION") ||
        starts_with(d, n, "FIELDS"))
        return TESSEL_FORMAT_PCD;
    /* OBJ: a vertex line near the start (comments and groups come first in
     * real files, never megabytes of them). */
    size_t limit = n < ((size_t)1 << 20) ? n : ((size_t)1 << 20);
    for (size_t i = 0; i + 1 < limit;) {
        if (d[i] == 'v' && (d[i + 1] == ' ' || d[i + 1] == '\t'))
            return TESSEL_FORMAT_OBJ;
        const uint8_t *nl = memchr(d + i, '\n', limit - i);
        if (!nl)
            break;
        i = (size_t)(nl - d) + 1;
    }
    return TESSEL_FORMAT_XYZ;
}

/* The format to read with: params first, then the name's extension, then
 * the content. */
static tessel_status read_format(const uint8_t *data, size_t size, const char *name,
                                 const tessel_read_params *params, tsl_parse_fn *fn,
                                 tessel_diag *diag)
{
    tessel_format f = params->format;
    if (f == TESSEL_FORMAT_AUTO)
        f = tessel_format_from_path(name);
    if (f == TESSEL_FORMAT_AUTO)
        f = sniff(data, size);
    *fn = parser_for(f);
    if (!*fn) {
        tsl_diag_set(diag, name, 0, 0, 0, "%s files cannot be read%s", tessel_format_name(f),
                     f == TESSEL_FORMAT_STL ? " (STL is a triangle soup: use PLY, OBJ or OFF)"
                                            : "");
        return f == TESSEL_FORMAT_AUTO ? TESSEL_ERR_INVALID_ARG : TESSEL_ERR_UNSUPPORTED;
    }
    return TESSEL_OK;
}

static void diag_clear(tessel_diag *diag)
{
    if (diag)
        memset(diag, 0, sizeof *diag);
}

tessel_status tsl_read_setup(const uint8_t *data, size_t size, const char *name,
                             const tessel_read_params *params, tsl_builder *b,
                             tsl_parse_fn *fn, tessel_diag *diag)
{
    tessel_read_params def = tessel_read_params_default();
    if (!params)
        params = &def;
    tessel_status st = read_format(data, size, name, params, fn, diag);
    if (st != TESSEL_OK)
        return st;
    tsl_builder_init(b, params);
    if (params->bbox) {
        /* A box filters LAS records as they are emitted (src/io/las.c). */
        const double *box = params->bbox;
        for (int k = 0; k < 3; k++)
            if (!(box[k] <= box[k + 3])) {
                tsl_diag_set(diag, name, 0, 0, 0,
                             "bounding box %c range [%g, %g] is empty or not a number",
                             "xyz"[k], box[k], box[k + 3]);
                return TESSEL_ERR_INVALID_ARG;
            }
        if (*fn != tsl_parse_las) {
            tsl_diag_set(diag, name, 0, 0, 0,
                         "a bounding box applies to LAS and LAZ input only");
            return TESSEL_ERR_UNSUPPORTED;
        }
        b->bbox = box;
    }
    return TESSEL_OK;
}

/* What tessel_cloud_parse and tessel_mesh_parse share: the arguments
 * checked (a NULL name reads as ""), the data parsed into b, which the
 * caller frees in any case; on failure diag says something. */
static tessel_status parse_buffer(tsl_builder *b, const void *data, size_t size,
                                  const char **name, const tessel_read_params *params,
                                  int want_faces, tessel_diag *diag)
{
    memset(b, 0, sizeof *b);
    if (!data && size)
        return TESSEL_ERR_INVALID_ARG;
    if (!*name)
        *name = "";
    if (!data)
        data = "";
    tsl_parse_fn fn;
    tessel_status st = tsl_read_setup(data, size, *name, params, b, &fn, diag);
    if (st != TESSEL_OK)
        return st;
    st = fn(data, size, *name, want_faces, b, diag);
    if (st != TESSEL_OK && diag && !diag->message[0])
        tsl_diag_set(diag, *name, 0, 0, 0, "%s", tessel_status_str(st));
    return st;
}

tessel_status tessel_cloud_parse(tessel_cloud *cloud, const void *data, size_t size,
                                 const char *name, const tessel_read_params *params,
                                 tessel_diag *diag)
{
    diag_clear(diag);
    if (!cloud)
        return TESSEL_ERR_INVALID_ARG;
    memset(cloud, 0, sizeof *cloud);
    tsl_builder b;
    tessel_status st = parse_buffer(&b, data, size, &name, params, 0, diag);
    if (st == TESSEL_OK) {
        st = tsl_builder_finish_cloud(&b, cloud);
        if (st != TESSEL_OK)
            tsl_diag_set(diag, name, 0, 0, 0, "%s", tessel_status_str(st));
    }
    tsl_builder_free(&b);
    if (st != TESSEL_OK)
        tessel_cloud_free(cloud);
    return st;
}

tessel_status tessel_mesh_parse(tessel_mesh *mesh, const void *data, size_t size,
                                const char *name, const tessel_read_params *params,
                                tessel_diag *diag)
{
    diag_clear(diag);
    if (!mesh)
        return TESSEL_ERR_INVALID_ARG;
    memset(mesh, 0, sizeof *mesh);
    tsl_builder b;
    tessel_status st = parse_buffer(&b, data, size, &name, params, 1, diag);
    if (st == TESSEL_OK) {
        st = tsl_builder_finish_mesh(&b, mesh);
        if (st != TESSEL_OK)
            tsl_diag_set(diag, name, 0, 0, 0, "%s", tessel_status_str(st));
    }
    tsl_builder_free(&b);
    if (st != TESSEL_OK)
        tessel_mesh_free(mesh);
    return st;
}

tessel_status tessel_cloud_read(tessel_cloud *cloud, const char *path,
                                const tessel_read_params *params, tessel_diag *diag)
{
    diag_clear(diag);
    if (!cloud)
        return TESSEL_ERR_INVALID_ARG;
    memset(cloud, 0, sizeof *cloud);
    uint8_t *data;
    size_t size;
    tessel_status st = tsl_read_file(path, &data, &size, diag);
    if (st != TESSEL_OK)
        return st;
    st = tessel_cloud_parse(cloud, data, size, path, params, diag);
    free(data);
    return st;
}

tessel_status tessel_mesh_read(tessel_mesh *mesh, const char *path,
                               const tessel_read_params *params, tessel_diag *diag)
{
    diag_clear(diag);
    if (!mesh)
        return TESSEL_ERR_INVALID_ARG;
    memset(mesh, 0, sizeof *mesh);
    uint8_t *data;
    size_t size;
    tessel_status st = tsl_read_file(path, &data, &size, diag);
    if (st != TESSEL_OK)
        return st;
    st = tessel_mesh_parse(mesh, data, size, path, params, diag);
    free(data);
    return st;
}

/* ---- writing ---- */

static const tsl_format_writer *writer_for(tessel_format format)
{
    switch (format) {
    case TESSEL_FORMAT_PLY: return &tsl_writer_ply;
    case TESSEL_FORMAT_XYZ:
    case TESSEL_FORMAT_CSV: return &tsl_writer_xyz;
    case TESSEL_FORMAT_OBJ: return &tsl_writer_obj;
    case TESSEL_FORMAT_OFF: return &tsl_writer_off;
    case TESSEL_FORMAT_STL: return &tsl_writer_stl;
    default: return NULL;
    }
}

tessel_status tsl_write_setup(const char *path, const tessel_write_params *params,
                              tessel_write_params *eff, const tsl_format_writer **w,
                              tessel_diag *diag)
{
    *eff = params ? *params : tessel_write_params_default();
    if (!path || !*path) {
        tsl_diag_set(diag, "", 0, 0, 0, "no output path given");
        return TESSEL_ERR_INVALID_ARG;
    }
    if (eff->format == TESSEL_FORMAT_AUTO)
        eff->format = tessel_format_from_path(path);
    if (eff->format == TESSEL_FORMAT_AUTO) {
        tsl_diag_set(diag, path, 0, 0, 0,
                     "cannot tell the output format from the file name "
                     "(use .ply .xyz .csv .obj .off or .stl)");
        return TESSEL_ERR_INVALID_ARG;
    }
    *w = writer_for(eff->format);
    if (!*w) {
        tsl_diag_set(diag, path, 0, 0, 0, "%s files cannot be written (read only)",
                     tessel_format_name(eff->format));
        return TESSEL_ERR_UNSUPPORTED;
    }
    return TESSEL_OK;
}

tessel_status tsl_write_finish(tsl_outfile *out, tessel_status st, const char *path,
                              tessel_diag *diag)
{
    if (st == TESSEL_OK && ferror(out->fp))
        st = TESSEL_ERR_IO;
    if (st != TESSEL_OK) {
        int err = errno;
        tsl_outfile_abort(out);
        if (st == TESSEL_ERR_IO)
            tsl_diag_set(diag, path, 0, 0, 0, "write failed: %s", strerror(err ? err : EIO));
        else
            tsl_diag_set(diag, path, 0, 0, 0, "%s", tessel_status_str(st));
        return st;
    }
    return tsl_outfile_commit(out, diag);
}

static tsl_vertices vertices_of(size_t count, const float *xyz, const float *normals,
                                const uint8_t *rgb, const double offset[3])
{
    tsl_vertices v;
    v.count = count;
    v.xyz = xyz;
    v.normals = normals;
    v.rgb = rgb;
    memcpy(v.offset, offset, sizeof v.offset);
    return v;
}

tessel_status tessel_cloud_write(const tessel_cloud *cloud, const char *path,
                                 const tessel_write_params *params, tessel_diag *diag)
{
    diag_clear(diag);
    if (!cloud || (cloud->count && !cloud->xyz))
        return TESSEL_ERR_INVALID_ARG;
    tessel_write_params eff;
    const tsl_format_writer *w;
    tessel_status st = tsl_write_setup(path, params, &eff, &w, diag);
    if (st != TESSEL_OK)
        return st;
    if (!w->vertices) {
        tsl_diag_set(diag, path, 0, 0, 0, "%s stores triangles only: write the cloud as "
                     "PLY, XYZ, CSV, OBJ or OFF", tessel_format_name(eff.format));
        return TESSEL_ERR_UNSUPPORTED;
    }
    tsl_outfile out;
    if ((st = tsl_outfile_open(&out, path, diag)) != TESSEL_OK)
        return st;
    if (eff.format == TESSEL_FORMAT_PLY) {
        st = tsl_ply_write_cloud(out.fp, cloud, &eff);
    } else {
        tsl_vertices v =
            vertices_of(cloud->count, cloud->xyz, cloud->normals, cloud->rgb, cloud->offset);
        st = w->begin ? w->begin(out.fp, &v, v.count, 0, &eff) : TESSEL_OK;
        if (st == TESSEL_OK)
            st = w->vertices(out.fp, &v, NULL, v.count, &eff);
        if (st == TESSEL_OK && w->end)
            st = w->end(out.fp, &eff);
    }
    return tsl_write_finish(&out, st, path, diag);
}

tessel_status tessel_mesh_write(const tessel_mesh *mesh, const char *path,
                                const tessel_write_params *params, tessel_diag *diag)
{
    diag_clear(diag);
    if (!mesh || (mesh->vertex_count && !mesh->xyz) ||
        (mesh->triangle_count && !mesh->triangles))
        return TESSEL_ERR_INVALID_ARG;
    for (size_t i = 0; i < 3 * mesh->triangle_count; i++) {
        if (mesh->triangles[i] >= mesh->vertex_count) {
            tsl_diag_set(diag, path, 0, 0, 0,
                         "triangle %zu uses vertex %lu, but the mesh has %zu vertices", i / 3,
                         (unsigned long)mesh->triangles[i], mesh->vertex_count);
            return TESSEL_ERR_INVALID_ARG;
        }
    }
    tessel_write_params eff;
    const tsl_format_writer *w;
    tessel_status st = tsl_write_setup(path, params, &eff, &w, diag);
    if (st != TESSEL_OK)
        return st;
    tsl_outfile out;
    if ((st = tsl_outfile_open(&out, path, diag)) != TESSEL_OK)
        return st;
    tsl_vertices v =
        vertices_of(mesh->vertex_count, mesh->xyz, mesh->normals, mesh->rgb, mesh->offset);
    size_t faces = w->faces ? mesh->triangle_count : 0;
    if (w->begin)
        st = w->begin(out.fp, &v, v.count, faces, &eff);
    if (st == TESSEL_OK && w->vertices)
        st = w->vertices(out.fp, &v, NULL, v.count, &eff);
    if (st == TESSEL_OK && w->faces)
        st = w->faces(out.fp, &v, mesh->triangles, mesh->triangles, faces, &eff);
    if (st == TESSEL_OK && w->end)
        st = w->end(out.fp, &eff);
    return tsl_write_finish(&out, st, path, diag);
}

/* ---- streaming mesh writer ---- */

/* Triangles per spool read/write batch at close (12 bytes each). */
#define SPOOL_BATCH ((size_t)1 << 16)
/* Vertices per batch of the compacted vertex list. */
#define VERTEX_BATCH ((size_t)1 << 14)

struct tessel_mesh_writer {
    tsl_outfile out;          /* the destination's temporary */
    tsl_outfile spool;        /* raw triangles, uint32 host order */
    const tsl_format_writer *w;
    tessel_write_params params;
    tsl_vertices v;
    int compact;
    uint8_t *used;            /* compact: one bit per point */
    size_t tri_count;
    tessel_status error;      /* first failure of add(), reported by close */
};

void tessel_mesh_writer_abort(tessel_mesh_writer *writer)
{
    if (!writer)
        return;
    tsl_outfile_abort(&writer->out);
    tsl_outfile_abort(&writer->spool);
    free(writer->used);
    free(writer);
}

tessel_status tessel_mesh_writer_open(tessel_mesh_writer **writer, const char *path,
                                      const tessel_cloud *vertices,
                                      const tessel_write_params *params, int compact,
                                      tessel_diag *diag)
{
    diag_clear(diag);
    if (!writer)
        return TESSEL_ERR_INVALID_ARG;
    *writer = NULL;
    if (!vertices || (vertices->count && !vertices->xyz))
        return TESSEL_ERR_INVALID_ARG;
    tessel_mesh_writer *mw = calloc(1, sizeof *mw);
    if (!mw)
        return TESSEL_ERR_NOMEM;
    tessel_status st = tsl_write_setup(path, params, &mw->params, &mw->w, diag);
    if (st == TESSEL_OK && !mw->w->faces) {
        tsl_diag_set(diag, path, 0, 0, 0, "%s stores no triangles: write meshes as PLY, "
                     "OBJ, OFF or STL", tessel_format_name(mw->params.format));
        st = TESSEL_ERR_UNSUPPORTED;
    }
    if (st != TESSEL_OK) {
        free(mw);
        return st;
    }
    mw->v = vertices_of(vertices->count, vertices->xyz, vertices->normals, vertices->rgb,
                        vertices->offset);
    mw->compact = compact != 0;
    if (mw->compact) {
        mw->used = calloc(vertices->count / 8 + 1, 1);
        if (!mw->used) {
            free(mw);
            return TESSEL_ERR_NOMEM;
        }
    }
    /* Both temporaries now, so a bad folder fails before any work. The
     * spool is named after the destination and never renamed. */
    if ((st = tsl_outfile_open(&mw->out, path, diag)) != TESSEL_OK ||
        (st = tsl_outfile_open(&mw->spool, path, diag)) != TESSEL_OK) {
        tessel_mesh_writer_abort(mw);
        return st;
    }
    *writer = mw;
    return TESSEL_OK;
}

tessel_status tessel_mesh_writer_add(tessel_mesh_writer *writer, const uint32_t *triangles,
                                     size_t count)
{
    if (!writer || (count && !triangles))
        return TESSEL_ERR_INVALID_ARG;
    if (writer->error != TESSEL_OK)
        return writer->error;
    size_t n = writer->v.count;
    for (size_t i = 0; i < 3 * count; i++) {
        if (triangles[i] >= n) {
            writer->error = TESSEL_ERR_INVALID_ARG;
            return writer->error;
        }
    }
    if (writer->used)
        for (size_t i = 0; i < 3 * count; i++)
            writer->used[triangles[i] >> 3] |= (uint8_t)(1u << (triangles[i] & 7));
    if (count && fwrite(triangles, 3 * sizeof(uint32_t), count, writer->spool.fp) != count) {
        writer->error = TESSEL_ERR_IO;
        return writer->error;
    }
    writer->tri_count += count;
    return TESSEL_OK;
}

static tessel_status emit_adapter(void *user_data, const uint32_t *triangles, size_t count)
{
    return tessel_mesh_writer_add(user_data, triangles, count);
}

tessel_triangle_sink tessel_mesh_writer_sink(tessel_mesh_writer *writer)
{
    tessel_triangle_sink sink;
    sink.emit = emit_adapter;
    sink.user_data = writer;
    return sink;
}

/* Vertices of the final file, in batches: all of them, or the used ones in
 * index order. Fills remap (old -> new) when compacting. */
static tessel_status write_final_vertices(tessel_mesh_writer *mw, uint32_t *remap)
{
    const tsl_format_writer *w = mw->w;
    size_t n = mw->v.count;
    if (!w->vertices)
        return TESSEL_OK;
    if (!remap)
        return w->vertices(mw->out.fp, &mw->v, NULL, n, &mw->params);
    uint32_t batch[VERTEX_BATCH];
    size_t k = 0;
    for (size_t i = 0; i < n; i++) {
        if (remap[i] == TESSEL_NONE)
            continue;
        batch[k++] = (uint32_t)i;
        if (k == VERTEX_BATCH) {
            tessel_status st = w->vertices(mw->out.fp, &mw->v, batch, k, &mw->params);
            if (st != TESSEL_OK)
                return st;
            k = 0;
        }
    }
    return k ? w->vertices(mw->out.fp, &mw->v, batch, k, &mw->params) : TESSEL_OK;
}

/* The spooled triangles, renumbered, in batches. */
static tessel_status write_final_faces(tessel_mesh_writer *mw, const uint32_t *remap)
{
    FILE *in = fopen(mw->spool.tmp_path, "rb");
    if (!in)
        return TESSEL_ERR_IO;
    uint32_t *orig = tsl_alloc_array(SPOOL_BATCH, 3 * sizeof(uint32_t));
    uint32_t *tris = remap ? tsl_alloc_array(SPOOL_BATCH, 3 * sizeof(uint32_t)) : orig;
    tessel_status st = (orig && tris) ? TESSEL_OK : TESSEL_ERR_NOMEM;
    size_t left = mw->tri_count;
    while (st == TESSEL_OK && left) {
        size_t want = left < SPOOL_BATCH ? left : SPOOL_BATCH;
        if (fread(orig, 3 * sizeof(uint32_t), want, in) != want) {
            st = TESSEL_ERR_IO;
            break;
        }
        if (remap)
            for (size_t i = 0; i < 3 * want; i++)
                tris[i] = remap[orig[i]];
        st = mw->w->faces(mw->out.fp, &mw->v, tris, orig, want, &mw->params);
        left -= want;
    }
    fclose(in);
    if (tris != orig)
        free(tris);
    free(orig);
    return st;
}

tessel_status tessel_mesh_writer_close(tessel_mesh_writer *writer, tessel_diag *diag)
{
    diag_clear(diag);
    if (!writer)
        return TESSEL_ERR_INVALID_ARG;
    tessel_mesh_writer *mw = writer;
    char *path = mw->out.path;
    tessel_status st = mw->error;
    if (st != TESSEL_OK) {
        tsl_diag_set(diag, path, 0, 0, 0, "an earlier batch of triangles failed: %s",
                     tessel_status_str(st));
        tessel_mesh_writer_abort(mw);
        return st;
    }
    /* The spool must be complete on disk before it is read back. */
    if (fflush(mw->spool.fp) != 0 || ferror(mw->spool.fp)) {
        int err = errno;
        tsl_diag_set(diag, path, 0, 0, 0, "writing the triangle spool failed: %s",
                     strerror(err ? err : EIO));
        tessel_mesh_writer_abort(mw);
        return TESSEL_ERR_IO;
    }
    uint32_t *remap = NULL;
    size_t n = mw->v.count;
    if (mw->compact) {
        remap = tsl_alloc_array(n ? n : 1, sizeof(uint32_t));
        if (!remap) {
            tsl_diag_set(diag, path, 0, 0, 0, "out of memory for the vertex remap");
            tessel_mesh_writer_abort(mw);
            return TESSEL_ERR_NOMEM;
        }
        size_t k = 0;
        for (size_t i = 0; i < n; i++)
            remap[i] = (mw->used[i >> 3] >> (i & 7)) & 1 ? (uint32_t)k++ : TESSEL_NONE;
        n = k;
        free(mw->used);
        mw->used = NULL;
    }
    if (mw->w->begin)
        st = mw->w->begin(mw->out.fp, &mw->v, n, mw->tri_count, &mw->params);
    if (st == TESSEL_OK)
        st = write_final_vertices(mw, remap);
    if (st == TESSEL_OK)
        st = write_final_faces(mw, remap);
    if (st == TESSEL_OK && mw->w->end)
        st = mw->w->end(mw->out.fp, &mw->params);
    free(remap);
    tsl_outfile_abort(&mw->spool);
    /* finish_output names the path; keep a copy past the outfile's end. */
    char name[512];
    snprintf(name, sizeof name, "%s", path);
    st = tsl_write_finish(&mw->out, st, name, diag);
    free(mw);
    return st;
}
