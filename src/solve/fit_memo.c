/* Masked fit, memoised (fit_impl.h fit_memo_execute): a fit is a
 * deterministic function of its shape, options, mask and the values on
 * the valid cells (fill_x reads no other; the ALS reads f->x or A by
 * lda == m, so that is part of the key), so while a job runs
 * (util/ctx_memo.h) a second fit of the same bytes takes the first's
 * terms.  The non-negative solver's masked fit beside each channel
 * (solver_nmf.c fill_holes) is the fit the SVD beside makes of that very
 * matrix (job.c job_svd_beside: the masked solver at J <= SB_CHAIN_JOINT,
 * fit_chain), the same to the bit: the default gold's nmf run fitted
 * each 64 x 992 channel twice. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "solve/fit_impl.h"
#include "util/ctx_memo.h"

/* The key's head: shape, layout of A and every option, as numbers. */
#define KEY_HEAD 16

/* The key, into a new buffer of *len bytes: the head, then a byte per
 * cell (valid or not), then the values of the valid cells (0 elsewhere). */
static unsigned char *make_key(const sb_fit_t *f, const double *A, size_t lda, const unsigned char *mask,
                               const sb_fit_opts_t *o, size_t *len) {
    size_t m = f->m, n = f->n, cells = m * n;
    double head[KEY_HEAD] = {(double)m,    (double)n, (double)f->k,    lda == m,
                             o->max_iters, o->tol,    (double)o->seed, o->target};
    memcpy(&head[6], &o->seed, sizeof o->seed); /* every bit of it */
    for (int i = 0; i < 4; i++) {
        head[8 + i] = (double)o->tex[i / 2][i % 2];
        head[12 + i] = o->wrap[i / 2][i % 2];
    }
    *len = sizeof head + cells + cells * sizeof(double);
    unsigned char *key = malloc(*len);
    if (!key) return NULL;
    memcpy(key, head, sizeof head);
    unsigned char *mk = key + sizeof head;
    double *x = malloc(cells * sizeof *x);
    if (!x) {
        free(key);
        return NULL;
    }
    for (size_t c = 0; c < n; c++)
        for (size_t r = 0; r < m; r++) {
            int ok = mask[r + c * lda] != 0;
            mk[r + c * m] = (unsigned char)ok;
            x[r + c * m] = ok ? A[r + c * lda] : 0;
        }
    memcpy(mk + cells, x, cells * sizeof *x);
    free(x);
    return key;
}

sb_result_t fit_memo_execute(sb_fit_t *f, const double *A, size_t lda, const unsigned char *mask,
                             const sb_fit_opts_t *opts, double *s, double *U, double *V, sb_fit_info_t *info) {
    size_t m = f->m, n = f->n, k = f->k, klen = 0;
    sb_fit_opts_t o = {0};
    if (opts) o = *opts;
    unsigned char *key = mask && U && V ? make_key(f, A, lda, mask, &o, &klen) : NULL;
    size_t nv = k + (m + n) * k, vlen = nv * sizeof(double) + sizeof(sb_fit_info_t);
    unsigned char *val = key ? malloc(vlen) : NULL;
    sb_result_t r = SB_OK;
    if (val && sb_ctx_memo_find(f->ctx, key, klen, val, vlen)) {
        /* the very terms stored */
        memcpy(s, val, k * sizeof *s);
        memcpy(U, val + k * sizeof(double), m * k * sizeof *U);
        memcpy(V, val + (k + m * k) * sizeof(double), n * k * sizeof *V);
        if (info) memcpy(info, val + nv * sizeof(double), sizeof *info);
    } else {
        sb_fit_info_t fi = {0};
        r = sb_fit_execute(f, A, lda, mask, opts, s, U, V, &fi);
        if (info) *info = fi;
        if (r == SB_OK && val) {
            memcpy(val, s, k * sizeof *s);
            memcpy(val + k * sizeof(double), U, m * k * sizeof *U);
            memcpy(val + (k + m * k) * sizeof(double), V, n * k * sizeof *V);
            memcpy(val + nv * sizeof(double), &fi, sizeof fi);
            sb_ctx_memo_store(f->ctx, key, klen, val, vlen);
        }
    }
    free(key);
    free(val);
    return r;
}
