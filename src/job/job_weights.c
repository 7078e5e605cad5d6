/* Term weights of the kept fit (estimate.h sb_estimate_term_weights): a
 * term that makes what a shader returns worse at J' is scaled down, to 0
 * if need be, so that the headline never rises with J'.  A fit's terms
 * minimise the error on the sampled cells; between them, at the
 * resolution floor or near the edge of a masked domain, one more term can
 * add more interpolation error than it removes. */
#include <math.h>
#include <stdlib.h>

#include "job_impl.h"
#include "sepbrdf/exr.h"
#include "util/internal.h"

/* Weights are dropped when they would raise the headline at J more than
 * this factor. */
#define JOB_WEIGHTS_MAX_LOSS 1.25

/* Scale term j, channel c of f by w (g and h by sqrt(w), sigma by w). */
void job_scale_term(sb_factors_t *f, size_t j, size_t c, double w) {
    double rt = sqrt(w);
    for (int s = 0; s < 2; s++) {
        size_t tw, th;
        sb_factors_size(f, s, &tw, &th);
        double *t = sb_factors_tex(f, s, j, c);
        for (size_t i = 0; i < tw * th; i++)
            t[i] *= rt;
    }
    sb_factors_set_sigma(f, j, c, sb_factors_sigma(f, j, c) * w);
}

/* The replicates each term's weight is fitted on: those a's estimate took
 * each prefix from (what a run of that many terms stops at, so a prefix's
 * weights do not depend on the terms after it); NULL (all the pairs) when
 * a has no full estimate of all its terms. */
static const size_t *weight_reps(const job_attempt_t *a) {
    return !a->est_rank && a->est->terms == sb_factors_terms(a->f) ? a->est->reps : NULL;
}

/* Whether every weight would be 1: a's estimate has each channel's
 * headline at most 1 after one term and non-increasing after it (each term
 * lowers the channel's error sum), where it compares two prefixes on the
 * pairs the weight is fitted on (the same replicates). */
static int weights_all_one(const job_attempt_t *a) {
    const sb_estimate_t *e = a->est;
    if (!weight_reps(a)) return 0;
    for (size_t j = 0; j < e->terms; j++)
        for (int c = 0; c < 3; c++)
            if ((j && e->reps[j] != e->reps[j - 1]) ||
                !(e->rel[j][SB_EST_FCOS][c] <= (j ? e->rel[j - 1][SB_EST_FCOS][c] : 1)))
                return 0;
    return 1;
}

sb_result_t job_terms_restore(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a,
                              sb_factors_t *keep, double *term_w) {
    sb_factors_destroy(a->f);
    a->f = keep;
    free(a->term_w);
    a->term_w = term_w;
    /* keep holds its terms' errors on the cells (job_factors_copy): only
     * the estimate is redone */
    return job_estimate_again(ctx, job, lv, a);
}

sb_result_t job_term_weights(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a) {
    size_t J = sb_factors_terms(a->f), C = sb_factors_channels(a->f);
    a->weights_dropped[0] = a->weights_dropped[1] = 0;
    if (job->o.plain_terms || !a->est || !job->pairs || weights_all_one(a)) return SB_OK;
    sb_exr_opts_t xo = {job->o.half};
    sb_factors_t *q = NULL;
    double *w = malloc(J * C * sizeof *w);
    if (!w) return sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    sb_result_t r = sb_factors_quantize(ctx, a->f, &xo, &q, NULL);
    if (r == SB_OK) r = sb_estimate_term_weights(ctx, job->pairs, q, NULL, a->param, a->m.form, weight_reps(a), w);
    sb_factors_destroy(q);
    int any = 0;
    for (size_t i = 0; r == SB_OK && i < J * C; i++)
        any |= w[i] != 1;
    if (r != SB_OK || !any) {
        free(w);
        return r;
    }
    /* the plain terms, kept aside: weights chosen term by term can starve
     * a term the later ones need (the Cornell acrylic on iso: headline at
     * J 0.12 plain, 0.77 weighted) */
    double plain = sb_estimate_headline(a->est, J);
    sb_factors_t *keep = NULL;
    if ((r = job_factors_copy(ctx, a->f, J, &keep)) != SB_OK) {
        free(w);
        return r;
    }
    for (size_t j = 0; j < J; j++)
        for (size_t c = 0; c < C; c++)
            job_scale_term(a->f, j, c, w[j * C + c]);
    free(a->term_w);
    a->term_w = w;
    r = job_remeasure(ctx, job, lv, a);
    double weighted = sb_estimate_headline(a->est, J);
    if (r != SB_OK || !(weighted > JOB_WEIGHTS_MAX_LOSS * plain)) {
        sb_factors_destroy(keep);
        return r;
    }
    /* the headline at J is what the user asked for: keep the plain terms,
     * and say that their prefixes are not nested */
    if ((r = job_terms_restore(ctx, job, lv, a, keep, NULL)) != SB_OK) return r;
    a->weights_dropped[0] = sb_estimate_headline(a->est, J);
    a->weights_dropped[1] = weighted;
    return SB_OK;
}

void job_warn_weights(sb_job_t *job) {
    const job_attempt_t *a = &job->best;
    if (a->weights_dropped[1] > 0)
        job_warn(job,
                 "the terms are kept as fitted: weights that keep the error falling with J' would raise it at J = "
                 "%zu from %.4g to %.4g; prefixes of fewer terms may have higher errors (report.json: errors)",
                 a->f ? sb_factors_terms(a->f) : 0, a->weights_dropped[0], a->weights_dropped[1]);
}
