/* sepbrdf: the factor job, what `sepbrdf factor` does, as one library call.
 *
 *   open the source -> choose the candidates (parameterisation, form,
 *   weighting) -> screen them cheaply (param "auto") -> sample and factor the
 *   kept one -> comparable error -> write the output set (EXR textures,
 *   sepbrdf.glsl, report.json, optional previews).
 *
 * Screening (several candidates): every candidate is sampled and factored
 * on a coarse grid (SB_JOB_SCREEN_COARSE cells per axis, masked fits
 * stopped early), those that cannot win are dropped, the others screened
 * again on SB_JOB_SCREEN_RES cells (both at most R), and ranked by their
 * headline error at J (estimate.h: f cos theta_i as a shader returns it,
 * on the estimator's first pairs, shared by every candidate).  Layouts on
 * the source's own tables (vndf) are screened first; when one returns the
 * source at J (headline at most SB_JOB_SCREEN_EXACT, band bounds kept) the
 * others are not screened.  Forms f and
 * cos of one layout share one sampling.  Only the best is then sampled and
 * factored at the requested settings, exactly as a run that asks for it
 * alone.  A candidate that fails (too few cells for J, a numerical
 * failure) is recorded as failed and skipped; the job fails only when
 * none is left, or at once (SB_ERR_OVERFLOW) when a candidate's matrix at
 * R exceeds the memory limit (R is then too large whichever would win).
 * While screening, a measured table is evaluated through a memo: the
 * candidates' reference grids repeat pairs, each an interpolation.
 *
 * Candidates: every parameterisation that can be created at R, with forms f
 * and cos (or the one form asked for; cos not on a layout that folds by
 * reciprocity: f cos theta_i is not reciprocal; cos2 is no candidate, its
 * division by cos theta_o is unbounded near the horizon), solid-angle
 * weighted; iso only for
 * isotropic sources, and layouts that assume reciprocity (iso's phi_d fold)
 * only for reciprocal ones.  Asking for such a layout explicitly on a
 * non-reciprocal source runs it and adds a warning (sb_job_warning). */
#ifndef SEPBRDF_JOB_H
#define SEPBRDF_JOB_H

#include <stdio.h>

#include "common.h"
#include "estimate.h"
#include "factor.h"
#include "matrix.h"
#include "measured.h"
#include "outset.h"
#include "param.h"
#include "scene.h"
#include "source.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The source of a job that names none: gold, microfacet. */
#define SB_JOB_DEFAULT_SOURCE "microfacet:base=gold,roughness=0.5"
/* Cells per axis of the two screening grids of auto, and the
 * factor by which a candidate's error on the first may exceed the best
 * one's and still go on to the second. */
#define SB_JOB_SCREEN_COARSE 8
#define SB_JOB_SCREEN_RES 16
#define SB_JOB_SCREEN_DROP 2.0
/* A layout on the source's own tables (vndf) screened at or below this
 * headline returns the file to float rounding: the others are not
 * screened. */
#define SB_JOB_SCREEN_EXACT 1e-6

/* Progress of a job: a label ("sampling", "screening") and the fraction
 * of that stage done, 0..1; called on the calling thread only. */
typedef void (*sb_job_progress_fn)(void *user, const char *label, double fraction);

/* Settings of a job.  Zero (or NULL) means the default given.  The job
 * keeps a copy of `source` but refers to the other strings (param, form,
 * warp, scene, shaders): they must outlive the job.  Versioned by size,
 * as OpenEXR's exr_context_initializer_t: start from SB_JOB_OPTS_INIT
 * (or set size = sizeof(sb_job_opts_t)), and a later library that has
 * more fields reads only those your headers had (the others keep their
 * defaults); size 0 stands for this version's struct, so a zeroed struct
 * keeps working.  A size larger than the library's is SB_ERR_ARG. */
typedef struct sb_job_opts {
    size_t size;                 /* sizeof(sb_job_opts_t) of the caller's headers; 0: SB_JOB_OPTS_SIZE_0_1 */
    const char *source;          /* model spec or measured file; NULL: SB_JOB_DEFAULT_SOURCE */
    sb_measured_opts_t measured; /* how a measured table is read and interpolated */
    /* NULL or "auto": choose among the candidates; a kind name ("iso"):
     * auto's candidates on that layout (its forms and weighting, screened
     * and fitted as auto fits them; form, weighted and warp given still
     * decide); a whole spec ("iso:th=64,td=62,pd=16"): used as given */
    const char *param;
    const char *form; /* NULL: f (auto and a kind name: f and cos as auto makes them); "f", "cos", "cos2" */
    /* warps of the elevation axes (param.h) of a layout that takes them
     * (iso, hd): NULL the layout's own; "uniform"; "merl" (theta_h MERL's
     * square root, theta_d uniform); "adaptive" (both measured from the
     * source, sb_warp_measure); "auto" (adaptive where its headline at J
     * is lower than with the layout's own, else the own).  The candidates
     * are screened with the layouts' own warps; the kept one is then
     * sampled and fitted again, warped. */
    const char *warp;
    /* solid-angle weighting of an explicit param: 0 as auto (weighted, but
     * for a whole param spec or sample_only: unweighted), 1 weighted, -1
     * unweighted (auto's candidates: always weighted) */
    int weighted;
    /* A scene spec (scene.h) or NULL: with one, the fit is weighted by the
     * scene's pairs and skips the cells they never touch (instead of the
     * solid-angle weights), and the headline, with everything decided on
     * it (auto's ranking, term weights, max_error), is measured over the
     * scene's pairs; the whole domain's is sb_job_domain_estimate.  The
     * same run without the scene runs beside it, and a scene fit above
     * 1.8x its error over the whole domain is replaced unless the spec
     * gives floor=X (scene.h; report.json scene.fallback). */
    const char *scene;
    int zero_fill;           /* factor invalid cells as zeros instead of a masked fit */
    size_t res;              /* R, cells per angular axis: 32 */
    size_t terms;            /* J: 4; with max_error the upper limit, min(R, 32) */
    size_t metric_res;       /* reference grid of the comparable error: 32 */
    double max_error;        /* keep the fewest terms whose headline is <= this; 0 = off */
    double theta_max_deg;    /* largest sampled elevation, degrees: 90 */
    sb_method_t method;      /* SVD method: SB_METHOD_AUTO */
    unsigned long long seed; /* randomized methods: 1 */
    unsigned channels;       /* channels to factor (1 R, 2 G, 4 B): all */
    int fit_max_iters;       /* masked fit sweeps: the plan's default */
    double fit_tol;          /* masked fit tolerance: the plan's default */
    int plain_terms;         /* keep the factorisation's terms as they are: no term weights (estimate.h,
                                sb_estimate_term_weights) */
    int half;                /* sb_job_write: HALF textures with per-term scales */
    int previews;            /* sb_job_write: PNG previews of the textures too */
    int sample_only;         /* explicit param only: sample the matrix, factor later with sb_job_refactor */
    /* A byte budget: the texels of every texture written
     * (all terms, g and h, every channel, 4 bytes FLOAT or 2 HALF) may take
     * at most this many bytes; the job then chooses the layout, texture
     * shape, warp, J and storage of the lowest screened headline within it
     * (see "Byte budgets" below).  0: off.  What is given of param, form,
     * res, terms, half and warp constrains the search; max_error is
     * refused (SB_ERR_ARG), as is sample_only. */
    size_t budget;
    /* Scattered measured tables (Cornell, ALTA, CSV, simulated gonio): the
     * measurements cut into cv_folds folds (sb_measured_fold), the kept
     * layout, form and weighting refitted without each fold, and the
     * error of f cos theta_i at the measurements left out reported per J'
     * (sb_job_cv: what most random splits see).  0: 10 folds of which the
     * first 5 are refitted (five splits, each without a random tenth);
     * K >= 2: all K refitted; 1: none. */
    size_t cv_folds;
    const char *out;             /* sb_job_run also writes the set here (sb_job_write); NULL: no */
    sb_job_progress_fn progress; /* NULL: none */
    void *progress_user;
    /* Shading languages of the snippet besides sepbrdf.glsl (glsl.h,
     * sb_shader_translate): a comma list of "hlsl", "msl", "wgsl" ("glsl"
     * is always written; "all": every language), each written by
     * sb_job_write as sepbrdf.<ext> (sepbrdf.hlsl, sepbrdf.metal,
     * sepbrdf.wgsl).  NULL: GLSL only. */
    const char *shaders;
} sb_job_opts_t;
/* The defaults, with the size set: sb_job_opts_t o = SB_JOB_OPTS_INIT; */
#define SB_JOB_OPTS_INIT                                                                                               \
    { .size = sizeof(sb_job_opts_t) }
/* The size of sepbrdf 0.1's sb_job_opts_t, which a size of 0 stands for:
 * frozen (a field added later is beyond it). */
#define SB_JOB_OPTS_SIZE_0_1 (offsetof(sb_job_opts_t, shaders) + sizeof(const char *))

/* One candidate of the job and what its screening gave. */
typedef struct sb_job_candidate {
    sb_param_kind_t kind;
    sb_form_t form;
    int weighted;
    int ok;       /* it factored; 0: failed or not screened (message in `why`) */
    int dropped;  /* left out after the coarse screening: it cannot win */
    int kept;     /* the one factored at the requested settings */
    size_t res;   /* cells per axis of the grid `error` was measured on */
    double error; /* ranking error at J: the headline (estimate.h) on the estimator's first pairs; NAN if not ok */
    int bands_ok; /* sb_estimate_bands_bounded at J on the same pairs: 1 kept, 0 broken, -1 unknown; auto ranks
                     the candidates that keep the band bounds first when one does, unless the one breaking
                     them is no worse in both bands and below half its headline */
    double band_err[2]; /* the band errors theta_i > 80 and > 89 degrees at J on the same pairs (NAN unknown) */
    double time_s;      /* its screening, and for the kept one its full fit too */
    sb_result_t result; /* SB_OK, or the code of its failure (message in `why`) */
    char why[160];
} sb_job_candidate_t;

/* Wall-clock seconds of the stages. */
typedef struct sb_job_timings {
    double screen_s;   /* all candidates' screening (0 with one candidate) */
    double sample_s;   /* building the kept matrix */
    double factor_s;   /* its factorisation */
    double metric_s;   /* its grid quadrature (comparable_grid) */
    double estimate_s; /* the error estimator, in all */
    double write_s;    /* sb_job_write: textures, snippet, report, previews */
    double total_s;    /* the whole job, from sb_job_run to the end of the last write */
} sb_job_timings_t;

typedef struct sb_job sb_job_t;

/* Byte budgets (opts.budget).  The candidates' layouts and forms are
 * screened as auto screens them (above); then for each candidate left,
 * each texture shape of a ladder (R = 8 .. 128, at most 2^20 matrix cells;
 * iso also with 4R theta_h cells, cheap in bytes, and R/4 phi_d cells) and
 * each warp (the layout's own and, on layouts that take one, adaptive),
 * one screening fit (masked fits stopped early) with the most terms the
 * budget allows there gives, on the estimator's first pairs, the headline
 * of every J' <= J for HALF and for FLOAT storage: every (J', storage)
 * whose bytes fit is an entry of the search.  Along the ladder a layout
 * stops, from R = 16 on, after two R in a row whose best entry is no
 * better than its best so far; under auto, a candidate screened at more than
 * 8 times the best entry so far walks no ladder on its own warp (report.json
 * budget.ladders_skipped).  The entry of the lowest headline is fitted in full, as an
 * explicit layout would be.  Within one search a smaller budget's entries
 * are a subset of a larger one's, so its best is never better. */
typedef struct sb_job_budget_try {
    sb_param_kind_t kind;
    sb_form_t form;
    int adaptive;       /* elevation axes warped by tables measured from the source */
    size_t res;         /* R */
    size_t g[2], h[2];  /* width, height of the g and the h textures */
    size_t texels;      /* texels of one term: g and h, one channel */
    size_t terms;       /* J */
    int half;           /* storage HALF (2 bytes), else FLOAT (4) */
    size_t bytes;       /* terms * channels * texels * (2 or 4) */
    double headline;    /* screened headline at J (the estimator's first pairs) */
    int bands_ok;       /* sb_estimate_bands_bounded at J on the same pairs (1, 0, -1 unknown): the lowest headline
                           among entries keeping the band bounds is chosen when one does (entries breaking them
                           but no worse in both bands and below half the headline of every entry keeping
                           them compete too) */
    double band_err[2]; /* the band errors theta_i > 80 and > 89 degrees at J on the same pairs (NAN unknown) */
} sb_job_budget_try_t;

typedef struct sb_job_budget {
    size_t budget;              /* opts.budget */
    sb_job_budget_try_t chosen; /* the entry fitted in full */
    size_t bytes_float;         /* its textures stored as FLOAT */
    size_t bytes_half;          /* its textures stored as HALF */
    size_t bytes_written; /* texel bytes of the EXR files written, read back from their headers; 0 before a write */
    size_t file_bytes;    /* those files' sizes (headers included); 0 before a write */
    size_t fits;          /* screening fits made */
    double search_s;      /* seconds of the search (layout screening included) */
} sb_job_budget_t;

/* Open a source like sb_source_open, or a measured table file with mo
 * (NULL: defaults).  A spec whose name part holds '/' or '.' can only be a
 * file: if it does not exist or is not a regular file the call fails with
 * SB_ERR_IO ("PATH: No such file or directory"), not "unknown model". */
SB_API sb_result_t sb_job_source_open(sb_context_t *ctx, const char *spec, const sb_measured_opts_t *mo,
                                      sb_source_t **out);

/* Whether parameterisation `kind` applies to src (iso: isotropic and
 * reciprocal sources only; vh, rv: isotropic; vndf: an RGL file's
 * tables); 0 with a static reason in *why (why may be NULL). */
SB_API int sb_job_param_applies(sb_param_kind_t kind, const sb_source_t *src, const char **why);

/* Run the job: open the source, choose, factor and measure; with opts->out
 * also write the output set (sb_job_write).  *out receives the job (free
 * with sb_job_destroy).  Errors: SB_ERR_UNKNOWN (param or form name),
 * SB_ERR_RANGE (J larger than the matrix allows), the source's errors
 * (SB_ERR_IO, SB_ERR_FORMAT, SB_ERR_PARSE ...), SB_ERR_NUMERIC (no
 * candidate could be factored), SB_ERR_NOMEM. */
SB_API sb_result_t sb_job_run(sb_context_t *ctx, const sb_job_opts_t *opts, sb_job_t **out);

/* The same, on a source the caller owns (opts->source is then only
 * recorded as the spec); src must outlive the job. */
SB_API sb_result_t sb_job_run_source(sb_context_t *ctx, const sb_source_t *src, const sb_job_opts_t *opts,
                                     sb_job_t **out);

/* Factor the kept matrix again with `terms` terms (no sampling), replacing
 * the factors, statistics and comparable errors (studies over J). */
SB_API sb_result_t sb_job_refactor(sb_context_t *ctx, sb_job_t *job, size_t terms);

/* Write the output set of the job into the open output set `set`
 * (outset.h), without publishing it: g_KK.exr, h_KK.exr (K < J),
 * sepbrdf.glsl, report.json and, with opts->previews, the PNG previews,
 * each named with sb_outset_add.  For callers that manage the set
 * themselves (a signal handler that knows its staging folder).  Errors:
 * SB_ERR_IO, SB_ERR_NOMEM. */
SB_API sb_result_t sb_job_write_set(sb_context_t *ctx, sb_job_t *job, sb_outset_t *set);

/* Write the output set into the folder `dir` (created if missing) and
 * publish it as one unit (outset.h, command "factor"): dir then holds this
 * set, files of an earlier factor set that this one does not write (terms
 * K >= J) are gone, files sepbrdf did not write stay.  Errors: those of
 * sb_outset_begin and sb_outset_commit, SB_ERR_IO, SB_ERR_NOMEM. */
SB_API sb_result_t sb_job_write(sb_context_t *ctx, sb_job_t *job, const char *dir);

/* Write report.json's content (see docs/report.md) to fp (nothing for a NULL job
 * or fp). */
SB_API void sb_job_report(const sb_job_t *job, FILE *fp);

SB_API void sb_job_destroy(sb_job_t *job); /* accepts NULL */

/* ---- results (owned by the job) ----
 * Every accessor takes a NULL job: NULL pointers, "" for the source spec,
 * 0 counts and flags, SB_FORM_F, NAN errors, zeroed structs. */
SB_API const sb_source_t *sb_job_source(const sb_job_t *job);
SB_API const char *sb_job_source_spec(const sb_job_t *job);
SB_API const sb_factors_t *sb_job_factors(const sb_job_t *job);
SB_API const sb_param_t *sb_job_param(const sb_job_t *job);
SB_API const sb_matrix_t *sb_job_matrix(const sb_job_t *job);
SB_API sb_form_t sb_job_form(const sb_job_t *job);
SB_API int sb_job_weighted(const sb_job_t *job);
SB_API int sb_job_masked(const sb_job_t *job); /* a masked fit: prefixes of J are not the J' fits */
SB_API void sb_job_stats(const sb_job_t *job, sb_plan_stats_t *out);
/* 1 if the kept masked fit ran under auto's early stop (a sweep gaining
 * less than 1e-3, at most 20 sweeps a stage: docs/guide.md), so that a stage
 * ending at its cap is that stated rule, not a failure to converge. */
SB_API int sb_job_fit_early_stop(const sb_job_t *job);
SB_API const sb_metric_t *sb_job_metric(const sb_job_t *job); /* the grid quadrature (comparable_grid) */
SB_API const sb_estimate_t *sb_job_estimate(const sb_job_t *job);
/* With opts.scene: the scene, and the estimate over the whole domain of the
 * factors as stored (sb_job_estimate is then the scene's); NULL without. */
SB_API const sb_scene_t *sb_job_scene(const sb_job_t *job);
SB_API const sb_estimate_t *sb_job_domain_estimate(const sb_job_t *job);
/* The estimator's headline (f cos theta_i), comparable (f cos cos) and
 * negative fraction after J' terms; NAN beyond the terms it holds. */
SB_API double sb_job_headline(const sb_job_t *job, size_t terms);
/* Whether the headline does not rise with J' by more than two standard
 * errors plus 2 % (out of sample, more terms can fit the cells better and
 * the pairs between them worse); 1 for a NULL job. */
SB_API int sb_job_headline_non_increasing(const sb_job_t *job);
SB_API double sb_job_comparable(const sb_job_t *job, size_t terms);
SB_API double sb_job_negative(const sb_job_t *job, size_t terms);
/* rel_rms of the stored textures (after sb_job_write) after J' terms,
 * index 3 = all channels; NAN if unknown. */
SB_API double sb_job_rel_stored(const sb_job_t *job, size_t terms, size_t channel);
/* With a non-negative method (--method nmf): the same run with the
 * default method (the SVD, or the masked fit where cells are excluded) on
 * the kept layout, form and weighting, fitted with the same J; its
 * headline and rel_rms after J' terms, beside this job's (what positivity
 * costs).  NAN for other methods, after sb_job_refactor, or when that run
 * failed (a warning says why). */
SB_API double sb_job_svd_headline(const sb_job_t *job, size_t terms);
SB_API double sb_job_svd_rel_rms(const sb_job_t *job, size_t terms);
SB_API int sb_job_auto(const sb_job_t *job); /* several candidates were screened */
SB_API size_t sb_job_candidate_count(const sb_job_t *job);
/* The candidates of --param auto lost to memory (the memory limit, an
 * allocation) or a failure, each also a warning; not those ranked out or
 * too small for J.  0 for a NULL job. */
SB_API size_t sb_job_lost_count(const sb_job_t *job);
SB_API const sb_job_candidate_t *sb_job_candidate(const sb_job_t *job, size_t i);
SB_API void sb_job_timings(const sb_job_t *job, sb_job_timings_t *out);
/* The budget search (opts.budget): 1 and *out filled when the job ran with
 * one, else 0.  Its entries (every (layout, shape, warp, J, storage)
 * screened within the budget) by index; NULL beyond the count. */
SB_API int sb_job_budget(const sb_job_t *job, sb_job_budget_t *out);
SB_API size_t sb_job_budget_tried_count(const sb_job_t *job);
SB_API const sb_job_budget_try_t *sb_job_budget_tried(const sb_job_t *job, size_t i);
/* Warnings of the run (report.json "warnings"): a layout that folds a
 * non-reciprocal source; for a measured table, a grid finer than half the
 * samples' median spacing and terms beyond the last one that lowers the
 * error at the measured samples (sb_measured_sample_errors), checked again
 * by sb_job_refactor. */
SB_API size_t sb_job_warning_count(const sb_job_t *job);
/* The cross-validated error at J' terms (1..J) of a scattered table: the
 * relative L2 of f cos theta_i at the measurements a random split of a
 * fold's size (a tenth by default) leaves out, the figure such splits land
 * within 1.5x of most often, drawn from the measurements each refit
 * (sb_job_opts_t.cv_folds) left out; its standard error (the jackknife
 * over the refits) into *se (may be NULL); NaN (and 0 held out) when not
 * computed: analytic sources, grids (MERL, RGL), cv_folds 1, a NULL job or
 * J' out of range.  *held: the measurements held out. */
SB_API double sb_job_cv(const sb_job_t *job, size_t terms, double *se, size_t *held);
SB_API const char *sb_job_warning(const sb_job_t *job, size_t i);

#ifdef __cplusplus
}
#endif
#endif
