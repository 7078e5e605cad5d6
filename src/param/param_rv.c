/* rv: the light's elevation and the view around the mirror direction, for
 * isotropic sources.  Rows theta_i (ti cells, texture ti x 1), columns
 * (theta_r, phi_r): the angle between the view and the mirror direction
 * r = (-l_x, -l_y, l_z) and its azimuth about r, folded into [0, pi]
 * (texture tr x pr, column c = tr * i_phi + i_theta_r, theta_r fastest).
 *
 * Phong's lobe is a function of r.v = cos theta_r alone, so classic Phong
 * in form cos, f cos theta_i = kd cos theta_i + ks (r.v)^n, is rank 2 here
 * (a row factor cos theta_i, a column factor (cos theta_r)^n) on every
 * pair, the grazing ones included, where the lobe meets the horizon and
 * vh needs far more than 8 terms (Phong n = 100: theta_i > 80 degrees
 * 12 % at J = 8 and 10 % at full rank on vh, docs/bands.md).
 *
 * Forward (coords), L = wi, V = wo, theta_i = theta(L):
 *     (c, s) = -L_xy / |L_xy|            ((1, 0) when L is the normal)
 *     r  = (sin theta_i c, sin theta_i s, cos theta_i)
 *     e1 = (cos theta_i c, cos theta_i s, -sin theta_i)   (d r / d theta_i)
 *     e2 = (-s, c, 0)
 *     x = V.e1, y = V.e2, z = V.r
 *     theta_r = atan2(|(x, y)|, z) in [0, pi], phi = atan2(|y|, x) in [0, pi]
 *     st_g = ((u (ti - 1) + 1/2) / ti, 1/2), u = min(theta_i / top, 1)
 *     st_h = (sqrt(theta_r / pi), phi / pi)
 * Isotropy maps phi to -phi (the mirror about the plane of incidence), so
 * the fold is lossless and both axes CLAMP.  The rows' texel centres lie
 * at u = i / (ti - 1): the first at the normal, the last at the top,
 * theta_max or, on the whole hemisphere, 89.9 degrees (at 90 f cos
 * theta_i is 0 by the shader's guard max(cos theta_i, 0.001), which the
 * division undoes; 89.9 is where sample/edge.h takes the light's edge
 * value too).  So the row factors reach grazing light by interpolation,
 * not by the clamp beyond a last centre half a cell from the edge, which
 * held cos theta_i at cos 88.6 degrees over the last 1.4 at ti = 32: a
 * third of the error at theta_i > 89 degrees for Phong's kd.
 * theta_r follows MERL's square-root spacing (the lobe is at theta_r = 0).
 * Inverse (cell_dirs): L = (-sin theta_i, 0, cos theta_i), V = cos
 * theta_r r + sin theta_r (cos phi e1 + sin phi e2); a BRDF pair iff L, V
 * are in the cap.
 *
 * Measures: at a fixed L the map V -> (theta_r, phi) is a rotation, so
 * dw_l dw_v = dw_l dw_r exactly: rows the solid angle of their theta_i
 * band (2 pi (cos lo - cos hi), the bands meeting halfway between the
 * centres), columns the solid angle of their (theta_r, phi) cell, doubled
 * for the fold.
 *
 * auto screens it for analytic sources that are not reciprocal
 * (SB_CAP_AUTO_NONRECIPROCAL, SB_CAP_AUTO_ANALYTIC): on the RGL files it
 * was kept only at J = 1 (RGL paper: 13 % against vndf's 33 %, but
 * theta_i > 80 degrees 60 %, above its bound of 39 %, which vndf keeps).
 *
 * V leaves the domain at its horizon (the rows are lights, all in the
 * cap), where f cos theta_i need not fall to 0 (Phong's lobe and kd
 * cos theta_i do not), so on the whole hemisphere an analytic source's
 * cells past it continue by its value with V lifted to 89.9 degrees
 * (SB_CAP_VIEW_EDGE, sample/edge.h) and the fit is a plain weighted SVD.
 * The masked fit, the other way, left the columns that only a few grazing
 * rows see underdetermined: Phong n = 100 at R = 32, J = 4 1.1 % (theta_o
 * > 89 degrees 7 %) against 0.10 % (0.36 %) continued.
 *
 * Sampling (SB_CAP_COL_SAMPLE | SB_CAP_COL_FOLD, sampler.h): the column
 * sampler reads g at the pair (mirror(V), V), rv's row theta_i = theta_V,
 * and draws s over the h texture's whole square; L lies about the view's
 * mirror direction r_V at (theta_r, phi) = (pi s.x^2, pi (1 - s.y)) in the
 * frame of V as the light (rv_col_sample), s.y in [0, 2] for the fold:
 *     |ds/dwi| = 1 / (2 (fold) 2 pi^2 s.x sin theta_r),
 * nodes weighted by s.x sin theta_r cos^8(theta_r / 2) (rv_col_weight).
 * Draws past the horizon fail (gold, share 0.15: 0.3 % at theta_o 10,
 * 11 % at 70).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "param/param_impl.h"

#define RV_MAX_CELLS 8192
/* theta_i of the last row on the whole hemisphere: 89.9 degrees */
#define RV_EDGE_COS 1.745328365898309e-3

static size_t rv_ti(const sb_param_t *p) { return p->opts.res_theta_v; }
static size_t rv_tr(const sb_param_t *p) { return p->opts.res_theta_h; }
static size_t rv_pr(const sb_param_t *p) { return p->opts.res_phi_d; }

/* The rows' last centre: theta_max, or 89.9 degrees on the whole hemisphere. */
static double rv_top(const sb_param_t *p) { return fmin(p->opts.theta_max, acos(RV_EDGE_COS)); }
/* theta_i of row centre x (u = x / (ti - 1) of rv_top) */
static double rv_theta_i(const sb_param_t *p, double x) { return x / (double)(rv_ti(p) - 1) * rv_top(p); }
/* theta_r at column position x (edges at integers) */
static double rv_theta_r(const sb_param_t *p, double x) {
    double u = x / (double)rv_tr(p);
    return u * u * SB_PI;
}

/* The frame of the mirror direction of a light at elevation ti, azimuth
 * (c, s) of r: r, e1, e2 (the comment above). */
static void rv_frame(double ti, double c, double s, double r[3], double e1[3], double e2[3]) {
    double ct = cos(ti), st = sin(ti);
    r[0] = st * c, r[1] = st * s, r[2] = ct;
    e1[0] = ct * c, e1[1] = ct * s, e1[2] = -st;
    e2[0] = -s, e2[1] = c, e2[2] = 0;
}

static int rv_cell_dirs(const sb_param_t *p, size_t row, size_t col, double wi[3], double wo[3]) {
    double ti = rv_theta_i(p, (double)row);
    double tr = rv_theta_r(p, (double)(col % rv_tr(p)) + 0.5);
    double ph = ((double)(col / rv_tr(p)) + 0.5) * SB_PI / (double)rv_pr(p), r[3], e1[3], e2[3];
    rv_frame(ti, 1, 0, r, e1, e2);
    wi[0] = -r[0], wi[1] = -r[1], wi[2] = r[2];
    for (int k = 0; k < 3; k++)
        wo[k] = cos(tr) * r[k] + sin(tr) * (cos(ph) * e1[k] + sin(ph) * e2[k]);
    return sb_dir_in_cap(p->opts.theta_max, wi) && sb_dir_in_cap(p->opts.theta_max, wo);
}

/* Row bands meet halfway between the centres; the first starts at the
 * normal, the last ends at theta_max. */
static double rv_row_measure(const sb_param_t *p, size_t row) {
    double x = (double)row, lo = row == 0 ? 0 : rv_theta_i(p, x - 0.5);
    double hi = row + 1 == rv_ti(p) ? p->opts.theta_max : rv_theta_i(p, x + 0.5);
    return 2 * SB_PI * (cos(lo) - cos(hi));
}

static double rv_col_measure(const sb_param_t *p, size_t col) {
    double it = (double)(col % rv_tr(p));
    return 2 * (SB_PI / (double)rv_pr(p)) * (cos(rv_theta_r(p, it)) - cos(rv_theta_r(p, it + 1)));
}

static int rv_coords(const sb_param_t *p, const double wi[3], const double wo[3], double st_g[2], double st_h[2]) {
    double lxy = hypot(wi[0], wi[1]), c = 1, s = 0, r[3], e1[3], e2[3];
    if (lxy > 0) {
        c = -wi[0] / lxy;
        s = -wi[1] / lxy;
    }
    double ti = sb_dir_theta(wi);
    rv_frame(ti, c, s, r, e1, e2);
    double x = wo[0] * e1[0] + wo[1] * e1[1] + wo[2] * e1[2], y = wo[0] * e2[0] + wo[1] * e2[1];
    double z = wo[0] * r[0] + wo[1] * r[1] + wo[2] * r[2];
    double tr = atan2(hypot(x, y), z), phi = (x != 0 || y != 0) ? atan2(fabs(y), x) : 0;
    double u = fmin(ti / rv_top(p), 1), n = (double)rv_ti(p);
    st_g[0] = (u * (n - 1) + 0.5) / n;
    st_g[1] = 0.5;
    st_h[0] = sqrt(tr / SB_PI);
    st_h[1] = phi / SB_PI;
    return sb_dir_in_cap(p->opts.theta_max, wi) && sb_dir_in_cap(p->opts.theta_max, wo);
}

static const char rv_glsl[] =
    "// rv: the light's elevation and the view around the mirror direction r;\n"
    "// g: s = (u (SB_RV_ROWS - 1) + 1/2) / SB_RV_ROWS, u = theta_i / SB_RV_TOP\n"
    "// (t = 1/2), h: s = sqrt(theta_r / pi), t = phi / pi, theta_r the angle\n"
    "// between V and r, phi its azimuth about r folded into [0, pi].\n"
    "vec4 sb_coords(vec3 L, vec3 V) {\n"
    "    float lxy = length(L.xy);\n"
    "    vec2 cs = lxy > 0.0 ? -L.xy / lxy : vec2(1.0, 0.0);\n"
    "    float ti = atan(lxy, L.z);\n"
    "    float ct = cos(ti);\n"
    "    float st = sin(ti);\n"
    "    vec3 R = vec3(st * cs.x, st * cs.y, ct);\n"
    "    vec3 e1 = vec3(ct * cs.x, ct * cs.y, -st);\n"
    "    float x = dot(V, e1);\n"
    "    float y = V.y * cs.x - V.x * cs.y;\n"
    "    float tr = atan(length(vec2(x, y)), dot(V, R));\n"
    "    float phi = (x != 0.0 || y != 0.0) ? atan(abs(y), x) : 0.0;\n"
    "    float u = min(ti / SB_RV_TOP, 1.0);\n"
    "    return vec4((u * (SB_RV_ROWS - 1.0) + 0.5) / SB_RV_ROWS, 0.5, sqrt(tr / SB_PI), phi / SB_PI);\n"
    "}\n"
    "bool sb_in_cap(vec3 w) { return w.z > 0.0 && atan(length(w.xy), w.z) <= SB_THETA_MAX; }\n"
    "bool sb_domain(vec3 L, vec3 V, vec4 st) { return sb_in_cap(L) && sb_in_cap(V); }\n"
    "// the sampler's weight of the h texture's node at s (rv_col_weight): s.x sin theta_r cos^8(theta_r / 2)\n"
    "#define SB_COL_WEIGHT 1\n"
    "float sb_col_weight(vec2 s) {\n"
    "    float x = clamp(s.x, 0.0, 1.0);\n"
    "    float tr = SB_PI * x * x;\n"
    "    float c = cos(0.5 * tr);\n"
    "    float c4 = c * c * c * c;\n"
    "    return max(x * sin(tr) * c4 * c4, 0.0);\n"
    "}\n";

/* The GLSL of rv_col_sample and rv_col_density (the sampler block,
 * data/sepbrdf_sample.glsl, calls them). */
static const char rv_sample_glsl[] =
    "// rv: s = (sqrt(theta_r / pi), 1 - phi / pi), (theta_r, phi) of L about V's mirror direction in the frame\n"
    "// of V as the light; s.y in [0, 2] (SB_COL_FOLD: above 1 the mirror half of phi)\n"
    "bool sb_col_dir(vec3 V, vec2 s, out vec3 L) {\n"
    "    L = vec3(0.0);\n"
    "    if (!sb_in_cap(V)) return false;\n"
    "    float vxy = length(V.xy);\n"
    "    vec2 cs = vxy > 0.0 ? -V.xy / vxy : vec2(1.0, 0.0);\n"
    "    float ti = atan(vxy, V.z);\n"
    "    float ct = cos(ti);\n"
    "    float st = sin(ti);\n"
    "    vec3 R = vec3(st * cs.x, st * cs.y, ct);\n"
    "    vec3 e1 = vec3(ct * cs.x, ct * cs.y, -st);\n"
    "    vec3 e2 = vec3(-cs.y, cs.x, 0.0);\n"
    "    float x = clamp(s.x, 0.0, 1.0);\n"
    "    float tr = SB_PI * x * x;\n"
    "    float ph = SB_PI * s.y;\n"
    "    L = cos(tr) * R + sin(tr) * (sin(ph) * e2 - cos(ph) * e1);\n"
    "    return sb_in_cap(L);\n"
    "}\n"
    "// theta_r from d = L / |L| - R / |R| with R = V's mirror, D = L - R exact near R and |R|^2 - |L|^2 =\n"
    "// -(2 R.D + D.D): relative to theta_r within float rounding also where it is 1e-5 (the lobe's peak;\n"
    "// sb_coords(V, L) was 4 % off there); theta_r / 2 and phi from atan and one Newton step (a + (y cos a -\n"
    "// x sin a) / |(x, y)|): llvmpipe's atan alone put s.x 1.2e-6 off and the pdf 2.5e-4 off where the\n"
    "// factored density falls to 0 at a node (Phong n = 100, theta_r 90-107 degrees; 2.4e-5 with the step)\n"
    "float sb_col_density(vec3 L, vec3 V, out vec2 s) {\n"
    "    s = vec2(0.5);\n"
    "    if (!(sb_in_cap(L) && sb_in_cap(V))) return 0.0;\n"
    "    vec3 R = vec3(-V.x, -V.y, V.z);\n"
    "    vec3 D = L - R;\n"
    "    float nl = length(L);\n"
    "    float nr = length(R);\n"
    "    vec3 d = (D * nr - R * ((2.0 * dot(R, D) + dot(D, D)) / (nl + nr))) / (nl * nr);\n"
    "    float dl = length(d);\n"
    "    float q = sqrt(max(4.0 - dl * dl, 0.0));\n"
    "    float a = atan(dl, q);\n"
    "    float tr = 2.0 * (a + 0.5 * (dl * cos(a) - q * sin(a)));\n"
    "    float vxy = length(V.xy);\n"
    "    vec2 cs = vxy > 0.0 ? -V.xy / vxy : vec2(1.0, 0.0);\n"
    "    float x = (dot(d.xy, cs) * V.z - d.z * vxy) / nr;\n"
    "    float y = d.y * cs.x - d.x * cs.y;\n"
    "    float ay = abs(y);\n"
    "    float ph = (x != 0.0 || y != 0.0) ? atan(ay, -x) : SB_PI;\n"
    "    ph += (ay * cos(ph) + x * sin(ph)) / max(length(vec2(x, y)), 1e-30);\n"
    "    s = vec2(sqrt(tr / SB_PI), ph / SB_PI);\n"
    "    float den = 4.0 * SB_PI * SB_PI * s.x * sin(tr);\n"
    "    return den > 0.0 ? 1.0 / den : 0.0;\n"
    "}\n";

/* The light of column position s for the view wo: about wo's mirror
 * direction r_V at (theta_r, phi) = (pi s.x^2, pi (1 - s.y)) in the frame
 * of wo as the light (s.y in [0, 2], the fold's mirror half above 1).
 * theta_r is the pair's own (r_L.V = L.r_V); pi - phi is, in the plane of
 * incidence exactly and near the mirror direction about, the azimuth of
 * V about r_L, the fitted h_k's own coordinate: the density is then about
 * f cos theta_i's, its cosine included.  phi itself (the forward map with
 * the roles swapped, f cos theta_o by reciprocity) gave variance ratios
 * against cosine sampling 2-6x lower on gold (docs/positive.md). */
static int rv_col_sample(const sb_param_t *p, const double wo[3], const double s[2], double wi[3]) {
    if (!sb_dir_in_cap(p->opts.theta_max, wo)) return 0;
    double vxy = hypot(wo[0], wo[1]), c = 1, sn = 0, r[3], e1[3], e2[3];
    if (vxy > 0) {
        c = -wo[0] / vxy;
        sn = -wo[1] / vxy;
    }
    rv_frame(sb_dir_theta(wo), c, sn, r, e1, e2);
    double x = fmin(fmax(s[0], 0), 1), tr = SB_PI * x * x, ph = SB_PI * s[1];
    for (int k = 0; k < 3; k++)
        wi[k] = cos(tr) * r[k] + sin(tr) * (sin(ph) * e2[k] - cos(ph) * e1[k]);
    return sb_dir_in_cap(p->opts.theta_max, wi);
}

/* The node weight: the solid angle of wi per unit s, 2 pi^2 s.x sin
 * theta_r less the constant, times cos^8(theta_r / 2) = ((1 + cos
 * theta_r) / 2)^4, a smooth stand-in for the light's cosine at the normal
 * view: the density over wi is about h_k's times it.  The solid angle
 * alone spread a flat h_k (a diffuse term) over the whole sphere, half of
 * it below the horizon: variance against cosine sampling 4.0-6.3 times
 * smaller on gold, against 9.6-38 now (docs/positive.md).  max(cos
 * theta_r, 0) did as well (9.5-30) but its nodes fall to 0 past 90
 * degrees: the bilinear density beside them is steep, and the GLSL's pdf
 * (llvmpipe's atan 1e-6 off) was 1e-4 to 3e-4 off the C's there. */
static double rv_col_weight(const sb_param_t *p, const double s[2]) {
    (void)p;
    double x = fmin(fmax(s[0], 0), 1), tr = SB_PI * x * x;
    double c = cos(tr / 2), c2 = c * c, c4 = c2 * c2;
    return fmax(x * sin(tr) * c4 * c4, 0);
}

/* Its density |ds/dwi| = 1 / (2 (fold) 2 pi^2 s.x sin theta_r) and the
 * pair's s: the h coordinate of (wo, wi), wo as the light, phi as pi - phi. */
static double rv_col_density(const sb_param_t *p, const double wi[3], const double wo[3], double s[2]) {
    double st_g[2];
    s[0] = s[1] = 0.5;
    if (!rv_coords(p, wo, wi, st_g, s)) return 0;
    s[1] = 1 - s[1];
    double den = 4 * SB_PI * SB_PI * s[0] * sin(SB_PI * s[0] * s[0]);
    return den > 0 ? 1 / den : 0;
}

static const sb_param_vt_t rv_vt = {rv_cell_dirs, rv_row_measure, rv_col_measure, rv_coords, rv_glsl, NULL, NULL};

static sb_result_t init_rv(sb_context_t *ctx, sb_param_t *p) {
    sb_param_opts_t *o = &p->opts;
    /* Defaults as vh's: ti = R rows, columns tr = 2R by pr = R/2 */
    if (!o->res_theta_v) o->res_theta_v = o->res;
    if (!o->res_theta_h) o->res_theta_h = 2 * o->res;
    if (!o->res_phi_d) o->res_phi_d = o->res / 2 > 2 ? o->res / 2 : 2;
    const size_t n[3] = {o->res_theta_v, o->res_theta_h, o->res_phi_d};
    static const char *const axes[3] = {"theta_i", "theta_r", "phi"}, *const keys[3] = {"ti", "tr", "pr"};
    sb_result_t r = sb_param_line_by_grid(ctx, p, &rv_vt, "rv", n, axes, keys, RV_MAX_CELLS, SB_WRAP_CLAMP);
    if (r != SB_OK) return r;
    size_t need = sizeof rv_glsl + 96; /* the rows' count and last centre, then rv_glsl (sb_param_glsl) */
    if (!(p->glsl = malloc(need))) return sb_error(ctx, SB_ERR_NOMEM, "param: out of memory");
    char top[40];
    snprintf(top, sizeof top, "%.9g", rv_top(p));
    snprintf(p->glsl, need, "#define SB_RV_ROWS %zu.0\n#define SB_RV_TOP %s%s\n%s", n[0], top,
             strpbrk(top, ".eEn") ? "" : ".0", rv_glsl);
    return SB_OK;
}

const sb_param_desc_t sb_param_desc_rv = {
    .name = "rv",
    .description = "light elevation and the view about the mirror direction (Phong's lobe), isotropic: rows "
                   "theta_i, columns (angle from the mirror direction, its azimuth)",
    .keys = "res,ti,tr,pr",
    .caps = SB_CAP_ROTATION_INVARIANT | SB_CAP_NEEDS_ISOTROPY | SB_CAP_PARTIAL_DOMAIN | SB_CAP_VIEW_EDGE |
            SB_CAP_AUTO_NONRECIPROCAL | SB_CAP_AUTO_ANALYTIC | SB_CAP_COL_SAMPLE | SB_CAP_COL_FOLD,
    .init = init_rv,
    .vt = &rv_vt,
    .warp_cells = NULL,
    .row_sample = NULL,
    .sample_glsl = rv_sample_glsl,
    .col_sample = rv_col_sample,
    .col_density = rv_col_density,
    .col_weight = rv_col_weight};
