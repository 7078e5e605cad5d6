/* sepbrdf: command-line front end.  Only calls the public API. */
#include <errno.h>
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "env_plan.h"

typedef struct command {
    const char *name;
    int (*fn)(int argc, char **argv);
    const char *summary;
} command_t;

static const command_t commands[] = {
    {"factor", cmd_factor, "factor a BRDF into texture pairs (EXR), report and GLSL"},
    {"batch", cmd_batch, "factor many materials: one folder each, parallel, resumable, summary"},
    {"study", cmd_study, "error vs J for sources x parameterisations (CSV, JSON, PNG)"},
    {"list", cmd_list, "list models, their keys and the material presets"},
    {"sample", cmd_sample, "measure a source with a simulated gonioreflectometer (CSV)"},
    {"info", cmd_info, "describe a file: factor EXR metadata, or a measured table"},
    {"convert", cmd_convert, "write any source as a MERL .binary or a CSV table"},
    {"render", cmd_render, "render the original and reconstructions on a lit sphere (PNG, PSNR)"},
    {"view", cmd_view, "write an interactive viewer page (index.html, WebGL2) for a factor folder"},
    {"bench", cmd_bench, "benchmark the factor step: time, error, memory per method"},
};
#define NCOMMANDS (sizeof commands / sizeof commands[0])

static void usage(FILE *fp) {
    fprintf(fp, "usage: sepbrdf [--version] [--help] [-q|-v] COMMAND [OPTIONS]\n"
                "\n"
                "Turn a BRDF, analytic or measured, into J pairs of 2D textures g_j, h_j with\n"
                "f_r(wi, wo) ~ sum_j g_j(wi) h_j(wo), via a truncated SVD.\n"
                "\n"
                "commands:\n");
    for (size_t i = 0; i < NCOMMANDS; i++)
        fprintf(fp, "  %-8s %s\n", commands[i].name, commands[i].summary);
    fprintf(fp, "\n"
                "Run `sepbrdf COMMAND --help` for the options of a command.\n"
                "With no command at all, `sepbrdf factor` runs on the embedded default.\n"
                "\n"
                "options (before or after COMMAND):\n"
                "  -q, --quiet      display level 0: nothing but errors\n"
                "  -v, --verbose    display level 2: more detail on stderr (-vv: 3)\n"
                "  -V, --version    print the version and exit\n"
                "  -h, --help       this text\n"
                "Results go to stdout or files; messages and progress to stderr (progress\n"
                "only when stderr is a terminal). An output folder is written beside itself\n"
                "and swapped in whole when complete: a run that fails or is killed leaves\n"
                "the folder's previous set; files sepbrdf did not write are kept.\n"
                "\n" CLI_EXIT_HELP);
}

/* Results on stdout that could not all be written (a full disk, a closed
 * file) fail the run like any other output file: exit 2. */
static int finish(int rc) {
    errno = 0;
    if (fflush(stdout) != 0 || ferror(stdout)) {
        int e = errno ? errno : EIO;
        cli_error(NULL, "standard output: cannot write: %s", sb_io_why(e));
        return rc == EXIT_OK || rc == EXIT_USAGE ? EXIT_IO : rc;
    }
    return rc;
}

static int run(int argc, char **argv) {
    /* display options before the command */
    while (argc >= 2 && cli_verbosity_opt(argv[1])) {
        argv[1] = argv[0];
        argv++;
        argc--;
    }
    if (argc < 2) return cmd_factor(argc, argv);
    const char *c = argv[1];
    if (strcmp(c, "--help") == 0 || strcmp(c, "-h") == 0 || strcmp(c, "help") == 0) {
        usage(stdout);
        return EXIT_OK;
    }
    if (strcmp(c, "--version") == 0 || strcmp(c, "-V") == 0) {
        printf("sepbrdf %s\n", sb_version());
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

int main(int argc, char **argv) {
    sb_cli_malloc_env_restore();
    cli_signals_install();
    return finish(run(argc, argv));
}
