/* Neighbour search of the scattered-sample source: the embedding of a
 * direction pair (its symmetries folded, see scattered.c), an implicit k-d
 * tree over the embedded points and the k nearest within a radius. */
#include <math.h>
#include <stdlib.h>

#include "source/scattered_impl.h"
#include "util/internal.h"

#define KD_LEAF 16

void sb_scat_embed_(int iso, int recip, const double wi[3], const double wo[3], double *x) {
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
void sb_kd_build_(size_t *idx, const double *p, unsigned char *split, size_t lo, size_t hi) {
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
        sb_kd_build_(idx, p, split, lo, mid);
        lo = mid + 1; /* the right half in the loop */
    }
}

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

/* Entry i of the heap after entry j: farther, or as far and later in the
 * tree.  The order is total, so the k nearest are one set whatever the
 * order of the search and whatever bound it starts from (ties included). */
static int knn_after(const knn_t *q, size_t i, size_t j) {
    return q->d2[i] > q->d2[j] || (q->d2[i] == q->d2[j] && q->at[i] > q->at[j]);
}

static void knn_sift_down(knn_t *q, size_t i, size_t n) {
    for (;;) {
        size_t l = 2 * i + 1, r = l + 1, m = i;
        if (l < n && knn_after(q, l, m)) m = l;
        if (r < n && knn_after(q, r, m)) m = r;
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
        while (i > 0 && (q->d2[(i - 1) / 2] < d2 || (q->d2[(i - 1) / 2] == d2 && q->at[(i - 1) / 2] < at))) {
            q->d2[i] = q->d2[(i - 1) / 2];
            q->at[i] = q->at[(i - 1) / 2];
            i = (i - 1) / 2;
        }
        q->d2[i] = d2;
        q->at[i] = at;
        return;
    }
    if (d2 > q->d2[0] || (d2 == q->d2[0] && at > q->at[0])) return;
    q->d2[0] = d2;
    q->at[0] = at;
    knn_sift_down(q, 0, q->n);
}

/* Descending (d2, at), the order knn_after defines, by insertion: a
 * max-heap is nearly in that order already, so few entries move. */
void sb_knn_canon_(knn_t *q) {
    for (size_t i = 1; i < q->n; i++) {
        double d = q->d2[i];
        size_t a = q->at[i], j = i;
        for (; j > 0 && (q->d2[j - 1] < d || (q->d2[j - 1] == d && q->at[j - 1] < a)); j--) {
            q->d2[j] = q->d2[j - 1];
            q->at[j] = q->at[j - 1];
        }
        q->d2[j] = d;
        q->at[j] = a;
    }
}

/* Heap sort in place: ascending d2. */
void sb_knn_sort_(knn_t *q) {
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

/* The search below node [lo, hi), off[a] the distance of its box from x
 * along axis a (Arya and Mount's incremental distance): a far child's box
 * is off by |x - split| along the split axis, the other axes as its
 * parent's, and is skipped when its squared distance exceeds the k-th
 * distance so far.  That distance is summed as dist2 sums, each term no
 * larger than a point's in the box, so rounding never skips a tie (the k
 * nearest stay one set). */
static void kd_search(const table_t *t, const double *x, size_t lo, size_t hi, knn_t *q, double *off) {
    while (hi - lo > KD_LEAF) {
        size_t mid = lo + (hi - lo) / 2;
        int ax = t->split[mid];
        const double *pm = t->pts + mid * MAX_DIM;
        double d2 = dist2(x, pm);
        if (d2 <= knn_bound(q) && !(q->nskip && knn_skips(q, pm))) knn_push(q, d2, mid);
        double diff = x[ax] - pm[ax];
        size_t nlo = diff < 0 ? lo : mid + 1, nhi = diff < 0 ? mid : hi;
        size_t flo = diff < 0 ? mid + 1 : lo, fhi = diff < 0 ? hi : mid;
        kd_search(t, x, nlo, nhi, q, off);
        double old = off[ax];
        off[ax] = fabs(diff);
        if (dist2(off, (const double[MAX_DIM]){0}) <= knn_bound(q)) kd_search(t, x, flo, fhi, q, off);
        off[ax] = old;
        return;
    }
    for (size_t i = lo; i < hi; i++) {
        double d2 = dist2(x, t->pts + i * MAX_DIM);
        if (d2 <= knn_bound(q) && !(q->nskip && knn_skips(q, t->pts + i * MAX_DIM))) knn_push(q, d2, i);
    }
}

void sb_kd_query_(const table_t *t, const double *x, size_t lo, size_t hi, knn_t *q) {
    double off[MAX_DIM] = {0};
    kd_search(t, x, lo, hi, q, off);
}

/* Median over points of the distance to the nearest other point that is
 * not at the same position (repeats and folded copies skipped); 0 when
 * there is no such pair, < 0 on no memory. */
double sb_table_spacing_(sb_context_t *ctx, const table_t *t) {
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
        sb_kd_query_(t, t->pts + i * MAX_DIM, 0, t->n, &q);
        sb_knn_sort_(&q);
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
