/* Stress: hostile and extreme inputs through sample -> factor -> store.
 *
 * Every fit goes through check_fit(), which asserts the invariants that
 * must hold whatever the input:
 *   - every output is finite: textures, sigma, errors, norms;
 *   - the same input factored twice (same plan, and a fresh plan) gives
 *     identical bits, and so does the same seed;
 *   - the error does not increase with J (unmasked fits);
 *   - exact methods on unmasked matrices meet Eckart-Young: sigma_j and
 *     rel_rms(J) = sqrt(sum_{k>J} s_k^2) / ||M|| against an independent
 *     LAPACKE_dgesvd of (W) M (W), to 1e-9 relative plus 16 N eps s_1/||M||
 *     (the backward error of an SVD grows with the size and with s_1/||M||);
 *     inexact ones (randomized) stay above that optimum and below the true
 *     sigma_j;
 *   - the sign rule of the plan (plan.c): sum(g_j) > 0, or, when that sum vanishes
 *     to 1e-8 of sum |g_j|, the entry of largest magnitude is positive;
 *   - sb_factors_errors_against() reproduces the plan's own errors;
 *   - the stored precision (FLOAT and HALF, sb_factors_quantize) is finite
 *     or refused with SB_ERR_RANGE, and its error is never below the
 *     optimum (exact unmasked fits) and never above the fit's error by more
 *     than the rounding can explain.
 * Sizes are kept so that the whole module runs in well under a minute on
 * two cores with the dense dgesdd path; R = 64 and R = 128 run only when a
 * top-k or randomized SVD is built in (they skip with a message otherwise). */
#include <float.h>
#include <lapacke.h>
#include <stdlib.h>
#include <string.h>

#include "fixtures.h"
#include "harness.h"
#include "sepbrdf/sepbrdf.h"
#include "util/shared.h" /* sizes, file errors: not exported, in the static archive */

/* ---- custom sources ----------------------------------------------------- */

typedef struct custom {
    int kind;
    double scale;  /* every value multiplied by this */
    int rank;      /* kind SEPARABLE: number of terms */
    int dependent; /* kind SEPARABLE: last g is the sum of the first two */
    const sb_source_t *inner;
} custom_t;

enum { ZERO, CONSTANT, SEPARABLE, SCALED, HOSTILE, GRAZING };

static double theta_of(const double w[3]) { return acos(fmin(fmax(w[2], -1), 1)); }

/* A few smooth, linearly independent functions of one direction. */
static double basis_g(int k, const double w[3]) {
    return cos(2 * k * theta_of(w) + 0.3 * k) * (1 + 0.25 * (k % 3) * w[0]);
}
static double basis_h(int k, const double w[3]) { return cos((2 * k + 1) * theta_of(w)) + 0.5 * (k % 2) * w[1]; }

/* Deterministic hash of a direction pair in [0, 1). */
static double pair_hash(const double wi[3], const double wo[3]) {
    unsigned long long s = 0x9e3779b97f4a7c15ULL;
    for (int i = 0; i < 3; i++) {
        s ^= (unsigned long long)(long long)(wi[i] * 1e6) + 0x632be59bd9b4e019ULL + (s << 6) + (s >> 2);
        s ^= (unsigned long long)(long long)(wo[i] * 1e6) + 0x632be59bd9b4e019ULL + (s << 6) + (s >> 2);
    }
    return sb_rand01(&s);
}

static int custom_eval(const void *self, const double wi[3], const double wo[3], double rgb[3]) {
    const custom_t *c = self;
    rgb[0] = rgb[1] = rgb[2] = 0;
    int known = 1;
    switch (c->kind) {
    case ZERO:
        break;
    case CONSTANT:
        rgb[0] = rgb[1] = rgb[2] = 0.3;
        break;
    case SEPARABLE:
        for (int k = 0; k < c->rank; k++) {
            double g = basis_g(k, wi), h = basis_h(k, wo);
            if (c->dependent && k == c->rank - 1) g = basis_g(0, wi) + basis_g(1, wi);
            for (int ch = 0; ch < 3; ch++)
                rgb[ch] += pow(0.5, k) * (1 + 0.1 * ch * k) * g * h;
        }
        break;
    case SCALED:
        known = sb_source_eval(c->inner, wi, wo, rgb);
        break;
    case HOSTILE: {
        known = sb_source_eval(c->inner, wi, wo, rgb);
        double u = pair_hash(wi, wo);
        if (u < 0.05)
            rgb[1] = NAN;
        else if (u < 0.10)
            rgb[0] = INFINITY;
        else if (u < 0.12)
            rgb[2] = -INFINITY;
        else if (u < 0.20) {
            rgb[0] = rgb[1] = rgb[2] = 0;
            known = 0; /* missing */
        } else if (u < 0.30)
            rgb[0] = rgb[1] = rgb[2] = -rgb[0]; /* negative values are values */
        break;
    }
    case GRAZING: { /* 1 / (cos theta_i cos theta_o): blows up at the horizon */
        double d = wi[2] * wo[2];
        rgb[0] = rgb[1] = rgb[2] = d > 0 ? 0.01 / d : 0;
        break;
    }
    }
    for (int ch = 0; ch < 3; ch++)
        rgb[ch] *= c->scale;
    return known;
}

/* A custom source (owns a copy of `c`). */
static sb_source_t *custom(custom_t c, unsigned flags) {
    custom_t *self = malloc(sizeof *self);
    *self = c;
    if (self->scale == 0) self->scale = 1;
    sb_source_ops_t ops = {custom_eval, free};
    sb_source_t *s = NULL;
    CHECK(sb_source_create(NULL, &ops, self, flags, "stress", &s) == SB_OK);
    return s;
}

/* ---- invariants --------------------------------------------------------- */

static int all_finite(const double *a, size_t n) {
    for (size_t i = 0; i < n; i++)
        if (!isfinite(a[i])) return 0;
    return 1;
}

static void check_finite(const sb_factors_t *f, const char *label) {
    size_t J = sb_factors_terms(f), C = sb_factors_channels(f);
    for (int s = 0; s < 2; s++) {
        size_t w, h;
        sb_factors_size(f, s, &w, &h);
        for (size_t j = 0; j < J; j++)
            for (size_t c = 0; c < C; c++)
                CHECKF(all_finite(sb_factors_tex_const(f, s, j, c), w * h), "%s: texture %c_%zu channel %zu not finite",
                       label, s ? 'h' : 'g', j, c);
    }
    const sb_factor_errors_t *e = sb_factors_errors(f);
    for (size_t j = 0; j < J; j++) {
        for (size_t c = 0; c < C; c++)
            CHECKF(isfinite(sb_factors_sigma(f, j, c)) && sb_factors_sigma(f, j, c) >= 0, "%s: sigma_%zu = %g", label,
                   j, sb_factors_sigma(f, j, c));
        CHECKF(all_finite(e->rel_rms + j * 4, 4) && all_finite(e->max_abs + j * 4, 4), "%s: errors of J=%zu not finite",
               label, j + 1);
    }
    CHECKF(all_finite(e->norm, 4), "%s: norm not finite", label);
}

static int same_bits(const sb_factors_t *a, const sb_factors_t *b) {
    size_t J = sb_factors_terms(a), C = sb_factors_channels(a);
    if (J != sb_factors_terms(b) || C != sb_factors_channels(b)) return 0;
    for (int s = 0; s < 2; s++) {
        size_t w, h;
        sb_factors_size(a, s, &w, &h);
        for (size_t j = 0; j < J; j++)
            for (size_t c = 0; c < C; c++)
                if (memcmp(sb_factors_tex_const(a, s, j, c), sb_factors_tex_const(b, s, j, c), w * h * sizeof(double)))
                    return 0;
    }
    const sb_factor_errors_t *ea = sb_factors_errors(a), *eb = sb_factors_errors(b);
    for (size_t j = 0; j < J; j++)
        for (size_t c = 0; c < C; c++)
            if (memcmp(&ea->rel_rms[j * 4 + c], &eb->rel_rms[j * 4 + c], sizeof(double)) ||
                sb_factors_sigma(a, j, c) != sb_factors_sigma(b, j, c))
                return 0;
    return 1;
}

/* The sign rule of the plan (plan.c), with margins around its 1e-8 tie threshold. */
static void check_signs(const sb_factors_t *f, const sb_matrix_t *m, const char *label) {
    size_t J = sb_factors_terms(f), n = m->rows;
    for (size_t j = 0; j < J; j++)
        for (size_t c = 0; c < 3; c++) {
            if (!m->data[c]) continue;
            const double *g = sb_factors_tex_const(f, SB_SIDE_G, j, c);
            double sum = 0, l1 = 0, big = 0, second = 0;
            for (size_t i = 0; i < n; i++) {
                sum += g[i];
                l1 += fabs(g[i]);
                if (fabs(g[i]) > fabs(big)) big = g[i];
            }
            if (l1 == 0) continue; /* a zero term has no sign */
            for (size_t i = 0; i < n; i++)
                if (g[i] * big < 0 && fabs(g[i]) > fabs(second)) second = g[i];
            if (fabs(sum) > 2e-8 * l1)
                CHECKF(sum > 0, "%s: term %zu channel %zu: sum(g) = %g < 0", label, j, c, sum);
            else if (fabs(sum) < 0.5e-8 * l1 && fabs(second) < fabs(big) * (1 - 1e-9))
                CHECKF(big > 0, "%s: term %zu channel %zu: sum(g) ~ 0 and largest entry %g < 0", label, j, c, big);
        }
}

/* Singular values of X (rows x cols, ld rows) by dgesvd, values only. */
static double *ref_sigma(const double *x, size_t rows, size_t cols) {
    size_t mn = rows < cols ? rows : cols;
    double *c = malloc(rows * cols * sizeof *c), *s = malloc(mn * sizeof *s), *sup = malloc(mn * sizeof *sup);
    memcpy(c, x, rows * cols * sizeof *c);
    lapack_int info = LAPACKE_dgesvd(LAPACK_COL_MAJOR, 'N', 'N', (lapack_int)rows, (lapack_int)cols, c,
                                     (lapack_int)rows, s, NULL, 1, NULL, 1, sup);
    CHECK(info == 0);
    free(c);
    free(sup);
    return s;
}

/* Eckart-Young for every J' and channel (see the top of the file): equal
 * for exact methods; for the others never below the optimum, and sigma_j
 * never above the true one (B = Q^T M interlaces). */
static void check_eckart_young(const sb_factors_t *f, const sb_matrix_t *m, const sb_param_t *p, int weighted,
                               int exact, const char *label) {
    size_t rows = m->rows, cols = m->cols, mn = rows < cols ? rows : cols, J = sb_factors_terms(f);
    const sb_factor_errors_t *e = sb_factors_errors(f);
    double *x = malloc(rows * cols * sizeof *x);
    for (int ch = 0; ch < 3; ch++) {
        if (!m->data[ch]) continue;
        for (size_t c = 0; c < cols; c++)
            for (size_t r = 0; r < rows; r++) {
                double w = weighted ? sqrt(sb_param_row_measure(p, r) * sb_param_col_measure(p, c)) : 1;
                x[r + c * rows] = w * m->data[ch][r + c * m->ld];
            }
        double *s = ref_sigma(x, rows, cols);
        if (s[0] == 0) { /* the zero matrix */
            for (size_t j = 0; j < J; j++)
                CHECK(sb_factors_sigma(f, j, (size_t)ch) == 0 && e->rel_rms[j * 4 + (size_t)ch] == 0);
            free(s);
            continue;
        }
        /* squares of s / s_1: no underflow for denormal matrices */
        double n2 = 0, kappa, tail = 0;
        for (size_t k = 0; k < mn; k++)
            n2 += (s[k] / s[0]) * (s[k] / s[0]);
        kappa = 1 / sqrt(n2); /* s_1 / ||M||_F */
        double tol_abs = 16 * (double)mn * DBL_EPSILON * kappa;
        for (size_t j = 0; j < J; j++) {
            tail = 0;
            for (size_t k = j + 1; k < mn; k++)
                tail += (s[k] / s[0]) * (s[k] / s[0]);
            double ref = sqrt(tail / n2), got = e->rel_rms[j * 4 + (size_t)ch], sj = sb_factors_sigma(f, j, (size_t)ch);
            double stol = 1e-9 * s[j] + 16 * (double)mn * DBL_EPSILON * s[0];
            if (exact) {
                CHECKF(fabs(got - ref) <= 1e-9 * ref + tol_abs,
                       "%s: channel %d J=%zu: rel_rms %.17g, Eckart-Young %.17g", label, ch, j + 1, got, ref);
                CHECKF(fabs(sj - s[j]) <= stol, "%s: channel %d sigma_%zu %.17g, dgesvd %.17g", label, ch, j, sj, s[j]);
            } else {
                CHECKF(got >= ref - 1e-9 * ref - tol_abs,
                       "%s: channel %d J=%zu: rel_rms %.17g below the Eckart-Young optimum %.17g", label, ch, j + 1,
                       got, ref);
                CHECKF(sj <= s[j] + stol, "%s: channel %d sigma_%zu %.17g above the true %.17g", label, ch, j, sj,
                       s[j]);
            }
        }
        free(s);
    }
    free(x);
}

/* The stored precision: quantize as the EXR writer would, measure the
 * error of what is stored against m. */
static void check_stored(const sb_factors_t *f, const sb_matrix_t *m, const sb_param_t *wp, int not_optimal,
                         const char *label) {
    size_t J = sb_factors_terms(f);
    const sb_factor_errors_t *e = sb_factors_errors(f);
    double *rel = malloc(J * 4 * sizeof *rel), *mx = malloc(J * 4 * sizeof *mx);
    for (int half = 0; half < 2; half++) {
        sb_context_t *ctx;
        sb_context_create(&ctx);
        sb_exr_opts_t eo = {half};
        sb_factors_t *q = NULL;
        sb_quantize_info_t qi;
        sb_result_t r = sb_factors_quantize(ctx, f, &eo, &q, &qi);
        if (r == SB_ERR_RANGE || r == SB_ERR_NUMERIC) { /* refused loudly: fine, as long as it says why */
            CHECKF(strlen(sb_context_last_error(ctx)) > 0, "%s: %s without a message", label, sb_result_name(r));
            sb_context_destroy(ctx);
            continue;
        }
        CHECKF(r == SB_OK, "%s: quantize %s: %s", label, half ? "half" : "float", sb_context_last_error(ctx));
        if (r != SB_OK) {
            sb_context_destroy(ctx);
            continue;
        }
        check_finite(q, label);
        CHECK(qi.flushed <= qi.texels);
        r = sb_factors_errors_against(ctx, q, m, wp, rel, mx);
        CHECKF(r == SB_OK, "%s: errors_against: %s", label, sb_context_last_error(ctx));
        /* never better than the optimum (unmasked: the fit is Eckart-Young
         * optimal in its own norm), never worse than rounding explains:
         * ||dM|| <= sum_j ||dg_j|| ||h~_j|| + ||g_j|| ||dh_j|| */
        for (int ch = 0; ch < 3 && r == SB_OK; ch++) {
            if (!m->data[ch] || e->norm[ch] == 0) continue;
            double bound = 0;
            for (size_t j = 0; j < J; j++) {
                size_t gw, gh, hw, hh;
                sb_factors_size(f, SB_SIDE_G, &gw, &gh);
                sb_factors_size(f, SB_SIDE_H, &hw, &hh);
                const double *g = sb_factors_tex_const(f, 0, j, (size_t)ch),
                             *gq = sb_factors_tex_const(q, 0, j, (size_t)ch);
                const double *h = sb_factors_tex_const(f, 1, j, (size_t)ch),
                             *hq = sb_factors_tex_const(q, 1, j, (size_t)ch);
                double ng = 0, ndg = 0, nhq = 0, ndh = 0;
                for (size_t i = 0; i < gw * gh; i++) {
                    double w = wp ? sqrt(sb_param_row_measure(wp, i)) : 1;
                    ng += w * g[i] * w * g[i];
                    ndg += w * (gq[i] - g[i]) * w * (gq[i] - g[i]);
                }
                for (size_t i = 0; i < hw * hh; i++) {
                    double w = wp ? sqrt(sb_param_col_measure(wp, i)) : 1;
                    nhq += w * hq[i] * w * hq[i];
                    ndh += w * (hq[i] - h[i]) * w * (hq[i] - h[i]);
                }
                bound += sqrt(ndg) * sqrt(nhq) + sqrt(ng) * sqrt(ndh);
                double dbl = e->rel_rms[j * 4 + (size_t)ch], got = rel[j * 4 + (size_t)ch];
                double slack = 1e-9 * dbl + 1e-12;
                CHECKF(isfinite(got), "%s: stored error not finite", label);
                if (!not_optimal) /* masked or inexact fits can be beaten by rounding */
                    CHECKF(got >= dbl - slack, "%s (%s) channel %d J=%zu: stored error %.17g below the optimum %.17g",
                           label, half ? "half" : "float", ch, j + 1, got, dbl);
                CHECKF(got <= dbl + bound / e->norm[ch] * 1.000001 + slack,
                       "%s (%s) channel %d J=%zu: stored error %.17g beyond %.17g + rounding bound %.3g", label,
                       half ? "half" : "float", ch, j + 1, got, dbl, bound / e->norm[ch]);
            }
        }
        sb_factors_destroy(q);
        sb_context_destroy(ctx);
    }
    free(rel);
    free(mx);
}

typedef struct fit_opts {
    size_t terms;
    int weighted, zero_fill;
    sb_method_t method;
    int exact;     /* method is exact: Eckart-Young equality, else bounds (unmasked only) */
    int no_stored; /* skip check_stored and the dgesvd reference (huge matrices) */
} fit_opts_t;

/* Factor m with the invariants; returns the factors (caller destroys) or NULL. */
static sb_factors_t *check_fit(const sb_matrix_t *m, const sb_param_t *p, fit_opts_t fo, const char *label) {
    sb_context_t *ctx;
    sb_context_create(&ctx);
    sb_plan_opts_t po = {0};
    po.terms = fo.terms;
    po.weighted = fo.weighted;
    po.zero_fill = fo.zero_fill;
    po.svd.method = fo.method;
    po.svd.seed = 7;
    sb_plan_t *plan = NULL, *plan2 = NULL;
    sb_factors_t *f = NULL, *f2 = NULL, *f3 = NULL;
    sb_result_t r = sb_plan_create(ctx, m->rows, m->cols, &po, &plan);
    CHECKF(r == SB_OK, "%s: plan: %s", label, sb_context_last_error(ctx));
    if (r == SB_OK) r = sb_plan_execute(plan, m, p, &f);
    CHECKF(r == SB_OK, "%s: execute: %s %s", label, sb_result_name(r), sb_context_last_error(ctx));
    if (r != SB_OK) goto out;
    check_finite(f, label);
    /* same input, same plan and a fresh plan: identical bits */
    CHECK(sb_plan_execute(plan, m, p, &f2) == SB_OK);
    CHECK(sb_plan_create(ctx, m->rows, m->cols, &po, &plan2) == SB_OK);
    CHECK(plan2 && sb_plan_execute(plan2, m, p, &f3) == SB_OK);
    CHECKF(f2 && same_bits(f, f2), "%s: second execute differs", label);
    CHECKF(f3 && same_bits(f, f3), "%s: fresh plan differs", label);
    sb_plan_stats_t st;
    sb_plan_stats(plan, &st);
    size_t J = sb_factors_terms(f);
    const sb_factor_errors_t *e = sb_factors_errors(f);
    /* rounding of the explicit residuals: 16 N eps relative to ||M|| */
    double noise = 16 * (double)(m->rows < m->cols ? m->rows : m->cols) * DBL_EPSILON;
    if (!st.masked)
        for (size_t j = 1; j < J; j++)
            for (int c = 0; c < 4; c++)
                CHECKF(e->rel_rms[j * 4 + c] <= e->rel_rms[(j - 1) * 4 + c] * (1 + 1e-12) + noise,
                       "%s: channel %d: rel_rms rises from %.17g (J=%zu) to %.17g", label, c,
                       e->rel_rms[(j - 1) * 4 + c], j, e->rel_rms[j * 4 + c]);
    for (size_t j = 0; j < J; j++)
        CHECKF(e->rel_rms[j * 4 + 3] <= 1 + 1e-9 || st.masked, "%s: rel_rms > 1", label);
    if (!m->mask && !fo.no_stored) check_eckart_young(f, m, p, fo.weighted, fo.exact, label);
    check_signs(f, m, label);
    /* errors_against on the fit itself reproduces the plan's bookkeeping */
    {
        double *rel = malloc(J * 4 * sizeof *rel), *mx = malloc(J * 4 * sizeof *mx);
        r = sb_factors_errors_against(ctx, f, m, fo.weighted ? p : NULL, rel, mx);
        CHECKF(r == SB_OK, "%s: errors_against: %s", label, sb_context_last_error(ctx));
        double tol = 1e-7 * e->rel_rms[0] + 16 * (double)m->rows * DBL_EPSILON;
        for (size_t j = 0; j < J && r == SB_OK; j++)
            for (int c = 0; c < 4; c++) {
                if (c < 3 && !m->data[c]) continue;
                CHECKF(fabs(rel[j * 4 + c] - e->rel_rms[j * 4 + c]) <= 1e-9 * e->rel_rms[j * 4 + c] + tol,
                       "%s: J=%zu channel %d: errors_against %.17g, plan %.17g", label, j + 1, c, rel[j * 4 + c],
                       e->rel_rms[j * 4 + c]);
            }
        free(rel);
        free(mx);
    }
    if (!fo.no_stored) check_stored(f, m, fo.weighted ? p : NULL, m->mask != NULL || !fo.exact, label);
out:
    sb_factors_destroy(f2);
    sb_factors_destroy(f3);
    sb_plan_destroy(plan);
    sb_plan_destroy(plan2);
    sb_context_destroy(ctx);
    return f;
}

/* Build m for src on fx_layout(SB_PARAM_IO, R), checking the build is deterministic. */
static int build(const sb_source_t *src, const sb_param_t *p, sb_form_t form, unsigned channels, sb_matrix_t *m) {
    sb_context_t *ctx;
    sb_context_create(&ctx);
    sb_matrix_opts_t mo = {0};
    mo.form = form;
    mo.channels = channels;
    sb_result_t r = sb_matrix_build(ctx, src, p, &mo, m);
    CHECKF(r == SB_OK, "build: %s", sb_context_last_error(ctx));
    sb_context_destroy(ctx);
    if (r != SB_OK) return 0;
    for (int c = 0; c < 3; c++)
        if (m->data[c]) CHECK(all_finite(m->data[c], m->rows * m->cols));
    return 1;
}

/* One source through check_fit on fx_layout(SB_PARAM_IO, R), J terms, every form asked for. */
static void run_source(const sb_source_t *src, size_t R, size_t J, int weighted, const char *label) {
    sb_param_t *p = fx_layout(SB_PARAM_IO, R);
    for (int form = 0; form < SB_FORM_COUNT_; form += 2) { /* f and cos2 */
        sb_matrix_t m;
        if (!build(src, p, (sb_form_t)form, 0, &m)) continue;
        char lab[256];
        snprintf(lab, sizeof lab, "%s R=%zu J=%zu form %s%s", label, R, J, sb_form_name((sb_form_t)form),
                 weighted ? " weighted" : "");
        fit_opts_t fo = {J, weighted, 0, SB_METHOD_FULL, 1, 0};
        sb_factors_destroy(check_fit(&m, p, fo, lab));
        sb_matrix_free(&m);
    }
    sb_param_destroy(p);
}

/* ---- cases -------------------------------------------------------------- */

/* GGX down to alpha = 1e-6 (roughness 1e-3): a near-delta lobe on a grid. */
SB_TEST(ggx_low_roughness) {
    static const char *const specs[] = {"microfacet:roughness=0.001", "microfacet:base=gold,roughness=0.0316",
                                        "microfacet:roughness=0.01,metallic=1,base=0.9/0.5/0.1"};
    for (size_t i = 0; i < 3; i++) {
        sb_source_t *s = fx_model(specs[i]);
        if (!s) continue;
        run_source(s, 12, 144, 0, specs[i]); /* J = N: every term */
        run_source(s, 16, 12, 1, specs[i]);
        sb_source_destroy(s);
    }
}

/* Directions at and beyond the horizon: evaluation, lookups and the
 * metric stay finite, and a 1/(cos cos) blow-up factors cleanly. */
SB_TEST(grazing) {
    sb_source_t *s = custom((custom_t){GRAZING, 1, 0, 0, NULL}, SB_SOURCE_RECIPROCAL);
    run_source(s, 24, 8, 0, "1/(cos cos)");
    sb_source_t *ggx = fx_model("microfacet:roughness=0.001");
    sb_param_t *p = fx_layout(SB_PARAM_IO, 8);
    sb_matrix_t m;
    CHECK(build(ggx, p, SB_FORM_F, 0, &m));
    fit_opts_t fo = {6, 0, 0, SB_METHOD_FULL, 1, 0};
    sb_factors_t *f = check_fit(&m, p, fo, "grazing ggx");
    static const double zs[] = {0, -0.0, 1e-300, 4.9e-324, 1e-12, 1e-6, -1e-12, 1};
    for (size_t a = 0; f && a < sizeof zs / sizeof zs[0]; a++)
        for (size_t b = 0; b < sizeof zs / sizeof zs[0]; b++) {
            double zi = zs[a], zo = zs[b];
            double wi[3] = {sqrt(fmax(1 - zi * zi, 0)), 0, zi},
                   wo[3] = {-0.6 * sqrt(fmax(1 - zo * zo, 0)), 0.8 * sqrt(fmax(1 - zo * zo, 0)), zo};
            double rgb[3], ref[3];
            int known = sb_source_eval(ggx, wi, wo, ref);
            CHECKF(known && all_finite(ref, 3), "ggx at z = %g, %g: %g %g %g", zi, zo, ref[0], ref[1], ref[2]);
            for (int form = 0; form < SB_FORM_COUNT_; form++) {
                int in = sb_factors_eval(f, p, (sb_form_t)form, 6, wi, wo, rgb);
                CHECKF(all_finite(rgb, 3), "eval at z = %g, %g form %d: %g", zi, zo, form, rgb[0]);
                if (zi <= 0 || zo <= 0)
                    CHECKF(!in && rgb[0] == 0, "below the horizon z = %g, %g counted inside", zi, zo);
            }
            double st_g[2], st_h[2];
            if (sb_param_coords(p, wi, wo, st_g, st_h))
                CHECK(all_finite(st_g, 2) && all_finite(st_h, 2) && st_g[0] <= 1 && st_h[0] <= 1);
        }
    sb_metric_t mt;
    CHECK(!f || sb_metric_compute(NULL, ggx, f, p, SB_FORM_F, NULL, &mt) == SB_OK);
    CHECK(!f || (all_finite(mt.rel_l2, mt.terms) && isfinite(mt.neg_texels)));
    sb_factors_destroy(f);
    sb_matrix_free(&m);
    sb_param_destroy(p);
    sb_source_destroy(ggx);
    sb_source_destroy(s);
}

/* f = 0: sigma 0, textures 0, errors 0, no division by a zero norm. */
SB_TEST(zero_brdf) {
    sb_source_t *s = custom((custom_t){ZERO, 1, 0, 0, NULL}, SB_SOURCE_RECIPROCAL | SB_SOURCE_ISOTROPIC);
    sb_param_t *p = fx_layout(SB_PARAM_IO, 8);
    sb_matrix_t m;
    CHECK(build(s, p, SB_FORM_COS2, 0, &m));
    for (int weighted = 0; weighted < 2; weighted++) {
        fit_opts_t fo = {64, weighted, 0, SB_METHOD_FULL, 1, 0};
        sb_factors_t *f = check_fit(&m, p, fo, weighted ? "zero weighted" : "zero");
        for (size_t j = 0; f && j < 64; j++)
            for (size_t c = 0; c < 3; c++) {
                CHECK(sb_factors_sigma(f, j, c) == 0);
                for (size_t i = 0; i < 64; i++)
                    CHECK(sb_factors_tex_const(f, SB_SIDE_G, j, c)[i] == 0);
                CHECK(sb_factors_errors(f)->rel_rms[j * 4 + c] == 0);
            }
        sb_factors_destroy(f);
    }
    sb_matrix_free(&m);
    sb_param_destroy(p);
    sb_source_destroy(s);
}

/* A constant: exact at J = 1, and every further term is rounding noise
 * that must still be finite, signed by the rule and non-increasing. */
SB_TEST(constant_brdf) {
    sb_source_t *s = custom((custom_t){CONSTANT, 1, 0, 0, NULL}, SB_SOURCE_RECIPROCAL | SB_SOURCE_ISOTROPIC);
    sb_param_t *p = fx_layout(SB_PARAM_IO, 8);
    sb_matrix_t m;
    CHECK(build(s, p, SB_FORM_F, 0, &m));
    fit_opts_t fo = {64, 0, 0, SB_METHOD_FULL, 1, 0};
    sb_factors_t *f = check_fit(&m, p, fo, "constant");
    if (f) {
        CHECKF(sb_factors_errors(f)->rel_rms[3] < 1e-14, "constant at J=1: %g", sb_factors_errors(f)->rel_rms[3]);
        for (size_t i = 0; i < 64; i += 9)
            CHECK_REL(sb_factors_cell(f, 1, 1, i, 63 - i), 0.3, 1e-14);
    }
    sb_factors_destroy(f);
    sb_matrix_free(&m);
    sb_param_destroy(p);
    sb_source_destroy(s);
}

/* sum_{k<K} g_k(wi) h_k(wo): exact at J = K, not before; and a rank-deficient
 * sum (g_last = g_0 + g_1) of K products has rank K - 1. */
SB_TEST(exact_rank_k) {
    static const int ranks[] = {1, 2, 3, 5, 7};
    sb_param_t *p = fx_layout(SB_PARAM_IO, 12);
    for (size_t i = 0; i < sizeof ranks / sizeof ranks[0]; i++)
        for (int dep = 0; dep < 2; dep++) {
            int K = ranks[i];
            if (dep && K < 3) continue;
            sb_source_t *s = custom((custom_t){SEPARABLE, 1, K, dep, NULL}, 0);
            sb_matrix_t m;
            if (!build(s, p, SB_FORM_F, 0, &m)) continue;
            char lab[64];
            snprintf(lab, sizeof lab, "rank %d%s", K, dep ? " (deficient)" : "");
            fit_opts_t fo = {20, 0, 0, SB_METHOD_FULL, 1, 0};
            sb_factors_t *f = check_fit(&m, p, fo, lab);
            int rank = dep ? K - 1 : K;
            for (size_t c = 0; f && c < 3; c++) {
                const sb_factor_errors_t *e = sb_factors_errors(f);
                double s1 = sb_factors_sigma(f, 0, c);
                CHECKF(sb_factors_sigma(f, (size_t)rank, c) < 1e-12 * s1, "%s: sigma_%d / sigma_1 = %g", lab, rank,
                       sb_factors_sigma(f, (size_t)rank, c) / s1);
                CHECKF(sb_factors_sigma(f, (size_t)rank - 1, c) > 1e-6 * s1, "%s: sigma_%d / sigma_1 = %g", lab,
                       rank - 1, sb_factors_sigma(f, (size_t)rank - 1, c) / s1);
                CHECKF(e->rel_rms[(size_t)(rank - 1) * 4 + c] < 1e-12, "%s: error at J = rank: %g", lab,
                       e->rel_rms[(size_t)(rank - 1) * 4 + c]);
                if (rank > 1) CHECK(e->rel_rms[(size_t)(rank - 2) * 4 + c] > 1e-8);
            }
            sb_factors_destroy(f);
            sb_matrix_free(&m);
            sb_source_destroy(s);
        }
    sb_param_destroy(p);
}

/* Values from 1e300 down to denormals: relative errors and signs do not
 * depend on the scale; storing refuses what FLOAT / HALF cannot hold
 * instead of flushing it. */
SB_TEST(extreme_scales) {
    static const double scales[] = {1, 1e300, 1e30, 1e-30, 1e-300, 1e-310}; /* 1 first: the reference */
    sb_source_t *ggx = fx_model("microfacet:base=copper,roughness=0.2");
    sb_param_t *p = fx_layout(SB_PARAM_IO, 8);
    double ref[8 * 4], ref_masked = 0;
    for (size_t i = 0; i < sizeof scales / sizeof scales[0]; i++) {
        sb_source_t *s = custom((custom_t){SCALED, scales[i], 0, 0, ggx}, 0);
        sb_matrix_t m;
        if (!build(s, p, SB_FORM_COS2, 0, &m)) continue;
        char lab[64];
        snprintf(lab, sizeof lab, "scale %g", scales[i]);
        fit_opts_t fo = {8, 0, 0, SB_METHOD_FULL, 1, 0};
        sb_factors_t *f = check_fit(&m, p, fo, lab);
        if (f && scales[i] == 1) memcpy(ref, sb_factors_errors(f)->rel_rms, sizeof ref);
        if (f && i > 0)
            for (size_t j = 0; j < 32; j++)
                CHECKF(fabs(sb_factors_errors(f)->rel_rms[j] - ref[j]) <= 1e-9 * ref[j] + 1e-13,
                       "%s: rel_rms[%zu] %.17g, at scale 1 %.17g", lab, j, sb_factors_errors(f)->rel_rms[j], ref[j]);
        /* storing: FLOAT refuses beyond its range or below its subnormals
         * (values outside the storage range: a numerical failure) */
        sb_context_t *ctx;
        sb_context_create(&ctx);
        sb_exr_opts_t eo = {0};
        sb_factors_t *q = NULL;
        sb_result_t r = f ? sb_factors_quantize(ctx, f, &eo, &q, NULL) : SB_OK;
        if (scales[i] >= 1e300 || scales[i] <= 1e-300)
            CHECKF(r == SB_ERR_NUMERIC, "%s: FLOAT storage gave %s", lab, sb_result_name(r));
        else
            CHECKF(r == SB_OK, "%s: FLOAT storage gave %s: %s", lab, sb_result_name(r), sb_context_last_error(ctx));
        sb_factors_destroy(q);
        sb_context_destroy(ctx);
        sb_factors_destroy(f);
        sb_matrix_free(&m);
        /* the masked fit (NaN/Inf/missing cells) is scale invariant too */
        sb_source_t *h = custom((custom_t){HOSTILE, 1, 0, 0, s}, SB_SOURCE_MEASURED);
        if (build(h, p, SB_FORM_COS2, 0, &m)) {
            snprintf(lab, sizeof lab, "masked, scale %g", scales[i]);
            fit_opts_t fm = {3, 0, 0, SB_METHOD_FULL, 1, 0};
            f = check_fit(&m, p, fm, lab);
            if (f && scales[i] == 1) ref_masked = sb_factors_errors(f)->rel_rms[2 * 4 + 3];
            if (f && i > 0)
                CHECKF(fabs(sb_factors_errors(f)->rel_rms[2 * 4 + 3] - ref_masked) <= 1e-6 * ref_masked,
                       "%s: rel_rms %.17g, at scale 1 %.17g", lab, sb_factors_errors(f)->rel_rms[2 * 4 + 3],
                       ref_masked);
            sb_factors_destroy(f);
            sb_matrix_free(&m);
        }
        sb_source_destroy(h);
        sb_source_destroy(s);
    }
    sb_param_destroy(p);
    sb_source_destroy(ggx);
}

/* NaN, +-Inf, missing and negative cells: non-finite becomes missing
 * (mask 0, value 0), negative values stay values; the masked fit and the
 * zero-filled fit give finite outputs. */
SB_TEST(hostile_cells) {
    sb_source_t *ggx = fx_model("microfacet:base=gold,roughness=0.3");
    sb_source_t *s = custom((custom_t){HOSTILE, 1, 0, 0, ggx}, SB_SOURCE_MEASURED);
    sb_param_t *p = fx_layout(SB_PARAM_IO, 8);
    sb_matrix_t m;
    if (build(s, p, SB_FORM_F, 0, &m)) {
        CHECK(m.mask != NULL);
        size_t bad = 0, neg = 0;
        for (size_t l = 0; l < m.cols; l++)
            for (size_t k = 0; k < m.rows; k++) {
                double wi[3], wo[3], rgb[3];
                sb_param_cell_dirs(p, k, l, wi, wo);
                int known = sb_source_eval(s, wi, wo, rgb);
                int ok = known && all_finite(rgb, 3);
                size_t at = k + l * m.ld;
                CHECKF(m.mask[at] == ok, "cell (%zu, %zu): mask %d, source %s", k, l, m.mask[at], ok ? "ok" : "bad");
                if (!ok) CHECK(m.data[0][at] == 0 && m.data[1][at] == 0 && m.data[2][at] == 0);
                bad += !ok;
                neg += ok && m.data[0][at] < 0;
            }
        CHECK(m.valid_count == m.rows * m.cols - bad);
        CHECKF(bad > m.rows * m.cols / 10 && neg > 0, "%zu bad, %zu negative cells", bad, neg);
        for (int zero = 0; zero < 2; zero++) {
            fit_opts_t fo = {8, 0, zero, SB_METHOD_FULL, 0, 0};
            sb_factors_t *f = check_fit(&m, p, fo, zero ? "hostile zero-filled" : "hostile masked");
            sb_metric_t mt;
            CHECK(!f || sb_metric_compute(NULL, s, f, p, SB_FORM_F, NULL, &mt) == SB_OK);
            CHECK(!f || all_finite(mt.rel_l2, mt.terms));
            sb_factors_destroy(f);
        }
        sb_matrix_free(&m);
    }
    sb_param_destroy(p);
    sb_source_destroy(s);
    sb_source_destroy(ggx);
}

/* R from 2 up, J from 1 to the full rank. */
SB_TEST(resolutions) {
    static const size_t Rs[] = {2, 3, 4, 5, 7, 8, 16};
    sb_source_t *ggx = fx_model("microfacet:base=silver,roughness=0.15");
    sb_source_t *lam = fx_model("lambert:albedo=0.9/0.5/0.1");
    for (size_t i = 0; i < sizeof Rs / sizeof Rs[0]; i++) {
        size_t R = Rs[i], N = R * R;
        size_t Js[3] = {1, N / 2 ? N / 2 : 1, N};
        if (R == 16) Js[2] = 64; /* N = 256: keep the run short */
        sb_param_t *p = fx_layout(SB_PARAM_IO, R);
        sb_matrix_t m, ml;
        if (build(ggx, p, SB_FORM_COS2, 0, &m) && build(lam, p, SB_FORM_F, 0, &ml)) {
            for (int k = 0; k < 3; k++) {
                char lab[64];
                snprintf(lab, sizeof lab, "ggx R=%zu J=%zu", R, Js[k]);
                fit_opts_t fo = {Js[k], k == 1, 0, SB_METHOD_FULL, 1, 0};
                sb_factors_destroy(check_fit(&m, p, fo, lab));
                snprintf(lab, sizeof lab, "lambert R=%zu J=%zu", R, Js[k]);
                sb_factors_t *f = check_fit(&ml, p, fo, lab);
                CHECK(!f || sb_factors_errors(f)->rel_rms[3] < 1e-13);
                sb_factors_destroy(f);
            }
            sb_matrix_free(&m);
            sb_matrix_free(&ml);
        }
        sb_param_destroy(p);
    }
    /* R = 32 (N = 1024), one channel */
    sb_param_t *p = fx_layout(SB_PARAM_IO, 32);
    sb_matrix_t m;
    if (build(ggx, p, SB_FORM_COS2, 2, &m)) {
        fit_opts_t fo = {16, 1, 0, SB_METHOD_FULL, 1, 0};
        sb_factors_destroy(check_fit(&m, p, fo, "ggx R=32 J=16 G"));
        sb_matrix_free(&m);
    }
    sb_param_destroy(p);
    sb_source_destroy(lam);
    sb_source_destroy(ggx);
}

/* A method other than dgesdd, if this build has one (probed on a small
 * plan); else 0. */
static sb_method_t fast_method(void) {
    static const sb_method_t tries[] = {SB_METHOD_RANDOMIZED, SB_METHOD_TOPK};
    for (size_t i = 0; i < 2; i++) {
        sb_svd_opts_t so = {0};
        so.method = tries[i];
        sb_svd_t *svd = NULL;
        if (sb_svd_create(NULL, 64, 64, 2, &so, &svd) == SB_OK) {
            sb_method_t got = sb_svd_method(svd);
            sb_svd_destroy(svd);
            if (got == tries[i]) return got;
        }
    }
    return SB_METHOD_AUTO;
}

/* Every SVD method this build has (full, topk, randomized: probed) on
 * exactly low-rank, zero, constant and smooth matrices, J below, at and
 * above the rank, sizes on both sides of the methods' internal switches:
 * the invariants of check_fit, and exactness at J >= rank for all of them
 * (a range finder captures an exactly rank-K range). */
SB_TEST(methods_on_low_rank) {
    static const sb_method_t methods[] = {SB_METHOD_AUTO, SB_METHOD_FULL, SB_METHOD_TOPK, SB_METHOD_RANDOMIZED};
    static const size_t Rs[] = {6, 12}; /* N = 36 and 144 */
    static const size_t Js[] = {1, 2, 4, 9};
    for (size_t mi = 0; mi < 4; mi++) {
        sb_method_t meth = methods[mi];
        if (meth == SB_METHOD_TOPK || meth == SB_METHOD_RANDOMIZED) {
            sb_svd_opts_t so = {0};
            so.method = meth;
            sb_svd_t *svd = NULL;
            int have = sb_svd_create(NULL, 64, 64, 2, &so, &svd) == SB_OK && sb_svd_method(svd) == meth;
            sb_svd_destroy(svd);
            if (!have) {
                fprintf(stderr, "note: method %s not in this build\n", sb_method_name(meth));
                continue;
            }
        }
        for (size_t ri = 0; ri < 2; ri++) {
            sb_param_t *p = fx_layout(SB_PARAM_IO, Rs[ri]);
            for (int src_kind = 0; src_kind < 5; src_kind++) {
                int rank = src_kind == 0 ? 0 : src_kind == 1 ? 1 : src_kind == 2 ? 3 : src_kind == 3 ? 4 : -1;
                sb_source_t *s = src_kind == 0   ? custom((custom_t){ZERO, 1, 0, 0, NULL}, 0)
                                 : src_kind == 1 ? custom((custom_t){CONSTANT, 1, 0, 0, NULL}, 0)
                                 : src_kind == 2 ? custom((custom_t){SEPARABLE, 1, 3, 0, NULL}, 0)
                                 : src_kind == 3 ? custom((custom_t){SEPARABLE, 1, 5, 1, NULL}, 0)
                                                 : fx_model("microfacet:base=gold,roughness=0.3");
                sb_matrix_t m;
                if (s && build(s, p, SB_FORM_F, 2, &m)) { /* one channel: the methods are per channel */
                    for (size_t ji = 0; ji < 4; ji++) {
                        char lab[128];
                        snprintf(lab, sizeof lab, "%s R=%zu source %d (rank %d) J=%zu", sb_method_name(meth), Rs[ri],
                                 src_kind, rank, Js[ji]);
                        int exact = meth == SB_METHOD_FULL || meth == SB_METHOD_TOPK;
                        fit_opts_t fo = {Js[ji], 0, 0, meth, exact, 0};
                        sb_factors_t *f = check_fit(&m, p, fo, lab);
                        if (f && rank >= 0 && Js[ji] >= (size_t)rank)
                            CHECKF(sb_factors_errors(f)->rel_rms[(Js[ji] - 1) * 4 + 3] < 1e-10,
                                   "%s: rank-%d source, error %g at J = %zu", lab, rank,
                                   sb_factors_errors(f)->rel_rms[(Js[ji] - 1) * 4 + 3], Js[ji]);
                        sb_factors_destroy(f);
                    }
                    sb_matrix_free(&m);
                }
                sb_source_destroy(s);
            }
            sb_param_destroy(p);
        }
    }
}

/* R = 64 (N = 4096) and R = 128 (N = 16384, 2 GiB per channel): only with
 * a method that does not need dense N x N workspaces (dgesdd takes ~30 s
 * per channel at N = 4096 here and 3 x 2 GiB of workspace at N = 16384). */
SB_TEST(large_resolutions) {
    sb_method_t meth = fast_method();
    if (meth == SB_METHOD_AUTO) SKIP("R = 64, 128: no top-k or randomized SVD in this build (dgesdd only)");
    sb_source_t *ggx = fx_model("microfacet:base=gold,roughness=0.3");
    sb_param_t *p = fx_layout(SB_PARAM_IO, 64);
    sb_matrix_t m;
    if (build(ggx, p, SB_FORM_COS2, 2, &m)) {
        fit_opts_t fo = {4, 1, 0, meth, meth == SB_METHOD_TOPK, 1};
        sb_factors_destroy(check_fit(&m, p, fo, "ggx R=64 J=4 G"));
        sb_matrix_free(&m);
    }
    sb_param_destroy(p);
    sb_source_destroy(ggx);
    if (sb_memory_limit() < ((size_t)8 << 30)) SKIP("R = 128: less than 8 GiB of memory");
    sb_source_t *lam = fx_model("lambert:albedo=0.5");
    p = fx_layout(SB_PARAM_IO, 128);
    if (build(lam, p, SB_FORM_F, 1, &m)) {
        sb_context_t *ctx;
        sb_context_create(&ctx);
        sb_plan_opts_t po = {0};
        po.terms = 1;
        po.svd.method = meth;
        sb_plan_t *plan = NULL;
        sb_factors_t *f = NULL;
        sb_result_t r = sb_plan_create(ctx, m.rows, m.cols, &po, &plan);
        if (r == SB_OK) r = sb_plan_execute(plan, &m, p, &f);
        CHECKF(r == SB_OK, "R=128: %s", sb_context_last_error(ctx));
        if (f) {
            check_finite(f, "lambert R=128");
            CHECKF(sb_factors_errors(f)->rel_rms[0] < 1e-6, "lambert R=128 J=1: %g", sb_factors_errors(f)->rel_rms[0]);
        }
        sb_factors_destroy(f);
        sb_plan_destroy(plan);
        sb_context_destroy(ctx);
        sb_matrix_free(&m);
    }
    sb_param_destroy(p);
    sb_source_destroy(lam);
}

/* The same seed gives the same masked fit; the matrix build does not depend
 * on the number of threads. */
SB_TEST(determinism) {
    sb_source_t *ggx = fx_model("microfacet:base=gold,roughness=0.3");
    sb_source_t *s = custom((custom_t){HOSTILE, 1, 0, 0, ggx}, SB_SOURCE_MEASURED);
    sb_param_t *p = fx_layout(SB_PARAM_IO, 8);
    sb_matrix_t a, b;
    sb_matrix_opts_t mo = {0};
    mo.threads = 1;
    CHECK(sb_matrix_build(NULL, s, p, &mo, &a) == SB_OK);
    mo.threads = 3;
    CHECK(sb_matrix_build(NULL, s, p, &mo, &b) == SB_OK);
    for (int c = 0; c < 3; c++)
        CHECK(memcmp(a.data[c], b.data[c], a.rows * a.cols * sizeof(double)) == 0);
    CHECK(memcmp(a.mask, b.mask, a.rows * a.cols) == 0);
    sb_factors_t *f[3] = {NULL, NULL, NULL};
    for (int k = 0; k < 3; k++) {
        sb_plan_opts_t po = {0};
        po.terms = 3;
        po.svd.seed = k < 2 ? 11 : 12;
        sb_plan_t *plan;
        CHECK(sb_plan_create(NULL, a.rows, a.cols, &po, &plan) == SB_OK);
        CHECK(sb_plan_execute(plan, k ? &b : &a, p, &f[k]) == SB_OK);
        sb_plan_destroy(plan);
    }
    CHECK(f[0] && f[1] && same_bits(f[0], f[1]));
    CHECK(f[2] != NULL);
    if (f[0] && f[2]) /* another seed: another local optimum of the masked fit, of similar quality */
        CHECK_REL(sb_factors_errors(f[2])->rel_rms[2 * 4 + 3], sb_factors_errors(f[0])->rel_rms[2 * 4 + 3], 0.1);
    for (int k = 0; k < 3; k++)
        sb_factors_destroy(f[k]);
    sb_matrix_free(&a);
    sb_matrix_free(&b);
    sb_param_destroy(p);
    sb_source_destroy(s);
    sb_source_destroy(ggx);
}

/* Phong exponents up to 1e4, if a Phong model is built in: the model whose
 * name contains "phong" and its key naming the exponent. */
SB_TEST(phong_high_exponent) {
    const sb_model_info_t *mi = NULL;
    const char *key = NULL;
    for (size_t i = 0; i < sb_model_count() && !key; i++) {
        mi = sb_model_at(i);
        if (!strstr(mi->name, "phong")) continue;
        for (size_t k = 0; k < mi->key_count && !key; k++) {
            const char *n = mi->keys[k].name;
            if (strstr(n, "exp") || strcmp(n, "n") == 0 || strstr(n, "shin")) key = n;
        }
    }
    if (!key) SKIP("no Phong model with an exponent key in this build");
    static const double exps[] = {1, 100, 1e4};
    for (size_t i = 0; i < 3; i++) {
        char spec[256];
        snprintf(spec, sizeof spec, "%s:%s=%g", mi->name, key, exps[i]);
        sb_context_t *ctx;
        sb_context_create(&ctx);
        sb_source_t *s = NULL;
        sb_result_t r = sb_model_create(ctx, spec, &s);
        if (r == SB_ERR_RANGE) { /* the model caps the exponent lower: say so, test the cap */
            fprintf(stderr, "note: %s refused: %s\n", spec, sb_context_last_error(ctx));
            sb_context_destroy(ctx);
            continue;
        }
        CHECKF(r == SB_OK, "%s: %s", spec, sb_context_last_error(ctx));
        sb_context_destroy(ctx);
        if (s) run_source(s, 12, 12, 0, spec);
        sb_source_destroy(s);
    }
}

/* Every model of this build at its defaults (models added later are
 * covered without editing this file). */
SB_TEST(all_models) {
    for (size_t i = 0; i < sb_model_count(); i++) {
        sb_source_t *s = fx_model(sb_model_at(i)->name);
        if (!s) continue;
        run_source(s, 8, 16, 1, sb_model_at(i)->name);
        sb_source_destroy(s);
    }
}

/* Up-front refusal: sizes beyond the memory limit are SB_ERR_OVERFLOW with
 * the bytes needed and what to lower (the resolution; the library names no
 * CLI option), before anything is allocated. */
SB_TEST(memory_limit) {
    sb_context_t *ctx;
    sb_context_create(&ctx);
    sb_source_t *s = fx_model("lambert");
    sb_param_t *p = fx_layout(SB_PARAM_IO, 32);
    sb_set_memory_limit((size_t)1 << 20);
    sb_matrix_t m;
    CHECK(sb_matrix_build(ctx, s, p, NULL, &m) == SB_ERR_OVERFLOW);
    const char *msg = sb_context_last_error(ctx);
    /* 1024 x 1024 cells x 3 channels of 8 bytes + a 1-byte mask */
    CHECKF(strstr(msg, "resolution") && strstr(msg, "26214400"), "message: %s", msg);
    CHECK(m.data[0] == NULL && m.mask == NULL);
    sb_plan_t *plan = NULL;
    CHECK(sb_plan_create(ctx, 1024, 1024, NULL, &plan) == SB_ERR_OVERFLOW && plan == NULL);
    msg = sb_context_last_error(ctx);
    CHECKF(strstr(msg, "resolution") && strstr(msg, "bytes"), "message: %s", msg);
    sb_set_memory_limit(0);
    /* --res 512 of the CLI: 262144^2 cells, beyond any memory here */
    CHECK(sb_plan_create(ctx, (size_t)1 << 18, (size_t)1 << 18, NULL, &plan) == SB_ERR_OVERFLOW && plan == NULL);
    msg = sb_context_last_error(ctx);
    CHECKF(strstr(msg, "resolution") && strstr(msg, "618475290624"), "message: %s", msg);
    /* products that overflow size_t */
    CHECK(sb_plan_create(ctx, SIZE_MAX / 2, 4, NULL, &plan) == SB_ERR_OVERFLOW);
    sb_factors_t *f = NULL;
    CHECK(sb_factors_create(ctx, SIZE_MAX / 2, 3, 1, 1, 1, 1, &f) == SB_ERR_OVERFLOW && f == NULL);
    CHECK(sb_factors_create(ctx, 2, 3, SIZE_MAX / 2, 2, 1, 1, &f) == SB_ERR_OVERFLOW && f == NULL);
    size_t out;
    CHECK(sb_size_mul(SIZE_MAX / 2 + 1, 2, &out) == 1 && sb_size_mul(SIZE_MAX, 0, &out) == 0 && out == 0);
    CHECK(sb_size_mul3(1u << 31, 1u << 31, 1u << 31, &out) == 1);
    CHECK(sb_size_add(SIZE_MAX, 1, &out) == 1 && sb_size_add(SIZE_MAX - 1, 1, &out) == 0 && out == SIZE_MAX);
    sb_param_destroy(p);
    sb_source_destroy(s);
    sb_context_destroy(ctx);
}

/* --half on GGX alpha = 1e-3 and 1e-6: stored values finite, the
 * stored-precision error close to the double one where that is large and
 * at least the half rounding level where the fit is exact. */
SB_TEST(half_precision_ggx) {
    static const char *const specs[] = {"microfacet:roughness=0.0316", "microfacet:roughness=0.001"};
    sb_param_t *p = fx_layout(SB_PARAM_IO, 16);
    for (size_t i = 0; i < 2; i++) {
        sb_source_t *s = fx_model(specs[i]);
        sb_matrix_t m;
        if (!s || !build(s, p, SB_FORM_COS2, 0, &m)) {
            sb_source_destroy(s);
            continue;
        }
        size_t Js[2] = {4, 256};
        for (int k = 0; k < 2; k++) {
            sb_context_t *ctx;
            sb_context_create(&ctx);
            sb_plan_opts_t po = {0};
            po.terms = Js[k];
            sb_plan_t *plan;
            sb_factors_t *f = NULL, *q = NULL;
            CHECK(sb_plan_create(ctx, m.rows, m.cols, &po, &plan) == SB_OK);
            CHECK(sb_plan_execute(plan, &m, p, &f) == SB_OK);
            sb_exr_opts_t eo = {1};
            sb_quantize_info_t qi;
            sb_result_t r = f ? sb_factors_quantize(ctx, f, &eo, &q, &qi) : SB_ERR_ARG;
            CHECKF(r == SB_OK, "%s: %s", specs[i], sb_context_last_error(ctx));
            if (q) {
                size_t J = Js[k];
                double *rel = malloc(J * 4 * sizeof *rel), *mx = malloc(J * 4 * sizeof *mx);
                check_finite(q, specs[i]);
                CHECK(sb_factors_errors_against(ctx, q, &m, NULL, rel, mx) == SB_OK);
                const double *d = sb_factors_errors(f)->rel_rms;
                fprintf(stderr, "%s J=%zu: double %.4e, half %.4e (%zu of %zu texels flushed)\n", specs[i], J,
                        d[(J - 1) * 4 + 3], rel[(J - 1) * 4 + 3], qi.flushed, qi.texels);
                if (d[(J - 1) * 4 + 3] > 0.01) /* large error: half is within 1% of it */
                    CHECK_REL(rel[(J - 1) * 4 + 3], d[(J - 1) * 4 + 3], 1e-2);
                else /* exact fit: what remains is the half rounding, ~2^-11 relative per texel */
                    CHECKF(rel[(J - 1) * 4 + 3] > 1e-6 && rel[(J - 1) * 4 + 3] < 0.05, "half error %g",
                           rel[(J - 1) * 4 + 3]);
                free(rel);
                free(mx);
            }
            sb_factors_destroy(q);
            sb_factors_destroy(f);
            sb_plan_destroy(plan);
            sb_context_destroy(ctx);
        }
        sb_matrix_free(&m);
        sb_source_destroy(s);
    }
    sb_param_destroy(p);
}

/* sb_factors_quantize is exactly a write and a read of the EXR files. */
SB_TEST(quantize_is_write_read) {
    sb_source_t *s = fx_model("microfacet:base=copper,roughness=0.05");
    sb_param_t *p = fx_layout(SB_PARAM_IO, 8);
    sb_matrix_t m;
    CHECK(build(s, p, SB_FORM_F, 0, &m));
    sb_plan_opts_t po = {0};
    po.terms = 20;
    sb_plan_t *plan;
    sb_factors_t *f = NULL;
    CHECK(sb_plan_create(NULL, m.rows, m.cols, &po, &plan) == SB_OK);
    CHECK(sb_plan_execute(plan, &m, p, &f) == SB_OK);
    /* a tiny texel next to a large one: flushed in HALF */
    if (f) sb_factors_tex(f, SB_SIDE_G, 19, 0)[3] = sb_factors_tex(f, SB_SIDE_G, 19, 0)[0] * 1e-12 + 1e-300;
    for (int half = 0; f && half < 2; half++) {
        char dir[4096];
        snprintf(dir, sizeof dir, "%s", sb_tmpdir("stress-q"));
        sb_context_t *ctx;
        sb_context_create(&ctx);
        sb_exr_opts_t eo = {half};
        sb_factors_t *q = NULL, *rd = NULL;
        sb_quantize_info_t qi;
        CHECK(sb_factors_quantize(ctx, f, &eo, &q, &qi) == SB_OK);
        CHECKF(sb_factors_write_exr(ctx, f, dir, &eo) == SB_OK, "%s", sb_context_last_error(ctx));
        CHECKF(sb_factors_read_exr(ctx, dir, &rd) == SB_OK, "%s", sb_context_last_error(ctx));
        if (q && rd) {
            CHECK(sb_factors_terms(q) == sb_factors_terms(rd));
            for (int sd = 0; sd < 2; sd++)
                for (size_t j = 0; j < 20; j++)
                    for (size_t c = 0; c < 3; c++) {
                        size_t w, h;
                        sb_factors_size(q, sd, &w, &h);
                        CHECKF(memcmp(sb_factors_tex_const(q, sd, j, c), sb_factors_tex_const(rd, sd, j, c),
                                      w * h * sizeof(double)) == 0,
                               "%s: %c_%zu channel %zu differs from the file", half ? "half" : "float", sd ? 'h' : 'g',
                               j, c);
                        CHECK(sb_factors_sigma(q, j, c) == sb_factors_sigma(rd, j, c));
                    }
            CHECK(half ? qi.flushed >= 1 : qi.flushed == 0);
            CHECK(qi.texels == 20 * 3 * 2 * 64);
        }
        sb_factors_destroy(q);
        sb_factors_destroy(rd);
        sb_context_destroy(ctx);
    }
    sb_factors_destroy(f);
    sb_plan_destroy(plan);
    sb_matrix_free(&m);
    sb_param_destroy(p);
    sb_source_destroy(s);
}
