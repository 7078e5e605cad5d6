/* The tabulated warps shared by the RGL reader and the vndf layout
 * (src/util/table2d.c): sb_table_warp_sample is the warp's inverse solved
 * by bisection, and its shortcuts (the marginal alone for u_y, the row's
 * constants once for u_x, a stop once the midpoint rounds to an end)
 * give the same bits as the plain 64-step bisection on
 * sb_table_warp_invert. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "util/table2d.h"

/* The plain bisection (the code before the shortcuts). */
static double solve_plain(const table2d_t *t, const slices_t *one, int axis, double other, double s) {
    double lo = 0, hi = 1, out[2], at[2];
    at[1 - axis] = other;
    for (int k = 0; k < 64; k++) {
        at[axis] = 0.5 * (lo + hi);
        sb_table_warp_invert(t, at, one, out);
        if (out[axis] < s)
            lo = at[axis];
        else
            hi = at[axis];
    }
    return hi;
}

/* A normalised warp table of w x h nodes, 2 slices, random values (a
 * column of zeros where `hole`); its CDFs as the RGL reader builds them. */
static void make_table(table2d_t *t, size_t w, size_t h, int hole, unsigned long long *rng) {
    size_t n = w * h;
    *t = (table2d_t){
        w, h, 2, 1, malloc(2 * n * sizeof(double)), malloc(2 * n * sizeof(double)), malloc(2 * h * sizeof(double))};
    for (size_t sl = 0; sl < 2; sl++) {
        double *v = t->v + sl * n, *cc = t->ccdf + sl * n, *mc = t->mcdf + sl * h, m = 0;
        for (size_t y = 0; y < h; y++)
            for (size_t x = 0; x < w; x++)
                v[y * w + x] = hole && x == 1 ? 0 : 0.05 + sb_rand01(rng);
        for (size_t y = 0; y < h; y++) {
            double c = 0;
            for (size_t x = 0; x < w; x++) {
                cc[y * w + x] = c;
                if (x + 1 < w) c += 0.5 * (v[y * w + x] + v[y * w + x + 1]) / (double)(w - 1);
            }
        }
        for (size_t y = 0; y < h; y++) {
            mc[y] = m;
            if (y + 1 < h) m += 0.5 * (cc[y * w + w - 1] + cc[(y + 1) * w + w - 1]) / (double)(h - 1);
        }
        for (size_t i = 0; i < n; i++)
            v[i] /= m, cc[i] /= m;
        for (size_t y = 0; y < h; y++)
            mc[y] /= m;
    }
}

SB_TEST(warp_sample_is_the_bisection) {
    unsigned long long rng = 4321;
    long differ = 0, far = 0, total = 0;
    for (int rep = 0; rep < 24; rep++) {
        table2d_t t;
        make_table(&t, 2 + rep % 9, 2 + rep % 5, rep % 4 == 0, &rng);
        slices_t one = {{(size_t)(rep % 2), 0, 0, 0}, {1, 0, 0, 0}};
        for (int i = 0; i < 4000; i++) {
            double s[2] = {sb_rand01(&rng), sb_rand01(&rng)}, u[2], ref[2], back[2];
            if (i % 5 == 0) s[i % 10 == 0] *= 1e-9; /* near the edge: more steps than a double's bits */
            if (i % 97 == 0) s[0] = 0, s[1] = 1;
            sb_table_warp_sample(&t, &one, s, u);
            ref[1] = solve_plain(&t, &one, 1, 0, s[1]);
            ref[0] = solve_plain(&t, &one, 0, ref[1], s[0]);
            differ += memcmp(u, ref, sizeof u) != 0;
            sb_table_warp_invert(&t, u, &one, back);
            far += !(fabs(back[0] - s[0]) < 1e-9 && fabs(back[1] - s[1]) < 1e-9);
            total++;
        }
        sb_table_free(&t);
    }
    CHECKF(differ == 0, "%ld of %ld differ from the plain bisection", differ, total);
    CHECKF(far == 0, "%ld of %ld do not invert back to s within 1e-9", far, total);
}
