/* The residual maxima of the block-circulant solver (circulant.h:
 * sb_circ_max_abs): the largest cell error of every truncation J', from
 * the R^3 distinct values and the selected triplets, one read of the
 * stored values (see rows_max). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "solve/circulant_impl.h"
#include "util/internal.h"
#include "util/parallel.h"

/* max_i |x[i] - t y[i]|; with `store`, x[i] becomes x[i] - t y[i] (the
 * subtraction and the maximum in one pass).  SSE2, or AVX2 where the CPU
 * has it (circ_avx2): the same operations, so the same bits. */
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
#include <immintrin.h>
#define CIRC_AVX2 1
__attribute__((target("avx2"))) static double absmax_axpy_avx2(double *x, double t, const double *y, size_t n,
                                                               int store) {
    size_t i = 0;
    __m256d vm = _mm256_setzero_pd(), vt = _mm256_set1_pd(t), sign = _mm256_set1_pd(-0.0);
    for (; i + 4 <= n; i += 4) {
        __m256d d = _mm256_sub_pd(_mm256_loadu_pd(x + i), _mm256_mul_pd(vt, _mm256_loadu_pd(y + i)));
        if (store) _mm256_storeu_pd(x + i, d);
        vm = _mm256_max_pd(vm, _mm256_andnot_pd(sign, d));
    }
    double tmp[4], mx;
    _mm256_storeu_pd(tmp, vm);
    mx = tmp[0] > tmp[1] ? tmp[0] : tmp[1];
    mx = tmp[2] > mx ? tmp[2] : mx;
    mx = tmp[3] > mx ? tmp[3] : mx;
    for (; i < n; i++) {
        double d = x[i] - t * y[i];
        if (store) x[i] = d;
        if (fabs(d) > mx) mx = fabs(d);
    }
    return mx;
}
#endif

#ifdef CIRC_AVX2
static int circ_avx2(void) {
    static int has = -1;
    if (has < 0) has = __builtin_cpu_supports("avx2") ? 1 : 0;
    return has;
}
#endif

double sb_circ_absmax_axpy(double *x, double t, const double *y, size_t n, int store) {
#ifdef CIRC_AVX2
    if (circ_avx2()) return absmax_axpy_avx2(x, t, y, n, store);
#endif
    size_t i = 0;
    double mx = 0;
#if defined(__SSE2__)
    __m128d vm = _mm_setzero_pd(), vt = _mm_set1_pd(t), sign = _mm_set1_pd(-0.0);
    for (; i + 2 <= n; i += 2) {
        __m128d d = _mm_sub_pd(_mm_loadu_pd(x + i), _mm_mul_pd(vt, _mm_loadu_pd(y + i)));
        if (store) _mm_storeu_pd(x + i, d);
        vm = _mm_max_pd(vm, _mm_andnot_pd(sign, d));
    }
    double tmp[2];
    _mm_storeu_pd(tmp, vm);
    mx = tmp[0] > tmp[1] ? tmp[0] : tmp[1];
#endif
    for (; i < n; i++) {
        double d = x[i] - t * y[i];
        if (store) x[i] = d;
        if (fabs(d) > mx) mx = fabs(d);
    }
    return mx;
}

static double absmax_axpy(const double *x, double t, const double *y, size_t n) {
    return sb_circ_absmax_axpy((double *)x, t, y, n, 0); /* store = 0: x is only read */
}

/* The three sweeps of a cos/sin pair on one row in one pass: m[0], m[1]
 * = max_i |x[i] - t1 y[i]|, |x[i] - t2 y[i]| (its cos vector alone), then
 * x[i] -= t3 y[i] and m[2] = max_i |x[i]| (the whole pair): the
 * operations of absmax_axpy_st, so the same bits, with one read of x and
 * y instead of three. */
#ifdef CIRC_AVX2
__attribute__((target("avx2"))) static double hmax4(__m256d v) {
    double tmp[4], mx;
    _mm256_storeu_pd(tmp, v);
    mx = tmp[0] > tmp[1] ? tmp[0] : tmp[1];
    mx = tmp[2] > mx ? tmp[2] : mx;
    return tmp[3] > mx ? tmp[3] : mx;
}

__attribute__((target("avx2"))) static void absmax_pair_avx2(double *x, const double t[3], const double *y, size_t n,
                                                             double m[3]) {
    size_t i = 0;
    __m256d sign = _mm256_set1_pd(-0.0), vm[3], vt[3];
    for (int k = 0; k < 3; k++)
        vm[k] = _mm256_setzero_pd(), vt[k] = _mm256_set1_pd(t[k]);
    for (; i + 4 <= n; i += 4) {
        __m256d xv = _mm256_loadu_pd(x + i), yv = _mm256_loadu_pd(y + i), d[3];
        for (int k = 0; k < 3; k++) {
            d[k] = _mm256_sub_pd(xv, _mm256_mul_pd(vt[k], yv));
            vm[k] = _mm256_max_pd(vm[k], _mm256_andnot_pd(sign, d[k]));
        }
        _mm256_storeu_pd(x + i, d[2]);
    }
    for (int k = 0; k < 3; k++)
        m[k] = hmax4(vm[k]);
    for (; i < n; i++) {
        double d[3];
        for (int k = 0; k < 3; k++) {
            d[k] = x[i] - t[k] * y[i];
            if (fabs(d[k]) > m[k]) m[k] = fabs(d[k]);
        }
        x[i] = d[2];
    }
}
#endif

static void absmax_pair(double *x, const double t[3], const double *y, size_t n, double m[3]) {
#ifdef CIRC_AVX2
    if (circ_avx2()) {
        absmax_pair_avx2(x, t, y, n, m);
        return;
    }
#endif
    m[0] = absmax_axpy(x, t[0], y, n);
    m[1] = absmax_axpy(x, t[1], y, n);
    m[2] = sb_circ_absmax_axpy(x, t[2], y, n, 1);
}

/* One step of the residual sweep of sb_circ_max_abs, for one error mx[j]:
 * lone, the cos vector of a pair alone (the largest |row - B v at| over v
 * in {hi[d], lo[d]}, B = sg bt[ot] / R, the row left as it is); else the
 * whole term or pair subtracted (row -= sg bt[ot] e[d] at) and the
 * largest |row| after it. */
typedef struct circ_step {
    int lone, fuse; /* fuse: lone, and the next step subtracts its pair (the same at and bt) */
    double sg;
    const double *at, *bt, *e; /* R each; lone: hi at e, lo at e + R */
} circ_step_t;

/* The residual kernel's rows d in [d0, d1) of one thread, every step on
 * each row while it is in the cache: one read of the stored values instead
 * of a read and a write of an R^3 copy per term (io R = 256, J = 8: the
 * factor step 1.95 -> 1.70 s, the peak 802 -> 675 MiB). */
typedef struct rows_job {
    const circ_step_t *st;
    size_t nst, R, ld, d0, d1;
    const double *a;
    double *row, *mx; /* R scratch; nst maxima */
} rows_job_t;

static void *rows_max(void *arg) {
    rows_job_t *j = arg;
    size_t R = j->R;
    double *row = j->row;
    for (size_t s = 0; s < j->nst; s++)
        j->mx[s] = 0;
    for (size_t d = j->d0; d < j->d1; d++)
        for (size_t ot = 0; ot < R; ot++) {
            memcpy(row, j->a + (d * R + ot) * j->ld, R * sizeof *row); /* over theta_i */
            for (size_t s = 0; s < j->nst; s++) {
                const circ_step_t *st = &j->st[s];
                double m;
                if (st->fuse) { /* this step and the next in one pass */
                    double B = st->sg * st->bt[ot] / (double)R, m3[3], t[3];
                    const circ_step_t *nx = &j->st[s + 1];
                    t[0] = B * st->e[d], t[1] = B * st->e[R + d], t[2] = nx->sg * nx->bt[ot] * nx->e[d];
                    absmax_pair(row, t, st->at, R, m3);
                    j->mx[s] = fmax(j->mx[s], fmax(m3[0], m3[1]));
                    s++;
                    j->mx[s] = fmax(j->mx[s], m3[2]);
                    continue;
                }
                if (st->lone) {
                    double B = st->sg * st->bt[ot] / (double)R;
                    double x = absmax_axpy(row, B * st->e[d], st->at, R);
                    double y = absmax_axpy(row, B * st->e[R + d], st->at, R);
                    m = fmax(x, y);
                } else {
                    double cf = st->sg * st->bt[ot] * st->e[d];
                    m = sb_circ_absmax_axpy(row, cf, st->at, R, 1); /* row -= cf at, and its largest |.| */
                }
                j->mx[s] = fmax(j->mx[s], m);
            }
        }
    return NULL;
}

/* The cos vector alone breaks the structure.  With
 * a = 2 pi k / R, its cell (i, o) is cf (2/R) cos(a i) cos(a o)
 * = (cf/R) (cos(a (o - i)) + cos(a (o + i))): for each azimuth
 * difference d the cells differ only in cos(a s), s = o + i =
 * d + 2i mod R, and |A - B cos| is largest at the extremes of
 * cos over the reachable s (the parity of d when R is even). */
static void cos_bounds(const sb_circ_t *c, const cand_t *q, double *e) {
    size_t R = c->R;
    double cmx[2] = {-2, -2}, cmn[2] = {2, 2};
    for (size_t s2 = 0; s2 < R; s2++) {
        double cv = c->ct[((size_t)q->k * s2) % R];
        int par = R % 2 == 0 ? (int)(s2 % 2) : 0;
        if (cv > cmx[par]) cmx[par] = cv;
        if (cv < cmn[par]) cmn[par] = cv;
    }
    if (R % 2) {
        cmx[1] = cmx[0];
        cmn[1] = cmn[0];
    }
    double *hi = e, *lo = e + R;
    for (size_t d = 0; d < R; d++) {
        double ck = c->ct[((size_t)q->k * d) % R];
        hi[d] = ck + cmx[d % 2]; /* A - B cmx = row - B (ck + cmx) */
        lo[d] = ck + cmn[d % 2];
    }
}

/* The phase of each azimuth difference d in a whole (circulant) term or
 * pair: 1/R (k = 0), (-1)^d / R (the single Nyquist term), else
 * 2 cos(2 pi k d / R) / R. */
static void term_phase(const sb_circ_t *c, const cand_t *q, double *e) {
    size_t R = c->R;
    for (size_t d = 0; d < R; d++) {
        double ph;
        if (q->k == 0)
            ph = 1 / (double)R;
        else if (sb_circ_single(c, q->k))
            ph = (d % 2 ? -1.0 : 1.0) / (double)R;
        else
            ph = 2 * c->ct[((size_t)q->k * d) % R] / (double)R;
        e[d] = ph;
    }
}

/* Whether every row (d, ot) of the table equals row (R - d, ot) bit for
 * bit (an even source's table: matrix.c mirrors it).  Then the residual
 * rows d and R - d differ only by the rounding of the cosine table
 * (cos(2 pi q / R) and cos(2 pi (R - q) / R) may part in the last bit):
 * every step's phase (term_phase, cos_bounds: cosines of k d, and the
 * parity of d, which R - d shares when R is even) is even in d, so the
 * maxima over d <= R / 2 are those of the whole table up to that rounding,
 * for half the reads (issue 36: 4 % of io -r 64's instructions). */
static int rows_even(const double *a, size_t ld, size_t R) {
    for (size_t d = 1; 2 * d < R; d++)
        for (size_t ot = 0; ot < R; ot++)
            if (memcmp(a + (d * R + ot) * ld, a + ((R - d) * R + ot) * ld, R * sizeof *a) != 0) return 0;
    return 1;
}

sb_result_t sb_circ_max_abs(sb_circ_t *c, const double *a, size_t ld, const double *w, double sigma_scale, size_t J,
                            double *mx) {
    size_t R = c->R, R2 = R * R;
    if (J == 0) return SB_OK;
    /* Step: the steps' vectors (at, bt, phi factors: 4R each) */
    int nt = c->nth;
    double *buf = sb_alloc(c->ctx, J * 4 * R + (size_t)nt * (R + J), sizeof *buf, "circulant residual steps");
    circ_step_t *st = malloc(J * sizeof *st);
    if (!buf || !st) {
        free(buf);
        free(st);
        return buf ? sb_error(c->ctx, SB_ERR_NOMEM, "circulant: out of memory") : SB_ERR_NOMEM;
    }
    size_t ns = 0;
    for (size_t j = 0; j < J; j++) {
        const cand_t *q = &c->cand[j];
        const double *A = c->A + (size_t)q->k * R2 + (size_t)q->idx * R, *VT = c->VT + (size_t)q->k * R2;
        double sg = q->s * sigma_scale, *at = buf + ns * 4 * R, *bt = at + R, *e = bt + R;
        for (size_t i = 0; i < R; i++) {
            double wi = w ? w[i] : 1;
            at[i] = wi > 0 ? A[i] / wi : 0;
            bt[i] = wi > 0 ? VT[q->idx + i * R] / wi : 0;
        }
        int pair_next =
            !sb_circ_single(c, q->k) && j + 1 < J && c->cand[j + 1].k == q->k && c->cand[j + 1].idx == q->idx;
        if (!sb_circ_single(c, q->k)) {
            cos_bounds(c, q, e);
            st[ns++] = (circ_step_t){1, pair_next, sg, at, bt, e};
            if (!pair_next) break; /* J ends inside the pair */
            j++;
            /* the pair's next step subtracts both members: the same vectors */
            memcpy(buf + ns * 4 * R, at, 2 * R * sizeof *at);
            at = buf + ns * 4 * R, bt = at + R, e = bt + R;
        }
        term_phase(c, q, e); /* Step: subtract the whole (circulant) term or pair */
        st[ns++] = (circ_step_t){0, 0, sg, at, bt, e};
    }
    /* Step: every row once, split by the azimuth difference d; on a table
     * even to the bit only d <= R / 2 (rows_even) */
    rows_job_t jobs[SB_THREADS_MAX];
    double *scratch = buf + J * 4 * R;
    size_t nd = rows_even(a, ld, R) ? R / 2 + 1 : R;
    for (int t = 0; t < nt; t++) {
        jobs[t] =
            (rows_job_t){st, ns, R, ld, 0, 0, a, scratch + (size_t)t * (R + J), scratch + (size_t)t * (R + J) + R};
        sb_part(nd, t, nt, &jobs[t].d0, &jobs[t].d1);
    }
    sb_parallel_run(rows_max, jobs, sizeof *jobs, nt, NULL, NULL);
    for (size_t s2 = 0; s2 < ns; s2++) {
        mx[s2] = 0;
        for (int t = 0; t < nt; t++)
            mx[s2] = fmax(mx[s2], jobs[t].mx[s2]);
    }
    free(buf);
    free(st);
    return SB_OK;
}
