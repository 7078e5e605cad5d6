/* Warnings when a run asks a measured table for more than its data
 * support (docs/measured.md, "Unmeasured regions: the policy"), and when
 * --param auto lost candidates. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "factor/sample_error.h"
#include "job_impl.h"
#include "sepbrdf/measured.h"
#include "util/internal.h"

/* A term "lowers" the error at the samples when it takes off more than this
 * fraction of it: a smaller gain is within what the last bits of the fit
 * move, not information the samples hold. */
#define SUPPORT_GAIN 1e-3

/* At or above this error at the samples with all its terms a fit misses
 * the table (an RGL file on hd: 98-99.998 %, its nodes with the light at
 * grazing holding values up to 3e10 that only vndf reproduces); below it
 * the terms' warning applies (the ALTA retro table on iso: 57 %, a CSV
 * of an RGL file's nodes: 68 %, both lowered by some terms). */
#define JOB_SAMPLES_MISSED 0.9

/* The largest J' whose term still lowers the error at the measured samples
 * (1-based); e(J') beyond it fits the interpolation between the samples,
 * not the data. */
static size_t supported_terms(const sb_sample_errors_t *se) {
    size_t best = 0;
    for (size_t k = 1; k < se->terms; k++)
        if (se->rel_l2[k] < se->rel_l2[best] * (1 - SUPPORT_GAIN)) best = k;
    return best + 1;
}

/* A scattered table's values against what a BRDF is (f >= 0): refused
 * when their mean is not positive (every value negated: a sign or unit
 * error, which the fit returned as a headline of 1.0, exit 0); a warning
 * when more than JOB_NEGATIVE_WARN of the rows hold a negative value
 * (kept: a little measurement noise around 0 averages out). */
#define JOB_NEGATIVE_WARN 0.1
sb_result_t job_check_values(sb_context_t *ctx, sb_job_t *job) {
    const sb_measured_info_t *in = sb_measured_source_info(job->src);
    if (!in || !in->dims || !in->samples) return SB_OK;
    double mean = in->value_mean[0] + in->value_mean[1] + in->value_mean[2];
    if (!(mean > 0))
        return sb_error(ctx, SB_ERR_FORMAT,
                        "%s: the mean of its values is %.3g 1/sr (%zu of %zu rows negative): a BRDF is not negative; "
                        "are the values negated or in other units?",
                        sb_source_description(job->src), mean / 3, in->negative, in->samples);
    if ((double)in->negative > JOB_NEGATIVE_WARN * (double)in->samples)
        job_warn(job,
                 "%zu of %zu rows (%.0f%%) hold a negative value: kept as measured (noise around 0 averages out), "
                 "but a BRDF is not negative and the fit follows them",
                 in->negative, in->samples, 100.0 * (double)in->negative / (double)in->samples);
    return SB_OK;
}

/* Drop the previous check's warnings: a refactor asks again. */
static void drop_support(sb_job_t *job) {
    for (; job->nsupport && job->nwarn; job->nsupport--)
        free(job->warn[--job->nwarn]);
    job->nsupport = 0;
}

/* Terms that buy nothing on a model: from J' = k on the headline is within
 * 1 % of J's, two terms or more before J, at an error a user sees (above
 * JOB_FLAT_MIN).  The layout's grid is what limits such a fit (GGX 0.1 on
 * iso at R = 32: J' = 2..8 all 1.19 %, at R = 64 0.29 % at J = 8); a
 * measured table says it at its samples instead (below). */
#define JOB_FLAT_MIN 1e-3
static void warn_flat_terms(sb_job_t *job) {
    const sb_estimate_t *e = job->best.est;
    size_t J = e ? e->terms : 0, k = J;
    if (J < 3 || job->o.max_error > 0 || job->best.est_rank) return;
    double hJ = e->rel[J - 1][SB_EST_FCOS][SB_CH_ALL];
    if (!(hJ >= JOB_FLAT_MIN)) return;
    while (k > 1 && e->rel[k - 2][SB_EST_FCOS][SB_CH_ALL] <= 1.01 * hJ)
        k--;
    if (J - k < 2) return;
    job_warn(job,
             "terms beyond J = %zu lower the headline by less than 1%% (%.3g%% at J = %zu, %.3g%% at J = %zu): layout "
             "%s at resolution %zu limits this fit, not the terms; a finer --res (or another --param) can go lower",
             k, 100 * e->rel[k - 1][SB_EST_FCOS][SB_CH_ALL], k, 100 * hJ, J,
             sb_param_kind_name(sb_param_kind(job->best.param)), job->o.res);
}

void job_warn_support(sb_job_t *job) {
    drop_support(job);
    const sb_measured_info_t *in = sb_measured_source_info(job->src);
    size_t before = job->nwarn;
    if (!in) {
        warn_flat_terms(job);
        job->nsupport = job->nwarn - before;
        return;
    }
    /* a grid finer than the samples: sampling at spacing s resolves
     * features of 2 s (Nyquist), so cells below s / 2 hold only what the
     * interpolation makes up between samples */
    double cell = 90.0 / (double)job->o.res, spacing = in->spacing * 180 / SB_PI;
    if (in->dims && spacing > 0 && cell < 0.5 * spacing)
        job_warn(job,
                 "resolution %zu: cells of %.3g deg are finer than half the samples' median spacing (%.3g deg); the "
                 "extra resolution holds interpolated values only",
                 job->o.res, cell, spacing);
    const job_attempt_t *a = &job->best;
    sb_sample_errors_t se;
    job->se_f = NULL;
    if (a->f && sb_sample_errors_(NULL, job->src, a->f, a->param, a->m.form, job->o.channels, job_measures_cap(job),
                                  &se) == SB_OK) { /* within a --theta-max cap: the samples there only */
        job->se = se, job->se_f = a->f; /* for the report: one pass over a MERL file's 1.4 M cells is seconds */
        size_t keep = supported_terms(&se);
        /* at the table's own floor (its evaluation against its samples: an
         * RGL file's pole nodes disagree), the terms are not the cause */
        if (keep < se.terms && se.rel_l2[keep - 1] <= 1.01 * se.source_rel_l2 + 1e-12)
            job_warn(job,
                     "terms beyond J = %zu do not lower the error at the %zu measured samples (%.3g%%): at J = %zu "
                     "the textures return them as the table's own evaluation does, which differs from its samples "
                     "by %.3g%% (samples that share a pair of directions)",
                     keep, se.samples, 100 * se.rel_l2[keep - 1], keep, 100 * se.source_rel_l2);
        else if (se.rel_l2[se.terms - 1] >= JOB_SAMPLES_MISSED) /* no J holds them: not the terms' doing */
            job_warn(job,
                     "the textures miss the %zu measured samples at every J (%.3g%% at J = 1, %.3g%% at J = %zu): "
                     "layout %s does not hold this table's values%s",
                     se.samples, 100 * se.rel_l2[0], 100 * se.rel_l2[se.terms - 1], se.terms,
                     sb_param_kind_name(sb_param_kind(a->param)),
                     job->o.param && strcmp(job->o.param, "auto") != 0
                         ? " (--param auto keeps the layout of lowest error among those that apply)"
                         : "");
        else if (keep < se.terms)
            job_warn(job,
                     "terms beyond J = %zu do not lower the error at the %zu measured samples (%.3g%% at J = %zu, "
                     "%.3g%% at J = %zu): they fit the interpolation, not the data",
                     keep, se.samples, 100 * se.rel_l2[keep - 1], keep, 100 * se.rel_l2[se.terms - 1], se.terms);
    }
    job->nsupport = job->nwarn - before;
}

/* Whether candidate c was lost to memory (the limit or an allocation); to
 * a failure: lost(c) and not lost_to_memory(c). */
static int lost_to_memory(const sb_job_candidate_t *c) {
    return c->result == SB_ERR_NOMEM || c->result == SB_ERR_OVERFLOW || strstr(c->why, "memory limit");
}
static int lost(const sb_job_candidate_t *c) {
    return !c->ok && !c->kept && c->why[0] && (c->result != SB_OK || lost_to_memory(c));
}

size_t sb_job_lost_count(const sb_job_t *job) {
    size_t n = 0;
    for (size_t i = 0; job && i < job->ncand; i++)
        n += (size_t)lost(&job->cands[i]);
    return n;
}

void job_warn_lost(sb_job_t *job) {
    for (size_t i = 0; i < job->ncand; i++) {
        const sb_job_candidate_t *c = &job->cands[i];
        int mem = lost_to_memory(c);
        if (!lost(c)) continue;
        job_warn(job, "--param auto lost the candidate %s/%s (%s): %s; the layout kept may be worse than it",
                 sb_param_kind_name(c->kind), sb_form_name(c->form),
                 mem                           ? "memory"
                 : c->result == SB_ERR_NUMERIC ? "numerical failure"
                                               : sb_result_message(c->result),
                 c->why);
    }
}
