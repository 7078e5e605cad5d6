/* Private: sb_form_divisor (matrix.h) inline, for the loops that divide
 * per pair (the estimator: one call a pair was 2 % of its instructions). */
#ifndef SEPBRDF_SAMPLE_DIVISOR_H
#define SEPBRDF_SAMPLE_DIVISOR_H

#include <math.h>

#include "sepbrdf/matrix.h"

static inline double sb_form_divisor_inline(sb_form_t form, const double wi[3], const double wo[3]) {
    double w = 1;
    if (form == SB_FORM_COS || form == SB_FORM_COS2) w = fmax(wi[2], 0.001);
    if (form == SB_FORM_COS2) w *= fmax(wo[2], 0.001);
    return w;
}

#endif
