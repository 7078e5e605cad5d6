/* Tabulated 2D functions and warps (table2d.h). */
#include "util/table2d.h"

#include "util/internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Bisection steps: 2^-64 of the unit interval, below double resolution. */
#define WARP_STEPS 64

void sb_table_interval(const double *x, size_t n, double p, size_t *i, double *w1) {
    *i = 0;
    *w1 = 0;
    if (n < 2) return;
    size_t lo = 0;
    while (lo + 2 < n && x[lo + 1] < p)
        lo++;
    double t = (p - x[lo]) / (x[lo + 1] - x[lo]);
    *i = lo;
    *w1 = t < 0 ? 0 : t > 1 ? 1 : t;
}

/* Value of a per-slice array a[slice * stride + k], slice-interpolated. */
static double mix(const double *a, size_t stride, size_t k, const slices_t *s) {
    double v = 0;
    for (int q = 0; q < 4; q++)
        if (s->wt[q] != 0) v += s->wt[q] * a[s->idx[q] * stride + k];
    return v;
}

/* Patch of a unit-square position: column/row index and fractions. */
static void patch(const table2d_t *t, const double pos[2], size_t *ix, size_t *iy, double f[2]) {
    double x = (pos[0] < 0 ? 0 : pos[0] > 1 ? 1 : pos[0]) * (double)(t->w - 1);
    double y = (pos[1] < 0 ? 0 : pos[1] > 1 ? 1 : pos[1]) * (double)(t->h - 1);
    *ix = (size_t)x < t->w - 2 ? (size_t)x : t->w - 2;
    *iy = (size_t)y < t->h - 2 ? (size_t)y : t->h - 2;
    f[0] = x - (double)*ix;
    f[1] = y - (double)*iy;
}

double sb_table_bilinear(const table2d_t *t, const double pos[2], const slices_t *s, size_t c) {
    static const slices_t one = {{0, 0, 0, 0}, {1, 0, 0, 0}};
    size_t ix, iy;
    double f[2];
    patch(t, pos, &ix, &iy, f);
    size_t n = t->w * t->h, stride = t->chans * n, k = c * n + iy * t->w + ix;
    if (!s) s = &one;
    double v00 = mix(t->v, stride, k, s), v10 = mix(t->v, stride, k + 1, s);
    double v01 = mix(t->v, stride, k + t->w, s), v11 = mix(t->v, stride, k + t->w + 1, s);
    return (1 - f[1]) * ((1 - f[0]) * v00 + f[0] * v10) + f[1] * ((1 - f[0]) * v01 + f[0] * v11);
}

/* Continuous marginal/conditional inversion: y' = marginal CDF at u_y, x'
 * = conditional CDF of the row interpolated at u_y, evaluated at u_x, over
 * that row's total.  The bilinear patch integrates exactly: x' within the
 * patch adds f_x (c0 + f_x (c1 - c0) / 2) with c0, c1 the patch's column
 * values at f_y. */
void sb_table_warp_invert(const table2d_t *t, const double u[2], const slices_t *s, double out[2]) {
    size_t ix, iy;
    double f[2];
    patch(t, u, &ix, &iy, f);
    size_t n = t->w * t->h, k = iy * t->w + ix, last = iy * t->w + t->w - 1;
    double v00 = mix(t->v, n, k, s), v10 = mix(t->v, n, k + 1, s);
    double v01 = mix(t->v, n, k + t->w, s), v11 = mix(t->v, n, k + t->w + 1, s);
    double c0 = (1 - f[1]) * v00 + f[1] * v01, c1 = (1 - f[1]) * v10 + f[1] * v11;
    double x = f[0] * (c0 + 0.5 * f[0] * (c1 - c0));
    x += (1 - f[1]) * mix(t->ccdf, n, k, s) + f[1] * mix(t->ccdf, n, k + t->w, s);
    double r0 = mix(t->ccdf, n, last, s), r1 = mix(t->ccdf, n, last + t->w, s);
    double row = (1 - f[1]) * r0 + f[1] * r1;
    out[0] = row > 0 ? x / row : u[0];
    out[1] = f[1] * (r0 + 0.5 * f[1] * (r1 - r0)) + mix(t->mcdf, t->h, iy, s);
}

/* warp_invert's out[1] alone at u_y: the marginal CDF, which u_x takes
 * no part in (the same operations, so the same bits). */
static double warp_marginal(const table2d_t *t, double uy, const slices_t *s) {
    size_t ix, iy;
    double f[2], u[2] = {0, uy};
    patch(t, u, &ix, &iy, f);
    size_t n = t->w * t->h, last = iy * t->w + t->w - 1;
    double r0 = mix(t->ccdf, n, last, s), r1 = mix(t->ccdf, n, last + t->w, s);
    return f[1] * (r0 + 0.5 * f[1] * (r1 - r0)) + mix(t->mcdf, t->h, iy, s);
}

/* warp_invert's out[0] along the row at u_y: what u_x does not change
 * (the row's patch, fraction and total) computed once. */
typedef struct warp_row {
    size_t iy;
    double fy, row;
} warp_row_t;

static void warp_row(const table2d_t *t, double uy, const slices_t *s, warp_row_t *r) {
    size_t ix;
    double f[2], u[2] = {0, uy};
    patch(t, u, &ix, &r->iy, f);
    size_t n = t->w * t->h, last = r->iy * t->w + t->w - 1;
    double r0 = mix(t->ccdf, n, last, s), r1 = mix(t->ccdf, n, last + t->w, s);
    r->fy = f[1];
    r->row = (1 - f[1]) * r0 + f[1] * r1;
}

static double warp_conditional(const table2d_t *t, const warp_row_t *r, double ux, const slices_t *s) {
    size_t ix, iy;
    double f[2], u[2] = {ux, 0};
    patch(t, u, &ix, &iy, f);
    size_t n = t->w * t->h, k = r->iy * t->w + ix;
    double v00 = mix(t->v, n, k, s), v10 = mix(t->v, n, k + 1, s);
    double v01 = mix(t->v, n, k + t->w, s), v11 = mix(t->v, n, k + t->w + 1, s);
    double c0 = (1 - r->fy) * v00 + r->fy * v01, c1 = (1 - r->fy) * v10 + r->fy * v11;
    double x = f[0] * (c0 + 0.5 * f[0] * (c1 - c0));
    x += (1 - r->fy) * mix(t->ccdf, n, k, s) + r->fy * mix(t->ccdf, n, k + t->w, s);
    return r->row > 0 ? x / r->row : ux;
}

/* The u in (0, 1] with warp_invert(u)[axis] = s by bisection, the other
 * coordinate of u at `row` (axis 1: NULL, the marginal CDF).  For s = 0
 * it stays 2^-64 off the edge.  Once the midpoint rounds to lo or hi
 * nothing changes any more (lo was found below s, hi at or above it, or
 * is 1, which the steps return either way): the loop stops there with
 * the same hi. */
static double warp_solve(const table2d_t *t, const slices_t *one, const warp_row_t *row, double s) {
    double lo = 0, hi = 1;
    for (int k = 0; k < WARP_STEPS; k++) {
        double at = 0.5 * (lo + hi);
        if (at == lo || at == hi) break;
        if ((row ? warp_conditional(t, row, at, one) : warp_marginal(t, at, one)) < s)
            lo = at;
        else
            hi = at;
    }
    return hi;
}

void sb_table_warp_sample(const table2d_t *t, const slices_t *one, const double s[2], double u[2]) {
    warp_row_t row;
    u[1] = warp_solve(t, one, NULL, s[1]);
    warp_row(t, u[1], one, &row);
    u[0] = warp_solve(t, one, &row, s[0]);
}

double sb_table_elevation(const double d[3]) {
    double h = 0.5 * sqrt(d[0] * d[0] + d[1] * d[1] + (d[2] - 1) * (d[2] - 1));
    return 2 * asin(h > 1 ? 1 : h);
}
double sb_table_theta2u(double theta) { return sqrt(theta * (2 / SB_PI)); }
double sb_table_phi2u(double phi) { return (phi + SB_PI) / (2 * SB_PI); }

static double *dup(const double *a, size_t n) {
    if (!a) return NULL;
    double *b = malloc(n * sizeof *b);
    if (b) memcpy(b, a, n * sizeof *b);
    return b;
}

int sb_table_copy(table2d_t *dst, const table2d_t *src) {
    size_t n = src->w * src->h * src->slices;
    *dst = *src;
    dst->v = dup(src->v, n * src->chans);
    dst->ccdf = dup(src->ccdf, n);
    dst->mcdf = dup(src->mcdf, src->h * src->slices);
    if ((src->v && !dst->v) || (src->ccdf && !dst->ccdf) || (src->mcdf && !dst->mcdf)) {
        sb_table_free(dst);
        return -1;
    }
    return 0;
}

void sb_table_free(table2d_t *t) {
    free(t->v);
    free(t->ccdf);
    free(t->mcdf);
    t->v = t->ccdf = t->mcdf = NULL;
}
