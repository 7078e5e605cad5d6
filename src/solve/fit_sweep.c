/* Masked fit, part 2a (fit.c has the whole picture): one sweep of
 * alternating least squares on the valid cells (gathered once per execute
 * in both orders by fit_cells.c), and the sweeps of a stage until its
 * error stops improving. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "solve/fit_impl.h"
#include "util/chol.h"
#include "util/internal.h"
#include "util/parallel.h"

/* Solve (G + ridge I) x = b for k x k SPD G in place (Cholesky); ridge
 * keeps rows with fewer than k valid cells well posed. */
static inline void spd_solve(double *G, double *b, size_t k) {
    double tr = 0;
    for (size_t i = 0; i < k; i++)
        tr += G[i * k + i];
    double ridge = 1e-12 * (tr > 0 ? tr / (double)k : 1.0) + 1e-300;
    for (size_t i = 0; i < k; i++)
        G[i * k + i] += ridge;
    sb_chol(G, k, 1e-150);
    sb_chol_solve(G, k, b, 1);
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

/* The normal equations of one least-squares update from the cells
 * t0..t1-1 of a row (column): with x_i, xx_i the fixed side's row-major
 * factor and packed outer product at the cell's other index idx[t],
 *     (sum_t xx_{idx[t]}) y = sum_t a_t x_{idx[t]},
 * the Gram packed into g (kt values) and the right-hand side into b (kf),
 * the sums in the order of t.  Where the cells left out (out[u],
 * u0..u1-1) are fewer, the Gram is `all` (the sum of every xx) less
 * theirs: a kt-vector sum per cell out instead of per cell in (the
 * default's iso cells are 75 % in: 19 % fewer instructions here), no
 * worse than 2 eps |all| / |Gram| in rounding while they are fewer. */
static inline __attribute__((always_inline)) void ls_gram(const uint32_t *idx, const double *a, size_t t0, size_t t1,
                                                          const uint32_t *out, size_t u0, size_t u1, const double *all,
                                                          const double *xt, const double *xx, size_t kf,
                                                          const double *bx, size_t bs, double *g, double *b) {
    size_t kt = kf * (kf + 1) / 2;
    memset(b, 0, kf * sizeof *b);
    if (bx) /* the right-hand side from the dense product (als_sweep) */
        for (size_t i = 0; i < kf; i++)
            b[i] = bx[i * bs];
    if (u1 - u0 < t1 - t0) {
        for (size_t i = 0; i < kt; i++)
            g[i] = all[i];
        for (size_t u = u0; u < u1; u++) {
            const double *x2 = xx + out[u] * kt;
            for (size_t i = 0; i < kt; i++)
                g[i] -= x2[i];
        }
        for (size_t t = t0; t < t1 && !bx; t++) {
            const double *x = xt + idx[t] * kf;
            double v = a[t];
            for (size_t i = 0; i < kf; i++)
                b[i] += v * x[i];
        }
    } else if (bx) {
        for (size_t i = 0; i < kt; i++)
            g[i] = 0;
        for (size_t t = t0; t < t1; t++) {
            const double *x2 = xx + idx[t] * kt;
            for (size_t i = 0; i < kt; i++)
                g[i] += x2[i];
        }
    } else {
        for (size_t i = 0; i < kt; i++)
            g[i] = 0;
        for (size_t t = t0; t < t1; t++) {
            const double *x = xt + idx[t] * kf, *x2 = xx + idx[t] * kt;
            double v = a[t];
            for (size_t i = 0; i < kf; i++)
                b[i] += v * x[i];
            for (size_t i = 0; i < kt; i++)
                g[i] += x2[i];
        }
    }
}

/* Solve them (spd_solve) into y; quad (where given): y^T Gram y - 2 y . b,
 * from the packed Gram. */
static inline __attribute__((always_inline)) void ls_solve(const double *g, const double *b, size_t kf, double *y,
                                                           double *quad) {
    double G[SB_ALS_MAX_K * SB_ALS_MAX_K], x[SB_ALS_MAX_K];
    for (size_t i = 0, at = 0; i < kf; i++)
        for (size_t j = 0; j <= i; j++, at++)
            G[i * kf + j] = G[j * kf + i] = g[at];
    memcpy(x, b, kf * sizeof *x);
    spd_solve(G, x, kf);
    memcpy(y, x, kf * sizeof *y);
    if (quad) {
        double qv = 0;
        for (size_t i = 0, at = 0; i < kf; i++) {
            double gy = 0;
            for (size_t j = 0; j < i; j++, at++)
                gy += 2 * g[at] * y[j];
            gy += g[at++] * y[i];
            qv += y[i] * (gy - 2 * b[i]);
        }
        *quad = qv;
    }
}

/* LANES solves side by side, up to LANE_MAX_K terms: lane l's Gram at g +
 * l kt, its right-hand side at b + l kf, its solution to y + l kf and
 * quad[l].  Each lane does what ls_solve does, in the same order (the same
 * bits: no operation is contracted), but the four divisions and roots of
 * a step go in one vector: the column half spent half its time waiting on
 * one column's chain of them (Cornell acrylic: 992 columns of 1-4 terms a
 * sweep). */
#define LANES 4
#define LANE_MAX_K 8
typedef double lanes_t __attribute__((vector_size(LANES * sizeof(double))));

static inline __attribute__((always_inline)) void ls_solve_lanes(const double *g, const double *b, size_t kf, double *y,
                                                                 double *quad) {
    size_t kt = kf * (kf + 1) / 2;
    lanes_t G[LANE_MAX_K * LANE_MAX_K], x[LANE_MAX_K], tr = {0, 0, 0, 0}, d;
    for (size_t i = 0, at = 0; i < kf; i++)
        for (size_t j = 0; j <= i; j++, at++)
            G[i * kf + j] = (lanes_t){g[at], g[kt + at], g[2 * kt + at], g[3 * kt + at]};
    for (size_t i = 0; i < kf; i++) {
        x[i] = (lanes_t){b[i], b[kf + i], b[2 * kf + i], b[3 * kf + i]};
        tr += G[i * kf + i];
    }
    for (int l = 0; l < LANES; l++) /* spd_solve's ridge */
        d[l] = 1e-12 * (tr[l] > 0 ? tr[l] / (double)kf : 1.0) + 1e-300;
    for (size_t i = 0; i < kf; i++)
        G[i * kf + i] += d;
    for (size_t j = 0; j < kf; j++) { /* sb_chol with the fallback 1e-150 */
        d = G[j * kf + j];
        for (size_t p = 0; p < j; p++)
            d -= G[j * kf + p] * G[j * kf + p];
        for (int l = 0; l < LANES; l++)
            d[l] = d[l] > 0 ? sqrt(d[l]) : 1e-150;
        G[j * kf + j] = d;
        for (size_t i = j + 1; i < kf; i++) {
            lanes_t v = G[i * kf + j];
            for (size_t p = 0; p < j; p++)
                v -= G[i * kf + p] * G[j * kf + p];
            G[i * kf + j] = v / d;
        }
    }
    for (size_t i = 0; i < kf; i++) { /* sb_chol_solve */
        lanes_t v = x[i];
        for (size_t p = 0; p < i; p++)
            v -= G[i * kf + p] * x[p];
        x[i] = v / G[i * kf + i];
    }
    for (size_t i = kf; i-- > 0;) {
        lanes_t v = x[i];
        for (size_t p = i + 1; p < kf; p++)
            v -= G[p * kf + i] * x[p];
        x[i] = v / G[i * kf + i];
    }
    for (int l = 0; l < LANES; l++)
        for (size_t i = 0; i < kf; i++)
            y[(size_t)l * kf + i] = x[i][l];
    if (quad) {
        lanes_t qv = {0, 0, 0, 0};
        for (size_t i = 0, at = 0; i < kf; i++) {
            lanes_t gy = {0, 0, 0, 0}, b0 = {b[i], b[kf + i], b[2 * kf + i], b[3 * kf + i]};
            for (size_t j = 0; j < i; j++, at++)
                gy += 2 * (lanes_t){g[at], g[kt + at], g[2 * kt + at], g[3 * kt + at]} * x[j];
            gy += (lanes_t){g[at], g[kt + at], g[2 * kt + at], g[3 * kt + at]} * x[i];
            at++;
            qv += x[i] * (gy - 2 * b0);
        }
        for (int l = 0; l < LANES; l++)
            quad[l] = qv[l];
    }
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
    const double *all; /* the sum of the fixed side's outer products (kt) */
    int quick;         /* the columns' errors from their normal equations */
} als_job_t;

/* Step of a half: the updates of the lines c..c+nb-1 (nb 1 or LANES) into
 * y (nb x kf) and quad, their Grams from the cells of that order. */
static inline __attribute__((always_inline)) void line_gram(const als_job_t *jb, int cols, size_t i, size_t kf,
                                                            double *g, double *b) {
    const sb_fit_t *f = jb->f;
    const als_cells_t *cl = jb->cl;
    const double *bx = cl->D ? cl->bt + i : NULL;
    if (cols)
        ls_gram(cl->cr, cl->cres, cl->cp[i], cl->cp[i + 1], cl->ci, cl->cip[i], cl->cip[i + 1], jb->all, f->pt, f->pp,
                kf, bx, f->n, g, b);
    else
        ls_gram(cl->rc, cl->rres, cl->rp[i], cl->rp[i + 1], cl->ri, cl->rip[i], cl->rip[i + 1], jb->all, f->qt, f->qq,
                kf, bx, f->m, g, b);
}

/* line_gram of LANES lines of one term with the dense residual, side by
 * side: a line's Gram is one sum, all less its cells out or its cells in,
 * a chain of dependent additions (the MERL file's 1024 x 1024 sweeps: 40
 * % of each half's time waiting on it); the lanes' chains go in one
 * vector, each lane adding its terms in its order (x - y is x + (-y):
 * the same bits), the longer ones finished alone. */
static inline __attribute__((always_inline)) void gram1_lanes(const als_job_t *jb, int cols, size_t i, double *g,
                                                              double *b) {
    const sb_fit_t *f = jb->f;
    const als_cells_t *cl = jb->cl;
    const size_t *p = cols ? cl->cp : cl->rp, *pu = cols ? cl->cip : cl->rip;
    const uint32_t *in = cols ? cl->cr : cl->rc, *out = cols ? cl->ci : cl->ri, *at[LANES];
    const double *xx = cols ? f->pp : f->qq;
    size_t len[LANES], common = SIZE_MAX;
    lanes_t sum = {0, 0, 0, 0}, sign = {0, 0, 0, 0};
    for (size_t l = 0; l < LANES; l++) {
        size_t t0 = p[i + l], t1 = p[i + l + 1], u0 = pu[i + l], u1 = pu[i + l + 1];
        int less = u1 - u0 < t1 - t0; /* ls_gram's choice */
        at[l] = less ? out + u0 : in + t0;
        len[l] = less ? u1 - u0 : t1 - t0;
        sum[l] = less ? jb->all[0] : 0;
        sign[l] = less ? -1 : 1;
        common = len[l] < common ? len[l] : common;
    }
    memcpy(b, cl->bt + i, LANES * sizeof *b);
    for (size_t u = 0; u < common; u++)
        sum += sign * (lanes_t){xx[at[0][u]], xx[at[1][u]], xx[at[2][u]], xx[at[3][u]]};
    for (size_t l = 0; l < LANES; l++) {
        double v = sum[l], s = sign[l];
        for (size_t u = common; u < len[l]; u++)
            v += s * xx[at[l][u]];
        g[l] = v;
    }
}

static inline __attribute__((always_inline)) void half_solve(const als_job_t *jb, int cols, size_t c, size_t nb,
                                                             size_t kf, double *y, double *quad) {
    size_t kt = kf * (kf + 1) / 2;
    double g[SB_ALS_MAX_K * (SB_ALS_MAX_K + 1) / 2], b[SB_ALS_MAX_K];
    if (nb == LANES && kf == 1 && jb->cl->D) {
        gram1_lanes(jb, cols, c, g, b);
        ls_solve_lanes(g, b, kf, y, quad);
    } else if (nb == LANES) {
        for (size_t l = 0; l < LANES; l++)
            line_gram(jb, cols, c + l, kf, g + l * kt, b + l * kf);
        ls_solve_lanes(g, b, kf, y, quad);
    } else {
        line_gram(jb, cols, c, kf, g, b);
        ls_solve(g, b, kf, y, quad);
    }
}

/* How many lines from c on go in one step: LANES where as many are left
 * and the terms fit the lanes, else 1. */
static size_t half_step(const als_job_t *jb, size_t c, size_t kf) {
    return kf <= LANE_MAX_K && jb->hi - c >= LANES ? LANES : 1;
}

/* The row half for kf = ka - j0 free terms (inlined with kf constant, and
 * always, so that the clones of als_rows compile it too):
 * p_r from G_r = sum_c q_c q_c^T, b_r = sum_c a_rc q_c over the valid c. */
static inline __attribute__((always_inline)) void rows_k(const als_job_t *jb, size_t kf) {
    sb_fit_t *f = jb->f;
    size_t m = f->m, j0 = jb->j0, kt = kf * (kf + 1) / 2;
    for (size_t r = jb->lo; r < jb->hi;) {
        double p[SB_ALS_MAX_K];
        size_t nb = half_step(jb, r, kf);
        half_solve(jb, 0, r, nb, kf, p, NULL);
        for (size_t l = 0; l < nb; l++, r++) {
            for (size_t j = 0; j < kf; j++)
                f->P[r + (j0 + j) * m] = p[l * kf + j];
            put_row(f->pt + r * kf, f->pp + r * kt, p + l * kf, kf);
        }
    }
}

/* The column half, then the error of column c with its new q_c. */
static inline __attribute__((always_inline)) void cols_k(als_job_t *jb, size_t kf) {
    sb_fit_t *f = jb->f;
    const als_cells_t *cl = jb->cl;
    size_t n = f->n, j0 = jb->j0;
    double e2 = 0;
    for (size_t c = jb->lo; c < jb->hi;) {
        double q[SB_ALS_MAX_K], quad[LANES];
        size_t nb = half_step(jb, c, kf);
        half_solve(jb, 1, c, nb, kf, q, jb->quick ? quad : NULL);
        for (size_t l = 0; l < nb; l++, c++) {
            const double *ql = q + l * kf;
            for (size_t j = 0; j < kf; j++)
                f->Q[c + (j0 + j) * n] = ql[j];
            if (jb->quick) { /* |a - P q|^2 = |a|^2 + q^T Gram q - 2 q . b */
                e2 += cl->ca2[c] + quad[l];
                continue;
            }
            for (size_t t = cl->cp[c]; t < cl->cp[c + 1]; t++) {
                const double *p = f->pt + cl->cr[t] * kf;
                double d = cl->cres[t];
                for (size_t j = 0; j < kf; j++)
                    d -= p[j] * ql[j];
                e2 += d * d;
            }
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

/* The halves with FMA where the CPU has it (SB_FMA_CLONES): the default
 * run's sweeps 13 % fewer instructions, its fit step 5 % faster (Xeon VM,
 * interleaved). */
SB_FMA_CLONES static void *als_rows(void *arg) {
    als_job_t *jb = arg;
    SB_ALS_DISPATCH(rows_k, jb);
    return NULL;
}

SB_FMA_CLONES static void *als_cols(void *arg) {
    als_job_t *jb = arg;
    SB_ALS_DISPATCH(cols_k, jb);
    return NULL;
}

/* Run fn on [0, n) split among threads (the caller's included). */
static void als_parallel(void *(*fn)(void *), als_job_t *proto, size_t n, double *e2) {
    /* small: not worth a thread (a cell costs kf (kf + 3) / 2 multiply-adds
     * a half-sweep).  A call costs a worker's wake-up, in the kernel on
     * the 2-core VMs (a half-sweep at 64 x 992 cells and 4 terms, 0.9 M
     * multiply-adds, takes about 0.3 ms): below 2 M multiply-adds the
     * sweeps stay on one thread.  On two threads the default gold run
     * took 0.89x the CPU at J = 4 and 0.87x at J = 8 against a bound of
     * 128 k, at the same wall time; the Cornell acrylic's 0.93x and 0.94x
     * the wall (its cross-validation refits run one per thread). */
    size_t kf = proto->ka - proto->j0;
    int nt = sb_threads_for(0, n, proto->f->m * proto->f->n * kf * (kf + 3) / 2, (size_t)1 << 21);
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

/* all (kt) = the sum of the n packed outer products xx (n x kt). */
static void sum_rows(const double *xx, size_t n, size_t kt, double *all) {
    memset(all, 0, kt * sizeof *all);
    for (size_t c = 0; c < n; c++)
        for (size_t i = 0; i < kt; i++)
            all[i] += xx[c * kt + i];
}

/* quick: the error of each column from its normal equations instead of its
 * cells (kf (kf + 3) / 2 multiply-adds a column instead of kf a cell: a
 * third of the default run's sweeps went there), exact but for rounding
 * of about 10 eps |a|^2, so only while the error is far above that. */
static double als_sweep(sb_fit_t *f, const als_cells_t *cl, size_t j0, size_t ka, int quick) {
    double all[SB_ALS_MAX_K * (SB_ALS_MAX_K + 1) / 2];
    als_job_t proto = {f, cl, j0, ka, 0, 0, 0, all, quick};
    size_t kf = ka - j0, kt = kf * (kf + 1) / 2;
    double e2;
    for (size_t c = 0; c < f->n; c++) {
        double q[SB_ALS_MAX_K];
        for (size_t j = 0; j < kf; j++)
            q[j] = f->Q[c + (j0 + j) * f->n];
        put_row(f->qt + c * kf, f->qq + c * kt, q, kf);
    }
    sum_rows(f->qq, f->n, kt, all);
    size_t m = f->m, n = f->n;
    if (cl->D) /* every row's right-hand side: D Q_free (m x kf) */
        fit_dense_product(cl->D, m, n, f->Q + j0 * n, n, kf, cl->bt, m);
    als_parallel(als_rows, &proto, m, NULL);
    sum_rows(f->pp, m, kt, all);
    if (cl->D) /* every column's: D^T P_free (n x kf), P as the rows left it */
        fit_dense_product(cl->DT, n, m, f->P + j0 * m, m, kf, cl->bt, n);
    als_parallel(als_cols, &proto, n, &e2);
    return e2;
}

/* The squared error on the cells after a sweep, from the cells, as the
 * column half sums it where it is not quick (the same parts of the
 * columns, their sums in the same order: the same bits). */
static double cells_e2(const sb_fit_t *f, const als_cells_t *cl, size_t j0, size_t ka) {
    size_t m = f->m, n = f->n, kf = ka - j0, lo, hi;
    int nt = sb_threads_for(0, n, m * n * kf * (kf + 3) / 2, (size_t)1 << 21);
    double e2 = 0;
    for (int t = 0; t < nt; t++) {
        sb_part(n, t, nt, &lo, &hi);
        double part = 0;
        for (size_t c = lo; c < hi; c++)
            for (size_t u = cl->cp[c]; u < cl->cp[c + 1]; u++) {
                const double *p = f->pt + cl->cr[u] * kf;
                double d = cl->cres[u];
                for (size_t j = 0; j < kf; j++)
                    d -= p[j] * f->Q[c + (j0 + j) * n];
                part += d * d;
            }
        e2 += part;
    }
    return e2;
}

/* ALS sweeps on columns j0..ka-1 until the error stops improving. */
double fit_als_until(sb_fit_t *f, als_cells_t *cl, size_t j0, size_t ka, const sb_fit_opts_t *o, double norm,
                     int *sweeps, int *converged) {
    double prev = INFINITY, err = 0;
    fit_cells_residual(cl, f, j0);
    for (int stage = 1;; stage++) {
        (*sweeps)++;
        /* the errors from the normal equations while the last was above
         * 1e-4 of the data's norm: their rounding then stays below 1e-7 of
         * it, far below the stop's tolerances; the first sweep's too, made
         * again from the cells when it is below 1e-6 of the data's (the
         * first sweep of a stage went to the cells every time: 17 % of the
         * column half's time on the Cornell acrylic) */
        int first = !isfinite(prev), quick = first || prev * prev >= 1e-8 * cl->a2;
        double e2 = als_sweep(f, cl, j0, ka, quick);
        if (first && !(e2 >= 1e-6 * cl->a2)) e2 = cells_e2(f, cl, j0, ka);
        err = sqrt(e2 > 0 ? e2 : 0);
        if (err <= 1e-15 * norm || (isfinite(prev) && prev - err <= o->tol * prev)) break;
        if (stage >= o->max_iters) {
            *converged = 0;
            break;
        }
        prev = err;
    }
    return err;
}
