/* The light's horizon continued outside the domain (edge.h). */
#include <math.h>

#include "sample/edge.h"
#include "util/internal.h"

/* theta_i of the lifted direction: 89.9 degrees, cos = 1.7e-3 (above the
 * 0.001 the shader divides by at most). */
#define SB_EDGE_COS 1.745328365898309e-3

static int lift(const double wi[3], double out[3]) {
    double n = hypot(wi[0], wi[1]), s = sqrt(1 - SB_EDGE_COS * SB_EDGE_COS);
    if (!(n > 0)) return 0;
    out[0] = wi[0] / n * s;
    out[1] = wi[1] / n * s;
    out[2] = SB_EDGE_COS;
    return 1;
}

size_t sb_matrix_extend_edge(const sb_source_t *src, const sb_param_t *param, sb_matrix_t *m) {
    if (!src || !param || !m || !m->mask || m->structured || m->streamed || m->form != SB_FORM_COS) return 0;
    size_t n = 0;
    for (size_t c = 0; c < m->cols; c++)
        for (size_t r = 0; r < m->rows; r++) {
            size_t at = r + c * m->ld;
            double wi[3], wo[3], l[3], rgb[3] = {0, 0, 0};
            if (m->mask[at] || sb_param_cell_dirs(param, r, c, wi, wo)) continue;
            if (!(wi[2] <= 0 && wo[2] > 0 && lift(wi, l) && sb_source_eval(src, l, wo, rgb))) continue;
            for (int ch = 0; ch < 3; ch++)
                if (m->data[ch] && isfinite(rgb[ch])) m->data[ch][at] = rgb[ch] * SB_EDGE_COS;
            n++;
        }
    return n;
}
