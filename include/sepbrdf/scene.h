/* sepbrdf: scenes, the distribution of direction pairs (wi, wo) a scene
 * uses, for fits and errors weighted by it.
 *
 * A scene is a probability distribution over pairs in the local frame
 * (wi towards the light, wo towards the viewer), given by a spec of items
 * KEY=VALUE separated by ';' (or by ',' before the next KEY=):
 *   view=A..B;light=C..D   elevation ranges, theta from the normal in
 *                          degrees, 0 <= A < B <= 90 (either may be left
 *                          out: 0..90); pairs uniform in solid angle over
 *                          both ranges, every azimuth.
 *   lights=EL,AZ/EL,AZ/... a product shot: the lit sphere of render.h
 *                          (orthographic camera, the unit sphere's
 *                          normals and tangent frames), lit by up to
 *                          SB_RENDER_MAX_LIGHTS directional lights given
 *                          as render.h gives them (elevation above the
 *                          image plane towards the camera, 0..90, and
 *                          azimuth, degrees); pairs (L, V) in the local
 *                          frame of a point uniform over the sphere's
 *                          image (every pixel alike) and a light chosen
 *                          uniformly, unlit pairs (L.n <= 0) left out:
 *                          the pairs `sepbrdf render` shades.
 *   pairs=FILE             a histogram of pairs: a text file with one pair
 *                          a line, "theta_i phi_i theta_o phi_o [weight]"
 *                          in degrees (theta 0..90), weight >= 0 (default
 *                          1), '#' starts a comment; pairs drawn with
 *                          probability proportional to the weight.  At
 *                          most SB_SCENE_MAX_PAIRS pairs and
 *                          SB_SCENE_MAX_FILE bytes; a device or FIFO is
 *                          refused (SB_ERR_IO), never read.
 *   floor=X                with any kind, 0 <= X <= SB_SCENE_FLOOR_MAX:
 *                          the cells the scene never touches share X times
 *                          the scene's mass (each the same; above 1 they
 *                          outweigh the scene) instead of being left out,
 *                          so the fit stays close to the whole-domain one
 *                          there; 0 leaves them out (unconstrained: the
 *                          reconstruction is then arbitrary one step
 *                          outside the scene).  Not given: SB_SCENE_FLOOR
 *                          on layouts with SB_CAP_PARTIAL_DOMAIN (their
 *                          fit is masked anyway; measured: inside as
 *                          without, outside near the unweighted fit) and
 *                          for view/light ranges on separable layouts (io,
 *                          io-area: the ranges' mass is rows x columns,
 *                          which the fit's separable weights hold exactly;
 *                          inside as without, outside 842x -> 0.56x the
 *                          unweighted fit, GGX 0.3 on io, R = 16, J = 2),
 *                          0 for lights and pairs there (the mask is what
 *                          makes their fit better inside, and any floor
 *                          gives that up; docs/bands.md).  Not given,
 *                          the factor job replaces a fit above 1.8x the
 *                          unweighted one over the whole domain (floors
 *                          from 1 down to 0.01 while within, else up to
 *                          10, then the unweighted fit: docs/guide.md,
 *                          Scene-weighted fits).
 * Exactly one of the three kinds; a key given twice, an unknown key, a
 * malformed number, a range out of order or beyond 0..90 are errors.
 *
 * Fits (the factor job's --scene): the pairs are splatted onto the matrix
 * cells with the bilinear footprints a shader's lookups read (every pair
 * touches its 4 g texels x 4 h texels), each weighted by the headline's
 * cos^2(theta_i) over the squared form weight, so that sum over cells
 * mass x (stored error)^2 estimates the scene's f cos(theta_i) error; cells
 * no pair touches get the mass floor (floor=X; with 0 they are left out of
 * the fit, masked), and all are weighted by the best separable fit
 * w_r^2 w_c^2 of their mass (plan weights). */
#ifndef SEPBRDF_SCENE_H
#define SEPBRDF_SCENE_H

#include "common.h"
#include "estimate.h"
#include "matrix.h"
#include "param.h"
#include "render.h"
#include "source.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum sb_scene_kind { SB_SCENE_RANGES = 0, SB_SCENE_LIGHTS, SB_SCENE_PAIRS } sb_scene_kind_t;

typedef struct sb_scene sb_scene_t;

#define SB_SCENE_MAX_PAIRS (1 << 22)
/* The default share of the mass floor (floor=X) on layouts with a partial
 * domain: GGX roughness 0.3, view=0..40;light=0..60, auto (iso), J = 4:
 * inside the scene 2.26e-4 as without, over the whole domain 0.16 %
 * instead of 70 % (docs/bands.md). */
#define SB_SCENE_FLOOR 1e-3
#define SB_SCENE_FLOOR_MAX 1000.0
#define SB_SCENE_MAX_FILE (256ull << 20)

/* Parse a spec (header); a pairs file is read now.  Errors: SB_ERR_ARG
 * (NULL), SB_ERR_PARSE (the message names the item and what is wrong),
 * SB_ERR_RANGE (a value beyond its range, too many lights, no pair of
 * positive weight), SB_ERR_IO (the pairs file), SB_ERR_NOMEM. */
SB_API sb_result_t sb_scene_parse(sb_context_t *ctx, const char *spec, sb_scene_t **out);
SB_API void sb_scene_destroy(sb_scene_t *s); /* accepts NULL */

SB_API sb_scene_kind_t sb_scene_kind(const sb_scene_t *s);
/* Canonical spec ("view=0..60;light=0..90", "lights=45,45/30,150",
 * "pairs=FILE"). */
SB_API const char *sb_scene_spec(const sb_scene_t *s);
/* The lights of a lights scene as render.h takes them (irradiance 0: the
 * default), at most max; returns how many (0 for another kind). */
SB_API size_t sb_scene_lights(const sb_scene_t *s, sb_light_t *out, size_t max);

/* Map a point x of [0,1)^6 to a pair of the scene: returns 1 with wi, wo
 * set when x maps to a pair the scene uses, 0 for an unlit point (lights)
 * or a NULL argument.  Uniform x gives pairs distributed as the scene. */
SB_API double sb_scene_draw(const sb_scene_t *s, const double x[6], double wi[3], double wo[3]);

/* The estimator's pairs (estimate.h) drawn from the scene instead of the
 * whole domain, replicates as sb_pairs_create draws them, so
 * sb_estimate_compute gives the errors over the scene's pairs with their
 * standard errors.  Pairs scenes: sb_scene_draw, every pair weight 1.
 * Ranges: a quarter uniform within the ranges (sb_scene_draw), the rest
 * by the whole domain's mixture toward the lobe with the pairs outside
 * the ranges left out, each pair weighted by 1 / (its density under that
 * mix): the errors over the ranges, uniform in solid angle, with a sharp
 * lobe's residual drawn often enough (a uniform draw reads it low or
 * high, or needs 8x the pairs).  Lights: a quarter uniform over the
 * sphere's pixels and the lights (sb_scene_draw), the rest toward each
 * light's highlight (the normal drawn about its half vector from GGX
 * lobes of alpha 0.005 to 0.3), each pair weighted by the uniform's
 * density over the mix's: the errors over the pixels, every pixel alike.
 * Errors as sb_pairs_create. */
SB_API sb_result_t sb_scene_pairs_create(sb_context_t *ctx, const sb_scene_t *s, const sb_source_t *src,
                                         const sb_estimate_opts_t *opts, sb_pairs_t **out);

/* The errors of factors f (on p, form `form`, as sb_estimate_compute
 * takes them, scales NULL) over the scene's pairs: sb_scene_pairs_create
 * then sb_estimate_compute with opts (NULL: defaults).  Errors as those. */
SB_API sb_result_t sb_scene_estimate(sb_context_t *ctx, const sb_scene_t *s, const sb_source_t *src,
                                     const sb_factors_t *f, const sb_param_t *p, sb_form_t form,
                                     const sb_estimate_opts_t *opts, sb_estimate_t *out);

/* floor=X of the spec; -1 when not given (or for NULL). */
SB_API double sb_scene_floor(const sb_scene_t *s);
/* The cells of mass 0 (of cells values, from sb_scene_mass on p) raised
 * to share the scene's floor X of the total mass, X * sum / (cells of mass
 * 0) each (X not given: SB_SCENE_FLOOR where p has SB_CAP_PARTIAL_DOMAIN,
 * or SB_CAP_SEPARABLE and s is of kind SB_SCENE_RANGES, else 0); nothing
 * for a NULL mass or X = 0. */
/* The floor sb_scene_mass_floor applies on p: floor=X of the spec, or
 * its default there (0 where cells of mass 0 stay out of the fit). */
SB_API double sb_scene_floor_on(const sb_scene_t *s, const sb_param_t *p);
SB_API void sb_scene_mass_floor(const sb_scene_t *s, const sb_param_t *p, double *mass, size_t cells);

/* The scene's mass on the cells of p for a matrix of form `form` (header):
 * mass[row + col * rows] >= 0, the largest 1, from n pairs (0: a default
 * that grows with the cell count).  Errors: SB_ERR_ARG, SB_ERR_RANGE (no
 * pair of the scene lies in p's domain), SB_ERR_OVERFLOW, SB_ERR_NOMEM. */
SB_API sb_result_t sb_scene_mass(sb_context_t *ctx, const sb_scene_t *s, const sb_param_t *p, sb_form_t form, size_t n,
                                 double *mass);

/* The square-root weights W_r (rows values), W_c (cols values) into w of
 * the separable fit W_r^2 W_c^2 ~ mass on its positive cells (header),
 * each at least 1e-3 of its side's largest (nothing for a NULL mass or w). */
SB_API void sb_scene_weights(const double *mass, size_t rows, size_t cols, double *w);

/* Weights for a fit of m on the scene: cells with mass 0 (after the
 * scene's floor, sb_scene_mass_floor) get mask 0 in m
 * (a stored, dense m: a mask is made when it has none; structure and
 * phi_period dropped; valid_count recounted), and w (rows + cols values)
 * the square-root weights W_r, W_c of the separable fit of the mass
 * (plan opts row_weights, col_weights).  Errors: SB_ERR_ARG (NULL,
 * structured or streamed m, sizes differ from p), those of
 * sb_scene_mass, SB_ERR_NOMEM. */
SB_API sb_result_t sb_scene_apply(sb_context_t *ctx, const sb_scene_t *s, const sb_param_t *p, sb_matrix_t *m,
                                  double *w);

#ifdef __cplusplus
}
#endif
#endif
