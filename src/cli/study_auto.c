/* sepbrdf study --param auto (the default): what `factor` builds at
 * every J studied. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "pipeline.h"
#include "study.h"

/* J terms exceed every layout's rows at this resolution (-r 3: 9): the
 * rows of fewer terms are kept and the Js beyond said skipped, where the
 * whole run failed and nothing was written (sixth outside pass).  1 if
 * that was the failure. */
static int study_beyond_rows(sb_context_t *ctx, sb_result_t res, run_t *r, size_t J, size_t jmax, const char *param) {
    const char *detail = sb_context_last_error(ctx);
    if (res != SB_ERR_RANGE || !detail || !strstr(detail, " terms exceed")) return 0;
    char msg[1024];
    snprintf(msg, sizeof msg, "J = %zu..%zu skipped: %s", J, jmax, detail);
    cli_error("study", "warning: %s on %s: %s", r->spec, param ? param : "auto", msg);
    if (r->nwarn < sizeof r->warn / sizeof r->warn[0]) r->warn[r->nwarn++] = study_dup(msg);
    return 1;
}

/* An auto run, or a layout named alone: `factor`'s whole job at every
 * studied J (its choice of layout, form, weighting and warps depends on
 * J, and term weights and texel fits are made for J), the row of J from
 * each. */
void study_run_auto(sb_context_t *ctx, const sb_source_t *src, const study_opts_t *o, run_t *r, const char *label,
                    double base, double span) {
    sb_job_opts_t jo = o->job;
    jo.param = r->kind == STUDY_AUTO ? NULL : sb_param_kind_name((sb_param_kind_t)r->kind);
    sb_result_t res = (r->r = calloc(o->nj, sizeof *r->r)) ? SB_OK : sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    size_t done = 0, J = 0;
    r->converged = 1;
    for (J = 1; J <= o->jmax && res == SB_OK; J++) {
        if (!o->want_j[J]) continue;
        cli_progress(label, base + span * (double)done++ / (double)o->nj);
        jo.terms = J;
        sb_job_t *job = NULL;
        sb_context_clear_error(ctx);
        if ((res = sb_job_run_source(ctx, src, &jo, &job)) == SB_OK) {
            sb_job_timings_t t;
            sb_job_timings(job, &t);
            study_take_rows(r, o, job, J, 1);
            row_t *w = &r->r[r->nr - 1];
            w->spec = study_dup(sb_param_spec(sb_job_param(job)));
            w->form = sb_form_name(sb_job_form(job));
            w->weighted = sb_job_weighted(job);
            w->t_factor = t.total_s;
            w->t_metric = 0;
            free(r->param_spec);
            r->param_spec = study_dup(w->spec);
            r->rows = sb_job_matrix(job)->rows;
            r->cols = sb_job_matrix(job)->cols;
            r->masked = 1; /* one fit per J */
        }
        if (J == o->jmax || res != SB_OK) study_run_warnings(r, job, jo.param ? jo.param : "auto");
        sb_job_destroy(job);
        if (res != SB_OK && r->nr > 0 && study_beyond_rows(ctx, res, r, J, o->jmax, jo.param)) {
            res = SB_OK; /* the rows of fewer terms stand */
            break;
        }
    }
    if (res == SB_OK && o->nmf && jo.param) { /* a layout named: its non-negative fits beside */
        jo.terms = o->jmax;
        study_nmf_rows(ctx, src, r, &jo);
    }
    if (res != SB_OK) {
        char msg[1024];
        cli_job_message(msg, sizeof msg, ctx, res, J - 1);
        study_run_fail(r, msg);
        return;
    }
    r->ok = 1;
}
