/* Cornell / pbrt spectral .brdf tables (measured.h): the reader. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "source/gonio_impl.h"
#include "util/internal.h"

#define MAX_WAVELENGTHS 4096

/* Cornell / pbrt .brdf state: n wavelengths (have read so far), their
 * XYZ-to-RGB weights w (3 x n), one row's values and fields. */
typedef struct cornell {
    size_t n, have;
    double *wl, *w, *vals;
    char **fields;
} cornell_t;

/* The wavelength count line: allocate for n wavelengths. */
static sb_result_t cornell_count(sb_gonio_t *rd, char *line, cornell_t *cn) {
    char *f[2];
    size_t nf = sb_split_fields(line, 0, f, 2);
    double v;
    if (nf != 1 || sb_parse_number(f[0], &v) != 0 || !(v >= 1 && v <= MAX_WAVELENGTHS) || v != floor(v))
        return sb_error(rd->ctx, SB_ERR_FORMAT, "%s:%zu: wavelength count '%.40s' is not an integer in 1..%d", rd->path,
                        rd->lr.line, nf ? f[0] : "", MAX_WAVELENGTHS);
    size_t n = cn->n = (size_t)v;
    cn->wl = malloc(n * sizeof *cn->wl);
    cn->w = malloc(3 * n * sizeof *cn->w);
    cn->vals = malloc(n * sizeof *cn->vals);
    cn->fields = malloc((n + 5) * sizeof *cn->fields);
    if (!cn->wl || !cn->w || !cn->vals || !cn->fields)
        return sb_error(rd->ctx, SB_ERR_NOMEM, "%s: out of memory", rd->path);
    return SB_OK;
}

/* A line of wavelengths (increasing, positive); after the last one the
 * spectral weights.  *done when all n are read. */
static sb_result_t cornell_wavelengths(sb_gonio_t *rd, char *line, const sb_measured_opts_t *o, cornell_t *cn,
                                       int *done) {
    sb_context_t *ctx = rd->ctx;
    double *wl = cn->wl;
    size_t n = cn->n, nf = sb_split_fields(line, 0, cn->fields, n + 5);
    if (cn->have + nf > n)
        return sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: more wavelengths than the %zu announced", rd->path, rd->lr.line,
                        n);
    for (size_t k = 0; k < nf; k++) {
        size_t h = cn->have;
        if (sb_parse_number(cn->fields[k], &wl[h]) != 0) return sb_gonio_bad_number_(rd, "wavelength", cn->fields[k]);
        if (!isfinite(wl[h]) || wl[h] <= 0)
            return sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: wavelength '%.40s' is not a positive number", rd->path,
                            rd->lr.line, cn->fields[k]);
        if (h > 0 && !(wl[h] > wl[h - 1]))
            return sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: wavelengths not increasing (%g nm after %g nm)", rd->path,
                            rd->lr.line, wl[h], wl[h - 1]);
        cn->have++;
    }
    *done = cn->have == n;
    if (!*done) return SB_OK;
    if (wl[n - 1] < 380 || wl[0] > 780)
        return sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: wavelengths %g..%g nm miss the visible range 380..780 nm",
                        rd->path, rd->lr.line, wl[0], wl[n - 1]);
    sb_result_t r = sb_spectral_weights(ctx, wl, n, o->white, cn->w);
    if (r != SB_OK) return r;
    rd->info->wavelengths = n;
    rd->info->channels = n;
    rd->info->wl_min = wl[0];
    rd->info->wl_max = wl[n - 1];
    return SB_OK;
}

/* A row: 4 angles and n spectral values, weighted into RGB. */
static sb_result_t cornell_row(sb_gonio_t *rd, char *line, cornell_t *cn) {
    size_t n = cn->n, nf = sb_split_fields(line, 0, cn->fields, n + 5);
    if (nf != 4 + n)
        return sb_error(rd->ctx, SB_ERR_FORMAT, "%s:%zu: %zu numbers, expected %zu (4 angles + %zu spectral values)",
                        rd->path, rd->lr.line, nf, 4 + n, n);
    static const char *const an[4] = {"theta_i", "phi_i", "theta_s", "phi_s"};
    double a[4];
    sb_result_t r;
    for (int k = 0; k < 4; k++)
        if ((r = sb_gonio_angle_(rd, an[k], cn->fields[k], 1, k % 2 ? SB_ANGLE_PHI : SB_ANGLE_THETA, &a[k])) != SB_OK)
            return r;
    int nan = 0;
    for (size_t k = 0; k < n; k++)
        if ((r = sb_gonio_value_(rd, "spectral value", cn->fields[4 + k], &cn->vals[k], &nan)) != SB_OK) return r;
    double wi[3], wo[3], f[3] = {0, 0, 0};
    sb_dir_from_angles(a[0], a[1], wi);
    sb_dir_from_angles(a[2], a[3], wo);
    int neg = 0;
    for (size_t k = 0; k < n && !nan; k++)
        neg |= cn->vals[k] < 0;
    for (int c = 0; c < 3 && !nan; c++)
        for (size_t k = 0; k < n; k++)
            f[c] += cn->w[(size_t)c * n + k] * cn->vals[k];
    return sb_gonio_add_(rd, wi, wo, f, nan, neg);
}

/* Cornell / pbrt .brdf: count, wavelengths (may span lines), then rows of
 * 4 + n numbers.  Lines starting with '#' are comments. */
static sb_result_t read_cornell(sb_gonio_t *rd, const sb_measured_opts_t *o, int *iso, int *recip) {
    (void)iso, (void)recip; /* isotropic and reciprocal */
    cornell_t cn = {0, 0, NULL, NULL, NULL, NULL};
    sb_result_t r = SB_OK;
    char *line;
    int st = 0, state = 0;
    while (r == SB_OK && (st = sb_lines_next(rd->ctx, &rd->lr, &line, &r)) > 0) {
        if (sb_gonio_blank_(line, '#')) continue;
        int done = 0;
        if (state == 0) {
            if ((r = cornell_count(rd, line, &cn)) == SB_OK) state = 1;
        } else if (state == 1) {
            if ((r = cornell_wavelengths(rd, line, o, &cn, &done)) == SB_OK && done) state = 2;
        } else {
            r = cornell_row(rd, line, &cn);
        }
    }
    if (r == SB_OK && st >= 0 && state < 2)
        r = sb_error(rd->ctx, SB_ERR_FORMAT, "%s:%zu: ends before the %s", rd->path, rd->lr.line,
                     state == 0 ? "wavelength count" : "last wavelength");
    free(cn.wl);
    free(cn.w);
    free(cn.vals);
    free(cn.fields);
    return r;
}

static sb_result_t open_cornell(sb_context_t *ctx, const char *path, const sb_measured_opts_t *o, sb_source_t **out,
                                sb_measured_info_t *info) {
    return sb_gonio_open_(ctx, path, read_cornell, o, out, info);
}

/* Cornell: "# num wls" first (after blanks and a UTF-8 byte order mark). */
static int sniff_cornell(const unsigned char *head, size_t n) {
    const char *h = (const char *)head;
    size_t i = n >= 3 && memcmp(h, "\xef\xbb\xbf", 3) == 0 ? 3 : 0;
    while (i < n && (h[i] == ' ' || h[i] == '\t' || h[i] == '\r' || h[i] == '\n'))
        i++;
    return n - i >= 9 && memcmp(h + i, "# num wls", 9) == 0 ? 2 : 0;
}

const sb_reader_t sb_reader_cornell = {"cornell", "Cornell .brdf", ".brdf", sniff_cornell, open_cornell};
