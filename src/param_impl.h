/* Private: the vtable behind sb_param_t, one implementation per file
 * (param_io.c, param_hd.c, param_iso.c ...). */
#ifndef SEPBRDF_PARAM_IMPL_H
#define SEPBRDF_PARAM_IMPL_H

#include "sepbrdf/param.h"

typedef struct sb_param_vt {
    int (*cell_dirs)(const sb_param_t *p, size_t row, size_t col, double wi[3], double wo[3]);
    double (*row_measure)(const sb_param_t *p, size_t row);
    double (*col_measure)(const sb_param_t *p, size_t col);
    int (*coords)(const sb_param_t *p, const double wi[3], const double wo[3], double st_g[2],
                  double st_h[2]);
    const char *glsl; /* defines vec4 sb_coords(vec3 L, vec3 V) */
} sb_param_vt_t;

struct sb_param {
    sb_param_kind_t kind;
    const sb_param_vt_t *vt;
    sb_param_opts_t opts;    /* resolved: res, theta_max set */
    size_t rows, cols;
    size_t tex_w[2], tex_h[2];
    int wrap[2][2];
    char spec[96];
    char *glsl;              /* resolved GLSL (constants substituted) */
};

/* Each implementation fills p (rows, cols, textures, wrap, spec, vt) from
 * p->opts; returns SB_OK or an error reported through ctx. */
sb_result_t sb_param_init_io(sb_context_t *ctx, sb_param_t *p);
sb_result_t sb_param_init_io_area(sb_context_t *ctx, sb_param_t *p);
sb_result_t sb_param_init_hd(sb_context_t *ctx, sb_param_t *p);
sb_result_t sb_param_init_iso(sb_context_t *ctx, sb_param_t *p);

/* Shared by implementations: theta-phi grid of R x R cells on [0, tmax] x
 * [0, 2pi): index -> centre direction, direction -> st (x = theta, y = phi). */
void sb_grid_dir(size_t R, double tmax, size_t index, double w[3]);
void sb_grid_st(double tmax, const double w[3], double st[2]);
double sb_grid_measure(size_t R, double tmax, size_t index);

#endif
