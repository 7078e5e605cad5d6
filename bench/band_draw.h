/* Pairs drawn uniformly in solid angle inside an angular band by the
 * band's own definition (estimate.h SB_BAND_*), written out here and not
 * through the library: the brute-force side of tests/test_bands.c and of
 * sepbrdf_bench_bands (bench/bands_check.c). */
#ifndef SEPBRDF_BENCH_BAND_DRAW_H
#define SEPBRDF_BENCH_BAND_DRAW_H

#include <math.h>

#include "sepbrdf/estimate.h"

/* A direction at polar cos z, azimuth 2 pi u about the unit axis a. */
static inline void band_around(const double a[3], double z, double u, double w[3]) {
    double t[3] = {fabs(a[0]) < 0.9 ? 1 : 0, fabs(a[0]) < 0.9 ? 0 : 1, 0}, b1[3], b2[3];
    b1[0] = a[1] * t[2] - a[2] * t[1], b1[1] = a[2] * t[0] - a[0] * t[2], b1[2] = a[0] * t[1] - a[1] * t[0];
    double n = sqrt(b1[0] * b1[0] + b1[1] * b1[1] + b1[2] * b1[2]);
    for (int k = 0; k < 3; k++)
        b1[k] /= n;
    b2[0] = a[1] * b1[2] - a[2] * b1[1], b2[1] = a[2] * b1[0] - a[0] * b1[2], b2[2] = a[0] * b1[1] - a[1] * b1[0];
    double s = sqrt(fmax(0, 1 - z * z)), ph = 2 * 3.14159265358979323846 * u;
    for (int k = 0; k < 3; k++)
        w[k] = s * cos(ph) * b1[k] + s * sin(ph) * b2[k] + z * a[k];
}

/* The pair of the uniform numbers u[4] inside band b (SB_BAND_*; -1: all
 * pairs); 0 when it falls below the horizon (it adds nothing to either
 * sum of a band's error, so the ratio is that over the band). */
static inline int band_draw(int b, const double u[4], double wi[3], double wo[3]) {
    static const double deg[3] = {60, 80, 89};
    const double up[3] = {0, 0, 1};
    if (b <= SB_BAND_TO89) { /* theta above T on one side (b = -1: none), the other side uniform */
        double cT = b >= 0 ? cos(deg[b % 3] * 3.14159265358979323846 / 180) : 1;
        band_around(up, cT * u[0], u[1], b < SB_BAND_TO60 ? wi : wo);
        band_around(up, u[2], u[3], b < SB_BAND_TO60 ? wo : wi);
        return wi[2] > 0 && wo[2] > 0;
    }
    band_around(up, u[0], u[1], wi);
    double axis[3] = {b == SB_BAND_SPECULAR ? -wi[0] : wi[0], b == SB_BAND_SPECULAR ? -wi[1] : wi[1], wi[2]};
    double cc = cos(SB_BAND_CONE_DEG * 3.14159265358979323846 / 180);
    band_around(axis, cc + (1 - cc) * u[2], u[3], wo);
    return wo[2] > 0 && wi[2] > 0;
}

/* GGX's density of the half vector's cos c (per solid angle of h). */
static inline double band_ggx_d(double a, double c) {
    if (c <= 0) return 0;
    double c2 = c * c, k = a * a + (1 - c2) / c2;
    return a * a / (3.14159265358979323846 * c2 * c2 * k * k);
}

/* Density (per solid angle) of wo reflected about h ~ D(h) cos theta_h. */
static inline double band_ggx_pdf(double a, const double wi[3], const double wo[3]) {
    double h[3] = {wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]}, n = sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
    if (!(n > 0)) return 0;
    double oh = fabs(wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2]) / n;
    return oh > 0 ? band_ggx_d(a, h[2] / n) * h[2] / n / (4 * oh) : 0;
}

/* wo for wi from the mixture of u[3] in [0, 1)^3: a third uniform over the
 * hemisphere, a third each reflected about a GGX half vector of roughness
 * a and 3a (the mirror peaks at grazing incidence, where a sharp lobe's
 * error sits, drawn often enough).  Returns the pair's weight against a
 * uniform wo, 1 / (2 pi p(wo)); 0 below the horizon. */
static inline double band_mix_draw(double a, const double wi[3], const double u[3], double wo[3]) {
    const double pi = 3.14159265358979323846;
    if (u[0] < 1.0 / 3) {
        double z = u[1], s = sqrt(1 - z * z);
        wo[0] = s * cos(2 * pi * u[2]), wo[1] = s * sin(2 * pi * u[2]), wo[2] = z;
    } else {
        double b = u[0] < 2.0 / 3 ? a : 3 * a, v = fmin(u[1], 1 - 1e-16), t2 = b * b * v / (1 - v);
        double ch = 1 / sqrt(1 + t2), sh = sqrt(1 - ch * ch),
               h[3] = {sh * cos(2 * pi * u[2]), sh * sin(2 * pi * u[2]), ch};
        double d = wi[0] * h[0] + wi[1] * h[1] + wi[2] * h[2];
        for (int k = 0; k < 3; k++)
            wo[k] = 2 * d * h[k] - wi[k];
    }
    double p = (wo[2] > 0 ? 1 / (2 * pi) : 0) / 3 + band_ggx_pdf(a, wi, wo) / 3 + band_ggx_pdf(3 * a, wi, wo) / 3;
    return wo[2] > 0 && p > 0 ? 1 / (2 * pi * p) : 0;
}

/* Plain Monte Carlo sums of one band: per pair the squared error of
 * f cos theta_i (all channels) and the squared value; the band's relative
 * L2 error is the ratio of their means, its standard error by the delta
 * method. */
typedef struct band_sums {
    double sa, sd, saa, sdd, sad;
    size_t n;
} band_sums_t;

/* A pair (f, its reconstruction rec, cos theta_i) of weight w (its density
 * in the band's measure over the draw's: 1 for a uniform draw); a draw
 * outside the band or an unknown value adds zeros (f = rec = 0) and still
 * counts. */
static inline void band_add_w(band_sums_t *s, const double f[3], const double rec[3], double ci, double w) {
    double a = 0, d = 0;
    for (int c = 0; c < 3; c++) {
        a += (rec[c] - f[c]) * (rec[c] - f[c]) * ci * ci * w;
        d += f[c] * f[c] * ci * ci * w;
    }
    s->sa += a, s->sd += d, s->saa += a * a, s->sdd += d * d, s->sad += a * d;
    s->n++;
}

static inline void band_add(band_sums_t *s, const double f[3], const double rec[3], double ci) {
    band_add_w(s, f, rec, ci, 1);
}

static inline double band_ratio(const band_sums_t *s, double *se) {
    double N = (double)s->n, q = s->sa / s->sd, ma = s->sa / N, md = s->sd / N;
    double var = (s->saa / N - ma * ma) - 2 * q * (s->sad / N - ma * md) + q * q * (s->sdd / N - md * md);
    *se = sqrt(fmax(var, 0) / N) / md / (2 * sqrt(q));
    return sqrt(q);
}

#endif
