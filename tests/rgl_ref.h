/* Test helpers for the RGL tensor_file reader (test_measured_rgl.c): a
 * writer of tensor files, synthetic materials, the test's own reader of
 * the real files, and an independent evaluation of the Mitsuba 3
 * `measured` semantics (its own parser, quadrature instead of the CDF
 * tables, acos-free angles). */
#ifndef SB_TEST_RGL_REF_H
#define SB_TEST_RGL_REF_H

#include <stdint.h>

#define PI 3.14159265358979323846

typedef struct wfield {
    const char *name;
    unsigned dtype; /* 1 u8, 10 f32 */
    int ndim;
    uint64_t shape[5];
    const void *data; /* u8 or float, C order */
} wfield_t;

/* Write the fields f[0..nf) as a tensor_file (version 1.0) at path. */
void write_tensor(const char *path, const wfield_t *f, int nf);

typedef struct mat {
    int nphi, ntheta, vw, vh, cw, ch, nw, nh, chans;
    float phi[16], theta[16];
    float *vndf, *col, *ndf, *sigma; /* [nphi][ntheta][vh][vw], [..][chans][ch][cw], [nh][nw] */
    int jacobian;
    double *norm;     /* integral of each vndf slice (set by mat_norms) */
    double cw3[3][8]; /* colour weights: RGB = sum cw3[c][k] col_k (identity for rgb) */
} mat_t;

double rnd(unsigned long long *s);
/* A random material: 5 theta_i slices, nphi phi_i slices over [phi0, phi1],
 * vndf 16 x 12, colour 9 x 7 (some negative), ndf/sigma 20 x 2, jacobian. */
void mat_random(mat_t *m, unsigned long long seed, int nphi, float phi0, float phi1);
void mat_free(mat_t *m);
/* Write m as a tensor_file (spectral with wavelengths wl when not NULL). */
void mat_write(const char *path, const mat_t *m, const float *wl);
/* Read the fields the reference needs from a real file; 1 on success. */
int load_real(const char *path, mat_t *m);

/* Bilinear texture lookup on nodes k/(n-1), position clamped. */
double tex(const float *t, int w, int h, double x, double y);
/* Each vndf slice's integral over the unit square (m->norm). */
void mat_norms(mat_t *m);
/* f_r for light l, view v (both above the horizon); s (may be NULL)
 * receives the sample-space position (X, Y) the colour table is read at,
 * *jac (may be NULL) the jacobian factor. */
void ref_eval(const mat_t *m, const double l_in[3], const double v_in[3], double rgb[3], double s[2], double *jac);

#endif
