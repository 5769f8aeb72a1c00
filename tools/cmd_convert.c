/* tessel convert IN OUT: any readable format to any writable one. */
#include "cli.h"

#include <string.h>

static const char convert_help[] =
    "usage: tessel convert IN OUT [--ascii] [--format FMT] [--no-normals] [--no-colours]\n\n"
    "Converts between formats. Reads PLY, XYZ/PTS/CSV, OBJ, OFF, PCD, LAS;\n"
    "writes PLY, XYZ/CSV, OBJ, OFF, STL. Formats follow the file extensions;\n"
    "--format overrides the output's. Meshes keep their triangles where the\n"
    "output format can hold them. --ascii writes ascii PLY.\n\n";

static const struct {
    const char *name;
    tessel_format format;
} output_formats[] = {
    {"ply", TESSEL_FORMAT_PLY}, {"xyz", TESSEL_FORMAT_XYZ}, {"csv", TESSEL_FORMAT_CSV},
    {"obj", TESSEL_FORMAT_OBJ}, {"off", TESSEL_FORMAT_OFF}, {"stl", TESSEL_FORMAT_STL},
};

static bool parse_format(const char *text, tessel_format *out)
{
    for (size_t i = 0; i < sizeof output_formats / sizeof output_formats[0]; i++) {
        if (strcmp(text, output_formats[i].name) == 0) {
            *out = output_formats[i].format;
            return true;
        }
    }
    cli_error("--format expects ply, xyz, csv, obj, off or stl, got '%s'", text);
    return false;
}

typedef struct convert_opts {
    tessel_write_params wp;
} convert_opts;

static int convert_option(void *ctx, int argc, char **argv, int *i)
{
    convert_opts *o = ctx;
    const char *a = argv[*i];
    if (strcmp(a, "--ascii") == 0) {
        o->wp.ascii = 1;
        return 1;
    }
    if (strcmp(a, "--no-normals") == 0) {
        o->wp.write_normals = 0;
        return 1;
    }
    if (strcmp(a, "--no-colours") == 0 || strcmp(a, "--no-colors") == 0) {
        o->wp.write_rgb = 0;
        return 1;
    }
    if (strcmp(a, "--format") == 0) {
        const char *v = cli_option_value(argc, argv, i);
        return v && parse_format(v, &o->wp.format) ? 1 : -1;
    }
    return 0;
}

/* Whether a file of this format can hold triangles. */
static bool holds_faces(tessel_format f)
{
    return f == TESSEL_FORMAT_PLY || f == TESSEL_FORMAT_OBJ || f == TESSEL_FORMAT_OFF ||
           f == TESSEL_FORMAT_STL;
}

int cmd_convert(int argc, char **argv)
{
    cli_common common = {0};
    convert_opts o = {tessel_write_params_default()};
    const char *in = NULL, *out = NULL;
    int r = cli_parse_in_out(argc, argv, convert_help, &common, &in, &out, convert_option, &o);
    if (r <= 0)
        return r == 0 ? CLI_OK : CLI_USAGE;
    cli_apply_threads(&common);

    tessel_format out_format = o.wp.format != TESSEL_FORMAT_AUTO ? o.wp.format
                                                                 : tessel_format_from_path(out);
    if (out_format == TESSEL_FORMAT_AUTO) {
        cli_error("%s: unknown output format (use an extension such as .ply or --format)",
                  out);
        return CLI_USAGE;
    }
    if (out_format == TESSEL_FORMAT_PCD || out_format == TESSEL_FORMAT_LAS) {
        cli_error("%s: tessel reads %s but does not write it", out,
                  tessel_format_name(out_format));
        return CLI_USAGE;
    }
    double t0 = cli_now();
    tessel_diag diag = {0};
    tessel_status st;
    tessel_format in_format = tessel_format_from_path(in);
    /* Meshes keep their triangles; everything else goes through the cloud
     * path, which keeps organized layout and viewpoint. */
    bool as_mesh = holds_faces(out_format) &&
                   (in_format == TESSEL_FORMAT_OBJ || in_format == TESSEL_FORMAT_OFF);
    tessel_mesh mesh = {0};
    tessel_cloud cloud = {0};
    if (in_format == TESSEL_FORMAT_PLY && holds_faces(out_format)) {
        /* A PLY may be either: read it as a mesh only when it has faces. */
        st = tessel_mesh_read(&mesh, in, NULL, &diag);
        if (st == TESSEL_OK && mesh.triangle_count > 0)
            as_mesh = true;
        else
            tessel_mesh_free(&mesh);
    }
    if (as_mesh && mesh.xyz == NULL)
        st = tessel_mesh_read(&mesh, in, NULL, &diag);
    else if (!as_mesh) {
        tessel_read_params rp = cli_read_params(&common);
        st = tessel_cloud_read(&cloud, in, &rp, &diag);
    }
    else
        st = TESSEL_OK;
    if (st != TESSEL_OK) {
        cli_error_status(st, &diag, in);
        return cli_exit_for_read(st);
    }
    size_t points = as_mesh ? mesh.vertex_count : cloud.count;
    o.wp.format = out_format;
    st = as_mesh ? tessel_mesh_write(&mesh, out, &o.wp, &diag)
                 : tessel_cloud_write(&cloud, out, &o.wp, &diag);
    size_t triangles = as_mesh ? mesh.triangle_count : 0;
    size_t dropped = as_mesh ? 0 : cloud.dropped_nonfinite;
    tessel_mesh_free(&mesh);
    tessel_cloud_free(&cloud);
    if (st != TESSEL_OK) {
        cli_error_status(st, &diag, out);
        return cli_exit_for_write(st);
    }
    double seconds = cli_now() - t0;
    if (common.json)
        printf("{\"points\": %zu, \"triangles\": %zu, \"nonfinite_dropped\": %zu, "
               "\"seconds\": %.6f}\n",
               points, triangles, dropped, seconds);
    else if (!common.quiet)
        fprintf(stderr, "tessel: wrote %s: %zu points, %zu triangles (%zu NaN/Inf dropped) "
                        "in %.2f s\n",
                out, points, triangles, dropped, seconds);
    return CLI_OK;
}
