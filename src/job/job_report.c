/* report.json of the factor job: every key is listed in docs/report.md's
 * "report.json" table (a test compares the two). */
#include <math.h>
#include <stdio.h>

#include "factor/sample_error.h"
#include "job_impl.h"
#include "sepbrdf/exr.h"
#include "sepbrdf/glsl.h"
#include "sepbrdf/measured.h"
#include "solve/solver.h"

static const char *const chan_name[3] = {"R", "G", "B"};

static void report_size(sb_json_t *j, const sb_param_t *param) {
    size_t w, h;
    sb_json_begin_object(j, "texture_size");
    for (int side = 0; side < 2; side++) {
        sb_param_texture_size(param, side, &w, &h);
        sb_json_begin_array(j, side == SB_SIDE_G ? "g" : "h");
        sb_json_int(j, NULL, (long long)w);
        sb_json_int(j, NULL, (long long)h);
        sb_json_end_array(j);
    }
    sb_json_end_object(j);
}

/* "warp": the option asked for, and per axis of a layout that takes warps
 * its kind and, for a table, the knots x_k (W(x_k) = k / K). */
static void report_warps(sb_json_t *j, const sb_job_t *job) {
    static const char *const axes[SB_AXIS_COUNT_] = {"theta_h", "theta_d"};
    sb_json_begin_object(j, "warp");
    sb_json_string(j, "requested", job->o.warp);
    sb_json_bool(j, "auto_tried", job->warp_tried); /* none asked for, headline above 5 %: auto tried */
    /* the kept candidate's layout on warps screened beside it (job_warp_screen) */
    sb_json_number(j, "screen_headline", job->warp_screen_error > 0 ? job->warp_screen_error : NAN);
    sb_json_bool(j, "screen_kept", job->warp_screened);
    for (int a = 0; a < SB_AXIS_COUNT_; a++) {
        const sb_warp_t *w = sb_param_warp(job->best.param, a);
        if (!w) continue;
        sb_json_begin_object(j, axes[a]);
        sb_json_string(j, "kind", sb_warp_kind_name(w->kind));
        if (w->kind == SB_WARP_TABLE) {
            sb_json_begin_array(j, "knots");
            for (size_t k = 0; k <= w->knots; k++)
                sb_json_number(j, NULL, w->x[k]);
            sb_json_end_array(j);
        }
        sb_json_end_object(j);
    }
    sb_json_end_object(j);
}

/* Why the factors' method: what it holds and the rule that picked it
 * (auto: the exact block-circulant SVD where the structure holds, a
 * stored matrix and a dense SVD where that fits the memory limit, else
 * the streamed passes, slower but bounded). */
static void method_why(const sb_job_t *job, char *why, size_t n) {
    const sb_matrix_t *m = &job->best.m;
    const char *method = sb_factors_get_meta(job->best.f, "method");
    double mib = 1.0 / (1 << 20), lim = (double)sb_memory_limit() * mib;
    double stored = (double)sb_matrix_bytes(job->src, job->best.param, &(sb_matrix_opts_t){.structured = 1}) * mib;
    if (!method) method = "none";
    if (m->streamed)
        snprintf(why, n,
                 "%s: the matrix is evaluated from the source in blocks of columns, never stored (%s): %.1f MiB "
                 "of columns at a time and the Krylov basis, O(R^2 (J + 10)) (the memory limit is %.0f MiB)",
                 method, job->o.method == SB_METHOD_STREAM ? "--method stream" : "its values exceed the memory limit",
                 (double)(sb_solve_stream_cols(m->rows, m->cols) * m->rows * 3 * sizeof(double)) * mib, lim);
    else if (m->structured)
        snprintf(why, n,
                 "%s: an isotropic source on an azimuth grid: the exact block-circulant SVD of its distinct values "
                 "(%.1f MiB stored), faster than a dense SVD and exact",
                 method, stored);
    else
        snprintf(why, n, "%s: %s; the stored matrix (%.1f MiB) fits the memory limit (%.0f MiB)", method,
                 job->o.method == SB_METHOD_AUTO ? "picked for the shape, J and mask (a stored matrix is read faster "
                                                   "than streamed passes)"
                                                 : "asked for",
                 stored, lim);
}

static void report_settings(sb_json_t *j, const sb_job_t *job) {
    const job_attempt_t *a = &job->best;
    const sb_matrix_t *m = &a->m;
    sb_json_string(j, "sepbrdf_version", SB_VERSION_STRING);
    sb_json_string(j, "command", "factor");
    sb_json_string(j, "source", sb_source_description(job->src));
    sb_json_string(j, "source_spec", job->o.source);
    sb_json_string(j, "param", sb_param_name(a->param));
    sb_json_string(j, "param_spec", sb_param_spec(a->param));
    report_warps(j, job);
    sb_json_int(j, "resolution", (long long)job->o.res);
    sb_json_int(j, "rows", (long long)m->rows);
    sb_json_int(j, "cols", (long long)m->cols);
    report_size(j, a->param);
    sb_json_string(j, "form", sb_form_name(m->form));
    sb_json_bool(j, "weighted", a->weighted);
    sb_json_string(j, "method", sb_factors_get_meta(a->f, "method"));
    sb_json_string(j, "svd_method", job->svd_beside ? job->svd_method : NULL);
    char why[400];
    method_why(job, why, sizeof why);
    sb_json_string(j, "method_why", why);
    sb_json_int(j, "terms", (long long)sb_factors_terms(a->f));
    sb_json_int(j, "terms_requested", (long long)job->o.terms);
    sb_json_number(j, "max_error", job->o.max_error);
    if (job->o.max_error > 0 && a->est) { /* whether the kept terms meet it */
        size_t J = sb_factors_terms(a->f);
        double e = sb_estimate_headline(a->est, J < a->est->terms ? J : a->est->terms);
        sb_json_bool(j, "max_error_met", e <= job->o.max_error);
        sb_json_number(j, "max_error_reached", e);
    } else { /* no target */
        sb_json_string(j, "max_error_met", NULL);
        sb_json_number(j, "max_error_reached", NAN);
    }
    sb_json_string(j, "storage", job->o.half ? "half" : "float");
    sb_json_begin_array(j, "channels");
    for (int c = 0; c < 3; c++)
        if (sb_matrix_has(m, c)) sb_json_string(j, NULL, chan_name[c]);
    sb_json_end_array(j);
}

static void report_fit(sb_json_t *j, const sb_job_t *job) {
    const job_attempt_t *a = &job->best;
    const sb_matrix_t *m = &a->m;
    size_t cells = m->rows * m->cols;
    sb_json_begin_object(j, "mask");
    sb_json_int(j, "cells", (long long)cells);
    sb_json_int(j, "valid", (long long)m->valid_count);
    sb_json_number(j, "coverage", cells ? (double)m->valid_count / (double)cells : 0);
    sb_json_string(j, "invalid_cells",
                   job_attempt_zero_fill(job, a) ? "zero-filled in the fit, excluded from the error"
                                                 : "excluded from the fit (masked imputation) and from the error");
    sb_json_end_object(j);
    sb_json_begin_object(j, "fit");
    sb_json_bool(j, "masked", a->stats.masked);
    sb_json_int(j, "iterations", a->stats.fit_iterations);
    int conv = job_fit_converged(a); /* the terms written (a fit of more, cut to J: its first J terms') */
    sb_json_bool(j, "converged", conv);
    /* what ended the sweeps: a sweep's gain under the tolerance, or the
     * sweep cap (a non-negative fit's stated stop, not a failure) */
    sb_json_string(j, "stopped", !a->stats.fit_iterations ? "none" : (conv ? "tolerance" : "sweeps"));
    /* the sweeps were auto's early stop (1e-3, at most 20 a stage): a
     * stage at its cap is that stated rule (job_early_stop) */
    sb_json_bool(j, "early_stop", a->stats.masked && a->early_stop);
    sb_json_number(j, "band_weight", a->band_weight); /* job_bandfit.c: 0 the plain fit */
    /* texture axes whose texels were fitted for the bilinear lookup
     * (t - D t / 12) instead of holding the samples at their centres */
    static const char *const axes[4] = {"g.s", "g.t", "h.s", "h.t"};
    sb_json_begin_array(j, "texels_fitted");
    for (int b = 0; b < 4; b++)
        if (a->texel_fit & (1u << b)) sb_json_string(j, NULL, axes[b]);
    sb_json_end_array(j);
    sb_json_end_object(j);
    const sb_factor_errors_t *e = sb_factors_errors(a->f);
    sb_json_begin_object(j, "norm");
    for (int c = 0; c < 3; c++)
        if (sb_matrix_has(m, c)) sb_json_number(j, chan_name[c], e->norm[c]);
    sb_json_number(j, "all", e->norm[3]);
    sb_json_end_object(j);
    sb_json_begin_object(j, "sigma");
    for (int c = 0; c < 3; c++) {
        if (!sb_matrix_has(m, c)) continue;
        sb_json_begin_array(j, chan_name[c]);
        for (size_t k = 0; k < sb_factors_terms(a->f); k++)
            sb_json_number(j, NULL, sb_factors_sigma(a->f, k, (size_t)c));
        sb_json_end_array(j);
    }
    sb_json_end_object(j);
}

static void report_channels(sb_json_t *j, const char *key, const sb_matrix_t *m, const double *v) {
    sb_json_begin_object(j, key);
    for (int c = 0; c < 3; c++)
        if (sb_matrix_has(m, c)) sb_json_number(j, chan_name[c], v[c]);
    sb_json_end_object(j);
}

/* Where the error of errors[k] is: the bands, the lit pairs, the most
 * negative value. */
static void report_bands(sb_json_t *j, const sb_job_t *job, size_t k) {
    const job_attempt_t *a = &job->best;
    const sb_estimate_t *e = a->est;
    int have = k < e->terms;
    static const char *const keys[2] = {"band_rel", "band_rel_se"};
    for (int s = 0; s < 2; s++) {
        sb_json_begin_object(j, keys[s]);
        for (int b = 0; b < SB_BAND_COUNT_; b++)
            sb_json_number(j, sb_band_name(b), have ? (s ? e->band_se : e->band)[k][b][SB_CH_ALL] : NAN);
        sb_json_end_object(j);
    }
    sb_json_begin_object(j, "band_rel_channel");
    for (int c = 0; c < 3; c++) {
        if (!sb_matrix_has(&a->m, c)) continue;
        sb_json_begin_array(j, chan_name[c]);
        for (int b = 0; b < SB_BAND_COUNT_; b++)
            sb_json_number(j, NULL, have ? e->band[k][b][c] : NAN);
        sb_json_end_array(j);
    }
    sb_json_end_object(j);
    sb_json_string(j, "worst_band", sb_band_name(have ? sb_estimate_worst_band(e, k + 1) : -1));
    static const char *const lit[3] = {"p99_rel_lit", "max_rel_lit", "min_rel"};
    for (int s = 0; s < 3; s++) {
        const double(*v)[4] = s == 0 ? e->p99_lit : s == 1 ? e->max_rel_lit : e->min_rel;
        double nan3[3] = {NAN, NAN, NAN};
        char key[32];
        snprintf(key, sizeof key, "%s_channel", lit[s]);
        sb_json_number(j, lit[s], have ? v[k][SB_CH_ALL] : NAN);
        report_channels(j, key, &a->m, have ? v[k] : nan3);
    }
}

/* The bands' definitions, shares and the map of the kept J. */
static void report_band_map(sb_json_t *j, const sb_job_t *job) {
    const sb_estimate_t *e = job->best.est;
    sb_json_begin_object(j, "bands");
    sb_json_number(j, "cone_deg", SB_BAND_CONE_DEG);
    sb_json_begin_object(j, "share");
    for (int b = 0; b < SB_BAND_COUNT_; b++)
        sb_json_number(j, sb_band_name(b), e->band_share[b]);
    sb_json_end_object(j);
    sb_json_begin_array(j, "map_edges");
    for (int k = 0; k <= SB_EST_MAP; k++)
        sb_json_number(j, NULL, sb_band_map_edges[k]);
    sb_json_end_array(j);
    sb_json_int(j, "map_terms", (long long)e->terms);
    sb_json_begin_array(j, "map");
    for (int r = 0; r < SB_EST_MAP; r++) {
        sb_json_begin_array(j, NULL);
        for (int c = 0; c < SB_EST_MAP; c++)
            sb_json_number(j, NULL, e->map[r][c]);
        sb_json_end_array(j);
    }
    sb_json_end_array(j);
    sb_json_end_object(j);
}

/* The estimator's keys of errors[k] (J' = k + 1). */
static void report_estimate(sb_json_t *j, const sb_job_t *job, size_t k) {
    const job_attempt_t *a = &job->best;
    const sb_estimate_t *e = a->est;
    int have = k < e->terms;
    sb_json_number(j, "headline", have ? e->rel[k][SB_EST_FCOS][SB_CH_ALL] : NAN);
    sb_json_number(j, "headline_se", have ? e->se[k][SB_EST_FCOS][SB_CH_ALL] : NAN);
    sb_json_number(j, "replicates", have ? (double)e->reps[k] : NAN);
    sb_json_begin_object(j, "headline_channel");
    for (int c = 0; c < 3; c++)
        if (sb_matrix_has(&a->m, c)) sb_json_number(j, chan_name[c], have ? e->rel[k][SB_EST_FCOS][c] : NAN);
    sb_json_end_object(j);
    sb_json_number(j, "comparable", have ? e->rel[k][SB_EST_FCOS2][SB_CH_ALL] : NAN);
    sb_json_number(j, "comparable_se", have ? e->se[k][SB_EST_FCOS2][SB_CH_ALL] : NAN);
    sb_json_number(j, "comparable_grid", k < a->metric.terms ? a->metric.rel_l2[k] : NAN);
    sb_json_number(j, "rel_f", have ? e->rel[k][SB_EST_F][SB_CH_ALL] : NAN);
    sb_json_number(j, "rel_f_se", have ? e->se[k][SB_EST_F][SB_CH_ALL] : NAN);
    sb_json_number(j, "p99_rel", have ? e->p99[k][SB_CH_ALL] : NAN);
    sb_json_number(j, "max_rel", have ? e->max_rel[k][SB_CH_ALL] : NAN);
    sb_json_number(j, "overshoot", have ? e->overshoot[k] : NAN);
    sb_json_number(j, "negative_fraction", have ? e->neg_frac[k] : NAN);
    sb_json_number(j, "chroma_de", have ? e->chroma_de[k] : NAN);
    report_bands(j, job, k);
    double cse;
    sb_json_number(j, "cv_headline", sb_job_cv(job, k + 1, &cse, NULL));
    sb_json_number(j, "cv_headline_se", cse);
    int cv = job->cv && k < job->cv_terms;
    sb_json_number(j, "cv_pooled", cv ? job->cv_pooled[k] : NAN);
    sb_json_number(j, "cv_fold_max", cv ? job->cv_max[k] : NAN);
    sb_json_number(j, "cv_fold_median", cv ? job->cv_median[k] : NAN);
}

int sb_job_headline_non_increasing(const sb_job_t *job) {
    const sb_estimate_t *e = job ? job->best.est : NULL;
    for (size_t k = 1; e && k < e->terms; k++) {
        double prev = e->rel[k - 1][SB_EST_FCOS][SB_CH_ALL], d = e->rel[k][SB_EST_FCOS][SB_CH_ALL] - prev;
        double se = hypot(e->se[k][SB_EST_FCOS][SB_CH_ALL], e->se[k - 1][SB_EST_FCOS][SB_CH_ALL]);
        if (d > 2 * se + 0.02 * prev) return 0;
    }
    return 1;
}

static void report_estimator(sb_json_t *j, const sb_job_t *job) {
    const sb_estimate_t *est = job->best.est;
    sb_json_begin_object(j, "estimate");
    sb_json_string(j, "domain", job->scene ? "scene" : (job_measures_cap(job) ? "cap" : "hemisphere"));
    sb_json_int(j, "pairs", (long long)est->pairs);
    sb_json_int(j, "known", (long long)est->known);
    sb_json_int(j, "replicates", (long long)est->replicates);
    sb_json_int(j, "band_pairs", (long long)job->best.band_pairs);
    sb_json_number(j, "se_target", SB_EST_REL_SE);
    sb_json_bool(j, "converged", est->converged);
    sb_json_bool(j, "headline_non_increasing", sb_job_headline_non_increasing(job));
    sb_json_end_object(j);
    sb_json_string(j, "form_choice",
                   job->o.form ? "as asked; the headline measures what its division does"
                               : (job->is_auto || job->layout_auto
                                      ? "auto: lowest headline among f and cos (cos2 is no candidate: "
                                        "dividing by cos theta_o is unbounded near the horizon in f cos "
                                        "theta_i)"
                                      : "f, the default"));
}

/* A measured table: what it held and the errors against its measurements
 * (docs/measured.md); nothing for analytic sources. */
static void json_rgb(sb_json_t *j, const char *key, const double v[3]) {
    sb_json_begin_array(j, key);
    for (int c = 0; c < 3; c++)
        sb_json_number(j, NULL, v[c]);
    sb_json_end_array(j);
}

/* The lobe a scattered table is interpolated relative to (null: none fitted). */
static void report_lobe(sb_json_t *j, const sb_lobe_fit_t *L) {
    if (!L->fitted) {
        sb_json_string(j, "lobe", NULL);
        return;
    }
    sb_json_begin_object(j, "lobe");
    sb_json_bool(j, "used", L->used);
    sb_json_string(j, "ndf", L->ndf);
    sb_json_number(j, "alpha", L->alpha);
    sb_json_number(j, "f0", L->f0);
    json_rgb(j, "f0_rgb", L->f0_rgb);
    sb_json_bool(j, "diffuse_fresnel", L->diffuse_fresnel);
    sb_json_number(j, "cos_power", L->cos_power);
    sb_json_bool(j, "smith_k_remapped", L->smith_k_remapped);
    json_rgb(j, "kd", L->kd);
    json_rgb(j, "ks", L->ks);
    sb_json_number(j, "d_cap", L->d_cap);
    json_rgb(j, "floor", L->floor);
    sb_json_number(j, "interp_cv_without", L->cv_off);
    sb_json_number(j, "interp_cv_with", L->cv_on);
    sb_json_end_object(j);
}

static void report_measured(sb_json_t *j, const sb_job_t *job) {
    const sb_measured_info_t *in = sb_measured_source_info(job->src);
    if (!in) return;
    const job_attempt_t *a = &job->best;
    sb_sample_errors_t se = job->se; /* job_warn_support's, while the terms are those it measured */
    int have = (a->f && a->f == job->se_f) || sb_sample_errors_(NULL, job->src, a->f, a->param, a->m.form,
                                                                job->o.channels, job_measures_cap(job), &se) == SB_OK;
    sb_json_begin_object(j, "measured");
    sb_json_string(j, "format", in->format);
    sb_json_int(j, "rows", (long long)in->rows);
    sb_json_int(j, "samples", (long long)(have ? se.samples : 0));
    sb_json_int(j, "outside", (long long)(have ? se.outside : 0));
    sb_json_number(j, "source_rel_l2", have ? se.source_rel_l2 : NAN);
    sb_json_begin_array(j, "sample_rel_l2");
    for (size_t k = 0; have && k < se.terms; k++)
        sb_json_number(j, NULL, se.rel_l2[k]);
    sb_json_end_array(j);
    sb_json_string(j, "interp", sb_interp_name(in->interp));
    sb_json_begin_object(j, "interp_cv");
    for (int m = SB_INTERP_NEAREST; m < SB_INTERP_COUNT_; m++)
        sb_json_number(j, sb_interp_name((sb_interp_t)m), in->interp_cv[m]);
    sb_json_end_object(j);
    sb_json_int(j, "cv_held_out", (long long)in->cv_held_out);
    report_lobe(j, &in->lobe);
    sb_json_begin_object(j, "cv");
    sb_json_int(j, "folds", (long long)job->cv_folds);
    sb_json_int(j, "refits", (long long)job->cv_refits);
    sb_json_int(j, "held_out", (long long)job->cv_held);
    sb_json_number(j, "table", job->cv ? job->cv_table : NAN);
    sb_json_string(j, "what",
                   job->cv ? "errors[].cv_headline: the relative L2 of f cos theta_i at the measurements a random "
                             "split of the table would leave out, the figure most such splits land within 1.5x of, "
                             "drawn from the measurements each refit of the kept layout, form and J left out (its "
                             "fold), each other measurement with the relative error of the held-out one nearest "
                             "to it in energy"
                           : "not computed (a grid table, or cv_folds 1)");
    sb_json_begin_array(j, "theta_h_bands");
    for (int b = 0; job->cv && b < JOB_CV_BANDS; b++) {
        sb_json_begin_object(j, NULL);
        sb_json_begin_array(j, "theta_h_deg");
        sb_json_number(j, NULL, job_cv_band_deg[b]);
        sb_json_number(j, NULL, job_cv_band_deg[b + 1]);
        sb_json_end_array(j);
        sb_json_int(j, "held_out", (long long)job->cv_band_n[b]);
        sb_json_number(j, "cv", job->cv_band_t[b] > 0 ? sqrt(job->cv_band_e[b] / job->cv_band_t[b]) : NAN);
        double all = 0;
        for (int c = 0; c < JOB_CV_BANDS; c++)
            all += job->cv_band_e[c];
        sb_json_number(j, "share", all > 0 ? job->cv_band_e[b] / all : NAN);
        sb_json_end_object(j);
    }
    sb_json_end_array(j);
    sb_json_end_object(j);
    sb_json_int(j, "out_of_gamut", (long long)in->out_of_gamut);
    sb_json_string(j, "gamut", sb_gamut_name(in->gamut));
    sb_json_end_object(j);
}

static void report_errors(sb_json_t *j, const sb_job_t *job) {
    const job_attempt_t *a = &job->best;
    const sb_factor_errors_t *e = sb_factors_errors(a->f);
    sb_json_begin_array(j, "errors");
    for (size_t k = 0; k < sb_factors_terms(a->f); k++) {
        sb_json_begin_object(j, NULL);
        sb_json_int(j, "terms", (long long)(k + 1));
        sb_json_number(j, "rel_rms", e->rel_rms[sb_err_at(k, SB_CH_ALL)]);
        sb_json_number(j, "rel_rms_stored", sb_job_rel_stored(job, k + 1, SB_CH_ALL));
        sb_json_number(j, "max_abs", e->max_abs[sb_err_at(k, SB_CH_ALL)]);
        sb_json_begin_array(j, "term_weight"); /* per factor channel; 1: as fitted */
        for (size_t c = 0; c < sb_factors_channels(a->f); c++)
            sb_json_number(j, NULL, a->term_w ? a->term_w[k * sb_factors_channels(a->f) + c] : 1.0);
        sb_json_end_array(j);
        report_estimate(j, job, k);
        double sh = sb_job_svd_headline(job, k + 1);
        sb_json_number(j, "svd_headline", sh);
        sb_json_number(j, "svd_rel_rms", sb_job_svd_rel_rms(job, k + 1));
        sb_json_number(j, "nmf_over_svd", sb_job_headline(job, k + 1) / sh);
        double shc[3], ratio[3];
        int have = k < a->est->terms;
        for (int c = 0; c < 3; c++) {
            shc[c] = job_svd_headline_channel(job, k + 1, c);
            ratio[c] = have ? a->est->rel[k][SB_EST_FCOS][c] / shc[c] : NAN;
        }
        report_channels(j, "svd_headline_channel", &a->m, shc);
        report_channels(j, "nmf_over_svd_channel", &a->m, ratio);
        report_channels(j, "rel_rms_channel", &a->m, e->rel_rms + sb_err_at(k, 0));
        report_channels(j, "max_abs_channel", &a->m, e->max_abs + sb_err_at(k, 0));
        sb_json_end_object(j);
    }
    sb_json_end_array(j);
    report_measured(j, job);
    sb_json_number(j, "negative_texels", a->metric.neg_texels);
    if (job->o.metric_res)
        sb_json_int(j, "metric_resolution", (long long)job->o.metric_res);
    else
        sb_json_number(j, "metric_resolution", NAN); /* null: no comparable_grid asked for */
    report_estimator(j, job);
    report_band_map(j, job);
}

static void report_auto(sb_json_t *j, const sb_job_t *job) {
    sb_json_begin_array(j, "auto_tried");
    for (size_t i = 0; i < job->ncand; i++) {
        const sb_job_candidate_t *c = &job->cands[i];
        sb_json_begin_object(j, NULL);
        sb_json_string(j, "param", sb_param_kind_name(c->kind));
        sb_json_string(j, "form", sb_form_name(c->form));
        sb_json_bool(j, "weighted", c->weighted);
        sb_json_bool(j, "ok", c->ok);
        sb_json_bool(j, "kept", c->kept);
        sb_json_int(j, "resolution", (long long)c->res);
        sb_json_number(j, "headline", c->ok ? c->error : NAN);
        if (c->bands_ok < 0)
            sb_json_string(j, "bands_ok", NULL);
        else
            sb_json_bool(j, "bands_ok", c->bands_ok);
        sb_json_begin_array(j, "band_err");
        for (int b = 0; b < 2; b++)
            sb_json_number(j, NULL, c->ok ? c->band_err[b] : NAN);
        sb_json_end_array(j);
        sb_json_number(j, "time_s", c->time_s);
        sb_json_string(j, "failure", c->why[0] ? c->why : NULL);
        sb_json_end_object(j);
    }
    sb_json_end_array(j);
}

/* The sampler's cosine-weighted share, its GGX lobe's share and alpha
 * and what they gain against the source (sampler_share.c); null and empty without a sampler. */
static void report_sampler(sb_json_t *j, const sb_job_t *job) {
    int has = job->wrote_sampler;
    sb_json_begin_object(j, "sampler");
    sb_json_number(j, "cosine_share", has ? job->share.share : NAN);
    sb_json_number(j, "lobe_share", has ? job->share.lobe_share : NAN);
    sb_json_number(j, "lobe_alpha", has ? job->share.lobe_alpha : NAN);
    sb_json_begin_array(j, "theta_o_deg");
    for (size_t e = 0; has && e < SB_SAMPLER_CHOICE_WO; e++)
        sb_json_number(j, NULL, job->share.theta_o_deg[e]);
    sb_json_end_array(j);
    sb_json_begin_array(j, "variance_ratio");
    for (size_t e = 0; has && e < SB_SAMPLER_CHOICE_WO; e++)
        sb_json_number(j, NULL, job->share.ratio[e]);
    sb_json_end_array(j);
    sb_json_end_object(j);
}

static void report_files(sb_json_t *j, const sb_job_t *job) {
    size_t J = sb_factors_terms(job->best.f);
    char name[64];
    sb_json_begin_object(j, "files");
    for (int side = 0; side < 2; side++) {
        sb_json_begin_array(j, side == SB_SIDE_G ? "g" : "h");
        for (size_t k = 0; k < J; k++) {
            sb_exr_name(side, k, name, sizeof name);
            sb_json_string(j, NULL, name);
        }
        sb_json_end_array(j);
    }
    sb_json_string(j, "glsl", "sepbrdf.glsl");
    sb_json_string(j, "sampler", job->wrote_sampler ? "sampler.bin" : NULL);
    /* the rest of the set: the tables a vndf snippet reads, the translations */
    sb_json_string(j, "vndf", sb_param_caps(job->best.param) & SB_CAP_TABLES ? "vndf.exr" : NULL);
    unsigned mask = 1;
    if (sb_shader_lang_list(NULL, job->o.shaders, &mask) != SB_OK) mask = 1;
    sb_json_begin_array(j, "shaders");
    for (size_t k = 1; k < sb_shader_lang_count(); k++) {
        if (!(mask & (1u << k))) continue;
        snprintf(name, sizeof name, "sepbrdf.%s", sb_shader_lang_ext(k));
        sb_json_string(j, NULL, name);
    }
    sb_json_end_array(j);
    sb_json_end_object(j);
}

void sb_job_report(const sb_job_t *job, FILE *fp) {
    if (!job || !fp) return;
    sb_json_t jw = {fp, 0, {0}}, *j = &jw;
    sb_json_begin_object(j, NULL);
    report_settings(j, job);
    report_fit(j, job);
    report_errors(j, job);
    job_scene_report(j, job);
    if (job->is_auto || job->layout_auto) report_auto(j, job);
    job_budget_report(j, job);
    sb_json_begin_array(j, "warnings");
    for (size_t i = 0; i < job->nwarn; i++)
        sb_json_string(j, NULL, job->warn[i]);
    sb_json_end_array(j);
    sb_json_begin_object(j, "timings");
    sb_json_number(j, "open_s", job->stage_s[0]); /* as stages.open_s: the top level's keys then cover the run */
    sb_json_number(j, "screen_s", job->t.screen_s);
    sb_json_number(j, "sample_s", job->t.sample_s);
    sb_json_number(j, "factor_s", job->t.factor_s);
    sb_json_number(j, "metric_s", job->t.metric_s);
    sb_json_number(j, "estimate_s", job->t.estimate_s);
    sb_json_number(j, "write_s", job->t.write_s);
    sb_json_number(j, "svd_s", job->svd_beside ? job->svd_s : NAN);
    sb_json_number(j, "cv_s", job->cv ? job->cv_s : NAN);
    sb_json_number(j, "total_s", job->t.total_s);
    /* consecutive stages: they add up to total_s, other_s what lies between them (warnings, the summary) */
    static const char *const stage[6] = {"open_s", "choose_s", "beside_s", "scene_s", "cv_s", "samples_s"};
    double sum = job->t.write_s;
    sb_json_begin_object(j, "stages");
    for (int k = 0; k < 6; k++) {
        sb_json_number(j, stage[k], job->stage_s[k]);
        sum += job->stage_s[k];
    }
    sb_json_number(j, "write_s", job->t.write_s);
    sb_json_number(j, "other_s", job->t.total_s - sum);
    sb_json_end_object(j);
    sb_json_end_object(j);
    report_files(j, job);
    report_sampler(j, job);
    sb_json_end_object(j);
}
