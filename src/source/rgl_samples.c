/* The measured samples of an RGL table: the stored colour values at the
 * nodes of each (phi_i, theta_i) slice, each placed at the pair of
 * directions where the reader's own evaluation (rgl.c) reads that node.
 *
 * Node (x, y) of slice q = p n_theta + t sits at s = (x/(S_x - 1),
 * y/(S_y - 1)) in the VNDF-warped sample space of the view
 * v = (theta_i[t], phi_i[p]).  The warp takes s to u_m, the point that
 * sb_table_warp_invert maps back to s (found by bisection: the inverse is
 * monotone in u_y alone for the y part, then in u_x on that row).  u_m
 * gives the microfacet normal m: theta_m = u_x^2 pi/2, phi_m = 2 pi u_y -
 * pi, plus the view's azimuth for isotropic tables; the light is v
 * reflected about m, l = 2 (v.m) m - v.  The stored value is f_r
 * cos(theta_l) before the jacobian factor, so the sample holds
 * f_r = max(0, value x NDF(u_m) / (4 sigma(u_v))) / l_z, what the
 * evaluation returns at (l, v).  A node whose light falls at or below the
 * horizon (x = S_x - 1 among them: m on the horizon) is no sample.  Where
 * nodes meet at one pair (x = 0: theta_m = 0 for every row; an anisotropic
 * table's slices of theta_i = 0, one per phi_i) each keeps its own value;
 * the evaluation reads one of them, or, off the pole by rounding only,
 * each its own when the view is along the normal. */
#include <math.h>

#include "source/measured_impl.h"
#include "source/rgl_impl.h"

size_t sb_rgl_sample_count_(const void *self) {
    const rgl_t *g = self;
    return g->rgb.slices * g->rgb.w * g->rgb.h;
}

int sb_rgl_sample_(const void *self, size_t k, double wi[3], double wo[3], double f[3]) {
    const rgl_t *g = self;
    size_t nodes = g->rgb.w * g->rgb.h, q = k / nodes, node = k % nodes;
    if (q >= g->rgb.slices) return 0;
    size_t x = node % g->rgb.w, y = node / g->rgb.w, p = q / g->n_theta, t = q % g->n_theta;
    double tv = g->theta[t], pv = g->phi[p];
    double v[3] = {sin(tv) * cos(pv), sin(tv) * sin(pv), cos(tv)};
    if (!(v[2] > SB_HORIZON_Z)) return 0;
    /* a reduced table's slices lie where the evaluation mirrors to (y <= 0,
     * and x <= 0 for 4): keep v there when it is +0 or beyond by rounding */
    if (g->reduction >= 2) v[1] = -fabs(v[1]);
    if (g->reduction == 4) v[0] = -fabs(v[0]);
    /* the view's coordinates as the evaluation computes them */
    double theta_v = sb_table_elevation(v), phi_v = atan2(v[1], v[0]);
    double u_v[2] = {sb_table_theta2u(theta_v), sb_table_phi2u(phi_v)};
    slices_t one = {{q, q, q, q}, {1, 0, 0, 0}};
    double s[2] = {(double)x / (double)(g->rgb.w - 1), (double)y / (double)(g->rgb.h - 1)}, u_m[2];
    sb_table_warp_sample(&g->vndf, &one, s, u_m);
    double tm = u_m[0] * u_m[0] * (SB_PI / 2), pm = 2 * SB_PI * u_m[1] - SB_PI + (g->isotropic ? phi_v : 0);
    double m[3] = {sin(tm) * cos(pm), sin(tm) * sin(pm), cos(tm)};
    double vm = v[0] * m[0] + v[1] * m[1] + v[2] * m[2];
    double l[3] = {2 * vm * m[0] - v[0], 2 * vm * m[1] - v[1], 2 * vm * m[2] - v[2]};
    if (!(l[2] > SB_HORIZON_Z)) return 0;
    double scale = sb_rgl_jacobian_(g, u_m, u_v);
    for (size_t c = 0; c < 3; c++) {
        double val = g->rgb.v[(q * g->rgb.chans + c) * nodes + node] * scale;
        f[c] = val > 0 ? val / l[2] : 0;
    }
    for (int c = 0; c < 3; c++) {
        wi[c] = l[c];
        wo[c] = v[c];
    }
    return 1;
}
