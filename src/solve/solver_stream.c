/* The streamed solver: the leading terms of matrices that are never held,
 * read in blocks of columns (sb_matrix_cols: evaluated from the source for
 * a streamed matrix, copied from a stored one), one pass over the matrix
 * for every channel at once.
 *
 * Block Krylov on X X^T, X = W_r A W_c (rows x cols), l = J + p vectors
 * a block: with Q_0 = qr(Omega) (Gaussian, rows x l, seeded), pass k reads
 * every block X_b of columns and forms
 *     Z_b = X_b^T Q_{k-1}   (block b of C_{k-1}^T = X^T Q_{k-1}),
 *     Y_k += X_b Z_b        (Y_k = X X^T Q_{k-1}),
 * so one pass is a full power step; Q_k = qr(Y_k).  After P passes
 * (P = q + 1, q power iterations, default 4; the last skips Y) the basis
 * K = [Q_0 .. Q_{P-1}] and C^T = X^T K are known exactly.  Rayleigh-Ritz
 * on span(K): G = K^T K = E D E^T, W = E D^(-1/2) (eigenvalues below
 * 1e-12 of the largest dropped: their columns of W are 0), Q~ = K W is
 * orthonormal and X^T Q~ = C^T W; its SVD V S U~^T gives v_j, s_j and
 * u_j = K W U~ e_j: the rank-J truncation of Q~ Q~^T X (HMT 2011 with
 * every iterate kept, Musco & Musco 2015).  Keeping them matters on io
 * matrices, whose spectra are flat: the last block alone (subspace
 * iteration) was 1.2 % above the optimum at J = 8, R = 32.  Measured
 * excess of rel_rms over the dense SVD's (anisotropic GGX, io, J = 8,
 * p = 10): R = 32: 2.2e-3, 1.2e-6, 1.5e-10 for q = 2, 3, 4; R = 64:
 * 4.0e-3, 8.7e-4, 2.0e-5.  Memory:
 * P l (rows + cols) + l rows doubles a channel plus one block of columns
 * (sb_solve_stream_cols), never rows x cols.  The plan (plan.c) measures the errors of the
 * stored textures in one more streamed pass (SB_CAP_STREAMED).  A grey
 * streamed matrix (every channel the same cells) is factored on its first
 * channel, whose results every channel takes.
 * Over a group of processes (common.h, sb_context_set_group: MPI ranks)
 * each reads every size-th block; Y is summed after every pass and C^T
 * (cols x L a channel) once before Rayleigh-Ritz, which every process
 * then runs on the same bits. */
#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <cblas.h>

#include "sample/stream.h"
#include "sepbrdf/matrix.h"
#include "solve/solver.h"
#include "util/internal.h"
#include "util/parallel.h"
#include "util/rng.h"

/* Power iterations by default: each one more pass over the source. */
#define SB_STREAM_POWER_ITERS 4

typedef struct stream_state {
    sb_context_t *ctx;
    size_t rows, cols, J, l, b;
    int passes, nt; /* passes over the matrix; threads of a pass */
    int same;       /* channel whose results every channel takes (grey), or -1 */
    uint64_t seed;
    size_t L;                      /* P l: columns of the Krylov basis */
    sb_svd_t *small;               /* FULL SVD of C^T W (cols x L) */
    double *k[3], *y[3], *ct[3];   /* K (rows x L), Y (rows x l), C^T (cols x L) a channel */
    double *blk[3];                /* a block of columns: rows x b a channel */
    double *s[3], *u[3], *v[3];    /* results: J, rows x J, cols x J a channel */
    double *g, *w, *ev, *ut, *cw;  /* L x L: G, W; L; L x J: U~; cols x L: C^T W */
    double *wu, *tau, *work, *mem; /* L x J: W U~; l; LAPACK workspace; one allocation */
    double *yt;                    /* the parts of Y of threads 1 .. nt-1: rows x l a channel */
    lapack_int lwork;
} stream_state_t;

static int takes(const sb_solve_problem_t *pb) {
    return !pb->masked && (pb->streamed || pb->svd.method == SB_METHOD_STREAM);
}

static void destroy(void *state) {
    stream_state_t *s = state;
    if (!s) return;
    sb_svd_destroy(s->small);
    free(s->mem);
    free(s);
}

/* The QR workspace: the larger of dgeqrf's and dorgqr's queries. */
static sb_result_t query_qr(stream_state_t *s) {
    double w1 = 0, w2 = 0, dummy = 0;
    lapack_int m = (lapack_int)s->rows, n = (lapack_int)s->l;
    if (LAPACKE_dgeqrf_work(LAPACK_COL_MAJOR, m, n, NULL, m, NULL, &w1, -1) != 0 ||
        LAPACKE_dorgqr_work(LAPACK_COL_MAJOR, m, n, n, NULL, m, &dummy, &w2, -1) != 0)
        return sb_error(s->ctx, SB_ERR_NUMERIC, "stream: QR workspace query failed");
    s->lwork = (lapack_int)fmax(fmax(fmax(w1, w2), 1), (double)(3 * s->L));
    return SB_OK;
}

/* One allocation for every buffer (sizes checked against the limit). */
static sb_result_t alloc_all(stream_state_t *s) {
    size_t rows = s->rows, cols = s->cols, l = s->l, J = s->J, L = s->L, per, total;
    if (sb_size_mul(rows + cols, L + l + J, &per) || sb_size_add(per, J + rows * s->b, &per) ||
        sb_size_mul(per, 3, &total) || sb_size_add(total, cols * L + 2 * L * L + 2 * L * J + L + l, &total) ||
        sb_size_add(total, (size_t)s->lwork, &total) || sb_size_mul(rows * l, 3 * (size_t)(s->nt - 1), &per) ||
        sb_size_add(total, per, &total))
        return sb_error(s->ctx, SB_ERR_OVERFLOW, "stream: workspace overflows");
    double *p = s->mem = sb_alloc(s->ctx, total, sizeof(double), "stream plan");
    if (!p) return SB_ERR_NOMEM;
    for (int c = 0; c < 3; c++) {
        s->k[c] = p, p += rows * L;
        s->y[c] = p, p += rows * l;
        s->ct[c] = p, p += cols * L;
        s->blk[c] = p, p += rows * s->b;
        s->s[c] = p, p += J;
        s->u[c] = p, p += rows * J;
        s->v[c] = p, p += cols * J;
    }
    s->cw = p, p += cols * L;
    s->g = p, p += L * L;
    s->w = p, p += L * L;
    s->ev = p, p += L;
    s->ut = p, p += L * J;
    s->wu = p, p += L * J;
    s->tau = p, p += l;
    s->yt = p, p += rows * l * 3 * (size_t)(s->nt - 1);
    s->work = p;
    return SB_OK;
}

static sb_result_t plan(sb_context_t *ctx, const sb_solve_problem_t *pb, void **state) {
    if (pb->rows > INT32_MAX || pb->cols > INT32_MAX)
        return sb_error(ctx, SB_ERR_OVERFLOW, "stream: %zu x %zu exceeds BLAS's sizes", pb->rows, pb->cols);
    stream_state_t *s = sb_calloc(ctx, 1, sizeof *s, "stream plan");
    if (!s) return SB_ERR_NOMEM;
    size_t d = pb->rows < pb->cols ? pb->rows : pb->cols;
    int p = pb->svd.oversample == 0 ? 10 : (pb->svd.oversample < 0 ? 0 : pb->svd.oversample);
    int q = pb->svd.power_iters == 0 ? SB_STREAM_POWER_ITERS : (pb->svd.power_iters < 0 ? 0 : pb->svd.power_iters);
    *s = (stream_state_t){.ctx = ctx, .rows = pb->rows, .cols = pb->cols, .J = pb->terms};
    s->l = pb->terms + (size_t)p < d ? pb->terms + (size_t)p : d;
    s->passes = q + 1;
    s->L = s->l * (size_t)s->passes;
    s->seed = pb->svd.seed ? pb->svd.seed : 1;
    s->b = sb_solve_stream_cols(pb->rows, pb->cols);
    s->nt = sb_thread_count(0);
    sb_svd_opts_t so = {0};
    so.method = SB_METHOD_FULL;
    sb_result_t r = query_qr(s);
    if (r == SB_OK) r = sb_svd_create(ctx, s->cols, s->L, s->J, &so, &s->small);
    if (r == SB_OK) r = alloc_all(s);
    if (r != SB_OK) {
        destroy(s);
        return r;
    }
    *state = s;
    return SB_OK;
}

static sb_result_t orthonormalise(stream_state_t *s, int c, int k);

/* Step: Q_0 = qr(Omega), Omega Gaussian, the same for every channel. */
static sb_result_t draw_omega(stream_state_t *s, const int *present) {
    sb_rng_t rng;
    sb_rng_seed(&rng, s->seed);
    size_t n = s->rows * s->l;
    for (size_t i = 0; i < n; i += 2) {
        double g[2];
        sb_rng_gauss2(&rng, g);
        s->y[0][i] = g[0];
        if (i + 1 < n) s->y[0][i + 1] = g[1];
    }
    sb_result_t r = orthonormalise(s, 0, 0);
    for (int c = 1; c < 3; c++)
        if (present[c]) memcpy(s->k[c], s->k[0], n * sizeof(double));
    return r;
}

/* Step: X_b = W_r A_b W_c in place on the block of columns c0 .. c0+n-1. */
static void weigh_block(const stream_state_t *s, const sb_solve_in_t *in, double *x, size_t c0, size_t n) {
    if (!in->wr) return;
    for (size_t k = 0; k < n; k++)
        for (size_t i = 0; i < s->rows; i++)
            x[i + k * s->rows] *= in->wr[i] * in->wc[c0 + k];
}

/* One thread's columns [a, b) of the block at c0 in pass k: evaluated
 * and weighed, their rows of C_k^T = X^T Q_k and, unless last, their part
 * of X C_k^T added to y (this thread's sum; first: nothing added yet). */
typedef struct slice {
    stream_state_t *s;
    const sb_solve_in_t *in;
    const int *present;
    size_t c0, a, b;
    int k, last, first;
    double *y[3];
    sb_result_t r;
} slice_t;

static void *pass_slice(void *arg) {
    slice_t *j = arg;
    stream_state_t *s = j->s;
    int rows = (int)s->rows, cols = (int)s->cols, l = (int)s->l, n = (int)(j->b - j->a);
    double *x[3];
    for (int c = 0; c < 3; c++)
        x[c] = j->present[c] ? s->blk[c] + (j->a - j->c0) * s->rows : NULL;
    if (n == 0 || j->r != SB_OK) return NULL;
    j->r = sb_matrix_cols(s->ctx, j->in->m, j->a, j->b, x, s->rows, 1);
    for (int c = 0; c < 3 && j->r == SB_OK; c++) {
        if (!j->present[c]) continue;
        double *q = s->k[c] + (size_t)j->k * s->l * s->rows, *ct = s->ct[c] + (size_t)j->k * s->l * s->cols + j->a;
        weigh_block(s, j->in, x[c], j->a, (size_t)n);
        cblas_dgemm(CblasColMajor, CblasTrans, CblasNoTrans, n, l, rows, 1.0, x[c], rows, q, rows, 0.0, ct, cols);
        if (!j->last)
            cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, rows, l, n, 1.0, x[c], rows, ct, cols,
                        j->first ? 0.0 : 1.0, j->y[c], rows);
    }
    j->first = 0;
    return NULL;
}

/* Step: Y = the threads' parts added in thread order (0 where none). */
static void sum_parts(stream_state_t *s, const slice_t *sl, int c) {
    size_t n = s->rows * s->l;
    if (sl[0].first) memset(s->y[c], 0, n * sizeof(double));
    for (int t = 1; t < s->nt; t++)
        for (size_t i = 0; !sl[t].first && i < n; i++)
            s->y[c][i] += sl[t].y[c][i];
}

/* Step: pass k over the blocks: C_k^T = X^T Q_k and, unless last, Y = X C_k^T.
 * Every block is cut among the threads, each evaluating its columns and
 * multiplying them itself with BLAS on one thread (sb_blas_threads_begin).
 * In a group (sb_context_set_group) this process reads its own blocks:
 * its rows of C_k^T (the others stay 0) and its part of Y, summed over
 * the group at the end of the pass. */
static sb_result_t one_pass(stream_state_t *s, const sb_solve_in_t *in, const int *present, int k, int last) {
    slice_t sl[SB_THREADS_MAX];
    for (int t = 0; t < s->nt; t++) {
        sl[t] = (slice_t){.s = s, .in = in, .present = present, .k = k, .last = last, .first = 1, .r = SB_OK};
        for (int c = 0; c < 3; c++)
            sl[t].y[c] = t == 0 ? s->y[c] : s->yt + ((size_t)(t - 1) * 3 + (size_t)c) * s->rows * s->l;
    }
    int blas = sb_blas_threads_begin();
    for (size_t c0 = 0; c0 < s->cols; c0 += s->b) {
        size_t n = c0 + s->b < s->cols ? s->b : s->cols - c0;
        if (!sb_group_owns(s->ctx, c0 / s->b)) continue;
        for (int t = 0; t < s->nt; t++) {
            sb_part(n, t, s->nt, &sl[t].a, &sl[t].b);
            sl[t].c0 = c0, sl[t].a += c0, sl[t].b += c0;
        }
        sb_parallel_run(pass_slice, sl, sizeof *sl, s->nt, NULL, NULL);
    }
    sb_blas_threads_end(blas);
    for (int t = 0; t < s->nt; t++)
        if (sl[t].r != SB_OK) return sl[t].r;
    for (int c = 0; c < 3 && !last; c++) {
        if (!present[c]) continue;
        sum_parts(s, sl, c);
        sb_result_t r = sb_group_reduce(s->ctx, s->y[c], s->rows * s->l, SB_REDUCE_SUM);
        if (r != SB_OK) return r;
    }
    return SB_OK;
}

/* Step: Q_k = qr(Y) (Householder: orthonormal even when Y is rank deficient). */
static sb_result_t orthonormalise(stream_state_t *s, int c, int k) {
    lapack_int m = (lapack_int)s->rows, n = (lapack_int)s->l;
    if (LAPACKE_dgeqrf_work(LAPACK_COL_MAJOR, m, n, s->y[c], m, s->tau, s->work, s->lwork) != 0 ||
        LAPACKE_dorgqr_work(LAPACK_COL_MAJOR, m, n, n, s->y[c], m, s->tau, s->work, s->lwork) != 0)
        return sb_error(s->ctx, SB_ERR_NUMERIC, "stream: QR failed");
    memcpy(s->k[c] + (size_t)k * s->l * s->rows, s->y[c], s->rows * s->l * sizeof(double));
    return SB_OK;
}

/* Step: W = E D^(-1/2) from G = K^T K = E D E^T (small eigenvalues: 0). */
static sb_result_t ritz_basis(stream_state_t *s, int c) {
    int rows = (int)s->rows, L = (int)s->L;
    cblas_dsyrk(CblasColMajor, CblasUpper, CblasTrans, L, rows, 1.0, s->k[c], rows, 0.0, s->g, L);
    if (LAPACKE_dsyev_work(LAPACK_COL_MAJOR, 'V', 'U', L, s->g, L, s->ev, s->work, s->lwork) != 0)
        return sb_error(s->ctx, SB_ERR_NUMERIC, "stream: eigenvalues of the Krylov basis failed");
    double top = s->ev[L - 1];
    for (int j = 0; j < L; j++) {
        double d = s->ev[j], f = d > 1e-12 * top && d > 0 ? 1 / sqrt(d) : 0;
        for (int i = 0; i < L; i++)
            s->w[i + j * L] = s->g[i + j * L] * f;
    }
    return SB_OK;
}

/* Step: C^T W = V S U~^T; u = K W U~, v = V. */
static sb_result_t small_svd(stream_state_t *s, int c) {
    int rows = (int)s->rows, cols = (int)s->cols, L = (int)s->L, J = (int)s->J;
    sb_result_t r = ritz_basis(s, c);
    if (r != SB_OK) return r;
    cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, cols, L, L, 1.0, s->ct[c], cols, s->w, L, 0.0, s->cw, cols);
    if ((r = sb_svd_execute(s->small, s->cw, s->cols, s->s[c], s->v[c], s->ut, NULL, NULL)) != SB_OK) return r;
    cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, L, J, L, 1.0, s->w, L, s->ut, L, 0.0, s->wu, L);
    cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, rows, J, L, 1.0, s->k[c], rows, s->wu, L, 0.0, s->u[c],
                rows);
    return SB_OK;
}

/* Every channel of the matrix, in P passes. */
static sb_result_t factor_all(stream_state_t *s, const sb_solve_in_t *in) {
    int present[3], first = 0;
    while (first < 2 && !sb_matrix_has(in->m, first))
        first++;
    s->same = sb_matrix_stream_grey(in->m) ? first : -1; /* one channel for all: a third of the products */
    for (int c = 0; c < 3; c++)
        present[c] = sb_matrix_has(in->m, c) && (s->same < 0 || c == first);
    sb_result_t r = draw_omega(s, present);
    for (int c = 0; c < 3 && sb_group_active(s->ctx); c++) /* the rows of C^T of others' blocks */
        if (present[c]) memset(s->ct[c], 0, s->cols * s->L * sizeof(double));
    for (int k = 0; k < s->passes && r == SB_OK; k++) {
        int last = k == s->passes - 1;
        r = one_pass(s, in, present, k, last);
        for (int c = 0; c < 3 && r == SB_OK && last; c++)
            if (present[c]) r = sb_group_reduce(s->ctx, s->ct[c], s->cols * s->L, SB_REDUCE_SUM);
        for (int c = 0; c < 3 && r == SB_OK; c++)
            if (present[c]) r = last ? small_svd(s, c) : orthonormalise(s, c, k + 1);
    }
    return r;
}

/* The first channel of the matrix factors all of them; the others read
 * the results (the plan asks for the channels in order). */
static sb_result_t execute(void *state, const sb_solve_in_t *in, sb_solve_out_t *out) {
    stream_state_t *s = state;
    int c = in->channel, first = 0;
    if (!in->m || c < 0 || c > 2) return sb_error(s->ctx, SB_ERR_ARG, "stream: no matrix or channel");
    while (first < c && !sb_matrix_has(in->m, first))
        first++;
    if (c == first) {
        sb_result_t r = factor_all(s, in);
        if (r != SB_OK) return r;
    }
    int from = s->same >= 0 ? s->same : c;
    memcpy(out->s, s->s[from], s->J * sizeof(double));
    memcpy(out->u, s->u[from], s->rows * s->J * sizeof(double));
    memcpy(out->v, s->v[from], s->cols * s->J * sizeof(double));
    return SB_OK;
}

const sb_solver_t sb_solver_stream = {
    .name = "stream",
    .description = "matrix-free subspace iteration: the matrix evaluated from the source in blocks of columns, one "
                   "pass per power step, all channels at once; for matrices beyond the memory limit",
    .caps = SB_CAP_ORTHONORMAL | SB_CAP_STRUCTURED | SB_CAP_STREAMED | SB_CAP_METHOD,
    .takes = takes,
    .plan = plan,
    .destroy = destroy,
    .execute = execute};
