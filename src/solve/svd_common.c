/* The truncated SVD's shared helpers (svd_internal.h), below svd.c (plan,
 * dispatch), svd_dense.c and svd_rand.c (the methods): workspaces, the
 * singular values of a plan, and the residual and rank they imply. */
#include <math.h>

#include "solve/svd_internal.h"
#include "util/internal.h"

void *sb_svd_ws_alloc(sb_svd_t *s, size_t count1, size_t count2, size_t size) {
    size_t count;
    if (sb_size_mul(count1, count2, &count)) {
        sb_error(s->ctx, SB_ERR_OVERFLOW, "svd: workspace size %zu x %zu overflows", count1, count2);
        s->failed = SB_ERR_OVERFLOW;
        return NULL;
    }
    void *p = sb_alloc_large(s->ctx, count, size, "svd workspace"); /* huge pages from 4 MiB on */
    if (!p) {
        s->failed = count > sb_memory_limit() / size ? SB_ERR_OVERFLOW : SB_ERR_NOMEM;
        return NULL;
    }
    s->bytes += count * size;
    return p;
}

double sb_svd_sv_at(const sb_svd_t *s, size_t j) {
    return s->single ? (double)((const float *)s->sv)[j] : ((const double *)s->sv)[j];
}

/* The errors below are kept relative to ||A|| (s_j / ||A|| squared) so that
 * neither a huge nor a tiny matrix overflows; nrm = 0 is the zero matrix,
 * whose every truncation is exact. */

double sb_svd_resid_from(double nrm, const double *sv, size_t r) {
    if (!(nrm > 0)) return 0;
    double c = 0, inv = 1 / nrm;
    for (size_t j = 0; j < r; j++)
        c += (sv[j] * inv) * (sv[j] * inv);
    return c < 1 ? nrm * sqrt(1 - c) : 0;
}

size_t sb_svd_rank_for(const double *sv, size_t k, double nrm, double tol2, size_t lo) {
    double c = 0, inv = nrm > 0 ? 1 / nrm : 0;
    if (lo < 1) lo = 1;
    for (size_t j = 0; j < k; j++) {
        c += (sv[j] * inv) * (sv[j] * inv);
        if (j + 1 >= lo && (!(nrm > 0) || 1 - c <= tol2)) return j + 1;
    }
    return k;
}

/* A == A^T, entry for entry (an io matrix of a reciprocal source is).
 * Blocks of SYM_B x SYM_B: the mirror block, read a column (SYM_B
 * contiguous values) at a time, is stored transposed in t, then compared
 * with the block, again a column at a time, so both sides stream.  The
 * first block pair that differs (or holds a NaN) ends it, so a matrix
 * that is not symmetric costs about one block. */
#define SYM_B 64
#define SYM_BODY(R)                                                                                                    \
    R t[SYM_B * SYM_B];                                                                                                \
    const R *a = A;                                                                                                    \
    for (size_t j0 = 0; j0 < n; j0 += SYM_B)                                                                           \
        for (size_t i0 = 0; i0 <= j0; i0 += SYM_B) {                                                                   \
            size_t nj = n - j0 < SYM_B ? n - j0 : SYM_B, ni = n - i0 < SYM_B ? n - i0 : SYM_B;                         \
            for (size_t i = 0; i < ni; i++) /* the mirror: rows j0.., columns i0.. */                                  \
                for (size_t j = 0; j < nj; j++)                                                                        \
                    t[i + j * SYM_B] = a[j0 + j + (i0 + i) * lda];                                                     \
            int differ = 0;                                                                                            \
            for (size_t j = 0; j < nj; j++)                                                                            \
                for (size_t i = 0; i < ni; i++)                                                                        \
                    differ |= !(a[i0 + i + (j0 + j) * lda] == t[i + j * SYM_B]);                                       \
            if (differ) return 0;                                                                                      \
        }                                                                                                              \
    return 1;

static int symmetric_d(const double *A, size_t n, size_t lda) { SYM_BODY(double) }
static int symmetric_f(const float *A, size_t n, size_t lda) { SYM_BODY(float) }

int sb_svd_symmetric(const void *A, size_t n, size_t lda, int single) {
    return single ? symmetric_f(A, n, lda) : symmetric_d(A, n, lda);
}
