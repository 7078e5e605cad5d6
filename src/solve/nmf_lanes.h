/* Loops of the non-negative solver's sweeps over a column (solver_nmf.c),
 * in four lanes where they sum, restrict so that they vectorise. */
#ifndef SB_SOLVE_NMF_LANES_H
#define SB_SOLVE_NMF_LANES_H

#include <stddef.h>

/* Step: *b = sum_i w_i r_i u_i and *d = sum_i w_i u_i^2, in four lanes. */
static inline void wdot(const double *restrict w, const double *restrict r, const double *restrict u, size_t m,
                        double *b, double *d) {
    double bl[4] = {0, 0, 0, 0}, dl[4] = {0, 0, 0, 0};
    size_t i = 0;
    for (; i + 4 <= m; i += 4)
        for (int l = 0; l < 4; l++) {
            double wu = w[i + l] * u[i + l];
            bl[l] += wu * r[i + l];
            dl[l] += wu * u[i + l];
        }
    for (; i < m; i++) {
        bl[0] += w[i] * u[i] * r[i];
        dl[0] += w[i] * u[i] * u[i];
    }
    *b = (bl[0] + bl[1]) + (bl[2] + bl[3]);
    *d = (dl[0] + dl[1]) + (dl[2] + dl[3]);
}

/* Step: y -= a x over n (restrict: the loops vectorise). */
static inline void axpy_neg(double *restrict y, const double *restrict x, double a, size_t n) {
    for (size_t i = 0; i < n; i++)
        y[i] -= a * x[i];
}

/* Step: returns sum_i w_i r_i^2, then r += a u (four lanes). */
static inline double wsq_add(const double *restrict w, double *restrict r, const double *restrict u, double a,
                             size_t m) {
    double fl[4] = {0, 0, 0, 0};
    size_t i = 0;
    for (; i + 4 <= m; i += 4)
        for (int l = 0; l < 4; l++) {
            fl[l] += w[i + l] * r[i + l] * r[i + l];
            r[i + l] += a * u[i + l];
        }
    for (; i < m; i++) {
        fl[0] += w[i] * r[i] * r[i];
        r[i] += a * u[i];
    }
    return (fl[0] + fl[1]) + (fl[2] + fl[3]);
}

#endif
