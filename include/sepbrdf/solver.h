/* sepbrdf: the factorisation methods (solvers) the plan can use.
 *
 * Each solver is one descriptor in a registry: a name, a description
 * and capability flags; programs can add their own
 * (experimental/solver.h).  The plan (factor.h) picks the
 * first solver of the registry that takes the problem: the masked fit for
 * matrices with excluded cells, the streamed solver for streamed matrices
 * (matrix.h: beyond the memory limit) or method stream, the block-circulant SVD for isotropic
 * sources on the io grid (method auto), else the dense method asked for
 * (or the one the auto rule of svd.h picks).  The name of the solver used
 * is the factors' "method" metadata. */
#ifndef SEPBRDF_SOLVER_H
#define SEPBRDF_SOLVER_H

#include "common.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Capabilities of a solver. */
enum {
    SB_CAP_ORTHONORMAL = 1u << 0, /* u_j, v_j orthonormal: the SVD's truncation identities hold */
    SB_CAP_NONNEG = 1u << 1,      /* g_j, h_j >= 0 (no sign rule) */
    SB_CAP_MASKS = 1u << 2,       /* fits the valid cells only */
    SB_CAP_EXACT_TAILS = 1u << 3, /* gives the exact error of every truncation without a residual pass */
    SB_CAP_ALL_SIGMA = 1u << 4,   /* computes every singular value */
    SB_CAP_STRUCTURED = 1u << 5,  /* reads the sampled values through a structure (weights applied inside) */
    SB_CAP_STREAMED = 1u << 6,    /* reads the matrix in blocks of columns, one pass per product, every channel
                                     at once: runs on matrices never held (matrix.h, streamed) */
    SB_CAP_METHOD = 1u << 7       /* a method: chosen by its name (sb_method_parse, the CLI's --method) */
};

/* Registered solvers, in the order the plan tries them. */
SB_API size_t sb_solver_count(void);
/* Name ("full", "circulant", ...), one-line description and capabilities
 * of solver i; NULL / 0 for i >= sb_solver_count(). */
SB_API const char *sb_solver_name(size_t i);
SB_API const char *sb_solver_description(size_t i);
SB_API unsigned sb_solver_caps(size_t i);

#ifdef __cplusplus
}
#endif
#endif
