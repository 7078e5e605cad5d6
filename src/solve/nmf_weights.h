/* The non-negative solver's cell weights toward the headline and the
 * reference errors of its prefixes (nmf_weights.c). */
#ifndef SB_SOLVE_NMF_WEIGHTS_H
#define SB_SOLVE_NMF_WEIGHTS_H

#include <stddef.h>

#include "sepbrdf/matrix.h"
#include "sepbrdf/param.h"

/* hw (m x n) = each data cell's weight in the headline over its weight in
 * the fit (ext 1: a data cell; the others get 0), clipped at the 99th
 * percentile of the data cells and divided by their mean: (f_r cos
 * theta_i / the stored form)^2, times the layout's gain (vndf: gain^2 x
 * the node's solid angle, which its warp makes 1 / gain).  Where raw is
 * given, the same weights unclipped (over their own mean) into it.
 * Returns 0, or -1 when out of memory or no data cell has a weight. */
int sb_nmf_headline_weights(const sb_param_t *p, sb_form_t form, const unsigned char *ext, size_t m, size_t n,
                            double *hw, double *raw);

/* U (m x J) and V (n x J): the J leading terms s_j u_j, v_j of the dense
 * m x n matrix x (LAPACK's SVD).  Returns 0, or -1 when out of memory or
 * the SVD fails. */
/* On a layout on the source's tables (columns the sw x sh nodes of the
 * colour grid): out = max(hw, k times the largest hw of the nodes one step
 * away in the grid, the same slice); elsewhere hw. */
void sb_nmf_spread_weights(const sb_param_t *p, const double *hw, size_t m, size_t n, double k, double *out);
int sb_nmf_svd_terms(const double *x, size_t m, size_t n, size_t J, double *U, double *V);

/* The largest over the prefixes p = 1..J of sum hw (x - U_p V_p^T)^2 /
 * sum hw (x - R_p S_p^T)^2 (U_p the first p columns of U; R, S the
 * reference's terms): the worst prefix against the reference in the
 * headline's weights.  A reference prefix without error counts as
 * floor2. */
double sb_nmf_worst_ratio(const double *x, const double *hw, size_t m, size_t n, size_t J, const double *U,
                          const double *V, const double *R, const double *S, double floor2);
/* The same ratios per prefix, p = 1..J, into ratio (J numbers). */
void sb_nmf_prefix_ratios(const double *x, const double *hw, size_t m, size_t n, size_t J, const double *U,
                          const double *V, const double *R, const double *S, double floor2, double *ratio);

#endif
