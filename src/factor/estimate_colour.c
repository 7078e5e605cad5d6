/* The estimator's colour error (estimate.h: chroma_de): for pairs whose
 * original f cos theta_i is above 1 % of the largest luminance, the
 * CIEDE2000 difference of the original's and the reconstruction's colour
 * at equal luminance (both scaled to Y = 0.5, negative channels clipped):
 * the chromaticity a viewer sees, apart from the energy the headline
 * measures.  A reconstruction with no light left there counts as a grey
 * of that luminance (its colour is gone).  Every EST_CHROMA_STRIDE-th pair
 * of the first EST_CHROMA_REPS replicates: CIEDE2000 costs about as much
 * as the rest of a pair's evaluation. */
#include <math.h>

#include "factor/estimate_impl.h"
#include "util/colour.h"

static double luminance(const double c[3]) { return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]; }

double est_chroma_threshold(const sb_pairs_t *P, size_t reps) {
    double ymax = 0;
    if (reps > EST_CHROMA_REPS) reps = EST_CHROMA_REPS;
    for (size_t i = 0; i < reps * P->rep && i < P->n; i++)
        if (P->known[i]) ymax = fmax(ymax, luminance(P->d + i * PD + 7) * P->d[i * PD + 2]);
    return 0.01 * ymax;
}

int est_chroma_pair(const eval_t *e, size_t i, const double *rec, double *de) {
    const double *d = e->P->d + i * PD, *f = d + 7;
    if (!(e->chroma_thr > 0) || i % EST_CHROMA_STRIDE || i >= EST_CHROMA_REPS * e->P->rep) return 0;
    double y = luminance(f);
    if (!(y * d[2] >= e->chroma_thr)) return 0;
    double lo[3], a[3];
    for (int c = 0; c < 3; c++)
        a[c] = (f[c] > 0 ? f[c] : 0) * 0.5 / y;
    sb_srgb_to_lab(a, lo);
    for (size_t j = 0; j < e->J; j++) {
        double r[3], lr[3];
        for (int c = 0; c < 3; c++) /* fmax(x, 0) inline: 0 for NaN and -0 as well */
            r[c] = rec[j * 3 + c] > 0 ? rec[j * 3 + c] : 0;
        double yr = luminance(r);
        for (int c = 0; c < 3; c++)
            r[c] = yr > 1e-12 * y ? r[c] * 0.5 / yr : 0.5;
        sb_srgb_to_lab(r, lr);
        de[j] += sb_ciede2000(lo, lr) * d[6];
    }
    return 1;
}
