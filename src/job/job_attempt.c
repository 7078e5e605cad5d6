/* The factor job's attempts: sample and factor one candidate (a layout,
 * form and weighting on one level); job_measure.c measures it.  Below the
 * stages that refine, screen and select attempts (job_bandfit.c,
 * job_texels.c, job_weights.c, job_screen.c). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "factor/plan_conv.h"
#include "job_impl.h"
#include "param/serial.h"
#include "sample/edge.h"
#include "sample/stream.h"
#include "sepbrdf/exr.h"
#include "solve/solver.h"
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
    po.plain = job->o.plain_terms;                 /* the plain truncated SVD: no clamp at 0 */
    po.tables = sb_source_layout_tables(job->src); /* layouts built on the source's tables (vndf) */
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

/* The error candidates are ranked by: the headline (f cos theta_i as a
 * shader returns it, estimate.h) at the J the attempt kept (the estimate
 * holds SB_EST_MAXJ terms at most: there beyond). */
double job_rank_error(const job_attempt_t *a) {
    size_t J = sb_factors_terms(a->f);
    return sb_estimate_headline(a->est, J < a->est->terms ? J : a->est->terms);
}

int job_terms_capped(const sb_job_t *job, sb_param_kind_t k) {
    return job->o.max_error > 0 || (job->is_auto && !job->budget && (sb_param_kind_caps(k) & SB_CAP_TABLES));
}

size_t job_level_terms(const sb_job_t *job, const job_level_t *lv, sb_param_kind_t kind, size_t mn) {
    return job_terms_capped(job, kind) && lv->terms > mn ? mn : lv->terms;
}

/* The matrix of job_sample (no scene): the form shared by the one
 * sampled before it (job->form_share), else built, with the shared form
 * too where it is wanted. */
static sb_result_t job_build(sb_context_t *ctx, const sb_job_t *job, const sb_param_t *param,
                             const sb_matrix_opts_t *mo, sb_matrix_t *m) {
    job_form_share_t *s = job->form_share;
    int plain = s && !mo->stream && mo->structured && !mo->only;
    if (plain && s->m.rows && s->form == mo->form && s->src == job->src && s->channels == mo->channels &&
        s->serial == sb_param_serial_(param) && s->m.rows == sb_param_rows(param)) {
        *m = s->m; /* the same bits as its own build (sb_matrix_build_two) */
        memset(&s->m, 0, sizeof s->m);
        if (mo->progress) mo->progress(mo->progress_user, 1.0);
        return SB_OK;
    }
    if (!plain || !s->want || s->form == mo->form) return sb_matrix_build(ctx, job->src, param, mo, m);
    s->want = 0;
    sb_matrix_free(&s->m);
    s->src = job->src;
    s->serial = sb_param_serial_(param);
    s->channels = mo->channels;
    return sb_matrix_build_two(ctx, job->src, param, mo, s->form, &s->m, m);
}

sb_result_t job_sample(sb_context_t *ctx, const sb_job_t *job, const job_level_t *lv, sb_param_kind_t kind,
                       sb_form_t form, job_attempt_t *a) {
    memset(a, 0, sizeof *a);
    sb_param_opts_t po = job_level_opts(job, lv, kind);
    sb_result_t r = sb_param_create(ctx, kind, &po, &a->param);
    if (r != SB_OK) return r;
    size_t rows = sb_param_rows(a->param), cols = sb_param_cols(a->param), mn = rows < cols ? rows : cols;
    if (job_level_terms(job, lv, kind, mn) > mn)
        return sb_error(ctx, SB_ERR_RANGE,
                        "%zu terms exceed the %zu rows/columns of %s; ask for fewer terms or more cells", lv->terms, mn,
                        sb_param_spec(a->param));
    double t0 = job_now();
    sb_matrix_opts_t mo = {0};
    mo.form = form;
    mo.channels = job->o.channels;
    mo.structured = 1;                             /* the distinct values only, where the factor plan reads no more */
    mo.stream = job->o.method == SB_METHOD_STREAM; /* never stored: a working set bounded by the memory limit */
    const void *pu[2] = {job, lv};
    if (lv->label && job->o.progress) {
        mo.progress = sample_progress;
        mo.progress_user = (void *)pu;
    }
    r = job->scene ? job_scene_sample(ctx, job, &mo, a) : job_build(ctx, job, a->param, &mo, &a->m);
    if (r != SB_OK) return r;
    /* the zero fill of SB_CAP_LIGHT_EDGE, SB_CAP_VIEW_EDGE: the horizon's value outside, not 0 (sample/edge.h) */
    if (!job->o.zero_fill && job_attempt_zero_fill(job, a)) sb_matrix_extend_edge(job->src, a->param, &a->m);
    a->t_sample = job_now() - t0;
    return r;
}

/* Cells outside a's domain fitted as given: zeros asked for (--zero-fill),
 * or where the form continues by its value at the edge there
 * (SB_CAP_LIGHT_EDGE, or SB_CAP_VIEW_EDGE for an analytic source, on the
 * whole hemisphere with a form holding cos theta_i; sample/edge.h): a
 * plain SVD, exact and fast, instead of the masked fit.  On rv the masked
 * fit left the columns that few rows see underdetermined (Phong n = 100,
 * R = 32, J = 4: 1.1 % with theta_o > 89 degrees 7 %; continued, 0.10 %). */
int job_attempt_zero_fill(const sb_job_t *job, const job_attempt_t *a) {
    if (job->o.zero_fill) return 1;
    int hemisphere = fabs(job->o.theta_max_deg - 90) < 1e-9;
    unsigned caps = a->param ? sb_param_caps(a->param) : 0;
    int edge =
        (caps & SB_CAP_LIGHT_EDGE) || ((caps & SB_CAP_VIEW_EDGE) && !(sb_source_flags(job->src) & SB_SOURCE_MEASURED));
    /* a scene with a floor fits every cell of the domain (scene.h) */
    int scene_ok = !job->scene || sb_scene_floor_on(job->scene, a->param) > 0;
    return edge && hemisphere && scene_ok && (a->m.form == SB_FORM_COS || a->m.form == SB_FORM_COS2);
}

int job_attempt_masked(const sb_job_t *job, const job_attempt_t *a) {
    return a->m.mask != NULL && !job_attempt_zero_fill(job, a);
}

/* Factor the sampled a->m with lv->terms terms (replacing a->f), then its
 * estimated errors and, with lv->metric_res, the grid quadrature. */
/* Cells past the view's horizon (SB_CAP_VIEW_EDGE) start at the edge's
 * value (sample/edge.h); the fit then imputes them (hard impute): each
 * sweep sets them to the current fit's value and fits again, so they
 * follow the low-rank structure of the valid cells rather than the edge,
 * while the columns that only a few grazing rows see keep the edge's value
 * as their start (the masked fit, from zeros, left them underdetermined).
 * Phong n = 100, R = 32, J = 4: 0.104 % -> 0.044 %, theta_i > 80 degrees
 * 0.83 % -> 0.33 %.  At most JOB_EDGE_SWEEPS sweeps, until one moves the
 * imputed cells by less than JOB_EDGE_TOL of the valid cells' norm. */
#define JOB_EDGE_SWEEPS 100
#define JOB_EDGE_TOL 1e-6
static double edge_impute(job_attempt_t *a, size_t J) {
    double moved = 0, norm = 0;
    sb_matrix_t *m = &a->m;
    for (size_t c = 0; c < m->cols; c++)
        for (size_t r = 0; r < m->rows; r++)
            for (int ch = 0; ch < 3; ch++) {
                double *x = m->data[ch] ? &m->data[ch][r + c * m->ld] : NULL;
                if (!x) continue;
                if (m->mask[r + c * m->ld]) {
                    norm += *x * *x;
                    continue;
                }
                double v = sb_factors_cell(a->f, J, (size_t)ch, r, c);
                moved += (v - *x) * (v - *x);
                *x = v;
            }
    return norm > 0 ? sqrt(moved / norm) : 0;
}

static sb_result_t edge_sweeps(sb_plan_t *plan, const sb_job_t *job, size_t J, job_attempt_t *a) {
    int view_edge = (sb_param_caps(a->param) & SB_CAP_VIEW_EDGE) && !job->o.zero_fill;
    if (!view_edge || !a->m.mask || a->m.structured || !job_attempt_zero_fill(job, a)) return SB_OK;
    sb_result_t r = SB_OK;
    for (int k = 0; k < JOB_EDGE_SWEEPS && r == SB_OK && edge_impute(a, J) > JOB_EDGE_TOL; k++) {
        sb_factors_destroy(a->f);
        a->f = NULL;
        r = sb_plan_execute(plan, &a->m, a->param, &a->f);
    }
    return r;
}

/* The edge sweeps nested (as the masked fit, fit_chain.c): the sweeps
 * impute the cells outside with the J-term fit, so its first j terms were
 * a fit of a matrix made for J (Phong n = 100 on rv, cos: 2.6e-2 at
 * J' = 2 of a -J 8 run, 1.3e-3 with -J 2).  Now the two-term fit with its
 * sweeps, then one term at a time, each fitted with its sweeps to what the
 * terms before leave (the cells outside start at 0 there: the fit so far
 * continues them); the first j terms of a J-term fit are the j-term fit. */
static int edge_nested(const sb_job_t *job, const job_attempt_t *a, size_t J) {
    int view_edge = (sb_param_caps(a->param) & SB_CAP_VIEW_EDGE) && !job->o.zero_fill;
    return J > 2 && view_edge && a->m.mask && !a->m.structured && !a->m.streamed && job_attempt_zero_fill(job, a);
}

/* out (created with J terms, f's channels and sizes) gets f's terms 0..k-1
 * as its terms at..at+k-1 (f's meta too when at is 0). */
static sb_result_t put_terms(sb_context_t *ctx, const sb_factors_t *f, size_t at, size_t J, sb_factors_t **out) {
    size_t C = sb_factors_channels(f), k = sb_factors_terms(f), w[2], h[2];
    for (int s = 0; s < 2; s++)
        sb_factors_size(f, s, &w[s], &h[s]);
    sb_result_t r = *out ? SB_OK : sb_factors_create(ctx, J, C, w[0], h[0], w[1], h[1], out);
    if (r == SB_OK && sb_factors_channels(*out) != C) return SB_ERR_RANGE; /* the caller falls back */
    for (size_t j = 0; r == SB_OK && j < k && at + j < J; j++)
        for (size_t c = 0; c < C; c++) {
            for (int s = 0; s < 2; s++)
                memcpy(sb_factors_tex(*out, s, at + j, c), sb_factors_tex_const(f, s, j, c),
                       w[s] * h[s] * sizeof(double));
            sb_factors_set_sigma(*out, at + j, c, sb_factors_sigma(f, j, c));
        }
    for (size_t i = 0; r == SB_OK && at == 0 && i < sb_factors_meta_count(f); i++) {
        const char *key, *value;
        sb_factors_meta_at(f, i, &key, &value);
        r = sb_factors_set_meta(*out, key, value);
    }
    return r;
}

/* res -= the terms of f at every cell (present channels). */
static void subtract_terms(sb_matrix_t *res, const sb_factors_t *f) {
    size_t C = sb_factors_channels(f), k = sb_factors_terms(f);
    for (int ch = 0; ch < 3; ch++)
        for (size_t c = 0; res->data[ch] && c < res->cols; c++)
            for (size_t r = 0; r < res->rows; r++)
                res->data[ch][r + c * res->ld] -= sb_factors_cell(f, k, C == 1 ? 0 : (size_t)ch, r, c);
}

/* The pieces after the first two terms (a->f), into a J-term a->f. */
static sb_result_t edge_chain(sb_context_t *ctx, const sb_job_t *job, const sb_plan_opts_t *pl, size_t J,
                              job_attempt_t *a) {
    job_attempt_t t = *a; /* the residual matrix: a's mask and shape, its own values */
    t.f = NULL;
    t.m.phi_period = 0; /* edited by hand */
    sb_factors_t *out = NULL;
    sb_plan_t *plan = NULL;
    sb_plan_opts_t one = *pl;
    one.terms = 1;
    sb_result_t r = put_terms(ctx, a->f, 0, J, &out);
    for (int ch = 0; r == SB_OK && ch < 3; ch++) {
        t.m.data[ch] = NULL;
        if (!a->m.data[ch]) continue;
        if (!(t.m.data[ch] = malloc(a->m.ld * a->m.cols * sizeof(double))))
            r = SB_ERR_NOMEM;
        else
            memcpy(t.m.data[ch], a->m.data[ch], a->m.ld * a->m.cols * sizeof(double));
    }
    if (r == SB_OK) r = sb_plan_create_for(ctx, &t.m, &one, &plan);
    const sb_factors_t *last = a->f;
    for (size_t j = sb_factors_terms(a->f); r == SB_OK && j < J; j++) {
        subtract_terms(&t.m, last);
        sb_factors_destroy(t.f);
        t.f = NULL;
        r = sb_plan_execute(plan, &t.m, t.param, &t.f);
        if (r == SB_OK) r = edge_sweeps(plan, job, 1, &t);
        if (r == SB_OK) r = put_terms(ctx, t.f, j, J, &out);
        last = t.f;
    }
    for (int ch = 0; ch < 3; ch++)
        free(t.m.data[ch]);
    sb_factors_destroy(t.f);
    sb_plan_destroy(plan);
    if (r == SB_OK) {
        sb_factor_errors_t *e = sb_factors_errors_mut(out);
        r = sb_factors_errors_against(ctx, out, &a->m, a->weighted ? a->param : NULL, e->rel_rms, e->max_abs);
    }
    if (r != SB_OK) {
        sb_factors_destroy(out);
        return r == SB_ERR_NOMEM ? sb_error(ctx, r, "out of memory") : r;
    }
    sb_factors_destroy(a->f);
    a->f = out;
    return SB_OK;
}

sb_plan_opts_t job_plan_opts(const sb_job_t *job, const job_level_t *lv, const job_attempt_t *a, size_t J) {
    sb_plan_opts_t pl = {0};
    pl.terms = J;
    pl.svd.method = job->o.method;
    pl.svd.seed = job->o.seed;
    pl.weighted = a->weighted;
    pl.zero_fill = job_attempt_zero_fill(job, a);
    pl.fit_tol = lv->fit_tol;
    pl.fit_max_iters = lv->fit_max_iters;
    /* nonneg_ratio is beyond sepbrdf 0.1's options: the size says so */
    pl.nonneg_ratio = lv->nonneg_ratio;
    pl.nonneg_ratio_channel = lv->nonneg_ratio_channel;
    pl.nonneg_first_fit = lv->nonneg_first_fit;
    pl.nonneg_rounds = lv->nonneg_rounds;
    pl.size = sizeof pl;
    if (a->scene_w) { /* the scene's weights instead of solid angles */
        pl.weighted = 1;
        pl.row_weights = a->scene_w;
        pl.col_weights = a->scene_w + a->m.rows;
    }
    return pl;
}

size_t job_fit_terms(const sb_job_t *job, const job_level_t *lv, const job_attempt_t *a) {
    return job_level_terms(job, lv, sb_param_kind(a->param), a->m.rows < a->m.cols ? a->m.rows : a->m.cols);
}

sb_result_t job_factor(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, int weighted, job_attempt_t *a) {
    sb_factors_destroy(a->f);
    a->f = NULL;
    free(a->term_w);
    a->term_w = NULL;
    a->texel_fit = 0;
    memset(&a->metric, 0, sizeof a->metric);
    memset(&a->stats, 0, sizeof a->stats);
    a->conv_terms = 0;
    a->early_stop = lv->early_stop;
    a->weighted = weighted;
    sb_result_t r = job_scene_prepare(ctx, job, a);
    if (r != SB_OK) return r;
    size_t J = job_fit_terms(job, lv, a);
    sb_plan_opts_t pl = job_plan_opts(job, lv, a, J);
    sb_plan_t *plan = NULL;
    int nested = edge_nested(job, a, J);
    if (nested) pl.terms = 2; /* then one term at a time (edge_chain) */
    r = sb_plan_create_for(ctx, &a->m, &pl, &plan);
    if (r != SB_OK) return r;
    /* the second form of named_pair: its maxima only where it is kept (job_forms.c pair_max_abs) */
    if (job->form_share && job->form_share->second && a->m.structured && !job->scene) sb_plan_skip_max_(plan, 1);
    if (!job->nonneg_carry && job_nonneg_method(sb_method_name(job->o.method)))
        job->nonneg_carry = sb_nmf_carry_create(); /* NULL: every fit made in full */
    sb_plan_set_nonneg_carry(plan, job->nonneg_carry);
    double t1 = job_now();
    /* a large dense matrix: the BLAS threads the job set aside (job.c) */
    int dense = !a->m.structured && !job_attempt_masked(job, a) && a->m.rows * a->m.cols >= JOB_BLAS_DENSE_CELLS;
    if (dense) sb_blas_threads_end(job->blas_threads);
    r = sb_plan_execute(plan, &a->m, a->param, &a->f);
    if (r == SB_ERR_NUMERIC && a->m.form == SB_FORM_F && (sb_source_flags(job->src) & SB_SOURCE_STORES_COS)) {
        char why[512]; /* the message, copied: the context's buffer is rewritten */
        snprintf(why, sizeof why, "%s", sb_context_last_error(ctx));
        r = sb_error(ctx, r,
                     "%s; %s stores f cos theta_i, and f grows as 1 / cos theta_i towards the horizon: --form cos "
                     "factors what the file holds",
                     why, sb_source_description(job->src));
    }
    if (r == SB_OK) r = edge_sweeps(plan, job, nested ? 2 : J, a);
    if (r == SB_OK && nested) r = edge_chain(ctx, job, &pl, J, a);
    if (dense) sb_blas_threads_begin();
    sb_plan_stats(plan, &a->stats);
    a->conv_terms = sb_plan_converged_terms(plan);
    double t2 = job_now();
    if (r == SB_OK && (sb_factors_set_meta(a->f, "source", sb_source_description(job->src)) != SB_OK ||
                       sb_factors_set_meta(a->f, "source_spec", job->o.source) != SB_OK))
        r = sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    a->t_factor = t2 - t1;
    sb_plan_destroy(plan); /* before the estimate: its buffers reuse the plan's memory */
    if (r == SB_OK) r = job_measure(ctx, job, lv, a);
    return r == SB_OK ? job_band_refit(ctx, job, lv, a) : r;
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

/* The masked fit's early stop (a sweep gaining less than 1e-3 relative, at
 * most 20 per stage: the error on the cells then falls by a few per cent
 * in a run, far below what interpolation between texels adds, and the
 * headline errors of the default gold, GGX, Blinn-Phong and the measured
 * tables came out the same or lower than at 40), unless the caller set its
 * own. */
void job_early_stop(const sb_job_t *job, job_level_t *lv) {
    lv->fit_tol = job->o.fit_tol > 0 ? job->o.fit_tol : 1e-3;
    lv->fit_max_iters = job->o.fit_max_iters > 0 ? job->o.fit_max_iters : 20;
    lv->early_stop = !(job->o.fit_max_iters > 0); /* the caller's own cap is no early stop */
}
