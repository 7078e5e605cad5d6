/* The factor job's scene against the unweighted fit (issue 33): the same
 * run without the scene, at the scene fit's J, gives the whole domain's
 * reference (report.json scene.unweighted_headline).  A scene fit whose
 * error over the whole domain is above SCENE_OUTSIDE x that reference is
 * replaced (scene.fallback): by the scene fit with a higher floor (the
 * cells outside the scene weigh X x the scene's mass, X walked along
 * job_scene_floors: from 1 down while within SCENE_OUTSIDE outside, else
 * up to the first within, then bisected on log X between the last within
 * and the last beyond) or by the unweighted fit, whichever of those
 * within SCENE_OUTSIDE outside is the lowest inside the scene.  A scene
 * fit within outside but above the unweighted fit inside the scene is
 * replaced by the unweighted fit.  Apart
 * from job_scene_domain.c, which measures and drops terms; the runs
 * themselves, whole jobs beside this one, are job_scene_guard in job.c,
 * which asks this file what to run and keep. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "job_impl.h"
#include "util/internal.h"

/* Measured (docs/bands.md, tenth pass): with the default floor, RGL files
 * on vndf were 5-35 000x the unweighted fit over the whole domain at J = 4
 * (the slices outside the scene fitted by what the scene's three rows
 * leave), Phong n = 100 on rv 30x.  1.8, not the 2: an independent
 * draw reads the ratio within about 10 % of the report's (gold J = 8:
 * 1.84 drawn, 2.0 in the report). */
#define SCENE_OUTSIDE 1.8
/* The bisection aims at the bound, so it keeps a wider margin: RGL
 * orange J = 4 at floor 0.562 was 1.70x in the report and 2.03x drawn
 * independently (bench/issue33.py; the unweighted fit 5.47 % against
 * 4.5 % drawn). */
#define SCENE_SEARCH 1.6
/* The floors walked (docs/scene.md, "Where the guard fires"), inside /
 * whole domain over the unweighted fit at R = 32: the walk's first pass
 * is at most 1.6x the lowest inside of these within 1.8x.  RGL aurora
 * J = 4: floor 1 1.59 % / 1.99x, 2 2.31 % / 1.61x, 10 4.29 % / 1.2x
 * (the unweighted fit 3.32 % inside); light blue J = 4: 3 0.92 % / 3.4x,
 * 5 0.68 % / 1.74x, 10 1.14 % / 1.23x; Phong n = 100 J = 1: 1 3.52 % /
 * 0.34x, 0.1 2.53 % / 0.19x.  Not monotone (silk blue J = 4: 3 1.71x,
 * 5 2.3x), hence a walk that stops at the first within, and only then a
 * bisection between it and the floor before. */
const double job_scene_floors[JOB_SCENE_FLOORS] = {0.01, 0.1, 1, 2, 3, 5, 10};
#define FLOOR_START 2 /* floor 1: the cells outside weigh what the scene does */
/* A floor fit within this share of the scene fit's inside and ratio
 * changed nothing (every cell touched: Phong n = 100 on rv, J = 4, any
 * floor 0.0313 % / 30.4x): no other floor will. */
#define FLOOR_SAME 0.01
/* Bisections on log floor after the ladder (docs/scene.md, "A floor
 * searched"). */
#define FLOOR_BISECT 3

/* The attempt and the screening of u become job's (and job's u's, to be
 * destroyed with it). */
static void take_fit(sb_job_t *job, sb_job_t *u) {
    job_attempt_t a = job->best;
    job->best = u->best;
    u->best = a;
    sb_job_candidate_t c[JOB_MAX_CANDS];
    memcpy(c, job->cands, sizeof c);
    memcpy(job->cands, u->cands, sizeof c);
    memcpy(u->cands, c, sizeof c);
    size_t n = job->ncand;
    job->ncand = u->ncand, u->ncand = n;
    memcpy(job->cand_need, u->cand_need, sizeof job->cand_need);
    memcpy(job->cand_terms, u->cand_terms, sizeof job->cand_terms);
    job->warp_tried = u->warp_tried;
}

static double domain_at(const sb_job_t *job, size_t J) {
    const sb_estimate_t *d = job->domain_est;
    return d && J <= d->terms ? d->rel[J - 1][SB_EST_FCOS][SB_CH_ALL] : NAN;
}

int job_scene_guarded(const sb_job_t *job) {
    return job->scene && !job->no_scene_guard && job->best.f && job->domain_est && !job->budget && !job->o.sample_only;
}

static job_level_t level(const sb_job_t *job, size_t J) {
    return (job_level_t){.res = job->o.res,
                         .terms = J,
                         .metric_res = job->o.metric_res,
                         .fit_tol = job->o.fit_tol,
                         .fit_max_iters = job->o.fit_max_iters};
}

static int same(double a, double b) { return fabs(a - b) <= FLOOR_SAME * fabs(b); }

sb_result_t job_scene_reference(sb_context_t *ctx, sb_job_t *job, sb_job_t *u, int *replace) {
    size_t J = sb_factors_terms(job->best.f);
    *replace = 0;
    free(job->scene_ref);
    if (!(job->scene_ref = malloc(J * sizeof *job->scene_ref))) return sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    for (size_t k = 0; k < J; k++)
        job->scene_ref[k] = sb_job_headline(u, k + 1);
    job->scene_ref_terms = J;
    /* floor=X given: the user's trade between the scene and the rest */
    if (sb_scene_floor(job->scene) >= 0 || job->o.plain_terms) return SB_OK;
    if (domain_at(job, J) > SCENE_OUTSIDE * job->scene_ref[J - 1]) {
        *replace = JOB_SCENE_OUTSIDE;
        return SB_OK;
    }
    /* within: the unweighted fit inside the scene (u's estimate is the
     * scene's from here), kept where lower there (Phong n = 100 on rv,
     * R = 16, J = 4: the scene fit 0.133 %, the unweighted 0.0999 %); not
     * where the two are the same within FLOOR_SAME (a scene that is the
     * --theta-max cap fits as the unweighted fit does: 0.0226 % against
     * 0.0226 % was a replacement and a warning) */
    job_level_t lv = level(job, J);
    sb_result_t r = job_estimate_again(ctx, job, &lv, &u->best);
    double hu = sb_job_headline(u, J), hs = sb_job_headline(job, J);
    if (r == SB_OK && hu < hs && !same(hu, hs)) *replace = JOB_SCENE_INSIDE;
    return r;
}

/* The next floor: the ladder as above, then (a floor within and one not
 * bracketing the bound) FLOOR_BISECT bisections on log floor between the
 * two, each kept only within SCENE_SEARCH, the inside mostly falling as the floor falls (RGL aurora J = 4:
 * floor 1 1.99x, 2 1.61x, 1.41 1.82x, 1.68 within). */
/* x to 3 significant digits, as floor=%g in the spec and the report */
static double neat(double x) {
    char b[32];
    snprintf(b, sizeof b, "%.3g", x);
    return strtod(b, NULL);
}

double job_scene_next_floor(const sb_job_t *job, const sb_job_t *w, job_floor_walk_t *k) {
    if (!k->started) {
        *k = (job_floor_walk_t){.started = 1, .i = FLOOR_START, .within = INFINITY, .beyond = 0};
        return job_scene_floors[k->i];
    }
    size_t J = sb_factors_terms(job->best.f);
    int pass = w && domain_at(w, J) <= job_scene_walk_bound(k) * job->scene_ref[J - 1];
    double x = k->bisect ? neat(sqrt(k->within * k->beyond)) : job_scene_floors[k->i];
    if (pass)
        k->within = fmin(k->within, x);
    else if (x < k->within)
        k->beyond = fmax(k->beyond, x);
    if (k->bisect) return --k->bisect > 0 ? neat(sqrt(k->within * k->beyond)) : -1;
    if (k->step == 0) {
        if (!pass && w && same(domain_at(w, J), domain_at(job, J)) &&
            same(sb_job_headline(w, J), sb_job_headline(job, J)))
            return -1;
        k->step = pass ? -1 : 1; /* down while within, else up to the first within */
    } else if (k->step < 0 ? !pass : pass)
        k->i = -2; /* the ladder ends */
    int next = k->i + k->step;
    if (k->i >= 0 && next >= 0 && next < JOB_SCENE_FLOORS) return job_scene_floors[k->i = next];
    /* within down to the ladder's end: the scene fit's own floor (rv:
     * 0.001) is beyond (Phong n = 100 J = 1: 3.3x) */
    double own = sb_scene_floor_on(job->scene, job->best.param);
    if (!(k->beyond > 0) && own > 0 && own < k->within) k->beyond = own;
    if (!(k->beyond > 0 && isfinite(k->within))) return -1;
    k->bisect = FLOOR_BISECT;
    return neat(sqrt(k->within * k->beyond));
}

double job_scene_walk_bound(const job_floor_walk_t *k) { return k->bisect ? SCENE_SEARCH : SCENE_OUTSIDE; }

int job_scene_better(const sb_job_t *job, const sb_job_t *v, const sb_job_t *w, double bound) {
    size_t J = sb_factors_terms(job->best.f);
    return w && domain_at(w, J) <= bound * job->scene_ref[J - 1] &&
           (!v || sb_job_headline(w, J) < sb_job_headline(v, J));
}

/* Replace the scene fit by the unweighted fit u or the floor candidate v,
 * whichever is lower inside the scene; the attempts set aside stay in u
 * and v (job.c destroys them). */
static sb_result_t replace(sb_context_t *ctx, sb_job_t *job, size_t J, sb_job_t *u, sb_job_t *v, double floor) {
    job->scene_fit_inside = job->best.est ? sb_estimate_headline(job->best.est, J) : NAN;
    job->scene_fallback = domain_at(job, J) / job->scene_ref[J - 1];
    job_level_t lv = level(job, J);
    take_fit(job, u);
    sb_result_t r = job_estimate_again(ctx, job, &lv, &job->best); /* the unweighted fit inside the scene */
    job->scene_kept_floor = 0;
    job->scene_ref_inside = r == SB_OK ? sb_job_headline(job, J) : NAN;
    if (r == SB_OK && v && sb_job_headline(v, J) < sb_job_headline(job, J)) {
        take_fit(job, v);
        job->scene_kept_floor = floor;
        r = job_estimate_again(ctx, job, &lv, &job->best);
    }
    return r == SB_OK ? job_scene_measure(ctx, job) : r;
}

sb_result_t job_scene_replace(sb_context_t *ctx, sb_job_t *job, sb_job_t *u, sb_job_t *v, double floor, int why) {
    size_t J = sb_factors_terms(job->best.f);
    double out = domain_at(job, J), ref = job->scene_ref[J - 1];
    job->scene_fallback_why = why;
    sb_result_t r = replace(ctx, job, J, u, v, floor);
    if (r != SB_OK) return r;
    char what[64] = "the unweighted fit";
    if (job->scene_kept_floor > 0) snprintf(what, sizeof what, "the scene's fit with floor=%g", job->scene_kept_floor);
    if (why == JOB_SCENE_INSIDE)
        job_warn(job,
                 "the scene's fit was worse inside the scene than the unweighted fit (%.3g %% against %.3g %%): kept "
                 "the unweighted fit (report.json scene.fallback); floor=X in --scene keeps the scene's as asked",
                 100 * job->scene_fit_inside, 100 * job->scene_ref_inside);
    else
        job_warn(job,
                 "the scene's fit was %.3gx the unweighted fit's error over the whole domain (%.3g %% against %.3g "
                 "%%): kept %s (inside the scene %.3g %%, the scene's fit %.3g %%, the unweighted fit %.3g %%; "
                 "report.json scene.fallback); floor=X in --scene keeps the scene's as asked",
                 out / ref, 100 * out, 100 * ref, what, 100 * sb_job_headline(job, J), 100 * job->scene_fit_inside,
                 100 * job->scene_ref_inside);
    return SB_OK;
}
