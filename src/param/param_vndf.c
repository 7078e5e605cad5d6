/* vndf: an RGL file's own grid (Dupuy & Jakob 2018), for the isotropic
 * tensor_files of the RGL database.  Such a file stores, per slice of the
 * view's elevation theta_v (its theta_i nodes), the colour of f cos
 * theta_l on a grid of S_x x S_y nodes in the sample space of its own
 * VNDF warp; its evaluation (as Mitsuba 3's `measured` plugin does it) is
 *
 *     value = max(0, RGB(s | theta_v)) NDF(u_m) / (4 sigma(u_v)),
 *     s = VNDF^-1(u_m | theta_v),  f = value / cos theta_l,
 *
 * with RGB and the VNDF tables interpolated linearly between the two
 * slices around theta_v.  Here rows are the slices (texture n x 1, texel
 * k = slice k, so bilinear filtering along the row coordinate
 * (k + w + 1/2) / n is exactly the file's slice interpolation) and columns
 * the colour grid's nodes (texture S_x x S_y, node (x, y) at the texel
 * centre, so bilinear filtering is the file's bilinear patch).  The matrix
 * of a channel is then the file's own nodes: rank <= n, and J = n terms
 * reproduce the file exactly wherever it is evaluated.
 *
 * The column coordinate needs the file's VNDF warp, and the value its NDF
 * and sigma: this layout carries them as tables (sb_layout_tables_t: from
 * the RGL source, or read back from vndf.exr), applies the known factor
 * NDF / (4 sigma) as its gain (sb_param_gain; the reconstruction is
 * max(0, sum) x gain), and its GLSL reads them from the texture sb_vndf
 * (vndf.exr, texelFetch only; the HLSL, MSL and WGSL rewritten from it
 * likewise, src/output/shader.c):
 *     rows q H_v + y (q < n, y < H_v): R the slice's normalised density,
 *         G its conditional CDF, B its marginal CDF at row y;
 *     then H_n rows of the NDF (R), H_s rows of sigma (R);
 *     last row: R = n, W_v, H_v, W_n, H_n, W_s, H_s, S_x, S_y, jacobian,
 *         then the n theta_i nodes (radians).
 * Cells: V = (sin theta_k, 0, cos theta_k), u_m = VNDF(s | slice k) (the
 * warp itself, by bisection of its inverse), m from u_m, L = 2 (V.m) m -
 * V; a BRDF pair when L and V are above the horizon.  Measures: rows the
 * solid angle of the views nearest the slice, columns 2 pi / (S_x S_y)
 * (the warp spends its nodes as the VNDF does: a weight, not a
 * quadrature).  Sampling (SB_CAP_COL_SAMPLE, sampler.h): the colour
 * grid's position s maps to the light by the warp itself, wi = reflect(wo,
 * m(VNDF(s | theta_v))), with density |ds/dwi| (vndf_col_density). */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "param/param_impl.h"
#include "param/vndf_tables.h"
#include "util/internal.h"

#define VNDF_HEADER 10 /* numbers of the last row before the theta nodes */

static const sb_layout_tables_t *tab(const sb_param_t *p) { return p->tables; }

/* The view's slice weights (the RGL reader's rule: linear in theta_v). */
static void view_slices(const sb_layout_tables_t *t, double theta_v, size_t *k, double *w, slices_t *s) {
    sb_table_interval(t->theta, t->n_theta, theta_v, k, w);
    size_t next = t->n_theta > 1 ? *k + 1 : *k;
    *s = (slices_t){{*k, next, *k, next}, {1 - *w, *w, 0, 0}};
}

/* The file's coordinates of a pair: u_m, u_v and the view's slices. */
static void pair_coords(const sb_layout_tables_t *t, const double l[3], const double v[3], double u_m[2], double u_v[2],
                        size_t *k, double *w, slices_t *s) {
    double m[3] = {v[0] + l[0], v[1] + l[1], v[2] + l[2]};
    double len = sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2]);
    for (int c = 0; c < 3; c++)
        m[c] /= len;
    double theta_v = sb_table_elevation(v), phi_v = atan2(v[1], v[0]);
    double theta_m = sb_table_elevation(m), phi_m = atan2(m[1], m[0]);
    u_v[0] = sb_table_theta2u(theta_v);
    u_v[1] = sb_table_phi2u(phi_v);
    u_m[0] = sb_table_theta2u(theta_m);
    u_m[1] = sb_table_phi2u(phi_m - phi_v);
    u_m[1] -= floor(u_m[1]);
    view_slices(t, theta_v, k, w, s);
}

/* The directions of the node (row, col): the bisection of the warp
 * (sb_table_warp_sample) took a tenth of `factor --method nmf` on RGL
 * files, every pass over the cells asking for them again (round h38w). */
static int cell_dirs(const sb_layout_tables_t *t, size_t row, size_t col, double wi[3], double wo[3]) {
    double tv = t->theta[row];
    size_t x = col % t->sw, y = col / t->sw;
    /* the last row of nodes sits at phi = pi, where u_m.y = 1 wraps to 0: just inside it */
    double s[2] = {(double)x / (double)(t->sw - 1), fmin((double)y / (double)(t->sh - 1), 1 - 0x1p-40)}, u_m[2];
    slices_t one = {{row, row, row, row}, {1, 0, 0, 0}};
    sb_table_warp_sample(&t->vndf, &one, s, u_m);
    double tm = u_m[0] * u_m[0] * (SB_PI / 2), pm = 2 * SB_PI * u_m[1] - SB_PI, m[3];
    sb_dir_from_angles(tv, 0, wo);
    sb_dir_from_angles(tm, pm, m);
    double vm = wo[0] * m[0] + wo[1] * m[1] + wo[2] * m[2];
    for (int c = 0; c < 3; c++)
        wi[c] = 2 * vm * m[c] - wo[c];
    return wo[2] > 1e-9; /* a light below the horizon too: the file holds its node (cell_value) */
}

static int vndf_cell_dirs(const sb_param_t *p, size_t row, size_t col, double wi[3], double wo[3]) {
    const sb_layout_tables_t *t = tab(p);
    if (!t->dirs) return cell_dirs(t, row, col, wi, wo);
    const double *d = t->dirs + 6 * (row + col * t->n_theta);
    memcpy(wi, d, 3 * sizeof *wi);
    memcpy(wo, d + 3, 3 * sizeof *wo);
    return wo[2] > 1e-9;
}

/* The file's node itself: the value over the gain, the entry of form cos. */
static int vndf_cell_value(const sb_param_t *p, size_t row, size_t col, double rgb[3]) {
    const table2d_t *t = &tab(p)->rgb;
    if (!t->v) return 0;
    size_t n = t->w * t->h;
    for (size_t c = 0; c < 3; c++)
        rgb[c] = t->v[(row * t->chans + c) * n + col];
    return 1;
}

static double vndf_row_measure(const sb_param_t *p, size_t row) {
    const sb_layout_tables_t *t = tab(p);
    double lo = row > 0 ? 0.5 * (t->theta[row - 1] + t->theta[row]) : 0;
    double hi = row + 1 < t->n_theta ? 0.5 * (t->theta[row] + t->theta[row + 1]) : SB_PI / 2;
    return 2 * SB_PI * (cos(lo) - cos(hi));
}

static double vndf_col_measure(const sb_param_t *p, size_t col) {
    (void)col;
    return 2 * SB_PI / (double)(tab(p)->sw * tab(p)->sh);
}

static int vndf_coords(const sb_param_t *p, const double wi[3], const double wo[3], double st_g[2], double st_h[2]) {
    const sb_layout_tables_t *t = tab(p);
    double u_m[2], u_v[2], w, s[2];
    size_t k;
    slices_t sl;
    st_g[0] = st_g[1] = st_h[0] = st_h[1] = 0.5;
    if (!(wi[2] > 0 && wo[2] > 0)) return 0;
    pair_coords(t, wi, wo, u_m, u_v, &k, &w, &sl);
    sb_table_warp_invert(&t->vndf, u_m, &sl, s);
    st_g[0] = ((double)k + w + 0.5) / (double)t->n_theta;
    st_h[0] = (s[0] * (double)(t->sw - 1) + 0.5) / (double)t->sw;
    st_h[1] = (s[1] * (double)(t->sh - 1) + 0.5) / (double)t->sh;
    return 1;
}

/* The file's value is f cos theta_l and its f = value / cos theta_l with
 * no guard, but the snippet divides the form cos by max(cos theta_l,
 * 0.001): below 0.001 (0.06 degrees from the horizon, 6 % of the pairs of
 * theta_i > 89 degrees) that alone left 13 % in the band at J = n on RGL
 * paper.  The gain carries the difference, max(cos, 0.001) / cos. */
static double guard_undo(const double wi[3]) { return wi[2] >= 0.001 ? 1 : 0.001 / wi[2]; }

static double vndf_gain(const sb_param_t *p, const double wi[3], const double wo[3]) {
    const sb_layout_tables_t *t = tab(p);
    if (!(wi[2] > 0 && wo[2] > 0)) return 0;
    if (!t->jacobian) return guard_undo(wi);
    double u_m[2], u_v[2], w;
    size_t k;
    slices_t sl;
    pair_coords(t, wi, wo, u_m, u_v, &k, &w, &sl);
    return guard_undo(wi) * sb_table_bilinear(&t->ndf, u_m, NULL, 0) / (4 * sb_table_bilinear(&t->sigma, u_v, NULL, 0));
}

/* Sampling (sb_param_col_sample): the light of colour-grid position s for
 * the view wo, u_m = VNDF(s | theta_v) (the warp itself, its slices mixed
 * as the file mixes them, by bisection of the inverse), theta_m = u_m.x^2
 * pi / 2, phi_m = 2 pi u_m.y - pi + phi_v, wi = 2 (wo.m) m - wo. */
static int vndf_col_sample(const sb_param_t *p, const double wo[3], const double s[2], double wi[3]) {
    const sb_layout_tables_t *t = tab(p);
    if (!(wo[2] > 0)) return 0;
    double w, u_m[2], m[3];
    size_t k;
    slices_t sl;
    view_slices(t, sb_table_elevation(wo), &k, &w, &sl);
    sb_table_warp_sample(&t->vndf, &sl, s, u_m);
    sb_dir_from_angles(u_m[0] * u_m[0] * (SB_PI / 2), 2 * SB_PI * u_m[1] - SB_PI + atan2(wo[1], wo[0]), m);
    double vm = wo[0] * m[0] + wo[1] * m[1] + wo[2] * m[2];
    for (int c = 0; c < 3; c++)
        wi[c] = 2 * vm * m[c] - wo[c];
    return vm > 0 && wi[2] > 0;
}

/* Its density |ds/dwi| = |ds/du_m| |du_m/dw_m| |dw_m/dwi|: the warp's
 * density in u (the slices' normalised tables mixed, bilinear, in units of
 * a patch: times (W - 1)(H - 1)), dw_m = sin theta_m dtheta_m dphi_m =
 * 2 pi^2 u_m.x sin theta_m du_m, and dwi = 4 (wo.m) dw_m. */
static double vndf_col_density(const sb_param_t *p, const double wi[3], const double wo[3], double s[2]) {
    const sb_layout_tables_t *t = tab(p);
    s[0] = s[1] = 0.5;
    if (!(wi[2] > 0 && wo[2] > 0)) return 0;
    double u_m[2], u_v[2], w, m[3];
    size_t k;
    slices_t sl;
    pair_coords(t, wi, wo, u_m, u_v, &k, &w, &sl);
    sb_table_warp_invert(&t->vndf, u_m, &sl, s);
    sb_dir_half(wi, wo, m);
    double vm = wo[0] * m[0] + wo[1] * m[1] + wo[2] * m[2];
    double pu = (double)((t->vndf.w - 1) * (t->vndf.h - 1)) * sb_table_bilinear(&t->vndf, u_m, &sl, 0);
    double den = 2 * SB_PI * SB_PI * u_m[0] * sin(sb_table_elevation(m)) * 4 * vm;
    return den > 0 && pu > 0 ? pu / den : 0;
}

static const char vndf_glsl[] =
    "uniform sampler2D sb_vndf; // vndf.exr: the file's VNDF, NDF and sigma tables (RGB float, texelFetch)\n"
    "float sb_vt(int c, int y, int x) { return texelFetch(sb_vndf, ivec2(x, y), 0)[c]; }\n"
    "float sb_elev(vec3 d) { return sb_atan2(length(d.xy), d.z); } // the polynomial atan: GPUs' asin is less exact\n"
    "float sb_azim(vec3 d) { return (d.x != 0.0 || d.y != 0.0) ? sb_atan2(d.y, d.x) : 0.0; }\n"
    "// the slice of a view's elevation and the weight of the next (linear in theta_v)\n"
    "void sb_vslice(float tv, out int k, out float w) {\n"
    "    k = 0;\n"
    "    w = 0.0;\n"
    "    if (SB_VN < 2) return;\n"
    "    for (int i = 1; i + 1 < SB_VN; i++)\n"
    "        if (sb_vtheta[i] < tv) k = i;\n"
    "    w = clamp((tv - sb_vtheta[k]) / (sb_vtheta[k + 1] - sb_vtheta[k]), 0.0, 1.0);\n"
    "}\n"
    "float sb_vmix(int c, int k, float w, int x, int y) {\n"
    "    float a = sb_vt(c, k * SB_VH + y, x);\n"
    "    return w == 0.0 ? a : (1.0 - w) * a + w * sb_vt(c, (k + 1) * SB_VH + y, x);\n"
    "}\n"
    "// the VNDF warp's inverse (marginal, then conditional CDF; exact on its bilinear patches)\n"
    "vec2 sb_vinvert(vec2 u, int k, float w) {\n"
    "    float x = clamp(u.x, 0.0, 1.0) * float(SB_VW - 1), y = clamp(u.y, 0.0, 1.0) * float(SB_VH - 1);\n"
    "    int ix = min(int(x), SB_VW - 2), iy = min(int(y), SB_VH - 2);\n"
    "    float fx = x - float(ix), fy = y - float(iy);\n"
    "    float v00 = sb_vmix(0, k, w, ix, iy), v10 = sb_vmix(0, k, w, ix + 1, iy);\n"
    "    float v01 = sb_vmix(0, k, w, ix, iy + 1), v11 = sb_vmix(0, k, w, ix + 1, iy + 1);\n"
    "    float c0 = (1.0 - fy) * v00 + fy * v01, c1 = (1.0 - fy) * v10 + fy * v11;\n"
    "    float xs = fx * (c0 + 0.5 * fx * (c1 - c0));\n"
    "    xs += (1.0 - fy) * sb_vmix(1, k, w, ix, iy) + fy * sb_vmix(1, k, w, ix, iy + 1);\n"
    "    float r0 = sb_vmix(1, k, w, SB_VW - 1, iy), r1 = sb_vmix(1, k, w, SB_VW - 1, iy + 1);\n"
    "    float row = (1.0 - fy) * r0 + fy * r1;\n"
    "    return vec2(row > 0.0 ? xs / row : u.x, fy * (r0 + 0.5 * fy * (r1 - r0)) + sb_vmix(2, k, w, 0, iy));\n"
    "}\n"
    "// bilinear on a plain table of W x H nodes starting at row r0 (R)\n"
    "float sb_vbilin(int r0, int W, int H, vec2 pos) {\n"
    "    float x = clamp(pos.x, 0.0, 1.0) * float(W - 1), y = clamp(pos.y, 0.0, 1.0) * float(H - 1);\n"
    "    int ix = min(int(x), W - 2), iy = min(int(y), H - 2);\n"
    "    float fx = x - float(ix), fy = y - float(iy);\n"
    "    float v00 = sb_vt(0, r0 + iy, ix), v10 = sb_vt(0, r0 + iy, ix + 1);\n"
    "    float v01 = sb_vt(0, r0 + iy + 1, ix), v11 = sb_vt(0, r0 + iy + 1, ix + 1);\n"
    "    return (1.0 - fy) * ((1.0 - fx) * v00 + fx * v10) + fy * ((1.0 - fx) * v01 + fx * v11);\n"
    "}\n"
    "vec2 sb_um(vec3 L, vec3 V) {\n"
    "    vec3 m = L + V; // unnormalised: sb_elev and sb_azim are atan2s, normalize would round it once more\n"
    "    float y = (sb_azim(m) - sb_azim(V) + SB_PI) / (2.0 * SB_PI);\n"
    "    return vec2(sqrt(sb_elev(m) * (2.0 / SB_PI)), y - floor(y));\n"
    "}\n"
    "vec4 sb_coords(vec3 L, vec3 V) {\n"
    "    int k;\n"
    "    float w;\n"
    "    sb_vslice(sb_elev(V), k, w);\n"
    "    vec2 s = sb_vinvert(sb_um(L, V), k, w);\n"
    "    return vec4((float(k) + w + 0.5) / float(SB_VN), 0.5, (s.x * float(SB_CW - 1) + 0.5) / float(SB_CW),\n"
    "                (s.y * float(SB_CH - 1) + 0.5) / float(SB_CH));\n"
    "}\n"
    "bool sb_domain(vec3 L, vec3 V, vec4 st) { return L.z > 0.0 && V.z > 0.0; }\n"
    "// the file's known factor NDF(u_m) / (4 sigma(u_v)), and max(L.z, 0.001) / L.z (the file's f is its\n"
    "// value / L.z, unguarded); the snippet returns max(0, sum) times it\n"
    "float sb_gain(vec3 L, vec3 V) {\n"
    "    float g = L.z >= 0.001 ? 1.0 : 0.001 / L.z;\n"
    "    if (SB_VJAC == 0) return g;\n"
    "    vec2 uv = vec2(sqrt(sb_elev(V) * (2.0 / SB_PI)), (sb_azim(V) + SB_PI) / (2.0 * SB_PI));\n"
    "    return g * sb_vbilin(SB_VN * SB_VH, SB_NW, SB_NH, sb_um(L, V)) /\n"
    "           (4.0 * sb_vbilin(SB_VN * SB_VH + SB_NH, SB_SW, SB_SH, uv));\n"
    "}\n";

/* The GLSL of vndf_col_sample and vndf_col_density (the sampler block,
 * data/sepbrdf_sample.glsl, calls them): the warp itself by bisection of
 * sb_vinvert in float (u_m.y on the marginal, then u_m.x on that row;
 * 32 halvings reach float's resolution), its density from the slices'
 * tables mixed as sb_vinvert mixes them. */
static const char vndf_sample_glsl[] =
    "bool sb_col_dir(vec3 V, vec2 s, out vec3 L) {\n"
    "    L = vec3(0.0);\n"
    "    if (!(V.z > 0.0)) return false;\n"
    "    int k;\n"
    "    float w, lo = 0.0, hi = 1.0;\n"
    "    sb_vslice(sb_elev(V), k, w);\n"
    "    for (int i = 0; i < 32; i++) {\n"
    "        float mid = 0.5 * (lo + hi);\n"
    "        if (sb_vinvert(vec2(0.0, mid), k, w).y < s.y) lo = mid; else hi = mid;\n"
    "    }\n"
    "    float uy = hi;\n"
    "    lo = 0.0;\n"
    "    hi = 1.0;\n"
    "    for (int i = 0; i < 32; i++) {\n"
    "        float mid = 0.5 * (lo + hi);\n"
    "        if (sb_vinvert(vec2(mid, uy), k, w).x < s.x) lo = mid; else hi = mid;\n"
    "    }\n"
    "    float tm = hi * hi * (0.5 * SB_PI), pm = 2.0 * SB_PI * uy - SB_PI + sb_azim(V);\n"
    "    vec3 m = vec3(sin(tm) * cos(pm), sin(tm) * sin(pm), cos(tm));\n"
    "    float vm = dot(V, m);\n"
    "    L = 2.0 * vm * m - V;\n"
    "    return vm > 0.0 && L.z > 0.0;\n"
    "}\n"
    "float sb_col_density(vec3 L, vec3 V, out vec2 s) {\n"
    "    s = vec2(0.5);\n"
    "    if (!(L.z > 0.0 && V.z > 0.0)) return 0.0;\n"
    "    int k;\n"
    "    float w;\n"
    "    sb_vslice(sb_elev(V), k, w);\n"
    "    vec2 u = sb_um(L, V);\n"
    "    s = sb_vinvert(u, k, w);\n"
    "    float x = clamp(u.x, 0.0, 1.0) * float(SB_VW - 1), y = clamp(u.y, 0.0, 1.0) * float(SB_VH - 1);\n"
    "    int ix = min(int(x), SB_VW - 2), iy = min(int(y), SB_VH - 2);\n"
    "    float fx = x - float(ix), fy = y - float(iy);\n"
    "    float pu = (1.0 - fy) * ((1.0 - fx) * sb_vmix(0, k, w, ix, iy) + fx * sb_vmix(0, k, w, ix + 1, iy)) +\n"
    "               fy * ((1.0 - fx) * sb_vmix(0, k, w, ix, iy + 1) + fx * sb_vmix(0, k, w, ix + 1, iy + 1));\n"
    "    vec3 m = normalize(L + V);\n"
    "    float den = 2.0 * SB_PI * SB_PI * u.x * sin(sb_elev(m)) * 4.0 * dot(V, m);\n"
    "    pu *= float((SB_VW - 1) * (SB_VH - 1));\n"
    "    return den > 0.0 && pu > 0.0 ? pu / den : 0.0;\n"
    "}\n";

static const sb_param_vt_t vndf_vt = {vndf_cell_dirs, vndf_row_measure, vndf_col_measure, vndf_coords,
                                      vndf_glsl,      vndf_gain,        vndf_cell_value};

/* p->glsl: the tables' sizes and theta nodes, then vndf_glsl. */
static sb_result_t vndf_build_glsl(sb_context_t *ctx, sb_param_t *p) {
    const sb_layout_tables_t *t = tab(p);
    size_t need = sizeof vndf_glsl + 600 + 24 * t->n_theta, n = 0;
    if (!(p->glsl = malloc(need))) return sb_error(ctx, SB_ERR_NOMEM, "param: out of memory");
    n += (size_t)snprintf(p->glsl + n, need - n,
                          "// vndf: an RGL file's own grid: g over its theta_i slices, h over its colour grid\n"
                          "// reached through its VNDF warp; value = max(0, sum) * sb_gain(L, V).\n"
                          "#define SB_GAIN 1\n#define SB_VN %zu\n#define SB_VW %zu\n#define SB_VH %zu\n"
                          "#define SB_NW %zu\n#define SB_NH %zu\n#define SB_SW %zu\n#define SB_SH %zu\n"
                          "#define SB_CW %zu\n#define SB_CH %zu\n#define SB_VJAC %d\n"
                          "const float sb_vtheta[SB_VN] = float[SB_VN](",
                          t->n_theta, t->vndf.w, t->vndf.h, t->ndf.w, t->ndf.h, t->sigma.w, t->sigma.h, t->sw, t->sh,
                          t->jacobian);
    for (size_t k = 0; k < t->n_theta; k++) { /* float literals: GLSL ES converts no int in a constructor */
        char num[40];
        snprintf(num, sizeof num, "%.9g", t->theta[k]);
        n += (size_t)snprintf(p->glsl + n, need - n, "%s%s%s", k ? ", " : "", num, strpbrk(num, ".e") ? "" : ".0");
    }
    snprintf(p->glsl + n, need - n, ");\n%s", vndf_glsl);
    return SB_OK;
}

static sb_result_t init_vndf(sb_context_t *ctx, sb_param_t *p) {
    if (!p->opts.tables)
        return sb_error(ctx, SB_ERR_UNSUPPORTED,
                        "vndf: the layout is built on an RGL file's own tables; factor an isotropic RGL .bsdf "
                        "file, or keep vndf.exr beside the textures");
    if (p->opts.theta_max < SB_PI / 2 - 1e-12)
        return sb_error(ctx, SB_ERR_UNSUPPORTED, "vndf: the RGL grid covers the whole hemisphere (no theta_max)");
    if (!(p->tables = sb_layout_tables_copy_(p->opts.tables)))
        return sb_error(ctx, SB_ERR_NOMEM, "vndf: out of memory");
    p->opts.tables = p->tables;
    const sb_layout_tables_t *t = p->tables;
    p->vt = &vndf_vt;
    p->rows = t->n_theta;
    p->cols = t->sw * t->sh;
    p->tex_w[SB_SIDE_G] = t->n_theta;
    p->tex_h[SB_SIDE_G] = 1;
    p->tex_w[SB_SIDE_H] = t->sw;
    p->tex_h[SB_SIDE_H] = t->sh;
    memset(p->wrap, 0, sizeof p->wrap); /* CLAMP everywhere */
    char body[96];
    snprintf(body, sizeof body, "vndf"); /* the sizes are the tables' (vndf.exr) */
    sb_param_spec_set(p, body);
    return vndf_build_glsl(ctx, p);
}

const sb_param_desc_t sb_param_desc_vndf = {
    .name = "vndf",
    .description = "an RGL file's own grid (isotropic RGL .bsdf only): rows its theta_i slices, columns its colour "
                   "grid through its VNDF warp; exact at J = slices",
    .keys = "res",
    .caps = SB_CAP_ROTATION_INVARIANT | SB_CAP_NEEDS_ISOTROPY | SB_CAP_TABLES | SB_CAP_COL_SAMPLE,
    .init = init_vndf,
    .vt = &vndf_vt,
    .row_sample = NULL,
    .sample_glsl = vndf_sample_glsl,
    .col_sample = vndf_col_sample,
    .col_density = vndf_col_density};

/* ---- the tables ------------------------------------------------------------- */

static void layout_tables_free(sb_layout_tables_t *t) {
    sb_table_free(&t->vndf);
    sb_table_free(&t->ndf);
    sb_table_free(&t->sigma);
    sb_table_free(&t->rgb);
    free(t->theta);
    free(t->dirs);
    free(t);
}

void sb_layout_tables_destroy(sb_layout_tables_t *t) {
    if (t) layout_tables_free(t);
}

/* Every value rounded to float: what vndf.exr and the shader hold. */
static void round_float(double *a, size_t n) {
    for (size_t k = 0; a && k < n; k++)
        a[k] = (float)a[k];
}

/* The tables, rounded, without the cells' directions. */
static sb_layout_tables_t *tables_new(size_t n_theta, const double *theta, const table2d_t *vndf, const table2d_t *ndf,
                                      const table2d_t *sigma, size_t sw, size_t sh, int jacobian) {
    sb_layout_tables_t *t = calloc(1, sizeof *t);
    if (!t) return NULL;
    t->n_theta = n_theta;
    t->sw = sw;
    t->sh = sh;
    t->jacobian = jacobian != 0;
    t->theta = malloc(n_theta * sizeof *t->theta);
    if (!t->theta || sb_table_copy(&t->vndf, vndf) || sb_table_copy(&t->ndf, ndf) || sb_table_copy(&t->sigma, sigma)) {
        layout_tables_free(t);
        return NULL;
    }
    memcpy(t->theta, theta, n_theta * sizeof *theta);
    size_t nv = vndf->w * vndf->h * vndf->slices;
    round_float(t->theta, n_theta);
    round_float(t->vndf.v, nv);
    round_float(t->vndf.ccdf, nv);
    round_float(t->vndf.mcdf, vndf->h * vndf->slices);
    round_float(t->ndf.v, ndf->w * ndf->h);
    round_float(t->sigma.v, sigma->w * sigma->h);
    return t;
}

sb_layout_tables_t *sb_layout_tables_make_(size_t n_theta, const double *theta, const table2d_t *vndf,
                                           const table2d_t *ndf, const table2d_t *sigma, size_t sw, size_t sh,
                                           int jacobian) {
    sb_layout_tables_t *t = tables_new(n_theta, theta, vndf, ndf, sigma, sw, sh, jacobian);
    /* the cells' directions, from the rounded tables (none out of memory) */
    size_t cells = t ? n_theta * sw * sh : 0;
    t->dirs = cells && cells <= SIZE_MAX / (6 * sizeof *t->dirs) ? malloc(6 * cells * sizeof *t->dirs) : NULL;
    for (size_t k = 0; t->dirs && k < cells; k++)
        cell_dirs(t, k % n_theta, k / n_theta, t->dirs + 6 * k, t->dirs + 6 * k + 3);
    return t;
}

int sb_layout_tables_set_rgb_(sb_layout_tables_t *t, const table2d_t *rgb) {
    sb_table_free(&t->rgb);
    return rgb && rgb->v ? sb_table_copy(&t->rgb, rgb) : 0;
}

sb_layout_tables_t *sb_layout_tables_copy_(const sb_layout_tables_t *t) {
    sb_layout_tables_t *c = tables_new(t->n_theta, t->theta, &t->vndf, &t->ndf, &t->sigma, t->sw, t->sh, t->jacobian);
    size_t n = 6 * t->n_theta * t->sw * t->sh * sizeof *t->dirs;
    if (c && t->dirs && (c->dirs = malloc(n))) memcpy(c->dirs, t->dirs, n);
    if (c && sb_layout_tables_set_rgb_(c, &t->rgb)) {
        sb_layout_tables_destroy(c);
        return NULL;
    }
    return c;
}

static size_t texture_width(const sb_layout_tables_t *t) {
    size_t w = t->vndf.w > VNDF_HEADER + t->n_theta ? t->vndf.w : VNDF_HEADER + t->n_theta;
    w = t->ndf.w > w ? t->ndf.w : w;
    return t->sigma.w > w ? t->sigma.w : w;
}

sb_result_t sb_param_tables_texture(const sb_param_t *p, size_t *width, size_t *height, float **rgb) {
    if (!p || !p->tables || !width || !height || !rgb) return SB_ERR_ARG;
    const sb_layout_tables_t *t = p->tables;
    size_t W = texture_width(t), H = t->n_theta * t->vndf.h + t->ndf.h + t->sigma.h + 1;
    float *a = calloc(W * H * 3, sizeof *a);
    if (!a) return SB_ERR_NOMEM;
    size_t n = t->vndf.w * t->vndf.h;
    for (size_t q = 0; q < t->n_theta; q++)
        for (size_t y = 0; y < t->vndf.h; y++)
            for (size_t x = 0; x < t->vndf.w; x++) {
                float *o = a + 3 * ((q * t->vndf.h + y) * W + x);
                o[0] = (float)t->vndf.v[q * n + y * t->vndf.w + x];
                o[1] = (float)t->vndf.ccdf[q * n + y * t->vndf.w + x];
                o[2] = (float)t->vndf.mcdf[q * t->vndf.h + y];
            }
    size_t r0 = t->n_theta * t->vndf.h;
    for (size_t k = 0; k < t->ndf.w * t->ndf.h; k++)
        a[3 * ((r0 + k / t->ndf.w) * W + k % t->ndf.w)] = (float)t->ndf.v[k];
    r0 += t->ndf.h;
    for (size_t k = 0; k < t->sigma.w * t->sigma.h; k++)
        a[3 * ((r0 + k / t->sigma.w) * W + k % t->sigma.w)] = (float)t->sigma.v[k];
    float *last = a + 3 * (H - 1) * W;
    const size_t head[VNDF_HEADER] = {t->n_theta, t->vndf.w,  t->vndf.h, t->ndf.w, t->ndf.h,
                                      t->sigma.w, t->sigma.h, t->sw,     t->sh,    (size_t)t->jacobian};
    for (size_t k = 0; k < VNDF_HEADER; k++)
        last[3 * k] = (float)head[k];
    for (size_t k = 0; k < t->n_theta; k++)
        last[3 * (VNDF_HEADER + k)] = (float)t->theta[k];
    *width = W;
    *height = H;
    *rgb = a;
    return SB_OK;
}

/* A whole number in 1..max stored in a float, or 0. */
static size_t header_count(float v, size_t max) { return v >= 1 && v <= (float)max && v == floorf(v) ? (size_t)v : 0; }

sb_result_t sb_layout_tables_from_texture(sb_context_t *ctx, size_t W, size_t H, const float *rgb,
                                          sb_layout_tables_t **out) {
    if (!rgb || !out || W < VNDF_HEADER + 1 || H < 4) return sb_error(ctx, SB_ERR_ARG, "vndf tables: no texture");
    *out = NULL;
    const float *last = rgb + 3 * (H - 1) * W;
    size_t d[VNDF_HEADER];
    for (size_t k = 0; k + 1 < VNDF_HEADER; k++)
        d[k] = header_count(last[3 * k], 1 << 16);
    d[9] = last[27] == 1;
    const size_t n = d[0], vw = d[1], vh = d[2], nw = d[3], nh = d[4], sw = d[5], sh = d[6];
    int ok = n && vw >= 2 && vh >= 2 && nw >= 2 && nh >= 2 && sw >= 2 && sh >= 2 && d[7] >= 2 && d[8] >= 2;
    ok = ok && (last[27] == 0 || last[27] == 1) && VNDF_HEADER + n <= W && vw <= W && nw <= W && sw <= W;
    ok = ok && H == n * vh + nh + sh + 1;
    for (size_t k = 0; ok && k < n; k++)
        ok = isfinite(last[3 * (VNDF_HEADER + k)]) &&
             (k == 0 || last[3 * (VNDF_HEADER + k)] > last[3 * (VNDF_HEADER + k - 1)]);
    for (size_t k = 0; ok && k < 3 * W * (H - 1); k++)
        ok = isfinite(rgb[k]);
    if (!ok) return sb_error(ctx, SB_ERR_FORMAT, "vndf tables: the texture's sizes or values are not an RGL grid's");
    double *theta = malloc(n * sizeof *theta);
    table2d_t v = {vw,
                   vh,
                   n,
                   1,
                   malloc(n * vw * vh * sizeof(double)),
                   malloc(n * vw * vh * sizeof(double)),
                   malloc(n * vh * sizeof(double))};
    table2d_t nd = {nw, nh, 1, 1, malloc(nw * nh * sizeof(double)), NULL, NULL};
    table2d_t sg = {sw, sh, 1, 1, malloc(sw * sh * sizeof(double)), NULL, NULL};
    sb_layout_tables_t *t = NULL;
    if (theta && v.v && v.ccdf && v.mcdf && nd.v && sg.v) {
        for (size_t k = 0; k < n; k++)
            theta[k] = last[3 * (VNDF_HEADER + k)];
        for (size_t q = 0; q < n; q++)
            for (size_t y = 0; y < vh; y++) {
                v.mcdf[q * vh + y] = rgb[3 * ((q * vh + y) * W) + 2];
                for (size_t x = 0; x < vw; x++) {
                    v.v[(q * vh + y) * vw + x] = rgb[3 * ((q * vh + y) * W + x)];
                    v.ccdf[(q * vh + y) * vw + x] = rgb[3 * ((q * vh + y) * W + x) + 1];
                }
            }
        for (size_t k = 0; k < nw * nh; k++)
            nd.v[k] = rgb[3 * ((n * vh + k / nw) * W + k % nw)];
        for (size_t k = 0; k < sw * sh; k++)
            sg.v[k] = rgb[3 * ((n * vh + nh + k / sw) * W + k % sw)];
        t = sb_layout_tables_make_(n, theta, &v, &nd, &sg, d[7], d[8], (int)d[9]);
    }
    free(theta);
    sb_table_free(&v);
    sb_table_free(&nd);
    sb_table_free(&sg);
    if (!t) return sb_error(ctx, SB_ERR_NOMEM, "vndf tables: out of memory");
    *out = t;
    return SB_OK;
}
