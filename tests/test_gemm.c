/* The transposed thin product that reads A in place (src/util/gemm_tn.c,
 * called by gemm_thin.c for the topk and randomized solvers' reads of
 * A^T): against BLAS on every shape class its tiles have (columns of A
 * and of B multiples of the tile or not, rows multiples of the vector or
 * not, leading dimensions above the sizes), in double and in float, and
 * the same bits for C's rows cut into parts (what the thread split does).
 * Skipped where the CPU lacks AVX2 and FMA (the kernel is not used). */
#include <cblas.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../src/util/internal.h"
#include "harness.h"

static double frand(unsigned long long *st) {
    return (double)((*st = *st * 6364136223846793005ULL + 1) >> 11) * 0x1.0p-53 - 0.5;
}

/* max |C - C_blas| / (||a_j|| ||b_q||) over the entries, double */
static double err_d(int rows, int cols, int inner, int pad, unsigned long long seed) {
    int lda = inner + pad, ldb = inner + 2 * pad, ldc = rows + pad;
    double *A = malloc(sizeof(double) * (size_t)lda * rows), *B = malloc(sizeof(double) * (size_t)ldb * cols);
    double *C = malloc(sizeof(double) * (size_t)ldc * cols), *D = malloc(sizeof(double) * (size_t)ldc * cols);
    for (size_t i = 0; i < (size_t)lda * rows; i++)
        A[i] = frand(&seed);
    for (size_t i = 0; i < (size_t)ldb * cols; i++)
        B[i] = frand(&seed);
    for (size_t i = 0; i < (size_t)ldc * cols; i++)
        C[i] = D[i] = 12345; /* entries beyond rows must stay */
    sb_dgemm_tn(rows, cols, inner, A, lda, B, ldb, C, ldc);
    cblas_dgemm(CblasColMajor, CblasTrans, CblasNoTrans, rows, cols, inner, 1, A, lda, B, ldb, 0, D, ldc);
    double worst = 0;
    for (int t = 0; t < cols; t++)
        for (int j = 0; j < ldc; j++) {
            double d = fabs(C[j + (size_t)t * ldc] - D[j + (size_t)t * ldc]);
            worst = fmax(worst, j < rows ? d / (0.25 * inner + 1e-300) : (d > 0 ? INFINITY : 0));
        }
    free(A), free(B), free(C), free(D);
    return worst;
}

static double err_f(int rows, int cols, int inner, int pad, unsigned long long seed) {
    int lda = inner + pad, ldb = inner + 2 * pad, ldc = rows + pad;
    float *A = malloc(sizeof(float) * (size_t)lda * rows), *B = malloc(sizeof(float) * (size_t)ldb * cols);
    float *C = malloc(sizeof(float) * (size_t)ldc * cols);
    for (size_t i = 0; i < (size_t)lda * rows; i++)
        A[i] = (float)frand(&seed);
    for (size_t i = 0; i < (size_t)ldb * cols; i++)
        B[i] = (float)frand(&seed);
    for (size_t i = 0; i < (size_t)ldc * cols; i++)
        C[i] = 12345;
    sb_sgemm_tn(rows, cols, inner, A, lda, B, ldb, C, ldc);
    double worst = 0;
    for (int t = 0; t < cols; t++)
        for (int j = 0; j < ldc; j++) {
            double d = 0;
            if (j >= rows) {
                worst = fmax(worst, C[j + (size_t)t * ldc] == 12345 ? 0 : INFINITY);
                continue;
            }
            for (int i = 0; i < inner; i++) /* the exact product of the floats, in double */
                d += (double)A[i + (size_t)j * lda] * (double)B[i + (size_t)t * ldb];
            worst = fmax(worst, fabs(C[j + (size_t)t * ldc] - d) / (0.25 * inner));
        }
    free(A), free(B), free(C);
    return worst;
}

SB_TEST(tn_matches_blas) {
    if (!sb_gemm_tn_usable(1)) SKIP("no AVX2 and FMA: the kernel is not used");
    static const int rows[] = {1, 3, 4, 5, 8, 13}, cols[] = {1, 2, 3, 4, 8, 18}, inner[] = {1, 3, 4, 7, 8, 9, 64, 301};
    unsigned long long seed = 7;
    for (size_t a = 0; a < sizeof rows / sizeof rows[0]; a++)
        for (size_t b = 0; b < sizeof cols / sizeof cols[0]; b++)
            for (size_t c = 0; c < sizeof inner / sizeof inner[0]; c++)
                for (int pad = 0; pad <= 3; pad += 3) {
                    double ed = err_d(rows[a], cols[b], inner[c], pad, seed++);
                    double ef = err_f(rows[a], cols[b], inner[c], pad, seed++);
                    /* sums of `inner` products of size <= 1/4: rounding, eps per term at most */
                    CHECKF(ed <= 4 * 0x1.0p-52, "double %dx%d inner %d pad %d: %.3g", rows[a], cols[b], inner[c], pad,
                           ed);
                    CHECKF(ef <= 4 * 0x1.0p-23, "float %dx%d inner %d pad %d: %.3g", rows[a], cols[b], inner[c], pad,
                           ef);
                }
}

/* C's rows in parts (as gemm_thin.c cuts them over threads): the same bits
 * as one call, since every entry is one fixed sum over A's column. */
SB_TEST(tn_parts_same_bits) {
    if (!sb_gemm_tn_usable(1)) SKIP("no AVX2 and FMA: the kernel is not used");
    int rows = 23, cols = 18, inner = 517;
    unsigned long long seed = 3;
    double *A = malloc(sizeof(double) * (size_t)inner * rows), *B = malloc(sizeof(double) * (size_t)inner * cols);
    double *C = malloc(sizeof(double) * (size_t)rows * cols), *D = malloc(sizeof(double) * (size_t)rows * cols);
    for (int i = 0; i < inner * rows; i++)
        A[i] = frand(&seed);
    for (int i = 0; i < inner * cols; i++)
        B[i] = frand(&seed);
    sb_dgemm_tn(rows, cols, inner, A, inner, B, inner, C, rows);
    int cut[] = {0, 5, 6, 17, rows};
    for (int p = 0; p + 1 < (int)(sizeof cut / sizeof cut[0]); p++)
        sb_dgemm_tn(cut[p + 1] - cut[p], cols, inner, A + (size_t)cut[p] * inner, inner, B, inner, D + cut[p], rows);
    CHECK(memcmp(C, D, sizeof(double) * (size_t)rows * cols) == 0);
    free(A), free(B), free(C), free(D);
}
