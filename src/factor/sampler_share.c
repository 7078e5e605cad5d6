/* The shares of a sampler's mixture chosen from the fit's own error
 * against the source (sepbrdf/sampler.h, sb_sampler_choose_share).
 *
 * For an outgoing wo, one sample of the mixture p = s c + s_l l_a + (1 -
 * s - s_l) p_F (c = cos(theta_i) / pi, l_a the GGX lobe of roughness a,
 * p_F the factored density) estimates L = int y dwi, y = Y(f_r(wi, wo))
 * cos(theta_i) of the source, with variance V = int y^2 / p dwi - L^2 (a
 * failed draw counts 0; p integrates to 1 minus the failures); cosine
 * sampling has V(s = 1).  Every candidate's V comes from the same N draws
 * of the proposal q = (p_{1/2} + mean_a l_a) / 2, half of them the sampler
 * at s = 1/2 without the lobe (positive wherever c is, so wherever y can
 * be), half the lobes of the candidate roughnesses in turn:
 *     int y^2 / p = E_q[y^2 / (q p)],   L = E_q[y / q],
 * with p_F(wi) = (p_{1/2} - c / 2) * 2 at each draw: one set of draws and
 * source values for every candidate.  Per elevation theta_o the relative
 * variances V / L^2 are averaged over three azimuths; the candidate kept
 * has the largest geometric mean of V(1) / V over the elevations among
 * those whose every ratio is at least SB_SHARE_MARGIN (the estimate's
 * noise), else s = 1: cosine sampling itself, never worse than cosine. */
#include <math.h>
#include <stdlib.h>

#include "sampler_impl.h"
#include "sepbrdf/source.h"
#include "util/rng.h"

/* The candidates (s, s_l, alpha): the cosine shares alone (the first, 1:
 * cosine sampling), then every (s, s_l) pair with every roughness. */
#define NSHARE 9
static const double SHARES[NSHARE] = {1, 0.7, 0.5, 0.35, 0.25, 0.15, 0.1, 0.05, SB_SAMPLER_MIN_SHARE};
#define NPAIR 18
static const double PAIRS[NPAIR][2] = {{0.9921875, 0.0078125},
                                       {0.984375, 0.015625},
                                       {0.96875, 0.03125},
                                       {0.9375, 0.0625},
                                       {0.875, 0.125},
                                       {0.75, 0.25},
                                       {0.5, 0.5},
                                       {0.25, 0.75},
                                       {0.125, 0.875},
                                       {0.75, 0.125},
                                       {0.5, 0.25},
                                       {0.5, 0.125},
                                       {0.25, 0.5},
                                       {0.25, 0.25},
                                       {0.125, 0.5},
                                       {0.125, 0.25},
                                       {0.0625, 0.5},
                                       {0.0625, 0.25}};
#define NALPHA 8
static const double ALPHAS[NALPHA] = {0.04, 0.06, 0.09, 0.13, 0.18, 0.25, 0.35, 0.5};
#define NCAND (NSHARE + NPAIR * NALPHA)
typedef struct cand {
    double c, l;
    int a; /* index in ALPHAS (l > 0) */
} cand_t;

static cand_t cand(int k) {
    if (k < NSHARE) return (cand_t){SHARES[k], 0, 0};
    k -= NSHARE;
    return (cand_t){PAIRS[k / NALPHA][0], PAIRS[k / NALPHA][1], k % NALPHA};
}

#define NPHI 3
static const double PHIS[NPHI] = {0.5, 2.6, 4.7};
/* A candidate is taken only where its estimated ratio is at least this at
 * every elevation: a margin for the estimate's noise (the default gold on
 * iso: 6.4, 6.3, 9.3, 17.1 estimated here, 5.9, 5.4, 8.0, 15.0 by
 * bench/sampler_variance.c with 10^5 new draws at another azimuth, before
 * the lobe). */
#define SB_SHARE_MARGIN 1.1

static const double TH_DEG[SB_SAMPLER_CHOICE_WO] = {10, 30, 50, 70};

/* Draw t of the proposal q (the sampler at s = 1/2 without the lobe on
 * even t, the lobe of roughness ALPHAS[(t / 2) % NALPHA] on odd t): wi,
 * p_{1/2}(wi) and every l_a(wi); 0 when nothing was drawn or wi is outside
 * the domain. */
static int draw(sb_sampler_t *s, const double wo[3], const double u[2], size_t t, double wi[3], double *ph,
                double *pl) {
    if (t % 2 == 0) {
        if (!sb_sample(s, wo, u, wi, ph, NULL)) return 0;
    } else {
        double d[3];
        if (!sb_lobe_dir_(ALPHAS[(t / 2) % NALPHA], wo, u[0], u[1], d) || !(d[2] > 0)) return 0;
        double n = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        for (int i = 0; i < 3; i++)
            wi[i] = d[i] / n;
        if (!(wi[2] > 0) || !((*ph = sb_pdf(s, wo, wi)) > 0)) return 0;
    }
    for (int a = 0; a < NALPHA; a++)
        pl[a] = sb_lobe_pdf_(ALPHAS[a], wo, wi);
    return 1;
}

/* For wo: m2[k] = int y^2 / p_k for every candidate k, over n draws of q;
 * *mean = L.  Returns 0 when nothing was drawn. */
static int moments(sb_sampler_t *s, const sb_source_t *src, const double wo[3], size_t n, uint64_t seed, double *m2,
                   double *mean) {
    sb_rng_t rng;
    sb_rng_seed(&rng, seed);
    double sum = 0;
    for (int k = 0; k < NCAND; k++)
        m2[k] = 0;
    for (size_t t = 0; t < n; t++) {
        double u[2] = {sb_unit(sb_rng_next(&rng)), sb_unit(sb_rng_next(&rng))}, wi[3], ph, pl[NALPHA], rgb[3];
        if (!draw(s, wo, u, t, wi, &ph, pl) || !sb_source_eval(src, wi, wo, rgb)) continue;
        double y = (0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]) * wi[2];
        if (!(y > 0) || !isfinite(y)) continue;
        double c = wi[2] / SB_PI, pf = fmax(2 * ph - c, 0), lm = 0;
        for (int a = 0; a < NALPHA; a++)
            lm += pl[a] / NALPHA;
        double q = 0.5 * (ph + lm);
        sum += y / q;
        for (int k = 0; k < NCAND; k++) {
            cand_t x = cand(k);
            m2[k] += y * y / (q * (x.c * c + x.l * pl[x.a] + fmax(1 - x.c - x.l, 0) * pf));
        }
    }
    *mean = sum / (double)n;
    for (int k = 0; k < NCAND; k++)
        m2[k] /= (double)n;
    return sum > 0;
}

/* The relative variances V(s_k) / L^2 at elevation e, averaged over the
 * azimuths; 0 when the source has nothing there. */
static int elevation(sb_sampler_t *s, const sb_source_t *src, size_t e, size_t n, double *rv) {
    int any = 0;
    for (int k = 0; k < NCAND; k++)
        rv[k] = 0;
    for (int a = 0; a < NPHI; a++) {
        double wo[3], m2[NCAND], mean;
        sb_dir_from_angles(TH_DEG[e] * SB_PI / 180, PHIS[a], wo);
        if (!moments(s, src, wo, n, 0x5eed0000u + 16 * e + (uint64_t)a, m2, &mean)) continue;
        any = 1;
        for (int k = 0; k < NCAND; k++)
            rv[k] += fmax(m2[k] / (mean * mean) - 1, 0) / NPHI;
    }
    return any;
}

sb_result_t sb_sampler_choose_share(sb_context_t *ctx, sb_sampler_t *s, const sb_source_t *src, size_t samples,
                                    sb_sampler_choice_t *out) {
    if (!s || !src || !out) return sb_error(ctx, SB_ERR_ARG, "sampler: no sampler, source or output");
    size_t n = samples ? samples : 4096;
    double rv[SB_SAMPLER_CHOICE_WO][NCAND];
    int has[SB_SAMPLER_CHOICE_WO];
    sb_sampler_set_lobe(s, 0, 0);
    sb_sampler_set_cosine_share(s, 0.5);
    for (size_t e = 0; e < SB_SAMPLER_CHOICE_WO; e++)
        has[e] = elevation(s, src, e, n, rv[e]);
    int best = 0; /* candidate 0: cosine sampling */
    double best_score = 0;
    for (int k = 1; k < NCAND; k++) {
        double score = 0, lo = INFINITY;
        for (size_t e = 0; e < SB_SAMPLER_CHOICE_WO; e++) {
            if (!has[e]) continue;
            double ratio = rv[e][k] > 0 ? rv[e][0] / rv[e][k] : (rv[e][0] > 0 ? INFINITY : 1);
            lo = fmin(lo, ratio);
            score += log(fmin(ratio, 1e6));
        }
        if (lo >= SB_SHARE_MARGIN && score > best_score) best = k, best_score = score;
    }
    cand_t x = cand(best);
    out->share = (float)x.c;
    out->lobe_share = (float)x.l;
    out->lobe_alpha = x.l > 0 ? (float)ALPHAS[x.a] : 0;
    for (size_t e = 0; e < SB_SAMPLER_CHOICE_WO; e++) {
        out->theta_o_deg[e] = TH_DEG[e];
        out->ratio[e] = !has[e] ? NAN : (rv[e][best] > 0 ? rv[e][0] / rv[e][best] : (rv[e][0] > 0 ? 1e6 : 1));
    }
    sb_result_t r = sb_sampler_set_cosine_share(s, out->share);
    return r ? r : sb_sampler_set_lobe(s, out->lobe_share, out->lobe_alpha);
}
