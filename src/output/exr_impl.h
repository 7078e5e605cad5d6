/* Private: shared by the EXR files of the factor textures: exr.c (names,
 * OpenEXR messages, paths, channels, stored precision), exr_write.c and
 * exr_read.c. */
#ifndef SEPBRDF_EXR_IMPL_H
#define SEPBRDF_EXR_IMPL_H

#include <math.h>
#include <openexr.h>
#include <stdint.h>

#include "sepbrdf/exr.h"

#define PREFIX "sepbrdf."
#define PREFIX_LEN 8

/* 1 if key is an attribute name the writer owns (metadata may not take it). */
int sb_exr_fixed_key_(const char *key);

/* OpenEXR messages: forget the last one (before a call whose failure is
 * reported); map a failure on path to our codes, fallback for the rest. */
void sb_exr_msg_reset_(void);
sb_result_t sb_exr_fail_(sb_context_t *ctx, exr_result_t rv, sb_result_t fallback, const char *path, const char *what);
/* The context initializer: our message handler; reading refuses damaged chunks. */
exr_context_initializer_t sb_exr_init_(int reading);

/* "dir/name" or, with tmp, "dir/.name.tmp-PID"; malloc'd. */
char *sb_exr_path_(sb_context_t *ctx, const char *dir, const char *name, int tmp);
/* float from a double that must be finite and within float range; 0 if not. */
int sb_exr_to_float_(double v, float *out);
/* Channel c's name (R, G, B, or Y for one channel); the plane of a name or -1. */
const char *sb_exr_channel_name_(size_t channels, size_t c);
int sb_exr_channel_plane_(size_t channels, const char *name);

/* IEEE binary16 from a double, round to nearest even; |x| < 65504 assumed
 * (the scale rule keeps stored values below 1024). */
static inline uint16_t half_from_double(double x) {
    uint16_t sign = signbit(x) ? 0x8000u : 0;
    double a = fabs(x);
    if (a < 0x1p-14) /* subnormal: units of 2^-24; 1024 carries into exponent 1 */
        return (uint16_t)(sign | (uint16_t)nearbyint(a * 0x1p24));
    int e;
    frexp(a, &e);                           /* a in [2^(e-1), 2^e) */
    double m = nearbyint(ldexp(a, 11 - e)); /* 11 significant bits: [1024, 2048] */
    int E = e - 1;
    if (m == 2048) {
        m = 1024;
        E++;
    }
    if (E > 15) return (uint16_t)(sign | 0x7c00u);
    return (uint16_t)(sign | (uint16_t)((E + 15) << 10) | (uint16_t)(m - 1024));
}

static inline double half_to_double(uint16_t h) {
    int E = (h >> 10) & 31, m = h & 1023;
    double a;
    if (E == 0)
        a = ldexp(m, -24);
    else if (E == 31)
        a = m ? NAN : INFINITY;
    else
        a = ldexp(m + 1024, E - 25);
    return (h & 0x8000u) ? -a : a;
}

/* Stored precision: the one place that decides what a texel becomes in a file: the writer
 * encodes through it, the reader decodes through it, and
 * sb_factors_quantize() does both, so the "stored" factors it returns are
 * bit for bit what a write followed by a read gives. */

typedef struct codec {
    int half;     /* HALF bits, else FLOAT */
    double scale; /* stored = value / scale (a power of two; 1 for FLOAT) */
} codec_t;

static inline void texel_encode(const codec_t *k, double v, void *plane, size_t i) {
    if (k->half)
        ((uint16_t *)plane)[i] = half_from_double(v / k->scale);
    else
        ((float *)plane)[i] = (float)v;
}

static inline double texel_decode(const codec_t *k, const void *plane, size_t i) {
    double v = k->half ? half_to_double(((const uint16_t *)plane)[i]) : (double)((const float *)plane)[i];
    return v * k->scale;
}

/* The value a texel has after a write and a read. */
static inline double texel_stored(const codec_t *k, double v) {
    union {
        uint16_t h;
        float f;
    } bits;
    texel_encode(k, v, &bits, 0);
    return texel_decode(k, &bits, 0);
}

/* Codec of one texture (see exr.c): every value storable, the HALF scale. */
sb_result_t sb_exr_texture_codec_(sb_context_t *ctx, const sb_factors_t *f, int side, size_t term, int half,
                                  const char *path, codec_t *out);

#endif
