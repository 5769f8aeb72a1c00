/* Shared pieces of the tessel command-line tool: exit codes, error
 * printing, option parsing helpers and the terminal progress bar. Each
 * subcommand lives in tools/cmd_<name>.c and is listed in tools/tessel.c. */
#ifndef TESSEL_CLI_H
#define TESSEL_CLI_H

#include "tessel.h"

#include <signal.h>
#include <stdbool.h>
#include <stdio.h>

/* Documented exit codes (see tessel --help and the README). */
enum {
    CLI_OK = 0,
    CLI_USAGE = 1,        /* bad command line */
    CLI_INPUT_ERROR = 2,  /* input file missing or malformed */
    CLI_OUTPUT_ERROR = 3, /* output could not be written */
    CLI_FAILURE = 4       /* the computation failed or was cancelled */
};

/* Options every subcommand accepts; parsed by cli_common_option(). */
typedef struct cli_common {
    int threads;   /* --threads N; 0 = OpenMP default (OMP_NUM_THREADS) */
    bool quiet;    /* --quiet: no progress, no summary */
    bool json;     /* --json: machine-readable summary on stdout */
    bool has_bbox; /* --bbox X0,Y0,Z0,X1,Y1,Z1: read only the LAS/LAZ points in it */
    double bbox[6];
} cli_common;

/* A subcommand: argv[0] is the subcommand's name. Returns an exit code. */
typedef int (*cli_command_fn)(int argc, char **argv);

/* The signal (SIGINT, SIGTERM) that interrupted the command, or 0. The
 * first one cancels the running library call through the progress
 * callback (the command removes its partial output and the process exits
 * with 128 + the signal: 130, 143); a second one stops the process at once. */
extern volatile sig_atomic_t cli_interrupted;
void cli_install_signals(void);

/* Prints "tessel: error: MESSAGE" to stderr. */
void cli_error(const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 1, 2)))
#endif
    ;
/* Prints a library error with its diagnostic:
 * "tessel: error: FILE: line 12: MESSAGE" (or "byte 345"). */
void cli_error_status(tessel_status status, const tessel_diag *diag, const char *path);
/* Exit code for a failed read / write / computation status. */
int cli_exit_for_read(tessel_status status);
int cli_exit_for_write(tessel_status status);
/* Hands a cloud already read (by reconstruct's method choice) to the
 * command it runs: the next cli_read_cloud of the same path takes it
 * instead of reading the file again, and the summaries say which method
 * was chosen and why (cli_chosen_*). */
void cli_preload_cloud(const char *path, tessel_cloud *cloud, const tessel_method_choice *choice);
/* The noise the method's choice measured on the preloaded cloud, if it did. */
bool cli_chosen_noise(double *noise, double *noise_ratio);
/* The JSON summary's end: the chosen method's fields (when the method was
 * chosen) and the closing brace and newline. */
void cli_chosen_json_end(void);
/* One line on stderr saying which method was chosen and why (nothing
 * unless one was). */
void cli_chosen_text(void);
/* Reads the cloud at path, printing any error. With fewer than min_points
 * points it says "PATH: N points: WHAT needs at least MIN" (and how many the
 * reader dropped) and frees the cloud. Points the reader dropped (a
 * coordinate NaN, infinite or beyond 1e15) get a warning unless
 * common->quiet. Returns CLI_OK or the exit code. */
int cli_read_cloud(const char *path, tessel_cloud *cloud, size_t min_points, const char *what,
                   const cli_common *common);
/* cli_read_cloud's checks and messages for a cloud read otherwise (st and
 * diag: the read's outcome). */
int cli_accept_cloud(const char *path, tessel_status st, const tessel_diag *diag,
                     tessel_cloud *cloud, size_t min_points, const char *what,
                     const cli_common *common);

/* Read parameters for an input file: the defaults, with --bbox. */
tessel_read_params cli_read_params(const cli_common *common);

/* If argv[*i] is a common option (--threads N, --quiet, --json, --bbox), consumes
 * it (and its value) and returns 1; 0 when it is not one; -1 on a bad
 * value (after printing the error). */
int cli_common_option(cli_common *common, int argc, char **argv, int *i);
/* Help text for the common options, for each subcommand's --help. */
extern const char cli_common_help[];

/* The value of option argv[*i] (advancing *i past it), or NULL after
 * reporting it missing. */
const char *cli_option_value(int argc, char **argv, int *i);
/* Parses a number option value; prints an error and returns false when
 * it is not a finite number / a non-negative integer within range. */
bool cli_parse_double(const char *opt, const char *text, double *out);
bool cli_parse_int(const char *opt, const char *text, long min, long max, long *out);

/* Applies --threads to OpenMP for the whole process (respecting
 * OMP_NUM_THREADS when it is 0). */
void cli_apply_threads(const cli_common *common);

/* Progress reporting: a bar on stderr when it is a terminal (stage,
 * percent, rate, time left), otherwise one line per finished stage; nothing
 * with --quiet. cli_callbacks() returns a record for library calls. */
typedef struct cli_progress {
    bool enabled, tty;
    const char *stage;
    double stage_start, last_draw;
    size_t items;              /* work items of the current stage, for rates */
    size_t pending_items;      /* items of the next stage to start */
} cli_progress;
void cli_progress_init(cli_progress *p, const cli_common *common);
tessel_callbacks cli_callbacks(cli_progress *p);
/* Sets how many items (points) the next stage to start processes, for the
 * points/s figure. */
void cli_progress_items(cli_progress *p, size_t items);
/* Ends the current stage's line. */
void cli_progress_done(cli_progress *p);

/* Parses "SUBCOMMAND IN OUT [options]": common options, then `extra` for
 * the subcommand's own (returns 1 if it consumed argv[*i] and its values, 0
 * if not its option, -1 after printing an error). Returns 1 to go on, 0
 * when --help was printed, -1 on a usage error (already reported). */
typedef int (*cli_extra_option_fn)(void *ctx, int argc, char **argv, int *i);
int cli_parse_in_out(int argc, char **argv, const char *help, cli_common *common,
                     const char **in, const char **out, cli_extra_option_fn extra,
                     void *ctx);

/* Runs a streaming reconstruction of `cloud` (read from `in`) into `out`:
 * opens the mesh writer (compact), calls run(cloud, callbacks, sink, ctx)
 * under a progress bar, then closes the file, or aborts it on failure so
 * nothing partial is left. `what` names the method in errors. Returns CLI_OK
 * or the exit code after printing the error; *t_write gets the seconds
 * spent finishing the file. The caller keeps and frees the cloud. */
typedef tessel_status (*cli_stream_fn)(const tessel_cloud *cloud, const tessel_callbacks *cb,
                                       const tessel_triangle_sink *sink, void *ctx);
int cli_stream_reconstruction(const char *in, const char *out, const tessel_cloud *cloud,
                              int ascii, const cli_common *common, const char *what,
                              cli_stream_fn run, void *ctx, double *t_write);

/* Writes s as a JSON string literal (quoted, escaped). */
void cli_json_string(FILE *out, const char *s);

/* Wall-clock seconds (monotonic). */
double cli_now(void);
/* Peak resident memory of the process so far, MiB. */
double cli_peak_mib(void);

/* Greedy projection's own options (--mu, --max-angle, --min-angle, --plane,
 * --max-spacing, --tile-points, --no-flip, --stream, --ascii, --method
 * greedy), for cli_parse_in_out; tools/cmd_reconstruct.c. */
typedef struct cli_greedy_opts {
    tessel_greedy_params p;
    int ascii;
    tessel_outofcore_params ooc; /* --memory SIZE, --scratch DIR */
} cli_greedy_opts;
/* How `reconstruct --method smooth` reads and reconstructs: tessel's own
 * (cmd_reconstruct_smooth) or through hooks (tessel-mpi: every process runs
 * the command; the reading and the reconstruction are collective, and a
 * worker process, which only serves tiles, neither writes nor reports). */
typedef struct cli_smooth_hooks {
    /* cli_read_cloud's contract */
    int (*read)(void *ctx, const char *path, tessel_cloud *cloud, const char *what,
                const cli_common *common);
    tessel_status (*reconstruct)(void *ctx, const tessel_cloud *cloud,
                                 const tessel_smooth_recon_params *params,
                                 const tessel_callbacks *callbacks, tessel_mesh *mesh,
                                 tessel_smooth_recon_stats *stats);
    void *ctx;
    bool worker;
} cli_smooth_hooks;
int cli_reconstruct_smooth_with(int argc, char **argv, const cli_smooth_hooks *hooks);

int cli_greedy_option(void *ctx, int argc, char **argv, int *i);

/* Out of core (tools/cmd_reconstruct_file.c): whether the cloud at in is
 * to be meshed out of core within o->ooc.memory (0: half the machine's
 * memory), judged by the file's size before reading it; and that run by
 * mesh (tessel_reconstruct_greedy_file, or tessel-mpi's over its
 * processes), with its summary. Returns an exit code. */
typedef tessel_status (*cli_file_mesher)(const char *in, const char *out,
                                         const tessel_read_params *read_params,
                                         const tessel_greedy_params *params,
                                         const tessel_write_params *write_params,
                                         const tessel_outofcore_params *op,
                                         const tessel_callbacks *callbacks,
                                         tessel_recon_summary *summary, tessel_diag *diag);
bool cli_outofcore_wanted(const char *in, const cli_greedy_opts *o);
int cli_reconstruct_outofcore(const char *in, const char *out, const cli_greedy_opts *o,
                              const cli_common *common, cli_file_mesher mesh);
/* Parses a size in bytes: a number with an optional K, M, G or T suffix
 * (powers of 1024). Prints an error and returns false when it is not. */
bool cli_parse_size(const char *opt, const char *text, uint64_t *out);

/* Subcommands. */
int cmd_info(int argc, char **argv);
int cmd_convert(int argc, char **argv);
int cmd_normals(int argc, char **argv);
int cmd_check(int argc, char **argv);
int cmd_render(int argc, char **argv);
int cmd_sample(int argc, char **argv);
int cmd_smooth(int argc, char **argv);
int cmd_simplify(int argc, char **argv);
/* tessel reconstruct IN OUT: dispatches on --mode / --method; the default
 * is the greedy projection (tools/cmd_reconstruct.c). */
int cmd_reconstruct(int argc, char **argv);
/* tessel reconstruct IN OUT --mode height|range|grid (fixed-plane mode);
 * argv[0] is "reconstruct". */
int cmd_reconstruct_fixed(int argc, char **argv);
/* tessel reconstruct IN OUT --method smooth (Mederos et al. 2003 pipeline);
 * argv[0] is "reconstruct". */
int cmd_reconstruct_smooth(int argc, char **argv);

#endif /* TESSEL_CLI_H */
