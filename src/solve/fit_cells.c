/* Masked fit: the valid cells gathered in both orders (als_cells_t,
 * fit_impl.h) and the data less the fixed terms of a stage, as the
 * alternating least squares of fit_als.c read them. */
#include <assert.h>
#include <stdlib.h>
#include <string.h>

#include "solve/fit_impl.h"
#include "util/internal.h"

void fit_cells_free(als_cells_t *cl) {
    free(cl->Dv);
    free(cl->DTv);
    free(cl->Dr);
    free(cl->DTr);
    free(cl->bt);
    free(cl->ca2v);
    free(cl->ca2r);
    free(cl->cip);
    free(cl->rip);
    free(cl->ci);
    free(cl->ri);
    free(cl->cp);
    free(cl->rp);
    free(cl->cr);
    free(cl->rc);
    free(cl->cv);
    free(cl->rv);
    free(cl->cbuf);
    free(cl->rbuf);
    free(cl->cmask);
    memset(cl, 0, sizeof *cl);
}

/* DT (n x m) = D (m x n) transposed, by square blocks of TRANSPOSE_BLOCK
 * and within them 4 x 4 through vectors: DT written a cell at a time
 * down D's columns (a store every 8 KiB at 1024 x 1024, every one in the
 * same cache set) was 70 % of the residual's time and 8 % of a MERL
 * file's default run; blocks of 32 cells by scalars took 1.8x these. */
#define TRANSPOSE_BLOCK 16
typedef double v4d_t __attribute__((vector_size(32), aligned(8))); /* four doubles, loads at any 8-byte address */

SB_AVX2_CLONES static void transpose(const double *D, size_t m, size_t n, double *DT) {
    for (size_t c0 = 0; c0 < n; c0 += TRANSPOSE_BLOCK)
        for (size_t r0 = 0; r0 < m; r0 += TRANSPOSE_BLOCK) {
            size_t c1 = n - c0 < TRANSPOSE_BLOCK ? n : c0 + TRANSPOSE_BLOCK;
            size_t r1 = m - r0 < TRANSPOSE_BLOCK ? m : r0 + TRANSPOSE_BLOCK;
            if (c1 - c0 < TRANSPOSE_BLOCK || r1 - r0 < TRANSPOSE_BLOCK) { /* the edges */
                for (size_t r = r0; r < r1; r++)
                    for (size_t c = c0; c < c1; c++)
                        DT[c + r * n] = D[r + c * m];
                continue;
            }
            for (size_t c = c0; c < c1; c += 4)
                for (size_t r = r0; r < r1; r += 4) {
                    const double *d = D + r + c * m;
                    v4d_t a0 = *(const v4d_t *)d, a1 = *(const v4d_t *)(d + m);
                    v4d_t a2 = *(const v4d_t *)(d + 2 * m), a3 = *(const v4d_t *)(d + 3 * m);
                    for (int i = 0; i < 4; i++)
                        *(v4d_t *)(DT + c + (r + (size_t)i) * n) = (v4d_t){a0[i], a1[i], a2[i], a3[i]};
                }
        }
}

/* D and DT from cres (zeros stay where no cell is). */
static void dense_residual(als_cells_t *cl, size_t m, size_t n) {
    if (!cl->D) return; /* zero where no cell is valid since fit_cells_build */
    for (size_t c = 0; c < n; c++)
        for (size_t t = cl->cp[c]; t < cl->cp[c + 1]; t++)
            cl->D[cl->cr[t] + c * m] = cl->cres[t];
    transpose(cl->D, m, n, cl->DT);
}

/* Step: allocate the index and value arrays (~40 bytes per valid cell,
 * through sb_alloc, so the memory limit holds); 0 or SB_ERR_NOMEM. */
static int cells_alloc(sb_context_t *ctx, als_cells_t *cl, size_t m, size_t n, size_t nvalid) {
    static const char what[] = "masked fit: gathered cells";
    cl->cp = sb_alloc(ctx, n + 1, sizeof *cl->cp, what);
    cl->rp = sb_calloc(ctx, m + 1, sizeof *cl->rp, what);
    cl->cr = sb_alloc(ctx, nvalid, sizeof *cl->cr, what);
    cl->rc = sb_alloc(ctx, nvalid, sizeof *cl->rc, what);
    cl->cv = sb_alloc(ctx, nvalid, sizeof *cl->cv, what);
    cl->rv = sb_alloc(ctx, nvalid, sizeof *cl->rv, what);
    cl->cbuf = sb_alloc(ctx, nvalid, sizeof *cl->cbuf, what);
    cl->rbuf = sb_alloc(ctx, nvalid, sizeof *cl->rbuf, what);
    size_t nout = m * n - nvalid;
    cl->cip = sb_alloc(ctx, n + 1, sizeof *cl->cip, what);
    cl->rip = sb_calloc(ctx, m + 1, sizeof *cl->rip, what);
    cl->ci = sb_alloc(ctx, nout ? nout : 1, sizeof *cl->ci, what);
    cl->ri = sb_alloc(ctx, nout ? nout : 1, sizeof *cl->ri, what);
    cl->ca2v = sb_alloc(ctx, n, sizeof *cl->ca2v, what);
    cl->ca2r = sb_alloc(ctx, n, sizeof *cl->ca2r, what);
    if (!cl->cp || !cl->rp || !cl->cr || !cl->rc || !cl->cv || !cl->rv || !cl->cbuf || !cl->rbuf || !cl->cip ||
        !cl->rip || !cl->ci || !cl->ri || !cl->ca2v || !cl->ca2r)
        return SB_ERR_NOMEM;
    return 0;
}

/* Step: the row order from the column order: prefix sums, then a scatter
 * in column order keeps each row's columns increasing (values too where
 * there is no dense residual: the rows read it instead); the cells left
 * out likewise.  0 or SB_ERR_NOMEM. */
static int cells_rows(sb_context_t *ctx, als_cells_t *cl, size_t m, size_t n) {
    for (size_t r = 0; r < m; r++)
        cl->rp[r + 1] += cl->rp[r];
    size_t *next = malloc(m * sizeof *next);
    if (!next) return sb_error(ctx, SB_ERR_NOMEM, "masked fit: cannot allocate %zu bytes", m * sizeof *next);
    memcpy(next, cl->rp, m * sizeof *next);
    for (size_t c = 0; c < n; c++)
        for (size_t v = cl->cp[c]; v < cl->cp[c + 1]; v++) {
            size_t at = next[cl->cr[v]]++;
            cl->rc[at] = (uint32_t)c;
            if (!cl->Dv) cl->rv[at] = cl->cv[v];
        }
    for (size_t r = 0; r < m; r++) /* the cells left out, likewise */
        cl->rip[r + 1] += cl->rip[r];
    memcpy(next, cl->rip, m * sizeof *next);
    for (size_t c = 0; c < n; c++)
        for (size_t v = cl->cip[c]; v < cl->cip[c + 1]; v++)
            cl->ri[next[cl->ci[v]]++] = (uint32_t)c;
    free(next);
    return 0;
}

/* Step: the dense residual's copies where at least half the cells are
 * valid (the default's iso cells: 75 %) and the four (the data's and the
 * residual's, each with its transpose) take at most 128 MiB and a quarter
 * of the memory limit; without them (or without the memory) the gathers.
 * The default run: 12 % fewer instructions, the same errors to 1e-8 */
static void cells_dense(als_cells_t *cl, size_t m, size_t n, size_t nvalid) {
    cl->D = cl->DT = NULL;
    if (2 * nvalid >= m * n && m * n <= ((size_t)1 << 22) && 32 * m * n <= sb_memory_limit() / 4) {
        cl->Dv = calloc(m * n, sizeof *cl->Dv);
        cl->DTv = calloc(m * n, sizeof *cl->DTv);
        cl->Dr = calloc(m * n, sizeof *cl->Dr);
        cl->DTr = calloc(m * n, sizeof *cl->DTr);
        cl->bt = malloc((m > n ? m : n) * SB_ALS_MAX_K * sizeof *cl->bt);
        if (!cl->Dv || !cl->DTv || !cl->Dr || !cl->DTr || !cl->bt) {
            free(cl->Dv), free(cl->DTv), free(cl->Dr), free(cl->DTr), free(cl->bt);
            cl->Dv = cl->DTv = cl->Dr = cl->DTr = cl->bt = NULL;
        }
    }
}

/* Whether cl was gathered for this mask (m x n, ld lda, nvalid cells). */
static int same_mask(const als_cells_t *cl, size_t m, size_t n, size_t lda, const unsigned char *mask, size_t nvalid) {
    if (!cl->cmask || cl->cm != m || cl->cn != n || cl->ncv != nvalid) return 0;
    for (size_t c = 0; c < n; c++)
        if (memcmp(cl->cmask + c * m, mask + c * lda, m) != 0) return 0;
    return 1;
}

/* Step, on the mask gathered before: the values anew, in both orders (the
 * row order only where the rows read it), the dense copies to be made
 * again from them (their cells left out are still 0: the same mask). */
static void cells_values(als_cells_t *cl, const double *X, size_t m, size_t n, size_t lda) {
    for (size_t c = 0; c < n; c++)
        for (size_t t = cl->cp[c]; t < cl->cp[c + 1]; t++)
            cl->cv[t] = X[cl->cr[t] + c * lda];
    for (size_t r = 0; !cl->Dv && r < m; r++)
        for (size_t t = cl->rp[r]; t < cl->rp[r + 1]; t++)
            cl->rv[t] = X[r + cl->rc[t] * lda];
    cl->cres = cl->cv;
    cl->rres = cl->rv;
    cl->D = cl->DT = NULL;
    cl->dv = 0;
}

/* Gather the valid cells of X (m x n, ld lda) in both orders; 0 or
 * SB_ERR_NOMEM.  A run on the mask of the last (a nested fit's pieces and
 * channels: 15 runs a MERL file's matrix at J = 8) gathers the values
 * only: the indices, and the buffers' pages, serve again (the gathering
 * and the first touch of some 60 MB a run were 12 % of the default run). */
int fit_cells_build(sb_context_t *ctx, als_cells_t *cl, const double *X, size_t m, size_t n, size_t lda,
                    const unsigned char *mask, size_t nvalid) {
    if (same_mask(cl, m, n, lda, mask, nvalid)) {
        cells_values(cl, X, m, n, lda);
        return 0;
    }
    fit_cells_free(cl);
    if (cells_alloc(ctx, cl, m, n, nvalid) != 0) {
        fit_cells_free(cl);
        return SB_ERR_NOMEM;
    }
    /* column order; count each row's cells on the way */
    size_t t = 0, u = 0;
    for (size_t c = 0; c < n; c++) {
        cl->cp[c] = t;
        cl->cip[c] = u;
        for (size_t r = 0; r < m; r++)
            if (mask[r + c * lda]) {
                cl->cr[t] = (uint32_t)r;
                cl->cv[t++] = X[r + c * lda];
                cl->rp[r + 1]++;
            } else {
                cl->ci[u++] = (uint32_t)r;
                cl->rip[r + 1]++;
            }
    }
    cl->cp[n] = t;
    cl->cip[n] = u;
    assert(t == nvalid && u == m * n - nvalid);
    cells_dense(cl, m, n, nvalid);
    if (cells_rows(ctx, cl, m, n) != 0) {
        fit_cells_free(cl);
        return SB_ERR_NOMEM;
    }
    cl->cres = cl->cv;
    cl->rres = cl->rv;
    if ((cl->cmask = malloc(m * n))) { /* without it: gathered again next time */
        for (size_t c = 0; c < n; c++)
            memcpy(cl->cmask + c * m, mask + c * lda, m);
        cl->cm = m, cl->cn = n, cl->ncv = nvalid;
    }
    return 0;
}

/* Step: the sums of squares of cres per column and in all. */
static void column_sums(als_cells_t *cl, size_t n) {
    cl->a2 = 0;
    for (size_t c = 0; c < n; c++) {
        double a2 = 0;
        for (size_t t = cl->cp[c]; t < cl->cp[c + 1]; t++)
            a2 += cl->cres[t] * cl->cres[t];
        cl->ca2[c] = a2;
        cl->a2 += a2;
    }
}

/* The data less the fixed terms 0..j0-1, in both orders (aliases of the
 * data for j0 = 0). */
void fit_cells_residual(als_cells_t *cl, const sb_fit_t *f, size_t j0) {
    size_t m = f->m, n = f->n;
    const double *P = f->P, *Q = f->Q;
    int dense = cl->Dv != NULL;
    if (j0 == 0) { /* the data: made once, kept for every joint stage */
        cl->cres = cl->cv;
        cl->rres = cl->rv;
        cl->ca2 = cl->ca2v;
        cl->D = dense ? cl->Dv : NULL, cl->DT = dense ? cl->DTv : NULL;
        if (!cl->dv) {
            column_sums(cl, n);
            dense_residual(cl, m, n);
            cl->a2v = cl->a2;
            cl->dv = 1;
        }
        cl->a2 = cl->a2v;
        return;
    }
    cl->ca2 = cl->ca2r;
    cl->D = dense ? cl->Dr : NULL, cl->DT = dense ? cl->DTr : NULL;
    for (size_t c = 0; c < n; c++)
        for (size_t t = cl->cp[c]; t < cl->cp[c + 1]; t++) {
            double a = cl->cv[t];
            for (size_t j = 0; j < j0; j++)
                a -= P[cl->cr[t] + j * m] * Q[c + j * n];
            cl->cbuf[t] = a;
        }
    /* the rows' half reads the dense residual where there is one */
    for (size_t r = 0; !cl->D && r < m; r++)
        for (size_t t = cl->rp[r]; t < cl->rp[r + 1]; t++) {
            double a = cl->rv[t];
            for (size_t j = 0; j < j0; j++)
                a -= P[r + j * m] * Q[cl->rc[t] + j * n];
            cl->rbuf[t] = a;
        }
    cl->cres = cl->cbuf;
    cl->rres = cl->D ? NULL : cl->rbuf;
    column_sums(cl, n);
    dense_residual(cl, m, n);
}

/* C (rows x kf, ld ldc) = A (rows x inner, ld rows) B (inner x kf, ld
 * ldb), each entry summed in the order of the inner index, as the plain
 * loop would (so the same bits on every CPU and thread count).  The
 * half-sweeps' right-hand sides: OpenBLAS packed all of the dense
 * residual on every call for a product with 1-4 columns (its copy was 7 %
 * of the Cornell acrylic's default run, its kernel 5 %).  A block of
 * PROD_ROWS rows and up to 4 columns of C stays in registers while the
 * inner index runs through a panel of PROD_PANEL columns of A; the next
 * panel carries on from what the block left in C (the same additions in
 * the same order).  A block that ran down the whole inner index read one
 * cache line of A every 8 KiB (a MERL file's 1024 x 1024 hd matrix), a
 * new page at every step that no prefetcher follows: the product was a
 * third of the run's CPU.  A panel of 8 columns is 8 streams of
 * consecutive lines, and the 4-column blocks beyond the first read it
 * from cache (4-7x faster at 1024 x 1024, the same at 64 x 992). */
#define PROD_ROWS 8
#define PROD_PANEL 8

/* A block of PROD_ROWS rows and nj (constant, 1-4) columns of C over the
 * inner indices t0..t1-1, from 0 (first) or from what C holds. */
static inline __attribute__((always_inline)) void prod_block(const double *A, size_t rows, size_t t0, size_t t1,
                                                             const double *B, size_t ldb, double *C, size_t ldc,
                                                             const size_t nj, int first) {
    v4d_t acc[4][PROD_ROWS / 4];
    for (size_t j = 0; j < nj; j++)
        for (size_t i = 0; i < PROD_ROWS / 4; i++)
            acc[j][i] = first ? (v4d_t){0, 0, 0, 0} : *(const v4d_t *)(C + 4 * i + j * ldc);
    for (size_t t = t0; t < t1; t++) {
        const v4d_t *a = (const v4d_t *)(A + t * rows);
        v4d_t a0 = a[0], a1 = a[1];
        for (size_t j = 0; j < nj; j++) {
            double b = B[t + j * ldb];
            acc[j][0] += a0 * b;
            acc[j][1] += a1 * b;
        }
    }
    for (size_t j = 0; j < nj; j++)
        for (size_t i = 0; i < PROD_ROWS / 4; i++)
            *(v4d_t *)(C + 4 * i + j * ldc) = acc[j][i];
}

/* Rows beyond the blocks, one entry at a time, likewise. */
static void prod_rest(const double *A, size_t rows, size_t t0, size_t t1, const double *B, size_t ldb, double *C,
                      size_t ldc, size_t nr, size_t nj) {
    for (size_t j = 0; j < nj; j++)
        for (size_t i = 0; i < nr; i++) {
            double s = t0 == 0 ? 0 : C[i + j * ldc];
            for (size_t t = t0; t < t1; t++)
                s += A[i + t * rows] * B[t + j * ldb];
            C[i + j * ldc] = s;
        }
}

SB_AVX2_CLONES static void prod(const double *A, size_t rows, size_t inner, const double *B, size_t ldb, size_t kf,
                                double *C, size_t ldc) {
    for (size_t j = 0; inner == 0 && j < kf; j++) /* empty sums */
        memset(C + j * ldc, 0, rows * sizeof *C);
    for (size_t t0 = 0; t0 < inner; t0 += PROD_PANEL) {
        size_t t1 = inner - t0 < PROD_PANEL ? inner : t0 + PROD_PANEL;
        int first = t0 == 0;
        for (size_t j = 0; j < kf; j += 4) {
            size_t nj = kf - j < 4 ? kf - j : 4;
            const double *b = B + j * ldb;
            for (size_t r = 0; r < rows; r += PROD_ROWS) {
                size_t nr = rows - r < PROD_ROWS ? rows - r : PROD_ROWS;
                double *c = C + r + j * ldc;
                if (nr == PROD_ROWS && nj == 4)
                    prod_block(A + r, rows, t0, t1, b, ldb, c, ldc, 4, first);
                else if (nr == PROD_ROWS && nj == 3)
                    prod_block(A + r, rows, t0, t1, b, ldb, c, ldc, 3, first);
                else if (nr == PROD_ROWS && nj == 2)
                    prod_block(A + r, rows, t0, t1, b, ldb, c, ldc, 2, first);
                else if (nr == PROD_ROWS)
                    prod_block(A + r, rows, t0, t1, b, ldb, c, ldc, 1, first);
                else
                    prod_rest(A + r, rows, t0, t1, b, ldb, c, ldc, nr, nj);
            }
        }
    }
}

void fit_dense_product(const double *A, size_t rows, size_t inner, const double *B, size_t ldb, size_t kf, double *C,
                       size_t ldc) {
    prod(A, rows, inner, B, ldb, kf, C, ldc);
}
