/* The working buffer of OpenBLAS, reserved while memory is still free.
 *
 * OpenBLAS (0.3.21 as Debian ships it) gives every thread that calls a
 * BLAS routine a working buffer of 128 MiB + 4 KiB (malloc'ed at its first
 * call, kept for the life of the process) and, when that allocation fails,
 * retries it forever at 100 % CPU: under `ulimit -v` (RLIMIT_AS) or
 * `ulimit -d` (RLIMIT_DATA) a run that reached its first BLAS call with
 * less than that left hung instead of failing.  sb_blas_reserve() makes the
 * buffer exist before any large allocation of the caller: it first checks
 * with an allocation of its own that the buffer fits (and reports
 * SB_ERR_NOMEM naming the bytes when it does not), then calls one small
 * dgemm so that OpenBLAS allocates the buffer into the space just released.
 * Without a limit the kernel overcommits and nothing is checked. */
#include <stdatomic.h>
#include <stdlib.h>
#include <sys/resource.h>

#include <cblas.h>

#include "util/internal.h"

/* OpenBLAS's BUFFER_SIZE plus its alignment page, measured (the malloc of
 * blas_memory_alloc) and rounded up to 64 KiB. */
#define SB_BLAS_BUFFER_BYTES (((size_t)128 << 20) + ((size_t)64 << 10))

/* dgemm size that takes OpenBLAS's general path (not the small-matrix
 * kernels OpenBLAS uses up to 100^3 multiply-adds, which skip the buffer):
 * 128^3 multiply-adds, about 1 ms. */
#define SB_BLAS_WARM_N 128

static _Thread_local int reserved;

static int limited(void) {
    struct rlimit as, data;
    int a = getrlimit(RLIMIT_AS, &as) == 0 && as.rlim_cur != RLIM_INFINITY;
    int d = getrlimit(RLIMIT_DATA, &data) == 0 && data.rlim_cur != RLIM_INFINITY;
    return a || d;
}

sb_result_t sb_blas_reserve(sb_context_t *ctx) {
    if (reserved) return SB_OK;
    if (!limited()) {
        reserved = 1;
        return SB_OK;
    }
    double *m = calloc(3 * (size_t)SB_BLAS_WARM_N * SB_BLAS_WARM_N, sizeof *m);
    void *probe = m ? malloc(SB_BLAS_BUFFER_BYTES) : NULL;
    if (!probe) {
        free(m);
        return sb_error(ctx, SB_ERR_NOMEM,
                        "cannot allocate %zu bytes: the linear algebra library (OpenBLAS) needs that much working "
                        "memory per thread, more than the memory limit (ulimit -v or -d) leaves",
                        SB_BLAS_BUFFER_BYTES);
    }
    free(probe);
    const int n = SB_BLAS_WARM_N;
    cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, n, n, n, 1.0, m, n, m + n * n, n, 0.0, m + 2 * n * n, n);
    free(m);
    reserved = 1;
    return SB_OK;
}

/* OpenBLAS's own threads, when the caller runs BLAS in threads of its own:
 * after every call they wait spinning (sched_yield) for the next, taking
 * the cores from the caller's threads (perf of a streamed factorisation:
 * 15 % in sched_yield).  Other BLAS builds keep their setting. */
int sb_blas_threads_begin(void) {
#ifdef OPENBLAS_CONFIG_H
    int n = openblas_get_num_threads();
    if (n > 1) openblas_set_num_threads(1);
    return n;
#else
    return 1;
#endif
}

void sb_blas_threads_end(int n) {
#ifdef OPENBLAS_CONFIG_H
    if (n > 1) openblas_set_num_threads(n);
#else
    (void)n;
#endif
}

/* The thread count OpenBLAS had when a thin solver began (0 outside one):
 * its small products and factorisations then run on one thread, and only
 * the reads of the large matrix (gemm_thin.c) use that many.  Under load
 * a threaded call of a few microseconds of work waits for the other
 * thread to be scheduled: topk at N = 4096 with two BLAS threads took
 * 2.2x the wall time of scipy svds on a loaded 2-core VM. */
static _Atomic int thin_outer;

int sb_blas_thin_begin(void) {
    int n = sb_blas_threads_begin();
    atomic_store(&thin_outer, n);
    return n;
}

void sb_blas_thin_end(int n) {
    atomic_store(&thin_outer, 0);
    sb_blas_threads_end(n);
}

int sb_blas_thin_threads(void) { return atomic_load(&thin_outer); }
