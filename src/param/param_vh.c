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
    "bool sb_domain(vec3 L, vec3 V, vec4 st) { return sb_in_cap(L) && sb_in_cap(V); }\n",
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
            SB_CAP_LIGHT_EDGE | SB_CAP_AUTO_NONRECIPROCAL,
    .warp = {SB_WARP_MERL, SB_WARP_UNIFORM},
    .init = init_vh,
    .vt = &vh_vt,
    .warp_cells = vh_warp_cells,
    .row_sample = NULL,
    .sample_glsl = ""};
