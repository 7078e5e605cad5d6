/* Colour difference as people judge it: linear sRGB (D65) -> CIE XYZ ->
 * CIELAB, and CIEDE2000 (Sharma, Wu & Dalal 2005, "The CIEDE2000
 * color-difference formula: implementation notes, supplementary test data,
 * and mathematical observations", with kL = kC = kH = 1). */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "util/colour.h"
#include "util/internal.h"

/* The cube root of a finite t > 0 (at most 1 ulp from the exact root over
 * 1e5 random t in [1e-6, 150] against 40 digits, as libm's cbrt): the
 * exponent by thirds from the bits, the root of the mantissa scaled into
 * [1, 8) from a quadratic (3.7 % off), two Halley steps and one Newton
 * step.  libm's cbrt (with its frexp and ldexp calls) was a third of the
 * estimator's colour error (issue 36). */
static double cbrt_pos(double t) {
    uint64_t b;
    memcpy(&b, &t, sizeof b);
    int e = (int)(b >> 52) - 1023, q = (e + 3 * 400) / 3 - 400; /* floor(e / 3) */
    b = (b & 0x000fffffffffffffULL) | 0x3ff0000000000000ULL;
    double m;
    memcpy(&m, &b, sizeof m);
    m *= (double)(1 << (e - 3 * q)); /* [1, 8) */
    double y = 0.8016089602148404 + m * (0.24782041775362446 + m * -0.01272919796295871);
    for (int k = 0; k < 2; k++) {
        double y3 = y * y * y;
        y = y * (y3 + 2 * m) / (2 * y3 + m);
    }
    y -= (y * y * y - m) / (3 * y * y);
    uint64_t s = (uint64_t)(q + 1023) << 52; /* 2^q: q is within the normal range for a normal t */
    double p2;
    memcpy(&p2, &s, sizeof p2);
    return y * p2;
}

/* CIELAB's f: cube root above (6/29)^3, linear below. */
static double lab_f(double t) {
    const double d = 6.0 / 29.0;
    return t > d * d * d && t <= DBL_MAX ? cbrt_pos(t) : (t > d * d * d ? cbrt(t) : t / (3 * d * d) + 4.0 / 29.0);
}

void sb_srgb_to_lab(const double rgb[3], double lab[3]) {
    /* IEC 61966-2-1 linear sRGB to XYZ (D65), white Y = 1 */
    double x = 0.4124 * rgb[0] + 0.3576 * rgb[1] + 0.1805 * rgb[2];
    double y = 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
    double z = 0.0193 * rgb[0] + 0.1192 * rgb[1] + 0.9505 * rgb[2];
    double fx = lab_f(x / 0.95047), fy = lab_f(y), fz = lab_f(z / 1.08883);
    lab[0] = 116 * fy - 16;
    lab[1] = 500 * (fx - fy);
    lab[2] = 200 * (fy - fz);
}

/* atan2(y, x) of finite y, x, not both 0, within 2 ulp (2e5 random pairs
 * against 40 digits; libm's: a quarter of CIEDE2000's time): t = min / max
 * of |x|, |y| in [0, 1], atan t = atan c + atan u with c = k / 8 the
 * nearest eighth and u = (t - c) / (1 + t c), |u| <= 1/16, by its series
 * to u^13 (the next term below 1e-17 u), then the octant. */
static double atan2_fin(double y, double x) {
    static const double tab[9] = {0.0,
                                  0.12435499454676144,
                                  0.24497866312686414,
                                  0.35877067027057225,
                                  0.4636476090008061,
                                  0.5585993153435624,
                                  0.6435011087932844,
                                  0.7188299996216245,
                                  0.7853981633974483};
    double ax = fabs(x), ay = fabs(y);
    int swap = ay > ax;
    double t = swap ? ax / ay : ay / ax;
    int k = (int)(t * 8 + 0.5);
    double c = k / 8.0, u = (t - c) / (1 + t * c), u2 = u * u;
    double p = 1.0 / 13;
    for (int n = 11; n >= 3; n -= 2) /* -1/3 + u2 (1/5 + u2 (... + u2 / 13)) */
        p = (n % 4 == 1 ? 1.0 : -1.0) / n + u2 * p;
    double a = tab[k] + (u + u * u2 * p);
    if (swap) a = 1.5707963267948966 - a;
    if (x < 0) a = 3.141592653589793 - a;
    return y < 0 ? -a : a;
}

/* Hue angle in degrees, [0, 360); 0 for a = b = 0 (Sharma's convention). */
static double hue_deg(double b, double a) {
    if (a == 0 && b == 0) return 0;
    double h = (isfinite(a) && isfinite(b) ? atan2_fin(b, a) : atan2(b, a)) * 180 / SB_PI;
    return h < 0 ? h + 360 : h;
}

static double rad(double deg) { return deg * SB_PI / 180; }

/* x^7 / (x^7 + 25^7) by products (pow is most of the formula's time). */
static double chroma7(double x) {
    double x2 = x * x, x7 = x2 * x2 * x2 * x;
    return x7 / (x7 + 6103515625.0);
}

/* Sharma's T(h) = 1 - 0.17 cos(h - 30) + 0.24 cos(2h) + 0.32 cos(3h + 6)
 * - 0.20 cos(4h - 63), the multiples from one sine and cosine by the angle sums. */
static double hue_t(double hm_deg) {
    double s = sin(rad(hm_deg)), c = cos(rad(hm_deg));
    double c2 = 2 * c * c - 1, s2 = 2 * s * c, c3 = c * (4 * c * c - 3), s3 = s * (3 - 4 * s * s);
    double c4 = 2 * c2 * c2 - 1, s4 = 2 * s2 * c2;
    static const double c30 = 0.86602540378443865, c6 = 0.99452189536827329, s6 = 0.10452846326765347;
    static const double c63 = 0.45399049973954675, s63 = 0.89100652418836786;
    return 1 - 0.17 * (c * c30 + s * 0.5) + 0.24 * c2 + 0.32 * (c3 * c6 - s3 * s6) - 0.20 * (c4 * c63 + s4 * s63);
}

double sb_ciede2000(const double lab1[3], const double lab2[3]) {
    double L1 = lab1[0], a1 = lab1[1], b1 = lab1[2], L2 = lab2[0], a2 = lab2[1], b2 = lab2[2];
    /* a' = (1 + G) a, G from the mean chroma (Lab values are far from
     * overflow: sqrt of the sum of squares, not hypot) */
    double cb = (sqrt(a1 * a1 + b1 * b1) + sqrt(a2 * a2 + b2 * b2)) / 2;
    double G = 0.5 * (1 - sqrt(chroma7(cb)));
    double ap1 = (1 + G) * a1, ap2 = (1 + G) * a2;
    double C1 = sqrt(ap1 * ap1 + b1 * b1), C2 = sqrt(ap2 * ap2 + b2 * b2), h1 = hue_deg(b1, ap1), h2 = hue_deg(b2, ap2);
    /* differences of lightness, chroma and hue */
    double dL = L2 - L1, dC = C2 - C1, dh = 0;
    if (C1 * C2 != 0) {
        dh = h2 - h1;
        if (dh > 180) dh -= 360;
        if (dh < -180) dh += 360;
    }
    double dH = 2 * sqrt(C1 * C2) * sin(rad(dh / 2));
    /* means: the hue's around the circle */
    double Lm = (L1 + L2) / 2, Cm = (C1 + C2) / 2, hm = h1 + h2;
    if (C1 * C2 != 0) {
        if (fabs(h1 - h2) <= 180)
            hm = (h1 + h2) / 2;
        else
            hm = h1 + h2 < 360 ? (h1 + h2 + 360) / 2 : (h1 + h2 - 360) / 2;
    }
    double T = hue_t(hm);
    double dtheta = 30 * exp(-((hm - 275) / 25) * ((hm - 275) / 25));
    double RC = 2 * sqrt(chroma7(Cm)), l50 = (Lm - 50) * (Lm - 50);
    double SL = 1 + 0.015 * l50 / sqrt(20 + l50), SC = 1 + 0.045 * Cm, SH = 1 + 0.015 * Cm * T;
    double RT = -sin(rad(2 * dtheta)) * RC;
    double tl = dL / SL, tc = dC / SC, th = dH / SH;
    return sqrt(tl * tl + tc * tc + th * th + RT * tc * th);
}

double sb_delta_e_exposed(const double ref[3], const double rec[3], double exposure) {
    double a[3], b[3], la[3], lb[3];
    for (int c = 0; c < 3; c++) {
        a[c] = fmax(ref[c], 0) * exposure;
        b[c] = fmax(rec[c], 0) * exposure;
    }
    sb_srgb_to_lab(a, la);
    sb_srgb_to_lab(b, lb);
    return sb_ciede2000(la, lb);
}
