/* The kept fit's stored factors (job_quantized): quantised once for the
 * estimate, the bands' own pairs and the written set's errors. */
#include <string.h>

#include "factor/errors.h"
#include "job_impl.h"
#include "sepbrdf/exr.h"

sb_result_t job_quantized(sb_context_t *ctx, sb_job_t *job, sb_factors_t *f, const sb_factors_t **q) {
    unsigned long long stamp = sb_factors_stamp(f);
    int k = 0;
    *q = NULL;
    while (k < 2 && !(job->quant[k] && job->quant_stamp[k] == stamp && job->quant_half[k] == job->o.half))
        k++;
    if (k == 2) { /* the older slot */
        sb_exr_opts_t eo = {job->o.half};
        k = !job->quant_last;
        sb_factors_destroy(job->quant[k]);
        job->quant[k] = NULL;
        sb_result_t r = sb_factors_quantize(ctx, f, &eo, &job->quant[k], NULL);
        if (r != SB_OK) return r;
        job->quant_stamp[k] = stamp;
        job->quant_half[k] = job->o.half;
    } else { /* the errors as f has them now, as sb_factors_quantize copies them */
        const sb_factor_errors_t *e = sb_factors_errors(f);
        sb_factor_errors_t *eq = sb_factors_errors_mut(job->quant[k]);
        size_t n = sb_err_at(sb_factors_terms(f), 0);
        memcpy(eq->rel_rms, e->rel_rms, n * sizeof *e->rel_rms);
        memcpy(eq->max_abs, e->max_abs, n * sizeof *e->max_abs);
        memcpy(eq->norm, e->norm, sizeof eq->norm);
    }
    job->quant_last = k;
    *q = job->quant[k];
    return SB_OK;
}
