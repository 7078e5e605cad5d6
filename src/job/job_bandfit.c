/* The fit weighted cell by cell toward the light's grazing band, for a
 * layout on the source's own tables (vndf) whose plain fit breaks the band
 * bounds (estimate.h).  The rows of vndf are the view's slices, so the
 * light's band theta_i > 80 degrees runs across the columns: no separable
 * weight reaches it (docs/bands.md).  A weighted low-rank fit by
 * alternating least squares from the plain fit's terms: each cell weighs
 * its pair measure, times 1 + w where the light lies between 70 and 95.7
 * degrees from the normal (the band and the nodes the lookup blends into
 * it; the band's own cells alone took RGL paper's band only to 7 %).  w
 * rises through bandfit_weights until the fit keeps the bounds with a
 * lower band error than the plain fit and a headline at most
 * BANDFIT_HEADLINE times the plain one's; otherwise the plain fit stays.
 * RGL paper, J = 4: headline 1.81 % -> 2.32 %, theta_i > 80 degrees
 * 9.26 % -> 5.80 % (w = 9). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "job_impl.h"
#include "util/internal.h"

#define BANDFIT_ITERS 30
#define BANDFIT_MAXJ 16
#define BANDFIT_HEADLINE 1.5
#define BANDFIT_HI 0.3420201433256687 /* cos 70 degrees */
#define BANDFIT_LO (-0.1)             /* 95.7 degrees: the nodes the lookup blends at the horizon */
static const double bandfit_weights[] = {1, 3, 9, 27};

static int applies(const sb_job_t *job, const job_level_t *lv, const job_attempt_t *a) {
    if (!a->param || !(sb_param_caps(a->param) & SB_CAP_TABLES) || a->m.mask || a->m.structured || a->m.streamed)
        return 0;
    if (job->scene || job->o.plain_terms || lv->rank_only || !a->est) return 0;
    /* the weighted fit is signed: on non-negative factors (RGL paper,
     * --method nmf --param vndf --form cos) it was kept with 15 % of the
     * texels negative */
    if (job_nonneg_method(sb_method_name(job->o.method))) return 0;
    size_t J = sb_factors_terms(a->f);
    return sb_estimate_bands_bounded(a->est, J < a->est->terms ? J : a->est->terms) == 0;
}

/* Solve the n x n system a x = b in place (a symmetric positive
 * semidefinite, a small ridge added): Gaussian elimination, no pivoting. */
static void solve_small(double *a, double *b, size_t n) {
    double tr = 0;
    for (size_t i = 0; i < n; i++)
        tr += a[i * n + i];
    for (size_t i = 0; i < n; i++)
        a[i * n + i] += 1e-12 * tr + 1e-300;
    for (size_t k = 0; k < n; k++)
        for (size_t i = k + 1; i < n; i++) {
            double f = a[i * n + k] / a[k * n + k];
            for (size_t j = k; j < n; j++)
                a[i * n + j] -= f * a[k * n + j];
            b[i] -= f * b[k];
        }
    for (size_t i = n; i-- > 0;) {
        for (size_t j = i + 1; j < n; j++)
            b[i] -= a[i * n + j] * b[j];
        b[i] /= a[i * n + i];
    }
}

/* One half-sweep of the weighted alternating least squares: each of the n
 * vectors y (n x J, row-major) fitted to its line of the cells, the other
 * side's m vectors z fixed.  Cell (i, k) of the line is x[i * si + k * sk],
 * its weight w[i * wi + k * wk]. */
static void als_side(double *y, const double *z, size_t n, size_t m, size_t J, const double *x, size_t si, size_t sk,
                     const double *w, size_t wi, size_t wk) {
    double a[BANDFIT_MAXJ * BANDFIT_MAXJ], b[BANDFIT_MAXJ];
    for (size_t i = 0; i < n; i++) {
        memset(a, 0, sizeof a);
        memset(b, 0, sizeof b);
        for (size_t k = 0; k < m; k++) {
            double wt = w[i * wi + k * wk], xv = x[i * si + k * sk];
            if (!(wt > 0)) continue;
            for (size_t p = 0; p < J; p++) {
                b[p] += wt * xv * z[k * J + p];
                for (size_t q = 0; q < J; q++)
                    a[p * J + q] += wt * z[k * J + p] * z[k * J + q];
            }
        }
        solve_small(a, b, J);
        memcpy(y + i * J, b, J * sizeof *b);
    }
}

/* The weighted fit of one channel: u (rows x J) and v (cols x J) start at
 * the plain fit's textures and end as the weighted fit's. */
static void weighted_channel(const sb_matrix_t *m, const double *x, const double *w, double *u, double *v, size_t J) {
    for (int it = 0; it < BANDFIT_ITERS; it++) {
        als_side(v, u, m->cols, m->rows, J, x, m->ld, 1, w, m->rows, 1);
        als_side(u, v, m->rows, m->cols, J, x, 1, m->ld, w, 1, m->rows);
    }
}

static sb_result_t weighted_fit(sb_context_t *ctx, job_attempt_t *a, const double *cw, const unsigned char *band,
                                double wband, sb_factors_t *f0) {
    sb_matrix_t *m = &a->m;
    size_t J = sb_factors_terms(f0), R = m->rows, C = m->cols;
    double *w = malloc(R * C * sizeof *w), *u = malloc(R * J * sizeof *u), *v = malloc(C * J * sizeof *v);
    sb_result_t r = w && u && v ? job_factors_copy(ctx, f0, J, &a->f) : sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    for (size_t i = 0; r == SB_OK && i < R * C; i++)
        w[i] = cw[i] * (band[i] ? 1 + wband : 1);
    for (size_t ch = 0; r == SB_OK && ch < sb_factors_channels(f0) && ch < 3; ch++) {
        if (!m->data[ch]) continue;
        for (size_t j = 0; j < J; j++) {
            for (size_t i = 0; i < R; i++)
                u[i * J + j] = sb_factors_tex_const(f0, 0, j, ch)[i];
            for (size_t k = 0; k < C; k++)
                v[k * J + j] = sb_factors_tex_const(f0, 1, j, ch)[k];
        }
        weighted_channel(m, m->data[ch], w, u, v, J);
        for (size_t j = 0; j < J; j++) {
            for (size_t i = 0; i < R; i++)
                sb_factors_tex(a->f, 0, j, ch)[i] = u[i * J + j];
            for (size_t k = 0; k < C; k++)
                sb_factors_tex(a->f, 1, j, ch)[k] = v[k * J + j];
        }
    }
    free(w);
    free(u);
    free(v);
    return r;
}

static sb_result_t try_weights(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a,
                               const unsigned char *band, const double *cw) {
    size_t J = sb_factors_terms(a->f);
    double h0 = sb_estimate_headline(a->est, J), b0 = a->est->band[J - 1][SB_BAND_TI80][3];
    sb_factors_t *f0 = a->f;
    sb_estimate_t e0 = *a->est;
    sb_metric_t m0 = a->metric;
    sb_result_t r = SB_OK;
    a->f = NULL;
    for (size_t k = 0; k < sizeof bandfit_weights / sizeof *bandfit_weights && r == SB_OK; k++) {
        sb_factors_destroy(a->f);
        a->f = NULL;
        if ((r = weighted_fit(ctx, a, cw, band, bandfit_weights[k], f0)) != SB_OK) break;
        if ((r = job_measure(ctx, job, lv, a)) != SB_OK) break;
        double h = sb_estimate_headline(a->est, J), b = a->est->band[J - 1][SB_BAND_TI80][3];
        if (sb_estimate_bands_bounded(a->est, J) == 1 && h <= BANDFIT_HEADLINE * h0 && b < b0) {
            a->band_weight = 1 + bandfit_weights[k];
            sb_factors_destroy(f0);
            return r;
        }
    }
    sb_factors_destroy(a->f); /* none kept them: the plain fit as it was */
    a->f = f0;
    *a->est = e0;
    a->metric = m0;
    return r;
}

/* Each cell's weight: its pair measure (the plain fit's), times 1 + w
 * where the light lies in the band.  The gain squared (the headline's own
 * weight of a cell) changed nothing on RGL paper (headline and bands
 * within 0.1 %). */
static void cell_weights(const job_attempt_t *a, unsigned char *band, double *cw) {
    const sb_matrix_t *m = &a->m;
    for (size_t c = 0; c < m->cols; c++)
        for (size_t row = 0; row < m->rows; row++) {
            double wi[3], wo[3];
            int in = sb_param_cell_dirs(a->param, row, c, wi, wo);
            band[row + c * m->rows] = (unsigned char)(in && wi[2] < BANDFIT_HI && wi[2] > BANDFIT_LO);
            cw[row + c * m->rows] = sb_param_row_measure(a->param, row) * sb_param_col_measure(a->param, c);
        }
}

sb_result_t job_band_refit(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a) {
    a->band_weight = 0;
    if (!applies(job, lv, a) || sb_factors_terms(a->f) > BANDFIT_MAXJ) return SB_OK;
    const sb_matrix_t *m = &a->m;
    double *cw = malloc(m->rows * m->cols * sizeof(double));
    unsigned char *band = malloc(m->rows * m->cols);
    sb_result_t r = band && cw ? SB_OK : sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    if (r == SB_OK) {
        cell_weights(a, band, cw);
        r = try_weights(ctx, job, lv, a, band, cw);
    }
    free(band);
    free(cw);
    return r;
}

sb_result_t job_band_refit_prefix(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a, size_t k,
                                  double max_error, int *kept) {
    *kept = 0;
    if (!a->param || !(sb_param_caps(a->param) & SB_CAP_TABLES) || !a->est || k < 1 || k >= sb_factors_terms(a->f) ||
        k > a->est->terms)
        return SB_OK;
    job_attempt_t t = *a; /* a's matrix and layout; its own factors and estimate */
    t.f = NULL;
    t.term_w = NULL;
    if (!(t.est = malloc(sizeof *t.est))) return sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    *t.est = *a->est;
    t.est->terms = k; /* the prefix's errors, measured with the others */
    if (t.metric.terms > k) t.metric.terms = k;
    sb_result_t r = job_factors_copy(ctx, a->f, k, &t.f);
    if (r == SB_OK) r = job_band_refit(ctx, job, lv, &t);
    if (r == SB_OK && t.band_weight > 0 && sb_estimate_headline(t.est, k) <= max_error) {
        job_attempt_adopt(a, &t);
        free(a->term_w);
        a->term_w = NULL; /* the refit's terms are its own */
        a->band_weight = t.band_weight;
        a->t_estimate += t.t_estimate;
        *kept = 1;
        return SB_OK;
    }
    sb_factors_destroy(t.f);
    free(t.est);
    return r;
}
