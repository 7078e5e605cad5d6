/* Fuzz the EXR reader: the input becomes g_00.exr and h_00.exr of a folder
 * read by sb_factors_read_exr.  An input "SBX2" + n (uint32, little
 * endian) + n bytes + rest is split: the n bytes are g_00.exr, the rest
 * h_00.exr (seeds made from a real pair reach the pixel decoder; the same
 * bytes in both files stop at the side check).  Invariants: failures come
 * with a documented code and a message; what is read is finite; a FLOAT
 * write of it reads back as sb_factors_quantize predicts. */
#include <math.h>
#include <string.h>

#include "fuzz.h"
#include "sepbrdf/sepbrdf.h"

static int same_textures(const sb_factors_t *a, const sb_factors_t *b) {
    size_t J = sb_factors_terms(a), C = sb_factors_channels(a);
    if (sb_factors_terms(b) != J || sb_factors_channels(b) != C) return 0;
    for (int s = 0; s < 2; s++) {
        size_t w, h;
        sb_factors_size(a, s, &w, &h);
        for (size_t j = 0; j < J; j++)
            for (size_t c = 0; c < C; c++)
                if (memcmp(sb_factors_tex_const(a, s, j, c), sb_factors_tex_const(b, s, j, c), w * h * sizeof(double)))
                    return 0;
        for (size_t j = 0; j < J; j++)
            for (size_t c = 0; c < C; c++)
                if (sb_factors_sigma(a, j, c) != sb_factors_sigma(b, j, c)) return 0;
    }
    return 1;
}

/* What was read: finite; a FLOAT write reads back exactly as
 * sb_factors_quantize says (one codec), which is the identity when every
 * value is a float; quantizing twice changes nothing. */
static void check_roundtrip(sb_context_t *ctx, const sb_factors_t *f, const char *dir) {
    size_t J = sb_factors_terms(f), C = sb_factors_channels(f);
    int floats = 1;
    for (int s = 0; s < 2; s++) {
        size_t w, h;
        sb_factors_size(f, s, &w, &h);
        for (size_t j = 0; j < J; j++)
            for (size_t c = 0; c < C; c++) {
                const double *t = sb_factors_tex_const(f, s, j, c);
                for (size_t i = 0; i < w * h; i++) {
                    SB_FUZZ_CHECK(isfinite(t[i]));
                    floats &= (double)(float)t[i] == t[i];
                }
            }
    }
    if (J > 4) return; /* a few files per input at most */
    char out[8192];
    snprintf(out, sizeof out, "%s/rt", dir);
    sb_exr_opts_t eo = {0};
    sb_factors_t *q = NULL, *q2 = NULL, *g = NULL;
    sb_result_t rq = sb_factors_quantize(ctx, f, &eo, &q, NULL);
    sb_result_t rw = sb_factors_write_exr(ctx, f, out, &eo);
    SB_FUZZ_CHECK(rq == rw); /* quantize refuses exactly what the writer refuses */
    if (rw == SB_OK) {
        SB_FUZZ_CHECK(sb_factors_read_exr(ctx, out, &g) == SB_OK);
        SB_FUZZ_CHECK(same_textures(q, g));
        if (floats) SB_FUZZ_CHECK(same_textures(f, g));
        SB_FUZZ_CHECK(sb_factors_quantize(ctx, q, &eo, &q2, NULL) == SB_OK && same_textures(q, q2));
    }
    sb_factors_destroy(q);
    sb_factors_destroy(q2);
    sb_factors_destroy(g);
}

SB_FUZZ_ENTRY(exr) {
    const char *dir = sb_fuzz_setup();
    char sub[8192];
    snprintf(sub, sizeof sub, "%s/exr", dir);
    static int made;
    if (!made) {
        char rt[8192];
        snprintf(rt, sizeof rt, "%s/rt", dir);
        SB_FUZZ_CHECK(sb_fuzz_mkdir(sub) == 0 && sb_fuzz_mkdir(rt) == 0);
        made = 1;
    }
    const uint8_t *g = data, *h = data;
    size_t ng = size, nh = size;
    if (size >= 8 && memcmp(data, "SBX2", 4) == 0) {
        size_t n = (size_t)data[4] | (size_t)data[5] << 8 | (size_t)data[6] << 16 | (size_t)data[7] << 24;
        if (n > size - 8) n = size - 8;
        g = data + 8;
        ng = n;
        h = g + n;
        nh = size - 8 - n;
    }
    if (sb_fuzz_write(sub, "g_00.exr", g, ng) || sb_fuzz_write(sub, "h_00.exr", h, nh)) return 0;
    sb_context_t *ctx;
    SB_FUZZ_CHECK(sb_context_create(&ctx) == SB_OK);
    sb_factors_t *f = (sb_factors_t *)1;
    sb_result_t r = sb_factors_read_exr(ctx, sub, &f);
    SB_FUZZ_CHECK((unsigned)r < SB_RESULT_COUNT_);
    if (r == SB_OK) {
        check_roundtrip(ctx, f, dir);
        sb_factors_destroy(f);
    } else {
        SB_FUZZ_CHECK(f == NULL && sb_context_last_error(ctx)[0] != 0);
    }
    sb_context_destroy(ctx);
    return 0;
}
