/* Private: the half-vector layouts' geometry of the sampler
 * (sampler_half.c; the maths there). */
#ifndef SEPBRDF_SAMPLER_IMPL_H
#define SEPBRDF_SAMPLER_IMPL_H

#include "sepbrdf/sampler.h"
#include "util/internal.h"

/* wo seen from the half vectors: sin, cos theta_v and phi_v. */
typedef struct half_view {
    double sv, cv, phiv;
} half_view_t;

void half_view(const double wo[3], half_view_t *v);
/* z = 1 - cos(theta) below which h on the phi arc [a, a + w] can reflect
 * wo above the horizon (w >= 2 pi: the whole circle). */
double half_zcut(const half_view_t *v, double a, double w);
/* Length of the phi in [a, a + w] whose h at z reflects wo above the
 * horizon.  Where the half-width's cosine c is within SB_HALF_FULL_ARC of
 * -1 the whole circle counts (the GLSL's SB_FULL_ARC): there acos(c) = pi
 * - sqrt(2 (1 + c)) turns float's rounding of c (1e-7) into 4.5e-4 of
 * the arc; at theta_V = 2 theta of a row's edge (45 deg and the iso
 * grid's middle edge, 22.5) c is -1 exactly, and the GLSL's pdfs of that
 * row were 6.7e-5 to 1.09e-4 off the C's (401 of the view's 4096, the
 * others within 2e-6).  The snap lengthens an arc by at most sqrt(2e-5)
 * rad; an h drawn there fails, as beyond the cut. */
#define SB_HALF_FULL_ARC 1e-5
double half_phi_len(const half_view_t *v, double z, double a, double w);
/* phi uniform over that set by u in [0, 1); 0 when it is empty. */
int half_phi_sample(const half_view_t *v, double z, double a, double w, double u, double *phi);
/* The steps of a cell that a whole-circle row's cut is rounded to
 * (half_cut_dz, half_arc_z; the GLSL's SB_CUT_STEPS). */
#define SB_HALF_CUT_STEPS 64
double half_cut_dz(double zlo, double zhi, double zc);
double half_arc_z(double zlo, double zhi, double zc);

/* CDFs (sampler_cdf.c): the inclusive CDF of n non-negative values,
 * rounded to float as sampler.bin holds it where as_float (the last 1;
 * uniform when they sum to 0), returning their sum; the entry that u falls
 * in, u rescaled within it; an entry's probability. */
double sb_cdf_build_(const double *v, size_t n, int as_float, double *cdf);
size_t sb_cdf_find_(const double *cdf, size_t n, double *u);
double sb_cdf_prob_(const double *cdf, size_t i);

/* The layouts that sample their columns (SB_CAP_COL_SAMPLE: vndf, vh;
 * sampler_cols.c): the tables of f's h textures for the luminance
 * weights lum; the factored component's direction from u0, u1 in [0, 1)
 * (1, or 0 when none) and its density p_F at wi; the cells W x H between
 * the h textures' nodes and texel (x, y) of layer k < K of sampler.bin
 * (sampler.h). */
typedef struct sb_col_sampler sb_col_sampler_t;
sb_result_t sb_col_sampler_create_(sb_context_t *ctx, const sb_factors_t *f, const sb_param_t *p, const double lum[3],
                                   sb_col_sampler_t **out);
void sb_col_sampler_destroy_(sb_col_sampler_t *c);
int sb_col_dir_(const sb_col_sampler_t *c, const double wo[3], double u0, double u1, double wi[3]);
double sb_col_pdf_(const sb_col_sampler_t *c, const double wo[3], const double wi[3]);
void sb_col_sampler_cells_(const sb_col_sampler_t *c, size_t *W, size_t *H);
double sb_col_file_texel_(const sb_col_sampler_t *c, size_t k, size_t x, size_t y);

/* The analytic lobe (sampler_lobe.c): a GGX visible-normal lobe of
 * roughness alpha about the normal; wi = reflect(wo, h) from u0, u1 in
 * [0, 1) (0 when wo is not above the horizon; wi may be below it) and its
 * density with respect to solid angle. */
int sb_lobe_dir_(double alpha, const double wo[3], double u0, double u1, double wi[3]);
double sb_lobe_pdf_(double alpha, const double wo[3], const double wi[3]);

#endif
