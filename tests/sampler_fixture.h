/* The tests' fixture of the importance sampler (test_sampler.c,
 * test_sampler_share.c): non-negative factors of a model or a measured
 * file and their sampler. */
#ifndef SB_TEST_SAMPLER_FIXTURE_H
#define SB_TEST_SAMPLER_FIXTURE_H

#include <string.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"

typedef struct fixture {
    sb_param_t *p;
    sb_factors_t *f;
    sb_sampler_t *s;
    sb_source_t *src;
} fixture_t;

static inline void fixture_free(fixture_t *x) {
    sb_sampler_destroy(x->s);
    sb_factors_destroy(x->f);
    sb_param_destroy(x->p);
    sb_source_destroy(x->src);
}

/* Non-negative factors (J terms, form f cos(theta_i)) of `spec` (a model
 * or, with a '/', a measured file) on kind at res R, and their sampler. */
static const sb_warp_t *fixture_warp_h; /* theta_h warp of the next fixture (NULL: the layout's own) */

static inline int fixture(const char *spec, sb_param_kind_t kind, size_t R, size_t J, sb_method_t method,
                          fixture_t *x) {
    memset(x, 0, sizeof *x);
    sb_param_opts_t po = {0};
    po.res = R;
    if (fixture_warp_h) po.warp[SB_AXIS_THETA_H] = *fixture_warp_h;
    sb_matrix_opts_t mo = {0};
    mo.form = SB_FORM_COS;
    sb_plan_opts_t pl = {0};
    pl.terms = J;
    pl.weighted = 1;
    pl.svd.method = method;
    sb_matrix_t m = {0};
    sb_plan_t *plan = NULL;
    sb_result_t r =
        strchr(spec, '/') ? sb_measured_open(NULL, spec, NULL, &x->src, NULL) : sb_model_create(NULL, spec, &x->src);
    if (!r) r = sb_param_create(NULL, kind, &po, &x->p);
    if (!r) r = sb_matrix_build(NULL, x->src, x->p, &mo, &m);
    if (!r) r = sb_plan_create_for(NULL, &m, &pl, &plan);
    if (!r) r = sb_plan_execute(plan, &m, x->p, &x->f);
    sb_plan_destroy(plan);
    sb_matrix_free(&m);
    CHECKF(r == SB_OK, "%s on %s: %s", spec, sb_param_kind_name(kind), sb_result_name(r));
    return r == SB_OK;
}

static inline int fixture_sampler(const char *spec, sb_param_kind_t kind, size_t R, size_t J, fixture_t *x) {
    if (!fixture(spec, kind, R, J, SB_METHOD_NMF, x)) return 0;
    sb_context_t *ctx;
    sb_context_create(&ctx);
    sb_result_t r = sb_sampler_create(ctx, x->f, x->p, SB_FORM_COS, &x->s);
    CHECKF(r == SB_OK, "sampler: %s", sb_context_last_error(ctx));
    sb_context_destroy(ctx);
    return r == SB_OK;
}

/* Integral of g(w) over the upper hemisphere, midpoint rule in (cos theta,
 * phi) on n x 2n cells. */
typedef double (*hemi_fn)(const fixture_t *x, const double wo[3], const double wi[3]);
static inline double hemi_integral(const fixture_t *x, const double wo[3], hemi_fn g, size_t n) {
    double dz = 1.0 / (double)n, dp = SB_PI / (double)n, sum = 0;
    for (size_t i = 0; i < n; i++)
        for (size_t k = 0; k < 2 * n; k++) {
            double z = 1 - (i + 0.5) * dz, phi = (k + 0.5) * dp, r = sqrt(1 - z * z);
            double w[3] = {r * cos(phi), r * sin(phi), z};
            sum += g(x, wo, w);
        }
    return sum * dz * dp;
}

#endif
