/* The factor job (job.h): options, the driver, the results. */
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include "job_impl.h"
#include "sepbrdf/glsl.h"
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

/* A model spec is NAME[:key=value,...] with NAME a plain identifier, so a
 * NAME with '/' or '.' can only be meant as a file.  Values may hold both
 * ("base=1/0.8/0.3", "roughness=0.5"), hence only the part before ':'. */
static int looks_like_path(const char *spec) {
    size_t n = strcspn(spec, ":");
    return memchr(spec, '/', n) != NULL || memchr(spec, '.', n) != NULL;
}

sb_result_t sb_job_source_open(sb_context_t *ctx, const char *spec, const sb_measured_opts_t *mo, sb_source_t **out) {
    struct stat st;
    if (!spec || !out) return sb_error(ctx, SB_ERR_ARG, "sb_job_source_open: NULL argument");
    if (looks_like_path(spec)) {
        if (stat(spec, &st) != 0) return sb_error(ctx, SB_ERR_IO, "%s: %s", spec, strerror(errno));
        if (!S_ISREG(st.st_mode)) return sb_error(ctx, SB_ERR_IO, "%s: not a regular file", spec);
    }
    if (stat(spec, &st) == 0 && S_ISREG(st.st_mode)) return sb_measured_open(ctx, spec, mo, out, NULL);
    if (stat(spec, &st) == 0 && !S_ISDIR(st.st_mode)) /* a FIFO or device named like a model */
        return sb_error(ctx, SB_ERR_IO, "%s: not a regular file (a device, FIFO or socket is not read)", spec);
    return sb_source_open(ctx, spec, out);
}

/* --param KIND:key=value (report.json's param_spec): the layout's shape
 * for the fit; its res, when given, is -r's (the two must agree). */
static sb_result_t resolve_spec(sb_context_t *ctx, sb_job_t *job, const sb_job_opts_t *in, sb_param_kind_t *kind) {
    sb_param_opts_t *po = &job->spec_shape;
    sb_result_t r = sb_param_parse_spec(ctx, job->o.param, kind, po);
    if (r != SB_OK) return r;
    if ((po->warp[0].kind != SB_WARP_DEFAULT || po->warp[1].kind != SB_WARP_DEFAULT) && in->warp)
        return sb_error(ctx, SB_ERR_ARG, "parameterisation '%s' has its warp; --warp %s asks for another", job->o.param,
                        in->warp);
    if (po->theta_max > 0 && !(in->theta_max_deg > 0)) job->o.theta_max_deg = po->theta_max * 180 / SB_PI;
    double tmax = job->o.theta_max_deg * SB_PI / 180;
    if (po->theta_max > 0 && fabs(po->theta_max - tmax) > 1e-6 * tmax)
        return sb_error(ctx, SB_ERR_ARG, "parameterisation '%s' has its theta_max; --theta-max is %g", job->o.param,
                        tmax * 180 / SB_PI);
    if (po->res && in->res && po->res != in->res)
        return sb_error(ctx, SB_ERR_ARG, "parameterisation '%s' has res=%zu and -r is %zu; give one", job->o.param,
                        po->res, in->res);
    if (po->res) job->o.res = po->res;
    po->res = job->o.res;
    job->shape = po;
    return SB_OK;
}

/* Fill in the defaults of o (job.h) and check the names. */
static sb_result_t resolve(sb_context_t *ctx, sb_job_t *job, const sb_job_opts_t *in, sb_param_kind_t *kind,
                           sb_form_t *form) {
    sb_job_opts_t *o = &job->o;
    *o = *in;
    job->source_spec = sb_strdup(in->source ? in->source : SB_JOB_DEFAULT_SOURCE);
    if (!job->source_spec) return sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    o->source = job->source_spec;
    o->out = NULL; /* not kept: the folder is sb_job_write's argument */
    if (!o->res) o->res = 32;
    if (!o->terms) o->terms = o->max_error > 0 ? (o->res < 32 ? o->res : 32) : 4;
    /* metric_res 0: no grid quadrature (comparable_grid), only when asked */
    if (!(o->theta_max_deg > 0)) o->theta_max_deg = 90;
    if (!o->seed) o->seed = 1;
    *kind = SB_PARAM_IO;
    *form = SB_FORM_F;
    job->is_auto = !o->param || strcmp(o->param, "auto") == 0;
    if (!job->is_auto && strchr(o->param, ':')) {
        sb_result_t r = resolve_spec(ctx, job, in, kind);
        if (r != SB_OK) return r;
    } else if (!job->is_auto && sb_param_kind_parse(o->param, kind) != SB_OK) {
        char names[128] = "auto";
        for (int k = 0; k < SB_PARAM_KIND_COUNT_; k++)
            snprintf(names + strlen(names), sizeof names - strlen(names), ", %s",
                     sb_param_kind_name((sb_param_kind_t)k));
        return sb_error(ctx, SB_ERR_UNKNOWN, "parameterisation '%s' unknown, need one of %s", o->param, names);
    }
    int adaptive;
    sb_warp_kind_t warp;
    if (job_warp_parse(ctx, o->warp, &adaptive, &warp) != SB_OK) return SB_ERR_UNKNOWN;
    if (o->form && sb_form_parse(o->form, form) != SB_OK)
        return sb_error(ctx, SB_ERR_UNKNOWN, "form '%s' unknown, need one of f, cos, cos2", o->form);
    if (job->is_auto) o->param = NULL;
    if (sb_shader_lang_list(ctx, o->shaders, NULL) != SB_OK) return SB_ERR_UNKNOWN;
    sb_result_t rb = job_budget_begin(ctx, job, in);
    if (rb != SB_OK) return rb;
    if (o->sample_only && job->is_auto)
        return sb_error(ctx, SB_ERR_ARG, "sample_only needs one parameterisation, not auto");
    return job_scene_open(ctx, job);
}

/* The driver: choose and fit (job_select), then write when asked.  With
 * own != NULL the job takes the source over (also on failure). */
/* --max-error not reached within the terms allowed: a warning (stderr and
 * report.json), never a quiet success. */
static void job_warn_max_error(sb_job_t *job) {
    if (!(job->o.max_error > 0) || !job->best.est) return;
    size_t J = sb_factors_terms(job->best.f);
    double e = sb_estimate_headline(job->best.est, J < job->best.est->terms ? J : job->best.est->terms);
    if (e <= job->o.max_error) return;
    job_warn(job,
             "--max-error %g not reached: the lowest headline error is %.4g at J = %zu, the most terms allowed "
             "(report.json: max_error_met false); raise --terms or --res",
             job->o.max_error, e, J);
}

static sb_result_t run(sb_context_t *ctx, const sb_source_t *src, sb_source_t *own, const sb_job_opts_t *opts,
                       double t0, int as_auto, sb_job_t **out) {
    sb_job_t *job = calloc(1, sizeof *job);
    if (!job) {
        sb_source_destroy(own);
        return sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    }
    job->t_start = t0;
    job->fit_as_auto = as_auto;
    job->src = job->eval_src = src;
    job->own_src = own;
    sb_param_kind_t kind;
    sb_form_t form;
    /* one OpenBLAS thread but where a large dense matrix is factored
     * (job_factor): its workers, idle between the many small calls of the
     * masked and block fits, spin (sched_yield) on the cores the
     * estimator's and the samplers' threads need */
    int blas = sb_blas_threads_begin();
    job->blas_threads = blas;
    sb_result_t r = resolve(ctx, job, opts, &kind, &form);
    if (r == SB_OK) r = job_candidates(ctx, job, kind, form);
    if (r == SB_OK) r = job->budget ? job_budget_select(ctx, job) : job_select(ctx, job);
    if (r == SB_OK && !job->budget) r = job_warp_refit(ctx, job);
    if (r == SB_OK) r = job_svd_beside(ctx, job);
    if (r == SB_OK) r = job_scene_measure(ctx, job);
    if (r == SB_OK) r = job_cv(ctx, job);
    if (r == SB_OK) {
        job_warn_max_error(job);
        job_warn_weights(job);
        job_warn_support(job);
        job->t.sample_s = job->best.t_sample;
        job->t.factor_s = job->best.t_factor;
        job->t.metric_s = job->best.t_metric;
        job->t.estimate_s = job->t_estimate;
        job->t.total_s = job_now() - job->t_start;
    }
    if (r == SB_OK && opts->out) r = sb_job_write(ctx, job, opts->out);
    sb_blas_threads_end(blas);
    if (r != SB_OK) {
        sb_job_destroy(job);
        return r;
    }
    *out = job;
    return SB_OK;
}

sb_result_t sb_job_run_source(sb_context_t *ctx, const sb_source_t *src, const sb_job_opts_t *opts, sb_job_t **out) {
    if (!src || !opts || !out) return sb_error(ctx, SB_ERR_ARG, "sb_job_run_source: NULL argument");
    *out = NULL;
    return run(ctx, src, NULL, opts, job_now(), 0, out);
}

sb_result_t job_run_as(sb_context_t *ctx, const sb_source_t *src, const sb_job_opts_t *opts, int as_auto,
                       sb_job_t **out) {
    *out = NULL;
    return run(ctx, src, NULL, opts, job_now(), as_auto, out);
}

sb_result_t sb_job_run(sb_context_t *ctx, const sb_job_opts_t *opts, sb_job_t **out) {
    if (!opts || !out) return sb_error(ctx, SB_ERR_ARG, "sb_job_run: NULL argument");
    *out = NULL;
    double t0 = job_now();
    sb_source_t *src = NULL;
    const char *spec = opts->source ? opts->source : SB_JOB_DEFAULT_SOURCE;
    sb_result_t r = sb_job_source_open(ctx, spec, &opts->measured, &src);
    if (r != SB_OK) return r;
    return run(ctx, src, src, opts, t0, 0, out);
}

sb_result_t sb_job_refactor(sb_context_t *ctx, sb_job_t *job, size_t terms) {
    if (!job || !job->best.param || !terms) return sb_error(ctx, SB_ERR_ARG, "sb_job_refactor: no job or no terms");
    size_t mn = job->best.m.rows < job->best.m.cols ? job->best.m.rows : job->best.m.cols;
    if (terms > mn)
        return sb_error(ctx, SB_ERR_RANGE, "%zu terms exceed the %zu rows/columns of %s", terms, mn,
                        sb_param_spec(job->best.param));
    job_level_t lv = {.res = job->o.res,
                      .terms = terms,
                      .metric_res = job->o.metric_res,
                      .fit_tol = job->o.fit_tol,
                      .fit_max_iters = job->o.fit_max_iters};
    free(job->rel_stored);
    job->rel_stored = NULL;
    free(job->svd_beside); /* of the previous terms */
    job->svd_beside = NULL;
    sb_result_t r = job_factor(ctx, job, &lv, job->best.weighted, &job->best);
    if (r == SB_OK) r = job_refine(ctx, job, &lv, &job->best);
    if (r == SB_OK) r = job_scene_measure(ctx, job);
    if (r == SB_OK) job_warn_support(job);
    job->t.factor_s = job->best.t_factor;
    job->t.metric_s = job->best.t_metric;
    job->t.estimate_s = job->best.t_estimate;
    return r;
}

void sb_job_destroy(sb_job_t *job) {
    if (!job) return;
    job_attempt_free(&job->best);
    job_budget_free(job);
    sb_pairs_destroy(job->pairs);
    job_scene_free(job);
    free(job->rel_stored);
    free(job->svd_beside);
    free(job->cv);
    free(job->cv_se);
    for (size_t i = 0; i < job->nwarn; i++)
        free(job->warn[i]);
    free(job->source_spec);
    sb_source_destroy(job->own_src);
    free(job);
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
int sb_job_masked(const sb_job_t *job) { return job ? job_attempt_masked(job, &job->best) : 0; }
void sb_job_stats(const sb_job_t *job, sb_plan_stats_t *out) {
    if (out) *out = job ? job->best.stats : (sb_plan_stats_t){0};
}
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
