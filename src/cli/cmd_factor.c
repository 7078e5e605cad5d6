/* sepbrdf factor: sample -> matrix -> truncated SVD -> EXR + report + GLSL. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "pipeline.h"

#define DEFAULT_SOURCE "microfacet:base=gold,roughness=0.5"
#define DEFAULT_OUT "sepbrdf-out"

static void help(void) {
    printf("usage: sepbrdf factor [SOURCE] [OPTIONS]\n"
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
           "      --max-error E    keep the fewest terms whose headline error (f cos theta_i, as a\n"
           "                       shader outputs it) is <= E\n"
           "                       (0 < E < 1); J (default 32 here, at most R) is then the\n"
           "                       upper limit\n"
           "      --channels C     channels to factor, any of R, G, B (e.g. G or R,B;\n"
           "                       default all); the others are written as zero\n"
           "      --theta-max DEG  largest sampled elevation in degrees (default 90)\n"
           "      --seed S         seed of randomized methods (default 1)\n"
           "      --half           store half floats with per-term scales\n"
           "      --previews       also write g_JJ/h_JJ_scale-S.png: each texture in a diverging\n"
           "                       colour map, blue -S, white 0, red +S (S = max |value|)\n" CLI_MEASURED_HELP
               CLI_VERBOSITY_HELP "\n"
           "Texture layout: texel (x, y) of an R x R io texture is theta index x\n"
           "(s = theta / theta_max, clamped) and phi index y (t = phi / 2pi, repeated),\n"
           "i.e. direction k = R * i_phi + i_theta of the seeds' sequentialisation.\n"
           "\n"
           "The set (with sepbrdf-set.txt, its list of files) is written beside the folder\n"
           "and swapped in whole when complete: the folder holds the previous set until\n"
           "then, whatever ends the run; files sepbrdf did not write stay.\n"
           "\n" CLI_EXIT_HELP);
}

typedef struct factor_opts {
    const char *source, *out;
    size_t res, terms, metric_res;
    int param_auto; /* --param auto (default) */
    sb_param_kind_t param;
    int form_set; /* --form given */
    sb_form_t form;
    sb_method_t method;
    double max_error, theta_max_deg;
    unsigned long long seed;
    int half, weighted, zero_fill;
    int terms_set;
    unsigned channels;
    sb_measured_opts_t mo; /* a measured table as SOURCE */
} factor_opts_t;

static int factor_previews; /* --previews: a PNG per texture (image.h) */

static int parse(int argc, char **argv, factor_opts_t *o) {
    static const char *const n_res[] = {"-r", "--res", NULL}, *const n_terms[] = {"-J", "--terms", NULL},
                             *const n_param[] = {"--param", NULL}, *const n_form[] = {"--form", NULL},
                             *const n_method[] = {"--method", NULL}, *const n_maxerr[] = {"--max-error", NULL},
                             *const n_tmax[] = {"--theta-max", NULL}, *const n_chan[] = {"--channels", NULL},
                             *const n_seed[] = {"--seed", NULL}, *const n_half[] = {"--half", NULL},
                             *const n_help[] = {"-h", "--help", NULL}, *const n_weighted[] = {"--weighted", NULL},
                             *const n_zero[] = {"--zero-fill", NULL}, *const n_mres[] = {"--metric-res", NULL};
    static const char *const n_previews[] = {"--previews", NULL};
    cli_args_t a = {argc, 1, argv, "factor"};
    for (; a.i < argc; a.i++) {
        const char *v = NULL;
        int m;
        if ((m = cli_opt(&a, n_help, 0, &v))) {
            help();
            return 0;
        }
        if ((m = cli_out_opt(&a, "folder", &o->out))) {
            if (m < 0) return EXIT_USAGE;
        } else if ((m = cli_opt(&a, n_res, 1, &v))) {
            if (m < 0 || cli_parse_size("factor", "--res", v, 2, 512, &o->res)) return EXIT_USAGE;
        } else if ((m = cli_opt(&a, n_terms, 1, &v))) {
            if (m < 0 || cli_parse_size("factor", "--terms", v, 1, (size_t)1 << 30, &o->terms)) return EXIT_USAGE;
            o->terms_set = 1;
        } else if ((m = cli_opt(&a, n_param, 1, &v))) {
            if (m < 0) return EXIT_USAGE;
            if (strcmp(v, "auto") == 0) {
                o->param_auto = 1;
            } else if (sb_param_kind_parse(v, &o->param) != SB_OK) {
                cli_error("factor", "--param '%s' unknown, need one of auto, %s", v, cli_param_names());
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
        } else if ((m = cli_opt(&a, n_chan, 1, &v))) {
            if (m < 0) return EXIT_USAGE;
            o->channels = 0;
            for (const char *q = v; *q; q++) {
                if (*q == ',') continue;
                const char *at = strchr("RGBrgb", *q);
                if (!at || !*q) {
                    cli_error("factor", "--channels '%s': '%c' is not R, G or B", v, *q);
                    return EXIT_USAGE;
                }
                o->channels |= 1u << ((at - "RGBrgb") % 3);
            }
            if (!o->channels) {
                cli_error("factor", "--channels '%s': no channel given (need R, G and/or B)", v);
                return EXIT_USAGE;
            }
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
        } else if (cli_opt(&a, n_previews, 0, &v)) {
            factor_previews = 1;
        } else if ((m = cli_measured_opt(&a, &o->mo))) {
            if (m < 0) return EXIT_USAGE;
        } else if (cli_verbosity_opt(argv[a.i])) {
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

typedef struct report_ctx {
    const factor_opts_t *o;
    const sb_source_t *src;
    const attempt_t *a;
    const pipe_cand_t *cands;
    size_t ncand;
    const double *rel_stored; /* rel_rms of the stored (FLOAT/HALF) factors, J * 4; NULL if unknown */
} report_ctx_t;

/* Whether the headline does not rise with J' by more than two standard
 * errors plus 2 % (out of sample, more terms can fit the cells better and
 * the pairs between them worse; a rise within 2 % is not worth a
 * warning). */
static int headline_non_increasing(const attempt_t *a) {
    const sb_estimate_t *e = a->est;
    for (size_t k = 1; k < e->terms; k++) {
        double prev = e->rel[k - 1][SB_EST_FCOS][3], d = e->rel[k][SB_EST_FCOS][3] - prev;
        double se = hypot(e->se[k][SB_EST_FCOS][3], e->se[k - 1][SB_EST_FCOS][3]);
        if (d > 2 * se + 0.02 * prev) return 0;
    }
    return 1;
}

/* The estimator's keys of errors[k] (J' = k + 1). */
static void write_estimate(json_t *j, const attempt_t *a, size_t k, const sb_matrix_t *m) {
    static const char *const cn[3] = {"R", "G", "B"};
    const sb_estimate_t *e = a->est;
    int have = k < e->terms;
    json_number(j, "headline", have ? e->rel[k][SB_EST_FCOS][3] : NAN);
    json_number(j, "headline_se", have ? e->se[k][SB_EST_FCOS][3] : NAN);
    json_begin_object(j, "headline_channel");
    for (int c = 0; c < 3; c++)
        if (m->data[c]) json_number(j, cn[c], have ? e->rel[k][SB_EST_FCOS][c] : NAN);
    json_end_object(j);
    json_number(j, "comparable", have ? e->rel[k][SB_EST_FCOS2][3] : NAN);
    json_number(j, "comparable_se", have ? e->se[k][SB_EST_FCOS2][3] : NAN);
    json_number(j, "comparable_grid", k < a->metric.terms ? a->metric.rel_l2[k] : NAN);
    json_number(j, "rel_f", have ? e->rel[k][SB_EST_F][3] : NAN);
    json_number(j, "rel_f_se", have ? e->se[k][SB_EST_F][3] : NAN);
    json_number(j, "p99_rel", have ? e->p99[k][3] : NAN);
    json_number(j, "max_rel", have ? e->max_rel[k][3] : NAN);
    json_number(j, "overshoot", have ? e->overshoot[k] : NAN);
    json_number(j, "negative_fraction", have ? e->neg_frac[k] : NAN);
}

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
    json_string(j, "invalid_cells",
                a->zero_fill ? "zero-filled in the fit, excluded from the error"
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
        for (size_t k = 0; k < J; k++)
            json_number(j, NULL, sb_factors_sigma(f, k, (size_t)c));
        json_end_array(j);
    }
    json_end_object(j);
    json_begin_array(j, "errors");
    for (size_t k = 0; k < J; k++) {
        json_begin_object(j, NULL);
        json_int(j, "terms", (long long)(k + 1));
        json_number(j, "rel_rms", e->rel_rms[sb_err_at(k, SB_CH_ALL)]);
        json_number(j, "rel_rms_stored", rx->rel_stored ? rx->rel_stored[sb_err_at(k, SB_CH_ALL)] : NAN);
        json_number(j, "max_abs", e->max_abs[sb_err_at(k, SB_CH_ALL)]);
        write_estimate(j, a, k, m);
        json_begin_object(j, "rel_rms_channel");
        for (int c = 0; c < 3; c++)
            if (m->data[c]) json_number(j, cn[c], e->rel_rms[sb_err_at(k, c)]);
        json_end_object(j);
        json_begin_object(j, "max_abs_channel");
        for (int c = 0; c < 3; c++)
            if (m->data[c]) json_number(j, cn[c], e->max_abs[sb_err_at(k, c)]);
        json_end_object(j);
        json_end_object(j);
    }
    json_end_array(j);
    cli_report_measured(j, rx->src, f, param, m->form);
    json_number(j, "negative_texels", a->metric.neg_texels);
    json_int(j, "metric_resolution", (long long)o->metric_res);
    const sb_estimate_t *est = a->est;
    json_begin_object(j, "estimate");
    json_int(j, "pairs", (long long)est->pairs);
    json_int(j, "known", (long long)est->known);
    json_bool(j, "converged", est->converged);
    json_bool(j, "headline_non_increasing", headline_non_increasing(a));
    json_end_object(j);
    json_string(j, "form_choice",
                o->form_set ? "as asked (--form); the headline measures what its division does"
                            : (o->param_auto ? "auto: lowest headline among f and cos (cos2 is no candidate: dividing "
                                               "by cos theta_o is unbounded near the horizon in f cos theta_i)"
                                             : "f, the default"));
    if (o->param_auto) {
        const pipe_cand_t *cd = rx->cands;
        json_begin_array(j, "auto_tried");
        for (size_t i = 0; i < rx->ncand; i++) {
            json_begin_object(j, NULL);
            json_string(j, "param", sb_param_kind_name(cd[i].kind));
            json_string(j, "form", sb_form_name(cd[i].form));
            json_bool(j, "weighted", cd[i].weighted);
            json_bool(j, "ok", cd[i].ok);
            json_number(j, "headline", cd[i].ok ? cd[i].err : NAN);
            json_end_object(j);
        }
        json_end_array(j);
    }
    json_begin_object(j, "timings");
    json_number(j, "sample_s", t[0]);
    json_number(j, "factor_s", t[1]);
    json_number(j, "metric_s", a->t_metric);
    json_number(j, "estimate_s", a->t_estimate);
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
    printf("%4s  %12s  %9s  %12s  %12s  %12s  %9s", "J", "headline", "+-", "comparable", "rel_rms", "max_abs",
           "negative");
    static const char *const cn[3] = {"R", "G", "B"};
    for (int c = 0; c < 3; c++)
        if (m->data[c]) printf("  %10s_%s", "rel_rms", cn[c]);
    printf("\n");
    for (size_t k = 0; k < J; k++) {
        double se = k < a->est->terms ? a->est->se[k][SB_EST_FCOS][3] : NAN;
        printf("%4zu  %12.4e  %9.2e  %12.4e  %12.4e  %12.4e  %8.2f%%", k + 1, attempt_headline(a, k + 1), se,
               attempt_comparable(a, k + 1), e->rel_rms[sb_err_at(k, SB_CH_ALL)], e->max_abs[sb_err_at(k, SB_CH_ALL)],
               100 * attempt_negative(a, k + 1));
        for (int c = 0; c < 3; c++)
            if (m->data[c]) printf("  %12.4e", e->rel_rms[sb_err_at(k, c)]);
        printf("\n");
    }
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
    if (o.max_error > 0 && !o.terms_set) o.terms = o.res < 32 ? o.res : 32; /* upper limit for --max-error */
    if ((rc = cli_check_outdir("factor", "--out", o.out)) != EXIT_OK) return rc;
    pipe_opts_t po = {
        o.res,    o.terms, o.metric_res, o.theta_max_deg, 0, /* --max-error acts on the estimator's headline, below */
        o.method, o.seed,  o.zero_fill,  "sampling",      0, 1, o.channels, 0, 0, NULL, o.half, 0};

    sb_context_t *ctx = NULL;
    sb_source_t *src = NULL;
    attempt_t best = {0};
    double *rel_stored = NULL; /* errors of the stored precision, J * 4 */
    sb_result_t r;
    sb_outset_t *set = NULL;
    double t0 = cli_now();
    if (sb_context_create(&ctx) != SB_OK) {
        cli_error("factor", "out of memory");
        return EXIT_IO;
    }
    /* Everything is checked before the output folder is touched. */
    if ((r = pipe_source_open(ctx, o.source, &o.mo, &src)) != SB_OK) goto fail;

    /* Candidates: the one asked for, or (auto) every parameterisation that
     * applies, with f and f cos cos unless --form fixes it. */
    pipe_cand_t cands[PIPE_MAX_CANDS];
    size_t ncand = pipe_candidates(src, &po, o.param_auto, o.param, o.form_set, o.form, o.weighted, cands);
    if ((r = pipe_select(ctx, "factor", src, &po, cands, ncand, &best)) != SB_OK) goto fail;
    if (o.max_error > 0) { /* the fewest terms whose headline meets --max-error */
        size_t keep = sb_factors_terms(best.f);
        for (size_t k = keep; k >= 1; k--)
            if (attempt_headline(&best, k) <= o.max_error) keep = k;
        if ((r = attempt_truncate(ctx, &best, keep)) != SB_OK) goto fail;
    }
    if (best.stats.masked && !best.stats.fit_converged)
        cli_error("factor",
                  "warning: the masked fit did not converge in %d sweeps (report.json: fit.converged false); "
                  "its errors are those of the factors written",
                  best.stats.fit_iterations);
    if (!headline_non_increasing(&best))
        cli_error("factor",
                  "warning: the headline error rises with J' (report.json: errors[].headline): the later terms fit "
                  "the sampled cells but not the pairs between them; fewer terms or a finer --res do better");
    if (!best.est->converged)
        cli_info(1, "factor: the error estimate kept a standard error above 5 %% at %zu pairs", best.est->pairs);
    if (o.param_auto && g_verbosity >= 1) {
        fprintf(stderr, "--param auto tried (headline error, f cos theta_i, at J = %zu):\n", o.terms);
        for (size_t i = 0; i < ncand; i++)
            if (cands[i].ok)
                fprintf(stderr, "  %-8s form %-4s %s %.4e\n", sb_param_kind_name(cands[i].kind),
                        sb_form_name(cands[i].form), cands[i].weighted ? "weighted" : "        ", cands[i].err);
        fprintf(stderr, "  chose %s, form %s\n", sb_param_spec(best.param), sb_form_name(best.m.form));
    }

    double t2 = cli_now();
    /* The whole set goes into a staging folder published in one step
     * (outset.h): DIR keeps its previous set until then. */
    if (!(set = cli_outset_begin(ctx, "factor", o.out, &rc))) goto out;
    const char *sd = sb_outset_dir(set);
    sb_exr_opts_t eo = {o.half};
    if ((r = sb_factors_write_exr(ctx, best.f, sd, &eo)) != SB_OK) goto fail;
    for (size_t k = 0; k < 2 * sb_factors_terms(best.f); k++) {
        char name[64];
        sb_exr_name((int)(k % 2), k / 2, name, sizeof name);
        sb_outset_add(set, name);
    }
    /* The error of what was stored (float or half), not only of the double fit */
    {
        sb_factors_t *q = NULL;
        size_t J = sb_factors_terms(best.f);
        double *mx = malloc(J * 4 * sizeof *mx);
        rel_stored = malloc(J * 4 * sizeof *rel_stored);
        if (!mx || !rel_stored || sb_factors_quantize(ctx, best.f, &eo, &q, NULL) != SB_OK ||
            (best.m.mask ? sb_factors_errors_against(ctx, q, &best.m, best.weighted ? best.param : NULL, rel_stored, mx)
                         : sb_factors_errors_near(ctx, best.f, q, &best.m, best.weighted ? best.param : NULL,
                                                  rel_stored)) != SB_OK) {
            free(rel_stored);
            rel_stored = NULL; /* reported as null */
        }
        sb_factors_destroy(q);
        free(mx);
    }
    if (factor_previews && (r = sb_factors_write_previews(ctx, best.f, sd)) != SB_OK) goto fail;
    char path[4200];
    cli_set_file(set, "sepbrdf.glsl", path, sizeof path);
    /* the snippet's sb_scale: what the shader multiplies the stored texels by (HALF) */
    double *scales = malloc(sb_factors_terms(best.f) * sizeof *scales);
    r = scales ? sb_exr_term_scales(ctx, best.f, &eo, scales) : sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    if (r == SB_OK) r = sb_glsl_write(ctx, path, best.param, best.m.form, sb_factors_terms(best.f), scales);
    free(scales);
    if (r != SB_OK) goto fail;
    double t3 = cli_now();
    double t[4] = {best.t_sample, best.t_factor, t3 - t2, t3 - t0};
    cli_set_file(set, "report.json", path, sizeof path);
    char tmp[4300];
    FILE *fp = cli_open_tmp(path, tmp, sizeof tmp);
    int e = fp ? 0 : errno;
    if (fp) {
        json_t j = {fp, 0, {0}};
        report_ctx_t rx = {&o, src, &best, cands, ncand, rel_stored};
        write_report(&j, &rx, t);
        e = cli_commit(fp, tmp, path, 1);
    }
    if (e) {
        cli_error("factor", "%s/report.json: cannot write: %s", o.out, sb_io_why(e));
        rc = EXIT_IO;
        goto out;
    }
    rc = cli_outset_end(ctx, "factor", set, 1);
    set = NULL;
    if (rc != EXIT_OK) goto out;
    if (g_verbosity >= 1) {
        printf("sepbrdf factor: %s\n  %s, %zu x %zu matrix, form %s%s, %zu terms, method %s\n",
               sb_source_description(src), sb_param_spec(best.param), best.m.rows, best.m.cols,
               sb_form_name(best.m.form), best.weighted ? ", solid-angle weighted" : "", sb_factors_terms(best.f),
               sb_factors_get_meta(best.f, "method"));
        print_table(&best);
        cli_print_measured(src, best.f, best.param, best.m.form, o.res);
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
    cli_outset_end(ctx, "factor", set, 0); /* a set not published: discarded */
    attempt_free(&best);
    sb_source_destroy(src);
    sb_context_destroy(ctx);
    return rc;
}
