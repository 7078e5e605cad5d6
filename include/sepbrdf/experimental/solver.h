/* sepbrdf (experimental): your own solver, registered by name.
 *
 * Experimental: these declarations may change between minor versions
 * (as zstd's ZSTD_STATIC_LINKING_ONLY part does); the stable API is
 * the headers directly in include/sepbrdf/.  A solver factors one channel: the J leading terms
 * s_j, u_j, v_j of the (weighted) matrix X = W_r A W_c.  Every built-in
 * solver (full, topk, randomized, nmf, stream, circulant, masked) is one
 * such descriptor in one file of the library plus one row of its
 * registry; sb_solver_register() adds one from a program:
 *
 *     static const sb_solver_t mine = {.name = "mine", .description = "...", .caps = SB_CAP_METHOD,
 *                                      .plan = my_plan, .destroy = my_destroy, .execute = my_execute};
 *     sb_method_t m;
 *     sb_solver_register(ctx, &mine, &m);  // then --method mine, sb_method_parse("mine") and the job's method m
 *
 * (docs/extending.md and tests/test_extend.c hold a complete one.) */
#ifndef SEPBRDF_EXPERIMENTAL_SOLVER_H
#define SEPBRDF_EXPERIMENTAL_SOLVER_H

#include "../common.h"
#include "../matrix.h"
#include "../param.h"
#include "../solver.h"
#include "../svd.h"

#ifdef __cplusplus
extern "C" {
#endif

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
    /* the plan's nonneg_ratio (factor.h); NULL: none */
    const double *nonneg_ratio;
    /* the plan's nonneg_ratio_channel (factor.h); NULL: none */
    const double *nonneg_ratio_channel;
    /* the plan's nonneg_first_fit (factor.h) */
    int nonneg_first_fit;
    /* the plan's nonneg_rounds (factor.h; 0 or 1: one) */
    size_t nonneg_rounds;
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
    /* iterative solvers that fit terms in stages: the leading terms whose
     * sweeps all ended by the tolerance (J when converged), so that a
     * caller keeping fewer terms knows whether those converged; 0 (as the
     * plan passes it): converged says for every term */
    size_t converged_terms;
} sb_solve_out_t;

/* A solver.  The library keeps the pointer: the descriptor and every
 * string it points to must live as long as the process. */
typedef struct sb_solver {
    const char *name;        /* the method's name (SB_CAP_METHOD) and the factors' "method" metadata */
    const char *description; /* one line */
    unsigned caps;           /* SB_CAP_ORTHONORMAL ... (solver.h) */
    /* whether the solver takes the problem (method asked, shape, mask);
     * NULL: exactly when its method (SB_CAP_METHOD) is asked for */
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
     * ||W_r A W_c||^2 pw^2 of this channel's data.  mx NULL: the maxima
     * are not wanted (the factor job's second form of a layout, whose
     * maxima are read only where it is kept): ssq and *n2 alone. */
    sb_result_t (*exact)(void *state, const sb_solve_in_t *in, double t, size_t J, double *ssq, double *mx, double *n2);
    /* SB_CAP_STRUCTURED: rows of A that hold every distinct value (the
     * rest repeat them), so scans of A can stop there. */
    size_t (*distinct_rows)(const void *state);
    /* SB_CAP_METHOD: a few words after the name in lists of methods
     * ("dgesdd": `full (dgesdd)`), or NULL */
    const char *note;
} sb_solver_t;

/* At most this many solvers in a process, built-in ones included (plans
 * keep one slot each). */
#define SB_SOLVERS_MAX 16

/* Add a solver to the process's registry (after the built-in ones, in
 * the order the plan tries them) and give its method (may be NULL; for a
 * solver with SB_CAP_METHOD, the next free number after the built-in
 * ones, else SB_METHOD_NONE).  A solver without takes is chosen when its
 * method is asked for, before any solver that decides by takes.  desc
 * must stay valid for the life of the process.  Safe to call from several
 * threads.  Errors: SB_ERR_ARG (NULL desc, a name that is empty, "auto"
 * or not of letters, digits, '-' and '_', no plan, destroy or execute, no
 * takes and no SB_CAP_METHOD, SB_CAP_EXACT_TAILS without exact,
 * SB_CAP_STRUCTURED without distinct_rows), SB_ERR_RANGE (the name is
 * taken; SB_SOLVERS_MAX reached). */
SB_API sb_result_t sb_solver_register(sb_context_t *ctx, const sb_solver_t *desc, sb_method_t *method);

#ifdef __cplusplus
}
#endif
#endif
