/* Loops of the non-negative solver's sweeps over a column (nmf_sweeps.c),
 * in four lanes where they sum, restrict so that they vectorise. */
#ifndef SB_SOLVE_NMF_LANES_H
#define SB_SOLVE_NMF_LANES_H

#include <stddef.h>
#include <string.h>

#if defined(__GNUC__)
/* Four doubles, one lane each: the loops below add lane l of every
 * quadruple into sum l as the plain arrays do (the same operations and
 * bits), in one 256-bit vector where the AVX2 clone runs (two halves in
 * the baseline), where GCC's vectoriser shuffled the arrays' lanes. */
typedef double sb_nmf_v4 __attribute__((vector_size(32)));
/* v = p[0..3], p[0..3] = v (unaligned; macros: a function returning a
 * vector would change the baseline's ABI) */
#define V4_LOAD(v, p) memcpy(&(v), (p), sizeof(v))
#define V4_STORE(p, v) memcpy((p), &(v), sizeof(v))
#define SB_NMF_V4 1
#endif

/* Step: *b = sum_i w_i r_i u_i and *d = sum_i w_i u_i^2, in four lanes. */
static inline void wdot(const double *restrict w, const double *restrict r, const double *restrict u, size_t m,
                        double *b, double *d) {
    double bl[4] = {0, 0, 0, 0}, dl[4] = {0, 0, 0, 0};
    size_t i = 0;
#ifdef SB_NMF_V4
    sb_nmf_v4 bv = {0, 0, 0, 0}, dv = {0, 0, 0, 0};
    for (; i + 4 <= m; i += 4) {
        sb_nmf_v4 uv, wv, rv;
        V4_LOAD(uv, u + i), V4_LOAD(wv, w + i), V4_LOAD(rv, r + i);
        sb_nmf_v4 wu = wv * uv;
        bv += wu * rv;
        dv += wu * uv;
    }
    V4_STORE(bl, bv);
    V4_STORE(dl, dv);
#endif
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

/* Step: e -= a du and r -= ar du, then *b = sum_i w_i r_i u_i and *d =
 * sum_i w_i u_i^2 (two axpy_neg and wdot in one pass: the same bits). */
static inline void sub2_wdot(double *restrict e, double *restrict r, const double *restrict du, double a, double ar,
                             const double *restrict w, const double *restrict u, size_t m, double *b, double *d) {
    double bl[4] = {0, 0, 0, 0}, dl[4] = {0, 0, 0, 0};
    size_t i = 0;
#ifdef SB_NMF_V4
    sb_nmf_v4 bv = {0, 0, 0, 0}, dv = {0, 0, 0, 0};
    for (; i + 4 <= m; i += 4) {
        sb_nmf_v4 ev, rv, duv, uv, wv;
        V4_LOAD(ev, e + i), V4_LOAD(rv, r + i), V4_LOAD(duv, du + i), V4_LOAD(uv, u + i), V4_LOAD(wv, w + i);
        ev -= a * duv;
        rv -= ar * duv;
        V4_STORE(e + i, ev);
        V4_STORE(r + i, rv);
        sb_nmf_v4 wu = wv * uv;
        bv += wu * rv;
        dv += wu * uv;
    }
    V4_STORE(bl, bv);
    V4_STORE(dl, dv);
#endif
    for (; i + 4 <= m; i += 4)
        for (int l = 0; l < 4; l++) {
            e[i + l] -= a * du[i + l];
            r[i + l] -= ar * du[i + l];
            double wu = w[i + l] * u[i + l];
            bl[l] += wu * r[i + l];
            dl[l] += wu * u[i + l];
        }
    for (; i < m; i++) {
        e[i] -= a * du[i];
        r[i] -= ar * du[i];
        bl[0] += w[i] * u[i] * r[i];
        dl[0] += w[i] * u[i] * u[i];
    }
    *b = (bl[0] + bl[1]) + (bl[2] + bl[3]);
    *d = (dl[0] + dl[1]) + (dl[2] + dl[3]);
}

/* Step: e -= a x and r -= ar x (two axpy_neg in one pass). */
static inline void axpy2_neg(double *restrict e, double *restrict r, const double *restrict x, double a, double ar,
                             size_t n) {
    for (size_t i = 0; i < n; i++) {
        e[i] -= a * x[i];
        r[i] -= ar * x[i];
    }
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
#ifdef SB_NMF_V4
    sb_nmf_v4 fv = {0, 0, 0, 0};
    for (; i + 4 <= m; i += 4) {
        sb_nmf_v4 wv, rv, uv;
        V4_LOAD(wv, w + i), V4_LOAD(rv, r + i), V4_LOAD(uv, u + i);
        fv += wv * rv * rv;
        rv += a * uv;
        V4_STORE(r + i, rv);
    }
    V4_STORE(fl, fv);
#endif
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
