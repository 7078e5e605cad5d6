/* Errors of a reconstruction against the measured samples of a table (see
 * sb_measured_sample_errors in measured.h): one pass over the samples,
 * every prefix J' of the terms accumulated together. */
#include <math.h>
#include <string.h>

#include "factor/lookup.h"
#include "factor/sample_error.h"
#include "sepbrdf/factor.h"
#include "sepbrdf/measured.h"

/* The reconstruction's prefix sums at one pair: acc[j * 3 + c] after j + 1
 * terms, divided by the form weight as sb_factors_eval does; 0 outside. */
static int prefix_values(const sb_factors_t *f, const sb_param_t *p, sb_form_t form, size_t J, const double wi[3],
                         const double wo[3], double *acc) {
    double sg[2], sh[2], run[SB_SAMPLE_ERRORS_MAX * 3];
    memset(acc, 0, J * 3 * sizeof *acc);
    if (!sb_param_coords(p, wi, wo, sg, sh)) return 0;
    size_t ch = sb_factors_channels(f);
    double w = sb_form_divisor(form, wi, wo), gain = sb_param_gain(p, wi, wo);
    sb_factors_prefix_sums_(f, p, J, sg, sh, run); /* each side's footprint once */
    for (size_t j = 0; j < J; j++)
        for (size_t c = 0; c < 3; c++)
            acc[j * 3 + c] = sb_param_apply_gain(p, run[j * ch + (ch == 1 ? 0 : c)], gain) / w;
    return 1;
}

sb_result_t sb_measured_sample_errors(sb_context_t *ctx, const sb_source_t *src, const struct sb_factors *f,
                                      const sb_param_t *p, sb_form_t form, sb_sample_errors_t *out) {
    return sb_measured_sample_errors_channels(ctx, src, f, p, form, 0, out);
}

sb_result_t sb_measured_sample_errors_channels(sb_context_t *ctx, const sb_source_t *src, const struct sb_factors *f,
                                               const sb_param_t *p, sb_form_t form, unsigned channels,
                                               sb_sample_errors_t *out) {
    return sb_sample_errors_(ctx, src, f, p, form, channels, 0, out);
}

sb_result_t sb_sample_errors_(sb_context_t *ctx, const sb_source_t *src, const struct sb_factors *f,
                              const sb_param_t *p, sb_form_t form, unsigned channels, int in_domain,
                              sb_sample_errors_t *out) {
    unsigned mask = channels & 7u ? channels & 7u : 7u;
    if (!src || !f || !p || !out) return sb_error(ctx, SB_ERR_ARG, "sample errors: missing argument");
    size_t n = sb_source_sample_count(src), J = sb_factors_terms(f);
    if (n == 0)
        return sb_error(ctx, SB_ERR_ARG, "sample errors: %s has no measured samples", sb_source_description(src));
    if (J > SB_SAMPLE_ERRORS_MAX) J = SB_SAMPLE_ERRORS_MAX;
    memset(out, 0, sizeof *out);
    out->terms = J;
    double num[SB_SAMPLE_ERRORS_MAX] = {0}, acc[SB_SAMPLE_ERRORS_MAX * 3], den = 0, src_num = 0;
    for (size_t k = 0; k < n; k++) {
        double wi[3], wo[3], v[3], s[3];
        if (!sb_source_sample(src, k, wi, wo, v)) continue;
        int inside = prefix_values(f, p, form, J, wi, wo, acc);
        out->outside += (size_t)!inside;
        if (!inside && in_domain) continue;
        out->samples++;
        double w2 = wi[2] * wi[2] * wo[2] * wo[2];
        sb_source_eval(src, wi, wo, s);
        for (int c = 0; c < 3; c++) {
            if (!(mask >> c & 1u)) continue; /* a channel not measured: 0 in both */
            den += v[c] * v[c] * w2;
            src_num += (s[c] - v[c]) * (s[c] - v[c]) * w2;
            for (size_t j = 0; j < J; j++)
                num[j] += (acc[j * 3 + (size_t)c] - v[c]) * (acc[j * 3 + (size_t)c] - v[c]) * w2;
        }
    }
    if (!(den > 0) || !isfinite(den))
        return sb_error(ctx, SB_ERR_NUMERIC, "sample errors: %s: the %zu samples have no finite non-zero value",
                        sb_source_description(src), out->samples);
    for (size_t j = 0; j < J; j++)
        out->rel_l2[j] = sqrt(num[j] / den);
    out->source_rel_l2 = sqrt(src_num / den);
    return SB_OK;
}
