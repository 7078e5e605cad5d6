/* What `sepbrdf factor` does, through the public API of an installed
 * sepbrdf: the factor job (job.h) chooses the parameterisation and form
 * (--param auto), factors, measures and writes the output set.
 *
 *   use_library [SOURCE] [R] [J] [OUT]
 *
 * is `sepbrdf factor SOURCE -r R -J J -o OUT` (defaults: the gold
 * microfacet, 16, 4, use_library-out): the same textures, report.json and
 * sepbrdf.glsl.  It prints the candidates screened, the error per J' <= J,
 * and compares one reconstructed value f~(wi, wo) (through texture
 * lookups, as a shader does) with the source.  Exit 0 on success. */
#include <sepbrdf/sepbrdf.h>
#include <stdio.h>
#include <stdlib.h>

static void on_error(void *user, sb_result_t code, const char *message) {
    (void)user;
    fprintf(stderr, "use_library: %s: %s\n", sb_result_name(code), message);
}

static void print_job(const sb_job_t *job) {
    const sb_job_candidate_t *c;
    for (size_t i = 0; (c = sb_job_candidate(job, i)) != NULL; i++)
        printf("  candidate %-8s %-4s %s %.4e%s\n", sb_param_kind_name(c->kind), sb_form_name(c->form),
               c->ok ? "comparable" : "failed", c->ok ? c->error : 0.0, c->kept ? "  kept" : "");
    const sb_factors_t *f = sb_job_factors(job);
    const sb_factor_errors_t *e = sb_factors_errors(f);
    printf("%s on %s, form %s\n", sb_source_description(sb_job_source(job)), sb_param_spec(sb_job_param(job)),
           sb_form_name(sb_job_form(job)));
    printf("%4s  %12s  %12s  %12s\n", "J", "sigma_R", "rel_rms", "comparable");
    for (size_t j = 0; j < sb_factors_terms(f); j++)
        printf("%4zu  %12.6g  %12.6e  %12.6e\n", j + 1, sb_factors_sigma(f, j, 0), e->rel_rms[j * 4 + 3],
               sb_job_comparable(job, j + 1));
}

int main(int argc, char **argv) {
    sb_job_opts_t o = SB_JOB_OPTS_INIT; /* every default of `sepbrdf factor` */
    o.source = argc > 1 ? argv[1] : NULL;
    o.res = argc > 2 ? (size_t)strtoul(argv[2], NULL, 10) : 16;
    o.terms = argc > 3 ? (size_t)strtoul(argv[3], NULL, 10) : 4;
    o.out = argc > 4 ? argv[4] : "use_library-out";
    sb_context_t *ctx = NULL;
    sb_job_t *job = NULL;
    if (sb_context_create(&ctx) != SB_OK) return 1;
    sb_context_set_error_callback(ctx, on_error, NULL);
    int rc = 1;
    if (sb_job_run(ctx, &o, &job) == SB_OK) {
        printf("sepbrdf %s: wrote %s/\n", sb_version(), o.out);
        print_job(job);
        double wi[3], wo[3], ref[3], rec[3];
        const sb_factors_t *f = sb_job_factors(job);
        sb_dir_from_angles(0.5, 0.3, wi);
        sb_dir_from_angles(0.4, 0.3 + SB_PI, wo);
        sb_source_eval(sb_job_source(job), wi, wo, ref);
        sb_factors_eval(f, sb_job_param(job), sb_job_form(job), sb_factors_terms(f), wi, wo, rec);
        printf("f_r(wi, wo) red: source %.6g, %zu terms %.6g\n", ref[0], sb_factors_terms(f), rec[0]);
        rc = 0;
    }
    sb_job_destroy(job);
    sb_context_destroy(ctx);
    return rc;
}
