/* sepbrdf: the error estimator, what a shader returns against the source.
 *
 * The reconstruction is evaluated as sepbrdf.glsl evaluates it: the
 * parameterisation's coordinates (sb_param_coords), GL bilinear filtering
 * with the texel-centre convention and wrap of param.h, the sum over the
 * first J' terms, the per-term scale and the division by the form weight
 * with the snippet's grazing guard max(cos, 0.001), and 0 outside the
 * domain.  Pass the factors as stored (sb_factors_quantize: FLOAT, or HALF
 * with its scales), so the estimate is that of the files written.
 *
 * The error is measured at direction pairs that are not the fit's cells
 * (out of sample), drawn once per source and reused for every candidate
 * and every J' (sb_pairs_t).  The pairs are randomised quasi-Monte Carlo:
 * K replicates of one 6D Kronecker point set (generalised golden ratio),
 * each shifted by an independent random vector (Cranley-Patterson), mapped
 * to (wi, wo) through a mixture density
 *     p(wi, wo) = p_i(wi) p_o(wo | wi),
 *     p_i = 1/2 uniform + 1/2 cosine on the hemisphere,
 *     p_o = 0.2 uniform + 0.2 cosine + 0.15 each of four GGX lobes of the
 *           half vector around the normal (alpha 0.005, 0.02, 0.08, 0.3;
 *           wo = reflect(wi, h), density D(h) cos(theta_h) / (4 wo.h)),
 * weighted by the exact mixture density, so sharp specular peaks, broad
 * lobes and grazing angles are all sampled.  For a quantity q(wi, wo)
 * (q = cos^2 theta_i: the headline, the error of f cos theta_i that a
 * shader outputs per light; cos^2 theta_i cos^2 theta_o: `comparable`;
 * 1: the error of f itself), the relative L2 error
 *     e^2 = int int (f~ - f)^2 q dwi dwo / int int f^2 q dwi dwo
 * over the pairs where the source is known is estimated by the ratio of
 * the two replicate means; its standard error comes from the spread of the
 * replicates (delta method: se(e^2) = sd_k(N_k - e^2 D_k) / (sqrt(K) mean D),
 * se(e) = se(e^2) / (2 e)).  sb_estimate_compute adds replicates (the
 * first ones, then doubling them) until the headline's standard error is
 * at most `rel_se` of the estimate for every J' (or max_pairs is reached:
 * then `converged` is 0).  Prefix J' is reported from the first count at
 * which J'' = 1..J' all met the target (reps[J' - 1]): the count an
 * estimate of J' terms stops at, so the figures of a prefix do not depend
 * on how many terms follow it, nor on how far earlier estimates grew the
 * pairs.  Since a
 * standard error from K replicates is itself uncertain (K - 1 degrees of
 * freedom: at K = 4 it can be a third of the true one), the test is on its
 * one-sided 95 % upper confidence bound, se sqrt((K - 1) / chi2_0.05(K - 1))
 * (3.0 se at K = 4, 1.8 at K = 8, 1.4 at K = 16; Wilson-Hilferty's
 * chi-square quantile).
 *
 * Per pair, the relative error of a channel is |f~ - f| / |f| (all
 * channels: the RGB Euclidean norms); p99 is its 99th percentile under the
 * headline's energy measure f^2 cos^2 theta_i dwi dwo (99 % of the shaded
 * energy has a smaller relative error), read from a histogram of 40 bins
 * per decade (the bin's upper edge: within 6 % above);
 * max is the largest over the sampled pairs with f != 0.  The negative
 * fraction is the fraction of the domain's solid angle pair measure where
 * a reconstructed channel is < 0; overshoot is the largest |f~| over the
 * sampled pairs divided by the largest |f|: above 1, the shader returns
 * values beyond anything in the BRDF (unconstrained texels of a masked fit
 * reached by the bilinear taps).  Everything is the same to the bit on any
 * thread count. */
#ifndef SEPBRDF_ESTIMATE_H
#define SEPBRDF_ESTIMATE_H

#include <stdint.h>

#include "common.h"
#include "factor.h"
#include "param.h"
#include "source.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SB_EST_MAXJ 256

/* Quantities, index q of sb_estimate_t. */
enum { SB_EST_FCOS = 0 /* headline: f cos(theta_i) */, SB_EST_FCOS2 /* f cos cos */, SB_EST_F, SB_EST_Q_COUNT_ };

/* Angular bands, index b of sb_estimate_t.band: where users see errors.
 * theta_i (theta_o) above 60, 80, 89 degrees (cos below cos 60 etc.);
 * specular: wo within SB_BAND_CONE_DEG of the mirror direction of wi
 * (-wi.x, -wi.y, wi.z); retro: wo within SB_BAND_CONE_DEG of wi.  A
 * pair may be in several bands. */
enum {
    SB_BAND_TI60 = 0,
    SB_BAND_TI80,
    SB_BAND_TI89,
    SB_BAND_TO60,
    SB_BAND_TO80,
    SB_BAND_TO89,
    SB_BAND_SPECULAR,
    SB_BAND_RETRO,
    SB_BAND_COUNT_
};
#define SB_BAND_CONE_DEG 10.0
/* Bit b set when (wi, wo) (unit, local frame, z up) is in band b; 0 for NULL. */
SB_API unsigned sb_band_mask(const double wi[3], const double wo[3]);
/* "theta_i_60", ..., "specular", "retro" (report.json keys); NULL beyond. */
SB_API const char *sb_band_name(int band);
/* The band map: cells over (theta_i, theta_o) with these edges in degrees
 * (finer towards the horizon). */
#define SB_EST_MAP 9
extern const double sb_band_map_edges[SB_EST_MAP + 1];

#define SB_EST_REL_SE 0.05 /* the default target of rel_se */

typedef struct sb_estimate_opts {
    size_t replicate;    /* pairs per replicate, default 4096 */
    size_t start;        /* replicates drawn at first, default 16 (at least 4) */
    size_t max_pairs;    /* sb_estimate_compute adds replicates up to this many pairs (and uses no more), default
                            2^19; start * replicate or less: never grows, uses the pairs there are */
    double rel_se;       /* target standard error of the headline relative to it, default SB_EST_REL_SE */
    uint64_t seed;       /* default 1 */
    int threads;         /* 0 = all cores */
    int headline_only;   /* skip the per-pair relative errors (p99 and max_rel are 0): a cheaper ranking */
    size_t replicates;   /* evaluate the first this many replicates only (at least 4), no growth; 0: all */
    int last_only;       /* with headline_only: the errors of all J terms only (those of shorter prefixes are 0) */
    int bands;           /* with headline_only: the band errors too (band, band_se, band_share; not the lit ones) */
    unsigned channels;   /* sb_pairs_create: the channels measured (1 R, 2 G, 4 B; 0 = all): the source's others read
                            as 0, so a fit of some channels (sb_matrix_opts_t.channels) is measured on them only */
    unsigned stop_bands; /* with bands: a mask of bands (1u << SB_BAND_*) whose standard errors must also be within
                            rel_se of them at every J' before the estimate stops growing (0: the headline alone) */
} sb_estimate_opts_t;

/* Pairs with the source's values: created once per source, reused. */
typedef struct sb_pairs sb_pairs_t;
/* Draw opts->start replicates of pairs for src (src must outlive them).
 * Errors: SB_ERR_ARG, SB_ERR_RANGE (replicate 0, start < 4), SB_ERR_NOMEM. */
SB_API sb_result_t sb_pairs_create(sb_context_t *ctx, const sb_source_t *src, const sb_estimate_opts_t *opts,
                                   sb_pairs_t **out);
/* A pair drawn from a point x of [0,1)^6 (wi, wo unit, local frame): its
 * density under the distribution measured over, or 0 for no pair.  Called
 * from several threads at once. */
typedef double (*sb_pair_draw_fn)(const void *user, const double x[6], double wi[3], double wo[3]);
/* As sb_pairs_create, the pairs drawn by `draw` from the same points
 * instead of the mixture above (user must outlive the pairs): errors over
 * another distribution of pairs, e.g. a scene's (scene.h). */
SB_API sb_result_t sb_pairs_create_drawn(sb_context_t *ctx, const sb_source_t *src, const sb_estimate_opts_t *opts,
                                         sb_pair_draw_fn draw, const void *user, sb_pairs_t **out);
SB_API void sb_pairs_destroy(sb_pairs_t *pairs);
SB_API size_t sb_pairs_count(const sb_pairs_t *pairs);

typedef struct sb_estimate {
    size_t terms;             /* J' = 1..terms are filled (at most SB_EST_MAXJ) */
    size_t pairs, known;      /* pairs used, pairs where the source is known */
    size_t replicates;        /* replicates of the pairs used at J' = terms (the standard errors' K) */
    size_t reps[SB_EST_MAXJ]; /* [J'-1] the replicates prefix J' comes from (at most replicates) */
    int converged;            /* the headline's standard error met rel_se for every J' */
    double rel[SB_EST_MAXJ][SB_EST_Q_COUNT_][4]; /* [J'-1][quantity][R, G, B, all] relative L2 error */
    double se[SB_EST_MAXJ][SB_EST_Q_COUNT_][4];  /* its standard error */
    double p99[SB_EST_MAXJ][4];                  /* 99th-percentile relative error per pair */
    double max_rel[SB_EST_MAXJ][4];              /* largest relative error of a pair */
    double neg_frac[SB_EST_MAXJ];                /* fraction of the pair domain with a negative channel */
    double overshoot[SB_EST_MAXJ];               /* max |f~| / max |f| over the sampled pairs */
    /* colour: mean CIEDE2000 between the original's and the reconstruction's
     * colour at equal luminance (both scaled to Y = 0.5), over pairs where
     * the original's f cos theta_i is above 1 % of its largest luminance
     * (every 4th pair of the first 16 replicates); NaN when none or with
     * headline_only.  About 1 is just noticeable, above 2 visible. */
    double chroma_de[SB_EST_MAXJ];
    /* Where the error is (not with headline_only).  band: the headline's
     * relative L2 error of f cos theta_i over the pairs of band b only
     * (e^2 = int_b (f~ - f)^2 cos^2 / int_b f^2 cos^2), band_se its standard
     * error (replicates, as the headline's); band_share: the band's share of
     * the headline's energy int f^2 cos^2 theta_i (all channels).
     * Lit: the pairs where the channel's f cos theta_i is above 1 % of its
     * largest over the first 16 replicates (all: the RGB norm); p99_lit the
     * 99th percentile of the relative error |f~ - f| / |f| there under the
     * pair measure dwi dwo (same histogram as p99), max_rel_lit its largest.
     * min_rel: the most negative reconstructed value over the sampled pairs
     * divided by the channel's largest |f| (all: over channels, by the
     * largest of all); 0 when none is negative.  map: at J' = terms, the
     * headline's relative error per (theta_i, theta_o) cell of
     * sb_band_map_edges, all channels (NaN where a cell has no energy). */
    double band[SB_EST_MAXJ][SB_BAND_COUNT_][4];
    double band_se[SB_EST_MAXJ][SB_BAND_COUNT_][4];
    double band_share[SB_BAND_COUNT_];
    double p99_lit[SB_EST_MAXJ][4], max_rel_lit[SB_EST_MAXJ][4];
    double min_rel[SB_EST_MAXJ][4];
    double map[SB_EST_MAP][SB_EST_MAP];
} sb_estimate_t;

/* Estimate the errors of the first J' = 1..min(J, SB_EST_MAXJ) terms of f
 * (as stored; `scales` the per-term factors a shader applies, as
 * sb_exr_term_scales gives them for the stored texels, NULL = 1) on p with
 * the form `form`, against the source of `pairs`, adding replicates to
 * pairs as the target standard error asks (opts: those given to
 * sb_pairs_create, NULL = defaults).  A 1-channel f is compared with every
 * channel.  Errors: SB_ERR_ARG, SB_ERR_NOMEM. */
SB_API sb_result_t sb_estimate_compute(sb_context_t *ctx, sb_pairs_t *pairs, const sb_factors_t *f,
                                       const double *scales, const sb_param_t *p, sb_form_t form,
                                       const sb_estimate_opts_t *opts, sb_estimate_t *out);

/* Per-term weights in [0, 1] that make the headline on `pairs` non-increasing
 * in J': w[j * C + c] (C = sb_factors_channels(f), J = sb_factors_terms(f)
 * values per channel), for j = 0, 1, ... in turn with the terms before
 * scaled by their weights, is 1 when term j lowers the headline's error
 * sum of channel c over the pairs of the first reps[j] replicates, else
 * the w that minimises that sum (a least-squares step: the error of every
 * prefix is then at most that of the shorter one; 0 leaves a term unused).
 * reps: J counts, non-decreasing, as sb_estimate_t.reps gives them for f
 * (term j's weight on the pairs an estimate of j + 1 terms stops at, so a
 * prefix's weights do not depend on the terms after it); NULL: all of the
 * pairs for every term.  f, scales, p and form as in sb_estimate_compute;
 * the pairs are not grown (a count beyond them: all of them).  Terms
 * beyond SB_EST_MAXJ get 1.  Errors: SB_ERR_ARG, SB_ERR_NOMEM. */
SB_API sb_result_t sb_estimate_term_weights(sb_context_t *ctx, const sb_pairs_t *pairs, const sb_factors_t *f,
                                            const double *scales, const sb_param_t *p, sb_form_t form,
                                            const size_t *reps, double *w);
/* The headline at J (all terms) of every combination of the g textures of
 * gs[a] (a < ng) with the h textures of hs[b] (b < nh), all of one layout
 * (the same terms, channels and texture sizes), on all of the pairs in one
 * pass: out[a * nh + b] as sb_estimate_headline(est, J) of
 * sb_estimate_compute with headline_only on the same pairs and factors, to
 * rounding.  The pairs are not grown.  Errors: SB_ERR_ARG, SB_ERR_NOMEM. */
SB_API sb_result_t sb_estimate_headlines(sb_context_t *ctx, const sb_pairs_t *pairs, const sb_factors_t *const *gs,
                                         size_t ng, const sb_factors_t *const *hs, size_t nh, const sb_param_t *p,
                                         sb_form_t form, double *out);

/* The headline (relative L2 error of f cos(theta_i), all channels) after
 * j >= 1 terms; NAN beyond est->terms. */
SB_API double sb_estimate_headline(const sb_estimate_t *est, size_t j);
/* The band bounds after j >= 1 terms (h the headline): the band error
 * theta_i > 80 degrees at most max(3 h, 1 %) and theta_i > 89 degrees at
 * most max(10 h, 5 %), each with two standard errors of slack.  1 when
 * both hold, 0 when one breaks, -1 when unknown (j beyond est->terms or
 * no band errors). */
SB_API int sb_estimate_bands_bounded(const sb_estimate_t *est, size_t j);
/* The band of the largest error (band[j - 1][b][all]) after j >= 1 terms;
 * -1 beyond est->terms or when no band has a finite error. */
SB_API int sb_estimate_worst_band(const sb_estimate_t *est, size_t j);

#ifdef __cplusplus
}
#endif
#endif
