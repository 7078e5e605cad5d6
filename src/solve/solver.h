/* Private: the solver descriptor and the registry (solvers.c).
 *
 * A solver factors one channel: the J leading terms s_j, u_j, v_j of the
 * (weighted) matrix X = W_r A W_c.  Adding one is one file holding one
 * sb_solver_t plus one row in the registry table of solvers.c. */
#ifndef SEPBRDF_SOLVER_INTERNAL_H
#define SEPBRDF_SOLVER_INTERNAL_H

#include "sepbrdf/matrix.h"
#include "sepbrdf/param.h"
#include "sepbrdf/solver.h"
#include "sepbrdf/svd.h"

/* What the plan knows before the data: shape, terms, options. */
typedef struct sb_solve_problem {
    size_t rows, cols, terms;
    sb_svd_opts_t svd; /* dense methods */
    int fit_max_iters; /* masked fit */
    double fit_tol;    /* masked fit */
    double max_error;  /* stop target (0 = all terms) */
    size_t period;     /* block-circulant period R (rows == cols == R^2), 0 = none */
    int masked;        /* cells to exclude */
    int zero_fill;     /* excluded cells count as zeros (the plan's zero_fill) */
    int streamed;      /* the matrix is streamed (matrix.h): never held, read in blocks of columns */
} sb_solve_problem_t;

/* One channel. */
typedef struct sb_solve_in {
    const double *x; /* W_r A W_c (A itself when unweighted), leading dimension ldx */
    size_t ldx;
    const double *a; /* A as sampled, leading dimension lda (SB_CAP_STRUCTURED solvers read it) */
    size_t lda;
    const unsigned char *mask; /* leading dimension lda; NULL = every cell valid */
    const double *wr, *wc;     /* weights, NULL = unweighted */
    double pw;                 /* power-of-two scale of sums of squares (sb_pow2_scale) */
    const sb_param_t *param;   /* texture layout and wrap of rows and columns (masked: taps), NULL = unknown */
    const sb_matrix_t *m;      /* the matrix (SB_CAP_STREAMED solvers read it in blocks of columns) */
    int channel;               /* which channel of m this is */
} sb_solve_in_t;

typedef struct sb_solve_out {
    double *s, *u, *v; /* J, rows x J, cols x J (column-major) */
    int iterations;    /* iterative solvers; 0 otherwise */
    int converged;     /* 1 unless an iterative solver stopped early */
} sb_solve_out_t;

typedef struct sb_solver {
    const char *name, *description;
    unsigned caps;
    /* whether the solver takes the problem (method asked, shape, mask) */
    int (*takes)(const sb_solve_problem_t *pb);
    sb_result_t (*plan)(sb_context_t *ctx, const sb_solve_problem_t *pb, void **state);
    void (*destroy)(void *state);
    /* whether a channel's data have the structure the solver needs; NULL:
     * any data.  Reads only; the plan falls back to a dense solver. */
    int (*suits)(const void *state, const sb_solve_in_t *in);
    sb_result_t (*execute)(void *state, const sb_solve_in_t *in, sb_solve_out_t *out);
    /* SB_CAP_EXACT_TAILS: for J' = 1..J, ssq[J'-1] the squared error (times
     * pw^2) and mx[J'-1] the max |error| in native units of the last
     * execute's terms scaled by t (a proportional channel: t A), and *n2 =
     * ||W_r A W_c||^2 pw^2 of this channel's data. */
    sb_result_t (*exact)(void *state, const sb_solve_in_t *in, double t, size_t J, double *ssq, double *mx, double *n2);
    /* SB_CAP_STRUCTURED: rows of A that hold every distinct value (the
     * rest repeat them), so scans of A can stop there. */
    size_t (*distinct_rows)(const void *state);
} sb_solver_t;

/* Bytes of the block of columns (all channels) a SB_CAP_STREAMED solver
 * and the plan's streamed residual pass hold at a time: at most this, and
 * at most an eighth of the memory limit. */
#define SB_SOLVE_STREAM_BLOCK ((size_t)96 << 20)

/* Columns of such a block for rows x cols matrices: 1 .. cols. */
static inline size_t sb_solve_stream_cols(size_t rows, size_t cols) {
    size_t bytes = sb_memory_limit() / 8 < SB_SOLVE_STREAM_BLOCK ? sb_memory_limit() / 8 : SB_SOLVE_STREAM_BLOCK;
    size_t b = bytes / (3 * rows * sizeof(double));
    return b < 1 ? 1 : (b > cols ? cols : b);
}

/* At most this many solvers in the registry (plans keep one slot each). */
#define SB_SOLVERS_MAX 8

/* Registry index of the first solver that takes pb (sb_solver_count() if
 * none), and the solver at an index (NULL beyond the registry). */
size_t sb_solver_index(const sb_solve_problem_t *pb);
const sb_solver_t *sb_solver_at(size_t i);

extern const sb_solver_t sb_solver_full, sb_solver_topk, sb_solver_randomized, sb_solver_circulant, sb_solver_masked,
    sb_solver_nmf, sb_solver_stream;

#endif
