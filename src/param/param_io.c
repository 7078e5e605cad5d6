/* io: the lecture's theta-phi grid for the pair (wi, wo).  Rows index wi,
 * columns wo, both k = R * i_phi + i_theta. */
#include <math.h>
#include <stdio.h>

#include "param/param_impl.h"

static int io_cell_dirs(const sb_param_t *p, size_t row, size_t col, double wi[3], double wo[3]) {
    sb_grid_dir(p->opts.res, p->opts.theta_max, NULL, row, wi);
    sb_grid_dir(p->opts.res, p->opts.theta_max, NULL, col, wo);
    return 1;
}
static double io_measure(const sb_param_t *p, size_t k) {
    return sb_grid_measure(p->opts.res, p->opts.theta_max, NULL, k);
}
static int io_coords(const sb_param_t *p, const double wi[3], const double wo[3], double st_g[2], double st_h[2]) {
    if (wi[2] <= 0 || wo[2] <= 0) return 0;
    sb_grid_st(p->opts.theta_max, wi, st_g);
    sb_grid_st(p->opts.theta_max, wo, st_h);
    if (st_g[0] > 1 || st_h[0] > 1) return 0;
    return 1;
}

/* The shader takes theta = atan(|w_xy|, w_z) (the snippet's sb_atan2):
 * acos(w_z) in float loses up to ~1e-3 rad near the pole, 2e-3 of a
 * texel at R = 16. */
static const sb_param_vt_t io_vt = {io_cell_dirs,
                                    io_measure,
                                    io_measure,
                                    io_coords,
                                    "// io: theta-phi grid; s = theta / SB_THETA_MAX (clamp), t = phi / 2pi (repeat)\n"
                                    "vec2 sb_grid_st(vec3 w) {\n"
                                    "    float theta = sb_atan2(length(w.xy), w.z);\n"
                                    "    float phi = sb_atan2(w.y, w.x);\n"
                                    "    if (phi < 0.0) phi += 2.0 * SB_PI;\n"
                                    "    return vec2(theta / SB_THETA_MAX, phi / (2.0 * SB_PI));\n"
                                    "}\n"
                                    "vec4 sb_coords(vec3 L, vec3 V) { return vec4(sb_grid_st(L), sb_grid_st(V)); }\n"
                                    "bool sb_domain(vec3 L, vec3 V, vec4 st) {\n"
                                    "    return L.z > 0.0 && V.z > 0.0 && st.x <= 1.0 && st.z <= 1.0;\n"
                                    "}\n",
                                    NULL,
                                    NULL};

const sb_param_desc_t sb_param_desc_io = {.name = "io",
                                          .description = "the lecture's theta-phi grid for (wi, wo)",
                                          .keys = "res",
                                          .caps = SB_CAP_SEPARABLE | SB_CAP_AZIMUTH_GRID,
                                          .wrap_y = SB_WRAP_REPEAT,
                                          .vt = &io_vt,
                                          .row_sample = sb_grid_row_sample,
                                          .sample_glsl = sb_grid_sample_glsl,
                                          .row_edge = sb_theta_phi_row_edge,
                                          .row_cell = sb_grid_row_cell};
