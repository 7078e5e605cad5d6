/* Private: the RGL tensor_file tables shared by the reader and evaluation
 * (rgl.c) and its measured samples (rgl_samples.c). */
#ifndef SEPBRDF_RGL_IMPL_H
#define SEPBRDF_RGL_IMPL_H

#include <math.h>
#include <stddef.h>

#include "util/internal.h"

/* One table: `slices` slices of h x w nodes (k/(w-1), k/(h-1) on the unit
 * square; column = x, row = y), `chans` values per node per slice, stored
 * [slice][chan][row][column]. */
typedef struct table2d {
    size_t w, h, slices, chans; /* chans: values per node per slice (rgb: C) */
    double *v;                  /* values (normalised for a warp) */
    double *ccdf;               /* warp: conditional CDF per row, [slice][h][w] */
    double *mcdf;               /* warp: marginal CDF, [slice][h] */
} table2d_t;

typedef struct rgl {
    size_t n_phi, n_theta;
    double *phi, *theta; /* slice positions (radians) */
    table2d_t ndf, sigma, vndf, rgb;
    int isotropic, jacobian, reduction;
} rgl_t;

/* Slice interpolation: up to four slices with weights. */
typedef struct slices {
    size_t idx[4];
    double wt[4];
} slices_t;

/* Bilinear value at pos of channel c, slices mixed by s (NULL: the one
 * slice of a plain table). */
double sb_rgl_bilinear_(const table2d_t *t, const double pos[2], const slices_t *s, size_t c);
/* The VNDF warp's inverse: the sample-space position of u (slices s). */
void sb_rgl_warp_invert_(const table2d_t *t, const double u[2], const slices_t *s, double out[2]);
/* Elevation of a unit vector, 2 asin(|d - z| / 2) (accurate near z). */
double sb_rgl_elevation_(const double d[3]);
/* The factor NDF(u_m) / (4 sigma(u_v)) when the file's jacobian flag is
 * set, else 1. */
double sb_rgl_jacobian_(const rgl_t *g, const double u_m[2], const double u_v[2]);
/* The tables' coordinates of an elevation and an azimuth. */
static inline double sb_rgl_theta2u(double theta) { return sqrt(theta * (2 / SB_PI)); }
static inline double sb_rgl_phi2u(double phi) { return (phi + SB_PI) / (2 * SB_PI); }

/* The measured samples (sb_source_sample): every colour node of every
 * (phi_i, theta_i) slice, mapped to its pair of directions. */
size_t sb_rgl_sample_count_(const void *self);
int sb_rgl_sample_(const void *self, size_t k, double wi[3], double wo[3], double f[3]);

#endif
