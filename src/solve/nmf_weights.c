/* The non-negative solver's cell weights toward the headline, and the
 * reference errors of its prefixes (nmf_weights.h).
 *
 * The headline measures f_r cos theta_i over the pairs' solid angles; the
 * fit, the stored form over the layout's cell measures.  A cell's entry A
 * is f_r x form weight / gain (sample/matrix.c), so the headline's error
 * of a cell is gain cos theta_i / form weight times the fit's.  The cell
 * measures are solid angles on every layout but vndf, whose nodes follow
 * its VNDF warp (param_vndf.c: "a weight, not a quadrature"): there a
 * node's solid angle is 4 sigma / NDF = 1 / gain of its column measure.
 * The SVD minimises the fit's error and is the best there at every J';
 * the non-negative terms are not, and where they lose decides the
 * headline: RGL cc_green_malachite on vndf, J' = 3, green 1.41x the SVD's
 * error on the cells and 3.75x its headline. */
#include "solve/nmf_weights.h"

#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Cells' weights above this quantile of the data cells' are clipped: the
 * vndf gain carries max(cos theta_l, 0.001) / cos theta_l below 0.001
 * (up to 1e7, param_vndf.c guard_undo) on a few nodes at the horizon. */
#define NMF_HW_QUANTILE 0.99

/* Step: the k-th smallest of q[0..n) (reorders q; Hoare's selection). */
static double select_kth(double *q, size_t n, size_t k) {
    size_t lo = 0, hi = n - 1;
    while (lo < hi) {
        double pivot = q[lo + (hi - lo) / 2];
        size_t i = lo, j = hi;
        while (i <= j) {
            while (q[i] < pivot)
                i++;
            while (q[j] > pivot)
                j--;
            if (i <= j) {
                double t = q[i];
                q[i] = q[j];
                q[j] = t;
                i++;
                if (j-- == 0) break;
            }
        }
        if (k <= j && j != (size_t)-1)
            hi = j;
        else if (k >= i)
            lo = i;
        else
            break;
    }
    return q[k];
}

/* Step: w (n numbers) divided by its mean over `data` cells; returns 0,
 * or -1 where it sums to 0. */
static int normalise(double *w, size_t n, size_t data) {
    double sum = 0;
    for (size_t k = 0; k < n; k++)
        sum += w[k];
    if (!(sum > 0)) return -1;
    for (size_t k = 0; k < n; k++)
        w[k] *= (double)data / sum;
    return 0;
}

/* Step: the weight of one cell, 0 where it is no BRDF pair. */
static double cell_weight(const sb_param_t *p, sb_form_t form, size_t row, size_t col) {
    double wi[3], wo[3];
    if (!sb_param_cell_dirs(p, row, col, wi, wo) || !(wi[2] > 0)) return 0;
    double fw = sb_form_weight(form, wi, wo), gain = sb_param_gain(p, wi, wo);
    if (!(fw > 0) || !(gain > 0)) return 0;
    double c = wi[2] / fw, w = c * c * gain * ((sb_param_caps(p) & SB_CAP_TABLES) ? 1 : gain);
    return isfinite(w) ? w : 0;
}

int sb_nmf_headline_weights(const sb_param_t *p, sb_form_t form, const unsigned char *ext, size_t m, size_t n,
                            double *hw, double *raw) {
    size_t cnt = 0;
    for (size_t c = 0; c < n; c++)
        for (size_t i = 0; i < m; i++) {
            size_t k = i + c * m;
            hw[k] = ext[k] == 1 ? cell_weight(p, form, i, c) : 0;
            cnt += hw[k] > 0;
        }
    if (!cnt) return -1;
    if (raw) memcpy(raw, hw, m * n * sizeof *raw);
    double *q = malloc(cnt * sizeof *q);
    if (!q) return -1;
    for (size_t k = 0, at = 0; k < m * n; k++)
        if (hw[k] > 0) q[at++] = hw[k];
    double clip = select_kth(q, cnt, (size_t)(NMF_HW_QUANTILE * (double)(cnt - 1))), sum = 0;
    free(q);
    size_t data = 0;
    for (size_t k = 0; k < m * n; k++) {
        hw[k] = fmin(hw[k], clip);
        sum += hw[k];
        data += ext[k] == 1;
    }
    if (!(sum > 0)) return -1;
    for (size_t k = 0; k < m * n; k++)
        hw[k] *= (double)data / sum;
    return raw ? normalise(raw, m * n, data) : 0;
}

int sb_nmf_svd_terms(const double *x, size_t m, size_t n, size_t J, double *U, double *V) {
    size_t r = m < n ? m : n;
    double *a = malloc(m * n * sizeof *a), *s = malloc(r * sizeof *s), *u = malloc(m * r * sizeof *u),
           *vt = malloc(r * n * sizeof *vt);
    int ok = a && s && u && vt;
    if (ok) {
        memcpy(a, x, m * n * sizeof *a);
        ok = LAPACKE_dgesdd(LAPACK_COL_MAJOR, 'S', (lapack_int)m, (lapack_int)n, a, (lapack_int)m, s, u, (lapack_int)m,
                            vt, (lapack_int)r) == 0;
    }
    for (size_t j = 0; ok && j < J; j++) {
        for (size_t i = 0; i < m; i++)
            U[i + j * m] = j < r ? s[j] * u[i + j * m] : 0;
        for (size_t c = 0; c < n; c++)
            V[c + j * n] = j < r ? vt[j + c * r] : 0;
    }
    free(a);
    free(s);
    free(u);
    free(vt);
    return ok ? 0 : -1;
}

/* Step: sum hw (x - A_p B_p^T)^2 for p = 1..J into f (A: m x J, B: n x J). */
static void prefix_errors(const double *x, const double *hw, size_t m, size_t n, size_t J, const double *A,
                          const double *B, double *f) {
    memset(f, 0, J * sizeof *f);
    for (size_t c = 0; c < n; c++)
        for (size_t i = 0; i < m; i++) {
            double r = x[i + c * m], w = hw[i + c * m];
            for (size_t p = 0; w > 0 && p < J; p++) {
                r -= A[i + p * m] * B[c + p * n];
                f[p] += w * r * r;
            }
        }
}

void sb_nmf_prefix_ratios(const double *x, const double *hw, size_t m, size_t n, size_t J, const double *U,
                          const double *V, const double *R, const double *S, double floor2, double *ratio) {
    double *f = malloc(2 * J * sizeof *f);
    for (size_t p = 0; !f && p < J; p++)
        ratio[p] = INFINITY;
    if (!f) return;
    prefix_errors(x, hw, m, n, J, U, V, f);
    prefix_errors(x, hw, m, n, J, R, S, f + J);
    for (size_t p = 0; p < J; p++)
        ratio[p] = f[p] / fmax(f[J + p], floor2);
    free(f);
}

double sb_nmf_worst_ratio(const double *x, const double *hw, size_t m, size_t n, size_t J, const double *U,
                          const double *V, const double *R, const double *S, double floor2) {
    double *f = malloc(J * sizeof *f), worst = 0;
    if (!f) return INFINITY;
    sb_nmf_prefix_ratios(x, hw, m, n, J, U, V, R, S, floor2, f);
    for (size_t p = 0; p < J; p++)
        worst = fmax(worst, f[p]);
    free(f);
    return worst;
}
