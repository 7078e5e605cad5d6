/* The layout of the structs the Python package (python/sepbrdf/_lib.py)
 * declares with ctypes, as this compiler lays them out: one line per
 * field, "struct field offset size", checked by python/tests. */
#include <stddef.h>
#include <stdio.h>

#include "sepbrdf/sepbrdf.h"

#define FIELD(T, f) printf("%s %s %zu %zu\n", #T, #f, offsetof(T, f), sizeof(((T *)0)->f))

int main(void) {
    FIELD(sb_measured_opts_t, format);
    FIELD(sb_measured_opts_t, interp);
    FIELD(sb_measured_opts_t, neighbours);
    FIELD(sb_measured_opts_t, radius);
    FIELD(sb_measured_opts_t, white);
    FIELD(sb_measured_opts_t, gamut);
    FIELD(sb_job_opts_t, size);
    FIELD(sb_job_opts_t, source);
    FIELD(sb_job_opts_t, measured);
    FIELD(sb_job_opts_t, param);
    FIELD(sb_job_opts_t, form);
    FIELD(sb_job_opts_t, warp);
    FIELD(sb_job_opts_t, weighted);
    FIELD(sb_job_opts_t, scene);
    FIELD(sb_job_opts_t, zero_fill);
    FIELD(sb_job_opts_t, res);
    FIELD(sb_job_opts_t, terms);
    FIELD(sb_job_opts_t, metric_res);
    FIELD(sb_job_opts_t, max_error);
    FIELD(sb_job_opts_t, theta_max_deg);
    FIELD(sb_job_opts_t, method);
    FIELD(sb_job_opts_t, seed);
    FIELD(sb_job_opts_t, channels);
    FIELD(sb_job_opts_t, fit_max_iters);
    FIELD(sb_job_opts_t, fit_tol);
    FIELD(sb_job_opts_t, plain_terms);
    FIELD(sb_job_opts_t, half);
    FIELD(sb_job_opts_t, previews);
    FIELD(sb_job_opts_t, sample_only);
    FIELD(sb_job_opts_t, budget);
    FIELD(sb_job_opts_t, out);
    FIELD(sb_job_opts_t, progress);
    FIELD(sb_job_opts_t, progress_user);
    FIELD(sb_job_opts_t, shaders);
    FIELD(sb_source_ops_t, eval);
    FIELD(sb_source_ops_t, destroy);
    printf("sizeof sb_measured_opts_t %zu\nsizeof sb_job_opts_t %zu\nsizeof sb_source_ops_t %zu\n",
           sizeof(sb_measured_opts_t), sizeof(sb_job_opts_t), sizeof(sb_source_ops_t));
    return 0;
}
