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

/* The largest |difference| of the reconstructions sum_j s_j u_j v_j^T of
 * two k-term fits over every cell, relative to the largest of the first. */
static double recon_diff(const double *s0, const double *U0, const double *V0, const double *s1, const double *U1,
                         const double *V1, size_t m, size_t n, size_t k) {
    double d = 0, big = 0;
    for (size_t c = 0; c < n; c++)
        for (size_t r = 0; r < m; r++) {
            double a = 0, b = 0;
            for (size_t j = 0; j < k; j++)
                a += s0[j] * U0[r + j * m] * V0[c + j * n], b += s1[j] * U1[r + j * m] * V1[c + j * n];
            d = fmax(d, fabs(a - b)), big = fmax(big, fabs(a));
        }
    return big > 0 ? d / big : d;
}

/* A warm start (sb_fit_set_start, the refits of job_cv.c): a fit started
 * from its own converged factors stops at once (a sweep or two a stage,
 * where the cold fit took tens) with the same fit, for four terms (the
 * joint stages alone) and six (then two pieces); started from the fit of
 * a nearby matrix (the values moved 1 %) it gets that matrix's own fit in
 * fewer sweeps; and the start is taken once (the next fit is cold: the
 * same bits as a fresh one). */
SB_TEST(warm_start_from_converged_fit_stops_at_once) {
    enum { M = 48, N = 40, KMAX = 6 };
    static double A[M * N], B[M * N];
    static unsigned char mask[M * N];
    uint64_t seed = 4242;
    for (size_t c = 0; c < N; c++)
        for (size_t r = 0; r < M; r++) {
            double x = (double)r / M, y = (double)c / N;
            A[r + c * M] = exp(-8 * (x - y) * (x - y)) + 0.3 * x * y + 0.02 * uniform(&seed);
            B[r + c * M] = A[r + c * M] * (1 + 0.01 * uniform(&seed));
            mask[r + c * M] = uniform(&seed) < 0.25;
        }
    sb_fit_opts_t o = {0};
    o.max_iters = 300, o.tol = 1e-6;
    for (size_t k = 4; k <= KMAX; k += 2) {
        static double s[4][KMAX], U[4][M * KMAX], V[4][N * KMAX];
        sb_fit_info_t cold = {0}, warm = {0}, near = {0}, again = {0};
        sb_fit_t *f = NULL, *g = NULL;
        CHECK(sb_fit_create(NULL, M, N, k, &f) == SB_OK && sb_fit_create(NULL, M, N, k, &g) == SB_OK);
        if (!f || !g) return;
        CHECK(fit_chain(f, A, M, mask, &o, s[0], U[0], V[0], &cold) == SB_OK && cold.converged);
        sb_fit_set_start(f, s[0], U[0], V[0]);
        CHECK(fit_chain(f, A, M, mask, &o, s[1], U[1], V[1], &warm) == SB_OK && warm.converged);
        int stages = k == 4 ? 2 : 4; /* the last joint stage (term alone, joint); each piece */
        CHECKF(warm.iterations <= 2 * stages && warm.iterations * 5 < cold.iterations,
               "k = %zu: started from its converged fit it swept %d times (cold %d)", k, warm.iterations,
               cold.iterations);
        double d = recon_diff(s[0], U[0], V[0], s[1], U[1], V[1], M, N, k);
        CHECKF(d < 1e-4, "k = %zu: started from its converged fit it moved by %.3g", k, d);
        CHECKF(warm.rel_err <= cold.rel_err * (1 + 1e-6), "k = %zu: error %.9g from the start, %.9g cold", k,
               warm.rel_err, cold.rel_err);
        /* a nearby matrix: from the fit of A, B's own fit in fewer sweeps */
        CHECK(fit_chain(g, B, M, mask, &o, s[2], U[2], V[2], &near) == SB_OK);
        sb_fit_set_start(f, s[0], U[0], V[0]);
        CHECK(fit_chain(f, B, M, mask, &o, s[3], U[3], V[3], &warm) == SB_OK);
        CHECKF(warm.iterations < near.iterations, "k = %zu: from the nearby fit %d sweeps, cold %d", k, warm.iterations,
               near.iterations);
        CHECKF(warm.rel_err <= near.rel_err * 1.01, "k = %zu: from the nearby fit error %.6g, cold %.6g", k,
               warm.rel_err, near.rel_err);
        /* taken once: the next fit is cold, a fresh fit's bits */
        CHECK(fit_chain(f, B, M, mask, &o, s[3], U[3], V[3], &again) == SB_OK);
        CHECKF(again.iterations == near.iterations && memcmp(s[3], s[2], k * sizeof *s[2]) == 0 &&
                   memcmp(U[3], U[2], M * k * sizeof *U[2]) == 0,
               "k = %zu: the fit after a warm one is not cold", k);
        sb_fit_destroy(f);
        sb_fit_destroy(g);
    }
}
