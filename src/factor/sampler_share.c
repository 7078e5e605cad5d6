/* The cosine-weighted share of a sampler chosen from the fit's own error
 * against the source (sepbrdf/sampler.h, sb_sampler_choose_share).
 *
 * For an outgoing wo, one sample of the mixture p_s = s c + (1 - s) p_F
 * (c = cos(theta_i) / pi, p_F the factored density) estimates
 * L = int y dwi, y = Y(f_r(wi, wo)) cos(theta_i) of the source, with
 * variance V(s) = int y^2 / p_s dwi - L^2 (a failed draw counts 0; p_s
 * integrates to 1 minus the failures); cosine sampling has V(1).  Every
 * V(s) comes from the same N draws of the proposal q = p_{1/2} (positive
 * wherever c is, so wherever y can be):
 *     int y^2 / p_s = E_q[y^2 / (q p_s)],   L = E_q[y / q],
 * with p_F(wi) = (q - c / 2) * 2 at each draw: one set of draws and
 * source values for every candidate s.  Per elevation theta_o the
 * relative variances V / L^2 are averaged over three azimuths; the share
 * kept is the candidate with the largest geometric mean of
 * V(1) / V(s) over the elevations among those whose every ratio is at
 * least SB_SHARE_MARGIN (the estimate's noise), else 1: cosine sampling
 * itself, never worse than cosine. */
#include <math.h>
#include <stdlib.h>

#include "sampler_impl.h"
#include "sepbrdf/source.h"
#include "util/rng.h"

#define NCAND 9
static const double CANDS[NCAND] = {1, 0.7, 0.5, 0.35, 0.25, 0.15, 0.1, 0.05, SB_SAMPLER_MIN_SHARE};
#define NPHI 3
static const double PHIS[NPHI] = {0.5, 2.6, 4.7};
/* A share is taken only where its estimated ratio is at least this at
 * every elevation: a margin for the estimate's noise (the default gold on
 * iso: 6.4, 6.3, 9.3, 17.1 estimated here, 5.9, 5.4, 8.0, 15.0 by
 * bench/sampler_variance.c with 10^5 new draws at another azimuth). */
#define SB_SHARE_MARGIN 1.1

static const double TH_DEG[SB_SAMPLER_CHOICE_WO] = {10, 30, 50, 70};

/* For wo: m2[k] = int y^2 / p_{s_k}, over n draws of q = p_{1/2} (the
 * sampler at share 1/2); *mean = L.  Returns 0 when nothing was drawn. */
static int moments(sb_sampler_t *s, const sb_source_t *src, const double wo[3], size_t n, uint64_t seed, double *m2,
                   double *mean) {
    sb_rng_t rng;
    sb_rng_seed(&rng, seed);
    double sum = 0;
    for (int k = 0; k < NCAND; k++)
        m2[k] = 0;
    for (size_t t = 0; t < n; t++) {
        double u[2] = {sb_unit(sb_rng_next(&rng)), sb_unit(sb_rng_next(&rng))}, wi[3], q, rgb[3];
        if (!sb_sample(s, wo, u, wi, &q, NULL) || !sb_source_eval(src, wi, wo, rgb)) continue;
        double y = (0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]) * wi[2];
        if (!(y > 0) || !isfinite(y)) continue;
        double c = wi[2] / SB_PI, pf = fmax(2 * q - c, 0);
        sum += y / q;
        for (int k = 0; k < NCAND; k++)
            m2[k] += y * y / (q * (CANDS[k] * c + (1 - CANDS[k]) * pf));
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
    double keep = sb_sampler_cosine_share(s);
    sb_sampler_set_cosine_share(s, 0.5);
    for (size_t e = 0; e < SB_SAMPLER_CHOICE_WO; e++)
        has[e] = elevation(s, src, e, n, rv[e]);
    sb_sampler_set_cosine_share(s, keep);
    int best = 0; /* CANDS[0] = 1: cosine sampling */
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
    out->share = (float)CANDS[best];
    for (size_t e = 0; e < SB_SAMPLER_CHOICE_WO; e++) {
        out->theta_o_deg[e] = TH_DEG[e];
        out->ratio[e] = !has[e] ? NAN : (rv[e][best] > 0 ? rv[e][0] / rv[e][best] : (rv[e][0] > 0 ? 1e6 : 1));
    }
    return sb_sampler_set_cosine_share(s, out->share);
}
