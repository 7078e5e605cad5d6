/* The streamed solver: the leading terms of matrices that are never held,
 * read in blocks of columns (sb_matrix_cols: evaluated from the source for
 * a streamed matrix, copied from a stored one), one pass over the matrix
 * for every channel at once.
 *
 * Subspace iteration on X X^T, X = W_r A W_c (rows x cols), l = J + p
 * vectors: with Q_0 = Omega (Gaussian, rows x l, seeded), pass k reads
 * every block X_b of columns and forms
 *     Z_b = X_b^T Q_{k-1}   (block b of B_k^T = X^T Q_{k-1}),
 *     Y_k += X_b Z_b        (Y_k = X X^T Q_{k-1}),
 * so one pass is a full power step; Q_k = qr(Y_k).  After P passes
 * (P = q + 1, q power iterations, default 2) B = Q_{P-1}^T X is known
 * exactly (the last pass skips Y), and the SVD of the small B^T = W S V~^T
 * gives u_j = Q V~ e_j, v_j = W e_j, s_j.  The terms are the rank-J
 * truncation of Q Q^T X: HMT 2011 (Alg. 4.4 with a one-pass power step),
 * so the error is within (1 + J/(p - 1))^(1/2) of the optimum in
 * expectation for q = 0, closer with every pass.  Memory: 3 l (rows +
 * cols) doubles a channel plus one block of SB_SOLVE_STREAM_BLOCK bytes,
 * never rows x cols.  The plan (plan.c) measures the errors of the
 * stored textures in one more streamed pass (SB_CAP_STREAMED). */
#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <cblas.h>

#include "sepbrdf/matrix.h"
#include "solve/solver.h"
#include "util/internal.h"
#include "util/rng.h"

typedef struct stream_state {
    sb_context_t *ctx;
    size_t rows, cols, J, l, b;
    int passes;
    uint64_t seed;
    sb_svd_t *small;               /* FULL SVD of B^T (cols x l) */
    double *q[3], *y[3], *bt[3];   /* rows x l, rows x l, cols x l a channel */
    double *blk[3];                /* a block of columns: rows x b a channel */
    double *s[3], *u[3], *v[3];    /* results: J, rows x J, cols x J a channel */
    double *ut, *tau, *work, *mem; /* l x J, l, QR workspace; one allocation */
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
    s->lwork = (lapack_int)fmax(fmax(w1, w2), 1);
    return SB_OK;
}

/* One allocation for every buffer (sizes checked against the limit). */
static sb_result_t alloc_all(stream_state_t *s) {
    size_t rows = s->rows, cols = s->cols, l = s->l, J = s->J, per, total;
    if (sb_size_mul(rows + cols, 3 * l + J, &per) || sb_size_add(per, J, &per) || sb_size_mul(per, 3, &total) ||
        sb_size_add(total, 3 * rows * s->b + l * J + l + (size_t)s->lwork, &total))
        return sb_error(s->ctx, SB_ERR_OVERFLOW, "stream: workspace overflows");
    double *p = s->mem = sb_alloc(s->ctx, total, sizeof(double), "stream plan");
    if (!p) return SB_ERR_NOMEM;
    for (int c = 0; c < 3; c++) {
        s->q[c] = p, p += rows * l;
        s->y[c] = p, p += rows * l;
        s->bt[c] = p, p += cols * l;
        s->blk[c] = p, p += rows * s->b;
        s->s[c] = p, p += J;
        s->u[c] = p, p += rows * J;
        s->v[c] = p, p += cols * J;
    }
    s->ut = p, p += l * J;
    s->tau = p, p += l;
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
    int q = pb->svd.power_iters == 0 ? 2 : (pb->svd.power_iters < 0 ? 0 : pb->svd.power_iters);
    *s = (stream_state_t){.ctx = ctx, .rows = pb->rows, .cols = pb->cols, .J = pb->terms};
    s->l = pb->terms + (size_t)p < d ? pb->terms + (size_t)p : d;
    s->passes = q + 1;
    s->seed = pb->svd.seed ? pb->svd.seed : 1;
    s->b = sb_solve_stream_cols(pb->rows, pb->cols);
    sb_svd_opts_t so = {0};
    so.method = SB_METHOD_FULL;
    sb_result_t r = query_qr(s);
    if (r == SB_OK) r = sb_svd_create(ctx, s->cols, s->l, s->J, &so, &s->small);
    if (r == SB_OK) r = alloc_all(s);
    if (r != SB_OK) {
        destroy(s);
        return r;
    }
    *state = s;
    return SB_OK;
}

/* Step: Q_0 = Omega, Gaussian, the same for every channel. */
static void draw_omega(stream_state_t *s, const int *present) {
    sb_rng_t rng;
    sb_rng_seed(&rng, s->seed);
    size_t n = s->rows * s->l;
    for (size_t i = 0; i < n; i += 2) {
        double g[2];
        sb_rng_gauss2(&rng, g);
        s->q[0][i] = g[0];
        if (i + 1 < n) s->q[0][i + 1] = g[1];
    }
    for (int c = 1; c < 3; c++)
        if (present[c]) memcpy(s->q[c], s->q[0], n * sizeof(double));
}

/* Step: X_b = W_r A_b W_c in place on the block of columns c0 .. c0+n-1. */
static void weigh_block(const stream_state_t *s, const sb_solve_in_t *in, double *x, size_t c0, size_t n) {
    if (!in->wr) return;
    for (size_t k = 0; k < n; k++)
        for (size_t i = 0; i < s->rows; i++)
            x[i + k * s->rows] *= in->wr[i] * in->wc[c0 + k];
}

/* Step: one pass over the blocks: B^T = X^T Q and, unless last, Y = X B^T. */
static sb_result_t one_pass(stream_state_t *s, const sb_solve_in_t *in, const int *present, int last) {
    int rows = (int)s->rows, cols = (int)s->cols, l = (int)s->l;
    for (size_t c0 = 0; c0 < s->cols; c0 += s->b) {
        size_t n = c0 + s->b < s->cols ? s->b : s->cols - c0;
        sb_result_t r = sb_matrix_cols(s->ctx, in->m, c0, c0 + n, s->blk, s->rows, 0);
        if (r != SB_OK) return r;
        for (int c = 0; c < 3; c++) {
            if (!present[c]) continue;
            weigh_block(s, in, s->blk[c], c0, n);
            cblas_dgemm(CblasColMajor, CblasTrans, CblasNoTrans, (int)n, l, rows, 1.0, s->blk[c], rows, s->q[c], rows,
                        0.0, s->bt[c] + c0, cols);
            if (!last)
                cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, rows, l, (int)n, 1.0, s->blk[c], rows,
                            s->bt[c] + c0, cols, c0 ? 1.0 : 0.0, s->y[c], rows);
        }
    }
    return SB_OK;
}

/* Step: Q = qr(Y) (Householder: orthonormal even when Y is rank deficient). */
static sb_result_t orthonormalise(stream_state_t *s, int c) {
    lapack_int m = (lapack_int)s->rows, n = (lapack_int)s->l;
    if (LAPACKE_dgeqrf_work(LAPACK_COL_MAJOR, m, n, s->y[c], m, s->tau, s->work, s->lwork) != 0 ||
        LAPACKE_dorgqr_work(LAPACK_COL_MAJOR, m, n, n, s->y[c], m, s->tau, s->work, s->lwork) != 0)
        return sb_error(s->ctx, SB_ERR_NUMERIC, "stream: QR failed");
    double *t = s->q[c];
    s->q[c] = s->y[c];
    s->y[c] = t;
    return SB_OK;
}

/* Step: B^T = W S V~^T; u = Q V~, v = W. */
static sb_result_t small_svd(stream_state_t *s, int c) {
    sb_result_t r = sb_svd_execute(s->small, s->bt[c], s->cols, s->s[c], s->v[c], s->ut, NULL, NULL);
    if (r != SB_OK) return r;
    cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, (int)s->rows, (int)s->J, (int)s->l, 1.0, s->q[c],
                (int)s->rows, s->ut, (int)s->l, 0.0, s->u[c], (int)s->rows);
    return SB_OK;
}

/* Every channel of the matrix, in P passes. */
static sb_result_t factor_all(stream_state_t *s, const sb_solve_in_t *in) {
    int present[3];
    for (int c = 0; c < 3; c++)
        present[c] = sb_matrix_has(in->m, c);
    draw_omega(s, present);
    sb_result_t r = SB_OK;
    for (int k = 0; k < s->passes && r == SB_OK; k++) {
        int last = k == s->passes - 1;
        r = one_pass(s, in, present, last);
        for (int c = 0; c < 3 && r == SB_OK; c++)
            if (present[c]) r = last ? small_svd(s, c) : orthonormalise(s, c);
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
    memcpy(out->s, s->s[c], s->J * sizeof(double));
    memcpy(out->u, s->u[c], s->rows * s->J * sizeof(double));
    memcpy(out->v, s->v[c], s->cols * s->J * sizeof(double));
    return SB_OK;
}

const sb_solver_t sb_solver_stream = {
    "stream",
    "matrix-free subspace iteration: the matrix evaluated from the source in blocks of columns, one pass per "
    "power step, all channels at once; for matrices beyond the memory limit",
    SB_CAP_ORTHONORMAL | SB_CAP_STRUCTURED | SB_CAP_STREAMED,
    takes,
    plan,
    destroy,
    NULL,
    execute,
    NULL,
    NULL,
};
