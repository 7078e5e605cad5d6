/* One precision of the truncated-SVD methods.  Included twice by svd.c, with
 *     R = double, SFX = d, and the d-prefixed BLAS/LAPACK routines, then
 *     R = float,  SFX = f, and the s-prefixed ones,
 * so the maths below is written once.  Not a header of its own: no guard.
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

/* RANDOMIZED, with l = k + p test vectors and L basis columns (l, or
 * l (q + 1) for block Krylov): Omega (om, n x l), basis Q (y, m x L),
 * scratch Z (z, n x L), B^T (bt, n x L), SVD of B^T = W S X^T with W (ws,
 * n x L), S (sv, L), X^T (vt, L x L), projection coefficients C (c, L x l),
 * tau (L), and Q X (u, m x k). */
static sb_result_t FN(plan_rand)(sb_svd_t *s) {
    size_t m = s->m, n = s->n, l = s->l, L = s->L, k = s->k;
    const size_t z = sizeof(R);
    if (!(s->om = ws_alloc(s, n, l, z)) || !(s->y = ws_alloc(s, m, L, z)) || !(s->z = ws_alloc(s, n, L, z)) ||
        !(s->bt = ws_alloc(s, n, L, z)) || !(s->ws = ws_alloc(s, n, L, z)) || !(s->sv = ws_alloc(s, L, 1, z)) ||
        !(s->vt = ws_alloc(s, L, L, z)) || !(s->c = ws_alloc(s, L, l, z)) || !(s->tau = ws_alloc(s, L, 1, z)) ||
        !(s->u = ws_alloc(s, m, k, z)) || !(s->iwork = ws_alloc(s, 8 * L, 1, sizeof(lapack_int))))
        return SB_ERR_NOMEM;
    s->liwork = 8 * (lapack_int)L;
    /* Omega: i.i.d. N(0, 1), drawn once per plan from the seed */
    R *om = s->om;
    uint64_t st[4];
    rng_seed(st, s->seed);
    for (size_t i = 0; i < n * l; i += 2) {
        double g[2];
        rng_gauss2(st, g);
        om[i] = (R)g[0];
        if (i + 1 < n * l) om[i + 1] = (R)g[1];
    }
    R q = 0;
    int big = 0;
    size_t rows[2] = {m, n}, bq = l; /* QR is of one block (<= l columns) at a time */
    for (int t = 0; t < 2; t++) {
        lapack_int info =
            GEQRF(LAPACK_COL_MAJOR, (lapack_int)rows[t], (lapack_int)bq, s->y, (lapack_int)rows[t], s->tau, &q, -1);
        big |= info != 0 || FN(lwork_of)(q, &s->lwork);
        info = ORGQR(LAPACK_COL_MAJOR, (lapack_int)rows[t], (lapack_int)bq, (lapack_int)bq, s->y, (lapack_int)rows[t],
                     s->tau, &q, -1);
        big |= info != 0 || FN(lwork_of)(q, &s->lwork);
    }
    lapack_int info = GESDD(LAPACK_COL_MAJOR, 'S', (lapack_int)n, (lapack_int)L, s->z, (lapack_int)n, s->sv, s->ws,
                            (lapack_int)n, s->vt, (lapack_int)L, &q, -1, s->iwork);
    big |= info != 0 || FN(lwork_of)(q, &s->lwork);
    if (big) return sb_error(s->ctx, SB_ERR_NUMERIC, "svd: workspace query failed or too large");
    return SB_OK;
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

/* Yb (rows x bb) <- an orthonormal basis of (I - Q Q^T) Yb, Q the first l
 * columns of the basis: block Gram-Schmidt twice, each pass followed by a
 * QR ("twice is enough", Giraud et al. 2005).  The QR between the passes
 * matters when Yb lies almost inside span(Q) (a Krylov iterate of a fast
 * spectrum, a rank-deficient A): the first remainder is rounding noise, and
 * only once it is normalised does the second pass make it orthogonal to Q.
 * "Twice is enough" needs the remainder to be more than rounding, though: a
 * column lying inside span(Q) to working precision (A of rank below the
 * basis size: a constant BRDF gave Q^T Q with entries 1, sigma_1 times
 * sqrt(q + 1) and rel_rms 2) leaves pure noise, whose normalised direction
 * is not orthogonal to Q at all.  Such a column carries nothing new, so it
 * is replaced by a fixed pseudo-random vector before the QR, and the passes
 * go on until no column had to be replaced (three at most). */
static sb_result_t FN(orth_against)(sb_svd_t *s, const R *Q, size_t l, R *Yb, size_t rows, size_t bb) {
    R *c = s->c;
    sb_result_t r = SB_OK;
    int passes = l > 0 ? 2 : 1;
    for (int pass = 0; pass < passes && r == SB_OK; pass++) {
        if (l > 0) {
            GEMM(CblasColMajor, CblasTrans, CblasNoTrans, (int)l, (int)bb, (int)rows, 1, Q, (int)rows, Yb, (int)rows, 0,
                 c, (int)l);
            GEMM(CblasColMajor, CblasNoTrans, CblasNoTrans, (int)rows, (int)bb, (int)l, -1, Q, (int)rows, c, (int)l, 1,
                 Yb, (int)rows);
            /* |projection|^2 + |remainder|^2 = |column|^2: a remainder at
             * rounding level means the column was inside span(Q) */
            int replaced = 0;
            for (size_t j = 0; j < bb; j++) {
                double pj = 0, rj = 0;
                for (size_t i = 0; i < l; i++)
                    pj += (double)c[i + j * l] * (double)c[i + j * l];
                for (size_t i = 0; i < rows; i++)
                    rj += (double)Yb[i + j * rows] * (double)Yb[i + j * rows];
                double floor2 = sizeof(R) == sizeof(float) ? 1e-10 : 1e-20; /* (1e3 eps)^2 or so */
                if (rj > floor2 * (pj + rj) && rj > 0) continue;
                uint64_t st = 0x5eedULL + (uint64_t)(l + j) * 0x9E3779B97F4A7C15ULL + (uint64_t)pass;
                for (size_t i = 0; i < rows; i++)
                    Yb[i + j * rows] = (R)((double)(splitmix64(&st) >> 11) * 0x1.0p-53 - 0.5);
                replaced = 1;
            }
            if (replaced && passes < 3) passes++; /* the new columns need their own two passes */
        }
        r = FN(orth)(s, Yb, rows, bb);
    }
    return r;
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

/* RANDOMIZED, blocked (Halko-Martinsson-Tropp 2011, Alg. 4.4 per block;
 * Martinsson-Voronin 2016 for the blocks; Musco-Musco 2015 for Krylov).
 * For each block of bb test vectors Omega_b, with Q the basis so far:
 *   Y = A Omega_b, orthogonalised against Q, QR;
 *   q times: Z = A^T Y, QR; Y = A Z, orthogonalised against Q, QR;
 *   B_b^T = A^T Q_b for the block's new columns Q_b.
 * Plain subspace iteration keeps only the last Y of a block; block Krylov
 * appends every Y to Q (each orthogonalised against all earlier columns),
 * so the block adds (q + 1) bb columns built from the same 2q + 2 reads of
 * A (each A^T Y is both the next iteration's start and a block of B^T),
 * and the basis holds every polynomial in A A^T of degree <= q applied to
 * A Omega instead of only the highest power.  Since the new Y is
 * orthogonal to the earlier Q, the iterations act on the deflated matrix
 * (I - Q Q^T) A.  Then B^T = W S X^T (gesdd, n x L) and
 * A ~ Q B = (Q X) S W^T.  Non-adaptive: one block of l vectors (the plain
 * HMT algorithm, or its block Krylov form).  Adaptive: blocks of s->b until
 * the relative error 1 - captured meets the target with r + p <= columns (see
 * svd.h).  Om is the start block (n x l).  Returns the columns of Q in
 * *lused and the rank in *rank. */
static sb_result_t FN(run_rand)(sb_svd_t *s, const R *A, size_t lda, const R *Om, int adaptive, double tol2, double nrm,
                                size_t min_rank, size_t *lused, size_t *rank) {
    size_t m = s->m, n = s->n, k = s->k, lmax = s->l, b = adaptive ? s->b : lmax, tv = 0, c = 0;
    R *Q = s->y, *Z = s->z, *Bt = s->bt;
    double captured = 0, inv = nrm > 0 ? 1 / nrm : 0; /* captured energy relative to ||A||^2 */
    sb_result_t r;
    *rank = k;
    while (tv < lmax) {
        size_t bb = lmax - tv < b ? lmax - tv : b, c0 = c;
        R *Y = Q + c * m;
        GEMM(CblasColMajor, CblasNoTrans, CblasNoTrans, (int)m, (int)bb, (int)n, 1, A, (int)lda, Om + tv * n, (int)n, 0,
             Y, (int)m);
        if ((r = FN(orth_against)(s, Q, c, Y, m, bb)) != SB_OK) return r;
        for (int it = 0;; it++) {
            /* A^T Y: the start of the next iteration, and the rows Y^T A of
             * B when Y stays in the basis (every iterate for Krylov, which
             * so needs no extra read of A for B) */
            R *AtY = s->krylov || it == s->q ? Bt + c * n : Z;
            GEMM(CblasColMajor, CblasTrans, CblasNoTrans, (int)n, (int)bb, (int)m, 1, A, (int)lda, Y, (int)m, 0, AtY,
                 (int)n);
            if (it == s->q) break;
            if (AtY != Z) memcpy(Z, AtY, n * bb * sizeof(R));
            if ((r = FN(orth)(s, Z, n, bb)) != SB_OK) return r;
            if (s->krylov) { /* keep this iterate: the next goes after it */
                c += bb;
                Y = Q + c * m;
            }
            GEMM(CblasColMajor, CblasNoTrans, CblasNoTrans, (int)m, (int)bb, (int)n, 1, A, (int)lda, Z, (int)n, 0, Y,
                 (int)m);
            if ((r = FN(orth_against)(s, Q, c, Y, m, bb)) != SB_OK) return r;
        }
        c += bb;
        tv += bb;
        R *Bb = Bt + c0 * n;
        if (adaptive) {
            for (size_t i = 0; i < n * (c - c0); i++)
                captured += ((double)Bb[i] * inv) * ((double)Bb[i] * inv);
            if (tv < lmax && nrm > 0 && 1 - captured > tol2) continue; /* not there yet with all c columns */
        }
        /* SVD of B^T (n x c) on a copy: B^T itself is kept for more blocks */
        memcpy(Z, Bt, n * c * sizeof(R));
        lapack_int info = GESDD(LAPACK_COL_MAJOR, 'S', (lapack_int)n, (lapack_int)c, Z, (lapack_int)n, s->sv, s->ws,
                                (lapack_int)n, s->vt, (lapack_int)c, s->work, s->lwork, s->iwork);
        if (info != 0) return sb_error(s->ctx, SB_ERR_NUMERIC, "svd: gesdd failed (info %d)", (int)info);
        if (!adaptive) break;
        const R *sv = s->sv;
        size_t want = k, lo = min_rank > 0 ? min_rank : 1;
        double cum = 0;
        for (size_t j = 0; j < k && j < c; j++) {
            cum += ((double)sv[j] * inv) * ((double)sv[j] * inv);
            if (j + 1 >= lo && (!(nrm > 0) || 1 - cum <= tol2)) {
                want = j + 1;
                break;
            }
        }
        *rank = want;
        if (want + (size_t)s->p <= c) break;
    }
    *lused = c;
    /* U = Q X for the leading columns of X (the rank is at most k) */
    GEMM(CblasColMajor, CblasNoTrans, CblasTrans, (int)m, (int)*rank, (int)c, 1, Q, (int)m, s->vt, (int)c, 0, s->u,
         (int)m);
    return SB_OK;
}

static void FN(out_rand)(const sb_svd_t *s, size_t r, double *sv, double *U, double *V) {
    const R *x = s->sv;
    for (size_t j = 0; j < r; j++)
        sv[j] = (double)x[j];
    if (U) FN(put)(s->u, s->m, s->m, r, U, s->m);
    if (V) FN(put)(s->ws, s->n, s->n, r, V, s->n);
}

/* TOPK by restarted block Krylov.  Each cycle is the block Krylov range
 * finder above from a start block V (n x l): the basis Q of
 * [A V, (A A^T) A V, ..., (A A^T)^q A V], B^T = A^T Q = W S X^T, Ritz
 * triplets (s_j, u_j = Q x_j, v_j = w_j).  Since B^T = A^T Q exactly,
 * A^T u_j = s_j v_j, and the residual of a triplet is
 *     r_j = A v_j - s_j u_j,
 * one more product A W_k (m x k).  A Ritz triplet with residual r is within
 * |r| of a singular value (Weyl, on [0 A; A^T 0]), and its vectors within
 * an angle |r| / gap of the singular subspace; the values' error is even
 * ~|r|^2 / gap.  Stop when max_j |r_j| <= tol s_1 (svd.h: tol = 2^-40 in
 * double, 2^-12 in single); otherwise restart from the l leading right
 * Ritz vectors (thick restart: the cycle keeps what it found and each new
 * one raises the polynomial degree by 2q + 1).  Every cycle reads A 2q + 3
 * times in BLAS-3 products.  *done = 0 when max_cycles did not suffice. */
static sb_result_t FN(run_topk_krylov)(sb_svd_t *s, const R *A, size_t lda, int max_cycles, int *done) {
    size_t m = s->m, n = s->n, k = s->k, l = s->l, lused, rank;
    const double tol = sizeof(R) == sizeof(float) ? 0x1.0p-12 : 0x1.0p-40;
    R *AW = s->g, *V = s->st;
    const R *sv = s->sv, *U = s->u;
    *done = 0;
    memcpy(V, s->om, n * l * sizeof(R));
    for (int cycle = 1; cycle <= max_cycles; cycle++) {
        sb_result_t r = FN(run_rand)(s, A, lda, V, 0, 0, -1, 0, &lused, &rank);
        if (r != SB_OK) return r;
        GEMM(CblasColMajor, CblasNoTrans, CblasNoTrans, (int)m, (int)k, (int)n, 1, A, (int)lda, s->ws, (int)n, 0, AW,
             (int)m);
        double worst = 0;
        for (size_t j = 0; j < k; j++) {
            double r2 = 0, sj = (double)sv[j];
            for (size_t i = 0; i < m; i++) {
                double x = (double)AW[i + j * m] - sj * (double)U[i + j * m];
                r2 += x * x;
            }
            worst = fmax(worst, sqrt(r2));
        }
        s->cycles = cycle;
        s->resid = (double)sv[0] > 0 ? worst / (double)sv[0] : 0;
        if (!(worst > tol * (double)sv[0])) { /* also s_1 = 0: the zero matrix */
            *done = 1;
            return SB_OK;
        }
        memcpy(V, s->ws, n * l * sizeof(R)); /* the l leading right Ritz vectors, orthonormal */
    }
    return SB_OK;
}

#undef FN
#undef SB_CAT
#undef SB_CAT_
