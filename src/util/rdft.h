/* Private: the real DFT over the columns of a tall matrix, by FFT (issue
 * 36).  The block-circulant solver and the structured product both take
 * C_f = sum_d X_d cos(2 pi f d / R) (and S_f with sin) of R columns X_d of
 * R^2 rows; as a matrix product that is 2 R^4 flops (R = 256: 8.6 GFlop a
 * channel, a third of the whole io run), as R^2 FFTs of length R it is
 * about 5 R^3 log2 R. */
#ifndef SEPBRDF_RDFT_H
#define SEPBRDF_RDFT_H

#include <stddef.h>

/* Whether sb_rdft_cols takes R: a power of two from 4 to 2^20. */
int sb_rdft_fits(size_t R);

/* For f = 0 .. nb - 1 (nb <= R / 2 + 1) and rows 0 .. rows - 1:
 *   C[r + f ldc] = sum_d X[r + d ldx] cos(2 pi f d / R)
 *   S[r + f lds] = sum_d X[r + d ldx] sin(2 pi f d / R)   (S may be NULL)
 * on nt threads (the library's pool; nt < 1 counts as 1).  Returns 0
 * (nothing written) when R does not fit (sb_rdft_fits) or memory is
 * short: the caller then takes the product. */
int sb_rdft_cols(size_t R, size_t nb, size_t rows, const double *X, size_t ldx, double *C, size_t ldc, double *S,
                 size_t lds, int nt);

#endif
