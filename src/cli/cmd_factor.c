/* sepbrdf factor: sample -> matrix -> truncated SVD -> EXR + report + GLSL. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

#define DEFAULT_SOURCE "microfacet:base=gold,roughness=0.5"
#define DEFAULT_OUT "sepbrdf-out"

static void help(void) {
    printf(
        "usage: sepbrdf factor [SOURCE] [OPTIONS]\n"
        "\n"
        "Sample SOURCE on a hemisphere grid, factor it by a truncated SVD into J\n"
        "texture pairs g_j(wi), h_j(wo), and write into the output folder:\n"
        "  g_JJ.exr, h_JJ.exr   one EXR per texture and term (R, G, B float32)\n"
        "  report.json          errors per J, sigma_j, timings, settings\n"
        "  sepbrdf.glsl         GLSL snippet: vec3 sb_brdf(vec3 L, vec3 V)\n"
        "\n"
        "SOURCE  MODEL[:key=value,...] (see `sepbrdf list`) or a measured file.\n"
        "        default: " DEFAULT_SOURCE "\n"
        "\n"
        "options:\n"
        "  -o, --out DIR        output folder, created if missing (default ./" DEFAULT_OUT ")\n"
        "  -r, --res R          cells per angular axis, 2..512; N = R*R directions (default 32)\n"
        "  -J, --terms J        number of terms kept, 1..N (default 4)\n"
        "      --param P        parameterisation: io (default; the seeds' theta-phi grid)\n"
        "      --form F         what is factored: f (default), cos (f cos theta_i),\n"
        "                       cos2 (f cos theta_i cos theta_o)\n"
        "      --method M       auto (default), full (dgesdd), topk, randomized\n"
        "      --max-error E    stop at the first J with relative RMS error <= E (0 < E < 1)\n"
        "      --theta-max DEG  largest sampled elevation in degrees (default 90)\n"
        "      --seed S         seed of randomized methods (default 1)\n"
        "      --half           store half floats with per-term scales\n"
        "  -q, --quiet          print nothing but errors\n"
        "  -v, --verbose        more detail on stderr\n"
        "  -h, --help           this text\n"
        "\n"
        "Texture layout: texel (x, y) of an R x R io texture is theta index x\n"
        "(s = theta / theta_max, clamped) and phi index y (t = phi / 2pi, repeated),\n"
        "i.e. direction k = R * i_phi + i_theta of the seeds' sequentialisation.\n");
}

typedef struct factor_opts {
    const char *source, *out;
    size_t res, terms;
    sb_param_kind_t param;
    sb_form_t form;
    sb_method_t method;
    double max_error, theta_max_deg;
    unsigned long long seed;
    int half;
} factor_opts_t;

static int parse(int argc, char **argv, factor_opts_t *o) {
    static const char *const n_out[] = {"-o", "--out", NULL}, *const n_res[] = {"-r", "--res", NULL},
                             *const n_terms[] = {"-J", "--terms", NULL}, *const n_param[] = {"--param", NULL},
                             *const n_form[] = {"--form", NULL}, *const n_method[] = {"--method", NULL},
                             *const n_maxerr[] = {"--max-error", NULL}, *const n_tmax[] = {"--theta-max", NULL},
                             *const n_seed[] = {"--seed", NULL}, *const n_half[] = {"--half", NULL},
                             *const n_q[] = {"-q", "--quiet", NULL}, *const n_v[] = {"-v", "--verbose", NULL},
                             *const n_help[] = {"-h", "--help", NULL};
    cli_args_t a = {argc, 1, argv, "factor"};
    for (; a.i < argc; a.i++) {
        const char *v = NULL;
        int m;
        if ((m = cli_opt(&a, n_help, 0, &v))) {
            help();
            return 0;
        }
        if ((m = cli_opt(&a, n_out, 1, &v))) {
            if (m < 0) return EXIT_USAGE;
            if (!*v) {
                cli_error("factor", "--out: empty folder name");
                return EXIT_USAGE;
            }
            o->out = v;
        } else if ((m = cli_opt(&a, n_res, 1, &v))) {
            if (m < 0 || cli_parse_size("factor", "--res", v, 2, 512, &o->res)) return EXIT_USAGE;
        } else if ((m = cli_opt(&a, n_terms, 1, &v))) {
            if (m < 0 || cli_parse_size("factor", "--terms", v, 1, (size_t)1 << 30, &o->terms)) return EXIT_USAGE;
        } else if ((m = cli_opt(&a, n_param, 1, &v))) {
            if (m < 0) return EXIT_USAGE;
            if (sb_param_kind_parse(v, &o->param) != SB_OK) {
                cli_error("factor", "--param '%s' unknown, need one of io, io-area, hd, iso", v);
                return EXIT_USAGE;
            }
        } else if ((m = cli_opt(&a, n_form, 1, &v))) {
            if (m < 0) return EXIT_USAGE;
            if (sb_form_parse(v, &o->form) != SB_OK) {
                cli_error("factor", "--form '%s' unknown, need one of f, cos, cos2", v);
                return EXIT_USAGE;
            }
        } else if ((m = cli_opt(&a, n_method, 1, &v))) {
            if (m < 0) return EXIT_USAGE;
            if (sb_method_parse(v, &o->method) != SB_OK) {
                cli_error("factor", "--method '%s' unknown, need one of auto, full, topk, randomized", v);
                return EXIT_USAGE;
            }
        } else if ((m = cli_opt(&a, n_maxerr, 1, &v))) {
            if (m < 0 || cli_parse_double("factor", "--max-error", v, 1e-15, 0.999999, &o->max_error))
                return EXIT_USAGE;
        } else if ((m = cli_opt(&a, n_tmax, 1, &v))) {
            if (m < 0 || cli_parse_double("factor", "--theta-max", v, 1, 90, &o->theta_max_deg)) return EXIT_USAGE;
        } else if ((m = cli_opt(&a, n_seed, 1, &v))) {
            size_t s;
            if (m < 0 || cli_parse_size("factor", "--seed", v, 0, SIZE_MAX, &s)) return EXIT_USAGE;
            o->seed = s;
        } else if (cli_opt(&a, n_half, 0, &v)) {
            o->half = 1;
        } else if (cli_opt(&a, n_q, 0, &v)) {
            g_verbosity = 0;
        } else if (cli_opt(&a, n_v, 0, &v)) {
            g_verbosity++;
        } else if (strcmp(argv[a.i], "-vv") == 0) {
            g_verbosity += 2;
        } else if (argv[a.i][0] == '-' && argv[a.i][1]) {
            cli_error("factor", "unknown option '%s' (see `sepbrdf factor --help`)", argv[a.i]);
            return EXIT_USAGE;
        } else if (!o->source) {
            o->source = argv[a.i];
        } else {
            cli_error("factor", "more than one SOURCE given ('%s' and '%s')", o->source, argv[a.i]);
            return EXIT_USAGE;
        }
    }
    return -1; /* go on */
}

static void write_report(json_t *j, const factor_opts_t *o, const sb_source_t *src, const sb_param_t *param,
                         const sb_matrix_t *m, const sb_factors_t *f, const double t[4]) {
    static const char *const cn[3] = {"R", "G", "B"};
    const sb_factor_errors_t *e = sb_factors_errors(f);
    size_t J = sb_factors_terms(f);
    json_begin_object(j, NULL);
    json_string(j, "sepbrdf_version", SB_VERSION_STRING);
    json_string(j, "command", "factor");
    json_string(j, "source", sb_source_description(src));
    json_string(j, "param", sb_param_name(param));
    json_string(j, "param_spec", sb_param_spec(param));
    json_int(j, "resolution", (long long)o->res);
    json_int(j, "rows", (long long)m->rows);
    json_int(j, "cols", (long long)m->cols);
    json_string(j, "form", sb_form_name(m->form));
    json_string(j, "method", sb_factors_get_meta(f, "method"));
    json_int(j, "terms", (long long)J);
    json_int(j, "terms_requested", (long long)o->terms);
    json_number(j, "max_error", o->max_error);
    json_string(j, "storage", o->half ? "half" : "float");
    json_begin_array(j, "channels");
    for (int c = 0; c < 3; c++)
        if (m->data[c]) json_string(j, NULL, cn[c]);
    json_end_array(j);
    size_t cells = m->rows * m->cols;
    json_begin_object(j, "mask");
    json_int(j, "cells", (long long)cells);
    json_int(j, "valid", (long long)m->valid_count);
    json_number(j, "coverage", cells ? (double)m->valid_count / (double)cells : 0);
    json_string(j, "missing_cells", "excluded from the error; zero in the factored matrix");
    json_end_object(j);
    json_begin_object(j, "norm");
    for (int c = 0; c < 3; c++)
        if (m->data[c]) json_number(j, cn[c], e->norm[c]);
    json_number(j, "all", e->norm[3]);
    json_end_object(j);
    json_begin_object(j, "sigma");
    for (int c = 0; c < 3; c++) {
        if (!m->data[c]) continue;
        json_begin_array(j, cn[c]);
        for (size_t k = 0; k < J; k++) json_number(j, NULL, sb_factors_sigma(f, k, (size_t)c));
        json_end_array(j);
    }
    json_end_object(j);
    json_begin_array(j, "errors");
    for (size_t k = 0; k < J; k++) {
        json_begin_object(j, NULL);
        json_int(j, "terms", (long long)(k + 1));
        json_number(j, "rel_rms", e->rel_rms[k * 4 + 3]);
        json_number(j, "max_abs", e->max_abs[k * 4 + 3]);
        json_begin_object(j, "rel_rms_channel");
        for (int c = 0; c < 3; c++)
            if (m->data[c]) json_number(j, cn[c], e->rel_rms[k * 4 + (size_t)c]);
        json_end_object(j);
        json_begin_object(j, "max_abs_channel");
        for (int c = 0; c < 3; c++)
            if (m->data[c]) json_number(j, cn[c], e->max_abs[k * 4 + (size_t)c]);
        json_end_object(j);
        json_end_object(j);
    }
    json_end_array(j);
    json_begin_object(j, "timings");
    json_number(j, "sample_s", t[0]);
    json_number(j, "factor_s", t[1]);
    json_number(j, "write_s", t[2]);
    json_number(j, "total_s", t[3]);
    json_end_object(j);
    json_begin_object(j, "files");
    json_begin_array(j, "g");
    char name[64];
    for (size_t k = 0; k < J; k++) {
        sb_exr_name(SB_SIDE_G, k, name, sizeof name);
        json_string(j, NULL, name);
    }
    json_end_array(j);
    json_begin_array(j, "h");
    for (size_t k = 0; k < J; k++) {
        sb_exr_name(SB_SIDE_H, k, name, sizeof name);
        json_string(j, NULL, name);
    }
    json_end_array(j);
    json_string(j, "glsl", "sepbrdf.glsl");
    json_end_object(j);
    json_end_object(j);
}

static void print_table(const sb_factors_t *f, const sb_matrix_t *m) {
    const sb_factor_errors_t *e = sb_factors_errors(f);
    size_t J = sb_factors_terms(f);
    printf("%4s  %12s  %12s", "J", "rel_rms", "max_abs");
    static const char *const cn[3] = {"R", "G", "B"};
    for (int c = 0; c < 3; c++)
        if (m->data[c]) printf("  %10s_%s", "rel_rms", cn[c]);
    printf("  %12s\n", "sigma_J(G)");
    for (size_t k = 0; k < J; k++) {
        printf("%4zu  %12.4e  %12.4e", k + 1, e->rel_rms[k * 4 + 3], e->max_abs[k * 4 + 3]);
        for (int c = 0; c < 3; c++)
            if (m->data[c]) printf("  %12.4e", e->rel_rms[k * 4 + (size_t)c]);
        printf("  %12.4e\n", sb_factors_sigma(f, k, m->data[1] ? 1 : 0));
    }
}

int cmd_factor(int argc, char **argv) {
    factor_opts_t o = {NULL, DEFAULT_OUT, 32, 4, SB_PARAM_IO, SB_FORM_F, SB_METHOD_AUTO, 0, 90, 1, 0};
    int rc = parse(argc, argv, &o);
    if (rc >= 0) return rc;
    if (!o.source) o.source = DEFAULT_SOURCE;

    sb_context_t *ctx = NULL;
    sb_source_t *src = NULL;
    sb_param_t *param = NULL;
    sb_matrix_t m = {0};
    sb_plan_t *plan = NULL;
    sb_factors_t *f = NULL;
    sb_result_t r;
    double t0 = cli_now(), t[4] = {0, 0, 0, 0};
    if (sb_context_create(&ctx) != SB_OK) {
        cli_error("factor", "out of memory");
        return EXIT_IO;
    }
    /* Everything is checked before the output folder is touched. */
    if ((r = sb_source_open(ctx, o.source, &src)) != SB_OK) goto fail;
    sb_param_opts_t po = {0};
    po.res = o.res;
    po.theta_max = o.theta_max_deg * SB_PI / 180;
    if ((r = sb_param_create(ctx, o.param, &po, &param)) != SB_OK) goto fail;
    size_t rows = sb_param_rows(param), cols = sb_param_cols(param), mn = rows < cols ? rows : cols;
    if (o.terms > mn) {
        cli_error("factor", "--terms %zu exceeds the %zu directions of --res %zu; lower --terms or raise --res",
                  o.terms, mn, o.res);
        rc = EXIT_USAGE;
        goto out;
    }
    sb_plan_opts_t pl = {0};
    pl.terms = o.terms;
    pl.max_error = o.max_error;
    pl.svd.method = o.method;
    pl.svd.seed = o.seed;
    if ((r = sb_plan_create(ctx, rows, cols, &pl, &plan)) != SB_OK) goto fail;

    cli_info(2, "sampling %s on %s (%zu x %zu)", sb_source_description(src), sb_param_spec(param), rows, cols);
    cli_progress("sampling", 0);
    sb_matrix_opts_t mo = {0};
    mo.form = o.form;
    if ((r = sb_matrix_build(ctx, src, param, &mo, &m)) != SB_OK) goto fail;
    double t1 = cli_now();
    t[0] = t1 - t0;
    cli_progress("factoring", 0.5);
    if ((r = sb_plan_execute(plan, &m, param, &f)) != SB_OK) goto fail;
    sb_factors_set_meta(f, "source", sb_source_description(src));
    double t2 = cli_now();
    t[1] = t2 - t1;
    cli_progress_done();

    if (cli_mkdirs(o.out) != 0) {
        cli_error("factor", "--out %s: cannot create the output folder", o.out);
        rc = EXIT_IO;
        goto out;
    }
    sb_exr_opts_t eo = {o.half};
    if ((r = sb_factors_write_exr(ctx, f, o.out, &eo)) != SB_OK) goto fail;
    char path[4096];
    snprintf(path, sizeof path, "%s/sepbrdf.glsl", o.out);
    if ((r = sb_glsl_write(ctx, path, param, m.form, sb_factors_terms(f), NULL)) != SB_OK) goto fail;
    double t3 = cli_now();
    t[2] = t3 - t2;
    t[3] = t3 - t0;
    snprintf(path, sizeof path, "%s/report.json", o.out);
    char tmp[4200];
    FILE *fp = cli_open_tmp(path, tmp, sizeof tmp);
    if (!fp) {
        cli_error("factor", "%s: cannot write", path);
        rc = EXIT_IO;
        goto out;
    }
    json_t j = {fp, 0, {0}};
    write_report(&j, &o, src, param, &m, f, t);
    if (cli_commit(fp, tmp, path, 1) != 0) {
        cli_error("factor", "%s: cannot write", path);
        rc = EXIT_IO;
        goto out;
    }
    if (g_verbosity >= 1) {
        printf("sepbrdf factor: %s\n  %s, %zu x %zu matrix, form %s, %zu terms, method %s\n",
               sb_source_description(src), sb_param_spec(param), rows, cols, sb_form_name(m.form),
               sb_factors_terms(f), sb_factors_get_meta(f, "method"));
        print_table(f, &m);
        printf("wrote %zu texture pairs, report.json and sepbrdf.glsl to %s/ (%.3f s)\n", sb_factors_terms(f),
               o.out, t[3]);
    }
    rc = EXIT_OK;
    goto out;
fail:
    cli_progress_done();
    rc = cli_fail("factor", ctx, r);
out:
    sb_factors_destroy(f);
    sb_plan_destroy(plan);
    sb_matrix_free(&m);
    sb_param_destroy(param);
    sb_source_destroy(src);
    sb_context_destroy(ctx);
    return rc;
}
