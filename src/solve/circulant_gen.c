/* General (not symmetric) blocks of the block-circulant solver: the steps
 * of dgesdd's path for a square matrix (LAPACK's path 5: dgebrd, then
 * dbdsdc, then dormbr), split in two so the selection pays for the
 * bidiagonal reduction once.  The values pass reduces C_k in place
 * (dgebrd, its d, e, tauq and taup kept in c->tri) and takes the values
 * from the bidiagonal (dbdsdc 'N'): dgesdd with jobz = 'N', step by step.
 * The vectors pass, for the blocks holding a selected triplet, starts
 * from the kept reduction: the bidiagonal's SVD (dbdsdc 'I', its values
 * then those of dgesdd with jobz = 'S') and the back-transforms (dormbr)
 * of only the c->nvec[k] leading vectors, not all R.  The same calls on
 * the same data with the same workspace as dgesdd's: the values are
 * dgesdd's to the bit; the vectors are its first columns (a column of
 * dormbr's product does not depend on the others).  Where dgesdd would
 * scale the block first (largest |entry| outside [sqrt(safe min) / eps,
 * its inverse], or not a number) the block is left as it is and the
 * caller takes dgesdd. */
#include <float.h>
#include <math.h>
#include <string.h>

#include "solve/circulant_impl.h"

/* Whether dgesdd would take the block as it is (no scaling, no NaN). */
static int unscaled(const double *a, size_t n) {
    double mx = 0;
    for (size_t i = 0; i < n; i++) {
        double x = fabs(a[i]);
        if (x != x) return 0;
        mx = x > mx ? x : mx;
    }
    double small = sqrt(DBL_MIN) / (DBL_EPSILON / 2); /* dlamch('S'), dlamch('P') = eps / 2 */
    return mx == 0 || (mx >= small && mx <= 1 / small);
}

lapack_int sb_circ_gen_values(sb_circ_t *c, size_t k, int t) {
    size_t R = c->R, R2 = R * R;
    lapack_int n = (lapack_int)R, *iw = c->iwork + (size_t)t * SB_CIRC_IW * R;
    double *a = c->C + k * R2, *d = c->tri + k * SB_CIRC_TRI * R, *e = d + R, *tq = e + R, *tp = tq + R;
    double *work = c->work + (size_t)t * (size_t)c->lwork, *ec = work, *lw = work + 3 * R;
    if (!unscaled(a, R2)) return SB_CIRC_GEN_SCALED;
    double *cv = c->Cv + (size_t)t * R2;
    memcpy(cv, a, R2 * sizeof *a);
    lapack_int info = LAPACKE_dgebrd_work(LAPACK_COL_MAJOR, n, n, cv, n, d, e, tq, tp, lw, c->lwork - 3 * n);
    if (info != 0) return info;
    memcpy(a, cv, R2 * sizeof *a);
    double *s = c->sv + k * R, dum = 0;
    lapack_int idum = 0;
    memcpy(s, d, R * sizeof *s);
    memcpy(ec, e, (R - 1) * sizeof *ec);
    return LAPACKE_dbdsdc_work(LAPACK_COL_MAJOR, 'U', 'N', n, s, ec, &dum, 1, &dum, 1, &dum, &idum, lw, iw);
}

lapack_int sb_circ_gen_vectors(sb_circ_t *c, size_t k, int t) {
    size_t R = c->R, R2 = R * R;
    lapack_int n = (lapack_int)R, m = (lapack_int)c->nvec[k], *iw = c->iwork + (size_t)t * SB_CIRC_IW * R;
    const double *d = c->tri + k * SB_CIRC_TRI * R, *e = d + R, *tq = e + R, *tp = tq + R;
    double *work = c->work + (size_t)t * (size_t)c->lwork, *ec = work, *lw = work + 3 * R;
    double *s = c->sv + k * R, *U = c->A + k * R2, *VT = c->VT + k * R2, dum = 0;
    lapack_int idum = 0;
    double *a = c->Cv + (size_t)t * R2;
    memcpy(a, c->C + k * R2, R2 * sizeof *a);
    memcpy(s, d, R * sizeof *s);
    memcpy(ec, e, (R - 1) * sizeof *ec);
    lapack_int info = LAPACKE_dbdsdc_work(LAPACK_COL_MAJOR, 'U', 'I', n, s, ec, U, n, VT, n, &dum, &idum, lw, iw);
    if (info == 0)
        info = LAPACKE_dormbr_work(LAPACK_COL_MAJOR, 'Q', 'L', 'N', n, m, n, a, n, tq, U, n, lw, c->lwork - 3 * n);
    if (info == 0)
        info = LAPACKE_dormbr_work(LAPACK_COL_MAJOR, 'P', 'R', 'T', m, n, n, a, n, tp, VT, n, lw, c->lwork - 3 * n);
    return info;
}
