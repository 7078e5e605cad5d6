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
    sb_result_t res =
        s->single ? run_rand_f(s, run->a, run->la, run->adaptive, run->tol2, run->nrm, run->min_rank, &sketch, &r)
                  : run_rand_d(s, run->a, run->la, run->adaptive, run->tol2, run->nrm, run->min_rank, &sketch, &r);
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
