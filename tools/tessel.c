/* tessel: the command-line tool. The only place with main(), argv parsing,
 * printing and exit codes; every subcommand is tools/cmd_<name>.c. */
#include "cli.h"

#include <string.h>

typedef struct command {
    const char *name;
    cli_command_fn run;
    const char *summary;
} command;

static const command commands[] = {
    {"reconstruct", cmd_reconstruct, "triangulate a point cloud (greedy projection by default)"},
    {"info", cmd_info, "describe a point cloud or mesh file"},
    {"convert", cmd_convert, "convert between file formats"},
    {"normals", cmd_normals, "estimate consistently oriented normals"},
    {"smooth", cmd_smooth, "denoise a cloud by robust local plane fitting"},
    {"simplify", cmd_simplify, "reduce a cloud to one representative per cluster"},
    {"check", cmd_check, "check a mesh: manifold, orientation, intersections, distances"},
    {"render", cmd_render, "render a mesh or point cloud to PNG"},
    {"sample", cmd_sample, "draw points uniformly over a mesh, with optional noise"},
};

static void usage(FILE *out)
{
    fprintf(out, "usage: tessel COMMAND [options] ...\n\n"
                 "tessel %s: surface reconstruction from 3D point clouds.\n\n"
                 "Commands:\n",
            tessel_version());
    for (size_t i = 0; i < sizeof commands / sizeof commands[0]; i++)
        fprintf(out, "  %-12s %s\n", commands[i].name, commands[i].summary);
    fprintf(out, "\n'tessel COMMAND --help' describes each command.\n"
                 "Exit codes: 0 ok, 1 usage, 2 input error, 3 output error, 4 failure,\n"
                 "130 / 143 interrupted by SIGINT (Ctrl-C) / SIGTERM (nothing partial is\n"
                 "left behind).\n");
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        usage(stderr);
        return CLI_USAGE;
    }
    const char *name = argv[1];
    if (strcmp(name, "--help") == 0 || strcmp(name, "-h") == 0 || strcmp(name, "help") == 0) {
        usage(stdout);
        return CLI_OK;
    }
    if (strcmp(name, "--version") == 0) {
        printf("tessel %s\n", tessel_version());
        return CLI_OK;
    }
    for (size_t i = 0; i < sizeof commands / sizeof commands[0]; i++) {
        if (strcmp(name, commands[i].name) == 0) {
            cli_install_signals();
            int rc = commands[i].run(argc - 1, argv + 1);
            if (cli_interrupted) {
                fprintf(stderr, "tessel: interrupted\n");
                return 128 + cli_interrupted;
            }
            return rc;
        }
    }
    cli_error("unknown command '%s' (see tessel --help)", name);
    return CLI_USAGE;
}
