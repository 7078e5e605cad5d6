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
#include "solve/solver.h"
#include "util/ctx_memo.h"
#include "util/internal.h"
#include "util/parallel.h"

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
        for (int k = 0; k < (int)sb_param_kind_count(); k++)
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
    /* a layout named alone: what auto would fit on it (job_candidates) */
    job->layout_auto = !job->is_auto && !strchr(o->param, ':') && !o->sample_only;
    if (job->layout_auto) job->fit_as_auto = job->named_alone = 1;
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
    size_t jb = job_cv_fewer(job, J); /* a scattered table: do more terms predict its measurements worse? */
    char hint[256] = "raise --terms or --res";
    if (jb)
        snprintf(hint, sizeof hint,
                 "more terms lower it only against the interpolation between the measurements: at those left out "
                 "of the fit %zu terms err least (%.3g, against %.3g at J = %zu)",
                 jb, sb_job_cv(job, jb, NULL, NULL), sb_job_cv(job, J, NULL, NULL), J);
    job_warn(job,
             "--max-error %g not reached: the lowest headline error is %.4g at J = %zu, the most terms allowed "
             "(report.json: max_error_met false); %s",
             job->o.max_error, e, J, hint);
}

/* Fewer terms than asked without --max-error: the kept layout holds fewer
 * rows (job_terms_capped: vndf's theta_i slices); said, never quiet. */
static void job_warn_fewer_terms(sb_job_t *job) {
    const sb_matrix_t *m = &job->best.m;
    size_t J = job->best.f ? sb_factors_terms(job->best.f) : 0, mn = m->rows < m->cols ? m->rows : m->cols;
    if (job->o.max_error > 0 || !J || J >= job->o.terms || J != mn ||
        !job_terms_capped(job, sb_param_kind(job->best.param)))
        return;
    job_warn(job,
             "%zu terms fitted, not the %zu asked: layout %s has %zu rows (an RGL file's theta_i slices), each "
             "term beyond them would be zero",
             J, job->o.terms, sb_param_kind_name(sb_param_kind(job->best.param)), J);
}

/* The same run with the default method (an SVD; a masked fit where cells
 * are excluded) on the kept layout and warp, form and weighting, with
 * the kept number of terms: its headline and rel_rms per J'.  A failure
 * is a warning: the non-negative fit stands on its own. */
static sb_result_t job_svd_beside(sb_context_t *ctx, sb_job_t *job) {
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
    /* fitted as the default run fits it; its headline alone is read */
    sb_result_t r = job_run_as(ctx, job->src, &o, (job->is_auto || job->fit_as_auto) | JOB_RUN_HEADLINE, &svd);
    if (r == SB_ERR_NOMEM) return r;
    free(job->svd_beside);
    job->svd_beside = r == SB_OK ? malloc(JOB_BESIDE_STRIDE * J * sizeof *job->svd_beside) : NULL;
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
    const sb_estimate_t *est = sb_job_estimate(svd);
    for (size_t k = 0; k < J; k++) {
        double *b = job->svd_beside + JOB_BESIDE_STRIDE * k;
        b[0] = sb_job_headline(svd, k + 1);
        b[1] = k < have ? e->rel_rms[sb_err_at(k, SB_CH_ALL)] : NAN;
        for (int c = 0; c < 3; c++) /* the channel's headline (NAN: not factored) */
            b[2 + c] = est && k < est->terms && sb_matrix_has(&svd->best.m, c) ? est->rel[k][SB_EST_FCOS][c] : NAN;
    }
    job->svd_beside_terms = J;
    const char *m = sb_factors_get_meta(sb_job_factors(svd), "method");
    snprintf(job->svd_method, sizeof job->svd_method, "%s", m ? m : "");
    job->svd_s = svd->t.total_s;
    sb_job_destroy(svd);
    return SB_OK;
}

/* A layout named alone that leaves more than JOB_EXPLICIT_POOR of the
 * headline at J (hd --form f on an RGL file, whose f reaches 1e10 at the
 * horizon: 0.9998) warns.  Where the source carries the tables of a layout
 * built on them (an RGL file's own grid, vndf) and the named one is not
 * that layout, that layout is fitted beside it as auto fits it, and the
 * warning names its form and headline where it does better by half: a
 * fit on the file's nodes, cheap.  Elsewhere the warning points to
 * --param auto without running it: auto beside `--param io -r 64 -J 8`
 * on the default source cost 2.5 s CPU against 0.16 s for io itself;
 * under --budget too (the budget's J and R stand).  A failure of the run beside is no warning: the fit asked for
 * stands. */
static sb_result_t job_auto_beside(sb_context_t *ctx, sb_job_t *job) {
    const job_attempt_t *a = &job->best;
    size_t J = a->f ? sb_factors_terms(a->f) : 0;
    double h = J && a->est ? sb_estimate_headline(a->est, J < a->est->terms ? J : a->est->terms) : NAN;
    if (!job->named_alone || job->headline_only || job->no_scene_guard || job->scene || !(h > JOB_EXPLICIT_POOR))
        return SB_OK;
    int own = -1; /* a layout on the source's own tables, not the named one */
    if (sb_source_layout_tables(job->src) && !(sb_param_caps(a->param) & SB_CAP_TABLES))
        for (size_t k = 0; k < sb_param_kind_count() && own < 0; k++)
            if (sb_param_kind_caps((sb_param_kind_t)k) & SB_CAP_TABLES) own = (int)k;
    const char *named = sb_param_name(a->param);
    if (own < 0 || job->o.method == SB_METHOD_STREAM || job->budget) { /* under --budget: no fit beside */
        job_warn(job,
                 "%s leaves a headline error of %.4g %% at J = %zu: it cannot reproduce this source; --param auto "
                 "chooses the layout, form, weighting and warp by the headline%s",
                 named, 100 * h, J, job->budget ? " within the same budget" : "");
        return SB_OK;
    }
    sb_job_opts_t o = job->o;
    o.param = sb_param_kind_name((sb_param_kind_t)own); /* named alone: fitted as auto fits it */
    o.form = NULL;
    o.weighted = 0;
    o.warp = NULL;
    o.out = NULL;
    /* at most its rows (vndf: the file's theta_i slices), as auto fits it */
    size_t mn = job_layout_min_side(job, (sb_param_kind_t)own, job->o.res, NULL);
    o.terms = mn && mn < J ? mn : J;
    o.max_error = 0;
    o.progress = NULL;
    sb_job_t *au = NULL;
    sb_result_t r = job_run_as(ctx, job->src, &o, 1 | JOB_RUN_HEADLINE, &au);
    if (r == SB_ERR_NOMEM) return r;
    double e = r == SB_OK ? sb_job_headline(au, o.terms) : NAN;
    if (r == SB_OK && 2 * e < h)
        job_warn(job,
                 "%s leaves a headline error of %.4g %% at J = %zu: it cannot reproduce this source; --param %s "
                 "(the file's own grid, as auto fits it) keeps form %s, headline %.4g %% at J = %zu",
                 named, 100 * h, J, o.param, sb_form_name(au->best.m.form), 100 * e, o.terms);
    else
        job_warn(job,
                 "%s leaves a headline error of %.4g %% at J = %zu: it cannot reproduce this source; --param auto "
                 "chooses the layout, form, weighting and warp by the headline",
                 named, 100 * h, J);
    sb_job_destroy(au);
    sb_context_clear_error(ctx);
    return SB_OK;
}

/* Under --method stream every fit at the requested R passes over the
 * source block by block: anisotropic GGX, io, R = 128, J = 8 took 285 s
 * CPU for a layout named alone in two forms (cos kept, 0.865), 169 s for
 * one.  The two forms are ranked by the same named layout fitted dense at
 * R = JOB_STREAM_RANK_RES (both forms, as a named layout is fitted: 0.8 s
 * there) and only the better is fitted at R; the screen at R = 16 alone
 * ranked f first there (f 1.086, cos 1.096), which is 0.973 at R = 128. */
#define JOB_STREAM_RANK_RES 32
static sb_result_t stream_one_form(sb_context_t *ctx, sb_job_t *job) {
    sb_job_candidate_t *a = &job->cands[0], *b = &job->cands[1];
    if (job->o.method != SB_METHOD_STREAM || !job->layout_auto || job->budget || job->o.max_error > 0 ||
        job->ncand != 2 || a->kind != b->kind || a->form == b->form || a->why[0] || b->why[0])
        return SB_OK;
    sb_job_opts_t o = job->o;
    o.method = SB_METHOD_AUTO;
    o.res = job->o.res < JOB_STREAM_RANK_RES ? job->o.res : JOB_STREAM_RANK_RES;
    o.out = NULL;
    o.progress = NULL;
    sb_job_t *au = NULL;
    sb_result_t r = job_run_as(ctx, job->src, &o, 1 | JOB_RUN_HEADLINE, &au);
    if (r == SB_ERR_NOMEM) return r;
    if (r == SB_OK && (au->best.m.form == a->form || au->best.m.form == b->form)) {
        if (au->best.m.form == b->form) *a = *b;
        job->ncand = 1;
    }
    sb_job_destroy(au);
    sb_context_clear_error(ctx);
    return SB_OK;
}

/* The job's options at J terms, beside it, into *out: without the scene
 * (floor < 0) or with it at floor=floor (job_scene_guard.c). */
static sb_result_t scene_beside(sb_context_t *ctx, const sb_job_t *job, size_t J, double floor, sb_job_t **out) {
    char spec[1100];
    sb_job_opts_t o = job->o;
    o.scene = NULL;
    if (floor >= 0) {
        if ((size_t)snprintf(spec, sizeof spec, "%s;floor=%g", sb_scene_spec(job->scene), floor) >= sizeof spec)
            return sb_error(ctx, SB_ERR_RANGE, "scene: spec too long for a floor beside it");
        o.scene = spec;
    }
    o.out = NULL;
    o.terms = J;
    o.max_error = 0;
    o.budget = 0;
    o.cv_folds = 1; /* none: only the fit is wanted */
    o.progress = NULL;
    return job_run_as(ctx, job->src, &o, job->fit_as_auto | JOB_RUN_NO_GUARD, out);
}

/* A scene fit far worse than the unweighted one over the whole domain
 * replaced (job_scene_guard.c): the unweighted fit, then the floors in
 * the order job_scene_next_floor gives them. */
static sb_result_t job_scene_guard(sb_context_t *ctx, sb_job_t *job) {
    if (!job_scene_guarded(job)) return SB_OK;
    size_t J = sb_factors_terms(job->best.f);
    sb_job_t *u = NULL, *v = NULL;
    sb_result_t r = scene_beside(ctx, job, J, -1, &u);
    if (r != SB_OK) {
        if (r != SB_ERR_NOMEM) job_warn(job, "no unweighted fit beside the scene's: %s", sb_context_last_error(ctx));
        return r == SB_ERR_NOMEM ? r : SB_OK;
    }
    int replace = 0;
    double floor = 0;
    if ((r = job_scene_reference(ctx, job, u, &replace)) != SB_OK || !replace) {
        sb_job_destroy(u);
        return r;
    }
    job_floor_walk_t k = {0};
    double x = replace == JOB_SCENE_OUTSIDE ? job_scene_next_floor(job, NULL, &k) : -1;
    while (x >= 0 && r == SB_OK) {
        sb_job_t *w = NULL;
        if ((r = scene_beside(ctx, job, J, x, &w)) != SB_ERR_NOMEM) r = SB_OK;
        int keep = job_scene_better(job, v, w, job_scene_walk_bound(&k));
        double next = job_scene_next_floor(job, w, &k);
        sb_job_destroy(keep ? v : w);
        if (keep) v = w, floor = x;
        x = next;
    }
    if (r == SB_OK) r = job_scene_replace(ctx, job, u, v, floor, replace);
    sb_job_destroy(u);
    sb_job_destroy(v);
    return r;
}

static sb_result_t run(sb_context_t *ctx, const sb_source_t *src, sb_source_t *own, const sb_job_opts_t *opts,
                       double t0, int as_auto, sb_job_t **out) {
    sb_job_t *job = calloc(1, sizeof *job);
    if (!job) {
        sb_source_destroy(own);
        return sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    }
    job->t_start = t0;
    /* fits repeated within the run made once: the masked fit beside nmf's
     * channels, a named layout's fit finished (three of the acrylic's 39
     * fits under `--param io -r 16`).  Under auto with another method none
     * repeated (0 of 60 fits of the Cornell acrylic, 48 of a MERL file,
     * 20 of the ALTA retro, 12 of the default gold): the memo's keys, the
     * matrix of every fit, cost 21 MB and 2-3 % of the acrylic's CPU. */
    int memo = (opts->param && strcmp(opts->param, "auto") != 0) || job_nonneg_method(sb_method_name(opts->method));
    if (memo) sb_ctx_memo_open(ctx);
    double ts = job_now();
    job->stage_s[0] = ts - t0; /* the source opened (sb_job_run) */
    job->fit_as_auto = as_auto & 1;
    job->no_scene_guard = (as_auto & JOB_RUN_NO_GUARD) != 0;
    job->headline_only = (as_auto & JOB_RUN_HEADLINE) != 0;
    job->src = src;
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
    if (r == SB_OK) r = job_check_values(ctx, job);
    if (r == SB_OK) r = job_candidates(ctx, job, kind, form);
    int cap_was = sb_thread_cap(r == SB_OK ? job_thread_cap(job) : 0);
    if (r == SB_OK) r = stream_one_form(ctx, job);
    if (r == SB_OK) r = job->budget ? job_budget_select(ctx, job) : job_select(ctx, job);
    if (r == SB_OK && !job->budget) r = job_warp_refit(ctx, job);
    double t1 = job_now();
    if (r == SB_OK) r = job_svd_beside(ctx, job);
    if (r == SB_OK) r = job_nonneg_refit(ctx, job);
    if (r == SB_OK) r = job_auto_beside(ctx, job);
    double t2 = job_now();
    if (r == SB_OK) r = job_scene_measure(ctx, job);
    if (r == SB_OK) r = job_scene_guard(ctx, job);
    double t3 = job_now();
    if (r == SB_OK && !job->headline_only) r = job_cv(ctx, job);
    if (r == SB_OK && !job->headline_only) r = job_band_pairs_measure(ctx, job, &job->best);
    double t4 = job_now();
    job->stage_s[1] = t1 - ts, job->stage_s[2] = t2 - t1, job->stage_s[3] = t3 - t2, job->stage_s[4] = t4 - t3;
    if (r == SB_OK) {
        job_warn_max_error(job);
        job_warn_fewer_terms(job);
        job_warn_weights(job);
        double t5 = job_now();
        if (!job->headline_only)
            job_warn_support(job); /* the errors at a measured table's samples: seconds for a MERL file */
        job->stage_s[5] = job_now() - t5;
        job->t.sample_s = job->best.t_sample;
        job->t.factor_s = job->best.t_factor;
        job->t.metric_s = job->best.t_metric;
        job->t.estimate_s = job->t_estimate;
        job->t.total_s = job_now() - job->t_start;
    }
    if (r == SB_OK && opts->out) r = sb_job_write(ctx, job, opts->out);
    sb_thread_cap(cap_was);
    sb_blas_threads_end(blas);
    if (memo) sb_ctx_memo_close(ctx);
    if (r != SB_OK) {
        sb_job_destroy(job);
        return r;
    }
    *out = job;
    return SB_OK;
}

/* The caller's options as this library's struct (job.h: versioned). */
static sb_result_t opts_take(sb_context_t *ctx, const sb_job_opts_t *in, sb_job_opts_t *o) {
    sb_result_t r = sb_opts_take(ctx, in, in->size, SB_JOB_OPTS_SIZE_0_1, o, sizeof *o, "job: options");
    o->size = sizeof *o;
    return r;
}

sb_result_t sb_job_run_source(sb_context_t *ctx, const sb_source_t *src, const sb_job_opts_t *opts, sb_job_t **out) {
    if (!src || !opts || !out) return sb_error(ctx, SB_ERR_ARG, "sb_job_run_source: NULL argument");
    *out = NULL;
    sb_job_opts_t o;
    sb_result_t r = opts_take(ctx, opts, &o);
    return r == SB_OK ? run(ctx, src, NULL, &o, job_now(), 0, out) : r;
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
    sb_job_opts_t o;
    sb_result_t r = opts_take(ctx, opts, &o);
    if (r != SB_OK) return r;
    const char *spec = o.source ? o.source : SB_JOB_DEFAULT_SOURCE;
    r = sb_job_source_open(ctx, spec, &o.measured, &src);
    if (r != SB_OK) return r;
    return run(ctx, src, src, &o, t0, 0, out);
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
    job->se_f = NULL;      /* the sample errors were those of the previous terms */
    free(job->svd_beside); /* of the previous terms */
    job->svd_beside = NULL;
    sb_result_t r = job_factor(ctx, job, &lv, job->best.weighted, &job->best);
    if (r == SB_OK) r = job_refine(ctx, job, &lv, &job->best);
    if (r == SB_OK) r = job_scene_measure(ctx, job);
    if (r == SB_OK) r = job_band_pairs_measure(ctx, job, &job->best);
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
    sb_pairs_destroy(job->band_pairs);
    sb_pairs_destroy(job->cone_pairs);
    job_scene_free(job);
    free(job->rel_stored);
    sb_factors_destroy(job->quant[0]);
    sb_factors_destroy(job->quant[1]);
    free(job->svd_beside);
    sb_nmf_carry_destroy(job->nonneg_carry);
    free(job->cv); /* cv_se, cv_pooled, cv_max, cv_median with it */
    for (size_t i = 0; i < job->nwarn; i++)
        free(job->warn[i]);
    free(job->source_spec);
    sb_source_destroy(job->own_src);
    free(job);
}

/* A masked fit kept (the accessors of job_base.c take a NULL job too). */
int sb_job_masked(const sb_job_t *job) { return job ? job_attempt_masked(job, &job->best) : 0; }
