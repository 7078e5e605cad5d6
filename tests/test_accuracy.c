/* Accuracy of the parameterisations (issue "Accuracy"): exact cases,
 * the GGX target, Eckart-Young for unmasked runs, monotone errors. */
#include <lapacke.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"

typedef struct run {
    sb_param_t *p;
    sb_matrix_t m;
    sb_factors_t *f;
    sb_metric_t metric;
} run_t;

static int factor_on(const char *spec, sb_param_kind_t kind, const sb_param_opts_t *po, sb_form_t form, size_t J,
                     int weighted, int zero_fill, run_t *out) {
    memset(out, 0, sizeof *out);
    sb_context_t *ctx;
    sb_context_create(&ctx);
    sb_source_t *s = NULL;
    sb_result_t r = sb_model_create(ctx, spec, &s);
    if (r != SB_OK) {
        sb_context_destroy(ctx);
        return r;
    }
    CHECK(sb_param_create(ctx, kind, po, &out->p) == SB_OK);
    sb_matrix_opts_t mo = {0};
    mo.form = form;
    CHECK(sb_matrix_build(ctx, s, out->p, &mo, &out->m) == SB_OK);
    sb_plan_opts_t pl = {0};
    pl.terms = J;
    pl.weighted = weighted;
    pl.zero_fill = zero_fill;
    sb_plan_t *plan;
    CHECK(sb_plan_create(ctx, out->m.rows, out->m.cols, &pl, &plan) == SB_OK);
    r = sb_plan_execute(plan, &out->m, out->p, &out->f);
    CHECKF(r == SB_OK, "%s on %s: %s", spec, sb_param_kind_name(kind), sb_context_last_error(ctx));
    CHECK(sb_metric_compute(ctx, s, out->f, out->p, form, NULL, &out->metric) == SB_OK);
    sb_plan_destroy(plan);
    sb_source_destroy(s);
    sb_context_destroy(ctx);
    return SB_OK;
}

/* factor_on with the layout's own shape at R cells per axis. */
static int factor(const char *spec, sb_param_kind_t kind, size_t R, sb_form_t form, size_t J, int weighted,
                  int zero_fill, run_t *out) {
    sb_param_opts_t po = {0};
    po.res = R;
    return factor_on(spec, kind, &po, form, J, weighted, zero_fill, out);
}

static void run_free(run_t *r) {
    sb_factors_destroy(r->f);
    sb_matrix_free(&r->m);
    sb_param_destroy(r->p);
}

SB_TEST(lambert_exact_everywhere) {
    for (int k = 0; k < (int)sb_param_kind_count(); k++) {
        run_t r;
        factor("lambert:albedo=0.7/0.5/0.3", (sb_param_kind_t)k, 16, SB_FORM_F, 1, 0, 0, &r);
        double e = sb_factors_errors(r.f)->rel_rms[3];
        CHECKF(e < 1e-10, "%s: J=1 rel_rms %g", sb_param_kind_name((sb_param_kind_t)k), e);
        CHECKF(r.metric.rel_l2[0] < 1e-6, "%s: J=1 comparable %g", sb_param_kind_name((sb_param_kind_t)k),
               r.metric.rel_l2[0]);
        run_free(&r);
    }
}

SB_TEST(zero_fill_hurts_hd) {
    run_t r;
    factor("lambert:albedo=0.5", SB_PARAM_HD, 16, SB_FORM_F, 1, 0, 1, &r);
    CHECKF(sb_factors_errors(r.f)->rel_rms[3] > 0.1, "zero-filled hd Lambert J=1: %g",
           sb_factors_errors(r.f)->rel_rms[3]);
    run_free(&r);
}

SB_TEST(blinn_phong_depends_on_h) {
    const char *specs[] = {"normalised-blinn-phong:kd=0,ks=1,n=10", "normalised-blinn-phong:kd=0,ks=1,n=100"};
    for (int i = 0; i < 2; i++) {
        run_t r;
        int rc = factor(specs[i], SB_PARAM_HD, 32, SB_FORM_F, 1, 0, 0, &r);
        if (rc == SB_ERR_UNKNOWN) SKIP("normalised Blinn-Phong model not available");
        double e = sb_factors_errors(r.f)->rel_rms[3];
        CHECKF(e < 1e-6, "%s: hd J=1 rel_rms %g", specs[i], e);
        run_free(&r);
    }
}

/* GGX alpha = 0.3 (roughness^2), F0 = 0.04, no diffuse: the best
 * parameterisation reaches 1 % comparable error at J = 4; io does not.
 * iso with R^2 + R texels a term as th = 32, td = 64, pd = 16 (its own
 * R = 32 shape, th = 64, td = 62, gives 1.7 % here: the converged masked
 * fit on 64 rows lands elsewhere; the headline of `factor` is 7.0e-3 for
 * both). */
SB_TEST(ggx_target) {
    const char *spec = "microfacet:base=0,metallic=0,reflectance=0.5,roughness=0.5477226";
    double best = 1, io = 0;
    for (int k = 0; k < (int)sb_param_kind_count(); k++)
        for (int form = 0; form < SB_FORM_COUNT_; form += 2) { /* f and cos2 */
            run_t r;
            sb_param_opts_t po = {.res = 32};
            if (k == SB_PARAM_ISO)
                po = (sb_param_opts_t){.res = 32, .res_theta_h = 32, .res_theta_d = 64, .res_phi_d = 16};
            factor_on(spec, (sb_param_kind_t)k, &po, (sb_form_t)form, 4, 1, 0, &r);
            double e = r.metric.rel_l2[3];
            if (k == SB_PARAM_IO && form == SB_FORM_COS2) io = e;
            if (e < best) best = e;
            run_free(&r);
        }
    CHECKF(best <= 0.01, "best comparable error at J=4: %g", best);
    CHECKF(io > 5 * best, "io should be much worse: io %g best %g", io, best);
}

static double *sigmas(const double *a, size_t m, size_t n) {
    size_t mn = m < n ? m : n;
    double *c = malloc(m * n * sizeof *c), *s = malloc(mn * sizeof *s), *sup = malloc(mn * sizeof *sup);
    memcpy(c, a, m * n * sizeof *c);
    CHECK(LAPACKE_dgesvd(LAPACK_COL_MAJOR, 'N', 'N', (lapack_int)m, (lapack_int)n, c, (lapack_int)m, s, NULL, 1, NULL,
                         1, sup) == 0);
    free(c);
    free(sup);
    return s;
}

SB_TEST(eckart_young_every_param) {
    for (int k = 0; k < (int)sb_param_kind_count(); k++) {
        run_t r;
        size_t J = 6;
        factor("microfacet:base=copper,roughness=0.4", (sb_param_kind_t)k, 10, SB_FORM_COS2, J, 0, 1, &r);
        const sb_factor_errors_t *e = sb_factors_errors(r.f);
        size_t m = r.m.rows, n = r.m.cols, mn = m < n ? m : n;
        double *s = sigmas(r.m.data[1], m, n), n2 = 0;
        for (size_t i = 0; i < mn; i++)
            n2 += s[i] * s[i];
        for (size_t j = 0; j < J; j++) {
            double t2 = 0;
            for (size_t i = j + 1; i < mn; i++)
                t2 += s[i] * s[i];
            /* The zero-filled matrix is what the SVD saw: without a mask the
             * error is the Eckart-Young value; with one (hd, iso) the error
             * is measured on the valid cells only, a part of the residual. */
            if (!r.m.mask)
                CHECK_REL(e->rel_rms[j * 4 + 1], sqrt(t2 / n2), 1e-8);
            else
                CHECK(e->rel_rms[j * 4 + 1] <= sqrt(t2 / n2) * (1 + 1e-9));
            if (j) CHECK(e->rel_rms[j * 4 + 3] <= e->rel_rms[(j - 1) * 4 + 3] * (1 + 1e-12));
        }
        free(s);
        run_free(&r);
    }
}
