/* Masked fit, part 2 (fit.c has the whole picture): alternating least
 * squares on the valid cells (gathered once per execute in both orders by
 * fit_cells.c), and the nested stages that add one term at a time. */
#include <assert.h>
#include <math.h>
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

/* One least-squares update from the cells t0..t1-1 of a row (column):
 * with x_i, xx_i the fixed side's row-major factor and packed outer
 * product at the cell's other index idx[t], solve
 *     (sum_t xx_{idx[t]}) y = sum_t a_t x_{idx[t]}
 * for y (kf values) by spd_solve, the sums in the order of t.  Where the
 * cells left out (out[u], u0..u1-1) are fewer, the Gram is `all` (the sum
 * of every xx) less theirs: a kt-vector sum per cell out instead of per
 * cell in (the default's iso cells are 75 % in: 19 % fewer instructions here),
 * no worse than 2 eps |all| / |Gram| in rounding while they are fewer. */
static inline __attribute__((always_inline)) void ls_update(const uint32_t *idx, const double *a, size_t t0, size_t t1,
                                                            const uint32_t *out, size_t u0, size_t u1,
                                                            const double *all, const double *xt, const double *xx,
                                                            size_t kf, const double *bx, size_t bs, double *y,
                                                            double *quad) {
    size_t kt = kf * (kf + 1) / 2;
    /* local accumulators: y may not alias what the loop reads */
    double g[SB_ALS_MAX_K * (SB_ALS_MAX_K + 1) / 2], b[SB_ALS_MAX_K], G[SB_ALS_MAX_K * SB_ALS_MAX_K];
    memset(b, 0, kf * sizeof *b);
    if (bx) /* the right-hand side from the dense product (als_sweep) */
        for (size_t i = 0; i < kf; i++)
            b[i] = bx[i * bs];
    if (u1 - u0 < t1 - t0) {
        memcpy(g, all, kt * sizeof *g);
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
        memset(g, 0, kt * sizeof *g);
        for (size_t t = t0; t < t1; t++) {
            const double *x2 = xx + idx[t] * kt;
            for (size_t i = 0; i < kt; i++)
                g[i] += x2[i];
        }
    } else {
        memset(g, 0, kt * sizeof *g);
        for (size_t t = t0; t < t1; t++) {
            const double *x = xt + idx[t] * kf, *x2 = xx + idx[t] * kt;
            double v = a[t];
            for (size_t i = 0; i < kf; i++)
                b[i] += v * x[i];
            for (size_t i = 0; i < kt; i++)
                g[i] += x2[i];
        }
    }
    for (size_t i = 0, at = 0; i < kf; i++)
        for (size_t j = 0; j <= i; j++, at++)
            G[i * kf + j] = G[j * kf + i] = g[at];
    double b0[SB_ALS_MAX_K];
    memcpy(b0, b, kf * sizeof *b0);
    spd_solve(G, b, kf);
    memcpy(y, b, kf * sizeof *y);
    if (quad) { /* y^T Gram y - 2 y . b, from the packed Gram */
        double qv = 0;
        for (size_t i = 0, at = 0; i < kf; i++) {
            double gy = 0;
            for (size_t j = 0; j < i; j++, at++)
                gy += 2 * g[at] * y[j];
            gy += g[at++] * y[i];
            qv += y[i] * (gy - 2 * b0[i]);
        }
        *quad = qv;
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

/* The row half for kf = ka - j0 free terms (inlined with kf constant, and
 * always, so that the clones of als_rows compile it too):
 * p_r from G_r = sum_c q_c q_c^T, b_r = sum_c a_rc q_c over the valid c. */
static inline __attribute__((always_inline)) void rows_k(const als_job_t *jb, size_t kf) {
    sb_fit_t *f = jb->f;
    const als_cells_t *cl = jb->cl;
    size_t m = f->m, j0 = jb->j0, kt = kf * (kf + 1) / 2;
    for (size_t r = jb->lo; r < jb->hi; r++) {
        double p[SB_ALS_MAX_K];
        ls_update(cl->rc, cl->rres, cl->rp[r], cl->rp[r + 1], cl->ri, cl->rip[r], cl->rip[r + 1], jb->all, f->qt, f->qq,
                  kf, cl->D ? cl->bt + r : NULL, m, p, NULL);
        for (size_t j = 0; j < kf; j++)
            f->P[r + (j0 + j) * m] = p[j];
        put_row(f->pt + r * kf, f->pp + r * kt, p, kf);
    }
}

/* The column half, then the error of column c with its new q_c. */
static inline __attribute__((always_inline)) void cols_k(als_job_t *jb, size_t kf) {
    sb_fit_t *f = jb->f;
    const als_cells_t *cl = jb->cl;
    size_t n = f->n, j0 = jb->j0;
    double e2 = 0;
    for (size_t c = jb->lo; c < jb->hi; c++) {
        double q[SB_ALS_MAX_K];
        size_t t0 = cl->cp[c], t1 = cl->cp[c + 1];
        double quad;
        ls_update(cl->cr, cl->cres, t0, t1, cl->ci, cl->cip[c], cl->cip[c + 1], jb->all, f->pt, f->pp, kf,
                  cl->D ? cl->bt + c : NULL, n, q, jb->quick ? &quad : NULL);
        for (size_t j = 0; j < kf; j++)
            f->Q[c + (j0 + j) * n] = q[j];
        if (jb->quick) { /* |a - P q|^2 = |a|^2 + q^T Gram q - 2 q . b */
            e2 += cl->ca2[c] + quad;
            continue;
        }
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

/* Whether stage ka refits its terms jointly: every stage up to
 * SB_JOINT_ALL terms, none beyond (the stages there add their term on the
 * residual, which keeps every prefix's error non-increasing).  A joint
 * sweep costs ka^2 per cell; the joint refits at 16, 32 and the last
 * stage that earlier versions ran were never kept on the default gold at
 * J = 32, GGX 0.1, Blinn-Phong, the Cornell and RGL tables at J = 16
 * (the same factors to the bit) and took half the time (J = 32: 5.1 ->
 * 2.1 s; Cornell J = 16: 45 -> 28 s); on explicit layouts, fitted to
 * convergence too, the same errors (gold iso J = 16, GGX 0.3 iso J = 12,
 * anisotropic GGX hd J = 12) or lower (Cornell hd J = 12 at 16 cells:
 * 22.3 % -> 19.9 %) at 40-50 % less time. */
static int joint_stage(size_t ka) { return ka > 1 && ka <= SB_JOINT_ALL; }

/* The staged ALS from the warm start in f->P, f->Q on the cells of X with
 * mask != 0 (nvalid of them); *err the last stage's error; *stretched 1
 * when the last stage kept a joint refit that made a shorter prefix more
 * than SB_PREFIX_SLACK times worse (not strict only); *converged 0
 * when the run that gave the last stage's kept result stopped at
 * max_iters (earlier stages only warm-start the later ones).  SB_OK or
 * SB_ERR_NOMEM. */
/* A run of the stages: what every stage reads, the copies a rejected
 * joint refit is restored from, and the accepted prefix errors. */
typedef struct als_run {
    sb_fit_t *f;
    als_cells_t cl;
    const sb_fit_opts_t *o;
    int strict, *total, *stretched;
    double norm2, *saveP, *saveQ;
    double acc[SB_ALS_MAX_K];
    als_resume_t *rs;
} als_run_t;

/* Step: the new term ka - 1 alone on the residual of the others: the error
 * can only go down (its first half-sweep is a least-squares step from the
 * warm start).  replay: the strict run's last stage computes what the
 * recorded one did (the same start and cells), taken from the record;
 * record: keep it there.  Returns the error. */
static double stage_new_term(als_run_t *ru, size_t ka, int replay, int record, int *c1) {
    sb_fit_t *f = ru->f;
    als_resume_t *rs = ru->rs;
    size_t m = f->m, n = f->n, k = f->k;
    double err;
    if (replay) {
        memcpy(f->P, rs->P1, m * k * sizeof *f->P);
        memcpy(f->Q, rs->Q1, n * k * sizeof *f->Q);
        err = rs->err1, *c1 = rs->c1;
    } else {
        err = fit_als_until(f, &ru->cl, ka - 1, ka, ru->o, sqrt(ru->norm2), ru->total, c1);
    }
    if (record) {
        memcpy(rs->P1, f->P, m * k * sizeof *f->P);
        memcpy(rs->Q1, f->Q, n * k * sizeof *f->Q);
        rs->err1 = err, rs->c1 = *c1;
    }
    return err;
}

/* Step: then all ka jointly: a joint refit may trade the prefixes'
 * accuracy for cancelling terms that are large outside the domain, which
 * also spoil interpolated lookups near its edge.  Kept only if no shorter
 * prefix gets more than SB_PREFIX_SLACK times worse (at the last stage: no
 * worse than no term at all); strict: and the prefixes' errors stay
 * non-increasing.  Returns 1 when kept (*err is then the joint error),
 * else 0 with the terms restored. */
static int stage_joint(als_run_t *ru, size_t ka, int replay, int record, double *err, int *cj) {
    sb_fit_t *f = ru->f;
    als_resume_t *rs = ru->rs;
    size_t m = f->m, n = f->n, k = f->k;
    double e2[SB_ALS_MAX_K], *acc = ru->acc, norm2 = ru->norm2;
    memcpy(ru->saveP, f->P, m * ka * sizeof *ru->saveP);
    memcpy(ru->saveQ, f->Q, n * ka * sizeof *ru->saveQ);
    double ej;
    if (replay) {
        memcpy(f->P, rs->Pj, m * k * sizeof *f->P);
        memcpy(f->Q, rs->Qj, n * k * sizeof *f->Q);
        memcpy(e2, rs->e2, sizeof e2);
        ej = rs->errj, *cj = rs->cj;
    } else {
        ej = fit_als_until(f, &ru->cl, 0, ka, ru->o, sqrt(norm2), ru->total, cj);
        prefix_errors(f, &ru->cl, ka, e2);
    }
    if (record) {
        memcpy(rs->Pj, f->P, m * k * sizeof *f->P);
        memcpy(rs->Qj, f->Q, n * k * sizeof *f->Q);
        memcpy(rs->e2, e2, sizeof e2);
        rs->errj = ej, rs->cj = *cj, rs->last = 1;
    }
    int keep = ej <= *err;
    double slack = ka == k && !ru->strict ? INFINITY : SB_PREFIX_SLACK;
    int within = 1, monotone = 1;
    for (size_t j = 0; keep && j + 1 < ka; j++) {
        keep = sqrt(e2[j]) <= fmin(acc[j] * slack, sqrt(norm2)) && (!ru->strict || e2[j + 1] <= e2[j]);
        within &= sqrt(e2[j]) <= acc[j] * SB_PREFIX_SLACK;
        monotone &= e2[j + 1] <= e2[j];
    }
    if (keep && !monotone && rs && rs->save && ka < k) rs->same = 0; /* strict would not keep it */
    if (keep && !within) *ru->stretched = 1;
    if (keep) {
        *err = ej;
        for (size_t j = 0; j + 1 < ka; j++)
            acc[j] = fmax(acc[j], sqrt(e2[j]));
    } else {
        memcpy(f->P, ru->saveP, m * ka * sizeof *ru->saveP);
        memcpy(f->Q, ru->saveQ, n * ka * sizeof *ru->saveQ);
    }
    return keep;
}

sb_result_t fit_als_stages(sb_fit_t *f, const double *As, size_t lda, const unsigned char *mask, size_t nvalid,
                           const sb_fit_opts_t *o, int strict, double norm2, int *total, int *converged, double *err,
                           int *stretched, als_resume_t *rs) {
    size_t m = f->m, n = f->n, k = f->k;
    /* Nested stages: terms are added one at a time and the first ka
     * are refitted jointly, so every prefix of the result is itself a
     * masked fit of its rank (the terms are not re-orthogonalised over
     * the whole matrix: that would mix in the unconstrained values the
     * fit implies outside the domain). */
    als_run_t ru = {.f = f, .o = o, .strict = strict, .total = total, .stretched = stretched, .norm2 = norm2, .rs = rs};
    ru.saveP = malloc(m * k * sizeof *ru.saveP);
    ru.saveQ = malloc(n * k * sizeof *ru.saveQ);
    if (!ru.saveP || !ru.saveQ || fit_cells_build(f->ctx, &ru.cl, As, m, n, lda, mask, nvalid) != 0) {
        int saved = ru.saveP && ru.saveQ; /* else fit_cells_build failed and named its bytes */
        free(ru.saveP);
        free(ru.saveQ);
        if (saved) return SB_ERR_NOMEM;
        return sb_error(f->ctx, SB_ERR_NOMEM, "fit: cannot allocate %zu bytes", (m + n) * k * sizeof(double));
    }
    size_t ka0 = 1;
    if (rs && rs->resume) { /* the non-strict run's state before its last stage */
        memcpy(f->P, rs->P, m * k * sizeof *f->P);
        memcpy(f->Q, rs->Q, n * k * sizeof *f->Q);
        memcpy(ru.acc, rs->acc, sizeof ru.acc);
        *err = rs->err;
        *converged = rs->converged;
        ka0 = k;
    }
    if (rs && rs->save) rs->same = 1, rs->valid = 0, rs->last = 0;
    for (size_t ka = ka0; ka <= k; ka++) {
        if (rs && rs->save && ka == k && k > 1) {
            memcpy(rs->P, f->P, m * k * sizeof *f->P);
            memcpy(rs->Q, f->Q, n * k * sizeof *f->Q);
            memcpy(rs->acc, ru.acc, sizeof ru.acc);
            rs->err = *err;
            rs->converged = *converged;
            rs->valid = 1;
        }
        int c1 = 1, cj = 1, keep = 0;
        int replay = rs && rs->resume && rs->last && ka == k, record = rs && rs->save && ka == k && k > 1;
        *err = stage_new_term(&ru, ka, replay, record, &c1);
        if (joint_stage(ka)) keep = stage_joint(&ru, ka, replay, record, err, &cj);
        ru.acc[ka - 1] = *err;
        *converged = keep ? cj : c1;
        if (o->target > 0 && *err <= o->target * sqrt(norm2)) { /* --max-error reached: stop adding terms */
            memset(f->P + ka * m, 0, (k - ka) * m * sizeof *f->P);
            memset(f->Q + ka * n, 0, (k - ka) * n * sizeof *f->Q);
            break;
        }
    }
    free(ru.saveP);
    free(ru.saveQ);
    fit_cells_free(&ru.cl);
    return SB_OK;
}

/* Squared errors of the prefixes on the valid cells (mask) of X: e2[j]
 * after the terms 0..j. */
void fit_valid_prefix_e2(const sb_fit_t *f, const double *X, size_t lda, const unsigned char *mask, double *e2) {
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

int fit_prefixes_monotone(const sb_fit_t *f, const double *X, size_t lda, const unsigned char *mask) {
    double e2[SB_ALS_MAX_K];
    fit_valid_prefix_e2(f, X, lda, mask, e2);
    for (size_t j = 1; j < f->k; j++)
        if (e2[j] > e2[j - 1]) return 0;
    return 1;
}
