/* RANDOMIZED in mixed precision (sb_svd_opts_t.mixed >= 0, the default: the
 * sketch in float, the projection in double) against the same method in
 * double (mixed < 0) and
 * against FULL (LAPACK's gesdd, the Eckart-Young optimum).  What the mixed
 * path promises (svd.h):
 *   - its values are those of an exact projection in double: the reported
 *     residual sqrt(||A||^2 - sum s^2) equals ||A - U S V^T||_F formed
 *     explicitly, to double rounding, and U, V are orthonormal to double
 *     rounding (float would leave 1e-7);
 *   - its subspace differs from the double method's by float rounding only:
 *     the singular values agree to MIXED_SV_TOL sigma_1, and the excess
 *     error over the optimum is at most the double method's plus a float
 *     rounding floor, MIXED_FLOOR eps_float ||A||_F (A rounded to float is
 *     within eps_float ||A||_F of A).  Where the double method reaches the
 *     optimum to 1e-12 (these well separated spectra) that floor is all of
 *     the mixed excess (1e-12 .. 1e-5 relative here); on the bench's
 *     matrices the sketch's own excess (3e-5) is far above it. */
#include <cblas.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"

#define MIXED_SV_TOL 1e-6
#define MIXED_FLOOR 8

/* A (m x n) = X diag(w) Y^T + noise E, X, Y and E uniform in [-1/2, 1/2],
 * w_j = decay^j: a numerically low-rank matrix with a noisy tail. */
static double *low_rank(size_t m, size_t n, double decay, double noise, unsigned long long seed) {
    size_t r = 24;
    double *X = malloc(m * r * sizeof *X), *Y = malloc(n * r * sizeof *Y), *A = malloc(m * n * sizeof *A);
    unsigned long long st = seed;
    for (size_t i = 0; i < m * n; i++)
        A[i] = noise * (sb_rand01(&st) - 0.5);
    for (size_t j = 0; j < r; j++) {
        double w = pow(decay, (double)j);
        for (size_t i = 0; i < m; i++)
            X[i + j * m] = w * (sb_rand01(&st) - 0.5);
        for (size_t i = 0; i < n; i++)
            Y[i + j * n] = sb_rand01(&st) - 0.5;
    }
    cblas_dgemm(CblasColMajor, CblasNoTrans, CblasTrans, (int)m, (int)n, (int)r, 1, X, (int)m, Y, (int)n, 1, A, (int)m);
    free(X);
    free(Y);
    return A;
}

typedef struct {
    double s[16], err, reported, defect;
} fit_t;

/* Factor A with the method and precision asked; the explicit residual, the
 * reported one and the largest |Q^T Q - I| of U and V. */
static fit_t fit(const double *A, size_t m, size_t n, size_t k, sb_method_t me, int mixed) {
    fit_t f = {{0}, -1, -1, -1};
    sb_svd_opts_t o = {.method = me, .mixed = mixed};
    sb_svd_t *svd = NULL;
    double *U = malloc(m * k * sizeof *U), *V = malloc(n * k * sizeof *V), *R = malloc(m * n * sizeof *R);
    CHECK(sb_svd_create(NULL, m, n, k, &o, &svd) == SB_OK);
    if (svd && sb_svd_execute(svd, A, m, f.s, U, V, NULL, NULL) == SB_OK) {
        f.reported = sb_svd_last_info(svd).resid_fro;
        memcpy(R, A, m * n * sizeof *R);
        for (size_t j = 0; j < k; j++) /* R = A - (U S) V^T */
            cblas_dger(CblasColMajor, (int)m, (int)n, -f.s[j], U + j * m, 1, V + j * n, 1, R, (int)m);
        f.err = cblas_dnrm2((int)(m * n), R, 1);
        f.defect = 0;
        for (int side = 0; side < 2; side++) {
            const double *Q = side ? V : U;
            size_t rows = side ? n : m;
            for (size_t a = 0; a < k; a++)
                for (size_t b = 0; b < k; b++)
                    f.defect = fmax(f.defect, fabs(cblas_ddot((int)rows, Q + a * rows, 1, Q + b * rows, 1) - (a == b)));
        }
    } else {
        CHECK(!"execute failed");
    }
    sb_svd_destroy(svd);
    free(U);
    free(V);
    free(R);
    return f;
}

SB_TEST(against_double) {
    static const struct {
        size_t m, n, k;
        double decay, noise;
    } cases[] = {{300, 200, 8, 0.7, 1e-3}, {180, 260, 5, 0.9, 1e-2}, {400, 400, 12, 0.5, 1e-6}, {256, 320, 1, 0.8, 0}};
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        size_t m = cases[c].m, n = cases[c].n, k = cases[c].k;
        double *A = low_rank(m, n, cases[c].decay, cases[c].noise, 7 + c);
        fit_t best = fit(A, m, n, k, SB_METHOD_FULL, 0), dbl = fit(A, m, n, k, SB_METHOD_RANDOMIZED, -1),
              mix = fit(A, m, n, k, SB_METHOD_RANDOMIZED, 1);
        double norm = cblas_dnrm2((int)(m * n), A, 1), eps = 2.220446049250313e-16;
        for (size_t j = 0; j < k; j++)
            CHECKF(fabs(mix.s[j] - dbl.s[j]) <= MIXED_SV_TOL * dbl.s[0], "case %zu sigma_%zu: mixed %.12g double %.12g",
                   c, j, mix.s[j], dbl.s[j]);
        /* the certificate: an exact projection in double */
        CHECKF(fabs(mix.reported - mix.err) <= 1e-9 * mix.err + 16 * eps * norm * norm / fmax(mix.err, 1e-300),
               "case %zu: reported residual %.15g, explicit %.15g", c, mix.reported, mix.err);
        CHECKF(mix.defect <= 1e3 * eps, "case %zu: orthonormality defect %g", c, mix.defect);
        /* the excess over the optimum: the double method's, to second order */
        double ex_d = dbl.err - best.err, ex_m = mix.err - best.err;
        CHECKF(ex_m <= ex_d + MIXED_FLOOR * 0x1.0p-24 * norm,
               "case %zu: excess mixed %.6g, double %.6g (optimum %.10g)", c, ex_m, ex_d, best.err);
        free(A);
    }
}

/* Mixed precision only applies to RANDOMIZED: FULL and TOPK ignore it and
 * give their double results bit for bit; the adaptive rank choice works
 * with it and reports a residual within the tolerance asked. */
SB_TEST(other_methods_and_adaptive) {
    size_t m = 200, n = 150, k = 10;
    double *A = low_rank(m, n, 0.6, 1e-4, 3);
    for (int me = SB_METHOD_FULL; me <= SB_METHOD_TOPK; me++) {
        fit_t a = fit(A, m, n, k, (sb_method_t)me, 0), b = fit(A, m, n, k, (sb_method_t)me, 1);
        CHECK(memcmp(a.s, b.s, sizeof a.s) == 0);
    }
    sb_svd_opts_t o = {.method = SB_METHOD_RANDOMIZED, .mixed = 1, .block = 4};
    sb_svd_t *svd = NULL;
    double s[10], norm = cblas_dnrm2((int)(m * n), A, 1);
    sb_svd_info_t info;
    CHECK(sb_svd_create(NULL, m, n, k, &o, &svd) == SB_OK);
    CHECK(sb_svd_execute_adaptive(svd, A, m, 0.05, norm, 1, s, NULL, NULL, &info) == SB_OK);
    CHECKF(info.rank >= 1 && info.rank <= k && info.resid_fro <= 0.05 * norm * (1 + 1e-12), "rank %zu resid %g of %g",
           info.rank, info.resid_fro, norm);
    sb_svd_destroy(svd);
    free(A);
}

/* The float copy is scaled by a power of two: a matrix beyond the float
 * range (1e39 .. 1e200) or below it (1e-200) gives the values of the
 * unscaled one, scaled; the default (mixed = 0) is the mixed path. */
SB_TEST(scaled_and_default) {
    size_t m = 120, n = 100, k = 6;
    double *A = low_rank(m, n, 0.7, 1e-3, 11);
    fit_t ref = fit(A, m, n, k, SB_METHOD_RANDOMIZED, 1), dflt = fit(A, m, n, k, SB_METHOD_RANDOMIZED, 0);
    CHECK(memcmp(ref.s, dflt.s, sizeof ref.s) == 0);
    static const double scales[] = {1e39, 1e200, 1e-200};
    for (size_t c = 0; c < 3; c++) {
        double *B = malloc(m * n * sizeof *B), s[6];
        for (size_t i = 0; i < m * n; i++)
            B[i] = A[i] * scales[c];
        sb_svd_opts_t o = {.method = SB_METHOD_RANDOMIZED, .mixed = 1};
        sb_svd_t *svd = NULL;
        CHECK(sb_svd_create(NULL, m, n, k, &o, &svd) == SB_OK);
        CHECK(svd && sb_svd_execute(svd, B, m, s, NULL, NULL, NULL, NULL) == SB_OK);
        for (size_t j = 0; j < k; j++)
            CHECKF(fabs(s[j] / scales[c] - ref.s[j]) <= MIXED_SV_TOL * ref.s[0], "scale %g sigma_%zu %.12g vs %.12g",
                   scales[c], j, s[j] / scales[c], ref.s[j]);
        sb_svd_destroy(svd);
        free(B);
    }
    free(A);
}
