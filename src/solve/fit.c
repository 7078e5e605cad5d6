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
 * full SVD; as the imputed values settle the subspace converges with them.
 *
 * Imputation converges slowly (linearly, at a rate set by the missing
 * fraction: hd leaves ~38 % of the cells outside the domain and needs
 * thousands of steps).  For k <= SB_ALS_MAX_K a few imputation steps only
 * warm-start alternating least squares on the valid cells,
 *     p_r = argmin sum_{c valid} (a_rc - p_r . q_c)^2,  then the same for q_c,
 * exact block coordinate descent that needs tens of sweeps.  Terms are
 * added one at a time (stage ka refits the first ka jointly), so each prefix
 * of the output is a masked fit of its own rank; sigma_j = |p_j| |q_j| is
 * the scale of term j, not a singular value, and the terms are not
 * orthogonal.
 *
 * A sweep reads the valid cells gathered once per execute in column and in
 * row order (no mask tests; the free factor columns and their outer
 * products are kept row-major, k contiguous values per row or column), so
 * a cell costs k multiply-adds and k(k+1)/2 additions per half-sweep; the
 * fixed terms of a stage are subtracted once, not in every sweep.  The sums
 * run in the order of plain loops over the mask, so the result is the same
 * to the bit as accumulating cell by cell. */
#include "solve/fit.h"

#include <cblas.h>
#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "solve/fit_impl.h"
#include "util/internal.h"
#include "util/rng.h"

static double gauss(uint64_t *s) {
    double g[2];
    sb_splitmix_gauss2(s, g); /* deterministic for a seed */
    return g[0];
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
    lapack_int info =
        LAPACKE_dgeqrf_work(LAPACK_COL_MAJOR, (lapack_int)m, (lapack_int)l, f->y, (lapack_int)m, f->tau, &q1, -1);
    info |= LAPACKE_dorgqr_work(LAPACK_COL_MAJOR, (lapack_int)m, (lapack_int)l, (lapack_int)l, f->y, (lapack_int)m,
                                f->tau, &q2, -1);
    info |= LAPACKE_dgesdd_work(LAPACK_COL_MAJOR, 'S', (lapack_int)l, (lapack_int)n, f->b, (lapack_int)l, f->sb, f->ub,
                                (lapack_int)l, f->vbt, (lapack_int)l, &q3, -1, f->iwork);
    if (info != 0) {
        sb_fit_destroy(f);
        return sb_error(ctx, SB_ERR_NUMERIC, "fit: LAPACK workspace query failed");
    }
    double q = fmax(q1, fmax(q2, q3));
    if (k <= SB_ALS_MAX_K) {
        f->P = sb_alloc(ctx, m * k, sizeof(double), "masked fit");
        f->Q = sb_alloc(ctx, n * k, sizeof(double), "masked fit");
        f->pt = sb_alloc(ctx, m * k, sizeof(double), "masked fit");
        f->qt = sb_alloc(ctx, n * k, sizeof(double), "masked fit");
        f->pp = sb_alloc(ctx, m * (k * (k + 1) / 2), sizeof(double), "masked fit");
        f->qq = sb_alloc(ctx, n * (k * (k + 1) / 2), sizeof(double), "masked fit");
        if (!f->P || !f->Q || !f->pt || !f->qt || !f->pp || !f->qq) {
            sb_fit_destroy(f);
            return SB_ERR_NOMEM;
        }
    }
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
    sb_fit_destroy(f->sub[0]);
    sb_fit_destroy(f->sub[1]);
    if (f->cells && !f->cells_borrowed) fit_cells_free(f->cells), free(f->cells);
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
    free(f->P);
    free(f->Q);
    free(f->pt);
    free(f->qt);
    free(f->pp);
    free(f->qq);
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
        for (size_t i = 0; i < n; i++)
            f->v[i + j * n] = f->vbt[j + i * l];
    return SB_OK;
}

/* X: data on valid cells; invalid cells start at the mean of the valid
 * cells of their column (far fewer iterations than starting at 0, which
 * drags the fit towards zero near the domain's edge).  X is A times a
 * power of two *pw (exact) that brings max |A| near 1, so that no sum of
 * squares underflows or overflows (1e-300 data stopped after one
 * iteration as "converged", 1e300 data failed as non-finite); the ALS
 * stages read the valid cells of X (same layout as A when lda == m, as
 * the plan passes) and sigma is divided by pw at the end.  Returns the
 * number of invalid cells; *norm2 the squared norm of the valid ones. */
static size_t fill_x(sb_fit_t *f, const double *A, size_t lda, const unsigned char *mask, double *pw, double *norm2) {
    size_t m = f->m, n = f->n, ninvalid = 0;
    double amax = 0;
    for (size_t c = 0; c < n && lda == m; c++)
        for (size_t r = 0; r < m; r++)
            if (mask[r + c * lda]) amax = fmax(amax, fabs(A[r + c * lda]));
    *pw = sb_pow2_scale(amax);
    *norm2 = 0;
    for (size_t c = 0; c < n; c++) {
        double sum = 0;
        size_t cnt = 0;
        for (size_t r = 0; r < m; r++)
            if (mask[r + c * lda]) {
                sum += A[r + c * lda] * *pw;
                cnt++;
            }
        double fill = cnt ? sum / (double)cnt : 0.0;
        for (size_t r = 0; r < m; r++) {
            int ok = mask[r + c * lda];
            double a = ok ? A[r + c * lda] * *pw : fill;
            f->x[r + c * m] = a;
            if (ok) *norm2 += a * a;
            ninvalid += !ok;
        }
    }
    return ninvalid;
}

/* One imputation step: the subspace step, qu = Q Ub[:, :k], the invalid
 * cells of X replaced by L = qu diag(s) Vb^T; returns the squared error on
 * the valid ones (NAN when the step failed: *r says why). */
static double impute(sb_fit_t *f, size_t lda, const unsigned char *mask, double *qu, double *coef, sb_result_t *r) {
    size_t m = f->m, n = f->n, k = f->k, l = f->l;
    if ((*r = step(f)) != SB_OK) return NAN;
    cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, (int)m, (int)k, (int)l, 1.0, f->y, (int)m, f->ub, (int)l,
                0.0, qu, (int)m);
    double e2 = 0, *col = qu + m * k; /* L's column c, a term at a time (each cell's sum in the order j) */
    for (size_t c = 0; c < n; c++) {
        for (size_t j = 0; j < k; j++)
            coef[j] = f->sb[j] * f->vbt[j + c * l];
        memset(col, 0, m * sizeof *col);
        for (size_t j = 0; j < k; j++)
            for (size_t r2 = 0; r2 < m; r2++)
                col[r2] += qu[r2 + j * m] * coef[j];
        for (size_t r2 = 0; r2 < m; r2++) {
            size_t at = r2 + c * m;
            double lv = col[r2];
            if (mask[r2 + c * lda]) {
                double d = f->x[at] - lv;
                e2 += d * d;
            } else {
                f->x[at] = lv;
            }
        }
    }
    return e2;
}

/* The ALS from the start in f->P, f->Q (fit_taps.c), then sigma_j =
 * |p_j| |q_j|, u_j = p_j / |p_j|, v_j = q_j / |q_j|. */
static sb_result_t als_done(sb_fit_t *f, const double *As, size_t lda, const unsigned char *mask, size_t nvalid,
                            const sb_fit_opts_t *o, double pw, double norm2, int total, double *s, double *U, double *V,
                            sb_fit_info_t *info) {
    size_t m = f->m, n = f->n, k = f->k;
    int converged = 1; /* the last stage's (fit_als_stages); the info reads the terms' flags */
    double err = 0;
    sb_result_t r = fit_als(f, As, lda, mask, nvalid, o, norm2, &total, &converged, &err);
    if (r != SB_OK) return r; /* fit_als and the gathered cells named the bytes */
    for (size_t j = 0; j < k; j++) {
        double np = cblas_dnrm2((int)m, f->P + j * m, 1), nq = cblas_dnrm2((int)n, f->Q + j * n, 1);
        /* a degenerate term (one side 0, the other grown without bound by
         * the ridge: 0 x inf) holds nothing: sigma 0, not NaN (a NaN sigma
         * made the chain's residual NaN and its next term's SVD fail) */
        int keep = np > 0 && nq > 0 && isfinite(np * nq / pw);
        s[j] = keep ? np * nq / pw : 0;
        for (size_t i = 0; i < m && U; i++)
            U[i + j * m] = keep ? f->P[i + j * m] / np : 0;
        for (size_t i = 0; i < n && V; i++)
            V[i + j * n] = keep ? f->Q[i + j * n] / nq : 0;
    }
    size_t conv = fit_conv_terms(f); /* the terms' own flags, not the last stage's alone */
    if (info) *info = (sb_fit_info_t){total, conv == k, norm2 > 0 ? err / sqrt(norm2) : 0, conv};
    return SB_OK;
}

/* ALS from the imputation's rank-k estimate: P = qu diag(sqrt s), Q = Vb^T'
 * diag(sqrt s). */
static sb_result_t als_finish(sb_fit_t *f, const double *As, size_t lda, const unsigned char *mask, size_t nvalid,
                              const sb_fit_opts_t *o, double pw, double norm2, const double *qu, int total, double *s,
                              double *U, double *V, sb_fit_info_t *info) {
    size_t m = f->m, n = f->n, k = f->k, l = f->l;
    for (size_t j = 0; j < k; j++) {
        double rt = sqrt(f->sb[j] > 0 ? f->sb[j] : 0);
        for (size_t i = 0; i < m; i++)
            f->P[i + j * m] = qu[i + j * m] * rt;
        for (size_t i = 0; i < n; i++)
            f->Q[i + j * n] = f->vbt[j + i * l] * rt;
    }
    return als_done(f, As, lda, mask, nvalid, o, pw, norm2, total, s, U, V, info);
}

void sb_fit_set_start(sb_fit_t *f, const double *s, const double *U, const double *V) {
    int all = s && U && V;
    f->init_s = all ? s : NULL, f->init_u = all ? U : NULL, f->init_v = all ? V : NULL;
}

/* Whether f's warm start is taken (fit.h): given, every sigma > 0. */
static int warm_given(const sb_fit_t *f) {
    int ok = f->init_s != NULL;
    for (size_t j = 0; ok && j < f->k; j++)
        ok = f->init_s[j] > 0 && isfinite(f->init_s[j]);
    return ok;
}

/* ALS from the warm start: P = U diag(sqrt(s pw)), Q = V diag(sqrt(s
 * pw)) (X is A times pw), its stages from the last (f->warm). */
static sb_result_t als_warm(sb_fit_t *f, const double *As, size_t lda, const unsigned char *mask, size_t nvalid,
                            const sb_fit_opts_t *o, double pw, double norm2, double *s, double *U, double *V,
                            sb_fit_info_t *info) {
    size_t m = f->m, n = f->n, k = f->k;
    for (size_t j = 0; j < k; j++) {
        double rt = sqrt(f->init_s[j] * pw);
        for (size_t i = 0; i < m; i++)
            f->P[i + j * m] = f->init_u[i + j * m] * rt;
        for (size_t i = 0; i < n; i++)
            f->Q[i + j * n] = f->init_v[i + j * n] * rt;
    }
    f->warm = 1;
    sb_result_t r = als_done(f, As, lda, mask, nvalid, o, pw, norm2, 0, s, U, V, info);
    f->warm = 0;
    return r;
}

sb_result_t sb_fit_execute(sb_fit_t *f, const double *A, size_t lda, const unsigned char *mask,
                           const sb_fit_opts_t *opts, double *s, double *U, double *V, sb_fit_info_t *info) {
    size_t m = f->m, n = f->n, k = f->k, l = f->l;
    sb_fit_opts_t o = {0};
    if (opts) o = *opts;
    if (o.max_iters <= 0) o.max_iters = 300;
    if (o.tol <= 0) o.tol = 1e-5;
    double pw, norm2;
    size_t ninvalid = fill_x(f, A, lda, mask, &pw, &norm2);
    const double *As = lda == m ? f->x : A; /* what the ALS stages read */
    int warm = f->P && ninvalid > 0 && warm_given(f);
    if (warm) {
        sb_result_t rw = als_warm(f, As, lda, mask, m * n - ninvalid, &o, pw, norm2, s, U, V, info);
        sb_fit_set_start(f, NULL, NULL, NULL); /* taken */
        return rw;
    }
    sb_fit_set_start(f, NULL, NULL, NULL); /* not taken: the next fit starts cold */
    uint64_t seed = o.seed ? o.seed : 1;
    for (size_t i = 0; i < n * l; i++)
        f->v[i] = gauss(&seed);
    double prev = INFINITY, err = 0;
    int it;
    double *qu = malloc(m * (k + 1) * sizeof *qu); /* Q Ub[:, :k], then a column of L (impute) */
    double *coef = malloc(k * sizeof *coef);
    if (!qu || !coef) {
        free(qu);
        free(coef);
        return sb_error(f->ctx, SB_ERR_NOMEM, "fit: cannot allocate %zu bytes", (m * (k + 1) + k) * sizeof(double));
    }
    sb_result_t r = SB_OK;
    int use_als = f->P != NULL && ninvalid > 0;
    int em_iters = use_als ? (o.max_iters < SB_ALS_WARM ? o.max_iters : SB_ALS_WARM) : o.max_iters;
    for (it = 1; it <= em_iters; it++) {
        err = sqrt(impute(f, lda, mask, qu, coef, &r));
        if (r != SB_OK || ninvalid == 0) break;
        if (err <= 1e-15 * sqrt(norm2) || (it >= 5 && prev - err <= o.tol * prev)) break;
        prev = err;
    }
    if (r == SB_OK && use_als) {
        r = als_finish(f, As, lda, mask, m * n - ninvalid, &o, pw, norm2, qu, it > em_iters ? em_iters : it, s, U, V,
                       info);
    } else if (r == SB_OK) {
        for (size_t j = 0; j < k; j++)
            s[j] = f->sb[j] / pw;
        if (U) memcpy(U, qu, m * k * sizeof *U);
        for (size_t j = 0; V && j < k; j++)
            for (size_t i = 0; i < n; i++)
                V[i + j * n] = f->vbt[j + i * l];
        if (info)
            *info = (sb_fit_info_t){it > o.max_iters ? o.max_iters : it, it <= o.max_iters,
                                    norm2 > 0 ? err / sqrt(norm2) : 0, it <= o.max_iters ? k : 0};
    }
    free(qu);
    free(coef);
    return r;
}
