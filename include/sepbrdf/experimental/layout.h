/* sepbrdf (experimental): your own parameterisation, registered by name.
 *
 * Experimental: these declarations may change between minor versions
 * (as zstd's ZSTD_STATIC_LINKING_ONLY part does); the stable API is
 * the headers directly in include/sepbrdf/.  Every built-in layout (io, io-area, hd, iso, vh)
 * is one such descriptor in one file of the library plus one row of its
 * registry; sb_param_register() adds one from a program, e.g.
 *
 *     static const sb_layout_vt_t my_vt = {my_cell_dirs, my_row_measure, my_col_measure, my_coords, MY_GLSL};
 *     static const sb_layout_desc_t my_layout = {.name = "mine", .description = "...", .keys = "res",
 *                                                .caps = SB_CAP_SEPARABLE, .wrap_y = SB_WRAP_REPEAT, .vt = &my_vt};
 *     sb_param_kind_t kind;
 *     sb_param_register(ctx, &my_layout, &kind);  // then "mine:res=16" works wherever a layout is named
 *
 * (docs/extending.md and tests/test_extend.c hold a complete one.)  A
 * layout registered by a program is one of the process's kinds like the
 * built-in ones: sb_param_kind_parse() and spec strings name it, the
 * factor job screens it under param "auto" where it applies, and its
 * snippet is written as the built-ins' are. */
#ifndef SEPBRDF_EXPERIMENTAL_LAYOUT_H
#define SEPBRDF_EXPERIMENTAL_LAYOUT_H

#include "../common.h"
#include "../param.h"

#ifdef __cplusplus
extern "C" {
#endif

/* A layout's functions.  The library calls them with rows and columns in
 * range and non-NULL arrays only; they read the layout's options through
 * the getters of param.h (sb_param_texture_size, sb_param_theta_max,
 * sb_param_warp). */
typedef struct sb_layout_vt {
    /* sb_param_cell_dirs: the directions at the centre of cell (row, col);
     * 1 for a BRDF pair, 0 for a cell outside the domain */
    int (*cell_dirs)(const sb_param_t *p, size_t row, size_t col, double wi[3], double wo[3]);
    double (*row_measure)(const sb_param_t *p, size_t row); /* sb_param_row_measure */
    double (*col_measure)(const sb_param_t *p, size_t col); /* sb_param_col_measure */
    /* sb_param_coords: the g and h texture coordinates of a pair; 0 outside the domain */
    int (*coords)(const sb_param_t *p, const double wi[3], const double wo[3], double st_g[2], double st_h[2]);
    /* GLSL defining vec4 sb_coords(vec3 L, vec3 V) and bool sb_domain(vec3
     * L, vec3 V, vec4 st) as coords computes them (SB_PI, SB_THETA_MAX,
     * sb_atan2 and sb_atan_q are defined: sb_param_glsl) */
    const char *glsl;
    /* Optional (NULL for most layouts).  gain: the known factor of the
     * value at a pair (sb_param_gain; SB_CAP_TABLES layouts: value = gain
     * x max(0, sum of the terms), and the GLSL defines SB_GAIN and float
     * sb_gain(vec3 L, vec3 V)).  cell_value: 1 and the cell's entry of
     * form cos (the value over the gain) where the layout's tables hold it
     * (sb_param_cell_value), 0 to sample the source. */
    double (*gain)(const sb_param_t *p, const double wi[3], const double wo[3]);
    int (*cell_value)(const sb_param_t *p, size_t row, size_t col, double rgb[3]);
} sb_layout_vt_t;

/* A layout.  The library keeps the pointer: the descriptor and every
 * string it points to must live as long as the process. */
typedef struct sb_layout_desc {
    const char *name;                    /* the spec's kind, e.g. "io": letters, digits, '-', '_' */
    const char *description;             /* one line, for help texts */
    const char *keys;                    /* spec keys besides theta_max, comma separated ("res") */
    unsigned caps;                       /* SB_CAP_SEPARABLE ... (param.h) */
    sb_warp_kind_t warp[SB_AXIS_COUNT_]; /* SB_CAP_WARPS: the layout's own warp per axis */
    int wrap_y;                          /* init NULL: y wrap of the square grids, SB_WRAP_CLAMP or SB_WRAP_REPEAT */
    /* Give the layout its shape from its options (sb_param_options):
     * call sb_param_set_shape once, return SB_OK or an error reported
     * through ctx.  NULL: rows and columns each on R x R textures (R =
     * res, cell k = R y + x), rows = cols = R^2, wrap CLAMP along x and
     * wrap_y along y, spec "NAME:res=R". */
    sb_result_t (*init)(sb_context_t *ctx, sb_param_t *p);
    const sb_layout_vt_t *vt;
    /* texels along warp axis `axis` that sb_warp_measure's scan describes,
     * 0 for none; NULL: theta_h along the g textures' x, theta_d along the
     * h textures' x */
    size_t (*warp_cells)(const sb_param_t *p, int axis);
    /* sampling (sb_param_row_sample, sampler.h): a direction uniform in
     * solid angle over row cell `row` (wi, or h for SB_CAP_HALF_ROWS), and
     * its GLSL `vec3 sb_row_dir(ivec2 cell, vec2 u)` (with col_sample
     * instead: `bool sb_col_dir(vec3 V, vec2 s, out vec3 L)` and `float
     * sb_col_density(vec3 L, vec3 V, out vec2 s)`); NULL both: the layout
     * has no sampler */
    void (*row_sample)(const sb_param_t *p, size_t row, const double u[2], double w[3]);
    const char *sample_glsl;
    /* Optional, with row_sample (sb_param_row_cell): the row cell whose
     * density the sampler gives a pair, decided by float operations that
     * the GLSL's `ivec2 sb_row_cell(vec3 L, vec3 V)` (in sample_glsl,
     * which then defines SB_ROW_CELL) repeats, against the constants
     * row_edge(p, axis, i) (axis 0: x, 1 <= i < W; axis 1: y, 1 <= i < H)
     * that sampler.bin holds as float (sb_edge_x, sb_edge_y).  NULL both:
     * the texel of st_g. */
    float (*row_edge)(const sb_param_t *p, int axis, size_t i);
    void (*row_cell)(const sb_param_t *p, const float *const edge[2], const double wi[3], const double wo[3],
                     size_t cell[2]);
    /* Sampling the columns instead (caps SB_CAP_COL_SAMPLE, both or
     * neither, without row_sample): sb_param_col_sample and
     * sb_param_col_density (param.h) */
    int (*col_sample)(const sb_param_t *p, const double wo[3], const double s[2], double wi[3]);
    double (*col_density)(const sb_param_t *p, const double wi[3], const double wo[3], double s[2]);
    /* Optional with col_sample: the weight of the node at s
     * (sb_param_col_weight); the sampler draws s by the bilinear h_k times
     * it, so that a layout whose s is not already a solid angle (vh: the
     * h texture's st) gives a density over wi close to h_k's.  Its GLSL
     * is the snippet's `float sb_col_weight(vec2 s)` with `#define
     * SB_COL_WEIGHT 1`.  NULL: 1 (vndf, whose s is the VNDF's). */
    double (*col_weight)(const sb_param_t *p, const double s[2]);
} sb_layout_desc_t;

/* A layout's shape: the g textures g[0] x g[1] texels (rows g[0] g[1],
 * row r at texel (r mod g[0], r / g[0])), the h textures h[0] x h[1]
 * (columns likewise), the wrap of each axis (SB_WRAP_CLAMP or
 * SB_WRAP_REPEAT, x then y) and the spec, "NAME:key=value,..." with the
 * layout's keys (theta_max and warps are appended when not the
 * defaults). */
typedef struct sb_layout_shape {
    size_t g[2], h[2];
    int wrap_g[2], wrap_h[2];
    const char *spec;
} sb_layout_shape_t;

/* Within a layout's init only: set p's shape.  Errors: SB_ERR_ARG (a NULL
 * argument, outside an init, a wrap that is neither, a spec that does not
 * start with the layout's name or is longer than 256 bytes), SB_ERR_RANGE
 * (a size 0, or rows or columns beyond 2^26). */
SB_API sb_result_t sb_param_set_shape(sb_context_t *ctx, sb_param_t *p, const sb_layout_shape_t *shape);
/* The options p was created with, resolved: res and theta_max set, the
 * counts of the layout's keys as given (0 when not), the warps of a
 * SB_CAP_WARPS layout resolved; NULL for a NULL p. */
SB_API const sb_param_opts_t *sb_param_options(const sb_param_t *p);

/* At most this many layouts in a process, built-in ones included. */
#define SB_LAYOUTS_MAX 32

/* Add a layout to the process's registry and give its kind (may be
 * NULL): the next free number after the built-in ones.  desc must stay
 * valid for the life of the process.  Safe to call from several threads.
 * Errors: SB_ERR_ARG (NULL desc, a name that is empty, not of letters,
 * digits, '-' and '_', or "auto", no vt or a vt function or glsl
 * missing, sample_glsl without row_sample or col_sample or the reverse, row_cell
 * without row_edge or the reverse, or either without row_sample,
 * col_sample, col_density and SB_CAP_COL_SAMPLE not all or none, or
 * with row_sample),
 * SB_ERR_RANGE (the name is taken; SB_LAYOUTS_MAX reached). */
SB_API sb_result_t sb_param_register(sb_context_t *ctx, const sb_layout_desc_t *desc, sb_param_kind_t *kind);

#ifdef __cplusplus
}
#endif
#endif
