/* The factor job's warps (job.h: opts.warp): the axes' warps of the kept
 * layout, measured from the source for "adaptive", and the kept fit made
 * again on the warped layout. */
#include <stdlib.h>
#include <string.h>

#include "job_impl.h"

sb_result_t job_warp_parse(sb_context_t *ctx, const char *name, int *adaptive, sb_warp_kind_t *kind) {
    *adaptive = name && (strcmp(name, "adaptive") == 0 || strcmp(name, "auto") == 0);
    *kind = SB_WARP_DEFAULT;
    if (!name || *adaptive) return SB_OK;
    if (sb_warp_kind_parse(name, kind) == SB_OK && (*kind == SB_WARP_UNIFORM || *kind == SB_WARP_MERL)) return SB_OK;
    return sb_error(ctx, SB_ERR_UNKNOWN, "warp '%s' unknown, need one of uniform, merl, adaptive, auto", name);
}

/* The warps of job->o.warp into po->warp: uniform (both axes), merl
 * (theta_h MERL, theta_d uniform) or adaptive and auto (both measured,
 * for the texels per axis of `like`). */
static sb_result_t job_warps(sb_context_t *ctx, sb_job_t *job, const char *warp, const sb_param_t *like,
                             sb_param_opts_t *po) {
    int adaptive;
    sb_warp_kind_t kind;
    sb_result_t r = job_warp_parse(ctx, warp, &adaptive, &kind);
    if (r == SB_OK && adaptive) return job_warps_measure(ctx, job, like, po);
    for (int a = 0; a < SB_AXIS_COUNT_ && r == SB_OK; a++)
        po->warp[a].kind = kind == SB_WARP_MERL && a == SB_AXIS_THETA_D ? SB_WARP_UNIFORM : kind;
    return r;
}

sb_result_t job_warps_measure(sb_context_t *ctx, const sb_job_t *job, const sb_param_t *like, sb_param_opts_t *po) {
    sb_result_t r = SB_OK;
    for (int a = 0; a < SB_AXIS_COUNT_ && r == SB_OK; a++) {
        sb_warp_measure_opts_t wo = {0};
        wo.theta_max = po->theta_max;
        if (!(wo.cells = sb_param_warp_cells(like, a))) continue; /* the layout's own spacing */
        r = sb_warp_measure(ctx, job->src, a, &wo, &po->warp[a]);
    }
    return r;
}

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
 * requested settings (a masked fit: the better of two, job_keep_early_fit),
 * replacing job->best (max_error: the fewest terms that meet it); "auto" keeps the warped fit only when its headline at
 * J is lower (both on the estimator's pairs). */
sb_result_t job_warp_refit(sb_context_t *ctx, sb_job_t *job) {
    job_attempt_t *b = &job->best, a = {0};
    const char *warp = job->o.warp;
    /* none asked for: "auto" where the layout's own spacing leaves more
     * than JOB_WARP_TRY at J (sharp lobes: GGX roughness 0.1 5.2 % ->
     * 1.8 %, the RGL vinyl 91 % -> 35 %); not where --param gave the
     * whole layout (KIND:key=value, its warps included) */
    if (!warp && b->f && b->est && !job->o.sample_only && job->shape != &job->spec_shape &&
        (sb_param_caps(b->param) & SB_CAP_WARPS) && rank_at_j(b) > JOB_WARP_TRY)
        warp = "auto";
    job->warp_tried = warp && !job->o.warp;
    if (!warp) return SB_OK;
    if (!(sb_param_caps(b->param) & SB_CAP_WARPS)) {
        job_warn(job, "%s has no axis that takes a warp; the warp asked for (%s) is not applied",
                 sb_param_name(b->param), warp);
        return SB_OK;
    }
    double t0 = job_now();
    sb_param_opts_t po = {0};
    if (job->shape) po = *job->shape; /* the layout's shape (--param KIND:key=value), its warps replaced */
    po.res = job->o.res;
    po.theta_max = job->o.theta_max_deg * SB_PI / 180;
    sb_result_t r = job_warps(ctx, job, warp, b->param, &po);
    if (r == SB_OK) r = sb_param_create(ctx, sb_param_kind(b->param), &po, &a.param);
    sb_matrix_opts_t mo = {0};
    mo.form = b->m.form;
    mo.channels = job->o.channels;
    mo.structured = 1;
    mo.stream = job->o.method == SB_METHOD_STREAM;
    if (r == SB_OK) r = sb_matrix_build(ctx, job->eval_src, a.param, &mo, &a.m);
    a.t_sample = job_now() - t0;
    a.weighted = b->weighted;
    job_level_t lv = {.res = job->o.res,
                      .terms = job->o.terms,
                      .po = &po,
                      .metric_res = job->o.metric_res,
                      .fit_tol = job->o.fit_tol,
                      .fit_max_iters = job->o.fit_max_iters};
    int fit = !job->o.sample_only, nonneg = job_nonneg_method(sb_method_name(job->o.method));
    if (nonneg) job_early_stop(job, &lv); /* one fit (job_fit_kept) */
    if (r == SB_OK && fit) r = job_factor(ctx, job, &lv, b->weighted, &a);
    if (r == SB_OK && fit && !nonneg && job_attempt_masked(job, &a)) r = job_keep_early_fit(ctx, job, &lv, &a);
    if (r == SB_OK && fit) r = job_refine(ctx, job, &lv, &a);
    if (r == SB_OK && fit && job->o.max_error > 0) r = job_keep_fewest(ctx, job, &lv, &a);
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
