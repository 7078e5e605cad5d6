/* sepbrdf: truncated singular value decomposition of one dense matrix.
 *
 * A (m x n, column-major, leading dimension lda) ~ U diag(s) V^T with the k
 * leading singular triplets, s descending.  Plan once, execute many: the plan
 * checks shapes, picks the method, draws the random test matrix, queries
 * LAPACK workspaces and allocates; execute allocates nothing and never
 * modifies A.
 *
 * Methods and what they guarantee (d = min(m, n), eps = 2^-52, or 2^-23 in
 * single precision):
 *   FULL        dgesdd on a copy of A: every singular value; the rank-k
 *               truncation is optimal to rounding (Eckart-Young).
 *   TOPK        Restarted block Krylov (the leading k exactly, to a
 *               certified residual): cycles of the block Krylov range
 *               finder below (l = k + p vectors, depth q = 8 unless
 *               power_iters sets it) from the previous cycle's l leading
 *               right Ritz vectors, until every triplet has
 *               |A v_j - s_j u_j| <= tol s_1 (and A^T u_j = s_j v_j
 *               exactly): tol = 2^-40 in double, 2^-12 in single.  Then
 *               each s_j is within tol s_1 of a singular value (in
 *               practice within ~tol^2 s_1^2 / gap) and the vectors within
 *               an angle tol s_1 / gap of the singular subspaces.  Block
 *               products only: 2q + 3 reads of A a cycle, one on the io
 *               matrices of docs/performance.md.  A cycle stops below
 *               depth q when the residuals, estimated from the next
 *               Krylov block without a read of A, are below tol / 2
 *               (2i + 4 reads at degree i; the certificate is still the
 *               residual read from A).  On a square A equal to
 *               A^T entry for entry (an io matrix of a reciprocal
 *               source; checked each execute, about two reads) every
 *               product A B is formed as A^T B, the faster read on x86-64
 *               with AVX2 (the same maths, other rounding).  Where the basis
 *               l (q + 1) would exceed d / 2 (q lowered to 1 first), or
 *               after 40 cycles without convergence (a flat spectrum), the
 *               Gram route: G of the smaller side (dsyrk), its k largest
 *               eigenpairs (dsyevr), one Rayleigh-Ritz step on A itself.
 *               That route squares the condition number, so a triplet with
 *               sigma_j < ~sqrt(eps) sigma_1 (1e-8 in double, 3e-4 in
 *               single) is only as good as the subspace the Gram matrix can
 *               resolve, and entries beyond ~1e154 (1e19 in single
 *               precision) overflow G and give SB_ERR_NUMERIC.
 *   RANDOMIZED  Halko-Martinsson-Tropp: Y = A Omega with a seeded Gaussian
 *               Omega (n x l, l = k + p), q power iterations with QR
 *               re-orthonormalisation, Q = qr(Y), SVD of B = Q^T A: 2q + 2
 *               reads of A.  Error in expectation <= (1 + k / (p - 1))^(1/2)
 *               times the optimum for q = 0 (HMT 2011, Thm. 10.5); each
 *               power iteration raises the decay ratio sigma_{k+1}/sigma_k
 *               in the bound to the power 2q + 1.  By default the basis
 *               keeps every iterate, [Y_0, Y_1, ..., Y_q] (block Krylov,
 *               Musco & Musco 2015): the same 2q + 2 reads of A (each
 *               A^T Y_i is also a block of B^T) and an error that depends
 *               far less on the gap (on the io matrices of
 *               docs/performance.md 10-100x closer to the optimum at
 *               q = 2).  Used when l (q + 1) <= d/2 (beyond, the SVD of the
 *               n x l (q + 1) matrix B^T costs more than it saves).  Worst
 *               case: a flat spectrum (noise).  Deterministic: the same
 *               seed gives the same bits.  In mixed precision by default
 *               (sb_svd_opts_t.mixed): the reads of the sketch in float
 *               (sgemm, twice the rate), the projection on the k leading
 *               Ritz vectors in double (one more read, k columns), so the
 *               identity below holds to double rounding; the subspace
 *               carries float rounding, a floor of a few 2^-24 ||A||_F
 *               in the error, so an execute whose residual is below
 *               2^-10 ||A||_F is made again in double.  Same error as
 *               double to 1e-10 relative on the io matrices of
 *               docs/performance.md, 1.6-2.5x less CPU.
 *   single precision: the same methods in float on a converted copy of A
 *               (one more read); singular values within ~1e-5 sigma_1.
 *   AUTO        FULL when d <= SB_SVD_AUTO_FULL_MAX (under 2 ms a matrix,
 *               and every sigma); else TOPK when d <= SB_SVD_AUTO_TOPK_MAX
 *               (exact for under ~5 ms a matrix) or when the sketch k + p
 *               exceeds d / SB_SVD_AUTO_SKETCH_DIV (a sketch that wide is
 *               no faster than TOPK); RANDOMIZED (block Krylov, q = 2,
 *               p = 10) otherwise.  Measured on 2 cores, see
 *               docs/performance.md.
 *
 * Every method returns orthonormal U and V with s_j = u_j^T A v_j and
 * U^T A V diagonal on the k terms, so the error of the rank-r truncation is
 *     ||A - U_r S_r V_r^T||_F^2 = ||A||_F^2 - sum_{j<=r} s_j^2
 * exactly (in exact arithmetic); sb_svd_info_t reports it.  The identity
 * loses relative accuracy ~eps ||A||^2 / err^2 when err << ||A||: below a
 * relative error of ~1e-6 compute residuals explicitly if they matter. */
#ifndef SEPBRDF_SVD_H
#define SEPBRDF_SVD_H

#include "common.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Methods are chosen by name (sb_method_parse): "auto" and the solvers
 * with SB_CAP_METHOD (solver.h), numbered 0 .. sb_method_count() - 1.
 * The six below keep their numbers for programs that name them; other
 * methods, built-in or registered by a program (experimental/solver.h),
 * get the numbers after them, so adding one changes no enum. */
typedef enum sb_method {
    SB_METHOD_NONE = -1,  /* no method: an unknown one asked for, or a NULL plan */
    SB_METHOD_AUTO = 0,   /* pick from m, n, k (see above) */
    SB_METHOD_FULL,       /* LAPACK dgesdd, all singular values */
    SB_METHOD_TOPK,       /* exact leading k: restarted block Krylov (or the Gram route) */
    SB_METHOD_RANDOMIZED, /* Halko-Martinsson-Tropp range finder */
    SB_METHOD_NMF,        /* non-negative factors (the plan's nmf solver; not an SVD: sb_svd_create refuses it) */
    SB_METHOD_STREAM      /* the plan's matrix-free solver (solver.h; sb_svd_create refuses it) */
} sb_method_t;

/* A method's number by name (auto, full, topk, randomized, nmf, stream
 * and those registered); SB_ERR_UNKNOWN otherwise (NULL name included),
 * SB_ERR_ARG for a NULL out. */
SB_API sb_result_t sb_method_parse(const char *name, sb_method_t *out);
/* Name of method m ("?" for an unknown m), and a few words on it for
 * lists ("dgesdd" for full, "default" for auto; "" for none or an
 * unknown m). */
SB_API const char *sb_method_name(sb_method_t m);
SB_API const char *sb_method_note(sb_method_t m);
/* The methods: auto, the built-in ones and those a program registered. */
SB_API size_t sb_method_count(void);

/* AUTO thresholds (see the comment at the top). */
#define SB_SVD_AUTO_FULL_MAX 128
#define SB_SVD_AUTO_TOPK_MAX 400
#define SB_SVD_AUTO_SKETCH_DIV 8

/* Most power iterations (each one more read of A; 2 already reach the
 * optimum to plotting accuracy on the matrices of docs/performance.md). */
#define SB_SVD_MAX_POWER_ITERS 64

/* Options; a zeroed struct gives the defaults. */
typedef struct sb_svd_opts {
    sb_method_t method;
    int oversample;       /* randomized: p, 0 = default 10, negative = none */
    int power_iters;      /* randomized: q, 0 = default 2, negative = none, at most SB_SVD_MAX_POWER_ITERS;
                             TOPK: the largest depth, default 8 */
    uint64_t seed;        /* randomized: seed of the test matrix, 0 = default 1 */
    int single_precision; /* compute in float (inputs/outputs stay double) */
    size_t block;         /* adaptive randomized: test vectors per step, 0 = default 32 */
    int krylov;           /* randomized: 0 = block Krylov when it fits, negative = plain
                             subspace iteration (see RANDOMIZED above) */
    int mixed;            /* randomized: >= 0 = mixed precision (the default): the sketch and its
                             power steps in float on a copy scaled by a power of two, then the k
                             leading Ritz vectors re-orthonormalised in double and A projected on
                             them in double, so the values, U, V and the residual identity are
                             those of an exact projection (the subspace moves by float rounding
                             only); the copy takes m n floats, and where it does not fit the
                             memory limit the plan is made in double; negative = every step in
                             double.  Ignored with single_precision and by FULL and TOPK. */
} sb_svd_opts_t;

/* What one execute did. */
typedef struct sb_svd_info {
    size_t rank;      /* triplets written: k, or the adaptive choice */
    size_t sketch;    /* randomized: columns of the basis Q; TOPK: k; FULL: d */
    double norm_fro;  /* ||A||_F when known (given, adaptive mode, FULL, TOPK, single), else 0 */
    double resid_fro; /* ||A - U_r S_r V_r^T||_F from the identity above, -1 if unknown */
    size_t cycles;    /* TOPK: Krylov cycles run (0: the Gram route alone) */
    size_t degree;    /* TOPK: Krylov degree of the last cycle (its basis has degree + 1 blocks; 0: Gram route) */
} sb_svd_info_t;

typedef struct sb_svd sb_svd_t;

/* The method a plan for (m, n, k, opts) would use: opts->method unless it
 * is AUTO, then the AUTO rule (SB_METHOD_NONE for an unknown method).
 * Plans nothing, allocates nothing. */
SB_API sb_method_t sb_svd_auto_method(size_t m, size_t n, size_t k, const sb_svd_opts_t *opts);

/* Plan a rank-k SVD of m x n matrices.  opts may be NULL (defaults).
 * Errors: SB_ERR_ARG (no output, empty matrix, bad method), SB_ERR_RANGE
 * (k = 0 or k > min(m, n), power_iters above SB_SVD_MAX_POWER_ITERS), SB_ERR_OVERFLOW (dimension beyond LAPACK's int,
 * or workspace beyond the memory limit), SB_ERR_NOMEM, SB_ERR_NUMERIC
 * (workspace query failed). */
SB_API sb_result_t sb_svd_create(sb_context_t *ctx, size_t m, size_t n, size_t k, const sb_svd_opts_t *opts,
                                 sb_svd_t **out);
/* Getters on a NULL plan: SB_METHOD_NONE, 0, 0 and a zeroed info. */
SB_API void sb_svd_destroy(sb_svd_t *svd);             /* accepts NULL */
SB_API sb_method_t sb_svd_method(const sb_svd_t *svd); /* the method actually used */
SB_API size_t sb_svd_rank(const sb_svd_t *svd);        /* k of the plan */
/* Bytes of workspace the plan holds (for reports). */
SB_API size_t sb_svd_workspace_bytes(const sb_svd_t *svd);

/* s[0..k-1], U (m x k, ld m), V (n x k, ld n).  U or V may be NULL when not
 * wanted.  If all_s is not NULL and the method computes every singular
 * value (FULL), all min(m, n) of them are written there and 1 returned via
 * *have_all; otherwise *have_all = 0.  A is read only; lda >= m.
 * Errors: SB_ERR_ARG (NULL svd, A or s, lda < m), SB_ERR_OVERFLOW (lda
 * beyond LAPACK's int, or lda x n overflows), SB_ERR_NUMERIC (LAPACK
 * failure or a non-finite entry in A). */
SB_API sb_result_t sb_svd_execute(sb_svd_t *svd, const double *A, size_t lda, double *s, double *U, double *V,
                                  double *all_s, int *have_all);

/* Adaptive rank: the smallest r in [min_rank, k] with
 *     ||A - U_r S_r V_r^T||_F <= rel_tol ||A||_F,
 * or r = k when no such r exists; rel_tol = 0 keeps all k.  norm_fro is ||A||_F if the caller knows
 * it, 0 to have it computed (one read of A).  FULL and TOPK compute the k
 * triplets and pick r from the identity above.  RANDOMIZED grows the range
 * basis Q `block` columns at a time (Martinsson-Voronin's blocked range
 * finder, with the plan's q and with re-orthogonalisation against the
 * earlier blocks) and stops once the target is met with r + p <= columns,
 * or at k + p columns: for a target reached early it reads A far fewer
 * times than the plan's k would.  Outputs as sb_svd_execute for r terms
 * (columns r..k-1 of U, V and s[r..k-1] are left as they were); *info (may
 * be NULL) receives rank r, the sketch size and both norms.
 * Errors as sb_svd_execute, and SB_ERR_RANGE for rel_tol outside [0, 1) or
 * min_rank > k. */
SB_API sb_result_t sb_svd_execute_adaptive(sb_svd_t *svd, const double *A, size_t lda, double rel_tol, double norm_fro,
                                           size_t min_rank, double *s, double *U, double *V, sb_svd_info_t *info);

/* Info of the last successful execute (zeros before the first). */
SB_API sb_svd_info_t sb_svd_last_info(const sb_svd_t *svd);

#ifdef __cplusplus
}
#endif
#endif
