/* sb_factors_errors_near (factor.h): the errors of factors close to a
 * fit (its rounding to the stored precision) from the fit's own errors,
 * with at most one product with the matrix per channel, none for an
 * exact fit (sb_factors_exact). */
#include <cblas.h>
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "factor/errors.h"
#include "solve/solver.h"
#include "util/internal.h"

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
 * the matrix.  Where the fit's own error is large (rel_rms at J of at
 * least NEAR_DIRECT_REL, which every prefix's is too), the direct form
 *   ||X - G~ H~^T||^2 = ||X||^2 - 2 <X, G~ H~^T> + ||G~ H~^T||^2
 * loses at most eps ||X||^2 against ||R||^2 >= NEAR_DIRECT_REL^2 ||X||^2
 * (a relative 1e-13 here), and reads the matrix with J columns, X H~,
 * instead of 2 J: half of the product, which is most of this routine's
 * work (issue 36, round six).  Values are scaled by powers of two near
 * 1 / ||X|| (exact). */
#define NEAR_DIRECT_REL 0x1.0p-5
static void gram(size_t n, size_t J, const double *a, const double *b, double *out) {
    cblas_dgemm(CblasColMajor, CblasTrans, CblasNoTrans, (int)J, (int)J, (int)n, 1.0, a, (int)n, b, (int)n, 0.0, out,
                (int)J);
}

/* Workspace of sb_factors_errors_near: G~ (rows x J), H~ (cols x J), the
 * weights, the sums of squares (3 J), the Gram blocks (J x J each), Z
 * (cols x 2J), Y = M Z (rows x 2J), then G, dG (rows x J) and H, dH
 * together (cols x 2J).  In this order the direct form (which reads G~,
 * H~ and the first J columns of Z and Y only) touches the first 40 % of
 * it; where every channel takes the direct form only that part is made
 * (Y then follows Z's J columns), 1.0 MiB instead of 2.6 MiB at io R = 64:
 * on the heap's 2 MiB pages the rest took room the matrix product's
 * scratch then found above the heap's top, a huge page more to zero. */
typedef struct near_ws {
    size_t rows, cols, J;
    double *G, *Gq, *dG, *HdH, *Hq, *Z, *Y, *wr, *wc, *ssq;
    double *GdG, *HH, *GGq, *HdH2, *dGdG, *dGGq, *GqGq, *dHdH;
} near_ws_t;

static double *near_alloc(sb_context_t *ctx, near_ws_t *w, size_t rows, size_t cols, size_t J, int direct) {
    size_t nr, nc, total, k = direct ? 2 : 5;
    if (sb_size_mul(rows, k * J, &nr) || sb_size_mul(cols, k * J, &nc) || sb_size_add(nr, nc, &total) ||
        sb_size_add(total, 8 * J * J + rows + cols + 3 * J, &total)) {
        sb_error(ctx, SB_ERR_OVERFLOW, "errors: workspace size overflows");
        return NULL;
    }
    double *ws = sb_alloc(ctx, total, sizeof(double), "errors workspace");
    if (!ws) return NULL;
    *w = (near_ws_t){.rows = rows, .cols = cols, .J = J, .Gq = ws};
    w->Hq = w->Gq + rows * J;
    w->wr = w->Hq + cols * J;
    w->wc = w->wr + rows;
    w->ssq = w->wc + cols;
    double **blocks[] = {&w->GdG, &w->HH, &w->GGq, &w->HdH2, &w->dGdG, &w->dGGq, &w->GqGq, &w->dHdH};
    double *at = w->ssq + 3 * J;
    for (size_t i = 0; i < 8; i++, at += J * J) /* the Gram blocks, J x J each */
        *blocks[i] = at;
    w->Z = at;
    w->Y = w->Z + cols * (direct ? 1 : 2) * J;
    if (direct) return ws; /* G, dG, H and dH: the other form's */
    w->G = w->Y + rows * 2 * J;
    w->dG = w->G + rows * J;
    w->HdH = w->dG + rows * J;
    return ws;
}

/* What near_factors makes: NEAR_DIRECT G~ and H~, NEAR_EXACT G~, dG, H
 * and dH, NEAR_PRODUCTS all of them (G too). */
enum { NEAR_DIRECT = 1, NEAR_EXACT = 2, NEAR_PRODUCTS = 3 };

/* Step: weighted, scaled factors and their differences (channel fc), as
 * `what` says. */
static void near_factors(near_ws_t *w, const sb_factors_t *fit, const sb_factors_t *near, size_t fc, double sg,
                         double sh, int what) {
    size_t rows = w->rows, cols = w->cols, J = w->J;
    for (size_t j = 0; j < J; j++) {
        const double *g = sb_factors_tex_const(fit, SB_SIDE_G, j, fc),
                     *q = sb_factors_tex_const(near, SB_SIDE_G, j, fc);
        const double *h = sb_factors_tex_const(fit, SB_SIDE_H, j, fc),
                     *p = sb_factors_tex_const(near, SB_SIDE_H, j, fc);
        for (size_t i = 0; i < rows; i++)
            w->Gq[i + j * rows] = w->wr[i] * q[i] * sg;
        for (size_t i = 0; (what & NEAR_DIRECT) && i < cols; i++)
            w->Hq[i + j * cols] = w->wc[i] * p[i] * sh;
        if (!(what & NEAR_EXACT)) continue;
        for (size_t i = 0; i < rows; i++) {
            if (what & NEAR_DIRECT) w->G[i + j * rows] = w->wr[i] * g[i] * sg;
            w->dG[i + j * rows] = w->wr[i] * (g[i] - q[i]) * sg;
        }
        for (size_t i = 0; i < cols; i++) {
            w->HdH[i + j * cols] = w->wc[i] * h[i] * sh;
            w->HdH[i + (J + j) * cols] = w->wc[i] * (h[i] - p[i]) * sh;
        }
    }
}

/* The Gram blocks of dG, G~, H and dH (||D||^2's). */
static void near_grams(near_ws_t *w) {
    size_t rows = w->rows, cols = w->cols, J = w->J;
    const double *dH = w->HdH + cols * J;
    gram(rows, J, w->dG, w->dG, w->dGdG);
    gram(rows, J, w->dG, w->Gq, w->dGGq);
    gram(rows, J, w->Gq, w->Gq, w->GqGq);
    gram(cols, J, w->HdH, w->HdH, w->HH);
    gram(cols, J, w->HdH, dH, w->HdH2);
    gram(cols, J, dH, dH, w->dHdH);
}

/* Step: Y = X [H, dH] = W_r M (W_c [H, dH]) (one read of M), Gram blocks. */
static sb_result_t near_products(sb_context_t *ctx, near_ws_t *w, const sb_matrix_t *m, int ch, double sx) {
    size_t rows = w->rows, cols = w->cols, J = w->J;
    for (size_t i = 0; i < cols * 2 * J; i++)
        w->Z[i] = w->HdH[i] * w->wc[i % cols] * sx;
    sb_result_t r = sb_matrix_mul(ctx, m, ch, 2 * J, w->Z, cols, w->Y, rows); /* dense or structured */
    if (r != SB_OK) return r;
    for (size_t i = 0; i < rows * 2 * J; i++)
        w->Y[i] *= w->wr[i % rows];
    gram(rows, J, w->G, w->dG, w->GdG);
    gram(rows, J, w->G, w->Gq, w->GGq);
    near_grams(w);
    return SB_OK;
}

/* The Gram terms of the pairs (a, b) with max(a, b) == b added to *gd
 * (<G H^T, D>; NULL: not wanted) and *dd (||D||^2), pair by pair. */
static void pairs_step(const near_ws_t *w, size_t b, double *gd, double *dd) {
    size_t J = w->J;
    for (size_t a2 = 0; a2 <= b; a2++) {
        size_t idx[2] = {a2 + b * J, b + a2 * J};
        for (int t = 0; t < (a2 != b ? 2 : 1); t++) {
            size_t ab = idx[t];
            if (gd) *gd += w->GdG[ab] * w->HH[ab] + w->GGq[ab] * w->HdH2[ab];
            *dd += w->dGdG[ab] * w->HH[ab] + 2 * w->dGGq[ab] * w->HdH2[ab] + w->GqGq[ab] * w->dHdH[ab];
        }
    }
}

/* Step, exact fit (sb_factors_exact): every prefix's residual R_b = X -
 * G_b H_b^T has G_b^T R_b = 0 and R_b H_b = 0 (weighted, scaled), so with
 * D_b = dG_b H_b^T + G~_b dH_b^T
 *   <R_b, dG_b H_b^T> = <R_b H_b, dG_b> = 0,
 *   <R_b, G~_b dH_b^T> = <(G_b - dG_b)^T R_b, dH_b^T> = -tr(dG_b^T R_b dH_b),
 *   ||X - G~_b H~_b^T||^2 = ||R_b||^2 + ||D_b||^2 - 2 tr(dG_b^T R_b dH_b),
 * and |tr(dG^T R dH)| <= ||R||_2 ||dG||_F ||dH||_F <= ||R||_F ||dG||_F
 * ||dH||_F.  ssq[b] = ||R_b||^2 + ||D_b||^2 from the Gram blocks alone
 * (no read of the matrix) where that bound, doubled, is at most
 * NEAR_EXACT_TOL ||R_b||^2 for every b (float storage at io R = 64: about
 * 1e-15); returns 0 (ssq not final) otherwise: the matrix is read. */
#define NEAR_EXACT_TOL 0x1.0p-40
static int near_exact(near_ws_t *w, const double *rel, double nx, double *ssq) {
    size_t J = w->J;
    near_grams(w);
    double dd = 0, ng = 0, nh = 0;
    for (size_t b = 0; b < J; b++) {
        pairs_step(w, b, NULL, &dd);
        ng += w->dGdG[b + b * J];
        nh += w->dHdH[b + b * J];
        double r = rel[sb_err_at(b, 0)] * nx;
        if (!(2 * sqrt(ng * nh) <= NEAR_EXACT_TOL * r)) return 0; /* NaN too */
        ssq[b] = r * r + dd;
    }
    return 1;
}

/* Step: prefix sums over J': ssq[b] = ||X - G~_b H~_b^T||^2 from the fit's
 * rel (rel_rms of the channel, stride 4) and norm nx (both scaled). */
static void near_prefix(const near_ws_t *w, const double *rel, double nx, double *ssq) {
    size_t rows = w->rows, J = w->J;
    double xd = 0, gd = 0, dd = 0;
    for (size_t b = 0; b < J; b++) {
        /* Y[:, b] = X h_b scaled by sx sh; the dG, G~ carry sg: sx sg sh = sx^2 */
        for (size_t i = 0; i < rows; i++)
            xd += w->dG[i + b * rows] * w->Y[i + b * rows] + w->Gq[i + b * rows] * w->Y[i + (J + b) * rows];
        pairs_step(w, b, &gd, &dd);
        double r = rel[sb_err_at(b, 0)] * nx, s2 = r * r + 2 * (xd - gd) + dd;
        ssq[b] = s2 < 0 ? 0 : s2;
    }
}

/* Step, direct form (NEAR_DIRECT_REL): Y = X H~ (J columns), the Gram
 * blocks of G~ and H~, and the prefix sums ssq[b] = ||X||^2 -
 * 2 sum_a g~_a . (X h~_a) + sum_ac (g~_a . g~_c)(h~_a . h~_c) over a, c <= b. */
static sb_result_t near_direct(sb_context_t *ctx, near_ws_t *w, const sb_matrix_t *m, int ch, double sx, double nx,
                               double *ssq) {
    size_t rows = w->rows, cols = w->cols, J = w->J;
    for (size_t i = 0; i < cols * J; i++)
        w->Z[i] = w->Hq[i] * w->wc[i % cols] * sx;
    sb_result_t r = sb_matrix_mul(ctx, m, ch, J, w->Z, cols, w->Y, rows);
    if (r != SB_OK) return r;
    for (size_t i = 0; i < rows * J; i++)
        w->Y[i] *= w->wr[i % rows];
    gram(rows, J, w->Gq, w->Gq, w->GqGq);
    gram(cols, J, w->Hq, w->Hq, w->HH);
    double xd = 0, dd = 0;
    for (size_t b = 0; b < J; b++) {
        for (size_t i = 0; i < rows; i++)
            xd += w->Gq[i + b * rows] * w->Y[i + b * rows];
        for (size_t a = 0; a <= b; a++) /* pairs (a, b) and (b, a) with max(a, b) == b */
            dd += (a != b ? 2 : 1) * w->GqGq[a + b * J] * w->HH[a + b * J];
        double s2 = nx * nx - 2 * xd + dd;
        ssq[b] = s2 < 0 ? 0 : s2;
    }
    return SB_OK;
}

sb_result_t sb_factors_errors_near(sb_context_t *ctx, const sb_factors_t *fit, const sb_factors_t *near,
                                   const sb_matrix_t *m, const sb_param_t *weights, double *rel_rms) {
    if (!fit || !near || !m || !rel_rms) return sb_error(ctx, SB_ERR_ARG, "errors: missing argument");
    if (m->mask) return sb_error(ctx, SB_ERR_ARG, "errors: a masked matrix needs the explicit residual");
    size_t J = sb_factors_terms(fit), C = sb_factors_channels(fit), rows = m->rows, cols = m->cols;
    if (sb_errors_check_fit(ctx, fit, m, weights) != SB_OK || sb_errors_check_fit(ctx, near, m, weights) != SB_OK ||
        sb_factors_terms(near) != J || sb_factors_channels(near) != C || J > INT_MAX / 2 || rows > INT_MAX ||
        cols > INT_MAX)
        return sb_error(ctx, SB_ERR_ARG, "errors: factors do not fit each other or the %zu x %zu matrix", rows, cols);
    sb_result_t rb = sb_blas_reserve(ctx);
    if (rb != SB_OK) return rb;
    const sb_factor_errors_t *fe = sb_factors_errors(fit);
    memset(rel_rms, 0, J * 4 * sizeof *rel_rms);
    /* Step: scales 2^-e ~ 1 / ||X||, split between the two sides */
    int ex = 0;
    if (fe->norm[3] > 0 && isfinite(fe->norm[3])) frexp(fe->norm[3], &ex);
    ex = ex > 1000 ? 1000 : (ex < -1000 ? -1000 : ex);
    double sx = ldexp(1, -ex), sg = ldexp(1, -(ex / 2)), sh = ldexp(1, -(ex - ex / 2));
    int direct[3], all_direct = 1, exact = sb_factors_exact(fit) && C == 3;
    for (int ch = 0; ch < 3; ch++) {
        direct[ch] = fe->rel_rms[sb_err_at(J - 1, (size_t)ch)] >= NEAR_DIRECT_REL;
        all_direct &= (direct[ch] && !exact) || !m->data[ch];
    }
    near_ws_t w;
    double *ws = near_alloc(ctx, &w, rows, cols, J, all_direct);
    if (!ws) return sb_error(ctx, SB_ERR_NOMEM, "errors: out of memory");
    double *ssq = w.ssq, n2[3] = {0, 0, 0};
    for (size_t i = 0; i < rows + cols; i++)
        w.wr[i] = 1;
    if (weights) sb_errors_weights(weights, w.wr, w.wc);
    int present[3];
    for (int ch = 0; ch < 3; ch++) {
        present[ch] = m->data[ch] != NULL;
        if (!present[ch]) continue;
        size_t fc = C == 1 ? 0 : (size_t)ch;
        int what = direct[ch] ? NEAR_DIRECT : NEAR_PRODUCTS;
        near_factors(&w, fit, near, fc, sg, sh, exact ? NEAR_EXACT : what);
        double nx = fe->norm[ch] * sx;
        n2[ch] = nx * nx;
        if (exact && near_exact(&w, fe->rel_rms + ch, nx, ssq + (size_t)ch * J)) continue;
        if (exact) near_factors(&w, fit, near, fc, sg, sh, what); /* the bound not met: the matrix is read */
        sb_result_t r =
            direct[ch] ? near_direct(ctx, &w, m, ch, sx, nx, ssq + (size_t)ch * J) : near_products(ctx, &w, m, ch, sx);
        if (r != SB_OK) {
            free(ws);
            return r;
        }
        if (!direct[ch]) near_prefix(&w, fe->rel_rms + ch, nx, ssq + (size_t)ch * J);
    }
    sb_result_t res = sb_errors_relative(ctx, J, present, ssq, NULL, n2, rel_rms, NULL);
    free(ws);
    return res;
}
