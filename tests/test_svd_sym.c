/* TOPK on a symmetric matrix (an io matrix of a reciprocal source is
 * one): the execute finds A = A^T entry for entry (sb_svd_symmetric) and
 * then reads every product A B as A^T B (gemm_tn.c's kernel, which reads A
 * in place).  Checked here: the check itself on every block edge and both
 * precisions; that a symmetric matrix with eigenvalues of both signs takes
 * that path and gives LAPACK's singular values and a certified residual;
 * and that a matrix one entry away from symmetric does not take it and
 * still gives its own values (read as symmetric it would give those of a
 * mixture of A and A^T). */
#include <cblas.h>
#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../src/solve/svd_internal.h"
#include "../src/util/internal.h"
#include "harness.h"
#include "sepbrdf/sepbrdf.h"

static double urand(unsigned long long *st) {
    return (double)((*st = *st * 6364136223846793005ULL + 1442695040888963407ULL) >> 11) * 0x1.0p-53 - 0.5;
}

/* n x n (ld lda, padding filled with garbage), symmetric */
static double *sym_matrix(size_t n, size_t lda, unsigned long long *st) {
    double *A = malloc(lda * n * sizeof *A);
    for (size_t i = 0; i < lda * n; i++)
        A[i] = 1e30; /* the padding: never compared */
    for (size_t j = 0; j < n; j++)
        for (size_t i = 0; i <= j; i++)
            A[i + j * lda] = A[j + i * lda] = urand(st);
    return A;
}

SB_TEST(check_every_edge) {
    static const size_t sizes[] = {1, 2, 63, 64, 65, 130};
    unsigned long long st = 11;
    for (size_t z = 0; z < sizeof sizes / sizeof sizes[0]; z++) {
        size_t n = sizes[z], lda = n + 3;
        double *A = sym_matrix(n, lda, &st);
        float *F = malloc(lda * n * sizeof *F);
        for (size_t i = 0; i < lda * n; i++)
            F[i] = (float)A[i];
        CHECKF(sb_svd_symmetric(A, n, lda, 0) && sb_svd_symmetric(F, n, lda, 1), "n %zu: symmetric", n);
        /* one entry off, above or below the diagonal, in the first, a middle and the last block */
        size_t at[][2] = {{0, 1}, {1, 0}, {n / 2, n - 1}, {n - 1, n / 3}, {n - 1, n - 2}};
        for (size_t p = 0; p < sizeof at / sizeof at[0]; p++) {
            size_t i = at[p][0], j = at[p][1];
            if (i >= n || j >= n || i == j) continue;
            double keep = A[i + j * lda];
            float keepf = F[i + j * lda];
            A[i + j * lda] = nextafter(keep, 2.0);
            F[i + j * lda] = nextafterf(keepf, 2.0f);
            CHECKF(!sb_svd_symmetric(A, n, lda, 0), "n %zu: (%zu, %zu) one ulp off, double", n, i, j);
            CHECKF(!sb_svd_symmetric(F, n, lda, 1), "n %zu: (%zu, %zu) one ulp off, float", n, i, j);
            A[i + j * lda] = NAN;
            CHECKF(!sb_svd_symmetric(A, n, lda, 0), "n %zu: a NaN is not symmetric", n);
            A[i + j * lda] = keep;
            F[i + j * lda] = keepf;
        }
        free(A);
        free(F);
    }
}

/* TOPK of A (n x n) against LAPACK: the largest |s_j - ref_j| / ref_0, and
 * whether the execute took the symmetric path. */
static double topk_against_gesdd(const double *A, size_t n, size_t k, int *sym, double *resid) {
    double *C = malloc(n * n * sizeof *C), *ref = malloc(n * sizeof *ref), *s = malloc(k * sizeof *s);
    double *U = malloc(n * k * sizeof *U), *V = malloc(n * k * sizeof *V), *AV = malloc(n * k * sizeof *AV);
    memcpy(C, A, n * n * sizeof *C);
    double worst = INFINITY;
    sb_svd_opts_t o = {.method = SB_METHOD_TOPK};
    sb_svd_t *svd = NULL;
    if (LAPACKE_dgesdd(LAPACK_COL_MAJOR, 'N', (int)n, (int)n, C, (int)n, ref, NULL, 1, NULL, 1) == 0 &&
        sb_svd_create(NULL, n, n, k, &o, &svd) == SB_OK && sb_svd_execute(svd, A, n, s, U, V, NULL, NULL) == SB_OK) {
        *sym = svd->sym;
        worst = 0;
        for (size_t j = 0; j < k; j++)
            worst = fmax(worst, fabs(s[j] - ref[j]) / ref[0]);
        /* the certificate, formed here from A itself: max_j |A v_j - s_j u_j| / s_1 */
        cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, (int)n, (int)k, (int)n, 1, A, (int)n, V, (int)n, 0, AV,
                    (int)n);
        *resid = 0;
        for (size_t j = 0; j < k; j++) {
            double r2 = 0;
            for (size_t i = 0; i < n; i++)
                r2 += (AV[i + j * n] - s[j] * U[i + j * n]) * (AV[i + j * n] - s[j] * U[i + j * n]);
            *resid = fmax(*resid, sqrt(r2) / s[0]);
        }
    }
    sb_svd_destroy(svd);
    free(C), free(ref), free(s), free(U), free(V), free(AV);
    return worst;
}

SB_TEST(topk_symmetric_both_signs) {
    if (!sb_gemm_tn_usable(18)) SKIP("no AVX2 and FMA: the symmetric path is not taken");
    size_t n = 700, k = 8;
    unsigned long long st = 5;
    /* A = sum_j lambda_j x_j x_j^T + noise, lambda_j = (-1)^j 0.8^j: a decaying spectrum of both signs, symmetric */
    double *A = sym_matrix(n, n, &st), *x = malloc(n * sizeof *x);
    for (size_t i = 0; i < n * n; i++)
        A[i] *= 1e-3;
    for (size_t t = 0; t < 24; t++) {
        double lam = (t % 2 ? -1 : 1) * pow(0.8, (double)t), nx = 0;
        for (size_t i = 0; i < n; i++) {
            x[i] = urand(&st);
            nx += x[i] * x[i];
        }
        for (size_t j = 0; j < n; j++)
            for (size_t i = 0; i < n; i++)
                A[i + j * n] += lam * (x[i] * x[j]) / nx; /* the same bits as its mirror */
    }
    int sym = -1;
    double resid = 1;
    double d = topk_against_gesdd(A, n, k, &sym, &resid);
    CHECKF(sym == 1, "symmetric A: path %d", sym);
    CHECKF(d <= 1e-10, "symmetric A: values %.3g from LAPACK's", d);
    CHECKF(resid <= 0x1.0p-38, "symmetric A: residual %.3g", resid);
    /* one entry changed (its mirror not): the general path, and this matrix's own values */
    A[n - 1 + (n / 2) * n] += 2;
    double d2 = topk_against_gesdd(A, n, k, &sym, &resid);
    CHECKF(sym == 0, "one entry off: path %d", sym);
    CHECKF(d2 <= 1e-10, "one entry off: values %.3g from LAPACK's", d2);
    CHECKF(resid <= 0x1.0p-38, "one entry off: residual %.3g", resid);
    free(A);
    free(x);
}
