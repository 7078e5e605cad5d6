/* Private: the registry of parameterisations.  Each lives in one file
 * (param_io.c, param_hd.c, ...) holding its functions (sb_param_vt_t) and
 * one descriptor (sb_param_desc_t), and has one row in the table of
 * built-in layouts in layouts.c; nothing else names it. */
#ifndef SEPBRDF_PARAM_IMPL_H
#define SEPBRDF_PARAM_IMPL_H

#include "sepbrdf/experimental/layout.h"
#include "sepbrdf/param.h"

/* Longest spec: a kind's keys plus two tables of 63 interior knots. */
#define SB_PARAM_SPEC_MAX 2048

/* The descriptor is public (experimental/layout.h: programs register
 * their own); the library's files use these names. */
typedef sb_layout_vt_t sb_param_vt_t;
typedef sb_layout_desc_t sb_param_desc_t;

/* The registry (layouts.c): the descriptor of kind, NULL out of range. */
const sb_param_desc_t *sb_param_desc_of(sb_param_kind_t kind);

struct sb_param {
    sb_param_kind_t kind;
    const sb_param_desc_t *desc; /* the registry's row of kind */
    const sb_param_vt_t *vt;
    sb_param_opts_t opts; /* resolved: res, theta_max, warps (SB_CAP_WARPS) set */
    size_t rows, cols;
    size_t tex_w[2], tex_h[2];
    int wrap[2][2];
    int edge[2][2];             /* SB_EDGE_*, per side and axis (0: CLAMP_TO_EDGE's) */
    char *glsl;                 /* the vt's GLSL, after the warp functions of SB_CAP_WARPS layouts */
    sb_layout_tables_t *tables; /* SB_CAP_TABLES: its own copy (opts.tables points here) */
    char spec[SB_PARAM_SPEC_MAX];
    unsigned long serial; /* the same for the same resolved layout (sb_param_serial_) */
    int in_init;          /* within the descriptor's init: sb_param_set_shape allowed */
};

/* Warps (warp.c).  Elevation of texel edge or centre i (i = index, or
 * index + 1/2) of n along an axis with warp w: W^-1(i / n) theta_max
 * (uniform: i theta_max / n, as the grids have always computed it). */
double sb_warp_theta(const sb_warp_t *w, double i, size_t n, double tmax);
/* Round a table's knots to what "%.6g" prints (the spec's digits). */
void sb_warp_round(sb_warp_t *w);
/* ",warp_h=VALUE" (name is "warp_h" or "warp_d") appended to buf at *n. */
void sb_warp_spec_append(const sb_warp_t *w, const char *name, char *buf, size_t size, size_t *n);
/* Parse a spec value: "uniform", "merl" or interior knots "x1/x2/...". */
sb_result_t sb_warp_parse_value(sb_context_t *ctx, const char *value, sb_warp_t *out);
/* GLSL `float NAME(float x)` computing sb_warp_map(w, x), NAME_inv
 * (sb_warp_inverse) and NAME_dinv (its slope in s), appended to buf
 * at *n (bounded by size); returns the bytes it needs. */
size_t sb_warp_glsl(const sb_warp_t *w, const char *name, char *buf, size_t size, size_t *n);

/* Shared by implementations: theta-phi grid of R x R cells on [0, tmax] x
 * [0, 2pi): index -> centre direction, direction -> st (x = theta, y = phi). */
void sb_grid_st(double tmax, const double w[3], double st[2]);
/* The theta axis warped by w (NULL: uniform) for the three below. */
void sb_grid_dir(size_t R, double tmax, const sb_warp_t *w, size_t index, double dir[3]);
double sb_grid_measure(size_t R, double tmax, const sb_warp_t *w, size_t index);
/* Row sampling on the R x R theta-phi grid of p->opts (io, hd): uniform in
 * solid angle over cell `row`, 1 - cos(theta) linear in u[0] between the
 * cell's bounds, phi linear in u[1]. */
void sb_grid_row_sample(const sb_param_t *p, size_t row, const double u[2], double w[3]);
/* GLSL `vec3 sb_row_dir(ivec2 cell, vec2 u)` of sb_grid_row_sample. */
extern const char sb_grid_sample_glsl[];
/* Row cells (row_cell.c, sb_param_row_cell): float arithmetic as the
 * GLSL's (each result rounded once to float); the largest i < n with
 * past(arg, i), past(0) taken as true, in the GLSL's order of steps; the
 * theta-phi rows' edges (tan^2 theta_i, cot phi_j) and cells of L (io)
 * and of L + V (hd, iso). */
float sb_f32(double v); /* v rounded to float, subnormals flushed to 0 */
float sb_f32_mul(float a, float b);
float sb_f32_add(float a, float b);
float sb_f32_div(float a, float b);
size_t sb_cell_search(size_t n, int (*past)(const void *arg, size_t i), const void *arg);
float sb_theta_phi_row_edge(const sb_param_t *p, int axis, size_t i);
void sb_grid_row_cell(const sb_param_t *p, const float *const edge[2], const double wi[3], const double wo[3],
                      size_t cell[2]);
void sb_half_row_cell(const sb_param_t *p, const float *const edge[2], const double wi[3], const double wo[3],
                      size_t cell[2]);
/* integral of 4 cos(theta) over grid cell `index`: 2 dphi (sin^2 hi - sin^2 lo),
 * the half/difference Jacobian dw_i dw_o = 4 cos(theta_d) dw_h dw_d. */
double sb_grid_measure_4cos(size_t R, double tmax, const sb_warp_t *w, size_t index);

/* Elevation theta = atan2(|w_xy|, w_z), accurate near the pole (acos is not). */
double sb_dir_theta(const double w[3]);
/* 1 if w is in the sampled cap: w_z > 0 and theta(w) <= tmax. */
int sb_dir_in_cap(double tmax, const double w[3]);
/* h = (l + v) / |l + v|; the normal (0, 0, 1) when l = -v (h undefined). */
void sb_dir_half(const double l[3], const double v[3], double h[3]);
/* p->spec = body, plus ",theta_max=DEG" when theta_max is not pi/2. */
void sb_param_spec_set(sb_param_t *p, const char *body);
/* A row line and a column grid (iso, vh): rows n[0] (texture n[0] x 1,
 * CLAMP), columns n[1] x n[2] (x CLAMP, y wrap_y); each count checked
 * against 2..max (SB_ERR_RANGE naming axes[i]); spec "NAME:k0=n0,k1=n1,k2=n2"
 * with keys[i]; vtable vt. */
sb_result_t sb_param_line_by_grid(sb_context_t *ctx, sb_param_t *p, const sb_param_vt_t *vt, const char *name,
                                  const size_t n[3], const char *const axes[3], const char *const keys[3], size_t max,
                                  int wrap_y);
/* Both sides on R x R textures (R = p->opts.res), rows = cols = R^2,
 * wrap CLAMP along x and wrap_y along y, vtable vt, spec "NAME:res=R". */
void sb_param_square_grids(sb_param_t *p, const sb_param_vt_t *vt, const char *name, int wrap_y);

#endif
