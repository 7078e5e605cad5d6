/* The residual norms of any factors against an even block-circulant matrix
 * (circulant.h: sb_circ_resid), from its R^3 distinct values and the
 * factors' azimuthal frequencies, without the R^4 cells (issue 36: the
 * term-weighted io fits read every cell J times, 1 s of a 1.5 s run).
 *
 * With F the unitary DFT over phi, F_{k,i} = e^{-2 pi i k i / R} / sqrt R,
 * and T = F (x) I over theta, the matrix is block-diagonal,
 *     T X T^H = blockdiag(L_k),  L_k = W_r (sum_m K_m e^{2 pi i k m / R}) W_c,
 * (W theta weights, commuting with T) and T G H^T T^H = Gh Hh^H with
 * Gh = T W_r G, Hh = T W_c H.  T is unitary, so (Parseval)
 *     ||W_r (M - G H^T) W_c||^2 = sum_k ||L_k - sum_j gh_jk hh_jk^H||^2
 *                               + sum_{a != b} ||sum_j gh_ja hh_jb^H||^2,
 * the second sum = sum_a sum_ij (gh_ia . gh_ja) conj(S_a[i, j]) with S_a =
 * sum_{b != a} (hh_ib . hh_jb): built from the small off-frequency parts
 * themselves (zero for a circulant fit's own terms), so nothing cancels.
 * Real factors make block R - k the conjugate of block k: the diagonal
 * sum runs over k <= R / 2, counting 0 < k < R / 2 twice. */
#include <complex.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "solve/circulant_impl.h"
#include "util/internal.h"
#include "util/rdft.h"

/* glibc's complex.h defines CMPLX for GCC only (clang: __builtin_complex) */
#ifndef CMPLX
#if defined(__clang__)
#define CMPLX(x, y) __builtin_complex((double)(x), (double)(y))
#else
#define CMPLX(x, y) ((double)(x) + _Complex_I * (double)(y))
#endif
#endif

/* C[r + f rows] = sum_d X[r + d ldx] cos(2 pi f d / R), S likewise with
 * sin, f = 0..nb-1: by FFT where R allows, else the sums (ct, st: the
 * tables of cos and sin(2 pi q / R)). */
static void dft_cols(size_t R, size_t nb, size_t rows, const double *X, size_t ldx, double *C, double *S,
                     const double *ct, const double *st, int nt) {
    if (sb_rdft_cols(R, nb, rows, X, ldx, C, rows, S, rows, nt)) return;
    for (size_t f = 0; f < nb; f++)
        for (size_t r = 0; r < rows; r++) {
            double c = 0, s = 0;
            for (size_t d = 0; d < R; d++) {
                size_t q = (f * d) % R;
                c += X[r + d * ldx] * ct[q];
                s += X[r + d * ldx] * st[q];
            }
            C[r + f * rows] = c;
            S[r + f * rows] = s;
        }
}

/* Step: the frequency parts of J factors (term j at x + j step, cell
 * R i_phi + i_theta), weighted: out[(j R + k) R + t] = w_t xh_jk[t] for
 * every k < R (k > R / 2 the conjugates).  cs: 2 R nb scratch. */
static void factor_parts(size_t R, size_t nb, size_t J, const double *x, size_t step, const double *w, const double *ct,
                         const double *st, double *cs, double complex *out) {
    double inv = 1 / sqrt((double)R);
    for (size_t j = 0; j < J; j++) {
        double *C = cs, *S = cs + R * nb;
        dft_cols(R, nb, R, x + j * step, R, C, S, ct, st, 1);
        double complex *o = out + j * R * R;
        for (size_t k = 0; k < nb; k++)
            for (size_t t = 0; t < R; t++) {
                double wt = (w ? w[t] : 1) * inv;
                o[k * R + t] = CMPLX(wt * C[t + k * R], -wt * S[t + k * R]);
                if (k && k < R - k) o[(R - k) * R + t] = conj(o[k * R + t]);
            }
    }
}

/* Step: per frequency a, the J x J Gram block gram[(a J + i) J + j] =
 * xh_ia^H xh_ja. */
static void part_grams(size_t R, size_t J, const double complex *xh, double complex *gram) {
    for (size_t a = 0; a < R; a++)
        for (size_t i = 0; i < J; i++)
            for (size_t j = 0; j < J; j++) {
                const double complex *u = xh + (i * R + a) * R, *v = xh + (j * R + a) * R;
                double sr = 0, si = 0; /* conj(u) v, spelt out: no C99 Annex G calls */
                for (size_t t = 0; t < R; t++) {
                    sr += creal(u[t]) * creal(v[t]) + cimag(u[t]) * cimag(v[t]);
                    si += creal(u[t]) * cimag(v[t]) - cimag(u[t]) * creal(v[t]);
                }
                gram[(a * J + i) * J + j] = CMPLX(sr, si);
            }
}

/* Step: off[i J + j] = sum_a Re(GA_a[i, j] conj(S_a[i, j])), S_a the sum
 * of HB_b over b != a, added directly (no difference of large sums). */
static void off_terms(size_t R, size_t J, const double complex *ga, const double complex *hb, double complex *sa,
                      double *off) {
    memset(off, 0, J * J * sizeof *off);
    for (size_t a = 0; a < R; a++) {
        memset(sa, 0, J * J * sizeof *sa);
        for (size_t b = 0; b < R; b++)
            for (size_t i = 0; b != a && i < J * J; i++)
                sa[i] += hb[b * J * J + i];
        for (size_t i = 0; i < J * J; i++)
            off[i] += creal(ga[a * J * J + i]) * creal(sa[i]) + cimag(ga[a * J * J + i]) * cimag(sa[i]);
    }
}

/* Step: the diagonal blocks: diag[j] = sum_k mult_k ||L_k - sum_{i<=j}
 * gh_ik hh_ik^H||^2, L_k = W_r (C_k + i S_k) W_c from the kernel's DFT. */
static void diag_terms(size_t R, size_t nb, size_t J, const double *C, const double *S, const double *wr,
                       const double *wc, const double complex *gh, const double complex *hh, double complex *E,
                       double *diag) {
    size_t R2 = R * R;
    memset(diag, 0, J * sizeof *diag);
    for (size_t k = 0; k < nb; k++) {
        double mult = (k == 0 || 2 * k == R) ? 1 : 2;
        for (size_t ot = 0; ot < R; ot++)
            for (size_t it = 0; it < R; it++) {
                double w = (wr ? wr[it] : 1) * (wc ? wc[ot] : 1);
                E[it + ot * R] = CMPLX(w * C[it + ot * R + k * R2], w * S[it + ot * R + k * R2]);
            }
        for (size_t j = 0; j < J; j++) {
            const double complex *g = gh + (j * R + k) * R, *h = hh + (j * R + k) * R;
            double s2 = 0;
            for (size_t ot = 0; ot < R; ot++) {
                double hr = creal(h[ot]), hi = -cimag(h[ot]); /* conj(h) */
                double *e = (double *)(E + ot * R);           /* re, im interleaved (C11 6.2.5) */
                const double *gg = (const double *)g;
                for (size_t it = 0; it < R; it++) {
                    double er = e[2 * it] - (gg[2 * it] * hr - gg[2 * it + 1] * hi);
                    double ei = e[2 * it + 1] - (gg[2 * it] * hi + gg[2 * it + 1] * hr);
                    e[2 * it] = er;
                    e[2 * it + 1] = ei;
                    s2 += er * er + ei * ei;
                }
            }
            diag[j] += mult * s2;
        }
    }
}

sb_result_t sb_circ_resid(sb_context_t *ctx, size_t R, const double *a, const double *wr, const double *wc, size_t J,
                          const double *g, size_t gstep, const double *h, size_t hstep, int nt, double *ssq,
                          double *n2) {
    size_t nb = R / 2 + 1, R2 = R * R, nd, nc;
    if (R < 1 || sb_size_mul(R2, 2 * nb + 2, &nd) || sb_size_add(nd, J * J + J + 2 * R * nb, &nd) ||
        sb_size_mul(R2, 2 * J + 1, &nc) || sb_size_add(nc, 3 * R * J * J + J * J, &nc))
        return sb_error(ctx, SB_ERR_OVERFLOW, "errors: circulant residual size overflows");
    double *d = sb_alloc(ctx, nd, sizeof *d, "circulant residual");
    double complex *z = sb_alloc(ctx, nc, sizeof *z, "circulant residual");
    if (!d || !z) {
        free(d);
        free(z);
        return SB_ERR_NOMEM;
    }
    double *C = d, *S = C + R2 * nb, *ct = S + R2 * nb, *st = ct + R, *off = st + R, *diag = off + J * J,
           *cs = diag + J;
    double complex *gh = z, *hh = gh + J * R2, *E = hh + J * R2, *ga = E + R2, *hb = ga + R * J * J,
                   *sa = hb + R * J * J;
    for (size_t q = 0; q < R; q++) {
        ct[q] = cos(2 * SB_PI * (double)q / (double)R);
        st[q] = sin(2 * SB_PI * (double)q / (double)R);
    }
    /* the kernel K_m (R^2 values at a + m R^2) to its blocks C_k + i S_k */
    dft_cols(R, nb, R2, a, R2, C, S, ct, st, nt);
    factor_parts(R, nb, J, g, gstep, wr, ct, st, cs, gh);
    factor_parts(R, nb, J, h, hstep, wc, ct, st, cs, hh);
    part_grams(R, J, gh, ga);
    part_grams(R, J, hh, hb);
    off_terms(R, J, ga, hb, sa, off);
    diag_terms(R, nb, J, C, S, wr, wc, gh, hh, E, diag);
    double o = 0, x2 = 0;
    for (size_t j = 0; j < J; j++) {
        for (size_t i = 0; i <= j; i++) /* the pairs (i, j), (j, i) with max(i, j) == j */
            o += off[i * J + j] + (i != j ? off[j * J + i] : 0);
        ssq[j] = diag[j] + (o > 0 ? o : 0);
    }
    for (size_t m = 0; m < R; m++)
        for (size_t ot = 0; ot < R; ot++)
            for (size_t it = 0; it < R; it++) {
                double v = a[it + ot * R + m * R2] * (wr ? wr[it] : 1) * (wc ? wc[ot] : 1);
                x2 += v * v;
            }
    *n2 = x2 * (double)R; /* each kernel value fills R cells (one per phi_i) */
    free(d);
    free(z);
    return SB_OK;
}

void sb_circ_resid_max(size_t R, const double *a, size_t J, const double *g, size_t gstep, const double *h,
                       size_t hstep, double *r, double *mx) {
    size_t prev = SIZE_MAX;
    for (size_t j = 0; j < J; j++)
        mx[j] = 0;
    for (size_t q = 0; q < SB_CIRC_MAX_ROWS; q++) {
        /* golden-ratio steps: rows q R / 4 see no sin of frequency 2 */
        size_t ip = (size_t)((double)(q * R) * 0.6180339887498949) % R;
        if (ip == prev) continue; /* R < 2 */
        prev = ip;
        for (size_t c = 0; c < R * R; c++) {
            size_t op = c / R, ot = c % R;
            memcpy(r, a + (((op + R - ip) % R) * R + ot) * R, R * sizeof *r);
            for (size_t j = 0; j < J; j++) {
                double m = sb_circ_absmax_axpy(r, h[j * hstep + c], g + j * gstep + ip * R, R, 1);
                mx[j] = m > mx[j] ? m : mx[j];
            }
        }
    }
}
