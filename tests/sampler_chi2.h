/* chi2 of the importance sampler against its own pdf (test_sampler.c,
 * bench/sampler_variance.c): directions binned on a theta-phi grid, bins
 * uniform in cos theta, against sb_pdf integrated over each bin by the
 * midpoint rule; bins expecting fewer than MIN_EXP counts pooled. */
#ifndef SB_TEST_SAMPLER_CHI2_H
#define SB_TEST_SAMPLER_CHI2_H

#include <math.h>
#include <stdlib.h>

#include "sepbrdf/sepbrdf.h"

#define NT 16      /* chi2 bins in theta over [0, pi/2] */
#define NP 32      /* and in phi */
#define MIN_EXP 5. /* bins expecting fewer counts are pooled */

/* Regularised upper incomplete gamma Q(a, x) (series below a + 1, Lentz's
 * continued fraction above): the chi2 p-value is Q(dof / 2, chi2 / 2). */
static inline double gamma_q(double a, double x) {
    if (x <= 0) return 1;
    double lg = lgamma(a);
    if (x < a + 1) {
        double ap = a, sum = 1 / a, del = sum;
        for (int n = 0; n < 10000 && fabs(del) > fabs(sum) * 1e-15; n++) {
            ap += 1;
            del *= x / ap;
            sum += del;
        }
        return 1 - sum * exp(-x + a * log(x) - lg);
    }
    double b = x + 1 - a, c = 1 / 1e-300, d = 1 / b, h = d;
    for (int i = 1; i < 10000; i++) {
        double an = -i * (i - a);
        b += 2;
        d = an * d + b;
        if (fabs(d) < 1e-300) d = 1e-300;
        c = b + an / c;
        if (fabs(c) < 1e-300) c = 1e-300;
        d = 1 / d;
        double del = d * c;
        h *= del;
        if (fabs(del - 1) < 1e-15) break;
    }
    return exp(-x + a * log(x) - lg) * h;
}

/* Bin of a direction in the upper hemisphere: theta uniform in cos. */
static inline size_t bin_of(const double w[3]) {
    double z = w[2] < 0 ? 0 : (w[2] > 1 ? 1 : w[2]), phi = atan2(w[1], w[0]);
    if (phi < 0) phi += 2 * SB_PI;
    size_t t = (size_t)((1 - z) * NT), q = (size_t)(phi / (2 * SB_PI) * NP);
    return (t < NT ? t : NT - 1) * NP + (q < NP ? q : NP - 1);
}

/* sb_pdf integrated over every bin (midpoint rule, sub^2 points a bin). */
static inline void expected_mass(const sb_sampler_t *s, const double wo[3], int sub, double *mass) {
    double dz = 1.0 / NT / sub, dp = 2 * SB_PI / NP / sub;
    for (size_t b = 0; b < NT * NP; b++) {
        size_t t = b / NP, q = b % NP;
        double sum = 0;
        for (int i = 0; i < sub; i++)
            for (int k = 0; k < sub; k++) {
                double z = 1 - ((double)t / NT + (i + 0.5) * dz), phi = (double)q * 2 * SB_PI / NP + (k + 0.5) * dp;
                double r = sqrt(fmax(1 - z * z, 0)), w[3] = {r * cos(phi), r * sin(phi), z};
                sum += sb_pdf(s, wo, w);
            }
        mass[b] = sum * dz * dp;
    }
}

static inline int cmp_desc(const void *a, const void *b) {
    const double *x = a, *y = b;
    return (x[0] < y[0]) - (x[0] > y[0]);
}

/* chi2 p-value of observed counts against n * mass, bins expecting fewer
 * than MIN_EXP pooled (the pool dropped if it still expects too few). */
static inline double chi2_p(const double *mass, const double *obs, double n, double *stat, int *dof) {
    double(*pairs)[2] = malloc(NT * NP * sizeof *pairs);
    for (size_t b = 0; b < NT * NP; b++) {
        pairs[b][0] = mass[b] * n;
        pairs[b][1] = obs[b];
    }
    qsort(pairs, NT * NP, sizeof *pairs, cmp_desc);
    double chi = 0, pe = 0, po = 0;
    int bins = 0;
    for (size_t b = 0; b < NT * NP; b++) {
        if (pairs[b][0] >= MIN_EXP) {
            double d = pairs[b][1] - pairs[b][0];
            chi += d * d / pairs[b][0];
            bins++;
        } else {
            pe += pairs[b][0];
            po += pairs[b][1];
        }
    }
    if (pe >= MIN_EXP) {
        chi += (po - pe) * (po - pe) / pe;
        bins++;
    } else if (po > 2 * MIN_EXP) {
        chi += 1e9; /* samples where the pdf says there are (almost) none */
    }
    free(pairs);
    *stat = chi;
    *dof = bins - 1;
    return gamma_q(0.5 * (bins - 1), 0.5 * chi);
}

#endif
