/* Proportional colour channels: is M_c = a_c M_base for every channel?
 *
 * Pass 1 gives the norms n_c = ||M_c||^2 and the inner products <M_c, M_b>
 * of every pair, so the base b (largest norm) and the least-squares scales
 * a_c = <M_c, M_b> / n_b.  The deviation is then measured explicitly in
 * pass 2, sum (M_c - a_c M_b)^2: the shortcut n_c - <M_c, M_b>^2 / n_b
 * cancels to rounding long before a tolerance of 1e-12 (its relative
 * accuracy is eps / 1e-24).  Pass 2 stops at the first column where a
 * channel already exceeds its budget rel_tol^2 n_c, so a non-proportional
 * matrix costs little more than pass 1. */
#include "sepbrdf/channels.h"

#include <math.h>
#include <string.h>

#include "util/internal.h"

/* sum (a_i pw)(b_i pw) with two partial sums (even and odd i).  Inlined
 * twice: with pw the constant 1 (x * 1 is x: the same bits, two
 * multiplications fewer per term) and with pw as given. */
static inline __attribute__((always_inline)) double dot2(const double *a, const double *b, size_t rows, double pw) {
    double s0 = 0, s1 = 0;
    size_t i = 0;
    for (; i + 2 <= rows; i += 2) {
        s0 += (a[i] * pw) * (b[i] * pw);
        s1 += (a[i + 1] * pw) * (b[i + 1] * pw);
    }
    if (i < rows) s0 += (a[i] * pw) * (b[i] * pw);
    return s0 + s1;
}

/* g[c][e] = <M_c, M_e> (c <= e, present channels) on values times pw,
 * column by column with two partial sums. */
/* The six dot2 of three columns in one pass (each value read once, not
 * four times): the same two partial sums each, so the same bits. */
static inline __attribute__((always_inline)) void dot6(const double *const c[3], size_t rows, double pw,
                                                       double p[3][3]) {
    double s[6][2] = {{0}};
    size_t i = 0;
    for (; i + 2 <= rows; i += 2)
        for (int l = 0; l < 2; l++) {
            double a = c[0][i + l] * pw, b = c[1][i + l] * pw, d = c[2][i + l] * pw;
            s[0][l] += a * a, s[1][l] += a * b, s[2][l] += a * d;
            s[3][l] += b * b, s[4][l] += b * d, s[5][l] += d * d;
        }
    if (i < rows) {
        double a = c[0][i] * pw, b = c[1][i] * pw, d = c[2][i] * pw;
        s[0][0] += a * a, s[1][0] += a * b, s[2][0] += a * d;
        s[3][0] += b * b, s[4][0] += b * d, s[5][0] += d * d;
    }
    p[0][0] = s[0][0] + s[0][1], p[0][1] = s[1][0] + s[1][1], p[0][2] = s[2][0] + s[2][1];
    p[1][1] = s[3][0] + s[3][1], p[1][2] = s[4][0] + s[4][1], p[2][2] = s[5][0] + s[5][1];
}

static void gram3(const double *const x[3], size_t rows, size_t cols, size_t ld, double pw, double g[3][3]) {
    memset(g, 0, 9 * sizeof g[0][0]);
    for (size_t j = 0; j < cols; j++) {
        double p[3][3] = {{0}};
        if (x[0] && x[1] && x[2]) {
            const double *c[3] = {x[0] + j * ld, x[1] + j * ld, x[2] + j * ld};
            if (pw == 1)
                dot6(c, rows, 1, p);
            else
                dot6(c, rows, pw, p);
            for (int a = 0; a < 3; a++)
                for (int e = a; e < 3; e++)
                    g[a][e] += p[a][e];
            continue;
        }
        for (int c = 0; c < 3; c++) {
            if (!x[c]) continue;
            const double *a = x[c] + j * ld;
            for (int e = c; e < 3; e++) {
                if (!x[e]) continue;
                const double *b = x[e] + j * ld;
                p[c][e] = pw == 1 ? dot2(a, b, rows, 1) : dot2(a, b, rows, pw);
            }
        }
        for (int c = 0; c < 3; c++)
            for (int e = c; e < 3; e++)
                g[c][e] += p[c][e];
    }
}

/* Products are taken on values times a power of two pw (exact): first
 * pw = 1, which serves every BRDF of ordinary magnitude in one pass; when
 * the sums leave the safe range (1e-300 data gives g = 0, "all channels
 * zero, proportional with scale 0"; 1e200 data overflows) an extra pass
 * finds max |M| and the Grams are taken again with pw near 1 / max |M|. */
static double scaled_grams(const double *const x[3], size_t rows, size_t cols, size_t ld, double g[3][3]) {
    double pw = 1;
    gram3(x, rows, cols, ld, pw, g);
    int safe = 1;
    for (int c = 0; c < 3; c++)
        if (x[c] && !(g[c][c] > 1e-280 && g[c][c] < 1e280)) safe = 0; /* 0: underflow, or a zero channel */
    if (safe) return pw;
    double amax = 0;
    for (int c = 0; c < 3; c++)
        for (size_t j = 0; x[c] && j < cols; j++)
            for (size_t i = 0; i < rows; i++) {
                double v = fabs(x[c][i + j * ld]);
                if (v > amax) amax = v;
            }
    pw = sb_pow2_scale(amax);
    gram3(x, rows, cols, ld, pw, g);
    return pw;
}

/* Pass 2: explicit deviations ||M_c - a_c M_b||, stopping early once one
 * is over budget (out->proportional = 0). */
static void deviations(const double *const x[3], size_t rows, size_t cols, size_t ld, double pw, double rel_tol,
                       const double g[3][3], sb_channels_t *out) {
    int b = out->base;
    double dev2[3] = {0, 0, 0}, budget[3];
    for (int c = 0; c < 3; c++)
        budget[c] = rel_tol * rel_tol * g[c][c];
    const double *mb = x[b];
    for (size_t j = 0; j < cols && out->proportional; j++)
        for (int c = 0; c < 3; c++) {
            if (!x[c] || c == b) continue;
            const double *a = x[c] + j * ld, *e = mb + j * ld;
            double ac = out->scale[c], s0 = 0, s1 = 0;
            size_t i = 0;
            for (; i + 2 <= rows; i += 2) {
                double d0 = (a[i] - ac * e[i]) * pw, d1 = (a[i + 1] - ac * e[i + 1]) * pw;
                s0 += d0 * d0;
                s1 += d1 * d1;
            }
            if (i < rows) s0 += ((a[i] - ac * e[i]) * pw) * ((a[i] - ac * e[i]) * pw);
            dev2[c] += s0 + s1;
            if (dev2[c] > budget[c]) out->proportional = 0;
        }
    for (int c = 0; c < 3; c++)
        out->dev[c] = x[c] && c != b && g[c][c] > 0 ? sqrt(dev2[c] / g[c][c]) : 0;
}

sb_result_t sb_channels_proportional(sb_context_t *ctx, const sb_matrix_t *m, double rel_tol, sb_channels_t *out) {
    if (!m || !out) return sb_error(ctx, SB_ERR_ARG, "channels: missing matrix or output");
    if (!m->structured && m->ld < m->rows)
        return sb_error(ctx, SB_ERR_ARG, "channels: leading dimension %zu < %zu rows", m->ld, m->rows);
    memset(out, 0, sizeof *out);
    out->base = -1;
    if (!(rel_tol >= 0 && rel_tol < 1))
        return sb_error(ctx, SB_ERR_RANGE, "channels: tolerance %g, need [0, 1)", rel_tol);
    if (rel_tol == 0) rel_tol = SB_CHANNELS_DEFAULT_TOL;
    const double *x[3];
    int present = 0;
    for (int c = 0; c < 3; c++) {
        x[c] = m->data[c];
        present += x[c] != NULL;
    }
    if (!present) return sb_error(ctx, SB_ERR_ARG, "channels: the matrix has no channel");
    /* structured: the stored rows hold every value, each R times */
    size_t rows = m->structured ? m->ld : m->rows;
    double g[3][3], pw = scaled_grams(x, rows, m->cols, m->ld, g),
                    copies = m->structured ? sqrt((double)m->phi_period) : 1;
    int b = -1;
    for (int c = 0; c < 3; c++)
        for (int e = c; e < 3; e++)
            if (x[c] && x[e] && !isfinite(g[c][e]))
                return sb_error(ctx, SB_ERR_NUMERIC, "channels: non-finite entries (or overflow) in channel %d or %d",
                                c, e);
    for (int c = 0; c < 3; c++) {
        if (!x[c]) continue;
        out->norm[c] = sqrt(g[c][c]) / pw * copies;
        if (b < 0 || g[c][c] > g[b][b]) b = c;
    }
    out->base = b;
    double nb = g[b][b];
    for (int c = 0; c < 3; c++) {
        if (!x[c]) continue;
        double dot = c < b ? g[c][b] : g[b][c];
        out->scale[c] = c == b ? 1 : nb > 0 ? dot / nb : 0;
    }
    out->proportional = 1;
    if (present > 1 && nb > 0) deviations(x, rows, m->cols, m->ld, pw, rel_tol, (const double(*)[3])g, out);
    return SB_OK;
}
