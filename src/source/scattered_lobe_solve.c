/* The linear weights of one lobe shape (scattered_lobe.c): per channel c
 * the non-negative least squares, in the norm of f cos theta_i (weights
 * w), of
 *   grey Fresnel:        f ~ kd + ks S,          S = D G F(f0) / den
 *   per-channel Fresnel: f ~ kd + a S1 + b T,    S1 = D G / den (F = 1),
 *                                                T = S1 (1 - v.h)^5
 * the second being Schlick's F with its own F0 per channel, ks F_c =
 * ks (f0_c + (1 - f0_c) m^5) = a + b m^5 with a = ks f0_c, b = ks (1 -
 * f0_c): a coloured metal's highlight turns white towards grazing, which
 * one F0 for all channels cannot follow.  Both are closed forms from the
 * sums of sums_t: the minimum over the supports (the non-negative
 * optimum is the unconstrained one on its support).  Also the floor under
 * the base (sb_lobe_floor_). */
#include <math.h>
#include <stdlib.h>

#include "source/scattered_impl.h"

double sb_lobe_solve2_(const lobe_sums_t *m, int c, double *kd, double *ks) {
    double best = INFINITY, cand[3][2] = {{0, 0}, {0, 0}, {0, 0}};
    double det = m->w * m->wss - m->ws * m->ws;
    if (det > 1e-300 * (m->w * m->wss + 1e-300)) {
        cand[0][0] = (m->wss * m->wf[c] - m->ws * m->wsf[c]) / det;
        cand[0][1] = (m->w * m->wsf[c] - m->ws * m->wf[c]) / det;
    }
    cand[1][0] = m->w > 0 ? fmax(m->wf[c] / m->w, 0) : 0;
    cand[2][1] = m->wss > 0 ? fmax(m->wsf[c] / m->wss, 0) : 0;
    for (int i = 0; i < 3; i++) {
        double a = cand[i][0], b = cand[i][1];
        if (a < 0 || b < 0) continue;
        double r = m->wff[c] - 2 * (a * m->wf[c] + b * m->wsf[c]) + a * a * m->w + 2 * a * b * m->ws + b * b * m->wss;
        if (r < best) best = r, *kd = a, *ks = b;
    }
    return best;
}

/* Solve the n x n system A y = A[.][n] (n <= 3) by Gaussian elimination
 * with partial pivoting; 0 when a pivot is below 1e-13 of the largest
 * diagonal (the support's columns are dependent: another support has the
 * same fit). */
static int solve_small(double A[3][4], int n, double y[3]) {
    double scale = 0;
    for (int i = 0; i < n; i++)
        scale = fmax(scale, fabs(A[i][i]));
    for (int k = 0; k < n; k++) {
        int p = k;
        for (int i = k + 1; i < n; i++)
            if (fabs(A[i][k]) > fabs(A[p][k])) p = i;
        if (!(fabs(A[p][k]) > 1e-13 * scale)) return 0;
        for (int j = 0; j <= n; j++) {
            double t = A[k][j];
            A[k][j] = A[p][j], A[p][j] = t;
        }
        for (int i = k + 1; i < n; i++) {
            double r = A[i][k] / A[k][k];
            for (int j = k; j <= n; j++)
                A[i][j] -= r * A[k][j];
        }
    }
    for (int k = n - 1; k >= 0; k--) {
        double s = A[k][n];
        for (int j = k + 1; j < n; j++)
            s -= A[k][j] * y[j];
        y[k] = s / A[k][k];
    }
    return 1;
}

double sb_lobe_solve3_(const lobe_sums_t *m, int c, double *kd, double *ks, double *f0) {
    const double G[3][3] = {{m->w, m->ws, m->wt}, {m->ws, m->wss, m->wst}, {m->wt, m->wst, m->wtt}};
    const double g[3] = {m->wf[c], m->wsf[c], m->wtf[c]};
    double best = m->wff[c], x[3] = {0, 0, 0}; /* the empty support: all weights 0 */
    for (int set = 1; set < 8; set++) {
        int at[3], n = 0;
        for (int i = 0; i < 3; i++)
            if (set >> i & 1) at[n++] = i;
        double A[3][4], y[3], z[3] = {0, 0, 0};
        for (int i = 0; i < n; i++) {
            for (int j = 0; j < n; j++)
                A[i][j] = G[at[i]][at[j]];
            A[i][n] = g[at[i]];
        }
        if (!solve_small(A, n, y)) continue;
        int neg = 0;
        for (int i = 0; i < n; i++)
            neg |= !(y[i] >= 0), z[at[i]] = y[i];
        if (neg) continue;
        double r = m->wff[c];
        for (int i = 0; i < 3; i++) {
            r -= 2 * z[i] * g[i];
            for (int j = 0; j < 3; j++)
                r += z[i] * G[i][j] * z[j];
        }
        if (r < best) best = r, x[0] = z[0], x[1] = z[1], x[2] = z[2];
    }
    *kd = x[0];
    *ks = x[1] + x[2];
    *f0 = *ks > 0 ? x[1] / *ks : 1;
    return best;
}

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

void sb_lobe_floor_(const double *smp, size_t ns, double floor_[3]) {
    double *v = malloc(ns * sizeof *v);
    for (int c = 0; c < 3; c++) {
        floor_[c] = 1e-12; /* never 0: the base divides */
        if (!v) continue;
        for (size_t i = 0; i < ns; i++)
            v[i] = smp[i * SB_SAMPLE_DOUBLES + 6 + (size_t)c];
        qsort(v, ns, sizeof *v, cmp_double);
        floor_[c] = fmax(v[ns / 2], 1e-3 * fmax(v[ns - 1], 0)) + 1e-12;
    }
    free(v);
}
