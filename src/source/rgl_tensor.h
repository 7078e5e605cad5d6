/* Private: the Mitsuba "tensor_file" container of RGL tables (rgl_tensor.c),
 * read whole and checked; the RGL reader (rgl.c) takes its fields. */
#ifndef SEPBRDF_RGL_TENSOR_H
#define SEPBRDF_RGL_TENSOR_H

#include <stdint.h>
#include <string.h>

#include "sepbrdf/common.h"

#define RGL_MAX_FIELDS 4096
#define RGL_MAX_DIMS 8

typedef struct tf_field {
    const unsigned char *name;
    size_t name_len;
    unsigned dtype; /* 1 uint8 ... 10 float32, 11 float64 */
    size_t ndim;
    uint64_t shape[RGL_MAX_DIMS];
    const unsigned char *data; /* inside the file buffer, bounds checked */
    size_t count;              /* product of shape */
} tf_field_t;

typedef struct tf_file {
    unsigned char *buf;
    size_t size, nfields;
    tf_field_t *fields;
} tf_file_t;

/* Little-endian unsigned of n bytes; a float32. */
static inline uint64_t tf_u(const unsigned char *b, int n) {
    uint64_t u = 0;
    for (int k = n - 1; k >= 0; k--)
        u = u << 8 | b[k];
    return u;
}
static inline double tf_f32(const unsigned char *b) {
    uint32_t u = (uint32_t)tf_u(b, 4);
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

/* The file at path, whole, into tf->buf (a regular file: sb_fopen_regular). */
sb_result_t tf_read(sb_context_t *ctx, const char *path, tf_file_t *tf);
/* The field table of tf->buf into tf->fields (freed by the caller), every
 * offset and size checked against the file. */
sb_result_t tf_parse(sb_context_t *ctx, const char *path, tf_file_t *tf);
/* The field `name`, NULL when absent. */
const tf_field_t *tf_find(const tf_file_t *tf, const char *name);
/* A required float32 field of `ndim` dimensions, each >= lo[d], all values
 * finite. */
sb_result_t tf_need_f32(sb_context_t *ctx, const char *path, const tf_file_t *tf, const char *name, size_t ndim,
                        const size_t *lo, const tf_field_t **out);

#endif
