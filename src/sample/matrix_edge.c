/* The light's or the view's horizon continued outside the domain (edge.h). */
#include <math.h>
#include <stdlib.h>

#include "sample/edge.h"
#include "util/internal.h"

/* theta_i of the lifted direction: 89.9 degrees, cos = 1.7e-3 (above the
 * 0.001 the shader divides by at most). */
#define SB_EDGE_COS 1.745328365898309e-3
/* Below this share of the largest valid value the edge counts as 0. */
#define SB_EDGE_SHARE 0.01

static int lift(const double wi[3], double out[3]) {
    double n = hypot(wi[0], wi[1]), s = sqrt(1 - SB_EDGE_COS * SB_EDGE_COS);
    if (!(n > 0)) return 0;
    out[0] = wi[0] / n * s;
    out[1] = wi[1] / n * s;
    out[2] = SB_EDGE_COS;
    return 1;
}

/* The form's value at cell (r, c) with the direction below its horizon
 * (wi, or wo; the other in the cap) lifted to the edge into v (3); 0 when
 * the cell is valid or neither is. */
static int edge_value(const sb_source_t *src, const sb_param_t *param, const sb_matrix_t *m, size_t r, size_t c,
                      double v[3]) {
    double wi[3], wo[3], l[3];
    v[0] = v[1] = v[2] = 0;
    if (m->mask[r + c * m->ld] || sb_param_cell_dirs(param, r, c, wi, wo)) return 0;
    int light = wi[2] <= 0 && wo[2] > 0, view = wo[2] <= 0 && wi[2] > 0;
    if (!(light || view) || !lift(light ? wi : wo, l)) return 0;
    if (!(light ? sb_source_eval(src, l, wo, v) : sb_source_eval(src, wi, l, v))) return 0;
    double c_i = light ? SB_EDGE_COS : wi[2]; /* the form's cos theta_i */
    for (int ch = 0; ch < 3; ch++)
        v[ch] = isfinite(v[ch]) ? v[ch] * c_i : 0;
    return 1;
}

size_t sb_matrix_extend_edge(const sb_source_t *src, const sb_param_t *param, sb_matrix_t *m) {
    if (!src || !param || !m || !m->mask || m->structured || m->streamed || m->form != SB_FORM_COS) return 0;
    if (sb_source_flags(src) & SB_SOURCE_MEASURED) return 0; /* a table's edge is its extrapolation */
    size_t cells = m->rows * m->cols, n = 0;
    double top = 0, edge = 0, v[3];
    for (size_t i = 0; i < cells; i++)
        for (int ch = 0; ch < 3 && m->mask[i]; ch++)
            top = fmax(top, m->data[ch] ? fabs(m->data[ch][i]) : 0);
    for (size_t c = 0; c < m->cols; c++) /* the edge's largest value, against the valid cells' */
        for (size_t r = 0; r < m->rows; r++)
            if (edge_value(src, param, m, r, c, v)) edge = fmax(edge, fmax(fabs(v[0]), fmax(fabs(v[1]), fabs(v[2]))));
    if (!(edge > SB_EDGE_SHARE * top)) return 0; /* falls to 0 at the horizon: zeros as they are */
    for (size_t c = 0; c < m->cols; c++)
        for (size_t r = 0; r < m->rows; r++) {
            if (!edge_value(src, param, m, r, c, v)) continue;
            for (int ch = 0; ch < 3; ch++)
                if (m->data[ch]) m->data[ch][r + c * m->ld] = v[ch];
            n++;
        }
    return n;
}
