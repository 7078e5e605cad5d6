/* Factor an analytic BRDF through the public API of an installed sepbrdf:
 * source -> io parameterisation -> matrix -> plan/execute -> errors.
 *
 *   use_library [MODEL_SPEC] [R] [J]
 *
 * prints sigma_j and the relative RMS error ||M - M_J'||_F / ||M||_F for
 * every J' <= J, then compares one reconstructed value f~(wi, wo) (through
 * texture lookups, as a shader does) with the source.  Exit 0 on success. */
#include <sepbrdf/sepbrdf.h>
#include <stdio.h>
#include <stdlib.h>

static void on_error(void *user, sb_result_t code, const char *message) {
    (void)user;
    fprintf(stderr, "use_library: %s: %s\n", sb_result_name(code), message);
}

int main(int argc, char **argv) {
    const char *spec = argc > 1 ? argv[1] : "microfacet:base=gold,roughness=0.5";
    size_t res = argc > 2 ? (size_t)strtoul(argv[2], NULL, 10) : 16;
    size_t terms = argc > 3 ? (size_t)strtoul(argv[3], NULL, 10) : 4;
    sb_context_t *ctx = NULL;
    sb_source_t *src = NULL;
    sb_param_t *param = NULL;
    sb_matrix_t m = {0};
    sb_plan_t *plan = NULL;
    sb_factors_t *f = NULL;
    int rc = 1;

    if (sb_context_create(&ctx) != SB_OK) return 1;
    sb_context_set_error_callback(ctx, on_error, NULL);
    sb_param_opts_t po = {0};
    po.res = res;
    sb_plan_opts_t pl = {0};
    pl.terms = terms;
    if (sb_model_create(ctx, spec, &src) != SB_OK) goto out;
    if (sb_param_create(ctx, SB_PARAM_IO, &po, &param) != SB_OK) goto out;
    if (sb_matrix_build(ctx, src, param, NULL, &m) != SB_OK) goto out;
    if (sb_plan_create(ctx, m.rows, m.cols, &pl, &plan) != SB_OK) goto out;
    if (sb_plan_execute(plan, &m, param, &f) != SB_OK) goto out;

    printf("sepbrdf %s: %s on %s, %zu x %zu matrix\n", SB_VERSION_STRING, sb_source_description(src),
           sb_param_spec(param), m.rows, m.cols);
    const sb_factor_errors_t *e = sb_factors_errors(f);
    printf("%4s  %12s  %12s\n", "J", "sigma_R", "rel_rms");
    for (size_t j = 0; j < sb_factors_terms(f); j++)
        printf("%4zu  %12.6g  %12.6e\n", j + 1, sb_factors_sigma(f, j, 0), e->rel_rms[j * 4 + 3]);

    double wi[3], wo[3], ref[3], rec[3];
    sb_dir_from_angles(0.5, 0.3, wi);
    sb_dir_from_angles(0.4, 0.3 + SB_PI, wo);
    sb_source_eval(src, wi, wo, ref);
    sb_factors_eval(f, param, SB_FORM_F, sb_factors_terms(f), wi, wo, rec);
    printf("f_r(wi, wo) red: source %.6g, %zu terms %.6g\n", ref[0], sb_factors_terms(f), rec[0]);
    rc = 0;
out:
    sb_factors_destroy(f);
    sb_plan_destroy(plan);
    sb_matrix_free(&m);
    sb_param_destroy(param);
    sb_source_destroy(src);
    sb_context_destroy(ctx);
    return rc;
}
