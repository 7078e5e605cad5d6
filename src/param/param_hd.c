/* hd: half / difference vectors in the Gram-Schmidt frame of Kautz &
 * McCool (1999).  Rows index h, columns d, both on the io theta-phi grid
 * (k = R * i_phi + i_theta, theta in [0, theta_max], phi in [0, 2pi)).
 *
 *     h  = (l + v) / |l + v|                (the normal when l = -v)
 *     t' = (T - (T.h) h) / |T - (T.h) h|,  T = (1, 0, 0)
 *        = (n, -h_x h_y / n, -h_x h_z / n),  n = sqrt(h_y^2 + h_z^2)
 *     b' = h x t'
 *     d  = (l.t', l.b', l.h)
 * |T - (T.h) h|^2 = 1 - h_x^2 = h_y^2 + h_z^2, written so to stay exact when
 * h is near T.  The frame is undefined only when h = +-T exactly (n = 0),
 * i.e. h on the horizon, which no BRDF pair reaches (h_z > 0 when l_z, v_z
 * > 0); there t' falls back to the bitangent B = (0, 1, 0) (= B - (B.h) h
 * since B.h = 0), so coords stay finite.
 *
 * The theta axes of h and d take warps (param.h: SB_AXIS_THETA_H,
 * SB_AXIS_THETA_D; uniform by default): st.x = W(theta / theta_max).
 *
 * Inverse: l = d_x t' + d_y b' + d_z h, v = 2 (h.l) h - l = 2 d_z h - l.
 * h and d stay in the cap theta <= theta_max when l and v do (h is the
 * midpoint of the arc from l to v and theta_d half its length), so both
 * grids span [0, theta_max]; cells whose l or v leave the cap (below the
 * horizon by default: most of the square) are not BRDF pairs.
 *
 * Measure: (l, v) -> (h, l) has Jacobian dw_v = 4 (l.h) dw_h (reflection
 * of l about h), and for fixed h, l -> d is a rotation, so
 *     dw_l dw_v = 4 cos(theta_d) dw_h dw_d,
 * which factors: row = solid angle of the h cell, column = integral of
 * 4 cos(theta_d) over the d cell.  Over all cells the sum is 2pi * 4pi =
 * 8pi^2 (every pair with h above the horizon); over valid cells it
 * approaches (2pi)^2. */
#include <math.h>
#include <stdio.h>

#include "param/param_impl.h"

/* Gram-Schmidt frame (t', b') around unit h. */
static void hd_frame(const double h[3], double t[3], double b[3]) {
    double n = hypot(h[1], h[2]);
    if (n > 0) {
        t[0] = n;
        t[1] = -h[0] * h[1] / n;
        t[2] = -h[0] * h[2] / n;
    } else { /* h = +-T: bitangent fallback */
        t[0] = 0;
        t[1] = 1;
        t[2] = 0;
    }
    b[0] = h[1] * t[2] - h[2] * t[1];
    b[1] = h[2] * t[0] - h[0] * t[2];
    b[2] = h[0] * t[1] - h[1] * t[0];
}

/* theta-phi texture coordinate with accurate theta (warped by wp) and
 * phi = 0 at the pole. */
static void hd_st(double tmax, const sb_warp_t *wp, const double w[3], double st[2]) {
    double ph = (w[0] != 0 || w[1] != 0) ? atan2(w[1], w[0]) : 0;
    if (ph < 0) ph += 2 * SB_PI;
    if (ph >= 2 * SB_PI) ph -= 2 * SB_PI;
    st[0] = sb_warp_map(wp, sb_dir_theta(w) / tmax);
    st[1] = ph / (2 * SB_PI);
}

static int hd_cell_dirs(const sb_param_t *p, size_t row, size_t col, double wi[3], double wo[3]) {
    double h[3], d[3], t[3], b[3];
    sb_grid_dir(p->opts.res, p->opts.theta_max, &p->opts.warp[SB_AXIS_THETA_H], row, h);
    sb_grid_dir(p->opts.res, p->opts.theta_max, &p->opts.warp[SB_AXIS_THETA_D], col, d);
    hd_frame(h, t, b);
    for (int i = 0; i < 3; i++) {
        wi[i] = d[0] * t[i] + d[1] * b[i] + d[2] * h[i];
        wo[i] = 2 * d[2] * h[i] - wi[i];
    }
    return sb_dir_in_cap(p->opts.theta_max, wi) && sb_dir_in_cap(p->opts.theta_max, wo);
}

static double hd_row_measure(const sb_param_t *p, size_t row) {
    return sb_grid_measure(p->opts.res, p->opts.theta_max, &p->opts.warp[SB_AXIS_THETA_H], row);
}
static double hd_col_measure(const sb_param_t *p, size_t col) {
    return sb_grid_measure_4cos(p->opts.res, p->opts.theta_max, &p->opts.warp[SB_AXIS_THETA_D], col);
}

static int hd_coords(const sb_param_t *p, const double wi[3], const double wo[3], double st_g[2], double st_h[2]) {
    double h[3], t[3], b[3];
    sb_dir_half(wi, wo, h);
    hd_frame(h, t, b);
    double d[3] = {wi[0] * t[0] + wi[1] * t[1] + wi[2] * t[2], wi[0] * b[0] + wi[1] * b[1] + wi[2] * b[2],
                   wi[0] * h[0] + wi[1] * h[1] + wi[2] * h[2]};
    hd_st(p->opts.theta_max, &p->opts.warp[SB_AXIS_THETA_H], h, st_g);
    hd_st(p->opts.theta_max, &p->opts.warp[SB_AXIS_THETA_D], d, st_h);
    return sb_dir_in_cap(p->opts.theta_max, wi) && sb_dir_in_cap(p->opts.theta_max, wo);
}

static const sb_param_vt_t hd_vt = {
    hd_cell_dirs,
    hd_row_measure,
    hd_col_measure,
    hd_coords,
    "// hd: h = normalize(L + V), Gram-Schmidt frame t' from T = (1,0,0) (bitangent\n"
    "// when h = +-T), d = L in (t', b', h); theta-phi st of h (g) and d (h):\n"
    "// s = sb_warp_h/d(theta / SB_THETA_MAX) (clamp), t = phi / 2pi (repeat).\n"
    "vec2 sb_hd_st(vec3 w) {\n"
    "    float theta = sb_atan2(length(w.xy), w.z);\n"
    "    float phi = (w.x != 0.0 || w.y != 0.0) ? sb_atan2(w.y, w.x) : 0.0;\n"
    "    if (phi < 0.0) phi += 2.0 * SB_PI;\n"
    "    return vec2(theta / SB_THETA_MAX, phi / (2.0 * SB_PI));\n"
    "}\n"
    "vec4 sb_coords(vec3 L, vec3 V) {\n"
    "    vec3 s = L + V;\n"
    "    float len = length(s);\n"
    "    vec3 H = len > 0.0 ? s / len : vec3(0.0, 0.0, 1.0);\n"
    "    float n = length(H.yz);\n"
    "    vec3 T = n > 0.0 ? vec3(n, -H.x * H.y / n, -H.x * H.z / n) : vec3(0.0, 1.0, 0.0);\n"
    "    vec3 D = vec3(dot(L, T), dot(L, cross(H, T)), dot(L, H));\n"
    "    vec2 h = sb_hd_st(H), d = sb_hd_st(D);\n"
    "    return vec4(sb_warp_h(h.x), h.y, sb_warp_d(d.x), d.y);\n"
    "}\n"
    "bool sb_in_cap(vec3 w) { return w.z > 0.0 && atan(length(w.xy), w.z) <= SB_THETA_MAX; }\n"
    "bool sb_domain(vec3 L, vec3 V, vec4 st) { return sb_in_cap(L) && sb_in_cap(V); }\n",
    NULL,
    NULL};

/* sb_grid_sample_glsl with the theta_h warp: the band's bounds through
 * its inverse, as sb_grid_row_sample takes them. */
static const char hd_sample_glsl[] =
    "// half-vector cell (x = theta_h through sb_warp_h, y = phi_h): 1 - cos(theta) and phi linear in u\n"
    "vec3 sb_row_dir(ivec2 cell, vec2 u) {\n"
    "    vec2 n = vec2(textureSize(sb_g, 0).xy);\n"
    "    float tlo = sb_warp_h_inv(float(cell.x) / n.x) * SB_THETA_MAX;\n"
    "    float thi = sb_warp_h_inv(float(cell.x + 1) / n.x) * SB_THETA_MAX;\n"
    "    float slo = sin(0.5 * tlo), shi = sin(0.5 * thi);\n"
    "    float z = 2.0 * (slo * slo + u.x * (shi * shi - slo * slo));\n"
    "    float s = sqrt(max(z * (2.0 - z), 0.0)), phi = (float(cell.y) + u.y) * 2.0 * SB_PI / n.y;\n"
    "    return vec3(s * cos(phi), s * sin(phi), 1.0 - z);\n"
    "}\n"
    "// the cell of h by tan^2 theta and cot phi of L + V against the edges (src/param/row_cell.c)\n"
    "#define SB_ROW_CELL 1\n"
    "ivec2 sb_row_cell(vec3 L, vec3 V) {\n"
    "    ivec2 n = textureSize(sb_g, 0).xy;\n"
    "    vec3 s = L + V;\n"
    "    return ivec2(sb_cell_tan2(s, n.x), sb_cell_phi(s.xy, n.y));\n"
    "}\n";

const sb_param_desc_t sb_param_desc_hd = {
    .name = "hd",
    .description = "half and difference vectors in the Gram-Schmidt frame of Kautz and McCool",
    .keys = "res",
    .caps = SB_CAP_PARTIAL_DOMAIN | SB_CAP_HALF_ROWS | SB_CAP_WARPS,
    .warp = {SB_WARP_UNIFORM, SB_WARP_UNIFORM},
    .wrap_y = SB_WRAP_REPEAT,
    .vt = &hd_vt,
    .row_sample = sb_grid_row_sample,
    .sample_glsl = hd_sample_glsl,
    .row_edge = sb_theta_phi_row_edge,
    .row_cell = sb_half_row_cell};
