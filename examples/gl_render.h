/* Render the sepbrdf test sphere on the GPU through the shipped GLSL snippet.
 *
 * Offscreen OpenGL 3.3 core through Mesa's OSMesa (llvmpipe on a machine
 * without a GPU).  The scene, frame and lighting are those of
 * sepbrdf/render.h; the BRDF is sb_brdf() of sb_glsl_snippet(), the text
 * that `sepbrdf factor` writes to sepbrdf.glsl, evaluated with the factors as
 * GL_TEXTURE_2D_ARRAY RGB32F textures (layer j = term j, GL_LINEAR, no
 * mipmaps, wrap from sb_param_wrap).  The result is read back from an
 * RGBA32F framebuffer as linear radiance.
 *
 * Shared by examples/gl_sphere.c and tests/test_render_gl.c, so the test
 * checks the code the example runs.  Depends on GL; the library does not. */
#ifndef SB_GL_RENDER_H
#define SB_GL_RENDER_H

#include <stddef.h>

#include "sepbrdf/sepbrdf.h"

typedef struct gl_sphere gl_sphere_t;

/* Create an offscreen GL 3.3 core context.  0 on success; otherwise -1
 * with a message in err. */
int gl_sphere_open(gl_sphere_t **out, char *err, size_t err_size);
void gl_sphere_close(gl_sphere_t *g); /* accepts NULL */
/* "OpenGL 4.5 (Core Profile) Mesa ..., llvmpipe ..." */
const char *gl_sphere_renderer(const gl_sphere_t *g);

/* Render the sphere of `opts` into *out (allocated, sb_image_free) with
 * `snippet`: the text of a sepbrdf.glsl file or of sb_glsl_snippet() for
 * p, its form and SB_TERMS <= the terms of f.  Every term of f is uploaded
 * (layer j = term j); the snippet sums the first SB_TERMS.  0 on success,
 * -1 with a message in err. */
int gl_sphere_render(gl_sphere_t *g, const char *snippet, const sb_factors_t *f, const sb_param_t *p,
                     const sb_render_opts_t *opts, sb_image_t *out, char *err, size_t err_size);

/* The sampler tables of sampler.bin (sepbrdf/sampler.h): width x height
 * texels, `layers` layers, float32 as stored (layer-major, x fastest). */
typedef struct gl_sampler_table {
    size_t width, height, layers;
    const float *data;
} gl_sampler_table_t;

/* Run sb_sample(V, u) of `snippet` (the snippet with the sampler block,
 * sb_glsl_sampler) for the n x n numbers u = ((x + 1/2) / n, (y + 1/2) / n),
 * the factors f as in gl_sphere_render and the tables t as the R32F array
 * sb_cdf.  out receives n * n * 4 floats, pixel (x, y) at (y n + x) * 4:
 * L and pdf, or (0, 0, 0, -1) where sb_sample returned false.  0 on
 * success, -1 with a message in err. */
int gl_sample_grid(gl_sphere_t *g, const char *snippet, const sb_factors_t *f, const sb_param_t *p,
                   const gl_sampler_table_t *t, const double V[3], size_t n, float *out, char *err, size_t err_size);

/* The same setup, evaluating sb_pdf(L, V) at the n x n directions L (3
 * floats each, pixel (x, y) at (y n + x) * 3): out receives n * n * 4
 * floats, the pdf first.  0 on success, -1 with a message in err. */
int gl_pdf_grid(gl_sphere_t *g, const char *snippet, const sb_factors_t *f, const sb_param_t *p,
                const gl_sampler_table_t *t, const double V[3], const float *L, size_t n, float *out, char *err,
                size_t err_size);

#endif
