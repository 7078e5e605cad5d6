/* The factor job's shared helpers, at the bottom of job/ (every other file
 * of the folder may call them; they call none): the clock, progress,
 * warnings, and the accessors of the results (job.h). */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <time.h>

#include "job_impl.h"
#include "util/internal.h"

double job_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

void job_progress(const sb_job_t *job, const char *label, double fraction) {
    if (job->o.progress && label) job->o.progress(job->o.progress_user, label, fraction);
}

void job_warn(sb_job_t *job, const char *fmt, ...) {
    if (job->nwarn == JOB_MAX_WARN) return;
    char buf[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    if ((job->warn[job->nwarn] = sb_strdup(buf)) != NULL) job->nwarn++;
}

/* The accessors take a NULL job (issue 34): NULL pointers, "" strings, 0
 * counts and flags, SB_FORM_F, NAN errors, zeroed structs. */
const sb_source_t *sb_job_source(const sb_job_t *job) { return job ? job->src : NULL; }
const char *sb_job_source_spec(const sb_job_t *job) { return job && job->o.source ? job->o.source : ""; }
const sb_factors_t *sb_job_factors(const sb_job_t *job) { return job ? job->best.f : NULL; }
const sb_param_t *sb_job_param(const sb_job_t *job) { return job ? job->best.param : NULL; }
const sb_matrix_t *sb_job_matrix(const sb_job_t *job) { return job ? &job->best.m : NULL; }
sb_form_t sb_job_form(const sb_job_t *job) { return job ? job->best.m.form : SB_FORM_F; }
int sb_job_weighted(const sb_job_t *job) { return job ? job->best.weighted : 0; }
int job_fit_converged(const job_attempt_t *a) {
    return a->stats.fit_converged || (a->f && a->conv_terms >= sb_factors_terms(a->f));
}

void sb_job_stats(const sb_job_t *job, sb_plan_stats_t *out) {
    if (out) *out = job ? job->best.stats : (sb_plan_stats_t){0};
    if (out && job) out->fit_converged = job_fit_converged(&job->best); /* of the terms written */
}
int sb_job_fit_early_stop(const sb_job_t *job) { return job ? job->best.early_stop : 0; }
const sb_metric_t *sb_job_metric(const sb_job_t *job) { return job ? &job->best.metric : NULL; }
int sb_job_auto(const sb_job_t *job) { return job ? job->is_auto : 0; }
size_t sb_job_candidate_count(const sb_job_t *job) { return job ? job->ncand : 0; }
const sb_job_candidate_t *sb_job_candidate(const sb_job_t *job, size_t i) {
    return job && i < job->ncand ? &job->cands[i] : NULL;
}
void sb_job_timings(const sb_job_t *job, sb_job_timings_t *out) {
    if (out) *out = job ? job->t : (sb_job_timings_t){0};
}
size_t sb_job_warning_count(const sb_job_t *job) { return job ? job->nwarn : 0; }
const char *sb_job_warning(const sb_job_t *job, size_t i) { return job && i < job->nwarn ? job->warn[i] : NULL; }

const sb_estimate_t *sb_job_estimate(const sb_job_t *job) { return job ? job->best.est : NULL; }

double sb_job_headline(const sb_job_t *job, size_t j) {
    return job && job->best.est ? sb_estimate_headline(job->best.est, j) : NAN;
}

double sb_job_comparable(const sb_job_t *job, size_t j) {
    const sb_estimate_t *e = job ? job->best.est : NULL;
    return e && j >= 1 && j <= e->terms ? e->rel[j - 1][SB_EST_FCOS2][SB_CH_ALL] : NAN;
}

double sb_job_negative(const sb_job_t *job, size_t j) {
    const sb_estimate_t *e = job ? job->best.est : NULL;
    return e && j >= 1 && j <= e->terms ? e->neg_frac[j - 1] : NAN;
}

double sb_job_rel_stored(const sb_job_t *job, size_t j, size_t c) {
    if (!job) return NAN;
    size_t J = sb_factors_terms(job->best.f);
    return job->rel_stored && j >= 1 && j <= J && c <= SB_CH_ALL ? job->rel_stored[sb_err_at(j - 1, c)] : NAN;
}
