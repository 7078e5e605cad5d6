/* The factor job's warps (job.h: opts.warp): the axes' warps of the kept
 * layout, measured from the source for "adaptive", and the kept fit made
 * again on the warped layout. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "job_impl.h"

/* The headline at the attempt's J. */
static double rank_at_j(const job_attempt_t *a) {
    size_t J = sb_factors_terms(a->f);
    return sb_estimate_headline(a->est, J < a->est->terms ? J : a->est->terms);
}

/* Whether the warped fit a is better than b: a lower headline at J; with
 * --max-error, meeting it within the band bounds first, then fewer terms. */
static int warp_better(const sb_job_t *job, const job_attempt_t *a, const job_attempt_t *b) {
    if (job->o.max_error > 0) {
        int ma = job_meets_bounded(job, a), mb = job_meets_bounded(job, b);
        size_t ja = sb_factors_terms(a->f), jb = sb_factors_terms(b->f);
        if (ma != mb) return ma;
        if (ma && ja != jb) return ja < jb;
    }
    return rank_at_j(a) < rank_at_j(b);
}

/* With opts.warp on a layout with SB_CAP_WARPS: sample the kept candidate
 * again on the warped layout and (unless sample_only) fit it with the
 * requested settings (job_warp_fit), replacing job->best (max_error: the
 * fewest terms that meet it); "auto" keeps the warped fit only when its
 * headline at J is lower (both on the estimator's pairs).  Decided in the
 * screening (job_warp_screen): job->best is that warped fit already. */
sb_result_t job_warp_refit(sb_context_t *ctx, sb_job_t *job) {
    job_attempt_t *b = &job->best, a = {0};
    const char *warp = job->o.warp;
    if (job->warp_screened) {
        job->warp_tried = 1;
        return SB_OK;
    }
    /* none asked for: "auto" where the layout's own spacing leaves more
     * than JOB_WARP_TRY at J (sharp lobes: GGX roughness 0.1 5.2 % ->
     * 1.8 %, the RGL vinyl 91 % -> 35 %); not where --param gave the
     * whole layout (KIND:key=value, its warps included) */
    if (!warp && b->f && b->est && !job->o.sample_only && job->shape != &job->spec_shape && !job_few_rows(job) &&
        (sb_param_caps(b->param) & SB_CAP_WARPS) && rank_at_j(b) > JOB_WARP_TRY)
        warp = "auto";
    job->warp_tried = warp && !job->o.warp;
    if (!warp) return SB_OK;
    if (!(sb_param_caps(b->param) & SB_CAP_WARPS)) {
        job_warn(job, "%s has no axis that takes a warp; the warp asked for (%s) is not applied",
                 sb_param_name(b->param), warp);
        return SB_OK;
    }
    sb_result_t r = job_warp_fit(ctx, job, warp, b->param, b->m.form, b->weighted, &a);
    int fit = !job->o.sample_only;
    int worse = r == SB_OK && fit && strcmp(warp, "auto") == 0 && !warp_better(job, &a, b);
    /* the unwarped fit left pending (job_fit_kept) is replaced only by a
     * warped fit with less than half its headline: its converged fit and
     * refinement may close less than that (an RGL file's CSV of nodes:
     * 0.9993 early-stopped and warped against 0.9298 converged) */
    if (r == SB_OK && fit && (job->fit_pending & FINISH_PENDING) && (worse || !(2 * rank_at_j(&a) < rank_at_j(b)))) {
        r = job_fit_finish(ctx, job); /* the unwarped fit whole, then compared again */
        worse = r == SB_OK && !warp_better(job, &a, b);
    }
    job->fit_pending = 0;
    if (r != SB_OK || worse) {
        job_attempt_free(&a);
        return r;
    }
    job_attempt_free(b);
    *b = a;
    return SB_OK;
}
