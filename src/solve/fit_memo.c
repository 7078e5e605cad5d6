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

static void key_head(const sb_fit_t *f, size_t lda, const sb_fit_opts_t *o, double head[KEY_HEAD]) {
    double h[KEY_HEAD] = {(double)f->m, (double)f->n, (double)f->k,    lda == f->m,
                          o->max_iters, o->tol,       (double)o->seed, o->target};
    memcpy(head, h, sizeof h);
    memcpy(&head[6], &o->seed, sizeof o->seed); /* every bit of it */
    for (int i = 0; i < 4; i++) {
        head[8 + i] = (double)o->tex[i / 2][i % 2];
        head[12 + i] = o->wrap[i / 2][i % 2];
    }
}

static uint64_t mix(uint64_t h, uint64_t w) {
    h = (h ^ w) * 1099511628211ull;
    return h ^ (h >> 29);
}

/* The key's hash, from the head, mask and values without building the
 * key: a word per cell (its value's bits where valid, else 0, and the
 * mask's byte), where hashing the key's bytes one by one (twice: to find,
 * then to store) and copying it into the memo was 3 % of the Cornell
 * acrylic's default run, whose 60 masked fits repeat none (issue 32 item
 * 5).  Equal keys hash alike; the memo tells keys apart by their bytes. */
static uint64_t key_hash(const sb_fit_t *f, const double *A, size_t lda, const unsigned char *mask,
                         const double head[KEY_HEAD]) {
    uint64_t h = 1469598103934665603ull, w;
    for (int i = 0; i < KEY_HEAD; i++) {
        memcpy(&w, &head[i], sizeof w);
        h = mix(h, w);
    }
    for (size_t c = 0; c < f->n; c++)
        for (size_t r = 0; r < f->m; r++) {
            int ok = mask[r + c * lda] != 0;
            double x = ok ? A[r + c * lda] : 0;
            memcpy(&w, &x, sizeof w);
            h = mix(h, w ^ (uint64_t)ok);
        }
    return h;
}

/* The key (klen bytes, malloc'd; NULL on no memory): the head, then a
 * byte per cell (valid or not), then the values of the valid cells (0
 * elsewhere). */
static unsigned char *make_key(const sb_fit_t *f, const double *A, size_t lda, const unsigned char *mask,
                               const double head[KEY_HEAD], size_t klen) {
    size_t m = f->m, n = f->n, cells = m * n;
    unsigned char *key = malloc(klen);
    if (!key) return NULL;
    memcpy(key, head, KEY_HEAD * sizeof *head);
    unsigned char *mk = key + KEY_HEAD * sizeof *head, *xb = mk + cells;
    for (size_t c = 0; c < n; c++)
        for (size_t r = 0; r < m; r++) {
            int ok = mask[r + c * lda] != 0;
            double x = ok ? A[r + c * lda] : 0;
            mk[r + c * m] = (unsigned char)ok;
            memcpy(xb + (r + c * m) * sizeof x, &x, sizeof x);
        }
    return key;
}

sb_result_t fit_memo_execute(sb_fit_t *f, const double *A, size_t lda, const unsigned char *mask,
                             const sb_fit_opts_t *opts, double *s, double *U, double *V, sb_fit_info_t *info) {
    size_t m = f->m, n = f->n, k = f->k, cells = m * n;
    sb_fit_opts_t o = {0};
    if (opts) o = *opts;
    double head[KEY_HEAD];
    key_head(f, lda, &o, head);
    size_t klen = sizeof head + cells + cells * sizeof(double);
    size_t nv = k + (m + n) * k, vlen = nv * sizeof(double) + sizeof(sb_fit_info_t);
    int memo = mask && U && V && sb_ctx_memo_room(f->ctx, 0); /* open */
    uint64_t h = memo ? key_hash(f, A, lda, mask, head) : 0;
    unsigned char *key = memo && sb_ctx_memo_holds(f->ctx, h, klen) ? make_key(f, A, lda, mask, head, klen) : NULL;
    unsigned char *val = memo ? malloc(vlen) : NULL;
    sb_result_t r = SB_OK;
    if (key && val && sb_ctx_memo_find_hashed(f->ctx, h, key, klen, val, vlen)) {
        /* the very terms stored */
        memcpy(s, val, k * sizeof *s);
        memcpy(U, val + k * sizeof(double), m * k * sizeof *U);
        memcpy(V, val + (k + m * k) * sizeof(double), n * k * sizeof *V);
        if (info) memcpy(info, val + nv * sizeof(double), sizeof *info);
    } else {
        sb_fit_info_t fi = {0};
        r = sb_fit_execute(f, A, lda, mask, opts, s, U, V, &fi);
        if (info) *info = fi;
        if (r == SB_OK && val && sb_ctx_memo_room(f->ctx, klen + vlen) &&
            (key || (key = make_key(f, A, lda, mask, head, klen)))) {
            memcpy(val, s, k * sizeof *s);
            memcpy(val + k * sizeof(double), U, m * k * sizeof *U);
            memcpy(val + (k + m * k) * sizeof(double), V, n * k * sizeof *V);
            memcpy(val + nv * sizeof(double), &fi, sizeof fi);
            sb_ctx_memo_store_hashed(f->ctx, h, key, klen, val, vlen); /* takes the key */
            key = NULL;
        }
    }
    free(key);
    free(val);
    return r;
}
