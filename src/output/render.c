/* CPU reference renderer: an orthographic view of a lit unit sphere, see
 * render.h for the scene and the frame conventions that the GL shaders of
 * examples/gl_render.c repeat. */
#include "sepbrdf/render.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "util/internal.h"

#define DEFAULT_SIZE 256
#define MAX_SIZE 16384

void sb_light_from_angles(double elev_deg, double azim_deg, double irradiance, sb_light_t *out) {
    if (!out) return;
    double el = elev_deg * SB_PI / 180, az = azim_deg * SB_PI / 180;
    out->dir[0] = cos(el) * cos(az);
    out->dir[1] = cos(el) * sin(az);
    out->dir[2] = sin(el);
    out->irradiance = irradiance;
}

static void normalize3(double v[3]) {
    double l = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (int i = 0; i < 3; i++)
        v[i] /= l;
}

/* Pixel centre p in [-e, e]^2 (y up), n on the sphere, t = normalize(dP/dphi)
 * for the pole on +y, b = n x t. */
int sb_render_frame(const sb_render_opts_t *opts, size_t x, size_t y, double n[3], double t[3], double b[3]) {
    size_t S = opts && opts->size ? opts->size : DEFAULT_SIZE;
    if (x >= S || y >= S) return 0;
    double e = SB_RENDER_EXTENT;
    return sb_render_frame_at((2 * (x + 0.5) / (double)S - 1) * e, (1 - 2 * (y + 0.5) / (double)S) * e, n, t, b);
}

int sb_render_frame_at(double px, double py, double n[3], double t[3], double b[3]) {
    if (!n || !t || !b) return 0;
    double r2 = px * px + py * py;
    if (!(r2 < 1)) return 0;
    n[0] = px;
    n[1] = py;
    n[2] = sqrt(1 - r2);
    t[0] = n[2];
    t[1] = 0;
    t[2] = -n[0];
    normalize3(t);
    b[0] = n[1] * t[2] - n[2] * t[1];
    b[1] = n[2] * t[0] - n[0] * t[2];
    b[2] = n[0] * t[1] - n[1] * t[0];
    return 1;
}

static double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

sb_result_t sb_render(sb_context_t *ctx, const sb_render_opts_t *opts, sb_render_brdf_fn fn, const void *user,
                      sb_image_t *out) {
    if (!fn || !out) return sb_error(ctx, SB_ERR_ARG, "render: no BRDF or output");
    memset(out, 0, sizeof *out);
    sb_render_opts_t o = {0};
    if (opts) o = *opts;
    if (o.size == 0) o.size = DEFAULT_SIZE;
    if (o.size > MAX_SIZE)
        return sb_error(ctx, SB_ERR_RANGE, "render: size %zu out of range, need 1..%d", o.size, MAX_SIZE);
    if (o.light_count > SB_RENDER_MAX_LIGHTS)
        return sb_error(ctx, SB_ERR_ARG, "render: %zu lights, at most %d", o.light_count, SB_RENDER_MAX_LIGHTS);
    if (o.light_count == 0) {
        sb_light_from_angles(45, 45, 0, &o.lights[0]);
        o.light_count = 1;
    }
    /* Normalise the lights and resolve the default irradiance */
    for (size_t i = 0; i < o.light_count; i++) {
        sb_light_t *l = &o.lights[i];
        double len = sqrt(dot3(l->dir, l->dir));
        if (!(len > 0) || !isfinite(len)) return sb_error(ctx, SB_ERR_ARG, "render: light %zu has no direction", i + 1);
        for (int k = 0; k < 3; k++)
            l->dir[k] /= len;
        if (!(l->irradiance >= 0) || !isfinite(l->irradiance))
            return sb_error(ctx, SB_ERR_ARG, "render: light %zu irradiance %g, need >= 0", i + 1, l->irradiance);
        if (l->irradiance == 0) l->irradiance = SB_PI;
    }
    sb_result_t r = sb_image_alloc(ctx, o.size, o.size, out);
    if (r) return r;
    /* Shade every covered pixel: sum_l f(L, V) E max(L.n, 0) */
    for (size_t y = 0; y < o.size; y++)
        for (size_t x = 0; x < o.size; x++) {
            double n[3], t[3], b[3];
            if (!sb_render_frame(&o, x, y, n, t, b)) continue;
            size_t i = y * o.size + x;
            out->mask[i] = 1;
            double V[3] = {t[2], b[2], n[2]}; /* (0, 0, 1) in the local frame */
            double acc[3] = {0, 0, 0};
            for (size_t k = 0; k < o.light_count; k++) {
                const double *lw = o.lights[k].dir;
                double L[3] = {dot3(lw, t), dot3(lw, b), dot3(lw, n)};
                if (!(L[2] > 0)) continue;
                double f[3] = {0, 0, 0};
                fn(user, L, V, f);
                for (int c = 0; c < 3; c++)
                    acc[c] += f[c] * o.lights[k].irradiance * L[2];
            }
            for (int c = 0; c < 3; c++)
                out->rgb[3 * i + (size_t)c] = acc[c];
        }
    return SB_OK;
}

static int eval_source(const void *user, const double wi[3], const double wo[3], double rgb[3]) {
    return sb_source_eval(user, wi, wo, rgb);
}

sb_result_t sb_render_source(sb_context_t *ctx, const sb_render_opts_t *opts, const sb_source_t *src, sb_image_t *out) {
    if (!src) return sb_error(ctx, SB_ERR_ARG, "render: no source");
    return sb_render(ctx, opts, eval_source, src, out);
}

typedef struct factors_brdf {
    const sb_factors_t *f;
    const sb_param_t *p;
    sb_form_t form;
    size_t terms;
} factors_brdf_t;

static int eval_factors(const void *user, const double wi[3], const double wo[3], double rgb[3]) {
    const factors_brdf_t *fb = user;
    return sb_factors_eval(fb->f, fb->p, fb->form, fb->terms, wi, wo, rgb);
}

sb_result_t sb_render_factors(sb_context_t *ctx, const sb_render_opts_t *opts, const sb_factors_t *f,
                              const sb_param_t *param, sb_form_t form, size_t terms, sb_image_t *out) {
    if (!f || !param) return sb_error(ctx, SB_ERR_ARG, "render: no factors or parameterisation");
    if ((unsigned)form >= SB_FORM_COUNT_) return sb_error(ctx, SB_ERR_ARG, "render: unknown form %d", (int)form);
    if (terms == 0) terms = sb_factors_terms(f);
    if (terms > sb_factors_terms(f))
        return sb_error(ctx, SB_ERR_ARG, "render: %zu terms asked, the factors have %zu", terms, sb_factors_terms(f));
    factors_brdf_t fb = {f, param, form, terms};
    return sb_render(ctx, opts, eval_factors, &fb, out);
}

/* ---- parameterisation from metadata ------------------------------------ */

sb_result_t sb_factors_param(sb_context_t *ctx, const sb_factors_t *f, sb_param_t **param, sb_form_t *form) {
    if (!f || !param || !form) return sb_error(ctx, SB_ERR_ARG, "factors param: NULL argument");
    *param = NULL;
    const char *spec = sb_factors_get_meta(f, "param"), *fs = sb_factors_get_meta(f, "form");
    if (!spec) return sb_error(ctx, SB_ERR_FORMAT, "factors: no \"param\" metadata");
    sb_form_t fm = SB_FORM_F;
    if (fs && sb_form_parse(fs, &fm) != SB_OK) return sb_error(ctx, SB_ERR_FORMAT, "factors: unknown form \"%s\"", fs);
    sb_param_kind_t kind;
    sb_param_opts_t po;
    sb_param_t *p = NULL;
    sb_result_t r = sb_param_parse_spec(ctx, spec, &kind, &po);
    po.tables = sb_factors_tables(f); /* vndf: read with the set */
    if (r == SB_OK) r = sb_param_create(ctx, kind, &po, &p);
    if (r != SB_OK) {
        if (r == SB_ERR_UNSUPPORTED) return r;
        char why[512]; /* copied: sb_error overwrites the context's message */
        snprintf(why, sizeof why, "%s", sb_context_last_error(ctx));
        return sb_error(ctx, SB_ERR_FORMAT, "factors: param \"%s\": %s", spec, why);
    }
    for (int side = 0; side < 2; side++) {
        size_t pw, ph, fw, fh;
        sb_param_texture_size(p, side, &pw, &ph);
        sb_factors_size(f, side, &fw, &fh);
        if (pw != fw || ph != fh) {
            sb_param_destroy(p);
            return sb_error(ctx, SB_ERR_FORMAT, "factors: %s textures are %zu x %zu, param \"%s\" needs %zu x %zu",
                            side ? "h" : "g", fw, fh, spec, pw, ph);
        }
    }
    *param = p;
    *form = fm;
    return SB_OK;
}
