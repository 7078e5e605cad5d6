/* Factor textures as OpenEXR files through OpenEXRCore (the C API).
 *
 * One single-part scanline file per texture and term, ZIP compressed
 * (lossless).  Pixels are planar in memory: plane c of a texture holds
 * width*height values, texel (x, y) at index y*width + x, which is pixel
 * (x, y) of the data window (0, 0)-(width-1, height-1).
 *
 * Writing goes in two phases so that a failure leaves nothing behind: every
 * file is first written completely under a temporary name in the target
 * folder (".g_00.exr.tmp-PID"), and only when all of them are complete are
 * they renamed; an error in either phase removes this call's temporaries and
 * the files it had already renamed.  Each file is assembled in memory and
 * written with one write() (exr_stream_write, sink_flush): ~10x fewer
 * system calls, and a full disk is reported with its cause and the file's
 * final name (never the temporary's).
 *
 * The pixel conversions are done here, not by the OpenEXR pack/unpack
 * routines, so that rounding is under our control: FLOAT stores (float)v and
 * reads back exactly that value; HALF is rounded to nearest even directly
 * from the double (no double rounding through float).
 *
 * Files: this one holds what writing and reading share (names, messages,
 * paths, channels, the stored precision); exr_write.c writes a set,
 * exr_read.c reads one. */
#include "sepbrdf/exr.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "output/exr_impl.h"
#include "util/internal.h"

/* HALF: stored = value / scale with scale a power of two chosen so that the
 * largest |value| of the texture is stored in [512, 1024).  Dividing by a
 * power of two is exact, so the only error is the half rounding itself:
 * relative 2^-11 (~4.9e-4) for every value down to 2^-24 (~6e-8) times the
 * texture's maximum, absolute 2^-25 scale below that (half subnormals).  The
 * half maximum 65504 is 64x above 1024: no rounding or later filtering of the
 * stored values can overflow.  An all-zero texture gets scale 1.  The scale
 * must itself be a normal float (the header stores it as one), which limits
 * HALF to textures with max |value| in about [1e-35, 1e41]. */
#define HALF_TOP_EXP 10 /* stored max < 2^10 */

/* Attribute names the writer owns; metadata keys may not take them. */
static const char *const fixed_keys[] = {"version", "side", "term", "terms", "channels", "sigma", "scale", "rel_rms"};

int sb_exr_fixed_key_(const char *key) {
    for (size_t i = 0; i < sizeof fixed_keys / sizeof fixed_keys[0]; i++)
        if (strcmp(key, fixed_keys[i]) == 0) return 1;
    return 0;
}

void sb_exr_name(int side, size_t term, char *buf, size_t size) {
    if (buf && size) snprintf(buf, size, "%s_%02zu.exr", side == SB_SIDE_H ? "h" : "g", term);
}

/* ---- OpenEXR messages -------------------------------------------------- */

/* OpenEXRCore prints to stderr unless given a handler, and the library must
 * not print.  The handler keeps the first message since the last reset (the
 * root cause) for our own error text.  Thread-local: contexts of different
 * threads do not mix their messages (the default file streams take the
 * context's user data, so it cannot carry a buffer). */
static _Thread_local char exr_msg[256];

static void exr_msg_handler(exr_const_context_t c, exr_result_t code, const char *msg) {
    (void)c;
    if (exr_msg[0]) return;
    snprintf(exr_msg, sizeof exr_msg, "%s", msg ? msg : exr_get_error_code_as_string(code));
}
void sb_exr_msg_reset_(void) { exr_msg[0] = 0; }
static const char *exr_why(exr_result_t rv) { return exr_msg[0] ? exr_msg : exr_get_error_code_as_string(rv); }

/* Map an OpenEXR failure on `path` to our codes; `fallback` for the rest. */
sb_result_t sb_exr_fail_(sb_context_t *ctx, exr_result_t rv, sb_result_t fallback, const char *path, const char *what) {
    sb_result_t code = fallback;
    if (rv == EXR_ERR_OUT_OF_MEMORY)
        code = SB_ERR_NOMEM;
    else if (rv == EXR_ERR_FILE_ACCESS)
        code = SB_ERR_IO;
    else if (rv == EXR_ERR_WRITE_IO && fallback != SB_ERR_FORMAT)
        code = SB_ERR_IO;
    return sb_error(ctx, code, "%s: %s: %s", path, what, exr_why(rv));
}

exr_context_initializer_t sb_exr_init_(int reading) {
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = exr_msg_handler;
    /* a damaged file is an error, not something to salvage */
    if (reading) init.flags = EXR_CONTEXT_FLAG_DISABLE_CHUNK_RECONSTRUCTION;
    return init;
}

/* ---- paths ------------------------------------------------------------- */

/* "dir/name" or, with tmp, "dir/.name.tmp-PID"; malloc'd. */
char *sb_exr_path_(sb_context_t *ctx, const char *dir, const char *name, int tmp) {
    char suffix[32] = "";
    if (tmp) snprintf(suffix, sizeof suffix, ".tmp-%ld", (long)getpid());
    size_t n = strlen(dir) + strlen(name) + strlen(suffix) + 3;
    char *p = sb_alloc(ctx, n, 1, "exr path");
    if (p) snprintf(p, n, "%s/%s%s%s", dir, tmp ? "." : "", name, suffix);
    return p;
}

/* float from a double that must be finite and within float range. */
int sb_exr_to_float_(double v, float *out) {
    if (!isfinite(v) || fabs(v) > FLT_MAX) return 0;
    *out = (float)v;
    return 1;
}

/* ---- channels ---------------------------------------------------------- */

static const char *const rgb_names[3] = {"R", "G", "B"};

const char *sb_exr_channel_name_(size_t channels, size_t c) { return channels == 1 ? "Y" : rgb_names[c]; }

/* Plane of channel `name` (R, G, B or Y) or -1. */
int sb_exr_channel_plane_(size_t channels, const char *name) {
    for (size_t c = 0; c < channels; c++)
        if (name && strcmp(name, sb_exr_channel_name_(channels, c)) == 0) return (int)c;
    return -1;
}

/* ---- stored precision ---------------------------------------------------- */

/* The largest |value| HALF with a power-of-two float scale holds: stored
 * values below 2^HALF_TOP_EXP, scales normal floats (2^-126 .. 2^127). */
#define HALF_SCALED_MAX ldexp(1, FLT_MAX_EXP - 1 + HALF_TOP_EXP)
#define HALF_SCALED_MIN ldexp(1, FLT_MIN_EXP - 1 + HALF_TOP_EXP - 1)

/* A texture whose largest value, amax, the storage cannot hold, named by
 * its real cause: a later term too small to store has nothing left to
 * carry (the BRDF's numerical rank is exhausted: ask for fewer terms,
 * SB_ERR_RANGE); values beyond both FLOAT and scaled HALF are a BRDF
 * outside the range textures can store (SB_ERR_NUMERIC); a range only one
 * of them holds names the other. */
static sb_result_t not_storable(sb_context_t *ctx, const sb_factors_t *f, size_t term, int half, const char *path,
                                double amax) {
    const char *fmt = half ? "HALF (with a float scale)" : "FLOAT";
    if (amax > FLT_MAX || amax >= HALF_SCALED_MAX) {
        if (!half && amax < HALF_SCALED_MAX)
            return sb_error(ctx, SB_ERR_NUMERIC,
                            "%s: values up to %g are above the FLOAT range (%g); HALF with a "
                            "per-texture scale holds them",
                            path, amax, (double)FLT_MAX);
        return sb_error(ctx, SB_ERR_NUMERIC,
                        "%s: values up to %g are above what %s can store (at most %g): the "
                        "BRDF's values are beyond the range of the textures",
                        path, amax, fmt, half ? HALF_SCALED_MAX : (double)FLT_MAX);
    }
    if (term > 0) {
        double s0 = 0, sj = 0;
        for (size_t c = 0; c < sb_factors_channels(f); c++) {
            s0 = fmax(s0, sb_factors_sigma(f, 0, c));
            sj = fmax(sj, sb_factors_sigma(f, term, c));
        }
        return sb_error(ctx, SB_ERR_RANGE,
                        "%s: term %zu has values of at most %g (sigma %g against %g for the first "
                        "term), below what %s can store: the BRDF's numerical rank is exhausted; ask for at most %zu "
                        "term%s",
                        path, term, amax, sj, s0, fmt, term, term == 1 ? "" : "s");
    }
    if (half && amax >= FLT_TRUE_MIN)
        return sb_error(ctx, SB_ERR_NUMERIC,
                        "%s: values of at most %g are below what HALF with a float scale can "
                        "store (%g); FLOAT stores down to %g",
                        path, amax, HALF_SCALED_MIN, (double)FLT_TRUE_MIN);
    return sb_error(ctx, SB_ERR_NUMERIC,
                    "%s: values of at most %g are below what %s can store (%g): the BRDF's "
                    "values are below the range of the textures",
                    path, amax, fmt, half ? HALF_SCALED_MIN : (double)FLT_TRUE_MIN);
}

/* Codec of one texture: checks that every value can be stored and picks
 * the HALF scale.  Refuses non-finite values, values beyond FLOAT, a
 * maximum HALF with a float scale cannot hold, and a texture whose largest
 * value would be stored as zero (a whole term flushed away: FLOAT below
 * 2^-149), through not_storable().  Single texels far below their
 * texture's maximum may still flush to zero; sb_factors_quantize counts
 * them. */
/* max |t[i]| over n values, and *z the sum of 0 t[i] (NaN where a value is
 * not finite): two lanes, the maximum exact in any order. */
static double abs_max(const double *t, size_t n, double *z) {
    size_t i = 0;
    double m = 0, zs = 0;
#if defined(__SSE2__)
    __m128d vm = _mm_setzero_pd(), vz = _mm_setzero_pd(), sign = _mm_set1_pd(-0.0);
    for (; i + 2 <= n; i += 2) {
        __m128d x = _mm_loadu_pd(t + i);
        vz = _mm_add_pd(vz, _mm_mul_pd(x, _mm_setzero_pd()));
        vm = _mm_max_pd(vm, _mm_andnot_pd(sign, x));
    }
    double v[4];
    _mm_storeu_pd(v, vm), _mm_storeu_pd(v + 2, vz);
    m = v[0] > v[1] ? v[0] : v[1], zs = v[2] + v[3];
#endif
    for (; i < n; i++)
        zs += t[i] * 0, m = fabs(t[i]) > m ? fabs(t[i]) : m;
    *z += zs;
    return m;
}

sb_result_t sb_exr_texture_codec_(sb_context_t *ctx, const sb_factors_t *f, int side, size_t term, int half,
                                  const char *path, codec_t *out) {
    size_t C = sb_factors_channels(f), w, h;
    sb_factors_size(f, side, &w, &h);
    size_t n = w * h;
    double amax = 0;
    for (size_t c = 0; c < C; c++) {
        const double *t = sb_factors_tex_const(f, side, term, c);
        double z = 0, m = abs_max(t, n, &z);
        for (size_t i = 0; z != 0 && i < n; i++) /* a value not finite: find the first for the message */
            if (!isfinite(t[i]))
                return sb_error(ctx, SB_ERR_NUMERIC, "%s: value %g at texel (%zu, %zu) of channel %s is not finite",
                                path, t[i], i % w, i / w, sb_exr_channel_name_(C, c));
        amax = m > amax ? m : amax;
    }
    out->half = half;
    out->scale = 1;
    if (!half && amax > FLT_MAX) return not_storable(ctx, f, term, half, path, amax);
    if (half && amax > 0) {
        int e;
        frexp(amax, &e); /* amax < 2^e */
        if (e - HALF_TOP_EXP > FLT_MAX_EXP - 1 || e - HALF_TOP_EXP < FLT_MIN_EXP - 1)
            return not_storable(ctx, f, term, half, path, amax);
        out->scale = ldexp(1, e - HALF_TOP_EXP);
    }
    if (amax > 0 && texel_stored(out, amax) == 0) return not_storable(ctx, f, term, half, path, amax);
    return SB_OK;
}

/* ---- stored precision of whole factors ---------------------------------- */

sb_result_t sb_exr_texture_scale(sb_context_t *ctx, const sb_factors_t *f, int side, size_t term,
                                 const sb_exr_opts_t *opts, double *scale) {
    if (!f || !scale || (side != SB_SIDE_G && side != SB_SIDE_H) || term >= sb_factors_terms(f))
        return sb_error(ctx, SB_ERR_ARG, "texture scale: missing argument or texture out of range");
    char name[64];
    codec_t cd;
    sb_exr_name(side, term, name, sizeof name);
    sb_result_t r = sb_exr_texture_codec_(ctx, f, side, term, opts && opts->half, name, &cd);
    if (r == SB_OK) *scale = cd.scale;
    return r;
}

sb_result_t sb_exr_term_scales(sb_context_t *ctx, const sb_factors_t *f, const sb_exr_opts_t *opts, double *scales) {
    if (!f || !scales) return sb_error(ctx, SB_ERR_ARG, "term scales: missing argument");
    for (size_t j = 0; j < sb_factors_terms(f); j++) {
        double sg = 1, sh = 1;
        sb_result_t r = sb_exr_texture_scale(ctx, f, SB_SIDE_G, j, opts, &sg);
        if (r == SB_OK) r = sb_exr_texture_scale(ctx, f, SB_SIDE_H, j, opts, &sh);
        if (r != SB_OK) return r;
        scales[j] = sg * sh;
    }
    return SB_OK;
}

sb_result_t sb_factors_quantize(sb_context_t *ctx, const sb_factors_t *f, const sb_exr_opts_t *opts,
                                sb_factors_t **stored, sb_quantize_info_t *info) {
    if (!stored) return sb_error(ctx, SB_ERR_ARG, "quantize: no output pointer");
    *stored = NULL;
    if (!f) return sb_error(ctx, SB_ERR_ARG, "quantize: no factors");
    if (info) memset(info, 0, sizeof *info);
    int half = opts && opts->half;
    size_t J = sb_factors_terms(f), C = sb_factors_channels(f), w[2], h[2];
    for (int s = 0; s < 2; s++)
        sb_factors_size(f, s, &w[s], &h[s]);
    sb_factors_t *q = NULL;
    sb_result_t r = sb_factors_create(ctx, J, C, w[0], h[0], w[1], h[1], &q);
    if (r != SB_OK) return r;
    for (size_t k = 0; k < 2 * J && r == SB_OK; k++) {
        int side = (int)(k % 2);
        size_t term = k / 2, n = w[side] * h[side];
        char name[64];
        sb_exr_name(side, term, name, sizeof name);
        codec_t cd;
        if ((r = sb_exr_texture_codec_(ctx, f, side, term, half, name, &cd)) != SB_OK) break;
        for (size_t c = 0; c < C; c++) {
            const double *t = sb_factors_tex_const(f, side, term, c);
            double *d = sb_factors_tex(q, side, term, c);
            size_t flushed = 0;
            if (!cd.half && cd.scale == 1) /* FLOAT: texel_stored's own operations, in a loop that vectorises */
                for (size_t i = 0; i < n; i++) {
                    float v = (float)t[i];
                    d[i] = (double)v;
                    flushed += t[i] != 0 && v == 0;
                }
            else
                for (size_t i = 0; i < n; i++) {
                    d[i] = texel_stored(&cd, t[i]);
                    flushed += t[i] != 0 && d[i] == 0;
                }
            if (info) {
                info->texels += n;
                info->flushed += flushed;
            }
        }
    }
    /* sigma as the header stores it (write_attrs refuses the same values) */
    for (size_t j = 0; j < J && r == SB_OK; j++)
        for (size_t c = 0; c < C; c++) {
            float s;
            if (!sb_exr_to_float_(sb_factors_sigma(f, j, c), &s)) {
                double v = sb_factors_sigma(f, j, c);
                r = sb_error(ctx, isfinite(v) ? SB_ERR_RANGE : SB_ERR_NUMERIC,
                             "quantize: sigma %g of term %zu is not representable as a float", v, j);
                break;
            }
            sb_factors_set_sigma(q, j, c, s);
        }
    for (size_t i = 0; i < sb_factors_meta_count(f) && r == SB_OK; i++) {
        const char *key, *value;
        sb_factors_meta_at(f, i, &key, &value);
        if (sb_factors_set_meta(q, key, value) != SB_OK) r = sb_error(ctx, SB_ERR_NOMEM, "quantize: out of memory");
    }
    if (r != SB_OK) {
        sb_factors_destroy(q);
        return r;
    }
    /* the errors stay those of the fit f (see exr.h) */
    const sb_factor_errors_t *e = sb_factors_errors(f);
    sb_factor_errors_t *eq = sb_factors_errors_mut(q);
    memcpy(eq->rel_rms, e->rel_rms, J * 4 * sizeof(double));
    memcpy(eq->max_abs, e->max_abs, J * 4 * sizeof(double));
    memcpy(eq->norm, e->norm, sizeof eq->norm);
    eq->terms = J;
    *stored = q;
    return SB_OK;
}
