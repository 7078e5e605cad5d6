/* Shared by the measured-table tests (test_measured.c, test_measured_rgl.c):
 * writing test files byte by byte, reading them back, and the check that
 * opening a hostile file fails with the right code and a message naming it. */
#ifndef SB_MEASURED_UTIL_H
#define SB_MEASURED_UTIL_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"

/* Write n bytes of b as the file path. */
static inline void write_bytes(const char *path, const void *b, size_t n) {
    FILE *fp = fopen(path, "wb");
    CHECK(fp != NULL);
    if (!fp) return;
    fwrite(b, 1, n, fp);
    fclose(fp);
}

static inline void write_text(const char *path, const char *text) { write_bytes(path, text, strlen(text)); }

/* The whole file into *out (malloc'ed); its size, -1 when unreadable. */
static inline long file_bytes(const char *path, unsigned char **out) {
    FILE *fp = fopen(path, "rb");
    if (!fp) return -1;
    fseek(fp, 0, SEEK_END);
    long n = ftell(fp);
    fseek(fp, 0, SEEK_SET);
    *out = malloc((size_t)n);
    if (fread(*out, 1, (size_t)n, fp) != (size_t)n) n = -1;
    fclose(fp);
    return n;
}

/* Expect opening path (options o, may be NULL) to fail with `code`, the
 * message naming the file and, when want is not NULL, containing want. */
static inline void expect_fail(const char *path, const sb_measured_opts_t *o, sb_result_t code, const char *want) {
    sb_context_t *ctx;
    sb_context_create(&ctx);
    sb_source_t *s = NULL;
    sb_result_t r = sb_measured_open(ctx, path, o, &s, NULL);
    const char *msg = sb_context_last_error(ctx);
    CHECKF(r == code, "%s: got %s, want %s (%s)", path, sb_result_name(r), sb_result_name(code), msg);
    CHECK(s == NULL);
    CHECKF(strstr(msg, path) != NULL, "message does not name the file: %s", msg);
    if (want) CHECKF(strstr(msg, want) != NULL, "message lacks '%s': %s", want, msg);
    sb_source_destroy(s);
    sb_context_destroy(ctx);
}

#endif
