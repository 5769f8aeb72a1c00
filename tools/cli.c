/* Shared CLI plumbing: error printing in the house format, common options,
 * the progress bar. */
#include "cli.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <signal.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

#ifdef _OPENMP
#include <omp.h>
#endif

const char cli_common_help[] =
    "Common options:\n"
    "  --threads N   worker threads (default: OMP_NUM_THREADS, else all cores)\n"
    "  --quiet       no progress bar and no summary\n"
    "  --json        print the summary as one JSON object on stdout\n"
    "  --bbox X0,Y0,Z0,X1,Y1,Z1\n"
    "                LAS/LAZ input: read only the points in this box (world\n"
    "                coordinates, bounds included; COPC: only the chunks whose\n"
    "                octree node meets it are decoded)\n"
    "  --help        this text\n"
    "Exit codes: 0 ok, 1 usage, 2 input error, 3 output error, 4 failure,\n"
    "130 / 143 interrupted by SIGINT / SIGTERM (nothing partial left behind).\n";

void cli_error(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    fputs("tessel: error: ", stderr);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
}

void cli_error_status(tessel_status status, const tessel_diag *diag, const char *path)
{
    const char *file = (diag && diag->file[0]) ? diag->file : path;
    fputs("tessel: error: ", stderr);
    if (file && *file)
        fprintf(stderr, "%s: ", file);
    if (diag && diag->line)
        fprintf(stderr, "line %llu: ", (unsigned long long)diag->line);
    else if (diag && diag->has_offset)
        fprintf(stderr, "byte %llu: ", (unsigned long long)diag->offset);
    if (diag && diag->message[0])
        fprintf(stderr, "%s\n", diag->message);
    else
        fprintf(stderr, "%s\n", tessel_status_str(status));
}

/* Why the reader drops a point (tessel_cloud.dropped_nonfinite). */
#define DROPPED_WHY "a coordinate NaN, infinite or beyond 1e15"

int cli_exit_for_read(tessel_status status)
{
    if (status == TESSEL_ERR_NOMEM || status == TESSEL_ERR_CANCELLED ||
        status == TESSEL_ERR_INTERNAL)
        return CLI_FAILURE;
    return CLI_INPUT_ERROR;
}

/* The cloud reconstruct read to choose its method (one process, one
 * command: a plain static is enough). */
static struct {
    const char *path;
    tessel_cloud cloud;
    int loaded, chosen;
    tessel_method_choice choice;
} preload;

void cli_preload_cloud(const char *path, tessel_cloud *cloud, const tessel_method_choice *choice)
{
    preload.path = path;
    preload.cloud = *cloud;
    memset(cloud, 0, sizeof *cloud);
    preload.loaded = 1;
    preload.chosen = 1;
    preload.choice = *choice;
}

bool cli_chosen_noise(double *noise, double *noise_ratio)
{
    if (!preload.chosen || !preload.choice.measured)
        return false;
    *noise = preload.choice.noise;
    *noise_ratio = preload.choice.noise_ratio;
    return true;
}

void cli_chosen_json_end(void)
{
    if (preload.chosen) {
        const tessel_method_choice *c = &preload.choice;
        printf(", \"chosen_by\": \"auto\", \"reason\": ");
        cli_json_string(stdout, c->reason);
        if (c->measured)
            printf(", \"measured_noise\": %.9g, \"measured_noise_ratio\": %.6g, "
                   "\"choice_seconds\": %.6f",
                   c->noise, c->noise_ratio, c->seconds);
    }
    printf("}\n");
}

void cli_chosen_text(void)
{
    if (!preload.chosen)
        return;
    const tessel_method_choice *c = &preload.choice;
    const char *name = c->method == TESSEL_METHOD_FIXED_PLANE ? "range mode"
                                                              : tessel_method_name(c->method);
    if (c->measured)
        fprintf(stderr,
                "tessel: method %s (auto): noise %.4g = %.2f surface spacings: %s\n", name,
                c->noise, c->noise_ratio, c->reason);
    else
        fprintf(stderr, "tessel: method %s (auto): %s\n", name, c->reason);
}

int cli_read_cloud(const char *path, tessel_cloud *cloud, size_t min_points, const char *what,
                   const cli_common *common)
{
    tessel_diag diag = {0};
    tessel_status st = TESSEL_OK;
    if (preload.loaded && strcmp(path, preload.path) == 0) {
        *cloud = preload.cloud;
        memset(&preload.cloud, 0, sizeof preload.cloud);
        preload.loaded = 0;
    } else {
        tessel_read_params rp = cli_read_params(common);
        st = tessel_cloud_read(cloud, path, &rp, &diag);
    }
    return cli_accept_cloud(path, st, &diag, cloud, min_points, what, common);
}

int cli_accept_cloud(const char *path, tessel_status st, const tessel_diag *diag,
                     tessel_cloud *cloud, size_t min_points, const char *what,
                     const cli_common *common)
{
    if (st != TESSEL_OK) {
        cli_error_status(st, diag, path);
        return cli_exit_for_read(st);
    }
    size_t dropped = cloud->dropped_nonfinite;
    if (cloud->count < min_points) {
        if (dropped)
            cli_error("%s: %zu points (%zu more dropped: " DROPPED_WHY "): %s needs at least %zu",
                      path, cloud->count, dropped, what, min_points);
        else
            cli_error("%s: %zu points: %s needs at least %zu", path, cloud->count, what,
                      min_points);
        tessel_cloud_free(cloud);
        return CLI_INPUT_ERROR;
    }
    if (dropped && !common->quiet)
        fprintf(stderr, "tessel: warning: %s: %zu of %zu points dropped: " DROPPED_WHY "\n",
                path, dropped, cloud->count + dropped);
    return CLI_OK;
}

int cli_exit_for_write(tessel_status status)
{
    if (status == TESSEL_ERR_NOMEM || status == TESSEL_ERR_CANCELLED ||
        status == TESSEL_ERR_INTERNAL)
        return CLI_FAILURE;
    return CLI_OUTPUT_ERROR;
}

bool cli_parse_double(const char *opt, const char *text, double *out)
{
    char *end = NULL;
    errno = 0;
    double v = text ? strtod(text, &end) : 0.0;
    if (!text || end == text || *end != '\0' || errno == ERANGE || !isfinite(v)) {
        cli_error("%s expects a number, got '%s'", opt, text ? text : "");
        return false;
    }
    *out = v;
    return true;
}

bool cli_parse_int(const char *opt, const char *text, long min, long max, long *out)
{
    char *end = NULL;
    errno = 0;
    long v = text ? strtol(text, &end, 10) : 0;
    if (!text || end == text || *end != '\0' || errno == ERANGE || v < min || v > max) {
        cli_error("%s expects a whole number from %ld to %ld, got '%s'", opt, min, max,
                  text ? text : "");
        return false;
    }
    *out = v;
    return true;
}

const char *cli_option_value(int argc, char **argv, int *i)
{
    if (*i + 1 >= argc) {
        cli_error("%s needs a value", argv[*i]);
        return NULL;
    }
    return argv[++*i];
}

tessel_read_params cli_read_params(const cli_common *common)
{
    tessel_read_params rp = tessel_read_params_default();
    if (common->has_bbox)
        rp.bbox = common->bbox;
    return rp;
}

int cli_common_option(cli_common *common, int argc, char **argv, int *i)
{
    const char *a = argv[*i];
    if (strcmp(a, "--bbox") == 0) {
        const char *v = cli_option_value(argc, argv, i);
        if (!v)
            return -1;
        const char *p = v;
        for (int k = 0; k < 6; k++) {
            char *end = NULL;
            errno = 0;
            common->bbox[k] = strtod(p, &end);
            if (end == p || errno != 0 || !isfinite(common->bbox[k]) ||
                (k < 5 ? *end != ',' : *end != '\0')) {
                cli_error("--bbox: '%s' is not six numbers X0,Y0,Z0,X1,Y1,Z1", v);
                return -1;
            }
            p = end + 1;
        }
        for (int k = 0; k < 3; k++)
            if (common->bbox[k] > common->bbox[k + 3]) {
                cli_error("--bbox: the %c range [%g, %g] is empty", "xyz"[k], common->bbox[k],
                          common->bbox[k + 3]);
                return -1;
            }
        common->has_bbox = true;
        return 1;
    }
    if (strcmp(a, "--quiet") == 0 || strcmp(a, "-q") == 0) {
        common->quiet = true;
        return 1;
    }
    if (strcmp(a, "--json") == 0) {
        common->json = true;
        return 1;
    }
    if (strcmp(a, "--threads") == 0 || strcmp(a, "-j") == 0) {
        const char *v = cli_option_value(argc, argv, i);
        long n;
        if (!v || !cli_parse_int(a, v, 0, 4096, &n))
            return -1;
        common->threads = (int)n;
        return 1;
    }
    return 0;
}

void cli_apply_threads(const cli_common *common)
{
#ifdef _OPENMP
    if (common->threads > 0)
        omp_set_num_threads(common->threads);
#else
    (void)common;
#endif
}

int cli_stream_reconstruction(const char *in, const char *out, const tessel_cloud *cloud,
                              int ascii, const cli_common *common, const char *what,
                              cli_stream_fn run, void *ctx, double *t_write)
{
    tessel_diag diag = {0};
    tessel_write_params wp = tessel_write_params_default();
    wp.ascii = ascii;
    tessel_mesh_writer *writer = NULL;
    tessel_status st = tessel_mesh_writer_open(&writer, out, cloud, &wp, 1, &diag);
    if (st != TESSEL_OK) {
        cli_error_status(st, &diag, out);
        return cli_exit_for_write(st);
    }
    tessel_triangle_sink sink = tessel_mesh_writer_sink(writer);
    cli_progress prog;
    cli_progress_init(&prog, common);
    tessel_callbacks cb = cli_callbacks(&prog);
    cli_progress_items(&prog, cloud->count);
    st = run(cloud, &cb, &sink, ctx);
    cli_progress_done(&prog);
    if (st != TESSEL_OK) {
        tessel_mesh_writer_abort(writer);
        if (st == TESSEL_ERR_IO) {
            cli_error("%s: writing the triangles failed", out);
            return CLI_OUTPUT_ERROR;
        }
        cli_error("%s: %s failed: %s", in, what, tessel_status_str(st));
        return CLI_FAILURE;
    }
    double t1 = cli_now();
    st = tessel_mesh_writer_close(writer, &diag);
    *t_write = cli_now() - t1;
    if (st != TESSEL_OK) {
        cli_error_status(st, &diag, out);
        return cli_exit_for_write(st);
    }
    return CLI_OK;
}

void cli_json_string(FILE *out, const char *s)
{
    fputc('"', out);
    for (; *s; s++) {
        unsigned char c = (unsigned char)*s;
        if (c == '"' || c == '\\')
            fprintf(out, "\\%c", c);
        else if (c < 0x20)
            fprintf(out, "\\u%04x", c);
        else
            fputc(c, out);
    }
    fputc('"', out);
}

/* Parses "IN OUT" plus the common options; command-specific options are
 * handled by `extra`, which returns 1 if it consumed argv[*i], 0 if not,
 * -1 on error. */
int cli_parse_in_out(int argc, char **argv, const char *help, cli_common *common,
                        const char **in, const char **out, cli_extra_option_fn extra, void *ctx)
{
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "-h") == 0) {
            fputs(help, stdout);
            fputs(cli_common_help, stdout);
            return 0;
        }
        int r = cli_common_option(common, argc, argv, &i);
        if (r == 0 && extra)
            r = extra(ctx, argc, argv, &i);
        if (r < 0)
            return -1;
        if (r > 0)
            continue;
        if (argv[i][0] == '-' && argv[i][1] != '\0') {
            cli_error("%s: unknown option '%s'", argv[0], argv[i]);
            return -1;
        }
        if (!*in)
            *in = argv[i];
        else if (!*out)
            *out = argv[i];
        else {
            cli_error("%s: expects IN and OUT, got a third file '%s'", argv[0], argv[i]);
            return -1;
        }
    }
    if (!*in || !*out) {
        fputs(help, stderr);
        return -1;
    }
    return 1;
}

double cli_peak_mib(void)
{
    struct rusage ru;
    if (getrusage(RUSAGE_SELF, &ru) != 0)
        return 0.0;
    return (double)ru.ru_maxrss / 1024.0; /* kilobytes on Linux */
}

double cli_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* ---- progress ---- */

void cli_progress_init(cli_progress *p, const cli_common *common)
{
    memset(p, 0, sizeof *p);
    p->enabled = !common->quiet;
    p->tty = isatty(STDERR_FILENO) != 0;
}

static void format_duration(char *buf, size_t size, double seconds)
{
    if (!(seconds >= 0) || seconds > 359999)
        snprintf(buf, size, "--:--");
    else if (seconds >= 3600)
        snprintf(buf, size, "%d:%02d:%02d", (int)seconds / 3600, ((int)seconds / 60) % 60,
                 (int)seconds % 60);
    else
        snprintf(buf, size, "%d:%02d", (int)seconds / 60, (int)seconds % 60);
}

static void draw_bar(cli_progress *p, double fraction, double now)
{
    const int width = 30;
    int filled = (int)(fraction * width + 0.5);
    char bar[64];
    for (int i = 0; i < width; i++)
        bar[i] = i < filled ? '#' : '.';
    bar[width] = '\0';
    double elapsed = now - p->stage_start;
    char left[32] = "--:--";
    if (fraction > 0.02)
        format_duration(left, sizeof left, elapsed * (1.0 - fraction) / fraction);
    char rate[48] = "";
    if (p->items && elapsed > 0)
        snprintf(rate, sizeof rate, "  %.2fM pts/s",
                 fraction * (double)p->items / elapsed / 1e6);
    fprintf(stderr, "\r%-10s [%s] %3d%%%s  left %s   ", p->stage, bar,
            (int)(fraction * 100.0 + 0.5), rate, left);
    fflush(stderr);
}

static void end_stage(cli_progress *p, double now)
{
    if (!p->stage)
        return;
    double elapsed = now - p->stage_start;
    char rate[48] = "";
    if (p->items && elapsed > 0)
        snprintf(rate, sizeof rate, ", %.2fM pts/s", (double)p->items / elapsed / 1e6);
    if (p->tty) {
        draw_bar(p, 1.0, now);
        fprintf(stderr, "\r%-10s done in %.2f s%s%*s\n", p->stage, elapsed, rate, 40, "");
    } else {
        fprintf(stderr, "%s: done in %.2f s%s\n", p->stage, elapsed, rate);
    }
    p->stage = NULL;
    p->items = 0;
}

volatile sig_atomic_t cli_interrupted;

static void on_signal(int sig) { cli_interrupted = sig; }

void cli_install_signals(void)
{
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    /* A second signal of the same kind stops at once. */
    sa.sa_flags = SA_RESETHAND;
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    /* Messages into a pipe closed early (tessel ... 2>&1 | head) must not
     * kill the command with its temporary output still there: the write
     * fails instead, and the command finishes. */
    signal(SIGPIPE, SIG_IGN);
}

static int progress_cb(void *user, const char *stage, double fraction)
{
    cli_progress *p = user;
    /* Ctrl-C and SIGTERM cancel the running call at its next progress
     * report; the command then removes what it was writing. */
    if (cli_interrupted)
        return 1;
    if (!p->enabled)
        return 0;
    double now = cli_now();
    if (!p->stage || strcmp(p->stage, stage) != 0) {
        end_stage(p, now);
        p->stage = stage;
        p->stage_start = now;
        p->last_draw = 0;
        p->items = p->pending_items;
        p->pending_items = 0;
    }
    if (p->tty && (now - p->last_draw > 0.1 || fraction >= 1.0)) {
        draw_bar(p, fraction < 0 ? 0 : fraction > 1 ? 1 : fraction, now);
        p->last_draw = now;
    }
    return 0;
}

static void log_cb(void *user, tessel_log_level level, const char *message)
{
    cli_progress *p = user;
    if (!p->enabled || level == TESSEL_LOG_DEBUG)
        return;
    if (p->tty && p->stage)
        fputc('\n', stderr);
    fprintf(stderr, "tessel: %s%s\n", level == TESSEL_LOG_WARNING ? "warning: " : "",
            message);
}

tessel_callbacks cli_callbacks(cli_progress *p)
{
    tessel_callbacks cb = {progress_cb, log_cb, p};
    return cb;
}

void cli_progress_items(cli_progress *p, size_t items) { p->pending_items = items; }

void cli_progress_done(cli_progress *p)
{
    if (p->enabled)
        end_stage(p, cli_now());
}
