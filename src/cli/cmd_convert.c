/* sepbrdf convert: write any source as a MERL .binary or a sepbrdf CSV. */
#include <errno.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

typedef enum out_format { OUT_AUTO, OUT_MERL, OUT_CSV } out_format_t;

static int ends_with(const char *s, const char *ext) {
    size_t n = strlen(s), e = strlen(ext);
    return n > e && strcmp(s + n - e, ext) == 0;
}

/* An option's value and whether it was given. */
typedef struct given_double {
    double v;
    int set;
} given_double_t;

typedef struct convert_opts {
    const char *source, *out;
    out_format_t format;
    int extrapolated; /* 0 not given, 1 drop, 2 keep */
    given_double_t horizon;
    sb_measured_opts_t mo;
} convert_opts_t;

static int set_format(const char *cmd, const cli_option_t *op, const char *v, void *dst) {
    if (strcmp(v, "merl") == 0)
        *(out_format_t *)dst = OUT_MERL;
    else if (strcmp(v, "csv") == 0)
        *(out_format_t *)dst = OUT_CSV;
    else {
        cli_error(cmd, "%s '%s' unknown, need merl or csv", op->name, v);
        return -1;
    }
    return 0;
}

static int set_extrapolated(const char *cmd, const cli_option_t *op, const char *v, void *dst) {
    if (strcmp(v, "drop") == 0 || strcmp(v, "keep") == 0) {
        *(int *)dst = v[0] == 'k' ? 2 : 1;
        return 0;
    }
    cli_error(cmd, "%s '%s' unknown, need keep or drop", op->name, v);
    return -1;
}

static int set_given(const char *cmd, const cli_option_t *op, const char *v, void *dst) {
    given_double_t *g = dst;
    g->set = 1;
    return cli_set_double(cmd, op, v, &g->v);
}

static const cli_option_t convert_only[] = {
    {NULL, "--format", "F", "merl or csv", set_format, offsetof(convert_opts_t, format), 0, 0, CLI_OWN},
    {NULL, "--extrapolated", "K",
     "merl: drop (default) writes the cells whose value\n"
     "lies above the largest the source measured as\n"
     "missing (-1); keep writes them as evaluated",
     set_extrapolated, offsetof(convert_opts_t, extrapolated), 0, 0, CLI_OWN},
    {NULL, "--horizon", "DEG",
     "a table that stores f cos theta_i (RGL): leave out\n"
     "the samples (csv) or cells (merl) whose light lies\n"
     "within DEG of the horizon (default 1; 0 keeps all)",
     set_given, offsetof(convert_opts_t, horizon), 0, 89, CLI_OWN},
    {0},
};

static void help(void) {
    printf("usage: sepbrdf convert SOURCE -o FILE [--format merl|csv] [table options]\n"
           "\n"
           "Write SOURCE (a model spec, see `sepbrdf list`, or a measured file) as\n"
           "  merl  a MERL .binary (90 x 90 x 180 cells): f_r at each cell's centre,\n"
           "        -1 (missing) where SOURCE has no value, (--extrapolated) a value\n"
           "        above the largest it measured or (--horizon, RGL) its light within\n"
           "        1 deg of the horizon;\n"
           "  csv   a sepbrdf CSV table (docs/measured.md): a measured table's samples as\n"
           "        read (MERL: its measured cells at their centres; RGL: its colour\n"
           "        nodes at their directions, but those with the light within 1 deg of\n"
           "        the horizon, --horizon), no interpolation; a model is measured on the\n"
           "        simulated gonioreflectometer's default grid (18,1,18,72; anisotropic\n"
           "        sources 18,24,18,72; other grids: `sepbrdf sample`).\n"
           "The format follows FILE's extension (.binary, .csv) unless --format is given.\n"
           "\n"
           "options:\n"
           "  -o, --out FILE       output file (required); written to a temporary name and\n"
           "                       renamed when complete\n");
    cli_table_help(convert_only, CLI_OWN);
    printf(CLI_MEASURED_HELP CLI_VERBOSITY_HELP "\n" CLI_EXIT_HELP);
}

/* Returns -1 to go on, else the exit code. */
static int parse(int argc, char **argv, convert_opts_t *o) {
    cli_parser_t p = {.cmd = "convert",
                      .help = help,
                      .out_what = "file",
                      .out = &o->out,
                      .tables = {{convert_only, CLI_OWN, o, NULL}},
                      .measured = &o->mo,
                      .what = "SOURCE",
                      .args = &o->source,
                      .max_args = 1};
    int rc = cli_parse(argc, argv, &p);
    if (rc >= 0) return rc;
    if (!o->source || !o->out) {
        cli_error("convert", "%s (see `sepbrdf convert --help`)", !o->source ? "no SOURCE given" : "no -o FILE given");
        return EXIT_USAGE;
    }
    if (o->format == OUT_AUTO)
        o->format = ends_with(o->out, ".binary") ? OUT_MERL : ends_with(o->out, ".csv") ? OUT_CSV : OUT_AUTO;
    if (o->format == OUT_AUTO) {
        cli_error("convert", "-o %s: no .binary or .csv extension; name the format with --format merl|csv", o->out);
        return EXIT_USAGE;
    }
    if (o->format == OUT_CSV && o->extrapolated) {
        cli_error("convert", "--extrapolated applies to MERL output; a CSV holds the source's samples as read");
        return EXIT_USAGE;
    }
    return -1;
}

/* MERL: the file, then what it holds and what it left out. */
static sb_write_opts_t write_opts(const convert_opts_t *o) {
    return (sb_write_opts_t){o->extrapolated == 2, !o->horizon.set ? 0 : o->horizon.v > 0 ? o->horizon.v : -1};
}

static sb_result_t write_merl(sb_context_t *ctx, const convert_opts_t *o, const sb_source_t *src) {
    sb_write_opts_t wo = write_opts(o);
    sb_merl_write_stats_t st;
    sb_result_t r = sb_merl_write_stats(ctx, o->out, src, &wo, &st);
    if (r != SB_OK) return r;
    cli_info(1, "sepbrdf convert: %s to %s (MERL): %zu of %zu cells with a value (%.1f %%), largest f_r %.4g",
             sb_source_description(src), o->out, st.written, st.cells, 100.0 * (double)st.written / (double)st.cells,
             st.value_max);
    if (st.grazing)
        cli_info(1,
                 "sepbrdf convert: %zu cells with the light within %g deg of the horizon written as missing (the "
                 "table stores f cos theta_i: f there is that over a cosine near 0); --horizon 0 writes them",
                 st.grazing, st.horizon_deg);
    if (st.above && !wo.keep_extrapolated)
        cli_info(1,
                 "sepbrdf convert: %zu cells whose value lies above the largest the table measured (%.4g, up to "
                 "%.4g: extrapolated, not measured, e.g. an RGL table's f cos theta divided by a grazing cos theta) "
                 "written as missing (-1); --extrapolated keep writes them",
                 st.above, st.value_measured, st.above_max);
    else if (st.above)
        cli_error("convert",
                  "warning: %zu cells hold values above the largest the table measured (%.4g, up to %.4g): "
                  "extrapolated, not measured (e.g. an RGL table's f cos theta divided by a grazing cos theta), "
                  "kept by --extrapolated keep; a fit of %s will spend its terms on them",
                  st.above, st.value_measured, st.above_max, o->out);
    return SB_OK;
}

/* The CSV: the samples when the source has them, else the default grid. */
static sb_result_t write_csv(sb_context_t *ctx, FILE *fp, const convert_opts_t *o, const sb_source_t *src,
                             sb_csv_write_stats_t *st) {
    *st = (sb_csv_write_stats_t){0};
    sb_write_opts_t wo = write_opts(o);
    if (sb_source_sample_count(src)) return sb_measured_write_csv_stats(ctx, fp, src, &wo, st);
    int iso = (sb_source_flags(src) & SB_SOURCE_ISOTROPIC) != 0;
    sb_gonio_opts_t go = {18, iso ? 1 : 24, 18, 72, 0, 1};
    return sb_gonio_write_csv(ctx, fp, src, &go, &st->rows);
}

static void csv_said(const convert_opts_t *o, const sb_source_t *src, const sb_csv_write_stats_t *st) {
    cli_info(1, "sepbrdf convert: %zu rows of %s to %s (CSV)", st->rows, sb_source_description(src), o->out);
    if (st->left_out)
        cli_info(1,
                 "sepbrdf convert: %zu samples with the light within %g deg of the horizon left out (the table "
                 "stores f cos theta_i: f there is that over a cosine near 0, up to %.4g); --horizon 0 keeps them",
                 st->left_out, st->horizon_deg, st->left_out_max);
    if (strncmp(sb_source_description(src), "rgl:", 4) == 0)
        cli_error("convert",
                  "warning: %s holds %zu of the RGL file's %zu colour nodes (nodes whose light falls below the "
                  "horizon are no pair) at their direction pairs: between them the file is read through its "
                  "VNDF warp, which rows of direction pairs cannot carry, so a fit of the CSV interpolates "
                  "between its rows instead; factor the .bsdf itself",
                  o->out, st->rows, sb_source_sample_count(src));
}

/* CSV: to a temporary name, renamed when complete.  Returns the exit code. */
static int convert_csv(sb_context_t *ctx, const convert_opts_t *o, const sb_source_t *src) {
    char tmp[4200];
    sb_csv_write_stats_t st;
    FILE *fp = cli_open_tmp(o->out, tmp, sizeof tmp);
    if (!fp) {
        cli_error("convert", "--out %s: cannot write: %s", o->out, strerror(errno));
        return EXIT_IO;
    }
    sb_result_t r = write_csv(ctx, fp, o, src, &st);
    if (r != SB_OK) {
        cli_commit(fp, tmp, o->out, 0);
        return cli_fail("convert", ctx, r);
    }
    int e = cli_commit(fp, tmp, o->out, 1);
    if (e != 0) {
        cli_error("convert", "--out %s: cannot write: %s", o->out, sb_io_why(e));
        return EXIT_IO;
    }
    csv_said(o, src, &st);
    return EXIT_OK;
}

int cmd_convert(int argc, char **argv) {
    convert_opts_t o = {0};
    int rc = parse(argc, argv, &o);
    if (rc >= 0) return rc;
    sb_context_t *ctx = NULL;
    sb_source_t *src = NULL;
    sb_result_t r;
    if (sb_context_create(&ctx) != SB_OK) {
        cli_error("convert", "out of memory");
        return EXIT_IO;
    }
    if ((r = sb_job_source_open(ctx, o.source, &o.mo, &src)) != SB_OK)
        rc = cli_fail("convert", ctx, r);
    else if (o.format == OUT_MERL)
        rc = (r = write_merl(ctx, &o, src)) != SB_OK ? cli_fail("convert", ctx, r) : EXIT_OK;
    else
        rc = convert_csv(ctx, &o, src);
    sb_source_destroy(src);
    sb_context_destroy(ctx);
    return rc;
}
