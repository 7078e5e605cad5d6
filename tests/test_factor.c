/* Factorisation: matrix layout, Eckart-Young errors, signs, reconstruction. */
#include <lapacke.h>
#include <stdlib.h>
#include <string.h>

#include "factor/plan_conv.h"
#include "fixtures.h"
#include "harness.h"
#include "sepbrdf/sepbrdf.h"

/* A deliberately non-reciprocal, anisotropic source with known values. */
static int probe_eval(const void *self, const double wi[3], const double wo[3], double rgb[3]) {
    (void)self;
    rgb[0] = 1 + wi[0] + 2 * wo[1] + 3 * wi[2] * wo[2];
    rgb[1] = rgb[0] * 0.5 + wo[0] * wo[0];
    rgb[2] = exp(wi[0] * wo[1]);
    return 1;
}

static sb_source_t *probe_source(void) {
    sb_source_ops_t ops = {probe_eval, NULL};
    sb_source_t *s = NULL;
    CHECK(sb_source_create(NULL, &ops, NULL, 0, "probe", &s) == SB_OK);
    return s;
}

/* M[k][l] = f(w_i^k, w_o^l), k = R i_phi + i_theta, column-major. */
SB_TEST(matrix_layout) {
    size_t R = 5;
    sb_source_t *s = probe_source();
    sb_param_t *p = fx_layout(SB_PARAM_IO, R);
    sb_matrix_t m;
    CHECK(sb_matrix_build(NULL, s, p, NULL, &m) == SB_OK);
    CHECK(m.rows == R * R && m.cols == R * R && m.ld == R * R && m.mask == NULL);
    double dt = SB_PI / 2 / R, dp = 2 * SB_PI / R;
    for (size_t k = 0; k < R * R; k += 3)
        for (size_t l = 0; l < R * R; l += 2) {
            double ti = ((k % R) + 0.5) * dt, pi_ = ((k / R) + 0.5) * dp;
            double to = ((l % R) + 0.5) * dt, po = ((l / R) + 0.5) * dp;
            double wi[3] = {sin(ti) * cos(pi_), sin(ti) * sin(pi_), cos(ti)};
            double wo[3] = {sin(to) * cos(po), sin(to) * sin(po), cos(to)};
            double rgb[3];
            probe_eval(NULL, wi, wo, rgb);
            for (int c = 0; c < 3; c++)
                CHECK_REL(m.data[c][k + l * m.ld], rgb[c], 1e-14);
        }
    sb_matrix_free(&m);
    sb_param_destroy(p);
    sb_source_destroy(s);
}

/* Independent singular values with LAPACK dgesvd (not the dgesdd path). */
static double *reference_sigma(const double *a, size_t n) {
    double *c = malloc(n * n * sizeof *c), *s = malloc(n * sizeof *s), *sup = malloc(n * sizeof *sup);
    memcpy(c, a, n * n * sizeof *c);
    lapack_int info = LAPACKE_dgesvd(LAPACK_COL_MAJOR, 'N', 'N', (lapack_int)n, (lapack_int)n, c, (lapack_int)n, s,
                                     NULL, 1, NULL, 1, sup);
    CHECK(info == 0);
    free(c);
    free(sup);
    return s;
}

SB_TEST(eckart_young) {
    size_t R = 8, J = 12, N = R * R;
    const char *specs[] = {"microfacet:base=gold,roughness=0.5", "microfacet:roughness=0.2"};
    for (int which = 0; which < 2; which++) {
        sb_source_t *s = which < 2 ? fx_model(specs[which]) : probe_source();
        sb_param_t *p = fx_layout(SB_PARAM_IO, R);
        sb_matrix_t m;
        CHECK(sb_matrix_build(NULL, s, p, NULL, &m) == SB_OK);
        sb_plan_opts_t po = {0};
        po.terms = J;
        po.svd.method = SB_METHOD_FULL;
        sb_factors_t *f = fx_factor(&m, p, &po);
        const sb_factor_errors_t *e = sb_factors_errors(f);
        double tot2 = 0, tail2[64] = {0};
        for (int c = 0; c < 3; c++) {
            double *sig = reference_sigma(m.data[c], N), n2 = 0;
            for (size_t k = 0; k < N; k++)
                n2 += sig[k] * sig[k];
            tot2 += n2;
            for (size_t j = 0; j < J; j++) {
                double t2 = 0;
                for (size_t k = j + 1; k < N; k++)
                    t2 += sig[k] * sig[k];
                tail2[j] += t2;
                CHECK_REL(e->rel_rms[j * 4 + c], sqrt(t2 / n2), 1e-9);
                CHECK_REL(sb_factors_sigma(f, j, c), sig[j], 1e-11);
            }
            free(sig);
        }
        for (size_t j = 0; j < J; j++) {
            CHECK_REL(e->rel_rms[j * 4 + 3], sqrt(tail2[j] / tot2), 1e-9);
            if (j) CHECK(e->rel_rms[j * 4 + 3] <= e->rel_rms[(j - 1) * 4 + 3]);
        }
        sb_factors_destroy(f);
        sb_matrix_free(&m);
        sb_param_destroy(p);
        sb_source_destroy(s);
    }
}

SB_TEST(lambert_rank1) {
    sb_source_t *s = fx_model("lambert:albedo=0.8/0.5/0.2");
    sb_param_t *p = fx_layout(SB_PARAM_IO, 16);
    sb_matrix_t m;
    CHECK(sb_matrix_build(NULL, s, p, NULL, &m) == SB_OK);
    sb_plan_opts_t po = {0};
    po.terms = 2;
    sb_factors_t *f = fx_factor(&m, p, &po);
    const sb_factor_errors_t *e = sb_factors_errors(f);
    CHECKF(e->rel_rms[3] < 1e-12, "rel_rms %g", e->rel_rms[3]);
    /* g_0 h_0 reconstructs albedo / pi everywhere */
    double alb[3] = {0.8, 0.5, 0.2};
    for (int c = 0; c < 3; c++)
        for (size_t r = 0; r < m.rows; r += 7)
            for (size_t col = 0; col < m.cols; col += 5)
                CHECK_REL(sb_factors_cell(f, 1, c, r, col), alb[c] / SB_PI, 1e-12);
    sb_factors_destroy(f);
    sb_matrix_free(&m);
    sb_param_destroy(p);
    sb_source_destroy(s);
}

SB_TEST(sign_convention) {
    sb_source_t *s = fx_model("microfacet:base=copper,roughness=0.3");
    sb_param_t *p = fx_layout(SB_PARAM_IO, 8);
    sb_matrix_t m;
    CHECK(sb_matrix_build(NULL, s, p, NULL, &m) == SB_OK);
    sb_plan_opts_t po = {0};
    po.terms = 8;
    sb_plan_t *plan;
    sb_factors_t *f;
    CHECK(sb_plan_create(NULL, m.rows, m.cols, &po, &plan) == SB_OK);
    CHECK(sb_plan_execute(plan, &m, p, &f) == SB_OK);
    for (size_t j = 0; j < 8; j++)
        for (size_t c = 0; c < 3; c++) {
            const double *g = sb_factors_tex_const(f, SB_SIDE_G, j, c);
            double sum = 0, l1 = 0, big = 0;
            for (size_t i = 0; i < m.rows; i++) {
                sum += g[i];
                l1 += fabs(g[i]);
                if (fabs(g[i]) > fabs(big)) big = g[i];
            }
            if (fabs(sum) > 1e-8 * l1)
                CHECKF(sum > 0, "term %zu channel %zu: sum(g) = %g", j, c, sum);
            else
                CHECKF(big > 0, "term %zu channel %zu: sum(g) ~ 0 and largest entry %g", j, c, big);
        }
    /* full reconstruction with all terms of a rank-limited plan matches the
     * residual bookkeeping: |M - M_J| max equals the reported max_abs */
    const sb_factor_errors_t *e = sb_factors_errors(f);
    double mx = 0;
    for (size_t col = 0; col < m.cols; col++)
        for (size_t r = 0; r < m.rows; r++) {
            double d = fabs(m.data[1][r + col * m.ld] - sb_factors_cell(f, 8, 1, r, col));
            if (d > mx) mx = d;
        }
    CHECK_REL(e->max_abs[7 * 4 + 1], mx, 1e-9);
    sb_factors_destroy(f);
    sb_plan_destroy(plan);
    sb_matrix_free(&m);
    sb_param_destroy(p);
    sb_source_destroy(s);
}

/* Reconstruction through texture lookups hits the cell values exactly at
 * cell centres, and a half-texel shift would be visible. */
SB_TEST(lookup_cell_centres) {
    size_t R = 6;
    sb_source_t *s = probe_source();
    sb_param_t *p = NULL, *clamped = fx_layout(SB_PARAM_IO, R);
    sb_param_opts_t o = {0};
    o.res = R;
    o.plain = 1; /* the probe is signed: the plain sum */
    CHECK(sb_param_create(NULL, SB_PARAM_IO, &o, &p) == SB_OK);
    sb_matrix_t m;
    CHECK(sb_matrix_build(NULL, s, p, NULL, &m) == SB_OK);
    sb_plan_opts_t po = {0};
    po.terms = R * R;
    sb_factors_t *f = fx_factor(&m, p, &po);
    double wi[3], wo[3], rgb[3], ref[3];
    for (size_t k = 0; k < R * R; k += 5)
        for (size_t l = 0; l < R * R; l += 3) {
            sb_param_cell_dirs(p, k, l, wi, wo);
            CHECK(sb_factors_eval(f, p, SB_FORM_F, R * R, wi, wo, rgb) == 1);
            probe_eval(NULL, wi, wo, ref);
            for (int c = 0; c < 3; c++)
                CHECK_REL(rgb[c], ref[c], 1e-9);
            /* by default the reconstruction is max(0, sum), as the snippet's SB_CLAMP */
            CHECK(sb_factors_eval(f, clamped, SB_FORM_F, R * R, wi, wo, rgb) == 1);
            for (int c = 0; c < 3; c++)
                CHECK_REL(rgb[c], fmax(ref[c], 0), 1e-9);
        }
    /* between two theta centres the lookup is the linear blend */
    size_t k0 = 2 * R + 1, l = 7;
    double wa[3], wb[3], wm[3];
    sb_param_cell_dirs(p, k0, l, wa, wo);
    sb_param_cell_dirs(p, k0 + 1, l, wb, wo);
    double ta, pa, tb, pb;
    sb_dir_to_angles(wa, &ta, &pa);
    sb_dir_to_angles(wb, &tb, &pb);
    sb_dir_from_angles(0.5 * (ta + tb), pa, wm);
    double ra[3], rb[3], rm[3];
    sb_factors_eval(f, p, SB_FORM_F, R * R, wa, wo, ra);
    sb_factors_eval(f, p, SB_FORM_F, R * R, wb, wo, rb);
    sb_factors_eval(f, p, SB_FORM_F, R * R, wm, wo, rm);
    CHECK_REL(rm[0], 0.5 * (ra[0] + rb[0]), 1e-9);
    CHECK(fabs(ra[0] - rb[0]) > 1e-3); /* the blend is not trivially equal */
    sb_factors_destroy(f);
    sb_matrix_free(&m);
    sb_param_destroy(p);
    sb_param_destroy(clamped);
    sb_source_destroy(s);
}

SB_TEST(plan_errors) {
    sb_context_t *ctx;
    sb_context_create(&ctx);
    sb_plan_t *plan = NULL;
    sb_plan_opts_t po = {0};
    po.terms = 17;
    CHECK(sb_plan_create(ctx, 16, 16, &po, &plan) == SB_ERR_RANGE && plan == NULL);
    CHECK(strstr(sb_context_last_error(ctx), "17 terms") != NULL); /* names the value, not a CLI option */
    po.terms = 2;
    po.max_error = 1.5;
    CHECK(sb_plan_create(ctx, 16, 16, &po, &plan) == SB_ERR_RANGE);
    CHECK(sb_plan_create(ctx, 0, 16, NULL, &plan) == SB_ERR_ARG);
    sb_param_t *p = NULL;
    sb_param_opts_t o = {0};
    o.res = 1;
    CHECK(sb_param_create(ctx, SB_PARAM_IO, &o, &p) == SB_ERR_RANGE && p == NULL);
    CHECK(sb_factors_create(ctx, 0, 3, 1, 1, 1, 1, NULL) == SB_ERR_ARG);
    sb_factors_t *f = NULL;
    CHECK(sb_factors_create(ctx, 1, 2, 1, 1, 1, 1, &f) == SB_ERR_RANGE);
    CHECK(strcmp(sb_result_name(SB_ERR_RANGE), "SB_ERR_RANGE") == 0);
    CHECK(strlen(sb_result_message(SB_ERR_NUMERIC)) > 0);
    sb_context_destroy(ctx);
}

/* Every method (structured, and the adaptive range finder of the dense
 * ones) keeps the fewest terms that meet the target, as its errors say. */
SB_TEST(max_error_stops) {
    sb_source_t *s = fx_model("microfacet:base=gold,roughness=0.5");
    sb_param_t *p = fx_layout(SB_PARAM_IO, 12);
    sb_matrix_t m;
    CHECK(sb_matrix_build(NULL, s, p, NULL, &m) == SB_OK);
    sb_method_t methods[] = {SB_METHOD_AUTO, SB_METHOD_FULL, SB_METHOD_TOPK, SB_METHOD_RANDOMIZED};
    for (size_t k = 0; k < 4; k++) {
        sb_plan_opts_t po = {0};
        po.terms = 24;
        po.max_error = 0.35;
        po.svd.method = methods[k];
        sb_factors_t *f = fx_factor(&m, p, &po);
        size_t J = sb_factors_terms(f);
        const sb_factor_errors_t *e = sb_factors_errors(f);
        CHECK(J > 1 && J < 24);
        CHECKF(e->rel_rms[(J - 1) * 4 + 3] <= 0.35, "method %s: J=%zu err %g", sb_method_name(methods[k]), J,
               e->rel_rms[(J - 1) * 4 + 3]);
        CHECKF(e->rel_rms[(J - 2) * 4 + 3] > 0.35, "method %s: J-1=%zu err %g", sb_method_name(methods[k]), J - 1,
               e->rel_rms[(J - 2) * 4 + 3]);
        sb_factors_destroy(f);
    }
    sb_matrix_free(&m);
    sb_param_destroy(p);
    sb_source_destroy(s);
}

/* A rank-1 source g(wi) h(wo) that is "missing" on a pattern of pairs. */
static int holey_eval(const void *self, const double wi[3], const double wo[3], double rgb[3]) {
    (void)self;
    double v = (1 + wi[0] * wi[0]) * (2 + wo[1] + wo[2]);
    for (int c = 0; c < 3; c++)
        rgb[c] = v * (c + 1);
    if (wi[2] + wo[2] < 0.9 || (wi[0] > 0.3 && wo[1] < -0.2)) return 0; /* not measured */
    return 1;
}

/* holey_eval as a measured source (its missing cells masked, not invented). */
static sb_source_t *holey_source(void) {
    sb_source_ops_t ops = {holey_eval, NULL};
    sb_source_t *s = NULL;
    CHECK(sb_source_create(NULL, &ops, NULL, SB_SOURCE_MEASURED, "holey", &s) == SB_OK);
    return s;
}

/* J terms of m fitted (masked unless zero) to tolerance tol in at most
 * iters sweeps; the plan's statistics in *st, the leading terms from
 * converged sweeps (factor/plan_conv.h) in *conv unless NULL. */
static sb_factors_t *fit_tight(const sb_matrix_t *m, const sb_param_t *p, size_t J, int zero, double tol, int iters,
                               sb_plan_stats_t *st, size_t *conv) {
    sb_plan_opts_t po = {0};
    po.terms = J;
    po.zero_fill = zero;
    po.fit_tol = tol;
    po.fit_max_iters = iters;
    sb_plan_t *plan;
    sb_factors_t *f = NULL;
    CHECK(sb_plan_create(NULL, m->rows, m->cols, &po, &plan) == SB_OK);
    CHECK(sb_plan_execute(plan, m, p, &f) == SB_OK);
    sb_plan_stats(plan, st);
    if (conv) *conv = sb_plan_converged_terms(plan);
    sb_plan_destroy(plan);
    return f;
}

SB_TEST(masked_fit_exact_rank1) {
    sb_source_t *s = holey_source();
    sb_param_t *p = fx_layout(SB_PARAM_IO, 8);
    sb_matrix_t m;
    CHECK(sb_matrix_build(NULL, s, p, NULL, &m) == SB_OK);
    CHECK(m.mask != NULL);
    CHECK(m.valid_count > m.rows * m.cols / 3 && m.valid_count < m.rows * m.cols);
    for (int zero = 0; zero < 2; zero++) {
        sb_plan_stats_t st;
        sb_factors_t *f = fit_tight(&m, p, 1, zero, 1e-12, 2000, &st, NULL);
        double e = sb_factors_errors(f)->rel_rms[3];
        if (zero) {
            CHECK(!st.masked);
            CHECKF(e > 1e-3, "zero-filled rank-1 fit of a holey rank-1 matrix should not be exact: %g", e);
        } else {
            CHECK(st.masked && st.fit_iterations > 1);
            CHECKF(e < 1e-6, "masked rank-1 fit error %g after %d iterations", e, st.fit_iterations);
            /* and the imputed product reproduces the hidden cells too */
            double wi[3], wo[3], ref[3];
            sb_param_cell_dirs(p, 0, 5, wi, wo);
            holey_eval(NULL, wi, wo, ref);
            CHECK_REL(sb_factors_cell(f, 1, 2, 0, 5), ref[2], 1e-5);
        }
        sb_factors_destroy(f);
    }
    sb_matrix_free(&m);
    sb_param_destroy(p);
    sb_source_destroy(s);
}

/* More terms than the masked data hold (a holey rank-1 source at J = 8):
 * the terms beyond its rank have nothing to fit; every sigma is finite,
 * the fit stays exact at every J' and the factor succeeds (a degenerate
 * term's sigma was 0 x inf = NaN, the next term's SVD then failed). */
SB_TEST(masked_fit_terms_beyond_rank) {
    sb_source_t *s = holey_source();
    sb_param_t *p = fx_layout(SB_PARAM_IO, 6);
    sb_matrix_t m;
    CHECK(sb_matrix_build(NULL, s, p, NULL, &m) == SB_OK && m.mask != NULL);
    sb_plan_stats_t st;
    sb_factors_t *f = fit_tight(&m, p, 8, 0, 1e-12, 2000, &st, NULL);
    CHECK(f != NULL && st.masked);
    for (size_t j = 1; f && j <= 8; j++) {
        double e = sb_factors_errors(f)->rel_rms[(j - 1) * 4 + 3];
        CHECKF(isfinite(e) && e < 1e-6, "J' = %zu: error %g", j, e);
        for (int c = 0; c < 3; c++)
            CHECKF(isfinite(sb_factors_sigma(f, j - 1, c)), "sigma %zu channel %d", j, c);
    }
    sb_factors_destroy(f);
    sb_matrix_free(&m);
    sb_param_destroy(p);
    sb_source_destroy(s);
}

/* A source missing on one of two patterns (self: 0, rank 2 with most
 * cells measured; 1, rank 1 with fewer than half): the masked fit keeps a
 * dense residual for the first and gathers cells for the second; both fit
 * the measured cells exactly, the rank-1 one also the hidden ones. */
static int holey2_eval(const void *self, const double wi[3], const double wo[3], double rgb[3]) {
    int sparse = *(const int *)self;
    double v = (1 + wi[0] * wi[0]) * (2 + wo[1] + wo[2]) + (sparse ? 0 : (0.5 + wi[1]) * (1 - wo[0] * wo[0]));
    for (int c = 0; c < 3; c++)
        rgb[c] = v * (c + 1);
    if (!sparse) return !(wi[0] > 0.3 && wo[1] < -0.2);
    return wi[0] * wo[1] - wi[1] * wo[0] > 0.15 || wi[2] * wo[2] > 0.8;
}

SB_TEST(masked_fit_exact_dense_and_sparse) {
    for (int sparse = 0; sparse < 2; sparse++) {
        sb_source_ops_t ops = {holey2_eval, NULL};
        sb_source_t *s = NULL;
        CHECK(sb_source_create(NULL, &ops, &sparse, SB_SOURCE_MEASURED, "holey2", &s) == SB_OK);
        sb_param_t *p = fx_layout(SB_PARAM_IO, 8);
        sb_matrix_t m;
        CHECK(sb_matrix_build(NULL, s, p, NULL, &m) == SB_OK);
        size_t cells = m.rows * m.cols, J = sparse ? 1 : 2;
        CHECKF(sparse ? m.valid_count < cells / 2 && m.valid_count > cells / 5
                      : m.valid_count > cells / 2 && m.valid_count < cells,
               "pattern %d: %zu of %zu cells", sparse, m.valid_count, cells);
        sb_plan_stats_t st;
        sb_factors_t *f = fit_tight(&m, p, J, 0, 1e-13, 5000, &st, NULL);
        double e = sb_factors_errors(f)->rel_rms[(J - 1) * 4 + 3];
        CHECK(st.masked);
        CHECKF(e < 1e-6, "pattern %d: masked rank-%zu fit error %g after %d iterations", sparse, J, e,
               st.fit_iterations);
        int hidden = 0; /* a hidden cell, imputed */
        for (size_t r = 0; r < m.rows && sparse && !hidden; r++)
            for (size_t c = 0; c < m.cols && !hidden; c++) {
                double wi[3], wo[3], ref[3];
                if (sb_param_cell_dirs(p, r, c, wi, wo) != 1 || holey2_eval(&sparse, wi, wo, ref)) continue;
                hidden = 1;
                CHECK_REL(sb_factors_cell(f, J, 2, r, c), ref[2], 1e-5);
            }
        CHECK(hidden == sparse);
        sb_factors_destroy(f);
        sb_matrix_free(&m);
        sb_param_destroy(p);
        sb_source_destroy(s);
    }
}

/* The comparable metric on io with form cos2, solid-angle weights and the
 * reference grid equal to the factor grid is exactly the weighted native
 * error (it samples the texel centres), for the plain sum the native error
 * measures (plain=1: no max(0, sum)). */
SB_TEST(metric_matches_weighted_native) {
    sb_source_t *s = fx_model("microfacet:base=copper,roughness=0.4");
    sb_param_t *p = NULL;
    sb_param_opts_t o = {0};
    o.res = 12;
    o.plain = 1;
    CHECK(sb_param_create(NULL, SB_PARAM_IO, &o, &p) == SB_OK);
    sb_matrix_t m;
    sb_matrix_opts_t mo = {0};
    mo.form = SB_FORM_COS2;
    CHECK(sb_matrix_build(NULL, s, p, &mo, &m) == SB_OK);
    sb_plan_opts_t po = {0};
    po.terms = 6;
    po.weighted = 1;
    sb_factors_t *f = fx_factor(&m, p, &po);
    sb_metric_opts_t mt = {0};
    mt.res = 12;
    sb_metric_t r;
    CHECK(sb_metric_compute(NULL, s, f, p, SB_FORM_COS2, &mt, &r) == SB_OK);
    CHECK(r.terms == 6 && r.known == r.pairs);
    for (size_t j = 0; j < 6; j++)
        CHECK_REL(r.rel_l2[j], sb_factors_errors(f)->rel_rms[j * 4 + 3], 1e-9);
    /* on a finer reference grid the metric measures interpolation too */
    mt.res = 17;
    CHECK(sb_metric_compute(NULL, s, f, p, SB_FORM_COS2, &mt, &r) == SB_OK);
    CHECK(r.rel_l2[5] > 0 && isfinite(r.rel_l2[5]));
    sb_factors_destroy(f);
    sb_matrix_free(&m);
    sb_param_destroy(p);
    sb_source_destroy(s);
}

SB_TEST(metric_lambert_zero) {
    sb_source_t *s = fx_model("lambert:albedo=0.3/0.6/0.9");
    sb_param_t *p = fx_layout(SB_PARAM_IO, 6);
    sb_matrix_t m;
    CHECK(sb_matrix_build(NULL, s, p, NULL, &m) == SB_OK);
    sb_plan_opts_t po = {0};
    po.terms = 1;
    sb_factors_t *f = fx_factor(&m, p, &po);
    sb_metric_t r;
    CHECK(sb_metric_compute(NULL, s, f, p, SB_FORM_F, NULL, &r) == SB_OK);
    CHECKF(r.rel_l2[0] < 1e-12, "lambert metric %g", r.rel_l2[0]);
    CHECK(r.neg_frac[0] == 0 && r.neg_texels == 0);
    sb_factors_destroy(f);
    sb_matrix_free(&m);
    sb_param_destroy(p);
    sb_source_destroy(s);
}

/* Weighted plans minimise the weighted norm: their weighted error equals the
 * Eckart-Young tail of W_r M W_c computed independently. */
SB_TEST(weighted_eckart_young) {
    sb_source_t *s = fx_model("microfacet:roughness=0.3");
    size_t R = 6, N = R * R, J = 5;
    sb_param_t *p = fx_layout(SB_PARAM_IO, R);
    sb_matrix_t m;
    CHECK(sb_matrix_build(NULL, s, p, NULL, &m) == SB_OK);
    sb_plan_opts_t po = {0};
    po.terms = J;
    po.weighted = 1;
    sb_factors_t *f = fx_factor(&m, p, &po);
    double *x = malloc(N * N * sizeof *x);
    for (size_t c = 0; c < N; c++)
        for (size_t r = 0; r < N; r++)
            x[r + c * N] = sqrt(sb_param_row_measure(p, r) * sb_param_col_measure(p, c)) * m.data[0][r + c * N];
    double *sig = reference_sigma(x, N), n2 = 0, t2 = 0;
    for (size_t k = 0; k < N; k++)
        n2 += sig[k] * sig[k];
    for (size_t k = J; k < N; k++)
        t2 += sig[k] * sig[k];
    CHECK_REL(sb_factors_errors(f)->rel_rms[(J - 1) * 4 + 0], sqrt(t2 / n2), 1e-9);
    free(sig);
    free(x);
    sb_factors_destroy(f);
    sb_matrix_free(&m);
    sb_param_destroy(p);
    sb_source_destroy(s);
}

/* The isotropic fast path (R^3 table) gives the same matrix as direct
 * evaluation of every pair. */
static const sb_source_t *wrapped;
static int wrap_eval(const void *self, const double wi[3], const double wo[3], double rgb[3]) {
    (void)self;
    return sb_source_eval(wrapped, wi, wo, rgb);
}

SB_TEST(isotropic_fast_path) {
    sb_source_t *s = fx_model("microfacet:base=gold,roughness=0.3");
    CHECK(sb_source_flags(s) & SB_SOURCE_ISOTROPIC);
    wrapped = s;
    sb_source_ops_t ops = {wrap_eval, NULL};
    sb_source_t *plain;
    CHECK(sb_source_create(NULL, &ops, NULL, 0, "plain", &plain) == SB_OK);
    sb_param_t *p = fx_layout(SB_PARAM_IO, 9);
    for (int form = 0; form < SB_FORM_COUNT_; form++) {
        sb_matrix_t a, b;
        sb_matrix_opts_t mo = {0};
        mo.form = (sb_form_t)form;
        CHECK(sb_matrix_build(NULL, s, p, &mo, &a) == SB_OK);
        CHECK(sb_matrix_build(NULL, plain, p, &mo, &b) == SB_OK);
        CHECK(a.valid_count == b.valid_count && (a.mask == NULL) == (b.mask == NULL));
        double worst = 0;
        for (int c = 0; c < 3; c++)
            for (size_t i = 0; i < a.rows * a.cols; i++) {
                double d = fabs(a.data[c][i] - b.data[c][i]) / fmax(fabs(b.data[c][i]), 1e-300);
                if (d > worst) worst = d;
            }
        CHECKF(worst < 1e-12, "form %d: largest relative difference %g", form, worst);
        sb_matrix_free(&a);
        sb_matrix_free(&b);
    }
    sb_param_destroy(p);
    sb_source_destroy(plain);
    sb_source_destroy(s);
}

/* The stored-precision error from factor space (sb_factors_errors_near)
 * equals the explicit residual of the rounded factors, for float and half,
 * weighted or not, structured or dense fits, a rank-1 source whose fit
 * error is ~1e-15 (the rounding then dominates), and tiny values; fits
 * whose own error is large (the direct form, errors.c NEAR_DIRECT_REL)
 * and small (the form in differences) both among them. */
SB_TEST(errors_near_matches_explicit) {
    int large = 0, small = 0;
    struct {
        const char *spec;
        sb_param_kind_t kind;
        size_t R, J;
        int weighted;
        sb_method_t method;
    } cases[] = {
        {"microfacet:base=gold,roughness=0.5", SB_PARAM_IO, 8, 8, 0, SB_METHOD_AUTO},
        {"microfacet:base=gold,roughness=0.3", SB_PARAM_IO_AREA, 8, 6, 1, SB_METHOD_TOPK},
        {"lambert:albedo=0.3/0.5/0.7", SB_PARAM_IO, 6, 3, 1, SB_METHOD_FULL},
        {"blinn-phong:n=50,kd=1e-20/1e-20/1e-20,ks=3e-21/2e-21/1e-21", SB_PARAM_IO, 7, 5, 0, SB_METHOD_RANDOMIZED},
    };
    for (size_t t = 0; t < sizeof cases / sizeof *cases; t++) {
        sb_source_t *s = fx_model(cases[t].spec);
        sb_param_t *p = NULL;
        sb_param_opts_t o = {0};
        o.res = cases[t].R;
        CHECK(sb_param_create(NULL, cases[t].kind, &o, &p) == SB_OK);
        sb_matrix_t m;
        CHECK(sb_matrix_build(NULL, s, p, NULL, &m) == SB_OK);
        CHECK(m.mask == NULL);
        sb_plan_opts_t po = {0};
        po.terms = cases[t].J;
        po.weighted = cases[t].weighted;
        po.svd.method = cases[t].method;
        sb_factors_t *f = fx_factor(&m, p, &po);
        size_t J = sb_factors_terms(f);
        double fit_rel = sb_factors_errors(f)->rel_rms[sb_err_at(J - 1, 3)];
        large += fit_rel >= 0.05, small += fit_rel < 0.01;
        for (int half = 0; half < 2; half++) {
            sb_exr_opts_t eo = {half};
            sb_factors_t *q;
            CHECK(sb_factors_quantize(NULL, f, &eo, &q, NULL) == SB_OK);
            double ex[64], mx[64], nr[64];
            const sb_param_t *w = cases[t].weighted ? p : NULL;
            CHECK(sb_factors_errors_against(NULL, q, &m, w, ex, mx) == SB_OK);
            CHECK(sb_factors_errors_near(NULL, f, q, &m, w, nr) == SB_OK);
            for (size_t k = 0; k < J * 4; k++)
                CHECKF(fabs(nr[k] - ex[k]) <= 1e-9 * ex[k] + 1e-14, "%s half %d [%zu]: %.17g vs explicit %.17g",
                       cases[t].spec, half, k, nr[k], ex[k]);
            /* the rounding is seen: float and half differ from the double fit */
            if (half) CHECK(nr[(J - 1) * 4 + 3] != sb_factors_errors(f)->rel_rms[(J - 1) * 4 + 3]);
            sb_factors_destroy(q);
        }
        /* a masked matrix needs the explicit residual */
        m.mask = calloc(m.rows * m.cols, 1);
        double tmp[64];
        CHECK(sb_factors_errors_near(NULL, f, f, &m, NULL, tmp) == SB_ERR_ARG);
        sb_factors_destroy(f);
        sb_matrix_free(&m);
        sb_param_destroy(p);
        sb_source_destroy(s);
    }
    CHECKF(large > 0 && small > 0, "fits with a large error %d, with a small one %d", large, small);
}

/* The solver registry: unique names; the factors' method is a registered
 * solver whose capabilities match what it did (a masked matrix takes the
 * solver with SB_CAP_MASKS); a plan made for the matrix gives the same
 * factors as one made from its shape. */
SB_TEST(solver_registry) {
    size_t n = sb_solver_count();
    CHECK(n >= 5 && sb_solver_name(n) == NULL && sb_solver_caps(n) == 0);
    for (size_t i = 0; i < n; i++) {
        CHECK(sb_solver_name(i) && strlen(sb_solver_description(i)) > 0);
        for (size_t k = 0; k < i; k++)
            CHECK(strcmp(sb_solver_name(i), sb_solver_name(k)) != 0);
    }
    sb_source_t *s = fx_model("microfacet:base=gold,roughness=0.5");
    sb_param_t *p = NULL;
    sb_param_opts_t o = {0};
    o.res = 6;
    CHECK(sb_param_create(NULL, SB_PARAM_HD, &o, &p) == SB_OK);
    sb_matrix_t m;
    CHECK(sb_matrix_build(NULL, s, p, NULL, &m) == SB_OK && m.mask != NULL);
    sb_plan_opts_t po = {0};
    po.terms = 3;
    sb_plan_t *a = NULL, *b = NULL;
    CHECK(sb_plan_create(NULL, m.rows, m.cols, &po, &a) == SB_OK);
    CHECK(sb_plan_create_for(NULL, &m, &po, &b) == SB_OK);
    sb_factors_t *fa = NULL, *fb = NULL;
    CHECK(sb_plan_execute(a, &m, p, &fa) == SB_OK && sb_plan_execute(b, &m, p, &fb) == SB_OK);
    const char *method = sb_factors_get_meta(fb, "method");
    size_t i = 0;
    while (i < n && strcmp(sb_solver_name(i), method) != 0)
        i++;
    CHECKF(i < n && (sb_solver_caps(i) & SB_CAP_MASKS), "method %s", method);
    CHECK(strcmp(sb_factors_get_meta(fa, "method"), method) == 0);
    const sb_factor_errors_t *ea = sb_factors_errors(fa), *eb = sb_factors_errors(fb);
    for (size_t j = 0; j < 3; j++)
        CHECK(ea->rel_rms[sb_err_at(j, SB_CH_ALL)] == eb->rel_rms[sb_err_at(j, SB_CH_ALL)]);
    sb_factors_destroy(fa);
    sb_factors_destroy(fb);
    sb_plan_destroy(a);
    sb_plan_destroy(b);
    sb_matrix_free(&m);
    sb_param_destroy(p);
    sb_source_destroy(s);
}

/* J terms of m (masked) at tolerance 1e-4 in at most iters sweeps a
 * stage: fit_converged in *conv, the leading terms from converged sweeps
 * returned. */
static size_t converged_terms(const sb_matrix_t *m, const sb_param_t *p, size_t J, int iters, int *conv) {
    sb_plan_stats_t st;
    size_t k = 0;
    sb_factors_destroy(fit_tight(m, p, J, 0, 1e-4, iters, &st, &k));
    *conv = st.fit_converged;
    return k;
}

/* H5 (docs/measured.md): a fit whose later terms stop at the sweep cap
 * says how many leading terms come from converged sweeps; those are the
 * fit of that many terms (nested, fit_chain.c), itself converged; the
 * plan's fit_converged is every term's.  At caps 16-18 the holey source's
 * 8-term fit has 5 such terms (more sweeps: all 8; fewer: none). */
SB_TEST(masked_converged_terms) {
    sb_source_t *s = holey_source();
    sb_param_t *p = fx_layout(SB_PARAM_IO, 6);
    sb_matrix_t m;
    CHECK(sb_matrix_build(NULL, s, p, NULL, &m) == SB_OK && m.mask != NULL);
    int partial = 0, none = 0, all = 0;
    for (int iters = 2; iters <= 40; iters += 2) {
        int conv = 0, conv_k = 0;
        size_t k = converged_terms(&m, p, 8, iters, &conv);
        CHECKF(k <= 8 && conv == (k == 8), "cap %d: %zu terms converged, fit_converged %d", iters, k, conv);
        if (k > 0 && k < 8 && converged_terms(&m, p, k, iters, &conv_k) == k)
            CHECKF(conv_k, "cap %d: the %zu-term fit is not converged", iters, k);
        partial += k > 0 && k < 8, none += k == 0, all += k == 8;
    }
    CHECKF(partial && none && all, "caps 2-40: %d partly, %d not, %d wholly converged", partial, none, all);
    sb_matrix_free(&m);
    sb_param_destroy(p);
    sb_source_destroy(s);
}

/* A job whose masked fit is capped at 2 sweeps a stage reports it (the
 * CLI's warning, report.json's fit.converged false). */
SB_TEST(capped_job_not_converged) {
    sb_job_opts_t o = {0};
    o.param = "iso";
    o.res = 16;
    o.fit_max_iters = 2;
    sb_job_t *job = NULL;
    sb_result_t r = sb_job_run(NULL, &o, &job);
    CHECKF(r == SB_OK, "run: %s", sb_result_name(r));
    sb_plan_stats_t st;
    sb_job_stats(job, &st);
    CHECKF(st.masked && !st.fit_converged, "masked %d, converged %d after %d sweeps", st.masked, st.fit_converged,
           st.fit_iterations);
    CHECK(!sb_job_fit_early_stop(job)); /* the caller's own cap: a failure to converge, warned */
    sb_job_destroy(job);
}

/* The plan's warm start (factor/plan_conv.h sb_plan_set_start, the
 * masked fit's from given factors): a weighted plan started from its own
 * converged factors undoes their textures into the solver's weighted unit
 * vectors and stops at once with the same fit (a few sweeps where cold took
 * 42: at a tolerance of 1e-10 the round trip through the textures leaves
 * gains to take); the start is taken once. */
SB_TEST(masked_plan_warm_start_from_own_fit) {
    int dense = 0;
    sb_source_ops_t ops = {holey2_eval, NULL};
    sb_source_t *s = NULL;
    CHECK(sb_source_create(NULL, &ops, &dense, SB_SOURCE_MEASURED, "holey2", &s) == SB_OK);
    sb_param_t *p = fx_layout(SB_PARAM_IO, 8);
    sb_matrix_t m;
    CHECK(sb_matrix_build(NULL, s, p, NULL, &m) == SB_OK && m.mask != NULL);
    sb_plan_opts_t po = {0};
    po.terms = 2, po.weighted = 1, po.fit_tol = 1e-10, po.fit_max_iters = 3000;
    sb_plan_t *plan = NULL;
    sb_factors_t *f[3] = {NULL, NULL, NULL};
    sb_plan_stats_t st[3];
    CHECK(sb_plan_create(NULL, m.rows, m.cols, &po, &plan) == SB_OK);
    for (int run = 0; run < 3 && plan; run++) {
        if (run == 1) sb_plan_set_start(plan, f[0]);
        CHECK(sb_plan_execute(plan, &m, p, &f[run]) == SB_OK);
        sb_plan_stats(plan, &st[run]);
    }
    CHECK(f[0] && f[1] && f[2] && st[0].masked);
    CHECKF(st[1].fit_iterations <= 10 && st[0].fit_iterations >= 4 * st[1].fit_iterations,
           "from its own fit %d sweeps (cold %d)", st[1].fit_iterations, st[0].fit_iterations);
    CHECKF(st[2].fit_iterations == st[0].fit_iterations, "after the warm run: %d sweeps, not cold's %d",
           st[2].fit_iterations, st[0].fit_iterations);
    double big = 0, d = 0;
    for (size_t r = 0; f[1] && r < m.rows; r++)
        for (size_t c = 0; c < m.cols; c++) {
            double a = sb_factors_cell(f[0], 2, 2, r, c), b = sb_factors_cell(f[1], 2, 2, r, c);
            big = fmax(big, fabs(a)), d = fmax(d, fabs(a - b));
        }
    CHECKF(d <= 1e-6 * big, "from its own fit the cells moved by %.3g (largest %.3g)", d, big);
    for (int run = 0; run < 3; run++)
        sb_factors_destroy(f[run]);
    sb_plan_destroy(plan);
    sb_matrix_free(&m);
    sb_param_destroy(p);
    sb_source_destroy(s);
}
