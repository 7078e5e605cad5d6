/* Private: the factor job's state and the functions its files share.  The
 * files form a tree (scripts/check_layers.sh checks it), each calling only
 * those on the lines above it:
 *   job_base.c (clock, progress, warnings, accessors), job_json.c,
 *   job_beside.c (which methods are non-negative)
 *   job_support.c, job_scene.c, job_candidates.c
 *   job_attempt.c (sample, factor and measure one candidate)
 *   job_cv.c, job_weights.c
 *   job_texels.c
 *   job_screen.c (screen the candidates, fit the kept one)
 *   job_warp.c, then job_budget.c
 *   job_report.c, then job_write.c
 *   job.c (options, the driver, the SVD beside a non-negative fit) */
#ifndef SEPBRDF_JOB_IMPL_H
#define SEPBRDF_JOB_IMPL_H

#include "sepbrdf/experimental/layout.h"
#include "sepbrdf/job.h"
#include "sepbrdf/sampler.h"
#include "util/shared.h"

/* The second form of a layout sampled with the first (job_sample): where
 * `want`, the next build evaluating an isotropic source on the io grid
 * builds `m` in `form` too, keyed by what it was built from; job_sample
 * for that form, layout and source takes it.  m.rows 0: none. */
typedef struct job_form_share {
    int want;
    int second; /* the second form is being fitted: its max_abs left out (pair_max_abs, job_forms.c) */
    sb_form_t form;
    sb_matrix_t m;
    const sb_source_t *src;
    unsigned long serial; /* sb_param_serial_ of the layout */
    unsigned channels;
} job_form_share_t;

/* One factorisation of the source on one parameterisation and form:
 * sample (param + matrix) -> plan + execute (factors) -> comparable error. */
typedef struct job_attempt {
    sb_param_t *param;
    sb_matrix_t m;
    sb_factors_t *f;
    sb_plan_stats_t stats;
    size_t conv_terms;         /* the leading terms from converged sweeps (plan_conv.h; job_fit_converged) */
    int early_stop;            /* the masked fit ran under auto's early stop (job_early_stop) */
    sb_metric_t metric;        /* grid quadrature (comparable_grid), the kept fit only */
    sb_estimate_t *est;        /* the estimator's errors of the stored factors */
    int est_rank;              /* est is a ranking's (lv.rank_only): no p99 or maxima, fewer pairs */
    int est_lean;              /* est holds headlines and bands alone (job->est_lean) */
    int est_probe;             /* est holds the headlines alone, no bands (job->est_probe) */
    double *term_w;            /* J * C term weights applied to f (job_weights.c); NULL: all 1 */
    double band_weight;        /* the band's weight 1 + w of the cell-weighted fit (job_bandfit.c); 0: plain */
    size_t band_pairs;         /* pairs of the bands' own estimates (job_bandpairs.c); 0: none */
    unsigned texel_fit;        /* texture axes filtered for the lookup (job_texels.c): bit 2 side + axis */
    double weights_dropped[2]; /* term weights dropped (job_weights.c): headline at J as fitted, weighted; 0: not */
    int weighted;
    double *scene_w;      /* with a scene: W_r (rows), W_c (cols) of its fit (job_scene.c); NULL: not yet */
    sb_form_t scene_form; /* the form scene_w was made for */
    double t_sample, t_factor, t_metric, t_estimate;
} job_attempt_t;

/* What one attempt is asked: resolution, J and the fit's limits. */
typedef struct job_level {
    size_t res, terms, metric_res; /* metric_res 0: no grid quadrature */
    size_t est_max_pairs;          /* the estimator's growth: 0 default, 1 none */
    int rank_only;                 /* a ranking: the headline only, on the first 16384 pairs */
    int rank_at_j;                 /* with rank_only: at J only (the shorter prefixes' errors 0) */
    double fit_tol;
    int fit_max_iters;
    int early_stop;            /* fit_tol, fit_max_iters are auto's early stop (job_early_stop) */
    const sb_param_opts_t *po; /* the layout's options (shape, warps; res is lv's); NULL: res alone */
    int half_shape;            /* screening: layouts folding reciprocity (iso) on R theta_h rows (job_level_opts) */
    const char *label;         /* progress label of the sampling; NULL = none */
    double base, span;         /* progress = base + span * fraction */
    /* the plan's nonneg_ratio (factor.h; job_nonneg_refit); NULL: none */
    const double *nonneg_ratio;
    const double *nonneg_ratio_channel; /* per channel, 3 x terms (factor.h); NULL: none */
    int nonneg_first_fit;               /* the plan's nonneg_first_fit (factor.h): screening */
    size_t nonneg_rounds;               /* the plan's nonneg_rounds (factor.h) */
} job_level_t;

#define JOB_MAX_CANDS (3 * SB_LAYOUTS_MAX) /* f and cos a layout, with room */
#define JOB_MAX_WARN 8
/* Without --warp, the kept layout's headline at J above which "auto"
 * warps are tried (one more fit). */
#define JOB_WARP_TRY 0.05
/* A scattered table of fewer rows (four a cross-validation fold: below
 * it job_cv holds none out) cannot tell layouts apart: every candidate's
 * screened headline measures how it fits the interpolation between a few
 * points, not the points.  Auto fits iso form f weighted there (its choice
 * on every full scattered table measured) and tries no warps
 * (job_few_rows). */
#define JOB_FEW_ROWS 40
#define JOB_BLAS_DENSE_CELLS ((size_t)1 << 20) /* a dense matrix from this many cells factors on every core */
/* Replicates of 4096 pairs the job's estimator starts with (grown while
 * the upper bound of the headline's standard error is above the target,
 * estimate.h; screening reads the first 4): gold on io at R = 64 has a
 * standard error of 0.2-0.7 % of its headline at 16384 pairs, the default
 * 0.7-1.1 %, within 5 % with the bound's factor 3; the 32768 pairs this
 * started with were 30 % of the CPU of `factor --param io -r 64 -J 8`
 * (issue 36), and the 65536 of the library's default start a fifth of the
 * default run. */
#define JOB_EST_START 4
/* The bound on nmf_over_svd (issue 38) above which job_nonneg_refit runs. */
#define JOB_NONNEG_RATIO 1.5
#define JOB_CONVERGED_TRY 0.01 /* auto: headline at J above which the converged masked fit is tried too */

/* theta_h bands of the cross-validated error (degrees, JOB_CV_BANDS + 1
 * edges in job_cv_band_deg): the highlight's core, its flanks, the body
 * and the grazing half vectors. */
#define JOB_CV_BANDS 5

struct sb_job {
    sb_job_opts_t o;   /* resolved: every default filled in */
    char *source_spec; /* o.source points here */
    sb_source_t *own_src;
    const sb_source_t *src;
    sb_pairs_t *pairs;      /* the estimator's direction pairs, for every candidate and J */
    sb_pairs_t *band_pairs; /* pairs with theta_i > 60 degrees for the reported grazing bands (job_bandpairs.c) */
    sb_pairs_t
        *cone_pairs;   /* pairs with wo near the mirror direction or wi for the specular and retro bands (the same) */
    double t_estimate; /* the estimator, in all */
    /* estimates at the requested settings take the headlines and bands of
     * every J' alone (no percentiles, maxima or colour: what choosing and
     * refining a fit read): named_pair, the whole estimate made for the
     * kept fit alone */
    int est_lean;
    /* with est_lean: the headlines of every J' alone, no bands (the second
     * form of pair_unscreened, measured again with its bands only where it
     * wins or is close: job_forms.c probe_clear) */
    int est_probe;
    /* named_pair's forms of one layout (job_forms.c): the second form's
     * matrix built by the first's job_sample from the same evaluations,
     * taken by the second's; NULL: none */
    struct job_form_share *form_share;
    int is_auto;
    int fit_as_auto; /* an explicit layout fitted as auto fits its kept one (the SVD beside an auto run) */
    /* --param KIND (a name, not a whole spec; not sample_only): auto
     * restricted to that layout, its candidates (forms, weighting) as auto
     * makes them, screened and fitted as auto fits its kept one */
    int layout_auto;
    int named_alone; /* --param KIND named so, kept where layout_auto is dropped (a layout not applying) */
    sb_job_candidate_t cands[JOB_MAX_CANDS];
    size_t ncand;
    /* --max-error: per candidate, the fewest terms of its screening whose
     * headline meets it and that keep the band bounds (0: none, or no
     * --max-error); job_rank ranks by it first */
    size_t cand_need[JOB_MAX_CANDS];
    size_t cand_terms[JOB_MAX_CANDS]; /* the terms it is fitted with at R (they differ only with --max-error) */
    job_attempt_t best;
    sb_scene_t *scene;         /* opts.scene parsed, NULL: none (job_scene.c) */
    double cap_cos;            /* --theta-max below 90: cos of the cap, where the estimator's pairs lie */
    sb_pairs_t *domain_pairs;  /* with a scene: the whole domain's pairs */
    sb_estimate_t *domain_est; /* with a scene: the kept fit's errors over the whole domain */
    double *scene_ref;         /* with a scene: the unweighted fit's headline per J' (job_scene_guard.c); NULL: none */
    size_t scene_ref_terms;
    double scene_fallback;   /* the scene fit's whole-domain error over scene_ref at J when it was replaced; 0: kept */
    int scene_fallback_why;  /* JOB_SCENE_OUTSIDE or JOB_SCENE_INSIDE where replaced */
    double scene_fit_inside; /* the replaced scene fit's headline at J over the scene's pairs */
    double scene_kept_floor; /* the floor of the scene fit kept instead (floor=X), 0: the unweighted fit */
    double scene_ref_inside; /* the unweighted fit's headline at J over the scene's pairs, when replaced */
    int no_scene_guard;      /* JOB_RUN_NO_GUARD: a candidate of job_scene_guard.c itself */
    int headline_only;       /* JOB_RUN_HEADLINE: read for its headline alone (job_svd_beside) */
    double *rel_stored;      /* J * 4 after sb_job_write, NULL before or if unknown */
    int wrote_sampler;       /* sb_job_write wrote sampler.bin (non-negative factors) */
    sb_sampler_choice_t share; /* its cosine-weighted share and variance ratios (when wrote_sampler) */
    double *svd_beside; /* non-negative method: J x {headline, rel_rms, R, G, B headlines} of the SVD (job_beside.c);
                           NULL: none */
    size_t svd_beside_terms;
    /* non-negative method: the fits its plans keep and take again (the
     * screening's on the source's tables, the refits' rounds; plan_conv.h
     * sb_plan_set_nonneg_carry), until job_nonneg_refit; NULL: none */
    struct sb_nmf_carry *nonneg_carry;
    int nonneg_same;     /* the last refit gave the refit before's factors bit for bit: not measured in full, dropped */
    char svd_method[16]; /* the method the SVD beside used ("masked", "circulant", ...) */
    double svd_s;        /* its whole run */
    int warp_tried;      /* no --warp given, and "auto" was tried (job_warp.c) */
    unsigned fit_pending; /* job_fit_kept's FINISH_* flags; FINISH_PENDING: best awaits job_fit_finish */
    /* job_warp_screen: the kept candidate's layout on adaptive warps at
     * its screening resolution, its headline at J (0: not screened) and
     * whether that decided the warp (best is the warped fit, no unwarped
     * fit made) */
    double warp_screen_error;
    int warp_screened;
    char *warn[JOB_MAX_WARN];
    size_t nwarn;
    size_t nsupport; /* the last of warn[] are job_warn_support's */
    /* the errors at a measured table's samples of best.f (job_support.c),
     * kept for the report while best.f is se_f (NULL: none kept) */
    sb_sample_errors_t se;
    const sb_factors_t *se_f;
    sb_job_timings_t t;
    double t_start;
    /* the whole job's wall time in consecutive stages (report.json
     * timings.stages): opening the source, choosing and fitting, the SVD
     * beside, the scene's errors, cross-validation, writing */
    double stage_s[6];
    struct job_budget *budget;    /* opts.budget: the search (job_budget.c); NULL without */
    const sb_param_opts_t *shape; /* the kept layout's options (a budget's choice); NULL: o.res alone */
    sb_param_opts_t spec_shape;   /* --param KIND:key=value's options (job->shape then points here) */
    int blas_threads;             /* OpenBLAS's thread count before the job (one thread during it) */
    /* scattered tables (job_cv.c), per J' (NULL: none): the error of
     * f cos theta_i at the measurements a fold's refit left out: the
     * figure a random split lands within 1.5x of most often (cv, drawn
     * from the refits' held-out rows, job_cv_stat.c) with its standard
     * error, over all the measurements held out (cv_pooled), in the worst
     * fold (cv_max) and the median over the folds (cv_median); one
     * allocation, cv the first of its five rows */
    double *cv, *cv_se, *cv_pooled, *cv_max, *cv_median;
    /* the same median for the tables the refits sampled (their lobe and
     * interpolation, no factoring): the table's share of cv */
    double cv_table;
    size_t cv_folds, cv_refits, cv_held, cv_terms;
    double cv_s; /* its time */
    /* at the kept J, per theta_h band (JOB_CV_BANDS edges): the held-out
     * squared error, energy and count, for the warning that says where */
    double cv_band_e[JOB_CV_BANDS], cv_band_t[JOB_CV_BANDS];
    size_t cv_band_n[JOB_CV_BANDS];
    /* job_quantized: the stored factors of the last two factors asked
     * for (quant_last the newer), while those keep the stamp they had
     * (sb_factors_stamp) */
    sb_factors_t *quant[2];
    unsigned long long quant_stamp[2];
    int quant_half[2], quant_last;
};

extern const double job_cv_band_deg[JOB_CV_BANDS + 1];

/* k-fold cross-validation of a scattered table's kept fit (job_cv.c). */
sb_result_t job_cv(sb_context_t *ctx, sb_job_t *job);
/* Where fewer terms predict the held-out measurements better than J do
 * (their cross-validated error JOB_CV_FEWER times lower): those terms, the
 * fewest of lowest error; 0 otherwise or without cross-validation. */
size_t job_cv_fewer(const sb_job_t *job, size_t J);

/* The figure random splits of n_split rows land within w of most often,
 * per J' < J, into fig[J], and its standard error into se[J] (NULL: not
 * wanted) (job_cv_stat.c): the refits' held-out rows, e[i * J + j] the
 * squared error of row i at J' = j + 1, t[i] its energy; fold k's rows
 * end at fold_end[k] (k < folds; the jackknife of the standard error
 * leaves out one fold at a time).  With row (row[i]: held-out row i's
 * place in the table) and the energies of all n_all table rows t_all the
 * splits are drawn from every table row, a row not held out given the
 * relative error of the held-out row nearest in energy rank; without
 * (NULL) from the held-out rows alone.  NaN without memory, n_split 0 or
 * more than the held-out rows. */
void job_cv_split_figure(const double *e, const double *t, const size_t *fold_end, size_t folds, const size_t *row,
                         const double *t_all, size_t n_all, size_t n_split, size_t J, double w, double *fig,
                         double *se);
double job_now(void);
void job_progress(const sb_job_t *job, const char *label, double fraction);
void job_warn(sb_job_t *job, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
/* (Re)check what the run asks of a measured table against what its data
 * support (job_support.c): a grid finer than the samples, terms that no
 * longer lower the error at the measured samples; replaces the warnings of
 * the previous check.  Nothing for analytic sources. */
void job_warn_support(sb_job_t *job);
/* A measured table's values refused (mean not positive) or warned about
 * (many negative rows) before any fit (job_support.c). */
sb_result_t job_check_values(sb_context_t *ctx, sb_job_t *job);
/* A warning for each candidate of --param auto lost to memory (the memory
 * limit, an allocation) or a failure, not those ranked out or too small
 * for J: a result that may be worse than a lost one is never silent. */
void job_warn_lost(sb_job_t *job);

/* The terms an attempt of layout `kind` on a matrix of smaller side mn is
 * fitted with: lv->terms, where job_terms_capped at most mn (a layout with
 * fewer rows, such as vndf's 8 slices, is fitted with all it has rather
 * than left out; with --max-error the kept fit is cut to the fewest terms
 * meeting the error anyway). */
size_t job_level_terms(const sb_job_t *job, const job_level_t *lv, sb_param_kind_t kind, size_t mn);
/* Whether layout k is fitted with all the rows it has where they are fewer
 * than the terms asked: with --max-error every layout; under auto the one
 * built on an RGL file's tables (vndf: its rows are the file's theta_i
 * slices, which no finer grid adds; not with --budget, whose search
 * takes a given J as fixed), else it would be left out and a worse layout
 * kept at J (orange film at J = 12: vh 0.096, vndf 1.7e-7 at
 * its 8 rows). */
int job_terms_capped(const sb_job_t *job, sb_param_kind_t k);
sb_result_t job_sample(sb_context_t *ctx, const sb_job_t *job, const job_level_t *lv, sb_param_kind_t kind,
                       sb_form_t form, job_attempt_t *a);
sb_result_t job_factor(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, int weighted, job_attempt_t *a);
/* The plan options of a's fit on level lv (a->weighted set), J terms,
 * and the terms job_factor fits there. */
sb_plan_opts_t job_plan_opts(const sb_job_t *job, const job_level_t *lv, const job_attempt_t *a, size_t J);
size_t job_fit_terms(const sb_job_t *job, const job_level_t *lv, const job_attempt_t *a);
/* A masked fit is a local optimum, and the closest fit to the valid cells
 * is not the best between them: fit a's matrix again with the early stop
 * (a sweep gaining less than 1e-3, at most 20 per stage) on level `full`
 * and keep that fit when its headline at J is lower.  Used for an explicit
 * layout's kept fit and for a warped refit (converged, a warped fit can
 * drift: GGX roughness 0.1 rose from 1.4 % at 10 sweeps to 6-130 %). */
sb_result_t job_keep_early_fit(sb_context_t *ctx, sb_job_t *job, const job_level_t *full, job_attempt_t *a);
/* The estimator's errors of a->f as stored (HALF or FLOAT) into a->est,
 * on the job's pairs, growing them up to lv->est_max_pairs. */
sb_result_t job_estimate(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a);
/* *q = f as stored (sb_factors_quantize with the job's --half): what a
 * shader reads.  Kept on the job while f is unchanged (its stamp), so the
 * estimate, the bands' own pairs and the written set's errors quantise
 * the kept fit once; *q is the job's (valid until the next call). */
sb_result_t job_quantized(sb_context_t *ctx, sb_job_t *job, sb_factors_t *f, const sb_factors_t **q);
/* a's estimate (on lv's pairs) and, with lv->metric_res, grid quadrature. */
sb_result_t job_measure(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a);
/* The plain fit breaking the band bounds on a tables layout: refitted
 * weighted cell by cell toward the light's grazing band (job_bandfit.c). */
sb_result_t job_band_refit(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a);
/* --max-error: the first k terms of a (fewer than its J) refitted so;
 * a keeps them (*kept 1) when the refit keeps the bounds with a headline
 * at most max_error, else a is as it was (job_bandfit.c). */
sb_result_t job_band_refit_prefix(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a, size_t k,
                                  double max_error, int *kept);
/* --max-error: keep the fewest terms of a whose headline meets it and
 * that keep the band bounds where some do (a prefix that meets it but
 * breaks them refitted toward the band first, job_band_refit_prefix), else
 * the fewest meeting it, else all (job_screen.c). */
sb_result_t job_keep_fewest(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a);
/* Whether a's headline at its J meets --max-error and keeps the bounds. */
int job_meets_bounded(const sb_job_t *job, const job_attempt_t *a);
/* The bands theta_i > 60, 80, 89 degrees of a's estimate measured again
 * on pairs drawn inside them (job_bandpairs.c), for the kept fit as
 * reported; nothing for a ranking's estimate, a scene's or sample_only. */
sb_result_t job_band_pairs_measure(sb_context_t *ctx, sb_job_t *job, job_attempt_t *a);
/* a's estimate as reported: a ranking's (lv.rank_only) is done again
 * with p99 and maxima, growing as lv allows. */
sb_result_t job_estimate_reported(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a);
/* a's estimate again on the job's pairs (growing them as lv says: each
 * prefix at the replicates a run of that many terms stops at), the errors
 * on the cells left as they are. */
sb_result_t job_estimate_again(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a);
/* After a->f changed (texels filtered, terms weighted): its errors on the
 * matrix's cells, then job_estimate_again. */
sb_result_t job_remeasure(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a);
/* Term j, channel c of f times w (g and h by sqrt(w), sigma by w). */
void job_scale_term(sb_factors_t *f, size_t j, size_t c, double w);
/* Put back terms kept aside by job_factors_copy (keep, with its term
 * weights term_w, NULL: all 1) in place of a's, and a's estimate with them. */
sb_result_t job_terms_restore(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a,
                              sb_factors_t *keep, double *term_w);
/* job_sample_weights.c: a scattered table's term weights at its samples */
sb_result_t job_sample_weights(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a);
/* Weight the terms of the kept fit a so that its headline is non-increasing
 * in J' (estimate.h sb_estimate_term_weights; a->term_w), then measure
 * its errors again; nothing when the weights are all 1 (the estimate's
 * headline already non-increasing per channel) or with o.plain_terms.  Weights that would raise the headline at
 * J more than JOB_WEIGHTS_MAX_LOSS times are dropped (a->weights_dropped). */
sb_result_t job_term_weights(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a);
/* The warning that the kept fit's term weights were dropped, if they were. */
void job_warn_weights(sb_job_t *job);
/* A layout named alone (layout_auto) whose headline at J exceeds this:
 * auto is run beside it on the same options, and a warning names auto's
 * choice and headline where it is better by half (job.c). */
#define JOB_EXPLICIT_POOR 0.5
/* Filter the texture axes of the kept fit a for bilinear lookups where
 * that lowers its headline at J (job_texels.c; a->texel_fit), then measure
 * its errors again (non-negative factors: texels clamped at 0); nothing
 * for a structured matrix or with o.plain_terms. */
sb_result_t job_texel_fit(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a);
/* *f (replaced) filtered along the texture axes of mask (bit 2 side + axis,
 * a->texel_fit), in the order job_texel_fit applies them: a refit given
 * the kept fit's texel choice (job_cv.c). */
sb_result_t job_texel_replay(sb_context_t *ctx, const sb_param_t *p, unsigned mask, sb_factors_t **f);
/* job_texel_fit, then job_term_weights: what every kept fit goes through. */
sb_result_t job_refine(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a);
void job_attempt_free(job_attempt_t *a);
/* Non-negative factors whose headline is above JOB_NONNEG_RATIO times the
 * SVD beside's at some J': the kept fit made again with those ratios
 * (the plan's nonneg_ratio) and refined, kept where its worst ratio to
 * the SVD beside is lower (job_screen.c). */
sb_result_t job_nonneg_refit(sb_context_t *ctx, sb_job_t *job);
/* Tests: 0 measures and refines the last refit in full even where its
 * factors are the refit before's (job_screen.c nonneg_refit_once). */
extern int job_nonneg_same_check;
/* Numbers per J' in job->svd_beside; channel c's headline of the SVD
 * beside at J' = j (NAN: none). */
#define JOB_BESIDE_STRIDE 5
double job_svd_headline_channel(const sb_job_t *job, size_t j, int c);
/* A copy of the first j terms of f (textures, sigma, metadata, errors). */
sb_result_t job_factors_copy(sb_context_t *ctx, const sb_factors_t *f, size_t j, sb_factors_t **out);
/* a takes t's fit (factors, estimate, stats, metric; t made from a copy
 * of a, sharing its matrix and layout), its own fit freed. */
void job_attempt_adopt(job_attempt_t *a, const job_attempt_t *t);
/* Whether the terms of a->f (those written) come from converged sweeps:
 * a fit of more terms whose later stage stopped at its sweep cap, cut to
 * a J before it, is converged (docs/measured.md, H5). */
int job_fit_converged(const job_attempt_t *a);
/* Keep the first j terms of a->f (errors and estimate with them). */
sb_result_t job_truncate(sb_context_t *ctx, job_attempt_t *a, size_t j);
int job_attempt_zero_fill(const sb_job_t *job, const job_attempt_t *a);
/* Smaller side of the matrix of `kind` at res cells per axis (the shape
 * of `shape`, NULL: the layout's own); 0 when it cannot be made there
 * (job_candidates.c). */
size_t job_layout_min_side(const sb_job_t *job, sb_param_kind_t kind, size_t res, const sb_param_opts_t *shape);
/* The candidates that screened into order: finest screening first, then
 * those keeping the band bounds (estimate.h) first, then by ascending
 * error; returns how many. */
size_t job_rank(const sb_job_t *job, size_t *order);
/* Candidate a before b by the screening alone (finest grid, then headline). */
int job_ranks_by_error(const sb_job_t *job, size_t a, size_t b);
/* The options of layout `kind` at level lv (its po, res, theta_max, and
 * the screening's half shape where it applies). */
sb_param_opts_t job_level_opts(const sb_job_t *job, const job_level_t *lv, sb_param_kind_t kind);
int job_attempt_masked(const sb_job_t *job, const job_attempt_t *a);

/* The job of opts on src (sb_job_run_source), its kept layout fitted as auto fits it when as_auto. */
/* The band errors theta_i > 80 and > 89 degrees after j terms (NAN
 * unknown; job_candidates.c). */
void job_band_errors(const sb_estimate_t *e, size_t j, double out[2]);
/* Whether a candidate breaking the band bounds (its band errors, headline)
 * may go before one keeping them: no worse in both bands and its headline
 * below the other's / JOB_BANDS_TRADE. */
#define JOB_BANDS_TRADE 2.0
int job_bands_trade(const double broken[2], double broken_err, const double keep[2], double keep_err);
/* A job inside a job: as_auto bit 0 fits an explicit layout as auto fits
 * its kept one, JOB_RUN_NO_GUARD runs no unweighted fit beside a scene's
 * (job_scene_guard.c: its own candidates), JOB_RUN_HEADLINE is read for
 * its fit's headline and rel_rms alone (job_svd_beside): no
 * cross-validation, band pairs or support warning, which its caller
 * measures on its own fit (the default gold's non-negative run: 0.07 s of
 * CPU, 7 %; docs/positive.md, round h38t). */
#define JOB_RUN_NO_GUARD 2
#define JOB_RUN_HEADLINE 4
sb_result_t job_run_as(sb_context_t *ctx, const sb_source_t *src, const sb_job_opts_t *opts, int as_auto,
                       sb_job_t **out);
/* Whether the solver named `name` (a method, or the factors' "method"
 * meta) gives non-negative factors by construction (SB_CAP_NONNEG). */
int job_nonneg_method(const char *name);

/* A small job on one thread (util/parallel.h: SB_SMALL_JOB_CELLS): the
 * thread cap (sb_thread_cap) of the job's run and write, from its
 * candidates' fits on an analytic source (a measured table's reading and
 * interpolation are not counted in cells, nor a scene's measure); 0 (none)
 * else. */
int job_thread_cap(const sb_job_t *job);

/* The candidates of the job (job->cands, job->ncand) and the kept one,
 * sampled and factored at the requested settings, in job->best. */
sb_result_t job_candidates(sb_context_t *ctx, sb_job_t *job, sb_param_kind_t kind, sb_form_t form);
sb_result_t job_select(sb_context_t *ctx, sb_job_t *job);
/* The cheap screening of several candidates (job.h; a measured table read
 * through a memo), recorded in job->cands and job->t.screen_s. */
void job_screen(sb_context_t *ctx, sb_job_t *job);
/* Sample and factor candidate c at the requested settings (o.res, o.terms,
 * job->shape) into job->best, as the kept one of job_select. */
sb_result_t job_fit_kept(sb_context_t *ctx, sb_job_t *job, const sb_job_candidate_t *c);
/* The rest of job_fit_kept's fit of job->best (the converged fit tried,
 * the estimate grown, refinement, --max-error's fewest terms), which it
 * leaves pending (FINISH_PENDING in job->fit_pending) where a warped fit
 * will be tried first (job_warp.c). */
#define FINISH_EARLY 1u     /* the fit was stopped early (auto) */
#define FINISH_CONVERGED 2u /* the converged fit is tried above JOB_CONVERGED_TRY */
#define FINISH_TWO 4u       /* two fits were compared on a ranking's estimate */
#define FINISH_PENDING 8u
sb_result_t job_fit_finish(sb_context_t *ctx, sb_job_t *job);
/* job_fit_kept; where `unfinished`, the fit is left before job_fit_finish
 * (*unfinished set: the caller finishes it with job_fit_finish, with
 * job->fit_pending as left, or frees it unfinished). */
sb_result_t job_fit_kept_unfinished(sb_context_t *ctx, sb_job_t *job, const sb_job_candidate_t *c, int *unfinished);
/* The level of the requested settings (o.res, o.terms, job->shape). */
job_level_t job_full_level(const sb_job_t *job);
/* The headline at the J the attempt kept (the estimate's last term beyond
 * SB_EST_MAXJ): what candidates are ranked by (job_screen.c). */
double job_rank_error(const job_attempt_t *a);
/* The masked fit's early stop (a sweep gaining less than 1e-3, at most 20
 * per stage) into lv, unless the caller set its own. */
void job_early_stop(const sb_job_t *job, job_level_t *lv);

/* opts.budget (job_budget.c): check the options against it (begin), then search
 * and fit the choice into job->best; the state is freed by
 * job_budget_free.  job_budget_written records what sb_job_write wrote
 * into dir (read back from the files). */
sb_result_t job_budget_begin(sb_context_t *ctx, sb_job_t *job, const sb_job_opts_t *in);
sb_result_t job_budget_select(sb_context_t *ctx, sb_job_t *job);
sb_result_t job_budget_written(sb_context_t *ctx, sb_job_t *job, const char *dir);
void job_budget_report(sb_json_t *j, const sb_job_t *job);
void job_budget_free(sb_job_t *job);

/* Scenes (job_scene.c).  Parse opts.scene into job->scene and check it
 * against the other options (SB_ERR_PARSE, SB_ERR_RANGE, SB_ERR_IO as
 * sb_scene_parse; SB_ERR_ARG with zero_fill). */
sb_result_t job_scene_open(sb_context_t *ctx, sb_job_t *job);
/* With a scene: mask a's matrix to the cells its pairs touch and make
 * a->scene_w for a's form (dense first: a structured matrix is expanded);
 * nothing when done for that form or without a scene. */
sb_result_t job_scene_prepare(sb_context_t *ctx, const sb_job_t *job, job_attempt_t *a);
/* With a scene: sample a's matrix (mo: the options of a plain build) on
 * the cells the scene's pairs touch only, the others masked unevaluated,
 * and make a->scene_w for mo's form. */
sb_result_t job_scene_sample(sb_context_t *ctx, const sb_job_t *job, const sb_matrix_opts_t *mo, job_attempt_t *a);
/* The estimator's pairs into job->pairs: the scene's; else below
 * --theta-max 90 the cap's (both directions within it: the snippet
 * returns 0 beyond, and the fit's weights are the domain's as before);
 * else the whole hemisphere pair's. */
sb_result_t job_pairs_create(sb_context_t *ctx, sb_job_t *job);
/* Pairs drawn within the --theta-max cap (both directions within it) into
 * *out: the estimator's without a scene, a scene's whole domain. */
sb_result_t job_cap_pairs(sb_context_t *ctx, sb_job_t *job, const sb_estimate_opts_t *eo, sb_pairs_t **out);
/* Whether the errors are measured within a --theta-max cap without a
 * scene (job_pairs_create). */
static inline int job_measures_cap(const sb_job_t *job) { return !job->scene && job->o.theta_max_deg < 90 - 1e-9; }
/* Whether channel c is factored (--channels): the others are written as 0
 * and every error of the job is over the factored channels only. */
static inline int job_factors_channel(const sb_job_t *job, int c) {
    return !job->o.channels || (job->o.channels >> c & 1u);
}
/* With a scene: the kept fit's estimate over the whole domain. */
sb_result_t job_scene_measure(sb_context_t *ctx, sb_job_t *job);
/* A scene fit against the same run without the scene beside it
 * (job_scene_guard.c decides, job.c's job_scene_guard runs and destroys
 * the jobs): whether the kept fit is one to compare; the unweighted fit
 * u's headlines recorded and *replace set where the scene fit is far
 * worse over the whole domain (JOB_SCENE_OUTSIDE) or, within, worse
 * inside the scene than u (JOB_SCENE_INSIDE; u's estimate then the
 * scene's); the next floor to try after the last
 * gave w (k zeroed: the first; w NULL: its run failed; k the walk's
 * state, set there), -1: none; whether
 * the scene fit with floor w is to be kept rather than v (either may be
 * NULL); the scene fit replaced by u or v, whichever is lower inside the
 * scene (the attempts set aside left in u and v). */
#define JOB_SCENE_FLOORS 7
extern const double job_scene_floors[JOB_SCENE_FLOORS];
int job_scene_guarded(const sb_job_t *job);
enum { JOB_SCENE_OUTSIDE = 1, JOB_SCENE_INSIDE = 2 }; /* why replaced: over the whole domain, inside */
sb_result_t job_scene_reference(sb_context_t *ctx, sb_job_t *job, sb_job_t *u, int *replace);
typedef struct job_floor_walk {
    int started, i, step, bisect; /* ladder index and direction; bisections left */
    double within, beyond;        /* the lowest floor within, the highest below it not */
} job_floor_walk_t;
double job_scene_next_floor(const sb_job_t *job, const sb_job_t *w, job_floor_walk_t *k);
/* the bound over the unweighted fit the floor the walk k gave is held to */
double job_scene_walk_bound(const job_floor_walk_t *k);
int job_scene_better(const sb_job_t *job, const sb_job_t *v, const sb_job_t *w, double bound);
sb_result_t job_scene_replace(sb_context_t *ctx, sb_job_t *job, sb_job_t *u, sb_job_t *v, double floor, int why);
/* report.json's "scene" object (null without a scene). */
void job_scene_report(sb_json_t *j, const sb_job_t *job);
void job_scene_free(sb_job_t *job);

/* opts.warp: NULL (the layout's own), "uniform", "merl" (kind set),
 * "adaptive" or "auto" (*adaptive = 1); SB_ERR_UNKNOWN otherwise
 * (job_warp.c). */
sb_result_t job_warp_parse(sb_context_t *ctx, const char *name, int *adaptive, sb_warp_kind_t *kind);
/* With opts.warp, the kept fit again on the warped layout (job_warp.c). */
sb_result_t job_warp_refit(sb_context_t *ctx, sb_job_t *job);
/* Whether the source is a scattered table of fewer than JOB_FEW_ROWS rows. */
int job_few_rows(const sb_job_t *job);
/* The warped layout screened against candidate c (job_fit_kept, where
 * warp_first would leave its fit pending): whether it wins there. */
int job_warp_screen(sb_context_t *ctx, sb_job_t *job, const sb_job_candidate_t *c);
sb_result_t job_warp_fit(sb_context_t *ctx, sb_job_t *job, const char *warp, const sb_param_t *like, sb_form_t form,
                         int weighted, job_attempt_t *a);
job_level_t job_screen_level(const sb_job_t *job, size_t res, sb_param_opts_t *po);
/* a's matrix fitted again on level lv; that fit replaces a's when its
 * headline at J is lower (job_warp_fit.c) */
sb_result_t job_keep_better_fit(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a);
/* Both axes' warps measured from the source (sb_warp_measure) into po,
 * for the texels per axis of `like` (job_warp_fit.c). */
sb_result_t job_warps_measure(sb_context_t *ctx, const sb_job_t *job, const sb_param_t *like, sb_param_opts_t *po);

#endif
