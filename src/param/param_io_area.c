/* io-area: the pair (wi, wo), each direction on an equal-area square map of
 * the cap theta <= theta_max (the hemisphere by default).  Rows index wi,
 * columns wo, both k = R * y + x over an R x R square grid.
 *
 * The map (Shirley & Chiu 1997, concentric): a square point (a, b) in
 * [-1,1]^2 goes to the disk point r (cos psi, sin psi) with
 *     |a| > |b|:  r = a, psi = (pi/4) b/a
 *     otherwise:  r = b, psi = pi/2 - (pi/4) a/b        ((0,0) -> centre)
 * which scales every area by pi/4.  The disk goes to the cap by
 * 1 - cos(theta) = rho^2 c with rho = |disk point|, c = 1 - cos(theta_max),
 * area-preserving up to the factor 2pi c / pi; the direction is
 *     (dx sqrt(c (2 - rho^2 c)), dy sqrt(c (2 - rho^2 c)), 1 - rho^2 c).
 * So each of the R^2 square cells has solid angle 2pi c / R^2, its
 * direction is the image of its centre, and s = (a + 1)/2, t = (b + 1)/2.
 *
 * The inverse takes rho^2 = (x^2 + y^2) / ((1 + z) c), which stays accurate
 * near the pole where 1 - z cancels, psi' = atan2(|y|, |x|) in [0, pi/2],
 *     psi' <= pi/4:  (|a|, |b|) = (rho, rho psi' 4/pi)
 *     otherwise:     (|a|, |b|) = (rho (pi/2 - psi') 4/pi, rho)
 * and the signs of x and y.
 *
 * At the rim: the square's border is the circle theta = theta_max, its
 * corners the azimuths 45, 135, 225 and 315 degrees.  Both axes CLAMP: a
 * direction between the outermost texel centres and the rim takes the rim
 * texels' values (GL_CLAMP_TO_EDGE).  Nothing lies across the border but
 * directions beyond the rim (below the horizon), which are outside the
 * domain: coords returns 0 and the shader returns black. */
#include <math.h>
#include <stdio.h>

#include "param/param_impl.h"

static double cap_c(const sb_param_t *p) { return 1 - cos(p->opts.theta_max); }

/* Square point (a, b) in [-1,1]^2 -> direction in the cap. */
static void square_dir(const sb_param_t *p, double a, double b, double w[3]) {
    /* concentric square -> disk */
    double r, psi;
    if (a == 0 && b == 0) {
        r = psi = 0;
    } else if (fabs(a) > fabs(b)) {
        r = a;
        psi = SB_PI / 4 * (b / a);
    } else {
        r = b;
        psi = SB_PI / 2 - SB_PI / 4 * (a / b);
    }
    double dx = r * cos(psi), dy = r * sin(psi), c = cap_c(p), rho2 = r * r;
    /* disk -> cap */
    double q = sqrt(c * (2 - rho2 * c));
    w[0] = dx * q;
    w[1] = dy * q;
    w[2] = 1 - rho2 * c;
}

/* Square cell k at (x + u[0], y + u[1]) in texel units -> direction: the
 * cell's centre for u = (1/2, 1/2); uniform u is uniform in solid angle
 * (the map is equal-area). */
static void area_row_sample(const sb_param_t *p, size_t k, const double u[2], double w[3]) {
    double R = (double)p->opts.res;
    square_dir(p, 2 * ((double)(k % p->opts.res) + u[0]) / R - 1, 2 * ((double)(k / p->opts.res) + u[1]) / R - 1, w);
}

static void area_dir(const sb_param_t *p, size_t k, double w[3]) {
    area_row_sample(p, k, (const double[2]){0.5, 0.5}, w);
}

/* Direction in the cap -> st (the inverse of area_dir, continuously). */
static void area_st(double c, const double w[3], double st[2]) {
    double rho = sqrt((w[0] * w[0] + w[1] * w[1]) / ((1 + w[2]) * c));
    double ax = fabs(w[0]), ay = fabs(w[1]);
    double psi = (ax > 0 || ay > 0) ? atan2(ay, ax) : 0;
    double a, b;
    if (psi <= SB_PI / 4) {
        a = rho;
        b = rho * psi * (4 / SB_PI);
    } else {
        a = rho * (SB_PI / 2 - psi) * (4 / SB_PI);
        b = rho;
    }
    st[0] = 0.5 * (w[0] < 0 ? -a : a) + 0.5;
    st[1] = 0.5 * (w[1] < 0 ? -b : b) + 0.5;
}

static int area_cell_dirs(const sb_param_t *p, size_t row, size_t col, double wi[3], double wo[3]) {
    area_dir(p, row, wi);
    area_dir(p, col, wo);
    return 1;
}

static double area_measure(const sb_param_t *p, size_t k) {
    (void)k;
    double R = (double)p->opts.res;
    return 2 * SB_PI * cap_c(p) / (R * R);
}

static int area_coords(const sb_param_t *p, const double wi[3], const double wo[3], double st_g[2], double st_h[2]) {
    if (!sb_dir_in_cap(p->opts.theta_max, wi) || !sb_dir_in_cap(p->opts.theta_max, wo)) {
        st_g[0] = st_g[1] = st_h[0] = st_h[1] = 0.5; /* unspecified, kept finite */
        return 0;
    }
    area_st(cap_c(p), wi, st_g);
    area_st(cap_c(p), wo, st_h);
    return 1;
}

static const sb_param_vt_t area_vt = {
    area_cell_dirs,
    area_measure,
    area_measure,
    area_coords,
    "// io-area: Shirley-Chiu concentric map of the cap theta <= SB_THETA_MAX,\n"
    "// equal-area; s = (a + 1)/2, t = (b + 1)/2 for the square point (a, b), both clamp.\n"
    "vec2 sb_area_st(vec3 w) {\n"
    "    float c = 1.0 - cos(SB_THETA_MAX);\n"
    "    float rho = sqrt(dot(w.xy, w.xy) / (max(1.0 + w.z, 1e-30) * c));\n"
    "    vec2 q = abs(w.xy);\n"
    "    float psi = (q.x > 0.0 || q.y > 0.0) ? atan(q.y, q.x) : 0.0;\n"
    "    vec2 ab = psi <= 0.25 * SB_PI ? vec2(rho, rho * psi * (4.0 / SB_PI))\n"
    "                                  : vec2(rho * (0.5 * SB_PI - psi) * (4.0 / SB_PI), rho);\n"
    "    ab = vec2(w.x < 0.0 ? -ab.x : ab.x, w.y < 0.0 ? -ab.y : ab.y);\n"
    "    return 0.5 * ab + 0.5;\n"
    "}\n"
    "vec4 sb_coords(vec3 L, vec3 V) { return vec4(sb_area_st(L), sb_area_st(V)); }\n"
    "bool sb_in_cap(vec3 w) { return w.z > 0.0 && atan(length(w.xy), w.z) <= SB_THETA_MAX; }\n"
    "bool sb_domain(vec3 L, vec3 V, vec4 st) { return sb_in_cap(L) && sb_in_cap(V); }\n",
    NULL,
    NULL};

static const char area_sample_glsl[] =
    "// io-area: square cell (x, y) at (x + u.x, y + u.y) texels -> cap (equal-area)\n"
    "vec3 sb_row_dir(ivec2 cell, vec2 u) {\n"
    "    vec2 ab = 2.0 * (vec2(cell) + u) / vec2(textureSize(sb_g, 0).xy) - 1.0;\n"
    "    float r = 0.0, psi = 0.0;\n"
    "    if (abs(ab.x) > abs(ab.y)) {\n"
    "        r = ab.x;\n"
    "        psi = 0.25 * SB_PI * (ab.y / ab.x);\n"
    "    } else if (ab.y != 0.0) {\n"
    "        r = ab.y;\n"
    "        psi = 0.5 * SB_PI - 0.25 * SB_PI * (ab.x / ab.y);\n"
    "    }\n"
    "    float c = 1.0 - cos(SB_THETA_MAX), z = r * r * c, q = sqrt(max(c * (2.0 - z), 0.0));\n"
    "    return vec3(r * cos(psi) * q, r * sin(psi) * q, 1.0 - z);\n"
    "}\n";

const sb_param_desc_t sb_param_desc_io_area = {.name = "io-area",
                                               .description = "(wi, wo) on an equal-area (concentric) hemisphere map",
                                               .keys = "res",
                                               .caps = SB_CAP_SEPARABLE,
                                               .wrap_y = SB_WRAP_CLAMP,
                                               .vt = &area_vt,
                                               .row_sample = area_row_sample,
                                               .sample_glsl = area_sample_glsl};
