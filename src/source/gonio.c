/* Scattered gonioreflectometer tables (Cornell .brdf, ALTA, sepbrdf CSV),
 * their interpolation, and the simulated gonioreflectometer.
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
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "source/measured_impl.h"
#include "util/internal.h"
#include "util/rng.h"

#define KD_LEAF 8
#define KNN_MAX 64
#define MAX_DIM 4
#define MAX_TERMS 15 /* 1 + 4 + 10: quadratic in 4D */
#define MAX_ROWS ((size_t)1 << 31)
#define MAX_WAVELENGTHS 4096
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

/* ---- samples ----------------------------------------------------------- */

/* Growing array of samples: wi[3], wo[3], f[3] per sample. */
typedef struct samples {
    double *s;
    size_t n, cap;
} samples_t;

enum { SAMPLE_DOUBLES = 9 };

static sb_result_t samples_push(sb_context_t *ctx, const char *path, samples_t *ss, const double wi[3],
                                const double wo[3], const double f[3], sb_measured_info_t *info) {
    if (ss->n == ss->cap) {
        size_t cap = ss->cap ? 2 * ss->cap : 1024, bytes;
        if (cap > MAX_ROWS) cap = MAX_ROWS;
        if (ss->n >= MAX_ROWS) return sb_error(ctx, SB_ERR_OVERFLOW, "%s: more than %zu samples", path, MAX_ROWS);
        if (sb_size_mul3(cap, SAMPLE_DOUBLES, sizeof(double), &bytes) || bytes > sb_memory_limit())
            return sb_error(ctx, SB_ERR_OVERFLOW, "%s: %zu samples exceed the memory limit", path, cap);
        double *s = realloc(ss->s, bytes);
        if (!s) return sb_error(ctx, SB_ERR_NOMEM, "%s: out of memory at sample %zu", path, ss->n);
        ss->s = s;
        ss->cap = cap;
    }
    double *p = ss->s + ss->n * SAMPLE_DOUBLES;
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
} table_t;

static void table_destroy(void *self) {
    table_t *t = self;
    if (!t) return;
    free(t->pts);
    free(t->val);
    free(t->split);
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
} knn_t;

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
        if (d2 < knn_bound(q) || (q->n < q->k && d2 <= q->r2)) knn_push(q, d2, mid);
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
        if (d2 < knn_bound(q) || (q->n < q->k && d2 <= q->r2)) knn_push(q, d2, i);
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

static int table_eval(const void *self, const double wi[3], const double wo[3], double rgb[3]) {
    const table_t *t = self;
    rgb[0] = rgb[1] = rgb[2] = 0;
    if (!(wi[2] > 0 && wo[2] > 0)) return 0;
    double x[MAX_DIM] = {0};
    embed(t->iso, t->recip, wi, wo, x);
    knn_t q;
    q.k = t->interp == SB_INTERP_NEAREST ? 1 : t->k;
    q.n = 0;
    q.r2 = t->interp == SB_INTERP_NEAREST ? t->r2 : t->s2;
    kd_query(t, x, 0, t->n, &q);
    knn_sort(&q);
    if (q.n == 0 || q.d2[0] > t->r2) return 0;
    /* At a measured position (or for nearest): the sample, repeats averaged. */
    if (q.d2[0] <= SAME_POSITION * SAME_POSITION || t->interp == SB_INTERP_NEAREST) {
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
        return 1;
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
    if (t->interp == SB_INTERP_QUADRATIC && q.n >= quad && poly_fit(t, x, &q, 1, rgb)) return 1;
    if ((t->interp == SB_INTERP_QUADRATIC || t->interp == SB_INTERP_LINEAR) && q.n >= lin) poly_fit(t, x, &q, 0, rgb);
    return 1;
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
        knn_t q = {8, 0, INFINITY, {0}, {0}};
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
static sb_result_t table_create(sb_context_t *ctx, const char *path, samples_t *ss, int iso, int recip,
                                const sb_measured_opts_t *o, sb_measured_info_t *info, sb_source_t **out) {
    sb_interp_t interp = o->interp == SB_INTERP_DEFAULT ? SB_INTERP_QUADRATIC : o->interp;
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
        const double *s = ss->s + (i / copies) * SAMPLE_DOUBLES;
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
                acc[c] += ss->s[(keys[k].i / copies) * SAMPLE_DOUBLES + 6 + (size_t)c];
        const double *s0 = ss->s + (keys[i].i / copies) * SAMPLE_DOUBLES;
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
    info->spacing = spacing;
    info->radius = radius;
    info->neighbours = t->interp == SB_INTERP_NEAREST ? 1 : t->k;
    info->interp = interp;
    info->dims = (size_t)t->dim;
    info->flags = SB_SOURCE_MEASURED | (iso ? SB_SOURCE_ISOTROPIC : 0u) | (recip ? SB_SOURCE_RECIPROCAL : 0u) |
                  (info->channels == 1 ? SB_SOURCE_GRAY : 0u);
    char desc[1400];
    snprintf(desc, sizeof desc, "%s:%s (%s, k=%zu, radius=%.3g deg)", sb_table_format_name(info->format), path,
             sb_interp_name(interp), info->neighbours, radius * 180 / SB_PI);
    sb_source_ops_t ops = {table_eval, table_destroy};
    r = sb_source_create(ctx, &ops, t, info->flags, desc, out);
    if (r == SB_OK) return SB_OK;
fail:
    free(keys);
    free(pts);
    free(val);
    free(perm);
    table_destroy(t);
    return r;
}

/* ---- readers ------------------------------------------------------------ */

typedef struct reader {
    sb_context_t *ctx;
    const char *path;
    sb_lines_t lr;
    samples_t ss;
    sb_measured_info_t *info;
} reader_t;

/* One row: classify (NaN, horizon), then keep.  Angles must be finite. */
static sb_result_t reader_add(reader_t *rd, const double wi[3], const double wo[3], const double f[3], int nan,
                              int negative) {
    rd->info->rows++;
    if (nan) {
        rd->info->nan_rows++;
        return SB_OK;
    }
    if (!(wi[2] > SB_HORIZON_Z && wo[2] > SB_HORIZON_Z)) {
        rd->info->horizon_rows++;
        return SB_OK;
    }
    rd->info->negative += (size_t)(negative != 0);
    rd->info->out_of_gamut += (size_t)(rd->info->wavelengths && (f[0] < 0 || f[1] < 0 || f[2] < 0));
    return samples_push(rd->ctx, rd->path, &rd->ss, wi, wo, f, rd->info);
}

static sb_result_t bad_number(reader_t *rd, const char *what, const char *field) {
    return sb_error(rd->ctx, SB_ERR_FORMAT, "%s:%zu: %s '%.40s' is not a number", rd->path, rd->lr.line, what, field);
}
static sb_result_t not_finite(reader_t *rd, const char *what, const char *field) {
    return sb_error(rd->ctx, SB_ERR_FORMAT, "%s:%zu: %s '%.40s' is not finite", rd->path, rd->lr.line, what, field);
}

/* Parse an angle field (finite), times `unit`. */
static sb_result_t angle_field(reader_t *rd, const char *what, const char *s, double unit, double *out) {
    if (sb_parse_number(s, out) != 0) return bad_number(rd, what, s);
    if (!isfinite(*out)) return not_finite(rd, what, s);
    *out *= unit;
    return SB_OK;
}

/* Parse a value field: NaN marks a missing value (*nan = 1), inf is an error. */
static sb_result_t value_field(reader_t *rd, const char *what, const char *s, double *out, int *nan) {
    if (sb_parse_number(s, out) != 0) return bad_number(rd, what, s);
    if (isnan(*out))
        *nan = 1;
    else if (!isfinite(*out))
        return not_finite(rd, what, s);
    return SB_OK;
}

static int is_blank_or_comment(const char *s, char comment) {
    while (*s == ' ' || *s == '\t')
        s++;
    return *s == 0 || *s == comment;
}

/* Cornell / pbrt .brdf: count, wavelengths (may span lines), then rows of
 * 4 + n numbers.  Lines starting with '#' are comments. */
static sb_result_t read_cornell(reader_t *rd, const sb_measured_opts_t *o) {
    sb_context_t *ctx = rd->ctx;
    size_t n = 0, have = 0;
    double *wl = NULL, *w = NULL, *vals = NULL;
    char **fields = NULL;
    sb_result_t r = SB_OK;
    char *line;
    int st, state = 0;
    while ((st = sb_lines_next(ctx, &rd->lr, &line, &r)) > 0) {
        if (is_blank_or_comment(line, '#')) continue;
        if (state == 0) { /* the wavelength count */
            char *f[2];
            size_t nf = sb_split_fields(line, 0, f, 2);
            double v;
            if (nf != 1 || sb_parse_number(f[0], &v) != 0 || !(v >= 1 && v <= MAX_WAVELENGTHS) || v != floor(v)) {
                r = sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: wavelength count '%.40s' is not an integer in 1..%d",
                             rd->path, rd->lr.line, nf ? f[0] : "", MAX_WAVELENGTHS);
                goto done;
            }
            n = (size_t)v;
            wl = malloc(n * sizeof *wl);
            w = malloc(3 * n * sizeof *w);
            vals = malloc(n * sizeof *vals);
            fields = malloc((n + 5) * sizeof *fields);
            if (!wl || !w || !vals || !fields) {
                r = sb_error(ctx, SB_ERR_NOMEM, "%s: out of memory", rd->path);
                goto done;
            }
            state = 1;
        } else if (state == 1) { /* wavelengths */
            size_t nf = sb_split_fields(line, 0, fields, n + 5);
            if (have + nf > n) {
                r = sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: more wavelengths than the %zu announced", rd->path,
                             rd->lr.line, n);
                goto done;
            }
            for (size_t k = 0; k < nf; k++) {
                if (sb_parse_number(fields[k], &wl[have]) != 0) {
                    r = bad_number(rd, "wavelength", fields[k]);
                    goto done;
                }
                if (!isfinite(wl[have]) || wl[have] <= 0) {
                    r = sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: wavelength '%.40s' is not a positive number", rd->path,
                                 rd->lr.line, fields[k]);
                    goto done;
                }
                if (have > 0 && !(wl[have] > wl[have - 1])) {
                    r = sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: wavelengths not increasing (%g nm after %g nm)", rd->path,
                                 rd->lr.line, wl[have], wl[have - 1]);
                    goto done;
                }
                have++;
            }
            if (have == n) {
                if (wl[n - 1] < 380 || wl[0] > 780) {
                    r = sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: wavelengths %g..%g nm miss the visible range 380..780 nm",
                                 rd->path, rd->lr.line, wl[0], wl[n - 1]);
                    goto done;
                }
                if ((r = sb_spectral_weights(ctx, wl, n, o->white, w)) != SB_OK) goto done;
                rd->info->wavelengths = n;
                rd->info->channels = n;
                rd->info->wl_min = wl[0];
                rd->info->wl_max = wl[n - 1];
                state = 2;
            }
        } else { /* rows */
            size_t nf = sb_split_fields(line, 0, fields, n + 5);
            if (nf != 4 + n) {
                r = sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: %zu numbers, expected %zu (4 angles + %zu spectral values)",
                             rd->path, rd->lr.line, nf, 4 + n, n);
                goto done;
            }
            static const char *const an[4] = {"theta_i", "phi_i", "theta_s", "phi_s"};
            double a[4];
            for (int k = 0; k < 4; k++)
                if ((r = angle_field(rd, an[k], fields[k], 1, &a[k])) != SB_OK) goto done;
            int nan = 0;
            for (size_t k = 0; k < n; k++)
                if ((r = value_field(rd, "spectral value", fields[4 + k], &vals[k], &nan)) != SB_OK) goto done;
            double wi[3], wo[3], f[3] = {0, 0, 0};
            sb_dir_from_angles(a[0], a[1], wi);
            sb_dir_from_angles(a[2], a[3], wo);
            int neg = 0;
            for (size_t k = 0; k < n && !nan; k++)
                neg |= vals[k] < 0;
            for (int c = 0; c < 3 && !nan; c++)
                for (size_t k = 0; k < n; k++)
                    f[c] += w[(size_t)c * n + k] * vals[k];
            if ((r = reader_add(rd, wi, wo, f, nan, neg)) != SB_OK) goto done;
        }
    }
    if (st < 0) goto done;
    if (state < 2)
        r = sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: ends before the %s", rd->path, rd->lr.line,
                     state == 0 ? "wavelength count" : "last wavelength");
done:
    free(wl);
    free(w);
    free(vals);
    free(fields);
    return r;
}

/* ALTA text: "#DIM 3 m", "#PARAM_IN ISOTROPIC_TL_TV_PROJ_DPHI", "#PARAM_OUT
 * INV_STERADIAN_COSINE_FACTOR | INV_STERADIAN | RGB_COLOR", "#VS 0", then
 * rows theta_l, theta_v cos(dphi), theta_v sin(dphi), m values. */
static sb_result_t read_alta(reader_t *rd) {
    sb_context_t *ctx = rd->ctx;
    long din = -1, dout = -1;
    int have_in = 0, cosine = -1;
    char *line;
    int st;
    sb_result_t r = SB_OK;
    while ((st = sb_lines_next(ctx, &rd->lr, &line, &r)) > 0) {
        if (is_blank_or_comment(line, 0)) continue;
        char *s = sb_trim(line);
        if (s[0] == '#') {
            char *f[4];
            size_t nf = sb_split_fields(s, 0, f, 4);
            if (strcmp(f[0], "#DIM") == 0) {
                char *e1 = NULL, *e2 = NULL;
                if (nf == 3) {
                    din = strtol(f[1], &e1, 10);
                    dout = strtol(f[2], &e2, 10);
                }
                if (nf != 3 || *e1 || *e2)
                    return sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: #DIM needs two integers", rd->path, rd->lr.line);
                if (din != 3 || (dout != 1 && dout != 3))
                    return sb_error(ctx, SB_ERR_UNSUPPORTED,
                                    "%s:%zu: ALTA #DIM %ld %ld not supported; need 3 inputs "
                                    "(ISOTROPIC_TL_TV_PROJ_DPHI) and 1 or 3 outputs",
                                    rd->path, rd->lr.line, din, dout);
            } else if (strcmp(f[0], "#PARAM_IN") == 0) {
                if (nf < 2 || strcmp(f[1], "ISOTROPIC_TL_TV_PROJ_DPHI") != 0)
                    return sb_error(ctx, SB_ERR_UNSUPPORTED,
                                    "%s:%zu: ALTA #PARAM_IN %s not supported; need ISOTROPIC_TL_TV_PROJ_DPHI", rd->path,
                                    rd->lr.line, nf >= 2 ? f[1] : "(none)");
                have_in = 1;
            } else if (strcmp(f[0], "#PARAM_OUT") == 0) {
                if (nf >= 2 && strcmp(f[1], "INV_STERADIAN_COSINE_FACTOR") == 0)
                    cosine = 1;
                else if (nf >= 2 && (strcmp(f[1], "INV_STERADIAN") == 0 || strcmp(f[1], "RGB_COLOR") == 0))
                    cosine = 0;
                else
                    return sb_error(ctx, SB_ERR_UNSUPPORTED,
                                    "%s:%zu: ALTA #PARAM_OUT %s not supported; need INV_STERADIAN_COSINE_FACTOR, "
                                    "INV_STERADIAN or RGB_COLOR",
                                    rd->path, rd->lr.line, nf >= 2 ? f[1] : "(none)");
            } else if (strcmp(f[0], "#VS") == 0) {
                if (nf != 2 || strcmp(f[1], "0") != 0)
                    return sb_error(ctx, SB_ERR_UNSUPPORTED, "%s:%zu: ALTA confidence columns (#VS %s) not supported",
                                    rd->path, rd->lr.line, nf >= 2 ? f[1] : "");
            }
            continue; /* other comments: #SAMPLE, #ORIGIN, #URL, ... */
        }
        if (din < 0 || !have_in || cosine < 0)
            return sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: data before the ALTA header (#DIM, #PARAM_IN, #PARAM_OUT)",
                            rd->path, rd->lr.line);
        char *f[8];
        size_t nf = sb_split_fields(s, 0, f, 8), want = 3 + (size_t)dout;
        if (nf != want)
            return sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: %zu numbers, expected %zu (3 angles + %ld values)", rd->path,
                            rd->lr.line, nf, want, dout);
        double a[3], v[3];
        static const char *const an[3] = {"theta_l", "theta_v cos(dphi)", "theta_v sin(dphi)"};
        for (int k = 0; k < 3; k++)
            if ((r = angle_field(rd, an[k], f[k], 1, &a[k])) != SB_OK) return r;
        int nan = 0;
        for (long k = 0; k < dout; k++)
            if ((r = value_field(rd, "value", f[3 + k], &v[k], &nan)) != SB_OK) return r;
        if (dout == 1) v[1] = v[2] = v[0];
        double wi[3], wo[3];
        sb_dir_from_angles(a[0], 0, wi);
        sb_dir_from_angles(hypot(a[1], a[2]), atan2(a[2], a[1]), wo);
        /* INV_STERADIAN_COSINE_FACTOR: the value is f_r cos(theta_v) */
        int neg = v[0] < 0 || v[1] < 0 || v[2] < 0;
        for (int c = 0; c < 3 && cosine; c++)
            v[c] = wo[2] > SB_HORIZON_Z ? v[c] / wo[2] : 0;
        if ((r = reader_add(rd, wi, wo, v, nan, neg)) != SB_OK) return r;
    }
    if (st < 0) return r;
    if (din < 0 || !have_in) return sb_error(ctx, SB_ERR_FORMAT, "%s: no ALTA header (#DIM, #PARAM_IN)", rd->path);
    rd->info->channels = (size_t)dout;
    return SB_OK;
}

/* sepbrdf CSV (docs/measured.md). */
enum { COL_TI, COL_PI, COL_TO, COL_PO, COL_R, COL_G, COL_B, COL_VALUE, NCOLS };

static sb_result_t read_csv(reader_t *rd, int *iso_out, int *recip_out) {
    sb_context_t *ctx = rd->ctx;
    static const char *const names[NCOLS] = {"theta_i", "phi_i", "theta_o", "phi_o", "r", "g", "b", "value"};
    long col[NCOLS];
    double unit[NCOLS], meta_unit = SB_PI / 180;
    int iso = -1, recip = 1, header = 0;
    size_t ncols = 0;
    char **f = NULL;
    char *line;
    int st;
    double phi_i0 = NAN;
    int phi_i_varies = 0;
    sb_result_t r = SB_OK;
    for (int k = 0; k < NCOLS; k++) {
        col[k] = -1;
        unit[k] = 0;
    }
    while ((st = sb_lines_next(ctx, &rd->lr, &line, &r)) > 0) {
        char *s = sb_trim(line);
        if (!*s) continue;
        if (s[0] == '#') {
            if (header) continue;
            char *colon = strchr(s + 1, ':');
            if (!colon) continue;
            *colon = 0;
            char *key = sb_trim(s + 1), *val = sb_trim(colon + 1);
            if (strcmp(key, "units") == 0) {
                if (strcmp(val, "degrees") == 0 || strcmp(val, "deg") == 0)
                    meta_unit = SB_PI / 180;
                else if (strcmp(val, "radians") == 0 || strcmp(val, "rad") == 0)
                    meta_unit = 1;
                else {
                    r = sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: units '%.40s' unknown, need degrees or radians", rd->path,
                                 rd->lr.line, val);
                    goto done;
                }
            } else if (strcmp(key, "symmetry") == 0) {
                if (strcmp(val, "isotropic") == 0)
                    iso = 1;
                else if (strcmp(val, "anisotropic") == 0)
                    iso = 0;
                else {
                    r = sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: symmetry '%.40s' unknown, need isotropic or anisotropic",
                                 rd->path, rd->lr.line, val);
                    goto done;
                }
            } else if (strcmp(key, "reciprocal") == 0) {
                if (strcmp(val, "yes") == 0)
                    recip = 1;
                else if (strcmp(val, "no") == 0)
                    recip = 0;
                else {
                    r = sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: reciprocal '%.40s' unknown, need yes or no", rd->path,
                                 rd->lr.line, val);
                    goto done;
                }
            }
            continue; /* other keys: free comments */
        }
        if (!header) {
            /* The header: count fields, then map names. */
            size_t n = 1;
            for (const char *q = s; *q; q++)
                n += *q == ',';
            if (n > 1024) {
                r = sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: header with %zu columns (at most 1024)", rd->path,
                             rd->lr.line, n);
                goto done;
            }
            f = malloc(n * sizeof *f);
            if (!f) {
                r = sb_error(ctx, SB_ERR_NOMEM, "%s: out of memory", rd->path);
                goto done;
            }
            ncols = sb_split_fields(s, ',', f, n);
            for (size_t c = 0; c < ncols; c++) {
                char name[64];
                double u = 0;
                snprintf(name, sizeof name, "%s", f[c]);
                size_t len = strlen(name);
                if (len > 4 && strcmp(name + len - 4, "_deg") == 0) {
                    name[len - 4] = 0;
                    u = SB_PI / 180;
                } else if (len > 4 && strcmp(name + len - 4, "_rad") == 0) {
                    name[len - 4] = 0;
                    u = 1;
                }
                for (int k = 0; k < NCOLS; k++)
                    if (strcmp(name, names[k]) == 0) {
                        if (col[k] >= 0) {
                            r = sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: column '%s' appears twice", rd->path, rd->lr.line,
                                         names[k]);
                            goto done;
                        }
                        if (u != 0 && k >= COL_R) {
                            r = sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: column '%.40s': only angles take a unit suffix",
                                         rd->path, rd->lr.line, f[c]);
                            goto done;
                        }
                        col[k] = (long)c;
                        unit[k] = u;
                    }
            }
            for (int k = 0; k <= COL_PO; k++)
                if (col[k] < 0) {
                    r = sb_error(ctx, SB_ERR_FORMAT,
                                 "%s:%zu: header lacks column '%s' (need theta_i, phi_i, theta_o, phi_o and "
                                 "r, g, b or value; is the first line a header?)",
                                 rd->path, rd->lr.line, names[k]);
                    goto done;
                }
            int rgb = col[COL_R] >= 0 && col[COL_G] >= 0 && col[COL_B] >= 0;
            int any_rgb = col[COL_R] >= 0 || col[COL_G] >= 0 || col[COL_B] >= 0;
            if ((any_rgb && !rgb) || (rgb == (col[COL_VALUE] >= 0))) {
                r = sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: header needs either r, g, b or value (not both)", rd->path,
                             rd->lr.line);
                goto done;
            }
            rd->info->channels = rgb ? 3 : 1;
            for (int k = 0; k <= COL_PO; k++)
                if (unit[k] == 0) unit[k] = meta_unit;
            header = 1;
            continue;
        }
        /* A row. */
        size_t n = sb_split_fields(s, ',', f, ncols);
        if (n != ncols) {
            r = sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: %zu fields, the header has %zu", rd->path, rd->lr.line, n, ncols);
            goto done;
        }
        double a[4], v[3];
        int nan = 0;
        for (int k = 0; k <= COL_PO; k++)
            if ((r = angle_field(rd, names[k], f[col[k]], unit[k], &a[k])) != SB_OK) goto done;
        if (rd->info->channels == 3) {
            for (int k = 0; k < 3; k++)
                if ((r = value_field(rd, names[COL_R + k], f[col[COL_R + k]], &v[k], &nan)) != SB_OK) goto done;
        } else {
            if ((r = value_field(rd, "value", f[col[COL_VALUE]], &v[0], &nan)) != SB_OK) goto done;
            v[1] = v[2] = v[0];
        }
        if (isnan(phi_i0))
            phi_i0 = a[1];
        else if (a[1] != phi_i0)
            phi_i_varies = 1;
        double wi[3], wo[3];
        sb_dir_from_angles(a[0], a[1], wi);
        sb_dir_from_angles(a[2], a[3], wo);
        if ((r = reader_add(rd, wi, wo, v, nan, v[0] < 0 || v[1] < 0 || v[2] < 0)) != SB_OK) goto done;
    }
    if (st < 0) goto done;
    if (!header) {
        r = sb_error(ctx, SB_ERR_FORMAT, "%s: no header line (theta_i,phi_i,theta_o,phi_o,r,g,b)", rd->path);
        goto done;
    }
    /* Undeclared symmetry: one light azimuth cannot show anisotropy. */
    *iso_out = iso >= 0 ? iso : !phi_i_varies;
    *recip_out = recip;
done:
    free(f);
    return r;
}

sb_result_t sb_scattered_open_(sb_context_t *ctx, const char *path, sb_table_format_t fmt, const sb_measured_opts_t *o,
                               sb_source_t **out, sb_measured_info_t *info) {
    FILE *fp = fopen(path, "rb");
    if (!fp) return sb_error(ctx, SB_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    reader_t rd = {ctx, path, {fp, path, 0, NULL, 0}, {NULL, 0, 0}, info};
    for (int c = 0; c < 3; c++) {
        info->value_min[c] = INFINITY;
        info->value_max[c] = -INFINITY;
    }
    info->white = o->white;
    int iso = 1, recip = 1;
    sb_result_t r;
    switch (fmt) {
    case SB_TABLE_CORNELL:
        r = read_cornell(&rd, o);
        break;
    case SB_TABLE_ALTA:
        r = read_alta(&rd);
        break;
    case SB_TABLE_CSV:
        r = read_csv(&rd, &iso, &recip);
        break;
    default:
        r = sb_error(ctx, SB_ERR_ARG, "%s: not a scattered table format", path);
    }
    free(rd.lr.buf);
    fclose(fp);
    info->samples = rd.ss.n;
    info->missing = info->nan_rows + info->horizon_rows;
    for (int c = 0; c < 3; c++) {
        info->value_mean[c] = rd.ss.n ? info->value_mean[c] / (double)rd.ss.n : 0;
        if (!rd.ss.n) info->value_min[c] = info->value_max[c] = 0;
    }
    if (r == SB_OK) r = table_create(ctx, path, &rd.ss, iso, recip, o, info, out);
    free(rd.ss.s);
    return r;
}

/* ---- simulated gonioreflectometer ------------------------------------- */

/* Standard normal by Box-Muller, one value per call (the pair's second
 * value is kept for the next call). */
typedef struct gauss {
    uint64_t s;
    int have;
    double next;
} gauss_t;

static double gauss_next(gauss_t *g) {
    if (g->have) {
        g->have = 0;
        return g->next;
    }
    double two[2];
    sb_splitmix_gauss2(&g->s, two); /* splitmix64: small, deterministic, good enough for test noise */
    g->next = two[1];
    g->have = 1;
    return two[0];
}

sb_result_t sb_gonio_write_csv(sb_context_t *ctx, FILE *fp, const sb_source_t *src, const sb_gonio_opts_t *opts,
                               size_t *rows) {
    if (!fp || !src) return sb_error(ctx, SB_ERR_ARG, "gonio: missing output or source");
    sb_gonio_opts_t o = {0};
    if (opts) o = *opts;
    if (!o.n_theta_i && !o.n_phi_i && !o.n_theta_o && !o.n_phi_o) {
        o.n_theta_i = 18;
        o.n_phi_i = 1;
        o.n_theta_o = 18;
        o.n_phi_o = 72;
    }
    size_t nn[4] = {o.n_theta_i, o.n_phi_i, o.n_theta_o, o.n_phi_o}, total = 1;
    static const char *const nm[4] = {"N_theta_i", "N_phi_i", "N_theta_o", "N_phi_o"};
    for (int k = 0; k < 4; k++) {
        if (nn[k] < 1 || nn[k] > 4096)
            return sb_error(ctx, SB_ERR_RANGE, "gonio: %s = %zu out of range, need 1..4096", nm[k], nn[k]);
        if (sb_size_mul(total, nn[k], &total) || total > MAX_ROWS)
            return sb_error(ctx, SB_ERR_OVERFLOW, "gonio: %zu x %zu x %zu x %zu positions exceed %zu rows", nn[0],
                            nn[1], nn[2], nn[3], MAX_ROWS);
    }
    if (!(o.noise >= 0 && o.noise <= 10))
        return sb_error(ctx, SB_ERR_RANGE, "gonio: noise %g out of range, need 0..10", o.noise);
    gauss_t g = {o.seed ? o.seed : 1, 0, 0};
    unsigned flags = sb_source_flags(src);
    fprintf(fp,
            "# sepbrdf gonio table (docs/measured.md)\n"
            "# source: %s\n"
            "# gonio: %zu,%zu,%zu,%zu (theta_k = (k + 1/2) 90/N deg, phi_k = k 360/N deg)\n"
            "# noise: %.17g (multiplicative gaussian, seed %llu)\n"
            "# units: degrees\n"
            "# symmetry: %s\n"
            "# reciprocal: %s\n"
            "theta_i,phi_i,theta_o,phi_o,r,g,b\n",
            sb_source_description(src), nn[0], nn[1], nn[2], nn[3], o.noise, (unsigned long long)(o.seed ? o.seed : 1),
            flags & SB_SOURCE_ISOTROPIC ? "isotropic" : "anisotropic", flags & SB_SOURCE_RECIPROCAL ? "yes" : "no");
    size_t written = 0;
    for (size_t a = 0; a < nn[0]; a++)
        for (size_t b = 0; b < nn[1]; b++)
            for (size_t c = 0; c < nn[2]; c++)
                for (size_t d = 0; d < nn[3]; d++) {
                    double ti = ((double)a + 0.5) * 90 / (double)nn[0], pi_ = (double)b * 360 / (double)nn[1];
                    double to = ((double)c + 0.5) * 90 / (double)nn[2], po = (double)d * 360 / (double)nn[3];
                    double wi[3], wo[3], v[3];
                    sb_dir_from_angles(ti * SB_PI / 180, pi_ * SB_PI / 180, wi);
                    sb_dir_from_angles(to * SB_PI / 180, po * SB_PI / 180, wo);
                    if (!sb_source_eval(src, wi, wo, v) || !isfinite(v[0]) || !isfinite(v[1]) || !isfinite(v[2]))
                        continue;
                    if (o.noise > 0)
                        for (int k = 0; k < 3; k++)
                            v[k] *= 1 + o.noise * gauss_next(&g);
                    fprintf(fp, "%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n", ti, pi_, to, po, v[0], v[1], v[2]);
                    written++;
                }
    if (rows) *rows = written;
    if (ferror(fp)) return sb_error(ctx, SB_ERR_IO, "gonio: write error: %s", strerror(errno));
    return SB_OK;
}
