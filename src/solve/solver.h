/* Private: the registry (solvers.c) and what solvers share.  The
 * descriptor is public (experimental/solver.h: programs register their
 * own).  Adding one to the library is one file holding one sb_solver_t
 * plus one row in the table of built-in solvers in solvers.c. */
#ifndef SEPBRDF_SOLVER_INTERNAL_H
#define SEPBRDF_SOLVER_INTERNAL_H

#include "sepbrdf/experimental/solver.h"

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

/* Registry index of the first solver that takes pb (sb_solver_count() if
 * none), and the solver at an index (NULL beyond the registry). */
size_t sb_solver_index(const sb_solve_problem_t *pb);
const sb_solver_t *sb_solver_at(size_t i);

/* The masked solver (solver_masked.c) and a warm start for its next
 * execute on state (fit.h sb_fit_set_start: s, u, v as it writes them,
 * read before it writes them; the plan's sb_plan_set_start). */
extern const sb_solver_t sb_solver_masked;
void sb_solver_masked_start(void *state, const double *s, const double *u, const double *v);

/* The non-negative solver (solver_nmf.c) and its carry (nmf_carry.c):
 * fits the factor job makes twice, kept per channel for an execute of
 * another plan from the same inputs: the state after rounds toward the
 * headline's ratios (the plan's nonneg_rounds; a refit asking for more
 * starts at the round after them), and a fit on a layout on the source's
 * own tables (the screening's, which the kept fit made again).  Either
 * way the terms are those the fit made again gives, bit for bit.
 * Created empty; sb_solver_nmf_carry hands it to the next executes on
 * state (NULL: none); a fit is kept in memory allocated when it is saved
 * (a failed allocation only leaves it out; so is a matrix the solver
 * fits without the mixes).  sb_nmf_carry_resumed and _reused: how many
 * executes started from rounds it held, or took a whole fit. */
typedef struct sb_nmf_carry sb_nmf_carry_t;
extern const sb_solver_t sb_solver_nmf;
sb_nmf_carry_t *sb_nmf_carry_create(void);
void sb_nmf_carry_destroy(sb_nmf_carry_t *c);
void sb_solver_nmf_carry(void *state, sb_nmf_carry_t *c);
size_t sb_nmf_carry_resumed(const sb_nmf_carry_t *c);
size_t sb_nmf_carry_reused(const sb_nmf_carry_t *c);

/* 1 when m is "auto" or names a solver (sb_method_name is not "?"). */
int sb_method_known(sb_method_t m);

#endif
