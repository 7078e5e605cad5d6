/* The factor job's fits below the choice (job_screen.c) and the warps
 * (job_warp.c): the screening level, the early-stopped fit kept when
 * better, the fewest terms meeting --max-error, the warps of a layout
 * measured and its warped fit, and the warped layout screened. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "job_impl.h"

/* A screening level: res cells per axis, the same J for every candidate
 * (at most the smallest matrix side there), masked fits stopped early (a
 * sweep gaining less than 1e-3, at most 20: the candidates' errors differ
 * by factors, not digits). */
job_level_t job_screen_level(const sb_job_t *job, size_t res, sb_param_opts_t *po) {
    job_level_t lv = {0};
    lv.res = res;
    memset(po, 0, sizeof *po);
    po->res = res;
    po->theta_max = job->o.theta_max_deg * SB_PI / 180;
    lv.half_shape = 1; /* job_level_opts */
    lv.po = po;
    lv.terms = job->o.terms;
    /* --max-error: a layout with fewer rows than o.terms at R is screened
     * with all it has (job_level_terms), the others with as many terms as
     * before; their shorter prefixes too (cand_need) */
    for (size_t i = 0; i < job->ncand; i++) {
        const sb_job_candidate_t *c = &job->cands[i];
        int capped =
            job_terms_capped(job, c->kind) && job_layout_min_side(job, c->kind, job->o.res, NULL) < job->o.terms;
        size_t mn = c->why[0] || capped ? 0 : job_layout_min_side(job, c->kind, lv.res, po);
        if (mn && mn < lv.terms) lv.terms = mn;
    }
    lv.metric_res = 0;    /* no grid quadrature */
    lv.est_max_pairs = 1; /* the estimator's first pairs, no growth */
    lv.rank_only = 1;
    lv.rank_at_j = !(job->o.max_error > 0); /* ranked at J (job_rank_error) */
    job_early_stop(job, &lv);
    return lv;
}

/* A masked fit is a local optimum, and the closest fit to the valid cells
 * is not the best between them: converged to 1e-5 it can carry large
 * cancelling terms in the cells no data constrain, which bilinear lookups
 * near the domain's edge read (the default gold at J = 4: headline 6.7
 * converged, 3.7e-3 stopped early).  An explicit layout also fits the
 * kept matrix with the early stop and keeps that fit when its headline at
 * J is lower than the converged fit's. */
sb_result_t job_keep_early_fit(sb_context_t *ctx, sb_job_t *job, const job_level_t *full, job_attempt_t *a) {
    job_level_t lv = *full;
    job_early_stop(job, &lv);
    return job_keep_better_fit(ctx, job, &lv, a);
}

/* a's matrix fitted again on level `lv` (early stop or not); that fit
 * replaces a's when its headline at J is lower. */
sb_result_t job_keep_better_fit(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a) {
    job_attempt_t tmp = *a; /* a's matrix and param, fitted again into tmp.f / tmp.est */
    tmp.f = NULL;
    tmp.est = NULL;
    sb_result_t r = job_factor(ctx, job, lv, a->weighted, &tmp);
    if (r == SB_OK && job_rank_error(&tmp) < job_rank_error(a)) {
        job_attempt_adopt(a, &tmp);
        a->t_factor += tmp.t_factor;
        return SB_OK;
    }
    sb_factors_destroy(tmp.f);
    free(tmp.est);
    return r == SB_ERR_NUMERIC ? SB_OK : r;
}

/* RGL paper, vndf cos, --max-error 0.03: J = 4 refitted (2.31 %, theta_i >
 * 80 degrees 5.8 %), where the plain J = 4 breaks the bounds and J = 7 is
 * the first plain prefix keeping them. */
sb_result_t job_keep_fewest(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a) {
    size_t J = sb_factors_terms(a->f), met = 0, bounded = 0;
    J = J < a->est->terms ? J : a->est->terms;
    for (size_t k = J; k >= 1; k--) {
        if (!(sb_estimate_headline(a->est, k) <= job->o.max_error)) continue;
        met = k;
        bounded = sb_estimate_bands_bounded(a->est, k) == 1 ? k : bounded;
    }
    sb_result_t r = SB_OK;
    int kept = 0;
    for (size_t k = met; met && !kept && r == SB_OK && k < (bounded ? bounded : J); k++)
        r = job_band_refit_prefix(ctx, job, lv, a, k, job->o.max_error, &kept);
    if (r != SB_OK || kept) return r;
    return job_truncate(ctx, a, bounded ? bounded : met ? met : sb_factors_terms(a->f));
}

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

/* The layout `like` (kind, its cells) sampled again on the warps of
 * `warp` at the requested settings into a and (unless sample_only)
 * fitted as job_warp_refit fits it (a masked fit: the better of two,
 * job_keep_early_fit; max_error: the fewest terms that meet it). */
sb_result_t job_warp_fit(sb_context_t *ctx, sb_job_t *job, const char *warp, const sb_param_t *like, sb_form_t form,
                         int weighted, job_attempt_t *a) {
    double t0 = job_now();
    sb_param_opts_t po = {0};
    if (job->shape) po = *job->shape; /* the layout's shape (--param KIND:key=value), its warps replaced */
    po.res = job->o.res;
    po.theta_max = job->o.theta_max_deg * SB_PI / 180;
    sb_result_t r = job_warps(ctx, job, warp, like, &po);
    if (r == SB_OK) r = sb_param_create(ctx, sb_param_kind(like), &po, &a->param);
    sb_matrix_opts_t mo = {0};
    mo.form = form;
    mo.channels = job->o.channels;
    mo.structured = 1;
    mo.stream = job->o.method == SB_METHOD_STREAM;
    if (r == SB_OK) r = sb_matrix_build(ctx, job->src, a->param, &mo, &a->m);
    a->t_sample = job_now() - t0;
    a->weighted = weighted;
    job_level_t lv = {.res = job->o.res,
                      .terms = job->o.terms,
                      .po = &po,
                      .metric_res = job->o.metric_res,
                      .fit_tol = job->o.fit_tol,
                      .fit_max_iters = job->o.fit_max_iters};
    int fit = !job->o.sample_only, nonneg = job_nonneg_method(sb_method_name(job->o.method));
    if (nonneg) job_early_stop(job, &lv); /* one fit (job_fit_kept) */
    if (r == SB_OK && fit) r = job_factor(ctx, job, &lv, weighted, a);
    if (r == SB_OK && fit && !nonneg && job_attempt_masked(job, a)) r = job_keep_early_fit(ctx, job, &lv, a);
    if (r == SB_OK && fit) r = job_refine(ctx, job, &lv, a);
    if (r == SB_OK && fit && job->o.max_error > 0) r = job_keep_fewest(ctx, job, &lv, a);
    return r;
}

/* The headline at J of the warped layout over candidate c's below
 * 1/JOB_WARP_SCREEN_WIN of c's, both screened at c's resolution: the
 * warped fit is kept without the unwarped one it would have been compared
 * against. */
#define JOB_WARP_SCREEN_WIN 2.0

int job_warp_screen(sb_context_t *ctx, sb_job_t *job, const sb_job_candidate_t *c) {
    sb_param_opts_t po, wpo;
    job_level_t lv = job_screen_level(job, c->res, &po);
    sb_param_t *like = NULL;
    job_attempt_t a = {0};
    wpo = job_level_opts(job, &lv, c->kind); /* c's layout as screened, its warps measured at those cells */
    sb_result_t r = sb_param_create(ctx, c->kind, &wpo, &like);
    if (r == SB_OK) r = job_warps_measure(ctx, job, like, &wpo);
    sb_param_destroy(like);
    lv.po = &wpo;
    if (r == SB_OK) r = job_sample(ctx, job, &lv, c->kind, c->form, &a);
    if (r == SB_OK) r = job_factor(ctx, job, &lv, c->weighted, &a);
    int wins = 0;
    if (r == SB_OK && a.est) {
        size_t J = sb_factors_terms(a.f);
        J = J < a.est->terms ? J : a.est->terms;
        job->warp_screen_error = sb_estimate_headline(a.est, J);
        wins = JOB_WARP_SCREEN_WIN * job->warp_screen_error < c->error && job_attempt_masked(job, &a);
    }
    job_attempt_free(&a);
    return wins;
}
