/* Private: tabulated 2D functions and warps on the unit square, as the RGL
 * tensor_file stores them (Mitsuba's Marginal2D): slices of h x w nodes at
 * k/(w-1), k/(h-1), bilinear between nodes, linear between slices.  Shared
 * by the RGL reader (source/rgl.c) and the layout built on its tables
 * (param/param_vndf.c). */
#ifndef SEPBRDF_TABLE2D_H
#define SEPBRDF_TABLE2D_H

#include <stddef.h>

/* One table: `slices` slices of h x w nodes (column = x, row = y),
 * `chans` values per node per slice, stored [slice][chan][row][column]. */
typedef struct table2d {
    size_t w, h, slices, chans; /* chans: values per node per slice (rgb: C) */
    double *v;                  /* values (normalised for a warp) */
    double *ccdf;               /* warp: conditional CDF per row, [slice][h][w] */
    double *mcdf;               /* warp: marginal CDF, [slice][h] */
} table2d_t;

/* Slice interpolation: up to four slices with weights. */
typedef struct slices {
    size_t idx[4];
    double wt[4];
} slices_t;

/* Largest i in [0, n-2] with x[i] < p (0 if none) and the weight of i + 1,
 * clamped to [0, 1] (0 for n < 2). */
void sb_table_interval(const double *x, size_t n, double p, size_t *i, double *w1);
/* Bilinear value at pos of channel c, slices mixed by s (NULL: the one
 * slice of a plain table). */
double sb_table_bilinear(const table2d_t *t, const double pos[2], const slices_t *s, size_t c);
/* The warp's inverse: the sample-space position of u (slices s). */
void sb_table_warp_invert(const table2d_t *t, const double u[2], const slices_t *s, double out[2]);
/* The warp itself on one slice: the u whose inverse is s (bisection to
 * double resolution: the inverse is monotone in u_y alone for the y part,
 * then in u_x on that row). */
void sb_table_warp_sample(const table2d_t *t, const slices_t *one, const double s[2], double u[2]);
/* The tensor_file's maps: elevation 2 asin(|d - z| / 2) (accurate near
 * z), u(theta) = sqrt(2 theta / pi), v(phi) = (phi + pi) / (2 pi). */
double sb_table_elevation(const double d[3]);
double sb_table_theta2u(double theta);
double sb_table_phi2u(double phi);
/* A deep copy of src's arrays into dst (NULL arrays stay NULL); -1 when out
 * of memory (dst then holds nothing to free). */
int sb_table_copy(table2d_t *dst, const table2d_t *src);
void sb_table_free(table2d_t *t);

#endif
