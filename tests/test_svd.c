/* Truncated SVD: every method against matrices of known spectrum
 * A = U diag(s) V^T (U, V orthonormal from the QR of Gaussian matrices), so
 * the Eckart-Young optimum sqrt(sum_{j>k} s_j^2) is known without another
 * SVD.  Bounds checked (d = min(m, n), eps = 2^-52):
 *   FULL        | err - opt | <= 64 d eps ||A||_F
 *   TOPK        the same plus 64 d eps sigma_1^2 / sigma_k (the Gram matrix)
 *   RANDOMIZED  err <= (1 + k / (p - 1))^(1/2) opt + 64 d eps ||A||_F
 * where err = ||A - U_k S_k V_k^T||_F is computed explicitly. */
#include <cblas.h>
#include <lapacke.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"

#define EPS 2.220446049250313e-16

static double gauss(unsigned long long *st) {
    double u1 = sb_rand01(st), u2 = sb_rand01(st);
    if (u1 < 1e-300) u1 = 1e-300;
    return sqrt(-2 * log(u1)) * cos(2 * SB_PI * u2);
}

/* rows x cols (rows >= cols) with orthonormal columns: Q of a Gaussian. */
static double *orthonormal(size_t rows, size_t cols, unsigned long long *st) {
    double *q = malloc(rows * cols * sizeof *q), *tau = malloc(cols * sizeof *tau);
    for (size_t i = 0; i < rows * cols; i++)
        q[i] = gauss(st);
    CHECK(LAPACKE_dgeqrf(LAPACK_COL_MAJOR, (int)rows, (int)cols, q, (int)rows, tau) == 0);
    CHECK(LAPACKE_dorgqr(LAPACK_COL_MAJOR, (int)rows, (int)cols, (int)cols, q, (int)rows, tau) == 0);
    free(tau);
    return q;
}

typedef enum { SP_FAST, SP_SLOW, SP_FLAT, SP_RANKK, SP_GAPS, SP_COUNT } spectrum_t;
static const char *const sp_name[SP_COUNT] = {"fast", "slow", "flat", "rank-k", "gaps"};

/* s[0..d-1] descending. */
static void spectrum(spectrum_t kind, size_t d, size_t k, double *s, unsigned long long *st) {
    for (size_t j = 0; j < d; j++) {
        switch (kind) {
        case SP_FAST:
            s[j] = exp(-0.5 * (double)j);
            break;
        case SP_SLOW:
            s[j] = 1.0 / (1.0 + (double)j);
            break;
        case SP_FLAT:
            s[j] = 1 + 0.01 * sb_rand01(st);
            break; /* noise: sorted below */
        case SP_RANKK:
            s[j] = j < k ? (double)(k - j) : 0;
            break;
        default:
            s[j] = j < 3 ? 10 - (double)j : j < 2 * k ? 1e-3 * (double)(2 * k - j) : 1e-6 / (double)(j + 1);
            break;
        }
    }
    for (size_t i = 1; i < d; i++) /* insertion sort, descending */
        for (size_t j = i; j > 0 && s[j] > s[j - 1]; j--) {
            double t = s[j];
            s[j] = s[j - 1];
            s[j - 1] = t;
        }
}

/* A (m x n, ld lda >= m) = U diag(s) V^T. */
static double *make_matrix(size_t m, size_t n, size_t lda, const double *s, unsigned long long *st) {
    size_t d = m < n ? m : n;
    double *U = orthonormal(m, d, st), *V = orthonormal(n, d, st), *A = calloc(lda * n, sizeof *A);
    for (size_t j = 0; j < d; j++)
        for (size_t i = 0; i < m; i++)
            U[i + j * m] *= s[j];
    cblas_dgemm(CblasColMajor, CblasNoTrans, CblasTrans, (int)m, (int)n, (int)d, 1, U, (int)m, V, (int)n, 0, A,
                (int)lda);
    free(U);
    free(V);
    return A;
}

/* ||A - U diag(s) V^T||_F, explicitly. */
static double resid(const double *A, size_t m, size_t n, size_t lda, size_t k, const double *s, const double *U,
                    const double *V) {
    /* calloc: GCC 12 -O2 -fsanitize=address takes Us for maybe-uninitialized when k == 0 */
    double *R = malloc(m * n * sizeof *R), *Us = calloc(m * k + 1, sizeof *Us), ss = 0;
    for (size_t j = 0; j < n; j++)
        memcpy(R + j * m, A + j * lda, m * sizeof *R);
    for (size_t j = 0; j < k; j++)
        for (size_t i = 0; i < m; i++)
            Us[i + j * m] = U[i + j * m] * s[j];
    cblas_dgemm(CblasColMajor, CblasNoTrans, CblasTrans, (int)m, (int)n, (int)k, -1, Us, (int)m, V, (int)n, 1, R,
                (int)m);
    for (size_t i = 0; i < m * n; i++)
        ss += R[i] * R[i];
    free(R);
    free(Us);
    return sqrt(ss);
}

/* max |Q^T Q - I| for Q rows x k. */
static double orth_defect(const double *Q, size_t rows, size_t k) {
    double mx = 0;
    for (size_t a = 0; a < k; a++)
        for (size_t b = 0; b < k; b++) {
            double dot = 0;
            for (size_t i = 0; i < rows; i++)
                dot += Q[i + a * rows] * Q[i + b * rows];
            double e = fabs(dot - (a == b));
            if (e > mx) mx = e;
        }
    return mx;
}

static double tail(const double *s, size_t d, size_t k) {
    double t = 0;
    for (size_t j = d; j-- > k;)
        t += s[j] * s[j];
    return sqrt(t);
}

typedef struct run {
    double err, opt, bound, norm;
    sb_svd_info_t info;
} run_t;

/* Factor A with `opts`, check orthonormality, sigma order and the
 * method's bound; return the figures. */
static run_t check_method(const sb_svd_opts_t *o, size_t m, size_t n, size_t lda, size_t k, spectrum_t sp,
                          unsigned long long seed) {
    run_t out = {0};
    size_t d = m < n ? m : n;
    unsigned long long st = seed;
    double *sig = malloc(d * sizeof *sig);
    spectrum(sp, d, k, sig, &st);
    double *A = make_matrix(m, n, lda, sig, &st);
    double *s = malloc(k * sizeof *s), *U = malloc(m * k * sizeof *U), *V = malloc(n * k * sizeof *V);
    sb_svd_t *svd = NULL;
    sb_context_t *ctx;
    sb_context_create(&ctx);
    sb_result_t r = sb_svd_create(ctx, m, n, k, o, &svd);
    CHECKF(r == SB_OK, "create: %s", sb_context_last_error(ctx));
    if (r == SB_OK) {
        r = sb_svd_execute(svd, A, lda, s, U, V, NULL, NULL);
        CHECKF(r == SB_OK, "execute: %s", sb_context_last_error(ctx));
        out.info = sb_svd_last_info(svd);
        double eps = o->single_precision ? 1.2e-7 : EPS;
        out.norm = tail(sig, d, 0);
        out.err = resid(A, m, n, lda, k, s, U, V);
        out.opt = tail(sig, d, k);
        double floor_ = 64 * (double)d * eps * out.norm;
        sb_method_t me = sb_svd_method(svd);
        if (me == SB_METHOD_RANDOMIZED) {
            int p = o->oversample > 0 ? o->oversample : o->oversample < 0 ? 0 : 10;
            out.bound = (p > 1 ? sqrt(1 + (double)k / (p - 1)) : 1e300) * out.opt + floor_;
        } else {
            out.bound = out.opt + floor_;
            if (me == SB_METHOD_TOPK) out.bound += 64 * (double)d * eps * sig[0] * sig[0] / fmax(sig[k - 1], 1e-300);
        }
        CHECKF(out.err <= out.bound, "%s m=%zu n=%zu k=%zu %s%s: err %.6g > bound %.6g (opt %.6g)", sb_method_name(me),
               m, n, k, sp_name[sp], o->single_precision ? " single" : "", out.err, out.bound, out.opt);
        for (size_t j = 1; j < k; j++)
            CHECK(s[j] <= s[j - 1]);
        double od = fmax(orth_defect(U, m, k), orth_defect(V, n, k));
        CHECKF(od < 1e3 * eps * (double)d, "%s %s: orthonormality defect %g", sb_method_name(me), sp_name[sp], od);
        if (out.info.resid_fro >= 0)
            CHECKF(fabs(out.info.resid_fro - out.err) <= 1e-6 * out.err + 8 * eps * out.norm * out.norm / out.err,
                   "%s %s: reported residual %.10g, explicit %.10g", sb_method_name(me), sp_name[sp],
                   out.info.resid_fro, out.err);
    }
    sb_svd_destroy(svd);
    sb_context_destroy(ctx);
    free(sig);
    free(A);
    free(s);
    free(U);
    free(V);
    return out;
}

static void every_spectrum(sb_method_t me, int single) {
    static const size_t shapes[][4] = {{120, 90, 120, 6}, {80, 150, 83, 10}, {200, 200, 200, 1}, {64, 64, 70, 8}};
    for (size_t sh = 0; sh < sizeof shapes / sizeof shapes[0]; sh++)
        for (int sp = 0; sp < SP_COUNT; sp++) {
            sb_svd_opts_t o = {0};
            o.method = me;
            o.single_precision = single;
            check_method(&o, shapes[sh][0], shapes[sh][1], shapes[sh][2], shapes[sh][3], (spectrum_t)sp,
                         1000 + 17 * sh + (unsigned long long)sp);
        }
}

SB_TEST(full_eckart_young) { every_spectrum(SB_METHOD_FULL, 0); }
SB_TEST(topk_eckart_young) { every_spectrum(SB_METHOD_TOPK, 0); }
SB_TEST(randomized_bound) { every_spectrum(SB_METHOD_RANDOMIZED, 0); }

/* Block Krylov (the default when l (q + 1) <= d / 2) and plain subspace
 * iteration both meet the bound; Krylov is the closer of the two on a slow
 * spectrum, and reports its wider basis. */
SB_TEST(randomized_krylov) {
    for (int sp = 0; sp < SP_COUNT; sp++) {
        sb_svd_opts_t o = {.method = SB_METHOD_RANDOMIZED};
        run_t kr = check_method(&o, 400, 300, 400, 8, (spectrum_t)sp, 77);
        CHECK(kr.info.sketch == 3 * 18);
        o.krylov = -1;
        run_t hmt = check_method(&o, 400, 300, 400, 8, (spectrum_t)sp, 77);
        CHECK(hmt.info.sketch == 18);
        if (sp == SP_SLOW) CHECKF(kr.err < hmt.err, "krylov %.10g, subspace iteration %.10g", kr.err, hmt.err);
    }
}

/* Exact methods meet Eckart-Young to rounding, not only the bound: also
 * the singular values themselves. */
SB_TEST(exact_sigma) {
    size_t m = 150, n = 110, k = 12;
    for (int me = SB_METHOD_FULL; me <= SB_METHOD_TOPK; me++) {
        unsigned long long st = 42;
        double sig[110], s[12];
        spectrum(SP_SLOW, n, k, sig, &st);
        double *A = make_matrix(m, n, m, sig, &st);
        sb_svd_opts_t o = {.method = (sb_method_t)me};
        sb_svd_t *svd;
        CHECK(sb_svd_create(NULL, m, n, k, &o, &svd) == SB_OK);
        CHECK(sb_svd_execute(svd, A, m, s, NULL, NULL, NULL, NULL) == SB_OK);
        for (size_t j = 0; j < k; j++)
            CHECK_REL(s[j], sig[j], 1e-13);
        sb_svd_destroy(svd);
        free(A);
    }
}

/* ||(I - X X^T) Y||_F^2 = sum of sin^2 of the principal angles between the
 * spans of X and Y (rows x k, orthonormal columns), formed explicitly (no
 * cancellation as in k - ||X^T Y||_F^2). */
static double sin2_angles(const double *X, const double *Y, size_t rows, size_t k) {
    double *c = malloc(k * k * sizeof *c), *r = malloc(rows * k * sizeof *r), f = 0;
    memcpy(r, Y, rows * k * sizeof *r);
    cblas_dgemm(CblasColMajor, CblasTrans, CblasNoTrans, (int)k, (int)k, (int)rows, 1, X, (int)rows, Y, (int)rows, 0, c,
                (int)k);
    cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, (int)rows, (int)k, (int)k, -1, X, (int)rows, c, (int)k, 1, r,
                (int)rows);
    for (size_t i = 0; i < rows * k; i++)
        f += r[i] * r[i];
    free(c);
    free(r);
    return f;
}

/* TOPK on the m x n matrix with singular values sig (d = min(m, n) of
 * them, descending) against LAPACK dgesdd on the same matrix: the largest
 * error of the k values over sigma_1, the sin^2 of the angles between the
 * singular subspaces (U and V), and TOPK's Krylov cycles.  0 when a call
 * failed. */
typedef struct {
    double dsig, su, sv;
    size_t cycles, degree;
} topk_vs_t;

static int topk_vs_gesdd(size_t m, size_t n, size_t k, const double *sig, unsigned long long *st, topk_vs_t *out) {
    size_t d = m < n ? m : n;
    double *A = make_matrix(m, n, m, sig, st), *C = malloc(m * n * sizeof *C);
    double *ref = malloc(d * sizeof *ref), *Ur = malloc(m * d * sizeof *Ur), *Vt = malloc(d * n * sizeof *Vt);
    double *Vr = malloc(n * k * sizeof *Vr), *s = malloc(k * sizeof *s), *U = malloc(m * k * sizeof *U),
           *V = malloc(n * k * sizeof *V);
    memcpy(C, A, m * n * sizeof *C);
    int ok = LAPACKE_dgesdd(LAPACK_COL_MAJOR, 'S', (int)m, (int)n, C, (int)m, ref, Ur, (int)m, Vt, (int)d) == 0;
    for (size_t j = 0; j < k; j++)
        for (size_t i = 0; i < n; i++)
            Vr[i + j * n] = Vt[j + i * d];
    sb_svd_opts_t o = {.method = SB_METHOD_TOPK};
    sb_svd_t *svd = NULL;
    ok = ok && sb_svd_create(NULL, m, n, k, &o, &svd) == SB_OK &&
         sb_svd_execute(svd, A, m, s, U, V, NULL, NULL) == SB_OK;
    if (ok) {
        out->cycles = sb_svd_last_info(svd).cycles;
        out->degree = sb_svd_last_info(svd).degree;
        out->dsig = 0;
        for (size_t j = 0; j < k; j++)
            out->dsig = fmax(out->dsig, fabs(s[j] - ref[j]) / ref[0]);
        out->su = sin2_angles(U, Ur, m, k);
        out->sv = sin2_angles(V, Vr, n, k);
    }
    sb_svd_destroy(svd);
    free(A);
    free(C);
    free(ref);
    free(Ur);
    free(Vt);
    free(Vr);
    free(s);
    free(U);
    free(V);
    return ok;
}

/* TOPK where its Krylov cycles apply (d >= 2 l (q + 1)) against LAPACK
 * dgesdd on the same matrix: the k values to 1e-10 sigma_1 and, where the
 * cut has a gap, both singular subspaces to an angle of 1e-9; on spectra
 * decaying fast and slowly, with clusters inside the k terms and across
 * the cut, and flat (noise: the cycles may hand over to the Gram route). */
SB_TEST(topk_krylov_vs_gesdd) {
    size_t m = 520, n = 440, k = 8, d = 440;
    for (int kind = 0; kind < 5; kind++) {
        unsigned long long st = 300 + (unsigned long long)kind;
        double *sig = malloc(d * sizeof *sig);
        for (size_t j = 0; j < d; j++) {
            double x = (double)j;
            sig[j] = kind == 0   ? exp(-0.3 * x)
                     : kind == 1 ? 1 / (1 + x)
                     : kind == 2 ? (j < 3   ? 5
                                    : j < 5 ? 4
                                    : j < 8 ? 2
                                            : 1 / (1 + x)) /* clusters inside */
                     : kind == 3 ? (j < 6    ? 3 - 0.1 * x
                                    : j < 11 ? 2
                                             : 1 / (1 + x)) /* 2 across the cut */
                                 : 1 + 0.01 * sb_rand01(&st);
        }
        for (size_t i = 1; i < d; i++) /* descending */
            for (size_t j = i; j > 0 && sig[j] > sig[j - 1]; j--) {
                double t = sig[j];
                sig[j] = sig[j - 1];
                sig[j - 1] = t;
            }
        topk_vs_t r = {1, 1, 1, 0, 0}; /* failing values if the call fails */
        CHECK(topk_vs_gesdd(m, n, k, sig, &st, &r));
        CHECKF(kind == 4 || r.cycles >= 1, "kind %d: Krylov cycles %zu", kind, r.cycles);
        CHECKF(r.dsig <= 1e-10, "kind %d: values %.3g sigma_1 from dgesdd's", kind, r.dsig);
        if (sig[k - 1] - sig[k] > 1e-3 * sig[0])
            CHECKF(r.su <= 1e-18 && r.sv <= 1e-18, "kind %d: sin^2 of the angles %.3g (U), %.3g (V)", kind, r.su, r.sv);
        free(sig);
    }
}

/* TOPK where the block (18) is well past the cut: the residual estimate
 * read off the next Krylov block ends the one cycle below the largest
 * depth (8 here) on fast spectra, never with a failed certificate (a
 * second cycle), and the triplets match dgesdd's (the certificate is read
 * from A). */
SB_TEST(topk_stops_at_the_degree_needed) {
    size_t m = 520, n = 440, k = 8, d = 440;
    double *sig = malloc(d * sizeof *sig);
    for (int kind = 0; kind < 3; kind++) {
        unsigned long long st = 900 + (unsigned long long)kind;
        for (size_t j = 0; j < d; j++)
            sig[j] = kind == 0 ? exp(-0.8 * (double)j) : kind == 1 ? exp(-0.4 * (double)j) : 1 / (1 + (double)j);
        topk_vs_t r = {1, 1, 1, 0, 0}; /* failing values if the call fails */
        CHECK(topk_vs_gesdd(m, n, k, sig, &st, &r));
        CHECKF(r.dsig <= 1e-10, "kind %d: values %.3g sigma_1 from dgesdd's", kind, r.dsig);
        CHECKF(r.su <= 1e-18 && r.sv <= 1e-18, "kind %d: sin^2 of the angles %.3g (U), %.3g (V)", kind, r.su, r.sv);
        CHECKF(r.cycles == 1, "kind %d: %zu cycles (a certificate failed)", kind, r.cycles);
        /* the slow one needs degree 6: its estimates would cost more than
         * the reads they save on a matrix this small (svd_tmpl_rand.h) */
        if (kind < 2) CHECKF(r.degree >= 1 && r.degree < 8, "kind %d: degree %zu", kind, r.degree);
    }
    free(sig);
}

/* TOPK on a spectrum that drops below sqrt(eps) sigma_1 inside the k terms:
 * the Ritz step keeps the leading triplets exact and the error still within
 * sqrt(eps) sigma_1 of the optimum (documented in svd.h). */
SB_TEST(topk_ill_conditioned) {
    size_t m = 100, n = 100, k = 10;
    unsigned long long st = 7;
    double sig[100], s[10];
    for (size_t j = 0; j < n; j++)
        sig[j] = pow(10.0, -(double)j * 1.2); /* 1 .. 1e-10.8 inside k */
    double *A = make_matrix(m, n, m, sig, &st);
    double *U = malloc(m * k * sizeof *U), *V = malloc(n * k * sizeof *V);
    sb_svd_opts_t o = {.method = SB_METHOD_TOPK};
    sb_svd_t *svd;
    CHECK(sb_svd_create(NULL, m, n, k, &o, &svd) == SB_OK);
    CHECK(sb_svd_execute(svd, A, m, s, U, V, NULL, NULL) == SB_OK);
    for (size_t j = 0; j < 4; j++)
        CHECK_REL(s[j], sig[j], 1e-8);
    double err = resid(A, m, n, m, k, s, U, V);
    CHECKF(err <= tail(sig, n, k) + 1e-7, "err %g opt %g", err, tail(sig, n, k));
    sb_svd_destroy(svd);
    free(A);
    free(U);
    free(V);
}

SB_TEST(single_precision) {
    for (int me = SB_METHOD_FULL; me <= SB_METHOD_RANDOMIZED; me++) {
        size_t m = 160, n = 130, k = 8;
        unsigned long long st = 99;
        double sig[130], sd[8], sf[8];
        spectrum(SP_FAST, n, k, sig, &st);
        double *A = make_matrix(m, n, m, sig, &st);
        sb_svd_opts_t o = {.method = (sb_method_t)me};
        sb_svd_t *a, *b;
        CHECK(sb_svd_create(NULL, m, n, k, &o, &a) == SB_OK);
        o.single_precision = 1;
        CHECK(sb_svd_create(NULL, m, n, k, &o, &b) == SB_OK);
        CHECK(sb_svd_execute(a, A, m, sd, NULL, NULL, NULL, NULL) == SB_OK);
        CHECK(sb_svd_execute(b, A, m, sf, NULL, NULL, NULL, NULL) == SB_OK);
        for (size_t j = 0; j < k; j++)
            CHECKF(fabs(sf[j] - sd[j]) <= 1e-5 * sd[0], "%s sigma_%zu %.9g vs %.9g", sb_method_name((sb_method_t)me), j,
                   sf[j], sd[j]);
        sb_svd_destroy(a);
        sb_svd_destroy(b);
        free(A);
        /* and the bounds, at single-precision rounding */
        o.single_precision = 1;
        check_method(&o, 90, 70, 90, 5, SP_FAST, 5);
        check_method(&o, 70, 90, 75, 5, SP_GAPS, 6);
    }
}

/* Same seed, same bits; another seed, other bits (randomized). */
SB_TEST(deterministic) {
    size_t m = 300, n = 280, k = 7;
    unsigned long long st = 3;
    double sig[280];
    spectrum(SP_SLOW, n, k, sig, &st);
    double *A = make_matrix(m, n, m, sig, &st);
    double *out[3];
    for (int t = 0; t < 3; t++) {
        sb_svd_opts_t o = {.method = SB_METHOD_RANDOMIZED, .seed = t == 2 ? 5 : 0};
        sb_svd_t *svd;
        out[t] = calloc(k + m * k + n * k, sizeof(double));
        CHECK(sb_svd_create(NULL, m, n, k, &o, &svd) == SB_OK);
        CHECK(sb_svd_execute(svd, A, m, out[t], out[t] + k, out[t] + k + m * k, NULL, NULL) == SB_OK);
        sb_svd_destroy(svd);
    }
    size_t bytes = (k + m * k + n * k) * sizeof(double);
    CHECK(memcmp(out[0], out[1], bytes) == 0);
    CHECK(memcmp(out[0], out[2], bytes) != 0);
    for (int t = 0; t < 3; t++)
        free(out[t]);
    free(A);
}

/* One plan, many matrices (and strided input); A is never modified. */
SB_TEST(plan_reuse) {
    size_t m = 140, n = 100, lda = 150, k = 5;
    for (int me = SB_METHOD_FULL; me <= SB_METHOD_RANDOMIZED; me++)
        for (int single = 0; single < 2; single++) {
            sb_svd_opts_t o = {.method = (sb_method_t)me, .single_precision = single};
            sb_svd_t *svd;
            CHECK(sb_svd_create(NULL, m, n, k, &o, &svd) == SB_OK);
            CHECK(sb_svd_method(svd) == (sb_method_t)me && sb_svd_rank(svd) == k);
            CHECK(sb_svd_workspace_bytes(svd) > 0);
            for (int sp = 0; sp < SP_COUNT; sp++) {
                unsigned long long st = 500 + (unsigned long long)sp;
                double sig[100], s[5];
                spectrum((spectrum_t)sp, n, k, sig, &st);
                double *A = make_matrix(m, n, lda, sig, &st), *copy = malloc(lda * n * sizeof *copy);
                double *U = malloc(m * k * sizeof *U), *V = malloc(n * k * sizeof *V);
                memcpy(copy, A, lda * n * sizeof *copy);
                CHECK(sb_svd_execute(svd, A, lda, s, U, V, NULL, NULL) == SB_OK);
                CHECK(memcmp(copy, A, lda * n * sizeof *copy) == 0);
                double err = resid(A, m, n, lda, k, s, U, V), opt = tail(sig, n, k);
                double bound = (me == SB_METHOD_RANDOMIZED ? sqrt(1 + 5.0 / 9) : 1) * opt +
                               (single ? 1e-4 : 1e-10) * tail(sig, n, 0);
                CHECKF(err <= bound, "%s %s: %g > %g", sb_method_name((sb_method_t)me), sp_name[sp], err, bound);
                free(A);
                free(copy);
                free(U);
                free(V);
            }
            sb_svd_destroy(svd);
        }
}

/* all_s: every singular value from FULL, none from the others. */
SB_TEST(all_singular_values) {
    size_t m = 50, n = 40, k = 3;
    unsigned long long st = 11;
    double sig[40], s[3], all[40];
    spectrum(SP_SLOW, n, k, sig, &st);
    double *A = make_matrix(m, n, m, sig, &st);
    for (int me = SB_METHOD_FULL; me <= SB_METHOD_RANDOMIZED; me++) {
        sb_svd_opts_t o = {.method = (sb_method_t)me};
        sb_svd_t *svd;
        int have = -1;
        CHECK(sb_svd_create(NULL, m, n, k, &o, &svd) == SB_OK);
        CHECK(sb_svd_execute(svd, A, m, s, NULL, NULL, all, &have) == SB_OK);
        CHECK(have == (me == SB_METHOD_FULL));
        if (have)
            for (size_t j = 0; j < n; j++)
                CHECK_ABS(all[j], sig[j], 1e-14);
        sb_svd_destroy(svd);
    }
    free(A);
}

/* Adaptive rank: the smallest r meeting the target (exact methods: exactly
 * the Eckart-Young r; randomized: the target is met, r at most one more). */
SB_TEST(adaptive_rank) {
    size_t m = 260, n = 240, k = 40;
    unsigned long long st = 21;
    double sig[240];
    spectrum(SP_FAST, n, k, sig, &st);
    double *A = make_matrix(m, n, m, sig, &st), norm = tail(sig, n, 0);
    double *s = malloc(k * sizeof *s), *U = malloc(m * k * sizeof *U), *V = malloc(n * k * sizeof *V);
    const double tols[] = {0.3, 0.05, 1e-3, 1e-5};
    for (int me = SB_METHOD_FULL; me <= SB_METHOD_RANDOMIZED; me++)
        for (int given = 0; given < 2; given++)
            for (size_t t = 0; t < sizeof tols / sizeof tols[0]; t++) {
                sb_svd_opts_t o = {.method = (sb_method_t)me, .block = 8};
                sb_svd_t *svd;
                sb_svd_info_t info;
                CHECK(sb_svd_create(NULL, m, n, k, &o, &svd) == SB_OK);
                CHECK(sb_svd_execute_adaptive(svd, A, m, tols[t], given ? norm : 0, 0, s, U, V, &info) == SB_OK);
                size_t ropt = 1;
                while (ropt < k && tail(sig, n, ropt) > tols[t] * norm)
                    ropt++;
                double err = resid(A, m, n, m, info.rank, s, U, V);
                CHECKF(err <= tols[t] * norm * (1 + 1e-9), "%s tol %g: err %g", sb_method_name((sb_method_t)me),
                       tols[t], err / norm);
                if (me == SB_METHOD_RANDOMIZED)
                    CHECKF(info.rank >= ropt && info.rank <= ropt + 1, "randomized tol %g: rank %zu, optimum %zu",
                           tols[t], info.rank, ropt);
                else
                    CHECKF(info.rank == ropt, "%s tol %g: rank %zu, optimum %zu", sb_method_name((sb_method_t)me),
                           tols[t], info.rank, ropt);
                CHECK_REL(info.norm_fro, norm, 1e-12);
                /* the identity ||A||^2 - sum s^2 cancels: relative error eps ||A||^2 / err^2 */
                CHECK_ABS(info.resid_fro, err, 1e-6 * err + 8 * EPS * norm * norm / err);
                /* a floor on the rank is honoured */
                CHECK(sb_svd_execute_adaptive(svd, A, m, tols[t], 0, ropt + 3, s, U, V, &info) == SB_OK);
                CHECK(info.rank == ropt + 3);
                sb_svd_destroy(svd);
            }
    /* blocked randomized reads A less often than the plan's k would need
     * when the target is met early: fewer columns */
    sb_svd_opts_t o = {.method = SB_METHOD_RANDOMIZED, .block = 8};
    sb_svd_t *svd;
    sb_svd_info_t info;
    CHECK(sb_svd_create(NULL, m, n, k, &o, &svd) == SB_OK);
    CHECK(sb_svd_execute_adaptive(svd, A, m, 0.05, 0, 0, s, U, V, &info) == SB_OK);
    CHECKF(info.sketch < k, "sketch %zu", info.sketch);
    /* an unreachable target keeps all k terms */
    CHECK(sb_svd_execute_adaptive(svd, A, m, 0, 0, 0, s, U, V, &info) == SB_OK);
    CHECK(info.rank == k && info.sketch == k + 10); /* l (q + 1) > d / 2: plain subspace iteration */
    sb_svd_destroy(svd);
    free(A);
    free(s);
    free(U);
    free(V);
}

/* Adaptive rank through the block Krylov basis, growing block by block. */
SB_TEST(adaptive_krylov) {
    size_t m = 600, n = 500, k = 30;
    unsigned long long st = 31;
    double sig[500];
    spectrum(SP_SLOW, n, k, sig, &st);
    double *A = make_matrix(m, n, m, sig, &st), norm = tail(sig, n, 0);
    double *s = malloc(k * sizeof *s), *U = malloc(m * k * sizeof *U), *V = malloc(n * k * sizeof *V);
    sb_svd_opts_t o = {.method = SB_METHOD_RANDOMIZED, .block = 6};
    sb_svd_t *svd;
    sb_svd_info_t info;
    CHECK(sb_svd_create(NULL, m, n, k, &o, &svd) == SB_OK);
    const double tols[] = {0.8, 0.6, 0.5};
    for (size_t t = 0; t < 3; t++) {
        size_t ropt = 1;
        while (ropt < k && tail(sig, n, ropt) > tols[t] * norm)
            ropt++;
        CHECK(sb_svd_execute_adaptive(svd, A, m, tols[t], norm, 0, s, U, V, &info) == SB_OK);
        double err = resid(A, m, n, m, info.rank, s, U, V);
        CHECKF(err <= tols[t] * norm * (1 + 1e-9), "tol %g: err %g", tols[t], err / norm);
        CHECKF(info.rank >= ropt && info.rank <= ropt + 1, "tol %g: rank %zu, optimum %zu", tols[t], info.rank, ropt);
        CHECKF(info.sketch % 18 == 0 && info.sketch < 3 * (k + 10), "tol %g: sketch %zu", tols[t], info.sketch);
        CHECK(orth_defect(U, m, info.rank) < 1e-12 && orth_defect(V, n, info.rank) < 1e-12);
    }
    sb_svd_destroy(svd);
    free(A);
    free(s);
    free(U);
    free(V);
}

SB_TEST(auto_rule) {
    static const struct {
        size_t m, n, k;
        sb_method_t want;
    } cases[] = {{100, 100, 4, SB_METHOD_FULL},           {128, 5000, 4, SB_METHOD_FULL},
                 {300, 300, 4, SB_METHOD_TOPK},           {1024, 1024, 8, SB_METHOD_RANDOMIZED},
                 {1024, 1024, 200, SB_METHOD_TOPK},       {4096, 401, 8, SB_METHOD_RANDOMIZED},
                 {1024, 1024, 118, SB_METHOD_RANDOMIZED}, {1024, 1024, 119, SB_METHOD_TOPK}};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        sb_svd_t *svd;
        CHECK(sb_svd_create(NULL, cases[i].m, cases[i].n, cases[i].k, NULL, &svd) == SB_OK);
        CHECKF(sb_svd_method(svd) == cases[i].want, "%zu x %zu, k %zu: %s", cases[i].m, cases[i].n, cases[i].k,
               sb_method_name(sb_svd_method(svd)));
        CHECK(sb_svd_auto_method(cases[i].m, cases[i].n, cases[i].k, NULL) == cases[i].want);
        sb_svd_destroy(svd);
    }
    sb_svd_opts_t o = {.method = SB_METHOD_TOPK};
    CHECK(sb_svd_auto_method(4096, 4096, 8, &o) == SB_METHOD_TOPK);
}

SB_TEST(method_names) {
    sb_method_t me;
    CHECK(sb_method_count() >= 6 && strcmp(sb_method_name(SB_METHOD_NONE), "?") == 0);
    for (int i = 0; i < (int)sb_method_count(); i++) {
        CHECK(sb_method_parse(sb_method_name((sb_method_t)i), &me) == SB_OK && me == (sb_method_t)i);
    }
    CHECK(sb_method_parse("svd", &me) == SB_ERR_UNKNOWN);
    CHECK(sb_method_parse(NULL, &me) == SB_ERR_UNKNOWN);
    CHECK(strcmp(sb_method_name((sb_method_t)99), "?") == 0);
}

SB_TEST(errors) {
    sb_context_t *ctx;
    sb_svd_t *svd = (sb_svd_t *)1;
    sb_context_create(&ctx);
    CHECK(sb_svd_create(ctx, 10, 10, 0, NULL, &svd) == SB_ERR_RANGE && svd == NULL);
    CHECK(strstr(sb_context_last_error(ctx), "1..10") != NULL);
    CHECK(sb_svd_create(ctx, 10, 8, 9, NULL, &svd) == SB_ERR_RANGE);
    CHECK(sb_svd_create(ctx, 0, 8, 1, NULL, &svd) == SB_ERR_ARG);
    CHECK(sb_svd_create(ctx, 8, 0, 1, NULL, &svd) == SB_ERR_ARG);
    CHECK(sb_svd_create(ctx, 8, 8, 1, NULL, NULL) == SB_ERR_ARG);
    sb_svd_opts_t bad = {.method = (sb_method_t)17};
    CHECK(sb_svd_create(ctx, 8, 8, 1, &bad, &svd) == SB_ERR_ARG);
    CHECK(sb_svd_create(ctx, (size_t)1 << 32, 4, 1, NULL, &svd) == SB_ERR_OVERFLOW);
    /* workspace over the memory limit: refused at plan time */
    sb_set_memory_limit(1 << 20);
    sb_svd_opts_t full = {.method = SB_METHOD_FULL};
    CHECK(sb_svd_create(ctx, 2000, 2000, 4, &full, &svd) == SB_ERR_OVERFLOW);
    sb_set_memory_limit(0);
    CHECK(sb_svd_execute(NULL, NULL, 1, NULL, NULL, NULL, NULL, NULL) == SB_ERR_ARG);
    CHECK(sb_svd_execute_adaptive(NULL, NULL, 1, 0.1, 0, 0, NULL, NULL, NULL, NULL) == SB_ERR_ARG);
    sb_svd_destroy(NULL);
    double A[64] = {0}, s[8], U[64], V[64];
    for (int me = SB_METHOD_FULL; me <= SB_METHOD_RANDOMIZED; me++)
        for (int single = 0; single < 2; single++) {
            sb_svd_opts_t o = {
                .method = (sb_method_t)me, .oversample = 4, .power_iters = 1, .single_precision = single};
            CHECK(sb_svd_create(ctx, 8, 8, 2, &o, &svd) == SB_OK);
            CHECK(sb_svd_execute(svd, A, 7, s, U, V, NULL, NULL) == SB_ERR_ARG); /* lda < m */
            CHECK(sb_svd_execute(svd, NULL, 8, s, U, V, NULL, NULL) == SB_ERR_ARG);
            CHECK(sb_svd_execute(svd, A, 8, NULL, U, V, NULL, NULL) == SB_ERR_ARG);
            CHECK(sb_svd_execute_adaptive(svd, A, 8, 1.0, 0, 0, s, U, V, NULL) == SB_ERR_RANGE);
            CHECK(sb_svd_execute_adaptive(svd, A, 8, -0.1, 0, 0, s, U, V, NULL) == SB_ERR_RANGE);
            CHECK(sb_svd_execute_adaptive(svd, A, 8, 0.1, 0, 3, s, U, V, NULL) == SB_ERR_RANGE);
            CHECK(sb_svd_execute_adaptive(svd, A, 8, 0.1, -1, 0, s, U, V, NULL) == SB_ERR_RANGE);
            /* the zero matrix is fine: sigma = 0 */
            CHECK(sb_svd_execute(svd, A, 8, s, U, V, NULL, NULL) == SB_OK);
            CHECK(s[0] == 0 && s[1] == 0);
            /* non-finite input is a numeric error, not a hang or garbage */
            A[9] = NAN;
            CHECK(sb_svd_execute(svd, A, 8, s, U, V, NULL, NULL) == SB_ERR_NUMERIC);
            A[9] = INFINITY;
            CHECK(sb_svd_execute(svd, A, 8, s, U, V, NULL, NULL) == SB_ERR_NUMERIC);
            A[9] = single ? 1e39 : 0; /* overflows float */
            CHECK(sb_svd_execute(svd, A, 8, s, U, V, NULL, NULL) == (single ? SB_ERR_NUMERIC : SB_OK));
            /* finite but squares overflow: fine except through a Gram matrix */
            A[9] = single ? 1e30 : 1e200;
            sb_result_t want = me == SB_METHOD_TOPK ? SB_ERR_NUMERIC : SB_OK;
            CHECK(sb_svd_execute(svd, A, 8, s, U, V, NULL, NULL) == want);
            if (want == SB_OK) CHECK_REL(s[0], A[9], 1e-6);
            sb_svd_info_t info;
            CHECK(sb_svd_execute_adaptive(svd, A, 8, 0.5, 0, 0, s, U, V, &info) == want);
            if (want == SB_OK && !single) CHECK_REL(info.norm_fro, 1e200, 1e-12);
            A[9] = 0;
            sb_svd_destroy(svd);
        }
    sb_context_destroy(ctx);
}

/* TOPK on a slowly decaying spectrum where a cycle does not converge: the
 * restart doubles the block (its leading Ritz vectors, up to twice the first;
 * the basis fits at 700 x 660) and still gives dgesdd's triplets. */
SB_TEST(topk_restart_grows_block) {
    size_t m = 700, n = 660, k = 8, d = 660;
    unsigned long long st = 4242;
    double *sig = malloc(d * sizeof *sig);
    for (size_t j = 0; j < d; j++)
        sig[j] = pow(1.0 + (double)j, -0.25);
    topk_vs_t r = {1, 1, 1, 0, 0}; /* failing values if the call fails */
    CHECK(topk_vs_gesdd(m, n, k, sig, &st, &r));
    CHECKF(r.cycles >= 2, "Krylov cycles %zu: the restart was not exercised", r.cycles);
    CHECKF(r.dsig <= 1e-10, "values %.3g sigma_1 from dgesdd's", r.dsig);
    CHECKF(r.su <= 1e-16 && r.sv <= 1e-16, "sin^2 of the angles %.3g (U), %.3g (V)", r.su, r.sv);
    free(sig);
}
