/* The non-negative solver's sweeps where every cell weighs 1
 * (nmf_gram.c): the nested objective of solver_nmf.c from products with
 * the data and the factors' Gram matrices. */
#ifndef SB_SOLVE_NMF_GRAM_H
#define SB_SOLVE_NMF_GRAM_H

#include <stddef.h>

#define SB_NMF_GRAM_MAX_TERMS 64

typedef struct sb_nmf_gram_opts {
    int max_iters;    /* sweeps of the last stage at most */
    int stage_sweeps; /* sweeps of each stage before the last at most */
    int seed_sweeps;  /* rank-one updates seeding a term */
    double tol;       /* a sweep gaining less than tol per prefix (in log ||E_p||^2) stops a stage */
    double floor2;    /* the least ||E_p||^2 a prefix weight takes */
} sb_nmf_gram_opts_t;

/* Fit X (m x n, column-major, leading dimension m) ~ U V^T with U (m x J)
 * and V (n x J) >= 0, in stages: term k seeded from the column sums of
 * the positive part of the residual of the k - 1 before it, then
 * o->seed_sweeps updates of that term alone, then nested sweeps of the k
 * terms minimising sum_p log ||X - U_p V_p^T||^2 (U_p, V_p the first p
 * columns).  Counts the nested sweeps into *iterations; *converged: the
 * last stage stopped at o->tol.  Returns 0, or -1 when out of memory or J
 * > SB_NMF_GRAM_MAX_TERMS. */
int sb_nmf_gram_fit(const sb_nmf_gram_opts_t *o, const double *x, size_t m, size_t n, size_t J, double *U, double *V,
                    int *iterations, int *converged);

/* The terms as s_j = |u_j| |v_j| with unit u_j (m rows) and v_j (n),
 * in place, j = 0..J-1 (a zero factor stays zero). */
void sb_nmf_normalise(size_t m, size_t n, size_t J, double *sig, double *U, double *V);

#endif
