/* Local fits of the scattered-sample source: the value at an embedded
 * position from its neighbours (weighted least-squares polynomial, inverse
 * distance weights or the nearest sample), and the source's eval with its
 * blend towards the azimuthal mean near the normal. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "source/scattered_impl.h"
#include "util/chol.h"
#include "util/internal.h"

#define MAX_TERMS 15 /* 1 + 4 + 10: quadratic in 4D */
/* Ridge on the polynomial's slopes and curvatures, relative to the
 * weighted spread of the neighbours: directions the neighbours do not span
 * get a zero slope instead of a wild one. */
#define RIDGE 1e-2

/* With the lobe: a neighbour whose base differs from the position's by
 * the factor e^LEVEL_SCALE counts e^-1 of its weight (Gaussian in the ln
 * of the ratio), and the weight its neighbours lose this way goes to the
 * lobe itself (q = 1 at the position).  Beside a highlight narrower than
 * the samples' spacing the neighbours of a position on the peak are off
 * it, and their quotients (the diffuse colour over the diffuse fit) say
 * nothing about the peak's: the lobe's colour and height then hold there,
 * as the samples on the peak hold them. */
#define LEVEL_SCALE 1.3862943611198906 /* ln 4 */

/* The grid (1 / POSITION_GRID radians, 1.5e-11) evaluated positions are
 * rounded to: pairs that isotropy and reciprocity fold onto one position
 * reach it through different arithmetic (hd's frame), a few units of the
 * last place apart; rounded, they meet in the memo (a value is a
 * function of the rounded position: the same bits in any order).  The
 * values move by far less than the interpolation's own error (the
 * acrylic's figures in the ninth digit). */
#define POSITION_GRID 68719476736.0 /* 2^36 */

/* Azimuth differences averaged over at the pole (pole_mean): 5 deg steps. */
#define POLE_STEPS 37

/* Weighted least squares y ~ sum_m c_m u_m(p - x) over the neighbours with
 * u = (1, p - x) (linear) or (1, p - x, (p - x)_a (p - x)_b, a <= b)
 * (quadratic), weights count/d^2 (count: samples merged into the point),
 * a ridge RIDGE * spread (spread^2 for the quadratic terms) on all but c_0,
 * solved by Cholesky; c_0 is the value at x, clamped to the neighbours'
 * range.  Returns 0 (rgb untouched) if the system is not positive
 * definite. */
/* The normal equations' lower triangle A (P x P, row-major) and right-hand
 * sides B (P x 3) over the neighbours, with the weights' sums; inlined
 * into one copy per (D, P) so that the loops have fixed bounds.  Each
 * entry is the sum over the neighbours in their order of w u_a u_b (w u_a
 * v_c), as a loop over the neighbours adding into A and B sums it, but
 * computed entry by entry: four entries of a row side by side in a
 * vector's lanes, each lane its own sum in the same order (the same
 * bits), held in a register through the neighbours instead of A and B
 * read and written once per neighbour (poly_fit was a fifth of the CPU of
 * a default run on a table of one theta_i, S3). */
typedef double v4d_t __attribute__((vector_size(32), aligned(8))); /* loads at any 8-byte address */
#define PW 16                                                      /* MAX_TERMS padded to whole vectors */
static inline __attribute__((always_inline)) void poly_accum(const table_t *t, const double *x, const knn_t *q,
                                                             const double *kw, const int D, const int P, double *A,
                                                             double *B, double lo[3], double hi[3], double *spread,
                                                             double *wsum) {
    double U[KNN_MAX][PW], WU[KNN_MAX][PW], V[KNN_MAX][3];
    const int nv = (P + 3) / 4;
    for (size_t i = 0; i < q->n; i++) {
        const double *p = t->pts + q->at[i] * MAX_DIM, *v = t->val + 4 * q->at[i];
        double w = v[3] / q->d2[i] * (kw ? kw[i] : 1), *u = U[i];
        u[0] = 1;
        for (int a = 0; a < D; a++)
            u[a + 1] = p[a] - x[a];
        for (int a = 0, m = 1 + D; P > 1 + D && a < D; a++)
            for (int b = a; b < D; b++)
                u[m++] = u[a + 1] * u[b + 1];
        for (int a = P; a < 4 * nv; a++)
            u[a] = 0;
        for (int a = 0; a < 4 * nv; a++)
            WU[i][a] = w * u[a];
        for (int c = 0; c < 3; c++) {
            V[i][c] = v[c];
            if (v[c] < lo[c]) lo[c] = v[c];
            if (v[c] > hi[c]) hi[c] = v[c];
        }
        *spread += w * q->d2[i];
        *wsum += w;
    }
    for (int a = 0; a < P; a++)
        for (int k = 0; 4 * k <= a; k++) {
            v4d_t acc = {0, 0, 0, 0};
            for (size_t i = 0; i < q->n; i++)
                acc += WU[i][a] * *(const v4d_t *)(U[i] + 4 * k);
            for (int b = 4 * k; b <= a && b < 4 * k + 4; b++)
                A[a * P + b] = acc[b - 4 * k];
        }
    for (int a = 0; a < P; a++) /* the upper triangle, unused, as zeros */
        for (int b = a + 1; b < P; b++)
            A[a * P + b] = 0;
    for (int k = 0; k < nv; k++)
        for (int c = 0; c < 3; c++) {
            v4d_t acc = {0, 0, 0, 0};
            for (size_t i = 0; i < q->n; i++)
                acc += *(const v4d_t *)(WU[i] + 4 * k) * V[i][c];
            for (int a = 4 * k; a < P && a < 4 * k + 4; a++)
                B[a * 3 + c] = acc[a - 4 * k];
        }
}
#undef PW

SB_AVX2_CLONES static int poly_fit(const table_t *t, const double *x, const knn_t *q, const double *kw, double prior,
                                   int quadratic, double rgb[3]) {
    int D = t->dim, P = 1 + D + (quadratic ? D * (D + 1) / 2 : 0);
    double A[MAX_TERMS * MAX_TERMS], B[MAX_TERMS * 3];
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY}, spread = 0, wsum = 0;
    if (D == 3 && quadratic)
        poly_accum(t, x, q, kw, 3, 10, A, B, lo, hi, &spread, &wsum);
    else if (D == 3)
        poly_accum(t, x, q, kw, 3, 4, A, B, lo, hi, &spread, &wsum);
    else if (quadratic)
        poly_accum(t, x, q, kw, 4, 15, A, B, lo, hi, &spread, &wsum);
    else
        poly_accum(t, x, q, kw, 4, 5, A, B, lo, hi, &spread, &wsum);
    if (prior > 0) { /* the lobe's own value, q = 1, observed at x */
        A[0] += prior;
        for (int c = 0; c < 3; c++) {
            B[c] += prior;
            lo[c] = fmin(lo[c], 1);
            hi[c] = fmax(hi[c], 1);
        }
    }
    double s2 = spread / wsum;
    for (int a = 1; a < P; a++)
        A[a * P + a] += RIDGE * wsum * (a <= D ? s2 : s2 * s2);
    if (!sb_chol(A, (size_t)P, 0)) return 0; /* A = L L^T in the lower triangle */
    double out[3];
    for (int c = 0; c < 3; c++) {
        sb_chol_solve(A, (size_t)P, B + c, 3); /* column c of B (row-major P x 3) */
        double y0 = B[c];
        if (!isfinite(y0)) return 0;
        out[c] = y0 < lo[c] ? lo[c] : (y0 > hi[c] ? hi[c] : y0);
    }
    memcpy(rgb, out, sizeof out);
    return 1;
}

/* The previous full query's neighbours on this thread.  A matrix row, a
 * scan line or a warp scan asks for neighbouring positions one after the
 * other, so the farthest of those k points from the new position bounds
 * the search from its start: any k distinct points of the table do, so
 * the k nearest found are the same (knn_after orders ties), with far
 * fewer nodes visited.  Indices beyond the table (another table since)
 * are not used. */
static _Thread_local struct {
    size_t n;
    size_t at[KNN_MAX];
    int missing; /* the previous position was missing (has_near) */
} last;

static double seed_bound(const table_t *t, const double *x, size_t k) {
    if (last.n != k) return INFINITY;
    double b = 0;
    for (size_t i = 0; i < k; i++) {
        if (last.at[i] >= t->n) return INFINITY;
        const double *p = t->pts + last.at[i] * MAX_DIM;
        double d = 0;
        for (int a = 0; a < MAX_DIM; a++)
            d += (p[a] - x[a]) * (p[a] - x[a]);
        if (d > b) b = d;
    }
    return b;
}

/* Whether a point lies within the radius of x (d^2 <= t->r2): a search
 * for the nearest bounded by the radius.  Where none does the position is
 * missing whatever its neighbours in the wider support (t->s2), and the
 * search for the k nearest there was the cost: on the Cornell acrylic cut
 * to one theta_i, 44 % of the queries of a default run were the pole
 * means' 37 azimuths (pole_mean) at positions no sample is near.  Asked
 * only after a missing position (missing ones come in runs along a row or
 * a pole mean's azimuths): before every query it cost the full acrylic
 * 4-9 % more CPU, where nearly every position is known. */
static int has_near(const table_t *t, const double *x) {
    knn_t q;
    q.k = 1;
    q.n = 0;
    q.r2 = t->r2;
    q.skip = NULL;
    q.nskip = 0;
    sb_kd_query_(t, x, 0, t->n, &q);
    return q.n > 0;
}

/* The value at embedded position x by method `interp` with k neighbours,
 * leaving out the points at the nskip positions of `skip`: 0 missing, 1
 * known, 2 known at a measured position (the measurement). */
int sb_table_at_(const table_t *t, sb_interp_t interp, size_t k, const double *x, const double *skip, int nskip,
                 double lx, double rgb[3]) {
    rgb[0] = rgb[1] = rgb[2] = 0;
    knn_t q;
    q.k = interp == SB_INTERP_NEAREST ? 1 : k;
    q.n = 0;
    q.r2 = interp == SB_INTERP_NEAREST ? t->r2 : t->s2;
    q.skip = skip;
    q.nskip = nskip;
    if (!nskip && last.missing && !has_near(t, x)) return 0; /* missing, as sb_table_from_knn_ would find */
    if (!nskip) {
        double b = seed_bound(t, x, q.k);
        if (b < q.r2) q.r2 = b;
    }
    sb_kd_query_(t, x, 0, t->n, &q);
    if (!nskip) {
        last.n = q.n;
        memcpy(last.at, q.at, q.n * sizeof *q.at);
    }
    /* The heap's order depends on the bound the search started from; in
     * one order the fits sum the same terms in the same order whatever
     * was asked before (a value is a function of x alone). */
    sb_knn_canon_(&q);
    int known = sb_table_from_knn_(t, interp, x, &q, lx, rgb);
    if (!nskip) last.missing = !known;
    return known;
}

int sb_table_from_knn_(const table_t *t, sb_interp_t interp, const double *x, const knn_t *q, double lx,
                       double rgb[3]) {
    rgb[0] = rgb[1] = rgb[2] = 0;
    double d0 = INFINITY; /* the nearest (the heap is ordered by the farthest) */
    for (size_t i = 0; i < q->n; i++)
        if (q->d2[i] < d0) d0 = q->d2[i];
    if (q->n == 0 || d0 > t->r2) return 0;
    /* At a measured position (or for nearest): the sample, repeats averaged. */
    if (d0 <= SAME_POSITION * SAME_POSITION || interp == SB_INTERP_NEAREST) {
        double lim = d0 <= SAME_POSITION * SAME_POSITION ? SAME_POSITION * SAME_POSITION : d0;
        double cnt = 0;
        const double *vals = d0 <= SAME_POSITION * SAME_POSITION && t->raw ? t->raw : t->val;
        for (size_t m = 0; m < q->n; m++) {
            if (q->d2[m] > lim) continue;
            const double *v = vals + 4 * q->at[m];
            for (int c = 0; c < 3; c++)
                rgb[c] += v[3] * v[c];
            cnt += v[3];
        }
        for (int c = 0; c < 3; c++)
            rgb[c] /= cnt;
        return d0 <= SAME_POSITION * SAME_POSITION ? 2 : 1;
    }
    /* With the lobe: each neighbour's weight by how near its base is to
     * the position's, the rest to the lobe (LEVEL_SCALE). */
    double kw[KNN_MAX], prior = 0;
    const double *kwp = NULL;
    if (t->lobe_on && t->lb) {
        if (isnan(lx)) lx = sb_lobe_level_(t, x);
        for (size_t i = 0; i < q->n; i++) {
            double d = (t->lb[q->at[i]] - lx) / LEVEL_SCALE, w = t->val[4 * q->at[i] + 3] / q->d2[i];
            kw[i] = exp(-d * d);
            prior += w * (1 - kw[i]);
        }
        kwp = kw;
    }
    /* Inverse squared distance weights: the value, or the fallback. */
    double wsum = prior;
    for (int c = 0; c < 3; c++)
        rgb[c] = prior;
    for (size_t i = 0; i < q->n; i++) {
        double w = t->val[4 * q->at[i] + 3] / q->d2[i] * (kwp ? kw[i] : 1);
        for (int c = 0; c < 3; c++)
            rgb[c] += w * t->val[4 * q->at[i] + c];
        wsum += w;
    }
    for (int c = 0; c < 3; c++)
        rgb[c] /= wsum;
    /* Local polynomial when there are enough neighbours: twice the terms. */
    size_t lin = 2 * ((size_t)t->dim + 1), quad = 2 * (1 + (size_t)t->dim + (size_t)(t->dim * (t->dim + 1) / 2));
    if (interp == SB_INTERP_QUADRATIC && q->n >= quad && poly_fit(t, x, q, kwp, prior, 1, rgb)) return 1;
    if ((interp == SB_INTERP_QUADRATIC || interp == SB_INTERP_LINEAR) && q->n >= lin)
        poly_fit(t, x, q, kwp, prior, 0, rgb);
    return 1;
}

/* Near the normal the azimuth difference is undefined: f is continuous at
 * theta = 0 whatever dphi, yet the isotropic embedding keeps dphi as a
 * coordinate, so near the pole the value depended on dphi and a pair could
 * be missing only because no sample shares its dphi (black pinholes where
 * light or view is along the normal).  Within the pole zone theta_min <
 * radius / pi (where every dphi lies within the radius on the sphere) the
 * value blends, linearly in theta_min, from the azimuthal mean at the pole
 * (the mean over POLE_STEPS values of dphi in [0, pi] of the values known
 * at the pair's two elevations) to the value itself at the zone's edge:
 * dphi-independent at the pole, continuous at the edge, never missing
 * where any azimuth is known.  A measured position keeps its measurement. */
static int pole_mean(const table_t *t, const double *x, double rgb[3]) {
    const double key[SB_MEMO_KEY] = {x[0], x[1], -1, 0, 0, 0}; /* no position has x[2] < 0 */
    int state = t->memo ? sb_memo_find(t->memo, key, rgb) : 0;
    if (state) return state == 1;
    double acc[3] = {0, 0, 0}, v[3], y[MAX_DIM] = {x[0], x[1], 0, 0};
    int n = 0;
    for (int k = 0; k < POLE_STEPS; k++) {
        y[2] = SB_PI * k / (POLE_STEPS - 1);
        int known = sb_table_at_(t, t->interp, t->k, y, NULL, 0, NAN, v);
        if (!known) continue;
        if (known == 2 && t->lobe_on) { /* a measurement: relative to the lobe as the others */
            double wi[3], wo[3], b[3];
            sb_table_dirs_(t, y, wi, wo);
            sb_lobe_base_(&t->lobe, wi, wo, b);
            for (int c = 0; c < 3; c++)
                v[c] = (v[c] + t->lobe.floor[c]) / b[c];
        }
        for (int c = 0; c < 3; c++)
            acc[c] += v[c];
        n++;
    }
    for (int c = 0; c < 3; c++)
        rgb[c] = n ? acc[c] / n : 0;
    if (t->memo) sb_memo_store(t->memo, key, rgb, n > 0 ? 1 : 2);
    return n > 0;
}

/* The value at embedded position x with the pole blend, before the lobe's
 * factor (0 missing, 1 known, 2 measured). */
static int table_at_pole(const table_t *t, const double *x, double lx, double rgb[3]) {
    int known = sb_table_at_(t, t->interp, t->k, x, NULL, 0, lx, rgb);
    double tmin = fmin(x[0], x[1]), zone = sqrt(t->r2) / SB_PI, pole[3];
    if (!(known == 2 || !t->iso || !(tmin < zone) || !pole_mean(t, x, pole))) {
        double w = known ? tmin / zone : 0;
        for (int c = 0; c < 3; c++)
            rgb[c] = w * rgb[c] + (1 - w) * pole[c];
        known = 1;
    }
    return known;
}

/* The value, remembered by embedded position (pairs that reciprocity and
 * isotropy fold onto one position share it, the lobe's factor included:
 * the base is that of x's own pair). */
int sb_table_eval_(const void *self, const double wi[3], const double wo[3], double rgb[3]) {
    const table_t *t = self;
    rgb[0] = rgb[1] = rgb[2] = 0;
    if (!(wi[2] > 0 && wo[2] > 0)) return 0;
    double x[MAX_DIM] = {0}, b[3] = {1, 1, 1}, lx = NAN;
    sb_scat_embed_(t->iso, t->recip, wi, wo, x);
    for (int a = 0; a < MAX_DIM; a++) /* one position however the pair's arithmetic reached it */
        x[a] = nearbyint(x[a] * POSITION_GRID) / POSITION_GRID;
    const double key[SB_MEMO_KEY] = {x[0], x[1], x[2], x[3], 0, 0};
    int state = t->memo ? sb_memo_find(t->memo, key, rgb) : 0;
    if (state) return state > 1;
    if (t->lobe_on) {
        double dwi[3], dwo[3];
        sb_table_dirs_(t, x, dwi, dwo);
        sb_lobe_base_(&t->lobe, dwi, dwo, b);
        lx = log(b[0] + b[1] + b[2]);
    }
    int known = table_at_pole(t, x, lx, rgb);
    if (known == 1 && t->lobe_on) /* the values are relative to the lobe */
        for (int c = 0; c < 3; c++)
            rgb[c] = rgb[c] * b[c] - t->lobe.floor[c];
    if (t->memo) sb_memo_store(t->memo, key, rgb, known + 1);
    return known != 0;
}

/* ---- the values relative to the lobe (scattered_lobe.c fits it) ---- */

void sb_table_dirs_(const table_t *t, const double *x, double wi[3], double wo[3]) {
    double ti, pi_, to, po;
    if (t->iso) {
        ti = x[0], pi_ = 0, to = x[1], po = x[2];
    } else {
        ti = hypot(x[0], x[1]), pi_ = atan2(x[1], x[0]), to = hypot(x[2], x[3]), po = atan2(x[3], x[2]);
    }
    wi[0] = sin(ti) * cos(pi_), wi[1] = sin(ti) * sin(pi_), wi[2] = cos(ti);
    wo[0] = sin(to) * cos(po), wo[1] = sin(to) * sin(po), wo[2] = cos(to);
}

double sb_lobe_level_(const table_t *t, const double *x) {
    double wi[3], wo[3], b[3];
    sb_table_dirs_(t, x, wi, wo);
    sb_lobe_base_(&t->lobe, wi, wo, b);
    return log(b[0] + b[1] + b[2]);
}

double *sb_lobe_values_(const table_t *t, const lobe_t *L, double **lb) {
    double *q = L->fitted ? malloc(t->n * 4 * sizeof *q) : NULL;
    *lb = q ? malloc(t->n * sizeof **lb) : NULL;
    if (!*lb) {
        free(q);
        return NULL;
    }
    for (size_t i = 0; i < t->n; i++) {
        double wi[3], wo[3], b[3];
        sb_table_dirs_(t, t->pts + i * MAX_DIM, wi, wo);
        sb_lobe_base_(L, wi, wo, b);
        for (int c = 0; c < 3; c++) {
            q[4 * i + (size_t)c] = (t->val[4 * i + (size_t)c] + L->floor[c]) / b[c];
            if (!isfinite(q[4 * i + (size_t)c])) { /* the lobe cannot carry these values */
                free(q);
                free(*lb);
                *lb = NULL;
                return NULL;
            }
        }
        (*lb)[i] = log(b[0] + b[1] + b[2]);
        q[4 * i + 3] = t->val[4 * i + 3];
    }
    return q;
}
