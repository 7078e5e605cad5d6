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
        "      --param P        parameterisation: auto (default), io (the seeds' theta-phi\n"
        "                       grid of (wi, wo)), io-area (equal-area maps), hd (half/\n"
        "                       difference vectors), iso (theta_h x (theta_d, phi_d)).\n"
        "                       auto factors every one that applies, with forms f and\n"
        "                       cos2, solid-angle weighted, and keeps the lowest\n"
        "                       comparable error at J; `--param io` alone reproduces\n"
        "                       the seeds' method exactly (form f, unweighted)\n"
        "      --form F         what is factored: f (default), cos (f cos theta_i),\n"
        "                       cos2 (f cos theta_i cos theta_o); the GLSL divides back\n"
        "      --weighted       weight cells by solid angle so the fit minimises the\n"
        "                       integrated error (on for every --param auto candidate)\n"
        "      --zero-fill      factor cells outside the domain / unmeasured as zeros\n"
        "                       instead of excluding them (masked fit, the default)\n"
        "      --metric-res R   reference io grid of the comparable error (default 32)\n"
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
    size_t res, terms, metric_res;
    int param_auto;          /* --param auto (default) */
    sb_param_kind_t param;
    int form_set;            /* --form given */
    sb_form_t form;
    sb_method_t method;
    double max_error, theta_max_deg;
    unsigned long long seed;
    int half, weighted, zero_fill;
} factor_opts_t;

/* One complete factorisation of the source on one parameterisation. */
typedef struct attempt {
    sb_param_t *param;
    sb_matrix_t m;
    sb_factors_t *f;
    sb_plan_stats_t stats;
    sb_metric_t metric;
    int weighted, zero_fill;
    double t_sample, t_factor, t_metric;
} attempt_t;

static void attempt_free(attempt_t *a) {
    sb_factors_destroy(a->f);
    sb_matrix_free(&a->m);
    sb_param_destroy(a->param);
    memset(a, 0, sizeof *a);
}

static int parse(int argc, char **argv, factor_opts_t *o) {
    static const char *const n_out[] = {"-o", "--out", NULL}, *const n_res[] = {"-r", "--res", NULL},
                             *const n_terms[] = {"-J", "--terms", NULL}, *const n_param[] = {"--param", NULL},
                             *const n_form[] = {"--form", NULL}, *const n_method[] = {"--method", NULL},
                             *const n_maxerr[] = {"--max-error", NULL}, *const n_tmax[] = {"--theta-max", NULL},
                             *const n_seed[] = {"--seed", NULL}, *const n_half[] = {"--half", NULL},
                             *const n_q[] = {"-q", "--quiet", NULL}, *const n_v[] = {"-v", "--verbose", NULL},
                             *const n_help[] = {"-h", "--help", NULL}, *const n_weighted[] = {"--weighted", NULL},
                             *const n_zero[] = {"--zero-fill", NULL}, *const n_mres[] = {"--metric-res", NULL};
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
            if (strcmp(v, "auto") == 0) {
                o->param_auto = 1;
            } else if (sb_param_kind_parse(v, &o->param) != SB_OK) {
                cli_error("factor", "--param '%s' unknown, need one of auto, io, io-area, hd, iso", v);
                return EXIT_USAGE;
            } else {
                o->param_auto = 0;
            }
        } else if ((m = cli_opt(&a, n_form, 1, &v))) {
            if (m < 0) return EXIT_USAGE;
            if (sb_form_parse(v, &o->form) != SB_OK) {
                cli_error("factor", "--form '%s' unknown, need one of f, cos, cos2", v);
                return EXIT_USAGE;
            }
            o->form_set = 1;
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
        } else if (cli_opt(&a, n_weighted, 0, &v)) {
            o->weighted = 1;
        } else if (cli_opt(&a, n_zero, 0, &v)) {
            o->zero_fill = 1;
        } else if ((m = cli_opt(&a, n_mres, 1, &v))) {
            if (m < 0 || cli_parse_size("factor", "--metric-res", v, 2, 256, &o->metric_res)) return EXIT_USAGE;
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

/* A candidate of --param auto and its comparable error. */
typedef struct cand {
    sb_param_kind_t kind;
    sb_form_t form;
    int weighted;
    double err;
    int ok;
} cand_t;

typedef struct report_ctx {
    const factor_opts_t *o;
    const sb_source_t *src;
    const attempt_t *a;
    const cand_t *cands;
    size_t ncand;
    const double *rel_stored; /* rel_rms of the stored (FLOAT/HALF) factors, J * 4; NULL if unknown */
} report_ctx_t;

static void write_report(json_t *j, const report_ctx_t *rx, const double t[4]) {
    static const char *const cn[3] = {"R", "G", "B"};
    const factor_opts_t *o = rx->o;
    const attempt_t *a = rx->a;
    const sb_matrix_t *m = &a->m;
    const sb_factors_t *f = a->f;
    const sb_param_t *param = a->param;
    const sb_factor_errors_t *e = sb_factors_errors(f);
    size_t J = sb_factors_terms(f);
    json_begin_object(j, NULL);
    json_string(j, "sepbrdf_version", SB_VERSION_STRING);
    json_string(j, "command", "factor");
    json_string(j, "source", sb_source_description(rx->src));
    json_string(j, "source_spec", o->source);
    json_string(j, "param", sb_param_name(param));
    json_string(j, "param_spec", sb_param_spec(param));
    json_int(j, "resolution", (long long)o->res);
    json_int(j, "rows", (long long)m->rows);
    json_int(j, "cols", (long long)m->cols);
    size_t w, h;
    json_begin_object(j, "texture_size");
    sb_param_texture_size(param, SB_SIDE_G, &w, &h);
    json_begin_array(j, "g");
    json_int(j, NULL, (long long)w);
    json_int(j, NULL, (long long)h);
    json_end_array(j);
    sb_param_texture_size(param, SB_SIDE_H, &w, &h);
    json_begin_array(j, "h");
    json_int(j, NULL, (long long)w);
    json_int(j, NULL, (long long)h);
    json_end_array(j);
    json_end_object(j);
    json_string(j, "form", sb_form_name(m->form));
    json_bool(j, "weighted", a->weighted);
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
    json_string(j, "invalid_cells", a->zero_fill ? "zero-filled in the fit, excluded from the error"
                                                 : "excluded from the fit (masked imputation) and from the error");
    json_end_object(j);
    json_begin_object(j, "fit");
    json_bool(j, "masked", a->stats.masked);
    json_int(j, "iterations", a->stats.fit_iterations);
    json_bool(j, "converged", a->stats.fit_converged);
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
        json_number(j, "rel_rms_stored", rx->rel_stored ? rx->rel_stored[k * 4 + 3] : NAN);
        json_number(j, "max_abs", e->max_abs[k * 4 + 3]);
        json_number(j, "comparable", a->metric.rel_l2[k]);
        json_number(j, "negative_fraction", a->metric.neg_frac[k]);
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
    json_number(j, "negative_texels", a->metric.neg_texels);
    json_int(j, "metric_resolution", (long long)o->metric_res);
    if (o->param_auto) {
        const cand_t *cd = rx->cands;
        json_begin_array(j, "auto_tried");
        for (size_t i = 0; i < rx->ncand; i++) {
            json_begin_object(j, NULL);
            json_string(j, "param", sb_param_kind_name(cd[i].kind));
            json_string(j, "form", sb_form_name(cd[i].form));
            json_bool(j, "weighted", cd[i].weighted);
            json_bool(j, "ok", cd[i].ok);
            json_number(j, "comparable", cd[i].ok ? cd[i].err : NAN);
            json_end_object(j);
        }
        json_end_array(j);
    }
    json_begin_object(j, "timings");
    json_number(j, "sample_s", t[0]);
    json_number(j, "factor_s", t[1]);
    json_number(j, "metric_s", a->t_metric);
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

static void print_table(const attempt_t *a) {
    const sb_factors_t *f = a->f;
    const sb_matrix_t *m = &a->m;
    const sb_factor_errors_t *e = sb_factors_errors(f);
    size_t J = sb_factors_terms(f);
    printf("%4s  %12s  %12s  %12s  %9s", "J", "comparable", "rel_rms", "max_abs", "negative");
    static const char *const cn[3] = {"R", "G", "B"};
    for (int c = 0; c < 3; c++)
        if (m->data[c]) printf("  %10s_%s", "rel_rms", cn[c]);
    printf("\n");
    for (size_t k = 0; k < J; k++) {
        printf("%4zu  %12.4e  %12.4e  %12.4e  %8.2f%%", k + 1, a->metric.rel_l2[k], e->rel_rms[k * 4 + 3],
               e->max_abs[k * 4 + 3], 100 * a->metric.neg_frac[k]);
        for (int c = 0; c < 3; c++)
            if (m->data[c]) printf("  %12.4e", e->rel_rms[k * 4 + (size_t)c]);
        printf("\n");
    }
}

/* Sample, factor and measure one candidate; errors via ctx. */
static sb_result_t attempt_run(sb_context_t *ctx, const sb_source_t *src, const factor_opts_t *o, sb_param_kind_t kind,
                               sb_form_t form, int weighted, attempt_t *a) {
    memset(a, 0, sizeof *a);
    a->weighted = weighted;
    a->zero_fill = o->zero_fill;
    sb_param_opts_t po = {0};
    po.res = o->res;
    po.theta_max = o->theta_max_deg * SB_PI / 180;
    sb_result_t r = sb_param_create(ctx, kind, &po, &a->param);
    if (r != SB_OK) return r;
    size_t rows = sb_param_rows(a->param), cols = sb_param_cols(a->param), mn = rows < cols ? rows : cols;
    if (o->terms > mn)
        return sb_error(ctx, SB_ERR_RANGE, "--terms %zu exceeds the %zu rows/columns of %s; lower --terms or raise --res",
                        o->terms, mn, sb_param_spec(a->param));
    sb_plan_opts_t pl = {0};
    pl.terms = o->terms;
    pl.max_error = o->max_error;
    pl.svd.method = o->method;
    pl.svd.seed = o->seed;
    pl.weighted = weighted;
    pl.zero_fill = o->zero_fill;
    sb_plan_t *plan = NULL;
    if ((r = sb_plan_create(ctx, rows, cols, &pl, &plan)) != SB_OK) return r;
    double t0 = cli_now();
    cli_info(2, "sampling %s on %s (%zu x %zu), form %s%s", sb_source_description(src), sb_param_spec(a->param), rows,
             cols, sb_form_name(form), weighted ? ", weighted" : "");
    sb_matrix_opts_t mo = {0};
    mo.form = form;
    if ((r = sb_matrix_build(ctx, src, a->param, &mo, &a->m)) != SB_OK) {
        sb_plan_destroy(plan);
        return r;
    }
    double t1 = cli_now();
    r = sb_plan_execute(plan, &a->m, a->param, &a->f);
    sb_plan_stats(plan, &a->stats);
    sb_plan_destroy(plan);
    if (r != SB_OK) return r;
    double t2 = cli_now();
    sb_factors_set_meta(a->f, "source", sb_source_description(src));
    sb_metric_opts_t mo2 = {0};
    mo2.res = o->metric_res;
    if ((r = sb_metric_compute(ctx, src, a->f, a->param, form, &mo2, &a->metric)) != SB_OK) return r;
    a->t_sample = t1 - t0;
    a->t_factor = t2 - t1;
    a->t_metric = cli_now() - t2;
    return SB_OK;
}

int cmd_factor(int argc, char **argv) {
    factor_opts_t o = {0};
    o.out = DEFAULT_OUT;
    o.res = 32;
    o.terms = 4;
    o.param_auto = 1;
    o.param = SB_PARAM_IO;
    o.form = SB_FORM_F;
    o.method = SB_METHOD_AUTO;
    o.theta_max_deg = 90;
    o.seed = 1;
    o.metric_res = 32;
    int rc = parse(argc, argv, &o);
    if (rc >= 0) return rc;
    if (!o.source) o.source = DEFAULT_SOURCE;

    sb_context_t *ctx = NULL;
    sb_source_t *src = NULL;
    attempt_t best = {0};
    double *rel_stored = NULL; /* errors of the stored precision, J * 4 */
    sb_result_t r;
    double t0 = cli_now();
    if (sb_context_create(&ctx) != SB_OK) {
        cli_error("factor", "out of memory");
        return EXIT_IO;
    }
    /* Everything is checked before the output folder is touched. */
    if ((r = sb_source_open(ctx, o.source, &src)) != SB_OK) goto fail;

    /* Candidates: the one asked for, or (auto) every parameterisation that
     * applies, with f and f cos cos unless --form fixes it. */
    cand_t cands[2 * SB_PARAM_KIND_COUNT_];
    size_t ncand = 0;
    if (!o.param_auto) {
        cands[ncand++] = (cand_t){o.param, o.form, o.weighted, 0, 0};
    } else {
        for (int k = 0; k < SB_PARAM_KIND_COUNT_; k++) {
            if (k == SB_PARAM_ISO && !(sb_source_flags(src) & SB_SOURCE_ISOTROPIC)) continue;
            sb_param_t *probe = NULL;
            sb_param_opts_t po = {0};
            po.res = o.res;
            po.theta_max = o.theta_max_deg * SB_PI / 180;
            if (sb_param_create(NULL, (sb_param_kind_t)k, &po, &probe) != SB_OK) continue; /* not available */
            sb_param_destroy(probe);
            if (o.form_set) {
                cands[ncand++] = (cand_t){(sb_param_kind_t)k, o.form, 1, 0, 0};
            } else {
                cands[ncand++] = (cand_t){(sb_param_kind_t)k, SB_FORM_F, 1, 0, 0};
                cands[ncand++] = (cand_t){(sb_param_kind_t)k, SB_FORM_COS2, 1, 0, 0};
            }
        }
    }
    for (size_t i = 0; i < ncand; i++) {
        attempt_t a;
        cli_progress("factoring", (double)i / (double)ncand);
        r = attempt_run(ctx, src, &o, cands[i].kind, cands[i].form, cands[i].weighted, &a);
        if (r != SB_OK) {
            attempt_free(&a);
            if (!o.param_auto || (r != SB_ERR_NUMERIC && r != SB_ERR_UNSUPPORTED)) goto fail;
            cli_info(1, "factor: --param auto: %s/%s failed: %s", sb_param_kind_name(cands[i].kind),
                     sb_form_name(cands[i].form), sb_context_last_error(ctx));
            continue;
        }
        size_t J = sb_factors_terms(a.f);
        cands[i].err = a.metric.rel_l2[J - 1];
        cands[i].ok = 1;
        if (!best.f || cands[i].err < best.metric.rel_l2[sb_factors_terms(best.f) - 1]) {
            attempt_free(&best);
            best = a;
        } else {
            attempt_free(&a);
        }
    }
    cli_progress_done();
    if (!best.f) {
        cli_error("factor", "no parameterisation could factor %s", o.source);
        rc = EXIT_NUMERIC;
        goto out;
    }
    if (o.param_auto && g_verbosity >= 1) {
        fprintf(stderr, "--param auto tried (comparable error at J = %zu):\n", o.terms);
        for (size_t i = 0; i < ncand; i++)
            if (cands[i].ok)
                fprintf(stderr, "  %-8s form %-4s %s %.4e\n", sb_param_kind_name(cands[i].kind),
                        sb_form_name(cands[i].form), cands[i].weighted ? "weighted" : "        ", cands[i].err);
        fprintf(stderr, "  chose %s, form %s\n", sb_param_spec(best.param), sb_form_name(best.m.form));
    }

    double t2 = cli_now();
    if (cli_mkdirs(o.out) != 0) {
        cli_error("factor", "--out %s: cannot create the output folder", o.out);
        rc = EXIT_IO;
        goto out;
    }
    sb_exr_opts_t eo = {o.half};
    if ((r = sb_factors_write_exr(ctx, best.f, o.out, &eo)) != SB_OK) goto fail;
    /* The error of what was stored (float or half), not only of the double fit */
    {
        sb_factors_t *q = NULL;
        size_t J = sb_factors_terms(best.f);
        double *mx = malloc(J * 4 * sizeof *mx);
        rel_stored = malloc(J * 4 * sizeof *rel_stored);
        if (!mx || !rel_stored || sb_factors_quantize(ctx, best.f, &eo, &q, NULL) != SB_OK ||
            sb_factors_errors_against(ctx, q, &best.m, best.weighted ? best.param : NULL, rel_stored, mx) != SB_OK) {
            free(rel_stored);
            rel_stored = NULL; /* reported as null */
        }
        sb_factors_destroy(q);
        free(mx);
    }
    char path[4096];
    snprintf(path, sizeof path, "%s/sepbrdf.glsl", o.out);
    if ((r = sb_glsl_write(ctx, path, best.param, best.m.form, sb_factors_terms(best.f), NULL)) != SB_OK) goto fail;
    double t3 = cli_now();
    double t[4] = {best.t_sample, best.t_factor, t3 - t2, t3 - t0};
    snprintf(path, sizeof path, "%s/report.json", o.out);
    char tmp[4200];
    FILE *fp = cli_open_tmp(path, tmp, sizeof tmp);
    if (!fp) {
        cli_error("factor", "%s: cannot write", path);
        rc = EXIT_IO;
        goto out;
    }
    json_t j = {fp, 0, {0}};
    report_ctx_t rx = {&o, src, &best, cands, ncand, rel_stored};
    write_report(&j, &rx, t);
    if (cli_commit(fp, tmp, path, 1) != 0) {
        cli_error("factor", "%s: cannot write", path);
        rc = EXIT_IO;
        goto out;
    }
    if (g_verbosity >= 1) {
        printf("sepbrdf factor: %s\n  %s, %zu x %zu matrix, form %s%s, %zu terms, method %s\n",
               sb_source_description(src), sb_param_spec(best.param), best.m.rows, best.m.cols,
               sb_form_name(best.m.form), best.weighted ? ", solid-angle weighted" : "", sb_factors_terms(best.f),
               sb_factors_get_meta(best.f, "method"));
        print_table(&best);
        printf("wrote %zu texture pairs, report.json and sepbrdf.glsl to %s/ (%.3f s)\n", sb_factors_terms(best.f),
               o.out, t[3]);
    }
    rc = EXIT_OK;
    goto out;
fail:
    cli_progress_done();
    rc = cli_fail("factor", ctx, r);
out:
    free(rel_stored);
    attempt_free(&best);
    sb_source_destroy(src);
    sb_context_destroy(ctx);
    return rc;
}
