/* Where the error is (estimate.h: band, p99_lit, min_rel, map): the
 * headline's ratio restricted to angular bands, the per-pair relative
 * errors where the BRDF is lit, the most negative reconstructed value and
 * the error per (theta_i, theta_o) cell, from the same reconstruction and
 * the same pairs as the headline.  Sums per replicate (bands, map) and per
 * thread in integers or by min/max (histograms, extremes), so the results
 * are the same to the bit on any thread count, as the headline's. */
#include <float.h>
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "factor/estimate_impl.h"
#include "factor/estimate_pair.h"
#include "util/internal.h"

const double sb_band_map_edges[SB_EST_MAP + 1] = {0, 20, 40, 60, 70, 80, 85, 88, 89, 90};

static const char *const band_names[SB_BAND_COUNT_] = {"theta_i_60", "theta_i_80", "theta_i_89", "theta_o_60",
                                                       "theta_o_80", "theta_o_89", "specular",   "retro"};

double est_map_cos[SB_EST_MAP + 1];

const char *sb_band_name(int band) { return band >= 0 && band < SB_BAND_COUNT_ ? band_names[band] : NULL; }

unsigned sb_band_mask(const double wi[3], const double wo[3]) { return wi && wo ? est_band_mask(wi, wo) : 0; }

int sb_estimate_bands_bounded(const sb_estimate_t *est, size_t j) {
    if (!est || j < 1 || j > est->terms) return -1;
    const double h = est->rel[j - 1][SB_EST_FCOS][3];
    const double *b80 = est->band[j - 1][SB_BAND_TI80], *b89 = est->band[j - 1][SB_BAND_TI89];
    const double s80 = est->band_se[j - 1][SB_BAND_TI80][3], s89 = est->band_se[j - 1][SB_BAND_TI89][3];
    if (!(est->band_share[SB_BAND_TI80] > 0) || !isfinite(h)) return -1;
    return b80[3] - 2 * s80 <= fmax(3 * h, 0.01) && b89[3] - 2 * s89 <= fmax(10 * h, 0.05);
}

int sb_estimate_worst_band(const sb_estimate_t *est, size_t j) {
    int w = -1;
    for (int b = 0; est && j >= 1 && j <= est->terms && b < SB_BAND_COUNT_; b++) {
        double v = est->band[j - 1][b][3];
        if (isfinite(v) && (w < 0 || v > est->band[j - 1][w][3])) w = b;
    }
    return w;
}

/* ---- histograms --------------------------------------------------------- */

/* log2 x (est_log2, estimate_impl.h): the table of log2 of the mantissa.
 * libm's log10 per pair, term and channel was a quarter of a whole io
 * run, a polynomial with its division half of the estimator's loop. */
double est_log2_tab[EST_LOG2_STEPS + 1];
static pthread_once_t log2_once = PTHREAD_ONCE_INIT;
static void log2_fill(void) {
    for (int i = 0; i <= EST_LOG2_STEPS; i++)
        est_log2_tab[i] = log2(1 + (double)i / EST_LOG2_STEPS);
    for (int k = 0; k <= SB_EST_MAP; k++)
        est_map_cos[k] = cos(sb_band_map_edges[k] * SB_PI / 180);
}

void est_log2_init(void) { pthread_once(&log2_once, log2_fill); }

double est_hist_p99(const uint64_t *hist, size_t stride, int nt, double mx) {
    uint64_t hb[NB] = {0}, total = 0, acc = 0;
    for (int t = 0; t < nt; t++)
        for (size_t b = 0; b < NB; b++)
            hb[b] += hist[(size_t)t * stride + b];
    for (size_t b = 0; b < NB; b++)
        total += hb[b];
    size_t b = 0;
    while (b + 1 < NB && (acc += hb[b]) < total - total / 100)
        b++;
    return total ? fmin(pow(10, (double)(b + 1) / 40 - 12), mx) : 0;
}

/* se of r^2 = sd_k(N_k - r^2 D_k) / (sqrt(K) mean D), se of r = se(r^2) / (2 r) */
void est_ratio(const double *num, size_t ns, const double *den, size_t ds, size_t K, double *r, double *se) {
    double n = 0, d = 0, v = 0;
    for (size_t k = 0; k < K; k++)
        n += num[k * ns], d += den[k * ds];
    double r2 = d > 0 ? n / d : (n > 0 ? INFINITY : 0);
    for (size_t k = 0; k < K && isfinite(r2); k++) {
        double x = num[k * ns] - r2 * den[k * ds];
        v += x * x;
    }
    double se2 = d > 0 && K > 1 ? sqrt(v / (double)(K - 1)) * sqrt((double)K) / d : 0;
    *r = sqrt(r2);
    *se = *r > 0 ? se2 / (2 * *r) : sqrt(se2);
}

/* ---- the sums ------------------------------------------------------------ */

sb_result_t est_bands_alloc(sb_context_t *ctx, eval_t *e, size_t kmax, int nt, size_t reps) {
    size_t J = e->J, T = (size_t)nt;
    const sb_pairs_t *P = e->P;
    e->bnum = sb_alloc(ctx, kmax * J, BQ * sizeof *e->bnum, "estimator band sums");
    e->bden = sb_alloc(ctx, kmax, BQ * sizeof *e->bden, "estimator band sums");
    e->mnum = sb_alloc(ctx, kmax, MM * sizeof *e->mnum, "estimator band sums");
    e->mden = sb_alloc(ctx, kmax, MM * sizeof *e->mden, "estimator band sums");
    size_t L = e->headline_only ? 1 : T * J; /* the lit sums: not with headline_only */
    e->hlit = sb_calloc(ctx, L * 4, NB * sizeof *e->hlit, "estimator histograms");
    size_t TL = e->headline_only ? 1 : T; /* per thread blocks of J * 4 (est_tstride) */
    e->maxl = sb_calloc(ctx, TL, est_tstride(J * 4) * sizeof *e->maxl, "estimator band sums");
    e->minv = sb_calloc(ctx, TL, est_tstride(J * 4) * sizeof *e->minv, "estimator band sums");
    /* the lit thresholds: 1 % of the largest f cos theta_i of the first 16 replicates */
    memset(e->lit_thr, 0, sizeof e->lit_thr);
    for (size_t i = 0; i < (reps < 16 ? reps : 16) * P->rep && i < P->n; i++) {
        const double *d = P->d + i * PD, *f = d + 7;
        if (!P->known[i]) continue;
        for (int c = 0; c < 3; c++)
            e->lit_thr[c] = fmax(e->lit_thr[c], 0.01 * fabs(f[c]) * d[2]);
        e->lit_thr[3] = fmax(e->lit_thr[3], 0.01 * sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]) * d[2]);
    }
    return e->bnum && e->bden && e->mnum && e->mden && e->hlit && e->maxl && e->minv ? SB_OK : SB_ERR_NOMEM;
}

void est_bands_clear(const eval_t *e, size_t k) {
    memset(e->bnum + k * e->J * BQ, 0, e->J * BQ * sizeof *e->bnum);
    memset(e->bden + k * BQ, 0, BQ * sizeof *e->bden);
    memset(e->mnum + k * MM, 0, MM * sizeof *e->mnum);
    memset(e->mden + k * MM, 0, MM * sizeof *e->mden);
}

void est_bands_combine(const eval_t *e, size_t K, int nt, size_t jlo, sb_estimate_t *out) {
    size_t J = e->J;
    double all = 0, share[SB_BAND_COUNT_] = {0};
    for (size_t k = 0; k < K; k++)
        for (int b = 0; b < SB_BAND_COUNT_; b++)
            share[b] += e->bden[k * BQ + b * 4 + 3];
    for (size_t k = 0; k < K; k++)
        for (size_t c = 0; c < MM; c++)
            all += e->mden[k * MM + c];
    for (int b = 0; b < SB_BAND_COUNT_; b++)
        out->band_share[b] = all > 0 ? share[b] / all : 0;
    for (size_t j = jlo; j < J; j++) {
        for (int i = 0; i < BQ; i++)
            est_ratio(e->bnum + j * BQ + i, J * BQ, e->bden + i, BQ, K, &out->band[j][i / 4][i % 4],
                      &out->band_se[j][i / 4][i % 4]);
        for (int c = 0; c < 4 && !e->headline_only; c++) {
            double mx = 0, mn = 0;
            for (int t = 0; t < nt; t++) {
                mx = fmax(mx, sqrt(e->maxl[(size_t)t * est_tstride(J * 4) + j * 4 + (size_t)c]));
                mn = fmin(mn, e->minv[(size_t)t * est_tstride(J * 4) + j * 4 + (size_t)c]);
            }
            out->p99_lit[j][c] = est_hist_p99(e->hlit + (j * 4 + (size_t)c) * NB, J * 4 * NB, nt, mx);
            out->max_rel_lit[j][c] = mx;
            out->min_rel[j][c] = mn;
        }
    }
    for (size_t c = 0; c < MM; c++) {
        double r, se;
        est_ratio(e->mnum + c, MM, e->mden + c, MM, K, &r, &se);
        int none = 1;
        for (size_t k = 0; k < K && none; k++)
            none = !(e->mden[k * MM + c] > 0);
        out->map[c / SB_EST_MAP][c % SB_EST_MAP] = none ? NAN : r;
    }
}

size_t est_bands_met(const eval_t *e, size_t K, unsigned mask, double rel_se) {
    size_t J = e->J;
    for (size_t j = 0; j < J; j++)
        for (unsigned m = mask; m; m &= m - 1) {
            size_t at = (size_t)__builtin_ctz(m) * 4 + 3;
            double r, se;
            est_ratio(e->bnum + j * BQ + at, J * BQ, e->bden + at, BQ, K, &r, &se);
            if (!(se <= rel_se * r)) return j;
        }
    return J;
}

void est_bands_free(eval_t *e) {
    free(e->bnum);
    free(e->bden);
    free(e->mnum);
    free(e->mden);
    free(e->hlit);
    free(e->maxl);
    free(e->minv);
}
