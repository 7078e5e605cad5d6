/* Precision template of the dense methods FULL and TOPK, included by svd_precisions.h once for double and
 * once for float: R is the real type, SFX its suffix, GEMM ... ORGQR the
 * matching BLAS/LAPACK routines, so the maths is written once.  Not a
 * header of its own: no guard.
 *
 * Storage: every matrix column-major; names follow the maths in svd.h.  In
 * double precision the products read the caller's A with its lda; in single
 * precision they read the float copy s->a (ld = m) made by svd.c. */

#include "solve/svd_tmpl_common.h"

/* ---- plans -------------------------------------------------------------- */

/* FULL: a = copy of A (m x n), sv (d), u (m x d), vt (d x n); dgesdd 'S'. */
static sb_result_t FN(plan_full)(sb_svd_t *s) {
    size_t m = s->m, n = s->n, d = s->d;
    const size_t e = sizeof(R);
    if (!(s->a = ws_alloc(s, m, n, e)) || !(s->sv = ws_alloc(s, d, 1, e)) || !(s->u = ws_alloc(s, m, d, e)) ||
        !(s->vt = ws_alloc(s, d, n, e)) || !(s->iwork = ws_alloc(s, 8 * d, 1, sizeof(lapack_int))))
        return SB_ERR_NOMEM;
    R q = 0;
    lapack_int info = GESDD(LAPACK_COL_MAJOR, 'S', (lapack_int)m, (lapack_int)n, s->a, (lapack_int)m, s->sv, s->u,
                            (lapack_int)m, s->vt, (lapack_int)d, &q, -1, s->iwork);
    if (info != 0) return sb_error(s->ctx, SB_ERR_NUMERIC, "svd: gesdd workspace query failed (info %d)", (int)info);
    if (FN(lwork_of)(q, &s->lwork)) return sb_error(s->ctx, SB_ERR_OVERFLOW, "svd: gesdd workspace too large");
    return SB_OK;
}

/* TOPK: G (d x d), eigenvalues w (d), eigenvectors z (d x k), Y (e x k, then
 * Q), tau (k), P (d x k, as bt), its SVD P = W S X^T with W (ws, d x k), S
 * (sv, k), X^T (vt, k x k), and the large-side vectors Q X (u, e x k). */
static sb_result_t FN(plan_topk)(sb_svd_t *s) {
    size_t d = s->d, e = s->m > s->n ? s->m : s->n, k = s->k;
    const size_t z = sizeof(R);
    if (!(s->g = ws_alloc(s, d, d, z)) || !(s->w = ws_alloc(s, d, 1, z)) || !(s->z = ws_alloc(s, d, k, z)) ||
        !(s->y = ws_alloc(s, e, k, z)) || !(s->tau = ws_alloc(s, k, 1, z)) || !(s->bt = ws_alloc(s, d, k, z)) ||
        !(s->ws = ws_alloc(s, d, k, z)) || !(s->sv = ws_alloc(s, k, 1, z)) || !(s->vt = ws_alloc(s, k, k, z)) ||
        !(s->u = ws_alloc(s, e, k, z)) || !(s->isuppz = ws_alloc(s, 2 * k, 1, sizeof(lapack_int))))
        return SB_ERR_NOMEM;
    R q = 0;
    lapack_int qi = 0, found = 0, info;
    info = SYEVR(LAPACK_COL_MAJOR, 'V', 'I', 'U', (lapack_int)d, s->g, (lapack_int)d, 0, 0, (lapack_int)(d - k + 1),
                 (lapack_int)d, 0, &found, s->w, s->z, (lapack_int)d, s->isuppz, &q, -1, &qi, -1);
    if (info != 0) return sb_error(s->ctx, SB_ERR_NUMERIC, "svd: syevr workspace query failed (info %d)", (int)info);
    int big = FN(lwork_of)(q, &s->lwork);
    s->liwork = qi > 8 * (lapack_int)k ? qi : 8 * (lapack_int)k;
    info = GEQRF(LAPACK_COL_MAJOR, (lapack_int)e, (lapack_int)k, s->y, (lapack_int)e, s->tau, &q, -1);
    big |= info != 0 || FN(lwork_of)(q, &s->lwork);
    info = ORGQR(LAPACK_COL_MAJOR, (lapack_int)e, (lapack_int)k, (lapack_int)k, s->y, (lapack_int)e, s->tau, &q, -1);
    big |= info != 0 || FN(lwork_of)(q, &s->lwork);
    lapack_int iw[8];
    info = GESDD(LAPACK_COL_MAJOR, 'S', (lapack_int)d, (lapack_int)k, s->bt, (lapack_int)d, s->sv, s->ws, (lapack_int)d,
                 s->vt, (lapack_int)k, &q, -1, iw);
    big |= info != 0 || FN(lwork_of)(q, &s->lwork);
    if (big) return sb_error(s->ctx, SB_ERR_NUMERIC, "svd: workspace query failed or too large");
    if (!(s->iwork = ws_alloc(s, (size_t)s->liwork, 1, sizeof(lapack_int)))) return SB_ERR_NOMEM;
    return SB_OK;
}

/* ---- methods ------------------------------------------------------------ */

/* FULL: A = U S V^T by gesdd on a copy; the caller has copied A into s->a
 * (checking finiteness).  Writes all d singular values to s->sv. */
static sb_result_t FN(run_full)(sb_svd_t *s) {
    size_t m = s->m, n = s->n, d = s->d;
    lapack_int info = GESDD(LAPACK_COL_MAJOR, 'S', (lapack_int)m, (lapack_int)n, s->a, (lapack_int)m, s->sv, s->u,
                            (lapack_int)m, s->vt, (lapack_int)d, s->work, s->lwork, s->iwork);
    return info == 0 ? SB_OK : sb_error(s->ctx, SB_ERR_NUMERIC, "svd: gesdd failed (info %d)", (int)info);
}

static void FN(out_full)(const sb_svd_t *s, size_t r, double *sv, double *U, double *V) {
    const R *x = s->sv, *u = s->u, *vt = s->vt;
    size_t m = s->m, n = s->n, d = s->d;
    for (size_t j = 0; j < r; j++)
        sv[j] = (double)x[j];
    if (U) FN(put)(u, m, m, r, U, m);
    if (V)
        for (size_t j = 0; j < r; j++)
            for (size_t i = 0; i < n; i++)
                V[i + j * n] = (double)vt[j + i * d];
}

/* TOPK.  With the Gram matrix on the smaller side (tr = 0: G = A^T A, d = n;
 * tr = 1: G = A A^T, d = m) and op(A) = A or A^T so that op(A) is e x d:
 *   G Z = Z Lambda, Z the k leading eigenvectors (d x k);
 *   Y = op(A) Z (e x k), Q = qr(Y)                     one power step,
 *   P = op(A)^T Q (d x k) = W S X^T (gesdd)             Rayleigh-Ritz,
 * so op(A) ~ Q P^T = (Q X) S W^T.  The small-side vectors are W, the
 * large-side ones Q X.  *trace = trace(G) = ||A||_F^2 comes for free. */
static sb_result_t FN(run_topk)(sb_svd_t *s, const R *A, size_t lda, double *trace) {
    size_t d = s->d, k = s->k, e = s->m > s->n ? s->m : s->n;
    int tr = s->tr;
    R *G = s->g, *Z = s->z, *Y = s->y, *P = s->bt;
    enum CBLAS_TRANSPOSE opA = tr ? CblasTrans : CblasNoTrans, opAt = tr ? CblasNoTrans : CblasTrans;
    /* Gram matrix, upper triangle */
    SYRK(CblasColMajor, CblasUpper, opAt, (int)d, (int)e, 1, A, (int)lda, 0, G, (int)d);
    double t = 0;
    for (size_t i = 0; i < d; i++)
        t += (double)G[i + i * d];
    *trace = t;
    if (!isfinite(t))
        return sb_error(s->ctx, SB_ERR_NUMERIC, "svd: matrix has non-finite entries or overflows %s precision",
                        sizeof(R) == 4 ? "single" : "double");
    /* k largest eigenpairs (ascending order; the Ritz step sorts) */
    lapack_int found = 0;
    lapack_int info =
        SYEVR(LAPACK_COL_MAJOR, 'V', 'I', 'U', (lapack_int)d, G, (lapack_int)d, 0, 0, (lapack_int)(d - k + 1),
              (lapack_int)d, 0, &found, s->w, Z, (lapack_int)d, s->isuppz, s->work, s->lwork, s->iwork, s->liwork);
    if (info != 0 || found != (lapack_int)k)
        return sb_error(s->ctx, SB_ERR_NUMERIC, "svd: syevr failed (info %d, %d of %zu found)", (int)info, (int)found,
                        k);
    /* one power step and Rayleigh-Ritz on A itself */
    GEMM(CblasColMajor, opA, CblasNoTrans, (int)e, (int)k, (int)d, 1, A, (int)lda, Z, (int)d, 0, Y, (int)e);
    sb_result_t r = FN(orth)(s, Y, e, k);
    if (r != SB_OK) return r;
    GEMM(CblasColMajor, opAt, CblasNoTrans, (int)d, (int)k, (int)e, 1, A, (int)lda, Y, (int)e, 0, P, (int)d);
    info = GESDD(LAPACK_COL_MAJOR, 'S', (lapack_int)d, (lapack_int)k, P, (lapack_int)d, s->sv, s->ws, (lapack_int)d,
                 s->vt, (lapack_int)k, s->work, s->lwork, s->iwork);
    if (info != 0) return sb_error(s->ctx, SB_ERR_NUMERIC, "svd: gesdd failed (info %d)", (int)info);
    /* large-side vectors Q X = Q (X^T)^T */
    GEMM(CblasColMajor, CblasNoTrans, CblasTrans, (int)e, (int)k, (int)k, 1, Y, (int)e, s->vt, (int)k, 0, s->u, (int)e);
    return SB_OK;
}

static void FN(out_topk)(const sb_svd_t *s, size_t r, double *sv, double *U, double *V) {
    size_t d = s->d, e = s->m > s->n ? s->m : s->n;
    const R *x = s->sv;
    for (size_t j = 0; j < r; j++)
        sv[j] = (double)x[j];
    const R *small = s->ws, *large = s->u;
    if (U) FN(put)(s->tr ? small : large, s->tr ? d : e, s->m, r, U, s->m);
    if (V) FN(put)(s->tr ? large : small, s->tr ? e : d, s->n, r, V, s->n);
}

#undef FN
#undef SB_CAT
#undef SB_CAT_
