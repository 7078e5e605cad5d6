/* Precision template (helpers of every method), included by svd_precisions.h once for double and
 * once for float: R is the real type, SFX its suffix, GEMM ... ORGQR the
 * matching BLAS/LAPACK routines, so the maths is written once.  Not a
 * header of its own: no guard.
 *
 * Storage: every matrix column-major; names follow the maths in svd.h.  In
 * double precision the products read the caller's A with its lda; in single
 * precision they read the float copy s->a (ld = m) made by svd.c. */

#define SB_CAT_(a, b) a##_##b
#define SB_CAT(a, b) SB_CAT_(a, b)
#define FN(name) SB_CAT(name, SFX)

/* Workspace query result (a floating-point count) as a lapack_int, rounded
 * up: in single precision a large count is not exact. */
static int FN(lwork_of)(R q, lapack_int *out) {
    double v = (double)q * (1 + 1e-6) + 1;
    if (!(v < (double)INT32_MAX)) return 1;
    if ((lapack_int)v > *out) *out = (lapack_int)v;
    return 0;
}

/* ---- helpers ------------------------------------------------------------ */

/* dst (rows x cols, ld ldd, double) = src (ld lds). */
static void FN(put)(const R *src, size_t lds, size_t rows, size_t cols, double *dst, size_t ldd) {
    for (size_t j = 0; j < cols; j++)
        for (size_t i = 0; i < rows; i++)
            dst[i + j * ldd] = (double)src[i + j * lds];
}

/* Y (rows x cols) <- its orthonormal factor Q of Y = Q R (Householder). */
static sb_result_t FN(orth)(sb_svd_t *s, R *Y, size_t rows, size_t cols) {
    lapack_int info =
        GEQRF(LAPACK_COL_MAJOR, (lapack_int)rows, (lapack_int)cols, Y, (lapack_int)rows, s->tau, s->work, s->lwork);
    if (info == 0)
        info = ORGQR(LAPACK_COL_MAJOR, (lapack_int)rows, (lapack_int)cols, (lapack_int)cols, Y, (lapack_int)rows,
                     s->tau, s->work, s->lwork);
    return info == 0 ? SB_OK : sb_error(s->ctx, SB_ERR_NUMERIC, "svd: QR failed (info %d)", (int)info);
}
