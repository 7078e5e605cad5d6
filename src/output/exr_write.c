/* Writing the factor textures: one EXR file per texture and term,
 * assembled in memory, written under temporary names and renamed when all
 * are complete (see exr.c). */
#include <assert.h>
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "output/exr_impl.h"
#include "sepbrdf/outset.h"
#include "util/internal.h"
#include "util/parallel.h"

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

/* A write context assembling the file in `sink` (messages reset). */
static exr_result_t start_write(exr_context_t *ex, const char *path, exr_sink_t *sink) {
    sb_exr_msg_reset_();
    exr_context_initializer_t init = sb_exr_init_(0);
    init.user_data = sink;
    init.write_fn = exr_stream_write;
    return exr_start_write(ex, path, EXR_WRITE_FILE_DIRECTLY, &init);
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

/* Convert one texture into `buf` (planar, float or half bits) and find its
 * scale. */
static sb_result_t pack_texture(sb_context_t *ctx, const sb_factors_t *f, int side, size_t term, int half,
                                const char *path, void *buf, float *scale_out) {
    size_t C = sb_factors_channels(f), w, h;
    sb_factors_size(f, side, &w, &h);
    size_t n = w * h;
    codec_t k;
    sb_result_t r = sb_exr_texture_codec_(ctx, f, side, term, half, path, &k);
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
        if (!sb_exr_to_float_(sb_factors_sigma(f, term, c), &sigma[c]))
            return sb_error(ctx, SB_ERR_RANGE, "%s: sigma %g of term %zu is not representable as a float", path,
                            sb_factors_sigma(f, term, c), term);
    float *rel = sb_alloc(ctx, J, sizeof(float), "exr rel_rms");
    if (!rel) return SB_ERR_NOMEM;
    for (size_t t = 0; t < J; t++)
        if (!sb_exr_to_float_(err->rel_rms[sb_err_at(t, SB_CH_ALL)], &rel[t])) {
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
    if (rv) return sb_exr_fail_(ctx, rv, SB_ERR_IO, path, "cannot set the sepbrdf attributes");
    char name[PREFIX_LEN + 256];
    for (size_t i = 0; i < sb_factors_meta_count(f); i++) {
        const char *key, *value;
        sb_factors_meta_at(f, i, &key, &value);
        snprintf(name, sizeof name, PREFIX "%s", key);
        rv = exr_attr_set_string(ex, 0, name, value);
        if (rv) return sb_exr_fail_(ctx, rv, SB_ERR_IO, path, "cannot set a metadata attribute");
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

/* Encode the pixels of buf (planar, C channels of w x h, float or half
 * bits) into the chunks of part, lines_per_chunk scanlines each. */
static exr_result_t encode_chunks(exr_context_t ex, int part, size_t C, size_t w, size_t h, int half, const void *buf) {
    size_t bpe = half ? 2 : 4;
    exr_pixel_type_t ptype = half ? EXR_PIXEL_HALF : EXR_PIXEL_FLOAT;
    exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
    compress_hook_t hook = {NULL};
    int enc_live = 0;
    int32_t nchunks = 0, lpc = 0;
    exr_result_t rv = exr_get_chunk_count(ex, part, &nchunks);
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
            int plane = sb_exr_channel_plane_(C, ch->channel_name);
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
    if (enc_live) exr_encoding_destroy(ex, &enc);
    return rv;
}

/* Write one texture to `tmp` (the temporary name); messages name `path`,
 * its final name. */
static sb_result_t write_one(sb_context_t *ctx, const sb_factors_t *f, int side, size_t term, int half, int longnames,
                             const char *tmp, const char *path, void *buf) {
    size_t C = sb_factors_channels(f), w, h;
    sb_factors_size(f, side, &w, &h);
    exr_pixel_type_t ptype = half ? EXR_PIXEL_HALF : EXR_PIXEL_FLOAT;
    float scale = 1;
    sb_result_t r = pack_texture(ctx, f, side, term, half, path, buf, &scale);
    if (r != SB_OK) return r;

    exr_sink_t sink = {NULL, 0, 0};
    exr_context_t ex = NULL;
    int part = 0;
    exr_result_t rv = start_write(&ex, path, &sink);
    if (rv) {
        r = sb_exr_fail_(ctx, rv, SB_ERR_IO, path, "cannot create");
        goto out;
    }
    /* Describe the part */
    if (longnames) rv = exr_set_longname_support(ex, 1);
    if (!rv) rv = exr_add_part(ex, NULL, EXR_STORAGE_SCANLINE, &part);
    /* uncompressed: ZIP as OpenEXRCore writes it by default found no gain on
     * any texture set measured (default, hd -r 64, --half: the same bytes
     * either way, every chunk stored raw) and cost a third of the writing */
    if (!rv) rv = exr_initialize_required_attr_simple(ex, part, (int32_t)w, (int32_t)h, EXR_COMPRESSION_NONE);
    for (size_t c = 0; c < C && !rv; c++)
        rv = exr_add_channel(ex, part, sb_exr_channel_name_(C, c), ptype, EXR_PERCEPTUALLY_LOGARITHMIC, 1, 1);
    if (rv) {
        r = sb_exr_fail_(ctx, rv, SB_ERR_IO, path, "cannot describe the image");
        goto out;
    }
    if ((r = write_attrs(ctx, ex, f, side, term, scale, path)) != SB_OK) goto out;
    if ((rv = exr_write_header(ex))) {
        r = sb_exr_fail_(ctx, rv, SB_ERR_IO, path, "cannot write the header");
        goto out;
    }
    if ((rv = encode_chunks(ex, part, C, w, h, half, buf)))
        r = sb_exr_fail_(ctx, rv, SB_ERR_IO, path, "cannot write the pixels");
out:
    if (ex) {
        /* finish writes the chunk offsets: its failure is a failed file */
        rv = exr_finish(&ex);
        if (rv && r == SB_OK) r = sb_exr_fail_(ctx, rv, SB_ERR_IO, path, "cannot complete");
    }
    if (r == SB_OK) r = sink_flush(ctx, &sink, tmp, path);
    free(sink.buf);
    return r;
}

/* What the format can hold, checked before touching the folder: the
 * term count and texture sizes within int32, metadata keys neither the
 * writer's own nor too long; *longnames when a key needs long names. */
static sb_result_t check_format(sb_context_t *ctx, const sb_factors_t *f, size_t n[2], int *longnames) {
    size_t J = sb_factors_terms(f), w[2], h[2];
    if (J > INT32_MAX) return sb_error(ctx, SB_ERR_RANGE, "exr write: %zu terms, at most %d", J, INT32_MAX);
    for (int s = 0; s < 2; s++) {
        sb_factors_size(f, s, &w[s], &h[s]);
        if (w[s] > INT32_MAX || h[s] > INT32_MAX)
            return sb_error(ctx, SB_ERR_RANGE, "exr write: %s texture %zu x %zu exceeds the EXR size limit",
                            s ? "h" : "g", w[s], h[s]);
        n[s] = w[s] * h[s]; /* the factors' own allocation proves this fits */
    }
    *longnames = 0;
    for (size_t i = 0; i < sb_factors_meta_count(f); i++) {
        const char *key, *value;
        sb_factors_meta_at(f, i, &key, &value);
        if (sb_exr_fixed_key_(key))
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
        if (len > 31) *longnames = 1;
    }
    return SB_OK;
}

/* Files lo..hi-1 of sb_factors_write_exr's phase 1, on one thread: its
 * own pixel buffer and context; the first failure is kept. */
typedef struct exr_part {
    const sb_factors_t *f;
    int half, longnames;
    char **tmp, **fin;
    size_t lo, hi, bytes;
    sb_result_t r;
    char why[1024];
} exr_part_t;

static void *write_part(void *arg) {
    exr_part_t *w = arg;
    sb_context_t *c = NULL;
    void *buf = malloc(w->bytes);
    w->r = sb_context_create(&c) == SB_OK && buf ? SB_OK : SB_ERR_NOMEM;
    snprintf(w->why, sizeof w->why, "exr write: out of memory");
    for (size_t k = w->lo; k < w->hi && w->r == SB_OK; k++)
        if ((w->r = write_one(c, w->f, (int)(k % 2), k / 2, w->half, w->longnames, w->tmp[k], w->fin[k], buf)) != SB_OK)
            snprintf(w->why, sizeof w->why, "%s", sb_context_last_error(c));
    sb_context_destroy(c);
    free(buf);
    return NULL;
}

sb_result_t sb_factors_write_exr(sb_context_t *ctx, const sb_factors_t *f, const char *dir, const sb_exr_opts_t *opts) {
    if (!f || !dir) return sb_error(ctx, SB_ERR_ARG, "exr write: no factors or no folder");
    int half = opts && opts->half, longnames = 0;
    size_t J = sb_factors_terms(f), C = sb_factors_channels(f), n[2] = {0, 0};
    sb_result_t r = check_format(ctx, f, n, &longnames);
    if (r != SB_OK) return r;

    size_t nfiles = 2 * J, done = 0, renamed = 0;
    char **tmp = sb_calloc(ctx, nfiles, sizeof(char *), "exr paths");
    char **fin = sb_calloc(ctx, nfiles, sizeof(char *), "exr paths");
    if (!tmp || !fin) {
        r = SB_ERR_NOMEM;
        goto out;
    }
    for (size_t k = 0; k < nfiles; k++) {
        char name[64];
        sb_exr_name((int)(k % 2), k / 2, name, sizeof name);
        tmp[k] = sb_exr_path_(ctx, dir, name, 1);
        fin[k] = sb_exr_path_(ctx, dir, name, 0);
        if (!tmp[k] || !fin[k]) {
            r = SB_ERR_NOMEM;
            goto out;
        }
    }
    /* Phase 0: every texture storable, before any file exists; messages
     * name the file the texture was for */
    for (size_t k = 0; k < nfiles; k++) {
        codec_t cd;
        if ((r = sb_exr_texture_codec_(ctx, f, (int)(k % 2), k / 2, half, fin[k], &cd)) != SB_OK) goto out;
    }
    /* Phase 1: every file complete under its temporary name, the files
     * shared among the cores (zlib is most of it); on a failure every
     * temporary may exist */
    exr_part_t parts[SB_THREADS_MAX];
    int nt = sb_threads_for(0, nfiles, nfiles * (n[0] > n[1] ? n[0] : n[1]), (size_t)1 << 14);
    for (int t = 0; t < nt; t++) {
        parts[t] = (exr_part_t){f,     half, longnames, tmp, fin, 0, 0, (n[0] > n[1] ? n[0] : n[1]) * C * sizeof(float),
                                SB_OK, ""};
        sb_part(nfiles, t, nt, &parts[t].lo, &parts[t].hi);
    }
    sb_parallel_run(write_part, parts, sizeof *parts, nt, NULL, NULL);
    done = nfiles;
    for (int t = 0; t < nt; t++)
        if (parts[t].r != SB_OK) {
            r = sb_error(ctx, parts[t].r, "%s", parts[t].why);
            goto out;
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
    return r;
}

sb_result_t sb_exr_write_rgb(sb_context_t *ctx, const char *path, size_t w, size_t h, const float *rgb) {
    if (!path || !rgb || w == 0 || h == 0 || w > INT32_MAX || h > INT32_MAX)
        return sb_error(ctx, SB_ERR_ARG, "exr: no image to write");
    float *planes = malloc(3 * w * h * sizeof *planes);
    char *tmp = sb_format("%s.tmp", path);
    if (!planes || !tmp) {
        free(planes);
        free(tmp);
        return sb_error(ctx, SB_ERR_NOMEM, "%s: out of memory", path);
    }
    for (size_t i = 0; i < w * h; i++)
        for (size_t c = 0; c < 3; c++)
            planes[c * w * h + i] = rgb[3 * i + c];
    exr_sink_t sink = {NULL, 0, 0};
    exr_context_t ex = NULL;
    int part = 0;
    sb_result_t r = SB_OK;
    exr_result_t rv = start_write(&ex, path, &sink);
    if (!rv) rv = exr_add_part(ex, NULL, EXR_STORAGE_SCANLINE, &part);
    if (!rv) rv = exr_initialize_required_attr_simple(ex, part, (int32_t)w, (int32_t)h, EXR_COMPRESSION_ZIP);
    for (size_t c = 0; c < 3 && !rv; c++)
        rv = exr_add_channel(ex, part, sb_exr_channel_name_(3, c), EXR_PIXEL_FLOAT, EXR_PERCEPTUALLY_LOGARITHMIC, 1, 1);
    /* what the file is, so that `info` knows it under any name */
    if (!rv) rv = exr_attr_set_string(ex, part, PREFIX "version", SB_VERSION_STRING);
    if (!rv) rv = exr_attr_set_string(ex, part, PREFIX "kind", SB_EXR_KIND_VNDF_TABLES);
    if (!rv) rv = exr_write_header(ex);
    if (!rv) rv = encode_chunks(ex, part, 3, w, h, 0, planes);
    if (rv) r = sb_exr_fail_(ctx, rv, SB_ERR_IO, path, "cannot write");
    if (ex) {
        rv = exr_finish(&ex);
        if (rv && r == SB_OK) r = sb_exr_fail_(ctx, rv, SB_ERR_IO, path, "cannot complete");
    }
    if (r == SB_OK) r = sink_flush(ctx, &sink, tmp, path);
    if (r == SB_OK && rename(tmp, path) != 0)
        r = sb_error(ctx, SB_ERR_IO, "%s: cannot write: %s", path, sb_io_why(errno));
    if (r != SB_OK) unlink(tmp);
    free(sink.buf);
    free(planes);
    free(tmp);
    return r;
}
