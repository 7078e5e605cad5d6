/* Private: the errors at a table's measured samples (sample_error.c) with
 * the samples outside the parameterisation's domain left out instead of
 * counted as 0: below --theta-max 90, where the snippet is not defined,
 * the job measures within the cap (job_support.c, job_report.c). */
#ifndef SEPBRDF_SAMPLE_ERROR_H
#define SEPBRDF_SAMPLE_ERROR_H

#include "sepbrdf/measured.h"

/* As sb_measured_sample_errors_channels; with in_domain, a sample outside
 * p's domain is counted in out->outside and left out of out->samples and
 * of every error. */
sb_result_t sb_sample_errors_(sb_context_t *ctx, const sb_source_t *src, const struct sb_factors *f,
                              const sb_param_t *p, sb_form_t form, unsigned channels, int in_domain,
                              sb_sample_errors_t *out);

#endif
