/* Private: Cholesky factorisation and solve of small dense symmetric
 * positive definite matrices (row-major, n x n, the lower triangle used),
 * inline for the hot loops that call them per row (the masked fit's least
 * squares, the scattered tables' local fits). */
#ifndef SEPBRDF_CHOL_H
#define SEPBRDF_CHOL_H

#include <math.h>
#include <stddef.h>

/* A = L L^T in place (L in the lower triangle).  A pivot that is not
 * positive becomes `fallback` (> 0), or, with fallback 0, ends the
 * factorisation: returns 0; 1 on success. */
static inline int sb_chol(double *A, size_t n, double fallback) {
    for (size_t j = 0; j < n; j++) {
        double d = A[j * n + j];
        for (size_t p = 0; p < j; p++)
            d -= A[j * n + p] * A[j * n + p];
        if (d > 0)
            d = sqrt(d);
        else if (fallback > 0)
            d = fallback;
        else
            return 0;
        A[j * n + j] = d;
        for (size_t i = j + 1; i < n; i++) {
            double v = A[i * n + j];
            for (size_t p = 0; p < j; p++)
                v -= A[i * n + p] * A[j * n + p];
            A[i * n + j] = v / d;
        }
    }
    return 1;
}

/* Solve L L^T x = b in place (b: n values at stride `stride`) with the
 * factor of sb_chol. */
static inline void sb_chol_solve(const double *L, size_t n, double *b, size_t stride) {
    for (size_t i = 0; i < n; i++) { /* L y = b */
        double v = b[i * stride];
        for (size_t p = 0; p < i; p++)
            v -= L[i * n + p] * b[p * stride];
        b[i * stride] = v / L[i * n + i];
    }
    for (size_t i = n; i-- > 0;) { /* L^T x = y */
        double v = b[i * stride];
        for (size_t p = i + 1; p < n; p++)
            v -= L[p * n + i] * b[p * stride];
        b[i * stride] = v / L[i * n + i];
    }
}

#endif
