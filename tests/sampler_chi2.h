/* chi2 of the importance sampler against its own pdf (test_sampler.c,
 * bench/sampler_variance.c): directions binned on a theta-phi grid, bins
 * uniform in cos theta, against sb_pdf integrated over each bin by an
 * adaptive midpoint rule; bins expecting fewer than MIN_EXP counts pooled. */
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

/* sb_pdf over the rectangle [z0, z1] x [p0, p1] of (cos theta, phi):
 * midpoint rule on QK x QK points. */
#define QK 8
static inline double rect_mass(const sb_sampler_t *s, const double wo[3], double z0, double z1, double p0, double p1) {
    double dz = (z1 - z0) / QK, dp = (p1 - p0) / QK, sum = 0;
    for (int i = 0; i < QK; i++)
        for (int k = 0; k < QK; k++) {
            double z = z0 + (i + 0.5) * dz, phi = p0 + (k + 0.5) * dp;
            double r = sqrt(fmax(1 - z * z, 0)), w[3] = {r * cos(phi), r * sin(phi), z};
            sum += sb_pdf(s, wo, w);
        }
    return sum * dz * dp;
}

/* Adaptive: the four quarters of the rectangle against the estimate
 * `whole` of all of it, split again (each quarter to half the tolerance)
 * until they agree within tol, at least to depth QMIN (64 points a bin
 * and axis: two coarser estimates can miss a narrow peak alike, the
 * acrylic's highlight on io at 12 cells, 0.55 % of the mass at depth 2),
 * at most QMAX.  The pdf jumps at the sampler's
 * cell edges, which cut across the bins: the midpoint rule's error there
 * falls only as the step, and a fixed step either costs everywhere or
 * leaves an error that the chi2 reads as the sampler's (p-values piled
 * toward 0 over many cases, issue 38). */
#define QMIN 3
#define QMAX 7
static inline double rect_adapt(const sb_sampler_t *s, const double wo[3], const double r[4], double whole, double tol,
                                int depth) {
    double zm = 0.5 * (r[0] + r[1]), pm = 0.5 * (r[2] + r[3]), q[4][4], m[4], sum = 0;
    for (int i = 0; i < 4; i++) {
        q[i][0] = i & 1 ? zm : r[0], q[i][1] = i & 1 ? r[1] : zm;
        q[i][2] = i & 2 ? pm : r[2], q[i][3] = i & 2 ? r[3] : pm;
        sum += m[i] = rect_mass(s, wo, q[i][0], q[i][1], q[i][2], q[i][3]);
    }
    if (depth >= QMAX || (depth >= QMIN && fabs(sum - whole) <= tol)) return sum;
    sum = 0;
    for (int i = 0; i < 4; i++)
        sum += rect_adapt(s, wo, q[i], m[i], 0.5 * tol, depth + 1);
    return sum;
}

/* sb_pdf integrated over every bin, for a test of n draws: each bin's
 * quadrature error held below a twentieth of its counting noise
 * sqrt(n mass) / n, so that it adds at most ~1/400 a bin to chi2. */
static inline void expected_mass(const sb_sampler_t *s, const double wo[3], double n, double *mass) {
    for (size_t b = 0; b < NT * NP; b++) {
        size_t t = b / NP, q = b % NP;
        double r[4] = {1 - (double)(t + 1) / NT, 1 - (double)t / NT, (double)q * 2 * SB_PI / NP,
                       (double)(q + 1) * 2 * SB_PI / NP};
        double whole = rect_mass(s, wo, r[0], r[1], r[2], r[3]);
        mass[b] = rect_adapt(s, wo, r, whole, 0.05 * sqrt(fmax(n * whole, 1)) / n, 1);
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
