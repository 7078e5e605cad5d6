/* The per-candidate pipeline of `factor` and `study`: sample, factor,
 * measure.  Only the public API. */
#include "pipeline.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

/* A model spec is NAME[:key=value,...] with NAME a plain identifier, so a
 * NAME with '/' or '.' can only be meant as a file.  Values may hold both
 * ("base=1/0.8/0.3", "roughness=0.5"), hence only the part before ':'. */
static int looks_like_path(const char *spec) {
    size_t n = strcspn(spec, ":");
    return memchr(spec, '/', n) != NULL || memchr(spec, '.', n) != NULL;
}

sb_result_t pipe_source_open(sb_context_t *ctx, const char *spec, const sb_measured_opts_t *mo, sb_source_t **out) {
    struct stat st;
    if (spec && looks_like_path(spec)) {
        if (stat(spec, &st) != 0) return sb_error(ctx, SB_ERR_IO, "%s: %s", spec, strerror(errno));
        if (!S_ISREG(st.st_mode)) return sb_error(ctx, SB_ERR_IO, "%s: not a regular file", spec);
    }
    if (spec && out && stat(spec, &st) == 0 && S_ISREG(st.st_mode)) return sb_measured_open(ctx, spec, mo, out, NULL);
    return sb_source_open(ctx, spec, out);
}

static void sample_progress(void *user, double fraction) {
    const pipe_opts_t *o = user;
    cli_progress(o->progress_label, o->progress_base + o->progress_span * fraction);
}

sb_result_t attempt_sample(sb_context_t *ctx, const sb_source_t *src, const pipe_opts_t *o, sb_param_kind_t kind,
                           sb_form_t form, attempt_t *a) {
    memset(a, 0, sizeof *a);
    a->zero_fill = o->zero_fill;
    sb_param_opts_t po = {0};
    po.res = o->res;
    po.theta_max = o->theta_max_deg * SB_PI / 180;
    sb_result_t r = sb_param_create(ctx, kind, &po, &a->param);
    if (r != SB_OK) return r;
    size_t rows = sb_param_rows(a->param), cols = sb_param_cols(a->param), mn = rows < cols ? rows : cols;
    if (o->terms > mn)
        return sb_error(ctx, SB_ERR_RANGE,
                        "--terms %zu exceeds the %zu rows/columns of %s; lower --terms or raise --res", o->terms, mn,
                        sb_param_spec(a->param));
    cli_info(2, "sampling %s on %s (%zu x %zu), form %s", sb_source_description(src), sb_param_spec(a->param), rows,
             cols, sb_form_name(form));
    double t0 = cli_now();
    sb_matrix_opts_t mo = {0};
    mo.form = form;
    mo.channels = o->channels;
    if (o->progress_label) {
        mo.progress = sample_progress;
        mo.progress_user = (void *)o;
    }
    if ((r = sb_matrix_build(ctx, src, a->param, &mo, &a->m)) != SB_OK) return r;
    a->t_sample = cli_now() - t0;
    return SB_OK;
}

int attempt_masked(const attempt_t *a) { return a->m.mask != NULL && !a->zero_fill; }

sb_result_t attempt_factor(sb_context_t *ctx, const sb_source_t *src, const pipe_opts_t *o, size_t terms, int weighted,
                           attempt_t *a) {
    sb_factors_destroy(a->f);
    a->f = NULL;
    memset(&a->metric, 0, sizeof a->metric);
    memset(&a->stats, 0, sizeof a->stats);
    a->weighted = weighted;
    sb_plan_opts_t pl = {0};
    pl.terms = terms;
    pl.max_error = o->max_error;
    pl.svd.method = o->method;
    pl.svd.seed = o->seed;
    pl.weighted = weighted;
    pl.zero_fill = o->zero_fill;
    pl.fit_tol = o->fit_tol;
    pl.fit_max_iters = o->fit_max_iters;
    size_t rank = a->m.rows < a->m.cols ? a->m.rows : a->m.cols;
    if (terms > rank)
        return sb_error(ctx, SB_ERR_RANGE,
                        "--terms %zu exceeds the matrix rank limit %zu; lower --terms or raise --res", terms, rank);
    sb_plan_t *plan = NULL;
    sb_result_t r = sb_plan_create_for(ctx, &a->m, &pl, &plan);
    if (r != SB_OK) return r;
    cli_info(2, "factoring %s, %zu terms%s%s", sb_param_spec(a->param), terms, weighted ? ", weighted" : "",
             attempt_masked(a) ? ", masked fit" : "");
    double t1 = cli_now();
    r = sb_plan_execute(plan, &a->m, a->param, &a->f);
    sb_plan_stats(plan, &a->stats);
    sb_plan_destroy(plan);
    if (r != SB_OK) return r;
    double t2 = cli_now();
    if (sb_factors_set_meta(a->f, "source", sb_source_description(src)) != SB_OK)
        return sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    sb_metric_opts_t mo = {0};
    mo.res = o->metric_res;
    if ((r = sb_metric_compute(ctx, src, a->f, a->param, a->m.form, &mo, &a->metric)) != SB_OK) return r;
    a->t_factor = t2 - t1;
    a->t_metric = cli_now() - t2;
    return SB_OK;
}

sb_result_t attempt_run(sb_context_t *ctx, const sb_source_t *src, const pipe_opts_t *o, sb_param_kind_t kind,
                        sb_form_t form, int weighted, attempt_t *a) {
    sb_result_t r = attempt_sample(ctx, src, o, kind, form, a);
    if (r == SB_OK) r = attempt_factor(ctx, src, o, o->terms, weighted, a);
    return r;
}

double attempt_comparable(const attempt_t *a, size_t j) {
    return j >= 1 && j <= a->metric.terms ? a->metric.rel_l2[j - 1] : NAN;
}

double attempt_negative(const attempt_t *a, size_t j) {
    return j >= 1 && j <= a->metric.terms ? a->metric.neg_frac[j - 1] : NAN;
}

void attempt_free(attempt_t *a) {
    sb_factors_destroy(a->f);
    sb_matrix_free(&a->m);
    sb_param_destroy(a->param);
    memset(a, 0, sizeof *a);
}

size_t pipe_candidates(const sb_source_t *src, const pipe_opts_t *o, int param_auto, sb_param_kind_t param,
                       int form_set, sb_form_t form, int weighted, pipe_cand_t *cands) {
    size_t n = 0;
    if (!param_auto) {
        cands[n++] = (pipe_cand_t){param, form, weighted, 0, 0};
        return n;
    }
    for (int k = 0; k < SB_PARAM_KIND_COUNT_; k++) {
        if (!sb_param_kind_applies((sb_param_kind_t)k, sb_source_flags(src))) continue;
        sb_param_t *probe = NULL;
        sb_param_opts_t po = {0};
        po.res = o->res;
        po.theta_max = (o->theta_max_deg > 0 ? o->theta_max_deg : 90) * SB_PI / 180;
        if (sb_param_create(NULL, (sb_param_kind_t)k, &po, &probe) != SB_OK) continue; /* not available */
        sb_param_destroy(probe);
        cands[n++] = (pipe_cand_t){(sb_param_kind_t)k, form_set ? form : SB_FORM_F, 1, 0, 0};
        if (!form_set) cands[n++] = (pipe_cand_t){(sb_param_kind_t)k, SB_FORM_COS2, 1, 0, 0};
    }
    return n;
}

sb_result_t pipe_select(sb_context_t *ctx, const char *cmd, const sb_source_t *src, const pipe_opts_t *o,
                        pipe_cand_t *cands, size_t ncand, attempt_t *best) {
    pipe_opts_t po = *o;
    double best_err = 0;
    memset(best, 0, sizeof *best);
    /* Screening: the comparable metric first on a coarser reference grid
     * (16 cells per axis, 16x fewer pairs), and masked fits stopped early
     * (a sweep gaining less than 1e-3, at most 40 sweeps: they were 3/4 of
     * the default run, and the candidates' errors differ by factors, not
     * digits); the kept one is refitted and measured in full. */
    int screened = 0;
    if (ncand > 1) {
        if (po.metric_res > 16) po.metric_res = 16;
        if (po.fit_tol == 0) po.fit_tol = 1e-3;
        if (po.fit_max_iters == 0) po.fit_max_iters = 40;
        screened = 1;
    }
    for (size_t i = 0; i < ncand; i++) {
        attempt_t a;
        char label[64];
        snprintf(label, sizeof label, "%s/%s %zu/%zu", sb_param_kind_name(cands[i].kind), sb_form_name(cands[i].form),
                 i + 1, ncand);
        po.progress_label = label; /* sampling: the first half of a candidate's bar */
        po.progress_base = (double)i / (double)ncand;
        po.progress_span = 0.5 / (double)ncand;
        sb_result_t r = attempt_sample(ctx, src, &po, cands[i].kind, cands[i].form, &a);
        cli_progress(label, (i + 0.5) / (double)ncand);
        if (r == SB_OK) r = attempt_factor(ctx, src, &po, po.terms, cands[i].weighted, &a);
        cli_progress(label, (i + 1.0) / (double)ncand);
        if (r != SB_OK) {
            attempt_free(&a);
            if (ncand == 1 || (r != SB_ERR_NUMERIC && r != SB_ERR_UNSUPPORTED)) {
                cli_progress_done();
                attempt_free(best);
                return r;
            }
            cli_info(1, "%s: --param auto: %s/%s failed: %s", cmd, sb_param_kind_name(cands[i].kind),
                     sb_form_name(cands[i].form), sb_context_last_error(ctx));
            continue;
        }
        size_t J = sb_factors_terms(a.f);
        /* the metric holds 256 terms at most: compare there beyond */
        cands[i].err = attempt_comparable(&a, J < a.metric.terms ? J : a.metric.terms);
        cands[i].ok = 1;
        cli_info(2, "  %s form %s: comparable error %.4e at J = %zu", sb_param_spec(a.param),
                 sb_form_name(cands[i].form), cands[i].err, J);
        if (!best->f || cands[i].err < best_err) {
            best_err = cands[i].err;
            attempt_free(best);
            *best = a;
        } else {
            attempt_free(&a);
        }
    }
    cli_progress_done();
    if (!best->f)
        return sb_error(ctx, SB_ERR_NUMERIC, "no parameterisation could factor %s", sb_source_description(src));
    if (screened && attempt_masked(best)) {
        double t_sample = best->t_sample;
        sb_result_t r = attempt_factor(ctx, src, o, o->terms, best->weighted, best);
        best->t_sample = t_sample;
        if (r != SB_OK) {
            attempt_free(best);
            return r;
        }
    } else if (po.metric_res != o->metric_res) {
        sb_metric_opts_t mo = {0};
        mo.res = o->metric_res;
        double tm = cli_now();
        sb_result_t r = sb_metric_compute(ctx, src, best->f, best->param, best->m.form, &mo, &best->metric);
        if (r != SB_OK) {
            attempt_free(best);
            return r;
        }
        best->t_metric += cli_now() - tm;
    }
    return SB_OK;
}
