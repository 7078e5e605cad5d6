/* The factor job's candidates: sample, factor and measure one candidate
 * (an attempt), and the cheap screening of --param auto (see job.h);
 * which layouts are candidates: job_candidates.c. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "job_impl.h"
#include "sample/stream.h"
#include "sepbrdf/exr.h"
#include "util/internal.h"

static void sample_progress(void *user, double fraction) {
    const void *const *pp = user; /* {job, level} */
    const sb_job_t *job = pp[0];
    const job_level_t *lv = pp[1];
    job_progress(job, lv->label, lv->base + lv->span * fraction);
}

sb_param_opts_t job_level_opts(const sb_job_t *job, const job_level_t *lv, sb_param_kind_t kind) {
    sb_param_opts_t po = {0};
    if (lv->po) po = *lv->po;
    po.res = lv->res;
    po.theta_max = job->o.theta_max_deg * SB_PI / 180;
    /* iso screens on R rows of theta_h (td = 2R), half its default: the
     * layouts' ranking is the same there, the masked fit half the cost;
     * vh keeps its own th = 2R (at R rows an RGL vinyl's mirror peak fell
     * between texels and it was ranked last: malachite 159 % at R = 16, 23 %
     * with th = 32, 6.3 % kept at R = 32) */
    if (lv->half_shape && (sb_param_kind_caps(kind) & SB_CAP_FOLDS_RECIPROCITY) && !po.res_theta_h) {
        po.res_theta_h = lv->res;
        po.res_theta_d = 2 * lv->res;
    }
    return po;
}

sb_result_t job_sample(sb_context_t *ctx, const sb_job_t *job, const job_level_t *lv, sb_param_kind_t kind,
                       sb_form_t form, job_attempt_t *a) {
    memset(a, 0, sizeof *a);
    sb_param_opts_t po = job_level_opts(job, lv, kind);
    sb_result_t r = sb_param_create(ctx, kind, &po, &a->param);
    if (r != SB_OK) return r;
    size_t rows = sb_param_rows(a->param), cols = sb_param_cols(a->param), mn = rows < cols ? rows : cols;
    if (lv->terms > mn)
        return sb_error(ctx, SB_ERR_RANGE,
                        "%zu terms exceed the %zu rows/columns of %s; ask for fewer terms or more cells", lv->terms, mn,
                        sb_param_spec(a->param));
    double t0 = job_now();
    sb_matrix_opts_t mo = {0};
    mo.form = form;
    mo.channels = job->o.channels;
    mo.structured = 1; /* the distinct values only, where the factor plan reads no more */
    const void *pu[2] = {job, lv};
    if (lv->label && job->o.progress) {
        mo.progress = sample_progress;
        mo.progress_user = (void *)pu;
    }
    r = job->scene ? job_scene_sample(ctx, job, &mo, a) : sb_matrix_build(ctx, job->eval_src, a->param, &mo, &a->m);
    if (r != SB_OK) return r;
    a->t_sample = job_now() - t0;
    return r;
}

/* Cells outside a's domain fitted as zeros: asked for (--zero-fill), or
 * where the form continues by 0 there (SB_CAP_LIGHT_EDGE on the whole
 * hemisphere with a form holding cos theta_i): a plain SVD, exact and
 * fast, instead of the masked fit. */
int job_attempt_zero_fill(const sb_job_t *job, const job_attempt_t *a) {
    if (job->o.zero_fill) return 1;
    int hemisphere = fabs(job->o.theta_max_deg - 90) < 1e-9;
    return a->param && (sb_param_caps(a->param) & SB_CAP_LIGHT_EDGE) && hemisphere && !job->scene &&
           (a->m.form == SB_FORM_COS || a->m.form == SB_FORM_COS2);
}

int job_attempt_masked(const sb_job_t *job, const job_attempt_t *a) {
    return a->m.mask != NULL && !job_attempt_zero_fill(job, a);
}

/* The estimator's errors of a->f as stored (HALF or FLOAT) into a->est,
 * on the job's pairs, growing them up to lv->est_max_pairs. */
static sb_result_t job_estimate(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a) {
    double t0 = job_now();
    sb_estimate_opts_t eo = {0};
    eo.max_pairs = lv->est_max_pairs;
    if (lv->rank_only) { /* screening: ranked on the headline, 16384 pairs */
        eo.headline_only = 1;
        eo.replicates = 4;
        eo.last_only = lv->rank_at_j;
    }
    sb_exr_opts_t xo = {job->o.half};
    sb_factors_t *q = NULL;
    sb_result_t r = SB_OK;
    if (!job->pairs) r = job_pairs_create(ctx, job);
    if (r == SB_OK && !a->est && !(a->est = malloc(sizeof *a->est))) r = sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    /* what a shader reads: the texels as stored */
    if (r == SB_OK) r = sb_factors_quantize(ctx, a->f, &xo, &q, NULL);
    if (r == SB_OK) r = sb_estimate_compute(ctx, job->pairs, q, NULL, a->param, a->m.form, &eo, a->est);
    sb_factors_destroy(q);
    a->est_rank = lv->rank_only;
    a->t_estimate = job_now() - t0;
    job->t_estimate += a->t_estimate;
    return r;
}

/* Factor the sampled a->m with lv->terms terms (replacing a->f), then its
 * estimated errors and, with lv->metric_res, the grid quadrature. */
sb_result_t job_factor(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, int weighted, job_attempt_t *a) {
    sb_factors_destroy(a->f);
    a->f = NULL;
    free(a->term_w);
    a->term_w = NULL;
    a->texel_fit = 0;
    memset(&a->metric, 0, sizeof a->metric);
    memset(&a->stats, 0, sizeof a->stats);
    a->weighted = weighted;
    sb_result_t r = job_scene_prepare(ctx, job, a);
    if (r != SB_OK) return r;
    sb_plan_opts_t pl = {0};
    pl.terms = lv->terms;
    pl.svd.method = job->o.method;
    pl.svd.seed = job->o.seed;
    pl.weighted = weighted;
    pl.zero_fill = job_attempt_zero_fill(job, a);
    pl.fit_tol = lv->fit_tol;
    pl.fit_max_iters = lv->fit_max_iters;
    if (a->scene_w) { /* the scene's weights instead of solid angles */
        pl.weighted = 1;
        pl.row_weights = a->scene_w;
        pl.col_weights = a->scene_w + a->m.rows;
    }
    sb_plan_t *plan = NULL;
    r = sb_plan_create_for(ctx, &a->m, &pl, &plan);
    if (r != SB_OK) return r;
    double t1 = job_now();
    /* a large dense matrix: the BLAS threads the job set aside (job.c) */
    int dense = !a->m.structured && !job_attempt_masked(job, a) && a->m.rows * a->m.cols >= JOB_BLAS_DENSE_CELLS;
    if (dense) sb_blas_threads_end(job->blas_threads);
    r = sb_plan_execute(plan, &a->m, a->param, &a->f);
    if (dense) sb_blas_threads_begin();
    sb_plan_stats(plan, &a->stats);
    sb_plan_destroy(plan);
    if (r != SB_OK) return r;
    double t2 = job_now();
    if (sb_factors_set_meta(a->f, "source", sb_source_description(job->src)) != SB_OK ||
        sb_factors_set_meta(a->f, "source_spec", job->o.source) != SB_OK)
        return sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    a->t_factor = t2 - t1;
    return job_measure(ctx, job, lv, a);
}

sb_result_t job_estimate_reported(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a) {
    if (!a->est || !a->est_rank) return SB_OK;
    job_level_t full = *lv;
    full.rank_only = full.rank_at_j = 0;
    return job_estimate(ctx, job, &full, a);
}

sb_result_t job_estimate_again(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a) {
    job_level_t same = *lv;
    same.est_max_pairs = 1;
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
    double t3 = job_now();
    if ((r = sb_metric_compute(ctx, job->eval_src, a->f, a->param, a->m.form, &mo, &a->metric)) != SB_OK) return r;
    a->t_metric = job_now() - t3;
    return SB_OK;
}

void job_attempt_free(job_attempt_t *a) {
    free(a->est);
    free(a->term_w);
    free(a->scene_w);
    sb_factors_destroy(a->f);
    sb_matrix_free(&a->m);
    sb_param_destroy(a->param);
    memset(a, 0, sizeof *a);
}

/* The error candidates are ranked by: the headline (f cos theta_i as a
 * shader returns it, estimate.h) at the J the attempt kept (the estimate
 * holds SB_EST_MAXJ terms at most: there beyond). */
static double rank_error(const job_attempt_t *a) {
    size_t J = sb_factors_terms(a->f);
    return sb_estimate_headline(a->est, J < a->est->terms ? J : a->est->terms);
}

#define SB_JOB_MEMO_CAP ((size_t)1 << 16)

/* The same layout as `from` (sampled as f, dense) with form `form`: each
 * valid cell times the form weight of its direction pair, as
 * sb_matrix_build applies it, so the source is not evaluated again. */
static sb_result_t job_reform(sb_context_t *ctx, const sb_job_t *job, const job_level_t *lv, const job_attempt_t *from,
                              sb_form_t form, job_attempt_t *a) {
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
    c->error = c->ok ? rank_error(a) : NAN;
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
        int derive = base.param && base.m.form == SB_FORM_F && base.m.phi_period == 0;
        sb_result_t r = screen_one(ctx, job, lv, c, derive ? &base : NULL, &a);
        if (r == SB_OK && !base.param) {
            base = a;
            continue;
        }
        job_attempt_free(&a);
    }
    job_attempt_free(&base);
}

/* The masked fit's early stop (a sweep gaining less than 1e-3 relative, at
 * most 20 per stage: the error on the cells then falls by a few per cent
 * in a run, far below what interpolation between texels adds, and the
 * headline errors of the default gold, GGX, Blinn-Phong and the measured
 * tables came out the same or lower than at 40), unless the caller set its
 * own. */
void job_early_stop(const sb_job_t *job, job_level_t *lv) {
    lv->fit_tol = job->o.fit_tol > 0 ? job->o.fit_tol : 1e-3;
    lv->fit_max_iters = job->o.fit_max_iters > 0 ? job->o.fit_max_iters : 20;
}

/* A screening level: res cells per axis, the same J for every candidate
 * (at most the smallest matrix side there), masked fits stopped early (a
 * sweep gaining less than 1e-3, at most 20: the candidates' errors differ
 * by factors, not digits). */
static job_level_t screen_level(const sb_job_t *job, size_t res, sb_param_opts_t *po) {
    job_level_t lv = {0};
    lv.res = res;
    memset(po, 0, sizeof *po);
    po->res = res;
    po->theta_max = job->o.theta_max_deg * SB_PI / 180;
    lv.half_shape = 1; /* job_level_opts */
    lv.po = po;
    lv.terms = job->o.terms;
    for (size_t i = 0; i < job->ncand; i++) {
        size_t mn = job->cands[i].why[0] ? 0 : job_layout_min_side(job, job->cands[i].kind, lv.res, po);
        if (mn && mn < lv.terms) lv.terms = mn;
    }
    lv.metric_res = 0;    /* no grid quadrature */
    lv.est_max_pairs = 1; /* the estimator's first pairs, no growth */
    lv.rank_only = 1;
    lv.rank_at_j = 1; /* ranked at J (rank_error) */
    job_early_stop(job, &lv);
    return lv;
}

static job_level_t full_level(const sb_job_t *job) {
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

/* Candidates that screened, finest screening first, then by ascending
 * error; returns how many. */
static int ranks_before(const sb_job_candidate_t *a, const sb_job_candidate_t *b) {
    return a->res != b->res ? a->res > b->res : a->error < b->error;
}

static size_t rank(const sb_job_t *job, size_t *order) {
    size_t n = 0;
    for (size_t i = 0; i < job->ncand; i++) {
        if (!job->cands[i].ok) continue;
        size_t k = n++;
        for (; k > 0 && ranks_before(&job->cands[i], &job->cands[order[k - 1]]); k--)
            order[k] = order[k - 1];
        order[k] = i;
    }
    return n;
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

/* A masked fit is a local optimum, and the closest fit to the valid cells
 * is not the best between them: converged to 1e-5 it can carry large
 * cancelling terms in the cells no data constrain, which bilinear lookups
 * near the domain's edge read (the default gold at J = 4: headline 6.7
 * converged, 3.7e-3 stopped early).  An explicit layout also fits the
 * kept matrix with the early stop and keeps that fit when its headline at
 * J is lower than the converged fit's. */
static sb_result_t keep_better_fit(sb_context_t *ctx, sb_job_t *job, const job_level_t *other, job_attempt_t *a);

sb_result_t job_keep_early_fit(sb_context_t *ctx, sb_job_t *job, const job_level_t *full, job_attempt_t *a) {
    job_level_t lv = *full;
    job_early_stop(job, &lv);
    return keep_better_fit(ctx, job, &lv, a);
}

/* a's matrix fitted again on level `lv` (early stop or not); that fit
 * replaces a's when its headline at J is lower. */
static sb_result_t keep_better_fit(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a) {
    job_attempt_t tmp = *a; /* a's matrix and param, fitted again into tmp.f / tmp.est */
    tmp.f = NULL;
    tmp.est = NULL;
    sb_result_t r = job_factor(ctx, job, lv, a->weighted, &tmp);
    if (r == SB_OK && rank_error(&tmp) < rank_error(a)) {
        sb_factors_destroy(a->f);
        free(a->est);
        a->f = tmp.f;
        a->est = tmp.est;
        a->est_rank = tmp.est_rank;
        a->stats = tmp.stats;
        a->metric = tmp.metric;
        a->t_factor += tmp.t_factor;
        return SB_OK;
    }
    sb_factors_destroy(tmp.f);
    free(tmp.est);
    return r == SB_ERR_NUMERIC ? SB_OK : r;
}

/* Sample and factor candidate c at the requested settings into job->best;
 * with max_error, keep the fewest terms whose headline meets it. */
sb_result_t job_fit_kept(sb_context_t *ctx, sb_job_t *job, const sb_job_candidate_t *c) {
    job_level_t lv = full_level(job);
    sb_result_t r = job_sample(ctx, job, &lv, c->kind, c->form, &job->best);
    job_progress(job, lv.label, 1);
    /* masked: auto fits once with the early stop (its screening ranked
     * the candidates with it); an explicit layout fits twice, converged
     * and stopped early, compared on the estimator's pairs so far (no
     * growth), then only the kept one's estimate grows, when needed, to
     * the target standard error */
    int masked = r == SB_OK && job_attempt_masked(job, &job->best);
    int as_auto = job->is_auto || job->fit_as_auto;
    int two = masked && !as_auto;
    if (masked && as_auto) job_early_stop(job, &lv);
    lv.est_max_pairs = two ? 1 : 0;
    lv.rank_only = lv.rank_at_j = two; /* the two fits compared on their headlines at J */
    if (r == SB_OK) r = job_factor(ctx, job, &lv, c->weighted, &job->best);
    if (r == SB_OK && two) r = job_keep_early_fit(ctx, job, &lv, &job->best);
    if (r == SB_OK && masked && as_auto && rank_error(&job->best) > JOB_CONVERGED_TRY) {
        /* auto's early-stopped fit leaves more than JOB_CONVERGED_TRY:
         * the fit to convergence too, the better kept (GGX roughness 0.3,
         * F0 0.04, iso, J = 4: 2.7 % -> 1.9 %) */
        job_level_t conv = full_level(job);
        conv.est_max_pairs = 1;
        conv.rank_only = conv.rank_at_j = 1;
        r = keep_better_fit(ctx, job, &conv, &job->best);
        two = 1; /* the kept one's estimate grows below */
    }
    lv.est_max_pairs = 0;
    lv.rank_only = lv.rank_at_j = 0;
    if (r == SB_OK && two && !job->best.est->converged && !job->best.est_rank)
        r = job_estimate(ctx, job, &lv, &job->best); /* a ranking's estimate is redone in job_refine */
    if (r == SB_OK) r = job_refine(ctx, job, &lv, &job->best);
    if (r == SB_OK && job->o.max_error > 0) {
        size_t keep = sb_factors_terms(job->best.f);
        for (size_t k = keep; k >= 1; k--)
            if (sb_estimate_headline(job->best.est, k) <= job->o.max_error) keep = k;
        r = job_truncate(ctx, &job->best, keep);
    }
    if (r != SB_OK) job_attempt_free(&job->best);
    return r;
}

/* Screen at SB_JOB_SCREEN_COARSE cells per axis, drop the candidates more
 * than SB_JOB_SCREEN_DROP times worse than the best (they cannot win: the
 * errors of one layout at two resolutions differ far less than that), and
 * screen the others again at SB_JOB_SCREEN_RES (each at most R), unless
 * only one is left. */
static void screen(sb_context_t *ctx, sb_job_t *job) {
    static const size_t levels[2] = {SB_JOB_SCREEN_COARSE, SB_JOB_SCREEN_RES};
    size_t prev = 0;
    for (int s = 0; s < 2; s++) {
        size_t res = levels[s] < job->o.res ? levels[s] : job->o.res;
        if (res == prev) break;
        prev = res;
        sb_param_opts_t po;
        job_level_t lv = screen_level(job, res, &po);
        for (int k = 0; k < SB_PARAM_KIND_COUNT_; k++) {
            job_progress(job, "screening", (s + (double)k / SB_PARAM_KIND_COUNT_) / 2);
            screen_layout(ctx, job, &lv, (sb_param_kind_t)k, job->cands, job->ncand);
        }
        double best = INFINITY;
        for (size_t i = 0; i < job->ncand; i++)
            if (job->cands[i].ok && job->cands[i].error < best) best = job->cands[i].error;
        size_t live = 0;
        for (size_t i = 0; i < job->ncand; i++) {
            if (job->cands[i].ok && job->cands[i].error > SB_JOB_SCREEN_DROP * best) job->cands[i].dropped = 1;
            live += job->cands[i].ok && !job->cands[i].dropped;
        }
        if (live <= 1) break; /* nothing left to rank */
    }
    job_progress(job, "screening", 1);
}

void job_screen(sb_context_t *ctx, sb_job_t *job) {
    double t0 = job_now();
    /* a measured table: the screening grids and the reference grid of the
     * candidates' errors repeat pairs, each an interpolation */
    sb_source_t *memo = NULL;
    if ((sb_source_flags(job->src) & SB_SOURCE_MEASURED) &&
        job_memo_create(ctx, job->src, SB_JOB_MEMO_CAP, &memo) == SB_OK)
        job->eval_src = memo;
    screen(ctx, job);
    job->eval_src = job->src;
    sb_source_destroy(memo);
    job->t.screen_s = job_now() - t0;
}

/* One candidate: fit it at the requested settings.  Several: screen them,
 * then fit the best that succeeds at the requested settings (the next on
 * a failure). */
sb_result_t job_select(sb_context_t *ctx, sb_job_t *job) {
    if (job->ncand == 1 && !job->is_auto) {
        sb_job_candidate_t *c = &job->cands[0];
        sb_result_t r;
        if (job->o.sample_only) {
            job_level_t lv = full_level(job);
            r = job_sample(ctx, job, &lv, c->kind, c->form, &job->best);
            job->best.weighted = c->weighted;
            return r;
        }
        r = job_fit_kept(ctx, job, c);
        c->ok = r == SB_OK;
        c->error = c->ok ? rank_error(&job->best) : NAN;
        c->res = job->o.res;
        return r;
    }
    job_screen(ctx, job);
    size_t order[JOB_MAX_CANDS], n = rank(job, order);
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
    if (r == SB_OK) {
        job_warn_lost(job);
        return SB_OK;
    }
    /* Out of memory or beyond the size limits anywhere is what the user can
     * act on (exit 2, lower the resolution); anything else is numerical. */
    const char *why = "";
    sb_result_t code = SB_ERR_NUMERIC;
    for (size_t i = 0; i < job->ncand; i++) {
        if (!*why) why = job->cands[i].why;
        if (job->cands[i].result == SB_ERR_NOMEM || job->cands[i].result == SB_ERR_OVERFLOW)
            code = job->cands[i].result;
    }
    return sb_error(ctx, code, "no parameterisation could factor %s%s%s", sb_source_description(job->src),
                    *why ? "; the first failure: " : "", why);
}
