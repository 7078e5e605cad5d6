/* Set-up shared by the factorisation tests: an analytic source from a model
 * spec, a layout from its kind and resolution, and one plan run on a matrix.
 * Each fails the running case (with the library's message) when the call
 * fails. */
#ifndef SB_TEST_FIXTURES_H
#define SB_TEST_FIXTURES_H

#include "harness.h"
#include "sepbrdf/sepbrdf.h"

/* The model `spec` ("microfacet:base=gold,roughness=0.3", ...). */
static inline sb_source_t *fx_model(const char *spec) {
    sb_source_t *s = NULL;
    sb_context_t *ctx = NULL;
    sb_context_create(&ctx);
    sb_result_t r = sb_model_create(ctx, spec, &s);
    CHECKF(r == SB_OK, "model %s: %s", spec, sb_context_last_error(ctx));
    sb_context_destroy(ctx);
    return s;
}

/* The layout `kind` at R x R texels, every other option at its default. */
static inline sb_param_t *fx_layout(sb_param_kind_t kind, size_t R) {
    sb_param_t *p = NULL;
    sb_param_opts_t o = {0};
    o.res = R;
    CHECKF(sb_param_create(NULL, kind, &o, &p) == SB_OK, "layout %s at R = %zu", sb_param_kind_name(kind), R);
    return p;
}

/* The factors of m under the plan options po (the plan is made for m's
 * sizes and destroyed; the factors outlive it). NULL on failure. */
static inline sb_factors_t *fx_factor(const sb_matrix_t *m, const sb_param_t *p, const sb_plan_opts_t *po) {
    sb_plan_t *plan = NULL;
    sb_factors_t *f = NULL;
    CHECK(sb_plan_create(NULL, m->rows, m->cols, po, &plan) == SB_OK);
    if (plan) CHECK(sb_plan_execute(plan, m, p, &f) == SB_OK);
    sb_plan_destroy(plan);
    return f;
}

#endif
