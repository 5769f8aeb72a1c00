/* tessel sample MESH N OUT: points drawn uniformly over a mesh's area,
 * with optional Gaussian noise (the inputs of the benches and of users'
 * experiments). */
#include "cli.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static const char sample_help[] =
    "usage: tessel sample MESH N OUT [options]\n\n"
    "Draws N points uniformly distributed over the area of MESH (any mesh\n"
    "format), each with the unit normal of its triangle, and writes them to\n"
    "OUT. N may be written 1e6. The same seed gives the same points, for any\n"
    "thread count.\n\n"
    "Options:\n"
    "  --noise-rel F    add isotropic Gaussian noise of standard deviation F\n"
    "                   times MESH's bounding-box diagonal (0.005: 0.5%)\n"
    "  --noise S        the same in world units (wins over --noise-rel)\n"
    "  --seed S         random seed, a non-negative integer (default 1)\n"
    "  --no-normals     write positions only\n"
    "  --ascii          write ascii PLY\n\n";

typedef struct sample_opts {
    tessel_sample_params sp;
    int ascii;
} sample_opts;

static int sample_option(sample_opts *o, int argc, char **argv, int *i)
{
    const char *a = argv[*i];
    if (strcmp(a, "--no-normals") == 0) {
        o->sp.normals = 0;
        return 1;
    }
    if (strcmp(a, "--ascii") == 0) {
        o->ascii = 1;
        return 1;
    }
    if (strcmp(a, "--noise") == 0 || strcmp(a, "--noise-rel") == 0) {
        const char *v = cli_option_value(argc, argv, i);
        double x;
        if (!v || !cli_parse_double(a, v, &x))
            return -1;
        if (!(x >= 0.0) || !isfinite(x)) {
            cli_error("%s: must be a finite number >= 0, got '%s'", a, v);
            return -1;
        }
        if (a[7] == '\0')
            o->sp.noise = x;
        else
            o->sp.noise_rel = x;
        return 1;
    }
    if (strcmp(a, "--seed") == 0) {
        const char *v = cli_option_value(argc, argv, i);
        char *end;
        if (!v)
            return -1;
        unsigned long long s = strtoull(v, &end, 10);
        if (*v == '-' || end == v || *end) {
            cli_error("--seed: expected a non-negative integer, got '%s'", v);
            return -1;
        }
        o->sp.seed = (uint64_t)s;
        return 1;
    }
    return 0;
}

/* N: a positive integer, or a number like 1e6 that is one. */
static bool parse_count(const char *text, size_t *out)
{
    char *end;
    double x = strtod(text, &end);
    if (end == text || *end || !(x >= 1.0) || x > 4e9 || x != floor(x)) {
        cli_error("N: expected a whole number of points (1 to 4e9), got '%s'", text);
        return false;
    }
    *out = (size_t)x;
    return true;
}

int cmd_sample(int argc, char **argv)
{
    cli_common common = {0};
    sample_opts o = {tessel_sample_params_default(), 0};
    const char *pos[3] = {NULL, NULL, NULL};
    int npos = 0;
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "-h") == 0) {
            fputs(sample_help, stdout);
            fputs(cli_common_help, stdout);
            return CLI_OK;
        }
        int r = cli_common_option(&common, argc, argv, &i);
        if (r == 0)
            r = sample_option(&o, argc, argv, &i);
        if (r < 0)
            return CLI_USAGE;
        if (r > 0)
            continue;
        if (argv[i][0] == '-' && argv[i][1] != '\0' && !(argv[i][1] >= '0' && argv[i][1] <= '9')) {
            cli_error("sample: unknown option '%s'", argv[i]);
            return CLI_USAGE;
        }
        if (npos == 3) {
            cli_error("sample: expects MESH N OUT, got a fourth argument '%s'", argv[i]);
            return CLI_USAGE;
        }
        pos[npos++] = argv[i];
    }
    if (npos < 3) {
        fputs(sample_help, stderr);
        return CLI_USAGE;
    }
    size_t count;
    if (!parse_count(pos[1], &count))
        return CLI_USAGE;
    cli_apply_threads(&common);
    o.sp.threads = common.threads;

    double t0 = cli_now();
    tessel_mesh mesh = {0};
    tessel_diag diag = {0};
    tessel_status st = tessel_mesh_read(&mesh, pos[0], NULL, &diag);
    if (st != TESSEL_OK) {
        cli_error_status(st, &diag, pos[0]);
        return cli_exit_for_read(st);
    }
    if (mesh.triangle_count == 0) {
        cli_error("%s: no triangles to sample (a mesh is needed, not a point cloud)", pos[0]);
        tessel_mesh_free(&mesh);
        return CLI_INPUT_ERROR;
    }
    cli_progress progress;
    cli_progress_init(&progress, &common);
    tessel_callbacks cb = cli_callbacks(&progress);
    cli_progress_items(&progress, count);
    tessel_cloud cloud = {0};
    st = tessel_mesh_sample(&mesh, count, &o.sp, &cb, &cloud);
    cli_progress_done(&progress);
    tessel_mesh_free(&mesh);
    if (st != TESSEL_OK) {
        if (st == TESSEL_ERR_TOO_FEW_POINTS)
            cli_error("%s: the mesh has no area to sample", pos[0]);
        else
            cli_error("%s: sampling failed: %s", pos[0], tessel_status_str(st));
        return st == TESSEL_ERR_INVALID_ARG || st == TESSEL_ERR_TOO_FEW_POINTS ? CLI_INPUT_ERROR
                                                                                : CLI_FAILURE;
    }
    tessel_write_params wp = tessel_write_params_default();
    wp.ascii = o.ascii;
    st = tessel_cloud_write(&cloud, pos[2], &wp, &diag);
    tessel_cloud_free(&cloud);
    if (st != TESSEL_OK) {
        cli_error_status(st, &diag, pos[2]);
        return cli_exit_for_write(st);
    }
    double seconds = cli_now() - t0;
    if (common.json)
        printf("{\"points\": %zu, \"noise\": %.9g, \"noise_rel\": %.9g, \"seed\": %llu, "
               "\"seconds\": %.6f}\n",
               count, o.sp.noise, o.sp.noise_rel, (unsigned long long)o.sp.seed, seconds);
    else if (!common.quiet)
        fprintf(stderr, "tessel: wrote %s: %zu points sampled from %s in %.2f s\n", pos[2],
                count, pos[0], seconds);
    return CLI_OK;
}
