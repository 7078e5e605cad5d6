/* RGL tensor_files checked against themselves (issue 34): a real file
 * (tests/data/measured) with one field's shape patched in its field table,
 * so it disagrees with another field, is refused with SB_ERR_FORMAT and a
 * message naming both fields; the file as it is loads.  The patches keep
 * every field's data inside the file, so only the disagreement is left to
 * catch. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"

#define REAL SB_MEASURED_DIR "/rgl_paper_white_rgb.bsdf"

static unsigned char *file;
static size_t file_size;

static int load(void) {
    if (file) return 1;
    FILE *fp = fopen(REAL, "rb");
    if (!fp) return 0;
    fseek(fp, 0, SEEK_END);
    file_size = (size_t)ftell(fp);
    fseek(fp, 0, SEEK_SET);
    file = malloc(file_size);
    int ok = file && fread(file, 1, file_size, fp) == file_size;
    fclose(fp);
    return ok;
}

static uint64_t get(const unsigned char *b, int n) {
    uint64_t u = 0;
    for (int k = n - 1; k >= 0; k--)
        u = u << 8 | b[k];
    return u;
}

/* Byte offset of field `name`'s shape in the field table (its ndim into
 * *ndim); 0 when absent.  The test's own walk of the container. */
static size_t shape_at(const unsigned char *b, const char *name, size_t *ndim) {
    size_t count = (size_t)get(b + 14, 4), p = 18;
    for (size_t k = 0; k < count; k++) {
        size_t len = (size_t)get(b + p, 2);
        int hit = len == strlen(name) && memcmp(b + p + 2, name, len) == 0;
        p += 2 + len;
        *ndim = (size_t)get(b + p, 2);
        p += 11;
        if (hit) return p;
        p += 8 * *ndim;
    }
    return 0;
}

static sb_result_t open_bytes(unsigned char *b, char *msg, size_t size);

/* The real file with field `name`'s shape set to shape[0..n) (n must be
 * its ndim), opened; the result code, the message in msg. */
static sb_result_t open_patched(const char *name, const uint64_t *shape, size_t n, char *msg, size_t size) {
    unsigned char *b = malloc(file_size);
    memcpy(b, file, file_size);
    size_t ndim = 0, at = shape_at(b, name, &ndim);
    CHECKF(at && ndim == n, "%s: %zu dimensions in the file", name, ndim);
    for (size_t d = 0; at && d < n && d < ndim; d++)
        for (int i = 0; i < 8; i++)
            b[at + 8 * d + (size_t)i] = (unsigned char)(shape[d] >> (8 * i));
    return open_bytes(b, msg, size);
}

/* The real file with field `name`'s data offset set to off (the offset
 * precedes the shape), opened. */
static sb_result_t open_offset(const char *name, uint64_t off, char *msg, size_t size) {
    unsigned char *b = malloc(file_size);
    memcpy(b, file, file_size);
    size_t ndim = 0, at = shape_at(b, name, &ndim);
    CHECKF(at > 8, "no field %s", name);
    for (int i = 0; at > 8 && i < 8; i++)
        b[at - 8 + (size_t)i] = (unsigned char)(off >> (8 * i));
    return open_bytes(b, msg, size);
}

/* The real file with float32 values [first, first + n) of field `name`
 * set to v, opened. */
static sb_result_t open_values(const char *name, size_t first, size_t n, float v, char *msg, size_t size) {
    unsigned char *b = malloc(file_size);
    memcpy(b, file, file_size);
    size_t ndim = 0, at = shape_at(b, name, &ndim);
    CHECKF(at > 8, "no field %s", name);
    size_t off = at > 8 ? (size_t)get(b + at - 8, 8) : 0;
    uint32_t u;
    memcpy(&u, &v, 4);
    for (size_t k = first; at > 8 && k < first + n && off + 4 * k + 4 <= file_size; k++)
        for (int i = 0; i < 4; i++)
            b[off + 4 * k + (size_t)i] = (unsigned char)(u >> (8 * i));
    return open_bytes(b, msg, size);
}

/* b (file_size bytes, freed here) written and opened. */
static sb_result_t open_bytes(unsigned char *b, char *msg, size_t size) {
    char path[4200];
    snprintf(path, sizeof path, "%s/patched.bsdf", sb_tmpdir("rgl_shapes"));
    FILE *fp = fopen(path, "wb");
    CHECK(fp && fwrite(b, 1, file_size, fp) == file_size);
    if (fp) fclose(fp);
    free(b);
    sb_context_t *ctx = NULL;
    sb_context_create(&ctx);
    sb_source_t *src = NULL;
    sb_result_t r = sb_measured_open(ctx, path, NULL, &src, NULL);
    snprintf(msg, size, "%s", sb_context_last_error(ctx));
    sb_source_destroy(src);
    sb_context_destroy(ctx);
    return r;
}

SB_TEST(unpatched_loads) {
    if (!load()) SKIP("no " REAL);
    char msg[1024];
    size_t nd;
    const uint64_t lum[4] = {1, 8, 32, 32};
    CHECK(shape_at(file, "luminance", &nd) && nd == 4);
    CHECKF(open_patched("luminance", lum, 4, msg, sizeof msg) == SB_OK, "%s", msg); /* the same shape */
}

SB_TEST(disagreeing_fields_refused) {
    if (!load()) SKIP("no " REAL);
    static const struct {
        const char *field;
        size_t n;
        uint64_t shape[5];
        const char *a, *b; /* the two fields the message names */
    } cases[] = {
        {"luminance", 4, {1, 4, 32, 32}, "luminance", "theta_i"},
        {"rgb", 5, {1, 8, 3, 16, 64}, "luminance", "rgb"},
        {"valid", 1, {1}, "valid", "rgb"},
        {"sigma", 2, {2, 3}, "sigma", "ndf"},
        {"ndf", 2, {2, 64}, "sigma", "ndf"},
        {"vndf", 4, {1, 4, 128, 128}, "vndf", "theta_i"},
        {"rgb", 5, {1, 4, 3, 32, 32}, "rgb", "theta_i"},
        {"theta_i", 1, {7}, "vndf", "theta_i"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        char msg[1024] = "";
        sb_result_t r = open_patched(cases[i].field, cases[i].shape, cases[i].n, msg, sizeof msg);
        CHECKF(r == SB_ERR_FORMAT && strstr(msg, cases[i].a) && strstr(msg, cases[i].b), "%s patched: %s: %s",
               cases[i].field, sb_result_name(r), msg);
    }
}

/* A field whose offset points into the header or at another field's data
 * is refused naming it (an rgb offset of 0 read the header's bytes as
 * colours, R up to 6e32, exit 0); the real offsets load. */
SB_TEST(overlapping_offsets_refused) {
    if (!load()) SKIP("no " REAL);
    size_t nd, at = shape_at(file, "vndf", &nd);
    CHECK(at > 8);
    uint64_t vndf_off = get(file + at - 8, 8);
    at = shape_at(file, "rgb", &nd);
    uint64_t rgb_off = get(file + at - 8, 8);
    char msg[1024] = "";
    CHECKF(open_offset("rgb", rgb_off, msg, sizeof msg) == SB_OK, "%s", msg);
    sb_result_t r = open_offset("rgb", 0, msg, sizeof msg);
    CHECKF(r == SB_ERR_FORMAT && strstr(msg, "field rgb") && strstr(msg, "inside the header"), "%s: %s",
           sb_result_name(r), msg);
    r = open_offset("rgb", vndf_off + 4, msg, sizeof msg);
    CHECKF(r == SB_ERR_FORMAT && strstr(msg, "vndf and rgb share bytes"), "%s: %s", sb_result_name(r), msg);
}

/* The NDF is a density (f_r = colour D(m) / (4 sigma)): a negative value
 * or a table of zeros is refused naming the field (they were read as f_r
 * <= 0 everywhere, factored, exit 0); the real table loads. */
SB_TEST(ndf_not_a_density_refused) {
    if (!load()) SKIP("no " REAL);
    size_t nd, at = shape_at(file, "ndf", &nd);
    CHECK(at && nd == 2);
    size_t n = at ? (size_t)(get(file + at, 8) * get(file + at + 8, 8)) : 0;
    CHECK(n == 256);
    char msg[1024] = "";
    CHECKF(open_values("ndf", 0, 0, 0, msg, sizeof msg) == SB_OK, "%s", msg);
    sb_result_t r = open_values("ndf", 0, n, 0, msg, sizeof msg);
    CHECKF(r == SB_ERR_FORMAT && strstr(msg, "ndf") && strstr(msg, "zero everywhere"), "%s: %s", sb_result_name(r),
           msg);
    r = open_values("ndf", 37, 1, -0.5f, msg, sizeof msg);
    CHECKF(r == SB_ERR_FORMAT && strstr(msg, "ndf[37] = -0.5"), "%s: %s", sb_result_name(r), msg);
}
