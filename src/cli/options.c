/* Option tables: one row per option generates both its parsing and its
 * --help line (cli.h).  The factor group (factor, render, study) shares
 * cli_factor_options, parsed into an sb_job_opts_t. */
#include <errno.h>
#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

int cli_set_flag(const char *cmd, const cli_option_t *op, const char *v, void *dst) {
    (void)cmd, (void)op, (void)v;
    *(int *)dst = 1;
    return 0;
}

int cli_set_size(const char *cmd, const cli_option_t *op, const char *v, void *dst) {
    return cli_parse_size(cmd, op->name, v, (size_t)op->lo, (size_t)op->hi, dst);
}

int cli_set_double(const char *cmd, const cli_option_t *op, const char *v, void *dst) {
    return cli_parse_double(cmd, op->name, v, op->lo, op->hi, dst);
}

int cli_set_string(const char *cmd, const cli_option_t *op, const char *v, void *dst) {
    (void)cmd, (void)op;
    *(const char **)dst = v;
    return 0;
}

static int set_param(const char *cmd, const cli_option_t *op, const char *v, void *dst) {
    sb_param_kind_t k;
    sb_param_opts_t po;
    if (strchr(v, ':')) { /* a layout spec as report.json's param_spec, e.g. iso:th=64,td=62,pd=16 */
        sb_context_t *ctx = NULL;
        sb_result_t r = sb_context_create(&ctx);
        if (r == SB_OK) r = sb_param_parse_spec(ctx, v, &k, &po);
        if (r != SB_OK) cli_error(cmd, "%s '%s': %s", op->name, v, ctx ? sb_context_last_error(ctx) : "out of memory");
        sb_context_destroy(ctx);
        if (r != SB_OK) return -1;
    } else if (strcmp(v, "auto") != 0 && sb_param_kind_parse(v, &k) != SB_OK) {
        cli_error(cmd, "%s '%s' unknown, need one of auto, %s", op->name, v, cli_param_names());
        return -1;
    }
    *(const char **)dst = v;
    return 0;
}

/* --weighted (lo 1) and --unweighted (lo -1): one of the two */
static int set_weighting(const char *cmd, const cli_option_t *op, const char *v, void *dst) {
    (void)v;
    int *w = dst;
    if (*w && *w != (int)op->lo) {
        cli_error(cmd, "--weighted and --unweighted ask for opposite things: give one");
        return -1;
    }
    *w = (int)op->lo;
    return 0;
}

static int set_form(const char *cmd, const cli_option_t *op, const char *v, void *dst) {
    sb_form_t f;
    if (sb_form_parse(v, &f) != SB_OK) {
        cli_error(cmd, "%s '%s' unknown, need one of %s, %s, %s", op->name, v, sb_form_name(SB_FORM_F),
                  sb_form_name(SB_FORM_COS), sb_form_name(SB_FORM_COS2));
        return -1;
    }
    *(const char **)dst = v;
    return 0;
}

static int set_warp(const char *cmd, const cli_option_t *op, const char *v, void *dst) {
    sb_warp_kind_t k;
    int ok = strcmp(v, "adaptive") == 0 || strcmp(v, "auto") == 0 ||
             (sb_warp_kind_parse(v, &k) == SB_OK && (k == SB_WARP_UNIFORM || k == SB_WARP_MERL));
    if (!ok) {
        cli_error(cmd, "%s '%s' unknown, need one of uniform, merl, adaptive, auto", op->name, v);
        return -1;
    }
    *(const char **)dst = v;
    return 0;
}

/* A scene spec (scene.h), checked now: a malformed spec is a usage error
 * (exit 1); a pairs file that cannot be read fails later, as input. */
static int set_scene(const char *cmd, const cli_option_t *op, const char *v, void *dst) {
    sb_context_t *ctx = NULL;
    sb_scene_t *s = NULL;
    if (sb_context_create(&ctx) != SB_OK) return -1;
    sb_result_t r = sb_scene_parse(ctx, v, &s);
    if (r != SB_OK && r != SB_ERR_IO) cli_error(cmd, "%s '%s': %s", op->name, v, sb_context_last_error(ctx));
    sb_scene_destroy(s);
    sb_context_destroy(ctx);
    if (r != SB_OK && r != SB_ERR_IO) return -1;
    *(const char **)dst = v;
    return 0;
}

static int set_method(const char *cmd, const cli_option_t *op, const char *v, void *dst) {
    if (sb_method_parse(v, dst) != SB_OK) {
        char names[256] = "";
        for (size_t m = 0; m < sb_method_count(); m++)
            snprintf(names + strlen(names), sizeof names - strlen(names), "%s%s", m ? ", " : "",
                     sb_method_name((sb_method_t)m));
        cli_error(cmd, "%s '%s' unknown, need one of %s", op->name, v, names);
        return -1;
    }
    return 0;
}

/* --method's help, from the library's registry: "auto (default), full
 * (dgesdd), topk, ...", lines broken before METHOD_HELP_WIDTH columns. */
#define METHOD_HELP_WIDTH 56
static const char *method_help(void) {
    static char help[512];
    size_t n = 0, line = 0;
    for (size_t m = 0; m < sb_method_count() && n + 1 < sizeof help; m++) {
        char item[128];
        const char *note = sb_method_note((sb_method_t)m);
        int len = snprintf(item, sizeof item, "%s%s%s%s%s", sb_method_name((sb_method_t)m), note[0] ? " (" : "", note,
                           note[0] ? ")" : "", m + 1 < sb_method_count() ? "," : "");
        const char *sep = m == 0 ? "" : line + 1 + (size_t)len > METHOD_HELP_WIDTH ? "\n" : " ";
        n += (size_t)snprintf(help + n, sizeof help - n, "%s%s", sep, item);
        line = sep[0] == '\n' ? (size_t)len : line + strlen(sep) + (size_t)len;
    }
    return help;
}

/* A size in bytes with an optional binary suffix K, M, G or T; the
 * library's memory limit (process-wide), at least 1 MiB. */
static int set_memory_limit(const char *cmd, const cli_option_t *op, const char *v, void *dst) {
    (void)dst;
    char *end = NULL;
    double x = strtod(v, &end);
    const char *units = "KMGT", *u = end && *end ? strchr(units, *end) : NULL;
    if (u) x *= (double)(1ull << (10 * (u - units + 1))), end++;
    if (!end || *end || !(x >= (double)(1u << 20) && x < 0x1p62)) {
        cli_error(cmd, "%s '%s': need a size of at least 1M, e.g. 2G", op->name, v);
        return -1;
    }
    sb_set_memory_limit((size_t)x);
    return 0;
}

int cli_list_items(const char *cmd, const char *opt, const char *s) {
    size_t n = strlen(s);
    if (n && s[0] != ',' && s[n - 1] != ',' && !strstr(s, ",,")) return 0;
    cli_error(cmd, "%s '%s': an empty item in the comma list", opt, s);
    return -1;
}

/* A byte count: a positive number with an optional unit, binary K, Ki,
 * KiB (1024), M, Mi, MiB, G, Gi, GiB, decimal kB / KB (1000), MB, GB, or
 * B; fractions are rounded down to whole bytes (3.2KB = 3200).  0, -1 and
 * garbage fail with a message naming the option and the text. */
int cli_parse_bytes(const char *cmd, const char *opt, const char *v, size_t *out) {
    static const struct {
        const char *unit;
        double scale;
    } units[] = {{"", 1},        {"B", 1},        {"K", 1024},      {"Ki", 1024},    {"KiB", 1024},    {"k", 1024},
                 {"kB", 1e3},    {"KB", 1e3},     {"M", 1 << 20},   {"Mi", 1 << 20}, {"MiB", 1 << 20}, {"MB", 1e6},
                 {"G", 1 << 30}, {"Gi", 1 << 30}, {"GiB", 1 << 30}, {"GB", 1e9}};
    char *end = NULL;
    errno = 0;
    double x = *v == '-' || *v == '+' ? NAN : strtod(v, &end);
    for (size_t i = 0; end && end != v && i < sizeof units / sizeof *units; i++) {
        if (strcmp(end, units[i].unit) != 0) continue;
        x *= units[i].scale;
        if (errno == 0 && x >= 1 && x < 0x1p52) {
            *out = (size_t)x;
            return 0;
        }
        break;
    }
    cli_error(cmd, "%s '%s': need a positive size in bytes, e.g. 3200, 16K, 48KiB, 1M (K = 1024, kB = 1000)", opt, v);
    return -1;
}

static int set_bytes(const char *cmd, const cli_option_t *op, const char *v, void *dst) {
    return cli_parse_bytes(cmd, op->name, v, dst);
}

static int set_channels(const char *cmd, const cli_option_t *op, const char *v, void *dst) {
    unsigned ch = 0;
    if (strspn(v, ",") < strlen(v) && cli_list_items(cmd, op->name, v) != 0) return -1; /* "R," as every list */
    for (const char *q = v; *q; q++) {
        if (*q == ',') continue;
        const char *at = strchr("RGBrgb", *q);
        if (!at) {
            cli_error(cmd, "%s '%s': '%c' is not R, G or B", op->name, v, *q);
            return -1;
        }
        ch |= 1u << ((at - "RGBrgb") % 3);
    }
    if (!ch) {
        cli_error(cmd, "%s '%s': no channel given (need R, G and/or B)", op->name, v);
        return -1;
    }
    *(unsigned *)dst = ch;
    return 0;
}

static int set_shaders(const char *cmd, const cli_option_t *op, const char *v, void *dst) {
    if (!*v) { /* the library's "" is its default, GLSL alone: here a value that names nothing */
        char names[128] = "";
        for (size_t k = 0; k < sb_shader_lang_count(); k++)
            snprintf(names + strlen(names), sizeof names - strlen(names), "%s, ", sb_shader_lang_name(k));
        cli_error(cmd, "%s '': no language given, need %sor all", op->name, names);
        return -1;
    }
    sb_context_t *ctx = NULL;
    sb_result_t r = sb_context_create(&ctx);
    if (r == SB_OK) r = sb_shader_lang_list(ctx, v, NULL);
    if (r != SB_OK) cli_error(cmd, "%s '%s': %s", op->name, v, ctx ? sb_context_last_error(ctx) : "out of memory");
    sb_context_destroy(ctx);
    if (r != SB_OK) return -1;
    *(const char **)dst = v;
    return 0;
}

static int set_seed(const char *cmd, const cli_option_t *op, const char *v, void *dst) {
    size_t s;
    if (cli_parse_size(cmd, op->name, v, 0, SIZE_MAX, &s)) return -1;
    *(unsigned long long *)dst = s ? s : 1; /* 0 is the job's "default", which is 1 */
    return 0;
}

#define F_ CLI_FACTOR
#define R_ CLI_RENDER
#define S_ CLI_STUDY
#define AT(m) offsetof(sb_job_opts_t, m)
const cli_option_t cli_factor_options[] = {
    /* render and study take lists of J: their own -J rows */
    {"-J", "--terms", "J",
     "number of terms kept, 1..N (default 4); auto fits an RGL\nfile's vndf with at most its theta_i slices (a "
     "warning\n"
     "says so)",
     cli_set_size, AT(terms), 1, (double)(1u << 30), F_},
    {"-r", "--res", "R", "cells per angular axis, 2..512; N = R*R directions (default 32)", cli_set_size, AT(res), 2,
     512, F_ | R_ | S_},
    {NULL, "--param", "P",
     "parameterisation: auto (default) or one of those below.\nauto screens every one that applies (iso: isotropic,\n"
     "reciprocal sources; vh: isotropic sources that are not\n"
     "reciprocal, RGL's own layout), with forms f and cos (not on iso;\ncos only on an RGL file: it stores f cos "
     "theta_i),\nsolid-angle weighted, on coarse grids, and "
     "factors the\n"
     "lowest headline error at J.  A layout named alone (io, hd,\n...) is auto restricted to it: its forms and "
     "weighting,\nwarps and term weights as auto would fit it, unless\n--form, --unweighted, --warp or --plain-terms "
     "say otherwise.\nA whole layout as report.json "
     "writes it (param_spec, e.g.\niso:th=64,td=62,pd=16 or hd:res=32,warp_h=...) is used as\ngiven: form f, "
     "unweighted, no warp tried, unless asked",
     set_param, AT(param), 0, 0, F_ | R_},
    {NULL, "--form", "F",
     "what is factored: f (f_r), cos (f cos theta_i), cos2 (f cos\ntheta_i cos theta_o); the GLSL divides back "
     "(default: auto's\nchoice of f and cos for the layout; f for a whole spec)",
     set_form, AT(form), 0, 0, F_ | R_ | S_},
    {NULL, "--warp", "W",
     "texel spacing along the elevations theta_h, theta_d (iso,\n"
     "hd; vh: theta_h, theta_v): uniform; merl (theta_h as MERL:\n"
     "square root); adaptive (measured from the source: equal\n"
     "interpolation error of f cos theta_i between texels); auto\n"
     "(adaptive where its headline error is lower); default: iso and\n"
     "vh merl, hd uniform, and auto where the headline at J is above\n"
     "5 % with those",
     set_warp, AT(warp), 0, 0, F_ | R_ | S_},
    {NULL, "--weighted", NULL,
     "weight cells by solid angle so the fit minimises the\nintegrated error (the default for auto and a layout named\n"
     "alone, always for --method nmf; for a whole spec: off)",
     set_weighting, AT(weighted), 1, 0, F_ | R_ | S_},
    {NULL, "--unweighted", NULL,
     "every cell alike (the lecture's plain SVD with --param io\n--form f --plain-terms); not for --method nmf",
     set_weighting, AT(weighted), -1, 0, F_ | R_ | S_},
    {NULL, "--scene", "SPEC",
     "fit and measure for the direction pairs a scene uses:\n"
     "'view=A..B;light=C..D' (theta from the normal, degrees),\n"
     "'lights=EL,AZ/EL,AZ/...' (render's sphere and camera, these\n"
     "lights), or 'pairs=FILE' (lines theta_i phi_i theta_o phi_o\n"
     "[weight], degrees), ';floor=X' (0..1000) the weight of the\n"
     "cells no pair touches; the headline is the scene's,\n"
     "report.json: scene also has the whole domain's and the\n"
     "unweighted fit's; a scene fit above 1.8x that over the\n"
     "whole domain is replaced unless floor=X is given\n"
     "(scene.fallback; docs/guide.md: Scene-weighted fits)",
     set_scene, AT(scene), 0, 0, F_ | R_ | S_},
    {NULL, "--zero-fill", NULL,
     "factor cells outside the domain / unmeasured as zeros\ninstead of excluding them (masked fit, the default)",
     cli_set_flag, AT(zero_fill), 0, 0, F_ | R_ | S_},
    {NULL, "--plain-terms", NULL,
     "keep the factorisation's terms as they are; by default a\nterm that raises the headline error at its J' is "
     "scaled\n"
     "down (report.json: term_weight), so errors fall with J'\n(unless that raises the error at J 1.25x), "
     "and texels are\nfitted for the bilinear lookup where that lowers the\nerror (report.json: fit.texels_fitted); "
     "the "
     "reconstruction\nis max(0, sum of the terms) unless this is given (the\nsnippet's SB_CLAMP, the layout's plain=1)",
     cli_set_flag, AT(plain_terms), 0, 0, F_ | R_ | S_},
    {NULL, "--cv-folds", "K",
     "scattered tables (Cornell, ALTA, CSV, simulated gonio):\ncut the measurements into K folds, refit the kept "
     "layout\nwithout each, and report the error at those left out, the\nfigure most random splits land near "
     "(report.json "
     "cv_headline; default:\n5 refits of 10 folds, each without a random tenth; 1: none)",
     cli_set_size, AT(cv_folds), 1, 100, F_},
    {NULL, "--metric-res", "R",
     "also the comparable error by the grid quadrature on an\nR-cell reference io grid (report.json "
     "comparable_grid;\nnone by default)",
     cli_set_size, AT(metric_res), 2, SB_METRIC_MAX_RES, F_ | S_},
    {NULL, "--method", "M", "" /* method_help(), from the registry */, set_method, AT(method), 0, 0, F_ | R_ | S_},
    {NULL, "--max-error", "E",
     "keep the fewest terms whose headline error (f cos theta_i,\nas a shader outputs it) is <= E (0 < E < 1); J "
     "(default\n32 here, at most R) is then the upper limit",
     cli_set_double, AT(max_error), 1e-15, 0.999999, F_},
    {NULL, "--channels", "C",
     "channels to factor, any of R, G, B (e.g. G or R,B;\ndefault all); the others are written as zero and\nevery "
     "error is over the channels factored",
     set_channels, AT(channels), 0, 0, F_},
    {NULL, "--theta-max", "DEG",
     "largest sampled elevation in degrees (default 90); the\nsnippet returns 0 beyond, and the errors (headline, "
     "bands,\nauto's ranking) are measured within the cap: both\ndirections within DEG of the normal "
     "(report.json\nestimate.domain \"cap\")",
     cli_set_double, AT(theta_max_deg), 1, 90, F_ | R_ | S_},
    {NULL, "--seed", "S", "seed of randomized methods (default 1)", set_seed, AT(seed), 0, 0, F_},
    {NULL, "--memory-limit", "SIZE",
     "largest memory to plan for, e.g. 2G (default 3/4 of RAM);\nio and io-area matrices beyond it are streamed",
     set_memory_limit, 0, 0, 0, F_ | S_},
    {NULL, "--half", NULL, "store half floats with per-term scales", cli_set_flag, AT(half), 0, 0, F_},
    {NULL, "--budget", "BYTES",
     "bytes of all textures written (every term, g and h, every\n"
     "channel; e.g. 16K, 48KiB, 1M): choose the layout, texture\n"
     "shape, warp, J and FLOAT or HALF of the lowest headline\n"
     "error within it; --param, --form, -r, -J, --half and --warp\n"
     "given constrain the search (--warp default there: auto);\n"
     "not with --max-error",
     set_bytes, AT(budget), 0, 0, F_},
    {NULL, "--shader", "LANGS",
     "also write the snippet in these shading languages, a\ncomma list of hlsl (sepbrdf.hlsl), msl (sepbrdf.metal),\n"
     "wgsl (sepbrdf.wgsl) or all; sepbrdf.glsl is always written",
     set_shaders, AT(shaders), 0, 0, F_},
    {NULL, "--previews", NULL,
     "also write g_JJ/h_JJ_scale-S.png: each texture in a diverging\ncolour map, blue -S, white 0, red +S (S = max "
     "|value|)",
     cli_set_flag, AT(previews), 0, 0, F_},
    {0},
};
#undef AT

int cli_table_opt(cli_args_t *a, const cli_option_t *table, unsigned command, void *base,
                  const cli_option_t **matched) {
    for (const cli_option_t *op = table; op->name; op++) {
        if (!(op->commands & command)) continue;
        const char *names[3] = {op->name, NULL, NULL}, *v = NULL;
        if (op->short_name) names[1] = op->short_name;
        int m = cli_opt(a, names, op->arg != NULL, &v);
        if (m == 0) continue;
        if (matched) *matched = op;
        if (m < 0 || op->set(a->cmd, op, v, (char *)base + op->offset) != 0) return -1;
        return 1;
    }
    return 0;
}

void cli_table_help(const cli_option_t *table, unsigned command) {
    for (const cli_option_t *op = table; op->name; op++) {
        if (!(op->commands & command) || !op->help) continue;
        char head[64];
        snprintf(head, sizeof head, "  %s%s%s %s", op->short_name ? op->short_name : "    ", op->short_name ? ", " : "",
                 op->name, op->arg ? op->arg : "");
        const char *h = op->set == set_method ? method_help() : op->help;
        size_t n = strcspn(h, "\n");
        if (strlen(head) > 22)
            printf("%s\n%23s%.*s\n", head, "", (int)n, h);
        else
            printf("%-23s%.*s\n", head, (int)n, h);
        for (h += n; *h == '\n'; h += n) {
            h++;
            n = strcspn(h, "\n");
            printf("%23s%.*s\n", "", (int)n, h);
        }
        if (op->set == set_param) /* the names, from the library's registry */
            for (size_t k = 0; k < sb_param_kind_count(); k++)
                printf("%25s%-8s %s\n", "", sb_param_kind_name((sb_param_kind_t)k),
                       sb_param_kind_description((sb_param_kind_t)k));
    }
}

/* The positional argument argv[a->i]; -1 after a message when one too many. */
static int positional(const cli_parser_t *p, const char *arg, size_t *n) {
    if (*n == p->max_args) {
        cli_error(p->cmd, "more than one %s given ('%s' and '%s')", p->what, p->args[0], arg);
        return -1;
    }
    p->args[(*n)++] = arg;
    if (p->nargs) *p->nargs = *n;
    return 0;
}

/* 1 if argv[a->i] is an option of the command (stored), 0 if not, -1 on a
 * bad value (message printed). */
static int known_option(cli_args_t *a, const cli_parser_t *p) {
    int m = 0;
    if (p->out_what && (m = cli_out_opt(a, p->out_what, p->out))) return m;
    for (const cli_table_use_t *t = p->tables; t < p->tables + 3 && t->table; t++) {
        const cli_option_t *op = NULL;
        if (!(m = cli_table_opt(a, t->table, t->command, t->base, &op))) continue;
        if (m > 0 && t->matched) *t->matched = op->name;
        return m;
    }
    if (p->measured && (m = cli_measured_opt(a, p->measured))) return m;
    return cli_verbosity_opt(a->argv[a->i]);
}

int cli_parse(int argc, char **argv, const cli_parser_t *p) {
    static const char *const n_help[] = {"-h", "--help", NULL};
    cli_args_t a = {argc, 1, argv, p->cmd};
    size_t n = p->nargs ? *p->nargs : 0;
    for (; a.i < argc; a.i++) {
        const char *v = NULL, *arg = argv[a.i];
        int m;
        if (cli_opt(&a, n_help, 0, &v)) {
            p->help();
            return EXIT_OK;
        }
        if ((m = known_option(&a, p)) != 0) {
            if (m < 0) return EXIT_USAGE;
        } else if (arg[0] == '-' && arg[1]) {
            cli_error(p->cmd, "unknown option '%s' (see `sepbrdf %s --help`)", arg, p->cmd);
            return EXIT_USAGE;
        } else if (positional(p, arg, &n) != 0) {
            return EXIT_USAGE;
        }
    }
    return -1;
}
