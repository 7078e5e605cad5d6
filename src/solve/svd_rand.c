/* The RANDOMIZED method of the truncated SVD (Halko-Martinsson-Tropp,
 * block Krylov, adaptive blocks; see svd.h).  The maths is in
 * svd_tmpl_rand.h, written once for both precisions. */
#include <cblas.h>
#include <lapacke.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "solve/svd_internal.h"
#include "util/internal.h"
#include "util/rng.h"

#define SB_SVD_TEMPLATE "solve/svd_tmpl_rand.h"
#include "solve/svd_precisions.h"
#undef SB_SVD_TEMPLATE

/* Mixed precision: the float sketch gave the leading Ritz vectors Uf
 * (s->u, m x r).  In double: U0 = the orthonormal factor of Uf (QR), W =
 * A^T U0 from the caller's A (one read, r columns), W = P S Z^T (gesdd,
 * n x r), so U0^T A = Z S P^T and the rank-r approximation U0 U0^T A =
 * (U0 Z) S P^T: values S, U = U0 Z, V = P.  It is an exact projection in
 * double, so ||A - U S V^T||^2 = ||A||^2 - sum S^2 holds to double
 * rounding (sb_svd_resid_from), and the subspace differs from the double
 * method's by float rounding only, a second-order change of the error. */
static sb_result_t mixed_finish(sb_svd_t *s, const sb_svd_run_t *run, size_t r) {
    size_t m = s->m, n = s->n;
    double *U0 = s->mu, *W = s->mv, *Zt = s->mz, *tau = s->mz + r * r;
    const float *uf = s->u;
    for (size_t i = 0; i < m * r; i++)
        U0[i] = (double)uf[i];
    lapack_int info = LAPACKE_dgeqrf(LAPACK_COL_MAJOR, (lapack_int)m, (lapack_int)r, U0, (lapack_int)m, tau);
    if (info == 0)
        info = LAPACKE_dorgqr(LAPACK_COL_MAJOR, (lapack_int)m, (lapack_int)r, (lapack_int)r, U0, (lapack_int)m, tau);
    if (info != 0) return sb_error(s->ctx, SB_ERR_NUMERIC, "svd: mixed precision QR failed (info %d)", (int)info);
    sb_dgemm_thin(1, (int)n, (int)r, (int)m, run->a0, (int)run->la0, U0, (int)m, W, (int)n);
    double one = 0;
    info = LAPACKE_dgesdd(LAPACK_COL_MAJOR, 'O', (lapack_int)n, (lapack_int)r, W, (lapack_int)n, run->sv, &one, 1, Zt,
                          (lapack_int)r);
    if (info != 0) return sb_error(s->ctx, SB_ERR_NUMERIC, "svd: mixed precision gesdd failed (info %d)", (int)info);
    if (run->U)
        cblas_dgemm(CblasColMajor, CblasNoTrans, CblasTrans, (int)m, (int)r, (int)r, 1, U0, (int)m, Zt, (int)r, 0,
                    run->U, (int)m);
    if (run->V) memcpy(run->V, W, n * r * sizeof(double));
    return SB_OK;
}

sb_result_t sb_svd_plan_rand(sb_svd_t *s) { return s->single ? plan_rand_f(s) : plan_rand_d(s); }

sb_result_t sb_svd_run_rand(sb_svd_t *s, sb_svd_run_t *run) {
    size_t r = s->k, sketch = 0;
    sb_result_t res = s->single ? run_rand_f(s, run->a, run->la, s->om, s->l, run->adaptive, run->tol2, run->nrm,
                                             run->min_rank, &sketch, &r)
                                : run_rand_d(s, run->a, run->la, s->om, s->l, run->adaptive, run->tol2, run->nrm,
                                             run->min_rank, &sketch, &r);
    if (res != SB_OK) return res;
    if (s->mixed) {
        if ((res = mixed_finish(s, run, r)) != SB_OK) return res;
    } else if (s->single)
        out_rand_f(s, r, run->sv, run->U, run->V);
    else
        out_rand_d(s, r, run->sv, run->U, run->V);
    if (run->nrm >= 0) {
        run->info.norm_fro = run->nrm;
        run->info.resid_fro = sb_svd_resid_from(run->nrm, run->sv, r);
    }
    run->r = r;
    run->sketch = sketch;
    return SB_OK;
}

/* TOPK's plan: the Krylov route's buffers (the randomized plan's, plus
 * A W_k in g and the start block st); svd.c adds the Gram route. */
sb_result_t sb_svd_plan_topk_krylov(sb_svd_t *s) {
    sb_result_t r = s->single ? plan_rand_f(s) : plan_rand_d(s);
    size_t z = s->single ? sizeof(float) : sizeof(double);
    if (r == SB_OK && (!(s->g = ws_alloc(s, s->m, s->k, z)) || !(s->st = ws_alloc(s, s->n, s->l, z)))) r = SB_ERR_NOMEM;
    if (r == SB_OK) r = s->single ? plan_est_f(s) : plan_est_d(s);
    return r;
}

/* TOPK by Krylov cycles (svd_tmpl_rand.h), the Gram route when they reach
 * the cycle limit.  ||A||_F is read once when not known (execute). */
sb_result_t sb_svd_run_topk_krylov(sb_svd_t *s, sb_svd_run_t *run) {
    int done = 0;
    size_t k = s->k;
    sb_result_t r = s->single ? run_topk_krylov_f(s, run->a, run->la, SB_SVD_TOPK_CYCLES, &done)
                              : run_topk_krylov_d(s, run->a, run->la, SB_SVD_TOPK_CYCLES, &done);
    if (r != SB_OK) return r;
    if (done && s->single)
        out_rand_f(s, k, run->sv, run->U, run->V);
    else if (done)
        out_rand_d(s, k, run->sv, run->U, run->V);
    else if (!s->gram_plan)
        return sb_error(s->ctx, SB_ERR_NUMERIC,
                        "svd: topk did not converge in %d cycles (residual %.3g of sigma_1); use the full method",
                        s->cycles, s->resid);
    if (!done) {
        s->gram_plan->ctx = s->ctx;
        sb_svd_run_t g = *run;
        g.adaptive = 0;
        sb_blas_threads_end(sb_blas_thin_threads()); /* the Gram route's dsyrk of A: every BLAS thread */
        r = sb_svd_run_topk(s->gram_plan, &g);
        sb_blas_threads_begin();
        if (r != SB_OK) return r;
    }
    run->r = run->adaptive ? sb_svd_rank_for(run->sv, k, run->nrm, run->tol2, run->min_rank) : k;
    run->info.norm_fro = run->nrm;
    run->info.resid_fro = sb_svd_resid_from(run->nrm, run->sv, run->r);
    run->info.cycles = (size_t)s->cycles;
    run->info.degree = done ? (size_t)(s->est_stop >= 0 ? s->est_stop : s->q) : 0;
    run->sketch = k;
    return SB_OK;
}
