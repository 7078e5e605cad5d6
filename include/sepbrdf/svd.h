/* sepbrdf: truncated singular value decomposition of one dense matrix.
 *
 * A (m x n, column-major, leading dimension lda) ~ U diag(s) V^T with the k
 * leading singular triplets, s descending.  Plan once, execute many: the plan
 * checks shapes, picks the method, queries LAPACK workspaces and allocates;
 * execute allocates nothing and never modifies A. */
#ifndef SEPBRDF_SVD_H
#define SEPBRDF_SVD_H

#include "common.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum sb_method {
    SB_METHOD_AUTO = 0,   /* pick from m, n, k and the accuracy asked */
    SB_METHOD_FULL,       /* LAPACK dgesdd, all singular values */
    SB_METHOD_TOPK,       /* exact leading k: Gram matrix + dsyevr */
    SB_METHOD_RANDOMIZED, /* Halko-Martinsson-Tropp range finder */
    SB_METHOD_COUNT_
} sb_method_t;

sb_result_t sb_method_parse(const char *name, sb_method_t *out); /* auto|full|topk|randomized */
const char *sb_method_name(sb_method_t m);

typedef struct sb_svd_opts {
    sb_method_t method;
    int oversample;       /* randomized: p, default 10 */
    int power_iters;      /* randomized: q, default 2 */
    uint64_t seed;        /* randomized: seed of the test matrix, default 1 */
    int single_precision; /* compute in float (inputs/outputs stay double) */
} sb_svd_opts_t;

typedef struct sb_svd sb_svd_t;

sb_result_t sb_svd_create(sb_context_t *ctx, size_t m, size_t n, size_t k, const sb_svd_opts_t *opts,
                          sb_svd_t **out);
void sb_svd_destroy(sb_svd_t *svd);
sb_method_t sb_svd_method(const sb_svd_t *svd); /* the method actually used */

/* s[0..k-1], U (m x k, ld m), V (n x k, ld n).  U or V may be NULL when not
 * wanted.  If all_s is not NULL and the method computes every singular
 * value (FULL), all min(m, n) of them are written there and 1 returned via
 * *have_all; otherwise *have_all = 0. */
sb_result_t sb_svd_execute(sb_svd_t *svd, const double *A, size_t lda, double *s, double *U, double *V,
                           double *all_s, int *have_all);

#ifdef __cplusplus
}
#endif
#endif
