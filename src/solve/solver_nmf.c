/* The non-negative solver: X ~ sum_j u_j v_j^T with u_j, v_j >= 0, fitted
 * by hierarchical alternating least squares (HALS, Cichocki-Phan 2009) on
 * the valid cells of X = W_r A W_c (all cells, invalid ones as zeros,
 * with zero_fill).  Positive weights keep the signs, so the textures
 * g_j = u_j / w_r, h_j = v_j / w_c are non-negative and so is every
 * reconstruction.  Taken for method nmf, with or without a mask.
 *
 * Nested: every prefix of the terms is a fit of its own, as the SVD's
 * are, since `factor` reports (and a shader may use) the first J' < J.
 * The sweeps minimise sum_p log ||W^1/2 o E_p||^2 over the prefixes p =
 * 1..J (E_p = X - the first p terms): the product of the prefixes' errors,
 * so equally of their ratios to the SVD's, scale-free.  Each sweep is a
 * step of majorisation-minimisation: with the weights alpha_p = 1 /
 * ||E_p||^2 of the sweep's start (log f <= log f0 + (f - f0) / f0), term
 * j, held by the prefixes p > j, is updated against
 *     R_j = sum_{p>j} alpha_p E_p,   A_j = sum_{p>j} alpha_p:
 *     u_j(i) <- max(0, u_j(i) + sum_c W(i,c) R_j(i,c) v_j(c) / (A_j sum_c W(i,c) v_j(c)^2))
 * (and v_j likewise), the exact minimiser of the weighted sum in u_j, so
 * no sweep raises it.  A fit stops when a sweep gains less than tol per
 * prefix (in log ||E_p||^2, i.e. relative), or after its sweep cap.
 * With a reference (toward_headline), alpha_p follows the prefixes'
 * ratios to its errors (ratio_weights), and W leans to the headline's.
 *
 * Cells out of the data (masked): bilinear taps of in-domain pairs read
 * those within two texels of the data (fit.h), so there the fit follows
 * the masked fit's extension (what the SVD's lookups read), clipped at 0
 * and bounded by the data around (fit_taps_range), with weight
 * SB_NMF_FILL_WEIGHT; the others are pulled to 0 with SB_NMF_HOLE_WEIGHT.
 *
 * Start: in stages, as the masked fit builds its terms.  Stage k seeds
 * term k from the positive part of the residual of the k - 1 before it
 * (v = column sums of max(E, 0), then rank-one updates of the term
 * alone) and refits the k terms (nested), the last stage up to max_iters
 * sweeps.  An NNDSVD start (Boutsidis-Gallopoulos 2008: the dominant
 * sign part of each SVD pair) leaves terms zero where the SVD's signed
 * terms cancel, and HALS keeps them there: GGX roughness 0.2 on iso
 * fitted the rows of theta_h 9-35 deg to 50-98 % (the peak's rows
 * dominate ||E||), 0.37 headline against the SVD's 0.058; staged, 0.04.
 * A successive-projection start (data columns as the terms) ended where
 * the stages do (rank 2 on the default gold: 5x the SVD's error on the
 * cells, after 3000 sweeps too).
 *
 * Without cells out of the data every cell weighs 1 and the sweeps run
 * on products with X and the factors' Gram matrices (nmf_gram.c); with
 * them, a term's update is two passes over the columns, split among
 * threads (nested_term).
 *
 * The terms come out as s_j = |u_j| |v_j| with unit u_j, v_j, in the
 * order fitted. */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "sepbrdf/param.h"
#include "solve/fit_impl.h"
#include "solve/nmf_gram.h"
#include "solve/nmf_lanes.h"
#include "solve/nmf_weights.h"
#include "solve/solver.h"
#include "util/internal.h"
#include "util/parallel.h"

#define SB_NMF_MAX_ITERS 300
/* Sweeps of a stage before the last (joint refit of the terms so far),
 * and rank-one updates seeding a term. */
#define SB_NMF_STAGE_SWEEPS 50
#define SB_NMF_SEED_SWEEPS 10
/* The same where every cell weighs 1 (nmf_gram.c): 3 sweeps of the new
 * term alone ended where 10 do or better (GGX roughness 0.3 on io, 32
 * cells, J = 4: 1.09, 0.70, 0.70, 0.70x the SVD's headline against
 * 1.01 at J' = 2-4; RGL chm_orange on vndf the same to 3 digits) in 6
 * sweeps of the last stage against 14. */
#define SB_NMF_GRAM_SEED_SWEEPS 3
/* per prefix: the default gold 259 sweeps at 1e-4, 126 at 1e-3, within
 * 0.13x of the SVD's headline (docs/positive.md, "Time, and ..."). */
#define SB_NMF_TOL 1e-3
/* The weight of a cell out of the data and beyond the taps' reach,
 * pulled towards 0, against 1 for a data cell: no lookup reads such a
 * cell, but nothing else bounds a product u_i v_c whose row and column
 * are fitted only elsewhere.  Small, since these cells are many (the
 * default gold on iso: the terms' values there 0.6-0.9 of the data's
 * norm) and every one of them pulls the terms away from the data: the
 * default gold's prefixes at 1e-4 2.05, 2.52, 1.69, 1.92x the SVD's
 * headline (J' = 1-4), at 1e-6 (and SB_NMF_FILL_WEIGHT 0.01) 2.27, 1.38,
 * 1.25, 1.35x (docs/positive.md, "The cells no lookup reads"). */
#define SB_NMF_HOLE_WEIGHT 1e-6
/* The weight of a cell within the taps' reach, against 1 for a data cell,
 * towards the masked fit's extension: at 1 it cost the cells' error (the
 * default gold: 3.4e-3 against 2.1e-3 at J = 4), at 0 (the data alone)
 * the headline on hd (GGX 0.3, 16 cells: 2.5x the SVD's at J = 4 against
 * 1.9x at 0.1); 0.01 with the hole weight 1e-6 (above). */
#define SB_NMF_FILL_WEIGHT 0.01
/* The data cells' weights: 1 - mu + mu x the headline's own weight of the
 * cell over its mean (nmf_weights.c), mu = SB_NMF_HEADLINE_MIX.  The fit
 * then trades its error where the headline measures it, and still
 * everywhere the SVD beside fits (the bands near the horizon).  Measured
 * (our runs, 32 cells, J = 4, nmf_over_svd at J' = 1..4): RGL
 * cc_green_malachite on vndf 1.45, 1.42, 3.65, 2.08 at mu = 0; 0.97, 1.48,
 * 0.56, 1.95 at 0.2; 0.96, 1.45, 0.59, 2.16 at 0.5; at 1 (the headline's
 * weights alone) 0.93, 2.45, 1.78, 8.84 (docs/positive.md has the rest). */
#define SB_NMF_HEADLINE_MIX 0.5
/* A second fit at this mix, the one kept whose worst prefix in the
 * headline's weights is lower against the reference
 * (sb_nmf_worst_ratio), on matrices of at most SB_NMF_MIX_CELLS cells
 * (vndf 8 x 1024; iso at 32 cells 64 x 992; not hd, 1024^2, where a
 * second fit costs seconds).  Measured (our runs, J = 4, the worst
 * nmf_over_svd over J' = 1..4, one fit -> the better of two): RGL on
 * vndf aurora 1.64 -> 1.59, malachite 1.70 -> 1.72, chm_light_blue 2.13
 * -> 1.84, chm_orange 1.65 -> 1.46, paper 2.14 -> 1.86, silk 1.82 ->
 * 1.75; the default gold 1.86 -> 1.66 (docs/positive.md). */
#define SB_NMF_SECOND_MIX 0.8
#define SB_NMF_MIX_CELLS ((size_t)1 << 17)
/* A third fit at the headline's own weights (mu = 1) on unmasked matrices
 * of at most SB_NMF_THIRD_CELLS cells (vndf), kept by this margin on the
 * squared ratio: the proxy misses vndf's interpolation between rows (RGL
 * malachite, red: 1.279 against 1.289 kept, J' = 4 1.72 -> 2.42x the
 * SVD's headline); chm_light_blue 1.84 -> 1.49, silk 1.75 -> 1.49. */
#define SB_NMF_THIRD_CELLS ((size_t)1 << 14)
#define SB_NMF_THIRD_MARGIN 0.81
/* The prefixes' errors weighted by their ratio to a reference's (the
 * masked fit beside, or the SVD where no cell is masked) raised to this
 * power: sum_p log ||E_p||^2 becomes k log (sum_p r_p^gamma)^(1/gamma), r_p =
 * ||E_p||^2 / ||E_p^ref||^2, a soft maximum of the ratios the issue bounds
 * (0: the product of the errors).  Only for J <= min(m, n) / 2: near the
 * matrix's rank the SVD's last prefixes are exact and their ratios, out of
 * reach, took the sweeps from the others (RGL files on vndf, 8 rows, J =
 * 8: up to 13x at J' <= 6, against 2.4-10x with the product). */
#define SB_NMF_RATIO_POWER 2.0
/* Cells of a matrix without masked cells above which the sweeps run from
 * products (nmf_gram.c: every cell weighs 1, no reference): io at 32
 * cells, 1024 x 1024.  Below, the cells are weighted (vndf: 8 x 1024). */
#define SB_NMF_WEIGHTED_CELLS ((size_t)1 << 16)

typedef struct nmf_state {
    size_t m, n, J;
    int max_iters, zero_fill;
    double tol, fill;     /* fill: the weight of the cells out of the data (ext 2) */
    double floor2;        /* the least ||E_p||^2 a prefix weight takes: 1e-24 of the data's */
    double *e;            /* m x n: masked residual of all the terms fitted */
    double *r;            /* m x n: the weighted sum of the prefixes' residuals a term is fitted to */
    double *alpha;        /* J: the prefixes' weights 1 / ||E_p||^2 (prefix_weights) */
    double *cq;           /* J: the terms' weights in a term's target (nested_term) */
    double *tw;           /* nt x (3 m + J): the parts' numbers (nmf_job_t) */
    int nt;               /* parts at most */
    double *x;            /* m x n: the data, and the targets of the cells within the taps' reach */
    double *w;            /* m x n: the cells' weights (cell_weights) */
    unsigned char *ext;   /* m x n: 1 data, 2 within the taps' reach, 0 beyond */
    double *t;            /* 2 m + J numbers (prefix_weights) */
    double *uref, *vref;  /* m x J, n x J: the reference's terms (toward_headline) */
    double *sref;         /* J: the reference's prefixes' errors, in the fit's weights */
    double gam;           /* SB_NMF_RATIO_POWER where a reference is known, else 0 */
    double *hw;           /* m x n: the headline's weights of the data cells (toward_headline) */
    double *w0, *ub, *vb; /* m x n, m x J, n x J: the weights and the terms of the first mix (fit_mixes) */
    int hw_ok;            /* hw holds them for hw_key (the channels of a matrix share them) */
    int conv;             /* whether the fit in ub, vb converged (fit_mix) */
    double hw_key[3];     /* the layout's address, the form, a sum over the data cells */
    sb_fit_t *fit;        /* masked: the masked fit whose extension fills the cells out of the data */
    sb_fit_opts_t fo;
} nmf_state_t;

static void destroy(void *state) {
    nmf_state_t *s = state;
    if (!s) return;
    free(s->e);
    free(s->r);
    free(s->alpha);
    free(s->cq);
    free(s->tw);
    free(s->x);
    free(s->w);
    free(s->ext);
    free(s->t);
    free(s->uref);
    free(s->vref);
    free(s->sref);
    free(s->hw);
    free(s->w0);
    free(s->ub);
    free(s->vb);
    sb_fit_destroy(s->fit);
    free(s);
}

static sb_result_t plan(sb_context_t *ctx, const sb_solve_problem_t *pb, void **state) {
    nmf_state_t *s = sb_calloc(ctx, 1, sizeof *s, "nmf plan");
    if (!s) return SB_ERR_NOMEM;
    s->m = pb->rows;
    s->n = pb->cols;
    s->J = pb->terms;
    /* the plan's fit_max_iters and fit_tol (the masked fit's, stopped
     * early by auto) only tighten the sweeps: 20 sweeps at 1e-3 left the
     * nested prefixes up to 1.3x further from the SVD's */
    s->max_iters = pb->fit_max_iters > SB_NMF_MAX_ITERS ? pb->fit_max_iters : SB_NMF_MAX_ITERS;
    s->zero_fill = pb->zero_fill;
    s->tol = pb->fit_tol > 0 && pb->fit_tol < SB_NMF_TOL ? pb->fit_tol : SB_NMF_TOL;
    size_t cells = s->m * s->n; /* checked by the plan */
    s->e = sb_alloc(ctx, cells, sizeof(double), "nmf plan");
    s->r = sb_alloc(ctx, cells, sizeof(double), "nmf plan");
    s->alpha = sb_alloc(ctx, s->J, sizeof(double), "nmf plan");
    s->cq = sb_alloc(ctx, s->J, sizeof(double), "nmf plan");
    s->nt = sb_thread_count(0);
    s->tw = sb_alloc(ctx, (size_t)s->nt * (3 * s->m + s->J), sizeof(double), "nmf plan");
    s->x = sb_alloc(ctx, cells, sizeof(double), "nmf plan");
    s->w = sb_alloc(ctx, cells, sizeof(double), "nmf plan");
    s->ext = sb_alloc(ctx, cells, 1, "nmf plan");
    s->t = sb_alloc(ctx, 2 * s->m + s->J, sizeof(double), "nmf plan");
    s->uref = sb_alloc(ctx, s->m * s->J, sizeof(double), "nmf plan");
    s->vref = sb_alloc(ctx, s->n * s->J, sizeof(double), "nmf plan");
    s->sref = sb_alloc(ctx, s->J, sizeof(double), "nmf plan");
    /* headline weights where the sweeps weigh cells, w0 for fit_mixes */
    int weighted = (pb->masked && !pb->zero_fill) || cells <= SB_NMF_WEIGHTED_CELLS || s->J > SB_NMF_GRAM_MAX_TERMS;
    s->hw = weighted ? sb_alloc(ctx, cells, sizeof(double), "nmf plan") : NULL;
    s->w0 = weighted && cells <= SB_NMF_MIX_CELLS ? sb_alloc(ctx, cells, sizeof(double), "nmf plan") : NULL;
    s->ub = sb_alloc(ctx, s->m * s->J, sizeof(double), "nmf plan");
    s->vb = sb_alloc(ctx, s->n * s->J, sizeof(double), "nmf plan");
    if (!s->e || !s->r || !s->alpha || !s->cq || !s->tw || !s->x || !s->w || !s->ext || !s->t || !s->uref || !s->vref ||
        !s->sref || (weighted && !s->hw) || (weighted && cells <= SB_NMF_MIX_CELLS && !s->w0) || !s->ub || !s->vb) {
        destroy(s);
        return SB_ERR_NOMEM;
    }
    s->fo = (sb_fit_opts_t){pb->fit_max_iters, pb->fit_tol, pb->svd.seed, 0, {{0, 0}, {0, 0}}, {{0, 0}, {0, 0}}};
    sb_result_t r = pb->masked && !pb->zero_fill ? sb_fit_create(ctx, s->m, s->n, s->J, &s->fit) : SB_OK;
    if (r != SB_OK) {
        destroy(s);
        return r;
    }
    *state = s;
    return SB_OK;
}

/* Whether cell (i, c) has a target (ext != 0). */
static int valid(const nmf_state_t *s, size_t i, size_t c) { return s->ext[i + c * s->m] != 0; }

/* Step: the weight of every cell in the fit (s->w): 1 for the data, the
 * fill weight within the taps' reach, SB_NMF_HOLE_WEIGHT beyond (target
 * 0).  Kept as numbers, so that the sweeps' loops have no branches. */
static void cell_weights(nmf_state_t *s) {
    for (size_t k = 0; k < s->m * s->n; k++) {
        unsigned char e = s->ext[k];
        s->w[k] = e == 1 ? 1 : (e == 2 ? s->fill : SB_NMF_HOLE_WEIGHT);
    }
}

/* Step: E = M o (X - U V^T) of the first k terms; returns ||E||^2. */
static double residual(nmf_state_t *s, const double *U, const double *V, size_t k) {
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
 * the prefixes' errors (prefix_cols). */
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
static void *term_rows(void *arg) {
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
static void *term_cols(void *arg) {
    nmf_job_t *jb = arg;
    nmf_state_t *s = jb->s;
    size_t m = s->m, n = s->n, j = jb->j;
    const double *du = jb->ws, *u = jb->U + j * m;
    double *v = jb->V + j * n, A = jb->A;
    int own = j + 1 < jb->k; /* R apart from E */
    for (size_t col = jb->c0; col < jb->c1; col++) {
        double *e = s->e + col * m, *rc = own ? s->r + col * m : e, b, d;
        if (v[col] != 0) {
            axpy_neg(e, du, v[col], m);
            if (own) axpy_neg(rc, du, A * v[col], m);
        }
        wdot(s->w + col * m, rc, u, m, &b, &d);
        double nv = d > 0 ? fmax(0, v[col] + b / (A * d)) : 0, dv = nv - v[col];
        v[col] = nv;
        if (dv == 0) continue;
        axpy_neg(e, u, dv, m);
        if (own) axpy_neg(rc, u, A * dv, m);
    }
    return NULL;
}

/* Job: f_p = sum over the part's columns of W E_p^2, p = k..1 (E_p = E_k
 * + the terms p + 1..k), in the part's f. */
static void *prefix_cols(void *arg) {
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
 * enough: every core for the default gold's 64 x 992 cells); returns the
 * number of parts. */
static int columns_run(nmf_state_t *s, void *(*fn)(void *), const nmf_job_t *proto, nmf_job_t *jobs) {
    int nt = sb_threads_for(0, s->n, s->m * s->n * proto->k, (size_t)1 << 17);
    if (nt > s->nt) nt = s->nt;
    for (int t = 0; t < nt; t++) {
        jobs[t] = *proto;
        jobs[t].ws = s->tw + (size_t)t * (3 * s->m + s->J);
        sb_part(s->n, t, nt, &jobs[t].c0, &jobs[t].c1);
    }
    sb_parallel_run(fn, jobs, sizeof *jobs, nt, NULL, NULL);
    return nt;
}

/* Step: with the ratios r_p = f_p / sref_p (rmax their largest), the
 * weights alpha_p = (r_p / rmax)^gamma / f_p, the gradient of k log (sum_p
 * r_p^gamma)^(1/gamma), returned (SB_NMF_RATIO_POWER). */
static double ratio_weights(nmf_state_t *s, const double *f, size_t k) {
    double rmax = 0, S = 0;
    for (size_t p = 0; p < k; p++)
        rmax = fmax(rmax, f[p] / s->sref[p]);
    for (size_t p = 0; p < k; p++) {
        double q = pow(f[p] / s->sref[p] / rmax, s->gam);
        s->alpha[p] = q / f[p];
        S += q;
    }
    return (log(S) / s->gam + log(rmax)) * (double)k;
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
    residual(s, out->u, out->v, k);
    double F = prefix_weights(s, out->u, out->v, k);
    out->converged = 0;
    for (int it = 0; it < sweeps && !out->converged; it++, out->iterations++) {
        for (size_t j = 0; j < k; j++)
            nested_term(s, out->u, out->v, k, j);
        double G = prefix_weights(s, out->u, out->v, k);
        out->converged = !(F - G > s->tol * (double)k);
        F = G;
    }
}

/* Step: the stages (see the top): term k - 1 seeded from the positive
 * part of the residual of the terms before it, then the k terms refitted
 * (nested: hals). */
static void stages(nmf_state_t *s, sb_solve_out_t *out) {
    size_t m = s->m, n = s->n;
    memset(out->u, 0, m * s->J * sizeof *out->u);
    memset(out->v, 0, n * s->J * sizeof *out->v);
    out->iterations = 0;
    for (size_t k = 1; k <= s->J; k++) {
        residual(s, out->u, out->v, k - 1);
        double *v = out->v + (k - 1) * n;
        for (size_t c = 0; c < n; c++)
            for (size_t i = 0; i < m; i++)
                v[c] += fmax(s->e[i + c * m], 0);
        for (int it = 0; it < SB_NMF_SEED_SWEEPS; it++)
            nested_term(s, out->u, out->v, k, k - 1); /* the new term alone, against E */
        hals(s, out, k, k == s->J ? s->max_iters : SB_NMF_STAGE_SWEEPS);
    }
}

/* Step: the cells out of the data (masked) take as targets the masked
 * fit's extension there (the SVD's lookups near the domain's edge read
 * it; fit.h bounds what bilinear taps reach), clipped at 0, with weight
 * fill (ext 2). */
static sb_result_t fill_holes(nmf_state_t *s, const sb_solve_in_t *in, sb_solve_out_t *out) {
    sb_fit_opts_t o = s->fo;
    for (int side = 0; in->param && side < 2; side++) {
        sb_param_texture_size(in->param, side, &o.tex[side][0], &o.tex[side][1]);
        sb_param_wrap(in->param, side, o.wrap[side]);
    }
    sb_fit_info_t fi;
    sb_result_t r = sb_fit_execute(s->fit, s->x, s->m, s->ext, &o, out->s, out->u, out->v, &fi);
    if (r != SB_OK || !in->param) return r;
    double *lo = s->e, *hi = s->r; /* free until the stages */
    if (fit_taps_range(&o, s->m, s->n, s->x, s->ext, lo, hi) != 0) return SB_ERR_NOMEM;
    for (size_t c = 0; c < s->n; c++)
        for (size_t i = 0; i < s->m; i++) {
            size_t k = i + c * s->m;
            if (s->ext[k] || !(lo[k] <= hi[k])) continue;
            double y = 0, d = hi[k] - lo[k] + 0.5 * fmax(fabs(lo[k]), fabs(hi[k]));
            for (size_t j = 0; j < s->J; j++)
                y += out->s[j] * out->u[i + j * s->m] * out->v[c + j * s->n];
            s->x[k] = fmin(fmax(y, fmax(lo[k] - d, 0)), hi[k] + d);
            s->ext[k] = 2;
        }
    return SB_OK;
}

/* Step: the headline's weights of the data cells in s->hw, once for the
 * channels of a matrix (the same layout, form and data cells); returns
 * whether they are there. */
static int headline_weights(nmf_state_t *s, const sb_solve_in_t *in) {
    if (!in->param || !in->m || !s->hw) return 0;
    double key[3] = {(double)(uintptr_t)in->param, (double)in->m->form, 0};
    for (size_t k = 0; k < s->m * s->n; k++)
        key[2] += s->ext[k] == 1 ? (double)(k % 65521) : 0;
    if (s->hw_ok && !memcmp(key, s->hw_key, sizeof key)) return 1;
    s->hw_ok = sb_nmf_headline_weights(in->param, in->m->form, s->ext, s->m, s->n, s->hw) == 0;
    memcpy(s->hw_key, key, sizeof key);
    return s->hw_ok;
}

/* Step: the data cells' weights mixed toward the headline's (mu of
 * them), and the reference's prefixes' errors in the fit's weights: the
 * masked fit fill_holes left in out, or the SVD (no cell masked), taken
 * unless `again` (the reference of the fit before); without one the
 * prefixes' errors are fitted alone (gam 0). */
static void toward_headline(nmf_state_t *s, const sb_solve_in_t *in, const sb_solve_out_t *out, double mu, int again) {
    size_t m = s->m, n = s->n, J = s->J;
    if (headline_weights(s, in))
        for (size_t k = 0; k < m * n; k++)
            if (s->ext[k] == 1) s->w[k] *= 1 - mu + mu * s->hw[k];
    s->gam = 0;
    if (2 * J > (m < n ? m : n)) return;
    for (size_t j = 0; !again && s->fit && j < J; j++) {
        for (size_t i = 0; i < m; i++)
            s->uref[i + j * m] = out->s[j] * out->u[i + j * m];
        memcpy(s->vref + j * n, out->v + j * n, n * sizeof *s->vref);
    }
    if (!again && !s->fit && sb_nmf_svd_terms(s->x, m, n, J, s->uref, s->vref) != 0) return;
    for (size_t k = 1; k <= J; k++)
        s->sref[k - 1] = fmax(residual(s, s->uref, s->vref, k), s->floor2);
    s->gam = SB_NMF_RATIO_POWER;
}

/* Step: the stages at `mix` (the reference of the fit before, `again`);
 * the fit kept in ub, vb when its worst prefix in the headline's weights
 * is below `margin` times *best (which it then becomes). */
static void fit_mix(nmf_state_t *s, const sb_solve_in_t *in, sb_solve_out_t *out, double mix, int again, double margin,
                    double *best) {
    size_t m = s->m, n = s->n, J = s->J;
    int sweeps = out->iterations;
    memcpy(s->w, s->w0, m * n * sizeof *s->w);
    toward_headline(s, in, out, mix, again);
    stages(s, out);
    out->iterations += again ? sweeps : 0;
    if (!s->hw_ok || !(s->gam > 0)) return;
    double r = sb_nmf_worst_ratio(s->x, s->hw, m, n, J, out->u, out->v, s->uref, s->vref, s->floor2);
    if (again && !(r < margin * *best)) return;
    *best = r;
    s->conv = out->converged;
    memcpy(s->ub, out->u, m * J * sizeof *s->ub);
    memcpy(s->vb, out->v, n * J * sizeof *s->vb);
}

/* Step: the stages at SB_NMF_HEADLINE_MIX, where the matrix is small and
 * a reference known at SB_NMF_SECOND_MIX and (smaller) at 1 too: the fit
 * kept whose worst prefix in the headline's weights is the lowest against
 * the reference (out->iterations counts them all). */
static void fit_mixes(nmf_state_t *s, const sb_solve_in_t *in, sb_solve_out_t *out) {
    size_t m = s->m, n = s->n, J = s->J;
    if (!s->w0) {
        toward_headline(s, in, out, SB_NMF_HEADLINE_MIX, 0);
        stages(s, out);
        return;
    }
    memcpy(s->w0, s->w, m * n * sizeof *s->w0);
    double best = INFINITY;
    fit_mix(s, in, out, SB_NMF_HEADLINE_MIX, 0, 1, &best);
    if (!s->hw_ok || !(s->gam > 0)) return;
    fit_mix(s, in, out, SB_NMF_SECOND_MIX, 1, 1, &best);
    if (!s->fit && m * n <= SB_NMF_THIRD_CELLS) fit_mix(s, in, out, 1, 1, SB_NMF_THIRD_MARGIN, &best);
    memcpy(out->u, s->ub, m * J * sizeof *s->ub);
    memcpy(out->v, s->vb, n * J * sizeof *s->vb);
    out->converged = s->conv;
}

static sb_result_t execute(void *state, const sb_solve_in_t *in, sb_solve_out_t *out) {
    nmf_state_t *s = state;
    size_t m = s->m, n = s->n;
    int masked = in->mask && !s->zero_fill;
    for (size_t c = 0; c < n; c++)
        for (size_t i = 0; i < m; i++) {
            s->x[i + c * m] = in->x[i + c * in->ldx];
            s->ext[i + c * m] = !masked || in->mask[i + c * in->lda];
        }
    s->floor2 = 0;
    for (size_t k = 0; k < m * n; k++)
        s->floor2 += s->ext[k] ? s->x[k] * s->x[k] : 0;
    s->floor2 = fmax(s->floor2 * 1e-24, DBL_MIN);
    s->fill = SB_NMF_FILL_WEIGHT;
    sb_result_t r = s->fit ? fill_holes(s, in, out) : SB_OK;
    if (r != SB_OK) return r;
    cell_weights(s);
    s->gam = 0;
    if (!masked && s->J <= SB_NMF_GRAM_MAX_TERMS && m * n > SB_NMF_WEIGHTED_CELLS) {
        /* every cell weighs 1: from products with X */
        sb_nmf_gram_opts_t go = {s->max_iters, SB_NMF_STAGE_SWEEPS, SB_NMF_GRAM_SEED_SWEEPS, s->tol, s->floor2};
        if (sb_nmf_gram_fit(&go, s->x, m, n, s->J, out->u, out->v, &out->iterations, &out->converged) != 0)
            return SB_ERR_NOMEM;
    } else
        fit_mixes(s, in, out);
    sb_nmf_normalise(m, n, s->J, out->s, out->u, out->v);
    return SB_OK;
}

const sb_solver_t sb_solver_nmf = {.name = "nmf",
                                   .description = "non-negative factors (nested HALS, terms added in stages) on the "
                                                  "valid cells: every texel and reconstruction >= 0",
                                   .caps = SB_CAP_NONNEG | SB_CAP_MASKS | SB_CAP_METHOD,
                                   .plan = plan,
                                   .destroy = destroy,
                                   .execute = execute,
                                   .note = "non-negative factors and a sampler"};
