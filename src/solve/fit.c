/* Masked low-rank fitting: the rank-k approximation of A on its valid cells
 * only (cells with mask 0 are not data: below the horizon, unmeasured).
 *
 * No closed form exists for an arbitrary mask; we iterate imputation (the
 * EM / hard-impute scheme): X = A on valid cells, the current rank-k
 * estimate L on the others; refactor X; repeat until the error on the valid
 * cells stops improving.  Each refactorisation is one step of subspace
 * iteration warm-started from the previous right subspace
 *     Y = X V, Q = qr(Y), B = Q^T X = Ub S Vb^T, L = Q Ub S Vb^T,
 * so an outer iteration costs two m x n x l products (l = k + p) instead of a
 * full SVD; as the imputed values settle the subspace converges with them.
 *
 * Imputation converges slowly (linearly, at a rate set by the missing
 * fraction: hd leaves ~38 % of the cells outside the domain and needs
 * thousands of steps).  For k <= SB_ALS_MAX_K a few imputation steps only
 * warm-start alternating least squares on the valid cells,
 *     p_r = argmin sum_{c valid} (a_rc - p_r . q_c)^2,  then the same for q_c,
 * exact block coordinate descent that needs tens of sweeps.  Terms are
 * added one at a time (stage ka refits the first ka jointly), so each prefix
 * of the output is a masked fit of its own rank; sigma_j = |p_j| |q_j| is
 * the scale of term j, not a singular value, and the terms are not
 * orthogonal.
 *
 * A sweep reads the valid cells gathered once per execute in column and in
 * row order (no mask tests; the free factor columns and their outer
 * products are kept row-major, k contiguous values per row or column), so
 * a cell costs k multiply-adds and k(k+1)/2 additions per half-sweep; the
 * fixed terms of a stage are subtracted once, not in every sweep.  The sums
 * run in the order of plain loops over the mask, so the result is the same
 * to the bit as accumulating cell by cell. */
#include "solve/fit.h"

#include <assert.h>
#include <cblas.h>
#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sepbrdf/param.h"
#include "util/internal.h"
#include "util/parallel.h"
#include "util/rng.h"

/* Up to this many terms the fit finishes with alternating least squares
 * (Grams of k x k per row and column); beyond, imputation alone. */
#define SB_ALS_MAX_K 32
/* A joint refit may make a shorter prefix at most this much worse. */
#define SB_PREFIX_SLACK 2.0
/* A taps' constraint may raise the error on the valid cells this much. */
#define SB_TAPS_COST 1.5
/* Stages up to this many terms all refit jointly (joint_stage). */
#define SB_JOINT_ALL 8
/* Joint sweeps that probe the cost of the taps' constraints. */
#define SB_TAPS_PROBE 10
/* Imputation steps that warm-start ALS. */
#define SB_ALS_WARM 4

struct sb_fit {
    sb_context_t *ctx;
    size_t m, n, k, l;
    double *x, *v, *y, *tau, *b, *sb, *ub, *vbt, *work;
    double *P, *Q; /* ALS: factors m x k, n x k */
    /* ALS sweep copies of the free columns, row-major: pt[r*kf + j] =
     * P[r + (j0+j)*m], qt likewise, and their outer products (lower
     * triangles, kt = kf(kf+1)/2 values per row / column) */
    double *pt, *qt, *pp, *qq;
    lapack_int *iwork;
    lapack_int lwork;
};

static double gauss(uint64_t *s) {
    double g[2];
    sb_splitmix_gauss2(s, g); /* deterministic for a seed */
    return g[0];
}

sb_result_t sb_fit_create(sb_context_t *ctx, size_t m, size_t n, size_t k, sb_fit_t **out) {
    *out = NULL;
    size_t mn = m < n ? m : n;
    if (k == 0 || k > mn) return sb_error(ctx, SB_ERR_RANGE, "fit: %zu terms asked, need 1..%zu", k, mn);
    sb_fit_t *f = calloc(1, sizeof *f);
    if (!f) return sb_error(ctx, SB_ERR_NOMEM, "fit: out of memory");
    f->ctx = ctx;
    f->m = m;
    f->n = n;
    f->k = k;
    f->l = k + 10 < mn ? k + 10 : mn;
    size_t l = f->l, cells;
    if (sb_size_mul(m, n, &cells)) {
        free(f);
        return sb_error(ctx, SB_ERR_OVERFLOW, "fit: matrix size overflows");
    }
    f->x = sb_alloc(ctx, cells, sizeof(double), "masked fit");
    f->v = sb_alloc(ctx, n * l, sizeof(double), "masked fit");
    f->y = sb_alloc(ctx, m * l, sizeof(double), "masked fit");
    f->tau = sb_alloc(ctx, l, sizeof(double), "masked fit");
    f->b = sb_alloc(ctx, l * n, sizeof(double), "masked fit");
    f->sb = sb_alloc(ctx, l, sizeof(double), "masked fit");
    f->ub = sb_alloc(ctx, l * l, sizeof(double), "masked fit");
    f->vbt = sb_alloc(ctx, l * n, sizeof(double), "masked fit");
    f->iwork = sb_alloc(ctx, 8 * l, sizeof(lapack_int), "masked fit");
    if (!f->x || !f->v || !f->y || !f->tau || !f->b || !f->sb || !f->ub || !f->vbt || !f->iwork) {
        sb_fit_destroy(f);
        return SB_ERR_NOMEM;
    }
    /* one workspace for dgeqrf, dorgqr and dgesdd: the largest query */
    double q1, q2, q3;
    lapack_int info =
        LAPACKE_dgeqrf_work(LAPACK_COL_MAJOR, (lapack_int)m, (lapack_int)l, f->y, (lapack_int)m, f->tau, &q1, -1);
    info |= LAPACKE_dorgqr_work(LAPACK_COL_MAJOR, (lapack_int)m, (lapack_int)l, (lapack_int)l, f->y, (lapack_int)m,
                                f->tau, &q2, -1);
    info |= LAPACKE_dgesdd_work(LAPACK_COL_MAJOR, 'S', (lapack_int)l, (lapack_int)n, f->b, (lapack_int)l, f->sb, f->ub,
                                (lapack_int)l, f->vbt, (lapack_int)l, &q3, -1, f->iwork);
    if (info != 0) {
        sb_fit_destroy(f);
        return sb_error(ctx, SB_ERR_NUMERIC, "fit: LAPACK workspace query failed");
    }
    double q = fmax(q1, fmax(q2, q3));
    if (k <= SB_ALS_MAX_K) {
        f->P = sb_alloc(ctx, m * k, sizeof(double), "masked fit");
        f->Q = sb_alloc(ctx, n * k, sizeof(double), "masked fit");
        f->pt = sb_alloc(ctx, m * k, sizeof(double), "masked fit");
        f->qt = sb_alloc(ctx, n * k, sizeof(double), "masked fit");
        f->pp = sb_alloc(ctx, m * (k * (k + 1) / 2), sizeof(double), "masked fit");
        f->qq = sb_alloc(ctx, n * (k * (k + 1) / 2), sizeof(double), "masked fit");
        if (!f->P || !f->Q || !f->pt || !f->qt || !f->pp || !f->qq) {
            sb_fit_destroy(f);
            return SB_ERR_NOMEM;
        }
    }
    f->lwork = (lapack_int)q + 1;
    f->work = sb_alloc(ctx, (size_t)f->lwork, sizeof(double), "masked fit");
    if (!f->work) {
        sb_fit_destroy(f);
        return SB_ERR_NOMEM;
    }
    *out = f;
    return SB_OK;
}

void sb_fit_destroy(sb_fit_t *f) {
    if (!f) return;
    free(f->x);
    free(f->v);
    free(f->y);
    free(f->tau);
    free(f->b);
    free(f->sb);
    free(f->ub);
    free(f->vbt);
    free(f->work);
    free(f->iwork);
    free(f->P);
    free(f->Q);
    free(f->pt);
    free(f->qt);
    free(f->pp);
    free(f->qq);
    free(f);
}

/* One subspace step on X: V (n x l) in, rank-l SVD of the projection out
 * (sb, Q Ub in y, Vb^T in vbt); V is replaced by Vb (orthonormal rows). */
static sb_result_t step(sb_fit_t *f) {
    size_t m = f->m, n = f->n, l = f->l;
    cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, (int)m, (int)l, (int)n, 1.0, f->x, (int)m, f->v, (int)n, 0.0,
                f->y, (int)m);
    lapack_int info = LAPACKE_dgeqrf_work(LAPACK_COL_MAJOR, (lapack_int)m, (lapack_int)l, f->y, (lapack_int)m, f->tau,
                                          f->work, f->lwork);
    if (!info)
        info = LAPACKE_dorgqr_work(LAPACK_COL_MAJOR, (lapack_int)m, (lapack_int)l, (lapack_int)l, f->y, (lapack_int)m,
                                   f->tau, f->work, f->lwork);
    if (info) return sb_error(f->ctx, SB_ERR_NUMERIC, "fit: QR failed (info %d)", (int)info);
    cblas_dgemm(CblasColMajor, CblasTrans, CblasNoTrans, (int)l, (int)n, (int)m, 1.0, f->y, (int)m, f->x, (int)m, 0.0,
                f->b, (int)l);
    info = LAPACKE_dgesdd_work(LAPACK_COL_MAJOR, 'S', (lapack_int)l, (lapack_int)n, f->b, (lapack_int)l, f->sb, f->ub,
                               (lapack_int)l, f->vbt, (lapack_int)l, f->work, f->lwork, f->iwork);
    if (info) return sb_error(f->ctx, SB_ERR_NUMERIC, "fit: SVD of the projection failed (info %d)", (int)info);
    /* the next starting subspace is the new right singular basis Vb */
    for (size_t j = 0; j < l; j++)
        for (size_t i = 0; i < n; i++)
            f->v[i + j * n] = f->vbt[j + i * l];
    return SB_OK;
}

/* Solve (G + ridge I) x = b for k x k SPD G in place (Cholesky); ridge
 * keeps rows with fewer than k valid cells well posed. */
static inline void spd_solve(double *G, double *b, size_t k) {
    double tr = 0;
    for (size_t i = 0; i < k; i++)
        tr += G[i * k + i];
    double ridge = 1e-12 * (tr > 0 ? tr / (double)k : 1.0) + 1e-300;
    for (size_t i = 0; i < k; i++)
        G[i * k + i] += ridge;
    for (size_t j = 0; j < k; j++) {
        double d = G[j * k + j];
        for (size_t p = 0; p < j; p++)
            d -= G[j * k + p] * G[j * k + p];
        d = d > 0 ? sqrt(d) : 1e-150;
        G[j * k + j] = d;
        for (size_t i = j + 1; i < k; i++) {
            double v = G[i * k + j];
            for (size_t p = 0; p < j; p++)
                v -= G[i * k + p] * G[j * k + p];
            G[i * k + j] = v / d;
        }
    }
    for (size_t i = 0; i < k; i++) { /* L y = b */
        double v = b[i];
        for (size_t p = 0; p < i; p++)
            v -= G[i * k + p] * b[p];
        b[i] = v / G[i * k + i];
    }
    for (size_t i = k; i-- > 0;) { /* L^T x = y */
        double v = b[i];
        for (size_t p = i + 1; p < k; p++)
            v -= G[p * k + i] * b[p];
        b[i] = v / G[i * k + i];
    }
}

/* The valid cells in both orders, built once per execute so that the sweeps
 * read contiguous memory and test no mask: column c's cells are t in
 * [cp[c], cp[c+1]) with row cr[t] (increasing) and value cv[t]; row r's are
 * t in [rp[r], rp[r+1]) with column rc[t] (increasing) and value rv[t].
 * cres / rres hold the values less the fixed terms (columns < j0) of the
 * current stage, a_rc - sum_{j<j0} P_rj Q_cj, computed once per stage (the
 * fixed terms do not move during its sweeps); they alias cv / rv when
 * j0 = 0.  Every sum runs in the order of the plain loops over the mask
 * (rows: c increasing; columns: r increasing), so the results are the same
 * to the bit. */
typedef struct als_cells {
    size_t *cp, *rp;
    uint32_t *cr, *rc;
    double *cv, *rv, *cbuf, *rbuf;
    const double *cres, *rres;
} als_cells_t;

static void cells_free(als_cells_t *cl) {
    free(cl->cp);
    free(cl->rp);
    free(cl->cr);
    free(cl->rc);
    free(cl->cv);
    free(cl->rv);
    free(cl->cbuf);
    free(cl->rbuf);
}

/* Gather the valid cells of X (m x n, ld lda) in both orders; 0 or
 * SB_ERR_NOMEM. */
static int cells_build(sb_context_t *ctx, als_cells_t *cl, const double *X, size_t m, size_t n, size_t lda,
                       const unsigned char *mask, size_t nvalid) {
    /* ~40 bytes per valid cell: through sb_alloc, so the memory limit holds */
    static const char what[] = "masked fit: gathered cells";
    memset(cl, 0, sizeof *cl);
    cl->cp = sb_alloc(ctx, n + 1, sizeof *cl->cp, what);
    cl->rp = sb_calloc(ctx, m + 1, sizeof *cl->rp, what);
    cl->cr = sb_alloc(ctx, nvalid, sizeof *cl->cr, what);
    cl->rc = sb_alloc(ctx, nvalid, sizeof *cl->rc, what);
    cl->cv = sb_alloc(ctx, nvalid, sizeof *cl->cv, what);
    cl->rv = sb_alloc(ctx, nvalid, sizeof *cl->rv, what);
    cl->cbuf = sb_alloc(ctx, nvalid, sizeof *cl->cbuf, what);
    cl->rbuf = sb_alloc(ctx, nvalid, sizeof *cl->rbuf, what);
    if (!cl->cp || !cl->rp || !cl->cr || !cl->rc || !cl->cv || !cl->rv || !cl->cbuf || !cl->rbuf) {
        cells_free(cl);
        return SB_ERR_NOMEM;
    }
    /* column order; count each row's cells on the way */
    size_t t = 0;
    for (size_t c = 0; c < n; c++) {
        cl->cp[c] = t;
        for (size_t r = 0; r < m; r++)
            if (mask[r + c * lda]) {
                cl->cr[t] = (uint32_t)r;
                cl->cv[t++] = X[r + c * lda];
                cl->rp[r + 1]++;
            }
    }
    cl->cp[n] = t;
    assert(t == nvalid);
    /* row order: prefix sums, then a scatter in column order keeps each
     * row's columns increasing */
    for (size_t r = 0; r < m; r++)
        cl->rp[r + 1] += cl->rp[r];
    size_t *next = malloc(m * sizeof *next);
    if (!next) {
        cells_free(cl);
        return sb_error(ctx, SB_ERR_NOMEM, "masked fit: cannot allocate %zu bytes", m * sizeof *next);
    }
    memcpy(next, cl->rp, m * sizeof *next);
    for (size_t c = 0; c < n; c++)
        for (size_t u = cl->cp[c]; u < cl->cp[c + 1]; u++) {
            size_t at = next[cl->cr[u]]++;
            cl->rc[at] = (uint32_t)c;
            cl->rv[at] = cl->cv[u];
        }
    free(next);
    cl->cres = cl->cv;
    cl->rres = cl->rv;
    return 0;
}

/* The data less the fixed terms 0..j0-1, in both orders (aliases of the
 * data for j0 = 0). */
static void cells_residual(als_cells_t *cl, const sb_fit_t *f, size_t j0) {
    size_t m = f->m, n = f->n;
    const double *P = f->P, *Q = f->Q;
    if (j0 == 0) {
        cl->cres = cl->cv;
        cl->rres = cl->rv;
        return;
    }
    for (size_t c = 0; c < n; c++)
        for (size_t t = cl->cp[c]; t < cl->cp[c + 1]; t++) {
            double a = cl->cv[t];
            for (size_t j = 0; j < j0; j++)
                a -= P[cl->cr[t] + j * m] * Q[c + j * n];
            cl->cbuf[t] = a;
        }
    for (size_t r = 0; r < m; r++)
        for (size_t t = cl->rp[r]; t < cl->rp[r + 1]; t++) {
            double a = cl->rv[t];
            for (size_t j = 0; j < j0; j++)
                a -= P[r + j * m] * Q[cl->rc[t] + j * n];
            cl->rbuf[t] = a;
        }
    cl->cres = cl->cbuf;
    cl->rres = cl->rbuf;
}

/* x (k values) and its outer product's lower triangle, row by row
 * (x_0 x_0, x_1 x_0, x_1 x_1, x_2 x_0, ...), to row-major copies. */
static inline void put_row(double *xt, double *xx, const double *x, size_t k) {
    for (size_t i = 0; i < k; i++) {
        xt[i] = x[i];
        for (size_t j = 0; j <= i; j++)
            *xx++ = x[i] * x[j];
    }
}

/* One least-squares update from the cells t0..t1-1 of a row (column):
 * with x_i, xx_i the fixed side's row-major factor and packed outer
 * product at the cell's other index idx[t], solve
 *     (sum_t xx_{idx[t]}) y = sum_t a_t x_{idx[t]}
 * for y (kf values) by spd_solve, the sums in the order of t. */
static inline void ls_update(const uint32_t *idx, const double *a, size_t t0, size_t t1, const double *xt,
                             const double *xx, size_t kf, double *y) {
    size_t kt = kf * (kf + 1) / 2;
    /* local accumulators: y may not alias what the loop reads */
    double g[SB_ALS_MAX_K * (SB_ALS_MAX_K + 1) / 2], b[SB_ALS_MAX_K], G[SB_ALS_MAX_K * SB_ALS_MAX_K];
    memset(g, 0, kt * sizeof *g);
    memset(b, 0, kf * sizeof *b);
    for (size_t t = t0; t < t1; t++) {
        const double *x = xt + idx[t] * kf, *x2 = xx + idx[t] * kt;
        double v = a[t];
        for (size_t i = 0; i < kf; i++)
            b[i] += v * x[i];
        for (size_t i = 0; i < kt; i++)
            g[i] += x2[i];
    }
    for (size_t i = 0, at = 0; i < kf; i++)
        for (size_t j = 0; j <= i; j++, at++)
            G[i * kf + j] = G[j * kf + i] = g[at];
    spd_solve(G, b, kf);
    memcpy(y, b, kf * sizeof *y);
}

/* One ALS sweep over the free columns j0..ka-1 of P and Q (columns below j0
 * stay fixed and are subtracted from the data): rows (P given Q), then
 * columns (Q given P).  Returns the squared error of all ka terms on the
 * valid cells after the sweep.  Each half is split among threads by rows /
 * columns: every thread owns the outputs of its range.  The Grams are sums
 * of the precomputed outer products q_c q_c^T (p_r p_r^T): a cell costs
 * k(k+1)/2 additions and k multiply-adds. */
typedef struct als_job {
    sb_fit_t *f;
    const als_cells_t *cl;
    size_t j0, ka, lo, hi;
    double e2;
} als_job_t;

/* The row half for kf = ka - j0 free terms (inlined with kf constant):
 * p_r from G_r = sum_c q_c q_c^T, b_r = sum_c a_rc q_c over the valid c. */
static inline void rows_k(const als_job_t *jb, size_t kf) {
    sb_fit_t *f = jb->f;
    const als_cells_t *cl = jb->cl;
    size_t m = f->m, j0 = jb->j0, kt = kf * (kf + 1) / 2;
    for (size_t r = jb->lo; r < jb->hi; r++) {
        double p[SB_ALS_MAX_K];
        ls_update(cl->rc, cl->rres, cl->rp[r], cl->rp[r + 1], f->qt, f->qq, kf, p);
        for (size_t j = 0; j < kf; j++)
            f->P[r + (j0 + j) * m] = p[j];
        put_row(f->pt + r * kf, f->pp + r * kt, p, kf);
    }
}

/* The column half, then the error of column c with its new q_c. */
static inline void cols_k(als_job_t *jb, size_t kf) {
    sb_fit_t *f = jb->f;
    const als_cells_t *cl = jb->cl;
    size_t n = f->n, j0 = jb->j0;
    double e2 = 0;
    for (size_t c = jb->lo; c < jb->hi; c++) {
        double q[SB_ALS_MAX_K];
        size_t t0 = cl->cp[c], t1 = cl->cp[c + 1];
        ls_update(cl->cr, cl->cres, t0, t1, f->pt, f->pp, kf, q);
        for (size_t j = 0; j < kf; j++)
            f->Q[c + (j0 + j) * n] = q[j];
        for (size_t t = t0; t < t1; t++) {
            const double *p = f->pt + cl->cr[t] * kf;
            double d = cl->cres[t];
            for (size_t j = 0; j < kf; j++)
                d -= p[j] * q[j];
            e2 += d * d;
        }
    }
    jb->e2 = e2;
}

/* Dispatch on the number of free terms: the common small counts get loops
 * of constant length. */
#define SB_ALS_DISPATCH(fn, jb)                                                                                        \
    switch ((jb)->ka - (jb)->j0) {                                                                                     \
    case 1:                                                                                                            \
        fn(jb, 1);                                                                                                     \
        break;                                                                                                         \
    case 2:                                                                                                            \
        fn(jb, 2);                                                                                                     \
        break;                                                                                                         \
    case 3:                                                                                                            \
        fn(jb, 3);                                                                                                     \
        break;                                                                                                         \
    case 4:                                                                                                            \
        fn(jb, 4);                                                                                                     \
        break;                                                                                                         \
    default:                                                                                                           \
        fn(jb, (jb)->ka - (jb)->j0);                                                                                   \
        break;                                                                                                         \
    }

static void *als_rows(void *arg) {
    als_job_t *jb = arg;
    SB_ALS_DISPATCH(rows_k, jb);
    return NULL;
}

static void *als_cols(void *arg) {
    als_job_t *jb = arg;
    SB_ALS_DISPATCH(cols_k, jb);
    return NULL;
}

/* Run fn on [0, n) split among threads (the caller's included). */
static void als_parallel(void *(*fn)(void *), als_job_t *proto, size_t n, double *e2) {
    /* small: not worth a thread */
    int nt = sb_threads_for(0, n, proto->f->m * proto->f->n, (size_t)1 << 16);
    als_job_t jobs[SB_THREADS_MAX];
    for (int t = 0; t < nt; t++) {
        jobs[t] = *proto;
        sb_part(n, t, nt, &jobs[t].lo, &jobs[t].hi);
        jobs[t].e2 = 0;
    }
    sb_parallel_run(fn, jobs, sizeof *jobs, nt, NULL, NULL);
    if (e2) {
        *e2 = 0;
        for (int t = 0; t < nt; t++)
            *e2 += jobs[t].e2; /* fixed order: deterministic */
    }
}

static double als_sweep(sb_fit_t *f, const als_cells_t *cl, size_t j0, size_t ka) {
    als_job_t proto = {f, cl, j0, ka, 0, 0, 0};
    size_t kf = ka - j0, kt = kf * (kf + 1) / 2;
    double e2;
    for (size_t c = 0; c < f->n; c++) {
        double q[SB_ALS_MAX_K];
        for (size_t j = 0; j < kf; j++)
            q[j] = f->Q[c + (j0 + j) * f->n];
        put_row(f->qt + c * kf, f->qq + c * kt, q, kf);
    }
    als_parallel(als_rows, &proto, f->m, NULL);
    als_parallel(als_cols, &proto, f->n, &e2);
    return e2;
}

/* Squared error on valid cells of each prefix of the first ka terms:
 * e2[j] for the terms 0..j. */
static void prefix_errors(const sb_fit_t *f, const als_cells_t *cl, size_t ka, double *e2) {
    size_t m = f->m, n = f->n;
    for (size_t j = 0; j < ka; j++)
        e2[j] = 0;
    for (size_t c = 0; c < n; c++)
        for (size_t t = cl->cp[c]; t < cl->cp[c + 1]; t++) {
            size_t r = cl->cr[t];
            double d = cl->cv[t];
            for (size_t j = 0; j < ka; j++) {
                d -= f->P[r + j * m] * f->Q[c + j * n];
                e2[j] += d * d;
            }
        }
}

/* ALS sweeps on columns j0..ka-1 until the error stops improving. */
static double als_until(sb_fit_t *f, als_cells_t *cl, size_t j0, size_t ka, const sb_fit_opts_t *o, double norm,
                        int *sweeps, int *converged) {
    double prev = INFINITY, err = 0;
    cells_residual(cl, f, j0);
    for (int stage = 1;; stage++) {
        (*sweeps)++;
        err = sqrt(als_sweep(f, cl, j0, ka));
        if (err <= 1e-15 * norm || (isfinite(prev) && prev - err <= o->tol * prev)) break;
        if (stage >= o->max_iters) {
            *converged = 0;
            break;
        }
        prev = err;
    }
    return err;
}

/* Whether stage ka refits its terms jointly: every stage up to
 * SB_JOINT_ALL terms, beyond only at powers of two and the last (a joint
 * sweep costs ka^2 per cell, and terms past the first few change the
 * error little; the stages between add their term on the residual, which
 * keeps every prefix's error non-increasing). */
static int joint_stage(size_t ka, size_t k) { return ka > 1 && (ka <= SB_JOINT_ALL || ka == k || !(ka & (ka - 1))); }

/* The staged ALS from the warm start in f->P, f->Q on the cells of X with
 * mask != 0 (nvalid of them); *err the last stage's error; *stretched 1
 * when the last stage kept a joint refit that made a shorter prefix more
 * than SB_PREFIX_SLACK times worse (not strict only); *converged 0
 * when the run that gave the last stage's kept result stopped at
 * max_iters (earlier stages only warm-start the later ones).  SB_OK or
 * SB_ERR_NOMEM. */
static sb_result_t als_stages(sb_fit_t *f, const double *As, size_t lda, const unsigned char *mask, size_t nvalid,
                              const sb_fit_opts_t *o, int strict, double norm2, int *total, int *converged, double *err,
                              int *stretched) {
    size_t m = f->m, n = f->n, k = f->k;
    /* Nested stages: terms are added one at a time and the first ka
     * are refitted jointly, so every prefix of the result is itself a
     * masked fit of its rank (the terms are not re-orthogonalised over
     * the whole matrix: that would mix in the unconstrained values the
     * fit implies outside the domain). */
    double acc[SB_ALS_MAX_K], e2[SB_ALS_MAX_K]; /* accepted prefix errors */
    double *saveP = malloc(m * k * sizeof *saveP), *saveQ = malloc(n * k * sizeof *saveQ);
    als_cells_t cl;
    if (!saveP || !saveQ || cells_build(f->ctx, &cl, As, m, n, lda, mask, nvalid) != 0) {
        int saved = saveP && saveQ; /* else cells_build failed and named its bytes */
        free(saveP);
        free(saveQ);
        if (saved) return SB_ERR_NOMEM;
        return sb_error(f->ctx, SB_ERR_NOMEM, "fit: cannot allocate %zu bytes", (m + n) * k * sizeof(double));
    }
    for (size_t ka = 1; ka <= k; ka++) {
        /* first the new term alone on the residual of the others: the
         * error can only go down (its first half-sweep is a least-squares
         * step from the warm start) */
        int c1 = 1, cj = 1, keep = 0;
        *err = als_until(f, &cl, ka - 1, ka, o, sqrt(norm2), total, &c1);
        if (joint_stage(ka, k)) {
            /* then all ka jointly: a joint refit may trade the prefixes'
             * accuracy for cancelling terms that are large outside the
             * domain, which also spoil interpolated lookups near its
             * edge */
            memcpy(saveP, f->P, m * ka * sizeof *saveP);
            memcpy(saveQ, f->Q, n * ka * sizeof *saveQ);
            double ej = als_until(f, &cl, 0, ka, o, sqrt(norm2), total, &cj);
            prefix_errors(f, &cl, ka, e2);
            /* kept only if no shorter prefix gets more than
             * SB_PREFIX_SLACK times worse (at the last stage: no worse than
             * no term at all); strict: and the prefixes' errors stay
             * non-increasing */
            keep = ej <= *err;
            double slack = ka == k && !strict ? INFINITY : SB_PREFIX_SLACK;
            int within = 1;
            for (size_t j = 0; keep && j + 1 < ka; j++) {
                keep = sqrt(e2[j]) <= fmin(acc[j] * slack, sqrt(norm2)) && (!strict || e2[j + 1] <= e2[j]);
                within &= sqrt(e2[j]) <= acc[j] * SB_PREFIX_SLACK;
            }
            if (keep && !within) *stretched = 1;
            if (keep) {
                *err = ej;
                for (size_t j = 0; j + 1 < ka; j++)
                    acc[j] = fmax(acc[j], sqrt(e2[j]));
            } else {
                memcpy(f->P, saveP, m * ka * sizeof *saveP);
                memcpy(f->Q, saveQ, n * ka * sizeof *saveQ);
            }
        }
        acc[ka - 1] = *err;
        *converged = keep ? cj : c1;
        if (o->target > 0 && *err <= o->target * sqrt(norm2)) { /* --max-error reached: stop adding terms */
            memset(f->P + ka * m, 0, (k - ka) * m * sizeof *f->P);
            memset(f->Q + ka * n, 0, (k - ka) * n * sizeof *f->Q);
            break;
        }
    }
    free(saveP);
    free(saveQ);
    cells_free(&cl);
    return SB_OK;
}

/* Squared errors of the prefixes on the valid cells (mask) of X: e2[j]
 * after the terms 0..j. */
static void valid_prefix_e2(const sb_fit_t *f, const double *X, size_t lda, const unsigned char *mask, double *e2) {
    size_t m = f->m, n = f->n, k = f->k;
    for (size_t j = 0; j < k; j++)
        e2[j] = 0;
    for (size_t c = 0; c < n; c++)
        for (size_t r = 0; r < m; r++) {
            if (!mask[r + c * lda]) continue;
            double d = X[r + c * lda];
            for (size_t j = 0; j < k; j++) {
                d -= f->P[r + j * m] * f->Q[c + j * n];
                e2[j] += d * d;
            }
        }
}

static int prefixes_monotone(const sb_fit_t *f, const double *X, size_t lda, const unsigned char *mask) {
    double e2[SB_ALS_MAX_K];
    valid_prefix_e2(f, X, lda, mask, e2);
    for (size_t j = 1; j < f->k; j++)
        if (e2[j] > e2[j - 1]) return 0;
    return 1;
}

/* Texels within two steps of texel i (x +- 2, y +- 2: the cell holding an
 * in-domain pair may be one away from a valid centre, its taps one more;
 * CLAMP axes stop at the edge, REPEAT axes wrap), i included, each once. */
static size_t neighbours(const size_t wh[2], const int wrap[2], size_t i, size_t out[25]) {
    size_t w = wh[0], h = wh[1], k = 0;
    long x = (long)(i % w), y = (long)(i / w);
    for (long dy = -2; dy <= 2; dy++)
        for (long dx = -2; dx <= 2; dx++) {
            long xs = x + dx, ys = y + dy;
            if (wrap[0] == SB_WRAP_REPEAT) xs = (xs + (long)w) % (long)w;
            if (wrap[1] == SB_WRAP_REPEAT) ys = (ys + (long)h) % (long)h;
            if (xs < 0 || ys < 0 || xs >= (long)w || ys >= (long)h) continue;
            size_t at = (size_t)ys * w + (size_t)xs, dup = 0;
            for (size_t q = 0; q < k; q++)
                dup |= out[q] == at;
            if (!dup) out[k++] = at;
        }
    return k;
}

/* Cells that bilinear taps of in-domain pairs reach, kept bounded by the
 * data around them: an invalid cell (r, c) with valid cells among rows N(r)
 * x columns N(c) (lo..hi their values in x) whose fitted value
 * sum_j P_rj Q_cj lies outside [lo - d, hi + d], d = hi - lo +
 * max(|lo|, |hi|) / 2, joins the data (ext = 2) with the value clamped
 * into [lo, hi]; cells already joined keep their targets.  (Joining every
 * such cell, or pulling it to its neighbours' mean, fits the data worse
 * and breaks exact recovery of low-rank data with holes.)  Per column the
 * column neighbours are reduced first, then the row neighbours: 50 reads
 * per cell.  Returns the cells added, or (size_t)-1 without memory. */
static size_t constrain_taps(const sb_fit_opts_t *o, const sb_fit_t *f, double *x, unsigned char *ext) {
    size_t m = f->m, n = f->n, k = f->k, added = 0;
    double *lo1 = malloc(m * sizeof *lo1), *hi1 = malloc(m * sizeof *hi1);
    if (!lo1 || !hi1) {
        free(lo1);
        free(hi1);
        return (size_t)-1;
    }
    for (size_t c = 0; c < n; c++) {
        size_t nc[25], nr[25], kc = neighbours(o->tex[1], o->wrap[1], c, nc);
        for (size_t r = 0; r < m; r++) {
            lo1[r] = INFINITY;
            hi1[r] = -INFINITY;
            for (size_t q = 0; q < kc; q++)
                if (ext[r + nc[q] * m] == 1) {
                    lo1[r] = fmin(lo1[r], x[r + nc[q] * m]);
                    hi1[r] = fmax(hi1[r], x[r + nc[q] * m]);
                }
        }
        for (size_t r = 0; r < m; r++) {
            if (ext[r + c * m]) continue;
            size_t kr = neighbours(o->tex[0], o->wrap[0], r, nr);
            double lo = INFINITY, hi = -INFINITY, v = 0;
            for (size_t q = 0; q < kr; q++) {
                lo = fmin(lo, lo1[nr[q]]);
                hi = fmax(hi, hi1[nr[q]]);
            }
            if (!(lo <= hi)) continue;
            for (size_t j = 0; j < k; j++)
                v += f->P[r + j * m] * f->Q[c + j * n];
            double d = hi - lo + 0.5 * fmax(fabs(lo), fabs(hi));
            if (v >= lo - d && v <= hi + d) continue;
            x[r + c * m] = fmin(fmax(v, lo), hi);
            ext[r + c * m] = 2; /* data from now on, not a neighbour's source */
            added++;
        }
    }
    free(lo1);
    free(hi1);
    return added;
}

/* Whether the fit costs the valid cells (mask) more than SB_TAPS_COST
 * times the squared error `before` the taps' constraints. */
static int taps_cost(const sb_fit_t *f, const double *As, size_t lda, const unsigned char *mask, double before,
                     double norm2) {
    double e2[SB_ALS_MAX_K];
    valid_prefix_e2(f, As, lda, mask, e2);
    return sqrt(e2[f->k - 1]) > SB_TAPS_COST * sqrt(before) + 1e-12 * sqrt(norm2);
}

/* SB_TAPS_PROBE joint sweeps of all k terms on the cells with ext != 0. */
static sb_result_t taps_probe(sb_fit_t *f, const double *As, size_t lda, const unsigned char *ext, size_t nvalid,
                              const sb_fit_opts_t *o, int *total) {
    als_cells_t cl;
    if (cells_build(f->ctx, &cl, As, f->m, f->n, lda, ext, nvalid) != 0) return SB_ERR_NOMEM;
    sb_fit_opts_t po = *o;
    int converged = 1;
    po.max_iters = SB_TAPS_PROBE;
    cells_residual(&cl, f, 0);
    als_until(f, &cl, 0, f->k, &po, 0, total, &converged);
    cells_free(&cl);
    return SB_OK;
}

/* The ALS part of a fit from the warm start in f->P, f->Q: the stages
 * (joint refits kept under SB_PREFIX_SLACK), the taps' constraints
 * (constrain_taps, twice at most, warm), and when the prefixes' errors on
 * the valid cells then rise anywhere, or the last stage made a prefix more
 * than SB_PREFIX_SLACK times worse, all of it again from the same start
 * with strict stages (a joint refit kept only if the prefixes' errors stay
 * non-increasing), so that every prefix is a fit no worse than the shorter
 * ones.  SB_OK or SB_ERR_NOMEM. */
static sb_result_t als_fit(sb_fit_t *f, const double *As, size_t lda, const unsigned char *mask, size_t nvalid0,
                           const sb_fit_opts_t *o, double norm2, int *total, int *converged, double *err) {
    size_t m = f->m, n = f->n, k = f->k;
    int taps = lda == m && o->tex[0][0] * o->tex[0][1] == m && o->tex[1][0] * o->tex[1][1] == n;
    unsigned char *ext = taps ? malloc(m * n) : NULL;
    double *P0 = malloc(m * k * sizeof *P0), *Q0 = malloc(n * k * sizeof *Q0);
    double *P1 = malloc(m * k * sizeof *P1), *Q1 = malloc(n * k * sizeof *Q1);
    double *P2 = malloc(m * k * sizeof *P2), *Q2 = malloc(n * k * sizeof *Q2);
    sb_result_t r = SB_OK;
    if ((taps && !ext) || !P0 || !Q0 || !P1 || !Q1 || !P2 || !Q2)
        r = sb_error(f->ctx, SB_ERR_NOMEM, "fit: cannot allocate %zu bytes", m * n + 3 * (m + n) * k * sizeof(double));
    if (r == SB_OK) {
        memcpy(P0, f->P, m * k * sizeof *P0);
        memcpy(Q0, f->Q, n * k * sizeof *Q0);
    }
    for (int strict = 0; strict < 2 && r == SB_OK; strict++) {
        size_t nvalid = nvalid0;
        int stretched = 0;
        memcpy(f->P, P0, m * k * sizeof *P0);
        memcpy(f->Q, Q0, n * k * sizeof *Q0);
        if (ext)
            for (size_t c = 0; c < n; c++)
                for (size_t i = 0; i < m; i++)
                    ext[i + c * m] = mask[i + c * lda] ? 1 : 0;
        r = als_stages(f, As, lda, mask, nvalid, o, strict, norm2, total, converged, err, &stretched);
        /* taps reaching unconstrained cells that overshoot: constrain
         * them and run the stages again from the fit found (twice at
         * most; warm, each stage stops after a few sweeps) */
        double e2[SB_ALS_MAX_K], before = 0;
        if (taps) {
            valid_prefix_e2(f, As, lda, mask, e2);
            before = e2[k - 1];
            memcpy(P1, f->P, m * k * sizeof *P1);
            memcpy(Q1, f->Q, n * k * sizeof *Q1);
        }
        size_t constrained = 0;
        for (int round = 0; r == SB_OK && taps && round < 2; round++) {
            size_t added = constrain_taps(o, f, f->x, ext); /* taps: As is f->x */
            if (added == (size_t)-1) r = SB_ERR_NOMEM;
            if (added == 0 || r != SB_OK) break;
            nvalid += added;
            constrained += added;
            /* a few joint sweeps first, from a copy: constraints that
             * already cost the valid cells more than SB_TAPS_COST there are
             * dropped without the staged refit (which would not do better) */
            memcpy(P2, f->P, m * k * sizeof *P2);
            memcpy(Q2, f->Q, n * k * sizeof *Q2);
            r = taps_probe(f, As, lda, ext, nvalid, o, total);
            if (r == SB_OK && taps_cost(f, As, lda, mask, before, norm2)) break;
            memcpy(f->P, P2, m * k * sizeof *P2); /* the stages start where the probe did */
            memcpy(f->Q, Q2, n * k * sizeof *Q2);
            if (r == SB_OK)
                r = als_stages(f, As, lda, ext, nvalid, o, strict, norm2, total, converged, err, &stretched);
            if (r == SB_OK && taps_cost(f, As, lda, mask, before, norm2)) break;
        }
        /* data that the rank-k structure extends exactly (or nearly) are
         * their own best extrapolation: a constraint that costs the valid
         * cells more than SB_TAPS_COST in error is dropped */
        if (r == SB_OK && constrained) {
            if (taps_cost(f, As, lda, mask, before, norm2)) {
                memcpy(f->P, P1, m * k * sizeof *P1);
                memcpy(f->Q, Q1, n * k * sizeof *Q1);
            }
        }
        if (r != SB_OK || (!stretched && prefixes_monotone(f, As, lda, mask))) break;
    }
    free(ext);
    free(P0);
    free(Q0);
    free(P1);
    free(Q1);
    free(P2);
    free(Q2);
    return r;
}

sb_result_t sb_fit_execute(sb_fit_t *f, const double *A, size_t lda, const unsigned char *mask,
                           const sb_fit_opts_t *opts, double *s, double *U, double *V, sb_fit_info_t *info) {
    size_t m = f->m, n = f->n, k = f->k, l = f->l;
    sb_fit_opts_t o = {0};
    if (opts) o = *opts;
    if (o.max_iters <= 0) o.max_iters = 300;
    if (o.tol <= 0) o.tol = 1e-5;
    /* X: data on valid cells; invalid cells start at the mean of the valid
     * cells of their column (far fewer iterations than starting at 0, which
     * drags the fit towards zero near the domain's edge).  X is A times a
     * power of two pw (exact) that brings max |A| near 1, so that no sum of
     * squares underflows or overflows (1e-300 data stopped after one
     * iteration as "converged", 1e300 data failed as non-finite); the ALS
     * stages read the valid cells of X (same layout as A when lda == m, as
     * the plan passes) and sigma is divided by pw at the end. */
    double amax = 0, pw;
    for (size_t c = 0; c < n && lda == m; c++)
        for (size_t r = 0; r < m; r++)
            if (mask[r + c * lda]) amax = fmax(amax, fabs(A[r + c * lda]));
    pw = sb_pow2_scale(amax);
    const double *As = lda == m ? f->x : A; /* what the ALS stages read */
    double norm2 = 0;
    size_t ninvalid = 0;
    for (size_t c = 0; c < n; c++) {
        double sum = 0;
        size_t cnt = 0;
        for (size_t r = 0; r < m; r++)
            if (mask[r + c * lda]) {
                sum += A[r + c * lda] * pw;
                cnt++;
            }
        double fill = cnt ? sum / (double)cnt : 0.0;
        for (size_t r = 0; r < m; r++) {
            size_t at = r + c * m;
            int ok = mask[r + c * lda];
            double a = ok ? A[r + c * lda] * pw : fill;
            f->x[at] = a;
            if (ok) norm2 += a * a;
            ninvalid += !ok;
        }
    }
    uint64_t seed = o.seed ? o.seed : 1;
    for (size_t i = 0; i < n * l; i++)
        f->v[i] = gauss(&seed);
    double prev = INFINITY, err = 0;
    int it;
    double *qu = malloc(m * k * sizeof *qu); /* Q Ub[:, :k] */
    double *coef = malloc(k * sizeof *coef);
    if (!qu || !coef) {
        free(qu);
        free(coef);
        return sb_error(f->ctx, SB_ERR_NOMEM, "fit: cannot allocate %zu bytes", (m + 1) * k * sizeof(double));
    }
    sb_result_t r = SB_OK;
    int use_als = f->P != NULL && ninvalid > 0;
    int em_iters = use_als ? (o.max_iters < SB_ALS_WARM ? o.max_iters : SB_ALS_WARM) : o.max_iters;
    for (it = 1; it <= em_iters; it++) {
        if ((r = step(f)) != SB_OK) break;
        cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, (int)m, (int)k, (int)l, 1.0, f->y, (int)m, f->ub, (int)l,
                    0.0, qu, (int)m);
        /* impute the invalid cells with L = qu diag(s) Vb^T and measure the
         * error on the valid ones */
        double e2 = 0;
        for (size_t c = 0; c < n; c++) {
            for (size_t j = 0; j < k; j++)
                coef[j] = f->sb[j] * f->vbt[j + c * l];
            for (size_t r2 = 0; r2 < m; r2++) {
                size_t at = r2 + c * m;
                double lv = 0;
                for (size_t j = 0; j < k; j++)
                    lv += qu[r2 + j * m] * coef[j];
                if (mask[r2 + c * lda]) {
                    double d = f->x[at] - lv;
                    e2 += d * d;
                } else {
                    f->x[at] = lv;
                }
            }
        }
        err = sqrt(e2);
        if (ninvalid == 0) break;
        if (err <= 1e-15 * sqrt(norm2) || (it >= 5 && prev - err <= o.tol * prev)) break;
        prev = err;
    }
    if (r == SB_OK && use_als) {
        /* P = qu diag(sqrt s), Q = Vb^T' diag(sqrt s), then sweeps */
        for (size_t j = 0; j < k; j++) {
            double rt = sqrt(f->sb[j] > 0 ? f->sb[j] : 0);
            for (size_t i = 0; i < m; i++)
                f->P[i + j * m] = qu[i + j * m] * rt;
            for (size_t i = 0; i < n; i++)
                f->Q[i + j * n] = f->vbt[j + i * l] * rt;
        }
        int total = it > em_iters ? em_iters : it, converged = 1;
        r = als_fit(f, As, lda, mask, m * n - ninvalid, &o, norm2, &total, &converged, &err);
        if (r != SB_OK) {
            free(qu);
            free(coef);
            return r; /* als_fit and the gathered cells named the bytes */
        }
        /* sigma_j = |p_j| |q_j|, u_j = p_j / |p_j|, v_j = q_j / |q_j| */
        for (size_t j = 0; j < k; j++) {
            double np = cblas_dnrm2((int)m, f->P + j * m, 1), nq = cblas_dnrm2((int)n, f->Q + j * n, 1);
            s[j] = np * nq / pw;
            for (size_t i = 0; i < m && U; i++)
                U[i + j * m] = np > 0 ? f->P[i + j * m] / np : 0;
            for (size_t i = 0; i < n && V; i++)
                V[i + j * n] = nq > 0 ? f->Q[i + j * n] / nq : 0;
        }
        if (info) {
            info->iterations = total;
            info->rel_err = norm2 > 0 ? err / sqrt(norm2) : 0;
            info->converged = converged;
        }
        free(qu);
        free(coef);
        return r;
    }
    if (r == SB_OK) {
        for (size_t j = 0; j < k; j++)
            s[j] = f->sb[j] / pw;
        if (U) memcpy(U, qu, m * k * sizeof *U);
        if (V)
            for (size_t j = 0; j < k; j++)
                for (size_t i = 0; i < n; i++)
                    V[i + j * n] = f->vbt[j + i * l];
        if (info) {
            info->iterations = it > o.max_iters ? o.max_iters : it;
            info->rel_err = norm2 > 0 ? err / sqrt(norm2) : 0;
            info->converged = it <= o.max_iters;
        }
    }
    free(qu);
    free(coef);
    return r;
}
