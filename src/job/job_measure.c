/* The factor job's measuring of an attempt: the estimator's errors of its
 * factors as stored (what a shader reads), the grid quadrature, and the
 * copies and truncations of its factors.  Below job_attempt.c (sample and
 * factor) and the stages that refine an attempt (job_bandfit.c,
 * job_weights.c, job_texels.c). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "job_impl.h"
#include "sepbrdf/exr.h"
#include "util/internal.h"

/* The most pairs the headline against a scattered table grows to (the
 * estimator's default is 2^19 elsewhere).  Between its samples such a
 * table is known only to its interpolation's leave-one-out error (13 % on
 * the Cornell acrylic), and what its user reads is the error at the
 * measurements left out (cv_headline); the headline against the
 * interpolation, 2 % there, needs no standard error below 5 % of itself:
 * it reached that only at 2^19 pairs, 1.8 s of a 4 s run. */
#define SCATTERED_MAX_PAIRS ((size_t)1 << 17)

/* Whether src is a scattered table (interpolated between its samples). */
static int scattered(const sb_source_t *src) {
    const sb_measured_info_t *mi = sb_measured_source_info(src);
    return mi && (unsigned)mi->interp < SB_INTERP_COUNT_ && isfinite(mi->interp_cv[mi->interp]);
}

/* The estimator's errors of a->f as stored (HALF or FLOAT) into a->est,
 * on the job's pairs, growing them up to lv->est_max_pairs. */
sb_result_t job_estimate(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a) {
    double t0 = job_now();
    sb_estimate_opts_t eo = {0};
    eo.max_pairs = lv->est_max_pairs;
    if (!eo.max_pairs && scattered(job->src)) eo.max_pairs = SCATTERED_MAX_PAIRS;
    if (lv->rank_only) { /* screening: ranked on the headline, 16384 pairs */
        eo.headline_only = 1;
        eo.replicates = 4;
        eo.last_only = lv->rank_at_j;
        eo.bands = 1;           /* the band bounds (auto ranks those that keep them first) */
    } else if (job->est_lean) { /* every J', growing as the whole estimate: the same headlines and bands */
        eo.headline_only = 1;
        eo.bands = !job->est_probe; /* a probe: the same headlines, no bands */
    }
    const sb_factors_t *q = NULL;
    sb_result_t r = SB_OK;
    if (!job->pairs) r = job_pairs_create(ctx, job);
    if (r == SB_OK && !a->est && !(a->est = malloc(sizeof *a->est))) r = sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    /* what a shader reads: the texels as stored */
    if (r == SB_OK) r = job_quantized(ctx, job, a->f, &q);
    if (r == SB_OK) r = sb_estimate_compute(ctx, job->pairs, q, NULL, a->param, a->m.form, &eo, a->est);
    a->est_rank = lv->rank_only;
    a->est_lean = !lv->rank_only && job->est_lean;
    a->est_probe = a->est_lean && job->est_probe;
    a->t_estimate = job_now() - t0;
    job->t_estimate += a->t_estimate;
    return r;
}

sb_result_t job_estimate_reported(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a) {
    if (!a->est || !a->est_rank) return SB_OK;
    job_level_t full = *lv;
    full.rank_only = full.rank_at_j = 0;
    return job_estimate(ctx, job, &full, a);
}

sb_result_t job_estimate_again(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a) {
    job_level_t same = *lv; /* growing as lv says: the pairs each prefix needs, whatever grew them before */
    same.rank_only = same.rank_at_j = 0; /* what is reported: p99 and maxima too */
    return job_measure(ctx, job, &same, a);
}

sb_result_t job_remeasure(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a) {
    sb_factor_errors_t *e = sb_factors_errors_mut(a->f);
    sb_result_t r = sb_factors_errors_against(ctx, a->f, &a->m, a->weighted ? a->param : NULL, e->rel_rms, e->max_abs);
    return r == SB_OK ? job_estimate_again(ctx, job, lv, a) : r;
}

sb_result_t job_measure(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a) {
    a->t_metric = 0;
    sb_result_t r;
    memset(&a->metric, 0, sizeof a->metric);
    if ((r = job_estimate(ctx, job, lv, a)) != SB_OK) return r;
    if (lv->metric_res == 0) { /* no grid quadrature: its texel count alone */
        a->metric.neg_texels = sb_factors_negative_fraction(a->f, sb_factors_terms(a->f));
        return SB_OK;
    }
    sb_metric_opts_t mo = {0};
    mo.res = lv->metric_res;
    mo.channels = job->o.channels;
    double t3 = job_now();
    if ((r = sb_metric_compute(ctx, job->src, a->f, a->param, a->m.form, &mo, &a->metric)) != SB_OK) return r;
    a->t_metric = job_now() - t3;
    return SB_OK;
}

sb_result_t job_factors_copy(sb_context_t *ctx, const sb_factors_t *f, size_t j, sb_factors_t **out) {
    size_t C = sb_factors_channels(f), w[2], h[2];
    for (int s = 0; s < 2; s++)
        sb_factors_size(f, s, &w[s], &h[s]);
    sb_factors_t *t = NULL;
    sb_result_t r = sb_factors_create(ctx, j, C, w[0], h[0], w[1], h[1], &t);
    if (r != SB_OK) return r;
    for (size_t k = 0; k < j; k++)
        for (size_t c = 0; c < C; c++) {
            for (int s = 0; s < 2; s++)
                memcpy(sb_factors_tex(t, s, k, c), sb_factors_tex_const(f, s, k, c), w[s] * h[s] * sizeof(double));
            sb_factors_set_sigma(t, k, c, sb_factors_sigma(f, k, c));
        }
    for (size_t i = 0; i < sb_factors_meta_count(f) && r == SB_OK; i++) {
        const char *key, *value;
        sb_factors_meta_at(f, i, &key, &value);
        r = sb_factors_set_meta(t, key, value);
    }
    const sb_factor_errors_t *e = sb_factors_errors(f);
    sb_factor_errors_t *et = sb_factors_errors_mut(t);
    if (r == SB_OK && et->rel_rms && et->max_abs) {
        memcpy(et->rel_rms, e->rel_rms, sb_err_at(j, 0) * sizeof *e->rel_rms);
        memcpy(et->max_abs, e->max_abs, sb_err_at(j, 0) * sizeof *e->max_abs);
        memcpy(et->norm, e->norm, sizeof et->norm);
    }
    if (r != SB_OK) {
        sb_factors_destroy(t);
        return sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    }
    *out = t;
    return SB_OK;
}

sb_result_t job_truncate(sb_context_t *ctx, job_attempt_t *a, size_t j) {
    if (j >= sb_factors_terms(a->f)) return SB_OK;
    sb_factors_t *t = NULL;
    sb_result_t r = job_factors_copy(ctx, a->f, j, &t);
    if (r != SB_OK) return r;
    sb_factors_destroy(a->f);
    a->f = t;
    if (a->est && a->est->terms > j) a->est->terms = j;
    if (a->metric.terms > j) a->metric.terms = j;
    return SB_OK;
}

void job_attempt_adopt(job_attempt_t *a, const job_attempt_t *t) {
    sb_factors_destroy(a->f);
    free(a->est);
    a->f = t->f;
    a->est = t->est;
    a->est_rank = t->est_rank;
    a->est_lean = t->est_lean;
    a->est_probe = t->est_probe;
    a->stats = t->stats;
    a->conv_terms = t->conv_terms;
    a->early_stop = t->early_stop;
    a->metric = t->metric;
}
