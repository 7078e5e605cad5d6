/* Private: cells beyond the light's or the view's horizon continued by
 * the horizon's value (matrix_edge.c). */
#ifndef SEPBRDF_SAMPLE_EDGE_H
#define SEPBRDF_SAMPLE_EDGE_H

#include "sepbrdf/matrix.h"

/* Every cell of the dense matrix m (form cos, sampled from src on param)
 * whose pair is outside the domain only because wi = (x, y, z) passes
 * below the horizon (z <= 0, wo in the cap) gets the form's value at wi
 * lifted to just above the horizon, (x, y) / |(x, y)| sin t, cos t, with
 * t = SB_EDGE_THETA: f cos theta_i continued outside by its value at the
 * edge instead of by 0.  Likewise where wo passes below it (wi in the
 * cap: rv, SB_CAP_VIEW_EDGE), wo lifted, times the cell's cos theta_i:
 * there f cos theta_i need not fall to 0 even for a physical BRDF
 * (Lambert's kd cos theta_i does not).  The mask keeps those cells invalid.  For a BRDF
 * whose f cos theta_i falls to 0 at the horizon (every physical one) that
 * is 0 as before; for one that does not (classic Phong: ks (r.v)^n at the
 * horizon) a zero-filled fit would see a jump at the horizon, and the
 * bilinear lookup of the texels beside it would blend it into the grazing
 * pairs.  Only where the edge matters and is known: nothing when every
 * value there is below 1 % of the largest valid cell's, nor for a measured
 * table (SB_SOURCE_MEASURED), whose value at 89.9 degrees is its
 * extrapolation (RGL paper on vh at R = 12: continued by it, the headline
 * rose 6.0 -> 8.8 %).  Returns the cells continued. */
size_t sb_matrix_extend_edge(const sb_source_t *src, const sb_param_t *param, sb_matrix_t *m);

#endif
