/* Truncated SVD: plan (shapes, method, workspaces) then execute.
 *
 * FULL: copy A, LAPACK dgesdd (jobz = 'S'), keep the k leading triplets. */
#include "sepbrdf/svd.h"

#include <lapacke.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"

static const char *const method_names[SB_METHOD_COUNT_] = {"auto", "full", "topk", "randomized"};

sb_result_t sb_method_parse(const char *name, sb_method_t *out) {
    for (int k = 0; k < SB_METHOD_COUNT_; k++)
        if (name && strcmp(name, method_names[k]) == 0) {
            *out = (sb_method_t)k;
            return SB_OK;
        }
    return SB_ERR_UNKNOWN;
}
const char *sb_method_name(sb_method_t m) { return (unsigned)m < SB_METHOD_COUNT_ ? method_names[m] : "?"; }

struct sb_svd {
    sb_context_t *ctx;
    size_t m, n, k, mn;
    sb_svd_opts_t opts;
    sb_method_t method;
    double *a, *s, *u, *vt, *work;
    lapack_int *iwork;
    lapack_int lwork;
};

sb_result_t sb_svd_create(sb_context_t *ctx, size_t m, size_t n, size_t k, const sb_svd_opts_t *opts,
                          sb_svd_t **out) {
    if (!out) return sb_error(ctx, SB_ERR_ARG, "svd: no output pointer");
    *out = NULL;
    if (m == 0 || n == 0) return sb_error(ctx, SB_ERR_ARG, "svd: empty matrix %zu x %zu", m, n);
    size_t mn = m < n ? m : n;
    if (k == 0 || k > mn) return sb_error(ctx, SB_ERR_RANGE, "svd: %zu terms asked, need 1..%zu", k, mn);
    if (m > (size_t)INT32_MAX || n > (size_t)INT32_MAX)
        return sb_error(ctx, SB_ERR_OVERFLOW, "svd: dimension too large for LAPACK");
    sb_svd_t *s = calloc(1, sizeof *s);
    if (!s) return sb_error(ctx, SB_ERR_NOMEM, "svd: out of memory");
    s->ctx = ctx;
    s->m = m;
    s->n = n;
    s->k = k;
    s->mn = mn;
    if (opts) s->opts = *opts;
    s->method = SB_METHOD_FULL;

    s->a = sb_alloc(ctx, m * n, sizeof(double), "svd workspace");
    s->s = sb_alloc(ctx, mn, sizeof(double), "svd workspace");
    s->u = sb_alloc(ctx, m * mn, sizeof(double), "svd workspace");
    s->vt = sb_alloc(ctx, mn * n, sizeof(double), "svd workspace");
    s->iwork = sb_alloc(ctx, 8 * mn, sizeof(lapack_int), "svd workspace");
    if (!s->a || !s->s || !s->u || !s->vt || !s->iwork) {
        sb_svd_destroy(s);
        return SB_ERR_NOMEM;
    }
    double q;
    lapack_int info = LAPACKE_dgesdd_work(LAPACK_COL_MAJOR, 'S', (lapack_int)m, (lapack_int)n, s->a,
                                          (lapack_int)m, s->s, s->u, (lapack_int)m, s->vt, (lapack_int)mn,
                                          &q, -1, s->iwork);
    if (info != 0) {
        sb_svd_destroy(s);
        return sb_error(ctx, SB_ERR_NUMERIC, "svd: dgesdd workspace query failed (info %d)", (int)info);
    }
    s->lwork = (lapack_int)q + 1;
    s->work = sb_alloc(ctx, (size_t)s->lwork, sizeof(double), "svd workspace");
    if (!s->work) {
        sb_svd_destroy(s);
        return SB_ERR_NOMEM;
    }
    *out = s;
    return SB_OK;
}

void sb_svd_destroy(sb_svd_t *s) {
    if (!s) return;
    free(s->a);
    free(s->s);
    free(s->u);
    free(s->vt);
    free(s->work);
    free(s->iwork);
    free(s);
}

sb_method_t sb_svd_method(const sb_svd_t *s) { return s->method; }

sb_result_t sb_svd_execute(sb_svd_t *s, const double *A, size_t lda, double *sv, double *U, double *V,
                           double *all_s, int *have_all) {
    size_t m = s->m, n = s->n, k = s->k, mn = s->mn;
    for (size_t j = 0; j < n; j++) memcpy(s->a + j * m, A + j * lda, m * sizeof(double));
    lapack_int info = LAPACKE_dgesdd_work(LAPACK_COL_MAJOR, 'S', (lapack_int)m, (lapack_int)n, s->a,
                                          (lapack_int)m, s->s, s->u, (lapack_int)m, s->vt, (lapack_int)mn,
                                          s->work, s->lwork, s->iwork);
    if (info != 0) return sb_error(s->ctx, SB_ERR_NUMERIC, "svd: dgesdd failed (info %d)", (int)info);
    memcpy(sv, s->s, k * sizeof(double));
    if (U) memcpy(U, s->u, m * k * sizeof(double));
    if (V)
        for (size_t j = 0; j < k; j++)
            for (size_t i = 0; i < n; i++) V[i + j * n] = s->vt[j + i * mn];
    if (all_s) memcpy(all_s, s->s, mn * sizeof(double));
    if (have_all) *have_all = all_s != NULL;
    return SB_OK;
}
