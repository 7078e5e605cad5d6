/* Exact SVD of even block-circulant matrices (see circulant.h for the
 * maths).  Storage: the weighted kernel K_m is kept as R blocks of R x R,
 * column-major over (theta_i, theta_o): K[m R^2 + it + ot R], i.e. an
 * R^2 x R matrix whose columns are the blocks; sb_circ_max_abs reads the
 * stored values' rows a[(d R + ot) ld + it] (d the azimuth difference). */
#include "solve/circulant.h"

#include <cblas.h>
#include <float.h>
#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "solve/circulant_impl.h"
#include "util/internal.h"
#include "util/parallel.h"
#include "util/rdft.h"

void sb_circ_destroy(sb_circ_t *c) {
    if (!c) return;
    free(c->K);
    free(c->C);
    free(c->Cv);
    free(c->T);
    free(c->list);
    free(c->done);
    free(c->fro);
    free(c->need);
    free(c->sv);
    free(c->A);
    free(c->VT);
    free(c->ct);
    free(c->work);
    free(c->iwork);
    free(c->cand);
    sb_circ_sym_free(c);
    free(c);
}

sb_result_t sb_circ_create(sb_context_t *ctx, size_t R, sb_circ_t **out) {
    *out = NULL;
    size_t R2, R3;
    if (R == 0 || R > 46340 || sb_size_mul(R, R, &R2) || sb_size_mul(R2, R, &R3))
        return sb_error(ctx, SB_ERR_OVERFLOW, "circulant: period %zu too large", R);
    sb_circ_t *c = calloc(1, sizeof *c);
    if (!c) return sb_error(ctx, SB_ERR_NOMEM, "circulant: out of memory");
    c->ctx = ctx;
    c->R = R;
    c->nb = R / 2 + 1;
    /* the (R/2 + 1) R^2 blocks on 2 MiB pages (first touch: util.c); the
     * R^3 kernel K only where the stored values are not it (kernel_fill) */
    c->C = sb_alloc_large(ctx, c->nb * R2, sizeof(double), "circulant blocks");
    c->sv = sb_alloc(ctx, c->nb * R, sizeof(double), "circulant blocks");
    c->T = sb_alloc(ctx, c->nb * R, sizeof(double), "circulant");
    c->need = sb_alloc(ctx, c->nb, 1, "circulant");
    c->list = sb_alloc(ctx, c->nb, sizeof(size_t), "circulant");
    c->done = sb_alloc(ctx, c->nb, 1, "circulant");
    c->fro = sb_alloc(ctx, c->nb, sizeof(double), "circulant");
    c->A = sb_alloc(ctx, c->nb * R2, sizeof(double), "circulant blocks");
    c->VT = sb_alloc(ctx, c->nb * R2, sizeof(double), "circulant blocks");
    c->ct = sb_alloc(ctx, R, sizeof(double), "circulant");
    /* the blocks are independent: one thread per core above ~2^22 flops */
    c->nth = sb_threads_for(0, c->nb, c->nb * R2 * R, (size_t)1 << 22);
    /* a block's copy for dgesdd, one a thread: it lives within one block's
     * step (a copy of every block, nb R^2, was 1 MiB at R = 64 and 66 MiB
     * at R = 256, and untouched where the blocks are symmetric) */
    c->Cv = sb_alloc(ctx, R2 * (size_t)c->nth, sizeof(double), "circulant blocks");
    c->iwork = sb_alloc(ctx, SB_CIRC_IW * R * (size_t)c->nth, sizeof(lapack_int), "circulant");
    c->cand = sb_alloc(ctx, R2, sizeof(cand_t), "circulant");
    if (!c->C || !c->Cv || !c->T || !c->need || !c->list || !c->done || !c->fro || !c->sv || !c->A || !c->VT ||
        !c->ct || !c->iwork || !c->cand) {
        sb_circ_destroy(c);
        return SB_ERR_NOMEM;
    }
    for (size_t q = 0; q < R; q++)
        c->ct[q] = cos(2 * SB_PI * (double)q / (double)R);
    for (size_t k = 0; k < c->nb; k++)
        for (size_t m = 0; m < R; m++)
            c->T[m + k * R] = c->ct[(k * m) % R];
    /* Step: LAPACK workspace query, once */
    double wq = 0;
    lapack_int n = (lapack_int)R;
    lapack_int info =
        LAPACKE_dgesdd_work(LAPACK_COL_MAJOR, 'S', n, n, c->Cv, n, c->sv, c->A, n, c->VT, n, &wq, -1, c->iwork);
    c->lwork = info == 0 ? (lapack_int)wq + 1 : 1;
    c->work = sb_alloc(ctx, (size_t)c->lwork * (size_t)c->nth, sizeof(double), "circulant LAPACK workspace");
    if (info != 0 || !c->work) {
        sb_circ_destroy(c);
        return c->work ? sb_error(ctx, SB_ERR_NUMERIC, "circulant: dgesdd workspace query failed") : SB_ERR_NOMEM;
    }
    sb_result_t r = sb_circ_sym_alloc(c);
    if (r != SB_OK) {
        sb_circ_destroy(c);
        return r;
    }
    *out = c;
    return SB_OK;
}

/* Entry (theta_i = it, phi_i = 0; theta_o = ot, phi_o = m) of A. */
static double kernel_at(const double *a, size_t ld, size_t R, size_t m, size_t it, size_t ot) {
    return a[it + (m * R + ot) * ld];
}

/* Row (m, ot) of sb_circ_is_even: mx[0], mx[1] raised to the largest |x|
 * and |x - y| (y the mirror row, NULL: none), x = wt a; returns the sum of
 * 0 x (NaN where an x is not finite).  Maxima are exact in any order. */
static double even_row(const double *a, const double *y, const double *w, double wo, size_t R, double mx[2]) {
    size_t it = 0;
    double z = 0, big = mx[0], diff = mx[1];
#if defined(__SSE2__)
    __m128d vb = _mm_set1_pd(big), vd = _mm_set1_pd(diff), vz = _mm_setzero_pd(), sign = _mm_set1_pd(-0.0);
    for (; it + 2 <= R; it += 2) {
        __m128d wt = w ? _mm_mul_pd(_mm_loadu_pd(w + it), _mm_set1_pd(wo)) : _mm_set1_pd(1);
        __m128d x = _mm_mul_pd(wt, _mm_loadu_pd(a + it));
        vz = _mm_add_pd(vz, _mm_mul_pd(x, _mm_setzero_pd()));
        vb = _mm_max_pd(vb, _mm_andnot_pd(sign, x));
        if (y) vd = _mm_max_pd(vd, _mm_andnot_pd(sign, _mm_sub_pd(x, _mm_mul_pd(wt, _mm_loadu_pd(y + it)))));
    }
    double t[6];
    _mm_storeu_pd(t, vb), _mm_storeu_pd(t + 2, vd), _mm_storeu_pd(t + 4, vz);
    big = t[0] > t[1] ? t[0] : t[1], diff = t[2] > t[3] ? t[2] : t[3], z = t[4] + t[5];
#endif
    for (; it < R; it++) {
        double wt = w ? w[it] * wo : 1, x = wt * a[it], dx = y ? fabs(x - wt * y[it]) : 0;
        z += x * 0, big = fabs(x) > big ? fabs(x) : big, diff = dx > diff ? dx : diff;
    }
    mx[0] = big, mx[1] = diff;
    return z;
}

/* Differences at m <= R / 2 only (the same at R - m); |x| and finiteness over all.
 * A row equal to its mirror row bit for bit (every row of a table an even
 * source's mirror built, iso_even in matrix.c) adds nothing the mirror row
 * does not: its differences are 0 (or NaN, where z is NaN too), its |x| and
 * 0 x those of the mirror row, so it is compared by memcmp and skipped:
 * the same result, about half the reads. */
int sb_circ_is_even(const sb_circ_t *c, const double *a, size_t ld, const double *w, double rel_tol) {
    size_t R = c->R;
    double mx[2] = {0, 0}, z = 0;
    for (size_t m = 0; m < R; m++)
        for (size_t ot = 0; ot < R; ot++) {
            int mirror = m != 0 && 2 * m < R; /* m = 0 and m = R / 2 are their own mirrors */
            const double *x = a + (m * R + ot) * ld, *y = mirror ? a + ((R - m) * R + ot) * ld : NULL;
            if (y && memcmp(x, y, R * sizeof *x) == 0) continue;
            z += even_row(x, y, w, w ? w[ot] : 1, R, mx);
        }
    return z == 0 && mx[1] <= rel_tol * mx[0];
}

/* Row (m, ot)'s squares into n2[4] (four partial sums, it mod 4). */
static void norm2_row(const double *k, size_t R, const double *w, double wo, double scale, double n2[4]) {
    size_t it = 0;
    for (; it + 4 <= R; it += 4)
        for (int l = 0; l < 4; l++) {
            double x = (w ? w[it + l] * wo : 1) * k[it + l] * scale;
            n2[l] += x * x;
        }
    for (; it < R; it++) {
        double x = (w ? w[it] * wo : 1) * k[it] * scale;
        n2[it % 4] += x * x;
    }
}

/* Four partial sums (it mod 4) instead of one dependent chain (that was
 * 1.5 % of io -r 64's time), and a row equal bit for bit to its mirror
 * (m and R - m: an even source's table) summed once and counted twice:
 * the sum differs from the one in order by rounding only (issue 36). */
double sb_circ_norm2(size_t R, const double *a, size_t ld, const double *w, double scale) {
    double n2[4] = {0, 0, 0, 0}, twice[4] = {0, 0, 0, 0};
    for (size_t m = 0; 2 * m <= R; m++)
        for (size_t ot = 0; ot < R; ot++) {
            const double *k = a + (m * R + ot) * ld; /* kernel_at(a, ld, R, m, it, ot) = k[it] */
            double wo = w ? w[ot] : 1;
            if (m == 0 || 2 * m == R) {
                norm2_row(k, R, w, wo, scale, n2);
                continue;
            }
            const double *y = a + ((R - m) * R + ot) * ld;
            if (memcmp(k, y, R * sizeof *k) == 0) {
                norm2_row(k, R, w, wo, scale, twice);
            } else {
                norm2_row(k, R, w, wo, scale, n2);
                norm2_row(y, R, w, wo, scale, n2);
            }
        }
    double sum = (n2[0] + n2[1]) + (n2[2] + n2[3]) + 2 * ((twice[0] + twice[1]) + (twice[2] + twice[3]));
    return sum * (double)R; /* each kernel value fills R cells (one per phi_i) */
}

/* Order: sigma descending, then frequency, index and member ascending, so
 * the two vectors of a pair stay adjacent with the cos vector first. */
static int cand_cmp(const void *pa, const void *pb) {
    const cand_t *a = pa, *b = pb;
    if (a->s != b->s) return a->s > b->s ? -1 : 1;
    if (a->k != b->k) return a->k < b->k ? -1 : 1;
    if (a->idx != b->idx) return a->idx < b->idx ? -1 : 1;
    return a->member < b->member ? -1 : (a->member > b->member);
}

/* The unit phi vector of (k, member) at azimuth index i. */
static double phi_vec(const sb_circ_t *c, unsigned k, unsigned member, size_t i) {
    size_t R = c->R;
    if (k == 0) return 1 / sqrt((double)R);
    if (sb_circ_single(c, k)) return (i % 2 ? -1.0 : 1.0) / sqrt((double)R);
    size_t q = ((size_t)k * i) % R;
    double ang = c->ct[q], amp = sqrt(2.0 / (double)R);
    if (member == 0) return amp * ang;
    /* sin(x) = cos(x - pi/2): index shift by R/4 is exact only for R % 4 == 0 */
    return amp * sin(2 * SB_PI * (double)q / (double)R);
}

/* Blocks [k0, k1) of one thread: the cosine transform of their columns
 * (pass 0) and dgesdd of each, values only (pass 0) or with vectors for
 * the blocks holding a selected triplet (pass 1), on the thread's own
 * LAPACK workspace. */
typedef struct blk_job {
    sb_circ_t *c;
    int t, pass;
    size_t k0, k1, bad;
    lapack_int info;
} blk_job_t;

/* Block k's step of pass 1 (vectors) or 2 (values): a symmetric block as
 * such, in place; else from its bidiagonal reduction (circulant_gen.c),
 * kept from the values to the vectors; else (a block dgesdd would scale,
 * or one the symmetric path failed on in pass 1) dgesdd on a copy, C_k
 * made again by the product where the symmetric path consumed it.
 * LAPACK's info. */
static lapack_int blk_one(sb_circ_t *c, size_t k, int t, int pass, lapack_int *iw, double *work) {
    size_t R = c->R, R2 = R * R;
    lapack_int n = (lapack_int)R, info;
    int was = pass == 2 ? c->ksym : c->sym[k];
    if (pass == 2) c->bid[k] = 0;
    c->sym[k] = was && (pass == 2 ? sb_circ_sym_values(c, k, t) : sb_circ_sym_vectors(c, k, t)) == 0;
    if (c->sym[k]) return 0;
    if (was)
        cblas_dgemv(CblasColMajor, CblasNoTrans, (int)R2, (int)R, 1.0, c->Kd, (int)R2, c->T + k * R, 1, 0.0,
                    c->C + k * R2, 1);
    if (pass == 1 && c->bid[k]) return sb_circ_gen_vectors(c, k, t);
    if (pass == 2 && (info = sb_circ_gen_values(c, k, t)) != SB_CIRC_GEN_SCALED) {
        c->bid[k] = 1;
        return info;
    }
    double *cv = c->Cv + (size_t)t * R2;
    memcpy(cv, c->C + k * R2, R2 * sizeof *c->C);
    int vec = pass == 1, keep = was && vec; /* keep: the values stay those the selection used */
    double *sv = keep ? c->tri + k * SB_CIRC_TRI * R : c->sv + k * R; /* the tridiagonal is of no more use */
    return LAPACKE_dgesdd_work(LAPACK_COL_MAJOR, vec ? 'S' : 'N', n, n, cv, n, sv, vec ? c->A + k * R2 : NULL, n,
                               vec ? c->VT + k * R2 : NULL, n, work, c->lwork, iw);
}

static void *blk_svd(void *arg) {
    blk_job_t *j = arg;
    sb_circ_t *c = j->c;
    size_t R = c->R, R2 = R * R;
    lapack_int *iw = c->iwork + (size_t)j->t * SB_CIRC_IW * R;
    double *work = c->work + (size_t)j->t * (size_t)c->lwork;
    if (j->pass == 0) { /* the transform and each block's squared Frobenius norm */
        if (j->k1 > j->k0 && !c->fft)
            cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, (int)R2, (int)(j->k1 - j->k0), (int)R, 1.0, c->Kd,
                        (int)R2, c->T + j->k0 * R, (int)R, 0.0, c->C + j->k0 * R2, (int)R2);
        for (size_t k = j->k0; k < j->k1; k++) {
            double f = 0;
            for (size_t i = 0; i < R2; i++)
                f += c->C[k * R2 + i] * c->C[k * R2 + i];
            c->fro[k] = f;
        }
        return NULL;
    }
    for (size_t p = j->k0; p < j->k1 && j->info == 0; p++) {
        size_t k = j->pass == 2 ? c->list[p] : p; /* pass 2: positions in the batch's list */
        if (j->pass == 1 && !c->need[k]) continue;
        j->bad = k;
        j->info = blk_one(c, k, j->t, j->pass, iw, work);
    }
    return NULL;
}

static sb_result_t blocks_run(sb_circ_t *c, int pass) {
    blk_job_t jobs[SB_THREADS_MAX];
    for (int t = 0; t < c->nth; t++) {
        jobs[t] = (blk_job_t){c, t, pass, 0, 0, 0, 0};
        sb_part(pass == 2 ? c->nlist : c->nb, t, c->nth, &jobs[t].k0, &jobs[t].k1);
    }
    sb_parallel_run(blk_svd, jobs, sizeof *jobs, c->nth, NULL, NULL);
    for (int t = 0; t < c->nth; t++)
        if (jobs[t].info != 0)
            return sb_error(c->ctx, SB_ERR_NUMERIC, "circulant: dgesdd failed on block %zu (info %d)", jobs[t].bad,
                            (int)jobs[t].info);
    return SB_OK;
}

static sb_result_t circ_svd(sb_circ_t *c, const double *a, size_t ld, const double *w, size_t J, double scale,
                            double *s, double *u, double *v, double *tails);

/* The blocks are small (R x R): OpenBLAS's threads cost more than they
 * save there (measured at R = 64: 6.5 ms a channel with one thread, 15-30
 * with two), so the block SVDs run with one BLAS thread and the setting is
 * restored afterwards (sb_blas_threads_begin). */
sb_result_t sb_circ_svd(sb_circ_t *c, const double *a, size_t ld, const double *w, size_t J, double scale, double *s,
                        double *u, double *v, double *tails) {
    int nt = sb_blas_threads_begin();
    sb_result_t r = circ_svd(c, a, ld, w, J, scale, s, u, v, tails);
    sb_blas_threads_end(nt);
    return r;
}

double sb_circ_last_norm2(const sb_circ_t *c, const double *a) { return c->n2_a == a ? c->n2 : -1; }

/* Norms with their blocks, to sort. */
typedef struct fro_k {
    double f;
    size_t k;
} fro_k_t;

static int fro_cmp(const void *a, const void *b) {
    const fro_k_t *x = a, *y = b;
    if (x->f != y->f) return x->f > y->f ? -1 : 1;
    return x->k < y->k ? -1 : x->k > y->k;
}

/* The candidates (every singular value of the computed blocks, each pair
 * member once) into c->cand, largest first; their count. */
static size_t gather(sb_circ_t *c) {
    size_t R = c->R, nc = 0;
    for (unsigned k = 0; k < c->nb; k++)
        for (unsigned i = 0; i < R && c->done[k]; i++)
            for (unsigned mb = 0; mb < (sb_circ_single(c, k) ? 1u : 2u); mb++)
                c->cand[nc++] = (cand_t){c->sv[k * R + i], k, i, mb};
    qsort(c->cand, nc, sizeof *c->cand, cand_cmp);
    return nc;
}

/* Compute the blocks' singular values, in decreasing norm, a batch of up
 * to two blocks a thread at a time, until the next block cannot hold one
 * of the J largest (c->done marks the computed blocks); c->cand and *nc as
 * gather.  Every block of a batch after the first has its norm at least
 * the J-th largest value known: a whole batch of 2 nth blocks went past
 * that bound (io -r 64 -J 8 on two threads: 8 blocks of the f form
 * decomposed where 5 hold the triplets). */
static sb_result_t select_blocks(sb_circ_t *c, size_t J, size_t *nc) {
    size_t nb = c->nb, next = 0, R = c->R;
    fro_k_t *o = malloc(nb * sizeof *o);
    if (!o) return sb_error(c->ctx, SB_ERR_NOMEM, "circulant: out of memory");
    for (size_t k = 0; k < nb; k++)
        o[k] = (fro_k_t){c->fro[k], k};
    qsort(o, nb, sizeof *o, fro_cmp);
    memset(c->done, 0, nb);
    size_t have = 0;
    double sJ = -1;
    sb_result_t r = SB_OK;
    while (next < nb && r == SB_OK) {
        c->nlist = 0;
        for (size_t b = 0; b < 2 * (size_t)c->nth && next < nb && !(sJ >= 0 && sqrt(o[next].f) < sJ); b++) {
            size_t k = o[next++].k;
            c->list[c->nlist++] = k;
            c->done[k] = 1;
            have += (sb_circ_single(c, k) ? 1 : 2) * R;
        }
        if (c->nlist == 0) break;
        r = blocks_run(c, 2);
        if (r == SB_OK && have >= J) {
            *nc = gather(c);
            sJ = c->cand[J - 1].s;
        }
    }
    free(o);
    if (r == SB_OK) *nc = gather(c);
    return r;
}

/* The symmetrised, weighted kernel (K_m + K_{R-m}) / 2 into c->Kd: the
 * stored values themselves where they are it to the bit (no weights,
 * K's layout: ld = R, a structured matrix; plane m equal to plane R - m
 * bit for bit, as an even source's table is, SB_SOURCE_EVEN; no |x| above
 * DBL_MAX / 2, so 0.5 (x + x) is x), else c->K filled (made on the first
 * such call, kept for the next).  Read in place: an R^3 copy (2 MiB at
 * R = 64) neither made nor written, and the same bits downstream. */
static sb_result_t kernel_fill(sb_circ_t *c, const double *a, size_t ld, const double *w) {
    size_t R = c->R, R2 = R * R;
    int same = !w && ld == R;
    for (size_t m = 1; same && 2 * m < R; m++)
        same = memcmp(a + m * R2, a + (R - m) * R2, R2 * sizeof *a) == 0;
    double mx = 0; /* a NaN: passed over or taken (then K is filled), a NaN in K either way */
    size_t i = 0, n = same ? R2 * R : 0;
#if defined(__SSE2__)
    __m128d vm = _mm_setzero_pd(), sign = _mm_set1_pd(-0.0);
    for (; i + 2 <= n; i += 2)
        vm = _mm_max_pd(vm, _mm_andnot_pd(sign, _mm_loadu_pd(a + i)));
    double t[2];
    _mm_storeu_pd(t, vm);
    mx = t[0] > t[1] || t[1] != t[1] ? t[0] : t[1];
#endif
    for (; i < n; i++) {
        double x = fabs(a[i]);
        mx = x > mx || x != x ? x : mx;
    }
    if (same && mx <= DBL_MAX / 2) {
        c->Kd = a;
        c->even = 1;
        return SB_OK;
    }
    if (!c->K && !(c->K = sb_alloc_large(c->ctx, R2 * R, sizeof(double), "circulant kernel"))) return SB_ERR_NOMEM;
    for (size_t m = 0; m < R; m++)
        for (size_t ot = 0; ot < R; ot++)
            for (size_t it = 0; it < R; it++) {
                double wt = w ? w[it] * w[ot] : 1;
                c->K[m * R2 + it + ot * R] =
                    0.5 * wt * (kernel_at(a, ld, R, m, it, ot) + kernel_at(a, ld, R, (R - m) % R, it, ot));
            }
    c->Kd = c->K;
    /* even to the bit: every row (m, ot) the same bits as its mirror (R - m, ot) */
    c->even = 1;
    for (size_t m = 1; c->even && 2 * m < R; m++)
        for (size_t ot = 0; c->even && ot < R; ot++)
            c->even = memcmp(&a[(m * R + ot) * ld], &a[((R - m) * R + ot) * ld], R * sizeof *a) == 0;
    return SB_OK;
}

static sb_result_t circ_svd(sb_circ_t *c, const double *a, size_t ld, const double *w, size_t J, double scale,
                            double *s, double *u, double *v, double *tails) {
    size_t R = c->R, R2 = R * R, N = R2;
    /* Step: symmetrised, weighted kernel (K_m + K_{R-m}) / 2 */
    sb_result_t res = kernel_fill(c, a, ld, w);
    if (res != SB_OK) return res;
    c->ksym = sb_circ_kernel_symmetric(c->Kd, R);
    /* Step: cosine transform over m, C_k = sum_m K_m cos(2 pi k m / R), and
     * each block's squared Frobenius norm, blocks split among threads */
    c->fft = sb_rdft_cols(R, c->nb, R2, c->Kd, R2, c->C, R2, NULL, 0, c->nth); /* R a power of two */
    res = blocks_run(c, 0);
    if (res != SB_OK) return res;
    double n2 = 0; /* Parseval: ||W A W||_F^2 = sum_k (1 or 2) ||C_k||_F^2 */
    for (size_t k = 0; k < c->nb; k++)
        n2 += (sb_circ_single(c, k) ? 1.0 : 2.0) * c->fro[k];
    c->n2 = c->even && isfinite(n2) ? n2 * scale * scale : -1;
    c->n2_a = a;
    /* Step: the singular values (no vectors: the cheap part) of the blocks
     * in decreasing norm, a batch at a time, until the next block's norm,
     * a bound on its largest value, is below the J-th largest value known:
     * no block after it holds a selected triplet.  Their squared values
     * enter the tails as their squared norms (the same sum, all terms
     * positive). */
    size_t nc = 0;
    if ((res = select_blocks(c, J, &nc)) != SB_OK) return res;
    double skipped = 0;
    for (size_t k = 0; k < c->nb; k++)
        if (!c->done[k]) skipped += (sb_circ_single(c, k) ? 1.0 : 2.0) * c->fro[k];
    /* Step: tails, summed from the smallest value up */
    double t = skipped * scale * scale;
    for (size_t r = nc; r-- > 1;) {
        double x = c->cand[r].s * scale;
        t += x * x;
        if (r - 1 < J) tails[r - 1] = t;
    }
    if (J >= nc) tails[nc - 1] = skipped * scale * scale; /* 0 unless blocks were skipped */
    /* Step: vectors of the blocks that hold a selected triplet; their
     * values replace the first pass's (equal to rounding, same order) */
    memset(c->need, 0, c->nb);
    c->nsym = 0;
    for (size_t k = 0; k < c->nb; k++) {
        c->nvec[k] = 0;
        c->nsym += c->done[k] && c->sym[k];
    }
    for (size_t j = 0; j < J; j++) {
        const cand_t *q = &c->cand[j];
        c->need[q->k] = 1;
        c->nvec[q->k] = q->idx + 1 > c->nvec[q->k] ? q->idx + 1 : c->nvec[q->k];
    }
    if ((res = blocks_run(c, 1)) != SB_OK) return res;
    for (size_t j = 0; j < J; j++)
        c->cand[j].s = c->sv[c->cand[j].k * R + c->cand[j].idx];
    /* Step: the J leading triplets, u = e_k (x) a, v = e_k (x) b */
    for (size_t j = 0; j < J; j++) {
        const cand_t *q = &c->cand[j];
        const double *A = c->A + (size_t)q->k * R2 + (size_t)q->idx * R, *VT = c->VT + (size_t)q->k * R2;
        s[j] = q->s;
        for (size_t ip = 0; ip < R; ip++) {
            double e = phi_vec(c, q->k, q->member, ip);
            for (size_t it = 0; it < R; it++) {
                u[j * N + ip * R + it] = e * A[it];
                v[j * N + ip * R + it] = e * VT[q->idx + it * R];
            }
        }
    }
    return SB_OK;
}
