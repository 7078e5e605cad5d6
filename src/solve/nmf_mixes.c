/* The non-negative solver's fits toward the headline (nmf_state.h): the
 * data cells' weights leaning to the headline's own, the prefixes fitted by
 * their ratio to a reference, and on small matrices the better of a few
 * such fits by their worst prefix (docs/positive.md). */
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "solve/nmf_state.h"
#include "solve/nmf_weights.h"

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
 * 1.75; the default gold 1.86 -> 1.66 (docs/positive.md).  On masked
 * layouts (iso, hd) the kept fit refitted at this mix (nested sweeps to
 * the tolerance) instead of the stages again: about 15 sweeps a channel
 * for the default gold at J = 4 where the stages took 50, and never kept
 * there; the Cornell acrylic's J = 4 (auto: iso) 1.44, 1.16, 1.18, 1.15
 * -> 1.39, 1.14, 1.21, 1.19, the gold's J = 2 and 3 1.75, 1.20 and 1.61,
 * 1.42, 1.42 -> 1.67, 1.26 and 1.68, 1.33, 1.42 (round h38t).  Not on
 * unmasked layouts: RGL malachite's and paper's auto layouts changed,
 * worst prefixes 1.51 and 1.68. */
#define SB_NMF_SECOND_MIX 0.8
/* A third fit at the headline's own weights (mu = 1) on unmasked matrices
 * of at most SB_NMF_THIRD_CELLS cells (vndf), kept by this margin on the
 * squared ratio: the proxy misses vndf's interpolation between rows (RGL
 * malachite, red: 1.279 against 1.289 kept, J' = 4 1.72 -> 2.42x the
 * SVD's headline); chm_light_blue 1.84 -> 1.49, silk 1.75 -> 1.49.
 * A fourth there at the headline's weights unclipped (a few nodes at the
 * horizon weigh up to 2e2 times the mean; sb_nmf_headline_weights), kept
 * where lower by the same clipped measure: RGL malachite 1.72 -> 1.56,
 * chm_orange 1.43 -> 1.22, the four other RGL files unchanged (round
 * h38d).  Fitted and chosen by the unclipped weights alone, paper went
 * 1.86 -> 2.44 and chm_light_blue 1.49 -> 2.12; chosen by the larger of
 * the two measures, silk 1.49 -> 2.56 (docs/positive.md). */
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
/* The kept fit's terms reordered, each prefix taking the term that leaves
 * the least error in the headline's weights (greedy_order), then refitted
 * from there with the ratios to this power, and kept where their worst
 * prefix is lower (reorder).  The nested sweeps can end with the terms in
 * an order that costs J' = 1: GGX alpha 0.3 (microfacet roughness 0.548)
 * on hd, J = 4, a diffuse first term and the peak second, 3.52, 1.10,
 * 1.08, 1.18x the SVD's headline; reordered and refitted at 2: 1.61,
 * 1.05, 0.95, 0.97; at 4: 1.04, 1.07, 0.95, 0.92; at 8 (the sweeps'
 * weights are then no majorant) 1.55, 2.10, 2.11, 2.44 (round h38f,
 * docs/positive.md). */
#define SB_NMF_REORDER_POWER 4.0
/* Then, wherever the headline's weights are known (hd at 1024^2 too), at
 * most SB_NMF_POLISH_STEPS safeguarded steps (polish) of one nested sweep
 * with the ratios to this power, in the kept mix's weights: GGX alpha 0.3
 * on hd, J = 8, 1.61 -> 1.49 at J' = 1 (3.56 before the reorder); RGL
 * cc_green_malachite (auto: vh, J = 4), J' = 1 1.56 -> 1.46x the SVD's
 * headline, vch_silk_blue J' = 4 1.49 -> 1.45 (swept in the last mix's
 * weights, malachite at power 4 1.51, at 16 1.45).  The default gold stops
 * after 0-2 steps (its worst prefix 1.654 -> 1.642 in the proxy on red:
 * no step lowers it further; round h38f, docs/positive.md). */
#define SB_NMF_POLISH_POWER 8.0
/* On masked layouts (iso, hd) and vndf the last prefix's ratio to the reference
 * counts more above SB_NMF_LAST_TARGET, growing with it up to
 * SB_NMF_LAST_WEIGHT times (on the squared ratios, the target and weight
 * squared; sb_nmf_last_boost): the J terms a renderer uses are the fit
 * the check reads at J = 1..4, and the nested minimax gave the
 * last prefix up to J' = 1 on the default gold (J = 2, 3, 4: 1.48, 1.54,
 * 1.56x the SVD's headline at J' = J, J' = 1 at 1.55-1.66).  With the
 * target 1.25 and weight 1.3: 1.20, 1.42, 1.42 at J' = J, J' = 1 at
 * 1.61-1.86; the Cornell acrylic's worst prefix 1.39 -> 1.44.  A fixed
 * weight 1.3 (no target) gave the gold 1.28, 1.35, 1.44 and the acrylic
 * 1.54 at J' = 1; 1.2: 1.34, 1.38, 1.49 (docs/positive.md, round h38n).
 * On vndf (SB_CAP_TABLES) it took RGL aurora and paper at J = 4 from
 * 0.81, 1.58, 1.36, 1.56 and 1.33, 1.66, 0.92, 1.68 to 0.83, 1.80, 1.79,
 * 1.23 and 1.39, 1.98, 1.19, 1.27; every RGL file keeps its auto layout
 * (round h38v).  Not on the other unmasked layouts (vh, io, rv): on all
 * of them malachite's auto went from vh to hd, 7x the CPU. */
#define SB_NMF_LAST_TARGET 1.25
#define SB_NMF_LAST_WEIGHT 1.3
/* On vndf the target is higher, so that the earlier prefixes keep more of
 * the trade: RGL aurora at J = 4 0.83, 1.80, 1.79, 1.23 -> 0.82, 1.63,
 * 1.41, 1.47x the SVD's headline; the other five RGL files at J = 2-4
 * within 0.04 (at 1.45: aurora's J' = 4 1.55).  In the job's refit
 * toward the headline's own ratios (the plan's nonneg_ratio; its stages
 * too, so to_headline corrects a fit made at this target, not the one the
 * job measured) higher still, the job keeping the refit only with its
 * last prefix within 1.5x: RGL paper 1.39, 1.98, 1.12, 1.30 -> 1.38,
 * 1.89, 1.04, 1.39 (at 1.6: J' = 4 1.74; round h38n, second,
 * docs/positive.md). */
#define SB_NMF_LAST_TARGET_TABLES 1.4
#define SB_NMF_LAST_TARGET_REFIT 1.5
/* On masked layouts (iso; matrices of at most SB_NMF_MIX_CELLS cells)
 * whose kept fit has a prefix above SB_NMF_MINIMAX_ABOVE times the
 * reference's in the headline's weights: SB_NMF_MINIMAX_SWEEPS nested sweeps
 * whose prefix weights follow the worst prefix (multiplicative weights,
 * exponent SB_NMF_MINIMAX_ETA; minimax), in the headline's weights with the
 * cells out of the data at SB_NMF_MINIMAX_FILL of theirs (at 1: the gold's
 * proxy stalls at 1.62-1.65; at 0, the lookups' taps read terms unbounded
 * there: 19-36x at J' = 2-4), the last prefix's ratio counted
 * SB_NMF_MINIMAX_LAST times (at 1 the gold's J' = 4 went 1.42 -> 1.51).
 * The default gold at J = 4: 1.86, 1.39, 1.42, 1.42 -> 1.53, 1.50, 1.21,
 * 1.41x the SVD's headline (round h38b, docs/positive.md).  Fill 0.01 ->
 * 0.003 and the last 1.1 -> 1.05 (round h38m): the gold's J = 4 1.53,
 * 1.46, 1.23, 1.45 (worst channel at J' = 4 1.50 -> 1.49), the Cornell
 * acrylic's green J' = 1 1.58 -> 1.53; J' = 1 stays at the frontier (1.52
 * at every fill from 0.001 to 0.01 and last from 1 to 1.1). */
#define SB_NMF_MINIMAX_SWEEPS 120
#define SB_NMF_MINIMAX_ETA 1.0
#define SB_NMF_MINIMAX_ABOVE 1.5
#define SB_NMF_MINIMAX_FILL 0.003
#define SB_NMF_MINIMAX_LAST 1.05
/* On vndf (SB_CAP_TABLES), given the headline's own ratios (the job's
 * refit, s->rho): the same minimax after to_headline, in the headline's
 * weights spread to the nodes beside (max(hw, SB_NMF_SPREAD_TABLES times
 * theirs): a lookup's bilinear patch reads a node the weights leave at 0
 * next to one they do not), each prefix's squared ratio there times its
 * calibration rho^2 / ratio^2, the last's counted
 * SB_NMF_MINIMAX_LAST_TABLES times, SB_NMF_MINIMAX_SWEEPS_TABLES sweeps.
 * RGL paper_white J = 4 (round h38r, docs/positive.md): worst channel
 * 1.88 -> 1.55; unspread the last prefix went to 2.2x in the headline
 * (predicted 1.36), with the last at 1 1.71 (1.41 predicted).  The
 * spread 0.2 -> 0.12 (round h38n, third): paper's J' = 1..4 1.52, 1.45,
 * 1.48, 1.45 -> 1.48, 1.43, 1.45, 1.47x the SVD's headline (pooled),
 * malachite's J' = 4 1.59 -> 1.61, the four other RGL files the same; at
 * 0.08 and below paper's refit has its last prefix above 1.5x and is not
 * kept (1.43, 2.28, 1.64, 1.02), at 0.15 1.48, 1.44, 1.47, 1.46 with
 * malachite's J' = 4 at 1.63 (docs/positive.md). */
#define SB_NMF_SPREAD_TABLES 0.12
#define SB_NMF_MINIMAX_LAST_TABLES 1.5
#define SB_NMF_MINIMAX_SWEEPS_TABLES 200
/* Its weights' exponent (SB_NMF_MINIMAX_ETA on masked layouts): at 1 RGL
 * paper_white at J = 4 kept blue J' = 1 at 1.517x the SVD's headline; at
 * 0.07 every prefix and channel within 1.49x (0.04-0.1 the same, 0.2
 * 1.516, 0.03 the refit not kept; the other RGL files within 0.01 from 0.06
 * to 0.2; round h38q2, docs/positive.md). */
#define SB_NMF_MINIMAX_ETA_TABLES 0.07
/* The worst prefix of U, V in the headline's weights against the
 * reference (sb_nmf_worst_ratio), each prefix's ratio times its
 * correction cp (1 but after to_headline's), the last's boosted. */
static double worst_ratio(const nmf_state_t *s, const double *U, const double *V) {
    if (s->J > SB_NMF_MAX_TERMS)
        return sb_nmf_worst_ratio(s->x, s->hw, s->m, s->n, s->J, U, V, s->uref, s->vref, s->floor2);
    double f[SB_NMF_MAX_TERMS], worst = 0;
    sb_nmf_prefix_ratios(s->x, s->hw, s->m, s->n, s->J, U, V, s->uref, s->vref, s->floor2, f);
    for (size_t p = 0; p < s->J; p++)
        worst = fmax(worst, s->cp[p] * f[p] * (p + 1 == s->J ? sb_nmf_last_boost(s, s->cp[p] * f[p]) : 1));
    return worst;
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
    s->hw_ok = sb_nmf_headline_weights(in->param, in->m->form, s->ext, s->m, s->n, s->hw, s->hwr) == 0;
    memcpy(s->hw_key, key, sizeof key);
    return s->hw_ok;
}

/* Step: the data cells' weights mixed toward the headline's (mu of
 * them; unclipped where raw), and the reference's prefixes' errors in the fit's weights: the
 * masked fit fill_holes left in out, or the SVD (no cell masked), taken
 * unless `again` (the reference of the fit before); without one the
 * prefixes' errors are fitted alone (gam 0). */
static void toward_headline(nmf_state_t *s, const sb_solve_in_t *in, const sb_solve_out_t *out, double mu, int again,
                            int raw) {
    size_t m = s->m, n = s->n, J = s->J;
    for (size_t p = 0; p < J && p < SB_NMF_MAX_TERMS; p++)
        s->cp[p] = 1;
    int tables = !s->fit && in->param && (sb_param_caps(in->param) & SB_CAP_TABLES); /* vndf */
    double tau = s->fit ? SB_NMF_LAST_TARGET : s->rho ? SB_NMF_LAST_TARGET_REFIT : SB_NMF_LAST_TARGET_TABLES;
    s->last_tau2 = (s->fit || tables) && J > 1 && J <= SB_NMF_MAX_TERMS ? tau * tau : 0;
    s->last_kap2 = SB_NMF_LAST_WEIGHT * SB_NMF_LAST_WEIGHT;
    if (headline_weights(s, in))
        for (size_t k = 0; k < m * n; k++)
            if (s->ext[k] == 1) s->w[k] *= 1 - mu + mu * (raw ? s->hwr : s->hw)[k];
    s->gam = 0;
    if (2 * J > (m < n ? m : n)) return;
    for (size_t j = 0; !again && s->fit && j < J; j++) {
        for (size_t i = 0; i < m; i++)
            s->uref[i + j * m] = out->s[j] * out->u[i + j * m];
        memcpy(s->vref + j * n, out->v + j * n, n * sizeof *s->vref);
    }
    if (!again && !s->fit && sb_nmf_svd_terms(s->x, m, n, J, s->uref, s->vref) != 0) return;
    for (size_t k = 1; k <= J; k++)
        s->sref[k - 1] = fmax(sb_nmf_residual(s, s->uref, s->vref, k), s->floor2);
    s->gam = SB_NMF_RATIO_POWER;
}

/* Step: the stages at `mix` (at |mix| of the unclipped weights where mix
 * < 0; the reference of the fit before, `again`; on masked layouts a fit
 * again is the kept fit refitted at `mix`, SB_NMF_SECOND_MIX);
 * the fit kept in ub, vb when its worst prefix in the headline's weights
 * is below `margin` times *best (which it then becomes). */
static void fit_mix(nmf_state_t *s, const sb_solve_in_t *in, sb_solve_out_t *out, double mix, int again, double margin,
                    double *best) {
    size_t m = s->m, n = s->n, J = s->J;
    int sweeps = out->iterations, raw = mix < 0;
    memcpy(s->w, s->w0, m * n * sizeof *s->w);
    toward_headline(s, in, out, fabs(mix), again, raw);
    if (again && s->fit) { /* masked: from the kept fit */
        memcpy(out->u, s->ub, m * J * sizeof *s->ub);
        memcpy(out->v, s->vb, n * J * sizeof *s->vb);
        sb_nmf_refit(s, out);
    } else {
        sb_nmf_stages(s, out);
        out->iterations += again ? sweeps : 0;
    }
    if (!s->hw_ok || !(s->gam > 0)) return;
    double r = worst_ratio(s, out->u, out->v);
    if (again && !(r < margin * *best)) return;
    *best = r;
    s->kept_mix = mix;
    s->conv = out->converged;
    memcpy(s->ub, out->u, m * J * sizeof *s->ub);
    memcpy(s->vb, out->v, n * J * sizeof *s->vb);
}

/* Step: into order, the terms of U, V prefix by prefix: at each, the one
 * whose prefix has the least error in the headline's weights hw (greedy;
 * s->r holds the residual of the terms taken). */
static void greedy_order(nmf_state_t *s, const double *U, const double *V, size_t *order) {
    size_t m = s->m, n = s->n, J = s->J;
    unsigned taken = 0;
    for (size_t k = 0; k < m * n; k++)
        s->r[k] = s->ext[k] == 1 ? s->x[k] : 0;
    for (size_t p = 0; p < J; p++) {
        double least = INFINITY;
        size_t at = 0;
        for (size_t j = 0; j < J; j++) {
            if (taken >> j & 1) continue;
            double f = 0;
            for (size_t c = 0; c < n; c++) {
                const double *hw = s->hw + c * m, *r = s->r + c * m, *u = U + j * m, vc = V[c + j * n];
                for (size_t i = 0; i < m; i++) {
                    double e = r[i] - u[i] * vc;
                    f += hw[i] * e * e;
                }
            }
            if (f < least) least = f, at = j;
        }
        taken |= 1u << at;
        order[p] = at;
        for (size_t c = 0; c < n; c++)
            for (size_t i = 0; i < m; i++)
                s->r[i + c * m] -= U[i + at * m] * V[c + at * n];
    }
}

/* Step: out's terms reordered greedily (greedy_order) and refitted from
 * there (nested sweeps in s's weights: the kept mix's); kept where their
 * worst prefix in the headline's weights is lower. */
static void reorder(nmf_state_t *s, sb_solve_out_t *out) {
    size_t m = s->m, n = s->n, J = s->J, order[32];
    if (!s->hw_ok || !(s->gam > 0) || J < 2 || J > 32) return;
    memcpy(s->ub, out->u, m * J * sizeof *s->ub);
    memcpy(s->vb, out->v, n * J * sizeof *s->vb);
    greedy_order(s, s->ub, s->vb, order);
    size_t moved = 0;
    for (size_t p = 0; p < J; p++) {
        moved += order[p] != p;
        memcpy(out->u + p * m, s->ub + order[p] * m, m * sizeof *s->ub);
        memcpy(out->v + p * n, s->vb + order[p] * n, n * sizeof *s->vb);
    }
    if (!moved) return;
    double r0 = worst_ratio(s, s->ub, s->vb);
    int conv = out->converged;
    double g0 = s->gam;
    s->gam = SB_NMF_REORDER_POWER;
    sb_nmf_refit(s, out);
    s->gam = g0;
    double r1 = worst_ratio(s, out->u, out->v);
    if (r1 < r0) return;
    memcpy(out->u, s->ub, m * J * sizeof *s->ub);
    memcpy(out->v, s->vb, n * J * sizeof *s->vb);
    out->converged = conv;
}

/* Step: out moved toward the least worst prefix in the headline's weights
 * (sb_nmf_worst_ratio) by safeguarded steps: one nested sweep with the
 * ratios to SB_NMF_POLISH_POWER from out, then out + t (sweep - out), t = 1,
 * 1/2, .. 1/8, the first that lowers the worst prefix taken; stops at the
 * first sweep none of them lowers, after a step that gains less than the
 * fit's tolerance, or after s->polish_steps.  So the
 * worst prefix never rises (s->ub, vb, u1, v1 hold the steps' ends). */
static void polish(nmf_state_t *s, sb_solve_out_t *out) {
    size_t m = s->m, n = s->n, J = s->J, mu = m * J, nv = n * J;
    if (!s->u1 || !s->hw_ok || !(s->gam > 0)) return;
    double best = worst_ratio(s, out->u, out->v), g0 = s->gam;
    double before = INFINITY;
    int conv = out->converged, ok = 1;
    if (!(best > 1)) return; /* no prefix worse than the reference's */
    for (int it = 0; ok && it < s->polish_steps && best < before * (1 - s->tol); it++) {
        before = best;
        memcpy(s->ub, out->u, mu * sizeof *s->ub);
        memcpy(s->vb, out->v, nv * sizeof *s->vb);
        s->gam = SB_NMF_POLISH_POWER;
        sb_nmf_refit_n(s, out, 1);
        s->gam = g0;
        memcpy(s->u1, out->u, mu * sizeof *s->u1);
        memcpy(s->v1, out->v, nv * sizeof *s->v1);
        ok = 0;
        for (double t = 0.5; !ok && t >= 1.0 / 16; t *= 0.5) {
            double r = worst_ratio(s, out->u, out->v);
            ok = r < best;
            best = ok ? r : best;
            for (size_t k = 0; !ok && k < mu; k++) /* out at 2t failed: the step to t */
                out->u[k] = s->ub[k] + t * (s->u1[k] - s->ub[k]);
            for (size_t k = 0; !ok && k < nv; k++)
                out->v[k] = s->vb[k] + t * (s->v1[k] - s->vb[k]);
        }
    }
    if (!ok) {
        memcpy(out->u, s->ub, mu * sizeof *s->ub);
        memcpy(out->v, s->vb, nv * sizeof *s->vb);
    }
    out->converged = conv;
}

/* Step: the reference's errors in the fit's weights (sref) at the
 * corrected ratios cp. */
static void correct_sref(nmf_state_t *s, const double *cp) {
    for (size_t p = 0; p < s->J; p++) {
        s->cp[p] *= cp[p]; /* on push_last's weight of the last prefix, if any */
        s->sref[p] /= cp[p];
    }
}

/* Step: out's fit refitted at the corrected ratios to SB_NMF_REORDER_POWER
 * (kept where its corrected worst prefix is lower), then polished. */
static void refit_corrected(nmf_state_t *s, sb_solve_out_t *out) {
    size_t m = s->m, n = s->n, J = s->J;
    memcpy(s->ub, out->u, m * J * sizeof *s->ub);
    memcpy(s->vb, out->v, n * J * sizeof *s->vb);
    double r0 = worst_ratio(s, s->ub, s->vb), g0 = s->gam;
    int conv = out->converged;
    s->gam = SB_NMF_REORDER_POWER;
    sb_nmf_refit(s, out);
    s->gam = g0;
    if (!(worst_ratio(s, out->u, out->v) < r0)) {
        memcpy(out->u, s->ub, m * J * sizeof *s->ub);
        memcpy(out->v, s->vb, n * J * sizeof *s->vb);
        out->converged = conv;
    }
    polish(s, out);
}

/* Step (vndf, with rho): s->hws, the headline's weights spread to the
 * nodes beside (SB_NMF_SPREAD_TABLES), and s->cal, rho^2 over out's
 * squared ratios in them: the headline's ratios predicted from that
 * measure, for the minimax after to_headline (minimax with cal). */
/* A round after the first (the plan's nonneg_rounds) moves each
 * correction c (rho^2 over the prefix's squared ratio in the solver's
 * weights) from the round before's only this far, geometrically: at 1,
 * the corrections swing (RGL chm_orange on vndf, J = 4: the second
 * refit's worst 3.74x the SVD's, its first's 2.07); at 0.3 its second
 * 1.93 (at 0.2 1.82 with the last prefix 1.52, not kept; at 0.4, 0.5
 * 2.10, 2.37; round h38v, docs/positive.md). */
#define SB_NMF_ROUND_STEP 0.3
/* c, moved from prev[p] by SB_NMF_ROUND_STEP after the first round; into prev[p]. */
static double damp(const nmf_state_t *s, double *prev, size_t p, double c) {
    if (s->round > 0) c = pow(prev[p], 1 - SB_NMF_ROUND_STEP) * pow(c, SB_NMF_ROUND_STEP);
    prev[p] = c;
    return c;
}

static void calibrate(nmf_state_t *s, const sb_solve_in_t *in, const sb_solve_out_t *out) {
    double f[SB_NMF_MAX_TERMS];
    sb_nmf_spread_weights(in->param, s->hw, s->m, s->n, SB_NMF_SPREAD_TABLES, s->hws);
    sb_nmf_prefix_ratios(s->x, s->hws, s->m, s->n, s->J, out->u, out->v, s->uref, s->vref, s->floor2, f);
    for (size_t p = 0; p < s->J; p++)
        s->cal[p] = damp(s, s->calprev, p, s->rho[p] > 0 && f[p] > 0 ? s->rho[p] * s->rho[p] / f[p] : 1);
    s->hws_ok = 1;
}

/* Step: with the headline's own ratios of this fit (s->rho, the plan's
 * nonneg_ratio: the job's estimate of the fit this solver made from the
 * same matrix without them), each prefix's ratio in the headline's
 * weights corrected to them (s->cp; the reference's errors in the fit's
 * weights likewise), then two candidates at the corrected ratios: the
 * fit refitted (refit_corrected) and the stages again in the kept mix's
 * weights, polished; the one kept whose corrected worst prefix is the
 * lower (s->uc, vc hold the first).  The stages again at the other mixes
 * were never kept (RGL paper and aurora, J = 4) and cost a fifth of the
 * run (docs/positive.md). */
static void to_headline(nmf_state_t *s, const sb_solve_in_t *in, sb_solve_out_t *out) {
    size_t m = s->m, n = s->n, J = s->J;
    if (!s->rho || !s->hw_ok || !(s->gam > 0) || J > SB_NMF_MAX_TERMS || !s->uc) return;
    double f[SB_NMF_MAX_TERMS], cp[SB_NMF_MAX_TERMS];
    sb_nmf_prefix_ratios(s->x, s->hw, m, n, J, out->u, out->v, s->uref, s->vref, s->floor2, f);
    for (size_t p = 0; p < J; p++)
        cp[p] = damp(s, s->cpprev, p, s->rho[p] > 0 && f[p] > 0 ? s->rho[p] * s->rho[p] / f[p] : 1);
    if (s->tables && s->hws) /* vndf: the measure of the minimax with cal */
        calibrate(s, in, out);
    correct_sref(s, cp);
    refit_corrected(s, out);
    double best = worst_ratio(s, out->u, out->v);
    int conv = out->converged, sweeps = out->iterations;
    memcpy(s->uc, out->u, m * J * sizeof *s->uc);
    memcpy(s->vc, out->v, n * J * sizeof *s->vc);
    sb_nmf_stages(s, out);
    out->iterations += sweeps;
    polish(s, out);
    if (worst_ratio(s, out->u, out->v) < best) return;
    memcpy(out->u, s->uc, m * J * sizeof *s->uc);
    memcpy(out->v, s->vc, n * J * sizeof *s->vc);
    out->converged = conv;
}

/* Step: where the last prefix's squared ratio in the headline's weights is
 * above the target (masked layouts and vndf: last_tau2), the fit polished once more
 * with that prefix counting SB_NMF_LAST_WEIGHT^2 times more (cp, sref):
 * the default gold's J' = J, J = 2, 3, 4, 1.38, 1.44, 1.45 -> 1.20, 1.42,
 * 1.42x the SVD's headline (docs/positive.md, round h38n). */
static void push_last(nmf_state_t *s, sb_solve_out_t *out) {
    size_t J = s->J;
    if (!(s->last_tau2 > 0) || !s->hw_ok || !(s->gam > 0)) return;
    double f[SB_NMF_MAX_TERMS];
    sb_nmf_prefix_ratios(s->x, s->hw, s->m, s->n, J, out->u, out->v, s->uref, s->vref, s->floor2, f);
    if (!(s->cp[J - 1] * f[J - 1] > s->last_tau2)) return;
    s->cp[J - 1] *= s->last_kap2;
    s->sref[J - 1] /= s->last_kap2;
    polish(s, out);
}

/* Step: on masked layouts (iso; small matrices: s->w0) where the worst
 * prefix in the headline's weights is above SB_NMF_MINIMAX_ABOVE times the
 * reference's, a minimax over the prefixes in those weights (mu = 1, the
 * cells out of the data at SB_NMF_MINIMAX_FILL of their weight): each sweep
 * fits sum_p c_p ||E_p||^2 / ||E_p^ref||^2, then c_p *= (f_p / max_q
 * f_q)^(eta / 2), f_p the prefixes' squared ratios (multiplicative weights:
 * the worst prefix gains weight until it falls); the sweep with the least
 * worst prefix is kept, the fit it starts from included. */
/* The worst over the prefixes of U, V's squared ratio in the headline's
 * weights, or (cal) in the spread weights s->hws times cal. */
static double worst_cal(const nmf_state_t *s, const double *U, const double *V, const double *cal) {
    if (!cal) return sb_nmf_worst_ratio(s->x, s->hw, s->m, s->n, s->J, U, V, s->uref, s->vref, s->floor2);
    double f[SB_NMF_MAX_TERMS], worst = 0;
    sb_nmf_prefix_ratios(s->x, s->hws, s->m, s->n, s->J, U, V, s->uref, s->vref, s->floor2, f);
    for (size_t p = 0; p < s->J; p++)
        worst = fmax(worst, cal[p] * f[p]);
    return worst;
}

/* U, V's last prefix's squared ratio in s->hws. */
static double last_spread(const nmf_state_t *s, const double *U, const double *V) {
    double f[SB_NMF_MAX_TERMS];
    sb_nmf_prefix_ratios(s->x, s->hws, s->m, s->n, s->J, U, V, s->uref, s->vref, s->floor2, f);
    return f[s->J - 1];
}

/* Step: on masked layouts (iso; small matrices: s->w0) where the worst
 * prefix in the headline's weights is above SB_NMF_MINIMAX_ABOVE times the
 * reference's, a minimax over the prefixes in those weights (mu = 1, the
 * cells out of the data at SB_NMF_MINIMAX_FILL of their weight): each sweep
 * fits sum_p c_p ||E_p||^2 / ||E_p^ref||^2, then c_p *= (f_p / max_q
 * f_q)^(eta / 2), f_p the prefixes' squared ratios (multiplicative weights:
 * the worst prefix gains weight until it falls); the sweep with the least
 * worst prefix is kept, the fit it starts from included.
 * With cal (vndf, after to_headline): the same in s->hws,
 * each prefix's squared ratio times cal (the headline's predicted), the
 * last's counted SB_NMF_MINIMAX_LAST_TABLES times in the sweeps. */
static int minimax(nmf_state_t *s, const sb_solve_in_t *in, sb_solve_out_t *out, const double *cal) {
    size_t m = s->m, n = s->n, J = s->J;
    int conv = out->converged;
    if (!s->w0 || !s->u1 || !s->hw_ok || !(s->gam > 0) || J < 2 || J > SB_NMF_MAX_TERMS) return 0;
    double r0 = worst_cal(s, out->u, out->v, cal);
    if (!(r0 > SB_NMF_MINIMAX_ABOVE * SB_NMF_MINIMAX_ABOVE)) return 0;
    if (cal && !(cal[J - 1] * last_spread(s, out->u, out->v) < r0)) return 0; /* toward an earlier prefix only */
    memcpy(s->w, s->w0, m * n * sizeof *s->w); /* the headline's weights, the reference's errors in them */
    toward_headline(s, in, out, 1, 1, 0);
    for (size_t k = 0; k < m * n; k++)
        s->w[k] = s->ext[k] != 1 ? s->w[k] * SB_NMF_MINIMAX_FILL : cal ? s->w0[k] * s->hws[k] : s->w[k];
    for (size_t k = 1; k <= J; k++)
        s->sref[k - 1] = fmax(sb_nmf_residual(s, s->uref, s->vref, k), s->floor2) / (cal ? cal[k - 1] : 1);
    for (size_t p = 0; p < J; p++)
        s->mmc[p] = 1;
    memcpy(s->u1, out->u, m * J * sizeof *s->u1);
    memcpy(s->v1, out->v, n * J * sizeof *s->v1);
    s->mm = 1, s->mm_eta = cal ? SB_NMF_MINIMAX_ETA_TABLES : SB_NMF_MINIMAX_ETA, s->mm_best = INFINITY;
    s->mm_last = cal ? SB_NMF_MINIMAX_LAST_TABLES : SB_NMF_MINIMAX_LAST * SB_NMF_MINIMAX_LAST;
    sb_nmf_refit_n(s, out, cal ? SB_NMF_MINIMAX_SWEEPS_TABLES : SB_NMF_MINIMAX_SWEEPS);
    s->mm = 0;
    /* the best sweep's, else the start's; on vndf only where its last
     * prefix, the least sure of the measure, did not rise */
    int keep =
        worst_cal(s, s->ub, s->vb, cal) < r0 && (!cal || last_spread(s, s->ub, s->vb) <= last_spread(s, s->u1, s->v1));
    memcpy(out->u, keep ? s->ub : s->u1, m * J * sizeof *s->ub);
    memcpy(out->v, keep ? s->vb : s->v1, n * J * sizeof *s->vb);
    out->converged = conv;
    return keep;
}

/* Step: the rounds from k on (the plan's nonneg_rounds), each from the
 * fit the round before gave; then the state after them kept where a
 * carry is given (nmf_carry.c). */
static void rounds_from(nmf_state_t *s, const sb_solve_in_t *in, sb_solve_out_t *out, size_t k) {
    for (; k < s->rounds && s->rho; k++) {
        s->rho = sb_nmf_rho(s, k), s->round = k;
        s->hws_ok = 0;
        if (s->w0) memcpy(s->w, s->w0, s->m * s->n * sizeof *s->w);
        toward_headline(s, in, out, fabs(s->kept_mix), 1, s->kept_mix < 0);
        push_last(s, out);
        to_headline(s, in, out);
        if (s->tables && s->hws_ok) minimax(s, in, out, s->cal);
    }
    sb_nmf_carry_save(s, in, out);
}

/* Step: the kept fit (in out; its mix's weights and reference's errors
 * in s) reordered, polished, its last prefix pushed, on masked layouts
 * the minimax, toward the headline's own ratios (vndf: then the minimax
 * with cal), and the rounds after the first (the plan's nonneg_rounds),
 * each from the fit the round before gave.  Without s->w0 (large
 * matrices) the minimax does nothing, and a round's weights are the
 * kept ones mixed toward the headline's once more. */
static void finish(nmf_state_t *s, const sb_solve_in_t *in, sb_solve_out_t *out) {
    reorder(s, out);
    polish(s, out);
    push_last(s, out);
    if (s->fit) minimax(s, in, out, NULL);
    to_headline(s, in, out);
    if (s->tables && s->hws_ok) minimax(s, in, out, s->cal); /* vndf: toward the headline's own ratios */
    rounds_from(s, in, out, 1);
}

/* Step: the stages at SB_NMF_HEADLINE_MIX, where the matrix is small and
 * a reference known at SB_NMF_SECOND_MIX and (smaller, no cell masked) at
 * 1, clipped and unclipped, too: the fit
 * kept whose worst prefix in the headline's weights is the lowest against
 * the reference (out->iterations counts them all); then finish.  Where
 * the carry holds this fit from an execute before (the same data,
 * headline's weights, settings and ratios; nmf_carry.c), its terms
 * instead; where it holds its first rounds, their state and the rounds
 * after them. */
void sb_nmf_fit_mixes(nmf_state_t *s, const sb_solve_in_t *in, sb_solve_out_t *out) {
    size_t m = s->m, n = s->n, J = s->J;
    if (!s->w0) {
        s->kept_mix = SB_NMF_HEADLINE_MIX;
        toward_headline(s, in, out, SB_NMF_HEADLINE_MIX, 0, 0);
        sb_nmf_stages(s, out);
        finish(s, in, out);
        return;
    }
    memcpy(s->w0, s->w, m * n * sizeof *s->w0);
    if (s->carry) headline_weights(s, in);       /* what the carry compares (else the first fit's) */
    size_t held = sb_nmf_carry_take(s, in, out); /* the fit, or its first rounds, an execute before made */
    if (held == s->rounds) return;
    if (held) {
        rounds_from(s, in, out, held);
        return;
    }
    double best = INFINITY;
    fit_mix(s, in, out, SB_NMF_HEADLINE_MIX, 0, 1, &best);
    if (!s->hw_ok || !(s->gam > 0)) return;
    if (s->first_fit && s->fit) { /* a ranking (the plan's nonneg_first_fit): the first fit alone */
        memcpy(out->u, s->ub, m * J * sizeof *s->ub);
        memcpy(out->v, s->vb, n * J * sizeof *s->vb);
        out->converged = s->conv;
        return;
    }
    fit_mix(s, in, out, SB_NMF_SECOND_MIX, 1, 1, &best);
    if (!s->fit && m * n <= SB_NMF_THIRD_CELLS) {
        fit_mix(s, in, out, 1, 1, SB_NMF_THIRD_MARGIN, &best);
        fit_mix(s, in, out, -1, 1, 1, &best); /* unclipped */
    }
    memcpy(out->u, s->ub, m * J * sizeof *s->ub);
    memcpy(out->v, s->vb, n * J * sizeof *s->vb);
    out->converged = s->conv;
    memcpy(s->w, s->w0, m * n * sizeof *s->w); /* the kept mix's weights and reference errors */
    toward_headline(s, in, out, fabs(s->kept_mix), 1, s->kept_mix < 0);
    finish(s, in, out);
}
