/* Private: the truncated-SVD plan shared by svd.c (plan, dispatch, norms),
 * svd_dense.c (FULL, TOPK), svd_rand.c (RANDOMIZED) and svd_common.c (the
 * helpers below them all).  The files form a tree: svd.c calls the methods,
 * svd_rand.c may call svd_dense.c, all of them svd_common.c. */
#ifndef SEPBRDF_SVD_INTERNAL_H
#define SEPBRDF_SVD_INTERNAL_H

#include <lapacke.h>

#include "sepbrdf/svd.h"

/* TOPK by restarted block Krylov: depth q of a cycle and the cycles tried
 * before the Gram route takes over (see run_topk_krylov).  Deeper cycles
 * need fewer restarts: on the io matrix of N = 1024 q = 2, 3, 4, 6 took
 * 6, 4, 2, 1 cycles (42, 36, 22, 15 reads of A), on N = 4096 q = 4, 6, 8
 * took 3, 2, 1 (33, 30, 19 reads).  q is lowered where the basis
 * l (q + 1) would exceed d / 2.  A cycle ends below q once the residual
 * estimate meets the tolerance (run_rand): at N = 4096 the top 1 at degree
 * 5-6, the top 16 at 7 (Xeon VM, 2026-12-02: 0.88 -> 0.64 s for three
 * channels at J = 1); the top 8 still needs 8. */
#define SB_SVD_TOPK_Q 8
/* TOPK's smallest Krylov block: a read of a large A with 18 columns costs
 * about what one with 12 does (OpenBLAS packs A either way), and a wider
 * block converges in fewer cycles (N = 4096, J = 4: l = 14 took two cycles,
 * 1.34-1.66 s, l = 16 one, 0.93-0.99 s; J = 1: 0.94 s with l = 11, 0.96-0.98 s).
 * Wider still does not pay on the Xeon VM: at J = 8, l = 24 and 32 stop at
 * degree 7 and 6 (18 and 16 reads against 20), but a read costs 12.4,
 * 15 and 16.9 ms, and the basis to orthogonalise grows. */
#define SB_SVD_TOPK_MIN_BLOCK 16
#define SB_SVD_TOPK_CYCLES 40

struct sb_svd {
    sb_context_t *ctx;
    size_t m, n, k, d; /* d = min(m, n) */
    size_t l, b, L;    /* randomized: test vectors k + p (<= d), adaptive block, basis columns */
    size_t l0;         /* TOPK Krylov: the first cycle's block (k + p); l is the largest a restart grows to */
    int p, q, single, tr, krylov;
    int sym;   /* TOPK: this execute's A is symmetric, so A B is read as A^T B (gemm_tn.c) */
    int mixed; /* RANDOMIZED in mixed precision (single is set too): see sb_svd_mixed_finish */
    uint64_t seed;
    sb_method_t method;
    /* Workspace, typed double or float by `single` (see the templates for
     * what each holds per method); NULL when the method does not use it. */
    void *a, *sv, *u, *vt, *g, *w, *z, *y, *bt, *ws, *om, *c, *tau, *work;
    void *st;             /* TOPK Krylov: start block of the next cycle (n x l) */
    void *rs, *ur;        /* RANDOMIZED, TOPK Krylov: R of B^T's QR and its left singular vectors (L x L) */
    double *mu, *mv, *mz; /* mixed: U (m x k), A^T U (n x k), Z^T and tau (k x k + k), all double */
    sb_svd_opts_t opts;   /* mixed: the options, for the plan in double (dbl) */
    sb_svd_t *dbl;        /* mixed: the plan in double, made when first needed (execute) */
    /* TOPK Krylov, the residual estimate of each degree (run_rand): the Gram
     * matrix of B^T (L x L, upper) and its copy for syevr, the eigenvalues
     * (L) and k leading eigenvectors (L x k), R of the last block (l x l),
     * R X (l x k), the projected residual block (m x k), syevr's workspace */
    void *eg, *egc, *ew, *ex, *er, *erx, *ep, *ewk;
    lapack_int *eiw, *eisuppz;
    lapack_int elwork, eliwork;
    double est_tol;      /* > 0: stop the Krylov expansion once the estimate is below it */
    int est_stop;        /* the degree at which the last cycle stopped early, or -1 */
    size_t eg_cols;      /* columns of eg formed in this cycle */
    int gram;            /* TOPK by the Gram route (when the Krylov basis does not fit) */
    int cycles;          /* TOPK Krylov: cycles of the last execute */
    double resid;        /* TOPK Krylov: its largest residual / s_1 */
    sb_svd_t *gram_plan; /* TOPK Krylov: the Gram route, if the cycle limit is reached */
    lapack_int *iwork, *isuppz;
    lapack_int lwork, liwork;
    size_t bytes;
    int failed;
    sb_svd_info_t info;
};

/* One execute: what it reads and where it writes (see execute in svd.c). */
typedef struct sb_svd_run {
    const void *a; /* A, or the plan's copy (FULL, single precision) */
    size_t la;
    int adaptive;
    double tol2;     /* adaptive: squared relative tolerance */
    double nrm;      /* ||A||_F, or < 0 when not known */
    size_t min_rank; /* adaptive: at least this rank */
    double *sv, *U, *V, *all_s;
    int *have_all;
    size_t r, sketch; /* out: rank written, basis size */
    sb_svd_info_t info;
    const double *a0; /* the caller's A (mixed precision projects it), set by execute */
    size_t la0;
} sb_svd_run_t;

/* count1 * count2 elements of `size` bytes, overflow-checked; counted in
 * s->bytes.  NULL (reported) on failure. */
void *sb_svd_ws_alloc(sb_svd_t *s, size_t count1, size_t count2, size_t size);
#define ws_alloc sb_svd_ws_alloc

/* Singular value j of the plan's buffer (double or float). */
double sb_svd_sv_at(const sb_svd_t *s, size_t j);
/* ||A - U_r S_r V_r^T||_F = ||A|| (1 - sum_{j<r} (s_j / ||A||)^2)^(1/2). */
double sb_svd_resid_from(double nrm, const double *sv, size_t r);
/* Smallest r in [max(lo, 1), k] with 1 - sum_{j<r} (s_j / ||A||)^2 <= tol^2. */
size_t sb_svd_rank_for(const double *sv, size_t k, double nrm, double tol2, size_t lo);

/* A (n x n, ld lda; float with single) equals A^T entry for entry. */
int sb_svd_symmetric(const void *A, size_t n, size_t lda, int single);

/* Workspaces of FULL and TOPK by the Gram route (svd_dense.c), RANDOMIZED
 * and TOPK by Krylov cycles (svd_rand.c). */
sb_result_t sb_svd_plan_dense(sb_svd_t *s);
sb_result_t sb_svd_plan_rand(sb_svd_t *s);
sb_result_t sb_svd_plan_topk_krylov(sb_svd_t *s);
/* The methods: fill run->sv, U, V, r, sketch and info. */
sb_result_t sb_svd_run_full(sb_svd_t *s, sb_svd_run_t *run);
sb_result_t sb_svd_run_topk(sb_svd_t *s, sb_svd_run_t *run);
sb_result_t sb_svd_run_rand(sb_svd_t *s, sb_svd_run_t *run);
sb_result_t sb_svd_run_topk_krylov(sb_svd_t *s, sb_svd_run_t *run);

#endif
