/* tessel-mpi reconstruct IN OUT [options]: greedy projection with its tiles
 * spread over the processes of MPI_COMM_WORLD (include/tessel_mpi.h,
 * docs/mpi.md). The processes read the cloud in parts and share them;
 * process 0 writes the mesh;
 * the file is byte for byte what `tessel reconstruct IN OUT --method
 * greedy` writes with the same options, for any number of processes; out
 * of core too (each slab's tiles over the processes). A failure anywhere
 * stops every process and leaves no output. */
#include "cli.h"
#include "mpi/mpi.h"
#include "tessel_mpi.h"

#include <stdlib.h>
#include <string.h>

static const char help[] =
    "usage: mpirun -np N tessel-mpi reconstruct IN OUT [options]\n\n"
    "Greedy projection (as tessel reconstruct --method greedy) with the tiles\n"
    "meshed by N processes: tile k by process k mod N, each with --threads\n"
    "threads. The processes read IN in parts (binary PLY, LAS, LAZ; other\n"
    "formats through process 0); process 0 joins the tiles on the threads of\n"
    "the processes on its machine (mpirun --bind-to none lets it use their\n"
    "cores) and writes OUT; the output is the same bytes for any N and any\n"
    "thread count. A cloud of at most --tile-points points is one tile: process 0\n"
    "meshes it alone. A cloud too large for --memory (as tessel judges it) is\n"
    "meshed out of core: process 0 sorts it into slabs in --scratch and sends\n"
    "each slab's tiles to the processes; no process holds the whole cloud.\n\n"
    "Options (see tessel reconstruct --method greedy --help):\n"
    "  --mu M, --max-angle DEG, --min-angle DEG, --plane pca|axis,\n"
    "  --max-spacing K, --no-flip, --tile-points N (default 262144), --ascii,\n"
    "  --memory SIZE, --scratch DIR\n\n"
    "With --method smooth: the noisy-cloud pipeline (tessel reconstruct\n"
    "--method smooth --help for its options) with the tiles of its advancing\n"
    "front (--tile-points, default 65536) meshed by the N processes, the rest\n"
    "on process 0; the same bytes as tessel for any N.\n\n";

typedef struct run_ctx {
    const tessel_greedy_params *params;
    tessel_recon_summary summary;
} run_ctx;

static tessel_status discard(void *user, const uint32_t *tris, size_t count)
{
    (void)user;
    (void)tris;
    (void)count;
    return TESSEL_OK;
}

/* Opens the writer on process 0 and tells the others whether it could. */
static tessel_status open_output(int rank, const char *out, const tessel_cloud *cloud, int ascii,
                                 tessel_mesh_writer **writer)
{
    int st = TESSEL_OK;
    if (rank == 0) {
        tessel_write_params wp = tessel_write_params_default();
        wp.ascii = ascii;
        tessel_diag diag = {0};
        st = (int)tessel_mesh_writer_open(writer, out, cloud, &wp, 1, &diag);
        if (st != TESSEL_OK)
            cli_error_status((tessel_status)st, &diag, out);
    }
    MPI_Bcast(&st, 1, MPI_INT, 0, MPI_COMM_WORLD);
    return (tessel_status)st;
}

static void print_summary(const tessel_recon_summary *s, size_t n, int procs, const char *out,
                          double t_read, double t_write, double total,
                          const cli_common *common)
{
    if (common->json) {
        printf("{\"method\": \"greedy\", \"processes\": %d, \"points\": %zu, "
               "\"points_used\": %zu, \"triangles\": %zu, \"components\": %zu, "
               "\"boundary_edges\": %zu, \"flips\": %zu, \"tiles\": %zu, "
               "\"read_seconds\": %.6f, "
               "\"reconstruct_seconds\": %.6f, \"write_seconds\": %.6f, \"seconds\": %.6f, "
               "\"peak_mib\": %.1f}\n",
               procs, n, s->points_used, s->triangles, s->components, s->boundary_edges,
               s->flips, s->tiles, t_read, s->seconds, t_write, total, cli_peak_mib());
    } else if (!common->quiet) {
        fprintf(stderr,
                "tessel-mpi: greedy on %d process%s, %zu tile%s: %zu of %zu points used, "
                "%zu triangles, %zu component%s, %zu boundary edges\n",
                procs, procs == 1 ? "" : "es", s->tiles, s->tiles == 1 ? "" : "s",
                s->points_used, n, s->triangles, s->components, s->components == 1 ? "" : "s",
                s->boundary_edges);
        fprintf(stderr,
                "tessel-mpi: wrote %s in %.2f s (read %.2f s, reconstruction "
                "%.2f s, write %.2f s; peak memory of process 0 %.0f MiB)\n",
                out, total, t_read, s->seconds, t_write, cli_peak_mib());
    }
}

/* The cloud read in parts and joined on process 0 (cli_read_cloud's
 * contract there); every process returns process 0's code. */
static int read_parts(void *unused, const char *path, tessel_cloud *cloud, const char *what,
                      const cli_common *common)
{
    (void)unused;
    int rank;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    tessel_diag diag = {0};
    tessel_read_params rp = cli_read_params(common);
    tessel_status st = tessel_mpi_cloud_read(MPI_COMM_WORLD, 0, path, &rp, cloud, &diag);
    int rc = rank == 0 ? cli_accept_cloud(path, st, &diag, cloud, 3, what, common) : CLI_OK;
    MPI_Bcast(&rc, 1, MPI_INT, 0, MPI_COMM_WORLD);
    if (rc != CLI_OK)
        tessel_cloud_free(cloud);
    return rc;
}

/* Out of core, the slabs' tiles meshed by every process. */
static tessel_status file_ranks(const char *in, const char *out, const tessel_read_params *rp,
                                const tessel_greedy_params *params,
                                const tessel_write_params *wp, const tessel_outofcore_params *op,
                                const tessel_callbacks *callbacks, tessel_recon_summary *summary,
                                tessel_diag *diag)
{
    return tessel_mpi_reconstruct_greedy_file(MPI_COMM_WORLD, in, out, rp, params, wp, op,
                                              callbacks, summary, diag);
}

static tessel_status smooth_ranks(void *unused, const tessel_cloud *cloud,
                                  const tessel_smooth_recon_params *params,
                                  const tessel_callbacks *callbacks, tessel_mesh *mesh,
                                  tessel_smooth_recon_stats *stats)
{
    (void)unused;
    return tessel_mpi_reconstruct_smooth(MPI_COMM_WORLD, cloud, params, callbacks, mesh, stats);
}

/* tessel reconstruct --method smooth, run by every process: process 0 as
 * tessel runs it, the others as workers that serve the front's tiles. */
static int reconstruct_smooth(int argc, char **argv, int rank)
{
    if (rank != 0 && !freopen("/dev/null", "w", stderr))
        return CLI_FAILURE;
    cli_smooth_hooks hooks = {read_parts, smooth_ranks, NULL, rank != 0};
    return cli_reconstruct_smooth_with(argc, argv, &hooks);
}

static bool wants_smooth(int argc, char **argv)
{
    for (int i = 1; i + 1 < argc; i++)
        if (strcmp(argv[i], "--method") == 0 && strcmp(argv[i + 1], "smooth") == 0)
            return true;
    return false;
}

static int reconstruct(int argc, char **argv, int rank, int procs)
{
    if (wants_smooth(argc, argv))
        return reconstruct_smooth(argc, argv, rank);
    cli_common common = {0};
    cli_greedy_opts o;
    memset(&o, 0, sizeof o);
    o.p = tessel_greedy_params_default();
    o.ooc = tessel_outofcore_params_default();
    const char *in = NULL, *out = NULL;
    /* Every process parses the same command line; only process 0 talks. */
    if (rank != 0 && !freopen("/dev/null", "w", stderr))
        return CLI_FAILURE;
    int r = cli_parse_in_out(argc, argv, help, &common, &in, &out, cli_greedy_option, &o);
    if (r <= 0)
        return r == 0 ? CLI_OK : CLI_USAGE;
    if (!o.p.orient_check && !o.p.flip) {
        cli_error("--stream writes as the front goes, one process alone: use tessel");
        return CLI_USAGE;
    }
    if (rank != 0) {
        common.quiet = true;
        common.json = false;
    }
    cli_apply_threads(&common);
    /* Process 0's file and memory decide, as tessel's would. */
    int outofcore = rank == 0 && cli_outofcore_wanted(in, &o);
    MPI_Bcast(&outofcore, 1, MPI_INT, 0, MPI_COMM_WORLD);
    if (outofcore)
        return cli_reconstruct_outofcore(in, out, &o, &common, file_ranks);
    double t0 = cli_now();
    tessel_cloud cloud = {0};
    int rc = read_parts(NULL, in, &cloud, "a surface", &common);
    if (rc != CLI_OK)
        return rc;
    tessel_status st;
    double t_read = cli_now() - t0;
    tessel_mesh_writer *writer = NULL;
    if ((st = open_output(rank, out, &cloud, o.ascii, &writer)) != TESSEL_OK) {
        tessel_cloud_free(&cloud);
        return cli_exit_for_write(st);
    }
    cli_progress prog;
    cli_progress_init(&prog, &common);
    tessel_callbacks cb = cli_callbacks(&prog);
    cli_progress_items(&prog, cloud.count);
    tessel_triangle_sink sink =
        rank == 0 ? tessel_mesh_writer_sink(writer) : (tessel_triangle_sink){discard, NULL};
    tessel_recon_summary sum;
    st = tessel_mpi_reconstruct_greedy(MPI_COMM_WORLD, &cloud, &o.p, &cb, &sink, &sum);
    cli_progress_done(&prog);
    size_t n = cloud.count;
    if (st != TESSEL_OK) {
        if (writer)
            tessel_mesh_writer_abort(writer);
        tessel_cloud_free(&cloud);
        cli_error("%s: reconstruction failed: %s", in, tessel_status_str(st));
        return st == TESSEL_ERR_CANCELLED && cli_interrupted ? 128 + cli_interrupted
                                                             : CLI_FAILURE;
    }
    double t_write = 0.0;
    tessel_diag diag = {0};
    if (rank == 0) {
        /* The writer takes the vertices from the cloud as it closes. */
        double t1 = cli_now();
        st = tessel_mesh_writer_close(writer, &diag);
        t_write = cli_now() - t1;
    }
    tessel_cloud_free(&cloud);
    if (rank == 0) {
        if (st != TESSEL_OK) {
            cli_error_status(st, &diag, out);
            return cli_exit_for_write(st);
        }
        print_summary(&sum, n, procs, out, t_read, t_write, cli_now() - t0, &common);
    }
    return CLI_OK;
}

int main(int argc, char **argv)
{
    MPI_Init(&argc, &argv);
    int rank, procs;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &procs);
    int code;
    if (argc >= 2 && strcmp(argv[1], "reconstruct") == 0) {
        /* mpirun passes a Ctrl-C to every process: each cancels. */
        cli_install_signals();
        code = reconstruct(argc - 1, argv + 1, rank, procs);
        /* Every process exits with process 0's code (a failure to write
         * is process 0's alone). */
        tsl_mpi_bcast(MPI_COMM_WORLD, 0, &code, 1, MPI_INT, sizeof code);
    } else {
        bool asked = argc >= 2 && (strcmp(argv[1], "--help") == 0 || strcmp(argv[1], "-h") == 0);
        if (rank == 0)
            fputs(help, asked ? stdout : stderr);
        code = asked ? CLI_OK : CLI_USAGE;
    }
    MPI_Finalize();
    return code;
}
