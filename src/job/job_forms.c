/* A layout named alone in two forms (job_select, job_impl.h): both fitted
 * at the requested settings, only the better finished. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "job_impl.h"

/* The headline at the J the attempt kept (as job_screen.c ranks them). */
static double headline_j(const job_attempt_t *a) {
    size_t J = sb_factors_terms(a->f);
    return sb_estimate_headline(a->est, J < a->est->terms ? J : a->est->terms);
}

/* A form's fit of named_pair: the attempt, its FINISH_* flags, whether
 * job_fit_finish is still to run on it, its result. */
typedef struct {
    job_attempt_t a;
    unsigned pending;
    int unfinished;
    sb_result_t r;
} form_fit_t;

/* Candidate c fitted into o (before job_fit_finish when `finish` is 0, else
 * finished); a failure is recorded in c. */
static sb_result_t pair_step(sb_context_t *ctx, sb_job_t *job, sb_job_candidate_t *c, form_fit_t *o, int finish) {
    double t1 = job_now();
    job->best = o->a;
    job->fit_pending = o->pending;
    if (!finish) {
        memset(&job->best, 0, sizeof job->best);
        o->r = job_fit_kept_unfinished(ctx, job, c, &o->unfinished);
    } else if (o->unfinished) {
        o->unfinished = 0;
        if ((o->r = job_fit_finish(ctx, job)) != SB_OK) job_attempt_free(&job->best);
    }
    o->a = job->best;
    o->pending = job->fit_pending;
    memset(&job->best, 0, sizeof job->best);
    job->fit_pending = 0;
    c->time_s += job_now() - t1;
    if (o->r != SB_OK) {
        c->ok = 0;
        c->result = o->r;
        snprintf(c->why, sizeof c->why, "%s", sb_context_last_error(ctx));
    }
    return o->r;
}

/* A form's fit behind the other's, both stopped early, by more than this
 * factor in the headline at J is not finished (job_fit_finish: the
 * converged fit tried, refinement): the converged fit gained 1.42x at
 * most where it was kept (GGX 0.3, iso, J = 4: 2.7 % -> 1.9 %). */
#define JOB_FORM_FINISH_MARGIN 1.5

/* A layout named alone whose screening kept two forms (f and cos) of it:
 * the coarse screen can rank them wrongly at the requested R (GGX 0.3 on
 * hd: cos screened first, 0.0517 at R = 32 against f's 0.0220), so both
 * are fitted there and the lower headline at J kept.  Both are compared
 * first as fitted (stopped early), and only the better is finished, the
 * other too where it is within JOB_FORM_FINISH_MARGIN (then compared
 * finished): on the default gold, hd, cos's converged fit and refinement
 * were a third of the run and it lost by 1.8x. */
sb_result_t job_named_pair(sb_context_t *ctx, sb_job_t *job, const size_t *order) {
    sb_job_candidate_t *c[2] = {&job->cands[order[0]], &job->cands[order[1]]};
    form_fit_t o[2];
    memset(o, 0, sizeof o);
    for (int k = 0; k < 2; k++)
        if (pair_step(ctx, job, c[k], &o[k], 0) == SB_ERR_NOMEM) {
            job_attempt_free(&o[0].a);
            return SB_ERR_NOMEM;
        }
    if (o[0].r != SB_OK && o[1].r != SB_OK) return o[1].r;
    int w = o[0].r != SB_OK || (o[1].r == SB_OK && headline_j(&o[1].a) < headline_j(&o[0].a)), l = !w;
    int other = o[l].r == SB_OK && !(headline_j(&o[l].a) > JOB_FORM_FINISH_MARGIN * headline_j(&o[w].a));
    sb_result_t r = pair_step(ctx, job, c[w], &o[w], 1);
    if (o[w].pending & FINISH_PENDING) other = 0; /* the warped fit is tried on it first (job_warp.c) */
    if (r == SB_OK || r == SB_ERR_NUMERIC) r = o[l].r == SB_OK && (other || r != SB_OK) ? pair_step(ctx, job, c[l], &o[l], 1) : r;
    if (r == SB_ERR_NOMEM) {
        job_attempt_free(&o[0].a);
        job_attempt_free(&o[1].a);
        return r;
    }
    /* finished both: the second kept where its headline is lower (as before) */
    int keep = o[w].r != SB_OK || (other && o[l].r == SB_OK && (l ? headline_j(&o[l].a) < headline_j(&o[w].a)
                                                                 : !(headline_j(&o[w].a) < headline_j(&o[l].a))))
                   ? l
                   : w;
    if (o[keep].r != SB_OK) return o[keep].r;
    job_attempt_free(&o[!keep].a);
    job->best = o[keep].a;
    job->fit_pending = o[keep].pending;
    c[keep]->kept = 1;
    c[!keep]->kept = 0;
    sb_context_clear_error(ctx);
    return SB_OK;
}

/* Whether job_select's candidates are one layout named alone in two forms
 * (named_pair). */
int job_is_named_pair(const sb_job_t *job, const size_t *order, size_t n) {
    if (n != 2 || !job->layout_auto || job->budget || job->o.max_error > 0) return 0;
    const sb_job_candidate_t *a = &job->cands[order[0]], *b = &job->cands[order[1]];
    return a->kind == b->kind && a->form != b->form;
}
