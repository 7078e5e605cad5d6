/* The masked fit's sweeps (src/solve/fit_sweep.c, fit_cells.c): the
 * right-hand sides' product sums every entry over the inner index in
 * order, as the plain loop does, so its bits are the same on every CPU and
 * for every block shape (rows not a multiple of the block, 1 to 9
 * columns). */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "solve/fit_impl.h" /* not exported, in the static archive */

static double uniform(uint64_t *s) {
    *s = *s * 6364136223846793005ull + 1442695040888963407ull;
    return (double)(*s >> 11) * 0x1.0p-53 - 0.5;
}

SB_TEST(dense_product_sums_in_order) {
    static const size_t rows[] = {1, 7, 8, 37, 64, 992}, inner[] = {1, 53, 64, 992};
    uint64_t seed = 12345;
    for (size_t a = 0; a < sizeof rows / sizeof *rows; a++)
        for (size_t b = 0; b < sizeof inner / sizeof *inner; b++)
            for (size_t kf = 1; kf <= 9; kf++) {
                size_t m = rows[a], n = inner[b], ldb = n + 3, ldc = m + 5;
                double *A = malloc(m * n * sizeof *A), *B = malloc(ldb * kf * sizeof *B);
                double *C = malloc(ldc * kf * sizeof *C), *R = malloc(ldc * kf * sizeof *R);
                CHECK(A && B && C && R);
                if (!A || !B || !C || !R) return;
                for (size_t i = 0; i < m * n; i++)
                    A[i] = uniform(&seed) * (i % 7 == 0 ? 1e6 : 1);
                for (size_t i = 0; i < ldb * kf; i++)
                    B[i] = uniform(&seed);
                memset(C, 0, ldc * kf * sizeof *C);
                memset(R, 0, ldc * kf * sizeof *R);
                for (size_t j = 0; j < kf; j++)
                    for (size_t i = 0; i < m; i++) {
                        double s = 0;
                        for (size_t t = 0; t < n; t++)
                            s += A[i + t * m] * B[t + j * ldb];
                        R[i + j * ldc] = s;
                    }
                fit_dense_product(A, m, n, B, ldb, kf, C, ldc);
                CHECKF(memcmp(C, R, ldc * kf * sizeof *C) == 0, "%zu x %zu times %zu columns: not the plain sums", m, n,
                       kf);
                free(A), free(B), free(C), free(R);
            }
}
