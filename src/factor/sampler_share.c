/* The shares of a sampler's mixture chosen from the fit's own error
 * against the source (sepbrdf/sampler.h, sb_sampler_choose_share).
 *
 * For an outgoing wo, one sample of the mixture p = s c + s_l l_a + (1 -
 * s - s_l) p_F (c = cos(theta_i) / pi, l_a the GGX lobe of roughness a,
 * p_F the factored density) estimates L = int y dwi, y = Y(f_r(wi, wo))
 * cos(theta_i) of the source; a failed draw counts 0, so with P = int p
 * over the hemisphere (1 less the failures) its variance is
 *     V = int (y / p - L)^2 p dwi + L^2 (1 - P).
 * Every candidate's V comes from the same N draws of the proposal q =
 * (p_{1/2} + mean_a l_a) / 2, half of them the sampler at s = 1/2 without
 * the lobe (positive wherever c is, so wherever y can be), half the lobes
 * of the candidate roughnesses in turn: the integral is E_q[(y / p - L)^2
 * p / q], with p_F(wi) = (p_{1/2} - c / 2) * 2 at each draw and L =
 * E_q[y / q] / E_q[c / q] (c integrates to 1: cosine the control variate).
 * P is known apart from the draws of the source: 1 for cosine, the
 * fraction of a grid of lobe draws above the horizon for l_a, and for p_F
 * the fraction of the factored half's draws that did not fail.  So each
 * V is a sum of squares, positive however small: cosine's, of order 1e-3
 * L^2 on a nearly diffuse source, was estimated before as E_q[y^2 / (q
 * c)] - E_q[y / q]^2, whose noise (L's, 1e-2 relative) put it at or
 * below 0 (GGX 0.3 on vh: cosine kept where a lobe gains 2-6 times).
 *
 * Per elevation theta_o the relative variances V / L^2 are averaged over
 * three azimuths; the candidate kept has the largest geometric mean of
 * V(1) / V over the elevations among those whose every ratio is at least
 * SB_SHARE_MARGIN and whose every V, raised by SB_SHARE_Z standard errors
 * of its estimate, stays below V(1), else s = 1: cosine sampling itself,
 * never worse than cosine.  (Not the error of V(1) - V: on a sharp
 * measured lobe cosine's own V is the noisy one, 40 % relative on RGL
 * malachite on io, and a gain of 35 to 600 times did not pass 2 of
 * them.) */
#include <math.h>
#include <stdlib.h>

#include "sampler_impl.h"
#include "sepbrdf/source.h"
#include "util/internal.h"
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
    double c, l, f; /* shares of cosine, lobe, factored */
    int a;          /* index in ALPHAS (l > 0) */
} cand_t;

static cand_t cand(int k) {
    if (k < NSHARE) return (cand_t){SHARES[k], 0, fmax(1 - SHARES[k], 0), 0};
    k -= NSHARE;
    double c = PAIRS[k / NALPHA][0], l = PAIRS[k / NALPHA][1];
    return (cand_t){c, l, fmax(1 - c - l, 0), k % NALPHA};
}

#define NPHI 3
static const double PHIS[NPHI] = {0.5, 2.6, 4.7};
/* A candidate is taken only where its estimated ratio is at least this at
 * every elevation: a margin for the estimate's noise (the default gold on
 * iso: 6.4, 6.3, 9.3, 17.1 estimated here, 5.9, 5.4, 8.0, 15.0 by
 * bench/sampler_variance.c with 10^5 new draws at another azimuth, before
 * the lobe). */
#define SB_SHARE_MARGIN 1.1
/* ... and where V(1) exceeds V by this many standard errors of V's
 * estimate (a guard against a V underestimated by its draws: with 0 the
 * same choices on the 45 materials and layouts of docs/positive.md, round
 * h38s). */
#define SB_SHARE_Z 2.0
/* The lobes' masses above the horizon: a G x G grid of their draws. */
#define MASS_GRID 32

static const double TH_DEG[SB_SAMPLER_CHOICE_WO] = {10, 30, 50, 70};

/* The draws of q for one wo that gave a wi in the hemisphere (m of n):
 * y, c, p_F, q and every l_a. */
typedef struct draws {
    size_t n, m;
    double *y, *c, *pf, *q, *pl; /* pl: m x NALPHA */
    double mass_f;               /* the factored part's mass above the horizon */
} draws_t;

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

/* n draws of q for wo into d; the source's y is 0 where it has no value.
 * The factored half's draws (even t, u0 >= 1/2) that fail give its mass.
 * With `first`, only up to the first y > 0 (whether the source has any). */
static void draw_view(sb_sampler_t *s, const sb_source_t *src, const double wo[3], size_t n, uint64_t seed, int first,
                      draws_t *d) {
    sb_rng_t rng;
    sb_rng_seed(&rng, seed);
    size_t tries = 0, fails = 0;
    d->n = n, d->m = 0;
    for (size_t t = 0; t < n; t++) {
        double u[2] = {sb_unit(sb_rng_next(&rng)), sb_unit(sb_rng_next(&rng))}, wi[3], ph, rgb[3];
        double *pl = d->pl + d->m * NALPHA;
        int factored = t % 2 == 0 && u[0] >= 0.5, ok = draw(s, wo, u, t, wi, &ph, pl);
        tries += factored, fails += factored && !ok;
        if (!ok) continue;
        double y = sb_source_eval(src, wi, wo, rgb) ? (0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]) * wi[2] : 0;
        double c = wi[2] / SB_PI, lm = 0;
        for (int a = 0; a < NALPHA; a++)
            lm += pl[a] / NALPHA;
        d->y[d->m] = y > 0 && isfinite(y) ? y : 0;
        d->c[d->m] = c;
        d->pf[d->m] = fmax(2 * ph - c, 0);
        d->q[d->m] = 0.5 * (ph + lm);
        if (d->y[d->m++] > 0 && first) break;
    }
    d->mass_f = tries ? 1 - (double)fails / (double)tries : 1;
}

/* The mass of the lobe of roughness alpha above the horizon for wo: the
 * fraction of a grid of its draws (the draws of draw() above). */
static double lobe_mass(double alpha, const double wo[3]) {
    size_t up = 0;
    for (int i = 0; i < MASS_GRID; i++)
        for (int j = 0; j < MASS_GRID; j++) {
            double d[3];
            up += sb_lobe_dir_(alpha, wo, (i + 0.5) / MASS_GRID, (j + 0.5) / MASS_GRID, d) && d[2] > 0;
        }
    return (double)up / (MASS_GRID * MASS_GRID);
}

/* For the draws of one wo: rv[k] += V_k / L^2 / NPHI for every candidate
 * k still in the running, se2[k] += the variance of that estimate /
 * NPHI^2.  Returns 0 (nothing added) where the source has nothing. */
static int view_variances(draws_t *d, const double mass_l[NALPHA], const unsigned char *alive, double *rv,
                          double *se2) {
    double sy = 0, sc = 0, n = (double)d->n;
    for (size_t i = 0; i < d->m; i++)
        sy += d->y[i] / d->q[i], sc += d->c[i] / d->q[i];
    if (!(sy > 0) || !(sc > 0)) return 0;
    double L = sy / sc;
    for (int k = 0; k < NCAND; k++) {
        if (!alive[k]) continue;
        cand_t x = cand(k);
        const double *pl = d->pl + x.a;
        double st = 0, st2 = 0;
        for (size_t i = 0; i < d->m; i++, pl += NALPHA) {
            double p = x.c * d->c[i] + x.l * *pl + x.f * d->pf[i], e = d->y[i] / p - L, t = e * e * p / d->q[i];
            st += t, st2 += t * t;
        }
        double miss = 1 - x.c - x.l * (x.l > 0 ? mass_l[x.a] : 1) - x.f * d->mass_f, mt = st / n;
        rv[k] += (mt + L * L * fmax(miss, 0)) / (L * L) / NPHI;
        se2[k] += fmax(st2 / n - mt * mt, 0) / n / (L * L * L * L) / (NPHI * NPHI);
    }
    return 1;
}

/* The relative variances and their estimates' squared errors at
 * elevation e, over the azimuths, for the candidates alive (cosine
 * always; where it is alone, only whether the source has anything
 * there); 0 when the source has nothing there. */
static int elevation(sb_sampler_t *s, const sb_source_t *src, size_t e, const unsigned char *alive, int alone,
                     draws_t *d, double *rv, double *se2) {
    int any = 0;
    for (int k = 0; k < NCAND; k++)
        rv[k] = se2[k] = 0;
    for (int a = 0; a < NPHI && !(alone && any); a++) {
        double wo[3], mass_l[NALPHA];
        sb_dir_from_angles(TH_DEG[e] * SB_PI / 180, PHIS[a], wo);
        draw_view(s, src, wo, d->n, 0x5eed0000u + 16 * e + (uint64_t)a, alone, d);
        for (int l = 0; l < NALPHA && !alone; l++)
            mass_l[l] = lobe_mass(ALPHAS[l], wo);
        any |= view_variances(d, mass_l, alive, rv, se2);
    }
    return any;
}

static double ratio_of(double v1, double v) { return v > 0 ? v1 / v : (v1 > 0 ? INFINITY : 1); }

/* Whether candidate k can be kept by elevation e's variances. */
static int admissible(const double *rv, const double *se2, int k) {
    return ratio_of(rv[0], rv[k]) >= SB_SHARE_MARGIN && rv[0] >= rv[k] + SB_SHARE_Z * sqrt(se2[k]);
}

/* The elevations in turn: a candidate not admissible at one cannot be
 * kept, so it is dropped from the next ones (the same choice as measuring
 * every candidate everywhere).  Returns the candidate kept (0: cosine):
 * of those admissible everywhere, the largest geometric mean ratio. */
static int measure_and_pick(sb_sampler_t *s, const sb_source_t *src, draws_t *d, double (*rv)[NCAND],
                            double (*se2)[NCAND], int *has) {
    unsigned char alive[NCAND];
    int left = NCAND - 1;
    for (int k = 0; k < NCAND; k++)
        alive[k] = 1;
    for (size_t e = 0; e < SB_SAMPLER_CHOICE_WO; e++) {
        has[e] = elevation(s, src, e, alive, left == 0, d, rv[e], se2[e]);
        for (int k = 1; k < NCAND && has[e] && left; k++)
            if (alive[k] && !admissible(rv[e], se2[e], k)) alive[k] = 0, left--;
    }
    int best = 0;
    double best_score = 0;
    for (int k = 1; k < NCAND && left; k++) {
        double score = 0;
        for (size_t e = 0; e < SB_SAMPLER_CHOICE_WO && alive[k]; e++)
            if (has[e]) score += log(fmin(ratio_of(rv[e][0], rv[e][k]), 1e6));
        if (alive[k] && score > best_score) best = k, best_score = score;
    }
    return best;
}

sb_result_t sb_sampler_choose_share(sb_context_t *ctx, sb_sampler_t *s, const sb_source_t *src, size_t samples,
                                    sb_sampler_choice_t *out) {
    if (!s || !src || !out) return sb_error(ctx, SB_ERR_ARG, "sampler: no sampler, source or output");
    size_t n = samples ? samples : 4096;
    double rv[SB_SAMPLER_CHOICE_WO][NCAND], se2[SB_SAMPLER_CHOICE_WO][NCAND];
    int has[SB_SAMPLER_CHOICE_WO];
    draws_t d = {n, 0, NULL, NULL, NULL, NULL, NULL, 1};
    double *buf = sb_alloc(ctx, n, (4 + NALPHA) * sizeof(double), "the share choice's draws");
    if (!buf) return SB_ERR_NOMEM;
    d.y = buf, d.c = buf + n, d.pf = buf + 2 * n, d.q = buf + 3 * n, d.pl = buf + 4 * n;
    sb_sampler_set_lobe(s, 0, 0);
    sb_sampler_set_cosine_share(s, 0.5);
    int best = measure_and_pick(s, src, &d, rv, se2, has);
    free(buf);
    cand_t x = cand(best);
    out->share = (float)x.c;
    out->lobe_share = (float)x.l;
    out->lobe_alpha = x.l > 0 ? (float)ALPHAS[x.a] : 0;
    for (size_t e = 0; e < SB_SAMPLER_CHOICE_WO; e++) {
        out->theta_o_deg[e] = TH_DEG[e];
        out->ratio[e] = !has[e] ? NAN : fmin(ratio_of(rv[e][0], rv[e][best]), 1e6);
    }
    sb_result_t r = sb_sampler_set_cosine_share(s, out->share);
    return r ? r : sb_sampler_set_lobe(s, out->lobe_share, out->lobe_alpha);
}
