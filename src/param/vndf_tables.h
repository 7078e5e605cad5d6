/* Private: the tables the vndf layout is built on (param_vndf.c), made by
 * the RGL reader (source/rgl.c) or read back from vndf.exr. */
#ifndef SEPBRDF_VNDF_TABLES_H
#define SEPBRDF_VNDF_TABLES_H

#include "sepbrdf/param.h"
#include "util/table2d.h"

struct sb_layout_tables {
    size_t n_theta;
    double *theta;              /* the view's elevation per slice, increasing (radians) */
    table2d_t vndf, ndf, sigma; /* vndf: n_theta slices with its CDFs; ndf, sigma: one slice */
    size_t sw, sh;              /* the colour grid's nodes */
    table2d_t rgb;              /* the nodes themselves, [slice][3][sh][sw] (from the source; v NULL when read
                                   back from vndf.exr) */
    int jacobian;               /* the value carries NDF / (4 sigma) */
    double *dirs;               /* per cell (row + col n_theta): wi, wo (vndf_cell_dirs, made once); NULL: none */
};

/* Copies of the arrays, every value rounded to float (as vndf.exr holds
 * them); NULL when out of memory. */
sb_layout_tables_t *sb_layout_tables_make_(size_t n_theta, const double *theta, const table2d_t *vndf,
                                           const table2d_t *ndf, const table2d_t *sigma, size_t sw, size_t sh,
                                           int jacobian);
sb_layout_tables_t *sb_layout_tables_copy_(const sb_layout_tables_t *t);
/* The colour nodes (copied, not rounded) into t; -1 when out of memory. */
int sb_layout_tables_set_rgb_(sb_layout_tables_t *t, const table2d_t *rgb);

#endif
