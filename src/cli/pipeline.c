/* The per-candidate pipeline of `factor` and `study`: sample, factor,
 * measure.  Only the public API. */
#include "pipeline.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

/* A model spec is NAME[:key=value,...] with NAME a plain identifier, so a
 * NAME with '/' or '.' can only be meant as a file.  Values may hold both
 * ("base=1/0.8/0.3", "roughness=0.5"), hence only the part before ':'. */
static int looks_like_path(const char *spec) {
    size_t n = strcspn(spec, ":");
    return memchr(spec, '/', n) != NULL || memchr(spec, '.', n) != NULL;
}

sb_result_t pipe_source_open(sb_context_t *ctx, const char *spec, const sb_measured_opts_t *mo, sb_source_t **out) {
    struct stat st;
    if (spec && looks_like_path(spec)) {
        if (stat(spec, &st) != 0) return sb_error(ctx, SB_ERR_IO, "%s: %s", spec, strerror(errno));
        if (!S_ISREG(st.st_mode)) return sb_error(ctx, SB_ERR_IO, "%s: not a regular file", spec);
    }
    if (spec && out && stat(spec, &st) == 0 && S_ISREG(st.st_mode)) return sb_measured_open(ctx, spec, mo, out, NULL);
    return sb_source_open(ctx, spec, out);
}

static void sample_progress(void *user, double fraction) {
    const pipe_opts_t *o = user;
    cli_progress(o->progress_label, o->progress_base + o->progress_span * fraction);
}

sb_result_t attempt_sample(sb_context_t *ctx, const sb_source_t *src, const pipe_opts_t *o, sb_param_kind_t kind,
                           sb_form_t form, attempt_t *a) {
    memset(a, 0, sizeof *a);
    a->zero_fill = o->zero_fill;
    sb_param_opts_t po = {0};
    po.res = o->res;
    po.theta_max = o->theta_max_deg * SB_PI / 180;
    sb_result_t r = sb_param_create(ctx, kind, &po, &a->param);
    if (r != SB_OK) return r;
    size_t rows = sb_param_rows(a->param), cols = sb_param_cols(a->param), mn = rows < cols ? rows : cols;
    if (o->terms > mn)
        return sb_error(ctx, SB_ERR_RANGE,
                        "--terms %zu exceeds the %zu rows/columns of %s; lower --terms or raise --res", o->terms, mn,
                        sb_param_spec(a->param));
    cli_info(2, "sampling %s on %s (%zu x %zu), form %s", sb_source_description(src), sb_param_spec(a->param), rows,
             cols, sb_form_name(form));
    double t0 = cli_now();
    sb_matrix_opts_t mo = {0};
    mo.form = form;
    mo.channels = o->channels;
    if (o->progress_label) {
        mo.progress = sample_progress;
        mo.progress_user = (void *)o;
    }
    if ((r = sb_matrix_build(ctx, src, a->param, &mo, &a->m)) != SB_OK) return r;
    a->t_sample = cli_now() - t0;
    return SB_OK;
}

int attempt_masked(const attempt_t *a) { return a->m.mask != NULL && !a->zero_fill; }

sb_result_t attempt_factor(sb_context_t *ctx, const sb_source_t *src, const pipe_opts_t *o, size_t terms, int weighted,
                           attempt_t *a) {
    sb_factors_destroy(a->f);
    a->f = NULL;
    memset(&a->metric, 0, sizeof a->metric);
    memset(&a->stats, 0, sizeof a->stats);
    a->weighted = weighted;
    a->t_metric = 0;
    sb_plan_opts_t pl = {0};
    pl.terms = terms;
    pl.max_error = o->max_error;
    pl.svd.method = o->method;
    pl.svd.seed = o->seed;
    pl.weighted = weighted;
    pl.zero_fill = o->zero_fill;
    pl.fit_tol = o->fit_tol;
    pl.fit_max_iters = o->fit_max_iters;
    size_t rank = a->m.rows < a->m.cols ? a->m.rows : a->m.cols;
    if (terms > rank)
        return sb_error(ctx, SB_ERR_RANGE,
                        "--terms %zu exceeds the matrix rank limit %zu; lower --terms or raise --res", terms, rank);
    sb_plan_t *plan = NULL;
    sb_result_t r = sb_plan_create_for(ctx, &a->m, &pl, &plan);
    if (r != SB_OK) return r;
    cli_info(2, "factoring %s, %zu terms%s%s", sb_param_spec(a->param), terms, weighted ? ", weighted" : "",
             attempt_masked(a) ? ", masked fit" : "");
    double t1 = cli_now();
    r = sb_plan_execute(plan, &a->m, a->param, &a->f);
    sb_plan_stats(plan, &a->stats);
    sb_plan_destroy(plan);
    if (r != SB_OK) return r;
    a->t_factor = cli_now() - t1;
    if (sb_factors_set_meta(a->f, "source", sb_source_description(src)) != SB_OK)
        return sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    if ((r = attempt_estimate(ctx, src, o, a)) != SB_OK) return r;
    if (o->metric_res > 0) {
        sb_metric_opts_t mo = {0};
        mo.res = o->metric_res;
        double t2 = cli_now();
        if ((r = sb_metric_compute(ctx, src, a->f, a->param, a->m.form, &mo, &a->metric)) != SB_OK) return r;
        a->t_metric = cli_now() - t2;
    }
    return SB_OK;
}

sb_result_t attempt_estimate(sb_context_t *ctx, const sb_source_t *src, const pipe_opts_t *o, attempt_t *a) {
    double t0 = cli_now();
    sb_estimate_opts_t eo = {0};
    eo.max_pairs = o->est_max_pairs;
    sb_exr_opts_t xo = {o->half};
    sb_pairs_t *own = NULL, *pairs = o->pairs;
    sb_factors_t *q = NULL;
    sb_result_t r = SB_OK;
    if (!a->est && !(a->est = malloc(sizeof *a->est))) return sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    if (!pairs) r = sb_pairs_create(ctx, src, &eo, &own);
    pairs = pairs ? pairs : own;
    /* what a shader reads: the texels as stored (FLOAT, or HALF with its scales) */
    if (r == SB_OK) r = sb_factors_quantize(ctx, a->f, &xo, &q, NULL);
    if (r == SB_OK) r = sb_estimate_compute(ctx, pairs, q, NULL, a->param, a->m.form, &eo, a->est);
    sb_factors_destroy(q);
    sb_pairs_destroy(own);
    a->t_estimate = cli_now() - t0;
    return r;
}

sb_result_t attempt_truncate(sb_context_t *ctx, attempt_t *a, size_t j) {
    size_t J = sb_factors_terms(a->f), C = sb_factors_channels(a->f), w[2], h[2];
    if (j >= J) return SB_OK;
    for (int s = 0; s < 2; s++)
        sb_factors_size(a->f, s, &w[s], &h[s]);
    sb_factors_t *t = NULL;
    sb_result_t r = sb_factors_create(ctx, j, C, w[0], h[0], w[1], h[1], &t);
    if (r != SB_OK) return r;
    for (size_t k = 0; k < j; k++)
        for (size_t c = 0; c < C; c++) {
            for (int s = 0; s < 2; s++)
                memcpy(sb_factors_tex(t, s, k, c), sb_factors_tex_const(a->f, s, k, c), w[s] * h[s] * sizeof(double));
            sb_factors_set_sigma(t, k, c, sb_factors_sigma(a->f, k, c));
        }
    for (size_t i = 0; i < sb_factors_meta_count(a->f) && r == SB_OK; i++) {
        const char *key, *value;
        sb_factors_meta_at(a->f, i, &key, &value);
        r = sb_factors_set_meta(t, key, value);
    }
    const sb_factor_errors_t *e = sb_factors_errors(a->f);
    sb_factor_errors_t *et = sb_factors_errors_mut(t);
    if (r == SB_OK && et->rel_rms && et->max_abs) {
        memcpy(et->rel_rms, e->rel_rms, j * 4 * sizeof *e->rel_rms);
        memcpy(et->max_abs, e->max_abs, j * 4 * sizeof *e->max_abs);
        memcpy(et->norm, e->norm, sizeof et->norm);
    }
    if (r != SB_OK) {
        sb_factors_destroy(t);
        return sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    }
    sb_factors_destroy(a->f);
    a->f = t;
    if (a->est && a->est->terms > j) a->est->terms = j;
    if (a->metric.terms > j) a->metric.terms = j;
    return SB_OK;
}

sb_result_t attempt_run(sb_context_t *ctx, const sb_source_t *src, const pipe_opts_t *o, sb_param_kind_t kind,
                        sb_form_t form, int weighted, attempt_t *a) {
    sb_result_t r = attempt_sample(ctx, src, o, kind, form, a);
    if (r == SB_OK) r = attempt_factor(ctx, src, o, o->terms, weighted, a);
    return r;
}

double attempt_headline(const attempt_t *a, size_t j) { return a->est ? sb_estimate_headline(a->est, j) : NAN; }

double attempt_comparable(const attempt_t *a, size_t j) {
    return a->est && j >= 1 && j <= a->est->terms ? a->est->rel[j - 1][SB_EST_FCOS2][3] : NAN;
}

double attempt_negative(const attempt_t *a, size_t j) {
    return a->est && j >= 1 && j <= a->est->terms ? a->est->neg_frac[j - 1] : NAN;
}

void attempt_free(attempt_t *a) {
    free(a->est);
    sb_factors_destroy(a->f);
    sb_matrix_free(&a->m);
    sb_param_destroy(a->param);
    memset(a, 0, sizeof *a);
}

size_t pipe_candidates(const sb_source_t *src, const pipe_opts_t *o, int param_auto, sb_param_kind_t param,
                       int form_set, sb_form_t form, int weighted, pipe_cand_t *cands) {
    size_t n = 0;
    if (!param_auto) {
        cands[n++] = (pipe_cand_t){param, form, weighted, 0, 0};
        return n;
    }
    for (int k = 0; k < SB_PARAM_KIND_COUNT_; k++) {
        if (!sb_param_kind_applies((sb_param_kind_t)k, sb_source_flags(src))) continue;
        sb_param_t *probe = NULL;
        sb_param_opts_t po = {0};
        po.res = o->res;
        po.theta_max = (o->theta_max_deg > 0 ? o->theta_max_deg : 90) * SB_PI / 180;
        if (sb_param_create(NULL, (sb_param_kind_t)k, &po, &probe) != SB_OK) continue; /* not available */
        sb_param_destroy(probe);
        cands[n++] = (pipe_cand_t){(sb_param_kind_t)k, form_set ? form : SB_FORM_F, 1, 0, 0};
        if (!form_set && !(sb_param_kind_caps((sb_param_kind_t)k) & SB_CAP_FOLDS_RECIPROCITY))
            cands[n++] = (pipe_cand_t){(sb_param_kind_t)k, SB_FORM_COS, 1, 0, 0};
    }
    return n;
}

/* Factor candidate i with po into a; SB_OK, or a failure to report. */
static sb_result_t select_one(sb_context_t *ctx, const sb_source_t *src, pipe_opts_t *po, const pipe_cand_t *cd,
                              size_t i, size_t ncand, attempt_t *a) {
    char label[64];
    snprintf(label, sizeof label, "%s/%s %zu/%zu", sb_param_kind_name(cd->kind), sb_form_name(cd->form), i + 1, ncand);
    po->progress_label = label; /* sampling: the first half of a candidate's bar */
    po->progress_base = (double)i / (double)ncand;
    po->progress_span = 0.5 / (double)ncand;
    sb_result_t r = attempt_sample(ctx, src, po, cd->kind, cd->form, a);
    cli_progress(label, (i + 0.5) / (double)ncand);
    if (r == SB_OK) r = attempt_factor(ctx, src, po, po->terms, cd->weighted, a);
    cli_progress(label, (i + 1.0) / (double)ncand);
    po->progress_label = NULL;
    return r;
}

/* The estimate with growth and the grid metric of a screened attempt. */
static sb_result_t measure_full(sb_context_t *ctx, const sb_source_t *src, const pipe_opts_t *full, attempt_t *a) {
    sb_result_t r = attempt_estimate(ctx, src, full, a);
    if (r == SB_OK && full->metric_res > 0) {
        sb_metric_opts_t mo = {0};
        mo.res = full->metric_res;
        double tm = cli_now();
        r = sb_metric_compute(ctx, src, a->f, a->param, a->m.form, &mo, &a->metric);
        a->t_metric = cli_now() - tm;
    }
    return r;
}

/* Refit the screened masked fit in full; a masked fit is a local optimum,
 * so the full refit is kept only if its headline at J is no worse than the
 * screened one's (the screened fit is then measured in full instead). */
static sb_result_t refit_best(sb_context_t *ctx, const sb_source_t *src, const pipe_opts_t *full, attempt_t *best) {
    size_t J = sb_factors_terms(best->f);
    double h0 = attempt_headline(best, J < best->est->terms ? J : best->est->terms);
    attempt_t keep = *best;
    best->f = NULL;
    best->est = NULL;
    sb_result_t r = attempt_factor(ctx, src, full, full->terms, best->weighted, best);
    best->t_sample = keep.t_sample;
    if (r == SB_OK && !(attempt_headline(best, J < best->est->terms ? J : best->est->terms) > h0)) {
        sb_factors_destroy(keep.f);
        free(keep.est);
        return SB_OK;
    }
    cli_info(2, "  the full refit measured worse than the screened fit (%.4e): keeping the screened one", h0);
    sb_factors_destroy(best->f);
    free(best->est);
    best->f = keep.f;
    best->est = keep.est;
    best->stats = keep.stats;
    best->t_factor = keep.t_factor;
    if (r != SB_OK && r != SB_ERR_NUMERIC) return r;
    return measure_full(ctx, src, full, best);
}

sb_result_t pipe_select(sb_context_t *ctx, const char *cmd, const sb_source_t *src, const pipe_opts_t *o,
                        pipe_cand_t *cands, size_t ncand, attempt_t *best) {
    pipe_opts_t po = *o, full = *o;
    double best_err = 0;
    memset(best, 0, sizeof *best);
    sb_pairs_t *own = NULL;
    if (!o->pairs) {
        sb_result_t r = sb_pairs_create(ctx, src, NULL, &own);
        if (r != SB_OK) return r;
        po.pairs = full.pairs = own;
    }
    /* Screening: the estimator on its first pairs (no growth), no grid
     * metric, and masked fits stopped early (a sweep gaining less than
     * 1e-3, at most 40 sweeps: they were 3/4 of the default run, and the
     * candidates' errors differ by factors, not digits); the kept one is
     * refitted and measured in full. */
    int screened = ncand > 1;
    double t_screen = 0;
    if (screened) {
        po.metric_res = 0;
        po.est_max_pairs = 1;
        if (po.fit_tol == 0) po.fit_tol = 1e-3;
        if (po.fit_max_iters == 0) po.fit_max_iters = 40;
    }
    sb_result_t r = SB_OK;
    for (size_t i = 0; i < ncand; i++) {
        attempt_t a;
        r = select_one(ctx, src, &po, &cands[i], i, ncand, &a);
        if (r != SB_OK) {
            attempt_free(&a);
            if (ncand == 1 || (r != SB_ERR_NUMERIC && r != SB_ERR_UNSUPPORTED)) break;
            cli_info(1, "%s: --param auto: %s/%s failed: %s", cmd, sb_param_kind_name(cands[i].kind),
                     sb_form_name(cands[i].form), sb_context_last_error(ctx));
            r = SB_OK;
            continue;
        }
        size_t J = sb_factors_terms(a.f);
        t_screen += screened ? a.t_estimate : 0;
        /* the estimate holds SB_EST_MAXJ terms at most: compare there beyond */
        cands[i].err = attempt_headline(&a, J < a.est->terms ? J : a.est->terms);
        cands[i].ok = 1;
        cli_info(2, "  %s form %s: headline error %.4e at J = %zu", sb_param_spec(a.param), sb_form_name(cands[i].form),
                 cands[i].err, J);
        if (!best->f || cands[i].err < best_err) {
            best_err = cands[i].err;
            attempt_free(best);
            *best = a;
        } else {
            attempt_free(&a);
        }
    }
    cli_progress_done();
    if (r == SB_OK && !best->f)
        r = sb_error(ctx, SB_ERR_NUMERIC, "no parameterisation could factor %s", sb_source_description(src));
    if (r == SB_OK && screened && attempt_masked(best)) {
        r = refit_best(ctx, src, &full, best);
    } else if (r == SB_OK && screened) {
        r = measure_full(ctx, src, &full, best);
    }
    if (r != SB_OK) attempt_free(best);
    best->t_estimate += t_screen; /* what the estimator cost in all */
    sb_pairs_destroy(own);
    return r;
}
