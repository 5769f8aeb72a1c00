/* tessel normals IN OUT: PCA normals, consistently oriented. */
#include "cli.h"

#include <string.h>

static const char normals_help[] =
    "usage: tessel normals IN OUT [-k K] [--no-orient]\n\n"
    "Estimates a unit normal per point from a plane fitted to its K nearest\n"
    "neighbours (default 16), oriented consistently over each connected part\n"
    "of the cloud (minimum spanning tree, Hoppe et al. 1992) and outward on\n"
    "closed surfaces. --no-orient keeps the fitted signs.\n\n";

typedef struct normals_opts {
    tessel_normals_params np;
} normals_opts;

static int normals_option(void *ctx, int argc, char **argv, int *i)
{
    normals_opts *o = ctx;
    const char *a = argv[*i];
    if (strcmp(a, "--no-orient") == 0) {
        o->np.orient = 0;
        return 1;
    }
    if (strcmp(a, "-k") == 0 || strcmp(a, "--k") == 0) {
        const char *v = cli_option_value(argc, argv, i);
        long k;
        if (!v || !cli_parse_int(a, v, 3, 256, &k))
            return -1;
        o->np.k = (uint32_t)k;
        return 1;
    }
    return 0;
}

int cmd_normals(int argc, char **argv)
{
    cli_common common = {0};
    normals_opts o = {tessel_normals_params_default()};
    const char *in = NULL, *out = NULL;
    int r = cli_parse_in_out(argc, argv, normals_help, &common, &in, &out, normals_option, &o);
    if (r <= 0)
        return r == 0 ? CLI_OK : CLI_USAGE;
    cli_apply_threads(&common);
    o.np.threads = common.threads;

    double t0 = cli_now();
    tessel_cloud cloud = {0};
    int rc = cli_read_cloud(in, &cloud, 0, NULL, &common);
    if (rc != CLI_OK)
        return rc;
    cli_progress progress;
    cli_progress_init(&progress, &common);
    tessel_callbacks cb = cli_callbacks(&progress);
    cli_progress_items(&progress, cloud.count);
    tessel_status st = tessel_normals_estimate(&cloud, &o.np, &cb);
    cli_progress_done(&progress);
    if (st != TESSEL_OK) {
        cli_error("%s: normals failed: %s", in, tessel_status_str(st));
        tessel_cloud_free(&cloud);
        return CLI_FAILURE;
    }
    tessel_write_params wp = tessel_write_params_default();
    tessel_diag diag = {0};
    st = tessel_cloud_write(&cloud, out, &wp, &diag);
    size_t n = cloud.count;
    tessel_cloud_free(&cloud);
    if (st != TESSEL_OK) {
        cli_error_status(st, &diag, out);
        return cli_exit_for_write(st);
    }
    double seconds = cli_now() - t0;
    if (common.json)
        printf("{\"points\": %zu, \"k\": %u, \"oriented\": %s, \"seconds\": %.6f}\n", n,
               o.np.k, o.np.orient ? "true" : "false", seconds);
    else if (!common.quiet)
        fprintf(stderr, "tessel: wrote %s: %zu points with normals in %.2f s\n", out, n,
                seconds);
    return CLI_OK;
}
