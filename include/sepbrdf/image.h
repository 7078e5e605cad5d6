/* sepbrdf: linear RGB images, tone mapping, image comparison and PNG output
 * (renders, texture previews).
 *
 * An image holds linear radiance, 3 doubles per pixel, rows top to bottom
 * (pixel (x, y) at index y * width + x), and a coverage mask (1 where the
 * rendered object covers the pixel centre).
 *
 * Display encoding of a radiance x (one channel):
 *     d = oetf(op(exposure * x)),  op = clamp01 (min(max(x, 0), 1)) or
 *     Reinhard (x / (1 + x), x >= 0),  oetf = the sRGB transfer function
 *         oetf(u) = 12.92 u                 for u <= 0.0031308
 *                 = 1.055 u^(1/2.4) - 0.055 otherwise,
 * so d lies in [0, 1]; PNG stores round(255 d).
 *
 * Comparison (sb_image_compare) works on the pixels either image covers:
 *     rmse_linear = sqrt(mean over pixels and channels of (a - b)^2)
 *     rmse        = the same on display values d (not quantised to 8 bit)
 *     psnr        = 10 log10(1 / rmse^2) dB (peak 1), +inf when equal. */
#ifndef SEPBRDF_IMAGE_H
#define SEPBRDF_IMAGE_H

#include "common.h"
#include "factor.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sb_image {
    size_t width, height;
    double *rgb;         /* width * height * 3, linear RGB */
    unsigned char *mask; /* width * height, 1 = covered */
} sb_image_t;

/* Allocate a zeroed image (mask all 0).  Errors: SB_ERR_ARG (NULL or empty
 * size), SB_ERR_OVERFLOW, SB_ERR_NOMEM. */
SB_API sb_result_t sb_image_alloc(sb_context_t *ctx, size_t width, size_t height, sb_image_t *out);
SB_API void sb_image_free(sb_image_t *img); /* accepts NULL and zeroed structs; zeroes it */

typedef enum sb_tonemap_op { SB_TONEMAP_CLAMP = 0, SB_TONEMAP_REINHARD, SB_TONEMAP_COUNT_ } sb_tonemap_op_t;

/* "clamp", "reinhard"; SB_ERR_UNKNOWN otherwise (NULL name included),
 * SB_ERR_ARG for a NULL out. */
SB_API sb_result_t sb_tonemap_parse(const char *name, sb_tonemap_op_t *out);
SB_API const char *sb_tonemap_name(sb_tonemap_op_t op);

typedef struct sb_tonemap {
    double exposure;    /* multiplies radiance first; 0 = 1 */
    sb_tonemap_op_t op; /* default SB_TONEMAP_CLAMP */
} sb_tonemap_t;

/* sRGB OETF of a linear value clamped to [0, 1]. */
SB_API double sb_srgb_oetf(double u);
/* Display value d in [0, 1] of one linear channel (header formula); tm may
 * be NULL (exposure 1, clamp).  NaN maps to 0. */
SB_API double sb_tonemap_apply(const sb_tonemap_t *tm, double x);

typedef struct sb_image_diff {
    size_t pixels;      /* pixels compared (either mask set) */
    double rmse_linear; /* RMS difference of linear radiance */
    double max_linear;  /* largest |a - b| of linear radiance */
    double rmse;        /* RMS difference of display values */
    double psnr;        /* dB on display values, peak 1; +inf if rmse == 0 */
} sb_image_diff_t;

/* Largest channel value over the covered pixels (all pixels if mask is
 * NULL); 0 for an empty or all-black image.  NaN is skipped. */
SB_API double sb_image_max(const sb_image_t *img);
/* Log-average luminance (Reinhard et al. 2002's key) over the covered
 * pixels: exp(mean log(delta + Y)), Y = 0.2126 R + 0.7152 G + 0.0722 B
 * (negative channels as 0), delta = 1e-4 of the largest Y so black pixels
 * count without sending it to 0; 0 for an empty or all-black image. */
SB_API double sb_image_log_average(const sb_image_t *img);

/* Compare two images of one size (header).  Errors: SB_ERR_ARG (NULL, size
 * mismatch). */
SB_API sb_result_t sb_image_compare(sb_context_t *ctx, const sb_image_t *a, const sb_image_t *b, const sb_tonemap_t *tm,
                                    sb_image_diff_t *out);

/* Write an 8-bit RGB PNG (rows top to bottom) under the temporary name
 * PATH.tmp-PID, then rename.  `text` is NULL or a NULL-terminated list of key, value, key,
 * value ... stored as PNG tEXt chunks.  Errors: SB_ERR_ARG, SB_ERR_IO. */
SB_API sb_result_t sb_png_write_rgb8(sb_context_t *ctx, const char *path, size_t width, size_t height,
                                     const unsigned char *rgb, const char *const *text);

/* One image, display-encoded (header); uncovered pixels black. */
SB_API sb_result_t sb_image_write_png(sb_context_t *ctx, const char *path, const sb_image_t *img,
                                      const sb_tonemap_t *tm);

/* A comparison strip, three panels left to right with 4-pixel gaps:
 *     a | b | min(1, diff_scale * |d(a) - d(b)|) per channel,
 * d the display values, so the third panel shows the display error
 * magnified diff_scale times (black = equal).  Images of one size. */
SB_API sb_result_t sb_image_write_strip_png(sb_context_t *ctx, const char *path, const sb_image_t *a,
                                            const sb_image_t *b, const sb_tonemap_t *tm, double diff_scale);

/* Texture previews: for every term j and side, one PNG
 *     DIR/g_JJ_scale-S.png, DIR/h_JJ_scale-S.png,  S = "%.2e" of max |value|
 * with the channels (R, G, B, or Y) side by side, texel (x, y) at the
 * panel's (x, y) magnified by an integer factor (nearest texel), each value
 * v mapped by a diverging blue-white-red colour map of v / S: -S blue,
 * 0 white, +S red.  S is also stored as tEXt "sepbrdf.scale".  Stale
 * previews of the same texture with another S in DIR are removed. */
SB_API sb_result_t sb_factors_write_previews(sb_context_t *ctx, const sb_factors_t *f, const char *dir);

/* The diverging colour map: u in [-1, 1] -> 8-bit sRGB (clamped). */
SB_API void sb_colormap_diverging(double u, unsigned char rgb[3]);

#ifdef __cplusplus
}
#endif
#endif
