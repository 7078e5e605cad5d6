/* The non-negative solver's cell weights toward the headline, and the
 * reference errors of its prefixes (nmf_weights.h).
 *
 * The headline measures f_r cos theta_i over the pairs' solid angles; the
 * fit, the stored form over the layout's cell measures.  A cell's entry A
 * is f_r x form weight / gain (sample/matrix.c), so the headline's error
 * of a cell is gain cos theta_i / form weight times the fit's.  The cell
 * measures are solid angles on every layout but vndf, whose nodes follow
 * its VNDF warp (param_vndf.c: "a weight, not a quadrature"): there a
 * node's solid angle is 4 sigma / NDF of its column measure.
 *
 * A cell's headline factor is cos theta_i gain / the snippet's divisor
 * (sb_form_divisor: max(cos theta_i, 0.001) for form cos), not the form
 * weight: vndf's gain carries 0.001 / cos theta_i below 0.001 (guard_undo
 * in param_vndf.c, up to 1e7) that this divisor cancels.  Taken as the
 * weight (round h32n and before), a few nodes at the horizon weighed up
 * to 1e7 times the others and the 0.99 quantile clip gave the top 1 % of
 * nodes one weight: RGL chm_orange on vndf, --method nmf -J 4, blue
 * headline 0.145 against the SVD's 0.021; with the headline's own factor
 * 0.027.  On vndf the nodes whose light is below the horizon are the
 * file's (cell_value) and the lookup blends them into the pairs just
 * above it: those next to a node above the horizon (in the slice or the
 * slices beside) weigh NMF_BELOW_WEIGHT of what the same node would weigh
 * just above the horizon, the others 0:
 * aurora_white's J' = 4 went from 0.51 (44x the SVD's) to 0.020 in the
 * first fit (docs/positive.md, "The vndf gain as a weight").
 * The SVD minimises the fit's error and is the best there at every J';
 * the non-negative terms are not, and where they lose decides the
 * headline: RGL cc_green_malachite on vndf, J' = 3, green 1.41x the SVD's
 * error on the cells and 3.75x its headline. */
#include "solve/nmf_weights.h"

#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Cells' weights above this quantile of the data cells' are clipped (the
 * NDF's peak on vndf; 1.0 changed nothing on RGL aurora, round h32n). */
#define NMF_HW_QUANTILE 0.99

/* A node below the horizon next to one above it, against the same node
 * just above the horizon (the lookup's pairs on one side of its patch
 * read it).  Measured (round h32n, RGL --method nmf -J 4, nmf_over_svd at
 * J' = 4, pooled): 0.1: aurora 1.63, paper 1.40; 0.2: 1.52, 1.43; 0.25:
 * 1.52, 1.40 (paper red 1.61); 0.5: 1.52, 1.63; 0 (none): aurora's vndf
 * screening fit 0.54 at J = 4 and auto kept vh (0.094 against vndf's
 * 0.018). */
#define NMF_BELOW_WEIGHT 0.2

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

/* Step: the weight of one cell, 0 where it is no BRDF pair; on a layout
 * on the source's tables a node whose light is below the horizon (*below)
 * weighs as the same node with its light just above it. */
static double cell_weight(const sb_param_t *p, sb_form_t form, size_t row, size_t col, unsigned char *below) {
    double wi[3], wo[3];
    int tables = (sb_param_caps(p) & SB_CAP_TABLES) != 0;
    *below = 0;
    if (!sb_param_cell_dirs(p, row, col, wi, wo)) return 0;
    if (!(wi[2] > 0) && tables) {
        double h = sqrt(wi[0] * wi[0] + wi[1] * wi[1]);
        if (!(h > 0)) return 0;
        wi[0] /= h, wi[1] /= h, wi[2] = 1e-7;
        *below = 1;
    }
    if (!(wi[2] > 0)) return 0;
    double fw = sb_form_weight(form, wi, wo), gain = sb_param_gain(p, wi, wo);
    if (!(fw > 0) || !(gain > 0)) return 0;
    double a = wi[2] * gain / sb_form_divisor(form, wi, wo), w = a * a;
    if (tables) w /= gain * wi[2] / fmax(wi[2], 0.001); /* the node's solid angle: NDF / (4 sigma) */
    return isfinite(w) ? w : 0;
}

/* Step: whether a node (i, c) of a layout on the source's tables (columns
 * the sw x sh nodes of the colour grid) has a node within one step, in its
 * slice or the slices beside, whose light is above the horizon. */
static int near_above(const double *hw, const unsigned char *below, size_t m, size_t n, size_t sw, size_t i, size_t c) {
    long x = (long)(c % sw), y = (long)(c / sw), sh = (long)(n / sw);
    for (long di = -1; di <= 1; di++)
        for (long dy = -1; dy <= 1; dy++)
            for (long dx = -1; dx <= 1; dx++) {
                long ii = (long)i + di, xx = x + dx, yy = y + dy;
                if (ii < 0 || ii >= (long)m || xx < 0 || xx >= (long)sw || yy < 0 || yy >= sh) continue;
                size_t k = (size_t)ii + (size_t)(xx + yy * (long)sw) * m;
                if (!below[k] && hw[k] > 0) return 1;
            }
    return 0;
}

/* Step: the nodes below the horizon at NMF_BELOW_WEIGHT of their weight
 * next to one above it, else 0; returns the number of cells weighing > 0. */
static size_t below_halved(const sb_param_t *p, double *hw, const unsigned char *below, size_t m, size_t n) {
    size_t sw = 0, sh = 0, cnt = 0;
    sb_param_texture_size(p, 1, &sw, &sh);
    for (size_t c = 0; c < n; c++)
        for (size_t i = 0; i < m; i++) {
            size_t k = i + c * m;
            if (below[k]) hw[k] *= sw && sw * sh == n && near_above(hw, below, m, n, sw, i, c) ? NMF_BELOW_WEIGHT : 0;
        }
    for (size_t k = 0; k < m * n; k++)
        cnt += hw[k] > 0;
    return cnt;
}

void sb_nmf_spread_weights(const sb_param_t *p, const double *hw, size_t m, size_t n, double k, double *out) {
    size_t sw = 0, sh = 0;
    sb_param_texture_size(p, 1, &sw, &sh);
    memcpy(out, hw, m * n * sizeof *out);
    if (!sw || sw * sh != n) return;
    for (size_t c = 0; c < n; c++) {
        long x = (long)(c % sw), y = (long)(c / sw);
        for (long dy = -1; dy <= 1; dy++)
            for (long dx = -1; dx <= 1; dx++) {
                long xx = x + dx, yy = y + dy;
                if (xx < 0 || xx >= (long)sw || yy < 0 || yy >= (long)sh) continue;
                const double *h = hw + (size_t)(xx + yy * (long)sw) * m;
                for (size_t i = 0; i < m; i++)
                    out[i + c * m] = fmax(out[i + c * m], k * h[i]);
            }
    }
}

int sb_nmf_headline_weights(const sb_param_t *p, sb_form_t form, const unsigned char *ext, size_t m, size_t n,
                            double *hw, double *raw) {
    unsigned char *below = calloc(m * n, 1);
    if (!below) return -1;
    for (size_t c = 0; c < n; c++)
        for (size_t i = 0; i < m; i++) {
            size_t k = i + c * m;
            hw[k] = ext[k] == 1 ? cell_weight(p, form, i, c, &below[k]) : 0;
        }
    size_t cnt = below_halved(p, hw, below, m, n);
    free(below);
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
