/* sepbrdf: importance sampling from non-negative factors (Lawrence et al.
 * 2004), in C and in the GLSL snippet.
 *
 * For non-negative factors (--method nmf) the stored form of the BRDF
 * (matrix.h: f, f cos(theta_i) or f cos(theta_i) cos(theta_o)) is, for a
 * fixed outgoing direction wo,
 *     F(wi) = sum_k g_k(row(wi, wo)) h_k(wo)      k = (term j, channel c)
 * and the sampler draws wi with a density proportional to the luminance
 * (Rec. 709 weights 0.2126, 0.7152, 0.0722; 1 for a single channel) of
 * F at the texel centres, piecewise constant in solid angle over the row
 * cells of the parameterisation:
 *   1. pick k with probability W_k / sum W: for io and io-area
 *      W_k = lum_c h_k(st_h) I_k, where I_k = sum_r g_k[r] m_r (m_r =
 *      sb_param_row_measure) and st_h is the h coordinate of wo (that of
 *      the pair (mirror(wo), wo), mirror(wo) = (-x, -y, z)); this is exact.
 *      For the half-vector layouts (hd, iso) h_k depends on wi too, and
 *      W_k is tabulated per row cell c of wo (taken as a direction: the
 *      cell of the pair (wo, wo)):
 *          W_k(c) = lum_c sum_r g_k[r] m_r h_k(st_h(wi_rc, wo_c)),
 *      over the cells r whose centre h_r reflects the centre wo_c of cell c
 *      to wi_rc = 2 (wo_c.h_r) h_r - wo_c inside the domain (the integral
 *      of term k over the directions this wo can reach; (W H)^2 J C
 *      lookups at creation: 0.5 s for hd at 32 cells, 16x that at 64),
 *      and read bilinear between the cell centres at wo's g coordinate
 *      (GL filtering with the g texture's wraps): continuous in wo, so
 *      that float (the GLSL) and double agree where wo is on a cell edge;
 *   2. pick the row cell r = (x, y) of g_k's texture by a marginal CDF over
 *      y and a conditional CDF over x, P_k(r) = g_k[r] m_r / I_k
 *      (piecewise constant: one value per texel, the matrix cell, not the
 *      bilinear lookup between texel centres);
 *   3. draw a direction uniformly in solid angle over the cell
 *      (sb_param_row_sample): wi itself (io, io-area), or the half vector h
 *      and wi = 2 (wo.h) h - wo (hd, iso: SB_CAP_HALF_ROWS).
 * So the factored density with respect to solid angle is
 *     p_F(wi | wo) = sum_k (W_k / sum W) P_k(r) / m_r
 * with r the row cell of wi: the one sb_param_row_cell places wi (io,
 * io-area) or h (hd, iso) in, by float comparisons against the edges that
 * the GLSL repeats exactly, so that both take the same cell for the same
 * float L and V also at a cell's edge.  The CDFs are rounded to float,
 * as the GLSL reads them, so that a cell's probability (a difference of
 * two entries) is the same in both.  In the half-vector layouts only the h that
 * can reflect wo above the horizon are drawn:
 * h does iff theta_h < pi/4 + atan2(cos(phi_h - phi_o) sin(theta_o),
 * cos(theta_o)) / 2, so the cells of a row whose lowest z = 1 - cos(theta_h)
 * is above the row's cut z_c (that bound at the row's most favourable phi)
 * less a 64th of the cell's z range are left out of steps 1-2 (a thinner
 * part below the cut would depend on rounding: the cosine share covers
 * it; P_k restricted to the others and renormalised by their mass
 * Z_k(wo); a term with Z_k = 0 is a failed sample), and step 3 draws h uniformly in z over [z_lo, min(z_hi, z_c)]
 * and in phi over the part A of the cell's arc whose h at z_lo reflect wo
 * above the horizon (a superset of that part at every higher z) where the
 * row's arc is the whole circle (iso), and over the whole cell (dz = z_hi
 * - z_lo, |A| its arc; an h beyond z_c or reflected below the horizon is
 * a failed sample) on the arcs of hd, where the kept part's extent is a
 * difference of nearly equal values that float (the GLSL) and double
 * round apart:
 *     p_F(wi | wo) = sum_k (W_k / sum W) P_k(r) / Z_k / (dz |A|) / (4 wo.h).  With the form f cos(theta_i) or
 * f cos(theta_i) cos(theta_o) it is proportional to f cos(theta_i) at the
 * cell centres (io, io-area); with the form f, to f cos(theta_i) at the
 * cell centres on io and io-area (rows are wi), to f on hd and iso.  A share s of the
 * samples is cosine-weighted (defensive sampling, one-sample MIS with the
 * balance heuristic), so that the density is positive wherever the
 * reconstruction is, also between texel centres where the bilinear lookup
 * reaches a texel that is 0 in the tables, and where a half-vector
 * layout's weight table is 0 for a term:
 *     pdf(wi | wo) = s cos(theta_i) / pi + (1 - s) p_F(wi | wo).
 * s is SB_SAMPLER_COSINE_SHARE unless set (sb_sampler_set_cosine_share);
 * `sepbrdf factor` sets it per material from the fit's own error against
 * the source (sb_sampler_choose_share): 1, cosine sampling itself, where
 * the factored density would add noise against the true BRDF.
 * In the half-vector layouts an h that still reflects wo below the horizon
 * (or beyond theta_max) is a failed sample (6-14 % of them in the tests,
 * 25-47 % when h was drawn from all of g_k): the pdf then integrates over
 * the hemisphere to 1 minus the probability of failure (as for microfacet
 * sampling in pbrt and Mitsuba); in io and io-area it integrates to 1
 * (with theta_max at the horizon).
 *
 * The layouts that sample their columns (SB_CAP_COL_SAMPLE: vndf, an RGL
 * file's own grid; vh) have rows of the view (g_k(theta_v), its slices) and
 * columns the nodes of a unit square of positions s that the layout maps
 * to the light for each wo (sb_param_col_sample: vndf's VNDF warp, u_m =
 * VNDF(s | theta_v), m from u_m, wi = reflect(wo, m); a wi below the
 * horizon is a failed sample), as Mitsuba's `measured` plugin samples
 * with the fit's colour grid in place of its luminance warp:
 *   1. pick k with W_k = lum_c g_k(st_g) I_k, st_g the g coordinate of
 *      the pair (mirror(wo), wo) and I_k = int h_k ds, exact for the
 *      bilinear h_k (per cell between nodes, the mean of its 4 corners
 *      times its area);
 *   2. pick a cell of the (S_x - 1) x (S_y - 1) between the h textures'
 *      nodes by a marginal CDF over y and a conditional CDF over x of
 *      those cell integrals (in double: sampler.bin's float copy is the
 *      GLSL's), then s in it with the density of the bilinear patch (its
 *      linear marginal in y, its linear conditional in x): h_k(s) / I_k;
 *   3. wi = sb_param_col_sample(wo, s).
 * So p_F(wi | wo) = sum_k lum_c g_k(st_g) h_k(s) / sum W |ds/dwi|,
 * continuous in s (no cell edges for float and double to take apart), s
 * and |ds/dwi| from sb_param_col_density (vndf: the warp's density in u_m
 * over 2 pi^2 u_m.x sin(theta_m) 4 (wo.m)); with the cosine share as
 * above.  vh (the view's elevation and the half vector in its azimuthal
 * frame) samples its columns too: s is the h texture's st, h_k's nodes
 * weighted by sb_param_col_weight (cos theta_h sin theta_h dtheta_h/ds,
 * the light's solid angle per unit s at the normal view) in h_k above,
 * and its folded phi (SB_CAP_COL_FOLD) drawn on either half with
 * probability 1/2 by u[0]'s remainder after step 1; a wi below the
 * horizon is a failed sample.
 *
 * A third component, a GGX lobe (Trowbridge-Reitz, roughness alpha,
 * about the surface normal; src/factor/sampler_lobe.c), takes a share s_l
 * (0 unless set: sb_sampler_set_lobe, sb_sampler_choose_share): wi is
 * wo reflected about a normal h drawn from the visible normals of wo
 * (Heitz 2018), p_lobe(wi) = D_V(h) / (4 wo.h) with D_V(h) = G1(wo)
 * max(0, wo.h) D(h) / wo.z (Smith's G1), and
 *     pdf(wi | wo) = s cos(theta_i) / pi + s_l p_lobe(wi | wo)
 *                    + (1 - s - s_l) p_F(wi | wo)
 * in the layout's domain (0 outside; a wi below the horizon or outside is
 * a failed sample).  It does not depend on the layout: every layout with
 * a sampler takes it.
 *
 * Two random numbers drive a sample: u[0] < s picks the cosine lobe
 * (r = sqrt(u[0] / s), phi = 2 pi u[1]); u[0] < s + s_l the GGX lobe
 * ((u[0] - s) / s_l and u[1] the disk's radius squared and angle in
 * Heitz's method); otherwise u[0] rescaled by (u[0] - s - s_l) / (1 - s
 * - s_l) picks k,
 * then (rescaled) y, then (rescaled) the position along y inside the
 * cell; u[1] picks x, then (rescaled) the position along x.  The GLSL
 * sampler (sb_glsl_sampler) repeats these steps on the tables that
 * sb_sampler_write stores. */
#ifndef SEPBRDF_SAMPLER_H
#define SEPBRDF_SAMPLER_H

#include "common.h"
#include "factor.h"
#include "matrix.h"
#include "param.h"
#include "source.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The cosine-weighted share s of the samples by default (see above), and
 * the least a sampler takes. */
#define SB_SAMPLER_COSINE_SHARE 0.05
#define SB_SAMPLER_MIN_SHARE 0.02
/* The least roughness alpha of the GGX lobe (sb_sampler_set_lobe). */
#define SB_SAMPLER_MIN_ALPHA 0.01
/* The elevations of wo sb_sampler_choose_share measures: 10, 30, 50, 70 deg. */
#define SB_SAMPLER_CHOICE_WO 4
/* The most rows of half vectors (g texture height, SB_CAP_HALF_ROWS) a
 * sampler takes. */
#define SB_SAMPLER_MAX_ROWS 1024

typedef struct sb_sampler sb_sampler_t;

/* Build the tables of a sampler for the factors f on p (textures of p's
 * sizes), factored in `form`.  f and p are borrowed: they must outlive the
 * sampler.  Errors: SB_ERR_ARG (NULL argument, unknown form, textures not
 * of p's sizes, a negative or non-finite texel: signed factors, e.g. from
 * the SVD, cannot be sampled; factor with --method nmf), SB_ERR_NUMERIC
 * (no positive texel: nothing to sample), SB_ERR_OVERFLOW, SB_ERR_NOMEM. */
SB_API sb_result_t sb_sampler_create(sb_context_t *ctx, const sb_factors_t *f, const sb_param_t *p, sb_form_t form,
                                     sb_sampler_t **out);
SB_API void sb_sampler_destroy(sb_sampler_t *s); /* accepts NULL */

/* Draw wi for the outgoing direction wo (unit, tangent frame) from u in
 * [0,1)^2.  Returns 1 with wi (unit), *pdf = sb_pdf(s, wo, wi) > 0 (1/sr)
 * and rgb = f_r(wi, wo) as sb_factors_eval reconstructs it (form divided
 * back; rgb may be NULL); 0 when no direction results (wo outside the
 * domain, all weights 0 for this wo, a reflected wi below the horizon):
 * wi and rgb zero, *pdf 0.  0 also for NULL arguments. */
SB_API int sb_sample(const sb_sampler_t *s, const double wo[3], const double u[2], double wi[3], double *pdf,
                     double rgb[3]);

/* Density of sb_sample's wi for wo, with respect to solid angle (1/sr): 0
 * outside the domain or for NULL arguments. */
SB_API double sb_pdf(const sb_sampler_t *s, const double wo[3], const double wi[3]);

/* The cosine-weighted share s (stored as a float: the GLSL reads it from
 * sampler.bin).  Errors: SB_ERR_ARG (NULL, s outside
 * [SB_SAMPLER_MIN_SHARE, 1]). */
SB_API sb_result_t sb_sampler_set_cosine_share(sb_sampler_t *s, double share);
SB_API double sb_sampler_cosine_share(const sb_sampler_t *s); /* NAN for NULL */

/* The GGX lobe's share s_l (0: no lobe, the default) and roughness alpha,
 * both stored as floats (the GLSL reads them from sampler.bin).  Errors:
 * SB_ERR_ARG (NULL, s_l < 0, s + s_l > 1 (also for a cosine share set
 * after), alpha outside [SB_SAMPLER_MIN_ALPHA, 1] where s_l > 0).
 * sb_sampler_lobe returns s_l (NAN for NULL) and alpha (0 without a
 * lobe) in *alpha where not NULL. */
SB_API sb_result_t sb_sampler_set_lobe(sb_sampler_t *s, double share, double alpha);
SB_API double sb_sampler_lobe(const sb_sampler_t *s, double *alpha);

/* What sb_sampler_choose_share measured: for wo at theta_o_deg[e] (three
 * azimuths each), the variance of cosine sampling over that of the
 * sampler at the chosen shares, estimating int Y(f_r) cos(theta_i) dwi of
 * the source (Y: Rec. 709 luminance); NAN where the source is 0 there.
 * lobe_share and lobe_alpha: the GGX lobe's s_l and alpha (0, 0: none). */
typedef struct sb_sampler_choice {
    double share;
    double theta_o_deg[SB_SAMPLER_CHOICE_WO];
    double ratio[SB_SAMPLER_CHOICE_WO];
    double lobe_share, lobe_alpha;
} sb_sampler_choice_t;

/* Choose and set s, s_l and alpha from the fit's own error against src
 * (the BRDF the factors were fitted to): the variances of every
 * candidate (the cosine shares alone, s_l = 0, and a grid of (s, s_l)
 * pairs times GGX roughnesses 0.04-0.5: src/factor/sampler_share.c) come
 * from `samples` draws per wo (0: 4096), half of the sampler at s = 1/2
 * without the lobe, half of the lobes of the candidate roughnesses (each
 * variance a sum of squares about the integral, positive however small),
 * and the candidate kept has the largest geometric mean of the ratios
 * over the elevations among those whose every ratio is at least 1.1 and
 * whose every variance, raised by 2 standard errors of its estimate,
 * stays below cosine's; where none is, s = 1 (cosine sampling: ratio 1).
 * Deterministic.  Errors: SB_ERR_ARG (NULL argument), SB_ERR_NOMEM. */
SB_API sb_result_t sb_sampler_choose_share(sb_context_t *ctx, sb_sampler_t *s, const sb_source_t *src, size_t samples,
                                           sb_sampler_choice_t *out);

/* The tables as the GLSL sampler reads them (file "sampler.bin" of an
 * output set; docs/guide.md "Importance sampling"): little-endian,
 *     char[8] "sbsampl1", uint32 W + 1, uint32 H + 1, uint32 layers,
 *     uint32 channels C, then layers x (H + 1) x (W + 1) float32,
 * layer-major, then row-major (x fastest): an R32F texture array
 * uploaded as is.  W x H is the g texture's size; layers = J C + 1.
 * Layer k = j C + c (term j, channel c): texel (x, y < H) the conditional
 * CDF of row y inclusive of x (the last is 1), texel (W, y) the marginal
 * CDF inclusive of y, texel (0, H) I_k / g_scale[j], the integral in the
 * units the g texture stores (g_scale: each g_j texture's storage scale,
 * sepbrdf.scale of g_JJ.exr; NULL = all 1, FLOAT textures).  Layer J C
 * holds m_r at texel (x, y), the cosine-weighted share s at (0, H), the
 * GGX lobe's share s_l at (W, H) and its alpha at (W, 0) (both 0 without
 * a lobe, as in files written before the lobe: read as s_l = 0), and
 * the row cells' edges (sb_param_row_edge, as float) of x at (i, H) for
 * 1 <= i < W and of y at (W, j) for 1 <= j < H.  For SB_CAP_HALF_ROWS layouts layers = 2 J C
 * + 1: layer J C + 1 + k holds W_k(c) for wo at the centre of cell c at texel
 * (x, y).  For SB_CAP_COL_SAMPLE layouts W x H are the cells between the
 * h textures' nodes, layers = J C + 1: layer k as above over those cells
 * with I_k = int h_k ds / g_scale[j] (g_scale: here each h_j texture's
 * storage scale), layer J C the share s at (0, H) and the lobe's s_l at
 * (W, H) and alpha at (W, 0) alone.
 * Unused texels are 0.  Written under a
 * temporary name and renamed.  Errors: SB_ERR_ARG, SB_ERR_NOMEM, SB_ERR_IO. */
SB_API sb_result_t sb_sampler_write(sb_context_t *ctx, const sb_sampler_t *s, const char *path, const double *g_scale);

#ifdef __cplusplus
}
#endif
#endif
