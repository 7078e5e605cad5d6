/* Private to the block-circulant solver: its workspace, shared by
 * circulant.c (transform, selection, residual maxima) and circulant_sym.c
 * (blocks that are symmetric decomposed as such). */
#ifndef SEPBRDF_CIRCULANT_IMPL_H
#define SEPBRDF_CIRCULANT_IMPL_H

#include <lapacke.h>
#include <stddef.h>

#include "solve/circulant.h"

typedef struct cand {
    double s;
    unsigned k, idx, member; /* frequency, index within block k, 0 = cos (or single), 1 = sin */
} cand_t;

/* LAPACK integers per thread: dgesdd's 8 R, or dstemr's 10 R and its
 * support 2 R. */
#define SB_CIRC_IW 12
/* Doubles a block keeps of its reduction in c->tri: dsytrd's d, e, tau
 * (symmetric) or dgebrd's d, e, tauq, taup (circulant_gen.c). */
#define SB_CIRC_TRI 4
/* sb_circ_gen_values: the block is one dgesdd scales first (left as it is) */
#define SB_CIRC_GEN_SCALED (-1000)

struct sb_circ {
    sb_context_t *ctx;
    size_t R, nb;             /* period, blocks R/2 + 1 */
    double *K;                /* R blocks R x R (weighted, symmetrised); made by the first execute that needs it */
    const double *Kd;         /* the kernel read: K, or the stored values where they are it (kernel_fill) */
    double *C;                /* nb blocks C_k (R^2 x nb); a symmetric block's dsytrd reflectors */
    double *Cv;               /* per thread: R x R, the copy of a block that dgesdd overwrites */
    double *T;                /* R x nb: cos(2 pi k m / R) */
    unsigned char *need;      /* nb: block k holds a selected triplet */
    size_t *nvec;             /* nb: how many of block k's leading triplets are selected */
    size_t *list, nlist;      /* the blocks whose singular values this batch computes */
    unsigned char *done;      /* nb: block k's singular values are known */
    double *fro;              /* nb: ||C_k||_F^2, the sum of block k's squared singular values */
    double *sv, *A, *VT;      /* per block: R singular values, R x R left vectors, R x R right vectors (transposed) */
    double *ct;               /* cos(2 pi q / R), q = 0..R-1 */
    double *work;             /* per thread: lwork doubles */
    lapack_int lwork, *iwork; /* per thread: SB_CIRC_IW R */
    int nth;                  /* threads of the block SVDs and the transform */
    int fft;                  /* C came from the FFT (util/rdft.h), not the product with T */
    int even;                 /* the last kernel was the weighted table itself: even to the bit */
    double n2;                /* its ||W A W||_F^2 scale^2 from the blocks' norms (Parseval), -1 where not even */
    const double *n2_a;       /* the table it was of */
    cand_t *cand;             /* R^2 candidates, sorted */
    /* symmetric blocks (circulant_sym.c): C_k = Q diag(lambda) Q^T, so
     * sigma = |lambda|, v = q, u = sign(lambda) q */
    int ksym;           /* the kernel of the last sb_circ_svd is symmetric (sb_circ_kernel_symmetric) */
    unsigned char *sym; /* nb: block k was decomposed as symmetric */
    double *tri;        /* nb x SB_CIRC_TRI R: block k's reduction (dsytrd's or dgebrd's, see SB_CIRC_TRI) */
    unsigned char *bid; /* nb: block k's values came from its kept bidiagonal reduction (circulant_gen.c) */
    double *lam;        /* nb x R: the eigenvalues in the order of sv (|lambda| decreasing) */
    lapack_int *pos;    /* nb x R: their places in the ascending order */
    double *swork;      /* per thread: slwork doubles */
    lapack_int slwork;
    size_t nsym; /* blocks decomposed as symmetric by the last sb_circ_svd */
};

/* Frequency k has one vector (k = 0, and R / 2 at even R), not a cos/sin
 * pair. */
static inline int sb_circ_single(const sb_circ_t *c, unsigned k) { return k == 0 || (c->R % 2 == 0 && k == c->R / 2); }

/* max_i |x[i] - t y[i]|; with store, x[i] becomes x[i] - t y[i]
 * (circulant_max.c: SSE2, or AVX2 where the CPU has it). */
double sb_circ_absmax_axpy(double *x, double t, const double *y, size_t n, int store);

/* Whether every block K_m of the symmetrised kernel K (R blocks R x R,
 * column-major, K_m = K_(R-m) to the bit) equals its transpose bit for
 * bit: the blocks m <= R / 2 are read. */
int sb_circ_kernel_symmetric(const double *K, size_t R);
/* The symmetric workspace of c (c->R, c->nb, c->nth set); SB_OK or
 * SB_ERR_NOMEM / SB_ERR_NUMERIC. */
sb_result_t sb_circ_sym_alloc(sb_circ_t *c);
void sb_circ_sym_free(sb_circ_t *c);
/* Block k's singular values (|eigenvalues|, decreasing) into c->sv, its
 * reduction kept in c->C (in place of C_k) and c->tri, on thread t's
 * workspace; LAPACK's info (C_k is then lost). */
lapack_int sb_circ_sym_values(sb_circ_t *c, size_t k, int t);
/* The c->nvec[k] leading triplets' vectors of block k (after
 * sb_circ_sym_values) into c->A and c->VT as dgesdd lays them out. */
lapack_int sb_circ_sym_vectors(sb_circ_t *c, size_t k, int t);

/* Block k (not symmetric) reduced in place to bidiagonal form (dgebrd,
 * kept in c->C and c->tri) and its singular values into c->sv, on thread
 * t's workspace: dgesdd's values with jobz = 'N' to the bit.  LAPACK's
 * info, or SB_CIRC_GEN_SCALED (C_k untouched) where dgesdd would scale
 * it. */
lapack_int sb_circ_gen_values(sb_circ_t *c, size_t k, int t);
/* The c->nvec[k] leading triplets of block k (after sb_circ_gen_values)
 * into c->A and c->VT as dgesdd with jobz = 'S' lays them out, its values
 * into c->sv (those of dgesdd 'S'); LAPACK's info. */
lapack_int sb_circ_gen_vectors(sb_circ_t *c, size_t k, int t);

#endif
