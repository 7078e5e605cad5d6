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
    "    bool wa = q.y <= q.x; // |a| = rho; else |b| = rho\n"
    "    float r = rho * sb_atan_q(wa ? (q.x > 0.0 ? q.y / q.x : 0.0) : q.x / q.y);\n"
    "    vec2 ab = wa ? vec2(rho, r) : vec2(r, rho);\n"
    "    ab = vec2(w.x < 0.0 ? -ab.x : ab.x, w.y < 0.0 ? -ab.y : ab.y);\n"
    "    return 0.5 * ab + 0.5;\n"
    "}\n"
    "vec4 sb_coords(vec3 L, vec3 V) { return vec4(sb_area_st(L), sb_area_st(V)); }\n"
    "bool sb_in_cap(vec3 w) { return w.z > 0.0 && atan(length(w.xy), w.z) <= SB_THETA_MAX; }\n"
    "bool sb_domain(vec3 L, vec3 V, vec4 st) { return sb_in_cap(L) && sb_in_cap(V); }\n",
    NULL,
    NULL};

/* Row cells (sb_param_row_cell, row_cell.c): square edge a_i = 2 i / R - 1
 * (the same on both axes) as edge e_i = a_i^2 c.  On the wedge |y| <= |x|,
 * |a| = rho and |b| = rho q with q = (4/pi) atan(|y| / |x|), and the other
 * way round on the other; rho^2 c = 1 - z.  So |a|^2 c is 1 - z or (1 -
 * z) q^2, compared with e_i, and the sign of a is that of x (-0 as +0).
 * q is a polynomial in float (area_q; 2.2e-7 from the exact, against
 * 1e-5 for llvmpipe's atan), the snippet's sb_atan_q step by step. */
static const float area_q_coef[8] = {1.2732393741607666f,   -0.42439383268356323f, 0.25422725081443787f,
                                     -0.17829543352127075f, 0.12565429508686066f,  -0.07490436732769012f,
                                     0.030278297141194344f, -0.005805707536637783f};

static float area_q(float t) {
    float x = sb_f32_mul(t, t), p = area_q_coef[7];
    for (int k = 6; k >= 0; k--)
        p = sb_f32_add(sb_f32_mul(p, x), area_q_coef[k]);
    return sb_f32_mul(t, p);
}

static float area_row_edge(const sb_param_t *p, int axis, size_t i) {
    (void)axis;
    double a = 2 * (double)i / (double)p->opts.res - 1;
    return (float)(a * a * cap_c(p));
}

typedef struct area_axis {
    float v, m2; /* the coordinate whose sign a has, |a|^2 c */
    size_t n;
    const float *e;
} area_axis_t;

static int area_past(const void *arg, size_t i) {
    const area_axis_t *a = arg;
    if (2 * i == a->n) return a->v >= 0;
    return 2 * i > a->n ? (a->v > 0 && a->m2 >= a->e[i]) : (a->v >= 0 || a->m2 <= a->e[i]);
}

static void area_row_cell(const sb_param_t *p, const float *const edge[2], const double wi[3], const double wo[3],
                          size_t cell[2]) {
    (void)wo;
    float x = sb_f32(wi[0]), y = sb_f32(wi[1]), m = sb_f32_add(1, -sb_f32(wi[2])), ax = fabsf(x), ay = fabsf(y);
    int wa = ay <= ax;
    float t = wa ? (ax > 0 ? sb_f32_div(ay, ax) : 0) : sb_f32_div(ax, ay), q = area_q(t);
    float mq = sb_f32_mul(m, sb_f32_mul(q, q));
    area_axis_t a = {x, wa ? m : mq, p->opts.res, edge[0]}, b = {y, wa ? mq : m, p->opts.res, edge[1]};
    cell[0] = sb_cell_search(p->opts.res, area_past, &a);
    cell[1] = sb_cell_search(p->opts.res, area_past, &b);
}

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
    "}\n"
    "// the cell of L: its ring 1 - z and wedge ratio q (sb_atan_q) against the edges a_i^2 c\n"
    "bool sb_area_past(float v, float m2, int i, int n, float e) {\n"
    "    if (2 * i == n) return v >= 0.0;\n"
    "    return 2 * i > n ? (v > 0.0 && m2 >= e) : (v >= 0.0 || m2 <= e);\n"
    "}\n"
    "int sb_area_axis(float v, float m2, int n, int axis) {\n"
    "    int lo = 0, hi = n - 1;\n"
    "    while (lo < hi) {\n"
    "        int mid = (lo + hi + 1) / 2;\n"
    "        if (sb_area_past(v, m2, mid, n, axis == 0 ? sb_edge_x(mid) : sb_edge_y(mid)))\n"
    "            lo = mid;\n"
    "        else\n"
    "            hi = mid - 1;\n"
    "    }\n"
    "    return lo;\n"
    "}\n"
    "#define SB_ROW_CELL 1\n"
    "ivec2 sb_row_cell(vec3 L, vec3 V) {\n"
    "    int n = textureSize(sb_g, 0).x;\n"
    "    float m = 1.0 - L.z;\n"
    "    vec2 a = abs(L.xy);\n"
    "    bool wa = a.y <= a.x;\n"
    "    float t = wa ? (a.x > 0.0 ? a.y / a.x : 0.0) : a.x / a.y, q = sb_atan_q(t), mq = m * (q * q);\n"
    "    return ivec2(sb_area_axis(L.x, wa ? m : mq, n, 0), sb_area_axis(L.y, wa ? mq : m, n, 1));\n"
    "}\n";

const sb_param_desc_t sb_param_desc_io_area = {.name = "io-area",
                                               .description = "(wi, wo) on an equal-area (concentric) hemisphere map",
                                               .keys = "res",
                                               .caps = SB_CAP_SEPARABLE,
                                               .wrap_y = SB_WRAP_CLAMP,
                                               .vt = &area_vt,
                                               .row_sample = area_row_sample,
                                               .sample_glsl = area_sample_glsl,
                                               .row_edge = area_row_edge,
                                               .row_cell = area_row_cell};
