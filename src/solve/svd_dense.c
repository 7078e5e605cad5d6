/* The dense methods of the truncated SVD: FULL (dgesdd on a copy, every
 * singular value) and TOPK (Gram matrix, dsyevr, one Rayleigh-Ritz step).
 * The maths is in svd_tmpl_dense.h, written once for both precisions. */
#include <cblas.h>
#include <lapacke.h>
#include <math.h>
#include <stdint.h>

#include "solve/svd_internal.h"
#include "util/internal.h"

#define SB_SVD_TEMPLATE "solve/svd_tmpl_dense.h"
#include "solve/svd_precisions.h"
#undef SB_SVD_TEMPLATE

sb_result_t sb_svd_plan_dense(sb_svd_t *s) {
    if (s->method == SB_METHOD_FULL) return s->single ? plan_full_f(s) : plan_full_d(s);
    return s->single ? plan_topk_f(s) : plan_topk_d(s);
}

/* FULL: every singular value (into all_s when asked); the adaptive rank
 * and the residual from the tail sum_{i>=j} (s_i / ||A||)^2, summed from
 * the end so that small errors are not differences. */
sb_result_t sb_svd_run_full(sb_svd_t *s, sb_svd_run_t *run) {
    sb_result_t res = s->single ? run_full_f(s) : run_full_d(s);
    if (res != SB_OK) return res;
    size_t d = s->d, k = s->k, r = k;
    if (run->all_s) {
        for (size_t j = 0; j < d; j++)
            run->all_s[j] = sb_svd_sv_at(s, j);
        if (run->have_all) *run->have_all = 1;
    }
    double nrm = run->nrm, t = 0, inv = nrm > 0 ? 1 / nrm : 0;
    size_t lo = run->min_rank > 0 ? run->min_rank : 1;
    for (size_t j = d; j-- > 0;) {
        double x = sb_svd_sv_at(s, j) * inv;
        t += x * x;
        if (run->adaptive && j >= lo && j <= k && t <= run->tol2) r = j;
    }
    t = 0;
    for (size_t j = d; j-- > r;)
        t += (sb_svd_sv_at(s, j) * inv) * (sb_svd_sv_at(s, j) * inv);
    if (s->single)
        out_full_f(s, r, run->sv, run->U, run->V);
    else
        out_full_d(s, r, run->sv, run->U, run->V);
    run->info.norm_fro = nrm;
    run->info.resid_fro = nrm > 0 ? nrm * sqrt(t) : 0;
    run->r = r;
    run->sketch = d;
    return SB_OK;
}

/* TOPK: the k leading triplets; ||A||_F from the trace of the Gram matrix
 * when not known. */
sb_result_t sb_svd_run_topk(sb_svd_t *s, sb_svd_run_t *run) {
    double tr;
    size_t k = s->k;
    sb_result_t res = s->single ? run_topk_f(s, run->a, run->la, &tr) : run_topk_d(s, run->a, run->la, &tr);
    if (res != SB_OK) return res;
    if (run->nrm < 0) run->nrm = sqrt(tr);
    if (s->single)
        out_topk_f(s, k, run->sv, run->U, run->V);
    else
        out_topk_d(s, k, run->sv, run->U, run->V);
    run->r = run->adaptive ? sb_svd_rank_for(run->sv, k, run->nrm, run->tol2, run->min_rank) : k;
    run->info.norm_fro = run->nrm;
    run->info.resid_fro = sb_svd_resid_from(run->nrm, run->sv, run->r);
    run->sketch = k;
    return SB_OK;
}
