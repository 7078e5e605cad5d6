/* iso: Rusinkiewicz half/difference angles for isotropic, reciprocal BRDFs.
 * Rows theta_h (th cells, texture th x 1), columns (theta_d, phi_d) (texture
 * td x pd, column c = td * i_phi_d + i_theta_d, theta_d fastest).
 *
 * Forward (coords):
 *     h = (l + v) / |l + v|            (the normal when l = -v)
 *     theta_h = atan2(|h_xy|, h_z),  (cos, sin) phi_h = h_xy / |h_xy|
 *                                      ((1, 0), phi_h = 0, when |h_xy| = 0)
 *     d = Ry(-theta_h) Rz(-phi_h) l:
 *         x1 = l_x cos phi_h + l_y sin phi_h,  y1 = -l_x sin phi_h + l_y cos phi_h
 *         d  = (x1 cos theta_h - l_z sin theta_h, y1, x1 sin theta_h + l_z cos theta_h)
 *     theta_d = atan2(|d_xy|, d_z), phi_d = atan2(d_y, d_x) (0 when d_xy = 0),
 *     folded modulo pi into [0, pi).
 * Swapping l and v keeps h and maps d to (-d_x, -d_y, d_z), i.e. phi_d to
 * phi_d + pi, so reciprocity makes f pi-periodic in phi_d and the fold is
 * lossless; the folded axis is a circle of length pi and REPEAT is the wrap
 * that filters across phi_d = 0 ~ pi correctly (CLAMP would be right only
 * with the extra mirror symmetry phi_d -> -phi_d).  theta axes CLAMP.
 * st_g = (W_h(theta_h / theta_max), 1/2), st_h = (W_d(theta_d / theta_max), phi_d / pi)
 * with the axes' warps (param.h).  Beyond the last theta_d texel centre
 * the lookup follows the line through the last two (SB_EDGE_LINEAR).
 *
 * Cells: by default theta_h follows MERL's square-root spacing, W_h(x) =
 * sqrt(x), theta_h = u^2 theta_max at uniform u = (i + 1/2) / th, which puts
 * rows where specular peaks are narrow (GGX alpha = 0.3 at R = 32:
 * comparable error at J = 4 drops from 1.25 % with uniform rows to under
 * 1 %), and theta_d is uniform; in general theta = W^-1((i + 1/2) / n)
 * theta_max.  phi_d centres are uniform, phi_d = (j + 1/2) pi / pd.
 * Inverse (cell_dirs): h = (sin theta_h, 0, cos theta_h) (phi_h = 0),
 * l = Rz(phi_h) Ry(theta_h) d, v = 2 d_z h - l; the cell is a BRDF pair iff
 * l and v are in the cap theta <= theta_max.  theta_h, theta_d <= theta_max
 * for every such pair, so the grids span [0, theta_max].
 *
 * Measure, so that sum m_r m_c f approximates the integral over (l, v):
 * dw_l dw_v = 4 cos(theta_d) dw_h dw_d (see param_hd.c); phi_h is integrated
 * out (row = 2pi (cos lo - cos hi)) and each folded column stands for two
 * (phi_d, phi_d + pi) cells (column = 2 * 4 dphi_d int cos sin dtheta_d
 * = 4 dphi_d (sin^2 hi - sin^2 lo)). */
#include <math.h>

#include "param/param_impl.h"

#define ISO_MAX_CELLS 8192

static size_t iso_th(const sb_param_t *p) { return p->opts.res_theta_h; }
static size_t iso_td(const sb_param_t *p) { return p->opts.res_theta_d; }
static size_t iso_pd(const sb_param_t *p) { return p->opts.res_phi_d; }

static int iso_cell_dirs(const sb_param_t *p, size_t row, size_t col, double wi[3], double wo[3]) {
    double tmax = p->opts.theta_max;
    double th = sb_warp_theta(&p->opts.warp[SB_AXIS_THETA_H], (double)row + 0.5, iso_th(p), tmax);
    double td = sb_warp_theta(&p->opts.warp[SB_AXIS_THETA_D], (double)(col % iso_td(p)) + 0.5, iso_td(p), tmax);
    double pd = ((double)(col / iso_td(p)) + 0.5) * SB_PI / (double)iso_pd(p);
    sb_dirs_from_halfdiff(th, 0, td, pd, wi, wo);
    return sb_dir_in_cap(tmax, wi) && sb_dir_in_cap(tmax, wo);
}

static double iso_row_measure(const sb_param_t *p, size_t row) {
    const sb_warp_t *w = &p->opts.warp[SB_AXIS_THETA_H];
    double tmax = p->opts.theta_max;
    return 2 * SB_PI *
           (cos(sb_warp_theta(w, (double)row, iso_th(p), tmax)) -
            cos(sb_warp_theta(w, (double)row + 1, iso_th(p), tmax)));
}

/* Uniform in solid angle over the theta_h band of `row` (bounds through
 * the theta_h warp: theta_max (i / th)^2 with merl), phi_h uniform in
 * [0, 2pi). */
static void iso_row_sample(const sb_param_t *p, size_t row, const double u[2], double w[3]) {
    const sb_warp_t *wh = &p->opts.warp[SB_AXIS_THETA_H];
    double tmax = p->opts.theta_max;
    double slo = sin(0.5 * sb_warp_theta(wh, (double)row, iso_th(p), tmax));
    double shi = sin(0.5 * sb_warp_theta(wh, (double)row + 1, iso_th(p), tmax));
    double z = 2 * (slo * slo + u[0] * (shi * shi - slo * slo)), s = sqrt(fmax(z * (2 - z), 0)), phi = 2 * SB_PI * u[1];
    w[0] = s * cos(phi);
    w[1] = s * sin(phi);
    w[2] = 1 - z;
}

static double iso_col_measure(const sb_param_t *p, size_t col) {
    const sb_warp_t *w = &p->opts.warp[SB_AXIS_THETA_D];
    double it = (double)(col % iso_td(p)), tmax = p->opts.theta_max;
    double lo = sin(sb_warp_theta(w, it, iso_td(p), tmax)), hi = sin(sb_warp_theta(w, it + 1, iso_td(p), tmax));
    return 4 * (SB_PI / (double)iso_pd(p)) * (hi * hi - lo * lo);
}

static int iso_coords(const sb_param_t *p, const double wi[3], const double wo[3], double st_g[2], double st_h[2]) {
    double h[3];
    sb_dir_half(wi, wo, h);
    double hxy = hypot(h[0], h[1]), c = 1, s = 0;
    if (hxy > 0) {
        c = h[0] / hxy;
        s = h[1] / hxy;
    }
    double x1 = wi[0] * c + wi[1] * s, y1 = -wi[0] * s + wi[1] * c;
    double d[3] = {x1 * h[2] - wi[2] * hxy, y1, x1 * hxy + wi[2] * h[2]};
    double pd = (d[0] != 0 || d[1] != 0) ? atan2(d[1], d[0]) : 0;
    if (pd < 0) pd += SB_PI;
    if (pd >= SB_PI) pd -= SB_PI;
    st_g[0] = sb_warp_map(&p->opts.warp[SB_AXIS_THETA_H], atan2(hxy, h[2]) / p->opts.theta_max);
    st_g[1] = 0.5;
    st_h[0] = sb_warp_map(&p->opts.warp[SB_AXIS_THETA_D], sb_dir_theta(d) / p->opts.theta_max);
    st_h[1] = pd / SB_PI;
    return sb_dir_in_cap(p->opts.theta_max, wi) && sb_dir_in_cap(p->opts.theta_max, wo);
}

static const sb_param_vt_t iso_vt = {
    iso_cell_dirs,
    iso_row_measure,
    iso_col_measure,
    iso_coords,
    "// iso: Rusinkiewicz angles; g: s = sb_warp_h(theta_h / SB_THETA_MAX) (t = 1/2),\n"
    "// h: s = sb_warp_d(theta_d / SB_THETA_MAX) (linear beyond the last texel centre,\n"
    "// SB_EDGE_H_S), t = phi_d / pi, phi_d folded\n"
    "// into [0, pi) by reciprocity (repeat).\n"
    "vec4 sb_coords(vec3 L, vec3 V) {\n"
    "    vec3 s = L + V;\n"
    "    float len = length(s);\n"
    "    vec3 H = len > 0.0 ? s / len : vec3(0.0, 0.0, 1.0);\n"
    "    float hxy = length(H.xy);\n"
    "    vec2 cs = hxy > 0.0 ? H.xy / hxy : vec2(1.0, 0.0);\n"
    "    float x1 = L.x * cs.x + L.y * cs.y;\n"
    "    float y1 = -L.x * cs.y + L.y * cs.x;\n"
    "    vec3 D = vec3(x1 * H.z - L.z * hxy, y1, x1 * hxy + L.z * H.z);\n"
    "    float phi_d = (D.x != 0.0 || D.y != 0.0) ? sb_atan2(D.y, D.x) : 0.0;\n"
    "    if (phi_d < 0.0) phi_d += SB_PI;\n"
    "    if (phi_d >= SB_PI) phi_d -= SB_PI;\n"
    "    return vec4(sb_warp_h(sb_atan2(hxy, H.z) / SB_THETA_MAX), 0.5,\n"
    "                sb_warp_d(sb_atan2(length(D.xy), D.z) / SB_THETA_MAX), phi_d / SB_PI);\n"
    "}\n"
    "bool sb_in_cap(vec3 w) { return w.z > 0.0 && atan(length(w.xy), w.z) <= SB_THETA_MAX; }\n"
    "bool sb_domain(vec3 L, vec3 V, vec4 st) { return sb_in_cap(L) && sb_in_cap(V); }\n",
    NULL,
    NULL};

static const char iso_sample_glsl[] =
    "// iso: theta_h band x (bounds through sb_warp_h), phi_h = 2pi u.y\n"
    "vec3 sb_row_dir(ivec2 cell, vec2 u) {\n"
    "    float n = float(textureSize(sb_g, 0).x);\n"
    "    float slo = sin(0.5 * sb_warp_h_inv(float(cell.x) / n) * SB_THETA_MAX);\n"
    "    float shi = sin(0.5 * sb_warp_h_inv(float(cell.x + 1) / n) * SB_THETA_MAX);\n"
    "    float z = 2.0 * (slo * slo + u.x * (shi * shi - slo * slo));\n"
    "    float s = sqrt(max(z * (2.0 - z), 0.0)), phi = 2.0 * SB_PI * u.y;\n"
    "    return vec3(s * cos(phi), s * sin(phi), 1.0 - z);\n"
    "}\n"
    "// the theta_h band of L + V by tan^2 against the edges (src/param/row_cell.c)\n"
    "#define SB_ROW_CELL 1\n"
    "ivec2 sb_row_cell(vec3 L, vec3 V) { return ivec2(sb_cell_tan2(L + V, textureSize(sb_g, 0).x), 0); }\n";

static sb_result_t init_iso(sb_context_t *ctx, sb_param_t *p) {
    sb_param_opts_t *o = &p->opts;
    /* Defaults, R^2 + R texels a term: th = 2R, td = 2R - 2, pd = R/2.
     * theta_d carries the Fresnel / shadowing variation and the domain
     * edge, phi_d varies least (GGX alpha = 0.3 at R = 32: td 32 -> 64 took
     * the comparable error at J = 4 from 1.05 % to 0.37 %; pd 16 -> 128
     * changed it by < 0.01 %), and theta_h carries the lobe: at the same
     * texel count th = 32, td = 64 -> th = 64, td = 62 takes the headline
     * at J = 4 of the default gold microfacet from 1.8e-3 to 9.6e-4, of
     * GGX roughness 0.5 from 2.6 % to 0.6 %, of GGX roughness 0.1 from
     * 1.8 % (with the adaptive warp) to 1.3 % (2-core VM, docs/guide.md). */
    if (!o->res_theta_h) o->res_theta_h = 2 * o->res;
    if (!o->res_theta_d) o->res_theta_d = o->res > 2 ? 2 * o->res - 2 : 2;
    if (!o->res_phi_d) o->res_phi_d = o->res / 2 > 2 ? o->res / 2 : 2;
    const size_t n[3] = {o->res_theta_h, o->res_theta_d, o->res_phi_d};
    static const char *const axes[3] = {"theta_h", "theta_d", "phi_d"}, *const keys[3] = {"th", "td", "pd"};
    sb_result_t r = sb_param_line_by_grid(ctx, p, &iso_vt, "iso", n, axes, keys, ISO_MAX_CELLS, SB_WRAP_REPEAT);
    /* theta_d beyond the last texel centre (89.27 deg at td = 62): the line
     * through the last two, where a clamp held f (GGX 0.3's mirror peak
     * rises 94.5 -> 110 there; docs/bands.md) */
    p->edge[SB_SIDE_H][0] = SB_EDGE_LINEAR;
    return r;
}

const sb_param_desc_t sb_param_desc_iso = {
    .name = "iso",
    .description = "Rusinkiewicz angles for isotropic sources: rows theta_h, columns (theta_d, phi_d)",
    .keys = "res,th,td,pd",
    .caps = SB_CAP_ROTATION_INVARIANT | SB_CAP_NEEDS_ISOTROPY | SB_CAP_FOLDS_RECIPROCITY | SB_CAP_PARTIAL_DOMAIN |
            SB_CAP_HALF_ROWS | SB_CAP_WARPS,
    .warp = {SB_WARP_MERL, SB_WARP_UNIFORM},
    .init = init_iso,
    .vt = &iso_vt,
    .row_sample = iso_row_sample,
    .sample_glsl = iso_sample_glsl,
    .row_edge = sb_theta_phi_row_edge,
    .row_cell = sb_half_row_cell};
