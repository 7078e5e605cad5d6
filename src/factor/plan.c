/* The factorisation plan and its execute driver.
 *
 * The plan picks a solver from the registry (solve/solver.h) for the
 * problem (shape, terms, method, mask, structure), plans it and allocates
 * every buffer execute needs.  Execute reads like the data flow:
 *     weight -> solve -> sign rule -> textures -> errors -> truncate -> metadata
 * with the errors of every truncation from one routine (factor/errors.h),
 * or exactly from solvers that know them (SB_CAP_EXACT_TAILS).  Execute
 * allocates only the factors it returns (the masked solver also gathers
 * the valid cells of the matrix at hand, fit.c). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "factor/errors.h"
#include "factor/plan_conv.h"
#include "sepbrdf/channels.h"
#include "solve/solver.h"
#include "util/internal.h"

/* |sum(u)| below this fraction of sum|u| counts as zero for the sign rule. */
#define SB_SIGN_TIE 1e-8

struct sb_plan {
    sb_context_t *ctx;
    size_t rows, cols, terms;
    sb_plan_opts_t opts;
    sb_solve_problem_t pb;       /* of the plan; execute adapts mask and period to the matrix */
    void *state[SB_SOLVERS_MAX]; /* planned solvers, by registry index */
    double *s, *u, *v;           /* one channel's terms (weighted space) */
    double *sbase;               /* sigma of the base channel (proportional channels) */
    double *x;                   /* weighted copy of a channel (weighted plans only) */
    double *wr, *wc;             /* row / column weights (weighted plans only) */
    double *ssq, *mx, *scratch;  /* errors: 3 J sums, 3 J maxima, residual scratch */
    int nthreads;                /* residual threads */
    int no_max;                  /* sb_plan_skip_max_: exact solvers' maxima not computed (NaN) */
    sb_plan_stats_t stats;
    size_t conv_terms;         /* the leading terms converged in every channel (plan_conv.h) */
    const sb_factors_t *start; /* the next execute's warm start (sb_plan_set_start) */
    sb_nmf_carry_t *carry;     /* the non-negative solver's rounds kept (sb_plan_set_nonneg_carry) */
};

/* What execute does to one matrix: the solver, channel order and scale. */
typedef struct run {
    const sb_matrix_t *m;
    const sb_param_t *param;
    size_t si; /* registry index of the solver */
    const sb_solver_t *sv;
    int prop, order[3];
    sb_channels_t chs;
    double pw, n2[3];
    const sb_factors_t *start; /* the warm start of this execute (sb_plan_set_start) */
} run_t;

/* Plan solver i of the registry unless it is planned already. */
static sb_result_t plan_solver(sb_plan_t *p, const sb_solve_problem_t *pb, size_t *index) {
    size_t i = sb_solver_index(pb);
    if (i >= sb_solver_count())
        return sb_error(p->ctx, SB_ERR_UNSUPPORTED, "plan: no solver takes a %zu x %zu matrix with %zu terms", pb->rows,
                        pb->cols, pb->terms);
    *index = i;
    if (p->state[i]) return SB_OK;
    return sb_solver_at(i)->plan(p->ctx, pb, &p->state[i]);
}

/* The solver for pb.  The dense solver that a structured one's unsuited
 * data fall back to is planned by execute when data do not suit
 * (choose_solver): an isotropic io run never needs it, and planning it
 * (the randomized SVD of the R^2 x R^2 matrix and its workspaces) was
 * 1.7 % of `factor --param io -r 64`'s instructions. */
static sb_result_t plan_solvers(sb_plan_t *p, const sb_solve_problem_t *pb) {
    size_t i = 0;
    return plan_solver(p, pb, &i);
}

/* Refuse up front what cannot fit: at least one channel of the matrix and
 * its mask (held by the caller), plus the weighted copy. */
static sb_result_t check_size(sb_context_t *ctx, size_t rows, size_t cols, int weighted, size_t *cells) {
    size_t need;
    if (sb_size_mul(rows, cols, cells) || sb_size_mul(*cells, 9 + (weighted ? 8 : 0), &need))
        return sb_error(ctx, SB_ERR_OVERFLOW,
                        "plan: a %zu x %zu matrix overflows the address space; lower the resolution", rows, cols);
    if (need > sb_memory_limit())
        return sb_error(ctx, SB_ERR_OVERFLOW,
                        "plan: a %zu x %zu matrix needs at least %zu bytes, more than the memory limit of %zu bytes; "
                        "lower the resolution",
                        rows, cols, need, sb_memory_limit());
    return SB_OK;
}

static sb_result_t alloc_buffers(sb_plan_t *p, size_t cells) {
    size_t rows = p->rows, cols = p->cols, J = p->terms;
    sb_context_t *ctx = p->ctx;
    p->nthreads = sb_thread_count(0);
    p->s = sb_alloc(ctx, J, sizeof(double), "plan");
    p->u = sb_alloc(ctx, rows * J, sizeof(double), "plan");
    p->v = sb_alloc(ctx, cols * J, sizeof(double), "plan");
    p->sbase = sb_alloc(ctx, J, sizeof(double), "plan");
    p->ssq = sb_alloc(ctx, 6 * J, sizeof(double), "plan");
    p->scratch = sb_alloc(ctx, sb_resid_scratch(rows, J, p->nthreads), sizeof(double), "plan");
    if (!p->s || !p->u || !p->v || !p->sbase || !p->ssq || !p->scratch) return SB_ERR_NOMEM;
    p->mx = p->ssq + 3 * J;
    if (!p->opts.weighted) return SB_OK;
    p->x = cells ? sb_alloc(ctx, cells, sizeof(double), "plan weighted matrix") : NULL; /* 0: structured */
    p->wr = sb_alloc(ctx, rows, sizeof(double), "plan");
    p->wc = sb_alloc(ctx, cols, sizeof(double), "plan");
    return (p->x || !cells) && p->wr && p->wc ? SB_OK : SB_ERR_NOMEM;
}

static sb_result_t plan_new(sb_context_t *ctx, size_t rows, size_t cols, const sb_plan_opts_t *opts,
                            const sb_matrix_t *m, sb_plan_t **out) {
    if (!out) return sb_error(ctx, SB_ERR_ARG, "plan: no output pointer");
    *out = NULL;
    sb_plan_opts_t o = {0};
    if (opts && sb_opts_take(ctx, opts, opts->size, SB_PLAN_OPTS_SIZE_0_1, &o, sizeof o, "plan: options") != SB_OK)
        return SB_ERR_ARG;
    o.size = sizeof o;
    if (o.terms == 0) o.terms = 4;
    size_t mn = rows < cols ? rows : cols, cells;
    if (rows == 0 || cols == 0) return sb_error(ctx, SB_ERR_ARG, "plan: empty matrix");
    if (o.terms > mn)
        return sb_error(ctx, SB_ERR_RANGE,
                        "plan: %zu terms exceed the matrix rank limit %zu; ask for fewer terms or a finer resolution",
                        o.terms, mn);
    if (!(o.max_error >= 0 && o.max_error < 1))
        return sb_error(ctx, SB_ERR_RANGE, "plan: maximum error %g out of range, need [0, 1)", o.max_error);
    if (!sb_method_known(o.svd.method)) return sb_error(ctx, SB_ERR_ARG, "plan: unknown method %d", (int)o.svd.method);
    sb_result_t rb = sb_blas_reserve(ctx);
    if (rb != SB_OK) return rb;
    int structured = m && m->structured; /* the R distinct rows are what is stored */
    int streamed = m && m->streamed;     /* nothing is stored */
    cells = 0;
    sb_result_t r = streamed ? SB_OK : check_size(ctx, structured ? m->ld : rows, cols, o.weighted, &cells);
    if (r != SB_OK) return r;
    sb_plan_t *p = calloc(1, sizeof *p);
    if (!p) return sb_error(ctx, SB_ERR_NOMEM, "plan: out of memory");
    *p = (sb_plan_t){.ctx = ctx, .rows = rows, .cols = cols, .terms = o.terms, .opts = o};
    p->pb = (sb_solve_problem_t){.rows = rows,
                                 .cols = cols,
                                 .terms = o.terms,
                                 .svd = o.svd,
                                 .fit_max_iters = o.fit_max_iters,
                                 .fit_tol = o.fit_tol,
                                 .max_error = o.max_error,
                                 .zero_fill = o.zero_fill,
                                 .nonneg_ratio = o.nonneg_ratio,
                                 .nonneg_ratio_channel = o.nonneg_ratio_channel,
                                 .nonneg_first_fit = o.nonneg_first_fit,
                                 .nonneg_rounds = o.nonneg_ratio ? o.nonneg_rounds : 0};
    sb_solve_problem_t pb = p->pb;
    if (m) {
        pb.masked = m->mask && !o.zero_fill;
        pb.period = m->mask ? 0 : m->phi_period;
        pb.streamed = streamed;
    }
    r = plan_solvers(p, &pb);
    if (r == SB_OK) r = alloc_buffers(p, structured ? 0 : cells);
    if (r != SB_OK) {
        sb_plan_destroy(p);
        return r;
    }
    *out = p;
    return SB_OK;
}

sb_result_t sb_plan_create(sb_context_t *ctx, size_t rows, size_t cols, const sb_plan_opts_t *opts, sb_plan_t **out) {
    return plan_new(ctx, rows, cols, opts, NULL, out);
}

sb_result_t sb_plan_create_for(sb_context_t *ctx, const sb_matrix_t *m, const sb_plan_opts_t *opts, sb_plan_t **out) {
    if (!m) return sb_error(ctx, SB_ERR_ARG, "plan: no matrix");
    return plan_new(ctx, m->rows, m->cols, opts, m, out);
}

void sb_plan_destroy(sb_plan_t *p) {
    if (!p) return;
    for (size_t i = 0; i < SB_SOLVERS_MAX; i++)
        if (p->state[i]) sb_solver_at(i)->destroy(p->state[i]);
    void *bufs[] = {p->s, p->u, p->v, p->sbase, p->x, p->wr, p->wc, p->ssq, p->scratch};
    for (size_t i = 0; i < sizeof bufs / sizeof bufs[0]; i++)
        free(bufs[i]);
    free(p);
}

size_t sb_plan_converged_terms(const sb_plan_t *p) { return p ? p->conv_terms : 0; }

void sb_plan_set_nonneg_carry(sb_plan_t *p, sb_nmf_carry_t *carry) {
    if (p) p->carry = carry;
}

void sb_plan_skip_max_(sb_plan_t *p, int skip) {
    if (p) p->no_max = skip != 0;
}

void sb_plan_stats(const sb_plan_t *p, sb_plan_stats_t *out) {
    sb_plan_stats_t none = {0, 0, 0, 0};
    if (out) *out = p ? p->stats : none;
}

/* ---- execute ------------------------------------------------------------ */

static sb_solve_in_t channel_in(const sb_plan_t *p, const run_t *rn, int ch) {
    const sb_matrix_t *m = rn->m;
    const double *a = m->data[ch], *wr = p->opts.weighted ? p->wr : NULL, *wc = p->opts.weighted ? p->wc : NULL;
    return (sb_solve_in_t){a, m->ld, a, m->ld, m->mask, wr, wc, rn->pw, rn->param, m, ch};
}

/* Step: the solver for this matrix (planned now if the plan was made
 * without it); a structured solver only when every channel suits it. */
static sb_result_t choose_solver(sb_plan_t *p, run_t *rn) {
    const sb_matrix_t *m = rn->m;
    sb_solve_problem_t pb = p->pb;
    pb.masked = m->mask && !p->opts.zero_fill;
    pb.period = m->mask ? 0 : m->phi_period;
    pb.streamed = m->streamed;
    sb_result_t r = plan_solvers(p, &pb);
    if (r != SB_OK) return r;
    rn->si = sb_solver_index(&pb);
    const sb_solver_t *sv = sb_solver_at(rn->si);
    for (int ch = 0; sv->suits && ch < 3; ch++) {
        sb_solve_in_t in = channel_in(p, rn, ch);
        if (m->data[ch] && !sv->suits(p->state[rn->si], &in)) {
            pb.period = 0;
            if ((r = plan_solver(p, &pb, &rn->si)) != SB_OK) return r;
            break;
        }
    }
    rn->sv = sb_solver_at(rn->si);
    return SB_OK;
}

/* Step: proportional channels (M_c = a_c M_base: grey or tinted BRDFs) are
 * factored once, base first; the check also gives the channel norms, which
 * bound max |M| for the power-of-two scale of the sums of squares.  A
 * streamed solver factors every channel in the same passes (no check; a
 * streamed matrix has no stored values to scan: scale 1). */
static void scan_channels(const sb_plan_t *p, run_t *rn) {
    sb_matrix_t scan = *rn->m; /* a structured solver: its distinct rows hold every value */
    if (rn->sv->distinct_rows)
        scan.rows = rn->sv->distinct_rows(p->state[rn->si]);
    else if (scan.structured)
        scan.rows = scan.ld;
    int have = !(rn->sv->caps & SB_CAP_STREAMED) && sb_channels_proportional(NULL, &scan, 0, &rn->chs) == SB_OK;
    double amax = 0;
    for (int ch = 0; ch < 3; ch++) {
        const double *a = scan.data[ch];
        for (size_t c = 0; a && c < scan.cols; c++)
            for (size_t i = 0; !have && i < scan.rows; i++)
                if (!scan.mask || scan.mask[i + c * scan.ld]) amax = fmax(amax, fabs(a[i + c * scan.ld]));
        if (have && a) amax = fmax(amax, rn->chs.norm[ch]);
    }
    rn->pw = sb_pow2_scale(amax);
    rn->prop = have && rn->chs.proportional && rn->chs.base >= 0;
    for (int c = 0; c < 3; c++)
        rn->order[c] = c;
    if (!rn->prop) return;
    rn->order[0] = rn->chs.base;
    for (int c = 0, n = 1; c < 3; c++)
        if (c != rn->chs.base) rn->order[n++] = c;
}

/* Step: X = W_r A W_c for solvers that read the weighted channel. */
static void weigh(sb_plan_t *p, const run_t *rn, sb_solve_in_t *in) {
    if (!p->opts.weighted || (rn->sv->caps & SB_CAP_STRUCTURED)) return;
    for (size_t c = 0; c < p->cols; c++)
        for (size_t i = 0; i < p->rows; i++)
            p->x[i + c * p->rows] = p->wr[i] * in->a[i + c * in->lda] * p->wc[c];
    in->x = p->x;
    in->ldx = p->rows;
}

/* Step: sign rule, sum(g_j) >= 0 with g_j = u_j / w_r; when the sum
 * vanishes to rounding (common for isotropic BRDFs, whose higher terms are
 * orthogonal to constants) the entry of largest magnitude is made positive
 * instead.  The product g_j h_j^T is unchanged. */
static void sign_rule(sb_plan_t *p) {
    size_t rows = p->rows, cols = p->cols;
    for (size_t j = 0; j < p->terms; j++) {
        double *u = p->u + j * rows, *v = p->v + j * cols, sum = 0, l1 = 0, big = 0;
        for (size_t i = 0; i < rows; i++) {
            double gi = p->opts.weighted && p->wr[i] > 0 ? u[i] / p->wr[i] : u[i];
            sum += gi;
            l1 += fabs(gi);
            if (fabs(gi) > fabs(big)) big = gi;
        }
        if (!(fabs(sum) > SB_SIGN_TIE * l1 ? sum < 0 : big < 0)) continue;
        for (size_t i = 0; i < rows; i++)
            u[i] = -u[i];
        for (size_t i = 0; i < cols; i++)
            v[i] = -v[i];
    }
}

void sb_plan_set_start(sb_plan_t *p, const sb_factors_t *start) {
    if (p) p->start = start;
}

/* Step: the warm start of channel ch for a masked fit (sb_plan_set_start):
 * u_j = g_j w_r / sqrt(s_j), v_j = h_j w_c / sqrt(s_j) (store_textures
 * undone) into p->u, p->v, s_j into p->s, handed to the solver; 0 where it
 * is not taken (no start, another solver or shape, a sigma <= 0). */
static int start_channel(sb_plan_t *p, const run_t *rn, int ch) {
    const sb_factors_t *st = rn->start;
    size_t rows = p->rows, cols = p->cols, J = p->terms, c = (size_t)ch, gw, gh, hw, hh;
    if (!st || rn->sv != &sb_solver_masked || sb_factors_terms(st) != J || sb_factors_channels(st) <= c) return 0;
    sb_factors_size(st, SB_SIDE_G, &gw, &gh);
    sb_factors_size(st, SB_SIDE_H, &hw, &hh);
    if (gw * gh != rows || hw * hh != cols) return 0;
    for (size_t j = 0; j < J; j++) {
        double sj = sb_factors_sigma(st, j, c), rt = sqrt(sj > 0 ? sj : 0);
        if (!(sj > 0) || !isfinite(sj)) return 0;
        const double *g = sb_factors_tex_const(st, SB_SIDE_G, j, c), *h = sb_factors_tex_const(st, SB_SIDE_H, j, c);
        p->s[j] = sj;
        for (size_t i = 0; i < rows; i++)
            p->u[i + j * rows] = g[i] * (p->opts.weighted ? p->wr[i] : 1) / rt;
        for (size_t i = 0; i < cols; i++)
            p->v[i + j * cols] = h[i] * (p->opts.weighted ? p->wc[i] : 1) / rt;
    }
    sb_solver_masked_start(p->state[rn->si], p->s, p->u, p->v);
    return 1;
}

/* Step: solve one channel; a proportional channel after the base takes the
 * base's vectors with sigma scaled by |a_c| (h negated for a_c < 0 when the
 * textures are stored). */
static sb_result_t solve(sb_plan_t *p, const run_t *rn, const sb_solve_in_t *in, int ch, int first) {
    if (rn->prop && !first) {
        for (size_t j = 0; j < p->terms; j++)
            p->s[j] = p->sbase[j] * fabs(rn->chs.scale[ch]);
        return SB_OK;
    }
    sb_solve_out_t out = {p->s, p->u, p->v, 0, 1, 0};
    start_channel(p, rn, ch); /* the masked fit copies its start before it writes out's */
    if (rn->sv == &sb_solver_nmf) sb_solver_nmf_carry(p->state[rn->si], p->carry);
    sb_result_t r = rn->sv->execute(p->state[rn->si], in, &out);
    if (out.iterations > p->stats.fit_iterations) p->stats.fit_iterations = out.iterations;
    if (!out.converged) p->stats.fit_converged = 0;
    size_t conv = out.converged_terms ? out.converged_terms : out.converged ? p->terms : 0;
    if (conv < p->conv_terms) p->conv_terms = conv;
    if (r != SB_OK) return r;
    if (!(rn->sv->caps & SB_CAP_NONNEG)) sign_rule(p);
    if (rn->prop) memcpy(p->sbase, p->s, p->terms * sizeof *p->s);
    return SB_OK;
}

/* Step: textures g_j = sqrt(s_j) u_j / w_r, h_j = sqrt(s_j) v_j / w_c. */
static void store_textures(const sb_plan_t *p, sb_factors_t *f, int ch, double hsign) {
    size_t rows = p->rows, cols = p->cols, c = (size_t)ch;
    for (size_t j = 0; j < p->terms; j++) {
        double sj = p->s[j], rt = sqrt(sj > 0 ? sj : 0);
        sb_factors_set_sigma(f, j, c, sj);
        double *g = sb_factors_tex(f, SB_SIDE_G, j, c), *h = sb_factors_tex(f, SB_SIDE_H, j, c);
        for (size_t i = 0; i < rows; i++) {
            double w = p->opts.weighted ? p->wr[i] : 1;
            g[i] = w > 0 ? rt * p->u[i + j * rows] / w : 0;
        }
        for (size_t i = 0; i < cols; i++) {
            double w = p->opts.weighted ? p->wc[i] : 1;
            h[i] = w > 0 ? hsign * rt * p->v[i + j * cols] / w : 0;
        }
    }
}

/* A non-finite sigma or texel of channel ch is a numerical failure of the
 * solver, named with the term and channel (never blamed on an option). */
static sb_result_t check_finite(const sb_plan_t *p, const run_t *rn, const sb_factors_t *f, int ch) {
    static const char names[] = "RGB";
    size_t rows = p->rows, cols = p->cols, c = (size_t)ch;
    for (size_t j = 0; j < p->terms; j++) {
        const double *g = sb_factors_tex_const(f, SB_SIDE_G, j, c), *h = sb_factors_tex_const(f, SB_SIDE_H, j, c);
        int ok = isfinite(sb_factors_sigma(f, j, c));
        for (size_t i = 0; i < rows && ok; i++)
            ok = isfinite(g[i]);
        for (size_t i = 0; i < cols && ok; i++)
            ok = isfinite(h[i]);
        if (!ok)
            return sb_error(p->ctx, SB_ERR_NUMERIC,
                            "factor: the %s solver gave non-finite values in term %zu of channel %c (%zu x %zu "
                            "matrix): a numerical failure",
                            rn->sv->name, j, names[c], rows, cols);
    }
    return SB_OK;
}

/* Step: errors of every truncation of one channel: exact from the solver,
 * or the residual pass of errors.h on the stored textures. */
static sb_result_t channel_errors(sb_plan_t *p, run_t *rn, const sb_factors_t *f, const sb_solve_in_t *in, int ch) {
    size_t J = p->terms, c = (size_t)ch;
    double *ssq = p->ssq + c * J, *mx = p->mx + c * J;
    if (rn->sv->caps & SB_CAP_EXACT_TAILS) {
        double t = rn->prop ? rn->chs.scale[ch] : 1; /* 1 for the base */
        for (size_t j = 0; p->no_max && j < J; j++)
            mx[j] = NAN;
        return rn->sv->exact(p->state[rn->si], in, t, J, ssq, p->no_max ? NULL : mx, &rn->n2[ch]);
    }
    sb_resid_t rs = {p->rows,
                     p->cols,
                     J,
                     in->a,
                     in->lda,
                     in->mask,
                     in->wr,
                     in->wc,
                     rn->pw,
                     sb_factors_tex_const(f, SB_SIDE_G, 0, c),
                     sb_factors_tex_const(f, SB_SIDE_H, 0, c),
                     3 * p->rows,
                     3 * p->cols};
    sb_resid_channel(&rs, p->nthreads, p->scratch, ssq, mx, &rn->n2[ch]);
    return SB_OK;
}

/* Step (SB_CAP_STREAMED): the errors of every channel's stored textures in
 * one more pass over the matrix, a block of columns at a time
 * (sb_resid_blocks). */
static sb_result_t stream_errors(sb_plan_t *p, run_t *rn, const sb_factors_t *f) {
    const double *g[3], *h[3], *wr = p->opts.weighted ? p->wr : NULL;
    for (size_t ch = 0; ch < 3; ch++) {
        g[ch] = sb_factors_tex_const(f, SB_SIDE_G, 0, ch);
        h[ch] = sb_factors_tex_const(f, SB_SIDE_H, 0, ch);
    }
    return sb_resid_blocks(p->ctx, rn->m, p->terms, g, h, 3 * p->rows, 3 * p->cols, wr, wr ? p->wc : NULL, rn->pw,
                           p->ssq, p->mx, rn->n2);
}

/* Step: relative errors, norms, and the truncation at the error asked for. */
static sb_result_t finish_errors(sb_plan_t *p, const run_t *rn, sb_factors_t *f) {
    sb_factor_errors_t *e = sb_factors_errors_mut(f);
    const sb_matrix_t *m = rn->m;
    int present[3] = {sb_matrix_has(m, 0), sb_matrix_has(m, 1), sb_matrix_has(m, 2)};
    sb_result_t r = sb_errors_relative(p->ctx, p->terms, present, p->ssq, p->mx, rn->n2, e->rel_rms, e->max_abs);
    if (r != SB_OK) return r;
    double total2 = 0;
    for (int ch = 0; ch < 3; ch++) {
        e->norm[ch] = present[ch] ? sqrt(rn->n2[ch]) / rn->pw : 0;
        total2 += present[ch] ? rn->n2[ch] : 0;
    }
    e->norm[3] = sqrt(total2) / rn->pw;
    for (size_t j = 0; p->opts.max_error > 0 && j < p->terms; j++)
        if (e->rel_rms[sb_err_at(j, SB_CH_ALL)] <= p->opts.max_error) {
            sb_factors_truncate(f, j + 1);
            break;
        }
    return SB_OK;
}

/* Whether the fit is an exact truncated SVD of every channel in the norm
 * errors.c measures (the cells' own measures): a solver with exact tails,
 * and proportional channels only where they are so to the last bit (a
 * channel within the tolerance of sb_channels_proportional takes the
 * base's vectors, which are not its own). */
static int exact_fit(const sb_plan_t *p, const run_t *rn) {
    if (!(rn->sv->caps & SB_CAP_EXACT_TAILS) || (p->opts.weighted && p->opts.row_weights && p->opts.col_weights))
        return 0;
    for (int c = 0; rn->prop && c < 3; c++)
        if (rn->chs.dev[c] != 0) return 0;
    return 1;
}

static sb_result_t check_execute(const sb_plan_t *p, const sb_matrix_t *m, const sb_param_t *param) {
    if (!m || !param) return sb_error(p->ctx, SB_ERR_ARG, "plan: missing matrix, parameterisation or output");
    if (!m->structured && m->ld < m->rows)
        return sb_error(p->ctx, SB_ERR_ARG, "plan: leading dimension %zu < %zu rows", m->ld, m->rows);
    if (m->rows != p->rows || m->cols != p->cols)
        return sb_error(p->ctx, SB_ERR_ARG, "plan: matrix is %zu x %zu, plan was made for %zu x %zu", m->rows, m->cols,
                        p->rows, p->cols);
    size_t gw, gh, hw, hh;
    sb_param_texture_size(param, SB_SIDE_G, &gw, &gh);
    sb_param_texture_size(param, SB_SIDE_H, &hw, &hh);
    if (gw * gh != p->rows || hw * hh != p->cols)
        return sb_error(p->ctx, SB_ERR_ARG,
                        "plan: parameterisation %s (%zu x %zu, %zu x %zu texels) does not match the %zu x %zu matrix",
                        sb_param_spec(param), gw, gh, hw, hh, p->rows, p->cols);
    return SB_OK;
}

/* A structured matrix for a solver that reads every cell: on a dense copy
 * (and the weighted workspace, which a plan made for it does not hold). */
static sb_result_t execute_expanded(sb_plan_t *p, const sb_matrix_t *m, const sb_param_t *param, sb_factors_t **out) {
    sb_matrix_t d;
    sb_result_t r = sb_matrix_expand(p->ctx, m, &d);
    if (r == SB_OK && p->opts.weighted && !p->x &&
        !(p->x = sb_alloc_large(p->ctx, p->rows * p->cols, sizeof(double), "plan weighted matrix")))
        r = SB_ERR_NOMEM;
    if (r == SB_OK) r = sb_plan_execute(p, &d, param, out);
    sb_matrix_free(&d);
    return r;
}

/* Step: the weights W_r, W_c, given (plan opts) or the cells' solid angles. */
static void plan_weights(sb_plan_t *p, const sb_param_t *param) {
    if (!p->opts.row_weights || !p->opts.col_weights) {
        sb_errors_weights(param, p->wr, p->wc);
        return;
    }
    memcpy(p->wr, p->opts.row_weights, p->rows * sizeof *p->wr);
    memcpy(p->wc, p->opts.col_weights, p->cols * sizeof *p->wc);
}

sb_result_t sb_plan_execute(sb_plan_t *p, const sb_matrix_t *m, const sb_param_t *param, sb_factors_t **out) {
    if (!p || !out) return sb_error(p ? p->ctx : NULL, SB_ERR_ARG, "plan: missing plan or output");
    *out = NULL;
    sb_result_t r = check_execute(p, m, param);
    run_t rn = {.m = m, .param = param, .start = p->start};
    p->start = NULL; /* this execute's alone */
    if (r == SB_OK && p->opts.weighted) plan_weights(p, param);
    if (r == SB_OK) r = choose_solver(p, &rn);
    if (r != SB_OK) return r;
    if ((m->structured || m->streamed) && !(rn.sv->caps & SB_CAP_STRUCTURED)) {
        p->start = rn.start; /* for the execute on the expanded matrix */
        return execute_expanded(p, m, param, out);
    }
    p->stats = (sb_plan_stats_t){m->mask && !p->opts.zero_fill, 0, 1, 0};
    p->conv_terms = p->terms;
    scan_channels(p, &rn);
    p->stats.proportional = rn.prop;
    size_t gw, gh, hw, hh;
    sb_param_texture_size(param, SB_SIDE_G, &gw, &gh);
    sb_param_texture_size(param, SB_SIDE_H, &hw, &hh);
    sb_factors_t *f;
    if ((r = sb_factors_create(p->ctx, p->terms, 3, gw, gh, hw, hh, &f)) != SB_OK) return r;
    memset(p->ssq, 0, 6 * p->terms * sizeof *p->ssq);
    for (int oi = 0; oi < 3 && r == SB_OK; oi++) {
        int ch = rn.order[oi];
        if (!sb_matrix_has(m, ch)) continue;
        sb_solve_in_t in = channel_in(p, &rn, ch);
        weigh(p, &rn, &in);
        r = solve(p, &rn, &in, ch, oi == 0);
        if (r != SB_OK) break;
        store_textures(p, f, ch, rn.prop && rn.chs.scale[ch] < 0 ? -1 : 1);
        if ((r = check_finite(p, &rn, f, ch)) != SB_OK) break;
        if (!(rn.sv->caps & SB_CAP_STREAMED)) r = channel_errors(p, &rn, f, &in, ch);
    }
    if (r == SB_OK && (rn.sv->caps & SB_CAP_STREAMED)) r = stream_errors(p, &rn, f);
    if (r == SB_OK) r = finish_errors(p, &rn, f);
    if (r != SB_OK) {
        sb_factors_destroy(f);
        return r;
    }
    sb_factors_set_meta(f, "param", sb_param_spec(param));
    sb_factors_set_meta(f, "form", sb_form_name(m->form));
    sb_factors_set_meta(f, "method", rn.sv->name);
    sb_factors_set_meta(f, "weighted", p->opts.weighted ? "1" : "0");
    /* an exact SVD in the norm errors.c measures (the cells' own measures) */
    if (exact_fit(p, &rn)) sb_factors_mark_exact(f);
    *out = f;
    return SB_OK;
}
