/* Private: the RGL tensor_file tables shared by the reader and evaluation
 * (rgl.c) and its measured samples (rgl_samples.c). */
#ifndef SEPBRDF_RGL_IMPL_H
#define SEPBRDF_RGL_IMPL_H

#include <math.h>
#include <stddef.h>

#include "util/internal.h"
#include "util/table2d.h"

typedef struct rgl {
    size_t n_phi, n_theta;
    double *phi, *theta; /* slice positions (radians) */
    table2d_t ndf, sigma, vndf, rgb;
    int isotropic, jacobian, reduction;
} rgl_t;

/* The factor NDF(u_m) / (4 sigma(u_v)) when the file's jacobian flag is
 * set, else 1. */
double sb_rgl_jacobian_(const rgl_t *g, const double u_m[2], const double u_v[2]);

/* The measured samples (sb_source_sample): every colour node of every
 * (phi_i, theta_i) slice, mapped to its pair of directions. */
size_t sb_rgl_sample_count_(const void *self);
int sb_rgl_sample_(const void *self, size_t k, double wi[3], double wo[3], double f[3]);

#endif
