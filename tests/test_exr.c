/* EXR textures: bit-exact FLOAT round trips, HALF with per-texture scales,
 * atomic writes, and readers fed missing, damaged and forged files. */
#include <dirent.h>
#include <float.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"

/* J terms of C channels, g gw x gh, h hw x hh, random values in
 * [-1, 1] * 10^(term-dependent exponent), sigma, errors and metadata. */
static sb_factors_t *make_factors(size_t J, size_t C, size_t gw, size_t gh, size_t hw, size_t hh,
                                  unsigned long long seed) {
    sb_factors_t *f = NULL;
    CHECK(sb_factors_create(NULL, J, C, gw, gh, hw, hh, &f) == SB_OK);
    if (!f) return NULL;
    for (int s = 0; s < 2; s++)
        for (size_t j = 0; j < J; j++)
            for (size_t c = 0; c < C; c++) {
                size_t w, h;
                sb_factors_size(f, s, &w, &h);
                double *t = sb_factors_tex(f, s, j, c);
                for (size_t i = 0; i < w * h; i++)
                    t[i] = (2 * sb_rand01(&seed) - 1) * pow(10, (double)j - 1);
            }
    sb_factor_errors_t *e = sb_factors_errors_mut(f);
    for (size_t j = 0; j < J; j++) {
        for (size_t c = 0; c < C; c++)
            sb_factors_set_sigma(f, j, c, 10 * sb_rand01(&seed) / (double)(j + 1));
        e->rel_rms[j * 4 + 3] = 0.5 * sb_rand01(&seed) / (double)(j + 1);
    }
    CHECK(sb_factors_set_meta(f, "param", "io:res=8") == SB_OK);
    CHECK(sb_factors_set_meta(f, "source", "probe with spaces, commas & \"quotes\"") == SB_OK);
    CHECK(sb_factors_set_meta(f, "form", "cos") == SB_OK);
    /* longer than 31 characters with the prefix: needs EXR long names */
    CHECK(sb_factors_set_meta(f, "a_rather_long_metadata_key_name", "x") == SB_OK);
    CHECK(sb_factors_set_meta(f, "empty", "") == SB_OK);
    return f;
}

static int same_float_bits(double a, double b) {
    float fa = (float)a, fb = (float)b;
    return memcmp(&fa, &fb, sizeof fa) == 0 && (double)fa == b;
}

/* Every texel of b is (double)(float) of a's, sigma likewise, metadata equal. */
static void check_exact(const sb_factors_t *a, const sb_factors_t *b) {
    size_t J = sb_factors_terms(a), C = sb_factors_channels(a);
    CHECK(sb_factors_terms(b) == J && sb_factors_channels(b) == C);
    if (sb_factors_terms(b) != J || sb_factors_channels(b) != C) return;
    for (int s = 0; s < 2; s++) {
        size_t w, h, w2, h2;
        sb_factors_size(a, s, &w, &h);
        sb_factors_size(b, s, &w2, &h2);
        CHECK(w == w2 && h == h2);
        if (w != w2 || h != h2) return;
        for (size_t j = 0; j < J; j++)
            for (size_t c = 0; c < C; c++) {
                const double *ta = sb_factors_tex_const(a, s, j, c), *tb = sb_factors_tex_const(b, s, j, c);
                size_t bad = 0;
                for (size_t i = 0; i < w * h; i++)
                    bad += !same_float_bits(ta[i], tb[i]);
                CHECKF(bad == 0, "side %d term %zu channel %zu: %zu texels differ", s, j, c, bad);
            }
    }
    for (size_t j = 0; j < J; j++) {
        for (size_t c = 0; c < C; c++)
            CHECK(sb_factors_sigma(b, j, c) == (double)(float)sb_factors_sigma(a, j, c));
        CHECK(sb_factors_errors(b)->rel_rms[j * 4 + 3] == (double)(float)sb_factors_errors(a)->rel_rms[j * 4 + 3]);
    }
    CHECK(sb_factors_meta_count(b) == sb_factors_meta_count(a));
    for (size_t i = 0; i < sb_factors_meta_count(a); i++) {
        const char *k, *v;
        sb_factors_meta_at(a, i, &k, &v);
        const char *v2 = sb_factors_get_meta(b, k);
        CHECKF(v2 && strcmp(v, v2) == 0, "metadata %s: \"%s\" vs \"%s\"", k, v, v2 ? v2 : "(absent)");
    }
}

static char *path_in(const char *dir, const char *name) {
    static char buf[2][4096];
    static int k;
    k ^= 1; /* two live results, for commands naming two files */
    if (snprintf(buf[k], sizeof buf[k], "%s/%s", dir, name) >= (int)sizeof buf[k]) buf[k][0] = 0;
    return buf[k];
}

/* Number of entries of dir other than . and .. */
static int count_entries(const char *dir) {
    DIR *d = opendir(dir);
    if (!d) return -1;
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)))
        if (strcmp(e->d_name, ".") && strcmp(e->d_name, "..")) n++;
    closedir(d);
    return n;
}

static unsigned char *slurp(const char *path, size_t *n) {
    *n = 0;
    FILE *fp = fopen(path, "rb");
    if (!fp) return NULL;
    fseek(fp, 0, SEEK_END);
    long len = ftell(fp);
    fseek(fp, 0, SEEK_SET);
    unsigned char *b = malloc((size_t)len + 1);
    *n = fread(b, 1, (size_t)len, fp);
    fclose(fp);
    return b;
}

static void spit(const char *path, const unsigned char *b, size_t n) {
    FILE *fp = fopen(path, "wb");
    CHECK(fp != NULL);
    if (!fp) return;
    CHECK(fwrite(b, 1, n, fp) == n);
    fclose(fp);
}

/* Offset of the first occurrence of pat (len bytes) in b, or -1. */
static long find_bytes(const unsigned char *b, size_t n, const void *pat, size_t len) {
    for (size_t i = 0; i + len <= n; i++)
        if (memcmp(b + i, pat, len) == 0) return (long)i;
    return -1;
}

/* Read dir, expecting failure with `code` (or any failure for SB_OK). */
static void expect_read_error(const char *dir, sb_result_t code, const char *mention) {
    sb_context_t *ctx;
    sb_context_create(&ctx);
    sb_factors_t *g = NULL;
    sb_result_t r = sb_factors_read_exr(ctx, dir, &g);
    CHECKF(r != SB_OK, "read succeeded");
    if (code != SB_OK)
        CHECKF(r == code, "got %s, expected %s (%s)", sb_result_name(r), sb_result_name(code),
               sb_context_last_error(ctx));
    CHECK(g == NULL);
    if (mention)
        CHECKF(strstr(sb_context_last_error(ctx), mention), "message \"%s\" does not name %s",
               sb_context_last_error(ctx), mention);
    sb_factors_destroy(g);
    sb_context_destroy(ctx);
}

static void write_ok(const sb_factors_t *f, const char *dir, int half) {
    sb_context_t *ctx;
    sb_context_create(&ctx);
    sb_exr_opts_t o = {half};
    sb_result_t r = sb_factors_write_exr(ctx, f, dir, &o);
    CHECKF(r == SB_OK, "write: %s %s", sb_result_name(r), sb_context_last_error(ctx));
    sb_context_destroy(ctx);
}

static sb_factors_t *read_ok(const char *dir) {
    sb_context_t *ctx;
    sb_context_create(&ctx);
    sb_factors_t *g = NULL;
    sb_result_t r = sb_factors_read_exr(ctx, dir, &g);
    CHECKF(r == SB_OK, "read: %s %s", sb_result_name(r), sb_context_last_error(ctx));
    sb_context_destroy(ctx);
    return g;
}

SB_TEST(names) {
    char b[32];
    sb_exr_name(SB_SIDE_G, 0, b, sizeof b);
    CHECK(strcmp(b, "g_00.exr") == 0);
    sb_exr_name(SB_SIDE_H, 7, b, sizeof b);
    CHECK(strcmp(b, "h_07.exr") == 0);
    sb_exr_name(SB_SIDE_G, 123, b, sizeof b);
    CHECK(strcmp(b, "g_123.exr") == 0);
}

SB_TEST(roundtrip_float_bitexact) {
    const char *dir = sb_tmpdir("exr-rt");
    sb_factors_t *f = make_factors(3, 3, 7, 5, 4, 9, 42);
    /* values that do not survive a float cast unchanged, and extremes */
    double *t = sb_factors_tex(f, SB_SIDE_G, 1, 2);
    t[0] = 0.1;
    t[1] = -1e-40; /* float subnormal */
    t[2] = 3e38;
    t[3] = -0.0;
    write_ok(f, dir, 0);
    CHECK(count_entries(dir) == 6); /* no temporaries left */
    sb_factors_t *g = read_ok(dir);
    if (g) check_exact(f, g);
    if (g) CHECK(signbit(sb_factors_tex_const(g, SB_SIDE_G, 1, 2)[3]));
    /* texel (x, y) = value y*w + x: pixel (6, 0) and (0, 1) of g 7x5 */
    if (g) CHECK(sb_factors_tex_const(g, SB_SIDE_G, 0, 0)[7] == (double)(float)sb_factors_tex_const(f, 0, 0, 0)[7]);
    sb_factors_destroy(g);
    /* writing again over the same folder replaces the files */
    write_ok(f, dir, 0);
    CHECK(count_entries(dir) == 6);
    sb_factors_destroy(f);
}

SB_TEST(roundtrip_gray) {
    const char *dir = sb_tmpdir("exr-gray");
    sb_factors_t *f = make_factors(2, 1, 3, 11, 13, 2, 7);
    write_ok(f, dir, 0);
    sb_factors_t *g = read_ok(dir);
    if (g) check_exact(f, g);
    sb_factors_destroy(g);
    sb_factors_destroy(f);
}

/* HALF: each texture scaled by a power of two to max |stored| in [512, 1024). */
SB_TEST(half_scaled) {
    char dir[4096], dir2[4096]; /* sb_tmpdir returns a static buffer */
    snprintf(dir, sizeof dir, "%s", sb_tmpdir("exr-half"));
    snprintf(dir2, sizeof dir2, "%s", sb_tmpdir("exr-half2"));
    sb_factors_t *f = make_factors(4, 3, 6, 5, 5, 6, 9);
    unsigned long long seed = 3;
    static const double mag[4] = {1e6, 1e-6, 1, 0};
    for (int s = 0; s < 2; s++)
        for (size_t j = 0; j < 4; j++)
            for (size_t c = 0; c < 3; c++) {
                double *t = sb_factors_tex(f, s, j, c);
                size_t w, h;
                sb_factors_size(f, s, &w, &h);
                for (size_t i = 0; i < w * h; i++)
                    t[i] = mag[j] * (sb_rand01(&seed) < 0.5 ? -1 : 1) * (0.25 + 0.75 * sb_rand01(&seed));
            }
    sb_factors_tex(f, SB_SIDE_H, 0, 1)[3] = 65504 * 4.0; /* beyond the plain half range */
    write_ok(f, dir, 1);
    sb_factors_t *g = read_ok(dir);
    if (!g) {
        sb_factors_destroy(f);
        return;
    }
    for (int s = 0; s < 2; s++)
        for (size_t j = 0; j < 4; j++)
            for (size_t c = 0; c < 3; c++) {
                const double *a = sb_factors_tex_const(f, s, j, c), *b = sb_factors_tex_const(g, s, j, c);
                size_t w, h;
                sb_factors_size(f, s, &w, &h);
                for (size_t i = 0; i < w * h; i++) {
                    CHECK(isfinite(b[i]));
                    /* half keeps 11 significant bits: relative 2^-11 */
                    if (a[i] == 0)
                        CHECK(b[i] == 0);
                    else
                        CHECK_REL(b[i], a[i], 4.9e-4);
                }
            }
    check_exact(g, g); /* metadata etc. of g consistent */
    for (size_t j = 0; j < 4; j++)
        for (size_t c = 0; c < 3; c++)
            CHECK(sb_factors_sigma(g, j, c) == (double)(float)sb_factors_sigma(f, j, c));
    sb_factors_destroy(g);

    /* the stored half values are exact: a second write/read changes nothing */
    g = read_ok(dir);
    write_ok(g, dir2, 1);
    sb_factors_t *g2 = read_ok(dir2);
    if (g && g2)
        for (int s = 0; s < 2; s++)
            for (size_t j = 0; j < 4; j++) {
                size_t w, h;
                sb_factors_size(g, s, &w, &h);
                CHECK(memcmp(sb_factors_tex_const(g, s, j, 0), sb_factors_tex_const(g2, s, j, 0),
                             3 * w * h * sizeof(double)) == 0);
            }
    sb_factors_destroy(g);
    sb_factors_destroy(g2);
    sb_factors_destroy(f);
}

/* Rounding to nearest even at the half quantum, and small values. */
SB_TEST(half_rounding) {
    const char *dir = sb_tmpdir("exr-hround");
    sb_factors_t *f = make_factors(1, 1, 8, 1, 1, 1, 1);
    double *t = sb_factors_tex(f, SB_SIDE_G, 0, 0);
    /* max 1000 -> scale 1, stored as is; quantum at [512, 1024) is 0.5 */
    double in[8] = {1000, 600.25, 600.75, 1.0 + 0x1p-11, 1.0 + 3 * 0x1p-11, 0x1p-24, 0x1p-26, -0.0};
    double want[8] = {1000, 600, 601, 1.0, 1.0 + 0x1p-9, 0x1p-24, 0, -0.0};
    memcpy(t, in, sizeof in);
    write_ok(f, dir, 1);
    sb_factors_t *g = read_ok(dir);
    if (g)
        for (int i = 0; i < 8; i++)
            CHECKF(sb_factors_tex_const(g, SB_SIDE_G, 0, 0)[i] == want[i], "texel %d: %.17g, expected %.17g", i,
                   sb_factors_tex_const(g, SB_SIDE_G, 0, 0)[i], want[i]);
    sb_factors_destroy(g);
    sb_factors_destroy(f);
}

SB_TEST(missing_file_error) {
    const char *dir = sb_tmpdir("exr-missing");
    expect_read_error(dir, SB_ERR_IO, "g_00.exr");
    sb_factors_t *f = make_factors(2, 3, 4, 4, 4, 4, 5);
    write_ok(f, dir, 0);
    CHECK(remove(path_in(dir, "h_01.exr")) == 0);
    expect_read_error(dir, SB_ERR_IO, "h_01.exr");
    CHECK(remove(path_in(dir, "h_00.exr")) == 0);
    expect_read_error(dir, SB_ERR_IO, "h_00.exr");
    expect_read_error("/nonexistent/sepbrdf/folder", SB_ERR_IO, NULL);
    sb_factors_destroy(f);

    sb_context_t *ctx;
    sb_context_create(&ctx);
    sb_factors_t *g = NULL;
    CHECK(sb_factors_read_exr(ctx, dir, NULL) == SB_ERR_ARG);
    CHECK(sb_factors_read_exr(ctx, NULL, &g) == SB_ERR_ARG && g == NULL);
    sb_context_destroy(ctx);
}

/* Files of one set must agree: a copy of another term or size is refused. */
SB_TEST(mismatched_files) {
    char dir[4096], other[4096]; /* sb_tmpdir returns a static buffer */
    snprintf(dir, sizeof dir, "%s", sb_tmpdir("exr-mix"));
    snprintf(other, sizeof other, "%s", sb_tmpdir("exr-mix2"));
    sb_factors_t *f = make_factors(2, 3, 4, 4, 5, 3, 5);
    sb_factors_t *f2 = make_factors(2, 3, 4, 6, 5, 3, 6);
    write_ok(f, dir, 0);
    write_ok(f2, other, 0);
    size_t n;
    unsigned char *b = slurp(path_in(dir, "h_00.exr"), &n);
    spit(path_in(dir, "h_01.exr"), b, n); /* term 0 under the name of term 1 */
    free(b);
    expect_read_error(dir, SB_ERR_FORMAT, "h_01.exr");

    write_ok(f, dir, 0);
    b = slurp(path_in(other, "g_01.exr"), &n); /* a g texture of another size */
    spit(path_in(dir, "g_01.exr"), b, n);
    free(b);
    expect_read_error(dir, SB_ERR_FORMAT, "g_01.exr");

    write_ok(f, dir, 0);
    CHECK(sb_factors_set_meta(f, "form", "cos2") == SB_OK);
    write_ok(f, other, 0);
    b = slurp(path_in(other, "h_01.exr"), &n); /* same shape, other metadata */
    spit(path_in(dir, "h_01.exr"), b, n);
    free(b);
    expect_read_error(dir, SB_ERR_FORMAT, "h_01.exr");
    sb_factors_destroy(f);
    sb_factors_destroy(f2);
}

/* Damaged and hostile files: an error code, never a crash (run under ASan). */
SB_TEST(forged_header) {
    const char *dir = sb_tmpdir("exr-forged");
    sb_factors_t *f = make_factors(2, 3, 9, 7, 4, 5, 11);
    write_ok(f, dir, 0);
    size_t n;
    unsigned char *orig = slurp(path_in(dir, "g_00.exr"), &n);
    CHECK(orig && n > 200);
    if (!orig) return;
    unsigned char *b = malloc(n);

    /* not an EXR at all */
    spit(path_in(dir, "g_00.exr"), (const unsigned char *)"P6\n1 1\n255\nabc", 14);
    expect_read_error(dir, SB_ERR_FORMAT, "g_00.exr");
    spit(path_in(dir, "g_00.exr"), (const unsigned char *)"", 0);
    expect_read_error(dir, SB_OK, "g_00.exr");

    /* truncated at many lengths: in the header, the offset table, the pixels */
    for (size_t len = 4; len < n; len += len < 64 ? 13 : 97) {
        spit(path_in(dir, "g_00.exr"), orig, len);
        expect_read_error(dir, SB_OK, "g_00.exr");
    }

    /* bytes overwritten all over the file; either refused or decoded to
     * finite values (zip data has no checksum that would catch all) */
    unsigned long long seed = 99;
    for (int trial = 0; trial < 200; trial++) {
        memcpy(b, orig, n);
        size_t at = (size_t)(sb_rand01(&seed) * (double)n);
        for (int k = 0; k < 4 && at + (size_t)k < n; k++)
            b[at + (size_t)k] = (unsigned char)(sb_rand01(&seed) * 256);
        spit(path_in(dir, "g_00.exr"), b, n);
        sb_context_t *ctx;
        sb_context_create(&ctx);
        sb_factors_t *g = NULL;
        sb_result_t r = sb_factors_read_exr(ctx, dir, &g);
        CHECK((r == SB_OK) == (g != NULL));
        sb_factors_destroy(g);
        sb_context_destroy(ctx);
    }

    /* forged data window: 65536 x 65536 g textures exceed the memory limit */
    memcpy(b, orig, n);
    long at = find_bytes(b, n, "dataWindow\0box2i\0", 17);
    CHECK(at >= 0);
    if (at >= 0) {
        int32_t big = 65535;
        memcpy(b + at + 17 + 4 + 8, &big, 4);
        memcpy(b + at + 17 + 4 + 12, &big, 4);
        spit(path_in(dir, "g_00.exr"), b, n);
        size_t old = sb_memory_limit();
        sb_set_memory_limit((size_t)1 << 30);
        expect_read_error(dir, SB_OK, "g_00.exr");
        sb_set_memory_limit(old);
    }

    /* forged term count */
    memcpy(b, orig, n);
    at = find_bytes(b, n, "sepbrdf.terms\0int\0", 18);
    CHECK(at >= 0);
    if (at >= 0) {
        int32_t big = 0x7fffffff;
        memcpy(b + at + 18 + 4, &big, 4);
        spit(path_in(dir, "g_00.exr"), b, n);
        expect_read_error(dir, SB_OK, "g_00.exr");
        big = -3;
        memcpy(b + at + 18 + 4, &big, 4);
        spit(path_in(dir, "g_00.exr"), b, n);
        expect_read_error(dir, SB_ERR_FORMAT, "g_00.exr");
    }

    /* wrong channel type: B becomes UINT (same size, the file stays valid) */
    memcpy(b, orig, n);
    at = find_bytes(b, n, "channels\0chlist\0", 16);
    CHECK(at >= 0 && b[at + 16 + 4] == 'B');
    if (at >= 0) {
        int32_t uint_type = 0;
        memcpy(b + at + 16 + 4 + 2, &uint_type, 4);
        spit(path_in(dir, "g_00.exr"), b, n);
        expect_read_error(dir, SB_ERR_FORMAT, "g_00.exr");
    }

    /* a missing attribute (renamed), and one of the wrong type */
    memcpy(b, orig, n);
    at = find_bytes(b, n, "sepbrdf.sigma", 13);
    CHECK(at >= 0);
    if (at >= 0) {
        b[at + 12] = 'b';
        spit(path_in(dir, "g_00.exr"), b, n);
        expect_read_error(dir, SB_ERR_FORMAT, "sepbrdf.sigma");
    }
    memcpy(b, orig, n);
    at = find_bytes(b, n, "sepbrdf.scale\0float\0", 20);
    CHECK(at >= 0);
    if (at >= 0) {
        memcpy(b + at + 14, "v2i  ", 5); /* not a known type: opaque */
        spit(path_in(dir, "g_00.exr"), b, n);
        expect_read_error(dir, SB_OK, "g_00.exr");
    }

    /* a zero scale */
    memcpy(b, orig, n);
    at = find_bytes(b, n, "sepbrdf.scale\0float\0", 20);
    if (at >= 0) {
        float zero = 0;
        memcpy(b + at + 20 + 4, &zero, 4);
        spit(path_in(dir, "g_00.exr"), b, n);
        expect_read_error(dir, SB_ERR_FORMAT, "sepbrdf.scale");
    }

    /* the original still reads */
    spit(path_in(dir, "g_00.exr"), orig, n);
    sb_factors_t *g = read_ok(dir);
    if (g) check_exact(f, g);
    sb_factors_destroy(g);
    free(b);
    free(orig);
    sb_factors_destroy(f);
}

/* A failing write leaves the folder as it was: no temporaries, no partial set. */
SB_TEST(write_failure_leaves_nothing) {
    const char *dir = sb_tmpdir("exr-fail");
    sb_factors_t *f = make_factors(3, 3, 4, 4, 4, 4, 13);
    sb_context_t *ctx;
    sb_context_create(&ctx);
    sb_exr_opts_t o = {0};
    sb_factors_tex(f, SB_SIDE_H, 2, 1)[5] = NAN; /* the last file fails */
    sb_result_t r = sb_factors_write_exr(ctx, f, dir, &o);
    CHECKF(r == SB_ERR_NUMERIC, "%s", sb_result_name(r));
    CHECK(strstr(sb_context_last_error(ctx), "h_02.exr") != NULL);
    CHECK(count_entries(dir) == 0);
    sb_factors_tex(f, SB_SIDE_H, 2, 1)[5] = -INFINITY; /* named by its texel, as a NaN */
    CHECK(sb_factors_write_exr(ctx, f, dir, &o) == SB_ERR_NUMERIC);
    CHECK(strstr(sb_context_last_error(ctx), "texel (1, 1)") && strstr(sb_context_last_error(ctx), "not finite"));
    CHECK(count_entries(dir) == 0);
    sb_factors_tex(f, SB_SIDE_H, 2, 1)[5] = 1e39; /* beyond float: the BRDF is outside the storage range */
    CHECK(sb_factors_write_exr(ctx, f, dir, &o) == SB_ERR_NUMERIC);
    CHECK(strstr(sb_context_last_error(ctx), "h_02.exr") && !strstr(sb_context_last_error(ctx), ".tmp-"));
    CHECK(count_entries(dir) == 0);
    o.half = 1; /* HALF takes it with a scale */
    CHECK(sb_factors_write_exr(ctx, f, dir, &o) == SB_OK);
    CHECK(count_entries(dir) == 6);
    /* (still HALF: the content is checked before the folder is touched) */
    CHECK(sb_factors_write_exr(ctx, f, "/nonexistent/sepbrdf/folder", &o) == SB_ERR_IO);
    o.half = 0;
    CHECK(sb_factors_write_exr(ctx, NULL, dir, &o) == SB_ERR_ARG);
    sb_factors_tex(f, SB_SIDE_H, 2, 1)[5] = 0;
    CHECK(sb_factors_set_meta(f, "sigma", "x") == SB_OK); /* collides with a fixed attribute */
    CHECK(sb_factors_write_exr(ctx, f, dir, &o) == SB_ERR_ARG);
    sb_context_destroy(ctx);
    sb_factors_destroy(f);
}

SB_TEST(exrheader_reads) {
    char out[65536];
    if (sb_run("command -v exrheader", out, sizeof out) != 0) SKIP("exrheader not installed (Debian: openexr)");
    const char *dir = sb_tmpdir("exr-tool");
    sb_factors_t *f = make_factors(1, 3, 7, 5, 4, 9, 17);
    write_ok(f, dir, 0);
    char cmd[8192];
    CHECK(snprintf(cmd, sizeof cmd, "exrheader '%s'", path_in(dir, "g_00.exr")) < (int)sizeof cmd);
    int rc = sb_run(cmd, out, sizeof out);
    CHECKF(rc == 0, "exrheader exit %d: %s", rc, out);
    CHECKF(strstr(out, "sepbrdf.sigma") != NULL, "no sepbrdf.sigma in: %s", out);
    CHECK(strstr(out, "sepbrdf.a_rather_long_metadata_key_name") != NULL);
    CHECKF(strstr(out, "compression") != NULL && strstr(out, "none") != NULL, "not uncompressed: %s", out);
    /* the C++ library also decodes every pixel (FLOAT and HALF) */
    if (sb_run("command -v exrmaketiled", out, sizeof out) == 0) {
        for (int half = 0; half < 2; half++) {
            write_ok(f, dir, half);
            CHECK(snprintf(cmd, sizeof cmd, "exrmaketiled '%s' '%s'", path_in(dir, "h_00.exr"),
                           path_in(dir, "tiled.exr")) < (int)sizeof cmd);
            rc = sb_run(cmd, out, sizeof out);
            CHECKF(rc == 0, "exrmaketiled (%s) exit %d: %s", half ? "HALF" : "FLOAT", rc, out);
        }
    }
    sb_factors_destroy(f);
}

/* A ZIP chunk whose deflated size equals its raw size (768 bytes here,
 * with Debian 12's zlib): OpenEXRCore before the fix of
 * AcademySoftwareFoundation/openexr#2306 stored the deflated bytes, which
 * every reader takes for raw pixels.  The writer must store such a chunk
 * raw; the pixels then read back bit for bit.  (With another zlib the
 * sizes may differ and the case only checks an ordinary round trip.) */
SB_TEST(zip_chunk_without_gain) {
    FILE *fp = fopen(SB_SOURCE_DIR "/tests/data/exr/zip-no-gain-8x8-rgb.f32", "rb");
    float px[3 * 64];
    CHECK(fp && fread(px, sizeof px, 1, fp) == 1);
    if (fp) fclose(fp);
    sb_factors_t *f = make_factors(1, 3, 8, 8, 1, 1, 3);
    for (size_t c = 0; f && c < 3; c++)
        for (size_t i = 0; i < 64; i++)
            sb_factors_tex(f, SB_SIDE_G, 0, c)[i] = px[c * 64 + i];
    const char *dir = sb_tmpdir("exr-zip");
    write_ok(f, dir, 0);
    sb_factors_t *g = read_ok(dir);
    if (f && g) check_exact(f, g);
    sb_factors_destroy(g);
    sb_factors_destroy(f);
}
