/* The real DFT over the columns of a tall matrix (rdft.h): blocks of
 * RDFT_B rows at a time, each an iterative radix-2 complex FFT of length
 * R whose butterflies run over the block's rows (contiguous, so every
 * butterfly is a vector loop), the block's 2 R RDFT_B values in cache. */
#include "util/rdft.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "util/internal.h"
#include "util/parallel.h"

#define RDFT_B 64 /* lanes (two rows each) a block: 2 R RDFT_B doubles, 256 KiB at R = 256 */

int sb_rdft_fits(size_t R) { return R >= 4 && R <= ((size_t)1 << 20) && (R & (R - 1)) == 0; }

typedef struct rdft_job {
    size_t R, nb, r0, r1, ldx, ldc, lds;
    const double *X, *tc, *ts; /* twiddles: cos, sin (2 pi k / R), k < R / 2 */
    const size_t *rev;         /* bit reversal of 0 .. R - 1 */
    double *C, *S, *buf;       /* buf: 2 R RDFT_B */
} rdft_job_t;

/* The butterflies of one block of n lanes: re, im [R][RDFT_B].  AVX2
 * where the CPU has it (the same operations, no contraction: the same
 * bits either way). */
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
__attribute__((target_clones("avx2", "default")))
#endif
static void
fft_block(const rdft_job_t *j, double *restrict re, double *restrict im, size_t n) {
    size_t R = j->R, B = RDFT_B;
    for (size_t len = 2; len <= R; len *= 2) {
        size_t half = len / 2, step = R / len;
        for (size_t s = 0; s < R; s += len)
            for (size_t k = 0; k < half; k++) {
                double wr = j->tc[k * step], wi = -j->ts[k * step]; /* e^{-i 2 pi k step / R} */
                double *ar = re + (s + k) * B, *ai = im + (s + k) * B;
                double *br = re + (s + k + half) * B, *bi = im + (s + k + half) * B;
                for (size_t r = 0; r < n; r++) {
                    double tr = wr * br[r] - wi * bi[r], ti = wr * bi[r] + wi * br[r];
                    br[r] = ar[r] - tr;
                    bi[r] = ai[r] - ti;
                    ar[r] += tr;
                    ai[r] += ti;
                }
            }
    }
}

/* Two real rows a lane: z = x_a + i x_b, whose transform Z gives
 *   X_a(f) = (Z(f) + conj Z(R - f)) / 2,  X_b(f) = (Z(f) - conj Z(R - f)) / 2i,
 * and C = Re X, S = -Im X of each. */
static void *rdft_rows(void *arg) {
    const rdft_job_t *j = arg;
    size_t R = j->R, B = RDFT_B;
    double *re = j->buf, *im = re + R * B;
    for (size_t r0 = j->r0; r0 < j->r1; r0 += 2 * B) {
        size_t m = j->r1 - r0 < 2 * B ? j->r1 - r0 : 2 * B, n = (m + 1) / 2, nb2 = m - n; /* lanes; rows b */
        for (size_t d = 0; d < R; d++) {
            const double *x = j->X + r0 + d * j->ldx;
            memcpy(re + j->rev[d] * B, x, n * sizeof *re);
            memcpy(im + j->rev[d] * B, x + n, nb2 * sizeof *im);
            memset(im + j->rev[d] * B + nb2, 0, (n - nb2) * sizeof *im);
        }
        fft_block(j, re, im, n);
        for (size_t f = 0; f < j->nb; f++) {
            const double *zr = re + f * B, *zi = im + f * B, *cr = re + ((R - f) % R) * B, *ci = im + ((R - f) % R) * B;
            double *ca = j->C + r0 + f * j->ldc, *sa = j->S ? j->S + r0 + f * j->lds : NULL;
            for (size_t r = 0; r < n; r++)
                ca[r] = 0.5 * (zr[r] + cr[r]);
            for (size_t r = 0; r < nb2; r++)
                ca[n + r] = 0.5 * (zi[r] + ci[r]);
            for (size_t r = 0; sa && r < n; r++)
                sa[r] = -0.5 * (zi[r] - ci[r]);
            for (size_t r = 0; sa && r < nb2; r++)
                sa[n + r] = 0.5 * (zr[r] - cr[r]);
        }
    }
    return NULL;
}

int sb_rdft_cols(size_t R, size_t nb, size_t rows, const double *X, size_t ldx, double *C, size_t ldc, double *S,
                 size_t lds, int nt) {
    if (!sb_rdft_fits(R) || nb > R / 2 + 1 || !X || !C) return 0;
    nt = nt < 1 ? 1 : (nt > SB_THREADS_MAX ? SB_THREADS_MAX : nt);
    if ((size_t)nt > rows / (2 * RDFT_B)) nt = rows / (2 * RDFT_B) > 0 ? (int)(rows / (2 * RDFT_B)) : 1;
    double *tw = malloc((R + 2 * R * RDFT_B * (size_t)nt) * sizeof *tw);
    size_t *rev = malloc(R * sizeof *rev);
    if (!tw || !rev) {
        free(tw);
        free(rev);
        return 0;
    }
    size_t bits = 0;
    while (((size_t)1 << bits) < R)
        bits++;
    for (size_t d = 0; d < R; d++) {
        size_t v = 0;
        for (size_t b = 0; b < bits; b++)
            v |= ((d >> b) & 1u) << (bits - 1 - b);
        rev[d] = v;
    }
    for (size_t k = 0; k < R / 2; k++) {
        tw[k] = cos(2 * SB_PI * (double)k / (double)R);
        tw[R / 2 + k] = sin(2 * SB_PI * (double)k / (double)R);
    }
    rdft_job_t jobs[SB_THREADS_MAX];
    for (int t = 0; t < nt; t++) {
        jobs[t] =
            (rdft_job_t){R, nb, 0, 0, ldx, ldc, lds, X, tw, tw + R / 2, rev, C, S, tw + R + 2 * R * RDFT_B * (size_t)t};
        sb_part(rows, t, nt, &jobs[t].r0, &jobs[t].r1);
    }
    sb_parallel_run(rdft_rows, jobs, sizeof *jobs, nt, NULL, NULL);
    free(tw);
    free(rev);
    return 1;
}
