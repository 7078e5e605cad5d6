/* Private: the state and the parts of the masked fit shared by fit.c
 * (imputation, the driver), fit_als.c and fit_sweep.c (alternating least
 * squares on the valid cells: the stages, the sweeps) and fit_taps.c
 * (bounding what bilinear taps reach outside the data). */
#ifndef SEPBRDF_FIT_IMPL_H
#define SEPBRDF_FIT_IMPL_H

#include <lapacke.h>
#include <stdint.h>

#include "solve/fit.h"

/* Up to this many terms the fit finishes with alternating least squares
 * (Grams of k x k per row and column); beyond, imputation alone. */
#define SB_ALS_MAX_K 32
/* A joint refit may make a shorter prefix at most this much worse. */
#define SB_PREFIX_SLACK 2.0
/* A taps' constraint may raise the error on the valid cells this much. */
#define SB_TAPS_COST 1.5
/* Stages up to this many terms all refit jointly (joint_stage). */
#define SB_JOINT_ALL 8
/* Imputation steps that warm-start ALS. */
#define SB_ALS_WARM 4
/* Nested fits (fit_chain.c): the first this many terms fitted jointly
 * (the staged fit), the others one at a time. */
#define SB_CHAIN_JOINT 4
struct sb_fit {
    sb_context_t *ctx;
    struct sb_fit *sub[2]; /* nested fits: the joint SB_CHAIN_JOINT terms, one term */
    size_t m, n, k, l;
    double *x, *v, *y, *tau, *b, *sb, *ub, *vbt, *work;
    double *P, *Q; /* ALS: factors m x k, n x k */
    /* ALS: tconv[j] 1 when the sweeps that last set term j (its stage's
     * new term, or a kept joint refit of a later stage) ended by the
     * tolerance, 0 at max_iters (fit_als_stages) */
    unsigned char tconv[SB_ALS_MAX_K];
    /* the valid cells gathered for the last mask the stages ran on, kept
     * for the next run on the same mask (fit_cells_build); the nested
     * fits borrow their parent's (cells_borrowed: not theirs to free) */
    struct als_cells *cells;
    int cells_borrowed;
    const double *init_s, *init_u, *init_v; /* the next fit's warm start (sb_fit_set_start) */
    int warm; /* the ALS runs from that start: the stages from the last (fit_als_stages) */
    /* ALS sweep copies of the free columns, row-major: pt[r*kf + j] =
     * P[r + (j0+j)*m], qt likewise, and their outer products (lower
     * triangles, kt = kf(kf+1)/2 values per row / column) */
    double *pt, *qt, *pp, *qq;
    lapack_int *iwork;
    lapack_int lwork;
};

/* The valid cells in both orders, built once per execute so that the sweeps
 * read contiguous memory and test no mask: column c's cells are t in
 * [cp[c], cp[c+1]) with row cr[t] (increasing) and value cv[t]; row r's are
 * t in [rp[r], rp[r+1]) with column rc[t] (increasing) and value rv[t].
 * cres / rres hold the values less the fixed terms (columns < j0) of the
 * current stage, a_rc - sum_{j<j0} P_rj Q_cj, computed once per stage (the
 * fixed terms do not move during its sweeps); they alias cv / rv when
 * j0 = 0; with D kept (below) rres is NULL for j0 > 0, the rows reading
 * D.  Every sum runs in the order of the plain loops over the mask
 * (rows: c increasing; columns: r increasing), but for the right-hand
 * sides where D is kept (a BLAS product's order).  A row (column) with
 * more cells in than out has its Gram formed as the sum over all columns
 * (rows) less those left out (ls_update). */
typedef struct als_cells {
    size_t *cp, *rp;
    uint32_t *cr, *rc;
    double *cv, *rv, *cbuf, *rbuf;
    const double *cres, *rres;
    /* the cells left out, likewise: column c's rows ci[u], u in
     * [cip[c], cip[c+1]); row r's columns ri[u], u in [rip[r], rip[r+1]) */
    size_t *cip, *rip;
    uint32_t *ci, *ri;
    /* sum of cres^2 per column (n) and in all (fit_cells_residual) */
    double *ca2, a2;
    /* where most cells are valid: cres as a dense m x n matrix D (0 at the
     * cells left out) and its transpose DT, so that the right-hand sides
     * of a half-sweep are one product (bt, m x kf or n x kf) instead of a
     * gather per cell; NULL otherwise */
    double *D, *DT, *bt;
    /* what D, DT, ca2 and a2 point to or hold: for the data itself (j0 =
     * 0, every joint stage; made once, at the first) and for the data
     * less fixed terms; dv: the data's are made */
    double *Dv, *DTv, *ca2v, a2v, *Dr, *DTr, *ca2r;
    int dv;
    /* the mask the cells were gathered for (m x n, ld m; cm x cn, ncv
     * valid cells): a run on the same mask gathers only the values */
    unsigned char *cmask;
    size_t cm, cn, ncv;
} als_cells_t;

/* Gather the valid cells of X (m x n, ld lda) with mask != 0 (nvalid of
 * them) in both orders into cl (zeroed, or as the last build left it: on
 * the same mask its indices and buffers serve again, the values are
 * gathered anew); 0 or SB_ERR_NOMEM (cl then zeroed). */
int fit_cells_build(sb_context_t *ctx, als_cells_t *cl, const double *X, size_t m, size_t n, size_t lda,
                    const unsigned char *mask, size_t nvalid);
void fit_cells_free(als_cells_t *cl); /* and zero it */
/* The data less the fixed terms 0..j0-1 of f, in both orders. */
void fit_cells_residual(als_cells_t *cl, const sb_fit_t *f, size_t j0);
/* C (rows x kf, ld ldc) = A (rows x inner, ld rows) B (inner x kf, ld
 * ldb), every entry summed over the inner index in order. */
void fit_dense_product(const double *A, size_t rows, size_t inner, const double *B, size_t ldb, size_t kf, double *C,
                       size_t ldc);
/* ALS sweeps on the columns j0..ka-1 of f->P, f->Q until the error on the
 * cells stops improving (o->tol) or o->max_iters; returns the error. */
double fit_als_until(sb_fit_t *f, als_cells_t *cl, size_t j0, size_t ka, const sb_fit_opts_t *o, double norm,
                     int *sweeps, int *converged);
/* The state of a non-strict staged run before its last stage, from which
 * a strict run resumes (fit_als.c): the last stage is the only one whose
 * rule differs, unless a joint refit kept earlier left the prefixes'
 * errors increasing (same 0). */
typedef struct als_resume {
    int save, resume; /* record (non-strict run) / start from the record (strict run) */
    int valid, same;  /* recorded; every earlier decision was also the strict one */
    double *P, *Q;    /* m x k, n x k */
    double acc[SB_ALS_MAX_K], err;
    int converged;
    unsigned char tconv[SB_ALS_MAX_K]; /* f->tconv then */
    /* the last stage's two fits from that state, the same in both runs
     * (only the rule that keeps one differs): the new term alone (err1,
     * c1) and the joint refit (errj, cj, its prefixes' squared errors
     * e2), m x k and n x k each; last: recorded */
    double *P1, *Q1, *Pj, *Qj, e2[SB_ALS_MAX_K], err1, errj;
    int c1, cj, last;
} als_resume_t;
/* The staged ALS (fit_als.c); rs may be NULL.  f->tconv says which of
 * the terms left come from converged sweeps. */
sb_result_t fit_als_stages(sb_fit_t *f, const double *As, size_t lda, const unsigned char *mask, size_t nvalid,
                           const sb_fit_opts_t *o, int strict, double norm2, int *total, int *converged, double *err,
                           int *stretched, als_resume_t *rs);
/* Squared errors of the prefixes of f on the cells of X with mask != 0. */
void fit_valid_prefix_e2(const sb_fit_t *f, const double *X, size_t lda, const unsigned char *mask, double *e2);
/* Whether those errors are non-increasing. */
int fit_prefixes_monotone(const sb_fit_t *f, const double *X, size_t lda, const unsigned char *mask);
/* The leading terms of f whose flags f->tconv are all set (k: all). */
size_t fit_conv_terms(const sb_fit_t *f);
/* Whether the k squared errors e2 are non-increasing. */
int fit_e2_monotone(const double *e2, size_t k);
/* For each cell that is not data (ext 0), the range [lo, hi] of the data
 * (ext 1) among the rows and columns within two texels (layout o->tex,
 * o->wrap) that bilinear taps sharing the cell read (x m x n, ld m; lo =
 * INFINITY where none, and at data).  Returns 0, or -1 without memory. */
int fit_taps_range(const sb_fit_opts_t *o, size_t m, size_t n, const double *x, const unsigned char *ext, double *lo,
                   double *hi);
/* A nested fit (the masked solver's): as sb_fit_execute, with more than
 * SB_CHAIN_JOINT terms one term at a time after those. */
sb_result_t fit_chain(sb_fit_t *f, const double *A, size_t lda, const unsigned char *mask, const sb_fit_opts_t *opts,
                      double *s, double *U, double *V, sb_fit_info_t *info);
/* sb_fit_execute, memoised while a job runs (fit_memo.c): a fit of the
 * same shape, options, mask and valid values as one made before in the
 * job takes its terms and info, the same bits.  U and V non-NULL to be
 * memoised. */
sb_result_t fit_memo_execute(sb_fit_t *f, const double *A, size_t lda, const unsigned char *mask,
                             const sb_fit_opts_t *opts, double *s, double *U, double *V, sb_fit_info_t *info);
/* The ALS part of a fit from the warm start in f->P, f->Q (fit_taps.c). */
sb_result_t fit_als(sb_fit_t *f, const double *As, size_t lda, const unsigned char *mask, size_t nvalid0,
                    const sb_fit_opts_t *o, double norm2, int *total, int *converged, double *err);

#endif
