/* The half-vector layouts' sampler (sampler.h, SB_CAP_HALF_ROWS): the h
 * that reflect wo above the horizon, so that no sample is spent below it.
 *
 * With theta_v, phi_v the angles of wo and h at (theta, phi), Delta = phi -
 * phi_v, the reflection wi = 2 (wo.h) h - wo has
 *     wi_z = 2 (wo.h) cos(theta) - cos(theta_v) > 0
 *       <=>  cos(Delta) sin(2 theta) sin(theta_v) > -cos(2 theta) cos(theta_v)
 *       <=>  theta < theta_max(Delta) = pi/4 + atan2(cos(Delta) sin(theta_v), cos(theta_v)) / 2
 * (wo.h > 0 follows).  So on a phi arc the valid h lie below the largest
 * theta_max over the arc, z = 1 - cos(theta) below z_cut = 1 - cos of it,
 * and at a given theta, Delta lies within +-acos(c), c = -cos(2 theta)
 * cos(theta_v) / (sin(2 theta) sin(theta_v)) (all of it when c <= -1).
 * The row cells of both layouts are z-phi rectangles (sb_param_row_sample
 * is linear in z and in phi): z in [z_lo, z_hi], phi in [a, a + w]. */
#include <math.h>

#include "sampler_impl.h"

void half_view(const double wo[3], half_view_t *v) {
    double r = hypot(wo[0], wo[1]);
    v->cv = wo[2];
    v->sv = r;
    v->phiv = r > 0 ? atan2(wo[1], wo[0]) : 0;
}

/* Delta = phi - phi_v wrapped into [-pi, pi). */
static double wrap_pi(double d) {
    d = fmod(d + SB_PI, 2 * SB_PI);
    return (d < 0 ? d + 2 * SB_PI : d) - SB_PI;
}

double half_zcut(const half_view_t *v, double a, double w) {
    double d0 = wrap_pi(a - v->phiv), cmax;
    if (w >= 2 * SB_PI || (d0 <= 0 && d0 + w >= 0) || d0 + w >= 2 * SB_PI)
        cmax = 1; /* the arc holds phi_v */
    else
        cmax = fmax(cos(d0), cos(d0 + w));
    double t = 0.25 * SB_PI + 0.5 * atan2(cmax * v->sv, v->cv);
    return 2 * sin(0.5 * t) * sin(0.5 * t); /* 1 - cos(t), accurate near 0 */
}

/* Half-width of the valid Delta at z (pi: all; 0: none). */
static double half_width(const half_view_t *v, double z) {
    double ct = 1 - z, st = sqrt(fmax(z * (2 - z), 0));
    double num = -(2 * ct * ct - 1) * v->cv, den = 2 * st * ct * v->sv;
    if (!(den > 0)) return num < 0 ? SB_PI : 0;
    double c = num / den;
    return c <= -1 + SB_HALF_FULL_ARC ? SB_PI : (c >= 1 ? 0 : acos(c));
}

/* The valid part of the arc [a, a + w] at z as up to 3 intervals of phi
 * (the arc against the copies of [phi_v - hw, phi_v + hw] 2 pi apart);
 * returns their total length. */
static double pieces(const half_view_t *v, double z, double a, double w, double p[3][2], int *np) {
    double hw = half_width(v, z), d0 = wrap_pi(a - v->phiv), len = 0;
    *np = 0;
    for (int k = -1; k <= 2 && hw > 0; k++) {
        double lo = fmax(d0, -hw + 2 * SB_PI * k), hi = fmin(d0 + w, hw + 2 * SB_PI * k);
        if (hi <= lo || *np == 3) continue;
        p[*np][0] = v->phiv + lo;
        p[*np][1] = v->phiv + hi;
        len += hi - lo;
        (*np)++;
    }
    return len;
}

double half_phi_len(const half_view_t *v, double z, double a, double w) {
    double p[3][2];
    int np;
    return pieces(v, z, a, w, p, &np);
}

int half_phi_sample(const half_view_t *v, double z, double a, double w, double u, double *phi) {
    double p[3][2];
    int np;
    double len = pieces(v, z, a, w, p, &np), t = u * len;
    if (!(len > 0)) return 0;
    for (int i = 0; i < np; i++) {
        double l = p[i][1] - p[i][0];
        if (t < l || i == np - 1) {
            *phi = p[i][0] + fmin(t, l);
            return 1;
        }
        t -= l;
    }
    return 0;
}

/* The cut cell of a whole-circle row (iso): z is drawn over [z_lo, z_lo +
 * half_cut_dz] and phi over the arc valid at half_arc_z, both rounded
 * away from the cut by a step of the cell (an h beyond the cut fails).
 * The kept extent z_cut - z_lo of a thin cut cell is a difference of
 * nearly equal values, and the arc's half-width there an acos near 1: in
 * float (the GLSL) both rounded up to 1.2e-3 from the C's (266 of
 * 102 400 pdfs beyond 1e-4, tests/test_sampler_gl.c at 25 views); rounded
 * to 64 steps, 85 beyond, up to 2.5e-4, for 0.4 % fewer successful
 * samples (GGX 0.3, 16 cells, theta_o 20: 0.899 -> 0.895); 16 and 32
 * steps: 40 and 57 beyond, up to 1.1e-4 and 1.4e-4, for 0.846 and 0.859. */
double half_cut_dz(double zlo, double zhi, double zc) {
    double w = zhi - zlo;
    if (!(zc < zhi)) return w;
    return w * fmax(ceil(SB_HALF_CUT_STEPS * (zc - zlo) / w), 1) / SB_HALF_CUT_STEPS;
}

double half_arc_z(double zlo, double zhi, double zc) { return fmin(zlo, zc - (zhi - zlo) / SB_HALF_CUT_STEPS); }
