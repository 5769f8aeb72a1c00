/* The public I/O entry points: format names and detection, read and write
 * parameters, reading from memory or files through the per-format parsers
 * and the shared builder, writing through the per-format writers and an
 * atomic output file, and the streaming mesh writer. */
#include "io_internal.h"

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
