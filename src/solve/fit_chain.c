/* Masked fit, part 4 (fit.c has the whole picture): nested terms.  A
 * k-term fit (k > SB_CHAIN_JOINT) is the SB_CHAIN_JOINT-term fit (stages,
 * taps, strict pass: fit_taps.c), then one term at a time, each a one-term
 * masked fit of what the terms before leave on the valid cells (without
 * taps: the cells outside continue the fit so far).  Nothing in a term
 * depends on k, so the first j >= SB_CHAIN_JOINT terms of a k-term fit are
 * the j-term fit to the bit, and what a shader returns with J' = j terms
 * of a -J 8 run is what the -J j run returns (but for the texel filter and
 * term weights the job chooses at J).
 *
 * Why: the staged fit of all k terms at once made its decisions for k.
 * Its warm start is a rank-k imputation, its taps' constraints are the
 * cells the k-term fit overshoots (and are kept or dropped on the k-term
 * error), its last stage keeps a joint refit that stretches the shorter
 * prefixes, and a taps' round reruns every stage from the k-term fit: GGX
 * roughness 0.3 (iso, f) at -J 8 had 5.05e-4 at J' = 4 where -J 4 has
 * 4.22e-4, and 7.9e-4 at J' = 2 where -J 2 has 5.8e-4.  The joint stages
 * stay up to four terms: a term at a time from two on was exactly nested
 * but lost 40 % on the Cornell acrylic (iso, adaptive warp, J = 4: 2.46e-2
 * -> 3.50e-2); beyond four its joint refits were almost never kept
 * (docs/bands.md, "More terms never worse"). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "solve/fit_impl.h"
#include "util/internal.h"

/* R (valid cells) -= sum_{j in [j0, j1)} s_j u_j v_j^T; returns the
 * squared norm of R on the valid cells after it. */
static double subtract(double *R, size_t lda, const unsigned char *mask, size_t m, size_t n, const double *s,
                       const double *u, const double *v, size_t j0, size_t j1) {
    double e2 = 0;
    for (size_t c = 0; c < n; c++)
        for (size_t r = 0; r < m; r++) {
            if (!mask[r + c * lda]) continue;
            double x = R[r + c * lda];
            for (size_t j = j0; j < j1; j++)
                x -= s[j] * u[r + j * m] * v[c + j * n];
            R[r + c * lda] = x;
            e2 += x * x;
        }
    return e2;
}

sb_result_t fit_chain(sb_fit_t *f, const double *A, size_t lda, const unsigned char *mask, const sb_fit_opts_t *opts,
                      double *s, double *U, double *V, sb_fit_info_t *info) {
    size_t m = f->m, n = f->n, k = f->k;
    sb_fit_opts_t o = *opts;
    size_t ninvalid = 0;
    double norm2 = 0;
    for (size_t c = 0; c < n; c++)
        for (size_t r = 0; r < m; r++) {
            int ok = mask[r + c * lda] != 0;
            ninvalid += !ok;
            if (ok) norm2 += A[r + c * lda] * A[r + c * lda];
        }
    /* every cell valid: an SVD, nested already; beyond SB_ALS_MAX_K terms
     * imputation alone */
    if (ninvalid == 0 || k <= SB_CHAIN_JOINT || k > SB_ALS_MAX_K) /* a warm start is not in the memo's key */
        return f->init_s ? sb_fit_execute(f, A, lda, mask, &o, s, U, V, info)
                         : fit_memo_execute(f, A, lda, mask, &o, s, U, V, info);
    double s0[SB_ALS_MAX_K]; /* the start's sigmas (s is written below: they may be its own) */
    const double *u0 = f->init_u, *v0 = f->init_v;
    int warm = f->init_s != NULL;
    if (warm) memcpy(s0, f->init_s, k * sizeof *s0);
    sb_fit_set_start(f, NULL, NULL, NULL); /* taken: the pieces each start from their own terms of it */
    sb_result_t r = SB_OK;
    for (int i = 0; i < 2 && r == SB_OK; i++)
        if (!f->sub[i]) r = sb_fit_create(f->ctx, m, n, i ? 1 : SB_CHAIN_JOINT, &f->sub[i]);
    if (r == SB_OK && !f->cells && !(f->cells = calloc(1, sizeof *f->cells)))
        r = sb_error(f->ctx, SB_ERR_NOMEM, "fit: out of memory");
    if (r != SB_OK) return r;
    /* the pieces share one gathering of the cells: the same mask in every
     * piece (and channel), gathered once (fit_cells_build) */
    for (int i = 0; i < 2; i++)
        f->sub[i]->cells = f->cells, f->sub[i]->cells_borrowed = 1;
    double *R = malloc(lda * n * sizeof *R), *u = malloc(m * k * sizeof *u), *v = malloc(n * k * sizeof *v);
    if (!R || !u || !v) {
        free(R), free(u), free(v);
        return sb_error(f->ctx, SB_ERR_NOMEM, "fit: cannot allocate %zu bytes",
                        (lda * n + (m + n) * k) * sizeof(double));
    }
    memcpy(R, A, lda * n * sizeof *R);
    memset(s, 0, k * sizeof *s);
    memset(u, 0, m * k * sizeof *u);
    memset(v, 0, n * k * sizeof *v);
    int iters = 0, converged = 1;
    size_t conv = 0; /* the leading terms from converged sweeps (a piece's own conv_terms) */
    double e2 = norm2;
    for (size_t done = 0; done < k && r == SB_OK;) {
        size_t kk = done == 0 ? SB_CHAIN_JOINT : 1;
        sb_fit_info_t fi = {0, 1, 0, kk};
        sb_fit_opts_t oo = o;
        if (done) memset(oo.tex, 0, sizeof oo.tex); /* the pieces: no taps */
        if (warm) sb_fit_set_start(f->sub[done ? 1 : 0], s0 + done, u0 + done * m, v0 + done * n);
        r = sb_fit_execute(f->sub[done ? 1 : 0], R, lda, mask, &oo, s + done, u + done * m, v + done * n, &fi);
        if (r != SB_OK) break;
        iters += fi.iterations;
        conv += conv == done ? (fi.conv_terms < kk ? fi.conv_terms : kk) : 0;
        converged &= fi.converged;
        e2 = subtract(R, lda, mask, m, n, s, u, v, done, done + kk);
        done += kk;
        /* --max-error reached: no more terms (the rest stay 0) */
        if (o.target > 0 && sqrt(e2) <= o.target * sqrt(norm2)) break;
    }
    if (r == SB_OK) {
        if (U) memcpy(U, u, m * k * sizeof *U);
        if (V) memcpy(V, v, n * k * sizeof *V);
        if (converged) conv = k; /* the terms past --max-error: none fitted */
        if (info) *info = (sb_fit_info_t){iters, converged, norm2 > 0 ? sqrt(e2 / norm2) : 0, conv};
    }
    free(R), free(u), free(v);
    return r;
}
