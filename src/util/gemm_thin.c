/* Products of a large matrix with a thin block, C = op(A) B, cut by the
 * rows of C over the library's threads, OpenBLAS on one thread in each.
 *
 * OpenBLAS threads a product of a 4096^2 matrix with 18 columns poorly:
 * each call packs all of A, and its two threads split the packing and the
 * kernel so that they wait on each other (AMD EPYC VM, Haswell kernels:
 * 17.5 ms with its two threads, 28.8 ms with one, 14.8 ms with A's rows
 * cut in two halves, one per thread, each half a single-threaded call).
 * The topk and randomized methods read A this way 20 times a channel. */
#include <cblas.h>

#include "util/internal.h"
#include "util/parallel.h"

/* Below this many elements of A, one call (a thread costs more than it saves). */
#define SB_THIN_MIN_CELLS ((size_t)1 << 22)

typedef struct {
    int single, trans, rows, cols, inner, lda, ldb, ldc, parts;
    const void *A, *B;
    void *C;
} thin_t;

typedef struct {
    const thin_t *g;
    int t;
} thin_job_t;

static void thin_call(const thin_t *g, int r0, int r1) {
    int rows = r1 - r0;
    if (rows <= 0) return;
    /* NoTrans: A is rows x inner, its rows r0..; Trans: A is inner x rows, its columns r0.. */
    size_t off = g->trans ? (size_t)r0 * (size_t)g->lda : (size_t)r0;
    if (g->trans && sb_gemm_tn_usable(g->cols)) { /* A^T B without packing A (gemm_tn.c) */
        if (g->single)
            sb_sgemm_tn(rows, g->cols, g->inner, (const float *)g->A + off, g->lda, g->B, g->ldb, (float *)g->C + r0,
                        g->ldc);
        else
            sb_dgemm_tn(rows, g->cols, g->inner, (const double *)g->A + off, g->lda, g->B, g->ldb, (double *)g->C + r0,
                        g->ldc);
        return;
    }
    CBLAS_TRANSPOSE ta = g->trans ? CblasTrans : CblasNoTrans;
    if (g->single)
        cblas_sgemm(CblasColMajor, ta, CblasNoTrans, rows, g->cols, g->inner, 1.0f, (const float *)g->A + off, g->lda,
                    g->B, g->ldb, 0.0f, (float *)g->C + r0, g->ldc);
    else
        cblas_dgemm(CblasColMajor, ta, CblasNoTrans, rows, g->cols, g->inner, 1.0, (const double *)g->A + off, g->lda,
                    g->B, g->ldb, 0.0, (double *)g->C + r0, g->ldc);
}

static void *thin_run(void *arg) {
    thin_job_t *j = arg;
    size_t b, e;
    sb_part((size_t)j->g->rows, j->t, j->g->parts, &b, &e);
    thin_call(j->g, (int)b, (int)e);
    return NULL;
}

static void thin(thin_t *g) {
    size_t cells = (size_t)g->rows * (size_t)g->inner;
    int blas = sb_blas_threads_begin(), avail = blas > 1 ? blas : sb_blas_thin_threads();
    int n = avail > 1 && cells >= SB_THIN_MIN_CELLS ? sb_thread_count(0) : 1;
    if (n > avail) n = avail;
    if (n > g->rows) n = g->rows;
    if (n <= 1) {
        sb_blas_threads_end(blas); /* OpenBLAS's own threads, as configured */
        thin_call(g, 0, g->rows);
        return;
    }
    thin_job_t jobs[SB_THREADS_MAX];
    g->parts = n;
    for (int t = 0; t < n; t++)
        jobs[t] = (thin_job_t){g, t};
    sb_parallel_run(thin_run, jobs, sizeof jobs[0], n, NULL, NULL);
    sb_blas_threads_end(blas);
}

void sb_dgemm_thin(int trans, int rows, int cols, int inner, const double *A, int lda, const double *B, int ldb,
                   double *C, int ldc) {
    thin_t g = {0, trans, rows, cols, inner, lda, ldb, ldc, 1, A, B, C};
    thin(&g);
}

void sb_sgemm_thin(int trans, int rows, int cols, int inner, const float *A, int lda, const float *B, int ldb, float *C,
                   int ldc) {
    thin_t g = {1, trans, rows, cols, inner, lda, ldb, ldc, 1, A, B, C};
    thin(&g);
}
