/* RGL material database tables: the Mitsuba "tensor_file" (.bsdf) of
 * Dupuy & Jakob 2018, evaluated as Mitsuba 3's `measured` plugin does.
 *
 * Container (little-endian): "tensor_file\0", version {1, 0}, uint32 field
 * count, then per field: uint16 name length, name, uint16 ndim, uint8
 * dtype, uint64 absolute offset, uint64 shape[ndim]; data in C order.
 *
 * Tables, all float32, 2D tables indexed [row][column] on the unit square
 * with nodes k/(size - 1) (column = x, row = y):
 *   ndf, sigma            [H, W]                plain bilinear
 *   vndf                  [n_phi, n_theta, H, W] normalised density (warp)
 *   rgb / spectra         [n_phi, n_theta, C, S, S] plain bilinear
 * The (phi_i, theta_i) slices are interpolated linearly (weights clamped to
 * [0, 1]: constant beyond the first and last slice).
 *
 * Evaluation for view v (conditions the tables) and light l, both above
 * the horizon:  m = normalize(v + l);  u(theta) = sqrt(2 theta / pi),
 * u(phi) = (phi + pi) / (2 pi);  u_m = (u(theta_m), u(phi_m - phi_v)) for
 * isotropic tables (phi_m alone otherwise), y wrapped into [0, 1);
 *   s = VNDF^-1(u_m | phi_v, theta_v)      (continuous marginal inversion)
 *   value_c = RGB_c(s | phi_v, theta_v) [x NDF(u_m) / (4 sigma(u_v)) when
 *             the file's jacobian flag is set]
 * and the stored value is f_r cos(theta_l):  f_r = max(0, value) / l_z.
 * Anisotropic tables with a symmetry reduction 2 or 4 (phi_i covering half
 * or a quarter turn) mirror v and l into the measured part first. */
#include <assert.h>
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "param/vndf_tables.h"
#include "sepbrdf/measured.h"
#include "source/measured_impl.h"
#include "source/rgl_impl.h"
#include "source/rgl_tensor.h"
#include "util/internal.h"

/* ---- tables ----------------------------------------------------------------- */

/* A table from a float32 field [..., chans, h, w] with `slices` slices. */
static sb_result_t table_load(sb_context_t *ctx, const char *path, const tf_field_t *f, size_t slices, size_t chans,
                              table2d_t *t) {
    t->h = (size_t)f->shape[f->ndim - 2];
    t->w = (size_t)f->shape[f->ndim - 1];
    t->slices = slices;
    t->chans = chans;
    assert(f->count == slices * chans * t->w * t->h);
    t->v = sb_alloc(ctx, f->count, sizeof(double), path);
    if (!t->v) return SB_ERR_NOMEM;
    for (size_t k = 0; k < f->count; k++)
        t->v[k] = tf_f32(f->data + 4 * k);
    return SB_OK;
}

/* Turn each slice into a normalised density with its CDFs: the
 * conditional CDF integrates each row by the trapezoid rule, the marginal
 * CDF the row totals, all in units of one patch (index space) and divided
 * by the slice's total, as are the values. */
static sb_result_t table_warp(sb_context_t *ctx, const char *path, const char *name, table2d_t *t) {
    size_t n = t->w * t->h;
    t->ccdf = sb_alloc(ctx, t->slices * n, sizeof(double), path);
    t->mcdf = sb_alloc(ctx, t->slices * t->h, sizeof(double), path);
    if (!t->ccdf || !t->mcdf) return SB_ERR_NOMEM;
    for (size_t s = 0; s < t->slices; s++) {
        double *v = t->v + s * n, *cc = t->ccdf + s * n, *mc = t->mcdf + s * t->h;
        for (size_t k = 0; k < n; k++)
            if (v[k] < 0)
                return sb_error(ctx, SB_ERR_FORMAT, "%s: RGL: field '%s' slice %zu has a negative density", path, name,
                                s);
        for (size_t y = 0; y < t->h; y++) {
            double sum = 0;
            cc[y * t->w] = 0;
            for (size_t x = 0; x + 1 < t->w; x++) {
                sum += 0.5 * (v[y * t->w + x] + v[y * t->w + x + 1]);
                cc[y * t->w + x + 1] = sum;
            }
        }
        double sum = 0;
        mc[0] = 0;
        for (size_t y = 0; y + 1 < t->h; y++) {
            sum += 0.5 * (cc[y * t->w + t->w - 1] + cc[(y + 1) * t->w + t->w - 1]);
            mc[y + 1] = sum;
        }
        if (!(sum > 0))
            return sb_error(ctx, SB_ERR_FORMAT, "%s: RGL: field '%s' slice %zu is zero everywhere", path, name, s);
        double norm = 1 / sum;
        for (size_t k = 0; k < n; k++) {
            cc[k] *= norm;
            v[k] *= norm;
        }
        for (size_t y = 0; y < t->h; y++)
            mc[y] *= norm;
    }
    return SB_OK;
}

static void slice_weights(const rgl_t *g, double phi, double theta, slices_t *s) {
    size_t ip, it;
    double wp, wt;
    sb_table_interval(g->phi, g->n_phi, phi, &ip, &wp);
    sb_table_interval(g->theta, g->n_theta, theta, &it, &wt);
    size_t sp = g->n_phi > 1 ? g->n_theta : 0, st = g->n_theta > 1 ? 1 : 0, base = ip * g->n_theta + it;
    s->idx[0] = base;
    s->idx[1] = base + st;
    s->idx[2] = base + sp;
    s->idx[3] = base + sp + st;
    s->wt[0] = (1 - wp) * (1 - wt);
    s->wt[1] = (1 - wp) * wt;
    s->wt[2] = wp * (1 - wt);
    s->wt[3] = wp * wt;
}

/* ---- evaluation ------------------------------------------------------------ */

double sb_rgl_jacobian_(const rgl_t *g, const double u_m[2], const double u_v[2]) {
    return g->jacobian ? sb_table_bilinear(&g->ndf, u_m, NULL, 0) / (4 * sb_table_bilinear(&g->sigma, u_v, NULL, 0))
                       : 1;
}

/* a with the sign flipped unless b is negative (Mitsuba's mulsign_neg). */
static double mulsign_neg(double a, double b) { return signbit(b) ? a : -a; }

static int rgl_eval(const void *self, const double wi[3], const double wo[3], double rgb[3]) {
    const rgl_t *g = self;
    rgb[0] = rgb[1] = rgb[2] = 0;
    if (!(wi[2] > 0 && wo[2] > 0)) return 0;
    double v[3] = {wo[0], wo[1], wo[2]}, l[3] = {wi[0], wi[1], wi[2]};
    if (g->reduction >= 2) { /* mirror into the measured part of phi */
        double sy = v[1], sx = g->reduction == 4 ? v[0] : sy;
        v[0] = mulsign_neg(v[0], sx);
        v[1] = mulsign_neg(v[1], sy);
        l[0] = mulsign_neg(l[0], sx);
        l[1] = mulsign_neg(l[1], sy);
    }
    double m[3] = {v[0] + l[0], v[1] + l[1], v[2] + l[2]};
    double len = sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2]);
    m[0] /= len;
    m[1] /= len;
    m[2] /= len;
    double theta_v = sb_table_elevation(v), phi_v = atan2(v[1], v[0]);
    double theta_m = sb_table_elevation(m), phi_m = atan2(m[1], m[0]);
    double u_v[2] = {sb_table_theta2u(theta_v), sb_table_phi2u(phi_v)};
    double u_m[2] = {sb_table_theta2u(theta_m), sb_table_phi2u(g->isotropic ? phi_m - phi_v : phi_m)};
    u_m[1] -= floor(u_m[1]);
    slices_t s;
    slice_weights(g, phi_v, theta_v, &s);
    double sample[2];
    sb_table_warp_invert(&g->vndf, u_m, &s, sample);
    double scale = sb_rgl_jacobian_(g, u_m, u_v);
    for (size_t c = 0; c < 3; c++) {
        double val = sb_table_bilinear(&g->rgb, sample, &s, c) * scale;
        rgb[c] = val > 0 ? val / l[2] : 0;
    }
    return 1;
}

static void rgl_destroy(void *self) {
    rgl_t *g = self;
    if (!g) return;
    table2d_t *t[4] = {&g->ndf, &g->sigma, &g->vndf, &g->rgb};
    for (int k = 0; k < 4; k++) {
        free(t[k]->v);
        free(t[k]->ccdf);
        free(t[k]->mcdf);
    }
    free(g->phi);
    free(g->theta);
    free(g);
}

/* ---- reading ---------------------------------------------------------------- */

/* theta_i and phi_i: increasing, theta in [0, pi/2], phi in [-pi, pi]
 * (a little slack for float rounding); phi_i decides the symmetry. */
static sb_result_t load_angles(sb_context_t *ctx, const char *path, const tf_field_t *th, const tf_field_t *ph,
                               rgl_t *g) {
    g->n_theta = th->count;
    g->n_phi = ph->count;
    g->theta = sb_alloc(ctx, g->n_theta, sizeof(double), path);
    g->phi = sb_alloc(ctx, g->n_phi, sizeof(double), path);
    if (!g->theta || !g->phi) return SB_ERR_NOMEM;
    const double slack = 1e-5;
    for (size_t k = 0; k < g->n_theta; k++) {
        g->theta[k] = tf_f32(th->data + 4 * k);
        if (g->theta[k] < -slack || g->theta[k] > SB_PI / 2 + slack || (k && !(g->theta[k] > g->theta[k - 1])))
            return sb_error(ctx, SB_ERR_FORMAT, "%s: RGL: theta_i[%zu] = %g rad: need increasing values in [0, pi/2]",
                            path, k, g->theta[k]);
    }
    for (size_t k = 0; k < g->n_phi; k++) {
        g->phi[k] = tf_f32(ph->data + 4 * k);
        if (fabs(g->phi[k]) > SB_PI + slack || (k && !(g->phi[k] > g->phi[k - 1])))
            return sb_error(ctx, SB_ERR_FORMAT, "%s: RGL: phi_i[%zu] = %g rad: need increasing values in [-pi, pi]",
                            path, k, g->phi[k]);
    }
    g->isotropic = g->n_phi <= 2;
    if (!g->isotropic) {
        double red = rint(2 * SB_PI / (g->phi[g->n_phi - 1] - g->phi[0]));
        if (red != 1 && red != 2 && red != 4)
            return sb_error(ctx, SB_ERR_UNSUPPORTED,
                            "%s: RGL: phi_i covers %g deg: symmetry reduction %g, only 1, 2 and 4 are supported", path,
                            (g->phi[g->n_phi - 1] - g->phi[0]) * 180 / SB_PI, red);
        g->reduction = (int)red;
    }
    return SB_OK;
}

/* The colour table against what a BRDF is: refused where a channel's mean
 * is not positive (every value negated, a sign or unit error: Mitsuba's
 * lookup clamps below 0, so the file read as black in that channel and
 * factored with exit 0); the real files' channel means are 0.08-0.94, a
 * few of their values slightly negative (kept, clamped as Mitsuba does). */
static sb_result_t colour_check(sb_context_t *ctx, const char *path, const table2d_t *t, const char *name) {
    size_t nodes = t->w * t->h;
    for (size_t c = 0; c < 3; c++) {
        double sum = 0;
        size_t neg = 0;
        for (size_t s = 0; s < t->slices; s++)
            for (size_t p = 0; p < nodes; p++) {
                double v = t->v[(s * 3 + c) * nodes + p];
                sum += v;
                neg += v < 0;
            }
        if (!(sum > 0))
            return sb_error(ctx, SB_ERR_FORMAT,
                            "%s: RGL: the mean of %s channel %c is %.3g (%zu of %zu values negative): a BRDF is not "
                            "negative; are the values negated?",
                            path, name, "RGB"[c], sum / (double)(t->slices * nodes), neg, t->slices * nodes);
    }
    return SB_OK;
}

/* The colour table: rgb [n_phi, n_theta, 3, S, S], or spectra [..., n, S, S]
 * with wavelengths [n] turned into linear sRGB node by node (the lookups are
 * linear in the table, so converting first gives the same values). */
static sb_result_t load_colour(sb_context_t *ctx, const char *path, const tf_file_t *tf, const sb_measured_opts_t *o,
                               rgl_t *g, sb_measured_info_t *info) {
    size_t slices = g->n_phi * g->n_theta, lo5[5] = {1, 1, 3, 2, 2};
    const tf_field_t *f = tf_find(tf, "spectra"), *wl = NULL;
    sb_result_t r;
    if (!f) {
        if ((r = tf_need_f32(ctx, path, tf, "rgb", 5, lo5, &f)) != SB_OK) return r;
        if (f->shape[2] != 3)
            return sb_error(ctx, SB_ERR_FORMAT, "%s: RGL: rgb has %ju channels, need 3", path, (uintmax_t)f->shape[2]);
        info->channels = 3;
    } else {
        lo5[2] = 1;
        if ((r = tf_need_f32(ctx, path, tf, "spectra", 5, lo5, &f)) != SB_OK) return r;
        size_t lo1[1] = {1};
        if ((r = tf_need_f32(ctx, path, tf, "wavelengths", 1, lo1, &wl)) != SB_OK) return r;
        if (wl->count != f->shape[2])
            return sb_error(ctx, SB_ERR_FORMAT, "%s: RGL: %zu wavelengths for %ju spectral channels", path, wl->count,
                            (uintmax_t)f->shape[2]);
        info->channels = info->wavelengths = wl->count;
    }
    if (f->shape[0] != g->n_phi || f->shape[1] != g->n_theta)
        return sb_error(ctx, SB_ERR_FORMAT, "%s: RGL: %s has %ju x %ju slices, phi_i x theta_i is %zu x %zu", path,
                        wl ? "spectra" : "rgb", (uintmax_t)f->shape[0], (uintmax_t)f->shape[1], g->n_phi, g->n_theta);
    table2d_t raw = {0};
    if ((r = table_load(ctx, path, f, slices, (size_t)f->shape[2], &raw)) != SB_OK) return r;
    if (!wl) {
        g->rgb = raw;
        return colour_check(ctx, path, &g->rgb, "rgb");
    }
    size_t n = wl->count, nodes = raw.w * raw.h;
    double *nm = sb_alloc(ctx, n, sizeof(double), path), *w = sb_alloc(ctx, 3 * n, sizeof(double), path);
    g->rgb = (table2d_t){raw.w, raw.h, slices, 3, sb_alloc(ctx, slices * 3 * nodes, sizeof(double), path), NULL, NULL};
    if (!nm || !w || !g->rgb.v) r = SB_ERR_NOMEM;
    for (size_t k = 0; r == SB_OK && k < n; k++)
        nm[k] = tf_f32(wl->data + 4 * k);
    if (r == SB_OK) {
        info->wl_min = nm[0];
        info->wl_max = nm[n - 1];
        r = sb_spectral_weights(ctx, nm, n, o->white, w);
    }
    for (size_t s = 0; r == SB_OK && s < slices; s++)
        for (size_t p = 0; p < nodes; p++) {
            double v[3] = {0, 0, 0};
            for (size_t c = 0; c < 3; c++)
                for (size_t k = 0; k < n; k++)
                    v[c] += w[c * n + k] * raw.v[(s * n + k) * nodes + p];
            info->out_of_gamut += (size_t)sb_gamut_map(o->gamut, v);
            for (size_t c = 0; c < 3; c++)
                g->rgb.v[(s * 3 + c) * nodes + p] = v[c];
        }
    free(raw.v);
    free(nm);
    free(w);
    return r == SB_OK ? colour_check(ctx, path, &g->rgb, "spectra (as sRGB)") : r;
}

/* ndf, sigma, vndf and jacobian, shapes checked against the slices. */
static sb_result_t load_tables(sb_context_t *ctx, const char *path, const tf_file_t *tf, rgl_t *g) {
    size_t lo2[2] = {2, 2}, lo4[4] = {1, 1, 2, 2};
    const tf_field_t *ndf = NULL, *sigma = NULL, *vndf = NULL, *jac = tf_find(tf, "jacobian");
    sb_result_t r;
    if ((r = tf_need_f32(ctx, path, tf, "ndf", 2, lo2, &ndf)) != SB_OK ||
        (r = tf_need_f32(ctx, path, tf, "sigma", 2, lo2, &sigma)) != SB_OK ||
        (r = tf_need_f32(ctx, path, tf, "vndf", 4, lo4, &vndf)) != SB_OK)
        return r;
    if (vndf->shape[0] != g->n_phi || vndf->shape[1] != g->n_theta)
        return sb_error(ctx, SB_ERR_FORMAT, "%s: RGL: vndf has %ju x %ju slices, phi_i x theta_i is %zu x %zu", path,
                        (uintmax_t)vndf->shape[0], (uintmax_t)vndf->shape[1], g->n_phi, g->n_theta);
    if (!jac || jac->dtype != 1 || jac->count != 1)
        return sb_error(ctx, SB_ERR_FORMAT, "%s: RGL: field 'jacobian' missing or not one uint8", path);
    g->jacobian = jac->data[0] != 0;
    if ((r = table_load(ctx, path, ndf, 1, 1, &g->ndf)) != SB_OK ||
        (r = table_load(ctx, path, sigma, 1, 1, &g->sigma)) != SB_OK ||
        (r = table_load(ctx, path, vndf, g->n_phi * g->n_theta, 1, &g->vndf)) != SB_OK)
        return r;
    /* the NDF is a density (f_r = colour D(m) / (4 sigma)): a negative value
     * or zeros everywhere would make f_r <= 0 everywhere */
    double ndf_sum = 0;
    for (size_t k = 0; k < g->ndf.w * g->ndf.h; k++) {
        if (g->ndf.v[k] < 0)
            return sb_error(ctx, SB_ERR_FORMAT, "%s: RGL: ndf[%zu] = %g, a microfacet density is never negative", path,
                            k, g->ndf.v[k]);
        ndf_sum += g->ndf.v[k];
    }
    if (!(ndf_sum > 0))
        return sb_error(ctx, SB_ERR_FORMAT, "%s: RGL: field 'ndf' is zero everywhere: f_r would be 0 everywhere", path);
    for (size_t k = 0; g->jacobian && k < g->sigma.w * g->sigma.h; k++)
        if (!(g->sigma.v[k] > 0))
            return sb_error(ctx, SB_ERR_FORMAT, "%s: RGL: sigma[%zu] = %g, the projected area must be positive", path,
                            k, g->sigma.v[k]);
    return table_warp(ctx, path, "vndf", &g->vndf);
}

/* A field's shape as "[a, b, ...]" into buf. */
static const char *shape_text(const tf_field_t *f, char *buf, size_t size) {
    size_t n = (size_t)snprintf(buf, size, "[");
    for (size_t d = 0; d < f->ndim && n < size; d++)
        n += (size_t)snprintf(buf + n, size - n, "%s%ju", d ? ", " : "", (uintmax_t)f->shape[d]);
    if (n < size) snprintf(buf + n, size - n, "]");
    return buf;
}

/* The fields' shapes against each other, each refusal naming both fields
 * (theta_i and the slices of vndf and the colour table: load_tables,
 * load_colour): sigma on ndf's grid; the optional luminance [n_phi,
 * n_theta, H, W] on the colour table's H x W grid; the optional valid mask
 * one flag per colour node. */
static sb_result_t check_shapes(sb_context_t *ctx, const char *path, const tf_file_t *tf, const rgl_t *g) {
    const tf_field_t *ndf = tf_find(tf, "ndf"), *sigma = tf_find(tf, "sigma"), *lum = tf_find(tf, "luminance");
    const tf_field_t *valid = tf_find(tf, "valid");
    const char *colour = tf_find(tf, "spectra") ? "spectra" : "rgb";
    char a[160], b[160];
    if (ndf->shape[0] != sigma->shape[0] || ndf->shape[1] != sigma->shape[1])
        return sb_error(ctx, SB_ERR_FORMAT, "%s: RGL: sigma %s and ndf %s differ: both lie on one grid", path,
                        shape_text(sigma, a, sizeof a), shape_text(ndf, b, sizeof b));
    if (lum && (lum->ndim != 4 || lum->shape[0] != g->n_phi || lum->shape[1] != g->n_theta))
        return sb_error(ctx, SB_ERR_FORMAT, "%s: RGL: luminance %s does not hold phi_i x theta_i = %zu x %zu slices",
                        path, shape_text(lum, a, sizeof a), g->n_phi, g->n_theta);
    if (lum && (lum->shape[2] != g->rgb.h || lum->shape[3] != g->rgb.w))
        return sb_error(ctx, SB_ERR_FORMAT, "%s: RGL: luminance's grid %ju x %ju differs from %s's %zu x %zu", path,
                        (uintmax_t)lum->shape[2], (uintmax_t)lum->shape[3], colour, g->rgb.h, g->rgb.w);
    if (valid && valid->count != g->rgb.w * g->rgb.h)
        return sb_error(ctx, SB_ERR_FORMAT, "%s: RGL: valid %s holds %zu flags, %s's grid %zu x %zu has %zu nodes",
                        path, shape_text(valid, a, sizeof a), valid->count, colour, g->rgb.h, g->rgb.w,
                        g->rgb.w * g->rgb.h);
    return SB_OK;
}

/* Value statistics of f_r with the view at each theta_i slice (below 89.5
 * deg) and the light at the centres of a 2-degree grid of the hemisphere. */
static void rgl_stats(const rgl_t *g, sb_measured_info_t *info) {
    double sum[3] = {0, 0, 0};
    size_t n = 0;
    for (int c = 0; c < 3; c++) {
        info->value_min[c] = INFINITY;
        info->value_max[c] = -INFINITY;
    }
    for (size_t k = 0; k < g->n_theta; k++) {
        double tv = g->theta[k] < 89.5 * SB_PI / 180 ? g->theta[k] : 89.5 * SB_PI / 180, rgb[3];
        double wo[3] = {sin(tv), 0, cos(tv)};
        for (int a = 0; a < 45; a++)
            for (int b = 0; b < 180; b++) {
                double t = (a + 0.5) * SB_PI / 90, p = (b + 0.5) * SB_PI / 90;
                double wi[3] = {sin(t) * cos(p), sin(t) * sin(p), cos(t)};
                rgl_eval(g, wi, wo, rgb);
                for (int c = 0; c < 3; c++) {
                    sum[c] += rgb[c];
                    if (rgb[c] < info->value_min[c]) info->value_min[c] = rgb[c];
                    if (rgb[c] > info->value_max[c]) info->value_max[c] = rgb[c];
                }
                n++;
            }
    }
    for (int c = 0; c < 3; c++)
        info->value_mean[c] = sum[c] / (double)n;
}

static void rgl_fields(const tf_file_t *tf, const rgl_t *g, sb_measured_info_t *info) {
    const tf_field_t *d = tf_find(tf, "description");
    char text[200] = "";
    if (d && d->dtype == 1) {
        size_t n = d->count < sizeof text - 1 ? d->count : sizeof text - 1;
        for (size_t k = 0; k < n; k++)
            text[k] = d->data[k] >= 32 && d->data[k] < 127 ? (char)d->data[k] : '?';
        text[n] = 0;
    }
    sb_info_field(info, "description", NAN, "%s", text[0] ? text : "(none)");
    sb_info_field(info, "layout", NAN, "%s, %zu theta_i slices (%.1f..%.1f deg) x %zu phi_i%s%s",
                  g->isotropic ? "isotropic" : "anisotropic", g->n_theta, g->theta[0] * 180 / SB_PI,
                  g->theta[g->n_theta - 1] * 180 / SB_PI, g->n_phi, g->reduction >= 2 ? ", symmetry reduction " : "",
                  g->reduction == 4   ? "4"
                  : g->reduction == 2 ? "2"
                                      : "");
    sb_info_field(info, "tables", NAN, "vndf %zu x %zu, %s %zu x %zu, ndf/sigma %zu x %zu, jacobian %s", g->vndf.h,
                  g->vndf.w, info->wavelengths ? "spectra" : "rgb", g->rgb.h, g->rgb.w, g->ndf.h, g->ndf.w,
                  g->jacobian ? "yes" : "no");
    sb_info_field(info, "nodes", (double)info->rows, "%zu (slices x colour nodes)", info->rows);
    sb_info_field(info, "interp", NAN, "Mitsuba 3 measured: VNDF warp, bilinear, linear between slices");
}

static sb_result_t rgl_open(sb_context_t *ctx, const char *path, const sb_measured_opts_t *o, sb_source_t **out,
                            sb_measured_info_t *info) {
    if (o->interp != SB_INTERP_DEFAULT)
        return sb_error(ctx, SB_ERR_ARG,
                        "%s: RGL tables are evaluated as Mitsuba 3 does (VNDF warp, bilinear); interpolation '%s' "
                        "does not apply",
                        path, sb_interp_name(o->interp));
    tf_file_t tf = {0};
    rgl_t *g = sb_calloc(ctx, 1, sizeof *g, path);
    sb_result_t r = g ? tf_read(ctx, path, &tf) : SB_ERR_NOMEM;
    size_t lo1[1] = {1};
    const tf_field_t *th = NULL, *ph = NULL;
    if (r == SB_OK) r = tf_parse(ctx, path, &tf);
    if (r == SB_OK && (r = tf_need_f32(ctx, path, &tf, "theta_i", 1, lo1, &th)) == SB_OK &&
        (r = tf_need_f32(ctx, path, &tf, "phi_i", 1, lo1, &ph)) == SB_OK)
        r = load_angles(ctx, path, th, ph, g);
    if (r == SB_OK) r = load_tables(ctx, path, &tf, g);
    if (r == SB_OK) r = load_colour(ctx, path, &tf, o, g, info);
    if (r == SB_OK) r = check_shapes(ctx, path, &tf, g);
    if (r == SB_OK) {
        info->rows = info->samples = g->rgb.slices * g->rgb.w * g->rgb.h;
        info->white = o->white;
        info->gamut = o->gamut;
        info->theta_i_max = info->theta_o_max = SB_PI / 2;
        info->flags = SB_SOURCE_MEASURED | SB_SOURCE_STORES_COS | (g->isotropic ? SB_SOURCE_ISOTROPIC : 0u);
        rgl_stats(g, info);
        rgl_fields(&tf, g, info);
        char *desc = sb_format("rgl:%s", path); /* paths of any length */
        sb_source_ops_t ops = {rgl_eval, rgl_destroy};
        r = desc ? sb_source_create(ctx, &ops, g, info->flags, desc, out) : SB_ERR_NOMEM;
        free(desc);
        if (r == SB_OK) sb_source_set_samples_(*out, sb_rgl_sample_count_, sb_rgl_sample_);
        /* the vndf layout's tables: isotropic files of one phi_i slice */
        if (r == SB_OK && g->isotropic && g->n_phi == 1 && g->reduction <= 1)
            sb_source_set_tables_(*out, sb_layout_tables_make_(g->n_theta, g->theta, &g->vndf, &g->ndf, &g->sigma,
                                                               g->rgb.w, g->rgb.h, g->jacobian));
        if (r == SB_OK && sb_source_layout_tables(*out) &&
            sb_layout_tables_set_rgb_((sb_layout_tables_t *)sb_source_layout_tables(*out), &g->rgb))
            sb_source_set_tables_(*out, NULL);
    }
    if (r != SB_OK) rgl_destroy(g);
    free(tf.fields);
    free(tf.buf);
    return r;
}

static int rgl_sniff(const unsigned char *head, size_t n) {
    return n >= 12 && memcmp(head, "tensor_file", 12) == 0 ? 2 : 0;
}

const sb_reader_t sb_reader_rgl = {"rgl", "RGL tensor_file (.bsdf)", ".bsdf", rgl_sniff, rgl_open};
