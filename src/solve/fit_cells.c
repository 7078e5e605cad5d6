/* Masked fit: the valid cells gathered in both orders (als_cells_t,
 * fit_impl.h) and the data less the fixed terms of a stage, as the
 * alternating least squares of fit_als.c read them. */
#include <assert.h>
#include <stdlib.h>
#include <string.h>

#include "solve/fit_impl.h"
#include "util/internal.h"

void fit_cells_free(als_cells_t *cl) {
    free(cl->D);
    free(cl->DT);
    free(cl->bt);
    free(cl->ca2);
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
}

/* D and DT from cres (zeros stay where no cell is). */
static void dense_residual(als_cells_t *cl, size_t m, size_t n) {
    if (!cl->D) return; /* zero where no cell is valid since fit_cells_build */
    for (size_t c = 0; c < n; c++)
        for (size_t t = cl->cp[c]; t < cl->cp[c + 1]; t++) {
            cl->D[cl->cr[t] + c * m] = cl->cres[t];
            cl->DT[c + cl->cr[t] * n] = cl->cres[t];
        }
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
    cl->ca2 = sb_alloc(ctx, n, sizeof *cl->ca2, what);
    if (!cl->cp || !cl->rp || !cl->cr || !cl->rc || !cl->cv || !cl->rv || !cl->cbuf || !cl->rbuf || !cl->cip ||
        !cl->rip || !cl->ci || !cl->ri || !cl->ca2)
        return SB_ERR_NOMEM;
    return 0;
}

/* Step: the row order from the column order: prefix sums, then a scatter
 * in column order keeps each row's columns increasing; the cells left
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
            cl->rv[at] = cl->cv[v];
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

/* Gather the valid cells of X (m x n, ld lda) in both orders; 0 or
 * SB_ERR_NOMEM. */
int fit_cells_build(sb_context_t *ctx, als_cells_t *cl, const double *X, size_t m, size_t n, size_t lda,
                    const unsigned char *mask, size_t nvalid) {
    memset(cl, 0, sizeof *cl);
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
    if (cells_rows(ctx, cl, m, n) != 0) {
        fit_cells_free(cl);
        return SB_ERR_NOMEM;
    }
    cl->cres = cl->cv;
    cl->rres = cl->rv;
    /* the dense residual where at least half the cells are valid (the
     * default's iso cells: 75 %) and the two copies take at most 64 MiB
     * and a quarter of the memory limit; without them (or without the
     * memory) the gathers.  The default run: 12 % fewer instructions, the same
     * errors to 1e-8 */
    if (2 * nvalid >= m * n && m * n <= ((size_t)1 << 22) && 16 * m * n <= sb_memory_limit() / 4) {
        cl->D = calloc(m * n, sizeof *cl->D);
        cl->DT = calloc(m * n, sizeof *cl->DT);
        cl->bt = malloc((m > n ? m : n) * SB_ALS_MAX_K * sizeof *cl->bt);
        if (!cl->D || !cl->DT || !cl->bt) {
            free(cl->D), free(cl->DT), free(cl->bt);
            cl->D = cl->DT = cl->bt = NULL;
        }
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
    if (j0 == 0) {
        cl->cres = cl->cv;
        cl->rres = cl->rv;
        column_sums(cl, n);
        dense_residual(cl, m, n);
        return;
    }
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
