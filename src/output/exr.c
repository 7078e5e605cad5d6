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
 * from the double (no double rounding through float). */
#include "sepbrdf/exr.h"

#include <assert.h>
#include <errno.h>
#include <fcntl.h>
#include <float.h>
#include <math.h>
#include <openexr.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "sepbrdf/outset.h"
#include "util/internal.h"

#define PREFIX "sepbrdf."
#define PREFIX_LEN 8

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

static int is_fixed_key(const char *key) {
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
static void exr_msg_reset(void) { exr_msg[0] = 0; }
static const char *exr_why(exr_result_t rv) { return exr_msg[0] ? exr_msg : exr_get_error_code_as_string(rv); }

/* The writer's stream: a file is assembled in memory (OpenEXR writes its
 * header in many small pieces and seeks back for the offset table) and
 * written by sink_flush with one write(), where a full disk or the file
 * size limit is found with its errno. */
typedef struct exr_sink {
    uint8_t *buf;
    size_t len, cap;
} exr_sink_t;

static int64_t exr_stream_write(exr_const_context_t c, void *user, const void *buf, uint64_t sz, uint64_t off,
                                exr_stream_error_func_ptr_t error_cb) {
    exr_sink_t *k = user;
    if (off > SIZE_MAX / 4 || sz > SIZE_MAX / 4) {
        error_cb(c, EXR_ERR_OUT_OF_MEMORY, "file too large");
        return -1;
    }
    size_t end = (size_t)(off + sz);
    if (end > k->cap) {
        size_t cap = k->cap ? k->cap : 65536;
        while (cap < end)
            cap *= 2;
        uint8_t *b = realloc(k->buf, cap);
        if (!b) {
            error_cb(c, EXR_ERR_OUT_OF_MEMORY, "out of memory for a %zu-byte file", end);
            return -1;
        }
        k->buf = b;
        k->cap = cap;
    }
    if (off > k->len) memset(k->buf + k->len, 0, (size_t)off - k->len);
    memcpy(k->buf + off, buf, (size_t)sz);
    if (end > k->len) k->len = end;
    return (int64_t)sz;
}

/* The assembled file into `tmp`; messages name `path`. */
static sb_result_t sink_flush(sb_context_t *ctx, const exr_sink_t *k, const char *tmp, const char *path) {
    int fd = open(tmp, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666), e = fd < 0 ? errno : 0;
    for (size_t done = 0; !e && done < k->len;) {
        ssize_t n = write(fd, k->buf + done, k->len - done);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0)
            e = n < 0 ? errno : ENOSPC;
        else
            done += (size_t)n;
    }
    if (fd >= 0 && close(fd) != 0 && !e) e = errno;
    return e ? sb_error(ctx, SB_ERR_IO, "%s: cannot write: %s", path, sb_io_why(e)) : SB_OK;
}

/* Map an OpenEXR failure on `path` to our codes; `fallback` for the rest. */
static sb_result_t exr_fail(sb_context_t *ctx, exr_result_t rv, sb_result_t fallback, const char *path,
                            const char *what) {
    sb_result_t code = fallback;
    if (rv == EXR_ERR_OUT_OF_MEMORY)
        code = SB_ERR_NOMEM;
    else if (rv == EXR_ERR_FILE_ACCESS)
        code = SB_ERR_IO;
    else if (rv == EXR_ERR_WRITE_IO && fallback != SB_ERR_FORMAT)
        code = SB_ERR_IO;
    return sb_error(ctx, code, "%s: %s: %s", path, what, exr_why(rv));
}

static exr_context_initializer_t exr_init(int reading) {
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = exr_msg_handler;
    /* a damaged file is an error, not something to salvage */
    if (reading) init.flags = EXR_CONTEXT_FLAG_DISABLE_CHUNK_RECONSTRUCTION;
    return init;
}

/* ---- half floats ------------------------------------------------------- */

/* IEEE binary16 from a double, round to nearest even; |x| < 65504 assumed
 * (the scale rule keeps stored values below 1024). */
static uint16_t half_from_double(double x) {
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

static double half_to_double(uint16_t h) {
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

/* ---- paths ------------------------------------------------------------- */

/* "dir/name" or, with tmp, "dir/.name.tmp-PID"; malloc'd. */
static char *make_path(sb_context_t *ctx, const char *dir, const char *name, int tmp) {
    char suffix[32] = "";
    if (tmp) snprintf(suffix, sizeof suffix, ".tmp-%ld", (long)getpid());
    size_t n = strlen(dir) + strlen(name) + strlen(suffix) + 3;
    char *p = sb_alloc(ctx, n, 1, "exr path");
    if (p) snprintf(p, n, "%s/%s%s%s", dir, tmp ? "." : "", name, suffix);
    return p;
}

/* float from a double that must be finite and within float range. */
static int to_float(double v, float *out) {
    if (!isfinite(v) || fabs(v) > FLT_MAX) return 0;
    *out = (float)v;
    return 1;
}

/* ---- write ------------------------------------------------------------- */

static const char *const rgb_names[3] = {"R", "G", "B"};

static const char *channel_name(size_t channels, size_t c) { return channels == 1 ? "Y" : rgb_names[c]; }

/* Plane of channel `name` (R, G, B or Y) or -1. */
static int channel_plane(size_t channels, const char *name) {
    for (size_t c = 0; c < channels; c++)
        if (name && strcmp(name, channel_name(channels, c)) == 0) return (int)c;
    return -1;
}

/* ---- stored precision ------------------------------------------------
 * The one place that decides what a texel becomes in a file: the writer
 * encodes through it, the reader decodes through it, and
 * sb_factors_quantize() does both, so the "stored" factors it returns are
 * bit for bit what a write followed by a read gives. */

typedef struct codec {
    int half;     /* HALF bits, else FLOAT */
    double scale; /* stored = value / scale (a power of two; 1 for FLOAT) */
} codec_t;

static void texel_encode(const codec_t *k, double v, void *plane, size_t i) {
    if (k->half)
        ((uint16_t *)plane)[i] = half_from_double(v / k->scale);
    else
        ((float *)plane)[i] = (float)v;
}

static double texel_decode(const codec_t *k, const void *plane, size_t i) {
    double v = k->half ? half_to_double(((const uint16_t *)plane)[i]) : (double)((const float *)plane)[i];
    return v * k->scale;
}

/* The value a texel has after a write and a read. */
static double texel_stored(const codec_t *k, double v) {
    union {
        uint16_t h;
        float f;
    } bits;
    texel_encode(k, v, &bits, 0);
    return texel_decode(k, &bits, 0);
}

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
static sb_result_t texture_codec(sb_context_t *ctx, const sb_factors_t *f, int side, size_t term, int half,
                                 const char *path, codec_t *out) {
    size_t C = sb_factors_channels(f), w, h;
    sb_factors_size(f, side, &w, &h);
    size_t n = w * h;
    double amax = 0;
    for (size_t c = 0; c < C; c++) {
        const double *t = sb_factors_tex_const(f, side, term, c);
        for (size_t i = 0; i < n; i++) {
            if (!isfinite(t[i]))
                return sb_error(ctx, SB_ERR_NUMERIC, "%s: value %g at texel (%zu, %zu) of channel %s is not finite",
                                path, t[i], i % w, i / w, channel_name(C, c));
            if (fabs(t[i]) > amax) amax = fabs(t[i]);
        }
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

/* Convert one texture into `buf` (planar, float or half bits) and find its
 * scale. */
static sb_result_t pack_texture(sb_context_t *ctx, const sb_factors_t *f, int side, size_t term, int half,
                                const char *path, void *buf, float *scale_out) {
    size_t C = sb_factors_channels(f), w, h;
    sb_factors_size(f, side, &w, &h);
    size_t n = w * h;
    codec_t k;
    sb_result_t r = texture_codec(ctx, f, side, term, half, path, &k);
    if (r != SB_OK) return r;
    size_t bpe = half ? 2 : 4;
    for (size_t c = 0; c < C; c++) {
        const double *t = sb_factors_tex_const(f, side, term, c);
        void *plane = (unsigned char *)buf + c * n * bpe;
        for (size_t i = 0; i < n; i++)
            texel_encode(&k, t[i], plane, i);
    }
    *scale_out = (float)k.scale;
    return SB_OK;
}

/* Header attributes of one file (see exr.h). */
static sb_result_t write_attrs(sb_context_t *ctx, exr_context_t ex, const sb_factors_t *f, int side, size_t term,
                               float scale, const char *path) {
    size_t C = sb_factors_channels(f), J = sb_factors_terms(f);
    const sb_factor_errors_t *err = sb_factors_errors(f);
    float sigma[3];
    for (size_t c = 0; c < C; c++)
        if (!to_float(sb_factors_sigma(f, term, c), &sigma[c]))
            return sb_error(ctx, SB_ERR_RANGE, "%s: sigma %g of term %zu is not representable as a float", path,
                            sb_factors_sigma(f, term, c), term);
    float *rel = sb_alloc(ctx, J, sizeof(float), "exr rel_rms");
    if (!rel) return SB_ERR_NOMEM;
    for (size_t t = 0; t < J; t++)
        if (!to_float(err->rel_rms[sb_err_at(t, SB_CH_ALL)], &rel[t])) {
            free(rel);
            return sb_error(ctx, SB_ERR_RANGE, "%s: rel_rms %g after %zu terms is not representable as a float", path,
                            err->rel_rms[sb_err_at(t, SB_CH_ALL)], t + 1);
        }
    exr_result_t rv = exr_attr_set_string(ex, 0, PREFIX "version", SB_VERSION_STRING);
    if (!rv) rv = exr_attr_set_string(ex, 0, PREFIX "side", side == SB_SIDE_H ? "h" : "g");
    if (!rv) rv = exr_attr_set_int(ex, 0, PREFIX "term", (int32_t)term);
    if (!rv) rv = exr_attr_set_int(ex, 0, PREFIX "terms", (int32_t)J);
    if (!rv) rv = exr_attr_set_int(ex, 0, PREFIX "channels", (int32_t)C);
    if (!rv) rv = exr_attr_set_float_vector(ex, 0, PREFIX "sigma", (int32_t)C, sigma);
    if (!rv) rv = exr_attr_set_float(ex, 0, PREFIX "scale", scale);
    if (!rv) rv = exr_attr_set_float_vector(ex, 0, PREFIX "rel_rms", (int32_t)J, rel);
    free(rel);
    if (rv) return exr_fail(ctx, rv, SB_ERR_IO, path, "cannot set the sepbrdf attributes");
    char name[PREFIX_LEN + 256];
    for (size_t i = 0; i < sb_factors_meta_count(f); i++) {
        const char *key, *value;
        sb_factors_meta_at(f, i, &key, &value);
        snprintf(name, sizeof name, PREFIX "%s", key);
        rv = exr_attr_set_string(ex, 0, name, value);
        if (rv) return exr_fail(ctx, rv, SB_ERR_IO, path, "cannot set a metadata attribute");
    }
    return SB_OK;
}

/* OpenEXRCore before the fix of AcademySoftwareFoundation/openexr#2306
 * (Debian 12 ships 3.1.5) stores a ZIP chunk whose deflated size equals
 * its raw size as deflated bytes, while readers take "packed size ==
 * unpacked size" to mean raw pixels: such a file reads back garbage.  Run
 * the library's compressor, then store a chunk that gained nothing raw, as
 * the fixed versions do. */
typedef struct compress_hook {
    exr_result_t (*fn)(exr_encode_pipeline_t *enc);
} compress_hook_t;

static exr_result_t compress_no_gain_raw(exr_encode_pipeline_t *enc) {
    const compress_hook_t *hook = enc->encoding_user_data;
    exr_result_t rv = hook->fn(enc);
    if (rv || enc->compressed_buffer == enc->packed_buffer || enc->compressed_bytes < enc->packed_bytes) return rv;
    if (enc->compressed_alloc_size < enc->packed_bytes) return EXR_ERR_OUT_OF_MEMORY; /* cannot fix: fail */
    memcpy(enc->compressed_buffer, enc->packed_buffer, enc->packed_bytes);
    enc->compressed_bytes = enc->packed_bytes;
    return EXR_ERR_SUCCESS;
}

/* Write one texture to `tmp` (the temporary name); messages name `path`,
 * its final name. */
static sb_result_t write_one(sb_context_t *ctx, const sb_factors_t *f, int side, size_t term, int half, int longnames,
                             const char *tmp, const char *path, void *buf) {
    size_t C = sb_factors_channels(f), w, h;
    sb_factors_size(f, side, &w, &h);
    size_t bpe = half ? 2 : 4;
    exr_pixel_type_t ptype = half ? EXR_PIXEL_HALF : EXR_PIXEL_FLOAT;
    float scale = 1;
    sb_result_t r = pack_texture(ctx, f, side, term, half, path, buf, &scale);
    if (r != SB_OK) return r;

    exr_sink_t sink = {NULL, 0, 0};
    exr_msg_reset();
    exr_context_initializer_t init = exr_init(0);
    init.user_data = &sink;
    init.write_fn = exr_stream_write;
    exr_context_t ex = NULL;
    exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
    compress_hook_t hook = {NULL};
    int enc_live = 0, part = 0;
    exr_result_t rv = exr_start_write(&ex, path, EXR_WRITE_FILE_DIRECTLY, &init);
    if (rv) {
        r = exr_fail(ctx, rv, SB_ERR_IO, path, "cannot create");
        goto out;
    }
    /* Describe the part */
    if (longnames) rv = exr_set_longname_support(ex, 1);
    if (!rv) rv = exr_add_part(ex, NULL, EXR_STORAGE_SCANLINE, &part);
    if (!rv) rv = exr_initialize_required_attr_simple(ex, part, (int32_t)w, (int32_t)h, EXR_COMPRESSION_ZIP);
    for (size_t c = 0; c < C && !rv; c++)
        rv = exr_add_channel(ex, part, channel_name(C, c), ptype, EXR_PERCEPTUALLY_LOGARITHMIC, 1, 1);
    if (rv) {
        r = exr_fail(ctx, rv, SB_ERR_IO, path, "cannot describe the image");
        goto out;
    }
    if ((r = write_attrs(ctx, ex, f, side, term, scale, path)) != SB_OK) goto out;
    if ((rv = exr_write_header(ex))) {
        r = exr_fail(ctx, rv, SB_ERR_IO, path, "cannot write the header");
        goto out;
    }
    /* Encode the chunks (lines_per_chunk scanlines each) */
    int32_t nchunks = 0, lpc = 0;
    rv = exr_get_chunk_count(ex, part, &nchunks);
    if (!rv) rv = exr_get_scanlines_per_chunk(ex, part, &lpc);
    for (int32_t k = 0; k < nchunks && !rv; k++) {
        exr_chunk_info_t ci;
        int y = k * lpc;
        rv = exr_write_scanline_chunk_info(ex, part, y, &ci);
        if (rv) break;
        rv = enc_live ? exr_encoding_update(ex, part, &ci, &enc) : exr_encoding_initialize(ex, part, &ci, &enc);
        if (rv) break;
        enc_live = 1;
        for (int16_t k2 = 0; k2 < enc.channel_count; k2++) {
            exr_coding_channel_info_t *ch = &enc.channels[k2];
            int plane = channel_plane(C, ch->channel_name);
            assert(plane >= 0);
            ch->user_bytes_per_element = (int16_t)bpe;
            ch->user_data_type = (uint16_t)ptype;
            ch->user_pixel_stride = (int32_t)bpe;
            ch->user_line_stride = (int32_t)(w * bpe);
            ch->encode_from_ptr = (const uint8_t *)buf + ((size_t)plane * w * h + (size_t)y * w) * bpe;
        }
        if (k == 0) {
            rv = exr_encoding_choose_default_routines(ex, part, &enc);
            if (!rv && enc.compress_fn) {
                hook.fn = enc.compress_fn;
                enc.compress_fn = compress_no_gain_raw;
                enc.encoding_user_data = &hook;
            }
        }
        if (!rv) rv = exr_encoding_run(ex, part, &enc);
    }
    if (rv) {
        r = exr_fail(ctx, rv, SB_ERR_IO, path, "cannot write the pixels");
        goto out;
    }
out:
    if (enc_live) exr_encoding_destroy(ex, &enc);
    if (ex) {
        /* finish writes the chunk offsets: its failure is a failed file */
        rv = exr_finish(&ex);
        if (rv && r == SB_OK) r = exr_fail(ctx, rv, SB_ERR_IO, path, "cannot complete");
    }
    if (r == SB_OK) r = sink_flush(ctx, &sink, tmp, path);
    free(sink.buf);
    return r;
}

sb_result_t sb_factors_write_exr(sb_context_t *ctx, const sb_factors_t *f, const char *dir, const sb_exr_opts_t *opts) {
    if (!f || !dir) return sb_error(ctx, SB_ERR_ARG, "exr write: no factors or no folder");
    int half = opts && opts->half;
    size_t J = sb_factors_terms(f), C = sb_factors_channels(f), w[2], h[2], n[2];
    /* Check what the format can hold before touching the folder */
    if (J > INT32_MAX) return sb_error(ctx, SB_ERR_RANGE, "exr write: %zu terms, at most %d", J, INT32_MAX);
    for (int s = 0; s < 2; s++) {
        sb_factors_size(f, s, &w[s], &h[s]);
        if (w[s] > INT32_MAX || h[s] > INT32_MAX)
            return sb_error(ctx, SB_ERR_RANGE, "exr write: %s texture %zu x %zu exceeds the EXR size limit",
                            s ? "h" : "g", w[s], h[s]);
        n[s] = w[s] * h[s]; /* the factors' own allocation proves this fits */
    }
    int longnames = 0;
    for (size_t i = 0; i < sb_factors_meta_count(f); i++) {
        const char *key, *value;
        sb_factors_meta_at(f, i, &key, &value);
        if (is_fixed_key(key))
            return sb_error(ctx, SB_ERR_ARG,
                            "exr write: metadata key \"%s\" collides with the attribute " PREFIX
                            "%s the writer sets itself",
                            key, key);
        size_t len = PREFIX_LEN + strlen(key);
        if (len > 255)
            return sb_error(ctx, SB_ERR_RANGE,
                            "exr write: metadata key \"%.40s...\" is %zu characters, EXR "
                            "attribute names allow %d",
                            key, strlen(key), 255 - PREFIX_LEN);
        if (len > 31) longnames = 1;
    }

    size_t nfiles = 2 * J, done = 0, renamed = 0;
    sb_result_t r = SB_OK;
    char **tmp = sb_calloc(ctx, nfiles, sizeof(char *), "exr paths");
    char **fin = sb_calloc(ctx, nfiles, sizeof(char *), "exr paths");
    void *buf = sb_alloc(ctx, (n[0] > n[1] ? n[0] : n[1]) * C, sizeof(float), "exr pixel buffer");
    if (!tmp || !fin || !buf) {
        r = SB_ERR_NOMEM;
        goto out;
    }
    for (size_t k = 0; k < nfiles; k++) {
        char name[64];
        sb_exr_name((int)(k % 2), k / 2, name, sizeof name);
        tmp[k] = make_path(ctx, dir, name, 1);
        fin[k] = make_path(ctx, dir, name, 0);
        if (!tmp[k] || !fin[k]) {
            r = SB_ERR_NOMEM;
            goto out;
        }
    }
    /* Phase 0: every texture storable, before any file exists; messages
     * name the file the texture was for */
    for (size_t k = 0; k < nfiles; k++) {
        codec_t cd;
        if ((r = texture_codec(ctx, f, (int)(k % 2), k / 2, half, fin[k], &cd)) != SB_OK) goto out;
    }
    /* Phase 1: every file complete under its temporary name */
    for (; done < nfiles; done++) {
        r = write_one(ctx, f, (int)(done % 2), done / 2, half, longnames, tmp[done], fin[done], buf);
        if (r != SB_OK) {
            done++; /* its temporary may exist */
            goto out;
        }
    }
    /* Phase 2: rename */
    for (; renamed < nfiles; renamed++)
        if (rename(tmp[renamed], fin[renamed]) != 0) {
            r = sb_error(ctx, SB_ERR_IO, "%s: cannot complete (rename): %s", fin[renamed], sb_io_why(errno));
            goto out;
        }
out:
    if (r != SB_OK && tmp && fin) {
        for (size_t k = 0; k < renamed; k++)
            remove(fin[k]);
        for (size_t k = renamed; k < done; k++)
            remove(tmp[k]);
    }
    for (size_t k = 0; k < nfiles && tmp && fin; k++) {
        free(tmp[k]);
        free(fin[k]);
    }
    free(tmp);
    free(fin);
    free(buf);
    return r;
}

/* ---- stored precision of whole factors ---------------------------------- */

sb_result_t sb_exr_texture_scale(sb_context_t *ctx, const sb_factors_t *f, int side, size_t term,
                                 const sb_exr_opts_t *opts, double *scale) {
    if (!f || !scale || (side != SB_SIDE_G && side != SB_SIDE_H) || term >= sb_factors_terms(f))
        return sb_error(ctx, SB_ERR_ARG, "texture scale: missing argument or texture out of range");
    char name[64];
    codec_t cd;
    sb_exr_name(side, term, name, sizeof name);
    sb_result_t r = texture_codec(ctx, f, side, term, opts && opts->half, name, &cd);
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
        if ((r = texture_codec(ctx, f, side, term, half, name, &cd)) != SB_OK) break;
        for (size_t c = 0; c < C; c++) {
            const double *t = sb_factors_tex_const(f, side, term, c);
            double *d = sb_factors_tex(q, side, term, c);
            size_t flushed = 0;
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
            if (!to_float(sb_factors_sigma(f, j, c), &s)) {
                r = sb_error(ctx, SB_ERR_RANGE, "quantize: sigma %g of term %zu is not representable as a float",
                             sb_factors_sigma(f, j, c), j);
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

/* ---- read -------------------------------------------------------------- */

/* What the header of one file says. */
typedef struct hdr {
    int side;
    int32_t term, terms, channels;
    size_t w, h;
    int half;
    float scale;
    float sigma[3];
    const float *rel; /* terms values, owned by the EXR context */
} hdr_t;

static const exr_attribute_t *find_attr(exr_context_t ex, const char *name) {
    const exr_attribute_t *a = NULL;
    if (exr_get_attribute_by_name(ex, 0, name, &a) != EXR_ERR_SUCCESS) return NULL;
    return a;
}

/* Attribute `name` of type `type`, or a FORMAT error naming the file. */
static sb_result_t need_attr(sb_context_t *ctx, exr_context_t ex, const char *path, const char *name,
                             exr_attribute_type_t type, const char *type_name, const exr_attribute_t **out) {
    const exr_attribute_t *a = find_attr(ex, name);
    if (!a) return sb_error(ctx, SB_ERR_FORMAT, "%s: missing attribute %s", path, name);
    if (a->type != type)
        return sb_error(ctx, SB_ERR_FORMAT, "%s: attribute %s has type %s, expected %s", path, name,
                        a->type_name ? a->type_name : "?", type_name);
    if ((type == EXR_ATTR_STRING && !a->string) || (type == EXR_ATTR_FLOAT_VECTOR && !a->floatvector))
        return sb_error(ctx, SB_ERR_FORMAT, "%s: attribute %s has no value", path, name);
    *out = a;
    return SB_OK;
}

/* Parse and check the header of an open file: one scanline part, data
 * window from (0, 0), channels R, G, B or Y all FLOAT or all HALF, the
 * sepbrdf attributes present with their types and sane values. */
static sb_result_t read_header(sb_context_t *ctx, exr_context_t ex, const char *path, hdr_t *hd) {
    memset(hd, 0, sizeof *hd);
    int parts = 0;
    exr_storage_t st;
    exr_attr_box2i_t dw;
    const exr_attr_chlist_t *cl = NULL;
    exr_result_t rv = exr_get_count(ex, &parts);
    if (rv || parts != 1) return sb_error(ctx, SB_ERR_FORMAT, "%s: %d parts, expected one", path, parts);
    if (exr_get_storage(ex, 0, &st) || st != EXR_STORAGE_SCANLINE)
        return sb_error(ctx, SB_ERR_FORMAT, "%s: not a scanline image", path);
    if (exr_get_data_window(ex, 0, &dw)) return sb_error(ctx, SB_ERR_FORMAT, "%s: no data window", path);
    if (dw.min.x != 0 || dw.min.y != 0 || dw.max.x < 0 || dw.max.y < 0)
        return sb_error(ctx, SB_ERR_FORMAT, "%s: data window (%d, %d)-(%d, %d), expected one from (0, 0)", path,
                        dw.min.x, dw.min.y, dw.max.x, dw.max.y);
    hd->w = (size_t)dw.max.x + 1;
    hd->h = (size_t)dw.max.y + 1;

    const exr_attribute_t *a;
    sb_result_t r;
    if ((r = need_attr(ctx, ex, path, PREFIX "version", EXR_ATTR_STRING, "string", &a))) return r;
    if ((r = need_attr(ctx, ex, path, PREFIX "side", EXR_ATTR_STRING, "string", &a))) return r;
    if (a->string->length != 1 || !a->string->str || (a->string->str[0] != 'g' && a->string->str[0] != 'h'))
        return sb_error(ctx, SB_ERR_FORMAT, "%s: " PREFIX "side is not \"g\" or \"h\"", path);
    hd->side = a->string->str[0] == 'h' ? SB_SIDE_H : SB_SIDE_G;
    if ((r = need_attr(ctx, ex, path, PREFIX "term", EXR_ATTR_INT, "int", &a))) return r;
    hd->term = a->i;
    if ((r = need_attr(ctx, ex, path, PREFIX "terms", EXR_ATTR_INT, "int", &a))) return r;
    hd->terms = a->i;
    if ((r = need_attr(ctx, ex, path, PREFIX "channels", EXR_ATTR_INT, "int", &a))) return r;
    hd->channels = a->i;
    if (hd->terms < 1 || hd->term < 0 || hd->term >= hd->terms)
        return sb_error(ctx, SB_ERR_FORMAT, "%s: term %d of %d terms", path, (int)hd->term, (int)hd->terms);
    if (hd->channels != 1 && hd->channels != 3)
        return sb_error(ctx, SB_ERR_FORMAT, "%s: %d channels, expected 1 or 3", path, (int)hd->channels);
    if ((r = need_attr(ctx, ex, path, PREFIX "scale", EXR_ATTR_FLOAT, "float", &a))) return r;
    hd->scale = a->f;
    if (!isfinite(hd->scale) || !(hd->scale > 0))
        return sb_error(ctx, SB_ERR_FORMAT, "%s: " PREFIX "scale %g is not a positive number", path, hd->scale);
    if ((r = need_attr(ctx, ex, path, PREFIX "sigma", EXR_ATTR_FLOAT_VECTOR, "floatvector", &a))) return r;
    if (a->floatvector->length != hd->channels || !a->floatvector->arr)
        return sb_error(ctx, SB_ERR_FORMAT, "%s: " PREFIX "sigma has %d values, expected %d", path,
                        (int)a->floatvector->length, (int)hd->channels);
    memcpy(hd->sigma, a->floatvector->arr, (size_t)hd->channels * sizeof(float));
    if ((r = need_attr(ctx, ex, path, PREFIX "rel_rms", EXR_ATTR_FLOAT_VECTOR, "floatvector", &a))) return r;
    if (a->floatvector->length != hd->terms || !a->floatvector->arr)
        return sb_error(ctx, SB_ERR_FORMAT, "%s: " PREFIX "rel_rms has %d values, expected %d", path,
                        (int)a->floatvector->length, (int)hd->terms);
    hd->rel = a->floatvector->arr;

    /* Channels: exactly the expected names, one pixel type, no subsampling */
    if (exr_get_channels(ex, 0, &cl) || !cl || cl->num_channels != hd->channels || !cl->entries)
        return sb_error(ctx, SB_ERR_FORMAT, "%s: %d image channels, expected %d (%s)", path, cl ? cl->num_channels : 0,
                        (int)hd->channels, hd->channels == 1 ? "Y" : "R, G, B");
    for (int k = 0; k < cl->num_channels; k++) {
        const exr_attr_chlist_entry_t *e = &cl->entries[k];
        if (channel_plane((size_t)hd->channels, e->name.str) < 0)
            return sb_error(ctx, SB_ERR_FORMAT, "%s: unexpected channel \"%s\", expected %s", path,
                            e->name.str ? e->name.str : "", hd->channels == 1 ? "Y" : "R, G, B");
        if (e->pixel_type != EXR_PIXEL_FLOAT && e->pixel_type != EXR_PIXEL_HALF)
            return sb_error(ctx, SB_ERR_FORMAT, "%s: channel %s has pixel type %d, expected FLOAT or HALF", path,
                            e->name.str, (int)e->pixel_type);
        if (e->x_sampling != 1 || e->y_sampling != 1)
            return sb_error(ctx, SB_ERR_FORMAT, "%s: channel %s is subsampled", path, e->name.str);
        int half = e->pixel_type == EXR_PIXEL_HALF;
        if (k > 0 && half != hd->half) return sb_error(ctx, SB_ERR_FORMAT, "%s: channels mix FLOAT and HALF", path);
        hd->half = half;
    }
    /* The writer's scales: 1 for FLOAT, a power of two for HALF.  Anything
     * else would make the values read differ from what a write stores. */
    int e;
    if (hd->half ? frexp(hd->scale, &e) != 0.5 : hd->scale != 1)
        return sb_error(ctx, SB_ERR_FORMAT, "%s: " PREFIX "scale %g, expected %s", path, hd->scale,
                        hd->half ? "a power of two for HALF" : "1 for FLOAT");
    return SB_OK;
}

static sb_result_t open_read(sb_context_t *ctx, const char *path, exr_context_t *ex) {
    exr_msg_reset();
    exr_context_initializer_t init = exr_init(1);
    exr_result_t rv = exr_start_read(ex, path, &init);
    if (rv) {
        if (*ex) exr_finish(ex);
        *ex = NULL;
        return exr_fail(ctx, rv, SB_ERR_FORMAT, path, "cannot read as OpenEXR");
    }
    return SB_OK;
}

/* Decode the pixels of an open, checked file into `buf` (planar, file
 * type), then scale them into the factors' texture. */
static sb_result_t read_pixels(sb_context_t *ctx, exr_context_t ex, const char *path, const hdr_t *hd, sb_factors_t *f,
                               int side, size_t term, void *buf) {
    size_t C = (size_t)hd->channels, w = hd->w, h = hd->h, n = w * h, bpe = hd->half ? 2 : 4;
    exr_pixel_type_t ptype = hd->half ? EXR_PIXEL_HALF : EXR_PIXEL_FLOAT;
    exr_decode_pipeline_t dec = EXR_DECODE_PIPELINE_INITIALIZER;
    int dec_live = 0;
    int32_t nchunks = 0, lpc = 0;
    sb_result_t r = SB_OK;
    exr_msg_reset();
    exr_result_t rv = exr_get_chunk_count(ex, 0, &nchunks);
    if (!rv) rv = exr_get_scanlines_per_chunk(ex, 0, &lpc);
    if (rv) return exr_fail(ctx, rv, SB_ERR_FORMAT, path, "cannot read the chunk layout");
    if (nchunks < 1 || lpc < 1 || (size_t)nchunks != (h + (size_t)lpc - 1) / (size_t)lpc)
        return sb_error(ctx, SB_ERR_FORMAT, "%s: %d chunks of %d lines for %zu lines", path, (int)nchunks, (int)lpc, h);
    for (int32_t k = 0; k < nchunks; k++) {
        exr_chunk_info_t ci;
        size_t y = (size_t)k * (size_t)lpc;
        rv = exr_read_scanline_chunk_info(ex, 0, (int)y, &ci);
        if (rv) break;
        /* the decoder writes ci.height lines of ci.width pixels: keep them inside buf */
        if (ci.start_y != (int32_t)y || ci.height < 1 || (size_t)ci.height > h - y || (size_t)ci.width != w) {
            r = sb_error(ctx, SB_ERR_FORMAT,
                         "%s: chunk %d covers lines %d..%d, width %d; expected from line %zu, "
                         "width %zu",
                         path, (int)k, (int)ci.start_y, (int)(ci.start_y + ci.height - 1), (int)ci.width, y, w);
            goto out;
        }
        rv = dec_live ? exr_decoding_update(ex, 0, &ci, &dec) : exr_decoding_initialize(ex, 0, &ci, &dec);
        if (rv) break;
        dec_live = 1;
        if ((size_t)dec.channel_count != C) {
            r = sb_error(ctx, SB_ERR_FORMAT, "%s: chunk %d has %d channels", path, (int)k, (int)dec.channel_count);
            goto out;
        }
        for (int16_t c = 0; c < dec.channel_count; c++) {
            exr_coding_channel_info_t *ch = &dec.channels[c];
            int plane = channel_plane(C, ch->channel_name);
            if (plane < 0 || ch->height != ci.height || ch->width != ci.width || ch->data_type != (uint16_t)ptype) {
                r = sb_error(ctx, SB_ERR_FORMAT, "%s: chunk %d: channel layout differs from the header", path, (int)k);
                goto out;
            }
            ch->user_bytes_per_element = (int16_t)bpe;
            ch->user_data_type = (uint16_t)ptype;
            ch->user_pixel_stride = (int32_t)bpe;
            ch->user_line_stride = (int32_t)(w * bpe);
            ch->decode_to_ptr = (uint8_t *)buf + ((size_t)plane * n + y * w) * bpe;
        }
        if (k == 0) rv = exr_decoding_choose_default_routines(ex, 0, &dec);
        if (!rv) rv = exr_decoding_run(ex, 0, &dec);
        if (rv) break;
    }
    if (rv) {
        r = exr_fail(ctx, rv, SB_ERR_FORMAT, path, "cannot decode the pixels");
        goto out;
    }
    /* Scale into the factors: (double)float * scale, exact for scale 1 */
    for (size_t c = 0; c < C; c++) {
        double *t = sb_factors_tex(f, side, term, c);
        const codec_t k = {hd->half, hd->scale};
        const void *plane = (const unsigned char *)buf + c * n * bpe;
        for (size_t i = 0; i < n; i++) {
            t[i] = texel_decode(&k, plane, i);
            if (!isfinite(t[i])) {
                r = sb_error(ctx, SB_ERR_FORMAT, "%s: non-finite value at texel (%zu, %zu) of channel %s", path, i % w,
                             i / w, channel_name(C, c));
                goto out;
            }
        }
    }
out:
    if (dec_live) exr_decoding_destroy(ex, &dec);
    return r;
}

/* Metadata: every "sepbrdf.<key>" string attribute other than the fixed
 * ones.  With set, store them into f; otherwise check that the file carries
 * exactly f's metadata. */
static sb_result_t read_meta(sb_context_t *ctx, exr_context_t ex, const char *path, sb_factors_t *f, int set,
                             const char *first) {
    int32_t count = 0;
    size_t found = 0;
    if (exr_get_attribute_count(ex, 0, &count)) return sb_error(ctx, SB_ERR_FORMAT, "%s: no attributes", path);
    for (int32_t i = 0; i < count; i++) {
        const exr_attribute_t *a = NULL;
        if (exr_get_attribute_by_index(ex, 0, EXR_ATTR_LIST_FILE_ORDER, i, &a) || !a || !a->name) continue;
        if (strncmp(a->name, PREFIX, PREFIX_LEN) != 0 || a->type != EXR_ATTR_STRING || !a->string) continue;
        const char *key = a->name + PREFIX_LEN;
        if (is_fixed_key(key)) continue;
        int32_t len = a->string->length;
        if (len < 0) return sb_error(ctx, SB_ERR_FORMAT, "%s: attribute %s has a negative length", path, a->name);
        char *value = sb_alloc(ctx, (size_t)len + 1, 1, "exr metadata");
        if (!value) return SB_ERR_NOMEM;
        if (len) memcpy(value, a->string->str, (size_t)len);
        value[len] = 0;
        sb_result_t r = SB_OK;
        if (set) {
            if (sb_factors_set_meta(f, key, value) != SB_OK) r = sb_error(ctx, SB_ERR_NOMEM, "%s: out of memory", path);
        } else {
            const char *mine = sb_factors_get_meta(f, key);
            if (!mine || strcmp(mine, value) != 0)
                r = sb_error(ctx, SB_ERR_FORMAT, "%s: attribute %s differs from %s", path, a->name, first);
            found++;
        }
        free(value);
        if (r != SB_OK) return r;
    }
    if (!set && found != sb_factors_meta_count(f))
        return sb_error(ctx, SB_ERR_FORMAT, "%s: %zu metadata attributes, %s has %zu", path, found, first,
                        sb_factors_meta_count(f));
    return SB_OK;
}

/* Open a file and read its header; missing files are IO errors. */
static sb_result_t open_header(sb_context_t *ctx, const char *dir, int side, size_t term, char **path,
                               exr_context_t *ex, hdr_t *hd) {
    char name[64];
    sb_exr_name(side, term, name, sizeof name);
    *path = make_path(ctx, dir, name, 0);
    if (!*path) return SB_ERR_NOMEM;
    sb_result_t r = open_read(ctx, *path, ex);
    if (r == SB_OK) r = read_header(ctx, *ex, *path, hd);
    if (r == SB_OK && (hd->side != side || (size_t)hd->term != term))
        r = sb_error(ctx, SB_ERR_FORMAT, "%s: holds %s term %d, expected %s term %zu", *path,
                     hd->side == SB_SIDE_H ? "h" : "g", (int)hd->term, side == SB_SIDE_H ? "h" : "g", term);
    return r;
}

sb_result_t sb_factors_read_exr(sb_context_t *ctx, const char *dir, sb_factors_t **out) {
    if (!out) return sb_error(ctx, SB_ERR_ARG, "exr read: no output pointer");
    *out = NULL;
    if (!dir) return sb_error(ctx, SB_ERR_ARG, "exr read: no folder");
    sb_factors_t *f = NULL;
    exr_context_t ex = NULL;
    char *path = NULL, *first = NULL;
    void *buf = NULL;
    float *rel = NULL;
    hdr_t hg, hh, hd;
    sb_result_t r;

    /* g_00 (kept open) and h_00 give terms, channels and both sizes */
    if ((r = open_header(ctx, dir, SB_SIDE_G, 0, &first, &ex, &hg)) != SB_OK) goto out;
    exr_context_t ex_h = NULL;
    r = open_header(ctx, dir, SB_SIDE_H, 0, &path, &ex_h, &hh);
    if (ex_h) exr_finish(&ex_h);
    free(path);
    path = NULL;
    if (r != SB_OK) goto out;
    if (hh.terms != hg.terms || hh.channels != hg.channels) {
        r = sb_error(ctx, SB_ERR_FORMAT, "exr read: %s says %d terms of %d channels, its h_00.exr %d of %d", first,
                     (int)hg.terms, (int)hg.channels, (int)hh.terms, (int)hh.channels);
        goto out;
    }
    size_t J = (size_t)hg.terms, C = (size_t)hg.channels, ng, nh, bytes;
    /* Refuse forged sizes before allocating: all textures as doubles */
    if (sb_size_mul(hg.w, hg.h, &ng) || sb_size_mul(hh.w, hh.h, &nh) || sb_size_add(ng, nh, &bytes) ||
        sb_size_mul3(bytes, J * C, sizeof(double), &bytes) || bytes > sb_memory_limit()) {
        r = sb_error(ctx, SB_ERR_OVERFLOW,
                     "%s: %zu terms of %zu x %zu and %zu x %zu texels exceed the memory limit "
                     "of %zu bytes",
                     first, J, hg.w, hg.h, hh.w, hh.h, sb_memory_limit());
        goto out;
    }
    if ((r = sb_factors_create(ctx, J, C, hg.w, hg.h, hh.w, hh.h, &f)) != SB_OK) goto out;
    if ((r = read_meta(ctx, ex, first, f, 1, first)) != SB_OK) goto out;
    rel = sb_alloc(ctx, J, sizeof(float), "exr rel_rms");
    buf = sb_alloc(ctx, (ng > nh ? ng : nh) * C, sizeof(float), "exr pixel buffer");
    if (!rel || !buf) {
        r = SB_ERR_NOMEM;
        goto out;
    }
    memcpy(rel, hg.rel, J * sizeof(float));
    sb_factor_errors_t *err = sb_factors_errors_mut(f);
    for (size_t t = 0; t < J; t++)
        err->rel_rms[sb_err_at(t, SB_CH_ALL)] = rel[t];

    /* Every file: header agrees with g_00 / h_00, then the pixels */
    float sigma[3] = {0, 0, 0};
    for (size_t k = 0; k < 2 * J; k++) {
        int side = (int)(k % 2);
        size_t term = k / 2;
        if (k > 0) {
            exr_finish(&ex);
            free(path);
            path = NULL;
            if ((r = open_header(ctx, dir, side, term, &path, &ex, &hd)) != SB_OK) goto out;
        } else {
            hd = hg;
        }
        const char *p = k ? path : first;
        const hdr_t *ref = side == SB_SIDE_H ? &hh : &hg;
        if (hd.terms != hg.terms || hd.channels != hg.channels || hd.w != ref->w || hd.h != ref->h) {
            r = sb_error(ctx, SB_ERR_FORMAT, "%s: %d terms of %d channels, %zu x %zu; %s has %d of %d, %zu x %zu", p,
                         (int)hd.terms, (int)hd.channels, hd.w, hd.h, side == SB_SIDE_H ? "h_00.exr" : first,
                         (int)hg.terms, (int)hg.channels, ref->w, ref->h);
            goto out;
        }
        if (memcmp(hd.rel, rel, J * sizeof(float)) != 0) {
            r = sb_error(ctx, SB_ERR_FORMAT, "%s: " PREFIX "rel_rms differs from %s", p, first);
            goto out;
        }
        if (k > 0 && (r = read_meta(ctx, ex, p, f, 0, first)) != SB_OK) goto out;
        if (side == SB_SIDE_G) {
            memcpy(sigma, hd.sigma, sizeof sigma);
            for (size_t c = 0; c < C; c++)
                sb_factors_set_sigma(f, term, c, hd.sigma[c]);
        } else if (memcmp(sigma, hd.sigma, C * sizeof(float)) != 0) {
            r = sb_error(ctx, SB_ERR_FORMAT, "%s: " PREFIX "sigma differs from its g file's", p);
            goto out;
        }
        if ((r = read_pixels(ctx, ex, p, &hd, f, side, term, buf)) != SB_OK) goto out;
    }
    *out = f;
    f = NULL;
out:
    if (ex) exr_finish(&ex);
    sb_factors_destroy(f);
    free(path);
    free(first);
    free(buf);
    free(rel);
    return r;
}
