/* A scene's weights for fits and its pairs for the estimator (scene.h).
 *
 * Mass: n points of the Kronecker set i alpha (alpha_d = 1/phi^(d+1), phi
 * the root of x^7 = x + 1, as the estimator draws) mapped to pairs; each
 * pair in the domain adds q a_r b_c to the cells (r, c) of its bilinear
 * footprints (a_r over the 4 g texels of its st_g, b_c over the 4 h
 * texels of st_h, the GL conventions of param.h), with q the headline's
 * weight over the squared form weight: cos^2(theta_i) for f, 1 for cos,
 * 1 / cos^2(theta_o) for cos2 (cos(theta_o) at least 0.001, the snippet's
 * guard).
 *
 * Separable weights: a_r b_c ~ mass_rc on the cells of positive mass,
 * by alternating least squares (rank one, non-negative from a
 * non-negative start), a few tens of sweeps; W_r = sqrt(a_r), W_c =
 * sqrt(b_c), at least 1e-3 of their largest. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "factor/estimate_draw.h"
#include "output/scene_impl.h"
#include "sepbrdf/scene.h"
#include "util/internal.h"

#define MASS_MIN_PAIRS ((size_t)1 << 18)
#define MASS_MAX_PAIRS ((size_t)1 << 22)
#define MASS_PER_CELL 8
#define SEP_SWEEPS 30
#define W_FLOOR 1e-3
/* A ranges scene's pairs: the share drawn uniformly within the ranges,
 * the rest by the whole domain's mixture (draw_ranges).  Measured
 * (docs/scene.md, "A scene's ranges drawn toward the lobe"): the
 * headline's spread over 8 seeds, view=0..40;light=0..60, uniform / 0.5
 * / 0.25 / 0.1: Cook-Torrance 0.1 hd J = 4 5.5 % (2^19 pairs) / 1.7 % /
 * 1.1 % / 1.1 % (65 536), RGL green malachite J = 4 21 % / 1.2 % / 1.5 %
 * / 1.3 %; smooth lobes (GGX 0.3, gold, Phong n = 100) 0.2-0.7 % / 0.5-0.8
 * % / 0.4-0.8 % / 0.5-1.7 %. */
#define RANGES_UNIFORM 0.25

static size_t wrap_at(long i, size_t n, int mode) {
    if (mode == SB_WRAP_REPEAT) {
        long m = i % (long)n;
        return (size_t)(m < 0 ? m + (long)n : m);
    }
    return i < 0 ? 0 : ((size_t)i >= n ? n - 1 : (size_t)i);
}

/* The 4 texels (row-major index) and bilinear weights of st on a w x h
 * texture with wraps wr. */
static void footprint(const double st[2], size_t w, size_t h, const int wr[2], size_t at[4], double fw[4]) {
    double u = st[0] * (double)w - 0.5, v = st[1] * (double)h - 0.5;
    double x0 = floor(u), y0 = floor(v), fx = u - x0, fy = v - y0;
    size_t xs[2] = {wrap_at((long)x0, w, wr[0]), wrap_at((long)x0 + 1, w, wr[0])};
    size_t ys[2] = {wrap_at((long)y0, h, wr[1]), wrap_at((long)y0 + 1, h, wr[1])};
    for (int k = 0; k < 4; k++) {
        at[k] = ys[k >> 1] * w + xs[k & 1];
        fw[k] = ((k & 1) ? fx : 1 - fx) * ((k >> 1) ? fy : 1 - fy);
    }
}

static double form_q(sb_form_t form, const double wi[3], const double wo[3]) {
    if (form == SB_FORM_COS) return 1;
    if (form == SB_FORM_COS2) return 1 / fmax(wo[2] * wo[2], 1e-6);
    return wi[2] * wi[2];
}

sb_result_t sb_scene_mass(sb_context_t *ctx, const sb_scene_t *s, const sb_param_t *p, sb_form_t form, size_t n,
                          double *mass) {
    if (!s || !p || !mass) return sb_error(ctx, SB_ERR_ARG, "scene: NULL argument");
    size_t rows = sb_param_rows(p), cols = sb_param_cols(p), cells, size[2][2];
    int wrap[2][2];
    if (sb_size_mul(rows, cols, &cells)) return sb_error(ctx, SB_ERR_OVERFLOW, "scene: cell count overflows");
    for (int side = 0; side < 2; side++) {
        sb_param_texture_size(p, side, &size[side][0], &size[side][1]);
        sb_param_wrap(p, side, wrap[side]);
    }
    if (n == 0) /* enough that every cell the scene's pairs touch is touched by one drawn */
        n = cells > MASS_MAX_PAIRS / MASS_PER_CELL
                ? MASS_MAX_PAIRS
                : (MASS_PER_CELL * cells < MASS_MIN_PAIRS ? MASS_MIN_PAIRS : MASS_PER_CELL * cells);
    memset(mass, 0, cells * sizeof *mass);
    double alpha[6], a = 1, top = 0;
    for (int d = 0; d < 6; d++)
        alpha[d] = (a /= 1.1127756842787055);
    for (size_t i = 0; i < n; i++) {
        double x[6], wi[3], wo[3], st[2][2], fw[2][4];
        size_t at[2][4];
        for (int d = 0; d < 6; d++) {
            double v = 0.5 + (double)(i + 1) * alpha[d];
            x[d] = v - floor(v);
        }
        if (!sb_scene_draw(s, x, wi, wo) || !sb_param_coords(p, wi, wo, st[0], st[1])) continue;
        for (int side = 0; side < 2; side++)
            footprint(st[side], size[side][0], size[side][1], wrap[side], at[side], fw[side]);
        double q = form_q(form, wi, wo);
        for (int g = 0; g < 4; g++)
            for (int h = 0; h < 4; h++)
                mass[at[0][g] + at[1][h] * rows] += q * fw[0][g] * fw[1][h];
    }
    for (size_t c = 0; c < cells; c++)
        top = fmax(top, mass[c]);
    if (!(top > 0))
        return sb_error(ctx, SB_ERR_RANGE, "scene: none of the pairs of %s lies in the domain of %s", sb_scene_spec(s),
                        sb_param_spec(p));
    for (size_t c = 0; c < cells; c++)
        mass[c] /= top;
    return SB_OK;
}

double sb_scene_floor_on(const sb_scene_t *s, const sb_param_t *p) {
    double x = sb_scene_floor(s);
    /* not given: on a partial domain (masked anyway), and for ranges on a
     * separable layout (io, io-area: the mass is then rows x columns, which
     * the fit's separable weights hold exactly, so the mask adds nothing) */
    unsigned caps = p ? sb_param_caps(p) : 0;
    int ranges = s && sb_scene_kind(s) == SB_SCENE_RANGES;
    if (x < 0) x = (caps & SB_CAP_PARTIAL_DOMAIN) || (ranges && (caps & SB_CAP_SEPARABLE)) ? SB_SCENE_FLOOR : 0;
    return x;
}

void sb_scene_mass_floor(const sb_scene_t *s, const sb_param_t *p, double *mass, size_t cells) {
    double x = sb_scene_floor_on(s, p), total = 0;
    size_t empty = 0;
    for (size_t c = 0; mass && x > 0 && c < cells; c++)
        total += mass[c], empty += !(mass[c] > 0);
    for (size_t c = 0; empty && c < cells; c++)
        if (!(mass[c] > 0)) mass[c] = x * total / (double)empty;
}

/* Rank-one a b^T ~ mass on its positive cells (header); w = sqrt, floored. */
void sb_scene_weights(const double *mass, size_t rows, size_t cols, double *w) {
    if (!mass || !w) return;
    double *a = w, *b = w + rows;
    for (size_t c = 0; c < cols; c++)
        b[c] = 1;
    for (int sweep = 0; sweep < SEP_SWEEPS; sweep++) {
        for (size_t r = 0; r < rows; r++) {
            double num = 0, den = 0;
            for (size_t c = 0; c < cols; c++)
                if (mass[r + c * rows] > 0) num += mass[r + c * rows] * b[c], den += b[c] * b[c];
            a[r] = den > 0 ? num / den : 0;
        }
        for (size_t c = 0; c < cols; c++) {
            double num = 0, den = 0;
            for (size_t r = 0; r < rows; r++)
                if (mass[r + c * rows] > 0) num += mass[r + c * rows] * a[r], den += a[r] * a[r];
            b[c] = den > 0 ? num / den : 0;
        }
    }
    double *v[2] = {a, b}, ma[2] = {0, 0};
    size_t len[2] = {rows, cols};
    for (int k = 0; k < 2; k++) {
        for (size_t i = 0; i < len[k]; i++)
            ma[k] = fmax(ma[k], v[k][i]);
        for (size_t i = 0; i < len[k]; i++)
            v[k][i] = sqrt(fmax(v[k][i], W_FLOOR * W_FLOOR * ma[k]));
    }
}

sb_result_t sb_scene_apply(sb_context_t *ctx, const sb_scene_t *s, const sb_param_t *p, sb_matrix_t *m, double *w) {
    if (!s || !p || !m || !w) return sb_error(ctx, SB_ERR_ARG, "scene: NULL argument");
    if (m->structured || m->streamed || m->ld != m->rows)
        return sb_error(ctx, SB_ERR_ARG, "scene: the matrix must be stored dense");
    if (m->rows != sb_param_rows(p) || m->cols != sb_param_cols(p))
        return sb_error(ctx, SB_ERR_ARG, "scene: the matrix does not match %s", sb_param_spec(p));
    size_t cells = m->rows * m->cols, valid = 0;
    double *mass = sb_alloc_large(ctx, cells, sizeof *mass, "scene mass");
    sb_result_t r = mass ? sb_scene_mass(ctx, s, p, m->form, 0, mass) : SB_ERR_NOMEM;
    if (r == SB_OK) sb_scene_mass_floor(s, p, mass, cells);
    if (r == SB_OK && !m->mask) {
        if ((m->mask = sb_alloc_large(ctx, cells, 1, "matrix mask")) != NULL)
            memset(m->mask, 1, cells);
        else
            r = SB_ERR_NOMEM;
    }
    if (r == SB_OK) {
        for (size_t c = 0; c < cells; c++) {
            m->mask[c] = (unsigned char)(m->mask[c] && mass[c] > 0);
            valid += m->mask[c];
        }
        m->valid_count = m->measured_count = valid;
        m->phi_period = 0;
        sb_scene_weights(mass, m->rows, m->cols, w);
    }
    free(mass);
    return r;
}

static double draw_scene(const void *user, const double x[6], double wi[3], double wo[3]) {
    return sb_scene_draw(user, x, wi, wo);
}

/* A ranges scene's pairs: with probability RANGES_UNIFORM uniform within
 * the ranges (sb_scene_draw, x0..x3), else the whole domain's mixture
 * toward the lobe (estimate_draw.h; x5 rescaled, so each branch sees
 * uniform points) with the pairs outside the ranges at density 0.  A pair
 * within has density a u + (1 - a) m (u the ranges' uniform density, m
 * the mixture's, both per solid angle): the estimate is over the ranges,
 * with the uniform's coverage on a tiny scene and the mixture's draws of
 * a sharp lobe's residual, which uniform draws read low. */
static double draw_ranges(const void *user, const double x[6], double wi[3], double wo[3]) {
    const double a = RANGES_UNIFORM;
    if (x[5] < a) {
        sb_scene_draw(user, x, wi, wo);
    } else {
        double y[6] = {x[0], x[1], x[2], x[3], x[4], (x[5] - a) / (1 - a)};
        if (!(sb_estimate_draw_pair(y, wi, wo) > 0)) return 0;
    }
    double u = sb_scene_ranges_pdf_(user, wi, wo);
    return u > 0 ? a * u + (1 - a) * sb_estimate_pair_pdf(wi, wo) : 0;
}

/* A lights scene's pairs: the share drawn uniformly over the sphere's
 * image (sb_scene_draw), the rest toward the highlights (draw_lights).
 * The lobes' GGX alphas are the estimator's (estimate.h), from a mirror
 * to a broad lobe. */
#define LIGHTS_UNIFORM 0.25
#define LIGHTS_LOBES 4
static const double lights_alpha[LIGHTS_LOBES] = {0.005, 0.02, 0.08, 0.3};

/* The half vector H = (L + V) / |L + V| of light k (V = (0, 0, 1)). */
static void light_half(const sb_scene_t *s, size_t k, double h[3]) {
    const double *l = sb_scene_light_dir_(s, k);
    double v[3] = {l[0], l[1], l[2] + 1}, n = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (int i = 0; i < 3; i++)
        h[i] = n > 0 ? v[i] / n : (i == 2);
}

/* The GGX normal distribution of width a at cos(theta) = c, times c: a
 * density per solid angle about its axis. */
static double ggx_dc(double a, double c) {
    double a2 = a * a, t = (a2 - 1) * c * c + 1;
    return c > 0 ? a2 * c / (SB_PI * t * t) : 0;
}

/* The direction at cos(theta) = z, azimuth 2 pi u about the unit axis h
 * (Duff et al. 2017's frame). */
static void about(const double h[3], double z, double u, double w[3]) {
    double sg = copysign(1, h[2]), a = -1 / (sg + h[2]), b = h[0] * h[1] * a, d[3];
    double t[3] = {1 + sg * h[0] * h[0] * a, sg * b, -sg * h[0]}, bt[3] = {b, sg + h[1] * h[1] * a, -h[1]};
    sb_estimate_dir_z(z, u, d);
    for (int i = 0; i < 3; i++)
        w[i] = d[0] * t[i] + d[1] * bt[i] + d[2] * h[i];
}

/* A lights scene's pair drawn from x: light k = floor(x2 N) and with
 * probability LIGHTS_UNIFORM the point p of the sphere's image uniform
 * over the unit disk, density 1 / pi per area (sb_scene_draw's map), else
 * the normal n about H_k from one of the lobes chosen alike (tan^2 theta
 * = a^2 x0 / (1 - x0), azimuth 2 pi x1: density D_a(n.H) n.H per solid
 * angle), p = (n_x, n_y) where n_z > 0 (dA = n_z dw: density D_a(n.H)
 * n.H / n_z per area), else no pair.  Returns the mixture's density over
 * the uniform's, a + (1 - a) pi mean_a D_a(n.H) n.H / n_z: the errors are
 * still those over the sphere's pixels, with the highlight's pairs drawn
 * often enough (a uniform draw over the pixels reads a sharp one with 8 %
 * spread at 2^19 pairs). */
static double draw_lights(const void *user, const double x[6], double wi[3], double wo[3]) {
    const sb_scene_t *s = user;
    const double a = LIGHTS_UNIFORM;
    size_t nl = sb_scene_light_count_(s), k = (size_t)(x[2] * (double)nl), lobe;
    double h[3], n[3], lobes = 0;
    if (!nl) return 0;
    light_half(s, k = k < nl ? k : nl - 1, h);
    if (x[5] < a) {
        double r = sqrt(x[0]), ang = 2 * SB_PI * x[1];
        n[0] = r * cos(ang), n[1] = r * sin(ang), n[2] = 1;
    } else {
        lobe = (size_t)((x[5] - a) / (1 - a) * LIGHTS_LOBES);
        double al = lights_alpha[lobe < LIGHTS_LOBES ? lobe : LIGHTS_LOBES - 1], t2 = al * al * x[0] / (1 - x[0]);
        about(h, 1 / sqrt(1 + t2), x[1], n);
    }
    if (!(n[2] > 0) || !sb_scene_light_pair_(s, n[0], n[1], k, wi, wo)) return 0;
    n[2] = sqrt(fmax(0, 1 - n[0] * n[0] - n[1] * n[1])); /* the normal at p */
    if (!(n[2] > 0)) return 0;
    double c = n[0] * h[0] + n[1] * h[1] + n[2] * h[2];
    for (int j = 0; j < LIGHTS_LOBES; j++)
        lobes += ggx_dc(lights_alpha[j], c);
    return a + (1 - a) * SB_PI * lobes / (LIGHTS_LOBES * n[2]);
}

sb_result_t sb_scene_pairs_create(sb_context_t *ctx, const sb_scene_t *s, const sb_source_t *src,
                                  const sb_estimate_opts_t *opts, sb_pairs_t **out) {
    if (!s) return sb_error(ctx, SB_ERR_ARG, "scene: NULL argument");
    sb_scene_kind_t kind = sb_scene_kind(s);
    sb_pair_draw_fn draw = kind == SB_SCENE_RANGES ? draw_ranges : kind == SB_SCENE_LIGHTS ? draw_lights : draw_scene;
    return sb_pairs_create_drawn(ctx, src, opts, draw, s, out);
}

sb_result_t sb_scene_estimate(sb_context_t *ctx, const sb_scene_t *s, const sb_source_t *src, const sb_factors_t *f,
                              const sb_param_t *p, sb_form_t form, const sb_estimate_opts_t *opts, sb_estimate_t *out) {
    sb_pairs_t *pairs = NULL;
    sb_result_t r = sb_scene_pairs_create(ctx, s, src, opts, &pairs);
    if (r == SB_OK) r = sb_estimate_compute(ctx, pairs, f, NULL, p, form, opts, out);
    sb_pairs_destroy(pairs);
    return r;
}
