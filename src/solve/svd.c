/* Truncated SVD: plan (shapes, method, workspaces) then execute.  This
 * file holds the plan, the dispatch, the norms and the adaptive rank
 * choice; the methods are in svd_dense.c (FULL, TOPK) and svd_rand.c
 * (RANDOMIZED), their maths in the precision templates svd_tmpl_*.h,
 * written once for double and float.  See svd.h for the guarantees of
 * each method and the AUTO rule. */
#include "sepbrdf/svd.h"

#include <cblas.h>
#include <float.h>
#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "solve/solver.h"
#include "solve/svd_internal.h"
#include "util/internal.h"

#define SB_SVD_DEFAULT_P 10
#define SB_SVD_DEFAULT_Q 2
#define SB_SVD_DEFAULT_BLOCK 32

/* ---- plan --------------------------------------------------------------- */

/* The AUTO rule (measurements in docs/performance.md). */
static sb_method_t auto_method(size_t d, size_t k, size_t p) {
    if (d <= SB_SVD_AUTO_FULL_MAX) return SB_METHOD_FULL;
    if (d <= SB_SVD_AUTO_TOPK_MAX || (k + p) * SB_SVD_AUTO_SKETCH_DIV > d) return SB_METHOD_TOPK;
    return SB_METHOD_RANDOMIZED;
}

static int resolve_p(int oversample) { return oversample > 0 ? oversample : oversample < 0 ? 0 : SB_SVD_DEFAULT_P; }

sb_method_t sb_svd_auto_method(size_t m, size_t n, size_t k, const sb_svd_opts_t *opts) {
    if (opts && !sb_method_known(opts->method)) return SB_METHOD_NONE;
    if (opts && opts->method != SB_METHOD_AUTO) return opts->method;
    return auto_method(m < n ? m : n, k, (size_t)resolve_p(opts ? opts->oversample : 0));
}

static sb_result_t check_opts(sb_context_t *ctx, const sb_svd_opts_t *o) {
    if (o->method != SB_METHOD_AUTO && o->method != SB_METHOD_FULL && o->method != SB_METHOD_TOPK &&
        o->method != SB_METHOD_RANDOMIZED)
        return sb_error(ctx, SB_ERR_ARG, "svd: method %d is not an SVD method", (int)o->method);
    if (o->power_iters > SB_SVD_MAX_POWER_ITERS)
        return sb_error(ctx, SB_ERR_RANGE, "svd: %d power iterations, at most %d", o->power_iters,
                        SB_SVD_MAX_POWER_ITERS);
    return SB_OK;
}

static sb_result_t create(sb_context_t *ctx, size_t m, size_t n, size_t k, const sb_svd_opts_t *opts, int gram,
                          sb_svd_t **out);

/* RANDOMIZED is in mixed precision by default; where its float copy of A
 * does not fit (the memory limit), the plan is made in double instead. */
sb_result_t sb_svd_create(sb_context_t *ctx, size_t m, size_t n, size_t k, const sb_svd_opts_t *opts, sb_svd_t **out) {
    sb_result_t r = create(ctx, m, n, k, opts, 0, out);
    if ((r == SB_ERR_NOMEM || r == SB_ERR_OVERFLOW) && (!opts || (opts->mixed == 0 && !opts->single_precision)) &&
        sb_svd_auto_method(m, n, k, opts) == SB_METHOD_RANDOMIZED) {
        sb_svd_opts_t o = {0};
        if (opts) o = *opts;
        o.mixed = -1;
        r = create(ctx, m, n, k, &o, 0, out);
    }
    return r;
}

static sb_result_t create(sb_context_t *ctx, size_t m, size_t n, size_t k, const sb_svd_opts_t *opts, int gram,
                          sb_svd_t **out) {
    if (!out) return sb_error(ctx, SB_ERR_ARG, "svd: no output pointer");
    *out = NULL;
    if (m == 0 || n == 0) return sb_error(ctx, SB_ERR_ARG, "svd: empty matrix %zu x %zu", m, n);
    size_t d = m < n ? m : n;
    if (k == 0 || k > d) return sb_error(ctx, SB_ERR_RANGE, "svd: %zu terms asked, need 1..%zu", k, d);
    if (m > (size_t)INT32_MAX || n > (size_t)INT32_MAX)
        return sb_error(ctx, SB_ERR_OVERFLOW, "svd: dimension %zu x %zu too large for LAPACK", m, n);
    sb_svd_opts_t o = {0};
    if (opts) o = *opts;
    sb_result_t rb = check_opts(ctx, &o);
    if (rb == SB_OK) rb = sb_blas_reserve(ctx);
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
    s->mixed = !s->single && o.mixed >= 0;
    s->opts = o;
    s->tr = m < n;
    s->method = o.method == SB_METHOD_AUTO ? auto_method(d, k, (size_t)s->p) : o.method;
    s->l = k + (size_t)s->p > d ? d : k + (size_t)s->p;
    s->b = o.block ? o.block : SB_SVD_DEFAULT_BLOCK;
    if (s->b > s->l) s->b = s->l;
    /* block Krylov keeps q + 1 blocks of the basis: l (q + 1) <= d / 2 */
    s->krylov = o.krylov >= 0 && s->q > 0 && 2 * s->l * (size_t)(s->q + 1) <= d;
    if (s->method == SB_METHOD_TOPK) { /* Krylov cycles when the basis fits, else the Gram route */
        s->q = o.power_iters > 0 ? o.power_iters : SB_SVD_TOPK_Q;
        if (s->l < SB_SVD_TOPK_MIN_BLOCK) s->l = SB_SVD_TOPK_MIN_BLOCK < d ? SB_SVD_TOPK_MIN_BLOCK : d;
        while (s->q > 1 && 2 * s->l * (size_t)(s->q + 1) > d)
            s->q--;
        s->krylov = 2 * s->l * (size_t)(s->q + 1) <= d && !gram;
        s->gram = !s->krylov;
        /* a cycle that does not converge restarts with twice the block
         * (the leading Ritz vectors of the last one), up to twice the first,
         * where that basis fits too: the plan holds the largest block */
        s->l0 = s->l;
        size_t grown = 2 * s->l < d ? 2 * s->l : d;
        if (s->krylov && 2 * grown * (size_t)(s->q + 1) <= d) s->l = grown;
    }
    s->L = s->krylov ? s->l * (size_t)(s->q + 1) : s->l;
    if (s->method != SB_METHOD_RANDOMIZED) s->mixed = 0;
    if (s->mixed) s->single = 1; /* the sketch in float; sb_svd_mixed_finish in double */

    sb_result_t r = SB_OK;
    if (s->single && s->method != SB_METHOD_FULL && !(s->a = ws_alloc(s, m, n, sizeof(float)))) r = SB_ERR_NOMEM;
    if (r == SB_OK && s->mixed &&
        (!(s->mu = ws_alloc(s, m, k, sizeof(double))) || !(s->mv = ws_alloc(s, n, k, sizeof(double))) ||
         !(s->mz = ws_alloc(s, k + 1, k, sizeof(double)))))
        r = SB_ERR_NOMEM;
    if (r == SB_OK)
        r = s->method == SB_METHOD_RANDOMIZED         ? sb_svd_plan_rand(s)
            : s->method == SB_METHOD_TOPK && !s->gram ? sb_svd_plan_topk_krylov(s)
                                                      : sb_svd_plan_dense(s);
    /* TOPK by Krylov cycles: the Gram route as a plan of its own for
     * matrices whose cycles do not converge; where that does not fit the
     * memory limit, such a matrix gives SB_ERR_NUMERIC instead */
    if (r == SB_OK && s->method == SB_METHOD_TOPK && !s->gram) create(NULL, m, n, k, &o, 1, &s->gram_plan);
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
    void *bufs[] = {s->a,   s->sv, s->u,   s->vt,   s->g,  s->w,  s->z,   s->y,  s->bt, s->ws,
                    s->om,  s->c,  s->tau, s->work, s->st, s->eg, s->egc, s->ew, s->ex, s->er,
                    s->erx, s->ep, s->ewk, s->rs,   s->ur, s->mu, s->mv,  s->mz};
    sb_svd_destroy(s->gram_plan);
    sb_svd_destroy(s->dbl);
    for (size_t i = 0; i < sizeof bufs / sizeof bufs[0]; i++)
        free(bufs[i]);
    free(s->iwork);
    free(s->isuppz);
    free(s->eiw);
    free(s->eisuppz);
    free(s);
}

sb_method_t sb_svd_method(const sb_svd_t *s) { return s ? s->method : SB_METHOD_NONE; }
size_t sb_svd_rank(const sb_svd_t *s) { return s ? s->k : 0; }
size_t sb_svd_workspace_bytes(const sb_svd_t *s) { return s ? s->bytes : 0; }
sb_svd_info_t sb_svd_last_info(const sb_svd_t *s) {
    sb_svd_info_t none = {0, 0, 0, 0, 0, 0};
    return s ? s->info : none;
}

/* ---- execute ------------------------------------------------------------ */

/* Sum of squares of one column, eight partial sums (which the compiler
 * vectorises); when f is not NULL the column is also converted to float
 * there and the squares are those of the float values (exact: of the
 * double ones), so an entry beyond the float range shows as inf (or NaN). */
static double col_sumsq(const double *a, size_t m, float *f, int exact) {
    double s8[8] = {0};
    size_t i = 0;
    if (f && exact)
        for (; i + 8 <= m; i += 8)
            for (int t = 0; t < 8; t++) {
                f[i + t] = (float)a[i + t]; /* f - f: 0, or NaN where f overflowed */
                s8[t] += a[i + t] * a[i + t] + ((double)f[i + t] - (double)f[i + t]);
            }
    else if (f)
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
        if (f) f[i] = (float)a[i];
        if (f && !exact) x = f[i];
        if (f && exact) s8[1] += (double)f[i] - (double)f[i];
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
            if (!isfinite(x) || (s->single && !s->mixed && fabs(x) > FLT_MAX)) return 1;
        }
    *nrm = LAPACKE_dlange_work(LAPACK_COL_MAJOR, 'F', (lapack_int)s->m, (lapack_int)s->n, A, (lapack_int)lda, NULL);
    return 0;
}

/* ||A||_F read from A; 1 if an entry is not finite. */
static int norm_of(const sb_svd_t *s, const double *A, size_t lda, double *nrm) {
    double t = 0;
    for (size_t j = 0; j < s->n; j++)
        t += col_sumsq(A + j * lda, s->m, NULL, 1);
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
            t += col_sumsq(a, m, (float *)s->a + j * m, s->mixed);
        } else {
            memcpy((double *)s->a + j * m, a, m * sizeof(double));
            t += col_sumsq(a, m, NULL, 1);
        }
    }
    return finish_norm(s, A, lda, t, nrm);
}

/* Mixed precision's float copy of A with ||A||_F (of the double values).
 * At scale 1 where ||A||_F lies in [2^-60, 2^60]: every entry then fits a
 * float, and one lost below 2^-126 is below 2^-66 ||A||.  Otherwise (or
 * where an entry overflowed) A is copied again scaled by the power of two
 * that brings ||A||_F into [1/2, 1): the basis does not depend on the scale,
 * and mixed_finish (svd_rand.c) projects the caller's A.  1 if an entry is
 * not finite. */
static int copy_mixed(sb_svd_t *s, const double *A, size_t lda, double *nrm) {
    size_t m = s->m, n = s->n;
    float *f = s->a;
    double t = 0;
    for (size_t j = 0; j < n; j++)
        t += col_sumsq(A + j * lda, m, f + j * m, 1);
    *nrm = sqrt(t);
    if (isfinite(t) && *nrm >= 0x1.0p-60 && *nrm <= 0x1.0p60) return 0;
    if (!isfinite(t)) { /* an entry not finite (1), or squares that overflow */
        if (norm_of(s, A, lda, nrm)) return 1;
    } else { /* squares that underflow: the scaled sum */
        *nrm = LAPACKE_dlange_work(LAPACK_COL_MAJOR, 'F', (lapack_int)m, (lapack_int)n, A, (lapack_int)lda, NULL);
    }
    double sc = *nrm > 0 ? ldexp(1.0, -ilogb(*nrm) - 1) : 1;
    for (size_t j = 0; j < n; j++)
        for (size_t i = 0; i < m; i++)
            f[i + j * m] = (float)(A[i + j * lda] * sc);
    return 0;
}

static sb_result_t execute(sb_svd_t *s, sb_svd_run_t *run, int want_norm);

/* Mixed precision leaves a floor of float rounding, a few 2^-24 ||A||_F
 * (A in float is within 2^-24 ||A||_F of A), in the error.  Below
 * SB_SVD_MIXED_MIN_RESID ||A||_F (an A of rank about k, a tight adaptive
 * tolerance) that floor could show, so the execute is made again in double
 * (a plan of its own, made once; where it does not fit the memory limit the
 * mixed result stays). */
#define SB_SVD_MIXED_MIN_RESID 0x1.0p-10
static sb_result_t in_double(sb_svd_t *s, sb_svd_run_t *run, int want_norm) {
    if (!s->dbl) {
        sb_svd_opts_t o = s->opts;
        o.mixed = -1;
        if (create(NULL, s->m, s->n, s->k, &o, 0, &s->dbl) != SB_OK) return SB_OK;
    }
    s->dbl->ctx = s->ctx;
    sb_svd_run_t r = *run;
    r.a = run->a0;
    r.la = run->la0;
    sb_result_t res = execute(s->dbl, &r, want_norm);
    if (res == SB_OK) *run = r;
    return res;
}

/* Copy or read A as the method needs (single precision and FULL take a
 * copy, which also gives ||A||_F), run the method, check the values. */
static sb_result_t execute(sb_svd_t *s, sb_svd_run_t *run, int want_norm) {
    if (!run->a || !run->sv || run->la < s->m)
        return sb_error(s->ctx, SB_ERR_ARG, "svd: missing matrix or output, or lda %zu < %zu rows", run->la, s->m);
    size_t span;
    if (run->la > (size_t)INT32_MAX || sb_size_mul(run->la, s->n - 1, &span) || sb_size_add(span, s->m, &span))
        return sb_error(s->ctx, SB_ERR_OVERFLOW, "svd: leading dimension %zu too large", run->la);
    const double *A = run->a;
    double got = 0;
    if (run->have_all) *run->have_all = 0;
    run->a0 = A;
    run->la0 = run->la;
    if (s->single || s->method == SB_METHOD_FULL) {
        if (s->mixed ? copy_mixed(s, A, run->la, &got) : copy_in(s, A, run->la, &got))
            return sb_error(s->ctx, SB_ERR_NUMERIC, "svd: matrix has non-finite entries%s",
                            s->single && !s->mixed ? " or overflows single precision" : "");
        if (run->nrm < 0) run->nrm = got;
        run->a = s->a;
        run->la = s->m;
    } else if (run->nrm < 0 &&
               ((want_norm && s->method == SB_METHOD_RANDOMIZED) || (s->method == SB_METHOD_TOPK && !s->gram))) {
        if (norm_of(s, A, run->la, &got)) return sb_error(s->ctx, SB_ERR_NUMERIC, "svd: matrix has non-finite entries");
        run->nrm = got;
    }
    run->info = (sb_svd_info_t){0, 0, 0, -1, 0, 0};
    /* Krylov and randomized read A only through the thin products: the
     * rest (QR of thin blocks, Rayleigh-Ritz) on one BLAS thread */
    int thin = s->method == SB_METHOD_RANDOMIZED || (s->method == SB_METHOD_TOPK && !s->gram);
    /* TOPK by Krylov cycles, on a symmetric A (m = n): its products A B are
     * A^T B, which gemm_tn.c reads in place where the kernel runs, 1.6x
     * dgemm's rate at 18 columns; the check costs about two reads, the
     * cycles read A B 2q + 2 times (RANDOMIZED's 2 + q would not repay it) */
    s->sym = s->method == SB_METHOD_TOPK && !s->gram && s->m == s->n && sb_gemm_tn_usable((int)s->l) &&
             sb_svd_symmetric(run->a, s->m, run->la, s->single);
    int blas = thin ? sb_blas_thin_begin() : 1;
    sb_result_t res = s->method == SB_METHOD_FULL ? sb_svd_run_full(s, run)
                      : s->method == SB_METHOD_TOPK
                          ? (s->gram ? sb_svd_run_topk(s, run) : sb_svd_run_topk_krylov(s, run))
                          : sb_svd_run_rand(s, run);
    if (thin) sb_blas_thin_end(blas);
    if (res == SB_OK && s->mixed && run->nrm > 0 && !(run->info.resid_fro >= SB_SVD_MIXED_MIN_RESID * run->nrm))
        res = in_double(s, run, want_norm);
    if (res != SB_OK) return res;
    for (size_t j = 0; j < run->r; j++)
        if (!isfinite(run->sv[j]))
            return sb_error(s->ctx, SB_ERR_NUMERIC, "svd: non-finite singular value (bad input?)");
    run->info.rank = run->r;
    run->info.sketch = run->sketch;
    s->info = run->info;
    return SB_OK;
}

sb_result_t sb_svd_execute(sb_svd_t *s, const double *A, size_t lda, double *sv, double *U, double *V, double *all_s,
                           int *have_all) {
    if (!s) return sb_error(NULL, SB_ERR_ARG, "svd: no plan");
    sb_svd_run_t run = {A, lda, 0, 0, -1, s->k, sv, U, V, all_s, have_all, 0, 0, {0}, NULL, 0};
    return execute(s, &run, 0);
}

sb_result_t sb_svd_execute_adaptive(sb_svd_t *s, const double *A, size_t lda, double rel_tol, double norm_fro,
                                    size_t min_rank, double *sv, double *U, double *V, sb_svd_info_t *info) {
    if (!s) return sb_error(NULL, SB_ERR_ARG, "svd: no plan");
    if (!(rel_tol >= 0 && rel_tol < 1) || min_rank > s->k || !(norm_fro >= 0) || !isfinite(norm_fro))
        return sb_error(s->ctx, SB_ERR_RANGE,
                        "svd: tolerance %g (need [0, 1)), norm %g or minimum rank %zu (need <= %zu)", rel_tol, norm_fro,
                        min_rank, s->k);
    /* rel_tol = 0 asks for no truncation: a plain execute (with the norm) */
    sb_svd_run_t run = {A,
                        lda,
                        rel_tol > 0,
                        rel_tol * rel_tol,
                        norm_fro > 0 ? norm_fro : -1,
                        min_rank,
                        sv,
                        U,
                        V,
                        NULL,
                        NULL,
                        0,
                        0,
                        {0},
                        NULL,
                        0};
    sb_result_t r = execute(s, &run, 1);
    if (r == SB_OK && info) *info = s->info;
    return r;
}
