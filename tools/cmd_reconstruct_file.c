/* tessel reconstruct out of core: clouds larger than the memory given
 * (--memory), meshed by greedy projection in slabs through scratch files
 * (tessel_reconstruct_greedy_file, docs/outofcore.md). */
#include "cli.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* Bytes of memory in core per byte of input file, at most: a binary PLY
 * of float coordinates holds 12 bytes a point and greedy projection in
 * core peaks near 370 bytes a point (the file's bytes read in as well). */
#define IN_CORE_PER_FILE_BYTE 32

bool cli_parse_size(const char *opt, const char *text, uint64_t *out)
{
    char *end;
    double x = strtod(text, &end);
    double unit = 1.0;
    switch (*end) {
    case 'k': case 'K': unit = 1024.0; end++; break;
    case 'm': case 'M': unit = 1048576.0; end++; break;
    case 'g': case 'G': unit = 1073741824.0; end++; break;
    case 't': case 'T': unit = 1099511627776.0; end++; break;
    default: break;
    }
    if (*end == 'B' || *end == 'b')
        end++;
    if (end == text || *end || !(x > 0.0) || !isfinite(x * unit) || x * unit > 1e18) {
        cli_error("%s must be a size such as 2G, 500M or 1048576, got '%s'", opt, text);
        return false;
    }
    *out = (uint64_t)(x * unit);
    return true;
}

static uint64_t memory_of(const cli_greedy_opts *o)
{
    if (o->ooc.memory)
        return o->ooc.memory;
    long pages = sysconf(_SC_PHYS_PAGES), size = sysconf(_SC_PAGESIZE);
    return pages > 0 && size > 0 ? (uint64_t)pages * (uint64_t)size / 2 : (uint64_t)2 << 30;
}

bool cli_outofcore_wanted(const char *in, const cli_greedy_opts *o)
{
    struct stat st;
    if (stat(in, &st) != 0 || !S_ISREG(st.st_mode))
        return false;
    return (double)st.st_size * IN_CORE_PER_FILE_BYTE > (double)memory_of(o);
}

int cli_reconstruct_outofcore(const char *in, const char *out, const cli_greedy_opts *o,
                              const cli_common *common, cli_file_mesher mesh)
{
    double t0 = cli_now();
    tessel_read_params rp = cli_read_params(common);
    tessel_write_params wp = tessel_write_params_default();
    wp.ascii = o->ascii;
    tessel_greedy_params p = o->p;
    p.threads = common->threads;
    tessel_outofcore_params op = o->ooc;
    op.memory = memory_of(o);
    cli_progress prog;
    cli_progress_init(&prog, common);
    tessel_callbacks cb = cli_callbacks(&prog);
    tessel_recon_summary sum;
    tessel_diag diag = {0};
    tessel_status st = mesh(in, out, &rp, &p, &wp, &op, &cb, &sum, &diag);
    cli_progress_done(&prog);
    if (st != TESSEL_OK) {
        if (st == TESSEL_ERR_CANCELLED)
            cli_error("%s: cancelled; no output written, scratch files removed", in);
        else
            cli_error_status(st, &diag, diag.file[0] ? diag.file : in);
        return st == TESSEL_ERR_IO ? CLI_OUTPUT_ERROR : CLI_FAILURE;
    }
    double seconds = cli_now() - t0;
    double rate = seconds > 0 ? (double)sum.points_in / seconds : 0.0;
    if (common->json) {
        printf("{\"method\": \"greedy\", \"out_of_core\": true, \"points\": %zu, "
               "\"points_used\": %zu, \"triangles\": %zu, \"slabs\": %zu, \"tiles\": %zu, "
               "\"flips\": %zu, \"spacing\": %.9g, \"mu\": %g, \"memory_bytes\": %llu, "
               "\"seconds\": %.6f, \"points_per_second\": %.0f, \"peak_mib\": %.1f}\n",
               sum.points_in, sum.points_used, sum.triangles, sum.slabs, sum.tiles, sum.flips,
               sum.spacing, sum.mu, (unsigned long long)op.memory, seconds, rate,
               cli_peak_mib());
    } else if (!common->quiet) {
        fprintf(stderr,
                "tessel: greedy, out of core: %zu of %zu points used, %zu triangles, "
                "%zu slabs of at most %.0f MiB (mu %g, spacing %.4g)\n",
                sum.points_used, sum.points_in, sum.triangles, sum.slabs,
                (double)op.memory / 1048576.0, sum.mu, sum.spacing);
        fprintf(stderr,
                "tessel: wrote %s in %.2f s (%.2fM points/s; peak memory %.0f MiB); "
                "tessel check counts its components and boundary edges\n",
                out, seconds, rate / 1e6, cli_peak_mib());
    }
    return CLI_OK;
}
