/* The non-negative solver's sweeps (solver_nmf.c has the method): the
 * cells' weights, the weighted residual, a term's nested HALS update over
 * rows and columns (split among threads) and the stages that add the terms
 * one at a time; nmf_mixes.c and solver_nmf.c call them. */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sepbrdf/param.h"
#include "solve/fit_impl.h"
#include "solve/nmf_gram.h"
#include "solve/nmf_lanes.h"
#include "solve/nmf_state.h"
#include "solve/nmf_weights.h"
#include "solve/solver.h"
#include "util/internal.h"
#include "util/parallel.h"

/* The minimax's sweeps (nmf_mixes.c minimax) in one part up to this much
 * work (m n k): the default gold's 64 x 992 cells, J = 4, spent 18 % less
 * CPU in them on one core than split on two, the same report
 * (docs/positive.md, round h38b). */
#define SB_NMF_MM_MIN_WORK ((size_t)1 << 19)

/* Whether cell (i, c) has a target (ext != 0). */
static int valid(const nmf_state_t *s, size_t i, size_t c) { return s->ext[i + c * s->m] != 0; }

/* Step: the weight of every cell in the fit (s->w): 1 for the data, the
 * fill weight within the taps' reach, SB_NMF_HOLE_WEIGHT beyond (target
 * 0).  Kept as numbers, so that the sweeps' loops have no branches. */
void sb_nmf_cell_weights(nmf_state_t *s) {
    for (size_t k = 0; k < s->m * s->n; k++) {
        unsigned char e = s->ext[k];
        s->w[k] = e == 1 ? 1 : (e == 2 ? s->fill : SB_NMF_HOLE_WEIGHT);
    }
}

/* Step: E = M o (X - U V^T) of the first k terms; returns ||E||^2. */
double sb_nmf_residual(nmf_state_t *s, const double *U, const double *V, size_t k) {
    double f = 0;
    for (size_t c = 0; c < s->n; c++)
        for (size_t i = 0; i < s->m; i++) {
            double r = valid(s, i, c) ? s->x[i + c * s->m] : 0;
            for (size_t j = 0; j < k; j++)
                r -= U[i + j * s->m] * V[c + j * s->n];
            s->e[i + c * s->m] = r;
            f += s->w[i + c * s->m] * r * r;
        }
    return f;
}

/* A part of the columns of one parallel step (sb_parallel_run): the
 * term's rows accumulated (term_rows), its columns updated (term_cols), or
 * the prefixes' errors (prefix_cols).  The three jobs are compiled twice
 * (SB_AVX2_CLONES: the same operations, so the same bits) and term_cols
 * makes one pass where it made three (nmf_lanes.h sub2_wdot): the default
 * gold's non-negative run, J = 4, spent 20 % of its CPU in term_cols,
 * then 10 % (docs/positive.md, round h38t). */
typedef struct nmf_job {
    nmf_state_t *s;
    double *U, *V;
    size_t k, j, c0, c1;
    double A;   /* the weight of the term's target (1: the last term, R = E) */
    double *ws; /* this part's 3 m + J numbers: b, d, a column, f */
} nmf_job_t;

/* Job: the term's target R = A E + sum_{q>j} c_q u_q v_q^T on the part's
 * columns (R is E itself for the last term), and the row sums b_i = sum_c
 * W R v_j, d_i = sum_c W v_j^2 over them. */
SB_AVX2_CLONES static void *term_rows(void *arg) {
    nmf_job_t *jb = arg;
    nmf_state_t *s = jb->s;
    size_t m = s->m, n = s->n, j = jb->j;
    double *restrict b = jb->ws, *restrict d = jb->ws + m;
    memset(jb->ws, 0, 2 * m * sizeof *b);
    for (size_t col = jb->c0; col < jb->c1; col++) {
        double *restrict rc = s->r + col * m;
        const double *restrict ec = s->e + col * m, *restrict w = s->w + col * m;
        if (j + 1 < jb->k) {
            for (size_t i = 0; i < m; i++)
                rc[i] = jb->A * ec[i];
            for (size_t q = j + 1; q < jb->k; q++)
                if (jb->V[col + q * n] != 0) axpy_neg(rc, jb->U + q * m, -s->cq[q] * jb->V[col + q * n], m);
        } else
            rc = s->e + col * m;
        double vc = jb->V[col + j * n], vc2 = vc * vc;
        for (size_t i = 0; i < m; i++) {
            b[i] += w[i] * rc[i] * vc;
            d[i] += w[i] * vc2;
        }
    }
    return NULL;
}

/* Job: on the part's columns, E and R follow the change du of u_j (in
 * the part's b), then v_j(c) <- max(0, v + sum_i W R u / (A sum_i W u^2))
 * and E, R follow it. */
SB_AVX2_CLONES static void *term_cols(void *arg) {
    nmf_job_t *jb = arg;
    nmf_state_t *s = jb->s;
    size_t m = s->m, n = s->n, j = jb->j;
    const double *du = jb->ws, *u = jb->U + j * m;
    double *v = jb->V + j * n, A = jb->A;
    int own = j + 1 < jb->k; /* R apart from E */
    for (size_t col = jb->c0; col < jb->c1; col++) {
        double *e = s->e + col * m, *rc = own ? s->r + col * m : e, b, d;
        const double *w = s->w + col * m;
        if (v[col] != 0 && own)
            sub2_wdot(e, rc, du, v[col], A * v[col], w, u, m, &b, &d);
        else {
            if (v[col] != 0) axpy_neg(e, du, v[col], m);
            wdot(w, rc, u, m, &b, &d);
        }
        double nv = d > 0 ? fmax(0, v[col] + b / (A * d)) : 0, dv = nv - v[col];
        v[col] = nv;
        if (dv == 0) continue;
        if (own)
            axpy2_neg(e, rc, u, dv, A * dv, m);
        else
            axpy_neg(e, u, dv, m);
    }
    return NULL;
}

/* Job: f_p = sum over the part's columns of W E_p^2, p = k..1 (E_p = E_k
 * + the terms p + 1..k), in the part's f. */
SB_AVX2_CLONES static void *prefix_cols(void *arg) {
    nmf_job_t *jb = arg;
    nmf_state_t *s = jb->s;
    size_t m = s->m, n = s->n, k = jb->k;
    double *col = jb->ws + 2 * m, *f = jb->ws + 3 * m;
    memset(f, 0, k * sizeof *f);
    for (size_t c = jb->c0; c < jb->c1; c++) {
        memcpy(col, s->e + c * m, m * sizeof *col);
        for (size_t p = k; p >= 1; p--)
            f[p - 1] += wsq_add(s->w + c * m, col, jb->U + (p - 1) * m, jb->V[c + (p - 1) * n], m);
    }
    return NULL;
}

/* Step: fn over the columns in parts (threads where the work is large
 * enough: every core for the default gold's 64 x 992 cells, but one part
 * in the minimax's sweeps, s->mm: SB_NMF_MM_MIN_WORK); returns the number
 * of parts. */
static int columns_run(nmf_state_t *s, void *(*fn)(void *), const nmf_job_t *proto, nmf_job_t *jobs) {
    int nt = sb_threads_for(0, s->n, s->m * s->n * proto->k, s->mm ? SB_NMF_MM_MIN_WORK : (size_t)1 << 17);
    if (nt > s->nt) nt = s->nt;
    for (int t = 0; t < nt; t++) {
        jobs[t] = *proto;
        jobs[t].ws = s->tw + (size_t)t * (3 * s->m + s->J);
        sb_part(s->n, t, nt, &jobs[t].c0, &jobs[t].c1);
    }
    sb_parallel_run(fn, jobs, sizeof *jobs, nt, NULL, NULL);
    return nt;
}

/* Step: with the ratios r_p = f_p / sref_p (rmax their largest; the last
 * prefix's of all J times sb_nmf_last_boost, held for the sweep), the
 * weights alpha_p = (r_p / rmax)^gamma / f_p, the gradient of k log (sum_p
 * r_p^gamma)^(1/gamma), returned (SB_NMF_RATIO_POWER). */
static double ratio_weights(nmf_state_t *s, const double *f, size_t k) {
    double rmax = 0, S = 0, bl = k == s->J ? sb_nmf_last_boost(s, f[k - 1] / s->sref[k - 1]) : 1;
    for (size_t p = 0; p < k; p++)
        rmax = fmax(rmax, f[p] / s->sref[p] * (p + 1 == k ? bl : 1));
    for (size_t p = 0; p < k; p++) {
        double q = pow(f[p] / s->sref[p] * (p + 1 == k ? bl : 1) / rmax, s->gam);
        s->alpha[p] = q / f[p];
        S += q;
    }
    return (log(S) / s->gam + log(rmax)) * (double)k;
}

/* Step (s->mm, nmf_mixes.c minimax): from the prefixes' squared ratios
 * r_p = f_p / sref_p (the last's times s->mm_last), U, V kept in s->ub, vb where their worst is the least
 * so far (s->mm_best), then c_p *= (r_p / max_q r_q)^(eta / 2) scaled to
 * a largest of 1, and alpha_p = c_p / sref_p; returns the worst. */
static double minimax_weights(nmf_state_t *s, const double *f, const double *U, const double *V, size_t k) {
    double worst = 0, top = 0, r[SB_NMF_MAX_TERMS];
    for (size_t p = 0; p < k; p++)
        worst = fmax(worst, r[p] = f[p] / s->sref[p] * (p + 1 == k ? s->mm_last : 1));
    if (worst < s->mm_best) {
        s->mm_best = worst;
        memcpy(s->ub, U, s->m * k * sizeof *s->ub);
        memcpy(s->vb, V, s->n * k * sizeof *s->vb);
    }
    for (size_t p = 0; p < k; p++)
        top = fmax(top, s->mmc[p] *= pow(r[p] / worst, 0.5 * s->mm_eta));
    for (size_t p = 0; p < k; p++) {
        s->mmc[p] /= top;
        s->alpha[p] = s->mmc[p] / s->sref[p];
    }
    return worst;
}

/* Step: the prefixes' weighted errors f_p = ||E_p||^2, p = 1..k, from E
 * = E_k (E_p = E_k + the terms p + 1..k), set the weights alpha_p = 1 /
 * f_p of the next sweep; returns sum_p log f_p (ratio_weights with a
 * reference). */
static double prefix_weights(nmf_state_t *s, double *U, double *V, size_t k) {
    nmf_job_t proto = {s, U, V, k, 0, 0, 0, 1, NULL}, jobs[SB_THREADS_MAX];
    int nt = columns_run(s, prefix_cols, &proto, jobs);
    double F = 0, *f = s->t; /* k numbers */
    for (size_t p = 0; p < k; p++) {
        f[p] = 0;
        for (int t = 0; t < nt; t++) /* fixed order: deterministic */
            f[p] += jobs[t].ws[3 * s->m + p];
        f[p] = fmax(f[p], s->floor2);
        s->alpha[p] = 1 / f[p];
        F += log(f[p]);
    }
    if (s->mm) return minimax_weights(s, f, U, V, k);
    return s->gam > 0 ? ratio_weights(s, f, k) : F;
}

/* Step: one HALS update of term j of the first k, u then v, fitted to
 * every prefix p > j that holds it, prefix p weighted by alpha_p: the
 * target is R = sum_p alpha_p E_p = A E + sum_{q > j} c_q u_q v_q^T with
 * A = sum_{p > j} alpha_p, c_q = sum_{j < p <= q} alpha_p. */
static void nested_term(nmf_state_t *s, double *U, double *V, size_t k, size_t j) {
    size_t m = s->m;
    double A = 0, cq = 0, *u = U + j * m;
    for (size_t p = j + 1; p <= k; p++)
        A += s->alpha[p - 1];
    for (size_t q = j + 1; q < k; q++)
        s->cq[q] = cq += s->alpha[q - 1];
    nmf_job_t proto = {s, U, V, k, j, 0, 0, j + 1 == k ? 1 : A, NULL}, jobs[SB_THREADS_MAX];
    int nt = columns_run(s, term_rows, &proto, jobs);
    double *b = jobs[0].ws, *d = jobs[0].ws + m;
    for (int t = 1; t < nt; t++) /* fixed order: deterministic */
        for (size_t i = 0; i < m; i++) {
            b[i] += jobs[t].ws[i];
            d[i] += jobs[t].ws[m + i];
        }
    for (size_t i = 0; i < m; i++) { /* b becomes the change of u */
        double nu = d[i] > 0 ? fmax(0, u[i] + b[i] / (proto.A * d[i])) : 0;
        b[i] = nu - u[i];
        u[i] = nu;
    }
    for (int t = 1; t < nt; t++)
        memcpy(jobs[t].ws, b, m * sizeof *b);
    columns_run(s, term_cols, &proto, jobs);
}

/* Step: nested HALS sweeps of the first k terms, each sweep a step of
 * majorisation-minimisation of sum_p log ||E_p||^2 (every prefix's error
 * relative to itself: the product of the prefixes' errors, so of their
 * ratios to any reference such as the SVD's), until a sweep gains less
 * than tol per prefix or after `sweeps` (out->iterations counts them all). */
static void hals(nmf_state_t *s, sb_solve_out_t *out, size_t k, int sweeps) {
    sb_nmf_residual(s, out->u, out->v, k);
    double F = prefix_weights(s, out->u, out->v, k);
    out->converged = 0;
    for (int it = 0; it < sweeps && !out->converged; it++, out->iterations++) {
        for (size_t j = 0; j < k; j++)
            nested_term(s, out->u, out->v, k, j);
        double G = prefix_weights(s, out->u, out->v, k);
        out->converged = !s->mm && !(F - G > s->tol * (double)k);
        F = G;
    }
}

void sb_nmf_refit(nmf_state_t *s, sb_solve_out_t *out) { hals(s, out, s->J, s->max_iters); }
void sb_nmf_refit_n(nmf_state_t *s, sb_solve_out_t *out, int n) { hals(s, out, s->J, n); }

/* Step: the stages (see the top): term k - 1 seeded from the positive
 * part of the residual of the terms before it, then the k terms refitted
 * (nested: hals). */
void sb_nmf_stages(nmf_state_t *s, sb_solve_out_t *out) {
    size_t m = s->m, n = s->n;
    memset(out->u, 0, m * s->J * sizeof *out->u);
    memset(out->v, 0, n * s->J * sizeof *out->v);
    out->iterations = 0;
    for (size_t k = 1; k <= s->J; k++) {
        sb_nmf_residual(s, out->u, out->v, k - 1);
        double *v = out->v + (k - 1) * n;
        for (size_t c = 0; c < n; c++)
            for (size_t i = 0; i < m; i++)
                v[c] += fmax(s->e[i + c * m], 0);
        for (int it = 0; it < SB_NMF_SEED_SWEEPS; it++)
            nested_term(s, out->u, out->v, k, k - 1); /* the new term alone, against E */
        hals(s, out, k, k == s->J ? s->max_iters : SB_NMF_STAGE_SWEEPS);
    }
}
