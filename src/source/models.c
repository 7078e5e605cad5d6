/* Analytic BRDF models behind the source interface: the formulas of the
 * lecture material (the lecture's GLSL, the lecture slides, Meister's PBR paper), their
 * keys, and the presets (metals with linear F0, dielectrics with eta).
 *
 * Conventions shared by every model: l = wi (towards the light), v = wo
 * (towards the viewer), n = z, all unit vectors; f = 0 when l_z <= 0 or
 * v_z <= 0.  Above the horizon l + v has z component l_z + v_z > 0, so the
 * half vector h = (l + v)/|l + v| always exists (l = -v needs one direction
 * below the horizon and gives 0), and
 *     h.l = h.v = |l + v|/2 >= (l_z + v_z)/2 > 0,   n.h > 0.
 * The mirror direction of l is r = 2 (n.l) n - l, so
 *     r.v = 2 l_z v_z - l.v,
 * symmetric in l and v.
 *
 * This file: presets, keys, the model table and spec parsing; the
 * formulas are in models_eval.c. */
#include "sepbrdf/models.h"

#include <ctype.h>
#include <errno.h>
#include <float.h>
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "source/models_impl.h"
#include "util/internal.h"

/* ---- presets ----------------------------------------------------------- */

/* Normal-incidence reflectance of a dielectric: F0 = ((eta - 1)/(eta + 1))^2. */
#define F0_OF_ETA(e) ((((e)-1.0) / ((e) + 1.0)) * (((e)-1.0) / ((e) + 1.0)))
#define METAL(name, r, g, b)                                                                                           \
    { name, "metal", {r, g, b}, 0 }
#define DIEL(name, eta)                                                                                                \
    { name, "dielectric", {F0_OF_ETA(eta), F0_OF_ETA(eta), F0_OF_ETA(eta)}, eta }

/* The lecture's tables: metals with linear F0 (gold's red 1.022 lies outside
 * [0, 1] in the table itself), dielectrics with their refractive index;
 * plastic spans 1.5 to 1.58 there, so both ends are offered. */
static const sb_preset_t presets[] = {
    METAL("titanium", 0.542, 0.497, 0.449),
    METAL("chromium", 0.549, 0.556, 0.554),
    METAL("iron", 0.562, 0.565, 0.578),
    METAL("nickel", 0.660, 0.609, 0.526),
    METAL("platinum", 0.673, 0.637, 0.585),
    METAL("copper", 0.955, 0.638, 0.538),
    METAL("palladium", 0.733, 0.697, 0.652),
    METAL("zinc", 0.664, 0.824, 0.850),
    METAL("gold", 1.022, 0.782, 0.344),
    METAL("aluminium", 0.913, 0.922, 0.924),
    METAL("silver", 0.972, 0.960, 0.915),
    DIEL("water", 1.333),
    DIEL("glass", 1.5),
    DIEL("plastic", 1.5),
    DIEL("plastic-high", 1.58),
    DIEL("diamond", 2.42),
};
#define NPRESETS (sizeof presets / sizeof presets[0])

size_t sb_preset_count(void) { return NPRESETS; }
const sb_preset_t *sb_preset_at(size_t i) { return i < NPRESETS ? &presets[i] : NULL; }
const sb_preset_t *sb_preset_find(const char *name) {
    if (!name) return NULL;
    for (size_t i = 0; i < NPRESETS; i++)
        if (strcmp(presets[i].name, name) == 0) return &presets[i];
    return NULL;
}

/* ---- model parameters (kinds and model_t: models_impl.h) ---------------- */

static const char *const d_names[] = {"ggx", "beckmann", "beckmann-norm", "gaussian", NULL};
static const char *const g_names[] = {"smith-schlick", "smith-disney", "smith-alpha", "vcavity", "none", NULL};
static const char *const f_names[] = {"schlick", "conductor", "dielectric", "none", NULL};
static const char *const denom_names[] = {"4", "cos", "pi", NULL};
static const char *const norm_names[] = {"rtr", "exact", NULL};

/* ---- keys --------------------------------------------------------------- */

typedef enum { K_NUM, K_RGB, K_BASE, K_F0, K_IOR, K_CHOICE } key_type_t;

typedef struct keyspec {
    key_type_t type;
    double lo, hi;
    int open_lo;                /* range (lo, hi] instead of [lo, hi] */
    size_t off;                 /* offsetof(model_t, field) */
    const char *const *choices; /* K_CHOICE: NULL-terminated names; the field is an int index */
} keyspec_t;

/* One list per model, expanded twice: the public key descriptions of
 * sb_model_at() and the parser's table, so that the two cannot drift apart.
 * X(name, type, lo, hi, open_lo, field, choices, meaning, range, default) */
#define KEY_PUB(nm, ty, lo, hi, op, fld, ch, mean, rng, def) {nm, mean, rng, def},
#define KEY_SPEC(nm, ty, lo, hi, op, fld, ch, mean, rng, def) {ty, lo, hi, op, offsetof(model_t, fld), ch},

#define GUARD_KEY(X, what)                                                                                             \
    X("guard", K_NUM, 0, 1, 0, guard, NULL,                                                                            \
      "floor of " what " (the lecture's max(n.v, 0.001)); 0 disables it (cosines are then only kept "                  \
      "above 1e-100 so f stays finite)",                                                                               \
      "[0, 1]", "0.001")
#define KD_KEY(X, mean) X("kd", K_RGB, 0, 1, 0, kd, NULL, mean, "[0, 1]", "0.5")
#define KS_KEY(X, mean) X("ks", K_RGB, 0, 1, 0, ks, NULL, mean, "[0, 1]", "0.5")
#define N_KEY(X) X("n", K_NUM, 0, 100000, 0, n, NULL, "shininess exponent", "[0, 100000]", "20")

#define LAMBERT_KEYS(X)                                                                                                \
    X("albedo", K_RGB, 0, 1, 0, albedo, NULL, "diffuse reflectance c (RGB r/g/b or one number); f = c/pi", "[0, 1]",   \
      "0.8")
#define PHONG_KEYS(X)                                                                                                  \
    KD_KEY(X, "diffuse term (RGB), a constant BRDF (no 1/pi)")                                                         \
    KS_KEY(X, "specular colour (RGB)")                                                                                 \
    N_KEY(X)                                                                                                           \
    GUARD_KEY(X, "cos theta_i in the denominator")
#define PHONG_GLSL_KEYS(X)                                                                                             \
    KD_KEY(X, "diffuse term (RGB), a constant BRDF (no 1/pi)")                                                         \
    KS_KEY(X, "specular colour (RGB)")                                                                                 \
    N_KEY(X)
#define MPHONG_KEYS(X)                                                                                                 \
    KD_KEY(X, "diffuse reflectance (RGB); energy conserving for kd + ks <= 1")                                         \
    KS_KEY(X, "specular reflectance (RGB); energy conserving for kd + ks <= 1")                                        \
    N_KEY(X)                                                                                                           \
    X("floor", K_NUM, 0, 1, 0, rv_floor, NULL,                                                                         \
      "floor of r.v before the power; 0 is the slides' max(r.v, 0), the lecture GLSL uses 0.001", "[0, 1]", "0")
#define BLINN_KEYS(X)                                                                                                  \
    KD_KEY(X, "diffuse term (RGB), a constant BRDF (no 1/pi)")                                                         \
    KS_KEY(X, "specular colour (RGB)")                                                                                 \
    N_KEY(X)
#define NBLINN_KEYS(X)                                                                                                 \
    KD_KEY(X, "diffuse reflectance (RGB)")                                                                             \
    KS_KEY(X, "specular reflectance (RGB)")                                                                            \
    N_KEY(X)                                                                                                           \
    X("norm", K_CHOICE, 0, 0, 0, norm, norm_names,                                                                     \
      "lobe normalisation: rtr = (n+8)/(8 pi) (exceeds energy 1 by up to 7.5% at normal incidence), "                  \
      "exact = (n+2)(n+4)/(8 pi (2^(-n/2) + n)) (normal-incidence albedo exactly ks)",                                 \
      "rtr|exact", "rtr")
#define CT_KEYS(X)                                                                                                     \
    KD_KEY(X, "diffuse weight (RGB); energy conserving for kd + ks <= 1 with normalised terms")                        \
    KS_KEY(X, "specular weight (RGB)")                                                                                 \
    X("albedo", K_RGB, 0, 1, 0, albedo, NULL, "diffuse colour c (RGB); diffuse term kd c/pi", "[0, 1]", "0.8")         \
    X("roughness", K_NUM, 0.001, 1, 0, roughness, NULL,                                                                \
      "roughness: GGX alpha = roughness^2, Beckmann/Gaussian m = roughness, Schlick-GGX k from roughness",             \
      "[0.001, 1]", "0.5")                                                                                             \
    X("d", K_CHOICE, 0, 0, 0, d, d_names,                                                                              \
      "normal distribution: ggx (paper eq. 6), beckmann (slides, 1/(4 m^2 cos^4), integrates to pi/4), "               \
      "beckmann-norm (1/(pi m^2 cos^4)), gaussian (slides, not normalised)",                                           \
      "ggx|beckmann|beckmann-norm|gaussian", "ggx")                                                                    \
    X("g", K_CHOICE, 0, 0, 0, g, g_names,                                                                              \
      "shadowing-masking: smith-schlick (paper, k=(r+1)^2/8), smith-disney (lecture G1_GGX_Schlick: same k, "          \
      "numerator max(n.v, guard)), smith-alpha (k = alpha/2 of D; for GGX the lecture's original r^2/2), "             \
      "vcavity (Cook-Torrance), none",                                                                                 \
      "smith-schlick|smith-disney|smith-alpha|vcavity|none", "smith-schlick")                                          \
    X("f", K_CHOICE, 0, 0, 0, f, f_names,                                                                              \
      "Fresnel: schlick (paper eq. 10, F0 from f0 or ior), conductor (Schlick with RGB F0 of a metal), "               \
      "dielectric (slides' full Fresnel with eta = ior), none (F = 1)",                                                \
      "schlick|conductor|dielectric|none", "schlick")                                                                  \
    X("f0", K_F0, 0, 1.1, 0, f0, NULL,                                                                                 \
      "normal-incidence reflectance for f=schlick|conductor (RGB or any preset name); not with ior",                   \
      "[0, 1.1] (the table's gold has 1.022)", "((ior-1)/(ior+1))^2 = 0.04 for schlick, gold for conductor")           \
    X("ior", K_IOR, 1, 10, 0, ior, NULL,                                                                               \
      "refractive index eta for f=dielectric, or F0 = ((eta-1)/(eta+1))^2 for f=schlick (number or a "                 \
      "dielectric preset name); not with f0",                                                                          \
      "[1, 10]", "1.5")                                                                                                \
    X("denom", K_CHOICE, 0, 0, 0, denom, denom_names,                                                                  \
      "specular denominator: 4 = 4 (n.l)(n.v) (paper), cos = (n.l)(n.v) (slides), pi = pi (n.l)(n.v) "                 \
      "(Cook & Torrance 1982)",                                                                                        \
      "4|cos|pi", "4")                                                                                                 \
    GUARD_KEY(X, "n.l and n.v in the denominator with g=vcavity|none (a Smith G cancels them: "                        \
                 "f is finite at the horizon and the guard has no effect)")
#define MICROFACET_KEYS(X)                                                                                             \
    X("base", K_BASE, 0, 1.1, 0, base, NULL, "base colour (RGB, or a metal preset name: the metal's F0)",              \
      "[0, 1.1] (the table's gold has 1.022)", "0.5")                                                                  \
    X("metallic", K_NUM, 0, 1, 0, metallic, NULL, "metalness: mixes f0 towards base; no diffuse for metals", "[0, 1]", \
      "0 (1 when base is a metal preset)")                                                                             \
    X("reflectance", K_NUM, 0, 1, 0, reflectance, NULL, "dielectric reflectance: f0 = 0.16 reflectance^2", "[0, 1]",   \
      "0.5")                                                                                                           \
    X("roughness", K_NUM, 0.001, 1, 0, roughness, NULL,                                                                \
      "perceptual roughness: GGX alpha = roughness^2, Schlick-GGX k = ((1 + roughness)/2)^2/2", "[0.001, 1]", "0.5")   \
    X("anisotropy", K_NUM, 0, 1, 0, anisotropy, NULL,                                                                  \
      "anisotropic GGX (Burley): alpha_x = alpha/a along the tangent x, alpha_y = alpha a, a = sqrt(1 - 0.9 "          \
      "anisotropy); 0 is isotropic",                                                                                   \
      "[0, 1]", "0")                                                                                                   \
    GUARD_KEY(X, "n.l and n.v in G's numerators and the denominator")

#define KEY_TABLES(tag, LIST)                                                                                          \
    static const sb_model_key_t tag##_pub[] = {LIST(KEY_PUB)};                                                         \
    static const keyspec_t tag##_spec[] = {LIST(KEY_SPEC)};
KEY_TABLES(lambert, LAMBERT_KEYS)
KEY_TABLES(phong, PHONG_KEYS)
KEY_TABLES(phong_glsl, PHONG_GLSL_KEYS)
KEY_TABLES(mphong, MPHONG_KEYS)
KEY_TABLES(blinn, BLINN_KEYS)
KEY_TABLES(nblinn, NBLINN_KEYS)
KEY_TABLES(ct, CT_KEYS)
KEY_TABLES(microfacet, MICROFACET_KEYS)

#define NKEYS(tag) (sizeof tag##_pub / sizeof tag##_pub[0])
#define MODEL_INFO(name, summary, tag)                                                                                 \
    { name, summary, tag##_pub, NKEYS(tag) }

/* Indexed by M_*. */
static const sb_model_info_t models[] = {
    MODEL_INFO("lambert", "ideal diffuse (paper eq. 4): f = albedo/pi", lambert),
    MODEL_INFO("phong",
               "classic Phong as a BRDF (slides): f = kd + ks max(r.v,0)^n / cos theta_i; not reciprocal, "
               "not energy conserving",
               phong),
    MODEL_INFO("phong-glsl", "the lecture's phongBRDF: f = kd + ks max(r.v,0)^n; reciprocal, not normalised",
               phong_glsl),
    MODEL_INFO("modified-phong",
               "modified Phong (slides, lecture modifiedPhongBRDF): f = kd/pi + ks (n+2)/(2 pi) max(r.v,floor)^n; "
               "energy conserving for kd + ks <= 1",
               mphong),
    MODEL_INFO("blinn-phong", "the lecture's blinnPhongBRDF: f = kd + ks max(n.h,0)^n; not normalised", blinn),
    MODEL_INFO("normalised-blinn-phong", "normalised Blinn-Phong: f = kd/pi + ks C_n (n.h)^n, C_n by norm", nblinn),
    MODEL_INFO("cook-torrance",
               "Cook-Torrance (paper eq. 11, slides): f = kd albedo/pi + ks D G F / den, D, G, F and den "
               "selectable",
               ct),
    MODEL_INFO("microfacet",
               "the lecture's microfacetBRDF: GGX D, Smith Schlick-GGX G (Disney remap), Schlick F, metallic "
               "workflow, diffuse (1-F)(1-metallic) base/pi",
               microfacet),
};
#define NMODELS (sizeof models / sizeof models[0])

static const keyspec_t *const model_specs[] = {lambert_spec, phong_spec,  phong_glsl_spec, mphong_spec,
                                               blinn_spec,   nblinn_spec, ct_spec,         microfacet_spec};
static int (*const model_evals[])(const void *, const double *, const double *, double *) = {
    sb_model_lambert_, sb_model_phong_,  sb_model_phong_glsl_, sb_model_mphong_,
    sb_model_blinn_,   sb_model_nblinn_, sb_model_ct_,         sb_model_microfacet_};

size_t sb_model_count(void) { return NMODELS; }
const sb_model_info_t *sb_model_at(size_t i) { return i < NMODELS ? &models[i] : NULL; }

/* ---- spec parsing ------------------------------------------------------ */

static sb_result_t parse_number(sb_context_t *ctx, const char *model, const char *key, const char *s, double *out) {
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (end == s || *end || isnan(v))
        return sb_error(ctx, SB_ERR_PARSE, "%s: key '%s': '%s' is not a number", model, key, s);
    /* ERANGE: overflow gives an infinity (refused); underflow a denormal or
     * zero, which is the number asked for as closely as a double holds it */
    if (!isfinite(v))
        return sb_error(ctx, SB_ERR_PARSE, "%s: key '%s': '%s' is not finite (largest number %g)", model, key, s,
                        DBL_MAX);
    *out = v;
    return SB_OK;
}

/* "0.8" -> (0.8, 0.8, 0.8); "0.9/0.6/0.3" -> RGB. */
static sb_result_t parse_rgb(sb_context_t *ctx, const char *model, const char *key, const char *s, double rgb[3]) {
    char buf[256];
    if (strlen(s) >= sizeof buf) return sb_error(ctx, SB_ERR_PARSE, "%s: key '%s': value too long", model, key);
    snprintf(buf, sizeof buf, "%s", s);
    char *parts[3] = {buf, NULL, NULL};
    int n = 1;
    for (char *q = buf; *q; q++)
        if (*q == '/') {
            if (n == 3)
                return sb_error(ctx, SB_ERR_PARSE, "%s: key '%s': '%s' has more than 3 components", model, key, s);
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

static sb_result_t check_range(sb_context_t *ctx, const char *model, const char *key, const keyspec_t *k, double v) {
    if ((k->open_lo ? v <= k->lo : v < k->lo) || v > k->hi)
        return sb_error(ctx, SB_ERR_RANGE, "%s: key '%s' = %g out of range, need %s%g, %g]", model, key, v,
                        k->open_lo ? "(" : "[", k->lo, k->hi);
    return SB_OK;
}

/* Parse one value into the field described by k.  Preset names are taken by
 * base (metals), f0 (any) and ior (dielectrics); *metal is set when a metal
 * preset was named. */
static sb_result_t parse_value(sb_context_t *ctx, const char *model, const char *key, const keyspec_t *k,
                               const char *val, model_t *m, int *metal) {
    void *field = (char *)m + k->off;
    const sb_preset_t *p = NULL;
    sb_result_t r = SB_OK;
    if ((k->type == K_BASE || k->type == K_F0 || k->type == K_IOR) && isalpha((unsigned char)val[0])) {
        p = sb_preset_find(val);
        if (!p)
            return sb_error(ctx, SB_ERR_UNKNOWN, "%s: key '%s': unknown preset '%s' (see `sepbrdf list`)", model, key,
                            val);
        int is_metal = strcmp(p->kind, "metal") == 0;
        if (k->type == K_BASE && !is_metal)
            return sb_error(ctx, SB_ERR_ARG, "%s: key '%s': '%s' is a dielectric; base takes a colour or a metal",
                            model, key, val);
        if (k->type == K_IOR && is_metal)
            return sb_error(ctx, SB_ERR_ARG, "%s: key '%s': '%s' is a metal, it has no refractive index here", model,
                            key, val);
        *metal = is_metal;
    }
    switch (k->type) {
    case K_CHOICE: {
        const char *const *c = k->choices;
        for (int i = 0; c[i]; i++)
            if (strcmp(c[i], val) == 0) {
                *(int *)field = i;
                return SB_OK;
            }
        char list[256] = "";
        for (int i = 0; c[i]; i++) {
            size_t len = strlen(list);
            snprintf(list + len, sizeof list - len, "%s%s", i ? ", " : "", c[i]);
        }
        return sb_error(ctx, SB_ERR_UNKNOWN, "%s: key '%s': unknown value '%s' (one of %s)", model, key, val, list);
    }
    case K_NUM:
    case K_IOR:
        if (p) {
            *(double *)field = p->ior;
            return SB_OK;
        }
        r = parse_number(ctx, model, key, val, field);
        return r == SB_OK ? check_range(ctx, model, key, k, *(double *)field) : r;
    default: { /* K_RGB, K_BASE, K_F0 */
        double *rgb = field;
        if (p) {
            memcpy(rgb, p->f0, sizeof p->f0);
            return SB_OK;
        }
        r = parse_rgb(ctx, model, key, val, rgb);
        for (int c = 0; r == SB_OK && c < 3; c++)
            r = check_range(ctx, model, key, k, rgb[c]);
        return r;
    }
    }
}

static void set3(double v[3], double x) { v[0] = v[1] = v[2] = x; }
static int is_gray(const double v[3]) { return v[0] == v[1] && v[1] == v[2]; }
static int is_zero(const double v[3]) { return v[0] == 0 && v[1] == 0 && v[2] == 0; }

static void defaults(model_t *m, int kind) {
    memset(m, 0, sizeof *m);
    m->kind = kind;
    set3(m->albedo, 0.8);
    set3(m->kd, 0.5);
    set3(m->ks, 0.5);
    m->n = 20;
    m->guard = 0.001;
    m->roughness = 0.5;
    m->ior = 1.5;
    set3(m->base, 0.5);
    m->reflectance = 0.5;
}

/* Whether a key is printed in the canonical description of m. */
static int key_relevant(const model_t *m, const char *name) {
    if (strcmp(name, "anisotropy") == 0) return m->anisotropy > 0; /* isotropic specs stay as they were */
    if (m->kind != M_CT) return 1;
    if (strcmp(name, "f0") == 0) return m->f == F_SCHLICK || m->f == F_CONDUCTOR;
    if (strcmp(name, "ior") == 0) return m->f == F_DIELECTRIC;
    return 1;
}

static void append_number(char *buf, size_t size, double v) {
    size_t len = strlen(buf);
    snprintf(buf + len, size - len, "%.15g", v);
}

/* The canonical spec "model:key=value,..." with every key that applies;
 * sb_model_create() on it gives the same model. */
static void describe(const model_t *m, char *buf, size_t size) {
    const sb_model_info_t *info = &models[m->kind];
    const keyspec_t *spec = model_specs[m->kind];
    snprintf(buf, size, "%s", info->name);
    int first = 1;
    for (size_t i = 0; i < info->key_count; i++) {
        if (!key_relevant(m, info->keys[i].name)) continue;
        size_t len = strlen(buf);
        snprintf(buf + len, size - len, "%s%s=", first ? ":" : ",", info->keys[i].name);
        first = 0;
        const void *field = (const char *)m + spec[i].off;
        if (spec[i].type == K_CHOICE) {
            len = strlen(buf);
            snprintf(buf + len, size - len, "%s", spec[i].choices[*(const int *)field]);
        } else if (spec[i].type == K_NUM || spec[i].type == K_IOR) {
            append_number(buf, size, *(const double *)field);
        } else {
            const double *rgb = field;
            for (int c = 0; c < (is_gray(rgb) ? 1 : 3); c++) {
                if (c) {
                    len = strlen(buf);
                    snprintf(buf + len, size - len, "/");
                }
                append_number(buf, size, rgb[c]);
            }
        }
    }
}

/* Normalised Blinn-Phong: f = kd/pi + ks C_n (n.h)^n with
 *   rtr:   C_n = (n + 8)/(8 pi)                      (the usual approximation)
 *   exact: C_n = (n + 2)(n + 4) / (8 pi (2^(-n/2) + n))
 * "exact" makes the lobe's albedo at normal incidence exactly ks:
 *   int (n.h)^n cos theta_o dw_o = 8 pi (n + 2^(-n/2)) / ((n + 2)(n + 4))
 * (h bisects n and v, substitute u = cos(theta_o/2)).  "rtr" overshoots it
 * by (n + 8)(n + 2^(-n/2)) / ((n + 2)(n + 4)), up to 1.075 near n = 10. */
static double blinn_norm(double n, int exact) {
    if (!exact) return (n + 8) / (8 * SB_PI);
    return (n + 2) * (n + 4) / (8 * SB_PI * (pow(2.0, -n / 2) + n));
}

/* Resolve defaults that depend on other keys, reject combinations where a
 * key would be silently ignored, and precompute the constants. */
static sb_result_t finish(sb_context_t *ctx, model_t *m, int f0_set, int ior_set, int metal_base, int metallic_set) {
    const char *name = models[m->kind].name;
    m->cmin = m->guard > 0 ? m->guard : SB_COS_FLOOR;
    switch (m->kind) {
    case M_MPHONG:
        m->cspec = (m->n + 2) / (2 * SB_PI);
        break;
    case M_NBLINN:
        m->cspec = blinn_norm(m->n, m->norm == NORM_EXACT);
        break;
    case M_CT:
        if (f0_set && ior_set) return sb_error(ctx, SB_ERR_ARG, "%s: give key 'f0' or key 'ior', not both", name);
        if (m->f == F_DIELECTRIC && f0_set)
            return sb_error(ctx, SB_ERR_ARG, "%s: key 'f0' is not used by f=dielectric; give ior", name);
        if (m->f == F_CONDUCTOR && ior_set)
            return sb_error(ctx, SB_ERR_ARG, "%s: key 'ior' is not used by f=conductor; give f0", name);
        if (m->f == F_NONE && (f0_set || ior_set))
            return sb_error(ctx, SB_ERR_ARG, "%s: key '%s' is not used by f=none", name, f0_set ? "f0" : "ior");
        if (m->f == F_SCHLICK && !f0_set) set3(m->f0, F0_OF_ETA(m->ior));
        if (m->f == F_CONDUCTOR && !f0_set) memcpy(m->f0, sb_preset_find("gold")->f0, sizeof m->f0);
        m->cspec = m->denom == DENOM_4 ? 4 : m->denom == DENOM_PI ? SB_PI : 1;
        m->alpha = m->d == D_GGX ? m->roughness * m->roughness : m->roughness;
        m->k = m->g == G_SMITH_ALPHA ? m->alpha / 2 : (m->roughness + 1) * (m->roughness + 1) / 8;
        break;
    case M_MICROFACET: {
        if (metal_base && !metallic_set) m->metallic = 1;
        m->d = D_GGX;
        m->alpha = m->roughness * m->roughness;
        double aspect = sqrt(1 - 0.9 * m->anisotropy);
        m->ax = m->alpha / aspect;
        m->ay = m->alpha * aspect;
        double r = 0.5 + 0.5 * m->roughness;
        m->k = r * r / 2;
        break;
    }
    default:
        break;
    }
    return SB_OK;
}

/* Flags that hold for this instance. */
static unsigned model_flags(const model_t *m) {
    unsigned flags = m->anisotropy > 0 ? 0u : SB_SOURCE_ISOTROPIC | SB_SOURCE_EVEN; /* of dot products only */
    /* Only classic Phong divides by n.l alone; with ks = 0 it is constant. */
    if (m->kind != M_PHONG || is_zero(m->ks)) flags |= SB_SOURCE_RECIPROCAL;
    int gray;
    switch (m->kind) {
    case M_LAMBERT:
        gray = is_gray(m->albedo);
        break;
    case M_CT: {
        double d[3] = {m->kd[0] * m->albedo[0], m->kd[1] * m->albedo[1], m->kd[2] * m->albedo[2]};
        int fgray = m->f == F_DIELECTRIC || m->f == F_NONE || is_gray(m->f0);
        gray = is_gray(d) && (is_zero(m->ks) || (is_gray(m->ks) && fgray));
        break;
    }
    case M_MICROFACET:
        gray = is_gray(m->base);
        break;
    default:
        gray = is_gray(m->kd) && is_gray(m->ks);
        break;
    }
    if (gray) flags |= SB_SOURCE_GRAY;
    return flags;
}

sb_result_t sb_model_create(sb_context_t *ctx, const char *spec, sb_source_t **out) {
    if (!spec || !out) return sb_error(ctx, SB_ERR_ARG, "model: no spec");
    *out = NULL;
    char buf[1024];
    if (strlen(spec) >= sizeof buf) return sb_error(ctx, SB_ERR_PARSE, "model spec too long");
    snprintf(buf, sizeof buf, "%s", spec);
    char *args = strchr(buf, ':');
    if (args) *args++ = 0;
    const char *name = buf;
    int kind = -1;
    for (size_t i = 0; i < NMODELS; i++)
        if (strcmp(models[i].name, name) == 0) kind = (int)i;
    if (kind < 0) return sb_error(ctx, SB_ERR_UNKNOWN, "unknown model '%s' (see `sepbrdf list`)", name);
    const sb_model_info_t *info = &models[kind];
    const keyspec_t *kspec = model_specs[kind];

    model_t m;
    defaults(&m, kind);
    unsigned long seen = 0;
    int metal_base = 0, f0_set = 0, ior_set = 0, metallic_set = 0;
    while (args && *args) {
        char *comma = strchr(args, ',');
        if (comma) *comma = 0;
        char *eq = strchr(args, '=');
        if (!eq || eq == args) return sb_error(ctx, SB_ERR_PARSE, "%s: '%s' is not key=value", name, args);
        *eq = 0;
        const char *key = args, *val = eq + 1;
        size_t i = 0;
        while (i < info->key_count && strcmp(info->keys[i].name, key) != 0)
            i++;
        if (i == info->key_count) {
            char list[256] = "";
            for (size_t j = 0; j < info->key_count; j++) {
                size_t len = strlen(list);
                snprintf(list + len, sizeof list - len, "%s%s", j ? ", " : "", info->keys[j].name);
            }
            return sb_error(ctx, SB_ERR_UNKNOWN, "%s: unknown key '%s' (keys: %s)", name, key, list);
        }
        if (seen & (1ul << i)) return sb_error(ctx, SB_ERR_ARG, "%s: key '%s' given twice", name, key);
        seen |= 1ul << i;
        int metal = 0;
        sb_result_t r = parse_value(ctx, name, key, &kspec[i], val, &m, &metal);
        if (r != SB_OK) return r;
        if (strcmp(key, "base") == 0) metal_base = metal;
        if (strcmp(key, "f0") == 0) f0_set = 1;
        if (strcmp(key, "ior") == 0) ior_set = 1;
        if (strcmp(key, "metallic") == 0) metallic_set = 1;
        args = comma ? comma + 1 : NULL;
    }
    sb_result_t r = finish(ctx, &m, f0_set, ior_set, metal_base, metallic_set);
    if (r != SB_OK) return r;

    model_t *self = malloc(sizeof *self);
    if (!self) return sb_error(ctx, SB_ERR_NOMEM, "model: out of memory");
    *self = m;
    char desc[1024];
    describe(&m, desc, sizeof desc);
    sb_source_ops_t ops = {model_evals[kind], free};
    r = sb_source_create(ctx, &ops, self, model_flags(&m), desc, out);
    if (r != SB_OK) free(self);
    return r;
}
