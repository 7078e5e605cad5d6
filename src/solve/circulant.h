/* Exact SVD of block-circulant matrices: isotropic BRDFs on the io grid.
 *
 * On the io grid (cell k = R i_phi + i_theta, phi uniform over 2 pi) an
 * isotropic BRDF depends on (theta_i, theta_o, phi_o - phi_i) only, and
 * reflection symmetry makes it even in phi_o - phi_i.  The matrix is then
 *     M = sum_m P^m (x) K_m,   K_m = K_{R-m}  (R x R blocks over theta),
 * with P the cyclic shift over phi.  The real Fourier vectors over phi
 * (1, cos(2 pi k i / R), sin(2 pi k i / R), (-1)^i) are eigenvectors of
 * every even circulant, so
 *     M (e_k (x) b) = e_k (x) C_k b,   C_k = sum_m K_m cos(2 pi k m / R),
 * and the SVD of M is the union of the SVDs of the R/2 + 1 blocks C_k
 * (k = 0, R/2 once; 0 < k < R/2 twice, with the cos and the sin vector).
 * Cost: R^4 / 2 for the transform and at most R/2 + 1 SVDs of R x R
 * (symmetric blocks by their eigendecomposition, circulant_sym.c), against
 * R^6 for a dense SVD; every singular value comes out, so the error of
 * every truncation is the exact tail sum_{r > J} sigma_r^2.
 *
 * Solid-angle weights of the io grid depend on theta only and keep the
 * structure.  Internal to the library (the plan uses it). */
#ifndef SEPBRDF_CIRCULANT_H
#define SEPBRDF_CIRCULANT_H

#include <stddef.h>

#include "sepbrdf/common.h"

typedef struct sb_circ sb_circ_t;

/* Workspace for R x R blocks (matrices of R^2 x R^2). */
sb_result_t sb_circ_create(sb_context_t *ctx, size_t R, sb_circ_t **out);
void sb_circ_destroy(sb_circ_t *c);

/* Whether channel `a` (ld >= R^2, the full matrix) weighted by w (R theta
 * weights, NULL = 1) is even in the azimuth difference to within rel_tol
 * of its largest entry.  Reads the first block row only. */
int sb_circ_is_even(const sb_circ_t *c, const double *a, size_t ld, const double *w, double rel_tol);

/* Exact SVD of W A W (A even block-circulant, W = diag(w) over theta):
 * the J leading triplets into s (J), u and v (R^2 x J, column-major), and
 * tails[j] = sum_{r > j} (sigma_r scale)^2 for j = 0..J-1 (the squared
 * error of the first j + 1 terms).  Ties between the two vectors of a pair
 * keep the cos vector first.  The selection is remembered for
 * sb_circ_max_abs.  Errors: SB_ERR_NUMERIC (LAPACK failed). */
sb_result_t sb_circ_svd(sb_circ_t *c, const double *a, size_t ld, const double *w, size_t J, double scale, double *s,
                        double *u, double *v, double *tails);

/* max |A - sum_{j<=J'} t s_j u_j v_j^T / (w w)| over all cells, for
 * J' = 1..J, with the triplets of the last sb_circ_svd (t = sigma_scale:
 * the factor of a proportional channel, 1 for the channel itself).  Works
 * on the R^3 distinct values, also where a truncation splits a cos/sin
 * pair (closed form over the azimuths).  mx receives J values. */
sb_result_t sb_circ_max_abs(sb_circ_t *c, const double *a, size_t ld, const double *w, double sigma_scale, size_t J,
                            double *mx);

/* How many blocks the last sb_circ_svd decomposed as symmetric matrices
 * (bit-for-bit symmetric: eigenvalues and eigenvectors, see
 * circulant_sym.c) rather than by dgesdd. */
size_t sb_circ_sym_blocks(const sb_circ_t *c);

/* The residual norms of any factors G, H (term j at g + j gstep and
 * h + j hstep, R^2 values each, cell R i_phi + i_theta) against a
 * block-circulant matrix stored as its first block row a (R x R^2, ld R:
 * cell (i, o) is a[i_theta + (R ((o_phi - i_phi) mod R) + o_theta) R]):
 *     ssq[j] = ||W_r (A - sum_{i<=j} g_i h_i^T) W_c||_F^2,  j < J,
 *     *n2   = ||W_r A W_c||_F^2,
 * W = diag of the theta weights wr, wc (R each, NULL = 1), by Parseval over
 * the azimuthal DFT (circulant_resid.c): about R^3 (J + log R) work, not
 * R^4 J; nt threads for the kernel's transform.  Errors: SB_ERR_OVERFLOW,
 * SB_ERR_NOMEM. */
sb_result_t sb_circ_resid(sb_context_t *ctx, size_t R, const double *a, const double *wr, const double *wc, size_t J,
                          const double *g, size_t gstep, const double *h, size_t hstep, int nt, double *ssq,
                          double *n2);

/* mx[j] = max |A - sum_{i<=j} g_i h_i^T| (unweighted, j < J, arguments as
 * sb_circ_resid's) over SB_CIRC_MAX_ROWS block rows, i_phi = floor(q R /
 * phi) mod R, q = 0, 1, ..., phi the golden ratio: every distinct value of
 * A at q = 0, so the largest cell wherever the residual is block-circulant
 * too (the two terms of a cos/sin pair kept and weighted alike), else the
 * largest of a sample of 4 R^3 of the R^4 cells (at most 0.9 % below the
 * largest on GGX 0.1 and 0.3, io R = 32 to 128: docs/performance.md).
 * r: R doubles of scratch. */
#define SB_CIRC_MAX_ROWS 4
void sb_circ_resid_max(size_t R, const double *a, size_t J, const double *g, size_t gstep, const double *h,
                       size_t hstep, double *r, double *mx);

/* ||W A W||_F^2 scale^2 of the last sb_circ_svd's channel where `a` is it
 * and it was even to the bit (mirror planes equal, finite): the sum of
 * its blocks' squared norms, (1 or 2) ||C_k||_F^2 (Parseval over the
 * azimuth), which equals sb_circ_norm2 to rounding at no cost; else -1. */
double sb_circ_last_norm2(const sb_circ_t *c, const double *a);

/* ||W A W||_F^2 scaled by scale^2, from the first block row. */
double sb_circ_norm2(size_t R, const double *a, size_t ld, const double *w, double scale);

#endif
