/* C = A^T B for a large A and a thin B without packing A (gemm_thin.c
 * calls it for its transposed products where the CPU has AVX2 and FMA).
 *
 * OpenBLAS copies every panel of A into a packed buffer before its kernel
 * reads it; with B only 8-18 columns wide that copy is a third of the
 * product (perf on the 4096^2 io matrix: dgemm_itcopy 14 %, the kernel
 * 52 % of `topk`).  Here each of C's entries is a dot product of a column
 * of A with a column of B, both contiguous: four columns of A and three of
 * B make a tile of 12 vector accumulators, the rows swept top to bottom in
 * one go, so the four columns of A (4 m values) stay in L2 while the
 * groups of B pass, and A streams from memory once.  On the AMD EPYC VM,
 * m = n = 4096, 18 columns, one thread: 21-24 ms against dgemm's 32-34 ms.
 *
 * Each C entry is one sum over all m rows in a fixed order (four, or eight
 * in float, partial sums a lane, then the lanes, then the rows left over),
 * whatever the thread split, so a cut of C's rows over threads gives the
 * same bits as one call. */
#include <stddef.h>

#include "util/internal.h"

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
#include <immintrin.h>
#define TN_AVX2 1

#define TN_TA 4 /* columns of A a tile */
#define TN_TB 3 /* columns of B a tile */

#define TN_ATTR __attribute__((target("avx2,fma"), always_inline)) static inline

TN_ATTR double hsum_d(__m256d v) {
    __m128d l = _mm_add_pd(_mm256_castpd256_pd128(v), _mm256_extractf128_pd(v, 1));
    return _mm_cvtsd_f64(_mm_add_sd(l, _mm_unpackhi_pd(l, l)));
}

TN_ATTR float hsum_f(__m256 v) {
    __m128 l = _mm_add_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps(v, 1));
    l = _mm_add_ps(l, _mm_movehl_ps(l, l));
    return _mm_cvtss_f32(_mm_add_ss(l, _mm_shuffle_ps(l, l, 1)));
}

/* One tile: C[p, q] = a_p . b_q for na <= TN_TA columns a_p (stride lda)
 * and nb <= TN_TB columns b_q (stride ldb) of m rows, into c (ldc).  na
 * and nb are constants where it is inlined, so the accumulators are
 * registers. */
#define TN_TILE(NAME, R, V, LANES, SET0, LOAD, FMA, HSUM)                                                              \
    TN_ATTR void NAME(const R *a, size_t lda, int na, const R *b, size_t ldb, int nb, int m, R *c, size_t ldc) {       \
        V s[TN_TA][TN_TB];                                                                                             \
        for (int p = 0; p < TN_TA; p++)                                                                                \
            for (int q = 0; q < TN_TB; q++)                                                                            \
                s[p][q] = SET0();                                                                                      \
        int i = 0;                                                                                                     \
        for (; i + LANES <= m; i += LANES) {                                                                           \
            V y[TN_TB];                                                                                                \
            _Pragma("GCC unroll 3") for (int q = 0; q < nb; q++) y[q] = LOAD(b + (size_t)q * ldb + i);                 \
            _Pragma("GCC unroll 4") for (int p = 0; p < na; p++) {                                                     \
                V x = LOAD(a + (size_t)p * lda + i);                                                                   \
                _Pragma("GCC unroll 3") for (int q = 0; q < nb; q++) s[p][q] = FMA(x, y[q], s[p][q]);                  \
            }                                                                                                          \
        }                                                                                                              \
        _Pragma("GCC unroll 4") for (int p = 0; p < na; p++) _Pragma("GCC unroll 3") for (int q = 0; q < nb; q++) {    \
            R t = HSUM(s[p][q]);                                                                                       \
            for (int r = i; r < m; r++)                                                                                \
                t += a[(size_t)p * lda + r] * b[(size_t)q * ldb + r];                                                  \
            c[p + (size_t)q * ldc] = t;                                                                                \
        }                                                                                                              \
    }

TN_TILE(tile_d, double, __m256d, 4, _mm256_setzero_pd, _mm256_loadu_pd, _mm256_fmadd_pd, hsum_d)
TN_TILE(tile_f, float, __m256, 8, _mm256_setzero_ps, _mm256_loadu_ps, _mm256_fmadd_ps, hsum_f)

/* C (rows x cols) = A^T B: A is inner x rows, B inner x cols.  The tiles
 * of TN_TA x TN_TB, then the columns of A and B left over; each call of
 * the tile with constant sizes is its own specialisation. */
#define TN_MAIN(NAME, TILE, R)                                                                                         \
    __attribute__((target("avx2,fma"))) static void NAME(int rows, int cols, int inner, const R *A, size_t lda,        \
                                                         const R *B, size_t ldb, R *C, size_t ldc) {                   \
        for (int j = 0; j < rows; j += TN_TA) {                                                                        \
            const R *a = A + (size_t)j * lda;                                                                          \
            int na = rows - j < TN_TA ? rows - j : TN_TA;                                                              \
            for (int t = 0; t < cols; t += TN_TB) {                                                                    \
                const R *b = B + (size_t)t * ldb;                                                                      \
                R *c = C + j + (size_t)t * ldc;                                                                        \
                int nb = cols - t < TN_TB ? cols - t : TN_TB;                                                          \
                if (na == 4 && nb == 3)                                                                                \
                    TILE(a, lda, 4, b, ldb, 3, inner, c, ldc);                                                         \
                else if (na == 4 && nb == 2)                                                                           \
                    TILE(a, lda, 4, b, ldb, 2, inner, c, ldc);                                                         \
                else if (na == 4)                                                                                      \
                    TILE(a, lda, 4, b, ldb, 1, inner, c, ldc);                                                         \
                else                                                                                                   \
                    for (int p = 0; p < na; p++)                                                                       \
                        for (int q = 0; q < nb; q++)                                                                   \
                            TILE(a + (size_t)p * lda, lda, 1, b + (size_t)q * ldb, ldb, 1, inner,                      \
                                 c + p + (size_t)q * ldc, ldc);                                                        \
            }                                                                                                          \
        }                                                                                                              \
    }

TN_MAIN(tn_d, tile_d, double)
TN_MAIN(tn_f, tile_f, float)

static int tn_cpu_ok(void) {
    static int has = -1; /* the same value from every thread */
    if (has < 0) has = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") ? 1 : 0;
    return has;
}
#endif

/* Where the kernel pays: a thin B (OpenBLAS's blocking wins for wide ones). */
#define TN_MAX_COLS 64

int sb_gemm_tn_usable(int cols) {
#ifdef TN_AVX2
    return cols >= 1 && cols <= TN_MAX_COLS && tn_cpu_ok();
#else
    (void)cols;
    return 0;
#endif
}

void sb_dgemm_tn(int rows, int cols, int inner, const double *A, int lda, const double *B, int ldb, double *C,
                 int ldc) {
#ifdef TN_AVX2
    tn_d(rows, cols, inner, A, (size_t)lda, B, (size_t)ldb, C, (size_t)ldc);
#else
    (void)rows, (void)cols, (void)inner, (void)A, (void)lda, (void)B, (void)ldb, (void)C, (void)ldc;
#endif
}

void sb_sgemm_tn(int rows, int cols, int inner, const float *A, int lda, const float *B, int ldb, float *C, int ldc) {
#ifdef TN_AVX2
    tn_f(rows, cols, inner, A, (size_t)lda, B, (size_t)ldb, C, (size_t)ldc);
#else
    (void)rows, (void)cols, (void)inner, (void)A, (void)lda, (void)B, (void)ldb, (void)C, (void)ldc;
#endif
}
