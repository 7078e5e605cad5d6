/* Private: every term's lookup at one pair of texture coordinates, each
 * side's bilinear footprint found once (factors.c). */
#ifndef SEPBRDF_FACTOR_LOOKUP_H
#define SEPBRDF_FACTOR_LOOKUP_H

#include "sepbrdf/factor.h"

/* run[j * C + c] = sum over t <= j of g_t,c(sg) h_t,c(sh) for j < J (C the
 * factors' channels), the same bits as sb_factors_lookup_brdf's products
 * summed term by term; NaN where a footprint is not finite. */
void sb_factors_prefix_sums_(const sb_factors_t *f, const sb_param_t *p, size_t J, const double sg[2],
                             const double sh[2], double *run);

#endif
