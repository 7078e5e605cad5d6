/* The factor job's candidates: which layouts and forms --param auto
 * screens (the candidate rules), and whether each fits the memory limit. */
#include <math.h>
#include <string.h>

#include "job_impl.h"
#include "sample/stream.h"
#include "util/internal.h"
#include "util/parallel.h"

int sb_job_param_applies(sb_param_kind_t kind, const sb_source_t *src, const char **why) {
    unsigned flags = sb_source_flags(src);
    const char *w = NULL;
    if ((sb_param_kind_caps(kind) & SB_CAP_TABLES) && !(flags & SB_SOURCE_TABLES))
        w = "is built on an RGL file's own tables: factor an isotropic RGL .bsdf file";
    else if (!sb_param_kind_applies(kind, flags))
        w = "needs an isotropic source";
    else if ((sb_param_kind_caps(kind) & SB_CAP_FOLDS_RECIPROCITY) && !(flags & SB_SOURCE_RECIPROCAL))
        w = "assumes a reciprocal BRDF, f(wi, wo) = f(wo, wi), and this source is not";
    if (why) *why = w;
    return w == NULL;
}

/* Smaller side of the matrix of `kind` at res cells per axis (the shape
 * of `shape`, NULL: the layout's own); 0 when the parameterisation cannot
 * be created there. */
size_t job_layout_min_side(const sb_job_t *job, sb_param_kind_t kind, size_t res, const sb_param_opts_t *shape) {
    sb_param_t *p = NULL;
    sb_param_opts_t po = {0};
    if (shape) po = *shape;
    po.res = res;
    po.theta_max = job->o.theta_max_deg * SB_PI / 180;
    po.tables = sb_source_layout_tables(job->src);
    if (sb_param_create(NULL, kind, &po, &p) != SB_OK) return 0;
    size_t r = sb_param_rows(p), c = sb_param_cols(p);
    sb_param_destroy(p);
    return r < c ? r : c;
}

/* Whether candidate k's matrix at R fits the memory limit as job_sample
 * stores it: an isotropic source on io or io-area its R^3 distinct values,
 * else the dense matrix; with --method stream a matrix on those layouts is
 * evaluated block by block instead (sb_matrix_bytes), never chosen
 * silently: beyond memory it takes hours where a lower R takes seconds.
 * SB_ERR_OVERFLOW naming the bytes otherwise (through ctx, may be NULL). */
static sb_result_t cand_fits(sb_context_t *ctx, const sb_job_t *job, sb_param_kind_t k) {
    sb_param_t *p = NULL;
    sb_param_opts_t po = {0};
    po.res = job->o.res;
    po.theta_max = job->o.theta_max_deg * SB_PI / 180;
    po.tables = sb_source_layout_tables(job->src);
    if (sb_param_create(NULL, k, &po, &p) != SB_OK) return SB_OK; /* sb_job_run names the problem */
    unsigned ch = job->o.channels ? job->o.channels & 7u : 7u;
    size_t nch = (ch & 1) + ((ch >> 1) & 1) + ((ch >> 2) & 1), rows = sb_param_rows(p), cols = sb_param_cols(p);
    size_t cells, bytes = SIZE_MAX, R = job->o.res;
    int structured = (sb_param_caps(p) & SB_CAP_AZIMUTH_GRID) && (sb_source_flags(job->src) & SB_SOURCE_ISOTROPIC);
    int stream = sb_matrix_streamable(p);
    if (stream && job->o.method == SB_METHOD_STREAM) {
        sb_matrix_opts_t mo = {0};
        mo.channels = ch;
        mo.structured = 1; /* as job_sample builds it */
        bytes = sb_matrix_bytes(job->src, p, &mo);
    } else if (structured ? !sb_size_mul3(R, R, R, &cells) : !sb_size_mul(rows, cols, &cells)) {
        if (!sb_size_mul3(cells, nch, sizeof(double), &bytes)) sb_size_add(bytes, cells, &bytes);
    }
    sb_param_destroy(p);
    if (bytes <= sb_memory_limit()) return SB_OK;
    return sb_error(ctx, SB_ERR_OVERFLOW,
                    "%s at %zu cells per axis: %zu x %zu cells x %zu channels need more than %zu bytes, the memory "
                    "limit%s",
                    sb_param_kind_name(k), job->o.res, rows, cols, nch, sb_memory_limit(),
                    stream && job->o.method != SB_METHOD_STREAM
                        ? "; --method stream evaluates it block by block instead (slow)"
                        : "");
}

static sb_result_t cand_add(sb_context_t *ctx, sb_job_t *job, sb_param_kind_t k, sb_form_t form, int weighted) {
    sb_job_candidate_t *c = &job->cands[job->ncand++];
    memset(c, 0, sizeof *c);
    c->kind = k;
    c->form = form;
    c->weighted = weighted;
    c->error = NAN;
    size_t mn = job_layout_min_side(job, k, job->o.res, NULL);
    if ((sb_param_kind_caps(k) & SB_CAP_TABLES) && !sb_source_layout_tables(job->src))
        snprintf(c->why, sizeof c->why,
                 "%s is built on an RGL file's own tables: factor an isotropic RGL .bsdf file (%s has none)",
                 sb_param_kind_name(k), sb_source_description(job->src));
    else if (mn < job->o.terms && !job_terms_capped(job, k)) /* fitted with its mn terms (job_terms_capped) */
        snprintf(c->why, sizeof c->why, "%zu terms exceed the %zu rows/columns of %s at %zu cells per axis",
                 job->o.terms, mn, sb_param_kind_name(k), job->o.res);
    if (!job->is_auto && c->why[0] && (sb_param_kind_caps(k) & SB_CAP_TABLES))
        return sb_error(ctx, SB_ERR_UNSUPPORTED, "%s", c->why);
    if (!job->is_auto) return cand_fits(ctx, job, k);
    /* auto: a layout beyond the memory limit is left out, the others tried */
    if (!c->why[0] && cand_fits(NULL, job, k) != SB_OK)
        snprintf(c->why, sizeof c->why, "%s at %zu cells per axis needs more than the memory limit, %zu bytes",
                 sb_param_kind_name(k), job->o.res, sb_memory_limit());
    return SB_OK;
}

int job_few_rows(const sb_job_t *job) {
    const sb_measured_info_t *in = sb_measured_source_info(job->src);
    size_t n = in && in->dims ? sb_source_sample_count(job->src) : 0;
    return n > 0 && n < JOB_FEW_ROWS;
}

/* JOB_FEW_ROWS: auto (not --budget) keeps its iso f candidate alone,
 * where it has one; the others are not screened (a Cornell table of 3
 * rows: io f kept at 3.8 s CPU, more than the whole table's 2.8 s). */
static void few_rows_one(sb_job_t *job) {
    size_t keep = job->ncand;
    for (size_t i = 0; i < job->ncand; i++)
        if (job->cands[i].kind == SB_PARAM_ISO && job->cands[i].form == SB_FORM_F && !job->cands[i].why[0]) keep = i;
    if (!job->is_auto || job->budget || !job_few_rows(job) || keep == job->ncand) return;
    for (size_t i = 0; i < job->ncand; i++) {
        sb_job_candidate_t *c = &job->cands[i];
        if (i == keep || c->why[0]) continue;
        snprintf(c->why, sizeof c->why, "not screened: %zu rows cannot tell layouts apart (fewer than %d: iso f kept)",
                 sb_source_sample_count(job->src), JOB_FEW_ROWS);
        c->dropped = 1;
    }
}

/* The forms auto makes candidates of on layout k (*f: form f, or the
 * form asked for; *cos: form cos). */
static void auto_forms(const sb_job_t *job, sb_param_kind_t k, int *f, int *cos) {
    /* a layout on the source's tables holds their nodes in form cos (sb_param_cell_value) */
    int tables = (sb_param_kind_caps(k) & SB_CAP_TABLES) != 0;
    /* cos: not on a layout that folds by reciprocity (f cos theta_i is
     * not reciprocal); cos2 is none: dividing by cos theta_o is
     * unbounded near the horizon in what a shader outputs */
    *cos = !job->o.form && !(sb_param_kind_caps(k) & SB_CAP_FOLDS_RECIPROCITY);
    /* f: not where the data are f cos theta_i and cos serves (an RGL
     * file: its f reaches 1e10-1e12 at the horizon, and the screened fit
     * of hd on it cost a third of paper's default run for a headline of 4e4) */
    *f = !(tables && !job->o.form) && !(*cos && (sb_source_flags(job->src) & SB_SOURCE_STORES_COS));
}

/* An explicit layout: one candidate as given (sample_only, a whole spec,
 * a layout that does not apply to the source: form f unless asked,
 * unweighted unless asked) or, named alone, auto's candidates on it
 * (job.h: layout_auto), solid-angle weighted unless opts.weighted < 0. */
static sb_result_t explicit_candidates(sb_context_t *ctx, sb_job_t *job, sb_param_kind_t kind, sb_form_t form) {
    const char *why = NULL;
    if (!sb_job_param_applies(kind, job->src, &why)) {
        job_warn(job, "%s %s; the fit averages what the layout folds together", sb_param_kind_name(kind), why);
        /* auto has no candidate there: the plain fit (iso on the RGL files,
         * not reciprocal: weighted, 0.96, 0.95, 1.0 at J = 4 where plain
         * read 0.84, 0.90, 0.90) */
        if (job->layout_auto) job->layout_auto = job->fit_as_auto = 0;
    }
    /* non-negative factors solid-angle weighted (as auto's candidates):
     * their nested prefixes trade error between regions, and unweighted
     * the trade follows the grazing cells' values, not the integrated
     * error (GGX 0.3 on iso: 3.3x the SVD's headline at J' = 3, 1.2x weighted) */
    int nonneg = job_nonneg_method(sb_method_name(job->o.method));
    int w = job->layout_auto ? job->o.weighted >= 0 || nonneg : job->o.weighted > 0 || nonneg;
    int f = 1, cos = 0;
    if (job->layout_auto) auto_forms(job, kind, &f, &cos);
    sb_result_t r = SB_OK;
    if (f) r = cand_add(ctx, job, kind, job->o.form ? form : SB_FORM_F, w);
    if (r == SB_OK && cos) r = cand_add(ctx, job, kind, SB_FORM_COS, w);
    for (size_t i = 0; i < job->ncand; i++)
        job->cands[i].why[0] = 0; /* the plan names the problem itself */
    return r;
}

sb_result_t job_candidates(sb_context_t *ctx, sb_job_t *job, sb_param_kind_t kind, sb_form_t form) {
    job->ncand = 0;
    if (job->o.weighted < 0 && job_nonneg_method(sb_method_name(job->o.method)))
        job_warn(job,
                 "--unweighted is not applied: non-negative factors (--method %s) are always solid-angle "
                 "weighted",
                 sb_method_name(job->o.method));
    if (!job->is_auto) return explicit_candidates(ctx, job, kind, form);
    /* solid-angle weighted unless --unweighted (never for non-negative factors) */
    int w = job->o.weighted >= 0 || job_nonneg_method(sb_method_name(job->o.method));
    for (int i = 0; i < (int)sb_param_kind_count(); i++) {
        sb_param_kind_t k = (sb_param_kind_t)i;
        sb_result_t r = SB_OK;
        if (!sb_job_param_applies(k, job->src, NULL)) continue;
        if ((sb_param_kind_caps(k) & SB_CAP_AUTO_NONRECIPROCAL) && (sb_source_flags(job->src) & SB_SOURCE_RECIPROCAL))
            continue; /* a layout folding reciprocity serves these */
        if ((sb_param_kind_caps(k) & SB_CAP_AUTO_ANALYTIC) && (sb_source_flags(job->src) & SB_SOURCE_MEASURED))
            continue; /* the measured tables' own layouts serve these */
        if (job_layout_min_side(job, k, job->o.res, NULL) == 0) continue; /* not available at R */
        int f, cos;
        auto_forms(job, k, &f, &cos);
        if (r == SB_OK && f) r = cand_add(ctx, job, k, job->o.form ? form : SB_FORM_F, w);
        if (r == SB_OK && cos) r = cand_add(ctx, job, k, SB_FORM_COS, w);
        if (r != SB_OK) return r;
    }
    few_rows_one(job);
    if (job->ncand == 0)
        return sb_error(ctx, SB_ERR_UNSUPPORTED, "no parameterisation applies to %s at %zu cells per axis",
                        sb_source_description(job->src), job->o.res);
    size_t fit = 0;
    for (size_t i = 0; i < job->ncand; i++)
        fit += job->cands[i].why[0] == 0;
    if (fit == 0 && strstr(job->cands[0].why, "memory limit"))
        return sb_error(ctx, SB_ERR_OVERFLOW, "no parameterisation fits: %s (lower --res)", job->cands[0].why);
    if (fit == 0)
        return sb_error(ctx, SB_ERR_RANGE,
                        "%zu terms exceed the rows/columns of every parameterisation at %zu cells "
                        "per axis; ask for fewer terms or more cells",
                        job->o.terms, job->o.res);
    return SB_OK;
}

void job_band_errors(const sb_estimate_t *e, size_t j, double out[2]) {
    int ok = e && j >= 1 && j <= e->terms;
    out[0] = ok ? e->band[j - 1][SB_BAND_TI80][3] : NAN;
    out[1] = ok ? e->band[j - 1][SB_BAND_TI89][3] : NAN;
}

int job_bands_trade(const double broken[2], double broken_err, const double keep[2], double keep_err) {
    return broken[0] <= keep[0] && broken[1] <= keep[1] && JOB_BANDS_TRADE * broken_err < keep_err;
}

/* Candidates that screened, finest screening first, then (--max-error)
 * the fewest terms of the screening that meet it and keep the band bounds
 * (job_screen.c, cand_need; none last), then by ascending error; returns
 * how many.  One keeping the band bounds goes before one
 * breaking them, unless the one breaking them is no worse in both bands
 * and JOB_BANDS_TRADE x lower in the headline: a fit wrong everywhere
 * keeps the bounds too (RGL paper, R = 12, J = 3: hd f 99.9 % against vh
 * cos, lower in both bands), but RGL paper at J = 1 keeps vndf cos
 * (33 %, theta_i > 80 degrees 75 %) rather than io cos (17.8 %, 66 % above
 * its bound 53 %). */
static int ranks_before(const sb_job_t *job, size_t i, size_t k) {
    const sb_job_candidate_t *a = &job->cands[i], *b = &job->cands[k];
    size_t na = job->cand_need[i], nb = job->cand_need[k];
    if (a->res != b->res) return a->res > b->res;
    if (na != nb) return na && (!nb || na < nb); /* --max-error: the fewest terms meeting it within the bounds */
    if ((a->bands_ok == 1) != (b->bands_ok == 1)) {
        const sb_job_candidate_t *keep = a->bands_ok == 1 ? a : b, *broken = keep == a ? b : a;
        if (!job_bands_trade(broken->band_err, broken->error, keep->band_err, keep->error)) return keep == a;
    }
    return a->error < b->error;
}

size_t job_rank(const sb_job_t *job, size_t *order) {
    size_t n = 0;
    for (size_t i = 0; i < job->ncand; i++) {
        if (!job->cands[i].ok) continue;
        size_t k = n++;
        for (; k > 0 && ranks_before(job, i, order[k - 1]); k--)
            order[k] = order[k - 1];
        order[k] = i;
    }
    return n;
}

/* Candidate a before b by the screening alone (finest grid, then headline). */
int job_ranks_by_error(const sb_job_t *job, size_t a, size_t b) {
    const sb_job_candidate_t *x = &job->cands[a], *y = &job->cands[b];
    return x->res != y->res ? x->res > y->res : x->error < y->error;
}

/* cells: every candidate fitted at R on an R^3 grid (screening at coarser
 * grids and the table layouts' other shapes are not counted); none
 * counted (no cap) without candidates or under a byte budget, whose
 * ladder chooses R itself */
int job_thread_cap(const sb_job_t *job) {
    if (!job->src || !job->ncand || job->budget || (sb_source_flags(job->src) & SB_SOURCE_MEASURED) || job->scene)
        return 0;
    size_t R = job->o.res, cells = job->ncand * R * R * R;
    return sb_small_job_threads(cells);
}
