/* The formulas of the analytic models (conventions in models.c): Lambert,
 * the Phong family, and the microfacet terms (distributions, shadowing,
 * Fresnel) of Cook-Torrance and the lecture's microfacet BRDF. */
#include <math.h>

#include "source/models_impl.h"
#include "util/internal.h"

/* ---- shared pieces ------------------------------------------------------ */

/* max(x, lo) and min(x, hi) as fmax/fmin give them for a NaN x (the bound),
 * written out: libm's fmax/fmin are calls (through the PLT) where these
 * are a compare, and they sit in the inner loop of every matrix cell. */
static inline double max_lo(double x, double lo) { return x > lo ? x : lo; }
static inline double min_hi(double x, double hi) { return x < hi ? x : hi; }
/* x^5 as products: pow() was 18 % of a streamed factorisation (perf). */
static inline double pow5(double x) {
    double x2 = x * x;
    return x2 * x2 * x;
}
static double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
static double clamp01(double x) { return min_hi(max_lo(x, 0.0), 1.0); }

static int below_horizon(const double l[3], const double v[3], double rgb[3]) {
    if (l[2] > 0 && v[2] > 0) return 0;
    rgb[0] = rgb[1] = rgb[2] = 0;
    return 1;
}

/* h = (l + v)/|l + v|; |l + v| >= l_z + v_z > 0 above the horizon.  The
 * length is taken after scaling by the largest component, so that it does
 * not underflow to 0 for grazing l = -v (l_z = v_z = 1e-300). */
static void half_vector(const double l[3], const double v[3], double h[3]) {
    double s[3] = {l[0] + v[0], l[1] + v[1], l[2] + v[2]}, len2 = dot3(s, s);
    if (len2 > 0x1p-900) { /* far from underflow: one quotient, then products (each ~1 ulp) */
        double ilen = 1 / sqrt(len2);
        for (int i = 0; i < 3; i++)
            h[i] = s[i] * ilen;
        return;
    }
    double big = max_lo(fabs(s[0]), max_lo(fabs(s[1]), s[2]));
    for (int i = 0; i < 3; i++)
        s[i] /= big;                    /* not * (1 / big): that overflows for a subnormal big */
    double ilen = 1 / sqrt(dot3(s, s)); /* len in [1, sqrt 3]: one quotient, then products */
    for (int i = 0; i < 3; i++)
        h[i] = s[i] * ilen;
}

/* sin^2 of the angle between n and the unit vector h, as h_x^2 + h_y^2:
 * exact where 1 - (n.h)^2 cancels (sharp lobes, n.h -> 1). */
static double sin2_n(const double h[3]) { return h[0] * h[0] + h[1] * h[1]; }

/* r.v with r = reflect(-l, n) = 2 (n.l) n - l. */
static double mirror_dot(const double l[3], const double v[3]) { return 2 * l[2] * v[2] - dot3(l, v); }

/* ---- Lambert ------------------------------------------------------------ */

/* f = c/pi */
int sb_model_lambert_(const void *self, const double l[3], const double v[3], double rgb[3]) {
    const model_t *m = self;
    if (below_horizon(l, v, rgb)) return 1;
    for (int c = 0; c < 3; c++)
        rgb[c] = m->albedo[c] / SB_PI;
    return 1;
}

/* ---- Phong family ------------------------------------------------------- */

/* Classic Phong as a BRDF (slides): f = kd + ks max(r.v, 0)^n / cos theta_i,
 * cos theta_i = n.l raised to the guard.  Not reciprocal (only n.l divides),
 * not energy conserving. */
int sb_model_phong_(const void *self, const double l[3], const double v[3], double rgb[3]) {
    const model_t *m = self;
    if (below_horizon(l, v, rgb)) return 1;
    double s = pow(max_lo(mirror_dot(l, v), 0.0), m->n) / max_lo(l[2], m->cmin);
    for (int c = 0; c < 3; c++)
        rgb[c] = m->kd[c] + m->ks[c] * s;
    return 1;
}

/* The lecture's phongBRDF: f = kd + ks max(r.v, 0)^n (no 1/cos theta_i, so
 * reciprocal, but neither 1/pi nor a lobe normalisation). */
int sb_model_phong_glsl_(const void *self, const double l[3], const double v[3], double rgb[3]) {
    const model_t *m = self;
    if (below_horizon(l, v, rgb)) return 1;
    double s = pow(max_lo(mirror_dot(l, v), 0.0), m->n);
    for (int c = 0; c < 3; c++)
        rgb[c] = m->kd[c] + m->ks[c] * s;
    return 1;
}

/* Modified (normalised) Phong, slides and lecture modifiedPhongBRDF:
 * f = kd/pi + ks (n + 2)/(2 pi) max(r.v, floor)^n.  The lobe integrates to
 * ks at normal incidence, so the albedo is <= kd + ks.  floor = 0 is the
 * slides' formula; the lecture's GLSL clamps r.v to 0.001 (pow(0, n) is
 * undefined in GLSL, not in C), reproduced by floor=0.001. */
int sb_model_mphong_(const void *self, const double l[3], const double v[3], double rgb[3]) {
    const model_t *m = self;
    if (below_horizon(l, v, rgb)) return 1;
    double s = m->cspec * pow(max_lo(mirror_dot(l, v), m->rv_floor), m->n);
    for (int c = 0; c < 3; c++)
        rgb[c] = m->kd[c] / SB_PI + m->ks[c] * s;
    return 1;
}

/* The lecture's blinnPhongBRDF: f = kd + ks max(n.h, 0)^n. */
int sb_model_blinn_(const void *self, const double l[3], const double v[3], double rgb[3]) {
    const model_t *m = self;
    if (below_horizon(l, v, rgb)) return 1;
    double h[3];
    half_vector(l, v, h);
    double s = pow(max_lo(h[2], 0.0), m->n);
    for (int c = 0; c < 3; c++)
        rgb[c] = m->kd[c] + m->ks[c] * s;
    return 1;
}

/* Normalised Blinn-Phong: f = kd/pi + ks C_n (n.h)^n, C_n = m->cspec (see
 * blinn_norm in models.c). */
int sb_model_nblinn_(const void *self, const double l[3], const double v[3], double rgb[3]) {
    const model_t *m = self;
    if (below_horizon(l, v, rgb)) return 1;
    double h[3];
    half_vector(l, v, h);
    double s = m->cspec * pow(max_lo(h[2], 0.0), m->n);
    for (int c = 0; c < 3; c++)
        rgb[c] = m->kd[c] / SB_PI + m->ks[c] * s;
    return 1;
}

/* ---- microfacet terms --------------------------------------------------- */

/* Normal distributions of the half vector; c = n.h > 0, s2 = 1 - c^2.
 *   ggx (paper eq. 6, lecture D_GGX), alpha = roughness^2:
 *       D = alpha^2 / (pi ((n.h)^2 (alpha^2 - 1) + 1)^2)
 *         = alpha^2 / (pi (s2 + c^2 alpha^2)^2)              (no cancellation)
 *   beckmann (slides), m = roughness:
 *       D = exp(-tan^2 g / m^2) / (4 m^2 cos^4 g)
 *     integrates to pi/4 over projected area (int D cos g dw = pi/4); with
 *     denom=pi it is the normalised Cook-Torrance (1982) specular term.
 *   beckmann-norm: D = exp(-tan^2 g / m^2) / (pi m^2 cos^4 g), int D cos g dw = 1.
 *   gaussian (slides), m = roughness:
 *       D = exp(-g^2 / (2 m^2)) / (m sqrt(2 pi)),  g = angle(n, h) in radians
 *     not normalised: int D cos g dw ~ sqrt(2 pi) m for small m (0.25 at
 *     m = 0.1, 1.25 at m = 0.5), so its albedo scales with m. */
static double ndf(const model_t *m, const double h[3]) {
    double c = h[2], s2 = sin2_n(h), a = m->alpha, a2 = a * a;
    switch (m->d) {
    case D_GGX: {
        double b = s2 + c * c * a2;
        return a2 / (SB_PI * b * b);
    }
    case D_BECKMANN:
    case D_BECKMANN_NORM: {
        /* m <= 1: where exp() is above underflow, tan^2 < 745, so c^2 > 1/746
         * and c^4 cannot underflow; where it is below, D = 0 exactly. */
        double c2 = c * c;
        if (c2 <= 0) return 0;
        double e = exp(-(s2 / c2) / a2);
        if (e == 0) return 0;
        double k = m->d == D_BECKMANN ? 4.0 : SB_PI;
        return e / (k * a2 * c2 * c2);
    }
    default: { /* D_GAUSSIAN */
        double g = atan2(sqrt(s2), c);
        return exp(-g * g / (2 * a2)) / (a * sqrt(2 * SB_PI));
    }
    }
}

/* Shadowing-masking G over the denominator's cosines, G / ((n.l)(n.v));
 * nl = n.l, nv = n.v, nh = n.h, vh = v.h = l.h.
 *   smith-schlick (paper eqs. 7-9): G = G1(n.l) G1(n.v), G1(c) = c/(c (1-k) + k),
 *       k = (roughness + 1)^2 / 8
 *   smith-disney (lecture G1_GGX_Schlick): the same k (Disney remapping
 *       r = (1 + roughness)/2, k = r^2/2), numerator max(c, guard)
 *   smith-alpha: k = alpha/2 with alpha the width of D (GGX roughness^2,
 *       Beckmann/Gaussian m = roughness); for GGX this is the lecture's
 *       commented-out original r = roughness, k = r^2/2; numerator c
 *   vcavity (slides, Cook-Torrance):
 *       G = min{1, 2 (n.h)(n.v)/(v.h), 2 (n.h)(n.l)/(l.h)}
 *   none: G = 1
 * A Smith G's numerators cancel the cosines (the guarded ones of
 * smith-disney too, as in the lecture's microfacetBRDF): one quotient
 * 1 / ((n.l (1-k) + k)(n.v (1-k) + k)), finite up to the horizon, that
 * needs no guard (raising only the cosines below to the guard made f fall
 * linearly to 0 within 0.06 degrees of the horizon).  With vcavity and
 * none the cosines are raised to the guard (lecture: max(n.v, 0.001)). */
static double shadowing_over_cos(const model_t *m, double nl, double nv, double nh, double vh) {
    double k = m->k;
    switch (m->g) {
    case G_SMITH_SCHLICK:
    case G_SMITH_ALPHA:
    case G_SMITH_DISNEY:
        return 1 / ((nl * (1 - k) + k) * (nv * (1 - k) + k));
    case G_VCAVITY:
        return fmin(1.0, fmin(2 * nh * nv / vh, 2 * nh * nl / vh)) / (max_lo(nl, m->cmin) * max_lo(nv, m->cmin));
    default:
        return 1 / (max_lo(nl, m->cmin) * max_lo(nv, m->cmin));
    }
}

/* Fresnel reflectance at c = l.h = v.h > 0, channel ch.
 *   schlick / conductor (paper eq. 10): F = F0 + (1 - F0)(1 - c)^5
 *   dielectric (slides): F = 1/2 ((g - c)/(g + c))^2 (1 + ((c (g + c) - 1)/(c (g - c) + 1))^2),
 *       g = sqrt(eta^2 + c^2 - 1); eta >= 1 gives g >= c, so g + c > 0 and
 *       c (g - c) + 1 >= 1.
 *   none: F = 1 */
static double fresnel(const model_t *m, double c, int ch) {
    switch (m->f) {
    case F_SCHLICK:
    case F_CONDUCTOR:
        return m->f0[ch] + (1 - m->f0[ch]) * pow5(1 - c);
    case F_DIELECTRIC: {
        double g = sqrt(m->ior * m->ior + c * c - 1);
        if (g + c <= 0) return 1; /* c -> 0 with eta = 1: the grazing limit */
        double a = (g - c) / (g + c), b = (c * (g + c) - 1) / (c * (g - c) + 1);
        return 0.5 * a * a * (1 + b * b);
    }
    default:
        return 1;
    }
}

/* Cook-Torrance with selectable terms:
 *   f = kd albedo/pi + ks D G F / den
 *   den = 4 (n.l)(n.v)  (denom=4, paper eq. 5/11)
 *       =   (n.l)(n.v)  (denom=cos, slides)
 *       = pi (n.l)(n.v) (denom=pi, Cook & Torrance 1982)
 * with G / ((n.l)(n.v)) from shadowing_over_cos (a Smith G cancels the
 * cosines; the others raise them to the guard). */
int sb_model_ct_(const void *self, const double l[3], const double v[3], double rgb[3]) {
    const model_t *m = self;
    if (below_horizon(l, v, rgb)) return 1;
    double h[3];
    half_vector(l, v, h);
    double nl = clamp01(l[2]), nv = clamp01(v[2]), nh = clamp01(h[2]), vh = clamp01(dot3(v, h));
    double dg = ndf(m, h) * shadowing_over_cos(m, nl, nv, nh, vh) / m->cspec;
    for (int c = 0; c < 3; c++)
        rgb[c] = m->kd[c] * m->albedo[c] / SB_PI + m->ks[c] * dg * fresnel(m, vh, c);
    return 1;
}

/* Anisotropic GGX (Burley 2012) with widths ax along the surface tangent
 * x and ay along y:  D = 1 / (pi ax ay (h_x^2/ax^2 + h_y^2/ay^2 + h_z^2)^2),
 * which is ndf()'s GGX for ax = ay = alpha. */
static double ndf_aniso(const model_t *m, const double h[3]) {
    /* = (ax ay)^3 / (pi B^2), B = ax^2 ay^2 b = h_x^2 ay^2 + h_y^2 ax^2 + h_z^2 ax^2 ay^2:
     * one quotient; every term positive, in range for widths >= 1e-6. */
    double ax2 = m->ax * m->ax, ay2 = m->ay * m->ay, axy = m->ax * m->ay;
    double b = h[0] * h[0] * ay2 + h[1] * h[1] * ax2 + h[2] * h[2] * (ax2 * ay2);
    return axy * axy * axy / (SB_PI * b * b);
}

/* The lecture's microfacetBRDF, unchanged (with anisotropy 0):
 *   f0 = mix(0.16 reflectance^2, base, metallic)
 *   F = f0 + (1 - f0)(1 - v.h)^5,  D = GGX(alpha = roughness^2),
 *   G = G1(n.l) G1(n.v), G1(c) = max(c, 0.001)/(c (1 - k) + k), k = ((1 + roughness)/2)^2 / 2
 *   f = (1 - F)(1 - metallic) base/pi + F D G / (4 max(n.v, 0.001) max(n.l, 0.001))
 * (0.001 is the guard key).  D uses the cancellation-free form above. */
int sb_model_microfacet_(const void *self, const double l[3], const double v[3], double rgb[3]) {
    const model_t *m = self;
    if (below_horizon(l, v, rgb)) return 1;
    double h[3];
    half_vector(l, v, h);
    double nv = clamp01(v[2]), nl = clamp01(l[2]), vh = clamp01(dot3(v, h));
    double D = m->anisotropy > 0 ? ndf_aniso(m, h) : ndf(m, h);
    double k = m->k;
    /* D G / (4 max(n.v, guard) max(n.l, guard)) with the guards of G's
     * numerators and of the denominator cancelled: one quotient. */
    double f5 = pow5(1 - vh), dgw = D / (4 * (nl * (1 - k) + k) * (nv * (1 - k) + k));
    for (int c = 0; c < 3; c++) {
        double f0 = 0.16 * m->reflectance * m->reflectance;
        f0 = f0 * (1 - m->metallic) + m->base[c] * m->metallic;
        double F = f0 + (1 - f0) * f5;
        double spec = F * dgw;
        double diff = m->base[c] * (1 - F) * (1 - m->metallic) / SB_PI;
        rgb[c] = diff + spec;
    }
    return 1;
}
