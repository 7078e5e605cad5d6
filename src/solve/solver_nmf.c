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
 * With a reference (nmf_mixes.c toward_headline), alpha_p follows the prefixes'
 * ratios to its errors (ratio_weights), and W leans to the headline's;
 * the kept fit's terms are then tried in the order of the prefixes'
 * errors and refitted (reorder), and moved by safeguarded steps toward
 * the least worst prefix (polish).  Given the headline's own ratios of
 * that fit (the plan's nonneg_ratio), the prefixes' ratios are corrected
 * to them and the fit made again toward the least corrected worst prefix
 * (nmf_mixes.c to_headline).
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

#define SB_NMF_MAX_ITERS 300
/* The same where every cell weighs 1 (nmf_gram.c): 3 sweeps of the new
 * term alone ended where 10 do or better (GGX roughness 0.3 on io, 32
 * cells, J = 4: 1.09, 0.70, 0.70, 0.70x the SVD's headline against
 * 1.01 at J' = 2-4; RGL chm_orange on vndf the same to 3 digits) in 6
 * sweeps of the last stage against 14. */
#define SB_NMF_GRAM_SEED_SWEEPS 3
/* per prefix: the default gold 259 sweeps at 1e-4, 126 at 1e-3, within
 * 0.13x of the SVD's headline (docs/positive.md, "Time, and ..."). */
#define SB_NMF_TOL 1e-3
/* The weight of a cell within the taps' reach, against 1 for a data cell,
 * towards the masked fit's extension: at 1 it cost the cells' error (the
 * default gold: 3.4e-3 against 2.1e-3 at J = 4), at 0 (the data alone)
 * the headline on hd (GGX 0.3, 16 cells: 2.5x the SVD's at J = 4 against
 * 1.9x at 0.1); 0.01 with the hole weight 1e-6 (above). */
#define SB_NMF_FILL_WEIGHT 0.01
/* Cells of a matrix without masked cells above which the sweeps run from
 * products (nmf_gram.c: every cell weighs 1, no reference): io at 32
 * cells, 1024 x 1024.  Below, the cells are weighted (vndf: 8 x 1024). */
#define SB_NMF_WEIGHTED_CELLS ((size_t)1 << 16)

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
    free(s->hwr);
    free(s->w0);
    free(s->hws);
    free(s->ub);
    free(s->vb);
    free(s->u1);
    free(s->v1);
    free(s->uc);
    free(s->vc);
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
    s->first_fit = pb->nonneg_first_fit;
    s->polish_steps = SB_NMF_POLISH_STEPS;
    s->rho = s->rho_all = pb->nonneg_ratio;
    s->rho_ch = pb->nonneg_ratio ? pb->nonneg_ratio_channel : NULL;
    s->rounds = pb->nonneg_rounds > 1 ? pb->nonneg_rounds : 1;
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
    s->hwr = s->w0 ? sb_alloc(ctx, cells, sizeof(double), "nmf plan") : NULL;
    s->hws = s->w0 && s->rho ? sb_alloc(ctx, cells, sizeof(double), "nmf plan") : NULL;
    s->u1 = s->hw ? sb_alloc(ctx, s->m * s->J, sizeof(double), "nmf plan") : NULL;
    s->v1 = s->hw ? sb_alloc(ctx, s->n * s->J, sizeof(double), "nmf plan") : NULL;
    s->uc = s->hw && s->rho ? sb_alloc(ctx, s->m * s->J, sizeof(double), "nmf plan") : NULL;
    s->vc = s->hw && s->rho ? sb_alloc(ctx, s->n * s->J, sizeof(double), "nmf plan") : NULL;
    s->ub = sb_alloc(ctx, s->m * s->J, sizeof(double), "nmf plan");
    s->vb = sb_alloc(ctx, s->n * s->J, sizeof(double), "nmf plan");
    if (!s->e || !s->r || !s->alpha || !s->cq || !s->tw || !s->x || !s->w || !s->ext || !s->t || !s->uref || !s->vref ||
        !s->sref || (weighted && !s->hw) || (weighted && (!s->u1 || !s->v1)) ||
        (weighted && cells <= SB_NMF_MIX_CELLS && (!s->w0 || !s->hwr || (s->rho && !s->hws))) || !s->ub || !s->vb ||
        (s->hw && s->rho && (!s->uc || !s->vc))) {
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
    sb_result_t r = fit_memo_execute(s->fit, s->x, s->m, s->ext, &o, out->s, out->u, out->v, &fi);
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

static sb_result_t execute(void *state, const sb_solve_in_t *in, sb_solve_out_t *out) {
    nmf_state_t *s = state;
    size_t m = s->m, n = s->n;
    int masked = in->mask && !s->zero_fill;
    s->channel = in->channel;
    s->rho = sb_nmf_rho(s, 0), s->round = 0;
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
    s->tables = !masked && in->param && (sb_param_caps(in->param) & SB_CAP_TABLES);
    s->hws_ok = 0;
    sb_result_t r = s->fit ? fill_holes(s, in, out) : SB_OK;
    if (r != SB_OK) return r;
    sb_nmf_cell_weights(s);
    s->gam = 0;
    if (!masked && s->J <= SB_NMF_GRAM_MAX_TERMS && m * n > SB_NMF_WEIGHTED_CELLS) {
        /* every cell weighs 1: from products with X */
        sb_nmf_gram_opts_t go = {s->max_iters, SB_NMF_STAGE_SWEEPS, SB_NMF_GRAM_SEED_SWEEPS, s->tol, s->floor2};
        if (sb_nmf_gram_fit(&go, s->x, m, n, s->J, out->u, out->v, &out->iterations, &out->converged) != 0)
            return SB_ERR_NOMEM;
    } else
        sb_nmf_fit_mixes(s, in, out);
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
