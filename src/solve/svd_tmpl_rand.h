/* Precision template of the RANDOMIZED method, included by svd_precisions.h once for double and
 * once for float: R is the real type, SFX its suffix, GEMM ... ORGQR the
 * matching BLAS/LAPACK routines, so the maths is written once.  Not a
 * header of its own: no guard.
 *
 * Storage: every matrix column-major; names follow the maths in svd.h.  In
 * double precision the products read the caller's A with its lda; in single
 * precision they read the float copy s->a (ld = m) made by svd.c. */

#include "solve/svd_tmpl_common.h"

/* ---- plan --------------------------------------------------------------- */

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
        !(s->u = ws_alloc(s, m, k, z)) || !(s->iwork = ws_alloc(s, 8 * L, 1, sizeof(lapack_int))) ||
        !(s->rs = ws_alloc(s, L, L, z)) || !(s->ur = ws_alloc(s, L, L, z)))
        return SB_ERR_NOMEM;
    s->liwork = 8 * (lapack_int)L;
    /* Omega: i.i.d. N(0, 1), drawn once per plan from the seed */
    R *om = s->om;
    sb_rng_t st;
    sb_rng_seed(&st, s->seed);
    for (size_t i = 0; i < n * l; i += 2) {
        double g[2];
        sb_rng_gauss2(&st, g);
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
    /* the Rayleigh-Ritz step (ritz): QR of B^T (n x L), SVD of its R, Qb applied to up to l columns */
    lapack_int info = GEQRF(LAPACK_COL_MAJOR, (lapack_int)n, (lapack_int)L, s->z, (lapack_int)n, s->tau, &q, -1);
    big |= info != 0 || FN(lwork_of)(q, &s->lwork);
    info = GESDD(LAPACK_COL_MAJOR, 'S', (lapack_int)L, (lapack_int)L, s->rs, (lapack_int)L, s->sv, s->ur, (lapack_int)L,
                 s->vt, (lapack_int)L, &q, -1, s->iwork);
    big |= info != 0 || FN(lwork_of)(q, &s->lwork);
    info = ORMQR(LAPACK_COL_MAJOR, 'L', 'N', (lapack_int)n, (lapack_int)l, (lapack_int)L, s->z, (lapack_int)n, s->tau,
                 s->ws, (lapack_int)n, &q, -1);
    big |= info != 0 || FN(lwork_of)(q, &s->lwork);
    if (big) return sb_error(s->ctx, SB_ERR_NUMERIC, "svd: workspace query failed or too large");
    return SB_OK;
}

/* ---- method ------------------------------------------------------------- */

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
                    Yb[i + j * rows] = (R)((double)(sb_splitmix64(&st) >> 11) * 0x1.0p-53 - 0.5);
                replaced = 1;
            }
            if (replaced && passes < 3) passes++; /* the new columns need their own two passes */
        }
        r = FN(orth)(s, Yb, rows, bb);
    }
    return r;
}

/* TOPK: the residual estimate's buffers (see krylov_est), for up to L
 * basis columns. */
static sb_result_t FN(plan_est)(sb_svd_t *s) {
    size_t L = s->L, l = s->l, k = s->k, m = s->m;
    const size_t z = sizeof(R);
    if (!(s->eg = ws_alloc(s, L, L, z)) || !(s->egc = ws_alloc(s, L, L, z)) || !(s->ew = ws_alloc(s, L, 1, z)) ||
        !(s->ex = ws_alloc(s, L, k, z)) || !(s->er = ws_alloc(s, l, l, z)) || !(s->erx = ws_alloc(s, l, k, z)) ||
        !(s->ep = ws_alloc(s, m, k, z)) || !(s->eisuppz = ws_alloc(s, 2 * k, 1, sizeof(lapack_int))))
        return SB_ERR_NOMEM;
    R q = 0;
    lapack_int qi = 0, found = 0;
    lapack_int info =
        SYEVR(LAPACK_COL_MAJOR, 'V', 'I', 'U', (lapack_int)L, s->egc, (lapack_int)L, 0, 0, (lapack_int)(L - k + 1),
              (lapack_int)L, 0, &found, s->ew, s->ex, (lapack_int)L, s->eisuppz, &q, -1, &qi, -1);
    if (info != 0 || FN(lwork_of)(q, &s->elwork) || qi < 1)
        return sb_error(s->ctx, SB_ERR_NUMERIC, "svd: workspace query failed or too large");
    s->eliwork = qi;
    if (!(s->ewk = ws_alloc(s, (size_t)s->elwork, 1, z)) || !(s->eiw = ws_alloc(s, (size_t)qi, 1, sizeof(lapack_int))))
        return SB_ERR_NOMEM;
    return SB_OK;
}

/* TOPK: the largest residual |A v_j - s_j u_j| / s_1 of the k leading Ritz
 * triplets of the basis Q so far (m x c, last block Q_i of bb columns),
 * read off the next block instead of A.  With A^T Q_i = Z Rb (Z
 * orthonormal, n x bb) and P = A Z, A A^T Q_i = P Rb, and every earlier
 * block maps into span(Q) (A A^T Q_h is the block after it before its
 * orthogonalisation).  The Ritz vectors are u_j = Q x_j and
 * v_j = A^T u_j / s_j with B B^T x_j = s_j^2 x_j (B^T = A^T Q), and
 * Q^T (A v_j - s_j u_j) = B B^T x_j / s_j - s_j x_j = 0, so
 *     A v_j - s_j u_j = (I - Q Q^T) P Rb x_j,i / s_j,
 * x_j,i the last bb entries of x_j: k thin products, no read of A.  x_j
 * comes from the Gram matrix B B^T, whose new columns are formed each
 * degree.  The estimate only decides when to stop expanding: the
 * certificate is run_topk_krylov's own residual, from A.  *est is
 * infinite where no estimate could be formed. */
static sb_result_t FN(krylov_est)(sb_svd_t *s, size_t c, size_t bb, const R *Zo, const R *P, double *est) {
    size_t m = s->m, n = s->n, k = s->k, L = s->L;
    const R *Q = s->y, *Bt = s->bt, *Bi = Bt + (c - bb) * n;
    R *G = s->eg, *Gc = s->egc, *w = s->ew, *X = s->ex, *Rb = s->er, *RX = s->erx, *Pk = s->ep, *C = s->c;
    *est = INFINITY;
    if (c < k || c > L) return SB_OK;
    /* the new columns of G = B B^T = (B^T)^T B^T, upper triangle */
    size_t g0 = s->eg_cols < c ? s->eg_cols : 0;
    GEMM(CblasColMajor, CblasTrans, CblasNoTrans, (int)c, (int)(c - g0), (int)n, 1, Bt, (int)n, Bt + g0 * n, (int)n, 0,
         G + g0 * L, (int)L);
    s->eg_cols = c;
    for (size_t j = 0; j < c; j++)
        memcpy(Gc + j * c, G + j * L, (j + 1) * sizeof(R));
    lapack_int found = 0;
    lapack_int info =
        SYEVR(LAPACK_COL_MAJOR, 'V', 'I', 'U', (lapack_int)c, Gc, (lapack_int)c, 0, 0, (lapack_int)(c - k + 1),
              (lapack_int)c, 0, &found, w, X, (lapack_int)c, s->eisuppz, s->ewk, s->elwork, s->eiw, s->eliwork);
    if (info != 0 || found != (lapack_int)k) return SB_OK; /* no estimate: expand on */
    double s1sq = (double)w[k - 1];                        /* ascending: the largest last */
    if (!(s1sq > 0) || !(w[0] > 0)) return SB_OK;
    GEMM(CblasColMajor, CblasTrans, CblasNoTrans, (int)bb, (int)bb, (int)n, 1, Zo, (int)n, Bi, (int)n, 0, Rb, (int)bb);
    GEMM(CblasColMajor, CblasNoTrans, CblasNoTrans, (int)bb, (int)k, (int)bb, 1, Rb, (int)bb, X + (c - bb), (int)c, 0,
         RX, (int)bb);
    GEMM(CblasColMajor, CblasNoTrans, CblasNoTrans, (int)m, (int)k, (int)bb, 1, P, (int)m, RX, (int)bb, 0, Pk, (int)m);
    for (int pass = 0; pass < 2; pass++) { /* (I - Q Q^T), twice; C is L x l >= c x k */
        GEMM(CblasColMajor, CblasTrans, CblasNoTrans, (int)c, (int)k, (int)m, 1, Q, (int)m, Pk, (int)m, 0, C, (int)c);
        GEMM(CblasColMajor, CblasNoTrans, CblasNoTrans, (int)m, (int)k, (int)c, -1, Q, (int)m, C, (int)c, 1, Pk,
             (int)m);
    }
    double worst2 = 0;
    for (size_t j = 0; j < k; j++) {
        double r2 = 0;
        for (size_t i = 0; i < m; i++)
            r2 += (double)Pk[i + j * m] * (double)Pk[i + j * m];
        worst2 = fmax(worst2, r2 / (double)w[j]);
    }
    *est = sqrt(worst2 / s1sq);
    return SB_OK;
}

/* W (s->ws) <- its first `cols` columns Qb Ur of the Rayleigh-Ritz step
 * below, from the reflectors of Qb (s->z, s->tau) and Ur (s->ur). */
static sb_result_t FN(ritz_left)(sb_svd_t *s, size_t c, size_t cols) {
    size_t n = s->n;
    R *W = s->ws;
    const R *Ur = s->ur;
    for (size_t j = 0; j < cols; j++) {
        memcpy(W + j * n, Ur + j * c, c * sizeof(R));
        memset(W + j * n + c, 0, (n - c) * sizeof(R));
    }
    lapack_int info = ORMQR(LAPACK_COL_MAJOR, 'L', 'N', (lapack_int)n, (lapack_int)cols, (lapack_int)c, s->z,
                            (lapack_int)n, s->tau, W, (lapack_int)n, s->work, s->lwork);
    return info == 0 ? SB_OK : sb_error(s->ctx, SB_ERR_NUMERIC, "svd: ormqr failed (info %d)", (int)info);
}

/* Rayleigh-Ritz: B^T (s->bt, n x c) = W S X^T, with S (s->sv, c values),
 * X^T (s->vt, c x c) and the first `cols` columns of W (s->ws).  By a QR
 * first, B^T = Qb Rb, and the SVD of the small Rb = Ur S X^T, so W = Qb Ur
 * is formed only for the columns asked for (a gesdd of the tall B^T forms
 * all c: 1.7x the time at n = 4096, c = 144..288). */
static sb_result_t FN(ritz)(sb_svd_t *s, size_t c, size_t cols) {
    size_t n = s->n;
    R *Z = s->z, *Rs = s->rs;
    memcpy(Z, s->bt, n * c * sizeof(R));
    lapack_int info =
        GEQRF(LAPACK_COL_MAJOR, (lapack_int)n, (lapack_int)c, Z, (lapack_int)n, s->tau, s->work, s->lwork);
    if (info != 0) return sb_error(s->ctx, SB_ERR_NUMERIC, "svd: QR failed (info %d)", (int)info);
    for (size_t j = 0; j < c; j++) {
        memcpy(Rs + j * c, Z + j * n, (j + 1) * sizeof(R));
        memset(Rs + j * c + j + 1, 0, (c - j - 1) * sizeof(R));
    }
    info = GESDD(LAPACK_COL_MAJOR, 'S', (lapack_int)c, (lapack_int)c, Rs, (lapack_int)c, s->sv, s->ur, (lapack_int)c,
                 s->vt, (lapack_int)c, s->work, s->lwork, s->iwork);
    if (info != 0) return sb_error(s->ctx, SB_ERR_NUMERIC, "svd: gesdd failed (info %d)", (int)info);
    return FN(ritz_left)(s, c, cols);
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
 * svd.h).  Om is the start block (n x lmax, lmax <= s->l).  Returns the columns of Q in
 * *lused and the rank in *rank. */
static sb_result_t FN(run_rand)(sb_svd_t *s, const R *A, size_t lda, const R *Om, size_t lmax, int adaptive,
                                double tol2, double nrm, size_t min_rank, size_t *lused, size_t *rank) {
    size_t m = s->m, n = s->n, k = s->k, b = adaptive ? s->b : lmax, tv = 0, c = 0;
    R *Q = s->y, *Z = s->z, *Bt = s->bt;
    double captured = 0, inv = nrm > 0 ? 1 / nrm : 0; /* captured energy relative to ||A||^2 */
    double last_est = INFINITY;                       /* TOPK: the last residual estimate, at degree last_deg */
    int last_deg = -1;
    sb_result_t r;
    *rank = k;
    while (tv < lmax) {
        size_t bb = lmax - tv < b ? lmax - tv : b, c0 = c;
        R *Y = Q + c * m;
        GEMM_THIN(s->sym, (int)m, (int)bb, (int)n, A, (int)lda, Om + tv * n, (int)n, Y, (int)m);
        if ((r = FN(orth_against)(s, Q, c, Y, m, bb)) != SB_OK) return r;
        for (int it = 0;; it++) {
            /* A^T Y: the start of the next iteration, and the rows Y^T A of
             * B when Y stays in the basis (every iterate for Krylov, which
             * so needs no extra read of A for B) */
            R *AtY = s->krylov || it == s->q ? Bt + c * n : Z;
            GEMM_THIN(1, (int)n, (int)bb, (int)m, A, (int)lda, Y, (int)m, AtY, (int)n);
            if (it == s->q) break;
            if (AtY != Z) memcpy(Z, AtY, n * bb * sizeof(R));
            if ((r = FN(orth)(s, Z, n, bb)) != SB_OK) return r;
            if (s->krylov) { /* keep this iterate: the next goes after it */
                c += bb;
                Y = Q + c * m;
            }
            GEMM_THIN(s->sym, (int)m, (int)bb, (int)n, A, (int)lda, Z, (int)n, Y, (int)m);
            /* TOPK: stop at the degree that suffices.  The estimate is
             * skipped where it could not be met (before degree 2, or while
             * the last one was more than 10^4 per degree above the
             * tolerance) and where it would cost more than the reads it can
             * save (syevr of the c x c Gram matrix runs at a small fraction
             * of a product's rate: N = 1024, c = 162) */
            if (s->est_tol > 0 && s->krylov && it >= 2 &&
                (last_deg < 0 || last_est <= s->est_tol * pow(1e4, (double)(it - last_deg))) &&
                (double)m * (double)n * (double)bb > 20.0 * (double)c * (double)c * (double)c) {
                double est;
                if ((r = FN(krylov_est)(s, c, bb, Z, Y, &est)) != SB_OK) return r;
                last_est = est;
                last_deg = it;
                if (est <= s->est_tol) {
                    s->est_stop = it;
                    c -= bb; /* the basis ends with block it (c grows by bb below) */
                    break;
                }
            }
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
        /* SVD of B^T (n x c): B^T itself is kept for more blocks */
        if ((r = FN(ritz)(s, c, k < c ? k : c)) != SB_OK) return r;
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
 * one raises the polynomial degree by 2q + 1; the block doubles up to
 * s->l, twice the first block, from the second cycle on).  Every cycle reads A 2q + 3
 * times in BLAS-3 products.  *done = 0 when max_cycles did not suffice. */
static sb_result_t FN(run_topk_krylov)(sb_svd_t *s, const R *A, size_t lda, int max_cycles, int *done) {
    size_t m = s->m, n = s->n, k = s->k, l = s->l0 ? s->l0 : s->l, lused, rank;
    const double tol = sizeof(R) == sizeof(float) ? 0x1.0p-12 : 0x1.0p-40;
    R *AW = s->g, *V = s->st;
    const R *sv = s->sv, *U = s->u;
    *done = 0;
    memcpy(V, s->om, n * l * sizeof(R));
    s->est_tol = tol / 2;
    for (int cycle = 1; cycle <= max_cycles; cycle++) {
        s->est_stop = -1;
        s->eg_cols = 0;
        sb_result_t r = FN(run_rand)(s, A, lda, V, l, 0, 0, -1, 0, &lused, &rank);
        if (r != SB_OK) return r;
        GEMM_THIN(s->sym, (int)m, (int)k, (int)n, A, (int)lda, s->ws, (int)n, AW, (int)m);
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
        /* restart from the leading right Ritz vectors (orthonormal; the
         * basis had lused >= 2 l of them), with twice the block up to the
         * plan's s->l: a slowly decaying spectrum (GGX roughness 0.1 at
         * N = 4096: 40 cycles of 18 columns and the Gram route, 57 s for
         * three channels) converges in a few cycles of a wider block */
        l = 2 * l < s->l ? 2 * l : s->l;
        if (l > lused) l = lused;
        if ((r = FN(ritz_left)(s, lused, l)) != SB_OK) return r;
        memcpy(V, s->ws, n * l * sizeof(R));
    }
    return SB_OK;
}

#undef FN
#undef SB_CAT
#undef SB_CAT_
