/* Scattered samples -> values anywhere: the interpolated source behind the
 * Cornell, ALTA and CSV readers (gonio.c), and its cross-validation.
 *
 * Every sample is a pair (l, v) with an RGB value of f_r.  Samples live in
 * an embedding where Euclidean distance is a distance between
 * configurations and where the symmetries that hold are folded:
 *   isotropic (3D): x = (theta_a, theta_b, |dphi|), dphi = phi_o - phi_i
 *     wrapped into [-pi, pi]; isotropy leaves only dphi, and its mirror
 *     dphi -> -dphi is folded by |dphi|; when reciprocal the swap l <-> v is
 *     folded by sorting, theta_a = max(theta_i, theta_o), theta_b = min
 *     (otherwise theta_a = theta_i, theta_b = theta_o).  Both folds are
 *     reflections, so the folded distance is the smallest distance to any
 *     symmetric copy and nothing is lost by folding.
 *   anisotropic (4D): x = (theta_i cos phi_i, theta_i sin phi_i, theta_o cos
 *     phi_o, theta_o sin phi_o) (polar maps of both hemispheres); when
 *     reciprocal every sample is stored a second time as (v, l).
 * Why io angles and not half/difference angles: on a 5 deg simulated
 * gonioreflectometer grid of the gold microfacet BRDF the half/difference
 * embeddings tried, (theta_h, theta_d cos phi_d, theta_d sin phi_d) and
 * variants, reached 2-5 % relative error at R = 16 (the phi_d cone at
 * theta_h = 0 and the grazing Fresnel ridge), this one 0.8 %, as good as
 * trilinear interpolation on the grid itself (1.0 %).  The azimuth is not
 * shrunk towards the normal (where it stops mattering): doing so packs the
 * samples of one elevation pair so tightly that they crowd out the next
 * elevations from the k nearest.  The cost is that near the normal a table
 * must hold the azimuths queried to cover them.
 *
 * A k-d tree answers the k nearest samples within a support of twice the
 * radius; a query whose nearest sample is farther than the radius is
 * missing.  The value is a weighted least-squares fit (weights 1/d^2, a
 * small ridge) of a local quadratic (default) or linear polynomial in the
 * embedding, evaluated at the query and clamped to the range of the
 * neighbours' values, or inverse-distance weighting, or the nearest sample.
 * Read-only after building, so eval is thread-safe. */
#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "source/measured_impl.h"
#include "util/internal.h"

#define KD_LEAF 8
#define KNN_MAX 64
#define MAX_DIM 4
#define MAX_TERMS 15 /* 1 + 4 + 10: quadratic in 4D */
#define RADIUS_FACTOR 2.5
#define SUPPORT_FACTOR 2.0
/* Ridge on the polynomial's slopes and curvatures, relative to the
 * weighted spread of the neighbours: directions the neighbours do not span
 * get a zero slope instead of a wild one. */
#define RIDGE 1e-2

/* Two configurations closer than this (radians of the embedding) are the
 * same measurement position: text tables print angles to about 6 decimals
 * and rounding leaves copies 1e-16 apart. */
#define SAME_POSITION 1e-6

/* Cross-validation holds out at most this many samples (evenly spread):
 * enough for a 1 % estimate, bounded time on large tables. */
#define CV_MAX 2000

/* Azimuth differences averaged over at the pole (pole_mean): 5 deg steps. */
#define POLE_STEPS 37

/* ---- samples ----------------------------------------------------------- */

sb_result_t sb_samples_push_(sb_context_t *ctx, const char *path, sb_samples_t *ss, const double wi[3],
                             const double wo[3], const double f[3], sb_measured_info_t *info) {
    if (ss->n == ss->cap) {
        size_t cap = ss->cap ? 2 * ss->cap : 1024, bytes;
        if (cap > SB_MAX_ROWS) cap = SB_MAX_ROWS;
        if (ss->n >= SB_MAX_ROWS) return sb_error(ctx, SB_ERR_OVERFLOW, "%s: more than %zu samples", path, SB_MAX_ROWS);
        if (sb_size_mul3(cap, SB_SAMPLE_DOUBLES, sizeof(double), &bytes) || bytes > sb_memory_limit())
            return sb_error(ctx, SB_ERR_OVERFLOW, "%s: %zu samples exceed the memory limit", path, cap);
        double *s = realloc(ss->s, bytes);
        if (!s) return sb_error(ctx, SB_ERR_NOMEM, "%s: out of memory at sample %zu", path, ss->n);
        ss->s = s;
        ss->cap = cap;
    }
    double *p = ss->s + ss->n * SB_SAMPLE_DOUBLES;
    memcpy(p, wi, 3 * sizeof *p);
    memcpy(p + 3, wo, 3 * sizeof *p);
    for (int c = 0; c < 3; c++) {
        p[6 + c] = f[c];
        if (f[c] < info->value_min[c]) info->value_min[c] = f[c];
        if (f[c] > info->value_max[c]) info->value_max[c] = f[c];
        info->value_mean[c] += f[c]; /* divided by the count at the end */
    }
    double ti = acos(fmin(wi[2], 1)), to = acos(fmin(wo[2], 1));
    if (ti > info->theta_i_max) info->theta_i_max = ti;
    if (to > info->theta_o_max) info->theta_o_max = to;
    ss->n++;
    return SB_OK;
}

/* ---- embedding and k-d tree ---------------------------------------------- */

typedef struct table {
    size_t n; /* points in the tree */
    int dim;  /* 3 (isotropic) or 4 */
    int iso, recip;
    double *pts;          /* n * MAX_DIM (unused coordinates 0), tree order */
    double *val;          /* n * 4: f_r (RGB, the mean over repeats) and
                           * the number of samples merged into the point */
    unsigned char *split; /* split axis of the node whose median is at i */
    size_t k;
    double r2; /* squared radius: nearest farther = missing */
    double s2; /* squared support: neighbours used */
    sb_interp_t interp;
    double *smp; /* the samples as read, SB_SAMPLE_DOUBLES each */
    size_t ns;
} table_t;

static void table_destroy(void *self) {
    table_t *t = self;
    if (!t) return;
    free(t->pts);
    free(t->val);
    free(t->split);
    free(t->smp);
    free(t);
}

static void embed(int iso, int recip, const double wi[3], const double wo[3], double *x) {
    double ti = atan2(hypot(wi[0], wi[1]), wi[2]), to = atan2(hypot(wo[0], wo[1]), wo[2]);
    double pi_ = atan2(wi[1], wi[0]), po = atan2(wo[1], wo[0]);
    if (iso) {
        x[0] = recip ? fmax(ti, to) : ti;
        x[1] = recip ? fmin(ti, to) : to;
        x[2] = fabs(remainder(po - pi_, 2 * SB_PI));
        return;
    }
    x[0] = ti * cos(pi_);
    x[1] = ti * sin(pi_);
    x[2] = to * cos(po);
    x[3] = to * sin(po);
}

/* Place the k-th smallest (by axis `ax`) of idx[lo, hi) at k; three-way
 * partition so that runs of equal coordinates (regular grids) terminate. */
static void kd_select(size_t *idx, const double *p, int dim, int ax, size_t lo, size_t hi, size_t k) {
    while (hi - lo > 1) {
        size_t a = idx[lo], b = idx[lo + (hi - lo) / 2], c = idx[hi - 1];
        double va = p[a * (size_t)dim + (size_t)ax], vb = p[b * (size_t)dim + (size_t)ax],
               vc = p[c * (size_t)dim + (size_t)ax];
        double piv = va < vb ? (vb < vc ? vb : (va < vc ? vc : va)) : (va < vc ? va : (vb < vc ? vc : vb));
        size_t lt = lo, i = lo, gt = hi;
        while (i < gt) {
            double v = p[idx[i] * (size_t)dim + (size_t)ax];
            if (v < piv) {
                size_t s = idx[lt];
                idx[lt++] = idx[i];
                idx[i++] = s;
            } else if (v > piv) {
                size_t s = idx[--gt];
                idx[gt] = idx[i];
                idx[i] = s;
            } else {
                i++;
            }
        }
        if (k < lt)
            hi = lt;
        else if (k >= gt)
            lo = gt;
        else
            return;
    }
}

/* Implicit tree: the node of [lo, hi) is its median mid, split on the axis
 * of largest spread; leaves of at most KD_LEAF points are scanned. */
static void kd_build(size_t *idx, const double *p, unsigned char *split, size_t lo, size_t hi) {
    const int dim = MAX_DIM;
    while (hi - lo > KD_LEAF) {
        double mn[MAX_DIM], mx[MAX_DIM];
        for (int a = 0; a < dim; a++) {
            mn[a] = INFINITY;
            mx[a] = -INFINITY;
        }
        for (size_t i = lo; i < hi; i++)
            for (int a = 0; a < dim; a++) {
                double v = p[idx[i] * (size_t)dim + (size_t)a];
                if (v < mn[a]) mn[a] = v;
                if (v > mx[a]) mx[a] = v;
            }
        int ax = 0;
        for (int a = 1; a < dim; a++)
            if (mx[a] - mn[a] > mx[ax] - mn[ax]) ax = a;
        size_t mid = lo + (hi - lo) / 2;
        kd_select(idx, p, dim, ax, lo, hi, mid);
        split[mid] = (unsigned char)ax;
        kd_build(idx, p, split, lo, mid);
        lo = mid + 1; /* the right half in the loop */
    }
}

/* The k nearest within sqrt(r2): a max-heap on d2 while searching
 * (d2[0] the farthest kept), sorted ascending by knn_sort afterwards. */
typedef struct knn {
    size_t k, n;
    double r2;
    double d2[KNN_MAX];
    size_t at[KNN_MAX];
    const double *skip; /* cross-validation: nskip positions (MAX_DIM each) held out */
    int nskip;
} knn_t;

/* A point at a held-out position is not a neighbour. */
static int knn_skips(const knn_t *q, const double *p) {
    for (int s = 0; s < q->nskip; s++) {
        double d = 0;
        for (int a = 0; a < MAX_DIM; a++)
            d += (p[a] - q->skip[s * MAX_DIM + a]) * (p[a] - q->skip[s * MAX_DIM + a]);
        if (d <= SAME_POSITION * SAME_POSITION) return 1;
    }
    return 0;
}

static double knn_bound(const knn_t *q) { return q->n < q->k ? q->r2 : q->d2[0]; }

static void knn_sift_down(knn_t *q, size_t i, size_t n) {
    for (;;) {
        size_t l = 2 * i + 1, r = l + 1, m = i;
        if (l < n && q->d2[l] > q->d2[m]) m = l;
        if (r < n && q->d2[r] > q->d2[m]) m = r;
        if (m == i) return;
        double d = q->d2[i];
        size_t a = q->at[i];
        q->d2[i] = q->d2[m];
        q->at[i] = q->at[m];
        q->d2[m] = d;
        q->at[m] = a;
        i = m;
    }
}

static void knn_push(knn_t *q, double d2, size_t at) {
    if (q->n < q->k) {
        if (d2 > q->r2) return;
        size_t i = q->n++;
        while (i > 0 && q->d2[(i - 1) / 2] < d2) { /* sift up */
            q->d2[i] = q->d2[(i - 1) / 2];
            q->at[i] = q->at[(i - 1) / 2];
            i = (i - 1) / 2;
        }
        q->d2[i] = d2;
        q->at[i] = at;
        return;
    }
    if (d2 >= q->d2[0]) return;
    q->d2[0] = d2;
    q->at[0] = at;
    knn_sift_down(q, 0, q->n);
}

/* Heap sort in place: ascending d2. */
static void knn_sort(knn_t *q) {
    for (size_t n = q->n; n > 1; n--) {
        double d = q->d2[0];
        size_t a = q->at[0];
        q->d2[0] = q->d2[n - 1];
        q->at[0] = q->at[n - 1];
        q->d2[n - 1] = d;
        q->at[n - 1] = a;
        knn_sift_down(q, 0, n - 1);
    }
}

/* Points are stored with MAX_DIM coordinates (unused ones 0) so that the
 * distance is one fixed-length loop. */
static inline double dist2(const double *a, const double *b) {
    double s = 0;
    for (int k = 0; k < MAX_DIM; k++)
        s += (a[k] - b[k]) * (a[k] - b[k]);
    return s;
}

static void kd_query(const table_t *t, const double *x, size_t lo, size_t hi, knn_t *q) {
    while (hi - lo > KD_LEAF) {
        size_t mid = lo + (hi - lo) / 2;
        int ax = t->split[mid];
        const double *pm = t->pts + mid * MAX_DIM;
        double d2 = dist2(x, pm);
        if ((d2 < knn_bound(q) || (q->n < q->k && d2 <= q->r2)) && !(q->nskip && knn_skips(q, pm)))
            knn_push(q, d2, mid);
        double diff = x[ax] - pm[ax];
        size_t nlo = diff < 0 ? lo : mid + 1, nhi = diff < 0 ? mid : hi;
        size_t flo = diff < 0 ? mid + 1 : lo, fhi = diff < 0 ? hi : mid;
        kd_query(t, x, nlo, nhi, q);
        if (diff * diff > knn_bound(q)) return;
        lo = flo;
        hi = fhi;
    }
    for (size_t i = lo; i < hi; i++) {
        double d2 = dist2(x, t->pts + i * MAX_DIM);
        if ((d2 < knn_bound(q) || (q->n < q->k && d2 <= q->r2)) && !(q->nskip && knn_skips(q, t->pts + i * MAX_DIM)))
            knn_push(q, d2, i);
    }
}

/* ---- evaluation -------------------------------------------------------- */

/* Weighted least squares y ~ sum_m c_m u_m(p - x) over the neighbours with
 * u = (1, p - x) (linear) or (1, p - x, (p - x)_a (p - x)_b, a <= b)
 * (quadratic), weights count/d^2 (count: samples merged into the point),
 * a ridge RIDGE * spread (spread^2 for the quadratic terms) on all but c_0,
 * solved by Cholesky; c_0 is the value at x, clamped to the neighbours'
 * range.  Returns 0 (rgb untouched) if the system is not positive
 * definite. */
static int poly_fit(const table_t *t, const double *x, const knn_t *q, int quadratic, double rgb[3]) {
    int D = t->dim, P = 1 + D + (quadratic ? D * (D + 1) / 2 : 0);
    double A[MAX_TERMS * MAX_TERMS] = {0}, B[MAX_TERMS * 3] = {0};
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY}, spread = 0, wsum = 0;
    for (size_t i = 0; i < q->n; i++) {
        const double *p = t->pts + q->at[i] * MAX_DIM, *v = t->val + 4 * q->at[i];
        double w = v[3] / q->d2[i], u[MAX_TERMS];
        u[0] = 1;
        for (int a = 0; a < D; a++)
            u[a + 1] = p[a] - x[a];
        for (int a = 0, m = 1 + D; quadratic && a < D; a++)
            for (int b = a; b < D; b++)
                u[m++] = u[a + 1] * u[b + 1];
        for (int a = 0; a < P; a++) {
            for (int b = 0; b <= a; b++)
                A[a * P + b] += w * u[a] * u[b];
            for (int c = 0; c < 3; c++)
                B[a * 3 + c] += w * u[a] * v[c];
        }
        for (int c = 0; c < 3; c++) {
            if (v[c] < lo[c]) lo[c] = v[c];
            if (v[c] > hi[c]) hi[c] = v[c];
        }
        spread += w * q->d2[i];
        wsum += w;
    }
    double s2 = spread / wsum;
    for (int a = 1; a < P; a++)
        A[a * P + a] += RIDGE * wsum * (a <= D ? s2 : s2 * s2);
    /* Cholesky A = L L^T in the lower triangle */
    for (int j = 0; j < P; j++) {
        double d = A[j * P + j];
        for (int k = 0; k < j; k++)
            d -= A[j * P + k] * A[j * P + k];
        if (!(d > 0)) return 0;
        d = sqrt(d);
        A[j * P + j] = d;
        for (int i = j + 1; i < P; i++) {
            double s = A[i * P + j];
            for (int k = 0; k < j; k++)
                s -= A[i * P + k] * A[j * P + k];
            A[i * P + j] = s / d;
        }
    }
    double out[3];
    for (int c = 0; c < 3; c++) {
        double y[MAX_TERMS];
        for (int i = 0; i < P; i++) {
            double s = B[i * 3 + c];
            for (int k = 0; k < i; k++)
                s -= A[i * P + k] * y[k];
            y[i] = s / A[i * P + i];
        }
        for (int i = P - 1; i >= 0; i--) {
            double s = y[i];
            for (int k = i + 1; k < P; k++)
                s -= A[k * P + i] * y[k];
            y[i] = s / A[i * P + i];
        }
        if (!isfinite(y[0])) return 0;
        out[c] = y[0] < lo[c] ? lo[c] : (y[0] > hi[c] ? hi[c] : y[0]);
    }
    memcpy(rgb, out, sizeof out);
    return 1;
}

/* The value at embedded position x by method `interp` with k neighbours,
 * leaving out the points at the nskip positions of `skip`: 0 missing, 1
 * known, 2 known at a measured position (the measurement). */
static int table_at(const table_t *t, sb_interp_t interp, size_t k, const double *x, const double *skip, int nskip,
                    double rgb[3]) {
    rgb[0] = rgb[1] = rgb[2] = 0;
    knn_t q;
    q.k = interp == SB_INTERP_NEAREST ? 1 : k;
    q.n = 0;
    q.r2 = interp == SB_INTERP_NEAREST ? t->r2 : t->s2;
    q.skip = skip;
    q.nskip = nskip;
    kd_query(t, x, 0, t->n, &q);
    knn_sort(&q);
    if (q.n == 0 || q.d2[0] > t->r2) return 0;
    /* At a measured position (or for nearest): the sample, repeats averaged. */
    if (q.d2[0] <= SAME_POSITION * SAME_POSITION || interp == SB_INTERP_NEAREST) {
        double lim = q.d2[0] <= SAME_POSITION * SAME_POSITION ? SAME_POSITION * SAME_POSITION : q.d2[0];
        double cnt = 0;
        for (size_t m = 0; m < q.n && q.d2[m] <= lim; m++) {
            const double *v = t->val + 4 * q.at[m];
            for (int c = 0; c < 3; c++)
                rgb[c] += v[3] * v[c];
            cnt += v[3];
        }
        for (int c = 0; c < 3; c++)
            rgb[c] /= cnt;
        return q.d2[0] <= SAME_POSITION * SAME_POSITION ? 2 : 1;
    }
    /* Inverse squared distance weights: the value, or the fallback. */
    double wsum = 0;
    for (size_t i = 0; i < q.n; i++) {
        double w = t->val[4 * q.at[i] + 3] / q.d2[i];
        for (int c = 0; c < 3; c++)
            rgb[c] += w * t->val[4 * q.at[i] + c];
        wsum += w;
    }
    for (int c = 0; c < 3; c++)
        rgb[c] /= wsum;
    /* Local polynomial when there are enough neighbours: twice the terms. */
    size_t lin = 2 * ((size_t)t->dim + 1), quad = 2 * (1 + (size_t)t->dim + (size_t)(t->dim * (t->dim + 1) / 2));
    if (interp == SB_INTERP_QUADRATIC && q.n >= quad && poly_fit(t, x, &q, 1, rgb)) return 1;
    if ((interp == SB_INTERP_QUADRATIC || interp == SB_INTERP_LINEAR) && q.n >= lin) poly_fit(t, x, &q, 0, rgb);
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
    double acc[3] = {0, 0, 0}, v[3], y[MAX_DIM] = {x[0], x[1], 0, 0};
    int n = 0;
    for (int k = 0; k < POLE_STEPS; k++) {
        y[2] = SB_PI * k / (POLE_STEPS - 1);
        if (!table_at(t, t->interp, t->k, y, NULL, 0, v)) continue;
        for (int c = 0; c < 3; c++)
            acc[c] += v[c];
        n++;
    }
    for (int c = 0; c < 3; c++)
        rgb[c] = n ? acc[c] / n : 0;
    return n > 0;
}

static int table_eval(const void *self, const double wi[3], const double wo[3], double rgb[3]) {
    const table_t *t = self;
    rgb[0] = rgb[1] = rgb[2] = 0;
    if (!(wi[2] > 0 && wo[2] > 0)) return 0;
    double x[MAX_DIM] = {0};
    embed(t->iso, t->recip, wi, wo, x);
    int known = table_at(t, t->interp, t->k, x, NULL, 0, rgb);
    double tmin = fmin(x[0], x[1]), zone = sqrt(t->r2) / SB_PI, pole[3];
    if (known == 2 || !t->iso || !(tmin < zone) || !pole_mean(t, x, pole)) return known != 0;
    double w = known ? tmin / zone : 0;
    for (int c = 0; c < 3; c++)
        rgb[c] = w * rgb[c] + (1 - w) * pole[c];
    return 1;
}

static size_t table_sample_count(const void *self) { return ((const table_t *)self)->ns; }
static int table_sample(const void *self, size_t k, double wi[3], double wo[3], double f[3]) {
    const double *s = ((const table_t *)self)->smp + k * SB_SAMPLE_DOUBLES;
    memcpy(wi, s, 3 * sizeof *wi);
    memcpy(wo, s + 3, 3 * sizeof *wo);
    memcpy(f, s + 6, 3 * sizeof *f);
    return 1;
}

/* ---- cross-validation ---------------------------------------------------- */

/* Leave-one-position-out error of method m (k neighbours): each held-out
 * sample (at most CV_MAX, evenly spread over the table) is predicted from
 * the others, every point at its position (repeats, and the swapped copy
 * of a reciprocal anisotropic table) left out, and compared with its
 * measured value in the norm of the comparable error:
 *   e = sqrt( sum (f~ - f)^2 c_i^2 c_o^2 / sum f^2 c_i^2 c_o^2 ).
 * Samples with no neighbour left within the radius are not predicted
 * (*missing); NAN when none was. */
static double cv_error(const table_t *t, sb_interp_t m, size_t k, size_t *held, size_t *missing) {
    size_t n = t->ns < CV_MAX ? t->ns : CV_MAX;
    double num = 0, den = 0;
    *held = n;
    *missing = 0;
    for (size_t h = 0; h < n; h++) {
        const double *s = t->smp + (h * t->ns / n) * SB_SAMPLE_DOUBLES;
        double x[2 * MAX_DIM] = {0}, rgb[3];
        embed(t->iso, t->recip, s, s + 3, x);
        int nskip = 1;
        if (!t->iso && t->recip) embed(t->iso, t->recip, s + 3, s, x + MAX_DIM), nskip = 2;
        if (!table_at(t, m, k, x, x, nskip, rgb)) {
            (*missing)++;
            continue;
        }
        double w = s[2] * s[5];
        for (int c = 0; c < 3; c++) {
            num += (rgb[c] - s[6 + c]) * (rgb[c] - s[6 + c]) * w * w;
            den += s[6 + c] * s[6 + c] * w * w;
        }
    }
    return *missing < n && den > 0 ? sqrt(num / den) : NAN;
}

/* Cross-validate every method; with interp DEFAULT keep the one of lowest
 * error (on ties the earlier of quadratic, linear, idw, nearest). */
static void cv_choose(table_t *t, const sb_measured_opts_t *o, size_t kfit, sb_measured_info_t *info) {
    static const sb_interp_t order[4] = {SB_INTERP_QUADRATIC, SB_INTERP_LINEAR, SB_INTERP_IDW, SB_INTERP_NEAREST};
    sb_interp_t best = SB_INTERP_QUADRATIC;
    double best_e = INFINITY;
    size_t miss[SB_INTERP_COUNT_] = {0};
    for (int k = 0; k < SB_INTERP_COUNT_; k++)
        info->interp_cv[k] = NAN;
    for (int i = 0; i < 4; i++) {
        sb_interp_t m = order[i];
        size_t kk = o->neighbours ? o->neighbours : m == SB_INTERP_IDW ? (size_t)t->dim + 1 : kfit;
        double e = cv_error(t, m, kk, &info->cv_held_out, &miss[m]);
        info->interp_cv[m] = e;
        if (isfinite(e) && e < best_e) {
            best_e = e;
            best = m;
        }
    }
    t->interp = o->interp == SB_INTERP_DEFAULT ? best : o->interp;
    t->k = o->neighbours ? o->neighbours : t->interp == SB_INTERP_IDW ? (size_t)t->dim + 1 : kfit;
    info->cv_missing = miss[t->interp];
}

/* Median over points of the distance to the nearest other point that is
 * not at the same position (repeats and folded copies skipped); 0 when
 * there is no such pair, < 0 on no memory. */
static double median_spacing(sb_context_t *ctx, const table_t *t) {
    double *d = sb_alloc(ctx, t->n ? t->n : 1, sizeof *d, "table spacing");
    size_t *idx = sb_alloc(ctx, t->n ? t->n : 1, sizeof *idx, "table spacing");
    if (!d || !idx) {
        free(d);
        free(idx);
        return -1;
    }
    size_t m = 0;
    for (size_t i = 0; i < t->n; i++) {
        knn_t q = {8, 0, INFINITY, {0}, {0}, NULL, 0};
        kd_query(t, t->pts + i * MAX_DIM, 0, t->n, &q);
        knn_sort(&q);
        for (size_t j = 0; j < q.n; j++)
            if (q.d2[j] > SAME_POSITION * SAME_POSITION) {
                d[m++] = sqrt(q.d2[j]);
                break;
            }
    }
    double med = 0;
    if (m) {
        for (size_t i = 0; i < m; i++)
            idx[i] = i;
        kd_select(idx, d, 1, 0, 0, m, m / 2); /* the tree's selection on a 1-D view */
        med = d[idx[m / 2]];
    }
    free(d);
    free(idx);
    return med;
}

/* Sort key of an embedded sample: its position on a grid of SAME_POSITION. */
typedef struct key {
    long long q[MAX_DIM];
    size_t i; /* sample * copies + copy */
} pkey_t;

static int key_cmp(const void *a, const void *b) {
    const pkey_t *x = a, *y = b;
    for (int k = 0; k < MAX_DIM; k++)
        if (x->q[k] != y->q[k]) return x->q[k] < y->q[k] ? -1 : 1;
    return 0;
}

/* Build the source from the samples. */
sb_result_t sb_table_create_(sb_context_t *ctx, const char *path, sb_samples_t *ss, int iso, int recip,
                             const sb_measured_opts_t *o, sb_measured_info_t *info, sb_source_t **out) {
    sb_interp_t interp = o->interp == SB_INTERP_DEFAULT ? SB_INTERP_QUADRATIC : o->interp; /* until cv_choose */
    if (ss->n == 0)
        return sb_error(ctx, SB_ERR_FORMAT, "%s: no usable samples (%zu rows: %zu NaN, %zu at or below the horizon)",
                        path, info->rows, info->nan_rows, info->horizon_rows);
    table_t *t = calloc(1, sizeof *t);
    if (!t) return sb_error(ctx, SB_ERR_NOMEM, "%s: out of memory", path);
    t->iso = iso;
    t->recip = recip;
    t->dim = iso ? 3 : 4;
    t->interp = interp;
    /* Default k: for the fits twice the quadratic's terms, plus a few: 24
     * (3D), 34 (4D); for idw a simplex, dim + 1 (more smears: on the 5 deg
     * round trip k = 4 gives 3.7 %, k = 8 8 %, k = 24 17 %). */
    size_t kfit = 2 * (size_t)(1 + t->dim + t->dim * (t->dim + 1) / 2) + 4;
    t->k = o->neighbours ? o->neighbours : interp == SB_INTERP_IDW ? (size_t)t->dim + 1 : kfit;
    size_t copies = (!iso && recip) ? 2 : 1, n;
    sb_result_t r = SB_OK;
    pkey_t *keys = NULL;
    size_t *perm = NULL;
    double *pts = NULL, *val = NULL;
    if (sb_size_mul(ss->n, copies, &n)) {
        r = sb_error(ctx, SB_ERR_OVERFLOW, "%s: sample count overflows", path);
        goto fail;
    }
    keys = sb_alloc(ctx, n, sizeof *keys, path);
    if (!keys) {
        r = SB_ERR_NOMEM;
        goto fail;
    }
    /* Embed (copy 1 is the swapped pair) and sort by position on a grid of
     * SAME_POSITION, so that repeats (and symmetric copies that fold onto
     * each other) become one point with the mean value and a count. */
    for (size_t i = 0; i < n; i++) {
        const double *s = ss->s + (i / copies) * SB_SAMPLE_DOUBLES;
        int swap = (int)(i % copies);
        double x[MAX_DIM] = {0};
        embed(iso, recip, swap ? s + 3 : s, swap ? s : s + 3, x);
        for (int a = 0; a < MAX_DIM; a++)
            keys[i].q[a] = (long long)llround(x[a] / SAME_POSITION);
        keys[i].i = i;
    }
    qsort(keys, n, sizeof *keys, key_cmp);
    size_t m = 0;
    for (size_t i = 0; i < n; i++)
        m += i == 0 || key_cmp(&keys[i - 1], &keys[i]) != 0;
    pts = sb_alloc(ctx, m, MAX_DIM * sizeof(double), path);
    val = sb_alloc(ctx, m, 4 * sizeof(double), path);
    perm = sb_alloc(ctx, m, sizeof *perm, path);
    t->pts = sb_alloc(ctx, m, MAX_DIM * sizeof(double), path);
    t->val = sb_alloc(ctx, m, 4 * sizeof(double), path);
    t->split = sb_calloc(ctx, m, 1, path);
    if (!pts || !val || !perm || !t->pts || !t->val || !t->split) {
        r = SB_ERR_NOMEM;
        goto fail;
    }
    /* Point p: the position of its run's first sample, the mean value. */
    for (size_t i = 0, p = 0; i < n; p++) {
        size_t j = i + 1;
        while (j < n && key_cmp(&keys[i], &keys[j]) == 0)
            j++;
        double acc[3] = {0, 0, 0}, x[MAX_DIM] = {0};
        for (size_t k = i; k < j; k++)
            for (int c = 0; c < 3; c++)
                acc[c] += ss->s[(keys[k].i / copies) * SB_SAMPLE_DOUBLES + 6 + (size_t)c];
        const double *s0 = ss->s + (keys[i].i / copies) * SB_SAMPLE_DOUBLES;
        int swap = (int)(keys[i].i % copies);
        embed(iso, recip, swap ? s0 + 3 : s0, swap ? s0 : s0 + 3, x);
        memcpy(pts + p * MAX_DIM, x, MAX_DIM * sizeof(double));
        for (int c = 0; c < 3; c++)
            val[4 * p + (size_t)c] = acc[c] / (double)(j - i);
        val[4 * p + 3] = (double)(j - i);
        perm[p] = p;
        i = j;
    }
    free(keys);
    keys = NULL;
    t->n = m;
    kd_build(perm, pts, t->split, 0, m);
    for (size_t i = 0; i < m; i++) {
        memcpy(t->pts + i * MAX_DIM, pts + perm[i] * MAX_DIM, MAX_DIM * sizeof(double));
        memcpy(t->val + 4 * i, val + 4 * perm[i], 4 * sizeof(double));
    }
    free(perm);
    free(pts);
    free(val);
    perm = NULL;
    pts = NULL;
    val = NULL;

    double spacing = median_spacing(ctx, t);
    if (spacing < 0) {
        r = SB_ERR_NOMEM;
        goto fail;
    }
    double radius = o->radius;
    if (radius == 0) radius = spacing > 0 ? RADIUS_FACTOR * spacing : INFINITY;
    if (radius < 0) radius = INFINITY;
    t->r2 = radius * radius;
    t->s2 = SUPPORT_FACTOR * SUPPORT_FACTOR * t->r2;
    t->smp = ss->s; /* the source keeps the samples as read */
    t->ns = ss->n;
    ss->s = NULL;
    ss->n = ss->cap = 0;
    cv_choose(t, o, kfit, info);
    info->spacing = spacing;
    info->radius = radius;
    info->neighbours = t->interp == SB_INTERP_NEAREST ? 1 : t->k;
    info->interp = t->interp;
    info->dims = (size_t)t->dim;
    info->flags = SB_SOURCE_MEASURED | (iso ? SB_SOURCE_ISOTROPIC : 0u) | (recip ? SB_SOURCE_RECIPROCAL : 0u) |
                  (info->channels == 1 ? SB_SOURCE_GRAY : 0u);
    char desc[1400];
    snprintf(desc, sizeof desc, "%s:%s (%s, k=%zu, radius=%.3g deg)", info->format, path, sb_interp_name(t->interp),
             info->neighbours, radius * 180 / SB_PI);
    sb_source_ops_t ops = {table_eval, table_destroy};
    r = sb_source_create(ctx, &ops, t, info->flags, desc, out);
    if (r == SB_OK) {
        sb_source_set_samples_(*out, table_sample_count, table_sample);
        return SB_OK;
    }
fail:
    free(keys);
    free(pts);
    free(val);
    free(perm);
    table_destroy(t);
    return r;
}
