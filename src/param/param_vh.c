/* vh: the view's elevation and the half vector in the view's azimuthal
 * frame, for isotropic sources.  Rows theta_v (tv cells, texture tv x 1),
 * columns (theta_h, phi) with phi = phi_h - phi_v folded into [0, pi]
 * (texture th x ph, column c = th * i_phi + i_theta_h, theta_h fastest).
 *
 * This is how the RGL database stores a material (Dupuy & Jakob 2018): the
 * view direction selects the table slices, and each slice holds f cos
 * theta_l over the half vector m, with phi_m measured from the view's
 * azimuth.  A material whose slices are interpolated linearly in theta_v
 * is close to rank (slices) per channel here, and a microfacet model's
 * D(h) is a column factor alone.  No reciprocity is assumed (RGL tables
 * are not reciprocal near the mirror direction); only isotropy, whose
 * mirror symmetry about the plane of the view and the normal maps phi to
 * -phi, so the fold to [0, pi] is lossless and the phi axis CLAMPs at both
 * ends (an even function has zero slope there).
 *
 * Forward (coords), L = wi, V = wo:
 *     h = (L + V) / |L + V|            (the normal when L = -V)
 *     (c, s) = V_xy / |V_xy|           ((1, 0) when V is the normal)
 *     x = h_x c + h_y s,  y = -h_x s + h_y c,  phi = atan2(|y|, x) in [0, pi]
 *     st_g = (W_d(theta_v / theta_max), 1/2)
 *     st_h = (W_h(theta_h / theta_max), phi / pi)
 * with the warps of the axes (param.h): axis SB_AXIS_THETA_H is theta_h
 * (MERL's square root by default: fine where specular peaks are narrow),
 * axis SB_AXIS_THETA_D is here the view's elevation (uniform by default).
 * Inverse (cell_dirs): V = (sin theta_v, 0, cos theta_v), h = dir(theta_h,
 * phi), L = 2 (V.h) h - V; a BRDF pair iff V.h > 0 and L, V in the cap.
 * theta_h <= theta_max for every pair (h lies between L and V).
 *
 * Measures: dw_l dw_v = 4 (V.h) dw_h dw_v.  The rows take the solid angle
 * of the theta_v band (2 pi (cos lo - cos hi)); V.h depends on both sides,
 * so the columns take it at the normal view, cos theta_h, times the solid
 * angle of the h cell, doubled for the fold (a weight, not a quadrature).
 *
 * The rows are views, all in the cap, and a cell leaves the domain only
 * where L = 2 (V.h) h - V passes below the horizon (V.h > 0 holds before
 * that), so on the whole hemisphere f cos theta_l falls to 0 at the edge
 * and continues by 0 outside (SB_CAP_LIGHT_EDGE): the job fits forms with
 * cos theta_i by a plain weighted SVD with those cells 0 instead of a
 * masked fit (RGL paper at J = 8: 1.63 % against 1.56 %, 0.3 s against
 * 20 s CPU).
 *
 * Sampling (SB_CAP_COL_SAMPLE | SB_CAP_COL_FOLD, sampler.h): the column
 * position s is the h texture's st itself, s = (W_h(theta_h /
 * theta_max), phi / pi), on the whole unit square.  The column sampler
 * puts the texels at its nodes s = x / (W - 1), not at their centres
 * (x + 1/2) / W: its proposal is the texture stretched by half a texel
 * each side, a valid density because sample and density use the same
 * map, and it matches the CLAMPed texture at every border (the node
 * there is the texel the CLAMP repeats).  Mapping s onto the centres'
 * range instead would leave the border half cells (phi near 0 and pi:
 * the plane of incidence, where the peak lies; theta_h near 0) with no
 * density at all.  The fold: the sampler gives s.y in [0, 2] (either
 * half of phi in [-pi, pi] with probability 1/2, phi = pi s.y), and
 *     |ds/dwi| = 1 / (W_h^-1'(s.x) theta_max pi sin theta_h 2 (4 V.h)).
 *
 * auto screens it for sources that are not reciprocal only
 * (SB_CAP_AUTO_NONRECIPROCAL): where iso applies it screened better on
 * every source tried (gold, GGX, the Cornell acrylic), and the default
 * run keeps its single screening level. */
#include <math.h>

#include "param/param_impl.h"

#define VH_MAX_CELLS 8192

static size_t vh_tv(const sb_param_t *p) { return p->opts.res_theta_v; }
static size_t vh_th(const sb_param_t *p) { return p->opts.res_theta_h; }
static size_t vh_ph(const sb_param_t *p) { return p->opts.res_phi_d; }

static double vh_theta_v(const sb_param_t *p, double i) {
    return sb_warp_theta(&p->opts.warp[SB_AXIS_THETA_D], i, vh_tv(p), p->opts.theta_max);
}
static double vh_theta_h(const sb_param_t *p, double i) {
    return sb_warp_theta(&p->opts.warp[SB_AXIS_THETA_H], i, vh_th(p), p->opts.theta_max);
}

static int vh_cell_dirs(const sb_param_t *p, size_t row, size_t col, double wi[3], double wo[3]) {
    double tv = vh_theta_v(p, (double)row + 0.5), th = vh_theta_h(p, (double)(col % vh_th(p)) + 0.5);
    double ph = ((double)(col / vh_th(p)) + 0.5) * SB_PI / (double)vh_ph(p), h[3];
    sb_dir_from_angles(tv, 0, wo);
    sb_dir_from_angles(th, ph, h);
    double vh = wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2];
    for (int k = 0; k < 3; k++)
        wi[k] = 2 * vh * h[k] - wo[k];
    return vh > 0 && sb_dir_in_cap(p->opts.theta_max, wi) && sb_dir_in_cap(p->opts.theta_max, wo);
}

static double vh_row_measure(const sb_param_t *p, size_t row) {
    return 2 * SB_PI * (cos(vh_theta_v(p, (double)row)) - cos(vh_theta_v(p, (double)row + 1)));
}

static double vh_col_measure(const sb_param_t *p, size_t col) {
    double it = (double)(col % vh_th(p)), lo = vh_theta_h(p, it), hi = vh_theta_h(p, it + 1);
    return 4 * cos(vh_theta_h(p, it + 0.5)) * 2 * (SB_PI / (double)vh_ph(p)) * (cos(lo) - cos(hi));
}

static int vh_coords(const sb_param_t *p, const double wi[3], const double wo[3], double st_g[2], double st_h[2]) {
    double h[3];
    sb_dir_half(wi, wo, h);
    double vxy = hypot(wo[0], wo[1]), c = 1, s = 0;
    if (vxy > 0) {
        c = wo[0] / vxy;
        s = wo[1] / vxy;
    }
    double x = h[0] * c + h[1] * s, y = -h[0] * s + h[1] * c;
    double phi = (x != 0 || y != 0) ? atan2(fabs(y), x) : 0;
    /* elevations clamped to the cap: pairs outside it still get coordinates in [0, 1] */
    double xv = fmin(sb_dir_theta(wo) / p->opts.theta_max, 1), xh = fmin(sb_dir_theta(h) / p->opts.theta_max, 1);
    st_g[0] = sb_warp_map(&p->opts.warp[SB_AXIS_THETA_D], xv);
    st_g[1] = 0.5;
    st_h[0] = sb_warp_map(&p->opts.warp[SB_AXIS_THETA_H], xh);
    st_h[1] = phi / SB_PI;
    return sb_dir_in_cap(p->opts.theta_max, wi) && sb_dir_in_cap(p->opts.theta_max, wo);
}

/* The slope of sb_warp_inverse at s, as the GLSL's sb_warp_h_dinv (the
 * table's segment by s). */
static double warp_dinv(const sb_warp_t *w, double s) {
    s = fmin(fmax(s, 0), 1);
    switch (w->kind) {
    case SB_WARP_MERL:
        return 2 * s;
    case SB_WARP_TABLE: {
        size_t k = (size_t)(s * (double)w->knots);
        if (k >= w->knots) k = w->knots - 1;
        return (double)w->knots * (w->x[k + 1] - w->x[k]);
    }
    default:
        return 1;
    }
}

/* The light of column position s for the view wo (s.y in [0, 2]: phi =
 * pi s.y from the view's azimuth, the fold's mirror half above 1). */
static int vh_col_sample(const sb_param_t *p, const double wo[3], const double s[2], double wi[3]) {
    if (!sb_dir_in_cap(p->opts.theta_max, wo)) return 0;
    double th = sb_warp_inverse(&p->opts.warp[SB_AXIS_THETA_H], fmin(fmax(s[0], 0), 1)) * p->opts.theta_max, h[3];
    double phi_v = (wo[0] != 0 || wo[1] != 0) ? atan2(wo[1], wo[0]) : 0;
    sb_dir_from_angles(th, SB_PI * s[1] + phi_v, h);
    double vh = wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2];
    for (int k = 0; k < 3; k++)
        wi[k] = 2 * vh * h[k] - wo[k];
    return vh > 0 && sb_dir_in_cap(p->opts.theta_max, wi);
}

/* The sampler's weight of the node at s: the solid angle of the light per
 * unit s at the normal view, 8 pi theta_max cos sin dtheta_h/ds.x, less
 * the constant: the density over wi is then close to h_k's, where s drawn
 * by h_k alone put 1 / s.x^3 (the theta_h warp's sqrt, sin theta_h) of
 * the mass near the mirror direction (variance ratios 0.02 on GGX 0.1). */
static double vh_col_weight(const sb_param_t *p, const double s[2]) {
    double x = fmin(fmax(s[0], 0), 1), th = sb_warp_inverse(&p->opts.warp[SB_AXIS_THETA_H], x) * p->opts.theta_max;
    return fmax(cos(th) * sin(th) * warp_dinv(&p->opts.warp[SB_AXIS_THETA_H], x), 0);
}

/* Its density |ds/dwi| and the pair's s (the h texture's st, folded). */
static double vh_col_density(const sb_param_t *p, const double wi[3], const double wo[3], double s[2]) {
    double st_g[2], h[3];
    s[0] = s[1] = 0.5;
    if (!vh_coords(p, wi, wo, st_g, s)) return 0;
    sb_dir_half(wi, wo, h);
    double vh = wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2], th = sb_dir_theta(h);
    if (!(vh > 0) || th > p->opts.theta_max) return 0;
    double den = warp_dinv(&p->opts.warp[SB_AXIS_THETA_H], s[0]) * p->opts.theta_max * SB_PI * sin(th) * 8 * vh;
    return den > 0 ? 1 / den : 0;
}

/* The GLSL of vh_col_sample and vh_col_density (the sampler block,
 * data/sepbrdf_sample.glsl, calls them). */
static const char vh_sample_glsl[] =
    "// vh: s = (sb_warp_h(theta_h / SB_THETA_MAX), phi / pi), the h texture's whole st square; s.y in [0, 2]\n"
    "// (SB_COL_FOLD: above 1 the mirror half of phi)\n"
    "bool sb_col_dir(vec3 V, vec2 s, out vec3 L) {\n"
    "    L = vec3(0.0);\n"
    "    if (!sb_in_cap(V)) return false;\n"
    "    float th = sb_warp_h_inv(clamp(s.x, 0.0, 1.0)) * SB_THETA_MAX;\n"
    "    float ph = SB_PI * s.y + ((V.x != 0.0 || V.y != 0.0) ? atan(V.y, V.x) : 0.0);\n"
    "    vec3 h = vec3(sin(th) * cos(ph), sin(th) * sin(ph), cos(th));\n"
    "    float vh = dot(V, h);\n"
    "    L = 2.0 * vh * h - V;\n"
    "    return vh > 0.0 && sb_in_cap(L);\n"
    "}\n"
    "float sb_col_density(vec3 L, vec3 V, out vec2 s) {\n"
    "    s = vec2(0.5);\n"
    "    if (!(sb_in_cap(L) && sb_in_cap(V))) return 0.0;\n"
    "    s = sb_coords(L, V).zw;\n"
    "    vec3 H = normalize(L + V);\n"
    "    float th = atan(length(H.xy), H.z), vh = dot(V, H);\n"
    "    if (!(vh > 0.0) || th > SB_THETA_MAX) return 0.0;\n"
    "    float den = sb_warp_h_dinv(s.x) * SB_THETA_MAX * SB_PI * sin(th) * 8.0 * vh;\n"
    "    return den > 0.0 ? 1.0 / den : 0.0;\n"
    "}\n";

static const sb_param_vt_t vh_vt = {
    vh_cell_dirs,
    vh_row_measure,
    vh_col_measure,
    vh_coords,
    "// vh: the view's elevation and the half vector in the view's azimuthal\n"
    "// frame; g: s = sb_warp_d(theta_v / SB_THETA_MAX) (t = 1/2), h: s =\n"
    "// sb_warp_h(theta_h / SB_THETA_MAX), t = phi / pi, phi = phi_h - phi_v\n"
    "// folded into [0, pi] by isotropy (both clamp).\n"
    "vec4 sb_coords(vec3 L, vec3 V) {\n"
    "    vec3 s = L + V;\n"
    "    float len = length(s);\n"
    "    vec3 H = len > 0.0 ? s / len : vec3(0.0, 0.0, 1.0);\n"
    "    float vxy = length(V.xy);\n"
    "    vec2 cs = vxy > 0.0 ? V.xy / vxy : vec2(1.0, 0.0);\n"
    "    float x = H.x * cs.x + H.y * cs.y;\n"
    "    float y = -H.x * cs.y + H.y * cs.x;\n"
    "    float phi = (x != 0.0 || y != 0.0) ? atan(abs(y), x) : 0.0;\n"
    "    return vec4(sb_warp_d(min(atan(vxy, V.z) / SB_THETA_MAX, 1.0)), 0.5,\n"
    "                sb_warp_h(min(atan(length(H.xy), H.z) / SB_THETA_MAX, 1.0)), phi / SB_PI);\n"
    "}\n"
    "bool sb_in_cap(vec3 w) { return w.z > 0.0 && atan(length(w.xy), w.z) <= SB_THETA_MAX; }\n"
    "bool sb_domain(vec3 L, vec3 V, vec4 st) { return sb_in_cap(L) && sb_in_cap(V); }\n"
    "// the sampler's weight of the h texture's node at s (vh_col_weight): cos sin dtheta_h/ds.x\n"
    "#define SB_COL_WEIGHT 1\n"
    "float sb_col_weight(vec2 s) {\n"
    "    float th = sb_warp_h_inv(clamp(s.x, 0.0, 1.0)) * SB_THETA_MAX;\n"
    "    return max(cos(th) * sin(th) * sb_warp_h_dinv(s.x), 0.0);\n"
    "}\n",
    NULL,
    NULL};

static sb_result_t init_vh(sb_context_t *ctx, sb_param_t *p) {
    sb_param_opts_t *o = &p->opts;
    /* Defaults: tv = R rows, columns th = 2R by ph = R/2, R^2 + R texels a
     * term as iso's defaults have. */
    if (!o->res_theta_v) o->res_theta_v = o->res;
    if (!o->res_theta_h) o->res_theta_h = 2 * o->res;
    if (!o->res_phi_d) o->res_phi_d = o->res / 2 > 2 ? o->res / 2 : 2;
    const size_t n[3] = {o->res_theta_v, o->res_theta_h, o->res_phi_d};
    static const char *const axes[3] = {"theta_v", "theta_h", "phi"}, *const keys[3] = {"tv", "th", "ph"};
    return sb_param_line_by_grid(ctx, p, &vh_vt, "vh", n, axes, keys, VH_MAX_CELLS, SB_WRAP_CLAMP);
}

/* The adaptive scan describes theta_h (the h textures' x), not theta_v. */
static size_t vh_warp_cells(const sb_param_t *p, int axis) { return axis == SB_AXIS_THETA_H ? vh_th(p) : 0; }

const sb_param_desc_t sb_param_desc_vh = {
    .name = "vh",
    .description = "view elevation and half vector (RGL's own layout), isotropic: rows theta_v, columns (theta_h, "
                   "phi_h - phi_v)",
    .keys = "res,tv,th,ph",
    .caps = SB_CAP_ROTATION_INVARIANT | SB_CAP_NEEDS_ISOTROPY | SB_CAP_PARTIAL_DOMAIN | SB_CAP_WARPS |
            SB_CAP_LIGHT_EDGE | SB_CAP_AUTO_NONRECIPROCAL | SB_CAP_COL_SAMPLE | SB_CAP_COL_FOLD,
    .warp = {SB_WARP_MERL, SB_WARP_UNIFORM},
    .init = init_vh,
    .vt = &vh_vt,
    .warp_cells = vh_warp_cells,
    .row_sample = NULL,
    .sample_glsl = vh_sample_glsl,
    .col_sample = vh_col_sample,
    .col_density = vh_col_density,
    .col_weight = vh_col_weight};
