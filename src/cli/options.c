/* Option tables: one row per option generates both its parsing and its
 * --help line (cli.h).  The factor group (factor, render, study) shares
 * cli_factor_options, parsed into an sb_job_opts_t. */
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

static int set_param(const char *cmd, const cli_option_t *op, const char *v, void *dst) {
    sb_param_kind_t k;
    if (strcmp(v, "auto") != 0 && sb_param_kind_parse(v, &k) != SB_OK) {
        cli_error(cmd, "%s '%s' unknown, need one of auto, %s", op->name, v, cli_param_names());
        return -1;
    }
    *(const char **)dst = v;
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

static int set_method(const char *cmd, const cli_option_t *op, const char *v, void *dst) {
    if (sb_method_parse(v, dst) != SB_OK) {
        char names[128] = "";
        for (int m = 0; m < SB_METHOD_COUNT_; m++)
            snprintf(names + strlen(names), sizeof names - strlen(names), "%s%s", m ? ", " : "",
                     sb_method_name((sb_method_t)m));
        cli_error(cmd, "%s '%s' unknown, need one of %s", op->name, v, names);
        return -1;
    }
    return 0;
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

static int set_channels(const char *cmd, const cli_option_t *op, const char *v, void *dst) {
    unsigned ch = 0;
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
    {"-r", "--res", "R", "cells per angular axis, 2..512; N = R*R directions (default 32)", cli_set_size, AT(res), 2,
     512, F_ | R_ | S_},
    {NULL, "--param", "P",
     "parameterisation: auto (default) or one of those below.\nauto screens every one that applies (iso: isotropic,\n"
     "reciprocal sources), with forms f and cos (not on iso),\nsolid-angle weighted, on coarse grids, and factors the\n"
     "lowest headline error at J",
     set_param, AT(param), 0, 0, F_ | R_},
    {NULL, "--form", "F",
     "what is factored: f (default), cos (f cos theta_i),\ncos2 (f cos theta_i cos theta_o); the GLSL divides back",
     set_form, AT(form), 0, 0, F_ | R_ | S_},
    {NULL, "--weighted", NULL,
     "weight cells by solid angle so the fit minimises the\nintegrated error (on for every --param auto candidate)",
     cli_set_flag, AT(weighted), 0, 0, F_ | R_ | S_},
    {NULL, "--zero-fill", NULL,
     "factor cells outside the domain / unmeasured as zeros\ninstead of excluding them (masked fit, the default)",
     cli_set_flag, AT(zero_fill), 0, 0, F_ | R_ | S_},
    {NULL, "--plain-terms", NULL,
     "keep the factorisation's terms as they are; by default a\nterm that raises the headline error at its J' is "
     "scaled\n"
     "down (report.json: term_weights), so errors fall with J'",
     cli_set_flag, AT(plain_terms), 0, 0, F_ | R_ | S_},
    {NULL, "--metric-res", "R", "reference io grid of the comparable error (default 32)", cli_set_size, AT(metric_res),
     2, SB_METRIC_MAX_RES, F_ | S_},
    {NULL, "--method", "M", "auto (default), full (dgesdd), topk, randomized, stream", set_method, AT(method), 0, 0,
     F_ | R_ | S_},
    {NULL, "--max-error", "E",
     "keep the fewest terms whose headline error (f cos theta_i,\nas a shader outputs it) is <= E (0 < E < 1); J "
     "(default\n32 here, at most R) is then the upper limit",
     cli_set_double, AT(max_error), 1e-15, 0.999999, F_},
    {NULL, "--channels", "C",
     "channels to factor, any of R, G, B (e.g. G or R,B;\ndefault all); the others are written as zero", set_channels,
     AT(channels), 0, 0, F_},
    {NULL, "--theta-max", "DEG", "largest sampled elevation in degrees (default 90)", cli_set_double, AT(theta_max_deg),
     1, 90, F_ | R_},
    {NULL, "--seed", "S", "seed of randomized methods (default 1)", set_seed, AT(seed), 0, 0, F_},
    {NULL, "--memory-limit", "SIZE",
     "largest memory to plan for, e.g. 2G (default 3/4 of RAM);\nio and io-area matrices beyond it are streamed",
     set_memory_limit, 0, 0, 0, F_ | S_},
    {NULL, "--half", NULL, "store half floats with per-term scales", cli_set_flag, AT(half), 0, 0, F_},
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
        if (!(op->commands & command)) continue;
        char head[64];
        snprintf(head, sizeof head, "  %s%s%s %s", op->short_name ? op->short_name : "    ", op->short_name ? ", " : "",
                 op->name, op->arg ? op->arg : "");
        const char *h = op->help;
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
            for (int k = 0; k < SB_PARAM_KIND_COUNT_; k++)
                printf("%25s%-8s %s\n", "", sb_param_kind_name((sb_param_kind_t)k),
                       sb_param_kind_description((sb_param_kind_t)k));
    }
}
