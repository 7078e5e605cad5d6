/* The block-circulant solver (circulant.h): the exact SVD of isotropic
 * sources on the io grid from their R^3 distinct values, with the exact
 * error of every truncation.  Taken for method auto when the matrix has
 * the shape (rows == cols == R^2, a period R); a channel suits when its
 * weights depend on theta only and it is even in the azimuth difference. */
#include <stdlib.h>

#include "solve/circulant.h"
#include "solve/solver.h"
#include "util/internal.h"

/* Entries within this fraction of the largest count as even. */
#define SB_CIRC_EVEN_TOL 1e-9

typedef struct circ_state {
    sb_circ_t *c;
    size_t R, J;
    double *tails; /* J: exact squared errors of the last execute */
} circ_state_t;

static int takes(const sb_solve_problem_t *pb) {
    size_t R = pb->period;
    return !pb->masked && pb->svd.method == SB_METHOD_AUTO && R > 0 && R * R == pb->rows && pb->rows == pb->cols;
}

static void destroy(void *state) {
    circ_state_t *s = state;
    if (!s) return;
    sb_circ_destroy(s->c);
    free(s->tails);
    free(s);
}

static sb_result_t plan(sb_context_t *ctx, const sb_solve_problem_t *pb, void **state) {
    circ_state_t *s = sb_calloc(ctx, 1, sizeof *s, "circulant plan");
    if (!s) return SB_ERR_NOMEM;
    s->R = pb->period;
    s->J = pb->terms;
    sb_result_t r = sb_circ_create(ctx, s->R, &s->c);
    if (r == SB_OK && !(s->tails = sb_alloc(ctx, s->J, sizeof(double), "circulant plan"))) r = SB_ERR_NOMEM;
    if (r != SB_OK) {
        destroy(s);
        return r;
    }
    *state = s;
    return SB_OK;
}

static int suits(const void *state, const sb_solve_in_t *in) {
    const circ_state_t *s = state;
    size_t R = s->R;
    for (size_t i = 0; in->wr && i < R * R; i++)
        if (in->wr[i] != in->wr[i % R] || in->wc[i] != in->wr[i % R]) return 0;
    return sb_circ_is_even(s->c, in->a, in->lda, in->wr, SB_CIRC_EVEN_TOL);
}

static sb_result_t execute(void *state, const sb_solve_in_t *in, sb_solve_out_t *out) {
    circ_state_t *s = state;
    return sb_circ_svd(s->c, in->a, in->lda, in->wr, s->J, in->pw, out->s, out->u, out->v, s->tails);
}

static sb_result_t exact(void *state, const sb_solve_in_t *in, double t, size_t J, double *ssq, double *mx,
                         double *n2) {
    circ_state_t *s = state;
    for (size_t j = 0; j < J; j++)
        ssq[j] = s->tails[j] * t * t;
    *n2 = sb_circ_last_norm2(s->c, in->a); /* from the blocks of the channel's execute */
    if (*n2 < 0) *n2 = sb_circ_norm2(s->R, in->a, in->lda, in->wr, in->pw);
    return mx ? sb_circ_max_abs(s->c, in->a, in->lda, in->wr, t, J, mx) : SB_OK;
}

static size_t distinct_rows(const void *state) { return ((const circ_state_t *)state)->R; }

const sb_solver_t sb_solver_circulant = {
    .name = "circulant",
    .description = "exact block-circulant SVD of isotropic sources on the io grid (R/2 + 1 blocks of R x R)",
    .caps = SB_CAP_ORTHONORMAL | SB_CAP_EXACT_TAILS | SB_CAP_ALL_SIGMA | SB_CAP_STRUCTURED,
    .takes = takes,
    .plan = plan,
    .destroy = destroy,
    .suits = suits,
    .execute = execute,
    .exact = exact,
    .distinct_rows = distinct_rows};
