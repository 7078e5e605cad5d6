/* Analytic BRDF models behind the source interface, their keys and the
 * presets of the lecture (metals with linear F0, dielectrics with eta). */
#include "sepbrdf/models.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"

/* ---- presets ----------------------------------------------------------- */

#define DIEL(name, eta) {name, "dielectric", {0, 0, 0}, eta}
static sb_preset_t presets[] = {
    {"titanium", "metal", {0.542, 0.497, 0.449}, 0},
    {"chromium", "metal", {0.549, 0.556, 0.554}, 0},
    {"iron", "metal", {0.562, 0.565, 0.578}, 0},
    {"nickel", "metal", {0.660, 0.609, 0.526}, 0},
    {"platinum", "metal", {0.673, 0.637, 0.585}, 0},
    {"copper", "metal", {0.955, 0.638, 0.538}, 0},
    {"palladium", "metal", {0.733, 0.697, 0.652}, 0},
    {"zinc", "metal", {0.664, 0.824, 0.850}, 0},
    {"gold", "metal", {1.022, 0.782, 0.344}, 0},
    {"aluminium", "metal", {0.913, 0.922, 0.924}, 0},
    {"silver", "metal", {0.972, 0.960, 0.915}, 0},
    DIEL("water", 1.333),
    DIEL("glass", 1.5),
    DIEL("plastic", 1.5),
    DIEL("diamond", 2.42),
};
#define NPRESETS (sizeof presets / sizeof presets[0])

static void fill_dielectric_f0(void) {
    for (size_t i = 0; i < NPRESETS; i++)
        if (presets[i].ior > 0) {
            double r = (presets[i].ior - 1) / (presets[i].ior + 1);
            presets[i].f0[0] = presets[i].f0[1] = presets[i].f0[2] = r * r;
        }
}

size_t sb_preset_count(void) { return NPRESETS; }
const sb_preset_t *sb_preset_at(size_t i) {
    fill_dielectric_f0();
    return i < NPRESETS ? &presets[i] : NULL;
}
const sb_preset_t *sb_preset_find(const char *name) {
    fill_dielectric_f0();
    for (size_t i = 0; i < NPRESETS; i++)
        if (strcmp(presets[i].name, name) == 0) return &presets[i];
    return NULL;
}

/* ---- models ------------------------------------------------------------ */

typedef struct model {
    int kind; /* 0 lambert, 1 microfacet */
    double albedo[3];
    double base[3], metallic, reflectance, roughness;
} model_t;

static int lambert_eval(const void *self, const double wi[3], const double wo[3], double rgb[3]) {
    const model_t *m = self;
    if (wi[2] <= 0 || wo[2] <= 0) {
        rgb[0] = rgb[1] = rgb[2] = 0;
        return 1;
    }
    for (int c = 0; c < 3; c++) rgb[c] = m->albedo[c] / SB_PI;
    return 1;
}

/* The lecture's microfacetBRDF: GGX D (alpha = roughness^2), Smith G from
 * Schlick-GGX with the Disney remapping k = ((1 + r)/2)^2 / 2, Schlick F
 * with f0 = mix(0.16 reflectance^2, base, metallic), diffuse
 * (1 - F)(1 - metallic) base / pi, guards max(n.v, 0.001). */
static int microfacet_eval(const void *self, const double L[3], const double V[3], double rgb[3]) {
    const model_t *m = self;
    rgb[0] = rgb[1] = rgb[2] = 0;
    if (L[2] <= 0 || V[2] <= 0) return 1;
    double H[3] = {L[0] + V[0], L[1] + V[1], L[2] + V[2]};
    double hl = sqrt(H[0] * H[0] + H[1] * H[1] + H[2] * H[2]);
    for (int i = 0; i < 3; i++) H[i] /= hl;
    double NoV = fmin(fmax(V[2], 0), 1), NoL = fmin(fmax(L[2], 0), 1), NoH = fmin(fmax(H[2], 0), 1);
    double VoH = fmin(fmax(V[0] * H[0] + V[1] * H[1] + V[2] * H[2], 0), 1);
    double a = m->roughness * m->roughness, a2 = a * a;
    /* NoH^2 (a2 - 1) + 1, written so that a2 below the rounding of 1 is not
     * lost: the old form gave b = 0, D = inf/NaN at the mirror pair for
     * roughness < 1e-4 */
    double b = (1 - NoH) * (1 + NoH) + NoH * NoH * a2;
    double D = a2 / (SB_PI * b * b);
    double r = 0.5 + 0.5 * m->roughness, k = r * r / 2;
    double G = (fmax(NoL, 0.001) / (NoL * (1 - k) + k)) * (fmax(NoV, 0.001) / (NoV * (1 - k) + k));
    double f5 = pow(1 - VoH, 5);
    for (int c = 0; c < 3; c++) {
        double f0 = 0.16 * m->reflectance * m->reflectance;
        f0 = f0 * (1 - m->metallic) + m->base[c] * m->metallic;
        double F = f0 + (1 - f0) * f5;
        double spec = F * D * G / (4 * fmax(NoV, 0.001) * fmax(NoL, 0.001));
        double diff = m->base[c] * (1 - F) * (1 - m->metallic) / SB_PI;
        rgb[c] = diff + spec;
    }
    return 1;
}

static const sb_model_key_t lambert_keys[] = {
    {"albedo", "diffuse reflectance c (RGB r/g/b or one number); f = c/pi", "[0, 1]", "0.8"},
};
static const sb_model_key_t microfacet_keys[] = {
    {"base", "base colour (RGB, or a metal preset name: F0 of the metal)", "[0, 1] (metal F0 up to 1.1)", "0.5"},
    {"metallic", "metalness: mixes f0 towards base; no diffuse for metals", "[0, 1]", "0 (1 when base is a metal preset)"},
    {"reflectance", "dielectric reflectance: f0 = 0.16 reflectance^2", "[0, 1]", "0.5"},
    {"roughness", "perceptual roughness, GGX alpha = roughness^2", "[1e-6, 1]", "0.5"},
};
static const sb_model_info_t models[] = {
    {"lambert", "ideal diffuse: f = albedo / pi", lambert_keys, 1},
    {"microfacet", "lecture microfacetBRDF: GGX D, Smith Schlick-GGX G (Disney remap), Schlick F, metallic workflow",
     microfacet_keys, 4},
};

size_t sb_model_count(void) { return sizeof models / sizeof models[0]; }
const sb_model_info_t *sb_model_at(size_t i) { return i < sb_model_count() ? &models[i] : NULL; }

/* ---- spec parsing ------------------------------------------------------ */

static sb_result_t parse_number(sb_context_t *ctx, const char *model, const char *key, const char *s, double *out) {
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (end == s || *end || errno == ERANGE || !isfinite(v))
        return sb_error(ctx, SB_ERR_PARSE, "%s: key '%s': '%s' is not a number", model, key, s);
    *out = v;
    return SB_OK;
}

/* "0.8" -> (0.8, 0.8, 0.8); "0.9/0.6/0.3" -> RGB; otherwise a preset name */
static sb_result_t parse_rgb(sb_context_t *ctx, const char *model, const char *key, const char *s, double rgb[3],
                             int *is_metal) {
    if (is_metal) *is_metal = 0;
    if (isalpha((unsigned char)s[0])) {
        const sb_preset_t *p = sb_preset_find(s);
        if (!p) return sb_error(ctx, SB_ERR_UNKNOWN, "%s: key '%s': unknown preset '%s' (see `sepbrdf list`)", model, key, s);
        memcpy(rgb, p->f0, sizeof p->f0);
        if (is_metal) *is_metal = strcmp(p->kind, "metal") == 0;
        return SB_OK;
    }
    char buf[256];
    snprintf(buf, sizeof buf, "%s", s);
    char *parts[3] = {buf, NULL, NULL};
    int n = 1;
    for (char *q = buf; *q; q++)
        if (*q == '/') {
            if (n == 3) return sb_error(ctx, SB_ERR_PARSE, "%s: key '%s': '%s' has more than 3 components", model, key, s);
            *q = 0;
            parts[n++] = q + 1;
        }
    if (n == 2) return sb_error(ctx, SB_ERR_PARSE, "%s: key '%s': '%s' needs 1 or 3 components", model, key, s);
    for (int i = 0; i < n; i++) {
        sb_result_t r = parse_number(ctx, model, key, parts[i], &rgb[i]);
        if (r != SB_OK) return r;
    }
    if (n == 1) rgb[1] = rgb[2] = rgb[0];
    return SB_OK;
}

static sb_result_t check_range(sb_context_t *ctx, const char *model, const char *key, double v, double lo,
                               double hi, int open_lo) {
    if ((open_lo ? v <= lo : v < lo) || v > hi)
        return sb_error(ctx, SB_ERR_RANGE, "%s: key '%s' = %g out of range, need %s%g, %g]", model, key, v,
                        open_lo ? "(" : "[", lo, hi);
    return SB_OK;
}

sb_result_t sb_model_create(sb_context_t *ctx, const char *spec, sb_source_t **out) {
    if (!spec || !out) return sb_error(ctx, SB_ERR_ARG, "model: no spec");
    *out = NULL;
    char buf[1024];
    if (strlen(spec) >= sizeof buf) return sb_error(ctx, SB_ERR_PARSE, "model spec too long");
    snprintf(buf, sizeof buf, "%s", spec);
    char *colon = strchr(buf, ':');
    char *args = NULL;
    if (colon) {
        *colon = 0;
        args = colon + 1;
    }
    const char *name = buf;
    model_t m = {0};
    int kind = -1;
    for (size_t i = 0; i < sb_model_count(); i++)
        if (strcmp(models[i].name, name) == 0) kind = (int)i;
    if (kind < 0) return sb_error(ctx, SB_ERR_UNKNOWN, "unknown model '%s' (see `sepbrdf list`)", name);
    m.kind = kind;
    m.albedo[0] = m.albedo[1] = m.albedo[2] = 0.8;
    m.base[0] = m.base[1] = m.base[2] = 0.5;
    m.reflectance = 0.5;
    m.roughness = 0.5;
    int metal_base = 0, metallic_set = 0;
    while (args && *args) {
        char *comma = strchr(args, ',');
        if (comma) *comma = 0;
        char *eq = strchr(args, '=');
        if (!eq || eq == args)
            return sb_error(ctx, SB_ERR_PARSE, "%s: '%s' is not key=value", name, args);
        *eq = 0;
        const char *key = args, *val = eq + 1;
        sb_result_t r;
        if (kind == 0 && strcmp(key, "albedo") == 0) {
            r = parse_rgb(ctx, name, key, val, m.albedo, NULL);
            for (int c = 0; r == SB_OK && c < 3; c++) r = check_range(ctx, name, key, m.albedo[c], 0, 1, 0);
        } else if (kind == 1 && strcmp(key, "base") == 0) {
            r = parse_rgb(ctx, name, key, val, m.base, &metal_base);
            for (int c = 0; r == SB_OK && c < 3; c++) r = check_range(ctx, name, key, m.base[c], 0, 1.1, 0);
        } else if (kind == 1 && strcmp(key, "metallic") == 0) {
            r = parse_number(ctx, name, key, val, &m.metallic);
            if (r == SB_OK) r = check_range(ctx, name, key, m.metallic, 0, 1, 0);
            metallic_set = 1;
        } else if (kind == 1 && strcmp(key, "reflectance") == 0) {
            r = parse_number(ctx, name, key, val, &m.reflectance);
            if (r == SB_OK) r = check_range(ctx, name, key, m.reflectance, 0, 1, 0);
        } else if (kind == 1 && strcmp(key, "roughness") == 0) {
            r = parse_number(ctx, name, key, val, &m.roughness);
            /* below ~1e-76 the peak 1/(pi alpha^2) overflows; 1e-6 (alpha 1e-12) is far below any grid */
            if (r == SB_OK) r = check_range(ctx, name, key, m.roughness, 1e-6, 1, 0);
        } else {
            r = sb_error(ctx, SB_ERR_UNKNOWN, "%s: unknown key '%s' (see `sepbrdf list`)", name, key);
        }
        if (r != SB_OK) return r;
        args = comma ? comma + 1 : NULL;
    }
    if (kind == 1 && metal_base && !metallic_set) m.metallic = 1;

    model_t *self = malloc(sizeof *self);
    if (!self) return sb_error(ctx, SB_ERR_NOMEM, "model: out of memory");
    *self = m;
    char desc[512];
    sb_source_ops_t ops = {kind == 0 ? lambert_eval : microfacet_eval, free};
    unsigned flags = SB_SOURCE_RECIPROCAL | SB_SOURCE_ISOTROPIC;
    if (kind == 0) {
        snprintf(desc, sizeof desc, "lambert:albedo=%.6g/%.6g/%.6g", m.albedo[0], m.albedo[1], m.albedo[2]);
        if (m.albedo[0] == m.albedo[1] && m.albedo[1] == m.albedo[2]) flags |= SB_SOURCE_GRAY;
    } else {
        snprintf(desc, sizeof desc, "microfacet:base=%.6g/%.6g/%.6g,metallic=%.6g,reflectance=%.6g,roughness=%.6g",
                 m.base[0], m.base[1], m.base[2], m.metallic, m.reflectance, m.roughness);
    }
    sb_result_t r = sb_source_create(ctx, &ops, self, flags, desc, out);
    if (r != SB_OK) free(self);
    return r;
}
