/* The SVD beside non-negative factors (job.h sb_job_svd_headline): what
 * positivity costs at each J', measured as `factor` measures its own fit. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "job_impl.h"
#include "sepbrdf/solver.h"

int job_nonneg_method(const char *name) {
    for (size_t i = 0; name && i < sb_solver_count(); i++)
        if (strcmp(sb_solver_name(i), name) == 0) return (sb_solver_caps(i) & SB_CAP_NONNEG) != 0;
    return 0;
}

/* The same run with the default method (an SVD; a masked fit where cells
 * are excluded) on the kept layout and warp, form and weighting, with
 * the kept number of terms: its headline and rel_rms per J'.  A failure
 * is a warning: the non-negative fit stands on its own. */
sb_result_t job_svd_beside(sb_context_t *ctx, sb_job_t *job) {
    if (!job_nonneg_method(sb_method_name(job->o.method)) || job->o.sample_only) return SB_OK;
    const job_attempt_t *a = &job->best;
    size_t J = sb_factors_terms(a->f);
    sb_job_opts_t o = job->o;
    o.method = SB_METHOD_AUTO;
    o.param = sb_param_spec(a->param); /* the same layout and warp, none tried */
    o.warp = NULL;
    o.form = sb_form_name(a->m.form);
    o.weighted = a->weighted;
    o.terms = J;
    o.max_error = 0;
    o.out = NULL;
    sb_job_t *svd = NULL;
    sb_result_t r = job_run_as(ctx, job->src, &o, job->is_auto, &svd); /* fitted as the default run fits it */
    if (r == SB_ERR_NOMEM) return r;
    free(job->svd_beside);
    job->svd_beside = r == SB_OK ? malloc(2 * J * sizeof *job->svd_beside) : NULL;
    if (r != SB_OK) {
        job_warn(job, "no SVD beside the non-negative fit: %s", sb_context_last_error(ctx));
        return SB_OK;
    }
    if (!job->svd_beside) {
        sb_job_destroy(svd);
        return sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    }
    const sb_factor_errors_t *e = sb_factors_errors(sb_job_factors(svd));
    size_t have = sb_factors_terms(sb_job_factors(svd));
    for (size_t k = 0; k < J; k++) {
        job->svd_beside[2 * k] = sb_job_headline(svd, k + 1);
        job->svd_beside[2 * k + 1] = k < have ? e->rel_rms[sb_err_at(k, SB_CH_ALL)] : NAN;
    }
    job->svd_beside_terms = J;
    const char *m = sb_factors_get_meta(sb_job_factors(svd), "method");
    snprintf(job->svd_method, sizeof job->svd_method, "%s", m ? m : "");
    job->svd_s = svd->t.total_s;
    sb_job_destroy(svd);
    return SB_OK;
}

double sb_job_svd_headline(const sb_job_t *job, size_t j) {
    return job && job->svd_beside && j >= 1 && j <= job->svd_beside_terms ? job->svd_beside[2 * (j - 1)] : NAN;
}

double sb_job_svd_rel_rms(const sb_job_t *job, size_t j) {
    return job && job->svd_beside && j >= 1 && j <= job->svd_beside_terms ? job->svd_beside[2 * (j - 1) + 1] : NAN;
}
