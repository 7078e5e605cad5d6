/* Masked low-rank fitting: the rank-k approximation of A on its valid cells
 * only (cells with mask 0 are not data: below the horizon, unmeasured).
 *
 * No closed form exists for an arbitrary mask; we iterate imputation (the
 * EM / hard-impute scheme): X = A on valid cells, the current rank-k
 * estimate L on the others; refactor X; repeat until the error on the valid
 * cells stops improving.  Each refactorisation is one step of subspace
 * iteration warm-started from the previous right subspace
 *     Y = X V, Q = qr(Y), B = Q^T X = Ub S Vb^T, L = Q Ub S Vb^T,
 * so an outer iteration costs two m x n x l products (l = k + p) instead of a
 * full SVD; as the imputed values settle the subspace converges with them. */
#include "fit.h"

#include <cblas.h>
#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"

struct sb_fit {
    sb_context_t *ctx;
    size_t m, n, k, l;
    double *x, *v, *y, *tau, *b, *sb, *ub, *vbt, *work;
    lapack_int *iwork;
    lapack_int lwork;
};

static double gauss(uint64_t *s) {
    /* splitmix64 + Box-Muller: deterministic for a seed */
    uint64_t z1, z2;
    *s += 0x9e3779b97f4a7c15ULL;
    z1 = *s;
    z1 = (z1 ^ (z1 >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z1 = (z1 ^ (z1 >> 27)) * 0x94d049bb133111ebULL;
    z1 ^= z1 >> 31;
    *s += 0x9e3779b97f4a7c15ULL;
    z2 = *s;
    z2 = (z2 ^ (z2 >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z2 = (z2 ^ (z2 >> 27)) * 0x94d049bb133111ebULL;
    z2 ^= z2 >> 31;
    double u1 = ((z1 >> 11) + 0.5) * (1.0 / 9007199254740992.0), u2 = (z2 >> 11) * (1.0 / 9007199254740992.0);
    return sqrt(-2 * log(u1)) * cos(2 * SB_PI * u2);
}

sb_result_t sb_fit_create(sb_context_t *ctx, size_t m, size_t n, size_t k, sb_fit_t **out) {
    *out = NULL;
    size_t mn = m < n ? m : n;
    if (k == 0 || k > mn) return sb_error(ctx, SB_ERR_RANGE, "fit: %zu terms asked, need 1..%zu", k, mn);
    sb_fit_t *f = calloc(1, sizeof *f);
    if (!f) return sb_error(ctx, SB_ERR_NOMEM, "fit: out of memory");
    f->ctx = ctx;
    f->m = m;
    f->n = n;
    f->k = k;
    f->l = k + 10 < mn ? k + 10 : mn;
    size_t l = f->l, cells;
    if (sb_size_mul(m, n, &cells)) {
        free(f);
        return sb_error(ctx, SB_ERR_OVERFLOW, "fit: matrix size overflows");
    }
    f->x = sb_alloc(ctx, cells, sizeof(double), "masked fit");
    f->v = sb_alloc(ctx, n * l, sizeof(double), "masked fit");
    f->y = sb_alloc(ctx, m * l, sizeof(double), "masked fit");
    f->tau = sb_alloc(ctx, l, sizeof(double), "masked fit");
    f->b = sb_alloc(ctx, l * n, sizeof(double), "masked fit");
    f->sb = sb_alloc(ctx, l, sizeof(double), "masked fit");
    f->ub = sb_alloc(ctx, l * l, sizeof(double), "masked fit");
    f->vbt = sb_alloc(ctx, l * n, sizeof(double), "masked fit");
    f->iwork = sb_alloc(ctx, 8 * l, sizeof(lapack_int), "masked fit");
    if (!f->x || !f->v || !f->y || !f->tau || !f->b || !f->sb || !f->ub || !f->vbt || !f->iwork) {
        sb_fit_destroy(f);
        return SB_ERR_NOMEM;
    }
    /* one workspace for dgeqrf, dorgqr and dgesdd: the largest query */
    double q1, q2, q3;
    lapack_int info = LAPACKE_dgeqrf_work(LAPACK_COL_MAJOR, (lapack_int)m, (lapack_int)l, f->y, (lapack_int)m, f->tau, &q1, -1);
    info |= LAPACKE_dorgqr_work(LAPACK_COL_MAJOR, (lapack_int)m, (lapack_int)l, (lapack_int)l, f->y, (lapack_int)m, f->tau, &q2, -1);
    info |= LAPACKE_dgesdd_work(LAPACK_COL_MAJOR, 'S', (lapack_int)l, (lapack_int)n, f->b, (lapack_int)l, f->sb, f->ub,
                                (lapack_int)l, f->vbt, (lapack_int)l, &q3, -1, f->iwork);
    if (info != 0) {
        sb_fit_destroy(f);
        return sb_error(ctx, SB_ERR_NUMERIC, "fit: LAPACK workspace query failed");
    }
    double q = fmax(q1, fmax(q2, q3));
    f->lwork = (lapack_int)q + 1;
    f->work = sb_alloc(ctx, (size_t)f->lwork, sizeof(double), "masked fit");
    if (!f->work) {
        sb_fit_destroy(f);
        return SB_ERR_NOMEM;
    }
    *out = f;
    return SB_OK;
}

void sb_fit_destroy(sb_fit_t *f) {
    if (!f) return;
    free(f->x);
    free(f->v);
    free(f->y);
    free(f->tau);
    free(f->b);
    free(f->sb);
    free(f->ub);
    free(f->vbt);
    free(f->work);
    free(f->iwork);
    free(f);
}

/* One subspace step on X: V (n x l) in, rank-l SVD of the projection out
 * (sb, Q Ub in y, Vb^T in vbt); V is replaced by Vb (orthonormal rows). */
static sb_result_t step(sb_fit_t *f) {
    size_t m = f->m, n = f->n, l = f->l;
    cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, (int)m, (int)l, (int)n, 1.0, f->x, (int)m, f->v, (int)n, 0.0,
                f->y, (int)m);
    lapack_int info = LAPACKE_dgeqrf_work(LAPACK_COL_MAJOR, (lapack_int)m, (lapack_int)l, f->y, (lapack_int)m, f->tau,
                                          f->work, f->lwork);
    if (!info)
        info = LAPACKE_dorgqr_work(LAPACK_COL_MAJOR, (lapack_int)m, (lapack_int)l, (lapack_int)l, f->y, (lapack_int)m,
                                   f->tau, f->work, f->lwork);
    if (info) return sb_error(f->ctx, SB_ERR_NUMERIC, "fit: QR failed (info %d)", (int)info);
    cblas_dgemm(CblasColMajor, CblasTrans, CblasNoTrans, (int)l, (int)n, (int)m, 1.0, f->y, (int)m, f->x, (int)m, 0.0,
                f->b, (int)l);
    info = LAPACKE_dgesdd_work(LAPACK_COL_MAJOR, 'S', (lapack_int)l, (lapack_int)n, f->b, (lapack_int)l, f->sb, f->ub,
                               (lapack_int)l, f->vbt, (lapack_int)l, f->work, f->lwork, f->iwork);
    if (info) return sb_error(f->ctx, SB_ERR_NUMERIC, "fit: SVD of the projection failed (info %d)", (int)info);
    /* the next starting subspace is the new right singular basis Vb */
    for (size_t j = 0; j < l; j++)
        for (size_t i = 0; i < n; i++) f->v[i + j * n] = f->vbt[j + i * l];
    return SB_OK;
}

sb_result_t sb_fit_execute(sb_fit_t *f, const double *A, size_t lda, const unsigned char *mask, const sb_fit_opts_t *opts,
                           double *s, double *U, double *V, sb_fit_info_t *info) {
    size_t m = f->m, n = f->n, k = f->k, l = f->l;
    sb_fit_opts_t o = {0};
    if (opts) o = *opts;
    if (o.max_iters <= 0) o.max_iters = 300;
    if (o.tol <= 0) o.tol = 1e-7;
    /* X: data on valid cells, 0 elsewhere to start, scaled by a power of
     * two (exact) to max |X| in [0.5, 1): the sums of squares that decide
     * convergence neither underflow (1e-300 data stopped after one
     * iteration, "converged") nor overflow; s is unscaled at the end. */
    double amax = 0, sc = 1;
    for (size_t c = 0; c < n; c++)
        for (size_t r = 0; r < m; r++)
            if (mask[r + c * lda]) amax = fmax(amax, fabs(A[r + c * lda]));
    if (amax > 0 && isfinite(amax)) {
        int ex;
        frexp(amax, &ex);
        sc = ldexp(1, ex > 1020 ? -1020 : (ex < -1020 ? 1020 : -ex));
    }
    double norm2 = 0;
    size_t ninvalid = 0;
    for (size_t c = 0; c < n; c++)
        for (size_t r = 0; r < m; r++) {
            size_t at = r + c * m;
            int ok = mask[r + c * lda];
            double a = ok ? A[r + c * lda] * sc : 0.0;
            f->x[at] = a;
            norm2 += a * a;
            ninvalid += !ok;
        }
    uint64_t seed = o.seed ? o.seed : 1;
    for (size_t i = 0; i < n * l; i++) f->v[i] = gauss(&seed);
    double prev = INFINITY, err = 0;
    int it;
    double *qu = malloc(m * k * sizeof *qu); /* Q Ub[:, :k] */
    double *coef = malloc(k * sizeof *coef);
    if (!qu || !coef) {
        free(qu);
        free(coef);
        return sb_error(f->ctx, SB_ERR_NOMEM, "fit: out of memory");
    }
    sb_result_t r = SB_OK;
    for (it = 1; it <= o.max_iters; it++) {
        if ((r = step(f)) != SB_OK) break;
        cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, (int)m, (int)k, (int)l, 1.0, f->y, (int)m, f->ub, (int)l, 0.0,
                    qu, (int)m);
        /* impute the invalid cells with L = qu diag(s) Vb^T and measure the
         * error on the valid ones */
        double e2 = 0;
        for (size_t c = 0; c < n; c++) {
            for (size_t j = 0; j < k; j++) coef[j] = f->sb[j] * f->vbt[j + c * l];
            for (size_t r2 = 0; r2 < m; r2++) {
                size_t at = r2 + c * m;
                double lv = 0;
                for (size_t j = 0; j < k; j++) lv += qu[r2 + j * m] * coef[j];
                if (mask[r2 + c * lda]) {
                    double d = f->x[at] - lv;
                    e2 += d * d;
                } else {
                    f->x[at] = lv;
                }
            }
        }
        err = sqrt(e2);
        if (ninvalid == 0) break;
        if (err <= 1e-15 * sqrt(norm2) || (it >= 5 && prev - err <= o.tol * prev)) break;
        prev = err;
    }
    if (r == SB_OK) {
        for (size_t j = 0; j < k; j++) s[j] = f->sb[j] / sc;
        if (U) memcpy(U, qu, m * k * sizeof *U);
        if (V)
            for (size_t j = 0; j < k; j++)
                for (size_t i = 0; i < n; i++) V[i + j * n] = f->vbt[j + i * l];
        if (info) {
            info->iterations = it > o.max_iters ? o.max_iters : it;
            info->rel_err = norm2 > 0 ? err / sqrt(norm2) : 0;
            info->converged = it <= o.max_iters;
        }
    }
    free(qu);
    free(coef);
    return r;
}
