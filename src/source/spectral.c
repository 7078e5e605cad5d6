/* Spectra -> linear sRGB through the CIE 1931 2 deg observer.
 *
 * The colour matching functions are the CIE's 1 nm table (380..780 nm),
 * data/cie1931_2deg_1nm.csv, embedded at build time (CMakeLists.txt
 * generates sb_cie_table.h), so nothing is looked up at run time.
 *
 * For a spectrum s sampled at wavelengths l_0 < ... < l_{n-1}, taken
 * piecewise linear between them and constant beyond the ends:
 *     X = sum_l s(l) xbar(l) / sum_l ybar(l)    (l = 380, 381, ..., 780 nm)
 * and likewise Y, Z: a flat spectrum of 1 gives Y = 1 and the chromaticity
 * of the equal-energy illuminant E.  Linear sRGB = M XYZ with the
 * IEC 61966-2-1 matrix (D65 white), optionally after a Bradford adaptation
 * from E to D65 so that a flat spectrum maps to RGB (1, 1, 1).  Everything
 * is linear in s, so it collapses into 3 x n weights computed once. */
#include <math.h>
#include <string.h>

#include "sb_cie_table.h"
#include "source/measured_impl.h"
#include "util/internal.h"

#define CIE_ROWS (sizeof sb_cie_table_ / sizeof sb_cie_table_[0])
_Static_assert(sizeof sb_cie_table_ / sizeof sb_cie_table_[0] == 401, "CIE table: 380..780 nm at 1 nm");

/* XYZ -> linear sRGB (D65), IEC 61966-2-1 as derived from the primaries. */
static const double xyz_to_srgb[3][3] = {
    {3.2404542, -1.5371385, -0.4985314},
    {-0.9692660, 1.8760108, 0.0415560},
    {0.0556434, -0.2040259, 1.0572252},
};
/* Bradford cone response matrix and the D65 white (Y = 1). */
static const double bradford[3][3] = {
    {0.8951, 0.2664, -0.1614},
    {-0.7502, 1.7135, 0.0367},
    {0.0389, -0.0685, 1.0296},
};
static const double d65_white[3] = {0.95047, 1.0, 1.08883};

void sb_cie_cmf(double nm, double xyz[3]) {
    if (!xyz) return;
    xyz[0] = xyz[1] = xyz[2] = 0;
    double lo = sb_cie_table_[0][0], hi = sb_cie_table_[CIE_ROWS - 1][0];
    if (!(nm >= lo && nm <= hi)) return;
    double u = nm - lo;
    size_t i = (size_t)u;
    if (i >= CIE_ROWS - 1) i = CIE_ROWS - 2;
    double t = u - (double)i;
    for (int c = 0; c < 3; c++)
        xyz[c] = (1 - t) * sb_cie_table_[i][c + 1] + t * sb_cie_table_[i + 1][c + 1];
}

static void mat3_mul(const double a[3][3], const double b[3][3], double out[3][3]) {
    double r[3][3];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            r[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
    memcpy(out, r, sizeof r);
}

static void mat3_inv(const double a[3][3], double out[3][3]) {
    double c00 = a[1][1] * a[2][2] - a[1][2] * a[2][1], c01 = a[1][2] * a[2][0] - a[1][0] * a[2][2],
           c02 = a[1][0] * a[2][1] - a[1][1] * a[2][0];
    double det = a[0][0] * c00 + a[0][1] * c01 + a[0][2] * c02;
    out[0][0] = c00 / det;
    out[1][0] = c01 / det;
    out[2][0] = c02 / det;
    out[0][1] = (a[0][2] * a[2][1] - a[0][1] * a[2][2]) / det;
    out[1][1] = (a[0][0] * a[2][2] - a[0][2] * a[2][0]) / det;
    out[2][1] = (a[0][1] * a[2][0] - a[0][0] * a[2][1]) / det;
    out[0][2] = (a[0][1] * a[1][2] - a[0][2] * a[1][1]) / det;
    out[1][2] = (a[0][2] * a[1][0] - a[0][0] * a[1][2]) / det;
    out[2][2] = (a[0][0] * a[1][1] - a[0][1] * a[1][0]) / det;
}

/* Bradford adaptation A = B^-1 diag(B w_dst / B w_src) B. */
static void bradford_adapt(const double src[3], const double dst[3], double out[3][3]) {
    double bs[3], bd[3], binv[3][3], d[3][3] = {{0}};
    for (int i = 0; i < 3; i++) {
        bs[i] = bradford[i][0] * src[0] + bradford[i][1] * src[1] + bradford[i][2] * src[2];
        bd[i] = bradford[i][0] * dst[0] + bradford[i][1] * dst[1] + bradford[i][2] * dst[2];
        d[i][i] = bd[i] / bs[i];
    }
    mat3_inv(bradford, binv);
    mat3_mul(d, bradford, out);
    mat3_mul(binv, out, out);
}

sb_result_t sb_spectral_weights(sb_context_t *ctx, const double *nm, size_t n, sb_white_t white, double *w) {
    if (!nm || !w) return sb_error(ctx, SB_ERR_ARG, "spectral: missing wavelengths or output");
    if (n == 0) return sb_error(ctx, SB_ERR_RANGE, "spectral: no wavelengths");
    size_t bytes; /* w holds 3 n doubles: a count whose arrays cannot exist is not read */
    if (sb_size_mul3(n, 3, sizeof *w, &bytes)) return sb_error(ctx, SB_ERR_OVERFLOW, "spectral: %zu wavelengths", n);
    if ((unsigned)white >= SB_WHITE_COUNT_) return sb_error(ctx, SB_ERR_ARG, "spectral: unknown white %d", (int)white);
    for (size_t k = 0; k < n; k++) {
        if (!isfinite(nm[k])) return sb_error(ctx, SB_ERR_RANGE, "spectral: wavelength %zu is not finite", k + 1);
        if (k > 0 && !(nm[k] > nm[k - 1]))
            return sb_error(ctx, SB_ERR_RANGE, "spectral: wavelengths not increasing (%g nm after %g nm)", nm[k],
                            nm[k - 1]);
    }
    /* Integrate each hat function of the piecewise-linear spectrum against
     * the CMFs at the table's 1 nm points: xyz[c][k]. */
    double ysum = 0;
    for (size_t r = 0; r < CIE_ROWS; r++)
        ysum += sb_cie_table_[r][2];
    memset(w, 0, 3 * n * sizeof *w);
    double *xyz = w; /* accumulate XYZ weights in place, then map to RGB */
    size_t k = 0;
    for (size_t r = 0; r < CIE_ROWS; r++) {
        double l = sb_cie_table_[r][0];
        const double *cmf = &sb_cie_table_[r][1];
        if (n == 1 || l <= nm[0]) {
            for (int c = 0; c < 3; c++)
                xyz[(size_t)c * n] += cmf[c];
            continue;
        }
        if (l >= nm[n - 1]) {
            for (int c = 0; c < 3; c++)
                xyz[(size_t)c * n + n - 1] += cmf[c];
            continue;
        }
        while (k + 1 < n && nm[k + 1] < l)
            k++;
        double t = (l - nm[k]) / (nm[k + 1] - nm[k]);
        for (int c = 0; c < 3; c++) {
            xyz[(size_t)c * n + k] += (1 - t) * cmf[c];
            xyz[(size_t)c * n + k + 1] += t * cmf[c];
        }
    }
    double m[3][3];
    memcpy(m, xyz_to_srgb, sizeof m);
    if (white == SB_WHITE_D65) {
        double we[3] = {0, 1, 0}, a[3][3];
        for (size_t r = 0; r < CIE_ROWS; r++) {
            we[0] += sb_cie_table_[r][1];
            we[2] += sb_cie_table_[r][3];
        }
        we[0] /= ysum;
        we[2] /= ysum;
        bradford_adapt(we, d65_white, a);
        mat3_mul(xyz_to_srgb, a, m);
    }
    for (size_t j = 0; j < n; j++) {
        double x = xyz[j] / ysum, y = xyz[n + j] / ysum, z = xyz[2 * n + j] / ysum;
        for (int c = 0; c < 3; c++)
            w[(size_t)c * n + j] = m[c][0] * x + m[c][1] * y + m[c][2] * z;
    }
    return SB_OK;
}

/* ---- gamut ------------------------------------------------------------------ */

static const char *const gamut_names[SB_GAMUT_COUNT_] = {"keep", "clip", "desaturate"};

const char *sb_gamut_name(sb_gamut_t g) { return (unsigned)g < SB_GAMUT_COUNT_ ? gamut_names[g] : "?"; }
sb_result_t sb_gamut_parse(const char *name, sb_gamut_t *out) {
    for (int k = 0; k < SB_GAMUT_COUNT_; k++)
        if (name && out && strcmp(name, gamut_names[k]) == 0) {
            *out = (sb_gamut_t)k;
            return SB_OK;
        }
    return SB_ERR_UNKNOWN;
}

/* Desaturation: rgb' = Y + t (rgb - Y) with the largest t in [0, 1] that
 * leaves every channel >= 0, i.e. t = Y / (Y - min); Y is unchanged. */
int sb_gamut_map(sb_gamut_t g, double rgb[3]) {
    if (!rgb) return 0;
    double mn = fmin(rgb[0], fmin(rgb[1], rgb[2]));
    if (!(mn < 0)) return 0;
    if (g == SB_GAMUT_CLIP)
        for (int c = 0; c < 3; c++)
            rgb[c] = fmax(rgb[c], 0);
    if (g == SB_GAMUT_DESATURATE) {
        double y = 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
        double t = y > 0 ? y / (y - mn) : 0;
        for (int c = 0; c < 3; c++)
            rgb[c] = y > 0 ? fmax(y + t * (rgb[c] - y), 0) : 0;
    }
    return 1;
}
