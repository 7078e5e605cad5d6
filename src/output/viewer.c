/* The viewer page (viewer.h): the template data/viewer.html with one line
 * replaced by the data of a factorisation, `const SB_DATA = {...};`, and
 * the 3D lobe and sky (data/viewer3d.js). */
#include "sepbrdf/viewer.h"

#include <assert.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "sb_viewer3d_js.h"
#include "sb_viewer_html.h"
#include "sepbrdf/glsl.h"
#include "sepbrdf/render.h"
#include "util/internal.h"

#define PLACEHOLDER "/* SB_VIEWER_DATA */"
#define TABLE_WIDTH 2048 /* the reference table's texture width (WebGL2 guarantees 2048) */
#define POLAR_NTI 36     /* theta_i = 0, 2.5, ..., 87.5 degrees */
#define POLAR_DTI 2.5
#define POLAR_NTO 179 /* theta_o = -89 .. 89 degrees */

/* ---- writing JSON and base64 ------------------------------------------ */

/* A JSON string that is also safe inside <script>: '<' as \u003c. */
static void put_string(FILE *fp, const char *s) {
    fputc('"', fp);
    for (const unsigned char *p = (const unsigned char *)s; *p; p++) {
        if (*p == '"' || *p == '\\')
            fprintf(fp, "\\%c", *p);
        else if (*p == '\n')
            fputs("\\n", fp);
        else if (*p < 0x20 || *p == '<')
            fprintf(fp, "\\u%04x", *p);
        else
            fputc(*p, fp);
    }
    fputc('"', fp);
}

/* base64 (RFC 4648) of n floats as little-endian IEEE binary32, quoted. */
static void put_floats(FILE *fp, const float *v, size_t n) {
    static const char abc[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    unsigned char in[3];
    size_t k = 0, bytes = n * 4;
    fputc('"', fp);
    for (size_t i = 0; i < bytes; i++) {
        uint32_t bits;
        memcpy(&bits, &v[i / 4], 4);
        in[k++] = (unsigned char)(bits >> (8 * (i % 4)));
        if (k < 3 && i + 1 < bytes) continue;
        uint32_t w = (uint32_t)in[0] << 16 | (k > 1 ? (uint32_t)in[1] << 8 : 0) | (k > 2 ? in[2] : 0);
        char out[4] = {abc[w >> 18], abc[(w >> 12) & 63], k > 1 ? abc[(w >> 6) & 63] : '=', k > 2 ? abc[w & 63] : '='};
        fwrite(out, 1, 4, fp);
        k = 0;
    }
    fputc('"', fp);
}

/* ---- the factors' texels ---------------------------------------------- */

/* Layers of one side as float RGB: ((j H + y) W + x) 3 + c. */
static float *side_texels(sb_context_t *ctx, const sb_factors_t *f, int side, size_t *count) {
    size_t w, h, J = sb_factors_terms(f), C = sb_factors_channels(f);
    sb_factors_size(f, side, &w, &h);
    float *out = sb_alloc(ctx, J * w * h, 3 * sizeof(float), "viewer texels");
    if (!out) return NULL;
    for (size_t j = 0; j < J; j++)
        for (size_t c = 0; c < 3; c++) {
            const double *t = sb_factors_tex_const(f, side, j, C == 1 ? 0 : c);
            for (size_t i = 0; i < w * h; i++)
                out[(j * w * h + i) * 3 + c] = (float)t[i];
        }
    *count = J * w * h * 3;
    return out;
}

/* ---- the reference table ---------------------------------------------- */

/* The factorisation's parameterisation, or the same kind with every count
 * shrunk by 4/5 until rows x cols <= cap (0 counts are the kind's defaults,
 * which follow res). */
static sb_result_t ref_param(sb_context_t *ctx, const sb_param_t *param, size_t cap, sb_param_t **out) {
    sb_param_kind_t kind;
    sb_param_opts_t o;
    sb_result_t r = sb_param_parse_spec(ctx, sb_param_spec(param), &kind, &o);
    if (r != SB_OK) return r;
    o.tables = sb_param_tables(param);
    if (o.res == 0) o.res = 32;
    for (;;) {
        if ((r = sb_param_create(ctx, kind, &o, out)) != SB_OK) return r;
        size_t cells = sb_param_rows(*out) * sb_param_cols(*out);
        if (cells <= cap || o.res <= 2) return SB_OK;
        sb_param_destroy(*out);
        size_t *n[4] = {&o.res, &o.res_theta_h, &o.res_theta_d, &o.res_phi_d};
        for (int i = 0; i < 4; i++)
            if (*n[i]) *n[i] = *n[i] * 4 / 5 < 2 ? 2 : *n[i] * 4 / 5;
    }
}

/* src sampled (form f) on ref as RGBA, cell (r, c) at (r cols + c) 4. */
static float *ref_table(sb_context_t *ctx, const sb_source_t *src, const sb_param_t *ref, size_t *count,
                        sb_result_t *r) {
    sb_matrix_t m = {0};
    sb_matrix_opts_t mo = {0};
    /* a layout on the source's tables: its nodes (form cos over the gain; the page multiplies back) */
    if (sb_param_caps(ref) & SB_CAP_TABLES) mo.form = SB_FORM_COS;
    if ((*r = sb_matrix_build(ctx, src, ref, &mo, &m)) != SB_OK) return NULL;
    size_t cells = m.rows * m.cols, texels = (cells + TABLE_WIDTH - 1) / TABLE_WIDTH * TABLE_WIDTH;
    float *out = sb_calloc(ctx, texels, 4 * sizeof(float), "viewer reference table");
    if (!out) *r = SB_ERR_NOMEM;
    for (size_t row = 0; out && row < m.rows; row++)
        for (size_t col = 0; col < m.cols; col++) {
            size_t i = row + col * m.ld;
            float *px = out + (row * m.cols + col) * 4;
            for (int c = 0; c < 3; c++)
                px[c] = (float)(m.data[c] ? m.data[c][i] : m.data[0][i]);
            px[3] = m.mask && !m.mask[i] ? 0.0f : 1.0f;
        }
    sb_matrix_free(&m);
    *count = texels * 4;
    return out;
}

/* ---- in-plane slices -------------------------------------------------- */

static double luminance(const double rgb[3]) { return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]; }

static void slice_dirs(size_t a, size_t b, double wi[3], double wo[3]) {
    double ti = a * POLAR_DTI * SB_PI / 180, to = ((double)b - (POLAR_NTO - 1) / 2) * SB_PI / 180;
    wi[0] = sin(ti), wi[1] = 0, wi[2] = cos(ti);
    wo[0] = -sin(to), wo[1] = 0, wo[2] = cos(to);
}

/* Slices [k][a][b]: k = 0 the original (NaN: unknown), k = J' the
 * reconstruction from J' terms. */
static float *slices(sb_context_t *ctx, const sb_source_t *src, const sb_factors_t *f, const sb_param_t *param,
                     sb_form_t form, size_t *count) {
    size_t J = sb_factors_terms(f), n = POLAR_NTI * POLAR_NTO;
    float *out = sb_alloc(ctx, (J + 1) * n, sizeof(float), "viewer slices");
    if (!out) return NULL;
    for (size_t a = 0; a < POLAR_NTI; a++)
        for (size_t b = 0; b < POLAR_NTO; b++) {
            double wi[3], wo[3], rgb[3] = {0, 0, 0};
            slice_dirs(a, b, wi, wo);
            int known = src ? sb_source_eval(src, wi, wo, rgb) : 0;
            out[a * POLAR_NTO + b] = known ? (float)luminance(rgb) : NAN;
            for (size_t k = 1; k <= J; k++) {
                sb_factors_eval(f, param, form, k, wi, wo, rgb);
                out[k * n + a * POLAR_NTO + b] = (float)luminance(rgb);
            }
        }
    *count = (J + 1) * n;
    return out;
}

/* ---- the data object -------------------------------------------------- */

/* Exposure that puts the brightest channel of the sphere at 1: the
 * original's (as `sepbrdf render --exposure auto`), else the
 * reconstruction's. */
static double auto_exposure(sb_context_t *ctx, const sb_factors_t *f, const sb_param_t *param, sb_form_t form,
                            const sb_source_t *src) {
    sb_render_opts_t ro;
    memset(&ro, 0, sizeof ro);
    ro.size = 64;
    sb_image_t img = {0};
    sb_result_t r = src ? sb_render_source(ctx, &ro, src, &img) : sb_render_factors(ctx, &ro, f, param, form, 0, &img);
    double peak = r == SB_OK ? sb_image_max(&img) : 0;
    sb_image_free(&img);
    return peak > 0 && isfinite(peak) ? 1 / peak : 1;
}

static void put_side(FILE *fp, const char *key, const sb_param_t *p, int side) {
    size_t w, h;
    int wrap[2];
    sb_param_texture_size(p, side, &w, &h);
    sb_param_wrap(p, side, wrap);
    fprintf(fp, "\"%s\":{\"size\":[%zu,%zu],\"wrap\":[%d,%d]},", key, w, h, wrap[0], wrap[1]);
}

typedef struct page_data {
    float *g, *h, *ref, *polar;
    size_t ng, nh, nref, npolar;
    sb_param_t *refp;
} page_data_t;

static void put_data(FILE *fp, const sb_factors_t *f, const sb_param_t *param, sb_form_t form, const char *glsl,
                     const sb_viewer_opts_t *o, const page_data_t *d, double exposure) {
    const sb_factor_errors_t *e = sb_factors_errors(f);
    const char *desc = o->source ? sb_source_description(o->source) : sb_factors_get_meta(f, "source");
    fputs("const SB_DATA = {\"version\":", fp);
    put_string(fp, SB_VERSION_STRING);
    fputs(",\"source\":", fp);
    put_string(fp, desc ? desc : "");
    fputs(",\"param\":", fp);
    put_string(fp, sb_param_spec(param));
    fprintf(fp, ",\"form\":%d,\"terms\":%zu,\"channels\":%zu,\"exposure\":%.9g,\"file_bytes\":%zu,", (int)form,
            sb_factors_terms(f), sb_factors_channels(f), exposure, o->file_bytes);
    put_side(fp, "g", param, SB_SIDE_G);
    put_side(fp, "h", param, SB_SIDE_H);
    fputs("\"rel_rms\":[", fp);
    for (size_t t = 0; e && t < e->terms; t++) {
        double v = e->rel_rms[sb_err_at(t, SB_CH_ALL)];
        fputs(t ? "," : "", fp);
        isfinite(v) ? fprintf(fp, "%.9g", v) : fputs("null", fp);
    }
    fputs("],\"glsl\":", fp);
    put_string(fp, glsl);
    fputs(",\"report\":", fp);
    put_string(fp, o->report_json ? o->report_json : "");
    fputs(",\"g_texels\":", fp);
    put_floats(fp, d->g, d->ng);
    fputs(",\"h_texels\":", fp);
    put_floats(fp, d->h, d->nh);
    fprintf(fp, ",\"polar\":{\"ti_step\":%g,\"nti\":%d,\"nto\":%d,\"data\":", POLAR_DTI, POLAR_NTI, POLAR_NTO);
    put_floats(fp, d->polar, d->npolar);
    fputs("},\"ref\":", fp);
    if (d->ref) {
        fputs("{\"param\":", fp);
        put_string(fp, sb_param_spec(d->refp));
        fprintf(fp, ",\"rows\":%zu,\"cols\":%zu,\"width\":%d,", sb_param_rows(d->refp), sb_param_cols(d->refp),
                TABLE_WIDTH);
        put_side(fp, "g", d->refp, SB_SIDE_G);
        put_side(fp, "h", d->refp, SB_SIDE_H);
        fputs("\"texels\":", fp);
        put_floats(fp, d->ref, d->nref);
        fputs("}", fp);
    } else {
        fputs("null", fp);
    }
    fputs(",\"vndf\":", fp);
    size_t tw, th;
    float *tab = NULL;
    if (sb_param_tables_texture(param, &tw, &th, &tab) == SB_OK) {
        fprintf(fp, "{\"width\":%zu,\"height\":%zu,\"texels\":", tw, th);
        put_floats(fp, tab, tw * th * 3);
        fputs("}", fp);
        free(tab);
    } else {
        fputs("null", fp);
    }
    fputs("};\n", fp);
}

static void page_data_free(page_data_t *d) {
    free(d->g);
    free(d->h);
    free(d->ref);
    free(d->polar);
    sb_param_destroy(d->refp);
}

static sb_result_t page_data_make(sb_context_t *ctx, const sb_factors_t *f, const sb_param_t *param, sb_form_t form,
                                  const sb_viewer_opts_t *o, page_data_t *d) {
    sb_result_t r = SB_OK;
    if (!(d->g = side_texels(ctx, f, SB_SIDE_G, &d->ng)) || !(d->h = side_texels(ctx, f, SB_SIDE_H, &d->nh)) ||
        !(d->polar = slices(ctx, o->source, f, param, form, &d->npolar)))
        return SB_ERR_NOMEM;
    if (!o->source) return SB_OK;
    if ((r = ref_param(ctx, param, o->ref_cells ? o->ref_cells : SB_VIEWER_REF_CELLS, &d->refp)) != SB_OK) return r;
    d->ref = ref_table(ctx, o->source, d->refp, &d->nref, &r);
    return r;
}

/* ---- the page --------------------------------------------------------- */

static sb_result_t check_args(sb_context_t *ctx, const char *path, const sb_factors_t *f, const sb_param_t *param) {
    if (!path || !f || !param) return sb_error(ctx, SB_ERR_ARG, "viewer: NULL path, factors or parameterisation");
    for (int side = 0; side < 2; side++) {
        size_t fw, fh, pw, ph;
        sb_factors_size(f, side, &fw, &fh);
        sb_param_texture_size(param, side, &pw, &ph);
        if (fw != pw || fh != ph)
            return sb_error(ctx, SB_ERR_ARG, "viewer: %s textures are %zu x %zu, %s needs %zu x %zu", side ? "h" : "g",
                            fw, fh, sb_param_spec(param), pw, ph);
    }
    return SB_OK;
}

sb_result_t sb_viewer_write(sb_context_t *ctx, const char *path, const sb_factors_t *f, const sb_param_t *param,
                            sb_form_t form, const sb_viewer_opts_t *opts) {
    sb_result_t r = check_args(ctx, path, f, param);
    if (r != SB_OK) return r;
    if ((unsigned)form >= SB_FORM_COUNT_) return sb_error(ctx, SB_ERR_ARG, "viewer: unknown form %d", (int)form);
    sb_viewer_opts_t o = {0};
    if (opts) o = *opts;
    char *own = o.glsl ? NULL : sb_glsl_snippet(param, form, sb_factors_terms(f), NULL);
    page_data_t d = {0};
    if (!o.glsl && !own) return sb_error(ctx, SB_ERR_NOMEM, "viewer: out of memory");
    if ((r = page_data_make(ctx, f, param, form, &o, &d)) != SB_OK) {
        free(own);
        page_data_free(&d);
        return r == SB_ERR_NOMEM ? sb_error(ctx, r, "viewer: out of memory") : r;
    }
    double exposure = auto_exposure(ctx, f, param, form, o.source);
    /* Write the template with its placeholder line replaced, then rename */
    char tmp[4096];
    snprintf(tmp, sizeof tmp, "%s.tmp-%ld", path, (long)getpid());
    FILE *fp = fopen(tmp, "wb");
    int ok = fp != NULL;
    if (fp) {
        const char *cut = strstr(sb_viewer_html_, PLACEHOLDER);
        assert(cut); /* the template (data/viewer.html) has the line */
        fwrite(sb_viewer_html_, 1, (size_t)(cut - sb_viewer_html_), fp);
        put_data(fp, f, param, form, o.glsl ? o.glsl : own, &o, &d, exposure);
        fputs(sb_viewer3d_js_, fp);
        fputs(cut + strlen(PLACEHOLDER), fp);
        ok = !ferror(fp) && ok;
        ok = fclose(fp) == 0 && ok;
    }
    free(own);
    page_data_free(&d);
    if (!ok || rename(tmp, path) != 0) {
        if (fp) remove(tmp);
        return sb_error(ctx, SB_ERR_IO, "%s: cannot write", path);
    }
    return SB_OK;
}
