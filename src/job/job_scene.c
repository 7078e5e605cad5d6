/* The factor job's scene (opts.scene, job.h): the fit weighted by the
 * scene's direction pairs and masked to the cells they touch (scene.h),
 * the estimator's pairs drawn from the scene, and the whole domain's
 * errors beside them in report.json. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "factor/estimate_draw.h"
#include "job_impl.h"
#include "sepbrdf/exr.h"
#include "util/internal.h"

sb_result_t job_scene_open(sb_context_t *ctx, sb_job_t *job) {
    if (!job->o.scene) return SB_OK;
    if (job->o.zero_fill)
        return sb_error(ctx, SB_ERR_ARG, "a scene skips the cells it never uses: it cannot zero-fill them too");
    return sb_scene_parse(ctx, job->o.scene, &job->scene);
}

sb_result_t job_scene_prepare(sb_context_t *ctx, const sb_job_t *job, job_attempt_t *a) {
    if (!job->scene || (a->scene_w && a->scene_form == a->m.form)) return SB_OK;
    sb_result_t r = SB_OK;
    if (a->m.streamed)
        return sb_error(ctx, SB_ERR_OVERFLOW,
                        "a scene weights stored cells: the %zu x %zu matrix is streamed; lower the resolution",
                        a->m.rows, a->m.cols);
    if (a->m.structured) {
        sb_matrix_t d;
        if ((r = sb_matrix_expand(ctx, &a->m, &d)) != SB_OK) return r;
        sb_matrix_free(&a->m);
        a->m = d;
    }
    free(a->scene_w);
    if (!(a->scene_w = sb_alloc(ctx, a->m.rows + a->m.cols, sizeof(double), "scene weights"))) return SB_ERR_NOMEM;
    a->scene_form = a->m.form;
    if ((r = sb_scene_apply(ctx, job->scene, a->param, &a->m, a->scene_w)) != SB_OK) {
        free(a->scene_w);
        a->scene_w = NULL;
    }
    return r;
}

sb_result_t job_scene_sample(sb_context_t *ctx, const sb_job_t *job, const sb_matrix_opts_t *mo, job_attempt_t *a) {
    size_t rows = sb_param_rows(a->param), cols = sb_param_cols(a->param), cells;
    if (sb_size_mul(rows, cols, &cells)) return sb_error(ctx, SB_ERR_OVERFLOW, "scene: cell count overflows");
    double *mass = sb_alloc_large(ctx, cells, sizeof *mass, "scene mass");
    unsigned char *only = mass ? sb_alloc_large(ctx, cells, 1, "scene cells") : NULL;
    a->scene_w = only ? sb_alloc(ctx, rows + cols, sizeof(double), "scene weights") : NULL;
    sb_result_t r = a->scene_w ? sb_scene_mass(ctx, job->scene, a->param, mo->form, 0, mass) : SB_ERR_NOMEM;
    if (r == SB_OK) {
        sb_scene_mass_floor(job->scene, a->param, mass, cells); /* outside the scene: near the whole domain's fit */
        for (size_t c = 0; c < cells; c++)
            only[c] = mass[c] > 0;
        sb_scene_weights(mass, rows, cols, a->scene_w);
        a->scene_form = mo->form;
        sb_matrix_opts_t o = *mo;
        o.only = only;
        r = sb_matrix_build(ctx, job->src, a->param, &o, &a->m);
    }
    free(mass);
    free(only);
    if (r != SB_OK) {
        free(a->scene_w);
        a->scene_w = NULL;
    }
    return r;
}

/* The whole domain's draw (its mixture toward the lobe) with the pairs
 * beyond the cap at density 0: left out of every sum, so the errors are
 * the cap's.  Uniform draws within the cap (as a scene's ranges drew)
 * read a sharp residual low: GGX 0.5 on hd at 60 deg, J' = 2, 65 536
 * pairs: the specular band 6.6e-4 against 8.7e-4 (2 M pairs); a
 * scene's ranges now mix both (scene_mass.c draw_ranges). */
static double draw_in_cap(const void *user, const double x[6], double wi[3], double wo[3]) {
    double c = *(const double *)user, p = sb_estimate_draw_pair(x, wi, wo);
    return wi[2] >= c && wo[2] >= c ? p : 0;
}

sb_result_t job_cap_pairs(sb_context_t *ctx, sb_job_t *job, const sb_estimate_opts_t *eo, sb_pairs_t **out) {
    job->cap_cos = cos(job->o.theta_max_deg * SB_PI / 180); /* the pairs keep a pointer to it */
    return sb_pairs_create_drawn(ctx, job->src, eo, draw_in_cap, &job->cap_cos, out);
}

sb_result_t job_pairs_create(sb_context_t *ctx, sb_job_t *job) {
    if (job->pairs) return SB_OK;
    sb_estimate_opts_t eo = {0};
    eo.channels = job->o.channels; /* measured on the channels factored (--channels) */
    if (job->scene) return sb_scene_pairs_create(ctx, job->scene, job->src, &eo, &job->pairs);
    if (job_measures_cap(job)) return job_cap_pairs(ctx, job, &eo, &job->pairs);
    eo.start = JOB_EST_START;
    return sb_pairs_create(ctx, job->src, &eo, &job->pairs);
}

static void headline_array(sb_json_t *j, const char *key, const sb_estimate_t *e, int se, size_t J) {
    sb_json_begin_array(j, key);
    for (size_t k = 0; k < J; k++)
        sb_json_number(j, NULL, e && k < e->terms ? (se ? e->se : e->rel)[k][SB_EST_FCOS][SB_CH_ALL] : NAN);
    sb_json_end_array(j);
}

void job_scene_report(sb_json_t *j, const sb_job_t *job) {
    static const char *const kinds[] = {"ranges", "lights", "pairs"};
    if (!job->scene) {
        sb_json_string(j, "scene", NULL);
        return;
    }
    const sb_estimate_t *s = job->best.est, *d = job->domain_est;
    size_t J = sb_factors_terms(job->best.f);
    sb_json_begin_object(j, "scene");
    sb_json_string(j, "spec", sb_scene_spec(job->scene));
    sb_json_string(j, "kind", kinds[sb_scene_kind(job->scene)]);
    sb_json_int(j, "fit_cells", (long long)job->best.m.valid_count);
    sb_json_int(j, "cells", (long long)(job->best.m.rows * job->best.m.cols));
    sb_json_int(j, "pairs", (long long)(s ? s->known : 0));
    headline_array(j, "headline", s, 0, J);
    headline_array(j, "headline_se", s, 1, J);
    sb_json_int(j, "domain_pairs", (long long)(d ? d->known : 0));
    headline_array(j, "domain_headline", d, 0, J);
    headline_array(j, "domain_headline_se", d, 1, J);
    sb_json_begin_array(j, "unweighted_headline");
    for (size_t k = 0; k < J; k++)
        sb_json_number(j, NULL, job->scene_ref && k < job->scene_ref_terms ? job->scene_ref[k] : NAN);
    sb_json_end_array(j);
    sb_json_bool(j, "fallback", job->scene_fallback > 0);
    sb_json_string(j, "fallback_why",
                   job->scene_fallback > 0 ? (job->scene_fallback_why == JOB_SCENE_INSIDE ? "inside" : "outside")
                                           : NULL);
    sb_json_number(j, "fallback_ratio", job->scene_fallback > 0 ? job->scene_fallback : NAN);
    sb_json_number(j, "fallback_inside", job->scene_fallback > 0 ? job->scene_fit_inside : NAN);
    sb_json_number(j, "fallback_unweighted_inside", job->scene_fallback > 0 ? job->scene_ref_inside : NAN);
    sb_json_number(j, "fallback_floor",
                   job->scene_fallback > 0 && job->scene_kept_floor > 0 ? job->scene_kept_floor : NAN);
    sb_json_end_object(j);
}

void job_scene_free(sb_job_t *job) {
    sb_scene_destroy(job->scene);
    sb_pairs_destroy(job->domain_pairs);
    free(job->domain_est);
    free(job->scene_ref);
    job->scene_ref = NULL;
    job->scene = NULL;
    job->domain_pairs = NULL;
    job->domain_est = NULL;
}

const sb_scene_t *sb_job_scene(const sb_job_t *job) { return job ? job->scene : NULL; }
const sb_estimate_t *sb_job_domain_estimate(const sb_job_t *job) { return job && job->scene ? job->domain_est : NULL; }
