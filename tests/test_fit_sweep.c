/* The masked fit's sweeps (src/solve/fit_sweep.c, fit_cells.c): the
 * right-hand sides' product sums every entry over the inner index in
 * order, as the plain loop does, so its bits are the same on every CPU and
 * for every block shape (rows not a multiple of the block, 1 to 9
 * columns). */
#include <math.h>
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

/* One fit run on several tables (fit_chain: the nested pieces and the
 * channels share the cells gathered for a mask, fit_cells_build keeps
 * them for the next run on the same mask) gives what a fresh fit gives
 * each, to the bit: new values on the same mask, another mask, and back.
 * 48 x 40 cells (dense residual; transposed blocks and their edges), six
 * terms (four jointly, then two pieces), with the taps' layout (their
 * rounds run the stages on other masks in between). */
SB_TEST(cells_kept_between_runs_change_nothing) {
    enum { M = 48, N = 40, K = 6, RUNS = 4 };
    static double A[2][M * N];
    static unsigned char mask[2][M * N];
    uint64_t seed = 777;
    for (int t = 0; t < 2; t++)
        for (size_t c = 0; c < N; c++)
            for (size_t r = 0; r < M; r++) {
                double x = (double)r / M, y = (double)c / N;
                A[t][r + c * M] = (t ? 2.0 : 1.0) * exp(-8 * (x - y) * (x - y)) + 0.3 * x * y + 0.05 * uniform(&seed);
                mask[t][r + c * M] = uniform(&seed) < (t ? 0.3 : 0.35);
            }
    static const int table[RUNS] = {0, 1, 0, 1}, mk[RUNS] = {0, 0, 1, 0};
    sb_fit_opts_t o = {0};
    o.tex[0][0] = 6, o.tex[0][1] = 8, o.tex[1][0] = 5, o.tex[1][1] = 8;
    sb_fit_t *kept = NULL;
    CHECK(sb_fit_create(NULL, M, N, K, &kept) == SB_OK);
    for (int run = 0; run < RUNS && kept; run++) {
        double s[2][K], U[2][M * K], V[2][N * K];
        sb_fit_t *fresh = NULL;
        CHECK(sb_fit_create(NULL, M, N, K, &fresh) == SB_OK);
        if (!fresh) break;
        const double *a = A[table[run]];
        const unsigned char *mm = mask[mk[run]];
        CHECK(fit_chain(kept, a, M, mm, &o, s[0], U[0], V[0], NULL) == SB_OK);
        CHECK(fit_chain(fresh, a, M, mm, &o, s[1], U[1], V[1], NULL) == SB_OK);
        CHECKF(memcmp(s[0], s[1], sizeof s[0]) == 0 && memcmp(U[0], U[1], sizeof U[0]) == 0 &&
                   memcmp(V[0], V[1], sizeof V[0]) == 0,
               "run %d (table %d, mask %d): the kept fit differs from a fresh one (sigma_0 %.17g, %.17g)", run,
               table[run], mk[run], s[0][0], s[1][0]);
        sb_fit_destroy(fresh);
    }
    sb_fit_destroy(kept);
}
