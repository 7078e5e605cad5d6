/* sepbrdf: parameterisations, the single place that knows how a direction
 * pair maps to a matrix cell and how a direction maps to a texture coordinate.
 *
 * A parameterisation splits a pair (wi, wo) into a "row" domain and a
 * "column" domain.  Row r is texel r of the g textures, column c texel c of
 * the h textures; textures are stored row-major (x fastest): texel (x, y) is
 * index y * width + x.  Texture coordinates follow OpenGL: st in [0,1]^2,
 * texel x has its centre at s = (x + 0.5) / width; bilinear filtering between
 * centres; per-axis wrap CLAMP (clamp to edge) or REPEAT.
 *
 * io (the lecture's theta-phi grid): a direction is (theta, phi), theta in [0, theta_max]
 * (theta_max = pi/2 unless limited), phi in [0, 2 pi), R cells each, centres.
 * Sequential index k = R * i_phi + i_theta (theta varies fastest), so the
 * texture has x = theta index (s = theta / theta_max, CLAMP) and y = phi
 * index (t = phi / 2pi, REPEAT).  Rows = wi, columns = wo, N = R^2 each.
 *
 * io-area: (wi, wo) again, each direction on the Shirley-Chiu concentric
 * map of the cap theta <= theta_max, which is equal-area: square
 * (a, b) in [-1,1]^2 -> disk (concentric) -> cap with 1 - cos(theta) =
 * r^2 (1 - cos theta_max).  s = (a + 1)/2, t = (b + 1)/2, both CLAMP; cell
 * k = R * y + x; every cell has solid angle 2pi (1 - cos theta_max) / R^2.
 * The square's border is the cap's rim (the horizon by default).
 *
 * hd (Kautz & McCool): h = normalize(wi + wo), frame t' = normalize(T -
 * (T.h) h) with T = (1,0,0) (the bitangent (0,1,0) when h = +-T), b' = h x
 * t', d = wi in (t', b', h).  Rows index h, columns d, both on the io grid
 * (theta-phi, R x R, CLAMP / REPEAT); h and d never leave the cap, so the
 * grid spans [0, theta_max].  Cells whose wi or wo leave the cap are not
 * BRDF pairs (cell_dirs returns 0).  Measures: row = solid angle of the h
 * cell, column = integral of 4 cos(theta_d) over the d cell, because
 * dw_i dw_o = 4 cos(theta_d) dw_h dw_d.
 *
 * iso (Rusinkiewicz angles, isotropic and reciprocal BRDFs): rows theta_h
 * (texture th x 1), columns (theta_d, phi_d) (texture td x pd, column c =
 * td * i_phi_d + i_theta_d), phi_d folded into [0, pi) modulo pi
 * (reciprocity swaps wi, wo and shifts phi_d by pi).  Cell centres
 * uniform in sqrt(theta_h / theta_max) (MERL's spacing: fine near the
 * specular peak), and uniform in theta_d over [0, theta_max] and phi_d
 * over [0, pi).  Wrap: theta axes CLAMP, phi_d REPEAT (after folding the
 * phi_d axis is a circle of length pi).  Defaults th = res, td = 2 res,
 * pd = max(res / 2, 2): measured on GGX, the theta_d resolution dominates
 * the error, phi_d matters least.  Measures: row = 2pi (cos lo - cos hi) (phi_h integrated
 * out), column = 2 x integral of 4 cos(theta_d) over the (theta_d, phi_d)
 * cell (the fold covers phi_d and phi_d + pi).  Conventions where angles
 * are undefined: phi_h = 0 when h is the normal, phi_d = 0 when d is,
 * h = normal when wi = -wo (as at io's pole, a pair within rounding of such
 * a pole gets an arbitrary phi, in the shader too).  Each of th, td, pd
 * must be 2..8192.  The measures make sum m_r m_c f approximate the (wi, wo)
 * integral for isotropic, reciprocal f. */
#ifndef SEPBRDF_PARAM_H
#define SEPBRDF_PARAM_H

#include "common.h"
#include "source.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Kinds are chosen by name (sb_param_kind_parse, specs): kind k is the
 * registry's row k, 0 .. sb_param_kind_count() - 1.  The five below keep
 * their numbers for programs that name them; other layouts, built-in or
 * registered by a program (experimental/layout.h), get the numbers after
 * them, so adding one changes no enum. */
typedef enum sb_param_kind {
    SB_PARAM_NONE = -1, /* no layout: the kind of a NULL parameterisation */
    SB_PARAM_IO = 0,    /* the lecture's theta-phi grid for (wi, wo) */
    SB_PARAM_IO_AREA,   /* (wi, wo) on an equal-area (concentric) hemisphere map */
    SB_PARAM_HD,        /* half / difference vectors, Gram-Schmidt frame */
    SB_PARAM_ISO,       /* rows theta_h, columns (theta_d, phi_d), isotropic */
    SB_PARAM_VH         /* rows theta_v, columns the half vector from the view's azimuth, isotropic */
} sb_param_kind_t;

enum { SB_WRAP_CLAMP = 0, SB_WRAP_REPEAT = 1 };
/* Edge of a CLAMP axis beyond its last texel centre (sb_param_edge): the
 * edge texel's value (CLAMP_TO_EDGE), or the line through the last two
 * texel centres continued to the texture's edge s = 1 (half a texel; the
 * snippet's SB_EDGE_H_S, data/sepbrdf.glsl).  iso's theta_d is LINEAR:
 * towards the horizon f changes fastest (Fresnel, GGX's grazing mirror
 * peak), where a clamp holds the value of the last centre (89.27 degrees
 * at R = 32) up to 90. */
enum { SB_EDGE_CLAMP = 0, SB_EDGE_LINEAR = 1 };
enum { SB_SIDE_G = 0, SB_SIDE_H = 1 }; /* row textures g, column textures h */

/* Warps: the monotone map s = W(x) of a texture's elevation axis, x =
 * theta / theta_max in [0, 1] to the texture coordinate s in [0, 1] (texel
 * i of n has its centre at s = (i + 1/2) / n, so its direction is at x =
 * W^-1((i + 1/2) / n) and its cell spans W^-1(i / n) .. W^-1((i + 1) / n)).
 * Bilinear filtering is linear in s, so texels go where W is steep.  Axes:
 * SB_AXIS_THETA_H, the half vector's elevation (iso's rows, hd's h
 * textures), and SB_AXIS_THETA_D, the difference vector's (iso's theta_d,
 * hd's d textures); layouts with SB_CAP_WARPS have both.
 *     uniform  W(x) = x
 *     merl     W(x) = sqrt(x) (MERL's theta_h spacing; iso's default for
 *              theta_h, uniform the default elsewhere)
 *     table    piecewise linear through K + 1 knots (x_k, k / K), x_0 = 0 <
 *              x_1 < ... < x_K = 1: W(x) = (k + (x - x_k) / (x_{k+1} - x_k))
 *              / K on [x_k, x_{k+1}) (clamped to [0, 1]); the knot found by
 *              the same binary search in C and GLSL.
 * A table is what sb_warp_measure() chooses from a source ("adaptive"). */
typedef enum sb_warp_kind {
    SB_WARP_DEFAULT = 0, /* the layout's own */
    SB_WARP_UNIFORM,
    SB_WARP_MERL,
    SB_WARP_TABLE,
    SB_WARP_KIND_COUNT_
} sb_warp_kind_t;

enum { SB_AXIS_THETA_H = 0, SB_AXIS_THETA_D = 1, SB_AXIS_COUNT_ };

#define SB_WARP_MAX_KNOTS 64 /* K of a table: 2..64 segments */

typedef struct sb_warp {
    sb_warp_kind_t kind;
    size_t knots;                    /* table: K */
    double x[SB_WARP_MAX_KNOTS + 1]; /* table: x_0 = 0 < x_1 < ... < x_K = 1 */
} sb_warp_t;

/* Tables a layout is built on (SB_CAP_TABLES: vndf takes an RGL file's
 * VNDF warp, NDF and sigma), from sb_source_layout_tables() or
 * sb_layout_tables_from_texture(). */
typedef struct sb_layout_tables sb_layout_tables_t;

typedef struct sb_param_opts {
    size_t res; /* R: cells per angular axis (default 32) */
    /* iso only, 0 = default: theta_h cells res, theta_d cells 2 res, phi_d cells max(res / 2, 2) */
    size_t res_theta_h, res_theta_d, res_phi_d;
    /* vh only, 0 = default: theta_v cells res (keys tv; th = res_theta_h, ph = res_phi_d) */
    size_t res_theta_v;
    double theta_max; /* largest sampled elevation in radians, 0 = pi/2 */
    /* per axis (SB_AXIS_*), SB_CAP_WARPS layouts only; kind 0 = the layout's own */
    sb_warp_t warp[SB_AXIS_COUNT_];
    /* SB_CAP_TABLES layouts only (NULL otherwise): the tables, copied by
     * sb_param_create (its opts then point at the copy) */
    const sb_layout_tables_t *tables;
    /* 0 (default): the reconstruction is max(0, sum of the terms) (the
     * snippet's SB_CLAMP 1): no negative value where the source is never
     * negative.  1: the plain sum, as the truncated SVD gives it (spec key
     * plain=1; the job's plain_terms). */
    int plain;
} sb_param_opts_t;

typedef struct sb_param sb_param_t;

/* Capabilities of a parameterisation; consumers test these, not kinds. */
enum {
    SB_CAP_SEPARABLE = 1u << 0,          /* st_g depends on wi alone, st_h on wo alone */
    SB_CAP_ROTATION_INVARIANT = 1u << 1, /* coordinates unchanged by a common rotation of wi, wo about z */
    SB_CAP_NEEDS_ISOTROPY = 1u << 2,     /* meaningful for isotropic sources only */
    SB_CAP_FOLDS_RECIPROCITY = 1u << 3,  /* identifies (wi, wo) with (wo, wi): exact for reciprocal sources */
    SB_CAP_PARTIAL_DOMAIN = 1u << 4,     /* some cells are no BRDF pair (masked unless zero-filled) */
    SB_CAP_AZIMUTH_GRID = 1u << 5,       /* rows and columns on the theta-phi grid: isotropic sources give
                                            block-circulant matrices */
    SB_CAP_HALF_ROWS = 1u << 6,          /* rows index the half vector h = normalize(wi + wo): a sampler
                                            (sampler.h) picks h and reflects wo about it */
    SB_CAP_WARPS = 1u << 7,              /* elevation axes theta_h and theta_d take warps (sb_warp_t) */
    SB_CAP_LIGHT_EDGE = 1u << 8,         /* on the whole hemisphere, cells leave the domain only where wi passes its
                                            horizon: f cos theta_i continues by 0 outside (vh) */
    SB_CAP_AUTO_NONRECIPROCAL = 1u << 9, /* auto screens it for sources that are not reciprocal only (where no
                                            layout folding reciprocity applies; vh) */
    SB_CAP_TABLES = 1u << 10,            /* built on a source's own tables (opts.tables; vndf): applies to sources
                                            with such tables only; value = sb_param_gain x max(0, sum) */
    SB_CAP_AUTO_ANALYTIC = 1u << 11,     /* auto screens it for analytic sources only (rv: on the RGL files it
                                            won only at J = 1, breaking the band bounds vndf keeps) */
    SB_CAP_VIEW_EDGE = 1u << 12,         /* on the whole hemisphere, cells leave the domain only where wo passes its
                                            horizon, where f cos theta_i need not fall to 0: an analytic source's
                                            cells there continue by its value at the edge (rv) */
    SB_CAP_COL_SAMPLE = 1u << 13,        /* rows are the view's, columns a warp of wi for each wo (vndf: the RGL
                                            colour grid through its VNDF warp): a sampler (sampler.h) draws the
                                            column position s and maps it to wi (sb_param_col_sample) */
    SB_CAP_COL_FOLD = 1u << 14 /* with SB_CAP_COL_SAMPLE: the columns' t axis is folded by a mirror symmetry (vh: phi
                                  in [0, pi]); the sampler draws either half with probability 1/2 and passes s.y in
                                  [0, 2] (above 1 the mirror half, at position 2 - s.y); the density counts the 1/2 */
};

/* The registry, indexed by kind 0 .. sb_param_kind_count() - 1: name ("io",
 * "io-area", "hd", "iso", "vh"), one-line description and capabilities ("?"
 * and 0 for a kind out of range). */
SB_API size_t sb_param_kind_count(void); /* the built-in layouts and those a program registered */
SB_API const char *sb_param_kind_name(sb_param_kind_t kind);
SB_API const char *sb_param_kind_description(sb_param_kind_t kind);
SB_API unsigned sb_param_kind_caps(sb_param_kind_t kind);
/* Whether the kind suits a source with these flags (sb_source_flags):
 * SB_CAP_NEEDS_ISOTROPY asks for SB_SOURCE_ISOTROPIC. */
SB_API int sb_param_kind_applies(sb_param_kind_t kind, unsigned source_flags);
/* The names joined by sep into buf (snprintf rules: truncated to size,
 * always terminated when size > 0); returns the full length. */
SB_API size_t sb_param_kind_list(char *buf, size_t size, const char *sep);
/* Parse a name of the registry; SB_ERR_UNKNOWN otherwise (NULL name
 * included), SB_ERR_ARG for a NULL out. */
SB_API sb_result_t sb_param_kind_parse(const char *name, sb_param_kind_t *out);

/* Parse a spec "KIND[:key=value,...]" into kind and options; keys res, th,
 * td, pd (iso only), theta_max (degrees) and, on SB_CAP_WARPS layouts,
 * warp_h and warp_d (theta_h's and theta_d's warp: uniform, merl, or a
 * table's interior knots x_1/x_2/.../x_{K-1}), as sb_param_spec() writes
 * them, so sb_param_spec() round-trips.  Options not named are 0 (default).
 * Errors: SB_ERR_ARG (NULL), SB_ERR_UNKNOWN (kind or key), SB_ERR_PARSE
 * (malformed pair, number or fractional count), SB_ERR_RANGE (a count 0,
 * theta_max outside (0, 90], knots not increasing inside (0, 1)); finer
 * limits are sb_param_create()'s. */
SB_API sb_result_t sb_param_parse_spec(sb_context_t *ctx, const char *spec, sb_param_kind_t *kind,
                                       sb_param_opts_t *opts);

SB_API sb_result_t sb_param_create(sb_context_t *ctx, sb_param_kind_t kind, const sb_param_opts_t *opts,
                                   sb_param_t **out);
SB_API void sb_param_destroy(sb_param_t *p);

/* Getters: for a NULL p, kind SB_PARAM_NONE, "" names, 0 counts,
 * NaN theta_max; side is SB_SIDE_G or SB_SIDE_H (another side: 0 sizes,
 * wrap CLAMP). */
SB_API sb_param_kind_t sb_param_kind(const sb_param_t *p);
SB_API const char *sb_param_name(const sb_param_t *p);
SB_API unsigned sb_param_caps(const sb_param_t *p); /* sb_param_kind_caps of its kind */
/* Canonical spec string, e.g. "io:res=32" or "iso:th=90,td=90,pd=180";
 * theta_max (degrees) is appended when not 90, warps (warp_h, warp_d)
 * when not the layout's own (a table's knots with 6 significant digits:
 * sb_param_create rounds them so, and they are the warp exactly). */
SB_API const char *sb_param_spec(const sb_param_t *p);
SB_API size_t sb_param_rows(const sb_param_t *p);
SB_API size_t sb_param_cols(const sb_param_t *p);
SB_API void sb_param_texture_size(const sb_param_t *p, int side, size_t *width, size_t *height);
SB_API void sb_param_wrap(const sb_param_t *p, int side, int wrap[2]);
SB_API void sb_param_edge(const sb_param_t *p, int side, int edge[2]); /* SB_EDGE_*, s then t */
SB_API double sb_param_theta_max(const sb_param_t *p);

/* Directions at the centre of matrix cell (row, col).  Returns 1 if the pair
 * is a BRDF pair (both directions above the horizon and within theta_max),
 * 0 if the cell lies outside the BRDF domain (then wi/wo are unspecified;
 * io and io-area have no such cells, hd and iso about 38 %), and for a
 * NULL argument or a row or column out of range. */
SB_API int sb_param_cell_dirs(const sb_param_t *p, size_t row, size_t col, double wi[3], double wo[3]);

/* Solid-angle measure associated with a row / a column cell, so that
 * sum_r sum_c m_r m_c f(r,c) approximates the integral over the domain.
 * NaN for a NULL p or an index out of range. */
SB_API double sb_param_row_measure(const sb_param_t *p, size_t row);
SB_API double sb_param_col_measure(const sb_param_t *p, size_t col);

/* Continuous texture coordinates of an arbitrary pair for the g and h
 * textures (GL convention above).  Returns 0 when the pair is outside the
 * domain (below the horizon, or beyond theta_max), or an argument is NULL. */
SB_API int sb_param_coords(const sb_param_t *p, const double wi[3], const double wo[3], double st_g[2], double st_h[2]);

/* GLSL source defining `vec4 sb_coords(vec3 L, vec3 V)` (xy: g coordinate,
 * zw: h coordinate) and `bool sb_domain(vec3 L, vec3 V, vec4 st)` that
 * compute exactly sb_param_coords() and its return value.  It may use the
 * constants SB_PI and SB_THETA_MAX and the functions float sb_atan2(float
 * y, float x) and sb_atan_q(float t) = (4/pi) atan(t) on [0, 1] (a
 * polynomial in float, more exact than GPUs' atan) defined by the
 * snippet header. */
SB_API const char *sb_param_glsl(const sb_param_t *p);

/* Importance sampling (sampler.h): the direction a row cell stands for,
 * drawn uniformly in solid angle over the cell.  For u in [0,1)^2 (u[0]
 * along the g texture's x axis, u[1] along y) w is wi itself (io,
 * io-area) or the half vector h (SB_CAP_HALF_ROWS: hd, iso; wi is then
 * wo reflected about h).  The cell of w is texel (floor(s W), floor(t H))
 * of st_g as sb_param_coords gives it, and row = y W + x.  Returns 1; 0
 * (w unchanged) for a NULL argument or a row out of range. */
SB_API int sb_param_row_sample(const sb_param_t *p, size_t row, const double u[2], double w[3]);
/* The row cell (x, y) of the pair (wi, wo) as the sampler's density
 * reads it: by comparisons against float constants, edge[0][i] =
 * sb_param_row_edge(p, 0, i) for 1 <= i < W and edge[1][j] = (p, 1, j)
 * for 1 <= j < H, in float arithmetic (each step rounded once, as IEEE
 * single) on wi and wo rounded to float, so that the GLSL's sb_row_cell
 * on the same float L and V takes the same cell, also at a cell's edge
 * (io, hd, iso: tan^2 of theta and cot of phi; io-area: its rings and
 * a polynomial atan).  Returns 1; 0 (cell unchanged) where the layout
 * places no cells so (the cell is then the texel of st_g) or for a NULL
 * argument.  sb_param_row_edge: NAN there. */
SB_API int sb_param_row_cell(const sb_param_t *p, const float *const edge[2], const double wi[3], const double wo[3],
                             size_t cell[2]);
SB_API float sb_param_row_edge(const sb_param_t *p, int axis, size_t i);

/* Importance sampling of SB_CAP_COL_SAMPLE layouts (sampler.h): the h
 * textures' node grid as a unit square, node (x, y) at s = (x / (W - 1),
 * y / (H - 1)) (vndf: the texel centres; vh: the texture's whole st
 * square, its border texels at the edges), mapped for each wo to a light
 * direction (SB_CAP_COL_FOLD: s.y in [0, 2], the fold's two halves).
 * sb_param_col_sample: the wi of position s for wo; 1 when it
 * is a BRDF pair (both above the horizon), else 0 (wi set or not).
 * sb_param_col_density: the s of the pair (wi, wo) and the density of
 * that map, |ds / dwi| (1/sr, so that a density p(s) over the square is
 * p(s) |ds/dwi| over the light's directions); 0 outside the domain.  Both
 * 0 for a NULL argument or a layout without the capability. */
SB_API int sb_param_col_sample(const sb_param_t *p, const double wo[3], const double s[2], double wi[3]);
SB_API double sb_param_col_density(const sb_param_t *p, const double wi[3], const double wo[3], double s[2]);
/* The weight of the column node at s that the sampler multiplies h_k by
 * (vh: cos theta_h sin theta_h dtheta_h/ds.x, the solid angle per unit s
 * at the normal view up to a constant); 1 for a layout without one, 0 for
 * a NULL argument. */
SB_API double sb_param_col_weight(const sb_param_t *p, const double s[2]);

/* The layout's known factor of the value at (wi, wo): the reconstruction
 * is gain x max(0, sum_j g_j h_j) for SB_CAP_TABLES layouts (vndf: the
 * RGL file's NDF(u_m) / (4 sigma(u_v)), 0 outside the domain), and the
 * plain sum (gain 1) for every other layout or a NULL argument. */
SB_API double sb_param_gain(const sb_param_t *p, const double wi[3], const double wo[3]);
/* The tables of an SB_CAP_TABLES layout (its own copy), NULL otherwise. */
SB_API const sb_layout_tables_t *sb_param_tables(const sb_param_t *p);
/* The entry of form cos (f cos theta_i over the gain) of matrix cell (row,
 * col) when the layout knows it from its tables (vndf: the RGL file's
 * node, also where the light falls below the horizon): 1 and rgb; 0 (the
 * source is sampled) otherwise. */
SB_API int sb_param_cell_value(const sb_param_t *p, size_t row, size_t col, double rgb[3]);
/* The value from a sum of terms and the gain: gain x max(0, sum), the
 * snippet's; the sum itself where opts.plain (not on SB_CAP_TABLES
 * layouts, whose gain is always applied to max(0, sum)). */
SB_API double sb_param_apply_gain(const sb_param_t *p, double sum, double gain);
/* The tables of an SB_CAP_TABLES layout as one RGB float texture (written
 * as vndf.exr; the GLSL reads it as sb_vndf): *rgb (malloc'ed, width x
 * height x 3, row-major) for the caller to free.  SB_ERR_ARG for a layout
 * without tables or a NULL argument, SB_ERR_NOMEM. */
SB_API sb_result_t sb_param_tables_texture(const sb_param_t *p, size_t *width, size_t *height, float **rgb);
/* The tables back from such a texture (checked: sizes and values);
 * SB_ERR_FORMAT for a texture that is not one. */
SB_API sb_result_t sb_layout_tables_from_texture(sb_context_t *ctx, size_t width, size_t height, const float *rgb,
                                                 sb_layout_tables_t **out);
SB_API void sb_layout_tables_destroy(sb_layout_tables_t *t);

/* GLSL source defining `vec3 sb_row_dir(ivec2 cell, vec2 u)`, the same map
 * as sb_param_row_sample for texel `cell` of the g textures (sizes from
 * textureSize(sb_g, 0)); "" for a NULL p. */
SB_API const char *sb_param_sample_glsl(const sb_param_t *p);
/* The warp of axis SB_AXIS_THETA_H or SB_AXIS_THETA_D, resolved (never
 * SB_WARP_DEFAULT); NULL for a layout without SB_CAP_WARPS, a NULL p or
 * another axis. */
SB_API const sb_warp_t *sb_param_warp(const sb_param_t *p, int axis);
/* Texels along warp axis SB_AXIS_THETA_H or SB_AXIS_THETA_D that an
 * adaptive table (sb_warp_measure) is made for; 0 where that scan does not
 * describe the axis (vh's theta_d axis is the view's elevation), for a
 * layout without SB_CAP_WARPS, a NULL p or another axis. */
SB_API size_t sb_param_warp_cells(const sb_param_t *p, int axis);
/* 1 when every warp of p is the layout's own (or p takes none, or is
 * NULL); 0 when one was chosen (uniform or merl instead, or a table). */
SB_API int sb_param_warps_default(const sb_param_t *p);

/* Warp names ("default", "uniform", "merl", "table"; "?" out of range) and
 * parsing ("adaptive" is no kind: sb_warp_measure makes a table). */
SB_API const char *sb_warp_kind_name(sb_warp_kind_t kind);
SB_API sb_result_t sb_warp_kind_parse(const char *name, sb_warp_kind_t *out);
/* W(x) and W^-1(s) of a resolved warp (not SB_WARP_DEFAULT); table: x and s
 * clamped to [0, 1]; uniform and merl: unclamped (merl: x >= 0). */
SB_API double sb_warp_map(const sb_warp_t *w, double x);
SB_API double sb_warp_inverse(const sb_warp_t *w, double s);
/* Check a warp: a known kind; a table with 2..SB_WARP_MAX_KNOTS segments,
 * x_0 = 0, x_K = 1, strictly increasing.  SB_ERR_RANGE otherwise. */
SB_API sb_result_t sb_warp_check(sb_context_t *ctx, const sb_warp_t *w);

/* The table a source asks for along one axis, by equalising the error of
 * linear interpolation between the texels along it.  A scan evaluates
 * f, weighted by cos^2(theta_i) as the headline weights it, over the
 * pair domain theta_i, theta_o <= theta_max on lines along the axis (a fine grid of
 * 512 points, MERL-spaced for theta_h, uniform for theta_d) at a coarse
 * grid of the other angles (the other elevation, phi_d, and phi_h for an
 * anisotropic source), each weighted by its share of the pair measure
 * dw_i dw_o = 4 cos theta_d sin theta_d sin theta_h dtheta_h dphi_h
 * dtheta_d dphi_d.  Starting from the floor's warp (MERL for theta_h,
 * uniform for theta_d), each of 12 rounds places `cells` texel centres by
 * the current warp, measures E_k, the squared error of interpolating f
 * linearly between neighbouring centres (clamped beyond the first and
 * last) times cos^2 theta_i, summed over segment k of the axis, gives
 * segment k the share E_k^(1/5) of the texels (E_k ~ Delta_k^5 for smooth
 * f, so the errors come out equal), mixed with `floor` of the floor's
 * density so no part of the axis is left without texels, and moves the
 * knots half way there (damped: undamped rounds oscillate).  out receives a table (SB_WARP_TABLE,
 * knots rounded as sb_param_create rounds them).  Errors: SB_ERR_ARG,
 * SB_ERR_RANGE (axis, knots, cells, theta_max or floor out of range),
 * SB_ERR_NUMERIC (the source is unknown wherever it was scanned),
 * SB_ERR_NOMEM. */
typedef struct sb_warp_measure_opts {
    size_t knots;     /* K, 2..SB_WARP_MAX_KNOTS (0 = SB_WARP_MAX_KNOTS: two segments a texel at 32 texels) */
    size_t cells;     /* texels along the axis the warp is made for, 2..8192 (0 = 32) */
    double floor;     /* share of the floor density, [0, 1) (0 = 0.15) */
    double theta_max; /* radians, 0 = pi/2 */
    int threads;      /* 0 = all cores */
} sb_warp_measure_opts_t;
SB_API sb_result_t sb_warp_measure(sb_context_t *ctx, const sb_source_t *src, int axis,
                                   const sb_warp_measure_opts_t *opts, sb_warp_t *out);

/* Unit direction <-> spherical angles in the local frame, phi in [0, 2pi). */
SB_API void sb_dir_from_angles(double theta, double phi, double w[3]);
SB_API void sb_dir_to_angles(const double w[3], double *theta, double *phi);
/* The pair of Rusinkiewicz's half/difference angles: h at (theta_h,
 * phi_h), d at (theta_d, phi_d) in h's frame; wi = R_z(phi_h) R_y(theta_h)
 * d, wo its mirror about h (either may lie below the horizon); nothing
 * for a NULL wi or wo. */
SB_API void sb_dirs_from_halfdiff(double theta_h, double phi_h, double theta_d, double phi_d, double wi[3],
                                  double wo[3]);

#ifdef __cplusplus
}
#endif
#endif
