/* Private: the one routine for the errors of a factorisation (errors.c).
 *
 * For a channel A with valid cells V (mask), weights W_r, W_c (square
 * roots of the cell measures; identity when unweighted) and textures
 * g_j, h_j in native units, for every truncation J' = 1..J:
 *     ssq[J'-1] = sum_V (w_r (A - sum_{j<=J'} g_j h_j^T) w_c pw)^2,
 *     mx[J'-1]  = max_V |A - sum_{j<=J'} g_j h_j^T|      (native units),
 *     n2        = sum_V (w_r A w_c pw)^2,
 * in one pass over the columns, split among threads (per-thread sums
 * added in a fixed order: the same bits on any thread count).  pw is a
 * power of two near 1 / max |A| (sb_pow2_scale), so the squares neither
 * underflow nor overflow; rel_rms = sqrt(ssq / n2) does not depend on it. */
#ifndef SEPBRDF_ERRORS_H
#define SEPBRDF_ERRORS_H

#include "sepbrdf/factor.h"

typedef struct sb_resid {
    size_t rows, cols, terms;
    const double *a; /* the channel, column-major with leading dimension ld */
    size_t ld;
    const unsigned char *mask; /* ld too; NULL = every cell valid */
    const double *wr, *wc;     /* rows / cols weights, NULL = unweighted */
    double pw;
    const double *g, *h; /* texture of term 0; term j at g + j * gstep (rows values), h likewise */
    size_t gstep, hstep;
} sb_resid_t;

/* Doubles of scratch sb_resid_channel needs for `threads` threads. */
size_t sb_resid_scratch(size_t rows, size_t terms, int threads);

/* ssq and mx receive `terms` values, *n2 one (see above). */
void sb_resid_channel(const sb_resid_t *in, int threads, double *scratch, double *ssq, double *mx, double *n2);

/* The residual pass of sb_resid_channel on a matrix read in blocks of
 * columns (sb_matrix_cols: a streamed one is evaluated once), every
 * channel of m in the same pass.  g[c], h[c]: channel c's textures (term
 * 0, steps gstep, hstep; g[c] NULL: channel skipped); weights wr, wc
 * (NULL: unweighted); ssq and mx receive 3 J values (channel c at c J),
 * n2 three, zero for skipped channels.  In a group of processes (common.h)
 * each reads its own blocks and the sums and maxima are combined over the
 * group.  Errors: SB_ERR_NOMEM, those of sb_matrix_cols and of the group. */
sb_result_t sb_resid_blocks(sb_context_t *ctx, const sb_matrix_t *m, size_t J, const double *const g[3],
                            const double *const h[3], size_t gstep, size_t hstep, const double *wr, const double *wc,
                            double pw, double *ssq, double *mx, double *n2);

/* Relative errors from the per-channel sums: rel_rms[sb_err_at(t, c)] =
 * sqrt(ssq[c * J + t] / n2[c]) for the present channels, SB_CH_ALL the
 * channels together, sqrt(sum_c ssq / sum_c n2); max_abs (may be NULL)
 * from mx[c * J + t] likewise, index 3 the largest.  Channels not present
 * stay 0.  SB_ERR_NUMERIC when an error is not finite. */
sb_result_t sb_errors_relative(sb_context_t *ctx, size_t J, const int present[3], const double *ssq, const double *mx,
                               const double n2[3], double *rel_rms, double *max_abs);

/* A number that changes with every change of f's texels, sigma, meta,
 * terms or tables (not its errors: sb_factors_errors_mut) and that no
 * other factors ever had: what was made from f (sb_factors_quantize's
 * stored factors, less their copy of the errors) is f's while the stamp is
 * the same.  0 for NULL. */
unsigned long long sb_factors_stamp(sb_factors_t *f);

/* Whether f is an exact truncated SVD of every channel it was fitted to,
 * in the fit's own norm: W_r G, W_c H span leading singular vectors of
 * W_r M W_c, so every prefix's residual R_J' has U_J'^T R_J' = 0 and
 * R_J' V_J' = 0 (sb_factors_errors_near uses it).  sb_plan_execute marks
 * the fits of solvers with SB_CAP_EXACT_TAILS on the cell measures'
 * weights; any write access to texels or sigma (sb_factors_tex,
 * sb_factors_set_sigma) clears it, and a copy does not have it. */
void sb_factors_mark_exact(sb_factors_t *f);
int sb_factors_exact(const sb_factors_t *f);

/* SB_OK where f's textures fit m (and weights, if given), else
 * SB_ERR_ARG with a message. */
sb_result_t sb_errors_check_fit(sb_context_t *ctx, const sb_factors_t *f, const sb_matrix_t *m,
                                const sb_param_t *weights);

/* Keep the first `keep` terms of f (1 <= keep <= terms; else nothing). */
void sb_factors_truncate(sb_factors_t *f, size_t keep);

/* wr[i] = sqrt(max(row measure i, 0)), wc likewise: the weights of a
 * weighted fit on parameterisation p. */
void sb_errors_weights(const sb_param_t *p, double *wr, double *wc);

#endif
