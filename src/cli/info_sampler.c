/* sepbrdf info: the sampler tables of a set (sampler.bin; the layout in
 * sepbrdf/sampler.h), described and checked as the GLSL sampler reads
 * them: the header's sizes against the file's, every texel finite, the
 * shares (cosine s, GGX lobe s_l and its alpha) in their ranges, every
 * CDF non-decreasing in [0, 1] and ending at 1, the integrals and the
 * half-vector rows' weights not negative, the row cells' measures
 * positive (row layouts), and every texel no layout writes 0.  A file that fails is refused
 * naming the layer and texel (no command reads it back: the GLSL would
 * sample it as it is). */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "cli.h"

#define HEAD 24
#define MAX_FILE ((size_t)1 << 31)

typedef struct tables {
    const char *path;
    const unsigned char *data; /* the texels */
    size_t W, H, layers, C, K; /* K = J C: the CDF layers; layer K the shares */
    int half_rows;             /* layers 2 K + 1: the half-vector rows' weights after layer K */
} tables_t;

static uint32_t get_u32(const unsigned char *b) {
    return (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
}

static float texel(const tables_t *t, size_t k, size_t x, size_t y) {
    uint32_t bits = get_u32(t->data + 4 * ((k * (t->H + 1) + y) * (t->W + 1) + x));
    float v;
    memcpy(&v, &bits, sizeof v);
    return v;
}

int info_is_sampler(const char *path) {
    struct stat st;
    if (stat(path, &st) != 0 || !S_ISREG(st.st_mode)) return 0;
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    unsigned char head[8];
    FILE *fp = fopen(path, "rb");
    size_t got = fp ? fread(head, 1, sizeof head, fp) : 0;
    if (fp) fclose(fp);
    return strcmp(base, "sampler.bin") == 0 || (got == sizeof head && memcmp(head, "sbsampl1", 8) == 0);
}

/* The header's sizes into t; 0, or -1 with the reason said. */
static int header(tables_t *t, const unsigned char *d, size_t n) {
    const char *p = t->path;
    if (n < HEAD || memcmp(d, "sbsampl1", 8) != 0) {
        cli_error("info", "%s: not sampler tables (%s)", p,
                  n < HEAD ? "shorter than the 24 bytes of the header" : "no \"sbsampl1\" at its start");
        return -1;
    }
    uint32_t W1 = get_u32(d + 8), H1 = get_u32(d + 12), L = get_u32(d + 16), C = get_u32(d + 20);
    if (W1 < 2 || H1 < 2 || C < 1 || C > 3 || L < C + 1 || (L - 1) % C != 0) {
        cli_error("info",
                  "%s: damaged header: width %u, height %u, layers %u, channels %u (need width and height >= 2, "
                  "1 to 3 channels, layers J C + 1 or 2 J C + 1)",
                  p, W1, H1, L, C);
        return -1;
    }
    uint64_t want = (uint64_t)W1 * H1 * L * 4 + HEAD; /* each below 2^32: no overflow */
    if (want != n) {
        cli_error("info", "%s: holds %zu bytes, its header's %u x %u texels x %u layers need %llu", p, n, W1, H1, L,
                  (unsigned long long)want);
        return -1;
    }
    t->data = d + HEAD, t->W = W1 - 1, t->H = H1 - 1, t->layers = L, t->C = C;
    return 0;
}

/* Whether layer k is a CDF layer: every row's conditional CDF ends at 1
 * (texel (W - 1, y)); the shares' layer holds the row cells' measures
 * there. */
static int cdf_layer(const tables_t *t, size_t k) {
    for (size_t y = 0; y < t->H; y++)
        if (texel(t, k, t->W - 1, y) != 1) return 0;
    return 1;
}

/* Which layer holds the shares: the last (layers J C + 1), or the middle
 * one where layers are 2 J C + 1 and the middle is no CDF layer (the
 * half-vector rows' weights after it; their unused texels are checked
 * with the others, so that a damaged one is named as such, not read as
 * the last layer's cosine share). */
static int shares_layer(tables_t *t) {
    const float min = (float)SB_SAMPLER_MIN_SHARE;
    size_t mid = (t->layers - 1) / 2;
    float last = texel(t, t->layers - 1, 0, t->H), m = texel(t, mid, 0, t->H);
    int half = !(last >= min && last <= 1) && (t->layers - 1) % (2 * t->C) == 0 && !cdf_layer(t, mid);
    size_t k = half ? mid : t->layers - 1;
    float s0 = half ? m : last;
    if (!(s0 >= min && s0 <= 1)) {
        cli_error("info", "%s: layer %zu, texel (0, %zu): cosine share %.9g outside [%.9g, 1]", t->path, k, t->H,
                  (double)s0, (double)min);
        return -1;
    }
    t->K = k, t->half_rows = half;
    float s = texel(t, t->K, 0, t->H), sl = texel(t, t->K, t->W, t->H), a = texel(t, t->K, t->W, 0);
    const char *bad = !(sl >= 0 && (double)s + sl <= 1 + 1e-6)                  ? "GGX lobe share"
                      : sl > 0 && !(a >= (float)SB_SAMPLER_MIN_ALPHA && a <= 1) ? "GGX lobe alpha"
                      : sl == 0 && a != 0                                       ? "alpha without a lobe"
                                                                                : NULL;
    if (bad)
        cli_error("info",
                  "%s: layer %zu: %s out of range (cosine share %.9g, lobe share %.9g at (%zu, %zu), alpha %.9g "
                  "at (%zu, 0); need s + s_l <= 1, alpha in [%g, 1] with a lobe, 0 without)",
                  t->path, t->K, bad, (double)s, (double)sl, t->W, t->H, (double)a, t->W, SB_SAMPLER_MIN_ALPHA);
    return bad ? -1 : 0;
}

/* One CDF of n texels from (x0, y0) stepping (dx, dy): non-decreasing in
 * [0, 1], the last 1; 0 or -1 with the texel said. */
static int cdf_ok(const tables_t *t, size_t k, size_t x0, size_t y0, size_t dx, size_t dy, size_t n, const char *what) {
    float prev = 0;
    for (size_t i = 0; i < n; i++) {
        size_t x = x0 + i * dx, y = y0 + i * dy;
        float v = texel(t, k, x, y);
        const char *why = v < prev               ? "decreases"
                          : v > 1                ? "exceeds 1"
                          : i + 1 == n && v != 1 ? "does not end at 1"
                                                 : NULL;
        if (why) {
            cli_error("info", "%s: layer %zu: the %s %s at texel (%zu, %zu): %.9g after %.9g", t->path, k, what, why, x,
                      y, (double)v, (double)prev);
            return -1;
        }
        prev = v;
    }
    return 0;
}

/* Texel (x, y) of layer k, one no layout writes but 0 (the GLSL sampler
 * does not read it): 0, or -1 naming it (a damaged file). */
static int unused_ok(const tables_t *t, size_t k, size_t x, size_t y, const char *what) {
    float v = texel(t, k, x, y);
    if (v == 0) return 0;
    cli_error("info", "%s: layer %zu, texel (%zu, %zu): %.9g in %s, written 0 (the GLSL sampler does not read it)",
              t->path, k, x, y, (double)v, what);
    return -1;
}

/* The shares' layer K: the row layouts (io, io-area, hd, iso) hold each
 * row cell's measure m_r at (x < W, y < H), by which the GLSL pdf divides
 * (0 gave an infinite pdf, a negative one a negative pdf, both described
 * as whole); the column layouts (vndf, vh) hold none: 0 there and at the
 * row layouts' edges.  Told apart by the most cells. */
static int measures_ok(const tables_t *t) {
    size_t nonzero = 0, k = t->K;
    for (size_t y = 0; y < t->H; y++)
        for (size_t x = 0; x < t->W; x++)
            nonzero += texel(t, k, x, y) != 0;
    int rows = t->half_rows || 2 * nonzero > t->W * t->H;
    for (size_t y = 0; y < t->H; y++)
        for (size_t x = 0; x < t->W; x++)
            if (rows && !(texel(t, k, x, y) > 0)) {
                cli_error("info",
                          "%s: layer %zu, texel (%zu, %zu): row cell measure %.9g is not positive (the GLSL pdf "
                          "divides by it)",
                          t->path, k, x, y, (double)texel(t, k, x, y));
                return -1;
            } else if (!rows && unused_ok(t, k, x, y, "the shares layer of a column layout") != 0) {
                return -1;
            }
    for (size_t x = 1; !rows && x < t->W; x++)
        if (unused_ok(t, k, x, t->H, "the shares layer of a column layout") != 0) return -1;
    for (size_t y = 1; !rows && y < t->H; y++)
        if (unused_ok(t, k, t->W, y, "the shares layer of a column layout") != 0) return -1;
    return 0;
}

/* Every texel finite; the CDFs, integrals and weights; 0 or -1. */
static int tables_ok(tables_t *t) {
    for (size_t k = 0; k < t->layers; k++)
        for (size_t y = 0; y <= t->H; y++)
            for (size_t x = 0; x <= t->W; x++)
                if (!isfinite(texel(t, k, x, y))) {
                    cli_error("info", "%s: layer %zu, texel (%zu, %zu): %g (not finite)", t->path, k, x, y,
                              (double)texel(t, k, x, y));
                    return -1;
                }
    if (shares_layer(t) != 0) return -1;
    for (size_t k = 0; k < t->K; k++) {
        if (cdf_ok(t, k, t->W, 0, 0, 1, t->H, "marginal CDF (column W)") != 0) return -1;
        for (size_t y = 0; y < t->H; y++)
            if (cdf_ok(t, k, 0, y, 1, 0, t->W, "row's CDF") != 0) return -1;
        if (texel(t, k, 0, t->H) < 0) {
            cli_error("info", "%s: layer %zu, texel (0, %zu): integral %.9g is negative", t->path, k, t->H,
                      (double)texel(t, k, 0, t->H));
            return -1;
        }
    }
    if (measures_ok(t) != 0) return -1;
    for (size_t k = 0; k < t->layers; k++) /* texels no layout writes: row H past the integral, the weights' edges */
        for (size_t x = k < t->K ? 1 : 0; k != t->K && x <= t->W; x++)
            if (unused_ok(t, k, x, t->H,
                          k < t->K ? "a CDF layer's row H past the integral" : "a weights layer's row H") != 0)
                return -1;
    for (size_t k = t->K + 1; k < t->layers; k++)
        for (size_t y = 0; y < t->H; y++)
            if (unused_ok(t, k, t->W, y, "a weights layer's column W") != 0) return -1;
    for (size_t k = t->K + 1; t->half_rows && k < t->layers; k++)
        for (size_t y = 0; y < t->H; y++)
            for (size_t x = 0; x < t->W; x++)
                if (texel(t, k, x, y) < 0) {
                    cli_error("info", "%s: layer %zu, texel (%zu, %zu): weight %.9g is negative", t->path, k, x, y,
                              (double)texel(t, k, x, y));
                    return -1;
                }
    return 0;
}

static void print(const tables_t *t, FILE *out, int json) {
    float s = texel(t, t->K, 0, t->H), sl = texel(t, t->K, t->W, t->H), a = texel(t, t->K, t->W, 0);
    if (json) {
        sb_json_t j = {out, 0, {0}};
        sb_json_begin_object(&j, NULL);
        sb_json_string(&j, "file", t->path);
        sb_json_string(&j, "kind", "sampler tables");
        sb_json_int(&j, "width", (long long)t->W);
        sb_json_int(&j, "height", (long long)t->H);
        sb_json_int(&j, "layers", (long long)t->layers);
        sb_json_int(&j, "channels", (long long)t->C);
        sb_json_int(&j, "terms", (long long)(t->K / t->C));
        sb_json_bool(&j, "half_rows", t->half_rows);
        sb_json_number(&j, "cosine_share", s);
        sb_json_number(&j, "lobe_share", sl);
        sb_json_number(&j, "lobe_alpha", a);
        sb_json_end_object(&j);
        return;
    }
    fprintf(out, "%s: sepbrdf sampler tables (the GLSL sampler's sb_cdf, an R32F texture array)\n", t->path);
    fprintf(out, "  cells      %zu x %zu, %zu layers: J = %zu terms x %zu channels%s\n", t->W, t->H, t->layers,
            t->K / t->C, t->C, t->half_rows ? ", then the half-vector rows' weights" : "");
    fprintf(out, "  shares     cosine %.9g, GGX lobe %.9g", (double)s, (double)sl);
    if (sl > 0) fprintf(out, " (alpha %.9g)", (double)a);
    fprintf(out, ", factored %.9g\n", 1 - (double)s - (double)sl);
}

int info_sampler(const char *path, FILE *out, int json) {
    char *text = NULL;
    size_t n = 0;
    int e = cli_read_file(path, MAX_FILE, &text, &n);
    if (e) {
        cli_error("info", "%s: cannot read: %s", path, cli_read_why(e));
        return EXIT_IO;
    }
    tables_t t = {.path = path};
    int ok = header(&t, (const unsigned char *)text, n) == 0 && tables_ok(&t) == 0;
    if (ok && out) print(&t, out, json);
    free(text);
    return ok ? EXIT_OK : EXIT_IO;
}
