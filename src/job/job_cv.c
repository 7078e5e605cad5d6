/* Cross-validation of a scattered table at its measurements (job.h:
 * cv_folds).  The samples are cut into K folds (sb_measured_fold); for
 * each fold refitted the table is read again without it and the kept
 * layout, form, weighting and J refitted (fold_fit), and the refit's
 * reconstruction is compared with the measurements it did not see.  By
 * default K = 10 and the first 5 folds are refitted: five splits that
 * each leave out a random tenth of the table, as a scientist checks a fit
 * (docs/measured.md); cv_folds K >= 2 refits all K.  Per fold k and J':
 *     r_k = sqrt(E_k / T_k),
 *     E_k = sum over fold k's samples of |f~ - f|^2 cos^2 theta_i,
 *     T_k = sum of |f|^2 cos^2 theta_i,
 * the error at that split's measurements.  On a glossy table a fold
 * holding one of the highlight's few brightest samples is off by 4-7x the
 * others, and an energy-weighted mean over all folds (cv_pooled,
 * sqrt(sum E / sum T)) is that fold's figure, not what a split sees.  cv
 * is the figure a random split of a K-th of the table lands within
 * JOB_CV_WITHIN of most often, drawn from the held-out samples' own errors
 * and, for the rows no refit held out, their nearest held-out peers' in
 * energy (job_cv_stat.c; docs/measured.md, "Random splits against the
 * reported figure", "What ten splits can say").
 * Its standard error is the jackknife's over the refits (job_cv_stat.c);
 * where no figure is drawn, cv is the median of the folds with the
 * median's, 1.2533 * 1.4826 MAD / sqrt(K) (the normal's relative
 * efficiency with the MAD as the scale); cv_max is the worst fold. */
#include <math.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "job_impl.h"
#include "util/internal.h"
#include "util/parallel.h"

/* Interpolation CV (leave-one-out at the measurements) above which the
 * table is said not to predict itself, whatever the refits found. */
#define JOB_CV_WARN 0.3
/* Folds and refits by default: a tenth of the table out each time. */
#define JOB_CV_FOLDS 10
#define JOB_CV_REFITS 5
/* The figure reported is within this factor of as many random splits as
 * any single figure (job_cv_stat.c). */
#define JOB_CV_WITHIN 1.5
/* The warning names fewer terms whose held-out error is this much lower. */
#define JOB_CV_FEWER 1.25
/* A refit's masked fit stops where a sweep gains less than this (auto's
 * early stop is 1e-3): the held-out error it is for is a figure with a
 * standard error of 5-10 %.  On the Cornell acrylic cut to one theta_i
 * (hd, 1024 x 1024 cells) the refits' sweeps halved (158-295 -> 66-174)
 * and cv_headline moved 0.0669 -> 0.0677 (its standard error 0.0045);
 * docs/performance.md, "Issue 32, the refits of a sparse table". */
#define JOB_CV_FIT_TOL 1e-2

/* The refit of fold k: the table read again without it, with the
 * interpolation the whole table resolved (method, neighbours, radius: not
 * chosen again on fewer samples; the lobe, when the table uses one, fitted
 * again from its family on: a narrow highlight's shape is what a fold
 * that holds out its edge sees differently), sampled on the kept layout with the kept
 * form, and factored with the kept weighting and J (masked fits stopped
 * early, JOB_CV_FIT_TOL: the error at unseen measurements is far above
 * what more sweeps change).  No estimator: the kept fit's own choices
 * made with it are replayed on the refit, its texel filters (job_texels.c)
 * and its term weights (job_weights.c, job_sample_weights.c), so that a
 * fold is fitted as the whole pipeline fits a table.  Without them the
 * figure was the plain fit's: a glossy simulated paint (roughness 0.15,
 * 3 % noise, 4 096 rows, J = 4) reported 0.0447 where the whole pipeline
 * refitted on the same five folds erred by 0.041, 0.030, 0.034, 0.024,
 * 0.042 (median 0.034); replayed, 0.0335 (the Cornell acrylic: 0.1189 ->
 * 0.1193). */
static sb_result_t fold_fit(sb_context_t *ctx, const sb_job_t *job, size_t K, size_t k, sb_factors_t **out,
                            sb_source_t **table) {
    const job_attempt_t *b = &job->best;
    const sb_measured_info_t *in = sb_measured_source_info(job->src);
    sb_measured_opts_t mo = job->o.measured;
    mo.cv_folds = K;
    mo.cv_fold = k;
    mo.interp = in->interp;
    mo.lobe = in->lobe.used ? SB_LOBE_ON : SB_LOBE_OFF; /* its shape, width and weights fitted again */
    mo.lobe_shape = NULL; /* as a refit by hand would: where a fold held the highlight's edge, the shape parts */
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
    pl.fit_tol = JOB_CV_FIT_TOL;
    sb_plan_t *plan = NULL;
    if (r == SB_OK) r = sb_plan_create_for(ctx, &m, &pl, &plan);
    if (r == SB_OK) r = sb_plan_execute(plan, &m, b->param, out);
    if (r == SB_OK) r = job_texel_replay(ctx, b->param, b->texel_fit, out);
    size_t J = sb_factors_terms(b->f), C = sb_factors_channels(b->f);
    if (r == SB_OK && b->term_w && sb_factors_terms(*out) == J && sb_factors_channels(*out) == C)
        for (size_t i = 0; i < J * C; i++)
            job_scale_term(*out, i / C, i % C, b->term_w[i]);
    sb_plan_destroy(plan);
    sb_matrix_free(&m);
    *table = src; /* what the fit was sampled from: its own error at the fold (fold_sums) */
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

/* Whether a sample counts: below a --theta-max cap without a scene the
 * errors are measured within the cap (job_measures_cap), where the snippet
 * is defined; a sample beyond it (the textures return 0 there) is left
 * out, as the errors at the table's samples leave it out. */
static int sample_counts(const sb_job_t *job, const double wi[3], const double wo[3]) {
    if (!job_measures_cap(job)) return 1;
    double c = cos(job->o.theta_max_deg * SB_PI / 180);
    return wi[2] >= c && wo[2] >= c;
}

/* Add fold k's squared errors (E[j], j < J) and energy (*T) at its
 * samples, and at J those of each theta_h band into the job's; each
 * sample's own (row_e[h * J + j], row_t[h], h counting the held-out
 * samples of all folds) and its place in the table (held_row[h]) for the
 * figure a random split lands near. */
static void fold_sums(sb_job_t *job, const sb_factors_t *f, const sb_source_t *table, size_t K, size_t k, size_t J,
                      double *E, double *T, double *Etab, size_t *held, double *row_e, double *row_t,
                      size_t *held_row) {
    const sb_param_t *p = job->best.param;
    sb_form_t form = job->best.m.form;
    size_t n = sb_source_sample_count(job->src);
    for (size_t i = 0; i < n; i++) {
        double wi[3], wo[3], v[3], rec[3], e = 0;
        if (sb_measured_fold(i, K) != k || !sb_source_sample(job->src, i, wi, wo, v) || !sample_counts(job, wi, wo))
            continue;
        for (int c = 0; c < 3; c++) /* a channel not factored (--channels) is measured nowhere */
            v[c] = job_factors_channel(job, c) ? v[c] : 0;
        double c2 = wi[2] * wi[2], t = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) * c2;
        for (size_t j = 0; j < J; j++) {
            if (!sb_factors_eval(f, p, form, j + 1, wi, wo, rec)) rec[0] = rec[1] = rec[2] = 0;
            e = 0;
            for (int c = 0; c < 3; c++)
                e += (rec[c] - v[c]) * (rec[c] - v[c]) * c2;
            E[j] += e;
            row_e[*held * J + j] = e;
        }
        row_t[*held] = t;
        held_row[*held] = i;
        double tv[3] = {0, 0, 0};
        if (!table || !sb_source_eval(table, wi, wo, tv)) tv[0] = tv[1] = tv[2] = 0;
        for (int c = 0; c < 3; c++)
            tv[c] = job_factors_channel(job, c) ? tv[c] : 0;
        for (int c = 0; c < 3; c++)
            *Etab += (tv[c] - v[c]) * (tv[c] - v[c]) * c2;
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

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* The median of x[0..n) (sorted in place). */
static double median(double *x, size_t n) {
    qsort(x, n, sizeof *x, cmp_double);
    return n % 2 ? x[n / 2] : 0.5 * (x[n / 2 - 1] + x[n / 2]);
}

/* cv_median (the median of the refits' errors), cv_pooled and cv_max
 * from the refits' sums (E[k * J + j], T[k], k < K); cv and cv_se are
 * set already (job_cv_split_figure), where they are not finite the median
 * and its standard error. */
static void cv_combine(sb_job_t *job, size_t K, size_t J, const double *E, const double *T) {
    double *r = malloc(2 * K * sizeof *r), *d = r ? r + K : NULL;
    for (size_t j = 0; j < J && !r; j++) /* no memory: no figures, said by NaN */
        job->cv[j] = job->cv_se[j] = job->cv_pooled[j] = job->cv_max[j] = job->cv_median[j] = NAN;
    for (size_t j = 0; j < J && r; j++) {
        double es = 0, ts = 0;
        size_t n = 0;
        job->cv_max[j] = 0;
        for (size_t k = 0; k < K; k++) {
            es += E[k * J + j], ts += T[k];
            if (!(T[k] > 0)) continue;
            r[n++] = sqrt(E[k * J + j] / T[k]);
            job->cv_max[j] = fmax(job->cv_max[j], r[n - 1]);
        }
        job->cv_pooled[j] = ts > 0 ? sqrt(es / ts) : NAN;
        job->cv_median[j] = n ? median(r, n) : NAN;
        if (isfinite(job->cv[j]) && isfinite(job->cv_se[j])) continue; /* the figure and its jackknife */
        job->cv[j] = job->cv_median[j];
        for (size_t k = 0; k < n; k++)
            d[k] = fabs(r[k] - job->cv[j]);
        job->cv_se[j] = n > 1 ? 1.2533 * 1.4826 * median(d, n) / sqrt((double)n) : NAN;
    }
    free(r);
}

/* The refits run side by side, one per thread, each on one thread inside
 * (a fold's matrix, fit and table are its own): every fork and join of a
 * fit's sweeps cost a wake-up, and two refits share no data.  Each thread
 * takes the next fold from a counter and keeps its errors in its own
 * context; the sums are added in fold order, so the figures do not depend
 * on which thread refitted which fold. */
typedef struct folds {
    const sb_job_t *job;
    size_t K, refits;
    atomic_size_t next;
    sb_factors_t **ff;
    sb_source_t **tab; /* per fold, the table the refit sampled */
    sb_result_t *r;
    sb_context_t **ctx; /* per fold, for its error message */
} folds_t;

static void *folds_run(void *arg) {
    folds_t *fs = arg;
    for (size_t k; (k = atomic_fetch_add(&fs->next, 1)) < fs->refits;)
        fs->r[k] = sb_context_create(&fs->ctx[k]) == SB_OK
                       ? fold_fit(fs->ctx[k], fs->job, fs->K, k, &fs->ff[k], &fs->tab[k])
                       : SB_ERR_NOMEM;
    return NULL;
}

/* E[k * J + j], T[k] as fold_sums adds them; T[refits + k] the squared
 * error there of the table refit k sampled. */
static sb_result_t folds_fit(sb_context_t *ctx, sb_job_t *job, size_t K, size_t refits, size_t J, double *E, double *T,
                             double *row_e, size_t *held_row, size_t *fold_end) {
    job_progress(job, "cross-validation", 0);
    folds_t fs = {job,
                  K,
                  refits,
                  0,
                  calloc(refits, sizeof *fs.ff),
                  calloc(refits, sizeof *fs.tab),
                  calloc(refits, sizeof *fs.r),
                  calloc(refits, sizeof *fs.ctx)};
    sb_result_t r =
        fs.ff && fs.tab && fs.r && fs.ctx ? SB_OK : sb_error(ctx, SB_ERR_NOMEM, "cross-validation: out of memory");
    int nt = sb_group_active(ctx) ? 1 : sb_threads_for(0, refits, refits, 2);
    if (r == SB_OK && nt == 1) { /* a group of processes shares the refits' matrices: in turn, with ctx */
        for (size_t k = 0; k < refits && (r = fold_fit(ctx, job, K, k, &fs.ff[k], &fs.tab[k])) == SB_OK; k++)
            job_progress(job, "cross-validation", (double)(k + 1) / (double)refits);
    } else if (r == SB_OK) {
        sb_parallel_run(folds_run, &fs, 0, nt, NULL, NULL); /* BLAS is on one thread during a job */
        for (size_t k = 0; k < refits && r == SB_OK; k++)
            if ((r = fs.r[k]) != SB_OK) sb_error(ctx, r, "%s", fs.ctx[k] ? sb_context_last_error(fs.ctx[k]) : "");
    }
    for (size_t k = 0; k < refits && r == SB_OK; k++) {
        fold_sums(job, fs.ff[k], fs.tab[k], K, k, J, E + k * J, T + k, T + refits + k, &job->cv_held, row_e,
                  row_e + sb_source_sample_count(job->src) * J, held_row);
        fold_end[k] = job->cv_held;
    }
    for (size_t k = 0; fs.ff && fs.tab && fs.ctx && k < refits; k++) {
        sb_factors_destroy(fs.ff[k]);
        sb_source_destroy(fs.tab[k]);
        sb_context_destroy(fs.ctx[k]);
    }
    free(fs.ff), free(fs.tab), free(fs.r), free(fs.ctx);
    return r;
}

/* cv and cv_se from the held-out rows (row: their squared errors, then
 * from row + n J their energies; held_row their places in the table):
 * random splits of a K-th of the table drawn from every row of it
 * (job_cv_stat.c), t_all (n) the table's energies, filled here. */
static void split_figure(sb_job_t *job, double *row, const size_t *fold_end, const size_t *held_row, double *t_all,
                         size_t refits, size_t K, size_t J, size_t n) {
    memmove(row + job->cv_held * J, row + n * J, job->cv_held * sizeof *row); /* energies beside the errors */
    for (size_t i = 0; i < n; i++) {
        double wi[3], wo[3], v[3];
        t_all[i] = 0;
        if (!sb_source_sample(job->src, i, wi, wo, v) || !sample_counts(job, wi, wo)) continue;
        for (int c = 0; c < 3; c++) /* as fold_sums counts them */
            t_all[i] += job_factors_channel(job, c) ? v[c] * v[c] * wi[2] * wi[2] : 0;
    }
    job_cv_split_figure(row, row + job->cv_held * J, fold_end, refits, held_row, t_all, n, (n + K / 2) / K, J,
                        JOB_CV_WITHIN, job->cv, job->cv_se);
}

sb_result_t job_cv(sb_context_t *ctx, sb_job_t *job) {
    const sb_measured_info_t *in = sb_measured_source_info(job->src);
    size_t K = job->o.cv_folds ? job->o.cv_folds : JOB_CV_FOLDS, refits = job->o.cv_folds ? K : JOB_CV_REFITS;
    if (!in || !in->dims || K < 2 || job->o.measured.cv_folds || !job->best.f || job->o.sample_only || job->scene)
        return SB_OK;
    size_t J = sb_factors_terms(job->best.f), n = sb_source_sample_count(job->src);
    struct stat st; /* the folds read the table again */
    if (n < 4 * K || !job->o.source || stat(job->o.source, &st) != 0 || !S_ISREG(st.st_mode)) return SB_OK;
    double t0 = job_now(), *E = calloc(refits * J, sizeof *E), *T = calloc(2 * refits, sizeof *T);
    double *row = calloc(n * (J + 2), sizeof *row); /* each held-out sample's squared errors, energies; the table's */
    size_t *fold_end = calloc(refits + n, sizeof *fold_end); /* then each held-out sample's place in the table */
    job->cv = calloc(5 * J, sizeof *job->cv);
    if (!E || !T || !row || !fold_end || !job->cv) {
        free(E), free(T), free(row), free(fold_end);
        return sb_error(ctx, SB_ERR_NOMEM, "cross-validation: out of memory");
    }
    job->cv_se = job->cv + J, job->cv_pooled = job->cv + 2 * J, job->cv_max = job->cv + 3 * J;
    job->cv_median = job->cv + 4 * J;
    sb_result_t r = folds_fit(ctx, job, K, refits, J, E, T, row, fold_end + refits, fold_end);
    if (r == SB_OK) {
        split_figure(job, row, fold_end, fold_end + refits, row + n * (J + 1), refits, K, J, n);
        cv_combine(job, refits, J, E, T);
        size_t nt = 0;
        for (size_t k = 0; k < refits; k++) /* the refits' tables' errors, over E's first row (used) */
            if (T[k] > 0) E[nt++] = sqrt(T[refits + k] / T[k]);
        job->cv_table = nt ? median(E, nt) : NAN;
        job->cv_folds = K;
        job->cv_refits = refits;
        job->cv_terms = J;
    } else { /* a fold's refit failed: no cross-validated error, said so */
        job_warn(job, "cross-validation skipped: a refit without one fold of the measurements failed: %s",
                 sb_context_last_error(ctx));
        free(job->cv);
        job->cv = job->cv_se = job->cv_pooled = job->cv_max = job->cv_median = NULL;
        job->cv_held = 0;
        r = SB_OK;
    }
    free(E), free(T), free(row), free(fold_end);
    job->cv_s = job_now() - t0;
    double h = job->cv ? sb_estimate_headline(job->best.est, J) : NAN, icv = in->interp_cv[in->interp], share;
    int w = job->cv ? worst_band(job, &share) : -1;
    if (job->cv && h > 0 && (job->cv_max[J - 1] > 1.5 * h || icv > JOB_CV_WARN) && w >= 0) {
        char why[200]; /* whose error it is: the refits' tables' (lobe, interpolation) or their fits' */
        double tc = job->cv_table;
        if (tc > JOB_CV_WARN)
            snprintf(why, sizeof why,
                     "the table does not predict them: without them its lobe and interpolation err by %.3g there "
                     "(interp cv %.3g)",
                     tc, icv);
        else if (!(job->cv[J - 1] > 2 * tc))
            snprintf(why, sizeof why, "about the table's own error between its samples (without them it errs by %.3g)",
                     tc);
        else
            snprintf(why, sizeof why,
                     "the table predicts them (without them it errs by %.3g) but %zu terms do not reproduce it there "
                     "(more terms or a finer -r may)",
                     tc, J);
        char fewer[120] = ""; /* terms past the best held-out error fit the samples, not the material */
        size_t jb = job_cv_fewer(job, J);
        if (jb)
            snprintf(fewer, sizeof fewer, "; fewer terms predict them better: %zu terms err by %.3g there", jb,
                     job->cv[jb - 1]);
        job_warn(job,
                 "at the measurements left out of the fit the error is %.3g at J = %zu (what most random splits "
                 "see, from %zu refits, each without 1/%zu of them; up to %.3g in one), %.1fx the headline %.3g; %s: "
                 "%.0f%% of the held-out "
                 "squared error is where theta_h is %g-%g deg (%zu measurements, error %.3g there over all "
                 "refits)%s; trust cv_headline (report.json) for this table",
                 job->cv[J - 1], J, job->cv_refits, K, job->cv_max[J - 1], job->cv[J - 1] / h, h, why, 100 * share,
                 job_cv_band_deg[w], job_cv_band_deg[w + 1], job->cv_band_n[w],
                 job->cv_band_t[w] > 0 ? sqrt(job->cv_band_e[w] / job->cv_band_t[w]) : NAN, fewer);
    }
    return r;
}

size_t job_cv_fewer(const sb_job_t *job, size_t J) {
    if (!job || !job->cv || J < 2 || J > job->cv_terms) return 0;
    size_t jb = J - 1;
    for (size_t j = 0; j + 1 < J; j++)
        if (job->cv[j] < job->cv[jb]) jb = j;
    return jb + 1 < J && job->cv[jb] * JOB_CV_FEWER < job->cv[J - 1] ? jb + 1 : 0;
}

double sb_job_cv(const sb_job_t *job, size_t terms, double *se, size_t *held) {
    int ok = job && job->cv && terms >= 1 && terms <= job->cv_terms;
    if (se) *se = ok ? job->cv_se[terms - 1] : NAN;
    if (held) *held = ok ? job->cv_held : 0;
    return ok ? job->cv[terms - 1] : NAN;
}
