/* sepbrdf: analytic BRDF models behind the source interface.
 *
 * A model spec is "MODEL[:key=value,key=value,...]", e.g.
 *     lambert:albedo=0.8
 *     microfacet:base=gold,roughness=0.5
 * Values are numbers, RGB triples "r/g/b", or preset names (metals for
 * base/f0, dielectrics for ior).  sb_model_count()/sb_model_at() describe
 * every model and key for `sepbrdf list`. */
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

size_t sb_model_count(void);
const sb_model_info_t *sb_model_at(size_t i);

typedef struct sb_preset {
    const char *name;    /* "gold", "glass", ... */
    const char *kind;    /* "metal" or "dielectric" */
    double f0[3];        /* linear F0 */
    double ior;          /* refractive index (dielectrics), 0 for metals */
} sb_preset_t;

size_t sb_preset_count(void);
const sb_preset_t *sb_preset_at(size_t i);
const sb_preset_t *sb_preset_find(const char *name); /* NULL if unknown */

/* Create an analytic source from a spec.  Errors name the key:
 * SB_ERR_UNKNOWN (model, key or preset), SB_ERR_PARSE (malformed number),
 * SB_ERR_RANGE (value outside its range). */
sb_result_t sb_model_create(sb_context_t *ctx, const char *spec, sb_source_t **out);

#ifdef __cplusplus
}
#endif
#endif
