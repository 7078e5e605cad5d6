/* The reported grazing bands (theta_i above 60, 80, 89 degrees) measured
 * again on pairs of their own.  The job's estimator draws a sixth of its
 * pairs with theta_i > 80 degrees (its wi mixture: uniform, cosine and a
 * tenth grazing), so at the 32768 pairs a run usually stops at, a band's
 * ratio rests on a few thousand pairs and 8 replicates: GGX roughness 0.3,
 * iso, J = 4 reported theta_i > 80 degrees 0.332 +- 0.006 % where the
 * estimator grown to 2^21 pairs gives 0.309 +- 0.001 % and 10^6 pairs
 * drawn uniformly inside the band 0.301 +- 0.007 % (bench/bands.py
 * --check); the default gold's theta_i > 89 degrees 3.42 +- 1.5 % against
 * 3.9 %.  Here wi is drawn inside theta_i > 60 degrees only (a quarter
 * uniform there, above 80 and above 89 degrees each, a quarter by the
 * estimator's grazing density above 80 degrees), wo by the estimator's own
 * mixture (sb_estimate_draw_wo), each pair weighted by the exact
 * density, and the three bands (nested: every pair lies in the first) are
 * the ratios over these pairs, which replace the estimate's.  Not drawn
 * where the estimate's own three bands have standard errors within 5 % of
 * them at every J' (io -r 64 -J 8 on the default gold: its grazing bands
 * are 70-88 % with se 1-3 %; the pairs were half that run's CPU).
 *
 * The specular and retro-reflection bands (within SB_BAND_CONE_DEG of the
 * mirror direction or of wi) likewise, on pairs whose wo is drawn inside
 * the cones: the estimate's own pairs put few there and their sums are
 * heavy-tailed, so at its 16 384 pairs the band read low with a standard
 * error that did not show it (the default gold, J = 4, specular band:
 * 5.10e-4 +- 2.7e-5 at seeds 1-4, 6.5-6.8e-4 at seeds 5-6 where the run
 * drew 32 768 pairs, 6.06e-4 +- 7e-6 from 1.6 M pairs drawn outside the
 * library, docs/bands.md). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "factor/estimate_draw.h"
#include "job_impl.h"
#include "sepbrdf/exr.h"
#include "util/internal.h"

#define BP_C80 0.17364817766693041
#define BP_C0 0.003     /* the grazing density's offset, as the estimator's */
#define BP_START 32     /* replicates of 4096 pairs at first */
#define BP_CONE_START 4 /* the cones': nearly all their pairs lie in a band; grown while a band's se is above 5 % */
#define BP_CONE_MAX ((size_t)1 << 16)
#define BP_ENOUGH 0.05                 /* a band whose se is within this share of it needs no pairs of its own */
#define BP_MAX_PAIRS ((size_t)1 << 18) /* grown while the theta_i > 60 band's se is above 5 % of it */

static double graze_k(void) { return 1 / BP_C0 - 1 / (BP_C80 + BP_C0); }

/* wi: a quarter each uniform with theta_i above 60, 80 and 89 degrees
 * (cos theta_i below BP_C[k]), and the estimator's grazing density above
 * 80 degrees. */
static const double BP_C[3] = {0.5, BP_C80, 0.017452406437283376};

/* Density of cos theta_i = c (per solid angle). */
static double wi_pdf(double c) {
    double p = 0;
    for (int k = 0; k < 3; k++)
        p += c >= 0 && c <= BP_C[k] ? 0.25 / (2 * SB_PI * BP_C[k]) : 0;
    if (c >= 0 && c <= BP_C80) p += 0.25 / (graze_k() * (c + BP_C0) * (c + BP_C0) * 2 * SB_PI);
    return p;
}

/* wi with theta_i > 60 degrees from x[0..2] (wi_pdf). */
static void graze_wi(const double x[3], double wi[3]) {
    int k = (int)(4 * x[0]);
    double c = k < 3 ? x[1] * BP_C[k < 0 ? 0 : k] : 1 / (1 / BP_C0 - x[1] * graze_k()) - BP_C0;
    sb_estimate_dir_z(fmin(BP_C[0], fmax(0, c)), x[2], wi);
}

static double band_draw(const void *user, const double x[6], double wi[3], double wo[3]) {
    (void)user;
    graze_wi(x, wi);
    return wi_pdf(wi[2]) * sb_estimate_draw_wo(wi, x + 3, wo);
}

/* A unit direction within the cone of cos cc about the unit axis d,
 * uniform in solid angle, from u[2]. */
static void in_cone(const double d[3], double cc, const double u[2], double w[3]) {
    double z = 1 - u[0] * (1 - cc), s = sqrt(fmax(0, 1 - z * z)), ph = 2 * SB_PI * u[1], t[3], b[3];
    /* an orthonormal frame (t, b, d) */
    double a[3] = {fabs(d[0]) < 0.9 ? 1 : 0, fabs(d[0]) < 0.9 ? 0 : 1, 0};
    t[0] = a[1] * d[2] - a[2] * d[1];
    t[1] = a[2] * d[0] - a[0] * d[2];
    t[2] = a[0] * d[1] - a[1] * d[0];
    double n = sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
    for (int i = 0; i < 3; i++)
        t[i] /= n;
    b[0] = d[1] * t[2] - d[2] * t[1];
    b[1] = d[2] * t[0] - d[0] * t[2];
    b[2] = d[0] * t[1] - d[1] * t[0];
    for (int i = 0; i < 3; i++)
        w[i] = s * cos(ph) * t[i] + s * sin(ph) * b[i] + z * d[i];
}

#define CONE_UNIFORM 0.5 /* the share of wo drawn uniformly inside a cone (half each cone) */

/* wi a third each by the estimator's mixture, by the grazing bands' draw
 * (graze_wi) and uniformly within the cone's angle of the normal (where a
 * sharp lobe's peak lies in both cones); wo with probability CONE_UNIFORM
 * uniformly inside the specular or the retro cone (a half each), else by
 * the estimator's mixture for wo.  A pair inside either cone has density
 * p_i(wi) (a/2 (u_s + u_r) + (1 - a) p_o(wo | wi)), p_i the mean of the
 * three wi densities, u the cones' uniform densities where wo lies inside
 * them; pairs outside both are left out (density 0): the two bands' sums
 * over the whole domain.  (bench/band_draw.h draws inside a band too, but
 * uniformly and outside the library.) */
static double cone_draw(const void *user, const double x[6], double wi[3], double wo[3]) {
    (void)user;
    const double a = CONE_UNIFORM, cc = cos(SB_BAND_CONE_DEG * SB_PI / 180), u = 1 / (2 * SB_PI * (1 - cc));
    double y0[3] = {fmod(3 * x[0], 1), x[1], x[2]};
    if (x[0] < 1 / 3.)
        sb_estimate_draw_wi(y0, wi);
    else if (x[0] < 2 / 3.)
        graze_wi(y0, wi);
    else /* theta_i within the cone's angle: where the two cones meet (a sharp lobe's peak in both) */
        sb_estimate_dir_z(1 - y0[1] * (1 - cc), y0[2], wi);
    double pn = wi[2] >= cc ? u : 0;
    double pi = (sb_estimate_wi_pdf(wi) + wi_pdf(wi[2]) + pn) / 3, mir[3] = {-wi[0], -wi[1], wi[2]};
    if (x[3] < a) {
        in_cone(x[3] < a / 2 ? mir : wi, cc, x + 4, wo);
    } else {
        double y[3] = {(x[3] - a) / (1 - a), x[4], x[5]};
        sb_estimate_draw_wo(wi, y, wo);
    }
    if (!(pi > 0) || !(wi[2] > 0) || !(wo[2] > 0)) return 0;
    double ds = mir[0] * wo[0] + mir[1] * wo[1] + mir[2] * wo[2], dr = wi[0] * wo[0] + wi[1] * wo[1] + wi[2] * wo[2];
    double pu = (ds > cc ? u : 0) + (dr > cc ? u : 0);
    return pu > 0 ? pi * (a / 2 * pu + (1 - a) * sb_estimate_wo_pdf(wi, wo)) : 0;
}

static const int BP_GRAZING[3] = {SB_BAND_TI60, SB_BAND_TI80, SB_BAND_TI89};
static const int BP_CONES[2] = {SB_BAND_SPECULAR, SB_BAND_RETRO};

/* Whether the estimate's own bands b[0..nb) are precise enough already at
 * every J': each standard error at most BP_ENOUGH of its band. */
static int bands_precise(const sb_estimate_t *e, const int *b, int nb) {
    for (size_t j = 0; j < e->terms; j++)
        for (int k = 0; k < nb; k++)
            if (!(e->band_se[j][b[k]][SB_CH_ALL] <= BP_ENOUGH * e->band[j][b[k]][SB_CH_ALL])) return 0;
    return 1;
}

/* The bands b[0..nb) of a->est measured again on the pairs *pairs (drawn
 * by draw the first time): their figures replace the estimate's; returns
 * the pairs used in *used.  grow_on_bands: the pairs grow until those
 * bands' standard errors meet the target too, not the headline's alone. */
static sb_result_t measure_on(sb_context_t *ctx, sb_job_t *job, job_attempt_t *a, sb_pairs_t **pairs,
                              sb_pair_draw_fn draw, const int *b, int nb, int grow_on_bands, size_t start, size_t max,
                              size_t *used) {
    sb_estimate_opts_t eo = {0};
    eo.start = start;
    for (int k = 0; k < nb && grow_on_bands; k++)
        eo.stop_bands |= 1u << b[k];
    eo.max_pairs = max;
    eo.seed = job->o.seed;
    eo.headline_only = 1;
    eo.bands = 1;
    eo.channels = job->o.channels;
    sb_result_t r = SB_OK;
    if (!*pairs) r = sb_pairs_create_drawn(ctx, job->src, &eo, draw, NULL, pairs);
    const sb_factors_t *q = NULL;
    sb_estimate_t *e = r == SB_OK ? malloc(sizeof *e) : NULL;
    if (r == SB_OK && !e) r = sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    if (r == SB_OK) r = job_quantized(ctx, job, a->f, &q); /* what a shader reads, as job_estimate */
    if (r == SB_OK) r = sb_estimate_compute(ctx, *pairs, q, NULL, a->param, a->m.form, &eo, e);
    for (size_t j = 0; r == SB_OK && j < a->est->terms && j < e->terms; j++)
        for (int k = 0; k < nb; k++) {
            memcpy(a->est->band[j][b[k]], e->band[j][b[k]], sizeof a->est->band[j][b[k]]);
            memcpy(a->est->band_se[j][b[k]], e->band_se[j][b[k]], sizeof a->est->band_se[j][b[k]]);
        }
    if (r == SB_OK) *used += e->pairs;
    free(e);
    return r;
}

sb_result_t job_band_pairs_measure(sb_context_t *ctx, sb_job_t *job, job_attempt_t *a) {
    /* within a --theta-max cap the estimate's pairs are the cap's: the bands beyond it are not measured */
    if (!a->est || !a->f || a->est_rank || job->scene || job_measures_cap(job) || job->o.sample_only) return SB_OK;
    double t0 = job_now();
    sb_result_t r = SB_OK;
    a->band_pairs = 0;
    if (!bands_precise(a->est, BP_GRAZING, 3)) /* else the estimate's own figures stand */
        r = measure_on(ctx, job, a, &job->band_pairs, band_draw, BP_GRAZING, 3, 0, BP_START, BP_MAX_PAIRS,
                       &a->band_pairs);
    if (r == SB_OK) /* always: their own standard errors did not show how far off they were */
        r = measure_on(ctx, job, a, &job->cone_pairs, cone_draw, BP_CONES, 2, 1, BP_CONE_START, BP_CONE_MAX,
                       &a->band_pairs);
    job->t_estimate += job_now() - t0;
    /* the pairs only sharpen figures the estimate has: short of memory (a
     * --memory-limit, a ulimit) the estimate's own bands stand */
    if (r == SB_ERR_NOMEM || r == SB_ERR_OVERFLOW) r = SB_OK;
    return r;
}
