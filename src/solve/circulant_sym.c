/* Symmetric blocks of the block-circulant solver.  A reciprocal source
 * sampled with the reciprocity of its table (theta_o >= theta_i evaluated,
 * the rest mirrored: f(theta_o, theta_i, -d) = f(theta_i, theta_o, d))
 * has a symmetrised kernel (K_m + K_(R-m)) / 2 that is symmetric in
 * (theta_i, theta_o) to the bit, and theta weights keep it (w_i w_o).
 * Every exact C_k = sum_m K_m cos(2 pi k m / R) is then symmetric; the
 * FFT's C_k is so to its rounding (the two entries ride in different
 * lanes), and the mean of C_k and its transpose is as close to the exact
 * block as either.  Its SVD is its eigen-
 * decomposition, C_k = Q diag(lambda) Q^T: sigma = |lambda|, v = q,
 * u = sign(lambda) q, with the same backward error as dgesdd's (the
 * values to eps ||C_k||, the vectors to eps ||C_k|| / gap).  It costs a
 * tridiagonal reduction (4/3 R^3 flops, against dgesdd's bidiagonal 8/3
 * R^3 and its second pass for the vectors): the values from the root-free
 * QR of the tridiagonal (dsterf), the few vectors the selection needs by
 * MRRR (dstemr) from the kept reduction, back-transformed by dormtr. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "solve/circulant_impl.h"
#include "util/internal.h"

int sb_circ_kernel_symmetric(const double *K, size_t R) {
    for (size_t m = 0; m <= R / 2; m++) /* K_(R-m) is K_m: the same two values summed */
        for (size_t o = 1; o < R; o++)
            for (size_t i = 0; i < o; i++)
                if (!(K[m * R * R + i + o * R] == K[m * R * R + o + i * R])) return 0; /* a NaN is not symmetric */
    return 1;
}

sb_result_t sb_circ_sym_alloc(sb_circ_t *c) {
    size_t R = c->R, nb = c->nb;
    lapack_int n = (lapack_int)R, info;
    c->sym = sb_calloc(c->ctx, nb, 1, "circulant");
    c->nvec = sb_calloc(c->ctx, nb, sizeof *c->nvec, "circulant");
    c->bid = sb_calloc(c->ctx, nb, 1, "circulant");
    c->tri = sb_alloc(c->ctx, nb * SB_CIRC_TRI * R, sizeof *c->tri, "circulant blocks");
    c->lam = sb_alloc(c->ctx, nb * R, sizeof *c->lam, "circulant blocks");
    c->pos = sb_alloc(c->ctx, nb * R, sizeof *c->pos, "circulant blocks");
    if (!c->sym || !c->bid || !c->nvec || !c->tri || !c->lam || !c->pos) return SB_ERR_NOMEM;
    /* LAPACK workspace queries: the reduction and the back-transform of R
     * vectors; dstemr needs 18 R */
    double q1 = 0, q2 = 0;
    info = LAPACKE_dsytrd_work(LAPACK_COL_MAJOR, 'L', n, c->C, n, c->tri, c->tri, c->tri, &q1, -1);
    if (info == 0) info = LAPACKE_dormtr_work(LAPACK_COL_MAJOR, 'L', 'L', 'N', n, n, c->C, n, c->tri, c->A, n, &q2, -1);
    if (info != 0) return sb_error(c->ctx, SB_ERR_NUMERIC, "circulant: symmetric workspace query failed");
    double lw = fmax(fmax(q1, q2), 18.0 * (double)R) + 1;
    c->slwork = (lapack_int)lw;
    c->swork = sb_alloc(c->ctx, (3 * R + R * R + (size_t)c->slwork) * (size_t)c->nth, sizeof *c->swork,
                        "circulant LAPACK workspace");
    return c->swork ? SB_OK : SB_ERR_NOMEM;
}

void sb_circ_sym_free(sb_circ_t *c) {
    free(c->sym);
    free(c->nvec);
    free(c->tri);
    free(c->bid);
    free(c->lam);
    free(c->pos);
    free(c->swork);
}

/* Thread t's scratch: dc, ec, w (R each), Z (R x R), then LAPACK's work. */
static double *scratch(const sb_circ_t *c, int t) {
    size_t R = c->R;
    return c->swork + (size_t)t * (3 * R + R * R + (size_t)c->slwork);
}

lapack_int sb_circ_sym_values(sb_circ_t *c, size_t k, int t) {
    size_t R = c->R, R2 = R * R;
    lapack_int n = (lapack_int)R;
    double *a = c->C + k * R2, *d = c->tri + k * SB_CIRC_TRI * R, *e = d + R, *tau = e + R;
    double *dc = scratch(c, t), *ec = dc + R, *work = dc + 3 * R + R2;
    for (size_t o = 0; o < R; o++) /* the lower triangle, which dsytrd reads: the mean of C_k and its transpose */
        for (size_t i = o + 1; i < R; i++)
            a[i + o * R] = 0.5 * (a[i + o * R] + a[o + i * R]);
    lapack_int info = LAPACKE_dsytrd_work(LAPACK_COL_MAJOR, 'L', n, a, n, d, e, tau, work, c->slwork);
    if (info != 0) return info;
    memcpy(dc, d, R * sizeof *dc);
    memcpy(ec, e, (R - 1) * sizeof *ec);
    if ((info = LAPACKE_dsterf_work(n, dc, ec)) != 0) return info;
    /* ascending eigenvalues: the largest |lambda| left is at one end */
    size_t lo = 0, hi = R - 1;
    for (size_t i = 0; i < R; i++) {
        size_t p = fabs(dc[hi]) >= fabs(dc[lo]) ? hi-- : lo++;
        c->sv[k * R + i] = fabs(dc[p]);
        c->lam[k * R + i] = dc[p];
        c->pos[k * R + i] = (lapack_int)p;
    }
    return 0;
}

/* Eigenvectors il..iu (1-based, ascending) of block k's tridiagonal into
 * the m columns of Z; LAPACK's info. */
static lapack_int tri_vectors(const sb_circ_t *c, size_t k, int t, lapack_int il, lapack_int iu, double *Z) {
    size_t R = c->R;
    lapack_int n = (lapack_int)R, m = 0, want = iu - il + 1, *iw = c->iwork + (size_t)t * SB_CIRC_IW * R;
    const double *d = c->tri + k * SB_CIRC_TRI * R, *e = d + R;
    double *dc = scratch(c, t), *ec = dc + R, *w = ec + R, *work = dc + 3 * R + R * R;
    memcpy(dc, d, R * sizeof *dc);
    memcpy(ec, e, (R - 1) * sizeof *ec);
    ec[R - 1] = 0;
    lapack_logical tryrac = 1;
    lapack_int info = LAPACKE_dstemr_work(LAPACK_COL_MAJOR, 'V', 'I', n, dc, ec, 0, 0, il, iu, &m, w, Z, n, want,
                                          iw + 10 * R, &tryrac, work, c->slwork, iw, (lapack_int)(10 * R));
    return info != 0 ? info : (m == want ? 0 : -1);
}

lapack_int sb_circ_sym_vectors(sb_circ_t *c, size_t k, int t) {
    size_t R = c->R, R2 = R * R, m = c->nvec[k], b = 0;
    lapack_int n = (lapack_int)R, info = 0;
    const lapack_int *pos = c->pos + k * R;
    /* the leading m by |lambda|: the b lowest and the a = m - b highest
     * eigenvalues (the order of sb_circ_sym_values, replayed) */
    for (size_t i = 0; i < m; i++)
        b += (size_t)pos[i] == b;
    size_t a = m - b;
    double *Z = scratch(c, t) + 3 * R, *work = Z + R2;
    if (b > 0) info = tri_vectors(c, k, t, 1, (lapack_int)b, Z);
    if (info == 0 && a > 0) info = tri_vectors(c, k, t, n - (lapack_int)a + 1, n, Z + b * R);
    if (info == 0)
        info = LAPACKE_dormtr_work(LAPACK_COL_MAJOR, 'L', 'L', 'N', n, (lapack_int)m, c->C + k * R2, n,
                                   c->tri + k * SB_CIRC_TRI * R + 2 * R, Z, n, work, c->slwork);
    if (info != 0) return info;
    for (size_t i = 0, lo = 0; i < m; i++) {
        size_t p = (size_t)pos[i], col = p == lo ? lo++ : b + p - (R - a);
        double sg = c->lam[k * R + i] < 0 ? -1 : 1, *A = c->A + k * R2 + i * R, *VT = c->VT + k * R2;
        for (size_t it = 0; it < R; it++) {
            A[it] = sg * Z[col * R + it];
            VT[i + it * R] = Z[col * R + it];
        }
    }
    return 0;
}

size_t sb_circ_sym_blocks(const sb_circ_t *c) { return c ? c->nsym : 0; }
