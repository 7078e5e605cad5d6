/* sepbrdf info: what a file holds.
 *
 * One handler per kind of file, tried in order; the first whose match()
 * accepts the path prints it: a folder `factor` wrote, an EXR (factor
 * textures, vndf.exr), a sampler's tables (sampler.bin), a measured
 * table. */
#include <errno.h>
#include <math.h>
#include <stddef.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cli.h"

typedef struct info_opts {
    const char *path;
    size_t res;
    int json;
    sb_measured_opts_t mo;
} info_opts_t;

typedef struct info_kind {
    const char *what;
    int (*match)(const char *path);
    int (*run)(const info_opts_t *o);
} info_kind_t;

/* The measured formats of the registry, "MERL .binary, RGL ...". */
static const char *formats_text(void) {
    static char buf[512];
    size_t at = 0;
    for (size_t k = 0; k < sb_measured_format_count() && at < sizeof buf; k++) {
        int m = snprintf(buf + at, sizeof buf - at, "%s%s", k ? ", " : "", sb_measured_format_title(k));
        if (m < 0) break;
        at += (size_t)m;
    }
    return buf;
}

static const cli_option_t info_only[] = {
    {"-r", "--res", "R", "io grid of the coverage, 2..512 (default 32)", cli_set_size, offsetof(info_opts_t, res), 2,
     512, CLI_OWN},
    {NULL, "--json", NULL, "print JSON instead of the table (factor files and folders too)", cli_set_flag,
     offsetof(info_opts_t, json), 0, 0, CLI_OWN},
    {0},
};

static void help(void) {
    printf("usage: sepbrdf info FILE [--res R] [--json] [--interp M] [--lobe L] [--neighbours K]\n"
           "                         [--radius DEG] [--white e|d65]\n"
           "\n"
           "Print what FILE holds.  For a factor file (g_KK.exr or h_KK.exr written by\n"
           "`sepbrdf factor`): its texture size, term and J, sigma_j per channel (from the\n"
           "g files of its folder), parameterisation, source, form, method and the\n"
           "relative RMS error per J.  For a measured table (%s): the format and what\n"
           "it held (rows or cells read and used, rows skipped, an RGL file's description\n"
           "and layout), wavelengths, value ranges of the RGB f_r (1/sr), the\n"
           "interpolation, and the coverage: the fraction of the cells of the io grid\n"
           "(R x R directions each for wi and wo) for which the table gives a value.\n"
           "Cells with none are missing: masked in `sepbrdf factor`.  For a set's\n"
           "sampler.bin (--method nmf): its cells, layers and the cosine and GGX lobe\n"
           "shares, after checking it as the GLSL sampler reads it (a damaged file:\n"
           "exit 2, the layer and texel named).  For a folder `factor` wrote: its\n"
           "first factor file, after checking its sampler.bin where it has one.\n"
           "\n"
           "options:\n",
           formats_text());
    cli_table_help(info_only, CLI_OWN);
    printf(CLI_MEASURED_HELP CLI_VERBOSITY_HELP "\n" CLI_EXIT_HELP);
}

static int is_regular_file(const char *path) {
    struct stat st;
    return stat(path, &st) == 0 && S_ISREG(st.st_mode);
}

static void flags_text(unsigned f, char *buf, size_t size) {
    snprintf(buf, size, "%s%s%s%s", f & SB_SOURCE_MEASURED ? "measured " : "",
             f & SB_SOURCE_ISOTROPIC ? "isotropic " : "anisotropic ", f & SB_SOURCE_RECIPROCAL ? "reciprocal " : "",
             f & SB_SOURCE_GRAY ? "gray " : "");
    size_t n = strlen(buf);
    if (n && buf[n - 1] == ' ') buf[n - 1] = 0;
}

/* The coverage map: 10-degree bands of theta_i (rows) and theta_o. */
#define MAP_BANDS 9

static double map_fraction(const size_t *known, const size_t *cells, size_t at) {
    return cells[at] ? (double)known[at] / (double)cells[at] : NAN;
}

static void print_map(const size_t *known, const size_t *cells) {
    printf("coverage map  %% of cells known, theta_i (rows) x theta_o (columns), 10-degree bands:\n"
           "  theta_i  ");
    for (int b = 0; b < MAP_BANDS; b++)
        printf("  %2d-%-2d", 10 * b, 10 * b + 10);
    printf("\n");
    for (size_t a = 0; a < MAP_BANDS; a++) {
        printf("  %2zu-%-2zu    ", 10 * a, 10 * a + 10);
        for (size_t b = 0; b < MAP_BANDS; b++) {
            double f = map_fraction(known, cells, a * MAP_BANDS + b);
            if (isnan(f))
                printf("  %5s", "-");
            else
                printf("  %5.1f", 100 * f);
        }
        printf("\n");
    }
}

/* What `info` shows of a table. */
typedef struct table_view {
    const char *path, *param;
    const sb_measured_info_t *in;
    size_t known, cells;
    double cov;
    const size_t *mk, *mc; /* coverage map */
    char flags[128];
} table_view_t;

static const char *const channel_names[3] = {"R", "G", "B"};

static void print_table_json(const table_view_t *v) {
    static const char *const *cn = channel_names;
    int scattered = v->in->dims > 0;
    json_t j = {stdout, 0, {0}};
    json_begin_object(&j, NULL);
    json_string(&j, "file", v->path);
    json_string(&j, "kind", "measured table");
    json_string(&j, "format", v->in->format);
    json_int(&j, "rows", (long long)v->in->rows);
    json_int(&j, "samples", (long long)v->in->samples);
    json_int(&j, "missing", (long long)v->in->missing);
    json_int(&j, "negative", (long long)v->in->negative);
    json_int(&j, "out_of_gamut", (long long)v->in->out_of_gamut);
    json_int(&j, "nan_rows", (long long)v->in->nan_rows);
    json_int(&j, "horizon_rows", (long long)v->in->horizon_rows);
    json_int(&j, "channels", (long long)v->in->channels);
    json_int(&j, "wavelengths", (long long)v->in->wavelengths);
    if (v->in->wavelengths) {
        json_number(&j, "wavelength_min_nm", v->in->wl_min);
        json_number(&j, "wavelength_max_nm", v->in->wl_max);
        json_string(&j, "white", v->in->white == SB_WHITE_D65 ? "d65" : "e");
        json_string(&j, "gamut", sb_gamut_name(v->in->gamut));
    }
    json_number(&j, "theta_i_max_deg", v->in->theta_i_max * 180 / SB_PI);
    json_number(&j, "theta_o_max_deg", v->in->theta_o_max * 180 / SB_PI);
    json_begin_object(&j, "value");
    for (int c = 0; c < 3; c++) {
        json_begin_object(&j, cn[c]);
        json_number(&j, "min", v->in->value_min[c]);
        json_number(&j, "max", v->in->value_max[c]);
        json_number(&j, "mean", v->in->value_mean[c]);
        json_end_object(&j);
    }
    json_end_object(&j);
    json_string(&j, "flags", v->flags);
    json_string(&j, "interp", sb_interp_name(v->in->interp));
    if (scattered) {
        json_int(&j, "neighbours", (long long)v->in->neighbours);
        json_number(&j, "spacing_deg", v->in->spacing * 180 / SB_PI);
        json_number(&j, "radius_deg", v->in->radius * 180 / SB_PI);
        json_int(&j, "embedding_dims", (long long)v->in->dims);
    }
    json_begin_object(&j, "details");
    for (size_t k = 0; k < v->in->nfields; k++)
        if (isfinite(v->in->fields[k].number))
            json_number(&j, v->in->fields[k].key, v->in->fields[k].number);
        else
            json_string(&j, v->in->fields[k].key, v->in->fields[k].text);
    json_end_object(&j);
    json_begin_object(&j, "coverage");
    json_string(&j, "param", v->param);
    json_int(&j, "cells", (long long)v->cells);
    json_int(&j, "known", (long long)v->known);
    json_int(&j, "missing", (long long)(v->cells - v->known));
    json_number(&j, "fraction", v->cov);
    json_begin_array(&j, "map");
    for (size_t a = 0; a < MAP_BANDS; a++) {
        json_begin_array(&j, NULL);
        for (size_t b = 0; b < MAP_BANDS; b++)
            json_number(&j, NULL, map_fraction(v->mk, v->mc, a * MAP_BANDS + b));
        json_end_array(&j);
    }
    json_end_array(&j);
    json_end_object(&j);
    json_end_object(&j);
}

static void print_table_text(const table_view_t *v) {
    static const char *const *cn = channel_names;
    int scattered = v->in->dims > 0;
    printf("file          %s\n", v->path);
    printf("format        %s\n", v->in->format);
    for (size_t k = 0; k < v->in->nfields; k++)
        printf("%-13s %s\n", v->in->fields[k].key, v->in->fields[k].text);
    if (v->in->wavelengths) {
        printf("wavelengths   %zu (%g..%g nm) -> linear sRGB, white %s\n", v->in->wavelengths, v->in->wl_min,
               v->in->wl_max, v->in->white == SB_WHITE_D65 ? "D65 (Bradford)" : "E");
        printf("gamut         %zu %s out of the sRGB gamut (a negative channel after the CIE conversion: "
               "colours more saturated than sRGB shows), %s%s\n",
               v->in->out_of_gamut, scattered ? "rows" : "nodes", sb_gamut_name(v->in->gamut),
               v->in->out_of_gamut && v->in->gamut == SB_GAMUT_KEEP ? " (--gamut clip or desaturate maps them)" : "");
    } else
        printf("channels      %zu%s\n", v->in->channels, v->in->channels == 1 ? " (gray)" : " (RGB)");
    printf("f_r (1/sr)    %12s %12s %12s\n", "min", "max", "mean");
    for (int c = 0; c < 3; c++)
        printf("  %-11s %12.5g %12.5g %12.5g\n", cn[c], v->in->value_min[c], v->in->value_max[c], v->in->value_mean[c]);
    printf("flags         %s\n", v->flags);
    printf("coverage      %s: %zu of %zu cells (%.2f %%), %zu missing\n", v->param, v->known, v->cells, 100 * v->cov,
           v->cells - v->known);
    print_map(v->mk, v->mc);
}

static int info_measured(const info_opts_t *o) {
    sb_context_t *ctx = NULL;
    sb_source_t *src = NULL;
    sb_param_t *param = NULL;
    sb_measured_info_t in;
    sb_result_t r;
    int rc = EXIT_OK;
    if (sb_context_create(&ctx) != SB_OK) {
        cli_error("info", "out of memory");
        return EXIT_IO;
    }
    if ((r = sb_measured_open(ctx, o->path, &o->mo, &src, &in)) != SB_OK) goto fail;
    sb_param_opts_t po = {0};
    po.res = o->res;
    if ((r = sb_param_create(ctx, SB_PARAM_IO, &po, &param)) != SB_OK) goto fail;
    size_t mk[MAP_BANDS * MAP_BANDS], mc[MAP_BANDS * MAP_BANDS];
    if ((r = sb_measured_coverage_map(ctx, src, param, MAP_BANDS, mk, mc)) != SB_OK) goto fail;
    table_view_t v = {o->path, sb_param_spec(param), &in, 0, 0, 0, mk, mc, ""};
    for (size_t b = 0; b < MAP_BANDS * MAP_BANDS; b++) {
        v.known += mk[b];
        v.cells += mc[b];
    }
    v.cov = v.cells ? (double)v.known / (double)v.cells : 0;
    flags_text(in.flags, v.flags, sizeof v.flags);
    if (o->json)
        print_table_json(&v);
    else
        print_table_text(&v);
    goto out;
fail:
    rc = cli_fail("info", ctx, r);
out:
    sb_param_destroy(param);
    sb_source_destroy(src);
    sb_context_destroy(ctx);
    return rc;
}

/* A file that starts with OpenEXR's magic, under any name (vndf.exr
 * renamed said "unrecognised measured table"), or an .exr name unless a
 * measured reader opens the file: such a table is described as `factor`
 * reads it, content first (it said "cannot read as an EXR file"); other
 * content named .exr keeps the EXR reader's message. */
static int is_factor_exr(const char *path) {
    size_t n = strlen(path);
    int named = n >= 4 && (strcmp(path + n - 4, ".exr") == 0 || strcmp(path + n - 4, ".EXR") == 0);
    struct stat st; /* a FIFO or a device: the EXR reader refuses it, naming it (opened here, a FIFO blocks) */
    if (stat(path, &st) != 0 || !S_ISREG(st.st_mode)) return named;
    static const unsigned char magic[4] = {0x76, 0x2f, 0x31, 0x01};
    unsigned char head[4];
    FILE *fp = fopen(path, "rb");
    size_t got = fp ? fread(head, 1, sizeof head, fp) : 0;
    if (fp) fclose(fp);
    if (got == sizeof head && memcmp(head, magic, sizeof head) == 0) return 1;
    if (!named) return 0;
    sb_context_t *ctx = NULL;
    sb_source_t *src = NULL;
    sb_context_create(&ctx);
    int table = sb_measured_open(ctx, path, NULL, &src, NULL) == SB_OK;
    sb_source_destroy(src);
    sb_context_destroy(ctx);
    return !table;
}
static int info_factors(const info_opts_t *o) { return info_exr(o->path, stdout, o->json, NULL); }

/* A folder: the set `factor` wrote (its first texture, g_00.exr, says
 * what the set is; its sampler.bin, where it has one, checked) or refused
 * saying what info takes. */
static int is_dir(const char *path) {
    struct stat st;
    return stat(path, &st) == 0 && S_ISDIR(st.st_mode);
}
static int info_folder(const info_opts_t *o) {
    char g[4200], rep[4200];
    snprintf(g, sizeof g, "%s/g_00.exr", o->path);
    snprintf(rep, sizeof rep, "%s/report.json", o->path);
    if (access(g, F_OK) != 0) {
        cli_error("info",
                  "%s: a folder without factors (no g_00.exr: not a set `factor` wrote); info takes a measured "
                  "table (%s), a factor texture (.exr) or a folder `factor` wrote",
                  o->path, formats_text());
        return EXIT_IO;
    }
    char sb[4200]; /* its sampler tables checked (a damaged one was passed over, exit 0) */
    snprintf(sb, sizeof sb, "%s/sampler.bin", o->path);
    if (access(sb, F_OK) == 0 && info_sampler(sb, NULL, 0) != EXIT_OK) return EXIT_IO;
    if (!o->json)
        printf("%s: a factor set (its errors, timings and choices: %s%s)\n", o->path, rep,
               access(rep, F_OK) == 0 ? "" : ", missing");
    return info_exr(g, stdout, o->json, o->json ? o->path : NULL);
}

static int info_tables(const info_opts_t *o) { return info_sampler(o->path, stdout, o->json); }

static const info_kind_t kinds[] = {
    {"factor folder", is_dir, info_folder},
    {"factor textures", is_factor_exr, info_factors},
    {"sampler tables", info_is_sampler, info_tables},
    {"measured table", is_regular_file, info_measured},
};

int cmd_info(int argc, char **argv) {
    info_opts_t o;
    memset(&o, 0, sizeof o);
    o.res = 32;
    cli_parser_t p = {.cmd = "info",
                      .help = help,
                      .tables = {{info_only, CLI_OWN, &o, NULL}},
                      .measured = &o.mo,
                      .what = "FILE",
                      .args = &o.path,
                      .max_args = 1};
    int rc = cli_parse(argc, argv, &p);
    if (rc >= 0) return rc;
    if (!o.path) {
        cli_error("info", "no FILE given (see `sepbrdf info --help`)");
        return EXIT_USAGE;
    }
    struct stat st;
    if (stat(o.path, &st) != 0) {
        cli_error("info", "%s: %s", o.path, strerror(errno));
        return EXIT_IO;
    }
    for (size_t k = 0; k < sizeof kinds / sizeof kinds[0]; k++)
        if (kinds[k].match(o.path)) return kinds[k].run(&o);
    cli_error("info", "%s: not a file this command knows (measured tables: %s)", o.path, formats_text());
    return EXIT_IO;
}
