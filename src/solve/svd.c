/* Truncated SVD: plan (shapes, method, random test matrix, workspaces) then
 * execute.  The maths of the three methods is in svd_impl.h, written once
 * and included for double and for float; this file holds the plan, the
 * dispatch, the generator and the adaptive rank choice.  See svd.h for the
 * guarantees of each method and the AUTO rule. */
#include "sepbrdf/svd.h"

#include <cblas.h>
#include <float.h>
#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "util/internal.h"

static const char *const method_names[SB_METHOD_COUNT_] = {"auto", "full", "topk", "randomized"};

sb_result_t sb_method_parse(const char *name, sb_method_t *out) {
    if (!out) return SB_ERR_ARG;
    for (int k = 0; k < SB_METHOD_COUNT_; k++)
        if (name && strcmp(name, method_names[k]) == 0) {
            *out = (sb_method_t)k;
            return SB_OK;
        }
    return SB_ERR_UNKNOWN;
}
const char *sb_method_name(sb_method_t m) { return (unsigned)m < SB_METHOD_COUNT_ ? method_names[m] : "?"; }

#define SB_SVD_DEFAULT_P 10
#define SB_SVD_DEFAULT_Q 2
#define SB_SVD_DEFAULT_BLOCK 32

struct sb_svd {
    sb_context_t *ctx;
    size_t m, n, k, d; /* d = min(m, n) */
    size_t l, b, L;    /* randomized: test vectors k + p (<= d), adaptive block, basis columns */
    int p, q, single, tr, krylov;
    uint64_t seed;
    sb_method_t method;
    /* Workspace, typed double or float by `single` (see svd_impl.h for
     * what each holds per method); NULL when the method does not use it. */
    void *a, *sv, *u, *vt, *g, *w, *z, *y, *bt, *ws, *om, *c, *tau, *work;
    lapack_int *iwork, *isuppz;
    lapack_int lwork, liwork;
    size_t bytes;
    int failed;
    sb_svd_info_t info;
};

/* count1 * count2 elements of `size` bytes, overflow-checked; counted in
 * s->bytes.  NULL (reported) on failure. */
static void *ws_alloc(sb_svd_t *s, size_t count1, size_t count2, size_t size) {
    size_t count;
    if (sb_size_mul(count1, count2, &count)) {
        sb_error(s->ctx, SB_ERR_OVERFLOW, "svd: workspace size %zu x %zu overflows", count1, count2);
        s->failed = SB_ERR_OVERFLOW;
        return NULL;
    }
    void *p = sb_alloc(s->ctx, count, size, "svd workspace");
    if (!p) {
        s->failed = count > sb_memory_limit() / size ? SB_ERR_OVERFLOW : SB_ERR_NOMEM;
        return NULL;
    }
    s->bytes += count * size;
    return p;
}

/* ---- Gaussian test matrix ---------------------------------------------- */
/* xoshiro256** (Blackman & Vigna 2018) seeded by splitmix64; normal pairs by
 * Box-Muller.  Written out here so the bits do not depend on the C library. */

static uint64_t splitmix64(uint64_t *x) {
    uint64_t z = (*x += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}
static void rng_seed(uint64_t st[4], uint64_t seed) {
    for (int i = 0; i < 4; i++)
        st[i] = splitmix64(&seed);
}
static uint64_t rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
static uint64_t rng_next(uint64_t st[4]) {
    uint64_t r = rotl(st[1] * 5, 7) * 9, t = st[1] << 17;
    st[2] ^= st[0];
    st[3] ^= st[1];
    st[1] ^= st[2];
    st[0] ^= st[3];
    st[2] ^= t;
    st[3] = rotl(st[3], 45);
    return r;
}
/* Two independent N(0, 1) numbers; u1 in (0, 1] so the log is finite. */
static void rng_gauss2(uint64_t st[4], double g[2]) {
    double u1 = ((double)(rng_next(st) >> 11) + 1) * 0x1.0p-53, u2 = (double)(rng_next(st) >> 11) * 0x1.0p-53;
    double r = sqrt(-2 * log(u1)), t = 2 * SB_PI * u2;
    g[0] = r * cos(t);
    g[1] = r * sin(t);
}

/* ---- the two precisions ------------------------------------------------- */

#define R double
#define SFX d
#define GEMM cblas_dgemm
#define SYRK cblas_dsyrk
#define GESDD LAPACKE_dgesdd_work
#define SYEVR LAPACKE_dsyevr_work
#define GEQRF LAPACKE_dgeqrf_work
#define ORGQR LAPACKE_dorgqr_work
#include "solve/svd_impl.h"
#undef R
#undef SFX
#undef GEMM
#undef SYRK
#undef GESDD
#undef SYEVR
#undef GEQRF
#undef ORGQR

#define R float
#define SFX f
#define GEMM cblas_sgemm
#define SYRK cblas_ssyrk
#define GESDD LAPACKE_sgesdd_work
#define SYEVR LAPACKE_ssyevr_work
#define GEQRF LAPACKE_sgeqrf_work
#define ORGQR LAPACKE_sorgqr_work
#include "solve/svd_impl.h"
#undef R
#undef SFX
#undef GEMM
#undef SYRK
#undef GESDD
#undef SYEVR
#undef GEQRF
#undef ORGQR

/* ---- plan --------------------------------------------------------------- */

/* The AUTO rule (measurements in docs/performance.md). */
static sb_method_t auto_method(size_t d, size_t k, size_t p) {
    if (d <= SB_SVD_AUTO_FULL_MAX) return SB_METHOD_FULL;
    if (d <= SB_SVD_AUTO_TOPK_MAX || (k + p) * SB_SVD_AUTO_SKETCH_DIV > d) return SB_METHOD_TOPK;
    return SB_METHOD_RANDOMIZED;
}

static int resolve_p(int oversample) { return oversample > 0 ? oversample : oversample < 0 ? 0 : SB_SVD_DEFAULT_P; }

sb_method_t sb_svd_auto_method(size_t m, size_t n, size_t k, const sb_svd_opts_t *opts) {
    if (opts && (unsigned)opts->method >= SB_METHOD_COUNT_) return SB_METHOD_COUNT_;
    if (opts && opts->method != SB_METHOD_AUTO) return opts->method;
    return auto_method(m < n ? m : n, k, (size_t)resolve_p(opts ? opts->oversample : 0));
}

sb_result_t sb_svd_create(sb_context_t *ctx, size_t m, size_t n, size_t k, const sb_svd_opts_t *opts, sb_svd_t **out) {
    if (!out) return sb_error(ctx, SB_ERR_ARG, "svd: no output pointer");
    *out = NULL;
    if (m == 0 || n == 0) return sb_error(ctx, SB_ERR_ARG, "svd: empty matrix %zu x %zu", m, n);
    size_t d = m < n ? m : n;
    if (k == 0 || k > d) return sb_error(ctx, SB_ERR_RANGE, "svd: %zu terms asked, need 1..%zu", k, d);
    if (m > (size_t)INT32_MAX || n > (size_t)INT32_MAX)
        return sb_error(ctx, SB_ERR_OVERFLOW, "svd: dimension %zu x %zu too large for LAPACK", m, n);
    sb_svd_opts_t o = {0};
    if (opts) o = *opts;
    if ((unsigned)o.method >= SB_METHOD_COUNT_)
        return sb_error(ctx, SB_ERR_ARG, "svd: unknown method %d", (int)o.method);
    if (o.power_iters > SB_SVD_MAX_POWER_ITERS)
        return sb_error(ctx, SB_ERR_RANGE, "svd: %d power iterations, at most %d", o.power_iters,
                        SB_SVD_MAX_POWER_ITERS);
    sb_result_t rb = sb_blas_reserve(ctx);
    if (rb != SB_OK) return rb;
    sb_svd_t *s = calloc(1, sizeof *s);
    if (!s) return sb_error(ctx, SB_ERR_NOMEM, "svd: out of memory");
    s->ctx = ctx;
    s->m = m;
    s->n = n;
    s->k = k;
    s->d = d;
    s->p = resolve_p(o.oversample);
    s->q = o.power_iters > 0 ? o.power_iters : o.power_iters < 0 ? 0 : SB_SVD_DEFAULT_Q;
    s->seed = o.seed ? o.seed : 1;
    s->single = o.single_precision != 0;
    s->tr = m < n;
    s->method = o.method == SB_METHOD_AUTO ? auto_method(d, k, (size_t)s->p) : o.method;
    s->l = k + (size_t)s->p > d ? d : k + (size_t)s->p;
    s->b = o.block ? o.block : SB_SVD_DEFAULT_BLOCK;
    if (s->b > s->l) s->b = s->l;
    /* block Krylov keeps q + 1 blocks of the basis: l (q + 1) <= d / 2 */
    s->krylov = o.krylov >= 0 && s->q > 0 && 2 * s->l * (size_t)(s->q + 1) <= d;
    s->L = s->krylov ? s->l * (size_t)(s->q + 1) : s->l;

    sb_result_t r = SB_OK;
    if (s->single && s->method != SB_METHOD_FULL && !(s->a = ws_alloc(s, m, n, sizeof(float)))) r = SB_ERR_NOMEM;
    if (r == SB_OK) switch (s->method) {
        case SB_METHOD_FULL:
            r = s->single ? plan_full_f(s) : plan_full_d(s);
            break;
        case SB_METHOD_TOPK:
            r = s->single ? plan_topk_f(s) : plan_topk_d(s);
            break;
        default:
            r = s->single ? plan_rand_f(s) : plan_rand_d(s);
            break;
        }
    if (r == SB_OK &&
        !(s->work = ws_alloc(s, (size_t)(s->lwork > 0 ? s->lwork : 1), 1, s->single ? sizeof(float) : sizeof(double))))
        r = SB_ERR_NOMEM;
    if (r != SB_OK) {
        if (s->failed) r = (sb_result_t)s->failed;
        sb_svd_destroy(s);
        return r;
    }
    *out = s;
    return SB_OK;
}

void sb_svd_destroy(sb_svd_t *s) {
    if (!s) return;
    void *bufs[] = {s->a, s->sv, s->u, s->vt, s->g, s->w, s->z, s->y, s->bt, s->ws, s->om, s->c, s->tau, s->work};
    for (size_t i = 0; i < sizeof bufs / sizeof bufs[0]; i++)
        free(bufs[i]);
    free(s->iwork);
    free(s->isuppz);
    free(s);
}

sb_method_t sb_svd_method(const sb_svd_t *s) { return s ? s->method : SB_METHOD_COUNT_; }
size_t sb_svd_rank(const sb_svd_t *s) { return s ? s->k : 0; }
size_t sb_svd_workspace_bytes(const sb_svd_t *s) { return s ? s->bytes : 0; }
sb_svd_info_t sb_svd_last_info(const sb_svd_t *s) {
    sb_svd_info_t none = {0, 0, 0, 0};
    return s ? s->info : none;
}

/* ---- execute ------------------------------------------------------------ */

/* Sum of squares of one column, eight partial sums (which the compiler
 * vectorises); when f is not NULL the column is also converted to float
 * there and the squares are those of the float values, so an entry beyond
 * the float range shows as inf. */
static double col_sumsq(const double *a, size_t m, float *f) {
    double s8[8] = {0};
    size_t i = 0;
    if (f)
        for (; i + 8 <= m; i += 8)
            for (int t = 0; t < 8; t++) {
                f[i + t] = (float)a[i + t];
                s8[t] += (double)f[i + t] * (double)f[i + t];
            }
    else
        for (; i + 8 <= m; i += 8)
            for (int t = 0; t < 8; t++)
                s8[t] += a[i + t] * a[i + t];
    for (; i < m; i++) {
        double x = a[i];
        if (f) x = f[i] = (float)a[i];
        s8[0] += x * x;
    }
    return ((s8[0] + s8[1]) + (s8[2] + s8[3])) + ((s8[4] + s8[5]) + (s8[6] + s8[7]));
}

/* *nrm = ||A||_F from the plain sum of squares t when it is finite.
 * Otherwise look closer: an entry that is not finite (or beyond the float
 * range in single precision) is an error (1); finite entries whose squares
 * overflow get the scaled norm of LAPACK's dlange. */
static int finish_norm(const sb_svd_t *s, const double *A, size_t lda, double t, double *nrm) {
    *nrm = sqrt(t);
    if (isfinite(t)) return 0;
    for (size_t j = 0; j < s->n; j++)
        for (size_t i = 0; i < s->m; i++) {
            double x = A[i + j * lda];
            if (!isfinite(x) || (s->single && fabs(x) > FLT_MAX)) return 1;
        }
    *nrm = LAPACKE_dlange_work(LAPACK_COL_MAJOR, 'F', (lapack_int)s->m, (lapack_int)s->n, A, (lapack_int)lda, NULL);
    return 0;
}

/* ||A||_F read from A; 1 if an entry is not finite. */
static int norm_of(const sb_svd_t *s, const double *A, size_t lda, double *nrm) {
    double t = 0;
    for (size_t j = 0; j < s->n; j++)
        t += col_sumsq(A + j * lda, s->m, NULL);
    return finish_norm(s, A, lda, t, nrm);
}

/* Copy A into the plan's buffer (double or float, ld m) with ||A||_F;
 * 1 if an entry is not finite or does not fit the precision. */
static int copy_in(sb_svd_t *s, const double *A, size_t lda, double *nrm) {
    size_t m = s->m, n = s->n;
    double t = 0;
    for (size_t j = 0; j < n; j++) {
        const double *a = A + j * lda;
        if (s->single) {
            t += col_sumsq(a, m, (float *)s->a + j * m);
        } else {
            memcpy((double *)s->a + j * m, a, m * sizeof(double));
            t += col_sumsq(a, m, NULL);
        }
    }
    return finish_norm(s, A, lda, t, nrm);
}

static double sv_at(const sb_svd_t *s, size_t j) {
    return s->single ? (double)((const float *)s->sv)[j] : ((const double *)s->sv)[j];
}

/* The errors below are kept relative to ||A|| (s_j / ||A|| squared) so that
 * neither a huge nor a tiny matrix overflows; nrm = 0 is the zero matrix,
 * whose every truncation is exact. */

/* ||A - U_r S_r V_r^T||_F = ||A|| (1 - sum_{j<r} (s_j / ||A||)^2)^(1/2). */
static double resid_from(double nrm, const double *sv, size_t r) {
    if (!(nrm > 0)) return 0;
    double c = 0, inv = 1 / nrm;
    for (size_t j = 0; j < r; j++)
        c += (sv[j] * inv) * (sv[j] * inv);
    return c < 1 ? nrm * sqrt(1 - c) : 0;
}

/* Smallest r in [max(lo, 1), k] with 1 - sum_{j<r} (s_j / ||A||)^2 <= tol^2. */
static size_t rank_for(const double *sv, size_t k, double nrm, double tol2, size_t lo) {
    double c = 0, inv = nrm > 0 ? 1 / nrm : 0;
    if (lo < 1) lo = 1;
    for (size_t j = 0; j < k; j++) {
        c += (sv[j] * inv) * (sv[j] * inv);
        if (j + 1 >= lo && (!(nrm > 0) || 1 - c <= tol2)) return j + 1;
    }
    return k;
}

static sb_result_t execute(sb_svd_t *s, const double *A, size_t lda, int adaptive, int want_norm, double tol,
                           double norm_fro, size_t min_rank, double *sv, double *U, double *V, double *all_s,
                           int *have_all) {
    if (!A || !sv || lda < s->m)
        return sb_error(s->ctx, SB_ERR_ARG, "svd: missing matrix or output, or lda %zu < %zu rows", lda, s->m);
    size_t span;
    if (lda > (size_t)INT32_MAX || sb_size_mul(lda, s->n - 1, &span) || sb_size_add(span, s->m, &span))
        return sb_error(s->ctx, SB_ERR_OVERFLOW, "svd: leading dimension %zu too large", lda);
    size_t k = s->k, r = k, sketch = 0;
    double nrm = norm_fro > 0 ? norm_fro : -1, got = 0, tol2 = tol * tol;
    sb_svd_info_t info = {0, 0, 0, -1};
    sb_result_t res = SB_OK;
    if (have_all) *have_all = 0;

    /* single precision (every method) and FULL take a copy of A */
    const void *a = A;
    size_t la = lda;
    if (s->single || s->method == SB_METHOD_FULL) {
        if (copy_in(s, A, lda, &got))
            return sb_error(s->ctx, SB_ERR_NUMERIC, "svd: matrix has non-finite entries%s",
                            s->single ? " or overflows single precision" : "");
        if (nrm < 0) nrm = got;
        a = s->a;
        la = s->m;
    } else if (want_norm && nrm < 0 && s->method == SB_METHOD_RANDOMIZED) {
        if (norm_of(s, A, lda, &got)) return sb_error(s->ctx, SB_ERR_NUMERIC, "svd: matrix has non-finite entries");
        nrm = got;
    }

    switch (s->method) {
    case SB_METHOD_FULL: {
        res = s->single ? run_full_f(s) : run_full_d(s);
        if (res != SB_OK) break;
        size_t d = s->d;
        if (all_s) {
            for (size_t j = 0; j < d; j++)
                all_s[j] = sv_at(s, j);
            if (have_all) *have_all = 1;
        }
        /* t = sum_{i>=j} (s_i / ||A||)^2, the relative error^2 of keeping
         * j terms, summed from the end so that small errors are not
         * differences */
        double t = 0, inv = nrm > 0 ? 1 / nrm : 0;
        size_t lo = min_rank > 0 ? min_rank : 1;
        for (size_t j = d; j-- > 0;) {
            double x = sv_at(s, j) * inv;
            t += x * x;
            if (adaptive && j >= lo && j <= k && t <= tol2) r = j;
        }
        t = 0;
        for (size_t j = d; j-- > r;)
            t += (sv_at(s, j) * inv) * (sv_at(s, j) * inv);
        if (s->single)
            out_full_f(s, r, sv, U, V);
        else
            out_full_d(s, r, sv, U, V);
        info.norm_fro = nrm;
        info.resid_fro = nrm > 0 ? nrm * sqrt(t) : 0;
        sketch = d;
        break;
    }
    case SB_METHOD_TOPK: {
        double tr;
        res = s->single ? run_topk_f(s, a, la, &tr) : run_topk_d(s, a, la, &tr);
        if (res != SB_OK) break;
        if (nrm < 0) nrm = sqrt(tr);
        if (s->single)
            out_topk_f(s, k, sv, U, V);
        else
            out_topk_d(s, k, sv, U, V);
        if (adaptive) r = rank_for(sv, k, nrm, tol2, min_rank);
        info.norm_fro = nrm;
        info.resid_fro = resid_from(nrm, sv, r);
        sketch = k;
        break;
    }
    default: {
        res = s->single ? run_rand_f(s, a, la, adaptive, tol2, nrm, min_rank, &sketch, &r)
                        : run_rand_d(s, a, la, adaptive, tol2, nrm, min_rank, &sketch, &r);
        if (res != SB_OK) break;
        if (s->single)
            out_rand_f(s, r, sv, U, V);
        else
            out_rand_d(s, r, sv, U, V);
        if (nrm >= 0) {
            info.norm_fro = nrm;
            info.resid_fro = resid_from(nrm, sv, r);
        }
        break;
    }
    }
    if (res != SB_OK) return res;
    for (size_t j = 0; j < r; j++)
        if (!isfinite(sv[j])) return sb_error(s->ctx, SB_ERR_NUMERIC, "svd: non-finite singular value (bad input?)");
    info.rank = r;
    info.sketch = sketch;
    s->info = info;
    return SB_OK;
}

sb_result_t sb_svd_execute(sb_svd_t *s, const double *A, size_t lda, double *sv, double *U, double *V, double *all_s,
                           int *have_all) {
    if (!s) return sb_error(NULL, SB_ERR_ARG, "svd: no plan");
    return execute(s, A, lda, 0, 0, 0, 0, s->k, sv, U, V, all_s, have_all);
}

sb_result_t sb_svd_execute_adaptive(sb_svd_t *s, const double *A, size_t lda, double rel_tol, double norm_fro,
                                    size_t min_rank, double *sv, double *U, double *V, sb_svd_info_t *info) {
    if (!s) return sb_error(NULL, SB_ERR_ARG, "svd: no plan");
    if (!(rel_tol >= 0 && rel_tol < 1) || min_rank > s->k || !(norm_fro >= 0) || !isfinite(norm_fro))
        return sb_error(s->ctx, SB_ERR_RANGE,
                        "svd: tolerance %g (need [0, 1)), norm %g or minimum rank %zu (need <= %zu)", rel_tol, norm_fro,
                        min_rank, s->k);
    /* rel_tol = 0 asks for no truncation: a plain execute (with the norm) */
    sb_result_t r = execute(s, A, lda, rel_tol > 0, 1, rel_tol, norm_fro, min_rank, sv, U, V, NULL, NULL);
    if (r == SB_OK && info) *info = s->info;
    return r;
}
