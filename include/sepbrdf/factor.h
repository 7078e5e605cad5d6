/* sepbrdf: factorisation plan, factors and reconstruction.
 *
 * For each channel c the plan computes the truncated SVD of the sampled
 * matrix M_c ~ sum_j sigma_j u_j v_j^T and stores the texture pairs
 *     g_j = sqrt(sigma_j) u_j   (row domain, e.g. incoming directions)
 *     h_j = sqrt(sigma_j) v_j   (column domain, e.g. outgoing directions)
 * with the sign of each pair chosen so that sum(g_j) >= 0 (the product is
 * unchanged).  Errors are measured on the valid cells of M for every
 * J' = 1..J by explicit residuals: rel_rms = ||M - M_J'||_F / ||M||_F. */
#ifndef SEPBRDF_FACTOR_H
#define SEPBRDF_FACTOR_H

#include "common.h"
#include "matrix.h"
#include "param.h"
#include "solver.h"
#include "source.h"
#include "svd.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- factors ----------------------------------------------------------- */

typedef struct sb_factors sb_factors_t;

/* Empty factors: `terms` pairs of `channels` (1 or 3) textures, g of
 * g_w x g_h texels, h of h_w x h_h texels, all zero. */
SB_API sb_result_t sb_factors_create(sb_context_t *ctx, size_t terms, size_t channels, size_t g_w, size_t g_h,
                                     size_t h_w, size_t h_h, sb_factors_t **out);
SB_API void sb_factors_destroy(sb_factors_t *f);

/* Accessors.  side is SB_SIDE_G or SB_SIDE_H; for a NULL f, another side,
 * a term >= sb_factors_terms() or a channel >= sb_factors_channels() they
 * give 0 sizes, NULL textures, NaN sigma, and set_sigma writes nothing. */
SB_API size_t sb_factors_terms(const sb_factors_t *f);
SB_API size_t sb_factors_channels(const sb_factors_t *f);
SB_API void sb_factors_size(const sb_factors_t *f, int side, size_t *width, size_t *height);
/* Texture of term j, channel c: width*height doubles, row-major. */
SB_API double *sb_factors_tex(sb_factors_t *f, int side, size_t term, size_t channel);
SB_API const double *sb_factors_tex_const(const sb_factors_t *f, int side, size_t term, size_t channel);
SB_API double sb_factors_sigma(const sb_factors_t *f, size_t term, size_t channel);
SB_API void sb_factors_set_sigma(sb_factors_t *f, size_t term, size_t channel, double sigma);

/* String metadata (copied).  Keys used by the library: "param" (param spec),
 * "source" (source description), "form" (f|cos|cos2), "method". */
SB_API sb_result_t sb_factors_set_meta(sb_factors_t *f, const char *key, const char *value);
SB_API const char *sb_factors_get_meta(const sb_factors_t *f, const char *key); /* NULL if absent */
/* The tables of a layout built on them (param.h SB_CAP_TABLES: vndf), read
 * with the set from vndf.exr; f owns them (set replaces and frees the old;
 * NULL f frees the tables). */
SB_API void sb_factors_set_tables(sb_factors_t *f, struct sb_layout_tables *tables);
SB_API const struct sb_layout_tables *sb_factors_tables(const sb_factors_t *f);
SB_API size_t sb_factors_meta_count(const sb_factors_t *f);
/* i-th pair; NULL key and value for i >= sb_factors_meta_count(). */
SB_API void sb_factors_meta_at(const sb_factors_t *f, size_t i, const char **key, const char **value);

/* Errors per number of terms, filled by sb_plan_execute (all zero before).
 * rel_rms[sb_err_at(t, c)]: after t+1 terms, channel c (0..2), c =
 * SB_CH_ALL (3) all channels together; same layout for max_abs.
 * norm[c]: ||M_c||_F. */
#define SB_CH_ALL 3
static inline size_t sb_err_at(size_t term, size_t channel) { return term * 4 + channel; }
typedef struct sb_factor_errors {
    size_t terms;
    double *rel_rms;
    double *max_abs;
    double norm[4];
} sb_factor_errors_t;
SB_API const sb_factor_errors_t *sb_factors_errors(const sb_factors_t *f);
SB_API sb_factor_errors_t *sb_factors_errors_mut(sb_factors_t *f);

/* Errors of the first J' = 1..J terms of f (J = sb_factors_terms) against
 * the matrix m, measured as sb_plan_execute measures them: on the valid
 * cells of m, rel_rms = ||W (M - sum_{j<=J'} g_j h_j^T) W||_F / ||W M W||_F
 * with W the square roots of the cell measures of `weights` for weighted
 * fits (NULL: unweighted), max_abs in native units.  For factors that are
 * not the fit itself, e.g. the stored precision (sb_factors_quantize in
 * exr.h): "the error of what was written".  rel_rms and max_abs receive
 * J * 4 values in the layout of sb_factor_errors_t (index 3: all channels;
 * channels absent from m: 0).  A 1-channel f is compared with every
 * channel of m.  Errors: SB_ERR_ARG (sizes differ), SB_ERR_NOMEM,
 * SB_ERR_NUMERIC (a non-finite error). */
SB_API sb_result_t sb_factors_errors_against(sb_context_t *ctx, const sb_factors_t *f, const sb_matrix_t *m,
                                             const sb_param_t *weights, double *rel_rms, double *max_abs);

/* rel_rms as sb_factors_errors_against gives it, for factors `near` that
 * differ little from `fit` (the same terms rounded to the stored precision,
 * sb_factors_quantize in exr.h), using the errors sb_plan_execute stored in
 * fit: ||X - G~H~^T||^2 = ||R||^2 + 2 <R, D> + ||D||^2 with R the fit's
 * residual and D = GH^T - G~H~^T, evaluated in factor space plus one
 * product of the matrix with 2J columns per channel (no residual pass,
 * no max_abs).  Unmasked matrices only.  Errors: SB_ERR_ARG (sizes differ,
 * masked matrix), SB_ERR_NOMEM, SB_ERR_NUMERIC. */
SB_API sb_result_t sb_factors_errors_near(sb_context_t *ctx, const sb_factors_t *fit, const sb_factors_t *near,
                                          const sb_matrix_t *m, const sb_param_t *weights, double *rel_rms);

/* Value of the first `terms` terms (at most all) at matrix cell (row,
 * col), channel c: sum_j g_j[row] h_j[col].  NaN for a NULL f, or a
 * channel, row or column out of range. */
SB_API double sb_factors_cell(const sb_factors_t *f, size_t terms, size_t channel, size_t row, size_t col);
/* Fraction of negative texels over all g_j, h_j of the first `terms` terms
 * (at most all); NaN for a NULL f. */
SB_API double sb_factors_negative_fraction(const sb_factors_t *f, size_t terms);

/* Texture lookup with the GL conventions of param.h (bilinear, wrap):
 * what a shader's texture() returns (the sampler's weights read it so).
 * NaN for NULL arguments, side, term or channel out of range, or a
 * non-finite st. */
SB_API double sb_factors_lookup(const sb_factors_t *f, const sb_param_t *p, int side, size_t term, size_t channel,
                                const double st[2]);
/* The lookup the reconstruction makes (sb_brdf in the snippet,
 * sb_factors_eval): sb_factors_lookup, but beyond the last texel centre of
 * an axis whose edge is SB_EDGE_LINEAR (sb_param_edge) the line through
 * the last two texel centres. */
SB_API double sb_factors_lookup_brdf(const sb_factors_t *f, const sb_param_t *p, int side, size_t term, size_t channel,
                                     const double st[2]);

/* Reconstructed f_r(wi, wo) from the first `terms` terms through texture
 * lookups exactly as the GLSL snippet does, divided back by the form
 * weight.  Returns 0 (rgb = 0) outside the domain, and for NULL arguments
 * or an unknown form. */
SB_API int sb_factors_eval(const sb_factors_t *f, const sb_param_t *p, sb_form_t form, size_t terms, const double wi[3],
                           const double wo[3], double rgb[3]);

/* ---- comparable metric -------------------------------------------------
 * One error for every parameterisation and form, computed on the same
 * work: the relative L2 error of f cos(theta_i) cos(theta_o) over the pairs
 * where the source is known, integrated over solid angle on a reference io
 * grid (cell centres, weights dw_i dw_o), with the reconstruction resampled
 * through sb_factors_eval (texture lookups, form divided back):
 *   e(J') = sqrt( sum w (f~ - f)^2 c_i^2 c_o^2 / sum w f^2 c_i^2 c_o^2 ).
 * Computed with exact reductions (an isotropic source tabulated on its R^3
 * distinct values, io / io-area sides tabulated per direction, iso pairs of
 * an isotropic source by rotation class): equal to the
 * pair-by-pair sums up to rounding, and the same bits on any thread count. */
/* Largest reference grid: R^4 pairs (R^3 for an isotropic source), 3 s
 * at 128 on the 2-core test machine, minutes at 256. */
#define SB_METRIC_MAX_RES 128

typedef struct sb_metric_opts {
    size_t res;        /* reference grid cells per angular axis, default 32, at most SB_METRIC_MAX_RES */
    int threads;       /* 0 = all cores */
    unsigned channels; /* the channels measured (1 R, 2 G, 4 B; 0 = all): the source's others read as 0 */
} sb_metric_opts_t;

typedef struct sb_metric {
    size_t terms;         /* J' = 1..terms are filled */
    double rel_l2[256];   /* comparable error after J' terms (index J'-1) */
    double neg_frac[256]; /* fraction of known pairs with a negative reconstructed channel */
    double neg_texels;    /* fraction of negative texels over all g_j, h_j */
    size_t pairs, known;  /* reference pairs, pairs the source knows */
} sb_metric_t;

/* Compute the metric for the first min(J, 256) terms of f.  Errors:
 * SB_ERR_ARG (NULL argument, unknown form, textures not of p's size),
 * SB_ERR_RANGE (res beyond 2..SB_METRIC_MAX_RES), SB_ERR_NOMEM. */
SB_API sb_result_t sb_metric_compute(sb_context_t *ctx, const sb_source_t *src, const sb_factors_t *f,
                                     const sb_param_t *p, sb_form_t form, const sb_metric_opts_t *opts,
                                     sb_metric_t *out);

/* ---- plan ------------------------------------------------------------- */

typedef struct sb_plan sb_plan_t;

/* Options of a plan; zero fields are the defaults.  Versioned by size as
 * sb_job_opts_t (job.h): SB_PLAN_OPTS_INIT sets it; 0 stands for
 * SB_PLAN_OPTS_SIZE_0_1; a size beyond the library's is SB_ERR_ARG. */
typedef struct sb_plan_opts {
    size_t size;       /* sizeof(sb_plan_opts_t) of the caller's headers; 0: SB_PLAN_OPTS_SIZE_0_1 */
    size_t terms;      /* J, default 4; with max_error: the upper limit */
    double max_error;  /* stop at the first J' with rel_rms <= max_error; 0 = off */
    sb_svd_opts_t svd; /* method and its parameters */
    /* Solid-angle weighting: factor W_r M W_c with W = sqrt(cell measure)
     * so the fit minimises the error integrated over the domain, then
     * unscale the textures (g /= W_r, h /= W_c).  rel_rms is then measured
     * in that weighted norm. */
    int weighted;
    /* With weighted: these square-root weights W_r (rows values) and W_c
     * (cols values) instead of the cells' solid angles, e.g. a scene's
     * (scene.h); both or neither, each > 0; they must outlive the plan. */
    const double *row_weights, *col_weights;
    /* Cells with mask 0 (outside the domain, unmeasured) are excluded from
     * the fit by iterative imputation (a low-rank fit of the valid cells) unless zero_fill is set,
     * in which case they are factored as zeros (the lecture's plain method). */
    int zero_fill;
    int fit_max_iters; /* masked fit: outer iterations, default 300 */
    double
        fit_tol; /* masked fit: relative improvement to stop, default 1e-5 (a sweep that gains less stops the stage) */
    /* Non-negative factors (SB_METHOD_NMF) only; NULL: none.  `terms`
     * numbers: the headline errors (estimate.h) of the factors this plan's
     * options gave without it for the same matrix, each over the default
     * method's headline at J' = 1..terms.  The solver then weighs each
     * prefix by its ratio corrected to these and fits again toward the
     * lowest worst ratio, keeping that fit only where its corrected worst
     * prefix is lower (docs/positive.md, "Refitted toward the headline's
     * own ratios").  Must outlive the plan. */
    const double *nonneg_ratio;
    /* As nonneg_ratio, per colour channel: 3 x `terms` numbers, channel c's
     * at c * terms (each channel's headline over the default method's
     * channel); where given, a channel's solve takes its own instead of
     * nonneg_ratio.  NULL: none.  Must outlive the plan. */
    const double *nonneg_ratio_channel;
    /* Non-negative factors only: 1 asks for a fit to rank layouts by (the
     * job's screening): where cells are out of the data, the solver keeps
     * its first fit, without the refits toward the headline after it
     * (docs/positive.md, round h38y).  0: the whole fit. */
    int nonneg_first_fit;
    /* Non-negative factors with nonneg_ratio only: the rounds of ratios it
     * holds (nonneg_ratio_channel likewise), round k's at k * terms (k * 3
     * * terms): round k's are the headline's ratios of the fit round k - 1
     * gave, the fit made again from that fit toward them.  0 or 1: one. */
    size_t nonneg_rounds;
} sb_plan_opts_t;
#define SB_PLAN_OPTS_INIT                                                                                              \
    { .size = sizeof(sb_plan_opts_t) }
/* sepbrdf 0.1's sb_plan_opts_t, which a size of 0 stands for (frozen). */
#define SB_PLAN_OPTS_SIZE_0_1 (offsetof(sb_plan_opts_t, fit_tol) + sizeof(double))

/* What the last sb_plan_execute did for the masked fit (0 if unmasked). */
typedef struct sb_plan_stats {
    int masked;         /* 1 if a masked fit ran */
    int fit_iterations; /* largest over channels */
    int fit_converged;  /* all channels converged */
    int proportional;   /* channels were proportional: factored once */
} sb_plan_stats_t;
SB_API void sb_plan_stats(const sb_plan_t *plan, sb_plan_stats_t *out);

/* Plan for rows x cols matrices: pick the solver from the registry
 * (solver.h) and allocate every buffer sb_plan_execute needs.  A plan made
 * from the shape alone plans a dense method; the masked fit (a matrix with
 * excluded cells) or the block-circulant SVD (phi_period set) is planned on
 * the first execute that needs it and kept.  sb_plan_create_for plans for
 * the shape, mask and structure of m, so that execute allocates nothing
 * but the factors it returns (and, for the masked fit, the lists of valid
 * cells of the matrix at hand), for m and every matrix like it.
 * Errors: SB_ERR_ARG (no output, empty matrix), SB_ERR_RANGE (terms above
 * min(rows, cols), max_error outside [0, 1)), SB_ERR_OVERFLOW (beyond the
 * memory limit), SB_ERR_NOMEM, and those of the solver's plan. */
SB_API sb_result_t sb_plan_create(sb_context_t *ctx, size_t rows, size_t cols, const sb_plan_opts_t *opts,
                                  sb_plan_t **out);
SB_API sb_result_t sb_plan_create_for(sb_context_t *ctx, const sb_matrix_t *m, const sb_plan_opts_t *opts,
                                      sb_plan_t **out);
SB_API void sb_plan_destroy(sb_plan_t *plan);

/* Factor every channel of m.  *out receives new factors (texture sizes from
 * `param`), with sigma, errors and the meta keys "param", "form", "method"
 * (the solver's name, solver.h), "weighted".  A channel missing in m
 * (data[c] == NULL) is not computed.  Errors: SB_ERR_ARG (NULL argument, sizes
 * differ from the plan's or the parameterisation's, ld < rows), SB_ERR_NOMEM, SB_ERR_NUMERIC (a
 * solver failed, a non-finite error). */
SB_API sb_result_t sb_plan_execute(sb_plan_t *plan, const sb_matrix_t *m, const sb_param_t *param, sb_factors_t **out);

#ifdef __cplusplus
}
#endif
#endif
