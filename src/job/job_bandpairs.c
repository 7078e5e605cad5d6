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
 * are 70-88 % with se 1-3 %; the pairs were half that run's CPU). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "factor/estimate_draw.h"
#include "job_impl.h"
#include "sepbrdf/exr.h"
#include "util/internal.h"

#define BP_C80 0.17364817766693041
#define BP_C0 0.003                    /* the grazing density's offset, as the estimator's */
#define BP_START 32                    /* replicates of 4096 pairs at first */
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

static double band_draw(const void *user, const double x[6], double wi[3], double wo[3]) {
    (void)user;
    int k = (int)(4 * x[0]);
    double c = k < 3 ? x[1] * BP_C[k < 0 ? 0 : k] : 1 / (1 / BP_C0 - x[1] * graze_k()) - BP_C0;
    sb_estimate_dir_z(fmin(BP_C[0], fmax(0, c)), x[2], wi);
    return wi_pdf(wi[2]) * sb_estimate_draw_wo(wi, x + 3, wo);
}

/* Whether the estimate's own grazing bands are precise enough already at
 * every J': each standard error at most BP_ENOUGH of its band. */
static int bands_precise(const sb_estimate_t *e) {
    static const int b[3] = {SB_BAND_TI60, SB_BAND_TI80, SB_BAND_TI89};
    for (size_t j = 0; j < e->terms; j++)
        for (int k = 0; k < 3; k++)
            if (!(e->band_se[j][b[k]][SB_CH_ALL] <= BP_ENOUGH * e->band[j][b[k]][SB_CH_ALL])) return 0;
    return 1;
}

sb_result_t job_band_pairs_measure(sb_context_t *ctx, sb_job_t *job, job_attempt_t *a) {
    /* within a --theta-max cap the estimate's pairs are the cap's: the bands beyond it are not measured */
    if (!a->est || !a->f || a->est_rank || job->scene || job_measures_cap(job) || job->o.sample_only) return SB_OK;
    if (bands_precise(a->est)) return SB_OK; /* the estimate's own figures stand */
    double t0 = job_now();
    sb_estimate_opts_t eo = {0};
    eo.start = BP_START;
    eo.max_pairs = BP_MAX_PAIRS;
    eo.seed = job->o.seed;
    eo.headline_only = 1;
    eo.bands = 1;
    eo.channels = job->o.channels;
    sb_result_t r = SB_OK;
    if (!job->band_pairs) r = sb_pairs_create_drawn(ctx, job->src, &eo, band_draw, NULL, &job->band_pairs);
    sb_exr_opts_t xo = {job->o.half};
    sb_factors_t *q = NULL;
    sb_estimate_t *e = r == SB_OK ? malloc(sizeof *e) : NULL;
    if (r == SB_OK && !e) r = sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    if (r == SB_OK) r = sb_factors_quantize(ctx, a->f, &xo, &q, NULL); /* what a shader reads, as job_estimate */
    if (r == SB_OK) r = sb_estimate_compute(ctx, job->band_pairs, q, NULL, a->param, a->m.form, &eo, e);
    static const int bands[3] = {SB_BAND_TI60, SB_BAND_TI80, SB_BAND_TI89};
    for (size_t j = 0; r == SB_OK && j < a->est->terms && j < e->terms; j++)
        for (int b = 0; b < 3; b++) {
            memcpy(a->est->band[j][bands[b]], e->band[j][bands[b]], sizeof a->est->band[j][bands[b]]);
            memcpy(a->est->band_se[j][bands[b]], e->band_se[j][bands[b]], sizeof a->est->band_se[j][bands[b]]);
        }
    if (r == SB_OK) a->band_pairs = e->pairs;
    sb_factors_destroy(q);
    free(e);
    job->t_estimate += job_now() - t0;
    /* the pairs only sharpen figures the estimate has: short of memory (a
     * --memory-limit, a ulimit) the estimate's own bands stand */
    if (r == SB_ERR_NOMEM || r == SB_ERR_OVERFLOW) r = SB_OK;
    return r;
}
