/* sepbrdf sample: a simulated gonioreflectometer writing a CSV table. */
#include <errno.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

static int parse_gonio(const char *v, size_t n[4]) {
    const char *p = v;
    for (int k = 0; k < 4; k++) {
        char buf[32];
        size_t len = strcspn(p, ",");
        if (len == 0 || len >= sizeof buf || (k < 3 && p[len] != ',') || (k == 3 && p[len] != 0)) {
            cli_error("sample", "--gonio '%s': need four integers Nti,Npi,Nto,Npo (e.g. 18,1,18,72)", v);
            return -1;
        }
        memcpy(buf, p, len);
        buf[len] = 0;
        static const char *const names[4] = {"--gonio N_theta_i", "--gonio N_phi_i", "--gonio N_theta_o",
                                             "--gonio N_phi_o"};
        if (cli_parse_size("sample", names[k], buf, 1, 4096, &n[k])) return -1;
        p += len + (k < 3);
    }
    return 0;
}

static int set_gonio(const char *cmd, const cli_option_t *op, const char *v, void *dst) {
    (void)cmd, (void)op;
    sb_gonio_opts_t *go = dst;
    size_t n[4];
    if (parse_gonio(v, n)) return -1;
    go->n_theta_i = n[0];
    go->n_phi_i = n[1];
    go->n_theta_o = n[2];
    go->n_phi_o = n[3];
    return 0;
}

static int set_seed(const char *cmd, const cli_option_t *op, const char *v, void *dst) {
    size_t s;
    if (cli_parse_size(cmd, op->name, v, 0, SIZE_MAX, &s)) return -1;
    *(uint64_t *)dst = s;
    return 0;
}

/* The options of `sample` (stored into an sb_gonio_opts_t); --gonio is
 * documented in help(), its value names do not fit the column. */
static const cli_option_t sample_only[] = {
    {"-g", "--gonio", "Nti,Npi,Nto,Npo", NULL, set_gonio, 0, 0, 0, CLI_OWN},
    {NULL, "--noise", "SIGMA",
     "multiplicative Gaussian noise v (1 + SIGMA z), z ~ N(0,1)\nper value, 0..10 (default 0)", cli_set_double,
     offsetof(sb_gonio_opts_t, noise), 0, 10, CLI_OWN},
    {NULL, "--seed", "S", "seed of the noise (default 1): same seed, same table", set_seed,
     offsetof(sb_gonio_opts_t, seed), 0, 0, CLI_OWN},
    {0},
};

static void help(void) {
    printf("usage: sepbrdf sample SOURCE [--gonio Nti,Npi,Nto,Npo] [--noise SIGMA] [--seed S] [table options]\n"
           "       [-o FILE]\n"
           "\n"
           "Measure SOURCE (a model spec, see `sepbrdf list`, or a measured file) at\n"
           "the positions of a simulated gonioreflectometer and write a sepbrdf CSV\n"
           "table (docs/measured.md), readable by `sepbrdf factor` and `sepbrdf info`.\n"
           "\n"
           "options:\n"
           "  -g, --gonio Nti,Npi,Nto,Npo  light and detector positions (default 18,1,18,72):\n"
           "                       theta_k = (k + 1/2) 90/N deg (cell centres, the horizon is\n"
           "                       never measured), phi_k = k 360/N deg; the spacing is\n"
           "                       90/N_theta and 360/N_phi degrees.  One light azimuth\n"
           "                       (Npi = 1) suffices for an isotropic source.\n");
    cli_table_help(sample_only, CLI_OWN);
    printf("  -o, --out FILE       output CSV (default: standard output); written to a\n"
           "                       temporary name and renamed when complete\n" CLI_MEASURED_HELP CLI_VERBOSITY_HELP "\n"
           "Rows where SOURCE has no value (a table's missing pairs) are left out.\n\n" CLI_EXIT_HELP);
}

/* A table of no rows is no measurement: `info` and `factor` refuse it. */
static sb_result_t no_rows(sb_context_t *ctx, const sb_gonio_opts_t *go) {
    return sb_error(ctx, SB_ERR_FORMAT,
                    "no position of --gonio %zu,%zu,%zu,%zu falls where the source has a value (0 rows; nothing "
                    "written): try a finer --gonio, or `sepbrdf convert` for a table's own directions",
                    go->n_theta_i, go->n_phi_i, go->n_theta_o, go->n_phi_o);
}

int cmd_sample(int argc, char **argv) {
    const char *source = NULL, *out = NULL;
    sb_gonio_opts_t go = {18, 1, 18, 72, 0, 1};
    sb_measured_opts_t mo;
    memset(&mo, 0, sizeof mo);
    cli_parser_t p = {.cmd = "sample",
                      .help = help,
                      .out_what = "file",
                      .out = &out,
                      .tables = {{sample_only, CLI_OWN, &go, NULL}},
                      .measured = &mo,
                      .what = "SOURCE",
                      .args = &source,
                      .max_args = 1};
    int rc = cli_parse(argc, argv, &p);
    if (rc >= 0) return rc;
    if (!source) {
        cli_error("sample", "no SOURCE given (see `sepbrdf sample --help`)");
        return EXIT_USAGE;
    }
    double rows_d = (double)go.n_theta_i * (double)go.n_phi_i * (double)go.n_theta_o * (double)go.n_phi_o;
    if (rows_d > 2147483648.0) {
        cli_error("sample", "--gonio %zu,%zu,%zu,%zu: %.0f positions, more than 2^31 rows", go.n_theta_i, go.n_phi_i,
                  go.n_theta_o, go.n_phi_o, rows_d);
        return EXIT_USAGE;
    }

    sb_context_t *ctx = NULL;
    sb_source_t *src = NULL;
    sb_result_t r;
    if (sb_context_create(&ctx) != SB_OK) {
        cli_error("sample", "out of memory");
        return EXIT_IO;
    }
    /* The source is opened before anything is written. */
    if ((r = sb_job_source_open(ctx, source, &mo, &src)) != SB_OK) {
        rc = cli_fail("sample", ctx, r);
        goto done;
    }
    size_t rows = 0;
    if (!out || strcmp(out, "-") == 0) {
        r = sb_gonio_write_csv(ctx, stdout, src, &go, &rows);
        if (r == SB_OK && rows == 0) r = no_rows(ctx, &go);
        if (r == SB_OK && fflush(stdout) != 0)
            r = sb_error(ctx, SB_ERR_IO, "standard output: cannot write: %s", sb_io_why(errno));
        rc = r == SB_OK ? EXIT_OK : cli_fail("sample", ctx, r);
        goto done;
    }
    char tmp[4200];
    /* Written as OUT.tmp-PID beside it and renamed when complete: OUT is
     * the previous file or the new one, never a part (SIGXFSZ is ignored,
     * so a file size limit is a write error, cleaned up here). */
    FILE *fp = cli_open_tmp(out, tmp, sizeof tmp);
    if (!fp) {
        cli_error("sample", "--out %s: cannot write: %s", out, sb_io_why(errno));
        rc = EXIT_IO;
        goto done;
    }
    r = sb_gonio_write_csv(ctx, fp, src, &go, &rows);
    int e = r == SB_ERR_IO && ferror(fp) ? (errno ? errno : EIO) : 0; /* the failed write's */
    if (r == SB_OK && rows == 0) r = no_rows(ctx, &go);
    if (r != SB_OK) {
        cli_commit(fp, tmp, out, 0);
        if (e) cli_error("sample", "--out %s: cannot write: %s", out, sb_io_why(e));
        rc = e ? EXIT_IO : cli_fail("sample", ctx, r);
        goto done;
    }
    if ((e = cli_commit(fp, tmp, out, 1)) != 0) {
        cli_error("sample", "--out %s: cannot write: %s", out, sb_io_why(e));
        rc = EXIT_IO;
        goto done;
    }
    cli_info(1, "sepbrdf sample: %zu rows of %s to %s", rows, sb_source_description(src), out);
    rc = EXIT_OK;
done:
    sb_source_destroy(src);
    sb_context_destroy(ctx);
    return rc;
}
