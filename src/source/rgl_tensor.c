/* The Mitsuba "tensor_file" container of RGL tables (rgl_tensor.h):
 * little-endian, "tensor_file\0", version {1, 0}, uint32 field count,
 * then per field: uint16 name length, name, uint16 ndim, uint8 dtype,
 * uint64 absolute offset, uint64 shape[ndim]; data in C order.  Every
 * offset and size is checked against the file. */
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "source/measured_impl.h"
#include "source/rgl_tensor.h"
#include "util/internal.h"

static const size_t dtype_size[12] = {0, 1, 1, 2, 2, 4, 4, 8, 8, 2, 4, 8};

sb_result_t tf_read(sb_context_t *ctx, const char *path, tf_file_t *tf) {
    sb_result_t r = SB_OK;
    FILE *fp = sb_fopen_regular(ctx, path, "RGL table", SB_MEASURED_MAX_FILE, &r);
    if (!fp) return r;
    struct stat st;
    if (fstat(fileno(fp), &st) != 0 || st.st_size < 0) {
        r = sb_error(ctx, SB_ERR_IO, "%s: cannot stat: %s", path, strerror(errno));
    } else if ((uintmax_t)st.st_size > SIZE_MAX / 2) {
        r = sb_error(ctx, SB_ERR_FORMAT, "%s: RGL: file too large (%jd bytes)", path, (intmax_t)st.st_size);
    } else {
        tf->size = (size_t)st.st_size;
        tf->buf = sb_alloc(ctx, tf->size ? tf->size : 1, 1, path);
        if (!tf->buf)
            r = SB_ERR_NOMEM;
        else if (fread(tf->buf, 1, tf->size, fp) != tf->size)
            r = sb_error(ctx, SB_ERR_IO, "%s: read error", path);
    }
    fclose(fp);
    return r;
}

/* Every field's data after the field table (which ends at byte end), no two
 * sharing bytes: a corrupt offset would read the header or another table
 * as values (an rgb offset of 0 read R up to 6e32, exit 0). */
static sb_result_t tf_layout_check(sb_context_t *ctx, const char *path, const tf_file_t *tf, size_t nf, size_t end) {
    for (size_t k = 0; k < nf; k++) {
        const tf_field_t *f = &tf->fields[k];
        size_t off = (size_t)(f->data - tf->buf), len = f->count * dtype_size[f->dtype];
        if (len && off < end)
            return sb_error(ctx, SB_ERR_FORMAT,
                            "%s: RGL: field %.*s: data at offset %zu lies inside the header and field table "
                            "(bytes 0..%zu)",
                            path, (int)f->name_len, (const char *)f->name, off, end - 1);
        for (size_t l = 0; len && l < k; l++) {
            const tf_field_t *g = &tf->fields[l];
            size_t goff = (size_t)(g->data - tf->buf), glen = g->count * dtype_size[g->dtype];
            if (glen && off < goff + glen && goff < off + len)
                return sb_error(
                    ctx, SB_ERR_FORMAT,
                    "%s: RGL: fields %.*s and %.*s share bytes (offsets %zu and %zu): a corrupt field table", path,
                    (int)g->name_len, (const char *)g->name, (int)f->name_len, (const char *)f->name, goff, off);
        }
    }
    return SB_OK;
}

/* Parse the field table at p; every offset and size checked against the
 * file (size products overflow-checked). */
sb_result_t tf_parse(sb_context_t *ctx, const char *path, tf_file_t *tf) {
    const unsigned char *b = tf->buf;
    size_t n = tf->size, p = 18;
    if (n < 18 || memcmp(b, "tensor_file", 12) != 0)
        return sb_error(ctx, SB_ERR_FORMAT, "%s: RGL: not a tensor_file (bad magic or shorter than 18 bytes)", path);
    if (b[12] != 1 || b[13] != 0)
        return sb_error(ctx, SB_ERR_UNSUPPORTED, "%s: RGL: tensor_file version %u.%u, only 1.0 is supported", path,
                        b[12], b[13]);
    uint64_t count = tf_u(b + 14, 4);
    if (count == 0 || count > RGL_MAX_FIELDS)
        return sb_error(ctx, SB_ERR_FORMAT, "%s: RGL: %ju fields, need 1..%d", path, (uintmax_t)count, RGL_MAX_FIELDS);
    tf->fields = sb_calloc(ctx, (size_t)count, sizeof *tf->fields, path);
    if (!tf->fields) return SB_ERR_NOMEM;
    for (size_t k = 0; k < count; k++) {
        tf_field_t *f = &tf->fields[k];
        if (n - p < 2) goto truncated;
        f->name_len = (size_t)tf_u(b + p, 2);
        f->name = b + (p += 2);
        if (n - p < f->name_len + 11) goto truncated;
        p += f->name_len;
        f->ndim = (size_t)tf_u(b + p, 2);
        f->dtype = b[p + 2];
        uint64_t off = tf_u(b + p + 3, 8);
        p += 11;
        if (f->ndim > RGL_MAX_DIMS || f->dtype < 1 || f->dtype > 11)
            return sb_error(ctx, SB_ERR_FORMAT, "%s: RGL: field %.*s: %zu dimensions, dtype %u (need <= %d, 1..11)",
                            path, (int)f->name_len, (const char *)f->name, f->ndim, f->dtype, RGL_MAX_DIMS);
        if ((n - p) / 8 < f->ndim) goto truncated;
        size_t cnt = 1;
        for (size_t d = 0; d < f->ndim; d++, p += 8) {
            f->shape[d] = tf_u(b + p, 8);
            if (f->shape[d] > SIZE_MAX || sb_size_mul(cnt, (size_t)f->shape[d], &cnt))
                return sb_error(ctx, SB_ERR_FORMAT, "%s: RGL: field %.*s: shape overflows", path, (int)f->name_len,
                                (const char *)f->name);
        }
        size_t bytes;
        if (sb_size_mul(cnt, dtype_size[f->dtype], &bytes) || off > n || bytes > n - off)
            return sb_error(ctx, SB_ERR_FORMAT,
                            "%s: RGL: field %.*s: data (%zu values at offset %ju) past the end "
                            "of the file (%zu bytes)",
                            path, (int)f->name_len, (const char *)f->name, cnt, (uintmax_t)off, n);
        f->count = cnt;
        f->data = b + off;
    }
    tf->nfields = (size_t)count;
    return tf_layout_check(ctx, path, tf, tf->nfields, p);
truncated:
    return sb_error(ctx, SB_ERR_FORMAT, "%s: RGL: field table truncated at byte %zu", path, p);
}

const tf_field_t *tf_find(const tf_file_t *tf, const char *name) {
    size_t len = strlen(name);
    for (size_t k = 0; k < tf->nfields; k++)
        if (tf->fields[k].name_len == len && memcmp(tf->fields[k].name, name, len) == 0) return &tf->fields[k];
    return NULL;
}

/* The tensor_file dtype codes' names (Mitsuba's Struct::Type). */
static const char *dtype_name(unsigned t) {
    static const char *const names[] = {"invalid", "uint8",  "int8",  "uint16",  "int16",   "uint32",
                                        "int32",   "uint64", "int64", "float16", "float32", "float64"};
    return t < sizeof names / sizeof *names ? names[t] : "of an unknown dtype";
}

/* A required float32 field of `ndim` dimensions, each >= lo[d]. */
sb_result_t tf_need_f32(sb_context_t *ctx, const char *path, const tf_file_t *tf, const char *name, size_t ndim,
                        const size_t *lo, const tf_field_t **out) {
    const tf_field_t *f = tf_find(tf, name);
    if (!f) return sb_error(ctx, SB_ERR_FORMAT, "%s: RGL: missing field '%s'", path, name);
    if (f->dtype != 10 || f->ndim != ndim)
        return sb_error(ctx, SB_ERR_FORMAT, "%s: RGL: field '%s' is %zu-D %s (dtype %u), need %zu-D float32", path,
                        name, f->ndim, dtype_name(f->dtype), f->dtype, ndim);
    for (size_t d = 0; d < ndim; d++)
        if (f->shape[d] < lo[d])
            return sb_error(ctx, SB_ERR_FORMAT, "%s: RGL: field '%s' dimension %zu is %ju, need at least %zu", path,
                            name, d, (uintmax_t)f->shape[d], lo[d]);
    for (size_t k = 0; k < f->count; k++) {
        float v = tf_f32(f->data + 4 * k);
        if (!isfinite(v))
            return sb_error(ctx, SB_ERR_FORMAT, "%s: RGL: field '%s' holds %s at index %zu (of %zu values)", path, name,
                            isnan(v) ? "NaN"
                            : v > 0  ? "+Inf"
                                     : "-Inf",
                            k, f->count);
    }
    *out = f;
    return SB_OK;
}
