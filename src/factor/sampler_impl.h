/* Private: the half-vector layouts' geometry of the sampler
 * (sampler_half.c; the maths there). */
#ifndef SEPBRDF_SAMPLER_IMPL_H
#define SEPBRDF_SAMPLER_IMPL_H

#include "sepbrdf/sampler.h"
#include "util/internal.h"

/* wo seen from the half vectors: sin, cos theta_v and phi_v. */
typedef struct half_view {
    double sv, cv, phiv;
} half_view_t;

void half_view(const double wo[3], half_view_t *v);
/* z = 1 - cos(theta) below which h on the phi arc [a, a + w] can reflect
 * wo above the horizon (w >= 2 pi: the whole circle). */
double half_zcut(const half_view_t *v, double a, double w);
/* Length of the phi in [a, a + w] whose h at z reflects wo above the
 * horizon. */
double half_phi_len(const half_view_t *v, double z, double a, double w);
/* phi uniform over that set by u in [0, 1); 0 when it is empty. */
int half_phi_sample(const half_view_t *v, double z, double a, double w, double u, double *phi);
/* The steps of a cell that a whole-circle row's cut is rounded to
 * (half_cut_dz, half_arc_z; the GLSL's SB_CUT_STEPS). */
#define SB_HALF_CUT_STEPS 64
double half_cut_dz(double zlo, double zhi, double zc);
double half_arc_z(double zlo, double zhi, double zc);

#endif
