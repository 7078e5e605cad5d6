/* The dense SVD solvers (svd.h): full (dgesdd), topk (Gram + dsyevr + a
 * Rayleigh-Ritz step) and randomized (Halko-Martinsson-Tropp, block
 * Krylov).  One sb_svd_t plan each; method auto takes the one the AUTO
 * rule of svd.h picks for the shape. */
#include "solve/solver.h"

static int takes_method(const sb_solve_problem_t *pb, sb_method_t own) {
    return !pb->masked && sb_svd_auto_method(pb->rows, pb->cols, pb->terms, &pb->svd) == own;
}
static int takes_full(const sb_solve_problem_t *pb) { return takes_method(pb, SB_METHOD_FULL); }
static int takes_topk(const sb_solve_problem_t *pb) { return takes_method(pb, SB_METHOD_TOPK); }
static int takes_rand(const sb_solve_problem_t *pb) { return takes_method(pb, SB_METHOD_RANDOMIZED); }

static sb_result_t plan(sb_context_t *ctx, const sb_solve_problem_t *pb, void **state) {
    return sb_svd_create(ctx, pb->rows, pb->cols, pb->terms, &pb->svd, (sb_svd_t **)state);
}

static void destroy(void *state) { sb_svd_destroy(state); }

static sb_result_t execute(void *state, const sb_solve_in_t *in, sb_solve_out_t *out) {
    return sb_svd_execute(state, in->x, in->ldx, out->s, out->u, out->v, NULL, NULL);
}

/* A dense solver: orthonormal terms, no mask, no structure; a method. */
#define SB_DENSE_SOLVER(id, name_, description_, caps_, takes_, note_)                                                 \
    const sb_solver_t id = {.name = name_,                                                                             \
                            .description = description_,                                                               \
                            .caps = SB_CAP_ORTHONORMAL | SB_CAP_METHOD | (caps_),                                      \
                            .takes = takes_,                                                                           \
                            .plan = plan,                                                                              \
                            .destroy = destroy,                                                                        \
                            .execute = execute,                                                                        \
                            .note = note_}

SB_DENSE_SOLVER(sb_solver_full, "full", "LAPACK dgesdd: every singular value, optimal truncation", SB_CAP_ALL_SIGMA,
                takes_full, "dgesdd");
SB_DENSE_SOLVER(sb_solver_topk, "topk", "the exact leading terms: Gram matrix, dsyevr and a Rayleigh-Ritz step", 0,
                takes_topk, NULL);
SB_DENSE_SOLVER(sb_solver_randomized, "randomized",
                "Halko-Martinsson-Tropp range finder with block Krylov iterations (seeded)", 0, takes_rand, NULL);
