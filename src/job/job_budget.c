/* The factor job's byte budgets (job.h: opts.budget, "Byte budgets").
 *
 * bytes(J, shape, storage) = J * C * (texels of g + texels of h) * s,
 * C = 3 (the job's factors hold R, G, B; a channel not factored is
 * written as zeros), s = 4 for FLOAT, 2 for HALF: the texels of every file
 * written, what a GPU holds.  The per-term HALF scales and a warp's table
 * travel in the snippet and the headers, not in the budget.
 *
 * The search: the candidates' layouts and forms screened as auto does
 * (job_screen), then per candidate left, warp and texture shape of the
 * ladder one screening fit with the most terms the budget allows there
 * (masked fits stopped early, the estimator's first pairs); its prefixes
 * give the headline of every J' for FLOAT and HALF (a masked fit's
 * prefixes are fits, an SVD's are the truncated SVDs).  Every (J',
 * storage) within the budget is an entry; the lowest headline is fitted in
 * full (job_fit_kept) on its shape and warp. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "job_impl.h"
#include "sepbrdf/exr.h"
#include "util/internal.h"

#define BUDGET_CHANNELS 3
#define BUDGET_MAX_CELLS ((size_t)1 << 20) /* matrix cells of a screening fit: io, hd up to R = 32 */
#define BUDGET_LADDER (sizeof ladder / sizeof *ladder)
#define BUDGET_MAX_TERMS 32 /* terms of a screening fit (as --max-error's default cap) */
#define BUDGET_PATIENCE 2   /* R in a row no better than the best so far end a ladder ... */
#define BUDGET_MIN_STOP 16  /* ... from this R on (below, fits are cheap and errors can sit near 1) */
#define BUDGET_SHAPES 3     /* texture shapes per R (those a layout takes) */
#define BUDGET_HOPELESS 8.0 /* an own-warp ladder screened this many times worse than the best is not walked */

static const size_t ladder[] = {4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128};

/* One screening fit's layout options, and an entry of the search. */
typedef struct fit {
    size_t cand; /* index into job->cands */
    int failed;  /* its full fit failed */
    sb_param_opts_t po;
} fit_t;
typedef struct entry {
    sb_job_budget_try_t t;
    size_t fit;
} entry_t;

typedef struct job_budget {
    sb_job_budget_t res;
    size_t fixed_res, fixed_terms; /* given R and J (0: searched) */
    int half_only;                 /* HALF given: FLOAT not searched */
    int try_own, try_adaptive;     /* warps searched on layouts that take one */
    sb_warp_kind_t own;            /* the own warp: the layout's (DEFAULT), or uniform / merl as given */
    fit_t *fits;
    entry_t *v;
    size_t nfit, capfit, n, cap;
    size_t skipped;        /* ladders not walked (hopeless) */
    sb_param_opts_t shape; /* the choice's, job->shape while it is fitted */
} job_budget_t;

sb_result_t job_budget_begin(sb_context_t *ctx, sb_job_t *job, const sb_job_opts_t *in) {
    if (!in->budget) return SB_OK;
    if (in->max_error > 0)
        return sb_error(ctx, SB_ERR_ARG,
                        "a budget of %zu bytes chooses J itself; it takes no maximum error (%g): give one of the two",
                        in->budget, in->max_error);
    if (in->sample_only) return sb_error(ctx, SB_ERR_ARG, "a budget fits its choice: sample_only does not apply");
    job_budget_t *b = calloc(1, sizeof *b);
    if (!b) return sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    job->budget = b;
    b->res.budget = in->budget;
    b->fixed_res = in->res;
    b->fixed_terms = in->terms;
    b->half_only = in->half;
    int adaptive;
    sb_warp_kind_t kind;
    if (job_warp_parse(ctx, in->warp, &adaptive, &kind) != SB_OK) return SB_ERR_UNKNOWN;
    /* none given: a budget's default is auto (both, the better kept) */
    b->try_adaptive = adaptive || !in->warp;
    b->try_own = !in->warp || strcmp(in->warp, "adaptive") != 0;
    b->own = kind;
    return SB_OK;
}

void job_budget_free(sb_job_t *job) {
    if (!job->budget) return;
    free(job->budget->fits);
    free(job->budget->v);
    free(job->budget);
    job->budget = NULL;
}

/* Layout options of shape `variant` at R: 0 the layout's default, 1 four
 * times the theta_h cells (a th x 1 texture: cheap in bytes, fine where
 * specular peaks are narrow), 2 that and a quarter of R phi_d cells (the
 * axis that matters least); 1 and 2 only on layouts that take them (iso),
 * the others ignore those keys. */
static void shape_opts(const sb_job_t *job, size_t R, int variant, sb_param_opts_t *po) {
    memset(po, 0, sizeof *po);
    po->res = R;
    po->theta_max = job->o.theta_max_deg * SB_PI / 180;
    po->tables = sb_source_layout_tables(job->src); /* layouts built on the source's tables (vndf) */
    if (variant >= 1) po->res_theta_h = 4 * R;
    if (variant >= 2) po->res_phi_d = R / 4 < 2 ? 2 : R / 4;
}

/* Texels of one term and channel of a layout, 0 when it cannot be made;
 * rows/cols the matrix sides. */
static size_t shape_texels(sb_param_kind_t kind, const sb_param_opts_t *po, size_t *rows, size_t *cols) {
    sb_param_t *p = NULL;
    *rows = *cols = 0;
    if (sb_param_create(NULL, kind, po, &p) != SB_OK) return 0;
    *rows = sb_param_rows(p);
    *cols = sb_param_cols(p);
    sb_param_destroy(p);
    return *rows + *cols;
}

static size_t entry_bytes(size_t terms, size_t texels, int half) {
    size_t b;
    return sb_size_mul3(terms, BUDGET_CHANNELS * texels, half ? 2 : 4, &b) ? SIZE_MAX : b;
}

/* The most terms within the budget at `texels` per term (stored as HALF,
 * the smaller), at most the matrix side and BUDGET_MAX_TERMS, or the
 * given J when it fits; 0: none. */
static size_t terms_within(const job_budget_t *b, size_t texels, size_t side) {
    size_t per = entry_bytes(1, texels, 1), j = per ? b->res.budget / per : 0;
    if (b->fixed_terms) return b->fixed_terms <= j && b->fixed_terms <= side ? b->fixed_terms : 0;
    if (j > side) j = side;
    return j > BUDGET_MAX_TERMS ? BUDGET_MAX_TERMS : j;
}

static int push(sb_context_t *ctx, void **v, size_t *n, size_t *cap, size_t size) {
    if (*n < *cap) return 0;
    size_t c = *cap ? 2 * *cap : 64;
    void *w = realloc(*v, c * size);
    if (!w) return sb_error(ctx, SB_ERR_NOMEM, "out of memory"), -1;
    *v = w;
    *cap = c;
    return 0;
}

/* Entries of the estimate of fit f (storage `half`): every J' within the
 * budget (the given J alone when one is); the best headline into *best. */
static sb_result_t add_entries(sb_context_t *ctx, job_budget_t *b, const job_attempt_t *a, size_t f, int half,
                               double *best) {
    size_t gw, gh, hw, hh;
    sb_param_texture_size(a->param, SB_SIDE_G, &gw, &gh);
    sb_param_texture_size(a->param, SB_SIDE_H, &hw, &hh);
    for (size_t j = 1; j <= a->est->terms; j++) {
        size_t bytes = entry_bytes(j, gw * gh + hw * hh, half);
        double e = sb_estimate_headline(a->est, j);
        if (bytes > b->res.budget || (b->fixed_terms && j != b->fixed_terms) || !isfinite(e)) continue;
        if (push(ctx, (void **)&b->v, &b->n, &b->cap, sizeof *b->v)) return SB_ERR_NOMEM;
        entry_t *en = &b->v[b->n++];
        memset(en, 0, sizeof *en);
        en->fit = f;
        en->t.kind = sb_param_kind(a->param);
        en->t.form = a->m.form;
        en->t.adaptive = b->fits[f].po.warp[0].kind == SB_WARP_TABLE;
        en->t.res = b->fits[f].po.res;
        en->t.g[0] = gw, en->t.g[1] = gh, en->t.h[0] = hw, en->t.h[1] = hh;
        en->t.texels = gw * gh + hw * hh;
        en->t.terms = j;
        en->t.half = half;
        en->t.bytes = bytes;
        en->t.headline = e;
        en->t.bands_ok = sb_estimate_bands_bounded(a->est, j);
        job_band_errors(a->est, j, en->t.band_err);
        if (e < *best) *best = e;
    }
    return SB_OK;
}

/* The HALF estimate of a; a later term too small to store in HALF (J above
 * what HALF resolves) halves the terms until it fits. */
static sb_result_t measure_half(sb_context_t *ctx, sb_job_t *job, const job_level_t *lv, job_attempt_t *a) {
    int keep = job->o.half;
    job->o.half = 1;
    sb_result_t r = job_measure(ctx, job, lv, a);
    while ((r == SB_ERR_RANGE || r == SB_ERR_NUMERIC) && sb_factors_terms(a->f) > 1) {
        r = job_truncate(ctx, a, sb_factors_terms(a->f) / 2);
        if (r == SB_OK) r = job_measure(ctx, job, lv, a);
    }
    job->o.half = keep;
    return r;
}

/* The warps of a fit: the own (the layout's, or uniform / merl as given)
 * or measured from the source; nothing on a layout that takes none. */
static sb_result_t fit_warps(sb_context_t *ctx, const sb_job_t *job, sb_param_kind_t kind, int adaptive,
                             sb_param_opts_t *po) {
    const job_budget_t *b = job->budget;
    if (!(sb_param_kind_caps(kind) & SB_CAP_WARPS)) return SB_OK;
    for (int a = 0; a < SB_AXIS_COUNT_; a++)
        po->warp[a].kind = b->own == SB_WARP_MERL && a == SB_AXIS_THETA_D ? SB_WARP_UNIFORM : b->own;
    if (!adaptive) return SB_OK;
    sb_param_t *like = NULL;
    sb_result_t r = sb_param_create(ctx, kind, po, &like);
    if (r == SB_OK) r = job_warps_measure(ctx, job, like, po);
    sb_param_destroy(like);
    return r;
}

/* One screening fit of candidate ci on `shape` (and warp): the most terms
 * within the budget, the entries of its FLOAT (unless HALF was given) and
 * HALF estimates; *best the lowest headline among them (INFINITY: none).
 * A shape beyond BUDGET_MAX_CELLS or the budget is skipped; a fit that
 * fails is skipped too (only running out of memory ends the search). */
static sb_result_t screen_fit(sb_context_t *ctx, sb_job_t *job, size_t ci, const sb_param_opts_t *shape, int adaptive,
                              double *best) {
    job_budget_t *b = job->budget;
    const sb_job_candidate_t *c = &job->cands[ci];
    size_t rows, cols, cells, texels = shape_texels(c->kind, shape, &rows, &cols);
    size_t J = texels ? terms_within(b, texels, rows < cols ? rows : cols) : 0;
    *best = INFINITY;
    if (!J || sb_size_mul(rows, cols, &cells) || cells > BUDGET_MAX_CELLS) return SB_OK;
    if (push(ctx, (void **)&b->fits, &b->nfit, &b->capfit, sizeof *b->fits)) return SB_ERR_NOMEM;
    fit_t *f = &b->fits[b->nfit];
    memset(f, 0, sizeof *f);
    f->cand = ci;
    f->po = *shape;
    sb_result_t r = fit_warps(ctx, job, c->kind, adaptive, &f->po);
    if (r != SB_OK) return r == SB_ERR_NOMEM ? r : SB_OK;
    size_t fi = b->nfit++;
    job_level_t lv = {.res = shape->res, .terms = J, .po = &b->fits[fi].po, .est_max_pairs = 1, .rank_only = 1};
    job_early_stop(job, &lv);
    job_attempt_t a = {0};
    int keep = job->o.half;
    job->o.half = 0;
    r = job_sample(ctx, job, &lv, c->kind, c->form, &a);
    if (r == SB_OK) r = job_factor(ctx, job, &lv, c->weighted, &a);
    job->o.half = keep;
    if (r == SB_OK && !b->half_only) r = add_entries(ctx, b, &a, fi, 0, best);
    if (r == SB_OK && (r = measure_half(ctx, job, &lv, &a)) == SB_OK) r = add_entries(ctx, b, &a, fi, 1, best);
    job_attempt_free(&a);
    b->res.fits++;
    return r == SB_ERR_NOMEM ? r : SB_OK;
}

/* The lowest headline of the entries so far that keep the band bounds
 * (INFINITY: none). */
static double search_best(const job_budget_t *b) {
    double best = INFINITY;
    for (size_t i = 0; i < b->n; i++)
        if (b->v[i].t.bands_ok == 1 && b->v[i].t.headline < best) best = b->v[i].t.headline;
    return best;
}

/* Candidate ci along the ladder of R (the given R alone), each R in every
 * shape the layout takes; stops, from BUDGET_MIN_STOP on, after
 * BUDGET_PATIENCE R in a row whose best entry is no better than the best
 * so far (at a fixed budget the error falls with R while terms are cheap,
 * then rises as they run out; a sharp lobe leaves errors near 1 at small R,
 * rung after rung: patience 1 stopped the RGL vinyl at R = 6).  It stops
 * too, from BUDGET_MIN_STOP on, where its best is more than
 * SB_JOB_SCREEN_DROP times the search's best so far (other ladders', within
 * the band bounds) while its last R gained less than that factor: it
 * cannot win at the finer R, whose fits cost most (the Cornell acrylic's
 * io-area and unwarped hd at 0.99 against iso's 0.013, four R = 32 fits
 * of 10^6 cells: 41 -> 16 s CPU). */
static sb_result_t ladder_walk(sb_context_t *ctx, sb_job_t *job, size_t ci, int adaptive) {
    job_budget_t *b = job->budget;
    double best = INFINITY, prev = INFINITY, others = search_best(b);
    int worse = 0;
    for (size_t k = 0; k < BUDGET_LADDER; k++) {
        size_t R = b->fixed_res ? b->fixed_res : ladder[k], seen[BUDGET_SHAPES] = {0};
        double at = INFINITY;
        job_progress(job, "budget search", (double)k / BUDGET_LADDER);
        for (int v = 0; v < BUDGET_SHAPES; v++) {
            sb_param_opts_t po;
            size_t rows, cols;
            shape_opts(job, R, v, &po);
            seen[v] = shape_texels(job->cands[ci].kind, &po, &rows, &cols);
            int dup = seen[v] == 0;
            for (int u = 0; u < v; u++)
                dup |= seen[u] == seen[v];
            double e;
            sb_result_t r = dup ? SB_OK : screen_fit(ctx, job, ci, &po, adaptive, &e);
            if (r != SB_OK) return r;
            if (!dup && e < at) at = e;
        }
        if (b->fixed_res) break;
        int slow = !(at * SB_JOB_SCREEN_DROP < prev); /* this R gained less than the factor */
        if (isfinite(at)) prev = at;
        if (at < best) {
            best = at;
            worse = 0;
        } else if (isfinite(best) && ++worse >= BUDGET_PATIENCE && R >= BUDGET_MIN_STOP) {
            break;
        }
        if (R >= BUDGET_MIN_STOP && slow && best > SB_JOB_SCREEN_DROP * others) break;
    }
    return SB_OK;
}

/* Whether candidate i is searched in pass `dropped`: auto's left after
 * screening (pass 0) or those it dropped (pass 1), or the one asked for. */
static int searched(const sb_job_t *job, size_t i, int dropped) {
    const sb_job_candidate_t *c = &job->cands[i];
    return job->is_auto || job->layout_auto ? c->ok && !c->dropped == !dropped : i == 0 && !dropped;
}

/* The candidates searched, the lowest screened error first (then in
 * their order): the ladders likely to hold the best entry are walked
 * first, so that the others can stop early (ladder_walk). */
static size_t search_order(const sb_job_t *job, int dropped, size_t *order) {
    size_t n = 0;
    for (size_t i = 0; i < job->ncand; i++) {
        if (!searched(job, i, dropped)) continue;
        size_t k = n++;
        double e = job->cands[i].error;
        while (k > 0 && (isnan(job->cands[order[k - 1]].error) ? !isnan(e) : e < job->cands[order[k - 1]].error)) {
            order[k] = order[k - 1];
            k--;
        }
        order[k] = i;
    }
    return n;
}

/* Whether candidate i's ladder on its own warp cannot win, so is not
 * walked: auto screened it, on that warp, at more than BUDGET_HOPELESS
 * times the best entry of the ladders walked before it (within the band
 * bounds).  Its screening fit is one rung (the screening's R, J terms);
 * the ladder's finer rungs and more terms lowered that error by at most
 * 3.4x on the tables measured (the ALTA retro table's iso: 0.574
 * screened, 0.167 at R = 64, the winner; the Cornell acrylic's iso 0.545,
 * 0.255), and the stop of ladder_walk ends a ladder stuck that high at
 * R = 16.  What is saved is the rungs up to there: on the acrylic its
 * unwarped hd and io-area, f and cos (0.99-1.0 against iso's 0.013), and
 * unwarped iso, 34 of 67 fits. */
static int hopeless(const sb_job_t *job, size_t i) {
    const job_budget_t *b = job->budget;
    return (job->is_auto || job->layout_auto) && !b->fixed_res &&
           job->cands[i].error > BUDGET_HOPELESS * search_best(b);
}

/* Whether the candidates screening dropped are searched too: those it
 * kept hold no entry within the budget, or (auto) their best entry within
 * the bounds is above SB_JOB_SCREEN_DROP x their best screened error.
 * Screening drops by that factor at its own J; where the budget affords
 * far fewer terms of the layout kept, the comparison does not hold (RGL
 * orange: vndf screened at 0.056 with 4 terms, 6 KiB a term; at 8 KiB
 * one term, 0.37, against vh cos at 4 KiB, 0.17).  The premise of the
 * drop, by the same factor, fails there.  It costs where nothing better
 * is found: Phong 100 within 1 and 2 KiB (rv cos 0.0091, 0.0047 against
 * 0.002 screened) walks the dropped ladders, 0.4 -> 1.6 s, 0.5 -> 2.4 s
 * CPU, and keeps the same entry. */
static int search_dropped(const sb_job_t *job) {
    const job_budget_t *b = job->budget;
    if (b->n == 0) return 1;
    if (!(job->is_auto || job->layout_auto)) return 0;
    double screened = INFINITY;
    for (size_t i = 0; i < job->ncand; i++)
        if (searched(job, i, 0)) screened = fmin(screened, job->cands[i].error);
    return isfinite(screened) && search_best(b) > SB_JOB_SCREEN_DROP * screened;
}

/* Refuse a budget below the smallest texture set searched (the smallest
 * shape of the ladder, or the given R, with one term or the given J, as
 * HALF), before any work. */
static sb_result_t check_room(sb_context_t *ctx, const sb_job_t *job) {
    const job_budget_t *b = job->budget;
    size_t least = SIZE_MAX, R = b->fixed_res ? b->fixed_res : ladder[0], J = b->fixed_terms ? b->fixed_terms : 1;
    const char *name = "";
    for (size_t i = 0; i < job->ncand; i++) {
        if (job->cands[i].why[0] && job->is_auto) continue;
        for (int v = 0; v < BUDGET_SHAPES; v++) {
            sb_param_opts_t po;
            size_t rows, cols;
            shape_opts(job, R, v, &po);
            size_t t = shape_texels(job->cands[i].kind, &po, &rows, &cols), bytes = entry_bytes(J, t, 1);
            if (t && bytes < least) {
                least = bytes;
                name = sb_param_kind_name(job->cands[i].kind);
            }
        }
    }
    if (least <= b->res.budget) return SB_OK;
    if (least == SIZE_MAX)
        return sb_error(ctx, SB_ERR_ARG, "budget %zu bytes: no layout can be made at %zu cells per axis", b->res.budget,
                        R);
    return sb_error(ctx, SB_ERR_ARG,
                    "budget %zu bytes is too small: the smallest texture set searched (%s at %zu cells per axis, "
                    "%zu term%s, %d channels, HALF) takes %zu bytes",
                    b->res.budget, name, R, J, J == 1 ? "" : "s", BUDGET_CHANNELS, least);
}

/* Whether entry i breaks the band bounds where an entry keeps them and it
 * may not trade them for that entry (job_bands_trade). */
static int yields(const job_budget_t *b, size_t i) {
    const sb_job_budget_try_t *t = &b->v[i].t;
    if (t->bands_ok == 1) return 0;
    for (size_t k = 0; k < b->n; k++) {
        const sb_job_budget_try_t *u = &b->v[k].t;
        if (!b->fits[b->v[k].fit].failed && u->bands_ok == 1 &&
            !job_bands_trade(t->band_err, t->headline, u->band_err, u->headline))
            return 1;
    }
    return 0;
}

/* The entry of the lowest headline (fewer bytes on a tie) among fits not
 * failed, leaving out those that yield (above); SIZE_MAX when none. */
static size_t best_entry(const job_budget_t *b) {
    size_t k = SIZE_MAX;
    for (size_t i = 0; i < b->n; i++) {
        const sb_job_budget_try_t *e = &b->v[i].t;
        if (b->fits[b->v[i].fit].failed || yields(b, i)) continue;
        if (k == SIZE_MAX || e->headline < b->v[k].t.headline ||
            (e->headline == b->v[k].t.headline && e->bytes < b->v[k].t.bytes))
            k = i;
    }
    return k;
}

/* The kept fit's shortest prefix whose headline is lower than its own at
 * J by more than two standard errors (keeping the band bounds where J
 * keeps them): fewer bytes and a lower error, so the budget keeps that
 * prefix.  The screening's prefixes fell where the full fit's last term
 * rose (the default gold in 48 KiB: J = 6, 0.114 %, where J = 5 gave
 * 0.096 %, and a warning that fewer terms do better). */
static sb_result_t best_prefix(sb_context_t *ctx, sb_job_t *job, size_t fit) {
    job_budget_t *b = job->budget;
    const sb_estimate_t *e = job->best.est;
    size_t J = sb_factors_terms(job->best.f), k = 0;
    if (!e || J > e->terms || b->fixed_terms) return SB_OK; /* -J given: those terms */
    double hJ = sb_estimate_headline(e, J), seJ = e->se[J - 1][SB_EST_FCOS][SB_CH_ALL], best = hJ;
    for (size_t j = 1; j < J; j++) {
        double h = sb_estimate_headline(e, j), se = e->se[j - 1][SB_EST_FCOS][SB_CH_ALL];
        int bands = !b->res.chosen.bands_ok || sb_estimate_bands_bounded(e, j) == 1;
        if (bands && h + 2 * hypot(se, seJ) < hJ && h < best) best = h, k = j;
    }
    if (!k) return SB_OK;
    sb_result_t r = job_truncate(ctx, &job->best, k);
    if (r != SB_OK) return r;
    for (size_t i = 0; i < b->n; i++) /* the screening's entry of that prefix: its headline, bands, bytes */
        if (b->v[i].fit == fit && b->v[i].t.terms == k && b->v[i].t.half == b->res.chosen.half)
            b->res.chosen = b->v[i].t;
    b->res.chosen.terms = k;
    b->res.chosen.bytes = entry_bytes(k, b->res.chosen.texels, b->res.chosen.half);
    b->res.bytes_float = entry_bytes(k, b->res.chosen.texels, 0);
    b->res.bytes_half = entry_bytes(k, b->res.chosen.texels, 1);
    job->o.terms = k;
    return SB_OK;
}

/* Fit the best entry in full on its shape and warp (the next best shape
 * when that fails) into job->best. */
static sb_result_t fit_best(sb_context_t *ctx, sb_job_t *job) {
    job_budget_t *b = job->budget;
    sb_result_t r = SB_ERR_NUMERIC;
    size_t k = SIZE_MAX;
    while (r != SB_OK && (k = best_entry(b)) != SIZE_MAX) {
        const entry_t *e = &b->v[k];
        fit_t *f = &b->fits[e->fit];
        sb_job_candidate_t *c = &job->cands[f->cand];
        job->o.res = e->t.res;
        job->o.terms = e->t.terms;
        job->o.half = e->t.half;
        b->shape = f->po;
        job->shape = &b->shape;
        double t0 = job_now();
        r = job_fit_kept(ctx, job, c);
        c->kept = r == SB_OK;
        c->time_s += job_now() - t0;
        f->failed = r != SB_OK;
        if (r == SB_ERR_NOMEM) return r;
        if (r != SB_OK) continue;
        b->res.chosen = e->t;
        b->res.bytes_float = entry_bytes(e->t.terms, e->t.texels, 0);
        b->res.bytes_half = entry_bytes(e->t.terms, e->t.texels, 1);
    }
    if (r == SB_OK) return best_prefix(ctx, job, b->v[k].fit);
    if (b->res.fits == 0)
        return sb_error(ctx, SB_ERR_ARG,
                        "budget %zu bytes: no texture shape searched holds %s within it at up to %zu matrix cells (a "
                        "screening fit's limit; lower -r)",
                        b->res.budget, b->fixed_terms ? "the terms asked" : "one term", BUDGET_MAX_CELLS);
    const char *why = sb_context_last_error(ctx);
    return sb_error(ctx, SB_ERR_NUMERIC, "no layout could be factored within the budget of %zu bytes%s%s",
                    b->res.budget, why && *why ? ": " : "", why ? why : "");
}

sb_result_t job_budget_select(sb_context_t *ctx, sb_job_t *job) {
    job_budget_t *b = job->budget;
    double t0 = job_now();
    sb_result_t r = check_room(ctx, job);
    if (r != SB_OK) return r;
    if (job->is_auto || job->layout_auto) job_screen(ctx, job);
    /* the layouts screening dropped too where those it kept hold no term
     * within the budget (an RGL file's vndf: its h is the file's 32 x 32
     * grid, 6 KiB a term as HALF; a budget of 4 KiB failed, "lower -r")
     * or only far fewer terms than screening compared (search_dropped) */
    for (int dropped = 0; dropped < 2 && r == SB_OK && (!dropped || search_dropped(job)); dropped++) {
        size_t order[JOB_MAX_CANDS], n = search_order(job, dropped, order);
        for (size_t k = 0; k < n && r == SB_OK; k++) {
            size_t i = order[k];
            int warps = (sb_param_kind_caps(job->cands[i].kind) & SB_CAP_WARPS) != 0;
            if (b->try_adaptive && warps) r = ladder_walk(ctx, job, i, 1);
            if (r == SB_OK && (b->try_own || !warps) && hopeless(job, i))
                b->skipped++;
            else if (r == SB_OK && (b->try_own || !warps))
                r = ladder_walk(ctx, job, i, 0);
        }
    }
    job_progress(job, "budget search", 1);
    b->res.search_s = job_now() - t0;
    if (r == SB_OK) r = fit_best(ctx, job);
    if (r == SB_OK && !b->try_own && !(sb_param_caps(job->best.param) & SB_CAP_WARPS))
        job_warn(job, "%s has no axis that takes a warp; the warp asked for (%s) is not applied",
                 sb_param_name(job->best.param), job->o.warp);
    return r;
}

sb_result_t job_budget_written(sb_context_t *ctx, sb_job_t *job, const char *dir) {
    if (!job->budget) return SB_OK;
    return sb_exr_set_bytes(ctx, dir, &job->budget->res.bytes_written, &job->budget->res.file_bytes);
}

static void report_entry(sb_json_t *j, const sb_job_budget_try_t *e) {
    sb_json_string(j, "param", sb_param_kind_name(e->kind));
    sb_json_string(j, "form", sb_form_name(e->form));
    sb_json_string(j, "warp", e->adaptive ? "adaptive" : "own");
    sb_json_int(j, "resolution", (long long)e->res);
    for (int s = 0; s < 2; s++) {
        sb_json_begin_array(j, s ? "h" : "g");
        sb_json_int(j, NULL, (long long)(s ? e->h : e->g)[0]);
        sb_json_int(j, NULL, (long long)(s ? e->h : e->g)[1]);
        sb_json_end_array(j);
    }
    sb_json_int(j, "terms", (long long)e->terms);
    sb_json_string(j, "storage", e->half ? "half" : "float");
    sb_json_int(j, "bytes", (long long)e->bytes);
    sb_json_begin_array(j, "band_err");
    for (int b = 0; b < 2; b++)
        sb_json_number(j, NULL, e->band_err[b]);
    sb_json_end_array(j);
    sb_json_number(j, "headline", e->headline);
    if (e->bands_ok < 0)
        sb_json_string(j, "bands_ok", NULL);
    else
        sb_json_bool(j, "bands_ok", e->bands_ok);
}

void job_budget_report(sb_json_t *j, const sb_job_t *job) {
    const job_budget_t *b = job->budget;
    if (!b) return;
    sb_json_begin_object(j, "budget");
    sb_json_int(j, "bytes", (long long)b->res.budget);
    sb_json_begin_object(j, "chosen");
    report_entry(j, &b->res.chosen);
    sb_json_end_object(j);
    sb_json_int(j, "bytes_float", (long long)b->res.bytes_float);
    sb_json_int(j, "bytes_half", (long long)b->res.bytes_half);
    sb_json_int(j, "bytes_written", (long long)b->res.bytes_written);
    sb_json_int(j, "file_bytes", (long long)b->res.file_bytes);
    sb_json_int(j, "fits", (long long)b->res.fits);
    sb_json_int(j, "ladders_skipped", (long long)b->skipped);
    sb_json_number(j, "search_s", b->res.search_s);
    sb_json_begin_array(j, "tried"); /* per screening fit, its best entry */
    for (size_t f = 0; f < b->nfit; f++) {
        const sb_job_budget_try_t *e = NULL;
        for (size_t i = 0; i < b->n; i++)
            if (b->v[i].fit == f && (!e || b->v[i].t.headline < e->headline)) e = &b->v[i].t;
        if (!e) continue;
        sb_json_begin_object(j, NULL);
        report_entry(j, e);
        sb_json_end_object(j);
    }
    sb_json_end_array(j);
    sb_json_end_object(j);
}

int sb_job_budget(const sb_job_t *job, sb_job_budget_t *out) {
    if (!job || !job->budget) return 0;
    if (out) *out = job->budget->res;
    return 1;
}

size_t sb_job_budget_tried_count(const sb_job_t *job) { return job && job->budget ? job->budget->n : 0; }

const sb_job_budget_try_t *sb_job_budget_tried(const sb_job_t *job, size_t i) {
    return i < sb_job_budget_tried_count(job) ? &job->budget->v[i].t : NULL;
}
