/* Reading a matrix whatever its storage: cells, columns, products with a
 * block of vectors, and a dense copy.
 *
 * A structured matrix (matrix.h) stores T = the first block row, R x N with
 * N = R^2, and cell (R ip + it, R op + ot) = T[it, R ((op - ip) mod R) + ot].
 * Column (op, ot) is then R contiguous pieces of T, and the product with a
 * block Z (N x k) is, for every block row ip,
 *     Y_ip = sum_d T_d Z_((ip + d) mod R) = T Z_(ip),
 * T_d the R x R block of columns d R .. d R + R - 1 and Z_(ip) the blocks
 * of Z rotated by ip: a block circulant, diagonalised by the Fourier basis
 * over the block index (sb_matrix_mul). */
#include <cblas.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sample/stream.h"
#include "sepbrdf/matrix.h"
#include "util/internal.h"
#include "util/parallel.h"
#include "util/rdft.h"

int sb_matrix_has(const sb_matrix_t *m, int ch) {
    if (!m || ch < 0 || ch > 2) return 0;
    return m->streamed ? (int)((m->channels >> ch) & 1u) : m->data[ch] != NULL;
}

double sb_matrix_at(const sb_matrix_t *m, int ch, size_t row, size_t col) {
    if (!sb_matrix_has(m, ch)) return 0;
    if (m->streamed) return sb_matrix_stream_at(m, ch, row, col);
    if (!m->structured) return m->data[ch][row + col * m->ld];
    size_t R = m->phi_period, ip = row / R, it = row % R, op = col / R, ot = col % R;
    return m->data[ch][it + (((op + R - ip) % R) * R + ot) * R];
}

const double *sb_matrix_col(const sb_matrix_t *m, int ch, size_t col, double *buf) {
    if (!sb_matrix_has(m, ch) || col >= m->cols) return NULL;
    if (!buf && (m->streamed || m->structured)) return NULL; /* no room to gather it */
    if (m->streamed) {
        double *out[3] = {NULL, NULL, NULL};
        out[ch] = buf;
        return sb_matrix_cols(NULL, m, col, col + 1, out, m->rows, 1) == SB_OK ? buf : NULL;
    }
    if (!m->structured) return m->data[ch] + col * m->ld;
    size_t R = m->phi_period, op = col / R, ot = col % R;
    for (size_t ip = 0; ip < R; ip++)
        memcpy(buf + ip * R, m->data[ch] + (((op + R - ip) % R) * R + ot) * R, R * sizeof *buf);
    return buf;
}

/* The structured product through the real Fourier basis over the block
 * index (see the top of the file): with theta_f = 2 pi f / R,
 * f = 0 .. R/2, and blocks Z_q = sum_f a_f cos(theta_f q) + b_f sin(theta_f q),
 *     Y_i = sum_f cos(theta_f i) (C_f a_f + S_f b_f) + sin(theta_f i) (C_f b_f - S_f a_f),
 *     C_f = sum_d T_d cos(theta_f d),   S_f = sum_d T_d sin(theta_f d),
 * exact for any block-circulant matrix (S_f = 0 when it is even).  Every
 * step is a BLAS-3 product: 2 R^4 flops for C and S, R^3 k for the rest,
 * instead of 2 R^4 k for the blocks directly.  Where T is even to the bit
 * (T_d = T_(R-d), an even source's table: matrix.c), S_f is 0 exactly and
 * is neither formed nor applied (the transform's S is rounding there, at
 * most 1e-16 of C: the products come out as close to the exact ones). */
typedef struct fourier {
    size_t R, nb, k;
    int even;                /* T_d = T_(R-d) bit for bit: S = 0 */
    double *cs, *sn;         /* R x nb: cos, sin (theta_f q) at [q + f R] */
    double *C, *S;           /* nb blocks R x R: [it + ot R + f R^2] */
    double *ac, *as, *e, *o; /* per column j of Z: R x nb (a_f, b_f; then the cos and sin coefficients of Y) */
    double *in, *out;        /* R x 2k: [a_f b_f], and R x 4k: [C_f, S_f] times it */
} fourier_t;

/* [C S] = T [cos sin] in one product: T is R^2 x R (rows it + ot R,
 * columns d), and sn follows cs, S follows C (R x 2 nb and R^2 x 2 nb).
 * One call instead of 2 R small ones: 0.83-1.0 against 0.93-1.35 ms a
 * channel at R = 64 (one BLAS thread, Xeon VM, interleaved). */
static void fourier_transform(const fourier_t *w, const double *t) {
    size_t R = w->R, nb = w->nb, R2 = R * R;
    int nt = sb_threads_for(0, R2 / 32, R2 * R, (size_t)1 << 22);
    if (sb_rdft_cols(R, nb, R2, t, R2, w->C, R2, w->even ? NULL : w->S, R2, nt))
        return; /* R a power of two: by FFT (util/rdft.h) */
    cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, (int)R2, (int)(w->even ? nb : 2 * nb), (int)R, 1.0, t,
                (int)R2, w->cs, (int)R, 0.0, w->C, (int)R2); /* even: C alone (no room for S) */
}

static void fourier_apply(const fourier_t *w, const double *z, size_t ldz, double *y, size_t ldy) {
    size_t R = w->R, nb = w->nb, k = w->k, R2 = R * R, Rb = R * nb;
    for (size_t j = 0; j < k; j++) { /* analysis: Z_j is R x R (rows ot, columns q) */
        cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, (int)R, (int)nb, (int)R, 1.0 / (double)R, z + j * ldz,
                    (int)R, w->cs, (int)R, 0.0, w->ac + j * Rb, (int)R);
        cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, (int)R, (int)nb, (int)R, 1.0 / (double)R, z + j * ldz,
                    (int)R, w->sn, (int)R, 0.0, w->as + j * Rb, (int)R);
    }
    for (size_t f = 0; f < nb; f++) {
        double alpha = f == 0 || 2 * f == R ? 1 : 2; /* the real DFT's weights */
        for (size_t j = 0; j < k; j++) {
            memcpy(w->in + j * R, w->ac + j * Rb + f * R, R * sizeof(double));
            memcpy(w->in + (k + j) * R, w->as + j * Rb + f * R, R * sizeof(double));
        }
        cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, (int)R, (int)(2 * k), (int)R, alpha, w->C + f * R2,
                    (int)R, w->in, (int)R, 0.0, w->out, (int)R);
        if (!w->even)
            cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, (int)R, (int)(2 * k), (int)R, alpha, w->S + f * R2,
                        (int)R, w->in, (int)R, 0.0, w->out + 2 * k * R, (int)R);
        const double *Ca = w->out, *Cb = Ca + k * R, *Sa = Cb + k * R, *Sb = Sa + k * R;
        for (size_t j = 0; j < k; j++)
            for (size_t i = 0; i < R; i++) {
                w->e[j * Rb + f * R + i] = w->even ? Ca[j * R + i] : Ca[j * R + i] + Sb[j * R + i];
                w->o[j * Rb + f * R + i] = w->even ? Cb[j * R + i] : Cb[j * R + i] - Sa[j * R + i];
            }
    }
    for (size_t j = 0; j < k; j++) { /* synthesis: Y_j is R x R (rows it, columns i) */
        cblas_dgemm(CblasColMajor, CblasNoTrans, CblasTrans, (int)R, (int)R, (int)nb, 1.0, w->e + j * Rb, (int)R, w->cs,
                    (int)R, 0.0, y + j * ldy, (int)R);
        cblas_dgemm(CblasColMajor, CblasNoTrans, CblasTrans, (int)R, (int)R, (int)nb, 1.0, w->o + j * Rb, (int)R, w->sn,
                    (int)R, 1.0, y + j * ldy, (int)R);
    }
}

/* Bytes of the block of columns a streamed product evaluates at a time. */
#define SB_STREAM_BLOCK_BYTES ((size_t)32 << 20)

/* Y = M_c Z over blocks of columns evaluated from the source: one pass. */
static sb_result_t stream_mul(sb_context_t *ctx, const sb_matrix_t *m, int ch, size_t k, const double *z, size_t ldz,
                              double *y, size_t ldy) {
    size_t rows = m->rows, b = SB_STREAM_BLOCK_BYTES / (rows * sizeof(double));
    b = b < 1 ? 1 : (b > m->cols ? m->cols : b);
    double *blk = sb_alloc(ctx, rows * b, sizeof(double), "streamed product"), *out[3] = {NULL, NULL, NULL};
    if (!blk) return SB_ERR_NOMEM;
    out[ch] = blk;
    for (size_t c0 = 0; c0 < m->cols; c0 += b) {
        size_t c1 = c0 + b < m->cols ? c0 + b : m->cols;
        sb_matrix_cols(ctx, m, c0, c1, out, rows, 0);
        cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, (int)rows, (int)k, (int)(c1 - c0), 1.0, blk, (int)rows,
                    z + c0, (int)ldz, c0 ? 1.0 : 0.0, y, (int)ldy);
    }
    free(blk);
    return SB_OK;
}

/* Whether the table T (R planes of R^2 values, plane d the block T_d)
 * has T_d = T_(R-d) bit for bit. */
static int table_even(const double *t, size_t R) {
    size_t R2 = R * R;
    for (size_t d = 1; 2 * d < R; d++)
        if (memcmp(t + d * R2, t + (R - d) * R2, R2 * sizeof *t) != 0) return 0;
    return 1;
}

sb_result_t sb_matrix_mul(sb_context_t *ctx, const sb_matrix_t *m, int ch, size_t k, const double *z, size_t ldz,
                          double *y, size_t ldy) {
    if (!sb_matrix_has(m, ch) || !z || !y || ldz < m->cols || ldy < m->rows)
        return sb_error(ctx, SB_ERR_ARG, "matrix: product with a missing channel or bad leading dimensions");
    if (m->rows > (size_t)INT32_MAX || m->cols > (size_t)INT32_MAX || k > (size_t)INT32_MAX / 4 ||
        ldz > (size_t)INT32_MAX || ldy > (size_t)INT32_MAX)
        return sb_error(ctx, SB_ERR_OVERFLOW, "matrix: product of %zu x %zu too large for BLAS", m->rows, m->cols);
    if (k == 0) return SB_OK;
    if (m->streamed) return stream_mul(ctx, m, ch, k, z, ldz, y, ldy);
    if (!m->structured) {
        cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, (int)m->rows, (int)k, (int)m->cols, 1.0, m->data[ch],
                    (int)m->ld, z, (int)ldz, 0.0, y, (int)ldy);
        return SB_OK;
    }
    fourier_t w = {m->phi_period, m->phi_period / 2 + 1, k, 0, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL,
                   NULL};
    w.even = table_even(m->data[ch], w.R);
    /* S (Rb R doubles, 1 MiB at R = 64) only where it is formed: on the
     * heap's 2 MiB pages an unused block still costs its pages' zeroing */
    size_t R = w.R, nb = w.nb, Rb = R * nb, n, total;
    if (sb_size_mul3(Rb, R, w.even ? 1 : 2, &n) || sb_size_mul3(Rb, k, 4, &total) || sb_size_add(n, total, &total) ||
        sb_size_add(total, 2 * Rb + 6 * R * k, &total))
        return sb_error(ctx, SB_ERR_OVERFLOW, "matrix: product workspace overflows");
    double *ws = sb_alloc(ctx, total, sizeof(double), "matrix product");
    if (!ws) return SB_ERR_NOMEM;
    w.cs = ws, w.sn = w.cs + Rb, w.C = w.sn + Rb, w.S = w.even ? NULL : w.C + Rb * R;
    w.ac = w.C + Rb * R * (w.even ? 1 : 2);
    w.as = w.ac + Rb * k, w.e = w.as + Rb * k, w.o = w.e + Rb * k, w.in = w.o + Rb * k, w.out = w.in + 2 * R * k;
    for (size_t f = 0; f < nb; f++)
        for (size_t q = 0; q < R; q++) {
            size_t a = (f * q) % R; /* exact angle index */
            w.cs[q + f * R] = cos(2 * SB_PI * (double)a / (double)R);
            w.sn[q + f * R] = sin(2 * SB_PI * (double)a / (double)R);
        }
    fourier_transform(&w, m->data[ch]);
    fourier_apply(&w, z, ldz, y, ldy);
    free(ws);
    return SB_OK;
}

sb_result_t sb_matrix_expand(sb_context_t *ctx, const sb_matrix_t *m, sb_matrix_t *out) {
    if (!m || !out) return sb_error(ctx, SB_ERR_ARG, "matrix: missing matrix");
    size_t rows = m->rows, cols = m->cols, cells;
    memset(out, 0, sizeof *out);
    if (sb_size_mul(rows, cols, &cells))
        return sb_error(ctx, SB_ERR_OVERFLOW, "matrix: %zu x %zu cells overflow; lower the resolution", rows, cols);
    *out = *m;
    out->ld = rows;
    out->structured = out->streamed = 0;
    out->mask = NULL;
    out->dirs = NULL;
    out->source = NULL;
    out->param = NULL;
    for (int ch = 0; ch < 3; ch++)
        out->data[ch] = NULL;
    for (int ch = 0; ch < 3; ch++) {
        if (!sb_matrix_has(m, ch)) continue;
        double *d = out->data[ch] = sb_alloc_large(ctx, cells, sizeof(double), "dense matrix");
        if (!d) {
            sb_matrix_free(out);
            return SB_ERR_NOMEM;
        }
        if (m->streamed) continue;
        for (size_t c = 0; c < cols; c++) {
            const double *col = sb_matrix_col(m, ch, c, d + c * rows);
            if (col != d + c * rows) memcpy(d + c * rows, col, rows * sizeof *d);
        }
    }
    if (m->streamed) sb_matrix_cols(ctx, m, 0, cols, out->data, rows, 0);
    if (m->mask) {
        if (!(out->mask = sb_alloc_large(ctx, cells, 1, "dense matrix mask"))) {
            sb_matrix_free(out);
            return SB_ERR_NOMEM;
        }
        for (size_t c = 0; c < cols; c++)
            memcpy(out->mask + c * rows, m->mask + c * m->ld, rows);
    }
    return SB_OK;
}
