/* The factor job's candidates: the cheap screening of --param auto (see
 * job.h) and the fit of the kept one, from the attempts of job_attempt.c;
 * which layouts are candidates: job_candidates.c. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "job_impl.h"
#include "sample/stream.h"
#include "sepbrdf/exr.h"
#include "solve/solver.h"
#include "util/internal.h"

/* Whether the attempt keeps the band bounds at its J (estimate.h). */
static int rank_bands(const job_attempt_t *a) {
    size_t J = sb_factors_terms(a->f);
    return sb_estimate_bands_bounded(a->est, J < a->est->terms ? J : a->est->terms);
}

/* The same layout as `from` (sampled as f, dense) with form `form`: each
 * valid cell times the form weight of its direction pair, as
 * sb_matrix_build applies it, so the source is not evaluated again. */
static sb_result_t job_reform(sb_context_t *ctx, const sb_job_t *job, const job_level_t *lv, const job_attempt_t *from,
                              sb_form_t form, job_attempt_t *a) {
    /* a layout that knows its cells (sb_param_cell_value) samples them again: cheap, and exact where the
     * light is below the horizon */
    if (sb_param_caps(from->param) & SB_CAP_TABLES)
        return job_sample(ctx, job, lv, sb_param_kind(from->param), form, a);
    memset(a, 0, sizeof *a);
    double t0 = job_now();
    sb_param_opts_t po = job_level_opts(job, lv, sb_param_kind(from->param)); /* as job_sample made `from` */
    sb_result_t r = sb_param_create(ctx, sb_param_kind(from->param), &po, &a->param);
    if (r != SB_OK) return r;
    const sb_matrix_t *f = &from->m;
    sb_matrix_t *m = &a->m;
    *m = *f;
    m->form = form;
    m->mask = NULL;
    memset(m->data, 0, sizeof m->data);
    size_t cells = f->ld * f->cols;
    if (f->mask && !(m->mask = sb_alloc(ctx, cells, 1, "matrix mask"))) return SB_ERR_NOMEM;
    if (f->mask) memcpy(m->mask, f->mask, cells);
    for (int c = 0; c < 3; c++)
        if (f->data[c] && !(m->data[c] = sb_alloc(ctx, cells, sizeof(double), "matrix"))) return SB_ERR_NOMEM;
    double wi[3], wo[3];
    for (size_t col = 0; col < f->cols; col++)
        for (size_t row = 0; row < f->rows; row++) {
            size_t at = row + col * f->ld;
            double w = sb_param_cell_dirs(a->param, row, col, wi, wo) ? sb_form_weight(form, wi, wo) : 0;
            for (int c = 0; c < 3; c++)
                if (f->data[c]) m->data[c][at] = f->data[c][at] * w;
        }
    a->t_sample = job_now() - t0;
    return SB_OK;
}

/* Sample candidate c on level lv (or derive it from `from`, its layout
 * sampled as f) and factor it; the outcome is recorded in c. */
static sb_result_t screen_one(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, sb_job_candidate_t *c,
                              const job_attempt_t *from, job_attempt_t *a) {
    double t0 = job_now();
    sb_result_t r = from ? job_reform(ctx, job, lv, from, c->form, a) : job_sample(ctx, job, lv, c->kind, c->form, a);
    if (r == SB_OK) r = job_factor(ctx, job, lv, c->weighted, a);
    c->ok = r == SB_OK;
    size_t i = (size_t)(c - job->cands), J = c->ok && a->est ? sb_factors_terms(a->f) : 0;
    size_t full = job_layout_min_side(job, c->kind, job->o.res, NULL);
    job->cand_terms[i] = job_terms_capped(job, c->kind) && full < job->o.terms ? full : job->o.terms;
    job->cand_need[i] = 0; /* --max-error: the fewest terms meeting it within the band bounds */
    for (size_t k = J && J > a->est->terms ? a->est->terms : J; job->o.max_error > 0 && k >= 1; k--)
        if (sb_estimate_headline(a->est, k) <= job->o.max_error && sb_estimate_bands_bounded(a->est, k) == 1)
            job->cand_need[i] = k;
    c->error = c->ok ? job_rank_error(a) : NAN;
    c->bands_ok = c->ok ? rank_bands(a) : -1;
    job_band_errors(c->ok ? a->est : NULL, sb_factors_terms(a->f), c->band_err);
    c->res = lv->res;
    c->result = r;
    if (!c->ok) snprintf(c->why, sizeof c->why, "%s", sb_context_last_error(ctx));
    c->time_s += job_now() - t0;
    return r;
}

/* Screen the live candidates of one layout: the first sampled (as f,
 * when it is one of them), the others derived from its matrix when it is
 * dense (a structured one is cheap to sample again). */
static void screen_layout(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, sb_param_kind_t kind,
                          sb_job_candidate_t *cands, size_t n) {
    job_attempt_t base = {0}, a;
    for (size_t i = 0; i < n; i++) {
        sb_job_candidate_t *c = &cands[i];
        if (c->kind != kind || c->why[0] || c->dropped) continue;
        /* not from a streamed matrix: it holds no values, only its directions (freed with it) */
        int derive = base.param && base.m.form == SB_FORM_F && base.m.phi_period == 0 && !base.m.streamed;
        sb_result_t r = screen_one(ctx, job, lv, c, derive ? &base : NULL, &a);
        if (r == SB_OK && !base.param) {
            base = a;
            continue;
        }
        job_attempt_free(&a);
    }
    job_attempt_free(&base);
}

job_level_t job_full_level(const sb_job_t *job) {
    job_level_t lv = {.res = job->o.res,
                      .terms = job->o.terms,
                      .metric_res = job->o.metric_res,
                      .fit_tol = job->o.fit_tol,
                      .fit_max_iters = job->o.fit_max_iters,
                      .po = job->shape,
                      .label = "sampling",
                      .span = 1};
    return lv;
}

/* The largest over J' of a's headline over the SVD beside's, pooled
 * (ratio) and of each channel (rch, channel c's at c J); NAN: none. */
static double nonneg_worst(const sb_job_t *job, const job_attempt_t *a, double *ratio, double *rch) {
    size_t J = sb_factors_terms(a->f);
    double worst = NAN;
    for (size_t k = 1; k <= J && a->est && k <= a->est->terms; k++) {
        ratio[k - 1] = sb_estimate_headline(a->est, k) / sb_job_svd_headline(job, k);
        worst = k == 1 || ratio[k - 1] > worst ? ratio[k - 1] : worst;
        for (int c = 0; c < 3; c++) {
            rch[(size_t)c * J + k - 1] = a->est->rel[k - 1][SB_EST_FCOS][c] / job_svd_headline_channel(job, k, c);
            worst = fmax(worst, rch[(size_t)c * J + k - 1]); /* NAN (no such channel) is skipped */
        }
    }
    return worst;
}

/* The largest of the pooled and channels' ratios at J (nonneg_worst). */
static double nonneg_last(const double *ratio, const double *rch, size_t J) {
    return fmax(ratio[J - 1], fmax(rch[J - 1], fmax(rch[2 * J - 1], rch[3 * J - 1])));
}

/* Refits of job_nonneg_refit, each from the ratios of the one before (the
 * plan's nonneg_rounds, its corrections moved partway: nmf_mixes.c damp):
 * RGL chm_orange on vndf, J = 4, worst channel 2.08 -> 1.93x the SVD's; a
 * third refit's was never kept (its last prefix above 1.5x, or not lower;
 * round h38v, docs/positive.md). */
#define JOB_NONNEG_REFITS 2

int job_nonneg_same_check = 1;

/* Whether a and b hold the same terms, bit for bit: sizes, sigmas and
 * texels (a channel not factored: no texels in both). */
static int factors_same(const sb_factors_t *a, const sb_factors_t *b) {
    size_t J = sb_factors_terms(a), C = sb_factors_channels(a), w[2][2], h[2][2];
    if (J != sb_factors_terms(b) || C != sb_factors_channels(b)) return 0;
    for (int s = 0; s < 2; s++) {
        sb_factors_size(a, s, &w[0][s], &h[0][s]);
        sb_factors_size(b, s, &w[1][s], &h[1][s]);
        if (w[0][s] != w[1][s] || h[0][s] != h[1][s]) return 0;
    }
    for (size_t j = 0; j < J; j++)
        for (size_t c = 0; c < C; c++) {
            double sa = sb_factors_sigma(a, j, c), sb = sb_factors_sigma(b, j, c);
            if (memcmp(&sa, &sb, sizeof sa) != 0) return 0;
            for (int s = 0; s < 2; s++) {
                const double *ta = sb_factors_tex_const(a, s, j, c), *tb = sb_factors_tex_const(b, s, j, c);
                if ((ta == NULL) != (tb == NULL) || (ta && memcmp(ta, tb, w[0][s] * h[0][s] * sizeof *ta) != 0))
                    return 0;
            }
        }
    return 1;
}

/* The kept fit a made again (a's matrix and layout, as job_fit_kept made
 * it) toward `rounds` rounds of the headline's ratios ratio, rch (the
 * plan's nonneg_rounds: round k's those of the fit round k - 1 gave, round
 * 0's a's), and refined, into t.  The solver keeps its state after the
 * rounds in the job's carry and starts from what it holds of the rounds
 * before (solve/solver.h sb_nmf_carry_t): refit k's first k - 1 rounds
 * are refit k - 1's, bit for bit (a's matrix is the kept refit's: the
 * same cells).  With `raw`, t's factors as fitted (before the refinement)
 * are copied there.  With `prev` (the refit before, as fitted, whose
 * refinement left the pairs as they were), t is first measured as a
 * ranking is (4 replicates, no growth): where its factors are prev's bit
 * for bit, so would be its estimate and refinement (the same pairs, the
 * same steps) and so its ratios, which did not beat the kept fit's or
 * are the kept fit's; then *same is set, t is left unrefined and not
 * kept (RGL paper_white: the second refit's round moved nothing).  Else
 * job_refine measures it in full, as job_measure would have. */
static sb_result_t nonneg_refit_once(sb_context_t *ctx, sb_job_t *job, const job_attempt_t *a, const double *ratio,
                                     const double *rch, size_t rounds, const sb_factors_t *prev, sb_factors_t **raw,
                                     job_attempt_t *t, int *same) {
    job_level_t lv = job_full_level(job);
    lv.nonneg_ratio = ratio;
    lv.nonneg_ratio_channel = rch;
    lv.nonneg_rounds = rounds;
    if (!job_nonneg_same_check) prev = NULL;
    lv.rank_only = prev != NULL;
    *t = *a;
    t->f = NULL, t->est = NULL, t->term_w = NULL;
    *same = 0;
    sb_result_t r = job_factor(ctx, job, &lv, a->weighted, t);
    lv.nonneg_ratio = lv.nonneg_ratio_channel = NULL;
    lv.nonneg_rounds = 0;
    lv.rank_only = 0;
    if (r == SB_OK && prev && factors_same(t->f, prev)) {
        *same = 1;
        return SB_OK;
    }
    size_t pairs = job->pairs ? sb_pairs_count(job->pairs) : 0;
    if (raw) sb_factors_destroy(*raw), *raw = NULL;
    if (r == SB_OK && raw) r = job_factors_copy(ctx, t->f, sb_factors_terms(t->f), raw);
    if (r == SB_OK) r = job_refine(ctx, job, &lv, t);
    if (raw && *raw && (!job->pairs || sb_pairs_count(job->pairs) != pairs)) { /* grown: the next is measured apart */
        sb_factors_destroy(*raw);
        *raw = NULL;
    }
    return r;
}

static void nonneg_free(job_attempt_t *t) {
    sb_factors_destroy(t->f);
    free(t->est);
    free(t->term_w);
    t->f = NULL, t->est = NULL, t->term_w = NULL;
}

/* Each channel is refitted toward its own ratios (the plan's
 * nonneg_ratio_channel) and the fit kept by the worst of the pooled and
 * the channels' ratios: RGL cc_green_malachite on vndf, J = 4, the pooled
 * ratios alone left red and blue at 1.81 and 2.40x the SVD's at J' = 4
 * with the pooled 1.56 (round h32n, docs/positive.md).  Then again from
 * each refit's own ratios (the correction is accurate near the fit it was
 * taken from), JOB_NONNEG_REFITS in all. */
sb_result_t job_nonneg_refit(sb_context_t *ctx, sb_job_t *job) {
    job_attempt_t *a = &job->best;
    size_t J = sb_factors_terms(a->f);
    double ratio[SB_EST_MAXJ], rch[3 * SB_EST_MAXJ];
    if (!job->svd_beside || job->o.max_error > 0 || job->budget || job->scene || J > SB_EST_MAXJ || !a->est ||
        a->est->terms < J)
        return SB_OK;
    /* masked layouts (iso, hd): the solver's measure of the prefixes is
     * close to the headline's (the default gold: 1.65 against 1.66 at J'
     * = 1) and the refit moved nothing (1.656 -> 1.661, not kept) */
    size_t mn = a->m.rows < a->m.cols ? a->m.rows : a->m.cols; /* the solver's reference: 2 J <= mn (nmf_mixes.c) */
    double worst = nonneg_worst(job, a, ratio, rch);
    if (job_attempt_masked(job, a) || 2 * J > mn || !(worst > JOB_NONNEG_RATIO)) return SB_OK;
    double last = fmax(nonneg_last(ratio, rch, J), JOB_NONNEG_RATIO);
    double rho[JOB_NONNEG_REFITS * SB_EST_MAXJ], rho_ch[JOB_NONNEG_REFITS * 3 * SB_EST_MAXJ];
    memcpy(rho, ratio, J * sizeof *rho);
    memcpy(rho_ch, rch, 3 * J * sizeof *rho_ch);
    sb_result_t r = SB_OK;
    sb_factors_t *raw = NULL; /* the refit before the last, as fitted, where its refinement grew no pairs */
    for (size_t k = 1; k <= JOB_NONNEG_REFITS; k++) {
        job_attempt_t t;
        int last_one = k == JOB_NONNEG_REFITS, same = 0;
        r = nonneg_refit_once(ctx, job, a, rho, rho_ch, k, last_one ? raw : NULL, last_one ? NULL : &raw, &t, &same);
        job->nonneg_same = same;
        if (r != SB_OK || same) {
            nonneg_free(&t);
            break;
        }
        /* kept where its worst prefix is lower and its last, the fit a run
         * of J terms renders, not above the bound (or a's, if that is above) */
        double *nr = rho + k * J, *nc = rho_ch + k * 3 * J; /* its ratios: the next round's */
        double w = k < JOB_NONNEG_REFITS ? nonneg_worst(job, &t, nr, nc) : nonneg_worst(job, &t, ratio, rch);
        double l = k < JOB_NONNEG_REFITS ? nonneg_last(nr, nc, J) : nonneg_last(ratio, rch, J);
        if (w < worst && !(l > last)) {
            nonneg_free(a);
            t.t_factor += a->t_factor;
            *a = t;
            worst = w;
        } else
            nonneg_free(&t);
    }
    sb_factors_destroy(raw);
    sb_nmf_carry_destroy(job->nonneg_carry); /* no fit after the refits is made twice */
    job->nonneg_carry = NULL;
    return r == SB_ERR_NUMERIC ? SB_OK : r;
}

int job_meets_bounded(const sb_job_t *job, const job_attempt_t *a) {
    size_t J = sb_factors_terms(a->f);
    J = J < a->est->terms ? J : a->est->terms;
    return sb_estimate_headline(a->est, J) <= job->o.max_error && sb_estimate_bands_bounded(a->est, J) == 1;
}

/* Whether the kept fit a, stopped early, leaves so much (twice
 * JOB_WARP_TRY at J, within the band bounds) that job_warp_refit will try
 * warps on it: its converged fit and refinement are then left until the
 * warped fit is known (job_fit_finish), since a warped fit that is better
 * replaces it whole (the Cornell acrylic: 0.24 unwarped, 0.020 warped;
 * the skipped work was a fifth of the default run's CPU). */
static int warp_first(const sb_job_t *job, const job_attempt_t *a) {
    size_t J = sb_factors_terms(a->f);
    J = J < a->est->terms ? J : a->est->terms;
    return !job->o.warp && !job->o.sample_only && !job->budget && !job->scene && !(job->o.max_error > 0) &&
           job->shape != &job->spec_shape && (sb_param_caps(a->param) & SB_CAP_WARPS) &&
           job_rank_error(a) > 2 * JOB_WARP_TRY && sb_estimate_bands_bounded(a->est, J) == 1;
}

/* warp_first on a measured table's candidate c as screened (at
 * SB_JOB_SCREEN_RES, below the requested resolution), with the fit auto
 * makes (early stop, then the converged fit): the warped layout is
 * screened beside it (job_warp_screen) and, when it wins there, fitted at
 * the requested settings instead, the unwarped fit never made (its
 * sampling and fit a fifth of a MERL file's default run).  Not on an
 * analytic source: GGX roughness 0.1 screened on iso at 16 leaves 0.22,
 * fitted at 32 0.012, where warps are not tried (a screened gain of 19x;
 * on the measured tables 2.2x at most). */
static int warp_screen_first(const sb_job_t *job, const sb_job_candidate_t *c) {
    size_t res = SB_JOB_SCREEN_RES < job->o.res ? SB_JOB_SCREEN_RES : job->o.res;
    int as_auto = job->is_auto || job->fit_as_auto, nonneg = job_nonneg_method(sb_method_name(job->o.method));
    return as_auto && !nonneg && (sb_source_flags(job->src) & SB_SOURCE_MEASURED) && c->ok && c->res == res &&
           res < job->o.res && c->bands_ok == 1 && !job->o.warp && !job->o.sample_only && !job->budget && !job->scene &&
           !(job->o.max_error > 0) && job->shape != &job->spec_shape && (sb_param_kind_caps(c->kind) & SB_CAP_WARPS) &&
           c->error > 2 * JOB_WARP_TRY;
}

static sb_result_t fit_warped(sb_context_t *ctx, sb_job_t *job, const sb_job_candidate_t *c) {
    job_level_t lv = job_full_level(job);
    sb_param_opts_t po = job_level_opts(job, &lv, c->kind); /* the unwarped layout job_sample would make */
    sb_param_t *like = NULL;
    sb_result_t r = sb_param_create(ctx, c->kind, &po, &like);
    memset(&job->best, 0, sizeof job->best);
    if (r == SB_OK) r = job_warp_fit(ctx, job, "auto", like, c->form, c->weighted, &job->best);
    sb_param_destroy(like);
    job->warp_screened = r == SB_OK;
    if (r != SB_OK) job_attempt_free(&job->best);
    return r;
}

sb_result_t job_fit_kept_unfinished(sb_context_t *ctx, sb_job_t *job, const sb_job_candidate_t *c, int *unfinished) {
    job_level_t lv = job_full_level(job);
    if (unfinished) *unfinished = 0;
    job->fit_pending = 0;
    job->warp_screened = 0;
    if (warp_screen_first(job, c) && job_warp_screen(ctx, job, c)) {
        sb_result_t w = fit_warped(ctx, job, c);
        if (w == SB_OK || w == SB_ERR_NOMEM) return w; /* a numerical failure: the unwarped fit as before */
    }
    sb_result_t r = job_sample(ctx, job, &lv, c->kind, c->form, &job->best);
    job_progress(job, lv.label, 1);
    /* masked: auto fits once with the early stop (its screening ranked
     * the candidates with it); an explicit layout fits twice, converged
     * and stopped early, compared on the estimator's pairs so far (no
     * growth), then only the kept one's estimate grows, when needed, to
     * the target standard error */
    int masked = r == SB_OK && job_attempt_masked(job, &job->best);
    /* non-negative factors: one fit, the masked fit beside it (their
     * targets out of the data) stopped early as auto's: the second fit
     * moved nmf_over_svd by at most 0.01 (GGX 0.1 and 0.3 on iso and hd,
     * 32 cells, J = 4) and cost half the time */
    int nonneg = job_nonneg_method(sb_method_name(job->o.method));
    int as_auto = job->is_auto || job->fit_as_auto || nonneg;
    int two = masked && !as_auto;
    if (masked && as_auto) job_early_stop(job, &lv);
    lv.est_max_pairs = two ? 1 : 0;
    lv.rank_only = lv.rank_at_j = two; /* the two fits compared on their headlines at J */
    if (r == SB_OK) r = job_factor(ctx, job, &lv, c->weighted, &job->best);
    if (r == SB_OK && two) r = job_keep_early_fit(ctx, job, &lv, &job->best);
    job->fit_pending = (masked && as_auto ? FINISH_EARLY : 0) | (masked && as_auto && !nonneg ? FINISH_CONVERGED : 0) |
                       (two ? FINISH_TWO : 0);
    if (r == SB_OK && (job->fit_pending & FINISH_CONVERGED) && warp_first(job, &job->best)) {
        job->fit_pending |= FINISH_PENDING; /* job_fit_finish, when the warped fit does not replace it */
        return SB_OK;
    }
    if (r == SB_OK && unfinished) {
        *unfinished = 1;
        return SB_OK;
    }
    if (r == SB_OK) r = job_fit_finish(ctx, job);
    if (r != SB_OK) job_attempt_free(&job->best);
    return r;
}

/* Sample and factor candidate c at the requested settings into job->best;
 * with max_error, keep the fewest terms whose headline meets it. */
sb_result_t job_fit_kept(sb_context_t *ctx, sb_job_t *job, const sb_job_candidate_t *c) {
    return job_fit_kept_unfinished(ctx, job, c, NULL);
}

sb_result_t job_fit_finish(sb_context_t *ctx, sb_job_t *job) {
    job_level_t lv = job_full_level(job);
    sb_result_t r = SB_OK;
    unsigned f = job->fit_pending;
    int two = (f & FINISH_TWO) != 0;
    job->fit_pending = 0;
    if ((f & FINISH_CONVERGED) && job_rank_error(&job->best) > JOB_CONVERGED_TRY) {
        /* auto's early-stopped fit leaves more than JOB_CONVERGED_TRY:
         * the fit to convergence too, the better kept (GGX roughness 0.3,
         * F0 0.04, iso, J = 4: 2.7 % -> 1.9 %) */
        job_level_t conv = job_full_level(job);
        conv.est_max_pairs = 1;
        conv.rank_only = conv.rank_at_j = 1;
        r = job_keep_better_fit(ctx, job, &conv, &job->best);
        two = 1; /* the kept one's estimate grows below */
    }
    if (f & FINISH_EARLY) job_early_stop(job, &lv); /* as the fit was made */
    if (r == SB_OK && two && !job->best.est->converged && !job->best.est_rank)
        r = job_estimate(ctx, job, &lv, &job->best); /* a ranking's estimate is redone in job_refine */
    if (r == SB_OK) r = job_refine(ctx, job, &lv, &job->best);
    if (r == SB_OK && job->o.max_error > 0) r = job_keep_fewest(ctx, job, &lv, &job->best);
    return r;
}

/* The best screened error that candidate i is dropped against: of all,
 * or of those keeping the band bounds when i keeps them (each against the
 * best of its own kind), among those fitted with as many terms at the
 * requested settings (with --max-error, vndf's 8 rows drop no layout that
 * may meet it with more terms). */
static double screen_best(const sb_job_t *job, size_t i) {
    const sb_job_candidate_t *c = &job->cands[i];
    double best = INFINITY;
    for (size_t k = 0; k < job->ncand; k++) {
        const sb_job_candidate_t *o = &job->cands[k];
        if (o->ok && (c->bands_ok != 1 || o->bands_ok == 1) && job->cand_terms[k] == job->cand_terms[i])
            best = fmin(best, o->error);
    }
    return best;
}

/* Screen at SB_JOB_SCREEN_COARSE cells per axis, drop the candidates more
 * than SB_JOB_SCREEN_DROP times worse than the best (they cannot win: the
 * errors of one layout at two resolutions differ far less than that), and
 * screen the others again at SB_JOB_SCREEN_RES (each at most R), unless
 * only one is left. */
/* A layout on the source's own tables (vndf) that returns the source to
 * float rounding at J, keeping the band bounds, cannot be beaten: the
 * other candidates are not screened (an RGL file at J >= its slices). */
static int own_tables_exact(sb_job_t *job) {
    const sb_job_candidate_t *best = NULL;
    for (size_t i = 0; i < job->ncand; i++) {
        const sb_job_candidate_t *c = &job->cands[i];
        if (c->ok && c->bands_ok == 1 && c->error <= SB_JOB_SCREEN_EXACT &&
            (sb_param_kind_caps(c->kind) & SB_CAP_TABLES))
            best = c;
    }
    if (!best) return 0;
    for (size_t i = 0; i < job->ncand; i++) {
        sb_job_candidate_t *c = &job->cands[i];
        if (c->ok || c->why[0]) continue;
        snprintf(c->why, sizeof c->why, "not screened: %s %s returns the file's own nodes at J (headline %.2g)",
                 sb_param_kind_name(best->kind), sb_form_name(best->form), best->error);
        c->dropped = 1;
    }
    return 1;
}

static void screen(sb_context_t *ctx, sb_job_t *job) {
    static const size_t levels[2] = {SB_JOB_SCREEN_COARSE, SB_JOB_SCREEN_RES};
    size_t prev = 0;
    for (int s = 0; s < 2; s++) {
        size_t res = levels[s] < job->o.res ? levels[s] : job->o.res;
        if (res == prev) break;
        prev = res;
        sb_param_opts_t po;
        job_level_t lv = job_screen_level(job, res, &po);
        /* non-negative: a masked candidate ranked by the solver's first
         * fit (docs/positive.md, round h38y: the default gold's hd f and
         * cos 0.1464, 0.1621 -> 0.1458, 0.1602, iso kept as before; 6 %
         * of the run's CPU) */
        lv.nonneg_first_fit = 1;
        /* the layouts on the source's own tables first: they may end it */
        for (int pass = 0; pass < 2; pass++) {
            if (pass == 1 && s == 0 && own_tables_exact(job)) break;
            for (int k = 0; k < (int)sb_param_kind_count(); k++) {
                if (((sb_param_kind_caps((sb_param_kind_t)k) & SB_CAP_TABLES) != 0) != (pass == 0)) continue;
                job_progress(job, "screening", (s + (double)k / (double)sb_param_kind_count()) / 2);
                screen_layout(ctx, job, &lv, (sb_param_kind_t)k, job->cands, job->ncand);
            }
        }
        size_t live = 0;
        for (size_t i = 0; i < job->ncand; i++) {
            sb_job_candidate_t *c = &job->cands[i];
            if (c->ok && c->error > SB_JOB_SCREEN_DROP * screen_best(job, i)) c->dropped = 1;
            live += c->ok && !c->dropped;
        }
        if (live <= 1) break; /* nothing left to rank */
    }
    job_progress(job, "screening", 1);
}

/* A measured table's repeated pairs are met by its own memo (values by
 * embedded position, scattered_fit.c); a second memo by direction pair
 * here answered none of the acrylic's, ALTA's, RGL's or a MERL file's
 * 7 500-119 000 screening evaluations (issue 32 item 5). */
void job_screen(sb_context_t *ctx, sb_job_t *job) {
    double t0 = job_now();
    screen(ctx, job);
    job->t.screen_s = job_now() - t0;
}
