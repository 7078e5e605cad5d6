/* Private helpers shared by the library modules. */
#ifndef SEPBRDF_INTERNAL_H
#define SEPBRDF_INTERNAL_H

#include <stddef.h>
#include <stdio.h>

#include "sepbrdf/common.h"
#include "util/shared.h"

char *sb_strdup(const char *s);
/* Versioned options (job.h, factor.h): the caller's struct `in`, whose
 * size field says `given` bytes (0: size0, the struct before it had a
 * size), as this library's struct of `size` bytes in out: the bytes the
 * caller's headers had, the rest zero (the defaults).  SB_ERR_ARG for a
 * size beyond `size` (newer headers) or below a size_t; `what` names the
 * struct in the message.  The caller then sets out's size field. */
sb_result_t sb_opts_take(sb_context_t *ctx, const void *in, size_t given, size_t size0, void *out, size_t size,
                         const char *what);
/* printf into a new string of any length (the caller frees it); NULL when
 * out of memory. */
char *sb_format(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
/* malloc with the overflow-checked product count * size and the memory
 * limit; reports through ctx naming `what`.  NULL on failure. */
void *sb_alloc(sb_context_t *ctx, size_t count, size_t size, const char *what);
void *sb_calloc(sb_context_t *ctx, size_t count, size_t size, const char *what);
/* sb_alloc for large buffers: backed by huge pages where the system offers
 * them (fewer page faults on first touch); released with free(). */
void *sb_alloc_large(sb_context_t *ctx, size_t count, size_t size, const char *what);
/* Below what size glibc's malloc serves blocks from a heap on transparent
 * huge pages, by the GLIBC_TUNABLES string it started with (NULL: none);
 * 0 where the heap is not on huge pages.  sb_alloc_large takes such
 * buffers from the heap (util.c). */
size_t sb_heap_huge_below(const char *tunables);

/* Open `path` for reading as a stream when it is a regular file of at
 * most max bytes; a device, FIFO, socket or folder is refused without
 * waiting for it (no read of /dev/zero or of a FIFO without a writer).
 * `what` starts the messages ("scene: pairs file").  NULL and *r set
 * (SB_ERR_IO, or SB_ERR_FORMAT for a file larger than max) on failure. */
FILE *sb_fopen_regular(sb_context_t *ctx, const char *path, const char *what, unsigned long long max, sb_result_t *r);

/* Write the n parts (bytes sizes[i]) to `path` under the temporary name
 * "PATH.tmp-PID", then rename; the temporary is removed on failure.
 * Returns 0 or the errno of the failure (ENAMETOOLONG for a long path). */
int sb_write_atomic(const char *path, const void *const *parts, const size_t *sizes, size_t n);

/* While from is set, sb_error writes `to` for every occurrence of `from` in
 * its messages (an output set names its target, not its staging folder).
 * Both strings stay owned by the caller; from NULL ends it. */
/* The slot of ctx that util/ctx_memo.c keeps its memo in (its address),
 * and the function sb_context_destroy frees what it holds with (set when
 * not NULL). */
void **sb_context_memo_slot(sb_context_t *ctx, void (*memo_free)(void *));
void sb_context_alias(sb_context_t *ctx, const char *from, const char *to);
/* The group of ctx (sb_context_set_group): whether it has more than one
 * process; whether this process reads block `block` (always when alone);
 * buf[0..n) combined over the group with op (nothing when alone;
 * SB_ERR_IO when the group's reduce fails). */
int sb_group_active(const sb_context_t *ctx);
int sb_group_owns(const sb_context_t *ctx, size_t block);
sb_result_t sb_group_reduce(sb_context_t *ctx, double *buf, size_t n, int op);

/* Most threads any parallel loop uses (parallel.h). */
#define SB_THREADS_MAX 64

/* A hot loop compiled twice, with FMA (and 256-bit AVX) and for the
 * baseline x86-64 the library is built for, the one the CPU runs chosen
 * when the library loads (GCC's target_clones, on x86-64 Linux; elsewhere
 * the baseline only).  Functions it inlines are compiled with it.
 * SB_AVX2_CLONES: the same with 256-bit AVX2 and no FMA (and C11 does
 * not contract a * b + c), so the same operations and the same bits as
 * the baseline, four doubles a vector instead of two.  On static
 * functions only: GCC exports a non-static function's clones and
 * resolver whatever -fvisibility says (exports.match_headers). */
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__)
#define SB_FMA_CLONES __attribute__((target_clones("fma", "default")))
#define SB_AVX2_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define SB_FMA_CLONES
#define SB_AVX2_CLONES
#endif

/* Number of worker threads to use: 1 inside a job of a parallel call
 * (parallel.h), else `requested` if > 0, else env SEPBRDF_THREADS or the
 * online cores; at most SB_THREADS_MAX. */
int sb_thread_count(int requested);

/* The power of two 2^-e nearest below 1 / amax (amax in [2^(e-1), 2^e)),
 * e clamped to [-1020, 1020] (2^1074 would overflow for denormal data); 1
 * when amax is 0 or not finite.  Sums of squares of values multiplied by
 * it neither underflow nor overflow, and the scaling itself is exact. */
double sb_pow2_scale(double amax);

/* Before the first BLAS call of the calling thread (plan creation): under
 * a memory limit (ulimit -v / -d), check that OpenBLAS's working buffer
 * fits and make it allocate it now, so that it cannot hang later retrying
 * the allocation (blas_guard.c).  SB_ERR_NOMEM names the bytes. */
sb_result_t sb_blas_reserve(sb_context_t *ctx);

/* BLAS on one thread until sb_blas_threads_end(the value returned), for
 * BLAS calls made from the library's own parallel loops (blas_guard.c). */
int sb_blas_threads_begin(void);
void sb_blas_threads_end(int n);
/* As those, for a solver that reads a large matrix only through
 * sb_dgemm_thin / sb_sgemm_thin: they keep the threads OpenBLAS had
 * (sb_blas_thin_threads, 0 outside), every other BLAS call runs on one. */
int sb_blas_thin_begin(void);
void sb_blas_thin_end(int n);
int sb_blas_thin_threads(void);

/* C (rows x cols, ldc) = op(A) B with op(A) rows x inner (trans: A is
 * stored inner x rows) and B inner x cols: for a large A and a thin B, C's
 * rows cut over the library's threads with OpenBLAS on one thread in each
 * (gemm_thin.c); one call where OpenBLAS has one thread or A is small. */
void sb_dgemm_thin(int trans, int rows, int cols, int inner, const double *A, int lda, const double *B, int ldb,
                   double *C, int ldc);
void sb_sgemm_thin(int trans, int rows, int cols, int inner, const float *A, int lda, const float *B, int ldb, float *C,
                   int ldc);
/* C (rows x cols, ldc) = A^T B, A inner x rows, B inner x cols, by a kernel
 * that reads A in place (gemm_tn.c): sb_gemm_tn_usable says whether it
 * runs here (x86-64 with AVX2 and FMA, B at most 64 columns); where it
 * does not, the two products do nothing. */
int sb_gemm_tn_usable(int cols);
void sb_dgemm_tn(int rows, int cols, int inner, const double *A, int lda, const double *B, int ldb, double *C, int ldc);
void sb_sgemm_tn(int rows, int cols, int inner, const float *A, int lda, const float *B, int ldb, float *C, int ldc);

#endif
