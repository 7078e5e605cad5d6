/* Texels fitted for the lookup, not point samples.  A shader interpolates
 * the textures bilinearly; texels that hold the samples at their centres
 * make the interpolant exact there and off between them: along an axis of
 * spacing h, f'' h^2 / 8 at the midpoints, always on the same side where f
 * curves one way.  The texels that minimise the L2 error of the
 * interpolant instead (the projection onto the hat functions, M c = b with
 * the mass matrix M = I + D/6 and b = f + D f / 12 to second order, D the
 * second difference) are, to that order,
 *     c = f - D f / 12,
 * which cuts the mean square of a smooth f's interpolation error from
 * h^4 f''^2 / 120 to h^4 f''^2 / 720 (2.45x in RMS).  The filter is linear
 * and acts on one texture axis, so filtering every term's g (h) along an
 * axis filters the reconstruction along it: the factorisation stays as it
 * is.  Near a sharp peak, a domain edge or the cells a masked fit
 * extrapolated, the curvature is not that of a smooth f, so each axis is
 * filtered only when the estimator's headline at J falls on its pairs
 * (greedily, g's axes then h's); the end texels of a clamped axis stay.
 * Non-negative factors keep their sign: their filtered texels are clamped
 * at 0 (Blinn-Phong on iso, 32 cells, J = 4: headline 8.2e-4 -> 3.4e-4). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "job_impl.h"
#include "sepbrdf/exr.h"
#include "util/internal.h"

#define TEXEL_FIT_ALPHA (1.0 / 12.0)

/* t (w x h, row-major, x fastest) along axis (0: x, 1: y): t_i -= alpha
 * (t_{i-1} - 2 t_i + t_{i+1}), at least lowest; wrap: repeated, else the end
 * texels stay. */
static void filter_axis(double *t, size_t w, size_t h, int axis, int wrap, double lowest, double *line) {
    size_t n = axis ? h : w, lines = axis ? w : h, step = axis ? w : 1, stride = axis ? 1 : w;
    for (size_t l = 0; l < lines; l++) {
        double *p = t + l * stride;
        for (size_t i = 0; i < n; i++)
            line[i] = p[i * step];
        for (size_t i = 0; i < n; i++) {
            int end = i == 0 || i + 1 == n;
            if (end && !wrap) continue;
            double lo = line[(i + n - 1) % n], hi = line[(i + 1) % n];
            p[i * step] = fmax(lowest, line[i] - TEXEL_FIT_ALPHA * (lo - 2 * line[i] + hi));
        }
    }
}

/* A copy of f with every term's texture of `side` filtered along axis. */
static sb_result_t filtered(sb_context_t *ctx, const sb_factors_t *f, const sb_param_t *p, int side, int axis,
                            sb_factors_t **out) {
    size_t J = sb_factors_terms(f), C = sb_factors_channels(f), w, h;
    sb_factors_size(f, side, &w, &h);
    int wrap[2];
    sb_param_wrap(p, side, wrap);
    sb_result_t r = job_factors_copy(ctx, f, J, out);
    double *line = r == SB_OK ? malloc((w > h ? w : h) * sizeof *line) : NULL;
    if (r == SB_OK && !line) {
        sb_factors_destroy(*out);
        *out = NULL;
        return sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    }
    double lowest = job_nonneg_method(sb_factors_get_meta(f, "method")) ? 0 : -INFINITY;
    for (size_t k = 0; r == SB_OK && k < J; k++)
        for (size_t c = 0; c < C; c++)
            filter_axis(sb_factors_tex(*out, side, k, c), w, h, axis, wrap[axis] == SB_WRAP_REPEAT, lowest, line);
    free(line);
    return r;
}

/* The headline at J of f as stored, on the job's pairs (no growth; on
 * fewer, the first 16384, the choice went the wrong way for GGX
 * roughness 0.3 and the Cornell table). */
static sb_result_t headline(sb_context_t *ctx, sb_job_t *job, const job_attempt_t *a, const sb_factors_t *f,
                            double *out) {
    sb_estimate_opts_t eo = {0};
    eo.max_pairs = 1;
    eo.headline_only = 1;
    eo.last_only = 1;
    sb_exr_opts_t xo = {job->o.half};
    sb_factors_t *q = NULL;
    sb_estimate_t *est = malloc(sizeof *est);
    if (!est) return sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    sb_result_t r = sb_factors_quantize(ctx, f, &xo, &q, NULL);
    if (r == SB_OK) r = sb_estimate_compute(ctx, job->pairs, q, NULL, a->param, a->m.form, &eo, est);
    *out = r == SB_OK ? sb_estimate_headline(est, sb_factors_terms(f)) : NAN;
    sb_factors_destroy(q);
    free(est);
    return r;
}

/* The texel fit's candidates: every combination of the filtered axes
 * (bit i: axis ax[i], filters applied in ascending order) ranked in one
 * pass (sb_estimate_headlines), then the greedy choice replayed on the
 * ranks; above this many bytes of variants' texels, one pass per axis. */
#define TEXEL_MANY_BYTES ((size_t)64 << 20)

/* Greedy, one estimator pass per axis: the way for large textures. */
static sb_result_t texel_fit_passes(sb_context_t *ctx, sb_job_t *job, job_attempt_t *a) {
    double best = sb_estimate_headline(a->est, sb_factors_terms(a->f));
    sb_result_t r = SB_OK;
    for (int side = 0; r == SB_OK && side < 2; side++)
        for (int axis = 0; r == SB_OK && axis < 2; axis++) {
            size_t w, h;
            sb_factors_size(a->f, side, &w, &h);
            if ((axis ? h : w) < 3) continue;
            sb_factors_t *g = NULL;
            double e = NAN;
            if ((r = filtered(ctx, a->f, a->param, side, axis, &g)) == SB_OK) r = headline(ctx, job, a, g, &e);
            if (r == SB_OK && e < best) {
                best = e;
                sb_factors_destroy(a->f);
                a->f = g;
                a->texel_fit |= 1u << (2 * side + axis);
            } else {
                sb_factors_destroy(g);
            }
        }
    return r;
}

/* a->f filtered along the axes ax[i] of the bits i of mask, in ascending
 * order (a copy; mask 0: a plain copy). */
static sb_result_t filtered_mask(sb_context_t *ctx, const job_attempt_t *a, const int *ax, size_t mask,
                                 sb_factors_t **out) {
    sb_factors_t *cur = NULL;
    sb_result_t r = job_factors_copy(ctx, a->f, sb_factors_terms(a->f), &cur);
    for (size_t i = 0; r == SB_OK && mask >> i; i++) {
        if (!(mask >> i & 1)) continue;
        sb_factors_t *next = NULL;
        r = filtered(ctx, cur, a->param, ax[i] / 2, ax[i] % 2, &next);
        sb_factors_destroy(cur);
        cur = next;
    }
    if (r != SB_OK) sb_factors_destroy(cur), cur = NULL;
    *out = cur;
    return r;
}

/* The same choice from one pass: the g variants (every subset of g's
 * filtered axes, ax[0..na_g-1]) against the h variants (h's axes, the
 * rest), sb_estimate_headlines; the greedy choice replayed on the ranks. */
static sb_result_t texel_fit_combined(sb_context_t *ctx, sb_job_t *job, job_attempt_t *a, const int *ax, size_t na,
                                      size_t na_g) {
    size_t ng = (size_t)1 << na_g, nh = (size_t)1 << (na - na_g);
    sb_factors_t *v[8] = {0}, *q[8] = {0}; /* g variants, then h variants (at most 4 + 4) */
    double h[16];
    sb_exr_opts_t xo = {job->o.half};
    sb_result_t r = SB_OK;
    for (size_t k = 0; r == SB_OK && k < ng + nh; k++) {
        size_t mask = k < ng ? k : (k - ng) << na_g;
        r = filtered_mask(ctx, a, ax, mask, &v[k]);
        if (r == SB_OK) r = sb_factors_quantize(ctx, v[k], &xo, &q[k], NULL); /* what a shader reads */
    }
    if (r == SB_OK)
        r = sb_estimate_headlines(ctx, job->pairs, (const sb_factors_t *const *)q, ng,
                                  (const sb_factors_t *const *)(q + ng), nh, a->param, a->m.form, h);
    for (size_t k = 0; k < ng + nh; k++) {
        sb_factors_destroy(v[k]);
        sb_factors_destroy(q[k]);
    }
    /* combination `mask` (bit i: axis ax[i]) is g variant mask & (ng - 1)
     * with h variant mask >> na_g */
    size_t cur = 0;
    for (size_t i = 0; r == SB_OK && i < na; i++) { /* greedy, axis by axis, as texel_fit_passes */
        size_t c = cur | (size_t)1 << i;
        if (h[(c & (ng - 1)) * nh + (c >> na_g)] < h[(cur & (ng - 1)) * nh + (cur >> na_g)]) cur = c;
    }
    if (r != SB_OK || cur == 0) return r;
    sb_factors_t *g = NULL;
    if ((r = filtered_mask(ctx, a, ax, cur, &g)) != SB_OK) return r;
    sb_factors_destroy(a->f);
    a->f = g;
    for (size_t i = 0; i < na; i++)
        if (cur >> i & 1) a->texel_fit |= 1u << ax[i];
    return SB_OK;
}

sb_result_t job_texel_fit(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a) {
    a->texel_fit = 0;
    if (job->o.plain_terms || a->m.structured || !a->est || !job->pairs) return SB_OK;
    double t0 = job_now();
    int ax[4];
    size_t na = 0, na_g = 0, texels = 0, J = sb_factors_terms(a->f), C = sb_factors_channels(a->f);
    for (int side = 0; side < 2; side++) {
        size_t w, h;
        sb_factors_size(a->f, side, &w, &h);
        texels += w * h;
        for (int axis = 0; axis < 2; axis++)
            if ((axis ? h : w) >= 3) ax[na++] = 2 * side + axis;
        if (side == 0) na_g = na;
    }
    if (!na) return SB_OK;
    /* interleaved texels of both sides for every variant */
    double bytes = (double)(((size_t)1 << na_g) + ((size_t)1 << (na - na_g))) * (double)texels *
                   (double)(J < SB_EST_MAXJ ? J : SB_EST_MAXJ) * (double)C * sizeof(double);
    sb_result_t r = bytes <= (double)TEXEL_MANY_BYTES ? texel_fit_combined(ctx, job, a, ax, na, na_g)
                                                      : texel_fit_passes(ctx, job, a);
    job->t_estimate += job_now() - t0;
    if (r != SB_OK || !a->texel_fit) return r;
    /* the texels no longer hold the samples */
    return job_remeasure(ctx, job, lv, a);
}

sb_result_t job_texel_replay(sb_context_t *ctx, const sb_param_t *p, unsigned mask, sb_factors_t **f) {
    sb_result_t r = SB_OK;
    for (int b = 0; r == SB_OK && b < 4; b++) {
        size_t w, h;
        sb_factors_size(*f, b / 2, &w, &h);
        if (!(mask >> b & 1) || (b % 2 ? h : w) < 3) continue;
        sb_factors_t *g = NULL;
        if ((r = filtered(ctx, *f, p, b / 2, b % 2, &g)) != SB_OK) break;
        sb_factors_destroy(*f);
        *f = g;
    }
    return r;
}

sb_result_t job_refine(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a) {
    sb_result_t r = job_estimate_reported(ctx, job, lv, a);
    if (r == SB_OK) r = job_texel_fit(ctx, job, lv, a);
    if (r == SB_OK) r = job_term_weights(ctx, job, lv, a);
    return r == SB_OK ? job_sample_weights(ctx, job, lv, a) : r;
}
