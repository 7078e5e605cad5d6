/* The row cell of a pair as the sampler's density reads it
 * (sb_param_row_cell), decided so that the GLSL's sb_row_cell takes the
 * same cell for the same float L and V, also at a cell's edge.
 *
 * Both compare quantities made by IEEE single operations (each rounded
 * once: +, -, *, / are correctly rounded in GLSL) against float constants
 * from sampler.bin, and search the edges in the same order; no atan or
 * acos, whose float results differ between GPUs and from the C's double
 * by up to 1e-5 (llvmpipe), which put 0-3 of 102 400 L per layout into
 * the neighbouring cell (docs/positive.md, item 3).  C rounds each step
 * of double to float: an operation on two floats done in double and
 * rounded once to float is the correctly rounded float result (53 >= 2 *
 * 24 + 2), and C's conversions are not contracted into FMAs.  Subnormal
 * inputs and results count as 0, as GPUs may flush them (llvmpipe does:
 * L_y = -1e-45 on the edge phi = 0 read as 0 there, 289 of 24 576 L on
 * io's edges took the other cell until the C did the same).
 *
 * The theta-phi rows (io: L; hd, iso: s = L + V, the half vector before
 * normalising) take
 *     theta >= theta_i  <=>  s_x^2 + s_y^2 >= tan^2(theta_i) s_z^2   (edge_x = tan^2)
 *     phi >= phi_j      <=>  s_y < 0, or s_x <= s_y cot(phi_j)        (phi_j < pi, edge_y = cot)
 *                           s_y < 0 and s_x >= s_y cot(phi_j)        (phi_j > pi)
 * (at phi_j = pi: s_y < 0, or s_y = 0 and s_x < 0). */
#include <float.h>
#include <math.h>

#include "param/param_impl.h"

float sb_f32(double v) {
    float f = (float)v;
    return fabsf(f) < FLT_MIN ? 0.0f : f;
}
float sb_f32_mul(float a, float b) { return sb_f32((double)a * (double)b); }
float sb_f32_add(float a, float b) { return sb_f32((double)a + (double)b); }
float sb_f32_div(float a, float b) { return sb_f32((double)a / (double)b); }

size_t sb_cell_search(size_t n, int (*past)(const void *arg, size_t i), const void *arg) {
    size_t lo = 0, hi = n ? n - 1 : 0;
    while (lo < hi) {
        size_t mid = (lo + hi + 1) / 2;
        if (past(arg, mid))
            lo = mid;
        else
            hi = mid - 1;
    }
    return lo;
}

typedef struct tan2 {
    float r2, z2;
    const float *e;
} tan2_t;

static int past_tan2(const void *arg, size_t i) {
    const tan2_t *t = arg;
    return t->r2 >= sb_f32_mul(t->e[i], t->z2);
}

typedef struct phi {
    float x, y;
    size_t n;
    const float *e;
} phi_t;

static int past_phi(const void *arg, size_t j) {
    const phi_t *q = arg;
    if (2 * j == q->n) return q->y < 0 || (q->y == 0 && q->x < 0);
    float p = sb_f32_mul(q->y, q->e[j]);
    return 2 * j < q->n ? (q->y < 0 || q->x <= p) : (q->y < 0 && q->x >= p);
}

/* The theta-phi cell of s on the g texture (W theta cells, H phi cells). */
static void theta_phi_cell(const sb_param_t *p, const float *const e[2], const float s[3], size_t cell[2]) {
    tan2_t t = {sb_f32_add(sb_f32_mul(s[0], s[0]), sb_f32_mul(s[1], s[1])), sb_f32_mul(s[2], s[2]), e[0]};
    phi_t q = {s[0], s[1], p->tex_h[SB_SIDE_G], e[1]};
    cell[0] = sb_cell_search(p->tex_w[SB_SIDE_G], past_tan2, &t);
    cell[1] = sb_cell_search(p->tex_h[SB_SIDE_G], past_phi, &q);
}

/* tan^2 of the theta edges (through the theta_h warp on hd and iso), cot
 * of the phi edges (phi_j = 2 pi j / H; 0 at pi, which is tested by signs). */
float sb_theta_phi_row_edge(const sb_param_t *p, int axis, size_t i) {
    if (axis == 0) {
        double t =
            tan(sb_warp_theta(sb_param_warp(p, SB_AXIS_THETA_H), (double)i, p->tex_w[SB_SIDE_G], p->opts.theta_max));
        return (float)(t * t);
    }
    size_t n = p->tex_h[SB_SIDE_G];
    if (2 * i == n) return 0;
    double a = 2 * SB_PI * (double)i / (double)n;
    return (float)(cos(a) / sin(a));
}

void sb_grid_row_cell(const sb_param_t *p, const float *const edge[2], const double wi[3], const double wo[3],
                      size_t cell[2]) {
    (void)wo;
    const float s[3] = {sb_f32(wi[0]), sb_f32(wi[1]), sb_f32(wi[2])};
    theta_phi_cell(p, edge, s, cell);
}

void sb_half_row_cell(const sb_param_t *p, const float *const edge[2], const double wi[3], const double wo[3],
                      size_t cell[2]) {
    float s[3];
    for (int i = 0; i < 3; i++)
        s[i] = sb_f32_add(sb_f32(wi[i]), sb_f32(wo[i]));
    theta_phi_cell(p, edge, s, cell);
}
