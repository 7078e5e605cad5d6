/* Importance sampling from non-negative factors: the tables (marginal and
 * conditional CDFs of every g_k weighted by the row measures), the term
 * weights of an outgoing direction, sb_sample and sb_pdf (the maths is in
 * sepbrdf/sampler.h), and the tables' file for the GLSL sampler. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "sampler_impl.h"

struct sb_sampler {
    const sb_factors_t *f;
    const sb_param_t *p;
    sb_form_t form;
    size_t W, H, J, C, K; /* g texture W x H, K = J C distributions */
    int half_rows;        /* SB_CAP_HALF_ROWS: rows index h, wi = reflect(wo, h) */
    double lum[3];
    double share;           /* the cosine-weighted share s (a float's value: the GLSL reads it so) */
    double lobe, alpha;     /* the GGX lobe's share s_l and roughness (floats' values; s_l = 0: none) */
    double *cond;           /* K x H x W: conditional CDF of x in row y, inclusive */
    double *marg;           /* K x H: marginal CDF of y, inclusive */
    double *integral;       /* K: I_k = sum_r g_k[r] m_r */
    double *measure;        /* H x W: m_r */
    double *mcos;           /* H x W: m_r, times cos theta_i at the centre for the form f on io, io-area */
    double *wtab;           /* half rows: K x H x W, W_k for wo in row cell c (sampler.h) */
    double *zlo, *zhi;      /* half rows: W, the z = 1 - cos(theta) bounds of column x's cells */
    double *pa, *pw;        /* half rows: H, the phi arc [pa, pa + pw] of row y's cells */
    float *edge[2];         /* W + 1, H + 1: the row cells' edges (sb_param_row_cell), in the file's layer K */
    sb_col_sampler_t *cols; /* SB_CAP_COL_SAMPLE: the columns' sampler (W x H its cells; no row tables) */
};

/* Half rows: the cut of every row for one wo (sampler_half.c): z_cut and
 * the count of the row's cells whose z_lo is below it (the others cannot
 * reflect wo above the horizon and are not sampled). */
typedef struct cuts {
    half_view_t v;
    double z[SB_SAMPLER_MAX_ROWS];
    size_t x[SB_SAMPLER_MAX_ROWS];
} cuts_t;

/* Where the weights of an outgoing direction are read: the h coordinate
 * (io, io-area), or for half rows the four row cells around wo's g
 * coordinate and their bilinear weights (GL: between cell centres). */
typedef struct wkey {
    double st_h[2];
    size_t cell[4];
    double bw[4];
} wkey_t;

/* Refuse what cannot be sampled: a negative or non-finite texel on either
 * side (the message names the first one). */
static sb_result_t check_nonneg(sb_context_t *ctx, const sb_factors_t *f) {
    static const char *const side_name[2] = {"g", "h"};
    for (int side = 0; side < 2; side++) {
        size_t w, h;
        sb_factors_size(f, side, &w, &h);
        for (size_t j = 0; j < sb_factors_terms(f); j++)
            for (size_t c = 0; c < sb_factors_channels(f); c++) {
                const double *t = sb_factors_tex_const(f, side, j, c);
                for (size_t i = 0; i < w * h; i++)
                    if (!(t[i] >= 0) || !isfinite(t[i]))
                        return sb_error(ctx, SB_ERR_ARG,
                                        "sampler: %s_%02zu channel %zu has texel %g at (%zu, %zu): signed factors "
                                        "(the SVD's) cannot be sampled; factor with --method nmf",
                                        side_name[side], j, c, t[i], i % w, i / w);
            }
    }
    return SB_OK;
}

/* The tables of distribution k: g_k m_r per texel (m_r including cos
 * theta_i at the cell's centre for the form f on io, io-area: measure),
 * rows' CDFs, marginal. */
static void build_tables(sb_sampler_t *s, size_t k, double *rowsum, double *tmp) {
    const double *g = sb_factors_tex_const(s->f, SB_SIDE_G, k / s->C, k % s->C);
    for (size_t y = 0; y < s->H; y++) {
        for (size_t x = 0; x < s->W; x++)
            tmp[x] = g[y * s->W + x] * s->mcos[y * s->W + x];
        rowsum[y] = sb_cdf_build_(tmp, s->W, 1, s->cond + (k * s->H + y) * s->W);
    }
    s->integral[k] = sb_cdf_build_(rowsum, s->H, 1, s->marg + k * s->H);
}

static size_t texel_of(double s, size_t n) {
    double v = floor(s * (double)n);
    if (!(v >= 0)) return 0;
    return v >= (double)n ? n - 1 : (size_t)v;
}

/* The two cells around st (in [0, 1]) on an axis of n cells, wrapped
 * (REPEAT) or clamped, and the weight of the second (GL bilinear). */
static double axis_taps(double st, size_t n, int repeat, size_t i[2]) {
    double u = (st < 0 ? 0 : (st > 1 ? 1 : st)) * (double)n - 0.5, f = floor(u);
    for (int t = 0; t < 2; t++) {
        long v = (long)f + t;
        i[t] = repeat ? (size_t)((v + (long)n) % (long)n) : (v < 0 ? 0 : (v >= (long)n ? n - 1 : (size_t)v));
    }
    return u - f;
}

/* The weights' key for wo: st_h of the pair (mirror(wo), wo),
 * mirror(wo) = (-x, -y, z), or for half rows the table's bilinear
 * footprint at the g coordinate of the pair (wo, wo), whose half vector is
 * wo: continuous in wo, so that float (the GLSL) and double pick the same
 * weights at a cell edge.  0 when wo is outside the domain. */
static int weight_key(const sb_sampler_t *s, const double wo[3], wkey_t *key) {
    const double m[3] = {-wo[0], -wo[1], wo[2]};
    double st_g[2], st_h[2];
    if (!s->half_rows) return sb_param_coords(s->p, m, wo, st_g, key->st_h);
    if (!sb_param_coords(s->p, wo, wo, st_g, st_h)) return 0;
    int wrap[2];
    size_t x[2], y[2];
    sb_param_wrap(s->p, SB_SIDE_G, wrap);
    double a = axis_taps(st_g[0], s->W, wrap[0] == SB_WRAP_REPEAT, x);
    double b = axis_taps(st_g[1], s->H, wrap[1] == SB_WRAP_REPEAT, y);
    for (int t = 0; t < 4; t++) {
        key->cell[t] = y[t / 2] * s->W + x[t % 2];
        key->bw[t] = (t % 2 ? a : 1 - a) * (t / 2 ? b : 1 - b);
    }
    return 1;
}

/* W_k = lum_c h_k(st_h) I_k (a bilinear lookup of non-negative texels), or
 * the table bilinear between cell centres for half rows. */
static double weight(const sb_sampler_t *s, size_t k, const wkey_t *key) {
    if (s->half_rows) {
        const double *t = s->wtab + k * s->W * s->H;
        return key->bw[0] * t[key->cell[0]] + key->bw[1] * t[key->cell[1]] + key->bw[2] * t[key->cell[2]] +
               key->bw[3] * t[key->cell[3]];
    }
    size_t c = k % s->C;
    double h = sb_factors_lookup(s->f, s->p, SB_SIDE_H, k / s->C, c, key->st_h);
    return s->lum[c] * h * s->integral[k];
}

/* Half rows: W_k(wo_c) = lum_c sum_r g_k[r] m_r h_k(st_h(wi_rc, wo_c)) over
 * the row cells r whose reflection wi_rc = 2 (wo_c.h_r) h_r - wo_c is in
 * the domain, h_r and wo_c the centres of cells r and c (u = 1/2). */
static void build_wtab(sb_sampler_t *s) {
    size_t n = s->W * s->H;
    const double mid[2] = {0.5, 0.5};
    for (size_t c = 0; c < n; c++) {
        double wo[3];
        sb_param_row_sample(s->p, c, mid, wo);
        for (size_t k = 0; k < s->K; k++)
            s->wtab[k * n + c] = 0;
        for (size_t r = 0; r < n; r++) {
            double h[3], wi[3], sg[2], sh[2];
            sb_param_row_sample(s->p, r, mid, h);
            double d = h[0] * wo[0] + h[1] * wo[1] + h[2] * wo[2];
            for (int i = 0; i < 3; i++)
                wi[i] = 2 * d * h[i] - wo[i];
            if (!(d > 0) || !sb_param_coords(s->p, wi, wo, sg, sh)) continue;
            for (size_t k = 0; k < s->K; k++) {
                double g = sb_factors_tex_const(s->f, SB_SIDE_G, k / s->C, k % s->C)[r];
                if (g > 0)
                    s->wtab[k * n + c] += s->lum[k % s->C] * g * s->measure[r] *
                                          sb_factors_lookup(s->f, s->p, SB_SIDE_H, k / s->C, k % s->C, sh);
            }
        }
    }
}

/* z = 1 - cos(theta) of a unit vector, accurate near the pole (the GLSL
 * sampler computes it so in float). */
static double one_minus_z(const double d[3]) { return (d[0] * d[0] + d[1] * d[1]) / (1 + d[2]); }

/* Half rows: the z bounds of each column of cells and the phi arc of each
 * row, read off sb_param_row_sample at the corners (linear in z and phi;
 * phi at z_hi, defined also in the cells at the pole). */
static void cell_bounds(sb_sampler_t *s) {
    double d[3], e[3];
    for (size_t x = 0; x < s->W; x++) {
        sb_param_row_sample(s->p, x, (const double[2]){0, 0}, d);
        sb_param_row_sample(s->p, x, (const double[2]){1, 0}, e);
        s->zlo[x] = one_minus_z(d);
        s->zhi[x] = one_minus_z(e);
    }
    for (size_t y = 0; y < s->H; y++) {
        sb_param_row_sample(s->p, y * s->W + s->W - 1, (const double[2]){1, 0}, d);
        sb_param_row_sample(s->p, y * s->W + s->W - 1, (const double[2]){1, 0.5}, e);
        double a = atan2(d[1], d[0]), half = atan2(e[1], e[0]) - a;
        if (half <= 0) half += 2 * SB_PI;
        s->pa[y] = a;
        s->pw[y] = 2 * half;
    }
}

static sb_result_t sampler_alloc(sb_context_t *ctx, sb_sampler_t *s) {
    size_t n = s->W * s->H;
    s->cond = sb_alloc(ctx, n, s->K * sizeof(double), "sampler tables");
    s->marg = sb_alloc(ctx, s->H, s->K * sizeof(double), "sampler tables");
    s->integral = sb_alloc(ctx, s->K, sizeof(double), "sampler tables");
    s->measure = sb_alloc(ctx, n, sizeof(double), "sampler tables");
    s->mcos = sb_alloc(ctx, n, sizeof(double), "sampler tables");
    s->edge[0] = sb_calloc(ctx, s->W + s->H + 2, sizeof(float), "sampler tables");
    if (!s->edge[0]) return SB_ERR_NOMEM;
    s->edge[1] = s->edge[0] + s->W + 1;
    for (size_t i = 1; i < s->W; i++)
        s->edge[0][i] = sb_param_row_edge(s->p, 0, i);
    for (size_t j = 1; j < s->H; j++)
        s->edge[1][j] = sb_param_row_edge(s->p, 1, j);
    if (s->half_rows) {
        s->wtab = sb_alloc(ctx, n, s->K * sizeof(double), "sampler tables");
        s->zlo = sb_alloc(ctx, s->W, 2 * sizeof(double), "sampler tables");
        s->pa = sb_alloc(ctx, s->H, 2 * sizeof(double), "sampler tables");
        if (!s->wtab || !s->zlo || !s->pa) return SB_ERR_NOMEM;
        s->zhi = s->zlo + s->W;
        s->pw = s->pa + s->H;
    }
    return s->cond && s->marg && s->integral && s->measure && s->mcos ? SB_OK : SB_ERR_NOMEM;
}

/* The rows' tables (every layout but SB_CAP_COL_SAMPLE ones, sampler_cols.c):
 * m_r, the CDFs of every distribution, for half rows W_k(c) and the
 * cells' bounds. */
static sb_result_t rows_build(sb_context_t *ctx, sb_sampler_t *s) {
    double *rowsum = NULL, *tmp = NULL;
    sb_result_t r = sampler_alloc(ctx, s);
    if (r == SB_OK) {
        rowsum = sb_alloc(ctx, s->H, sizeof *rowsum, "sampler tables");
        tmp = sb_alloc(ctx, s->W, sizeof *tmp, "sampler tables");
        if (!rowsum || !tmp) r = SB_ERR_NOMEM;
    }
    double total = 0;
    for (size_t i = 0; r == SB_OK && i < s->W * s->H; i++) {
        double d[3];
        s->measure[i] = s->mcos[i] = (float)sb_param_row_measure(s->p, i); /* the file's value */
        if (s->form == SB_FORM_F && !s->half_rows) { /* f: the density follows f cos theta_i (rows are wi) */
            sb_param_row_sample(s->p, i, (const double[2]){0.5, 0.5}, d);
            s->mcos[i] *= fmax(d[2], 0);
        }
    }
    for (size_t k = 0; r == SB_OK && k < s->K; k++) {
        build_tables(s, k, rowsum, tmp);
        total += s->integral[k];
    }
    free(rowsum);
    free(tmp);
    if (r == SB_OK && s->half_rows) {
        build_wtab(s);
        cell_bounds(s);
    }
    if (r == SB_OK && !(total > 0)) r = sb_error(ctx, SB_ERR_NUMERIC, "sampler: every texel is 0, nothing to sample");
    return r;
}

sb_result_t sb_sampler_create(sb_context_t *ctx, const sb_factors_t *f, const sb_param_t *p, sb_form_t form,
                              sb_sampler_t **out) {
    if (!out) return sb_error(ctx, SB_ERR_ARG, "sampler: no output");
    *out = NULL;
    if (!f || !p || (unsigned)form >= SB_FORM_COUNT_)
        return sb_error(ctx, SB_ERR_ARG, "sampler: no factors, no parameterisation or unknown form");
    size_t gw, gh, hw, hh, pw[2], ph[2];
    sb_factors_size(f, SB_SIDE_G, &gw, &gh);
    sb_factors_size(f, SB_SIDE_H, &hw, &hh);
    sb_param_texture_size(p, SB_SIDE_G, &pw[0], &ph[0]);
    sb_param_texture_size(p, SB_SIDE_H, &pw[1], &ph[1]);
    if (gw != pw[0] || gh != ph[0] || hw != pw[1] || hh != ph[1] || gw * gh == 0)
        return sb_error(ctx, SB_ERR_ARG, "sampler: textures %zux%zu and %zux%zu are not those of %s", gw, gh, hw, hh,
                        sb_param_spec(p));
    int cols = (sb_param_caps(p) & SB_CAP_COL_SAMPLE) != 0;
    if (!cols && !sb_param_sample_glsl(p)[0])
        return sb_error(ctx, SB_ERR_UNSUPPORTED,
                        "sampler: %s has no sampler (its layout samples neither rows nor columns)",
                        sb_param_kind_name(sb_param_kind(p)));
    if ((sb_param_caps(p) & SB_CAP_HALF_ROWS) && gh > SB_SAMPLER_MAX_ROWS)
        return sb_error(ctx, SB_ERR_UNSUPPORTED, "sampler: %s has %zu rows of half vectors, at most %d are sampled",
                        sb_param_spec(p), gh, SB_SAMPLER_MAX_ROWS);
    sb_result_t r = check_nonneg(ctx, f);
    if (r != SB_OK) return r;
    sb_sampler_t *s = sb_calloc(ctx, 1, sizeof *s, "sampler");
    if (!s) return SB_ERR_NOMEM;
    *s = (sb_sampler_t){.f = f, .p = p, .form = form, .W = gw, .H = gh, .J = sb_factors_terms(f)};
    s->share = (float)SB_SAMPLER_COSINE_SHARE;
    s->C = sb_factors_channels(f);
    s->K = s->J * s->C;
    s->half_rows = (sb_param_caps(p) & SB_CAP_HALF_ROWS) != 0;
    const double rec709[3] = {0.2126, 0.7152, 0.0722};
    for (int c = 0; c < 3; c++)
        s->lum[c] = s->C == 1 ? 1 : rec709[c];
    r = cols ? sb_col_sampler_create_(ctx, f, p, s->lum, &s->cols) : rows_build(ctx, s);
    if (r == SB_OK && cols) sb_col_sampler_cells_(s->cols, &s->W, &s->H); /* the file's sizes */
    if (r != SB_OK) {
        sb_sampler_destroy(s);
        return r;
    }
    *out = s;
    return SB_OK;
}

void sb_sampler_destroy(sb_sampler_t *s) {
    if (!s) return;
    free(s->cond);
    free(s->marg);
    free(s->integral);
    free(s->measure);
    free(s->mcos);
    free(s->wtab);
    free(s->zlo);
    free(s->pa);
    free(s->edge[0]);
    sb_col_sampler_destroy_(s->cols);
    free(s);
}

/* Pick k by u[0] (rescaled in place); the last k of positive weight when
 * rounding runs past the end.  total > 0. */
static size_t pick_term(const sb_sampler_t *s, const wkey_t *key, double total, double *u) {
    double target = *u * total, acc = 0;
    size_t last = 0;
    for (size_t k = 0; k < s->K; k++) {
        double wk = weight(s, k, key);
        if (!(wk > 0)) continue;
        if (target < acc + wk) {
            double r = (target - acc) / wk;
            *u = r < 0 ? 0 : (r < 1 ? r : nextafter(1.0, 0.0));
            return k;
        }
        last = k;
        acc += wk;
    }
    *u = nextafter(1.0, 0.0);
    return last;
}

/* Half rows: every row's cut for wo (cuts_t). */
static void cuts_of(const sb_sampler_t *s, const double wo[3], cuts_t *c) {
    half_view(wo, &c->v);
    for (size_t y = 0; y < s->H; y++) {
        c->z[y] = half_zcut(&c->v, s->pa[y], s->pw[y]);
        size_t lo = 0, hi = s->W; /* the first x with z_lo >= z_cut less a step of the cell */
        while (lo < hi) {
            size_t mid = (lo + hi) / 2;
            if (s->zlo[mid] < c->z[y] - (s->zhi[mid] - s->zlo[mid]) / SB_HALF_CUT_STEPS)
                lo = mid + 1;
            else
                hi = mid;
        }
        c->x[y] = lo;
    }
}

/* Half rows: the mass of distribution k in row y on the cells wo's cuts
 * keep, and on all of them. */
static double row_mass(const sb_sampler_t *s, size_t k, const cuts_t *c, size_t y) {
    const double *cond = s->cond + (k * s->H + y) * s->W;
    return c->x[y] ? sb_cdf_prob_(s->marg + k * s->H, y) * cond[c->x[y] - 1] : 0;
}

static double kept_mass(const sb_sampler_t *s, size_t k, const cuts_t *c) {
    double z = 0;
    for (size_t y = 0; y < s->H; y++)
        z += row_mass(s, k, c, y);
    return z;
}

/* Probability of row cell (x, y) per distribution k, summed with the
 * terms' weights: sum_k W_k P_k(x, y) / sum W, the tables restricted to
 * wo's cuts for half rows.  0 where no term has weight. */
static double cell_prob(const sb_sampler_t *s, const wkey_t *key, const cuts_t *c, size_t x, size_t y) {
    double num = 0, total = 0;
    for (size_t k = 0; k < s->K; k++) {
        double wk = weight(s, k, key);
        if (!(wk > 0)) continue;
        total += wk;
        double z = c ? kept_mass(s, k, c) : 1;
        if (z > 0)
            num += wk * sb_cdf_prob_(s->marg + k * s->H, y) * sb_cdf_prob_(s->cond + (k * s->H + y) * s->W, x) / z;
    }
    return total > 0 ? num / total : 0;
}

/* Whether a row's arc is the whole circle (iso): its h are drawn in z up
 * to the row's cut and in phi on the part valid at the cell's lowest z.
 * On the arcs of hd, over the whole cell (an h reflected below the
 * horizon is a failed sample): the kept part's extent there is a
 * difference of nearly equal values near the cut, which float and double
 * round apart (the GLSL's pdf at the same L differed by up to 13 %, beyond
 * 1e-4 relative at 4 % of the samples; now within 3.1e-5), for 94 -> 89 %
 * of the samples succeeding (GGX 0.3, 16 cells, theta_o 20; 93 -> 87 % at
 * 65).  On iso the same cost 90 -> 70 % and 96 -> 55 %. */
static int full_circle(double w) { return w >= 2 * SB_PI - 1e-6; }

/* The factored component's density at wi (0 where no term has weight).
 * Half rows: h uniform over the cell's z range below the row's cut and
 * the part of its phi arc that reflects wo above the horizon at the
 * cell's lowest z (a superset of that part at every higher z: the valid
 * half-width of Delta falls with theta), so the density stays bounded. */
static double factored_pdf(const sb_sampler_t *s, const double wo[3], const double wi[3], const double sg[2],
                           const wkey_t *key) {
    if (s->cols) return sb_col_pdf_(s->cols, wo, wi);
    size_t cell[2] = {texel_of(sg[0], s->W), texel_of(sg[1], s->H)}; /* kept where the layout places none */
    const float *const edge[2] = {s->edge[0], s->edge[1]};
    sb_param_row_cell(s->p, edge, wi, wo, cell);
    size_t x = cell[0], y = cell[1];
    if (!s->half_rows) return cell_prob(s, key, NULL, x, y) / s->measure[y * s->W + x];
    cuts_t c;
    cuts_of(s, wo, &c);
    if (x >= c.x[y]) return 0;
    double h[3], n = 0;
    for (int i = 0; i < 3; i++) {
        h[i] = wi[i] + wo[i];
        n += h[i] * h[i];
    }
    n = sqrt(n);
    for (int i = 0; i < 3; i++)
        h[i] /= n;
    double cosv = h[0] * wo[0] + h[1] * wo[1] + h[2] * wo[2];
    /* hd: the whole cell, its solid angle the file's m_r (the GLSL's arc and
     * z bounds from float atan and sin put its pdfs 5.6e-5 off the C's) */
    double area = s->measure[y * s->W + x];
    if (full_circle(s->pw[y]))
        area = half_cut_dz(s->zlo[x], s->zhi[x], c.z[y]) *
               half_phi_len(&c.v, half_arc_z(s->zlo[x], s->zhi[x], c.z[y]), s->pa[y], s->pw[y]);
    if (!(cosv > 0) || !(area > 0)) return 0;
    return cell_prob(s, key, &c, x, y) / area / (4 * cosv);
}

double sb_pdf(const sb_sampler_t *s, const double wo[3], const double wi[3]) {
    double sg[2], sh[2];
    wkey_t key;
    if (!s || !wo || !wi || !sb_param_coords(s->p, wi, wo, sg, sh) || !weight_key(s, wo, &key)) return 0;
    double rest = 1 - s->share - s->lobe, fp = rest > 0 ? factored_pdf(s, wo, wi, sg, &key) : 0;
    double lp = s->lobe > 0 ? s->lobe * sb_lobe_pdf_(s->alpha, wo, wi) : 0;
    return s->share * wi[2] / SB_PI + lp + (rest > 0 ? rest : 0) * fp;
}

/* Half rows: the row cell (x, y) of distribution k among those wo's cuts
 * keep (row by the restricted marginal, u0; column by the conditional
 * up to the cut, u1), then h in it and wi = 2 (wo.h) h - wo. */
static int half_dir(const sb_sampler_t *s, const double wo[3], size_t k, double u0, double u1, double d[3]) {
    cuts_t c;
    cuts_of(s, wo, &c);
    double total = kept_mass(s, k, &c), target = u0 * total, acc = 0, m = 0;
    if (!(total > 0)) return 0;
    size_t y = 0, last = 0;
    for (; y < s->H; y++) {
        if (!((m = row_mass(s, k, &c, y)) > 0)) continue;
        last = y;
        if (target < acc + m) break;
        acc += m;
    }
    if (y == s->H) { /* rounding ran past the end */
        y = last;
        m = row_mass(s, k, &c, y);
        acc = total - m;
    }
    double r = (target - acc) / m;
    u0 = r < 0 ? 0 : (r < 1 ? r : nextafter(1.0, 0.0));
    const double *cond = s->cond + (k * s->H + y) * s->W;
    u1 *= cond[c.x[y] - 1]; /* the conditional up to the cut */
    size_t x = sb_cdf_find_(cond, c.x[y], &u1);
    int circle = full_circle(s->pw[y]);
    double z = s->zlo[x] + u1 * (circle ? half_cut_dz(s->zlo[x], s->zhi[x], c.z[y]) : s->zhi[x] - s->zlo[x]), phi;
    if (!(z <= c.z[y])) return 0;
    if (!circle)
        phi = s->pa[y] + u0 * s->pw[y];
    else if (!half_phi_sample(&c.v, half_arc_z(s->zlo[x], s->zhi[x], c.z[y]), s->pa[y], s->pw[y], u0, &phi))
        return 0;
    double st = sqrt(fmax(z * (2 - z), 0)), h[3] = {st * cos(phi), st * sin(phi), 1 - z};
    double cv = h[0] * wo[0] + h[1] * wo[1] + h[2] * wo[2];
    if (!(cv > 0)) return 0;
    for (int i = 0; i < 3; i++)
        d[i] = 2 * cv * h[i] - wo[i];
    return 1;
}

/* The factored component's direction (before the domain check): the term
 * by its weight, the row cell by the tables, a direction in it (half rows:
 * half_dir).  0 when none (no weight, nothing kept for wo). */
static int factored_dir(const sb_sampler_t *s, const double wo[3], const wkey_t *key, double u0, double u1,
                        double d[3]) {
    if (s->cols) return sb_col_dir_(s->cols, wo, u0, u1, d);
    double total = 0;
    for (size_t k = 0; k < s->K; k++)
        total += weight(s, k, key);
    if (!(total > 0)) return 0;
    size_t k = pick_term(s, key, total, &u0);
    if (s->half_rows) return half_dir(s, wo, k, u0, u1, d);
    size_t y = sb_cdf_find_(s->marg + k * s->H, s->H, &u0);
    size_t x = sb_cdf_find_(s->cond + (k * s->H + y) * s->W, s->W, &u1);
    double uc[2] = {u1, u0};
    sb_param_row_sample(s->p, y * s->W + x, uc, d);
    return 1;
}

int sb_sample(const sb_sampler_t *s, const double wo[3], const double u[2], double wi[3], double *pdf, double rgb[3]) {
    if (wi) wi[0] = wi[1] = wi[2] = 0;
    if (pdf) *pdf = 0;
    if (rgb) rgb[0] = rgb[1] = rgb[2] = 0;
    double d[3];
    wkey_t key;
    if (!s || !wo || !u || !wi || !pdf || !weight_key(s, wo, &key)) return 0;
    if (u[0] < s->share) { /* cosine-weighted: r = sqrt(u0'), phi = 2 pi u1 */
        double r = sqrt(u[0] / s->share), phi = 2 * SB_PI * u[1];
        d[0] = r * cos(phi);
        d[1] = r * sin(phi);
        d[2] = sqrt(fmax(1 - r * r, 0));
    } else if (u[0] < s->share + s->lobe) { /* the GGX lobe: u0 rescaled */
        double u0 = (u[0] - s->share) / s->lobe;
        if (!sb_lobe_dir_(s->alpha, wo, u0 < 1 ? u0 : nextafter(1.0, 0.0), u[1], d)) return 0;
    } else {
        double u0 = (u[0] - s->share - s->lobe) / (1 - s->share - s->lobe);
        if (!factored_dir(s, wo, &key, u0 < 1 ? u0 : nextafter(1.0, 0.0), u[1], d)) return 0;
    }
    double n = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    double w[3] = {d[0] / n, d[1] / n, d[2] / n};
    double p = sb_pdf(s, wo, w);
    if (!(p > 0) || !(w[2] > 0)) return 0;
    memcpy(wi, w, sizeof w);
    *pdf = p;
    if (rgb) sb_factors_eval(s->f, s->p, s->form, s->J, wi, wo, rgb);
    return 1;
}

sb_result_t sb_sampler_set_cosine_share(sb_sampler_t *s, double share) {
    if (!s || !(share >= (float)SB_SAMPLER_MIN_SHARE && share <= 1) || (double)(float)share + s->lobe > 1)
        return SB_ERR_ARG;
    s->share = (float)share;
    return SB_OK;
}

double sb_sampler_cosine_share(const sb_sampler_t *s) { return s ? s->share : NAN; }

sb_result_t sb_sampler_set_lobe(sb_sampler_t *s, double share, double alpha) {
    int on = share > 0;
    if (!s || !(share >= 0) || (double)(float)share + s->share > 1 ||
        (on && !(alpha >= SB_SAMPLER_MIN_ALPHA && alpha <= 1)))
        return SB_ERR_ARG;
    s->lobe = (float)share;
    s->alpha = on ? (float)alpha : 0;
    return SB_OK;
}

double sb_sampler_lobe(const sb_sampler_t *s, double *alpha) {
    if (alpha) *alpha = s ? s->alpha : NAN;
    return s ? s->lobe : NAN;
}

/* ---- the tables' file --------------------------------------------------- */

static void put_u32(unsigned char *b, uint32_t v) {
    for (int i = 0; i < 4; i++)
        b[i] = (unsigned char)(v >> (8 * i));
}

/* Texel (x, y) of layer k of the file (layout: sampler.h). */
static double file_texel(const sb_sampler_t *s, const double *g_scale, size_t k, size_t x, size_t y) {
    int in = x < s->W && y < s->H;
    if (k == s->K && x == s->W && (y == s->H || y == 0)) return y ? s->lobe : s->alpha; /* the lobe */
    if (s->cols) /* the integrals in the h textures' units (g_scale: those of the side sampled) */
        return k < s->K
                   ? sb_col_file_texel_(s->cols, k, x, y) / (x == 0 && y == s->H && g_scale ? g_scale[k / s->C] : 1)
                   : (x == 0 && y == s->H ? s->share : 0);
    if (k > s->K) return in ? s->wtab[(k - s->K - 1) * s->W * s->H + y * s->W + x] : 0;
    if (k == s->K && in) return s->measure[y * s->W + x];
    if (k == s->K) return x == 0 && y == s->H ? s->share : (y == s->H ? s->edge[0][x % s->W] : s->edge[1][y]);
    if (in) return s->cond[(k * s->H + y) * s->W + x];
    if (x == s->W && y < s->H) return s->marg[k * s->H + y];
    return x == 0 ? s->integral[k] / (g_scale ? g_scale[k / s->C] : 1) : 0;
}

/* Layers x (H + 1) x (W + 1) little-endian float32. */
static void fill_layers(const sb_sampler_t *s, const double *g_scale, size_t layers, unsigned char *out) {
    size_t W1 = s->W + 1, H1 = s->H + 1;
    for (size_t k = 0; k < layers; k++)
        for (size_t y = 0; y < H1; y++)
            for (size_t x = 0; x < W1; x++) {
                float fv = (float)file_texel(s, g_scale, k, x, y);
                uint32_t bits;
                memcpy(&bits, &fv, sizeof bits);
                put_u32(out + 4 * ((k * H1 + y) * W1 + x), bits);
            }
}

sb_result_t sb_sampler_write(sb_context_t *ctx, const sb_sampler_t *s, const char *path, const double *g_scale) {
    if (!s || !path) return sb_error(ctx, SB_ERR_ARG, "sampler: no sampler or no path");
    size_t layers = s->half_rows ? 2 * s->K + 1 : s->K + 1, count = (s->W + 1) * (s->H + 1);
    unsigned char *buf = sb_alloc(ctx, layers * count, 4, "sampler file");
    if (!buf) return SB_ERR_NOMEM;
    unsigned char head[24] = "sbsampl1";
    put_u32(head + 8, (uint32_t)(s->W + 1));
    put_u32(head + 12, (uint32_t)(s->H + 1));
    put_u32(head + 16, (uint32_t)layers);
    put_u32(head + 20, (uint32_t)s->C);
    fill_layers(s, g_scale, layers, buf);
    const void *parts[2] = {head, buf};
    size_t sizes[2] = {sizeof head, layers * count * 4};
    int e = sb_write_atomic(path, parts, sizes, 2);
    free(buf);
    if (e) return sb_error(ctx, SB_ERR_IO, "%s: cannot write: %s", path, sb_io_why(e));
    return SB_OK;
}
