/* sepbrdf: analytic BRDF models behind the source interface.
 *
 * A model spec is "MODEL[:key=value,key=value,...]", e.g.
 *     lambert:albedo=0.8
 *     microfacet:base=gold,roughness=0.5
 *     cook-torrance:d=beckmann,g=vcavity,f=dielectric,ior=glass,denom=cos
 * Values are numbers, RGB triples "r/g/b", choices, or preset names (metals
 * for base, any preset for f0, dielectrics for ior).  sb_model_count() and
 * sb_model_at() describe every model and key (meaning, range, default) for
 * `sepbrdf list`.
 *
 * With l = wi (to the light), v = wo (to the viewer), n = z,
 * r = 2 (n.l) n - l, h = (l + v)/|l + v| (f = 0 when l_z <= 0 or v_z <= 0):
 *   lambert                 f = albedo/pi
 *   phong                   f = kd + ks max(r.v,0)^n / max(n.l, guard)       (slides; not reciprocal)
 *   phong-glsl              f = kd + ks max(r.v,0)^n                         (lecture phongBRDF)
 *   modified-phong          f = kd/pi + ks (n+2)/(2 pi) max(r.v,floor)^n     (slides, lecture)
 *   blinn-phong             f = kd + ks max(n.h,0)^n                         (lecture blinnPhongBRDF)
 *   normalised-blinn-phong  f = kd/pi + ks C_n (n.h)^n, C_n = (n+8)/(8 pi) or exact
 *   cook-torrance           f = kd albedo/pi + ks D G F / den; D ggx|beckmann|beckmann-norm|gaussian,
 *                           G smith-schlick|smith-disney|smith-alpha|vcavity|none,
 *                           F schlick|conductor|dielectric|none, den 4|cos|pi times (n.l)(n.v)
 *   microfacet              the lecture's microfacetBRDF (metallic workflow)
 * Cosines in denominators are raised to `guard` (default 0.001, the
 * lecture's max(n.v, 0.001); guard=0 turns that off).  The flags of each
 * instance say what holds: ISOTROPIC always, RECIPROCAL unless classic Phong
 * with ks != 0, GRAY when no term is coloured. */
#ifndef SEPBRDF_MODELS_H
#define SEPBRDF_MODELS_H

#include "common.h"
#include "source.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sb_model_key {
    const char *name;
    const char *meaning;
    const char *range;
    const char *def;
} sb_model_key_t;

typedef struct sb_model_info {
    const char *name;
    const char *summary;
    const sb_model_key_t *keys;
    size_t key_count;
} sb_model_info_t;

SB_API size_t sb_model_count(void);
SB_API const sb_model_info_t *sb_model_at(size_t i);

typedef struct sb_preset {
    const char *name; /* "gold", "glass", ... */
    const char *kind; /* "metal" or "dielectric" */
    double f0[3];     /* linear F0 */
    double ior;       /* refractive index (dielectrics), 0 for metals */
} sb_preset_t;

SB_API size_t sb_preset_count(void);
SB_API const sb_preset_t *sb_preset_at(size_t i);
SB_API const sb_preset_t *sb_preset_find(const char *name); /* NULL if unknown */

/* Create an analytic source from a spec; its description is the canonical
 * spec with every key that applies (creating a source from it gives the
 * same model).  Errors name the model and the key:
 * SB_ERR_UNKNOWN (model, key, preset or choice), SB_ERR_PARSE (malformed
 * number, RGB triple or key=value), SB_ERR_RANGE (value outside its range),
 * SB_ERR_ARG (NULL argument, a key given twice, a key the other keys make
 * meaningless: f0 with ior, f0 with f=dielectric, ior with f=conductor,
 * either with f=none; a dielectric preset as base, a metal as ior). */
SB_API sb_result_t sb_model_create(sb_context_t *ctx, const char *spec, sb_source_t **out);

#ifdef __cplusplus
}
#endif
#endif
