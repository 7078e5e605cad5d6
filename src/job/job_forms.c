/* The factor job's choice at the requested settings (job_select): the
 * screened candidates fitted in their order; a layout named alone in two
 * forms: both fitted, only the better finished. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "job_impl.h"

/* A form's fit of named_pair: the attempt, its FINISH_* flags, whether
 * job_fit_finish is still to run on it, its result. */
typedef struct {
    job_attempt_t a;
    unsigned pending;
    int unfinished;
    sb_result_t r;
} form_fit_t;

/* Candidate c fitted into o (before job_fit_finish when `finish` is 0, else
 * finished); a failure is recorded in c. */
static sb_result_t pair_step(sb_context_t *ctx, sb_job_t *job, sb_job_candidate_t *c, form_fit_t *o, int finish) {
    double t1 = job_now();
    job->best = o->a;
    job->fit_pending = o->pending;
    if (!finish) {
        memset(&job->best, 0, sizeof job->best);
        o->r = job_fit_kept_unfinished(ctx, job, c, &o->unfinished);
    } else if (o->unfinished) {
        o->unfinished = 0;
        if ((o->r = job_fit_finish(ctx, job)) != SB_OK) job_attempt_free(&job->best);
    }
    o->a = job->best;
    o->pending = job->fit_pending;
    memset(&job->best, 0, sizeof job->best);
    job->fit_pending = 0;
    c->time_s += job_now() - t1;
    if (o->r != SB_OK) {
        c->ok = 0;
        c->result = o->r;
        snprintf(c->why, sizeof c->why, "%s", sb_context_last_error(ctx));
    }
    return o->r;
}

/* a's max_abs where its fit left it out (the second form's fit,
 * sb_plan_skip_max_: NaN): its plan executed again on a->m (the same
 * factors to the bit, every prefix's maximum its own); else nothing. */
static sb_result_t pair_max_abs(sb_context_t *ctx, sb_job_t *job, job_attempt_t *a) {
    sb_factor_errors_t *e = sb_factors_errors_mut(a->f);
    size_t n = a->f ? sb_err_at(sb_factors_terms(a->f), 0) : 0;
    int skipped = 0;
    for (size_t i = 0; i < n && e->max_abs; i++)
        skipped |= isnan(e->max_abs[i]);
    if (!skipped || !a->m.structured || job->scene) return SB_OK;

    job_level_t lv = job_full_level(job);
    size_t J = job_fit_terms(job, &lv, a);
    sb_plan_opts_t pl = job_plan_opts(job, &lv, a, J);
    sb_plan_t *plan = NULL;
    sb_factors_t *f = NULL;
    sb_result_t r = sb_plan_create_for(ctx, &a->m, &pl, &plan);
    if (r == SB_OK) r = sb_plan_execute(plan, &a->m, a->param, &f);
    if (r == SB_OK && sb_factors_terms(f) * 4 >= n) /* a prefix's maximum is its own: the first n */
        memcpy(e->max_abs, sb_factors_errors(f)->max_abs, n * sizeof *e->max_abs);
    sb_factors_destroy(f);
    sb_plan_destroy(plan);
    return r;
}

/* A form's fit behind the other's, both stopped early, by more than this
 * factor in the headline at J is not finished (job_fit_finish: the
 * converged fit tried, refinement): the converged fit gained 1.42x at
 * most where it was kept (GGX 0.3, iso, J = 4: 2.7 % -> 1.9 %). */
#define JOB_FORM_FINISH_MARGIN 1.5

/* Which fit of named_pair is kept: the other where the better one's
 * finishing failed; where both were finished, the second in the order
 * where its headline is lower, else the first (as before). */
static int pair_keep(const form_fit_t o[2], int w, int finished_both) {
    if (o[w].r != SB_OK) return !w;
    if (!finished_both || o[!w].r != SB_OK) return w;
    return job_rank_error(&o[1].a) < job_rank_error(&o[0].a);
}

/* Candidate c, not screened (pair_unscreened), as fitted at R: its
 * ranking error, band bounds and band errors at J, as a screening records
 * them (report.json auto_tried). */
static void pair_record(sb_job_candidate_t *c, const job_attempt_t *a) {
    size_t J = sb_factors_terms(a->f), j = J < a->est->terms ? J : a->est->terms;
    c->error = job_rank_error(a);
    c->bands_ok = a->est_probe ? -1 : sb_estimate_bands_bounded(a->est, j);
    job_band_errors(a->est, J, c->band_err);
    if (a->est_probe) c->band_err[0] = c->band_err[1] = NAN; /* not measured: null in auto_tried */
}

/* How many standard errors apart the headlines of pair_unscreened's two
 * forms must be for the second's probe (its headlines alone, no bands:
 * job->est_probe) to stand as its measure.  The headline's standard error
 * is at most 5 % of it (SB_EST_REL_SE); io -r 64 of the default gold:
 * cos 0.502 (standard error 0.0046), f 0.586, both on 4 replicates. */
#define JOB_PROBE_CLEAR_SE 4

/* Whether the probe of the second form (o[1]) stands: it lost to the
 * first by more than JOB_PROBE_CLEAR_SE combined standard errors of the
 * headline at J.  Where it won or is close, it is measured again with its
 * bands (what the first form's fit has), so everything a close or winning
 * fit goes on to is as before. */
static int probe_clear(const form_fit_t o[2]) {
    if (!o[1].a.est_probe || o[1].r != SB_OK) return 1;
    if (o[0].r != SB_OK) return 0; /* the first failed: the second is kept */
    double h[2], se[2];
    for (int k = 0; k < 2; k++) {
        const job_attempt_t *a = &o[k].a;
        size_t J = sb_factors_terms(a->f), j = J < a->est->terms ? J : a->est->terms;
        h[k] = job_rank_error(a);
        se[k] = j >= 1 ? a->est->se[j - 1][SB_EST_FCOS][3] : NAN;
    }
    return h[1] - h[0] > JOB_PROBE_CLEAR_SE * sqrt(se[0] * se[0] + se[1] * se[1]);
}

/* A layout named alone whose screening kept two forms (f and cos) of it:
 * the coarse screen can rank them wrongly at the requested R (GGX 0.3 on
 * hd: cos screened first, 0.0517 at R = 32 against f's 0.0220), so both
 * are fitted there and the lower headline at J kept.  Both are compared
 * first as fitted (stopped early), and only the better is finished, the
 * other too where it is within JOB_FORM_FINISH_MARGIN (then compared
 * finished): on the default gold, hd, cos's converged fit and refinement
 * were a third of the run and it lost by 1.8x. */
static sb_result_t named_pair(sb_context_t *ctx, sb_job_t *job, const size_t *order, int unscreened) {
    sb_job_candidate_t *c[2] = {&job->cands[order[0]], &job->cands[order[1]]};
    form_fit_t o[2];
    memset(o, 0, sizeof o);
    /* the second form's matrix from the first's evaluations (io: its
     * sampling was a fifth of the second fit) */
    job_form_share_t share = {.want = c[0]->kind == c[1]->kind, .form = c[1]->form};
    job->form_share = &share;
    for (int k = 0; k < 2; k++) {
        job->est_lean = !(unscreened && k == 0); /* pair_unscreened_order */
        job->est_probe = unscreened && k == 1;
        share.second = k == 1 && share.want == 0 && c[0]->kind == c[1]->kind;
        sb_result_t rk = pair_step(ctx, job, c[k], &o[k], 0);
        share.want = share.second = 0;
        job->est_lean = 1;
        job->est_probe = 0;
        if (rk == SB_OK && k == 1 && !probe_clear(o)) { /* close or won: its bands too, as before */
            job_level_t lv = job_full_level(job);
            rk = o[1].r = job_estimate(ctx, job, &lv, &o[1].a);
        }
        if (rk == SB_ERR_NOMEM) {
            job_attempt_free(&o[0].a);
            job_attempt_free(&o[1].a);
            job->form_share = NULL;
            sb_matrix_free(&share.m);
            return SB_ERR_NOMEM;
        }
        if (unscreened && o[k].r == SB_OK) pair_record(c[k], &o[k].a);
    }
    job->form_share = NULL;
    sb_matrix_free(&share.m);
    if (o[0].r != SB_OK && o[1].r != SB_OK) return o[1].r;
    int w = o[0].r != SB_OK || (o[1].r == SB_OK && job_rank_error(&o[1].a) < job_rank_error(&o[0].a)), l = !w;
    int other = o[l].r == SB_OK && !(job_rank_error(&o[l].a) > JOB_FORM_FINISH_MARGIN * job_rank_error(&o[w].a));
    sb_result_t r = pair_step(ctx, job, c[w], &o[w], 1);
    if (o[w].pending & FINISH_PENDING) other = 0; /* the warped fit is tried on it first (job_warp.c) */
    if (r == SB_OK || r == SB_ERR_NUMERIC)
        r = o[l].r == SB_OK && (other || r != SB_OK) ? pair_step(ctx, job, c[l], &o[l], 1) : r;
    if (r == SB_ERR_NOMEM) {
        job_attempt_free(&o[0].a);
        job_attempt_free(&o[1].a);
        return r;
    }
    int keep = pair_keep(o, w, other);
    if (o[keep].r != SB_OK) return o[keep].r;
    if ((r = pair_max_abs(ctx, job, &o[keep].a)) != SB_OK) {
        job_attempt_free(&o[0].a);
        job_attempt_free(&o[1].a);
        return r;
    }
    job_attempt_free(&o[!keep].a);
    job->best = o[keep].a;
    job->fit_pending = o[keep].pending;
    c[keep]->kept = 1;
    c[!keep]->kept = 0;
    sb_context_clear_error(ctx);
    return SB_OK;
}

/* Whether job_select's candidates are one layout named alone in two forms
 * (named_pair). */
static int is_named_pair(const sb_job_t *job, const size_t *order, size_t n) {
    if (n != 2 || !job->layout_auto || job->budget || job->o.max_error > 0) return 0;
    const sb_job_candidate_t *a = &job->cands[order[0]], *b = &job->cands[order[1]];
    return a->kind == b->kind && a->form != b->form;
}

/* A layout named alone in two forms (f and cos) on a layout whose every
 * cell is a pair (no mask, no tables: io, io-area; each fit one SVD) of
 * an analytic source: both forms are fitted at R and the lower headline
 * kept (named_pair) whatever the screening ranks, so it is not screened
 * (R = 8 and 16, both forms, four ranking estimates: a fifth of io -r 64's
 * CPU); each candidate records its fit at R instead (pair_record).  A form
 * the screening would have dropped (2x worse there: lambert's cos) is
 * fitted too, and kept only where its headline is lower.  Masked layouts
 * (their fits at R cost seconds, the coarse drop saves one) and measured
 * tables (the warp screening reads the screened candidates) are screened
 * as before. */
static int pair_unscreened(sb_job_t *job) {
    if (job->ncand != 2 || job->is_auto || !job->layout_auto || job->budget || job->o.max_error > 0 ||
        job->o.sample_only || job->scene || (sb_source_flags(job->src) & SB_SOURCE_MEASURED))
        return 0;
    sb_job_candidate_t *a = &job->cands[0], *b = &job->cands[1];
    unsigned caps = sb_param_kind_caps(a->kind);
    if (a->kind != b->kind || a->form == b->form || a->why[0] || b->why[0] || a->dropped || b->dropped ||
        (caps & (SB_CAP_PARTIAL_DOMAIN | SB_CAP_TABLES)))
        return 0;
    for (int k = 0; k < 2; k++) {
        sb_job_candidate_t *c = &job->cands[k];
        c->ok = 1;
        c->res = job->o.res;
        c->error = NAN;
        c->bands_ok = -1;
        c->band_err[0] = c->band_err[1] = NAN;
        job->cand_need[k] = 0;
    }
    return 1;
}

/* The order of pair_unscreened's two forms: cos first, its estimate made
 * whole as fitted (the lean one is that estimate's headlines and bands to
 * the bit: estimate_prefix.lean_equals_whole), so where cos is kept and
 * not refined no estimate is made again (io -r 64: 5 ms, a lean estimate,
 * of about 90); f's estimate lean.  cos was kept on io -r 32 and 64 of
 * the default gold, GGX 0.1 and 0.3, phong:n=100 and blinn-phong:n=200, f
 * on lambert (its exact fit: then 13 ms more). */
static void pair_unscreened_order(const sb_job_t *job, size_t *order) {
    if (job->cands[order[0]].form != SB_FORM_COS) {
        size_t t = order[0];
        order[0] = order[1];
        order[1] = t;
    }
}

/* Fit the candidates in `order` at the requested settings until one
 * succeeds (job->best, marked kept). */
static sb_result_t fit_first(sb_context_t *ctx, sb_job_t *job, const size_t *order, size_t n) {
    sb_result_t r = SB_ERR_NUMERIC;
    for (size_t k = 0; k < n && r != SB_OK; k++) {
        sb_job_candidate_t *c = &job->cands[order[k]];
        double t1 = job_now();
        if ((r = job_fit_kept(ctx, job, c)) != SB_OK) {
            c->ok = 0;
            c->result = r;
            snprintf(c->why, sizeof c->why, "%s", sb_context_last_error(ctx));
        }
        c->kept = r == SB_OK;
        c->time_s += job_now() - t1;
    }
    return r;
}

static int meets_bound(const sb_job_t *job, const job_attempt_t *a, const job_attempt_t *first) {
    (void)first;
    return job_meets_bounded(job, a);
}

static int lower_headline(const sb_job_t *job, const job_attempt_t *a, const job_attempt_t *first) {
    (void)job;
    return job_rank_error(a) < job_rank_error(first);
}

/* Candidate c fitted at the requested settings beside the kept fit
 * (job->best); where wins(job, c's fit, the kept fit) it is kept instead
 * (*won set), else the kept fit stays.  A failure of c's fit is no error
 * but for memory. */
static sb_result_t fit_instead(sb_context_t *ctx, sb_job_t *job, sb_job_candidate_t *c,
                               int (*wins)(const sb_job_t *, const job_attempt_t *, const job_attempt_t *), int *won) {
    job_attempt_t first = job->best;
    memset(&job->best, 0, sizeof job->best);
    double t1 = job_now();
    sb_result_t r = job_fit_kept(ctx, job, c);
    c->time_s += job_now() - t1;
    *won = r == SB_OK && wins(job, &job->best, &first);
    if (*won) {
        for (size_t i = 0; i < job->ncand; i++)
            job->cands[i].kept = 0;
        c->kept = 1;
        job_attempt_free(&first);
        return SB_OK;
    }
    job_attempt_free(&job->best);
    job->best = first;
    sb_context_clear_error(ctx);
    return r == SB_ERR_NOMEM ? r : SB_OK;
}

/* --max-error: the kept fit (order[0]'s or, having failed, a later one's)
 * does not meet it within the band bounds: the next candidates whose
 * screening did (cand_need) are fitted in turn, the first that does kept
 * instead; none: the first fit stays. */
static sb_result_t max_error_next(sb_context_t *ctx, sb_job_t *job, const size_t *order, size_t n) {
    if (job_meets_bounded(job, &job->best)) return SB_OK;
    size_t k = 0;
    while (k < n && !job->cands[order[k]].kept)
        k++;
    sb_result_t r = SB_OK;
    int won = 0;
    for (k++; k < n && r == SB_OK && !won; k++)
        if (job->cand_need[order[k]]) r = fit_instead(ctx, job, &job->cands[order[k]], meets_bound, &won);
    return r;
}

/* A layout named alone whose screening kept two forms (f and cos): the
 * coarse screen can rank them wrongly at the requested R (GGX 0.3 on hd:
 * cos screened first, 0.0517 at R = 32 against f's 0.0220), so the
 * other is fitted too and the lower headline at J kept. */
static sb_result_t named_other_form(sb_context_t *ctx, sb_job_t *job, const size_t *order, size_t n) {
    size_t k = 0;
    while (k < n && !job->cands[order[k]].kept)
        k++;
    if (k + 1 >= n) return SB_OK;
    sb_job_candidate_t *kept = &job->cands[order[k]], *c = &job->cands[order[k + 1]];
    if (c->kind != kept->kind || c->form == kept->form) return SB_OK;
    int won;
    return fit_instead(ctx, job, c, lower_headline, &won);
}

/* One candidate: fit it at the requested settings.  Several: screen them,
 * then fit the best that succeeds at the requested settings (the next on
 * a failure). */
sb_result_t job_select(sb_context_t *ctx, sb_job_t *job) {
    if (job->ncand == 1 && !job->is_auto && !job->layout_auto) {
        sb_job_candidate_t *c = &job->cands[0];
        sb_result_t r;
        if (job->o.sample_only) {
            job_level_t lv = job_full_level(job);
            r = job_sample(ctx, job, &lv, c->kind, c->form, &job->best);
            job->best.weighted = c->weighted;
            return r;
        }
        r = job_fit_kept(ctx, job, c);
        c->ok = r == SB_OK;
        c->error = c->ok ? job_rank_error(&job->best) : NAN;
        c->res = job->o.res;
        return r;
    }
    int unscreened = pair_unscreened(job);
    if (!unscreened) job_screen(ctx, job);
    size_t order[JOB_MAX_CANDS] = {0}, n = job_rank(job, order);
    if (is_named_pair(job, order, n)) {
        if (unscreened) pair_unscreened_order(job, order);
        job->est_lean = 1; /* both forms fitted and refined on lean estimates, the kept one's made whole */
        sb_result_t r = named_pair(ctx, job, order, unscreened);
        job->est_lean = 0;
        if (r == SB_OK && job->best.est_lean) {
            job_level_t lv = job_full_level(job);
            r = job_estimate(ctx, job, &lv, &job->best);
        }
        if (r == SB_OK) job_warn_lost(job);
        return r;
    }
    sb_result_t r = fit_first(ctx, job, order, n);
    if (r == SB_OK && n > 1 && job->o.max_error > 0) {
        r = max_error_next(ctx, job, order, n);
    } else if (r == SB_OK && n > 1 && sb_estimate_bands_bounded(job->best.est, sb_factors_terms(job->best.f)) == 0) {
        /* ranked first for its band bounds, it broke them at the requested
         * settings: the lowest screened headline instead */
        size_t first = n;
        for (size_t k = 0; k < n; k++)
            if (job->cands[order[k]].ok && (first == n || job_ranks_by_error(job, order[k], order[first]))) first = k;
        if (first < n && !job->cands[order[first]].kept) {
            for (size_t k = 0; k < n; k++)
                job->cands[order[k]].kept = 0;
            job_attempt_free(&job->best);
            r = fit_first(ctx, job, order + first, 1);
        }
    }
    if (r == SB_OK && n > 1 && job->layout_auto && !job->budget && !(job->o.max_error > 0))
        r = named_other_form(ctx, job, order, n);
    if (r == SB_OK) {
        job_warn_lost(job);
        return SB_OK;
    }
    /* Out of memory or beyond the size limits anywhere is what the user can
     * act on (exit 2, lower the resolution); anything else is numerical. */
    const char *why = "";
    sb_result_t code = SB_ERR_NUMERIC;
    /* a layout named alone: its last failure, as a run asking for it alone
     * reports it (the context holds its whole message) */
    for (size_t i = job->ncand; job->layout_auto && n == 0 && i-- > 0;)
        if (job->cands[i].result != SB_OK) return job->cands[i].result;
    if (job->layout_auto) return r;
    for (size_t i = 0; i < job->ncand; i++) {
        if (!*why) why = job->cands[i].why;
        if (job->cands[i].result == SB_ERR_NOMEM || job->cands[i].result == SB_ERR_OVERFLOW)
            code = job->cands[i].result;
    }
    return sb_error(ctx, code, "no parameterisation could factor %s%s%s", sb_source_description(job->src),
                    *why ? "; the first failure: " : "", why);
}
