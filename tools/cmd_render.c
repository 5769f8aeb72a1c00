/* tessel render IN OUT.png: a picture of a mesh or a point cloud. */
#include "cli.h"
#include "png_writer.h"

#include <stdlib.h>
#include <string.h>

static const char render_help[] =
    "usage: tessel render IN OUT.png [options]\n"
    "\n"
    "Draws a mesh or a point cloud (any supported format) into a PNG image:\n"
    "front faces light grey, back faces blue (so flipped triangles show),\n"
    "boundary edges red (so holes show). A cloud, or a mesh file without\n"
    "faces, is drawn as points coloured by their rgb, their normals or depth.\n"
    "\n"
    "Options:\n"
    "  --view V        front, back, left, right, top, iso (default) or all\n"
    "                  (a 2x2 sheet of front, right, top and iso)\n"
    "  --size WxH      image size in pixels (default 1024x768; at most 16384)\n"
    "  --up y|z        which axis points up (default y; z for terrain, LAS)\n"
    "  --edges         draw every triangle edge\n"
    "  --points        draw the mesh's vertices as points too\n"
    "  --point-size N  point width in pixels (default: from the point count)\n"
    "  --no-boundary   do not mark boundary edges\n";

static bool parse_size(const char *text, uint32_t *w, uint32_t *h)
{
    char *end = NULL;
    unsigned long a = strtoul(text, &end, 10);
    if (end == text || (*end != 'x' && *end != 'X'))
        return false;
    const char *b = end + 1;
    unsigned long c = strtoul(b, &end, 10);
    if (end == b || *end != '\0' || a < 1 || c < 1 || a > 16384 || c > 16384)
        return false;
    *w = (uint32_t)a;
    *h = (uint32_t)c;
    return true;
}

int cmd_render(int argc, char **argv)
{
    cli_common common = {0};
    tessel_render_params params = tessel_render_params_default();
    const char *paths[2] = {NULL, NULL};
    int npaths = 0;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        int c = cli_common_option(&common, argc, argv, &i);
        if (c < 0)
            return CLI_USAGE;
        if (c > 0)
            continue;
        bool has_value = i + 1 < argc;
        if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
            fputs(render_help, stdout);
            fputs(cli_common_help, stdout);
            return CLI_OK;
        } else if (strcmp(a, "--view") == 0 && has_value) {
            int v = tessel_view_from_name(argv[++i]);
            if (v < 0) {
                cli_error("--view expects front, back, left, right, top, iso or all, got '%s'",
                          argv[i]);
                return CLI_USAGE;
            }
            params.view = (tessel_view)v;
        } else if (strcmp(a, "--size") == 0 && has_value) {
            if (!parse_size(argv[++i], &params.width, &params.height)) {
                cli_error("--size expects WxH with 1..16384 pixels each, got '%s'", argv[i]);
                return CLI_USAGE;
            }
        } else if (strcmp(a, "--up") == 0 && has_value) {
            const char *u = argv[++i];
            if (strcmp(u, "y") != 0 && strcmp(u, "z") != 0) {
                cli_error("--up expects y or z, got '%s'", u);
                return CLI_USAGE;
            }
            params.z_up = u[0] == 'z';
        } else if (strcmp(a, "--point-size") == 0 && has_value) {
            long n;
            if (!cli_parse_int(a, argv[++i], 1, 64, &n))
                return CLI_USAGE;
            params.point_size = (uint32_t)n;
        } else if (strcmp(a, "--edges") == 0) {
            params.edges = 1;
        } else if (strcmp(a, "--points") == 0) {
            params.points = 1;
        } else if (strcmp(a, "--no-boundary") == 0) {
            params.boundary = 0;
        } else if (a[0] == '-' && a[1] != '\0') {
            if (!has_value && (strcmp(a, "--view") == 0 || strcmp(a, "--size") == 0 ||
                               strcmp(a, "--up") == 0 || strcmp(a, "--point-size") == 0))
                cli_error("%s needs a value", a);
            else
                cli_error("unknown option '%s' (see tessel render --help)", a);
            return CLI_USAGE;
        } else if (npaths < 2) {
            paths[npaths++] = a;
        } else {
            cli_error("too many arguments: '%s' (see tessel render --help)", a);
            return CLI_USAGE;
        }
    }
    if (npaths != 2) {
        cli_error("render needs IN and OUT.png (see tessel render --help)");
        return CLI_USAGE;
    }
    cli_apply_threads(&common);
    params.threads = common.threads;

    double t0 = cli_now();
    tessel_mesh mesh;
    tessel_diag diag;
    memset(&diag, 0, sizeof diag);
    tessel_status st = tessel_mesh_read(&mesh, paths[0], NULL, &diag);
    if (st != TESSEL_OK) {
        cli_error_status(st, &diag, paths[0]);
        return cli_exit_for_read(st);
    }
    double t1 = cli_now();
    size_t bytes = (size_t)params.width * params.height * 3;
    uint8_t *rgb = malloc(bytes);
    if (!rgb) {
        cli_error("out of memory for a %ux%u image", (unsigned)params.width,
                  (unsigned)params.height);
        tessel_mesh_free(&mesh);
        return CLI_FAILURE;
    }
    st = tessel_render(&mesh, &params, rgb);
    if (st != TESSEL_OK) {
        cli_error("%s: %s", paths[0], tessel_status_str(st));
        free(rgb);
        tessel_mesh_free(&mesh);
        return st == TESSEL_ERR_INVALID_ARG ? CLI_INPUT_ERROR : CLI_FAILURE;
    }
    double t2 = cli_now();
    char err[256];
    if (png_write_rgb(paths[1], rgb, params.width, params.height, err, sizeof err) != 0) {
        cli_error("%s: %s", paths[1], err);
        free(rgb);
        tessel_mesh_free(&mesh);
        return CLI_OUTPUT_ERROR;
    }
    double t3 = cli_now();
    static const char *const view_names[] = {"front", "back", "left", "right",
                                             "top",   "iso",  "all"};
    if (common.json) {
        printf("{\"input\": ");
        cli_json_string(stdout, paths[0]);
        printf(", \"output\": ");
        cli_json_string(stdout, paths[1]);
        printf(", \"vertices\": %zu, \"triangles\": %zu, \"view\": \"%s\", \"width\": %u, "
               "\"height\": %u, \"read_seconds\": %.3f, \"render_seconds\": %.3f, "
               "\"write_seconds\": %.3f}\n",
               mesh.vertex_count, mesh.triangle_count, view_names[params.view],
               (unsigned)params.width, (unsigned)params.height, t1 - t0, t2 - t1, t3 - t2);
    } else if (!common.quiet) {
        fprintf(stderr, "%s: %zu vertices, %zu triangles -> %s (%s view, %ux%u): read %.2f s, "
                        "render %.2f s, write %.2f s\n",
                paths[0], mesh.vertex_count, mesh.triangle_count, paths[1],
                view_names[params.view], (unsigned)params.width, (unsigned)params.height,
                t1 - t0, t2 - t1, t3 - t2);
    }
    free(rgb);
    tessel_mesh_free(&mesh);
    return CLI_OK;
}
