/* Importance sampling of the layouts that sample their columns
 * (SB_CAP_COL_SAMPLE: vndf, an RGL file's own grid; the maths is in
 * sepbrdf/sampler.h).  Rows are the view's (g_k read at wo's g
 * coordinate), columns the nodes of a unit square of positions s that
 * the layout maps to the light for each wo (sb_param_col_sample): term k
 * is drawn with the density of the bilinear h_k itself over s, a cell
 * between the nodes by its exact integral (the mean of its 4 corners
 * times its area; the CDFs in double, so that the density is h_k(s) /
 * I_k exactly), then s in the cell by the patch's linear marginal in y and
 * linear conditional in x, and the layout's |ds/dwi| turns it into a
 * density over wi:
 *     p_F(wi | wo) = sum_k lum_c g_k(st_g) h_k(s) / sum_k W_k |ds/dwi|,
 * continuous in s, so that the GLSL's float s and the C's double give the
 * same density also at a cell's edge.  h_k's nodes are weighted by the
 * layout's sb_param_col_weight (vh: the solid angle per unit s; 1 for
 * vndf).  A layout whose columns fold a
 * mirror symmetry (SB_CAP_COL_FOLD: vh) gets either half with
 * probability 1/2 (s.y in [0, 2]); its |ds/dwi| counts the 1/2. */
#include <math.h>
#include <stdlib.h>

#include "sampler_impl.h"

struct sb_col_sampler {
    const sb_factors_t *f;
    const sb_param_t *p;
    size_t W, H, C, K; /* cells W x H between the nodes, K = J C distributions */
    double lum[3];
    double *cond;     /* K x H x W: conditional CDF of x in row y, inclusive */
    double *marg;     /* K x H: marginal CDF of y, inclusive */
    double *integral; /* K: I_k = int h_k ds over the unit square */
    double *weight;   /* (W + 1) x (H + 1): the nodes' sb_param_col_weight */
};

/* The tables of distribution k: per cell the mean of its corners. */
static void corners(const sb_col_sampler_t *c, size_t k, size_t x, size_t y, double v[4]);
static void build_tables(sb_col_sampler_t *c, size_t k, double *rowsum, double *tmp) {
    double v[4];
    for (size_t y = 0; y < c->H; y++) {
        for (size_t x = 0; x < c->W; x++) {
            corners(c, k, x, y, v);
            tmp[x] = 0.25 * (v[0] + v[1] + v[2] + v[3]);
        }
        rowsum[y] = sb_cdf_build_(tmp, c->W, 0, c->cond + (k * c->H + y) * c->W);
    }
    c->integral[k] = sb_cdf_build_(rowsum, c->H, 0, c->marg + k * c->H) / (double)(c->W * c->H);
}

sb_result_t sb_col_sampler_create_(sb_context_t *ctx, const sb_factors_t *f, const sb_param_t *p, const double lum[3],
                                   sb_col_sampler_t **out) {
    size_t sw, sh;
    sb_factors_size(f, SB_SIDE_H, &sw, &sh);
    if (sw < 2 || sh < 2) return sb_error(ctx, SB_ERR_ARG, "sampler: %s has fewer than 2 x 2 nodes", sb_param_spec(p));
    sb_col_sampler_t *c = sb_calloc(ctx, 1, sizeof *c, "sampler");
    if (!c) return SB_ERR_NOMEM;
    *c = (sb_col_sampler_t){.f = f, .p = p, .W = sw - 1, .H = sh - 1, .C = sb_factors_channels(f)};
    c->K = sb_factors_terms(f) * c->C;
    for (int i = 0; i < 3; i++)
        c->lum[i] = lum[i];
    c->cond = sb_alloc(ctx, c->W * c->H, c->K * sizeof(double), "sampler tables");
    c->marg = sb_alloc(ctx, c->H, c->K * sizeof(double), "sampler tables");
    c->integral = sb_alloc(ctx, c->K, sizeof(double), "sampler tables");
    c->weight = sb_alloc(ctx, sw * sh, sizeof(double), "sampler tables");
    for (size_t i = 0; c->weight && i < sw * sh; i++) {
        const double s[2] = {(double)(i % sw) / (double)c->W, (double)(i / sw) / (double)c->H};
        double w = sb_param_col_weight(p, s);
        c->weight[i] = w > 0 && isfinite(w) ? w : 0;
    }
    double *rowsum = sb_alloc(ctx, c->H, sizeof(double), "sampler tables");
    double *tmp = sb_alloc(ctx, c->W, sizeof(double), "sampler tables");
    int ok = c->cond && c->marg && c->integral && c->weight && rowsum && tmp;
    double total = 0;
    for (size_t k = 0; ok && k < c->K; k++) {
        build_tables(c, k, rowsum, tmp);
        total += c->integral[k];
    }
    free(rowsum);
    free(tmp);
    sb_result_t r = !ok ? SB_ERR_NOMEM : SB_OK;
    if (ok && !(total > 0)) r = sb_error(ctx, SB_ERR_NUMERIC, "sampler: every texel is 0, nothing to sample");
    if (r != SB_OK) {
        sb_col_sampler_destroy_(c);
        return r;
    }
    *out = c;
    return SB_OK;
}

void sb_col_sampler_destroy_(sb_col_sampler_t *c) {
    if (!c) return;
    free(c->cond);
    free(c->marg);
    free(c->integral);
    free(c->weight);
    free(c);
}

/* W_k(wo) = lum_c g_k(st_g) I_k for every k, st_g the g coordinate of the
 * pair (mirror(wo), wo) (the view's alone); their sum, 0 when wo is
 * outside the domain. */
static double weights(const sb_col_sampler_t *c, const double wo[3], double *w) {
    const double m[3] = {-wo[0], -wo[1], wo[2]};
    double st_g[2], st_h[2], total = 0;
    if (!sb_param_coords(c->p, m, wo, st_g, st_h)) return 0;
    for (size_t k = 0; k < c->K; k++) {
        size_t ch = k % c->C;
        w[k] = c->lum[ch] * sb_factors_lookup(c->f, c->p, SB_SIDE_G, k / c->C, ch, st_g) * c->integral[k];
        if (!(w[k] > 0)) w[k] = 0;
        total += w[k];
    }
    return total;
}

/* t in [0, 1] with density proportional to (1 - t) a + t b (a, b >= 0,
 * not both 0) by u (pbrt-v4's SampleLinear). */
static double sample_linear(double a, double b, double u) {
    if (u == 0 && a == 0) return 0;
    double t = u * (a + b) / (a + sqrt((1 - u) * a * a + u * b * b));
    return t < 1 ? t : nextafter(1.0, 0.0);
}

/* The 4 nodes of cell (x, y) of h_k, each times its weight: v[0] (x,
 * y), v[1] (x + 1, y), v[2] (x, y + 1), v[3] (x + 1, y + 1). */
static void corners(const sb_col_sampler_t *c, size_t k, size_t x, size_t y, double v[4]) {
    const double *h = sb_factors_tex_const(c->f, SB_SIDE_H, k / c->C, k % c->C), *w = c->weight;
    size_t n = c->W + 1, i = y * n + x;
    v[0] = h[i] * w[i], v[1] = h[i + 1] * w[i + 1], v[2] = h[i + n] * w[i + n], v[3] = h[i + n + 1] * w[i + n + 1];
}

int sb_col_dir_(const sb_col_sampler_t *c, const double wo[3], double u0, double u1, double wi[3]) {
    double *w = malloc(c->K * sizeof *w);
    double total = w ? weights(c, wo, w) : 0, target = u0 * total, acc = 0;
    size_t k = 0, last = 0;
    for (; total > 0 && k < c->K; k++) {
        if (!(w[k] > 0)) continue;
        last = k;
        if (target < acc + w[k]) break;
        acc += w[k];
    }
    if (k == c->K) k = last, acc = total - w[last]; /* rounding ran past the end */
    double r = total > 0 ? (target - acc) / w[k] : 0, v[4];
    free(w);
    if (!(total > 0)) return 0;
    u0 = r < 0 ? 0 : (r < 1 ? r : nextafter(1.0, 0.0));
    int mirror = 0; /* SB_CAP_COL_FOLD: either half of the fold by the term's remainder */
    if (sb_param_caps(c->p) & SB_CAP_COL_FOLD) {
        mirror = u0 >= 0.5;
        u0 = mirror ? 2 * u0 - 1 : 2 * u0;
    }
    size_t y = sb_cdf_find_(c->marg + k * c->H, c->H, &u0);
    size_t x = sb_cdf_find_(c->cond + (k * c->H + y) * c->W, c->W, &u1);
    corners(c, k, x, y, v); /* in the cell: y by the patch's marginal, x by its conditional at y */
    double fy = sample_linear(v[0] + v[1], v[2] + v[3], u0);
    double fx = sample_linear(v[0] + fy * (v[2] - v[0]), v[1] + fy * (v[3] - v[1]), u1);
    double s[2] = {((double)x + fx) / (double)c->W, ((double)y + fy) / (double)c->H};
    if (mirror) s[1] = 2 - s[1];
    return sb_param_col_sample(c->p, wo, s, wi);
}

/* h_k at s (in [0, 1]^2), bilinear between the nodes. */
static double node_lerp(const sb_col_sampler_t *c, size_t k, const double s[2]) {
    double px = fmin(fmax(s[0], 0), 1) * (double)c->W, py = fmin(fmax(s[1], 0), 1) * (double)c->H, v[4];
    size_t x = px < (double)c->W ? (size_t)px : c->W - 1, y = py < (double)c->H ? (size_t)py : c->H - 1;
    double fx = px - (double)x, fy = py - (double)y;
    corners(c, k, x, y, v);
    return (1 - fy) * ((1 - fx) * v[0] + fx * v[1]) + fy * ((1 - fx) * v[2] + fx * v[3]);
}

double sb_col_pdf_(const sb_col_sampler_t *c, const double wo[3], const double wi[3]) {
    double s[2], jac = sb_param_col_density(c->p, wi, wo, s);
    double *w = jac > 0 ? malloc(c->K * sizeof *w) : NULL;
    double total = w ? weights(c, wo, w) : 0, num = 0;
    for (size_t k = 0; total > 0 && k < c->K; k++)
        if (w[k] > 0) num += w[k] / c->integral[k] * node_lerp(c, k, s);
    free(w);
    return total > 0 ? num / total * jac : 0;
}

void sb_col_sampler_cells_(const sb_col_sampler_t *c, size_t *W, size_t *H) {
    *W = c->W;
    *H = c->H;
}

double sb_col_file_texel_(const sb_col_sampler_t *c, size_t k, size_t x, size_t y) {
    if (x < c->W && y < c->H) return c->cond[(k * c->H + y) * c->W + x];
    if (x == c->W && y < c->H) return c->marg[k * c->H + y];
    return x == 0 && y == c->H ? c->integral[k] : 0;
}
