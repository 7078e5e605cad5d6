/* Factors (texture pairs with sigma and metadata) and the reconstruction
 * through texture lookups. */
#include "sepbrdf/factor.h"

#include <math.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "factor/errors.h"
#include "factor/lookup.h"
#include "util/internal.h"
#include "util/tex_axis.h"

/* ---- factors ----------------------------------------------------------- */

typedef struct meta {
    char *key, *value;
} meta_t;

struct sb_factors {
    size_t terms, channels;
    size_t w[2], h[2];
    double *tex[2]; /* [side]: terms * channels * w*h, term-major */
    double *sigma;  /* terms * channels */
    meta_t *meta;
    size_t nmeta;
    sb_factor_errors_t err;
    sb_layout_tables_t *tables; /* read with the set (vndf.exr), for sb_factors_param */
    unsigned long long stamp;   /* sb_factors_stamp: new after every change */
    int changed;                /* since the stamp was taken */
    int exact;                  /* sb_factors_exact: set by the plan, cleared by a change of texels or sigma */
};

/* A change: the next sb_factors_stamp is a new one (a plain store, as
 * sb_factors_tex is called once a texel in places). */
static void touch(sb_factors_t *f) { f->changed = 1; }
unsigned long long sb_factors_stamp(sb_factors_t *f) {
    static atomic_ullong next;
    if (!f) return 0;
    if (f->changed || !f->stamp) f->stamp = atomic_fetch_add(&next, 1) + 1;
    f->changed = 0;
    return f->stamp;
}
void sb_factors_mark_exact(sb_factors_t *f) {
    if (f) f->exact = 1;
}
int sb_factors_exact(const sb_factors_t *f) { return f && f->exact; }

sb_result_t sb_factors_create(sb_context_t *ctx, size_t terms, size_t channels, size_t g_w, size_t g_h, size_t h_w,
                              size_t h_h, sb_factors_t **out) {
    if (!out) return sb_error(ctx, SB_ERR_ARG, "factors: no output pointer");
    *out = NULL;
    if (terms == 0) return sb_error(ctx, SB_ERR_RANGE, "factors: need at least one term");
    if (channels != 1 && channels != 3)
        return sb_error(ctx, SB_ERR_RANGE, "factors: %zu channels, need 1 or 3", channels);
    if (!g_w || !g_h || !h_w || !h_h) return sb_error(ctx, SB_ERR_RANGE, "factors: empty texture size");
    if (terms > SIZE_MAX / 4) return sb_error(ctx, SB_ERR_OVERFLOW, "factors: %zu terms overflow", terms);
    sb_factors_t *f = calloc(1, sizeof *f);
    if (!f) return sb_error(ctx, SB_ERR_NOMEM, "factors: out of memory");
    touch(f);
    f->terms = terms;
    f->channels = channels;
    f->w[0] = g_w;
    f->h[0] = g_h;
    f->w[1] = h_w;
    f->h[1] = h_h;
    for (int s = 0; s < 2; s++) {
        size_t n;
        if (sb_size_mul3(f->w[s], f->h[s], terms * channels, &n)) {
            sb_factors_destroy(f);
            return sb_error(ctx, SB_ERR_OVERFLOW, "factors: texture size overflows");
        }
        f->tex[s] = sb_calloc(ctx, n, sizeof(double), "factor textures");
        if (!f->tex[s]) {
            sb_factors_destroy(f);
            return SB_ERR_NOMEM;
        }
    }
    f->sigma = sb_calloc(ctx, terms * channels, sizeof(double), "factors");
    f->err.terms = terms;
    f->err.rel_rms = sb_calloc(ctx, terms * 4, sizeof(double), "factor errors");
    f->err.max_abs = sb_calloc(ctx, terms * 4, sizeof(double), "factor errors");
    if (!f->sigma || !f->err.rel_rms || !f->err.max_abs) {
        sb_factors_destroy(f);
        return SB_ERR_NOMEM;
    }
    *out = f;
    return SB_OK;
}

void sb_factors_set_tables(sb_factors_t *f, sb_layout_tables_t *tables) {
    if (!f) {
        sb_layout_tables_destroy(tables);
        return;
    }
    touch(f);
    sb_layout_tables_destroy(f->tables);
    f->tables = tables;
}
const sb_layout_tables_t *sb_factors_tables(const sb_factors_t *f) { return f ? f->tables : NULL; }

void sb_factors_destroy(sb_factors_t *f) {
    if (!f) return;
    sb_layout_tables_destroy(f->tables);
    free(f->tex[0]);
    free(f->tex[1]);
    free(f->sigma);
    for (size_t i = 0; i < f->nmeta; i++) {
        free(f->meta[i].key);
        free(f->meta[i].value);
    }
    free(f->meta);
    free(f->err.rel_rms);
    free(f->err.max_abs);
    free(f);
}

/* Accessors: safe values for NULL and out-of-range arguments (common.h). */
static int in_range(const sb_factors_t *f, int side, size_t term, size_t ch) {
    return f && (side == SB_SIDE_G || side == SB_SIDE_H) && term < f->terms && ch < f->channels;
}
size_t sb_factors_terms(const sb_factors_t *f) { return f ? f->terms : 0; }
size_t sb_factors_channels(const sb_factors_t *f) { return f ? f->channels : 0; }
void sb_factors_size(const sb_factors_t *f, int side, size_t *w, size_t *h) {
    int ok = in_range(f, side, 0, 0);
    if (w) *w = ok ? f->w[side] : 0;
    if (h) *h = ok ? f->h[side] : 0;
}
double *sb_factors_tex(sb_factors_t *f, int side, size_t term, size_t ch) {
    if (!in_range(f, side, term, ch)) return NULL;
    touch(f); /* the caller may write: another state, no longer the exact fit */
    f->exact = 0;
    return f->tex[side] + (term * f->channels + ch) * f->w[side] * f->h[side];
}
const double *sb_factors_tex_const(const sb_factors_t *f, int side, size_t term, size_t ch) {
    if (!in_range(f, side, term, ch)) return NULL;
    return f->tex[side] + (term * f->channels + ch) * f->w[side] * f->h[side];
}
double sb_factors_sigma(const sb_factors_t *f, size_t term, size_t ch) {
    return in_range(f, SB_SIDE_G, term, ch) ? f->sigma[term * f->channels + ch] : NAN;
}
void sb_factors_set_sigma(sb_factors_t *f, size_t term, size_t ch, double s) {
    if (!in_range(f, SB_SIDE_G, term, ch)) return;
    touch(f);
    f->exact = 0;
    f->sigma[term * f->channels + ch] = s;
}

sb_result_t sb_factors_set_meta(sb_factors_t *f, const char *key, const char *value) {
    if (!f || !key || !value) return SB_ERR_ARG;
    touch(f);
    for (size_t i = 0; i < f->nmeta; i++)
        if (strcmp(f->meta[i].key, key) == 0) {
            char *v = sb_strdup(value);
            if (!v) return SB_ERR_NOMEM;
            free(f->meta[i].value);
            f->meta[i].value = v;
            return SB_OK;
        }
    meta_t *m = realloc(f->meta, (f->nmeta + 1) * sizeof *m);
    if (!m) return SB_ERR_NOMEM;
    f->meta = m;
    m[f->nmeta].key = sb_strdup(key);
    m[f->nmeta].value = sb_strdup(value);
    if (!m[f->nmeta].key || !m[f->nmeta].value) {
        free(m[f->nmeta].key);
        free(m[f->nmeta].value);
        return SB_ERR_NOMEM;
    }
    f->nmeta++;
    return SB_OK;
}
const char *sb_factors_get_meta(const sb_factors_t *f, const char *key) {
    if (!f || !key) return NULL;
    for (size_t i = 0; i < f->nmeta; i++)
        if (strcmp(f->meta[i].key, key) == 0) return f->meta[i].value;
    return NULL;
}
size_t sb_factors_meta_count(const sb_factors_t *f) { return f ? f->nmeta : 0; }
void sb_factors_meta_at(const sb_factors_t *f, size_t i, const char **key, const char **value) {
    int ok = f && i < f->nmeta;
    if (key) *key = ok ? f->meta[i].key : NULL;
    if (value) *value = ok ? f->meta[i].value : NULL;
}
const sb_factor_errors_t *sb_factors_errors(const sb_factors_t *f) { return f ? &f->err : NULL; }
sb_factor_errors_t *sb_factors_errors_mut(sb_factors_t *f) { return f ? &f->err : NULL; }

double sb_factors_cell(const sb_factors_t *f, size_t terms, size_t ch, size_t row, size_t col) {
    if (!in_range(f, SB_SIDE_G, 0, ch) || row >= f->w[0] * f->h[0] || col >= f->w[1] * f->h[1]) return NAN;
    double s = 0;
    if (terms > f->terms) terms = f->terms;
    for (size_t j = 0; j < terms; j++)
        s += sb_factors_tex_const(f, 0, j, ch)[row] * sb_factors_tex_const(f, 1, j, ch)[col];
    return s;
}

/* The lookup of side at st with edges `edge` (util/tex_axis.h). */
static double lookup_edged(const sb_factors_t *f, const sb_param_t *p, int side, size_t term, size_t ch,
                           const double st[2], const int edge[2]) {
    if (!in_range(f, side, term, ch) || !p || !st) return NAN;
    size_t at[4];
    double fw[4];
    int wrap[2];
    sb_param_wrap(p, side, wrap);
    sb_tex_footprint(st, f->w[side], f->h[side], wrap, edge, at, fw);
    if (!isfinite(fw[0] + fw[3])) return NAN;
    const double *t = sb_factors_tex_const(f, side, term, ch);
    return fw[0] * t[at[0]] + fw[1] * t[at[1]] + fw[2] * t[at[2]] + fw[3] * t[at[3]];
}

double sb_factors_lookup(const sb_factors_t *f, const sb_param_t *p, int side, size_t term, size_t ch,
                         const double st[2]) {
    static const int clamp[2] = {SB_EDGE_CLAMP, SB_EDGE_CLAMP};
    return lookup_edged(f, p, side, term, ch, st, clamp);
}

double sb_factors_lookup_brdf(const sb_factors_t *f, const sb_param_t *p, int side, size_t term, size_t ch,
                              const double st[2]) {
    int edge[2];
    sb_param_edge(p, side, edge);
    return lookup_edged(f, p, side, term, ch, st, edge);
}

void sb_factors_prefix_sums_(const sb_factors_t *f, const sb_param_t *p, size_t J, const double sg[2],
                             const double sh[2], double *run) {
    size_t at[2][4], C = f->channels;
    double fw[2][4], acc[3] = {0, 0, 0};
    int ok = J <= f->terms;
    for (int s = 0; s < 2 && ok; s++) {
        int wrap[2], edge[2];
        sb_param_wrap(p, s, wrap);
        sb_param_edge(p, s, edge);
        sb_tex_footprint(s ? sh : sg, f->w[s], f->h[s], wrap, edge, at[s], fw[s]);
        ok = isfinite(fw[s][0] + fw[s][3]);
    }
    for (size_t j = 0; j < J; j++)
        for (size_t c = 0; c < C; c++) {
            const double *g = sb_factors_tex_const(f, 0, j, c), *h = sb_factors_tex_const(f, 1, j, c);
            if (ok)
                acc[c] +=
                    (fw[0][0] * g[at[0][0]] + fw[0][1] * g[at[0][1]] + fw[0][2] * g[at[0][2]] +
                     fw[0][3] * g[at[0][3]]) *
                    (fw[1][0] * h[at[1][0]] + fw[1][1] * h[at[1][1]] + fw[1][2] * h[at[1][2]] + fw[1][3] * h[at[1][3]]);
            run[j * C + c] = ok ? acc[c] : NAN;
        }
}

int sb_factors_eval(const sb_factors_t *f, const sb_param_t *p, sb_form_t form, size_t terms, const double wi[3],
                    const double wo[3], double rgb[3]) {
    double sg[2], sh[2];
    if (!rgb) return 0;
    rgb[0] = rgb[1] = rgb[2] = 0;
    if (!f || (unsigned)form >= SB_FORM_COUNT_ || !sb_param_coords(p, wi, wo, sg, sh)) return 0;
    if (terms > f->terms) terms = f->terms;
    double acc[3] = {0, 0, 0};
    for (size_t j = 0; j < terms; j++)
        for (size_t c = 0; c < f->channels; c++)
            acc[c] += sb_factors_lookup_brdf(f, p, 0, j, c, sg) * sb_factors_lookup_brdf(f, p, 1, j, c, sh);
    if (f->channels == 1) acc[1] = acc[2] = acc[0];
    /* divide back the factored form, with the lecture's grazing guard */
    double w = sb_form_divisor(form, wi, wo), gain = sb_param_gain(p, wi, wo);
    for (int c = 0; c < 3; c++)
        rgb[c] = sb_param_apply_gain(p, acc[c], gain) / w;
    return 1;
}

void sb_factors_truncate(sb_factors_t *f, size_t keep) {
    if (!f || keep == 0 || keep > f->terms) return;
    touch(f);        /* a prefix of an exact fit stays exact */
    f->terms = keep; /* textures beyond `keep` stay allocated but unused */
    f->err.terms = keep;
}
