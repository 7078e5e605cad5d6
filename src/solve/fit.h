/* Private: masked low-rank fitting by iterative imputation (fit.c); the plan uses it through the masked solver
 * (solver_masked.c). */
#ifndef SEPBRDF_FIT_H
#define SEPBRDF_FIT_H

#include "sepbrdf/common.h"

typedef struct sb_fit sb_fit_t;

typedef struct sb_fit_opts {
    int max_iters; /* default 300 */
    double tol;    /* stop when the valid-cell error improves by less than tol relative; default 1e-5 */
    uint64_t seed; /* starting subspace; default 1 */
    double target; /* stop adding terms once the relative error is <= target (0 = all k) */
    /* Texture layout of the rows (tex[0]: g, width x height = m) and the
     * columns (tex[1]: h, = n) with their wrap (SB_WRAP_*): when given, an
     * invalid cell within two texels of valid ones on both sides (what a
     * bilinear tap of an in-domain pair reaches) whose fitted value
     * overshoots the data around it is constrained into their range and
     * the fit repeated (fit.c: constrain_taps), so lookups near the
     * domain's edge stay bounded.  0: no layout. */
    size_t tex[2][2];
    int wrap[2][2];
} sb_fit_opts_t;

typedef struct sb_fit_info {
    int iterations, converged; /* converged: every term's sweeps ended by the tolerance */
    double rel_err;            /* on valid cells */
    /* the leading terms whose sweeps (those that last set them) all ended
     * by the tolerance: k when converged; a prefix of that many terms
     * written alone is a converged fit */
    size_t conv_terms;
} sb_fit_info_t;

sb_result_t sb_fit_create(sb_context_t *ctx, size_t m, size_t n, size_t k, sb_fit_t **out);
void sb_fit_destroy(sb_fit_t *f);
/* Rank-k fit of A (m x n, lda) on cells with mask != 0 (mask has leading
 * dimension lda too).  s (k), U (m x k), V (n x k) as in sb_svd_execute. */
sb_result_t sb_fit_execute(sb_fit_t *f, const double *A, size_t lda, const unsigned char *mask,
                           const sb_fit_opts_t *opts, double *s, double *U, double *V, sb_fit_info_t *info);
/* A warm start for f's next fit (fit_chain or sb_fit_execute; that fit
 * takes it and leaves none; NULL: none): a k-term fit of this shape, s (k),
 * U (m x k) and V (n x k) as sb_fit_execute writes them (a converged fit
 * of a nearby matrix: a refit without a tenth of the table), from which
 * the alternating least squares start instead of the imputation's
 * estimate, at their last stage (term k alone on the others, then all k
 * jointly; the shorter prefixes' errors the start's), so that a fit
 * started from its own converged factors stops after a sweep a stage.
 * Taken where every sigma is > 0 and the fit runs its ALS (cells masked,
 * k <= 32); such a fit is not memoised (fit_memo.c). */
void sb_fit_set_start(sb_fit_t *f, const double *s, const double *U, const double *V);

#endif
