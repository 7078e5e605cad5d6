/* Term weights at the measurements of a scattered table (Cornell, ALTA,
 * CSV, simulated gonio): the truth there is the samples, and the error at
 * them (report.json measured.sample_rel_l2, sb_measured_sample_errors)
 * must not rise with J'.  The terms are fitted to the interpolated table,
 * and one more term can move the reconstruction away from a sample while
 * it brings it closer to the interpolation between samples.
 *
 * Term by term (one weight for every channel of a term): with R the
 * prefix before term j (weights already chosen) and t the term's value at
 * each sample, the error at the samples after it is
 * e(w) = sum_s W_s (max(0, R_s + w t_s) - v_s)^2 (W_s = cos^2 theta_i
 * cos^2 theta_o, as sample_rel_l2 weighs them).  A term that lowers it as
 * fitted keeps w = 1; one that raises it keeps the most of itself that
 * does not: w = 2 b / a where e would be the parabola e(0) - 2 w b + w^2 a
 * without the clipping at 0, shrunk until e(w) <= e(0) holds with it (w =
 * 0 always does).  Layouts on a source's own tables keep their terms (the
 * gain there is not a sum of terms).  Applied on top of the headline's
 * weights (job_weights.c); kept
 * unless they raise the headline at J by more than JOB_SW_MAX_LOSS. */
#include <math.h>
#include <stdlib.h>

#include "job_impl.h"
#include "util/internal.h"

#define JOB_SW_MAX_LOSS 1.25

/* One sample, where the terms are read and what they must return. */
typedef struct sw_sample {
    double sg[2], sh[2], v[3], W, div;
} sw_sample_t;

/* The samples inside the layout (*n of them). */
static sw_sample_t *sw_samples(const sb_job_t *job, const job_attempt_t *a, size_t *n) {
    size_t N = sb_source_sample_count(job->src), k = 0;
    sw_sample_t *s = N ? malloc(N * sizeof *s) : NULL;
    for (size_t i = 0; s && i < N; i++) {
        double wi[3], wo[3];
        sw_sample_t *x = &s[k];
        if (!sb_source_sample(job->src, i, wi, wo, x->v) || !sb_param_coords(a->param, wi, wo, x->sg, x->sh)) continue;
        x->W = wi[2] * wi[2] * wo[2] * wo[2];
        for (int c = 0; c < 3; c++) /* a channel not factored (--channels) is measured nowhere */
            x->v[c] = job_factors_channel(job, c) ? x->v[c] : 0;
        x->div = sb_form_divisor(a->m.form, wi, wo);
        k += x->W > 0 && x->div > 0;
    }
    *n = k;
    return s;
}

/* The error at the samples (squared, weighted) of max(0, R + w t), as
 * sb_measured_sample_errors measures the reconstruction. */
static double sw_error(const sw_sample_t *s, size_t n, const double *R, const double *t, size_t C, double w) {
    double e = 0;
    for (size_t i = 0; i < n; i++)
        for (size_t o = 0; o < 3; o++) {
            double r = fmax(0, R[i * 3 + o] + w * t[i * C + (C == 1 ? 0 : o)]) - s[i].v[o];
            e += s[i].W * r * r;
        }
    return e;
}

/* Choose w[j * C + c] in [0, 1] (1 where the term lowers the error at the
 * samples); R: n * 3 running prefixes.  Returns whether any is below 1. */
static int sw_choose(const sb_factors_t *f, const sb_param_t *p, const sw_sample_t *s, size_t n, double *R, double *w) {
    size_t J = sb_factors_terms(f), C = sb_factors_channels(f);
    int any = 0;
    double *t = malloc(n * C * sizeof *t);
    if (!t) return 0;
    for (size_t j = 0; j < J; j++) {
        for (size_t i = 0; i < n; i++)
            for (size_t c = 0; c < C; c++)
                t[i * C + c] = sb_factors_lookup_brdf(f, p, 0, j, c, s[i].sg) *
                               sb_factors_lookup_brdf(f, p, 1, j, c, s[i].sh) / s[i].div;
        double e0 = sw_error(s, n, R, t, C, 0), wj = 1;
        if (sw_error(s, n, R, t, C, 1) > e0) { /* the most of the term that does not raise it */
            double a = 0, b = 0;               /* linear: e(w) = e(0) - 2 w b + w^2 a, e(w) <= e(0) up to w = 2 b / a */
            for (size_t i = 0; i < n; i++)
                for (size_t o = 0; o < 3; o++) {
                    double x = t[i * C + (C == 1 ? 0 : o)];
                    a += s[i].W * x * x;
                    b += s[i].W * x * (s[i].v[o] - R[i * 3 + o]);
                }
            wj = a > 0 ? fmin(1, fmax(0, 2 * b / a)) : 0;
            while (wj > 1e-3 && sw_error(s, n, R, t, C, wj) > e0) /* the reconstruction clips at 0: not linear */
                wj *= 0.7;
            if (wj <= 1e-3) wj = 0;
        }
        any |= wj < 1;
        for (size_t c = 0; c < C; c++)
            w[j * C + c] = wj;
        for (size_t i = 0; i < n; i++)
            for (size_t o = 0; o < 3; o++)
                R[i * 3 + o] += wj * t[i * C + (C == 1 ? 0 : o)];
    }
    free(t);
    return any;
}

sb_result_t job_sample_weights(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a) {
    const sb_measured_info_t *in = sb_measured_source_info(job->src);
    if (!in || !in->dims || job->o.plain_terms || !a->f || !a->est || (sb_param_caps(a->param) & SB_CAP_TABLES))
        return SB_OK;
    size_t n = 0, J = sb_factors_terms(a->f), C = sb_factors_channels(a->f);
    sw_sample_t *s = sw_samples(job, a, &n);
    double *R = s ? calloc(n * 3 + 1, sizeof *R) : NULL, *w = R ? malloc(J * C * sizeof *w) : NULL;
    sb_factors_t *keep = NULL;
    sb_result_t r = w ? SB_OK : sb_error(ctx, SB_ERR_NOMEM, "term weights at the samples: out of memory");
    int any = r == SB_OK && n > 0 && sw_choose(a->f, a->param, s, n, R, w);
    free(s);
    free(R);
    if (any) r = job_factors_copy(ctx, a->f, J, &keep);
    if (!any || r != SB_OK) {
        free(w);
        return r;
    }
    double before = sb_estimate_headline(a->est, J);
    double *old = a->term_w;
    for (size_t i = 0; i < J * C; i++) {
        job_scale_term(a->f, i / C, i % C, w[i]);
        w[i] *= old ? old[i] : 1;
    }
    a->term_w = w;
    r = job_remeasure(ctx, job, lv, a);
    if (r != SB_OK || !(sb_estimate_headline(a->est, J) > JOB_SW_MAX_LOSS * before)) {
        free(old);
        sb_factors_destroy(keep);
        return r;
    }
    /* the headline at J is what the user asked for: the terms as they were */
    return job_terms_restore(ctx, job, lv, a, keep, old);
}
