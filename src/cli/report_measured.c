/* The "measured" part of report.json and of factor's summary: what the
 * table held and the errors against its measurements (not against the
 * interpolated grid). */
#include <math.h>
#include <stdio.h>

#include "cli.h"

void cli_report_measured(json_t *j, const sb_source_t *src, const sb_factors_t *f, const sb_param_t *p,
                         sb_form_t form) {
    const sb_measured_info_t *in = sb_measured_source_info(src);
    if (!in) return;
    sb_sample_errors_t se;
    int have = sb_measured_sample_errors(NULL, src, f, p, form, &se) == SB_OK;
    json_begin_object(j, "measured");
    json_string(j, "format", in->format);
    json_int(j, "rows", (long long)in->rows);
    json_int(j, "samples", (long long)(have ? se.samples : 0));
    json_int(j, "outside", (long long)(have ? se.outside : 0));
    json_number(j, "source_rel_l2", have ? se.source_rel_l2 : NAN);
    json_begin_array(j, "sample_rel_l2");
    for (size_t k = 0; have && k < se.terms; k++)
        json_number(j, NULL, se.rel_l2[k]);
    json_end_array(j);
    json_string(j, "interp", sb_interp_name(in->interp));
    json_begin_object(j, "interp_cv");
    for (int m = SB_INTERP_NEAREST; m < SB_INTERP_COUNT_; m++)
        json_number(j, sb_interp_name((sb_interp_t)m), in->interp_cv[m]);
    json_end_object(j);
    json_int(j, "cv_held_out", (long long)in->cv_held_out);
    json_int(j, "out_of_gamut", (long long)in->out_of_gamut);
    json_string(j, "gamut", sb_gamut_name(in->gamut));
    json_end_object(j);
}

/* Warnings when the run asks for more than the data support: terms that
 * no longer lower the error at the measured samples (they fit the
 * interpolation between samples, not the data), and grid cells finer than
 * the samples' spacing (the grid then holds interpolated values only). */
static void warn_support(const sb_measured_info_t *in, const sb_sample_errors_t *se, size_t res) {
    size_t best = 0;
    for (size_t k = 1; k < se->terms; k++)
        if (se->rel_l2[k] < se->rel_l2[best] * (1 - 1e-3)) best = k;
    if (best + 1 < se->terms)
        cli_error(
            "factor",
            "warning: terms beyond J = %zu do not lower the error at the %zu measured samples (%.3g%% at J = %zu, "
            "%.3g%% at J = %zu): they fit the interpolation, not the data",
            best + 1, se->samples, 100 * se->rel_l2[best], best + 1, 100 * se->rel_l2[se->terms - 1], se->terms);
    double cell = 90.0 / (double)res, spacing = in->spacing * 180 / SB_PI;
    if (in->dims && spacing > 0 && cell < 0.5 * spacing)
        cli_error("factor",
                  "warning: --res %zu: cells of %.3g deg are finer than half the samples' median spacing (%.3g deg); "
                  "the extra resolution holds interpolated values only",
                  res, cell, spacing);
}

void cli_print_measured(const sb_source_t *src, const sb_factors_t *f, const sb_param_t *p, sb_form_t form,
                        size_t res) {
    const sb_measured_info_t *in = sb_measured_source_info(src);
    sb_sample_errors_t se;
    if (!in || sb_measured_sample_errors(NULL, src, f, p, form, &se) != SB_OK) return;
    warn_support(in, &se, res);
    printf("  at the %zu measured samples (f cos cos, relative L2):", se.samples);
    for (size_t k = 0; k < se.terms; k++)
        printf(" J=%zu %.3g%%", k + 1, 100 * se.rel_l2[k]);
    printf("\n");
    if (in->out_of_gamut)
        printf("  %zu spectral %s out of the sRGB gamut, %s\n", in->out_of_gamut, in->dims ? "rows" : "nodes",
               sb_gamut_name(in->gamut));
    if (isfinite(in->interp_cv[in->interp]))
        printf("  interpolation %s: cross-validated error %.3g%% at %zu held-out samples\n", sb_interp_name(in->interp),
               100 * in->interp_cv[in->interp], in->cv_held_out);
}
