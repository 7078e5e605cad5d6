/* The masked solver (fit.h): cells outside the domain or not measured are
 * excluded from the fit (imputation warm start, then alternating least
 * squares on the valid cells: four terms jointly, then one term at a
 * time, so that the first j >= 4 terms of a k-term fit are the j-term fit;
 * fit_chain.c).  Taken whenever the matrix has excluded cells. */
#include <stdlib.h>

#include "solve/fit_impl.h"
#include "solve/solver.h"
#include "util/internal.h"

typedef struct masked_state {
    sb_fit_t *fit;
    sb_fit_opts_t opts;
} masked_state_t;

static int takes(const sb_solve_problem_t *pb) { return pb->masked; }

static void destroy(void *state) {
    masked_state_t *s = state;
    if (!s) return;
    sb_fit_destroy(s->fit);
    free(s);
}

static sb_result_t plan(sb_context_t *ctx, const sb_solve_problem_t *pb, void **state) {
    masked_state_t *s = sb_calloc(ctx, 1, sizeof *s, "masked plan");
    if (!s) return SB_ERR_NOMEM;
    s->opts = (sb_fit_opts_t){pb->fit_max_iters, pb->fit_tol,      pb->svd.seed,
                              pb->max_error,     {{0, 0}, {0, 0}}, {{0, 0}, {0, 0}}};
    sb_result_t r = sb_fit_create(ctx, pb->rows, pb->cols, pb->terms, &s->fit);
    if (r != SB_OK) {
        destroy(s);
        return r;
    }
    *state = s;
    return SB_OK;
}

void sb_solver_masked_start(void *state, const double *s, const double *u, const double *v) {
    masked_state_t *st = state;
    if (st) sb_fit_set_start(st->fit, s, u, v);
}

static sb_result_t execute(void *state, const sb_solve_in_t *in, sb_solve_out_t *out) {
    masked_state_t *s = state;
    sb_fit_info_t fi;
    sb_fit_opts_t o = s->opts;
    for (int side = 0; in->param && side < 2; side++) { /* the cells bilinear taps reach (fit.h) */
        sb_param_texture_size(in->param, side, &o.tex[side][0], &o.tex[side][1]);
        sb_param_wrap(in->param, side, o.wrap[side]);
    }
    sb_result_t r = fit_chain(s->fit, in->x, in->ldx, in->mask, &o, out->s, out->u, out->v, &fi);
    out->iterations = fi.iterations;
    out->converged = fi.converged;
    out->converged_terms = fi.conv_terms;
    return r;
}

const sb_solver_t sb_solver_masked = {.name = "masked",
                                      .description =
                                          "fit on the valid cells only: imputation, then alternating least squares",
                                      .caps = SB_CAP_MASKS,
                                      .takes = takes,
                                      .plan = plan,
                                      .destroy = destroy,
                                      .execute = execute};
