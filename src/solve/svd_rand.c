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

sb_result_t sb_svd_plan_rand(sb_svd_t *s) { return s->single ? plan_rand_f(s) : plan_rand_d(s); }

sb_result_t sb_svd_run_rand(sb_svd_t *s, sb_svd_run_t *run) {
    size_t r = s->k, sketch = 0;
    sb_result_t res = s->single ? run_rand_f(s, run->a, run->la, s->om, s->l, run->adaptive, run->tol2, run->nrm,
                                             run->min_rank, &sketch, &r)
                                : run_rand_d(s, run->a, run->la, s->om, s->l, run->adaptive, run->tol2, run->nrm,
                                             run->min_rank, &sketch, &r);
    if (res != SB_OK) return res;
    if (s->single)
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
