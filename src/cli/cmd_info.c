/* sepbrdf info: metadata of a file.  This build knows factor files (EXR,
 * see info_exr.c); measured tables come with the measured readers. */
#include <string.h>

#include "cli.h"

static void help(void) {
    printf("usage: sepbrdf info FILE... [OPTIONS]\n"
           "\n"
           "Print the metadata of each FILE. A factor file (g_KK.exr or h_KK.exr written\n"
           "by `sepbrdf factor`) shows its texture size and R, the term and J, sigma_j per\n"
           "channel (from the g files of its folder), parameterisation, source, form,\n"
           "method and the relative RMS error per J.\n"
           "\n"
           "options:\n" CLI_VERBOSITY_HELP "\n" CLI_EXIT_HELP);
}

static int ends_with(const char *s, const char *suffix) {
    size_t n = strlen(s), k = strlen(suffix);
    return n >= k && strcmp(s + n - k, suffix) == 0;
}

int cmd_info(int argc, char **argv) {
    int nfiles = 0, rc = EXIT_OK;
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "-h") == 0) {
            help();
            return EXIT_OK;
        }
        if (cli_verbosity_opt(argv[i])) continue;
        if (argv[i][0] == '-' && argv[i][1]) {
            cli_error("info", "unknown option '%s' (see `sepbrdf info --help`)", argv[i]);
            return EXIT_USAGE;
        }
        nfiles++;
    }
    if (nfiles == 0) {
        cli_error("info", "no FILE given (see `sepbrdf info --help`)");
        return EXIT_USAGE;
    }
    int first = 1;
    for (int i = 1; i < argc; i++) {
        if (argv[i][0] == '-' && argv[i][1]) continue;
        if (!first) putchar('\n');
        first = 0;
        int r;
        if (ends_with(argv[i], ".exr") || ends_with(argv[i], ".EXR")) {
            r = info_exr(argv[i], stdout);
        } else {
            cli_error("info", "%s: not a factor file (expected an .exr written by `sepbrdf factor`)", argv[i]);
            r = EXIT_IO;
        }
        if (r != EXIT_OK && rc == EXIT_OK) rc = r;
    }
    return rc;
}
