/* The non-negative solver: X ~ sum_j u_j v_j^T with u_j, v_j >= 0, fitted
 * by hierarchical alternating least squares (HALS, Cichocki-Phan 2009) on
 * the valid cells of X = W_r A W_c (all cells, invalid ones as zeros,
 * with zero_fill).  Positive weights keep the signs, so
 * the textures g_j = u_j / w_r, h_j = v_j / w_c are non-negative and so is
 * every reconstruction.  Taken for method nmf, with or without a mask.
 *
 * One HALS sweep updates each term in turn, u_j then v_j, against the
 * residual E = M o X - U V^T, weighted by W (1 on the valid cells of M;
 * on the others 0, or during the stages SB_NMF_HOLE_WEIGHT: pulled to 0):
 *     u_j(i) <- max(0, u_j(i) + sum_c W(i,c) E(i,c) v_j(c) / sum_c W(i,c) v_j(c)^2)
 * (and E updated with the change), which never raises ||W^1/2 o E||; a fit stops
 * when a sweep gains less than tol relative, or after its sweep cap.
 *
 * Start: in stages, as the masked fit builds its terms.  Stage k seeds
 * term k from the positive part of the residual of the k - 1 before it
 * (v = column sums of max(E, 0), then rank-one updates of the term
 * alone) and refits the k terms jointly, the last stage up to max_iters
 * sweeps; the stages weigh the cells outside the data with
 * SB_NMF_HOLE_WEIGHT, then up to max_iters sweeps fit the data alone (a
 * low-rank matrix with holes is then recovered exactly).  An NNDSVD start (Boutsidis-Gallopoulos 2008: the dominant
 * sign part of each SVD pair) leaves terms zero where the SVD's signed terms cancel, and HALS keeps them there: GGX
 * roughness 0.2 on iso fitted the rows of theta_h 9-35 deg to 50-98 % (the peak's rows dominate ||E||), 0.37 headline
 * against the SVD's 0.058; staged, 0.04.
 *
 * The terms come out as s_j = |u_j| |v_j| with unit u_j, v_j, ordered
 * greedily: each next term is the one that lowers ||E|| of the prefix
 * most.  Unlike the SVD's, the first J' < J terms are not the best
 * J'-term fit: the plan's errors for J' are those of this prefix. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sepbrdf/param.h"
#include "solve/fit_impl.h"
#include "solve/solver.h"
#include "util/internal.h"

#define SB_NMF_MAX_ITERS 300
/* Sweeps of a stage before the last (joint refit of the terms so far),
 * and rank-one updates seeding a term. */
#define SB_NMF_STAGE_SWEEPS 50
#define SB_NMF_SEED_SWEEPS 10
#define SB_NMF_TOL 1e-5
/* The weight of a masked cell during the stages, pulled towards 0, against
 * 1 for a data cell: without it nothing bounds a product u_i v_c whose row
 * and column are fitted only elsewhere, and the fit the stages leave stays
 * there (GGX roughness 0.5 on iso, 32 cells: 2400 beside texels of 7 near
 * the horizon, headline 6.8x the SVD's; with it, then the data alone,
 * 1.02x); 1e-4 leaves a cell near the data (~5) at 2.5e-3 of that fit's
 * squared error.  1e-3 pulled the lookups at the domain's edge down (GGX
 * roughness 0.2: 0.66 -> 1.66 of the SVD's). */
#define SB_NMF_HOLE_WEIGHT 1e-4
/* The taps' constraints are kept while the data's cells' error stays
 * within SB_TAPS_COST of the fit without them (as in the masked fit), or
 * below this fraction of the data's norm: a non-negative fit that follows
 * the cells closely can extend them badly (iso, GGX roughness 0.5, 32
 * cells: 0.36 % on the cells, 3.7 % out of sample; constrained 0.94 % and
 * 0.8 %, the SVD's 1.3 %).  At 0.02 it also kept constraints that took a
 * staged fit's error on the cells from 0.5 % to 1.4 %, all of it in the
 * rows of the diffuse floor (GGX roughness 0.3 and 0.4 on iso,
 * 32 cells: headline 2.9x and 7.6x the SVD's; at 0.005 0.84x and 0.93x). */
#define SB_NMF_TAPS_FLOOR 0.005

typedef struct nmf_state {
    size_t m, n, J;
    int max_iters, zero_fill;
    double tol, hole;   /* hole: the weight of the cells that are not data */
    double *e;          /* m x n: masked residual */
    double *x;          /* m x n: the data, and the targets of cells the taps' constraints join */
    unsigned char *ext; /* m x n: 1 valid, 2 joined by the taps' constraints, 0 left out */
    double *t;          /* 2 m sums */
    double *u1, *v1;    /* the fit before the taps' constraints, m x J, n x J */
} nmf_state_t;

static void destroy(void *state) {
    nmf_state_t *s = state;
    if (!s) return;
    free(s->e);
    free(s->x);
    free(s->ext);
    free(s->u1);
    free(s->v1);
    free(s->t);
    free(s);
}

static sb_result_t plan(sb_context_t *ctx, const sb_solve_problem_t *pb, void **state) {
    nmf_state_t *s = sb_calloc(ctx, 1, sizeof *s, "nmf plan");
    if (!s) return SB_ERR_NOMEM;
    s->m = pb->rows;
    s->n = pb->cols;
    s->J = pb->terms;
    s->max_iters = pb->fit_max_iters > 0 ? pb->fit_max_iters : SB_NMF_MAX_ITERS;
    s->zero_fill = pb->zero_fill;
    s->tol = pb->fit_tol > 0 ? pb->fit_tol : SB_NMF_TOL;
    size_t cells = s->m * s->n; /* checked by the plan */
    s->e = sb_alloc(ctx, cells, sizeof(double), "nmf plan");
    s->x = sb_alloc(ctx, cells, sizeof(double), "nmf plan");
    s->ext = sb_alloc(ctx, cells, 1, "nmf plan");
    s->t = sb_alloc(ctx, 2 * s->m, sizeof(double), "nmf plan");
    s->u1 = sb_alloc(ctx, s->m, s->J * sizeof(double), "nmf plan");
    s->v1 = sb_alloc(ctx, s->n, s->J * sizeof(double), "nmf plan");
    if (!s->e || !s->x || !s->ext || !s->t || !s->u1 || !s->v1) {
        destroy(s);
        return SB_ERR_NOMEM;
    }
    *state = s;
    return SB_OK;
}

/* Whether cell (i, c) is data (ext != 0). */
static int valid(const nmf_state_t *s, size_t i, size_t c) { return s->ext[i + c * s->m] != 0; }

/* The weight of cell (i, c) in the fit: 1 for the data, SB_NMF_HOLE_WEIGHT for the others (target 0). */
static double wt(const nmf_state_t *s, size_t i, size_t c) { return s->ext[i + c * s->m] ? 1 : s->hole; }

/* Step: E = M o (X - U V^T) of the first k terms; returns ||E||^2. */
static double residual(nmf_state_t *s, const double *U, const double *V, size_t k) {
    double f = 0;
    for (size_t c = 0; c < s->n; c++)
        for (size_t i = 0; i < s->m; i++) {
            double r = valid(s, i, c) ? s->x[i + c * s->m] : 0;
            for (size_t j = 0; j < k; j++)
                r -= U[i + j * s->m] * V[c + j * s->n];
            s->e[i + c * s->m] = r;
            f += wt(s, i, c) * r * r;
        }
    return f;
}

/* Step: HALS update of u (rows) against v, with E kept current. */
static void update_rows(nmf_state_t *s, double *u, const double *v) {
    size_t m = s->m;
    double *b = s->t, *d = s->t + m, *e = s->e;
    memset(s->t, 0, 2 * m * sizeof *s->t);
    for (size_t c = 0; c < s->n; c++)
        for (size_t i = 0; i < m; i++) {
            double w = wt(s, i, c);
            b[i] += w * e[i + c * m] * v[c];
            d[i] += w * v[c] * v[c];
        }
    for (size_t i = 0; i < m; i++) { /* b becomes the change of u */
        double nu = d[i] > 0 ? fmax(0, u[i] + b[i] / d[i]) : 0;
        b[i] = nu - u[i];
        u[i] = nu;
    }
    for (size_t c = 0; c < s->n; c++)
        for (size_t i = 0; i < m; i++)
            e[i + c * m] -= b[i] * v[c];
}

/* Step: HALS update of v (columns) against u, with E kept current. */
static void update_cols(nmf_state_t *s, const double *u, double *v) {
    size_t m = s->m;
    for (size_t c = 0; c < s->n; c++) {
        double *e = s->e + c * m, b = 0, d = 0;
        for (size_t i = 0; i < m; i++) {
            double w = wt(s, i, c);
            b += w * e[i] * u[i];
            d += w * u[i] * u[i];
        }
        double nv = d > 0 ? fmax(0, v[c] + b / d) : 0, dv = nv - v[c];
        v[c] = nv;
        for (size_t i = 0; dv != 0 && i < m; i++)
            e[i] -= u[i] * dv;
    }
}

/* Swap terms a and b (sigma, columns of U and V). */
static void swap_terms(const nmf_state_t *s, double *sig, double *U, double *V, size_t a, size_t b) {
    double t = sig[a];
    sig[a] = sig[b];
    sig[b] = t;
    for (size_t i = 0; i < s->m; i++)
        t = U[i + a * s->m], U[i + a * s->m] = U[i + b * s->m], U[i + b * s->m] = t;
    for (size_t i = 0; i < s->n; i++)
        t = V[i + a * s->n], V[i + a * s->n] = V[i + b * s->n], V[i + b * s->n] = t;
}

/* Change of ||E||^2 when the product u v^T leaves E (over the fitted
 * cells; sign +1) or joins it (-1): sum (E - sg u v)^2 - E^2. */
static double term_gain(const nmf_state_t *s, const double *u, const double *v, double sg) {
    double d = 0;
    for (size_t c = 0; c < s->n; c++)
        for (size_t i = 0; i < s->m; i++)
            if (valid(s, i, c)) {
                double p = sg * u[i] * v[c];
                d += p * (p - 2 * s->e[i + c * s->m]);
            }
    return d;
}

/* Step: s_j = |u_j| |v_j| with unit u_j, v_j; then, from E = M o X, each
 * next place takes the term that lowers ||E|| most (E less it after). */
static void normalise(nmf_state_t *s, double *sig, double *U, double *V) {
    size_t m = s->m, n = s->n;
    for (size_t j = 0; j < s->J; j++) {
        double nu = 0, nv = 0, *u = U + j * m, *v = V + j * n;
        for (size_t i = 0; i < m; i++)
            nu += u[i] * u[i];
        for (size_t i = 0; i < n; i++)
            nv += v[i] * v[i];
        nu = sqrt(nu);
        nv = sqrt(nv);
        sig[j] = nu * nv;
        for (size_t i = 0; nu > 0 && i < m; i++)
            u[i] /= nu;
        for (size_t i = 0; nv > 0 && i < n; i++)
            v[i] /= nv;
    }
    residual(s, U, V, 0);
    for (size_t p = 0; p + 1 < s->J; p++) {
        size_t best = p;
        double gbest = INFINITY;
        for (size_t j = p; j < s->J; j++) {
            double g = sig[j] > 0 ? term_gain(s, U + j * m, V + j * n, sig[j]) : 0;
            if (g < gbest) gbest = g, best = j;
        }
        swap_terms(s, sig, U, V, p, best);
        for (size_t c = 0; c < n; c++)
            for (size_t i = 0; i < m; i++)
                if (valid(s, i, c)) s->e[i + c * m] -= sig[p] * U[i + p * m] * V[c + p * n];
    }
}

/* Step: HALS sweeps of the first k terms of U, V until a sweep gains
 * less than tol relative or after `sweeps` (out->iterations counts them
 * all). */
static void hals(nmf_state_t *s, sb_solve_out_t *out, size_t k, int sweeps) {
    size_t m = s->m, n = s->n;
    double f = residual(s, out->u, out->v, k);
    out->converged = 0;
    for (int it = 0; it < sweeps && !out->converged; it++, out->iterations++) {
        for (size_t j = 0; j < k; j++) {
            update_rows(s, out->u + j * m, out->v + j * n);
            update_cols(s, out->u + j * m, out->v + j * n);
        }
        double g = 0;
        for (size_t c = 0; c < n; c++)
            for (size_t i = 0; i < m; i++)
                g += wt(s, i, c) * s->e[i + c * m] * s->e[i + c * m];
        out->converged = !(f > 0) || f - g <= s->tol * f;
        f = g;
    }
}

/* Step: the stages (see the top): term k - 1 seeded from the positive
 * part of the residual of the terms before it, then the k terms refitted
 * jointly. */
static void stages(nmf_state_t *s, sb_solve_out_t *out) {
    size_t m = s->m, n = s->n;
    memset(out->u, 0, m * s->J * sizeof *out->u);
    memset(out->v, 0, n * s->J * sizeof *out->v);
    out->iterations = 0;
    for (size_t k = 1; k <= s->J; k++) {
        residual(s, out->u, out->v, k - 1);
        double *u = out->u + (k - 1) * m, *v = out->v + (k - 1) * n;
        for (size_t c = 0; c < n; c++)
            for (size_t i = 0; i < m; i++)
                v[c] += fmax(s->e[i + c * m], 0);
        for (int it = 0; it < SB_NMF_SEED_SWEEPS; it++) {
            update_rows(s, u, v);
            update_cols(s, u, v);
        }
        hals(s, out, k, k == s->J ? s->max_iters : SB_NMF_STAGE_SWEEPS);
    }
}

/* ||M o (X - U V^T)||^2 over the data's own cells (ext 1). */
static double data_err2(const nmf_state_t *s, const double *U, const double *V) {
    double f = 0;
    for (size_t c = 0; c < s->n; c++)
        for (size_t i = 0; i < s->m; i++) {
            if (s->ext[i + c * s->m] != 1) continue;
            double r = s->x[i + c * s->m];
            for (size_t j = 0; j < s->J; j++)
                r -= U[i + j * s->m] * V[c + j * s->n];
            f += r * r;
        }
    return f;
}

/* Step: the masked fit's bound on what bilinear taps of in-domain pairs
 * read outside the data (fit_constrain_taps: an invalid cell near valid
 * ones whose product overshoots them joins the data, clamped into their
 * range), then HALS again, twice at most; the fit before is kept when the
 * constraints cost the data's cells more than SB_TAPS_COST in error and
 * more than SB_NMF_TAPS_FLOOR of their norm (data that the factors extend
 * exactly are their own best extrapolation).  Without this, non-negative
 * factors on hd and iso returned 2-3x the SVD's headline error (GGX
 * roughness 0.5, 32 cells), all of it where both directions graze. */
static sb_result_t constrain(nmf_state_t *s, const sb_solve_in_t *in, sb_solve_out_t *out) {
    sb_fit_opts_t o = {0};
    for (int side = 0; side < 2; side++) {
        sb_param_texture_size(in->param, side, &o.tex[side][0], &o.tex[side][1]);
        sb_param_wrap(in->param, side, o.wrap[side]);
    }
    if (o.tex[0][0] * o.tex[0][1] != s->m || o.tex[1][0] * o.tex[1][1] != s->n) return SB_OK;
    sb_fit_t ft = {.m = s->m, .n = s->n, .k = s->J, .P = out->u, .Q = out->v};
    double before = data_err2(s, out->u, out->v), norm2 = 0;
    for (size_t k = 0; k < s->m * s->n; k++)
        norm2 += s->ext[k] == 1 ? s->x[k] * s->x[k] : 0;
    memcpy(s->u1, out->u, s->m * s->J * sizeof *s->u1);
    memcpy(s->v1, out->v, s->n * s->J * sizeof *s->v1);
    size_t joined = 0;
    for (int round = 0; round < 2; round++) {
        size_t added = fit_constrain_taps(&o, &ft, s->x, s->ext);
        if (added == (size_t)-1) return SB_ERR_NOMEM;
        if (added == 0) break;
        joined += added;
        hals(s, out, s->J, s->max_iters);
    }
    double after = sqrt(data_err2(s, out->u, out->v));
    if (joined && after > SB_TAPS_COST * sqrt(before) + 1e-12 * sqrt(norm2) &&
        after > SB_NMF_TAPS_FLOOR * sqrt(norm2)) {
        memcpy(out->u, s->u1, s->m * s->J * sizeof *s->u1);
        memcpy(out->v, s->v1, s->n * s->J * sizeof *s->v1);
    }
    return SB_OK;
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
    sb_result_t r = SB_OK;
    s->hole = SB_NMF_HOLE_WEIGHT;
    stages(s, out);
    s->hole = 0; /* then the data alone: exact where the data are of rank J */
    hals(s, out, s->J, s->max_iters);
    if (masked && in->param && (r = constrain(s, in, out)) != SB_OK) return r;
    normalise(s, out->s, out->u, out->v);
    return SB_OK;
}

const sb_solver_t sb_solver_nmf = {
    .name = "nmf",
    .description =
        "non-negative factors (HALS, terms added in stages) on the valid cells: every texel and reconstruction >= 0",
    .caps = SB_CAP_NONNEG | SB_CAP_MASKS | SB_CAP_METHOD,
    .plan = plan,
    .destroy = destroy,
    .execute = execute,
    .note = "non-negative factors and a sampler"};
