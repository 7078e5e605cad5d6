/* The registry of solvers (solver.h).  The plan tries them in this order
 * and takes the first that takes the problem; adding a solver is one file
 * with its descriptor and one row here. */
#include <stddef.h>

#include "solve/solver.h"

static const sb_solver_t *const registry[] = {
    &sb_solver_nmf,  &sb_solver_masked, &sb_solver_stream,     &sb_solver_circulant,
    &sb_solver_full, &sb_solver_topk,   &sb_solver_randomized,
};
#define NSOLVERS (sizeof registry / sizeof registry[0])
_Static_assert(NSOLVERS <= SB_SOLVERS_MAX, "raise SB_SOLVERS_MAX");

size_t sb_solver_index(const sb_solve_problem_t *pb) {
    size_t i = 0;
    while (i < NSOLVERS && !registry[i]->takes(pb))
        i++;
    return i;
}
const sb_solver_t *sb_solver_at(size_t i) { return i < NSOLVERS ? registry[i] : NULL; }

size_t sb_solver_count(void) { return NSOLVERS; }
const char *sb_solver_name(size_t i) { return i < NSOLVERS ? registry[i]->name : NULL; }
const char *sb_solver_description(size_t i) { return i < NSOLVERS ? registry[i]->description : NULL; }
unsigned sb_solver_caps(size_t i) { return i < NSOLVERS ? registry[i]->caps : 0; }
