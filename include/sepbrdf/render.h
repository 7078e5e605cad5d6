/* sepbrdf: CPU reference renderer, a lit sphere.
 *
 * Scene (world coordinates, right-handed, y up):
 *   - the unit sphere at the origin, seen by an orthographic camera looking
 *     down -z; the square image of S x S pixels spans [-e, e]^2 with
 *     e = 1.05 (SB_RENDER_EXTENT).  Pixel (x, y), row 0 at the top, has its
 *     centre at
 *         p = ((2 (x + 1/2) / S - 1) e,  (1 - 2 (y + 1/2) / S) e),
 *     and is covered when |p| < 1; then n = (p, sqrt(1 - |p|^2)).
 *   - the tangent frame of the sphere parameterised with its pole on +y,
 *     P(theta, phi) = (sin theta sin phi, cos theta, sin theta cos phi):
 *         t = normalize(dP/dphi) = normalize(n.z, 0, -n.x),  b = n x t,
 *     so (t, b, n) is right-handed; at the image centre t = +x (right),
 *     b = +y (up).  t is defined wherever the sphere is visible (n.z > 0).
 *   - directions into the local frame: w_local = (w.t, w.b, w.n); the
 *     viewer is V = (0, 0, 1) in the world.
 *   - directional lights, each a unit direction L towards the light and an
 *     irradiance E (on a surface facing it):
 *         radiance = sum_lights f_r(L_local, V_local) E max(L.n, 0).
 *     A light at elevation el and azimuth az (degrees) has
 *         L = (cos el cos az, cos el sin az, sin el):
 *     az in the image plane from +x (right) towards +y (up), el from the
 *     image plane towards the camera (90 = from the viewer).
 * The GL shaders in examples/gl_render.c compute exactly this, so CPU and GPU
 * images can be compared pixel by pixel. */
#ifndef SEPBRDF_RENDER_H
#define SEPBRDF_RENDER_H

#include "common.h"
#include "factor.h"
#include "image.h"
#include "matrix.h"
#include "param.h"
#include "source.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SB_RENDER_EXTENT 1.05
#define SB_RENDER_MAX_LIGHTS 8

typedef struct sb_light {
    double dir[3];     /* towards the light, world; normalised by the renderer */
    double irradiance; /* E; 0 = pi (a white Lambertian facing it shows 1) */
} sb_light_t;

/* Light from elevation and azimuth in degrees (header); irradiance as
 * sb_light_t (0 = default). */
SB_API void sb_light_from_angles(double elev_deg, double azim_deg, double irradiance, sb_light_t *out);

typedef struct sb_render_opts {
    size_t size;        /* S, image width = height in pixels; default 256 */
    size_t light_count; /* 0 = one light at elevation 45, azimuth 45, E = pi */
    sb_light_t lights[SB_RENDER_MAX_LIGHTS];
} sb_render_opts_t;

/* Shading frame of pixel (x, y) (header): n, t, b world unit vectors.
 * Returns 1 when the sphere covers the pixel, 0 otherwise (frame unset),
 * also for a pixel outside the image or a NULL output.  opts may be NULL
 * (defaults). */
SB_API int sb_render_frame(const sb_render_opts_t *opts, size_t x, size_t y, double n[3], double t[3], double b[3]);
/* The same at the image-plane point (px, py) (y up): 1 when |p| < 1. */
SB_API int sb_render_frame_at(double px, double py, double n[3], double t[3], double b[3]);

/* A BRDF to render: write f_r(wi, wo) (local frame) to rgb; return value
 * ignored (missing pairs give rgb = 0). */
typedef int (*sb_render_brdf_fn)(const void *user, const double wi[3], const double wo[3], double rgb[3]);

/* Render the sphere with fn into *out (allocated here, sb_image_free).
 * Errors: SB_ERR_ARG (NULL fn/out, light_count > SB_RENDER_MAX_LIGHTS, a
 * zero or non-finite light direction, negative irradiance), SB_ERR_RANGE
 * (size 0 after defaults or above 16384), SB_ERR_NOMEM. */
SB_API sb_result_t sb_render(sb_context_t *ctx, const sb_render_opts_t *opts, sb_render_brdf_fn fn, const void *user,
                             sb_image_t *out);

/* The original: sb_source_eval. */
SB_API sb_result_t sb_render_source(sb_context_t *ctx, const sb_render_opts_t *opts, const sb_source_t *src,
                                    sb_image_t *out);

/* The reconstruction from the first `terms` terms: sb_factors_eval (the
 * GL conventions of param.h).  terms 0 = all.  Errors as sb_render plus
 * SB_ERR_ARG for NULL factors/param or terms > available. */
SB_API sb_result_t sb_render_factors(sb_context_t *ctx, const sb_render_opts_t *opts, const sb_factors_t *f,
                                     const sb_param_t *param, sb_form_t form, size_t terms, sb_image_t *out);

/* The parameterisation and form a factorisation was made with, from its
 * metadata "param" (a spec as sb_param_spec() writes it, e.g. "io:res=32",
 * "iso:th=90,td=90,pd=180", read by sb_param_parse_spec()) and "form"
 * (absent = f).  Checks that the texture sizes match.  *param is new (destroy it).
 * Errors: SB_ERR_FORMAT (meta missing, malformed or not matching the
 * textures), SB_ERR_UNSUPPORTED (parameterisation not in this build). */
SB_API sb_result_t sb_factors_param(sb_context_t *ctx, const sb_factors_t *f, sb_param_t **param, sb_form_t *form);

#ifdef __cplusplus
}
#endif
#endif
