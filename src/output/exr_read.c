/* Reading the factor textures back: every file of a set checked against
 * the first (terms, channels, sizes, errors, sigma, metadata), pixels
 * decoded through the stored precision of exr.c. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "output/exr_impl.h"
#include "util/internal.h"

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
        if (sb_exr_channel_plane_((size_t)hd->channels, e->name.str) < 0)
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
    struct stat st;
    /* OpenEXR would wait on a FIFO and read a device without end */
    if (stat(path, &st) == 0 && !S_ISREG(st.st_mode))
        return sb_error(ctx, SB_ERR_IO, "%s: not a regular file (a device, FIFO or folder is not read)", path);
    sb_exr_msg_reset_();
    exr_context_initializer_t init = sb_exr_init_(1);
    exr_result_t rv = exr_start_read(ex, path, &init);
    if (rv) {
        if (*ex) exr_finish(ex);
        *ex = NULL;
        return sb_exr_fail_(ctx, rv, SB_ERR_FORMAT, path, "cannot read as OpenEXR");
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
    sb_exr_msg_reset_();
    exr_result_t rv = exr_get_chunk_count(ex, 0, &nchunks);
    if (!rv) rv = exr_get_scanlines_per_chunk(ex, 0, &lpc);
    if (rv) return sb_exr_fail_(ctx, rv, SB_ERR_FORMAT, path, "cannot read the chunk layout");
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
            int plane = sb_exr_channel_plane_(C, ch->channel_name);
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
        r = sb_exr_fail_(ctx, rv, SB_ERR_FORMAT, path, "cannot decode the pixels");
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
                             i / w, sb_exr_channel_name_(C, c));
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
        if (sb_exr_fixed_key_(key)) continue;
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
    *path = sb_exr_path_(ctx, dir, name, 0);
    if (!*path) return SB_ERR_NOMEM;
    sb_result_t r = open_read(ctx, *path, ex);
    if (r == SB_OK) r = read_header(ctx, *ex, *path, hd);
    if (r == SB_OK && (hd->side != side || (size_t)hd->term != term))
        r = sb_error(ctx, SB_ERR_FORMAT, "%s: holds %s term %d, expected %s term %zu", *path,
                     hd->side == SB_SIDE_H ? "h" : "g", (int)hd->term, side == SB_SIDE_H ? "h" : "g", term);
    return r;
}

/* g_00 (left open in *ex, its path in *first) and h_00 give terms,
 * channels and both sizes; forged sizes are refused before anything is
 * allocated (all textures as doubles within the memory limit).  *npix:
 * the texels of the larger side. */
sb_result_t sb_exr_texture_check(sb_context_t *ctx, const char *path) {
    if (!path) return sb_error(ctx, SB_ERR_ARG, "exr check: no path");
    exr_context_t ex = NULL;
    hdr_t hd;
    sb_factors_t *f = NULL;
    void *buf = NULL;
    size_t n, bytes;
    sb_result_t r = open_read(ctx, path, &ex);
    if (r == SB_OK) r = read_header(ctx, ex, path, &hd);
    if (r == SB_OK && (sb_size_mul(hd.w, hd.h, &n) || sb_size_mul3(n, (size_t)hd.channels, sizeof(double), &bytes) ||
                       bytes > sb_memory_limit()))
        r = sb_error(ctx, SB_ERR_OVERFLOW, "%s: %zu x %zu texels exceed the memory limit of %zu bytes", path, hd.w,
                     hd.h, sb_memory_limit());
    /* one term of this side's size (the other side 1 x 1) to decode into */
    if (r == SB_OK)
        r = hd.side == SB_SIDE_H ? sb_factors_create(ctx, 1, (size_t)hd.channels, 1, 1, hd.w, hd.h, &f)
                                 : sb_factors_create(ctx, 1, (size_t)hd.channels, hd.w, hd.h, 1, 1, &f);
    if (r == SB_OK && !(buf = sb_alloc(ctx, n * (size_t)hd.channels, sizeof(float), "exr pixel buffer")))
        r = SB_ERR_NOMEM;
    if (r == SB_OK) r = read_pixels(ctx, ex, path, &hd, f, hd.side, 0, buf);
    free(buf);
    sb_factors_destroy(f);
    if (ex) exr_finish(&ex);
    return r;
}

static sb_result_t read_shape(sb_context_t *ctx, const char *dir, char **first, exr_context_t *ex, hdr_t *hg, hdr_t *hh,
                              size_t *npix) {
    char *path = NULL;
    sb_result_t r = open_header(ctx, dir, SB_SIDE_G, 0, first, ex, hg);
    if (r != SB_OK) return r;
    exr_context_t ex_h = NULL;
    r = open_header(ctx, dir, SB_SIDE_H, 0, &path, &ex_h, hh);
    if (ex_h) exr_finish(&ex_h);
    free(path);
    if (r != SB_OK) return r;
    if (hh->terms != hg->terms || hh->channels != hg->channels)
        return sb_error(ctx, SB_ERR_FORMAT, "exr read: %s says %d terms of %d channels, its h_00.exr %d of %d", *first,
                        (int)hg->terms, (int)hg->channels, (int)hh->terms, (int)hh->channels);
    size_t J = (size_t)hg->terms, C = (size_t)hg->channels, ng, nh, bytes;
    if (sb_size_mul(hg->w, hg->h, &ng) || sb_size_mul(hh->w, hh->h, &nh) || sb_size_add(ng, nh, &bytes) ||
        sb_size_mul3(bytes, J * C, sizeof(double), &bytes) || bytes > sb_memory_limit())
        return sb_error(ctx, SB_ERR_OVERFLOW,
                        "%s: %zu terms of %zu x %zu and %zu x %zu texels exceed the memory limit "
                        "of %zu bytes",
                        *first, J, hg->w, hg->h, hh->w, hh->h, sb_memory_limit());
    *npix = ng > nh ? ng : nh;
    return SB_OK;
}

/* The header hd of file p agrees with g_00 (hg) or h_00 (hh) for its
 * side: terms, channels, size, and the errors rel (the first file's). */
static sb_result_t check_agrees(sb_context_t *ctx, const hdr_t *hd, const hdr_t *hg, const hdr_t *hh, int side,
                                const float *rel, const char *p, const char *first) {
    const hdr_t *ref = side == SB_SIDE_H ? hh : hg;
    if (hd->terms != hg->terms || hd->channels != hg->channels || hd->w != ref->w || hd->h != ref->h)
        return sb_error(ctx, SB_ERR_FORMAT, "%s: %d terms of %d channels, %zu x %zu; %s has %d of %d, %zu x %zu", p,
                        (int)hd->terms, (int)hd->channels, hd->w, hd->h, side == SB_SIDE_H ? "h_00.exr" : first,
                        (int)hg->terms, (int)hg->channels, ref->w, ref->h);
    if (memcmp(hd->rel, rel, (size_t)hg->terms * sizeof(float)) != 0)
        return sb_error(ctx, SB_ERR_FORMAT, "%s: " PREFIX "rel_rms differs from %s", p, first);
    return SB_OK;
}

/* DIR/vndf.exr, the tables of a layout built on them (SB_CAP_TABLES), when
 * the set has one. */
static sb_result_t read_tables(sb_context_t *ctx, const char *dir, sb_factors_t *f) {
    char *path = sb_format("%s/vndf.exr", dir);
    if (!path) return sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    struct stat st;
    sb_result_t r = SB_OK;
    if (stat(path, &st) == 0) {
        size_t w, h;
        float *rgb = NULL;
        sb_layout_tables_t *t = NULL;
        r = sb_exr_read_rgb(ctx, path, &w, &h, &rgb);
        if (r == SB_OK) r = sb_layout_tables_from_texture(ctx, w, h, rgb, &t);
        if (r == SB_OK) sb_factors_set_tables(f, t);
        free(rgb);
    }
    free(path);
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
    size_t npix = 0;
    sb_result_t r = read_shape(ctx, dir, &first, &ex, &hg, &hh, &npix);
    if (r != SB_OK) goto out;
    size_t J = (size_t)hg.terms, C = (size_t)hg.channels;
    if ((r = sb_factors_create(ctx, J, C, hg.w, hg.h, hh.w, hh.h, &f)) != SB_OK) goto out;
    if ((r = read_meta(ctx, ex, first, f, 1, first)) != SB_OK) goto out;
    rel = sb_alloc(ctx, J, sizeof(float), "exr rel_rms");
    buf = sb_alloc(ctx, npix * C, sizeof(float), "exr pixel buffer");
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
        if ((r = check_agrees(ctx, &hd, &hg, &hh, side, rel, p, first)) != SB_OK) goto out;
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
    if ((r = read_tables(ctx, dir, f)) != SB_OK) goto out;
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

sb_result_t sb_exr_set_bytes(sb_context_t *ctx, const char *dir, size_t *texel_bytes, size_t *file_bytes) {
    if (!dir || !texel_bytes || !file_bytes) return sb_error(ctx, SB_ERR_ARG, "sb_exr_set_bytes: NULL argument");
    *texel_bytes = *file_bytes = 0;
    sb_result_t r = SB_OK;
    size_t n = 2;
    for (size_t k = 0; k < n && r == SB_OK; k++) {
        char *path = NULL;
        exr_context_t ex = NULL;
        hdr_t hd;
        struct stat st;
        r = open_header(ctx, dir, (int)(k % 2), k / 2, &path, &ex, &hd);
        if (r == SB_OK && k == 0) n = 2 * (size_t)hd.terms;
        if (r == SB_OK && stat(path, &st) != 0) r = sb_error(ctx, SB_ERR_IO, "%s: %s", path, strerror(errno));
        size_t b;
        if (r == SB_OK && (sb_size_mul3(hd.w, hd.h, (size_t)hd.channels * (hd.half ? 2 : 4), &b) ||
                           sb_size_add(*texel_bytes, b, texel_bytes)))
            r = sb_error(ctx, SB_ERR_FORMAT, "%s: %zu x %zu texels overflow a size", path, hd.w, hd.h);
        if (r == SB_OK) *file_bytes += (size_t)st.st_size;
        if (ex) exr_finish(&ex);
        free(path);
    }
    return r;
}

sb_result_t sb_exr_read_rgb(sb_context_t *ctx, const char *path, size_t *width, size_t *height, float **rgb) {
    if (!path || !width || !height || !rgb) return sb_error(ctx, SB_ERR_ARG, "exr: no file or output");
    *rgb = NULL;
    exr_context_t ex = NULL;
    sb_result_t r = open_read(ctx, path, &ex);
    if (r != SB_OK) return r;
    exr_attr_box2i_t dw;
    const exr_attr_chlist_t *cl = NULL;
    int32_t nchunks = 0, lpc = 0;
    exr_result_t rv = exr_get_data_window(ex, 0, &dw);
    if (!rv) rv = exr_get_channels(ex, 0, &cl);
    if (!rv) rv = exr_get_chunk_count(ex, 0, &nchunks);
    if (!rv) rv = exr_get_scanlines_per_chunk(ex, 0, &lpc);
    size_t w = rv ? 0 : (size_t)dw.max.x - (size_t)dw.min.x + 1, h = rv ? 0 : (size_t)dw.max.y - (size_t)dw.min.y + 1;
    if (rv || dw.min.x != 0 || dw.min.y != 0 || dw.max.x < 0 || dw.max.y < 0 || w > (1u << 16) || h > (1u << 20) ||
        !cl || cl->num_channels != 3 || lpc < 1 || (size_t)nchunks != (h + (size_t)lpc - 1) / (size_t)lpc) {
        exr_finish(&ex);
        return sb_error(ctx, SB_ERR_FORMAT, "%s: not an RGB float image from (0, 0)", path);
    }
    float *planes = malloc(3 * w * h * sizeof *planes), *out = malloc(3 * w * h * sizeof *out);
    exr_decode_pipeline_t dec = EXR_DECODE_PIPELINE_INITIALIZER;
    int live = 0;
    for (int32_t k = 0; planes && out && k < nchunks && r == SB_OK; k++) {
        exr_chunk_info_t ci;
        size_t y = (size_t)k * (size_t)lpc;
        rv = exr_read_scanline_chunk_info(ex, 0, (int)y, &ci);
        if (!rv && (ci.start_y != (int32_t)y || ci.height < 1 || (size_t)ci.height > h - y || (size_t)ci.width != w))
            rv = EXR_ERR_BAD_CHUNK_LEADER;
        if (!rv) rv = live ? exr_decoding_update(ex, 0, &ci, &dec) : exr_decoding_initialize(ex, 0, &ci, &dec);
        if (rv) break;
        live = 1;
        for (int16_t c = 0; c < dec.channel_count; c++) {
            exr_coding_channel_info_t *ch = &dec.channels[c];
            int plane = sb_exr_channel_plane_(3, ch->channel_name);
            if (plane < 0 || ch->data_type != EXR_PIXEL_FLOAT || ch->width != ci.width || ch->height != ci.height) {
                r = sb_error(ctx, SB_ERR_FORMAT, "%s: channels are not R, G, B as float", path);
                break;
            }
            ch->user_bytes_per_element = 4;
            ch->user_data_type = EXR_PIXEL_FLOAT;
            ch->user_pixel_stride = 4;
            ch->user_line_stride = (int32_t)(w * 4);
            ch->decode_to_ptr = (uint8_t *)(planes + (size_t)plane * w * h + y * w);
        }
        if (r == SB_OK && k == 0) rv = exr_decoding_choose_default_routines(ex, 0, &dec);
        if (r == SB_OK && !rv) rv = exr_decoding_run(ex, 0, &dec);
        if (rv) break;
    }
    if (live) exr_decoding_destroy(ex, &dec);
    exr_finish(&ex);
    if (r == SB_OK && (!planes || !out)) r = sb_error(ctx, SB_ERR_NOMEM, "%s: out of memory", path);
    if (r == SB_OK && rv) r = sb_exr_fail_(ctx, rv, SB_ERR_FORMAT, path, "cannot decode the pixels");
    if (r == SB_OK)
        for (size_t i = 0; i < w * h; i++)
            for (size_t c = 0; c < 3; c++)
                out[3 * i + c] = planes[c * w * h + i];
    free(planes);
    if (r != SB_OK) {
        free(out);
        return r;
    }
    *width = w;
    *height = h;
    *rgb = out;
    return SB_OK;
}
