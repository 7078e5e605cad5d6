/* One axis of the snippet's texture lookup (data/sepbrdf.glsl, sb_brdf),
 * shared by the C reconstructions (sb_factors_eval, the estimator, the
 * grid metric): the two texels i[0], i[1] and the weight a of the second,
 * value = (1 - a) t[i[0]] + a t[i[1]].
 *     GL_LINEAR: u = s n - 1/2, i[0] = floor(u), i[1] = i[0] + 1, a = u - i[0],
 *     the indices wrapped (REPEAT: modulo n) or clamped (CLAMP_TO_EDGE);
 *     SB_EDGE_LINEAR (a CLAMP axis, n >= 2) beyond the last texel centre,
 *     u > n - 1: the line through the last two centres, i = (n - 2, n - 1),
 *     a = min(u, n - 1/2) - (n - 2) in (1, 3/2] (s beyond 1 reads s = 1).
 * A non-finite s gives index 0, weight NaN (the caller's NaN). */
#ifndef SEPBRDF_TEX_AXIS_H
#define SEPBRDF_TEX_AXIS_H

#include <math.h>
#include <stddef.h>

#include "sepbrdf/param.h"

static inline size_t sb_tex_wrap(long i, size_t n, int wrap) {
    if (i >= 0 && (size_t)i < n) return (size_t)i; /* inside: no division */
    if (wrap == SB_WRAP_REPEAT) {
        long m = i % (long)n;
        return (size_t)(m < 0 ? m + (long)n : m);
    }
    return i < 0 ? 0 : n - 1;
}

static inline double sb_tex_axis(double s, size_t n, int wrap, int edge, size_t i[2]) {
    double u = s * (double)n - 0.5;
    if (!isfinite(u)) {
        i[0] = i[1] = 0;
        return NAN;
    }
    if (edge == SB_EDGE_LINEAR && wrap != SB_WRAP_REPEAT && n >= 2 && u > (double)(n - 1)) {
        i[0] = n - 2, i[1] = n - 1;
        return fmin(u, (double)n - 0.5) - (double)(n - 2);
    }
    /* far outside: whole periods off (REPEAT) or any edge value (CLAMP),
     * so that the texel index fits a long */
    if (fabs(u) > 1e9) u = wrap == SB_WRAP_REPEAT ? fmod(u, (double)n) : copysign(1e9, u);
    double f = floor(u);
    i[0] = sb_tex_wrap((long)f, n, wrap);
    i[1] = sb_tex_wrap((long)f + 1, n, wrap);
    return u - f;
}

/* Both axes of a w x h texture: the 4 texels (row-major, x fastest) and
 * their weights (the product of the axes'). */
static inline void sb_tex_footprint(const double st[2], size_t w, size_t h, const int wrap[2], const int edge[2],
                                    size_t at[4], double fw[4]) {
    size_t x[2], y[2];
    double a = sb_tex_axis(st[0], w, wrap[0], edge[0], x), b = sb_tex_axis(st[1], h, wrap[1], edge[1], y);
    for (int k = 0; k < 4; k++) {
        at[k] = y[k >> 1] * w + x[k & 1];
        fw[k] = ((k & 1) ? a : 1 - a) * ((k >> 1) ? b : 1 - b);
    }
}

#endif
