/* Errors of given factors against a sampled matrix, for factors that
 * changed after the fit (rounded to the stored precision, read back from
 * files, edited).  Same measure as sb_plan_execute: on the valid cells of
 * M, for every J' = 1..J,
 *     rel_rms = ||W_r (M - sum_{j<=J'} g_j h_j^T) W_c||_F / ||W_r M W_c||_F
 * with W = diag(sqrt(cell measure)) for weighted fits and W = I otherwise,
 * and max_abs = max |M - sum g_j h_j^T| in native units.
 *
 * Sums of squares are taken on values divided by a power of two near
 * max |M| (exact), so matrices of 1e-300 or 1e200 neither underflow to a
 * zero norm nor overflow to an infinite one.  One pass over the columns,
 * one column of scratch. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"
#include "sepbrdf/factor.h"

sb_result_t sb_factors_errors_against(sb_context_t *ctx, const sb_factors_t *f, const sb_matrix_t *m,
                                      const sb_param_t *weights, double *rel_rms, double *max_abs) {
    if (!f || !m || !rel_rms || !max_abs) return sb_error(ctx, SB_ERR_ARG, "errors: missing argument");
    size_t J = sb_factors_terms(f), C = sb_factors_channels(f), rows = m->rows, cols = m->cols, gw, gh, hw, hh;
    sb_factors_size(f, SB_SIDE_G, &gw, &gh);
    sb_factors_size(f, SB_SIDE_H, &hw, &hh);
    if (gw * gh != rows || hw * hh != cols)
        return sb_error(ctx, SB_ERR_ARG,
                        "errors: factors of %zu x %zu and %zu x %zu texels do not fit a %zu x %zu matrix", gw, gh, hw,
                        hh, rows, cols);
    if (weights && (sb_param_rows(weights) != rows || sb_param_cols(weights) != cols))
        return sb_error(ctx, SB_ERR_ARG, "errors: the weighting parameterisation does not match the matrix");
    memset(rel_rms, 0, J * 4 * sizeof *rel_rms);
    memset(max_abs, 0, J * 4 * sizeof *max_abs);

    /* Step: power-of-two scale of the largest valid |M| over all channels */
    double amax = 0;
    for (int ch = 0; ch < 3; ch++) {
        const double *a = m->data[ch];
        if (!a) continue;
        for (size_t c = 0; c < cols; c++)
            for (size_t i = 0; i < rows; i++)
                if (!m->mask || m->mask[i + c * m->ld]) amax = fmax(amax, fabs(a[i + c * m->ld]));
    }
    double sc = 1;
    if (amax > 0 && isfinite(amax)) {
        int e;
        frexp(amax, &e); /* amax * sc in [0.5, 1), clamped: 2^1074 would overflow for denormal data */
        sc = ldexp(1, e > 1020 ? -1020 : (e < -1020 ? 1020 : -e));
    }

    size_t scratch;
    if (sb_size_add(rows, weights ? rows + cols : 0, &scratch) || sb_size_add(scratch, 2 * J, &scratch))
        return sb_error(ctx, SB_ERR_OVERFLOW, "errors: scratch size overflows");
    double *r = sb_alloc(ctx, scratch, sizeof(double), "errors scratch");
    if (!r) return SB_ERR_NOMEM;
    double *ssq = r + rows, *wr = ssq + J, *wc = weights ? wr + rows : NULL;
    if (!weights) wr = NULL;
    if (weights) {
        for (size_t i = 0; i < rows; i++)
            wr[i] = sqrt(fmax(sb_param_row_measure(weights, i), 0));
        for (size_t i = 0; i < cols; i++)
            wc[i] = sqrt(fmax(sb_param_col_measure(weights, i), 0));
    }

    /* Step: residual columns, every truncation in one pass */
    double total2 = 0, *tail2 = calloc(J, sizeof *tail2); /* per J', summed over channels */
    if (!tail2) {
        free(r);
        return sb_error(ctx, SB_ERR_NOMEM, "errors: out of memory");
    }
    for (int ch = 0; ch < 3; ch++) {
        const double *a = m->data[ch];
        if (!a) continue;
        size_t fc = C == 1 ? 0 : (size_t)ch;
        double n2 = 0;
        for (size_t j = 0; j < J; j++)
            ssq[j] = 0;
        for (size_t c = 0; c < cols; c++) {
            const unsigned char *mk = m->mask ? m->mask + c * m->ld : NULL;
            double w_c = wc ? wc[c] * sc : sc;
            for (size_t i = 0; i < rows; i++) {
                r[i] = a[i + c * m->ld];
                if (mk && !mk[i]) continue;
                double x = (wr ? wr[i] : 1) * r[i] * w_c;
                n2 += x * x;
            }
            for (size_t j = 0; j < J; j++) {
                const double *g = sb_factors_tex_const(f, SB_SIDE_G, j, fc);
                double hv = sb_factors_tex_const(f, SB_SIDE_H, j, fc)[c], s2 = 0;
                for (size_t i = 0; i < rows; i++) {
                    r[i] -= g[i] * hv;
                    if (mk && !mk[i]) continue;
                    double d = (wr ? wr[i] : 1) * r[i] * w_c;
                    s2 += d * d;
                    double ad = fabs(r[i]);
                    if (ad > max_abs[j * 4 + (size_t)ch]) max_abs[j * 4 + (size_t)ch] = ad;
                }
                ssq[j] += s2;
            }
        }
        total2 += n2;
        for (size_t j = 0; j < J; j++) {
            rel_rms[j * 4 + (size_t)ch] = n2 > 0 ? sqrt(ssq[j] / n2) : 0;
            tail2[j] += ssq[j];
            if (max_abs[j * 4 + (size_t)ch] > max_abs[j * 4 + 3]) max_abs[j * 4 + 3] = max_abs[j * 4 + (size_t)ch];
        }
    }
    sb_result_t res = SB_OK;
    for (size_t j = 0; j < J; j++) {
        rel_rms[j * 4 + 3] = total2 > 0 ? sqrt(tail2[j] / total2) : 0;
        if (!isfinite(rel_rms[j * 4 + 3]) && res == SB_OK)
            res = sb_error(ctx, SB_ERR_NUMERIC, "errors: non-finite error after %zu terms", j + 1);
    }
    free(tail2);
    free(r);
    return res;
}
