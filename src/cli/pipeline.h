/* sepbrdf CLI: the per-candidate pipeline shared by `factor` and `study`.
 *
 * One attempt = one source on one parameterisation and form:
 *     sample (param + matrix) -> plan + execute (factors) -> comparable metric.
 * The two halves are separate so that `study` samples once and factors the
 * same matrix several times (one plan per J when the fit is masked). */
#ifndef SEPBRDF_CLI_PIPELINE_H
#define SEPBRDF_CLI_PIPELINE_H

#include "cli.h"

/* Settings of an attempt; zero means the library default except where
 * noted. */
typedef struct pipe_opts {
    size_t res;           /* R, cells per angular axis */
    size_t terms;         /* J of the plan (attempt_sample checks it fits) */
    size_t metric_res;    /* reference grid of the comparable metric */
    double theta_max_deg; /* 0 = 90 */
    double max_error;     /* plan stops at the first J' with rel_rms <= this; 0 = off */
    sb_method_t method;
    unsigned long long seed;
    int zero_fill; /* factor invalid cells as zeros (no masked fit) */
    /* Progress of the sampling stage: cli_progress(label, base + span * f)
     * with f the fraction of the matrix built; label NULL = no progress. */
    const char *progress_label;
    double progress_base, progress_span;
    unsigned channels; /* bit mask of channels to build (1 R, 2 G, 4 B); 0 = all */
    double fit_tol;    /* masked fit: stop tolerance, 0 = the library default */
    int fit_max_iters; /* masked fit: sweeps, 0 = the library default */
    /* The error estimator (estimate.h): its pairs for the source, shared by
     * every candidate and J (NULL: pipe_select makes them once, a lone
     * attempt_factor for itself); the stored precision it measures; how
     * many pairs it may grow to (0 = the library default, 1 = never grows:
     * screening). */
    sb_pairs_t *pairs;
    int half;
    size_t est_max_pairs;
} pipe_opts_t;

/* One complete factorisation of a source on one parameterisation. */
typedef struct attempt {
    sb_param_t *param;
    sb_matrix_t m;
    sb_factors_t *f;
    sb_plan_stats_t stats;
    sb_metric_t metric; /* grid quadrature (comparable_grid), kept candidate only */
    sb_estimate_t *est; /* the estimator's errors of the stored factors */
    int weighted, zero_fill;
    double t_sample, t_factor, t_metric, t_estimate;
} attempt_t;

/* Open SOURCE like sb_source_open, but a spec that names a path (its model
 * part contains '/' or '.') and does not exist, or is not a regular file,
 * fails with SB_ERR_IO "PATH: no such file" instead of "unknown model". */
/* A model spec, or a measured table file read with mo (NULL: defaults). */
sb_result_t pipe_source_open(sb_context_t *ctx, const char *spec, const sb_measured_opts_t *mo, sb_source_t **out);

/* Create the parameterisation and sample the source into a->m (a is reset
 * first).  Fails with SB_ERR_RANGE when o->terms exceeds the matrix's
 * smaller dimension. */
sb_result_t attempt_sample(sb_context_t *ctx, const sb_source_t *src, const pipe_opts_t *o, sb_param_kind_t kind,
                           sb_form_t form, attempt_t *a);
/* Factor the sampled a->m with `terms` terms (replacing a->f), record the
 * plan statistics and estimate the errors of the stored factors for
 * J' = 1..terms (attempt_estimate); with o->metric_res > 0 also the grid
 * quadrature (a->metric). */
sb_result_t attempt_factor(sb_context_t *ctx, const sb_source_t *src, const pipe_opts_t *o, size_t terms, int weighted,
                           attempt_t *a);
/* The estimator's errors of a->f as stored (o->half) into a->est, on
 * o->pairs (or pairs of its own when NULL). */
sb_result_t attempt_estimate(sb_context_t *ctx, const sb_source_t *src, const pipe_opts_t *o, attempt_t *a);
/* Keep the first j terms of a->f (errors, estimate and metric with them). */
sb_result_t attempt_truncate(sb_context_t *ctx, attempt_t *a, size_t j);
/* attempt_sample + attempt_factor with o->terms. */
sb_result_t attempt_run(sb_context_t *ctx, const sb_source_t *src, const pipe_opts_t *o, sb_param_kind_t kind,
                        sb_form_t form, int weighted, attempt_t *a);
/* Whether factoring a->m is a masked fit (invalid cells and no zero fill):
 * then the leading J' terms of a rank-J fit are not the rank-J' fit. */
int attempt_masked(const attempt_t *a);
void attempt_free(attempt_t *a);
/* The estimator's headline (f cos theta_i), comparable (f cos cos) and
 * negative fraction after j >= 1 terms; NAN beyond the terms it holds
 * (SB_EST_MAXJ). */
double attempt_headline(const attempt_t *a, size_t j);
double attempt_comparable(const attempt_t *a, size_t j);
double attempt_negative(const attempt_t *a, size_t j);

/* A candidate of --param auto (or the one parameterisation asked for) and
 * its headline error at J. */
typedef struct pipe_cand {
    sb_param_kind_t kind;
    sb_form_t form;
    int weighted;
    double err;
    int ok;
} pipe_cand_t;
#define PIPE_MAX_CANDS (2 * SB_PARAM_KIND_COUNT_)

/* The candidates: with param_auto every parameterisation that applies to
 * src (iso only for isotropic sources, none that sb_param_create refuses),
 * with forms f and cos unless form_set (cos not on a layout that folds by
 * reciprocity, SB_CAP_FOLDS_RECIPROCITY: f cos(theta_i) is not reciprocal), solid-angle
 * weighted; otherwise just (param, form, weighted).  cos2 is no candidate:
 * its division by cos(theta_o) turns small errors near the horizon into
 * unbounded ones in what a shader outputs, f cos(theta_i).  Returns the
 * count (<= PIPE_MAX_CANDS). */
size_t pipe_candidates(const sb_source_t *src, const pipe_opts_t *o, int param_auto, sb_param_kind_t param,
                       int form_set, sb_form_t form, int weighted, pipe_cand_t *cands);
/* Factor every candidate and keep the one with the lowest headline error
 * (the estimator's f cos(theta_i) at J) in *best.  With several candidates
 * they are screened on the first pairs without growing them and with
 * masked fits stopped early; the kept one is refitted (masked) or
 * estimated again with growth, and gets the grid metric at o->metric_res.
 * A candidate that fails numerically or is unsupported is skipped (others
 * fail the call).  cmd names the messages. */
sb_result_t pipe_select(sb_context_t *ctx, const char *cmd, const sb_source_t *src, const pipe_opts_t *o,
                        pipe_cand_t *cands, size_t ncand, attempt_t *best);

#endif
