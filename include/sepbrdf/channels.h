/* sepbrdf: proportional colour channels.
 *
 * Many BRDFs are one shape times a colour: M_c = a_c M for every channel c
 * (Lambert, a tinted glossy lobe without Fresnel colour shift, grey measured
 * data).  Then the truncated SVD of one matrix serves all three: the factor
 * step can factor the base channel once and give each term a colour,
 *     M_c ~ sum_j (a_c sigma_j) u_j v_j^T,
 * which is optimal for every channel at once (scaling does not change the
 * singular vectors) and costs a third of the work. */
#ifndef SEPBRDF_CHANNELS_H
#define SEPBRDF_CHANNELS_H

#include "common.h"
#include "matrix.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Default relative tolerance of sb_channels_proportional: a few hundred
 * roundings of double precision, far below anything visible, far above
 * the error of computing a_c M in floating point. */
#define SB_CHANNELS_DEFAULT_TOL 1e-12

typedef struct sb_channels {
    int proportional; /* 1: every present channel is scale[c] * M_base */
    int base;         /* the present channel of largest norm, -1 if none */
    double scale[3];  /* least-squares a_c = <M_c, M_base> / ||M_base||^2; 1 for base, 0 if absent */
    double dev[3];    /* ||M_c - a_c M_base||_F / ||M_c||_F (0 for a zero or absent channel);
                         when not proportional the check stops early and this is a lower bound */
    double norm[3];   /* ||M_c||_F (0 for an absent channel) */
} sb_channels_t;

/* Decide whether the channels of m are proportional: with base the present
 * channel of largest Frobenius norm, every present channel c must satisfy
 *     ||M_c - a_c M_base||_F <= rel_tol ||M_c||_F,
 * a_c the least-squares scale.  rel_tol = 0 means SB_CHANNELS_DEFAULT_TOL.
 * Masked cells hold 0 in every channel (matrix.h) and so take no part.  A
 * zero channel is proportional (a_c = 0); a single present channel, or an
 * all-zero matrix, is trivially proportional.  One read of each channel.
 * Errors: SB_ERR_ARG (NULL m or out, no channel present), SB_ERR_RANGE
 * (rel_tol negative or >= 1), SB_ERR_NUMERIC (a non-finite entry). */
SB_API sb_result_t sb_channels_proportional(sb_context_t *ctx, const sb_matrix_t *m, double rel_tol,
                                            sb_channels_t *out);

#ifdef __cplusplus
}
#endif
#endif
