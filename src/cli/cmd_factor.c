/* sepbrdf factor: sample -> matrix -> truncated SVD -> EXR + report + GLSL. */
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
           "      --max-error E    keep the fewest terms whose relative RMS error is <= E\n"
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
           "Files are written under temporary names and renamed when complete; a run\n"
           "interrupted (SIGINT, SIGTERM, SIGHUP) while writing removes the set.\n"
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
        json_number(j, "rel_rms", e->rel_rms[k * 4 + 3]);
        json_number(j, "rel_rms_stored", rx->rel_stored ? rx->rel_stored[k * 4 + 3] : NAN);
        json_number(j, "max_abs", e->max_abs[k * 4 + 3]);
        json_number(j, "comparable", attempt_comparable(a, k + 1));
        json_number(j, "negative_fraction", attempt_negative(a, k + 1));
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
    cli_report_measured(j, rx->src, f, param, m->form);
    json_number(j, "negative_texels", a->metric.neg_texels);
    json_int(j, "metric_resolution", (long long)o->metric_res);
    if (o->param_auto) {
        const pipe_cand_t *cd = rx->cands;
        json_int(j, "auto_metric_resolution", (long long)(o->metric_res < 16 ? o->metric_res : 16));
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
        printf("%4zu  %12.4e  %12.4e  %12.4e  %8.2f%%", k + 1, attempt_comparable(a, k + 1), e->rel_rms[k * 4 + 3],
               e->max_abs[k * 4 + 3], 100 * attempt_negative(a, k + 1));
        for (int c = 0; c < 3; c++)
            if (m->data[c]) printf("  %12.4e", e->rel_rms[k * 4 + (size_t)c]);
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
    pipe_opts_t po = {o.res,
                      o.terms,
                      o.metric_res,
                      o.theta_max_deg,
                      o.max_error,
                      o.method,
                      o.seed,
                      o.zero_fill,
                      "sampling",
                      0,
                      1,
                      o.channels,
                      0,
                      0};

    sb_context_t *ctx = NULL;
    sb_source_t *src = NULL;
    attempt_t best = {0};
    double *rel_stored = NULL; /* errors of the stored precision, J * 4 */
    sb_result_t r;
    int guarded = 0;
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
    if (o.param_auto && g_verbosity >= 1) {
        fprintf(stderr, "--param auto tried (comparable error at J = %zu, reference grid %zu):\n", o.terms,
                ncand > 1 && po.metric_res > 16 ? (size_t)16 : po.metric_res);
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
    /* From here to the last rename, an interrupt removes the whole set. */
    pipe_guard_factor_outputs(o.out, sb_factors_terms(best.f), 1);
    guarded = 1;
    sb_exr_opts_t eo = {o.half};
    if ((r = sb_factors_write_exr(ctx, best.f, o.out, &eo)) != SB_OK) goto fail;
    /* Terms beyond J left by an earlier run into the same folder would be
     * taken for part of this set: remove them. */
    for (size_t k = sb_factors_terms(best.f);; k++) {
        int gone = 1;
        for (int side = 0; side < 2; side++) {
            char name[64], path[4200];
            sb_exr_name(side, k, name, sizeof name);
            snprintf(path, sizeof path, "%s/%s", o.out, name);
            if (remove(path) == 0) gone = 0;
        }
        if (gone) break;
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
    if (factor_previews && (r = sb_factors_write_previews(ctx, best.f, o.out)) != SB_OK) goto fail;
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
    pipe_guard_factor_outputs(o.out, sb_factors_terms(best.f), 0);
    guarded = 0;
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
    if (guarded) pipe_guard_factor_outputs(o.out, sb_factors_terms(best.f), 0);
    attempt_free(&best);
    sb_source_destroy(src);
    sb_context_destroy(ctx);
    return rc;
}
