/* sepbrdf: command-line front end.  Only calls the public API. */
#include <stdio.h>
#include <string.h>

#include "cli.h"

typedef struct command {
    const char *name;
    int (*fn)(int argc, char **argv);
    const char *summary;
} command_t;

static const command_t commands[] = {
    {"factor", cmd_factor, "factor a BRDF into texture pairs (EXR), report and GLSL"},
    {"list", cmd_list, "list models, their keys and the material presets"},
    {"bench", cmd_bench, "benchmark the factor step: time, error, memory per method"},
};
#define NCOMMANDS (sizeof commands / sizeof commands[0])

static void usage(FILE *fp) {
    fprintf(fp,
            "usage: sepbrdf [--version] [--help] COMMAND [OPTIONS]\n"
            "\n"
            "Turn a BRDF, analytic or measured, into J pairs of 2D textures g_j, h_j with\n"
            "f_r(wi, wo) ~ sum_j g_j(wi) h_j(wo), via a truncated SVD.\n"
            "\n"
            "commands:\n");
    for (size_t i = 0; i < NCOMMANDS; i++) fprintf(fp, "  %-8s %s\n", commands[i].name, commands[i].summary);
    fprintf(fp,
            "\n"
            "Run `sepbrdf COMMAND --help` for the options of a command.\n"
            "With no command at all, `sepbrdf factor` runs on the embedded default.\n"
            "\n"
            "exit status: 0 ok, 1 usage (bad option, value or spec), 2 input/output\n"
            "(missing or malformed file, unwritable output), 3 numerical failure.\n");
}

int main(int argc, char **argv) {
    if (argc < 2) return cmd_factor(argc, argv);
    const char *c = argv[1];
    if (strcmp(c, "--help") == 0 || strcmp(c, "-h") == 0 || strcmp(c, "help") == 0) {
        usage(stdout);
        return EXIT_OK;
    }
    if (strcmp(c, "--version") == 0 || strcmp(c, "-V") == 0) {
        printf("sepbrdf %s\n", SB_VERSION_STRING);
        return EXIT_OK;
    }
    for (size_t i = 0; i < NCOMMANDS; i++)
        if (strcmp(c, commands[i].name) == 0) return commands[i].fn(argc - 1, argv + 1);
    if (c[0] == '-') {
        cli_error(NULL, "unknown option '%s' (see `sepbrdf --help`)", c);
        return EXIT_USAGE;
    }
    cli_error(NULL, "unknown command '%s' (see `sepbrdf --help`)", c);
    return EXIT_USAGE;
}
