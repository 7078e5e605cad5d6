/* The SVD beside non-negative factors (job.h sb_job_svd_headline): what
 * positivity costs at each J', measured as `factor` measures its own fit
 * (the run itself, a whole job beside this one, is job_svd_beside in
 * job.c); which methods are non-negative. */
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

double sb_job_svd_headline(const sb_job_t *job, size_t j) {
    return job && job->svd_beside && j >= 1 && j <= job->svd_beside_terms ? job->svd_beside[JOB_BESIDE_STRIDE * (j - 1)]
                                                                          : NAN;
}

double sb_job_svd_rel_rms(const sb_job_t *job, size_t j) {
    return job && job->svd_beside && j >= 1 && j <= job->svd_beside_terms
               ? job->svd_beside[JOB_BESIDE_STRIDE * (j - 1) + 1]
               : NAN;
}

double job_svd_headline_channel(const sb_job_t *job, size_t j, int c) {
    return job && job->svd_beside && j >= 1 && j <= job->svd_beside_terms && c >= 0 && c < 3
               ? job->svd_beside[JOB_BESIDE_STRIDE * (j - 1) + 2 + c]
               : NAN;
}
