/* sepbrdf: factor textures as OpenEXR files (OpenEXRCore, C API only).
 *
 * Layout: one scanline EXR per texture of each term, in one folder:
 *     g_00.exr, h_00.exr, g_01.exr, h_01.exr, ...   (term index, 0-based)
 * Channels R, G, B (or Y for a single-channel factorisation), FLOAT (32 bit)
 * by default, HALF with per-term scales when asked.  Width x height as the
 * parameterisation's texture size; texel (x, y) of the factor is pixel
 * (x, y) of the image (data window starting at 0, 0).
 *
 * Header attributes (all files of one factorisation carry the same):
 *   sepbrdf.version (string), sepbrdf.side ("g"|"h"), sepbrdf.term (int),
 *   sepbrdf.terms (int J), sepbrdf.channels (int), sepbrdf.sigma
 *   (floatvector, sigma_j per channel of this term), sepbrdf.scale (float:
 *   stored = value / scale; 1 for FLOAT), and every factors metadata key as a
 *   string attribute "sepbrdf.<key>" (param, source, form, method, ...), and
 *   sepbrdf.rel_rms (floatvector: overall relative RMS error per J).  The
 *   fixed names above are reserved: a metadata key equal to one of them is
 *   refused with SB_ERR_ARG. */
#ifndef SEPBRDF_EXR_H
#define SEPBRDF_EXR_H

#include "common.h"
#include "factor.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sb_exr_opts {
    int half; /* store HALF with a per-term scale instead of FLOAT */
} sb_exr_opts_t;

/* Write all terms of f into directory `dir` (must exist).  Each file is
 * written under a temporary name and renamed when complete: every file of
 * the set is first written as "DIR/.NAME.tmp-PID" (NAME from sb_exr_name,
 * PID the writing process), then all are renamed.  The names are part of
 * the interface, so a program interrupted by a signal can remove them.
 * Every texture is checked before the first file is created; messages
 * name DIR/NAME.  Errors: SB_ERR_ARG, SB_ERR_NUMERIC (a non-finite texel,
 * or values beyond what FLOAT, or HALF with a float scale, can store: the
 * BRDF is outside the range of textures), SB_ERR_RANGE (a later term too
 * small to store: J is above the BRDF's numerical rank; sizes beyond EXR's
 * limits), SB_ERR_IO, SB_ERR_NOMEM. */
SB_API sb_result_t sb_factors_write_exr(sb_context_t *ctx, const sb_factors_t *f, const char *dir,
                                        const sb_exr_opts_t *opts);

/* Read the factors in `dir` written by sb_factors_write_exr (the number of
 * terms from the files' headers).  Values are the stored ones, exactly. */
SB_API sb_result_t sb_factors_read_exr(sb_context_t *ctx, const char *dir, sb_factors_t **out);

/* Whether one factor texture file (g_KK.exr or h_KK.exr) reads as
 * sb_factors_read_exr would read it: its header, and every chunk of its
 * pixels decoded and finite.  SB_OK, else the reader's error (SB_ERR_IO,
 * SB_ERR_FORMAT, SB_ERR_OVERFLOW, SB_ERR_NOMEM, SB_ERR_ARG) with its
 * message naming the file. */
SB_API sb_result_t sb_exr_texture_check(sb_context_t *ctx, const char *path);

/* The sizes of the set of factor textures in `dir` as written, read back
 * from the files: texel_bytes = sum over g_KK.exr, h_KK.exr (K < the
 * terms of g_00.exr's header) of width * height * channels * (4 FLOAT, 2
 * HALF), what the textures take in GPU memory; file_bytes = the files'
 * sizes (headers and attributes included).  Errors: those of
 * sb_factors_read_exr's header checks (SB_ERR_IO, SB_ERR_FORMAT), SB_ERR_ARG. */
SB_API sb_result_t sb_exr_set_bytes(sb_context_t *ctx, const char *dir, size_t *texel_bytes, size_t *file_bytes);

/* What sb_factors_quantize found. */
typedef struct sb_quantize_info {
    size_t texels;  /* texels of the kept terms, both sides, every channel */
    size_t flushed; /* nonzero texels stored as zero (far below their texture's maximum) */
} sb_quantize_info_t;

/* The factors exactly as sb_factors_write_exr followed by
 * sb_factors_read_exr would return them, without touching a file: every
 * texel rounded through the same code as the writer (FLOAT: (float)v; HALF:
 * the texture's power-of-two scale, then round to nearest even), sigma
 * rounded to float.  Metadata is copied; the errors are f's (those of the
 * double fit): measure the stored precision with
 * sb_factors_errors_against().  *stored is new; info may be NULL.
 * Errors: the writer's (SB_ERR_NUMERIC for a non-finite texel or values
 * beyond the format's range, including a first term whose largest value
 * would be stored as 0; SB_ERR_RANGE for a later term stored as 0, J above
 * the numerical rank), SB_ERR_NOMEM. */
SB_API sb_result_t sb_factors_quantize(sb_context_t *ctx, const sb_factors_t *f, const sb_exr_opts_t *opts,
                                       sb_factors_t **stored, sb_quantize_info_t *info);

/* The per-term factor a shader applies to the stored texels: scales[j] =
 * scale(g_j) * scale(h_j) with each texture's sepbrdf.scale as
 * sb_factors_write_exr(opts) chooses it (all 1 for FLOAT), so that
 * sum_j stored_g_j stored_h_j scales[j] is the reconstruction.  The GLSL
 * snippet takes them as sb_scale (sb_glsl_snippet's `scales`).  scales
 * receives sb_factors_terms(f) values.  Errors: the writer's (SB_ERR_NUMERIC,
 * SB_ERR_RANGE), SB_ERR_ARG. */
SB_API sb_result_t sb_exr_term_scales(sb_context_t *ctx, const sb_factors_t *f, const sb_exr_opts_t *opts,
                                      double *scales);

/* The storage scale of texture (side, term) alone (its sepbrdf.scale: 1
 * for FLOAT), as sb_factors_write_exr(opts) chooses it; the sampler's
 * table stores g's integrals in these units (sampler.h).  Errors: those of
 * sb_exr_term_scales. */
SB_API sb_result_t sb_exr_texture_scale(sb_context_t *ctx, const sb_factors_t *f, int side, size_t term,
                                        const sb_exr_opts_t *opts, double *scale);

/* File name of one texture: "g_00.exr" etc. written into buf. */
SB_API void sb_exr_name(int side, size_t term, char *buf, size_t size);

/* A plain RGB float image (the vndf layout's tables, vndf.exr): rgb holds
 * width x height x 3 floats, row-major; written whole under a temporary
 * name and renamed, with the string attributes sepbrdf.version and
 * sepbrdf.kind = SB_EXR_KIND_VNDF_TABLES (what `sepbrdf info` knows it by).  Reading gives a malloc'ed array for the
 * caller to free; SB_ERR_FORMAT for a file that is not three float channels R, G, B. */
#define SB_EXR_KIND_VNDF_TABLES "vndf tables"
SB_API sb_result_t sb_exr_write_rgb(sb_context_t *ctx, const char *path, size_t width, size_t height, const float *rgb);
SB_API sb_result_t sb_exr_read_rgb(sb_context_t *ctx, const char *path, size_t *width, size_t *height, float **rgb);

#ifdef __cplusplus
}
#endif
#endif
