/* Cross-validation of a scattered table at its measurements (job.h:
 * cv_folds).  The samples are cut into K folds (sb_measured_fold); for
 * each fold the table is read again without it and the kept layout, form,
 * weighting and J refitted (fold_fit), and the refit's reconstruction is
 * compared with the measurements it did not see.  Per J':
 *     cv = sqrt(sum_k E_k / sum_k T_k),
 *     E_k = sum over fold k's samples of |f~ - f|^2 cos^2 theta_i,
 *     T_k = sum of |f|^2 cos^2 theta_i,
 * and its standard error from the folds' spread (the ratio estimator the
 * headline's replicates use: se(cv^2) = sd_k(E_k - cv^2 T_k) sqrt(K) /
 * sum T, se(cv) = se(cv^2) / (2 cv)). */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "job_impl.h"
#include "util/internal.h"

/* Interpolation CV (leave-one-out at the measurements) above which the
 * table is said not to predict itself, whatever the refits found. */
#define JOB_CV_WARN 0.3

/* The refit of fold k: the table read again without it, with the
 * interpolation the whole table resolved (method, neighbours, radius: not
 * chosen again on fewer samples), sampled on the kept layout with the kept
 * form, and factored with the kept weighting and J (masked fits stopped
 * early, as auto screens: the error at unseen measurements is far above
 * what more sweeps change).  No estimator, term weights or texel fits:
 * the plain fit of the kept settings. */
static sb_result_t fold_fit(sb_context_t *ctx, const sb_job_t *job, size_t K, size_t k, sb_factors_t **out) {
    const job_attempt_t *b = &job->best;
    const sb_measured_info_t *in = sb_measured_source_info(job->src);
    sb_measured_opts_t mo = job->o.measured;
    mo.cv_folds = K;
    mo.cv_fold = k;
    mo.interp = in->interp;
    mo.lobe = in->lobe.used ? SB_LOBE_ON : SB_LOBE_OFF; /* its width and weights fitted again */
    mo.lobe_shape = &in->lobe;
    mo.neighbours = in->neighbours;
    mo.radius = isfinite(in->radius) ? in->radius : -1;
    sb_source_t *src = NULL;
    sb_result_t r = sb_measured_open(ctx, job->o.source, &mo, &src, NULL);
    sb_matrix_opts_t xo = {0};
    xo.form = b->m.form;
    xo.channels = job->o.channels;
    xo.structured = 1;
    sb_matrix_t m = {0};
    if (r == SB_OK) r = sb_matrix_build(ctx, src, b->param, &xo, &m);
    sb_plan_opts_t pl = {0};
    pl.terms = sb_factors_terms(b->f);
    pl.svd.method = job->o.method;
    pl.svd.seed = job->o.seed;
    pl.weighted = b->weighted;
    pl.zero_fill = job_attempt_zero_fill(job, b);
    pl.fit_max_iters = 20;
    pl.fit_tol = 1e-3;
    sb_plan_t *plan = NULL;
    if (r == SB_OK) r = sb_plan_create_for(ctx, &m, &pl, &plan);
    if (r == SB_OK) r = sb_plan_execute(plan, &m, b->param, out);
    sb_plan_destroy(plan);
    sb_matrix_free(&m);
    sb_source_destroy(src);
    return r;
}

const double job_cv_band_deg[JOB_CV_BANDS + 1] = {0, 5, 15, 30, 50, 90};

static int theta_h_band(const double wi[3], const double wo[3]) {
    double h[3] = {wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]}, n = sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
    double th = n > 0 ? acos(fmin(1, fmax(-1, h[2] / n))) * 180 / SB_PI : 90;
    int b = 0;
    while (b + 1 < JOB_CV_BANDS && th >= job_cv_band_deg[b + 1])
        b++;
    return b;
}

/* Add fold k's squared errors (E[j], j < J) and energy (*T) at its
 * samples, and at J those of each theta_h band into the job's. */
static void fold_sums(sb_job_t *job, const sb_factors_t *f, size_t K, size_t k, size_t J, double *E, double *T,
                      size_t *held) {
    const sb_param_t *p = job->best.param;
    sb_form_t form = job->best.m.form;
    size_t n = sb_source_sample_count(job->src);
    for (size_t i = 0; i < n; i++) {
        double wi[3], wo[3], v[3], rec[3], e = 0;
        if (sb_measured_fold(i, K) != k || !sb_source_sample(job->src, i, wi, wo, v)) continue;
        double c2 = wi[2] * wi[2], t = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) * c2;
        for (size_t j = 0; j < J; j++) {
            if (!sb_factors_eval(f, p, form, j + 1, wi, wo, rec)) rec[0] = rec[1] = rec[2] = 0;
            e = 0;
            for (int c = 0; c < 3; c++)
                e += (rec[c] - v[c]) * (rec[c] - v[c]) * c2;
            E[j] += e;
        }
        int b = theta_h_band(wi, wo);
        job->cv_band_e[b] += e;
        job->cv_band_t[b] += t;
        job->cv_band_n[b]++;
        *T += t;
        ++*held;
    }
}

/* The theta_h band holding the largest share of the held-out error at J
 * (-1: none), its share into *share. */
static int worst_band(const sb_job_t *job, double *share) {
    double all = 0;
    int w = -1;
    for (int b = 0; b < JOB_CV_BANDS; b++) {
        all += job->cv_band_e[b];
        if (job->cv_band_n[b] && (w < 0 || job->cv_band_e[b] > job->cv_band_e[w])) w = b;
    }
    *share = w >= 0 && all > 0 ? job->cv_band_e[w] / all : NAN;
    return w;
}

/* cv and its standard error from the folds' sums. */
static void cv_combine(sb_job_t *job, size_t K, size_t J, const double *E, const double *T) {
    for (size_t j = 0; j < J; j++) {
        double es = 0, ts = 0, v = 0;
        for (size_t k = 0; k < K; k++)
            es += E[k * J + j], ts += T[k];
        double r2 = ts > 0 ? es / ts : NAN;
        for (size_t k = 0; k < K; k++) {
            double x = E[k * J + j] - r2 * T[k];
            v += x * x;
        }
        double se2 = ts > 0 ? sqrt(v / (double)(K - 1)) * sqrt((double)K) / ts : NAN;
        job->cv[j] = sqrt(r2);
        job->cv_se[j] = job->cv[j] > 0 ? se2 / (2 * job->cv[j]) : sqrt(se2);
    }
}

sb_result_t job_cv(sb_context_t *ctx, sb_job_t *job) {
    const sb_measured_info_t *in = sb_measured_source_info(job->src);
    size_t K = job->o.cv_folds ? job->o.cv_folds : 5;
    if (!in || !in->dims || K < 2 || job->o.measured.cv_folds || !job->best.f || job->o.sample_only || job->scene)
        return SB_OK;
    size_t J = sb_factors_terms(job->best.f), n = sb_source_sample_count(job->src);
    struct stat st; /* the folds read the table again */
    if (n < 4 * K || !job->o.source || stat(job->o.source, &st) != 0 || !S_ISREG(st.st_mode)) return SB_OK;
    double t0 = job_now(), *E = calloc(K * J, sizeof *E), *T = calloc(K, sizeof *T);
    job->cv = calloc(J, sizeof *job->cv);
    job->cv_se = calloc(J, sizeof *job->cv_se);
    if (!E || !T || !job->cv || !job->cv_se) {
        free(E), free(T);
        return sb_error(ctx, SB_ERR_NOMEM, "cross-validation: out of memory");
    }
    sb_result_t r = SB_OK;
    for (size_t k = 0; k < K && r == SB_OK; k++) {
        job_progress(job, "cross-validation", (double)k / (double)K);
        sb_factors_t *ff = NULL;
        if ((r = fold_fit(ctx, job, K, k, &ff)) == SB_OK) fold_sums(job, ff, K, k, J, E + k * J, T + k, &job->cv_held);
        sb_factors_destroy(ff);
    }
    if (r == SB_OK) {
        cv_combine(job, K, J, E, T);
        job->cv_folds = K;
        job->cv_terms = J;
    } else { /* a fold's refit failed: no cross-validated error, said so */
        job_warn(job, "cross-validation skipped: a refit without one fold of the measurements failed: %s",
                 sb_context_last_error(ctx));
        free(job->cv), free(job->cv_se);
        job->cv = job->cv_se = NULL;
        job->cv_held = 0;
        r = SB_OK;
    }
    free(E), free(T);
    job->cv_s = job_now() - t0;
    double h = job->cv ? sb_estimate_headline(job->best.est, J) : NAN, icv = in->interp_cv[in->interp], share;
    int w = job->cv ? worst_band(job, &share) : -1;
    if (job->cv && h > 0 && (job->cv[J - 1] > 1.5 * h || icv > JOB_CV_WARN) && w >= 0)
        job_warn(job,
                 "at the measurements left out of the fit the error is %.3g at J = %zu (%zu-fold refits), %.1fx the "
                 "headline %.3g; the table does not predict itself between its samples (interp cv %.3g): %.0f%% of "
                 "that error is where theta_h is %g-%g deg (%zu measurements, error %.3g there); trust cv_headline "
                 "(report.json) for this table",
                 job->cv[J - 1], J, K, job->cv[J - 1] / h, h, icv, 100 * share, job_cv_band_deg[w],
                 job_cv_band_deg[w + 1], job->cv_band_n[w],
                 job->cv_band_t[w] > 0 ? sqrt(job->cv_band_e[w] / job->cv_band_t[w]) : NAN);
    return r;
}

double sb_job_cv(const sb_job_t *job, size_t terms, double *se, size_t *held) {
    int ok = job && job->cv && terms >= 1 && terms <= job->cv_terms;
    if (se) *se = ok ? job->cv_se[terms - 1] : NAN;
    if (held) *held = ok ? job->cv_held : 0;
    return ok ? job->cv[terms - 1] : NAN;
}
