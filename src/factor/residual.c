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
#include <cblas.h>
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sepbrdf/factor.h"
#include "util/internal.h"

/* rel_rms of all channels together (index 3) from the per-J' sums. */
static sb_result_t all_channels(sb_context_t *ctx, size_t J, double total2, const double *tail2, double *rel_rms) {
    sb_result_t res = SB_OK;
    for (size_t j = 0; j < J; j++) {
        rel_rms[j * 4 + 3] = total2 > 0 ? sqrt(tail2[j] / total2) : 0;
        if (!isfinite(rel_rms[j * 4 + 3]) && res == SB_OK)
            res = sb_error(ctx, SB_ERR_NUMERIC, "errors: non-finite error after %zu terms", j + 1);
    }
    return res;
}

sb_result_t sb_factors_errors_against(sb_context_t *ctx, const sb_factors_t *f, const sb_matrix_t *m,
                                      const sb_param_t *weights, double *rel_rms, double *max_abs) {
    if (!f || !m || !rel_rms || !max_abs) return sb_error(ctx, SB_ERR_ARG, "errors: missing argument");
    if (m->ld < m->rows) return sb_error(ctx, SB_ERR_ARG, "errors: leading dimension %zu < %zu rows", m->ld, m->rows);
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
    sb_result_t res = all_channels(ctx, J, total2, tail2, rel_rms);
    free(tail2);
    free(r);
    return res;
}

/* Errors of factors `near` close to the fit `fit` (its rounding to the
 * stored precision), without a residual pass.  Per channel, in the fitted
 * (weighted) norm, with R = X - G H^T the residual of the fit, whose norm
 * the fit knows, and D = G H^T - G~ H~^T = dG H^T + G~ dH^T:
 *   ||X - G~ H~^T||^2 = ||R||^2 + 2 (<X, D> - <G H^T, D>) + ||D||^2
 *   <X, D>      = sum_b dg_b . (X h_b) + g~_b . (X dh_b)
 *   <G H^T, D>  = sum_ab (g_a . dg_b)(h_a . h_b) + (g_a . g~_b)(h_a . dh_b)
 *   ||D||^2     = sum_ab (dg_a . dg_b)(h_a . h_b) + 2 (dg_a . g~_b)(h_a . dh_b)
 *                        + (g~_a . g~_b)(dh_a . dh_b)
 * (<A B^T, C D^T> = sum_ab (a_a . c_b)(b_a . d_b)); every term is built
 * from the small differences dG, dH themselves, so nothing cancels beyond
 * eps ||X|| ||D||.  One product X [H, dH] per channel is the only read of
 * the matrix.  Values are scaled by powers of two near 1 / ||X|| (exact). */
static void gram(size_t n, size_t J, const double *a, const double *b, double *out) {
    cblas_dgemm(CblasColMajor, CblasTrans, CblasNoTrans, (int)J, (int)J, (int)n, 1.0, a, (int)n, b, (int)n, 0.0, out,
                (int)J);
}

sb_result_t sb_factors_errors_near(sb_context_t *ctx, const sb_factors_t *fit, const sb_factors_t *near,
                                   const sb_matrix_t *m, const sb_param_t *weights, double *rel_rms) {
    if (!fit || !near || !m || !rel_rms) return sb_error(ctx, SB_ERR_ARG, "errors: missing argument");
    if (m->ld < m->rows) return sb_error(ctx, SB_ERR_ARG, "errors: leading dimension %zu < %zu rows", m->ld, m->rows);
    if (m->mask) return sb_error(ctx, SB_ERR_ARG, "errors: a masked matrix needs the explicit residual");
    sb_result_t rb = sb_blas_reserve(ctx);
    if (rb != SB_OK) return rb;
    size_t J = sb_factors_terms(fit), C = sb_factors_channels(fit), rows = m->rows, cols = m->cols, gw, gh, hw, hh;
    sb_factors_size(fit, SB_SIDE_G, &gw, &gh);
    sb_factors_size(fit, SB_SIDE_H, &hw, &hh);
    size_t nw, nh;
    sb_factors_size(near, SB_SIDE_G, &nw, &nh);
    if (gw * gh != rows || hw * hh != cols || nw * nh != rows || sb_factors_terms(near) != J ||
        sb_factors_channels(near) != C || J > INT_MAX / 2 || rows > INT_MAX || cols > INT_MAX)
        return sb_error(ctx, SB_ERR_ARG, "errors: factors do not fit each other or the %zu x %zu matrix", rows, cols);
    if (weights && (sb_param_rows(weights) != rows || sb_param_cols(weights) != cols))
        return sb_error(ctx, SB_ERR_ARG, "errors: the weighting parameterisation does not match the matrix");
    const sb_factor_errors_t *fe = sb_factors_errors(fit);
    memset(rel_rms, 0, J * 4 * sizeof *rel_rms);
    /* Step: scales 2^-e ~ 1 / ||X||, split between the two sides */
    int ex = 0;
    if (fe->norm[3] > 0 && isfinite(fe->norm[3])) frexp(fe->norm[3], &ex);
    ex = ex > 1000 ? 1000 : (ex < -1000 ? -1000 : ex);
    double sx = ldexp(1, -ex), sg = ldexp(1, -(ex / 2)), sh = ldexp(1, -(ex - ex / 2));

    /* Step: workspace: G, G~, dG (rows x J); H, dH together, then Z (cols x 2J); Y = M Z; Gram blocks */
    size_t nr, nc, total;
    if (sb_size_mul(rows, 3 * J, &nr) || sb_size_mul(cols, 4 * J, &nc) || sb_size_add(nr, nc, &total) ||
        sb_size_add(total, rows * 2 * J + 8 * J * J + rows + cols, &total))
        return sb_error(ctx, SB_ERR_OVERFLOW, "errors: workspace size overflows");
    double *ws = sb_alloc(ctx, total, sizeof(double), "errors workspace");
    if (!ws) return SB_ERR_NOMEM;
    double *G = ws, *Gq = G + rows * J, *dG = Gq + rows * J, *HdH = dG + rows * J, *Z = HdH + cols * 2 * J,
           *Y = Z + cols * 2 * J, *gr = Y + rows * 2 * J, *wr = gr + 8 * J * J, *wc = wr + rows;
    double *GdG = gr, *HH = GdG + J * J, *GGq = HH + J * J, *HdH2 = GGq + J * J, *dGdG = HdH2 + J * J,
           *dGGq = dGdG + J * J, *GqGq = dGGq + J * J, *dHdH = GqGq + J * J;
    for (size_t i = 0; i < rows; i++)
        wr[i] = weights ? sqrt(fmax(sb_param_row_measure(weights, i), 0)) : 1;
    for (size_t i = 0; i < cols; i++)
        wc[i] = weights ? sqrt(fmax(sb_param_col_measure(weights, i), 0)) : 1;
    double total2 = 0, *tail2 = calloc(J, sizeof *tail2);
    if (!tail2) {
        free(ws);
        return sb_error(ctx, SB_ERR_NOMEM, "errors: out of memory");
    }
    for (int ch = 0; ch < 3; ch++) {
        const double *a = m->data[ch];
        if (!a) continue;
        size_t fc = C == 1 ? 0 : (size_t)ch;
        /* Step: weighted, scaled factors and their differences */
        for (size_t j = 0; j < J; j++) {
            const double *g = sb_factors_tex_const(fit, SB_SIDE_G, j, fc),
                         *q = sb_factors_tex_const(near, SB_SIDE_G, j, fc);
            const double *h = sb_factors_tex_const(fit, SB_SIDE_H, j, fc),
                         *p = sb_factors_tex_const(near, SB_SIDE_H, j, fc);
            for (size_t i = 0; i < rows; i++) {
                G[i + j * rows] = wr[i] * g[i] * sg;
                Gq[i + j * rows] = wr[i] * q[i] * sg;
                dG[i + j * rows] = wr[i] * (g[i] - q[i]) * sg;
            }
            for (size_t i = 0; i < cols; i++) {
                HdH[i + j * cols] = wc[i] * h[i] * sh;
                HdH[i + (J + j) * cols] = wc[i] * (h[i] - p[i]) * sh;
            }
        }
        /* Step: Y = X [H, dH] = W_r M (W_c [H, dH]) (one read of M) */
        for (size_t i = 0; i < cols * 2 * J; i++)
            Z[i] = HdH[i] * wc[i % cols] * sx;
        cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, (int)rows, (int)(2 * J), (int)cols, 1.0, a, (int)m->ld,
                    Z, (int)cols, 0.0, Y, (int)rows);
        for (size_t i = 0; i < rows * 2 * J; i++)
            Y[i] *= wr[i % rows];
        /* Step: Gram blocks */
        gram(rows, J, G, dG, GdG);
        gram(rows, J, G, Gq, GGq);
        gram(rows, J, dG, dG, dGdG);
        gram(rows, J, dG, Gq, dGGq);
        gram(rows, J, Gq, Gq, GqGq);
        gram(cols, J, HdH, HdH, HH);
        gram(cols, J, HdH, HdH + cols * J, HdH2);
        gram(cols, J, HdH + cols * J, HdH + cols * J, dHdH);
        /* Step: prefix sums over J' */
        double nx = fe->norm[ch] * sx, xd = 0, gd = 0, dd = 0;
        total2 += nx * nx;
        for (size_t b = 0; b < J; b++) {
            /* Y[:, b] = X h_b scaled by sx sh; the dG, G~ carry sg: sx sg sh = sx^2 */
            for (size_t i = 0; i < rows; i++)
                xd += dG[i + b * rows] * Y[i + b * rows] + Gq[i + b * rows] * Y[i + (J + b) * rows];
            /* pairs (a, b) with max(a, b) == b */
            for (size_t a2 = 0; a2 <= b; a2++) {
                size_t ab = a2 + b * J, ba = b + a2 * J;
                gd += GdG[ab] * HH[ab] + GGq[ab] * HdH2[ab];
                dd += dGdG[ab] * HH[ab] + 2 * dGGq[ab] * HdH2[ab] + GqGq[ab] * dHdH[ab];
                if (a2 != b) {
                    gd += GdG[ba] * HH[ba] + GGq[ba] * HdH2[ba];
                    dd += dGdG[ba] * HH[ba] + 2 * dGGq[ba] * HdH2[ba] + GqGq[ba] * dHdH[ba];
                }
            }
            double r = fe->rel_rms[b * 4 + (size_t)ch] * nx, s2 = r * r + 2 * (xd - gd) + dd;
            if (s2 < 0) s2 = 0;
            rel_rms[b * 4 + (size_t)ch] = nx > 0 ? sqrt(s2) / nx : 0;
            tail2[b] += s2;
        }
    }
    sb_result_t res = all_channels(ctx, J, total2, tail2, rel_rms);
    free(tail2);
    free(ws);
    return res;
}
