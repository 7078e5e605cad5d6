/* sepbrdf: the GLSL snippet that evaluates the factors in a shader.
 *
 * The snippet (GLSL 3.30 core) declares
 *     uniform sampler2DArray sb_g;   // layer j = g_j, RGB
 *     uniform sampler2DArray sb_h;   // layer j = h_j, RGB
 *     vec3 sb_brdf(vec3 L, vec3 V);  // f_r(L, V), L and V unit, tangent frame
 * and computes sum_j g_j(L) h_j(V) with the same direction -> texture
 * coordinate mapping and texel-centre convention as sb_factors_eval(), then
 * divides back the factored form (cos theta_i, cos theta_o). */
#ifndef SEPBRDF_GLSL_H
#define SEPBRDF_GLSL_H

#include "common.h"
#include "factor.h"
#include "param.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The generic part shipped with the tool (data/sepbrdf.glsl). */
SB_API const char *sb_glsl_library(void);

/* Most terms a snippet declares: bounds its size (32 bytes a term).  A
 * shader binds at most GL_MAX_ARRAY_TEXTURE_LAYERS of them (at least 256;
 * 2048 since GL 4.5). */
#define SB_GLSL_MAX_TERMS (1 << 20)

/* Full snippet for one factorisation: #defines (SB_TERMS, form, scales
 * (NULL: all 1, else `terms` values)), the parameterisation's sb_coords()
 * and the generic evaluation.  The returned string is malloc'ed; the
 * caller frees it.  NULL on no memory, a NULL p, an unknown form or terms
 * outside 1..SB_GLSL_MAX_TERMS. */
SB_API char *sb_glsl_snippet(const sb_param_t *p, sb_form_t form, size_t terms, const double *scales);

/* Write the snippet to `path` (temporary name "PATH.tmp-PID", then rename).
 * Errors: SB_ERR_ARG (NULL path or p, unknown form), SB_ERR_RANGE (terms
 * outside 1..SB_GLSL_MAX_TERMS), SB_ERR_NOMEM, SB_ERR_IO. */
SB_API sb_result_t sb_glsl_write(sb_context_t *ctx, const char *path, const sb_param_t *p, sb_form_t form, size_t terms,
                                 const double *scales);

/* The sampler block for non-negative factors (data/sepbrdf_sample.glsl,
 * sampler.h): #defines SB_SAMPLE_CH (channels, 1 or 3), SB_HALF_ROWS,
 * SB_COL_SAMPLE, the parameterisation's sb_row_dir() (SB_CAP_COL_SAMPLE:
 * sb_col_dir() and sb_col_density()) and
 *     uniform sampler2DArray sb_cdf;   // sampler.bin, R32F
 *     bool  sb_sample(vec3 V, vec2 u, out vec3 L, out float pdf);
 *     float sb_pdf(vec3 L, vec3 V);
 * to be placed after the snippet of the same factorisation.  malloc'ed;
 * NULL on no memory, a NULL p, channels not 1 or 3, or a layout without a
 * sampler (vh, rv: their rows are views, not light directions). */
SB_API char *sb_glsl_sampler(const sb_param_t *p, size_t channels);

/* sb_glsl_write with the sampler block appended (the file `sepbrdf factor`
 * writes for non-negative factors).  Errors: sb_glsl_write's (SB_ERR_ARG
 * for any argument it cannot make a snippet of). */
SB_API sb_result_t sb_glsl_write_sampled(sb_context_t *ctx, const char *path, const sb_param_t *p, sb_form_t form,
                                         size_t terms, const double *scales, size_t channels);

/* ---- the snippet in other shading languages ----
 * Languages by name, a registry: "glsl" (the snippet itself), "hlsl"
 * (HLSL, shader model 5.0 and later; file sepbrdf.hlsl), "msl" (the Metal
 * Shading Language 2.0 and later; sepbrdf.metal) and "wgsl" (WebGPU;
 * sepbrdf.wgsl).  Count, name, file
 * extension of language k ("?" out of range), and the index of a name
 * (-1 if none). */
SB_API size_t sb_shader_lang_count(void);
SB_API const char *sb_shader_lang_name(size_t k);
SB_API const char *sb_shader_lang_ext(size_t k);
SB_API int sb_shader_lang_find(const char *name);
/* A comma list of language names ("hlsl,msl"; "all": every one) as bits
 * 1 << k in *mask (may be NULL), GLSL's always set; NULL or "" gives GLSL
 * alone.  SB_ERR_UNKNOWN, naming the word, for a name not in the registry
 * or an empty item ("hlsl,", ",hlsl"). */
SB_API sb_result_t sb_shader_lang_list(sb_context_t *ctx, const char *list, unsigned *mask);

/* The snippet text `glsl` (sb_glsl_snippet, optionally followed by
 * sb_glsl_sampler) in language `lang`: the same functions (sb_brdf, and
 * sb_sample / sb_pdf with the sampler block), coordinate code, warps and
 * constants, with the language's texture bindings stated in a header
 * comment (HLSL: registers t0/s0 sb_g, t1/s1 sb_h, t2 sb_cdf; MSL: the
 * functions are members of `struct sb_shader`, made from the textures and
 * samplers; WGSL: @group(0) bindings 0..5, out parameters as pointers).
 * malloc'ed; NULL for a NULL text, an unknown language or no memory, and
 * for WGSL also for a top-level declaration outside the subset.  Only the
 * GLSL subset the library writes is translated; other text gives some
 * output (or NULL), never a crash. */
SB_API char *sb_shader_translate(const char *glsl, const char *lang);

#ifdef __cplusplus
}
#endif
#endif
