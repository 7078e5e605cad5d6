/* The stored-precision errors of an exact fit without a read of the
 * matrix (sb_factors_errors_near on factors sb_factors_exact marks:
 * ||X - G~ H~^T||^2 = ||R||^2 + ||D||^2 - 2 tr(dG^T R dH)), against the
 * explicit residual; the mark and the factors' stamp that the job's
 * quantised factors are kept by. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../src/factor/errors.h"
#include "fixtures.h"
#include "harness.h"
#include "sepbrdf/sepbrdf.h"

static void build(const sb_source_t *s, const sb_param_t *p, int structured, sb_matrix_t *m) {
    sb_matrix_opts_t mo = {0};
    mo.structured = structured;
    CHECK(sb_matrix_build(NULL, s, p, &mo, m) == SB_OK);
}

static sb_factors_t *fit(const sb_matrix_t *m, const sb_param_t *p, size_t J, int weighted, sb_method_t method) {
    sb_plan_opts_t po = {0};
    po.terms = J;
    po.svd.method = method;
    po.weighted = weighted;
    return fx_factor(m, p, &po);
}

/* near: f's textures, side g times (1 + eg s_i) and side h times
 * (1 + eh s_i) with s_i = sin(1.3 i + 0.7 j + c): a change of either side
 * alone, or of both. */
static sb_factors_t *perturbed(const sb_factors_t *f, double eg, double eh) {
    sb_exr_opts_t eo = {0};
    sb_factors_t *q = NULL;
    CHECK(sb_factors_quantize(NULL, f, &eo, &q, NULL) == SB_OK);
    double e[2] = {eg, eh};
    for (int s = 0; s < 2; s++) {
        size_t w, h;
        sb_factors_size(f, s, &w, &h);
        for (size_t j = 0; j < sb_factors_terms(f); j++)
            for (size_t c = 0; c < 3; c++) {
                const double *t = sb_factors_tex_const(f, s, j, c);
                double *d = sb_factors_tex(q, s, j, c);
                for (size_t i = 0; i < w * h; i++)
                    d[i] = t[i] * (1 + e[s] * sin(1.3 * (double)i + 0.7 * (double)j + (double)c));
            }
    }
    return q;
}

/* m with every distinct value NaN: a routine that reads it fails or
 * returns NaN. */
static sb_matrix_t poisoned(const sb_matrix_t *m, double **buf) {
    size_t n = m->rows * m->phi_period;
    *buf = malloc(n * sizeof **buf);
    for (size_t i = 0; i < n; i++)
        (*buf)[i] = NAN;
    sb_matrix_t z = *m;
    for (int c = 0; c < 3; c++)
        z.data[c] = m->data[c] ? *buf : NULL;
    return z;
}

/* Against the explicit residual on the dense matrix: the matrix-free form
 * where the rounding is FLOAT's or one side alone moved (the cross term
 * then vanishes: if the first-order terms did not, a relative change of
 * 1e-3 would show at 1e-4), the same answer with the matrix poisoned
 * (it is not read); both sides moved by 1e-3 the cross term is not
 * negligible and the matrix is read (poisoned: no finite answer). */
SB_TEST(near_exact_fit) {
    sb_source_t *s = fx_model("microfacet:base=gold,roughness=0.5");
    sb_param_t *p = fx_layout(SB_PARAM_IO, 8);
    sb_matrix_t m, d;
    build(s, p, 1, &m);
    build(s, p, 0, &d);
    size_t J = 6;
    double *rn = malloc(J * 4 * sizeof *rn), *rz = malloc(J * 4 * sizeof *rz), *rd = malloc(J * 4 * sizeof *rd),
           *mx = malloc(J * 4 * sizeof *mx), *nan;
    sb_matrix_t z = poisoned(&m, &nan);
    for (int w = 0; w < 2; w++) {
        sb_factors_t *f = fit(&m, p, J, w, SB_METHOD_AUTO);
        const sb_param_t *wp = w ? p : NULL;
        CHECK(strcmp(sb_factors_get_meta(f, "method"), "circulant") == 0);
        CHECK(sb_factors_exact(f));
        const double eps[4][2] = {{0, 0}, {1e-3, 0}, {0, 1e-3}, {1e-3, 1e-3}};
        for (int k = 0; k < 4; k++) {
            sb_factors_t *q = perturbed(f, eps[k][0], eps[k][1]);
            if (k == 0) { /* FLOAT storage itself */
                sb_exr_opts_t eo = {0};
                sb_factors_destroy(q);
                CHECK(sb_factors_quantize(NULL, f, &eo, &q, NULL) == SB_OK);
            }
            CHECK(!sb_factors_exact(q));
            CHECK(sb_factors_errors_near(NULL, f, q, &m, wp, rn) == SB_OK);
            CHECK(sb_factors_errors_against(NULL, q, &d, wp, rd, mx) == SB_OK);
            for (size_t i = 0; i < J * 4; i++)
                CHECKF(fabs(rn[i] - rd[i]) <= 1e-12 * rd[i], "w %d case %d: %zu %.17g vs explicit %.17g", w, k, i,
                       rn[i], rd[i]);
            sb_result_t r = sb_factors_errors_near(NULL, f, q, &z, wp, rz);
            if (k < 3) {
                CHECK(r == SB_OK);
                CHECK(memcmp(rz, rn, J * 4 * sizeof *rn) == 0);
            } else {
                CHECK(r != SB_OK || !isfinite(rz[sb_err_at(J - 1, SB_CH_ALL)]));
            }
            sb_factors_destroy(q);
        }
        /* a write access ends the mark: the matrix is read again */
        sb_factors_tex(f, SB_SIDE_G, 0, 0);
        CHECK(!sb_factors_exact(f));
        sb_exr_opts_t eo = {0};
        sb_factors_t *q = NULL;
        CHECK(sb_factors_quantize(NULL, f, &eo, &q, NULL) == SB_OK);
        sb_result_t r = sb_factors_errors_near(NULL, f, q, &z, wp, rz);
        CHECK(r != SB_OK || !isfinite(rz[sb_err_at(J - 1, SB_CH_ALL)]));
        sb_factors_destroy(q);
        sb_factors_destroy(f);
    }
    free(nan);
    free(rn);
    free(rz);
    free(rd);
    free(mx);
    sb_matrix_free(&m);
    sb_matrix_free(&d);
    sb_param_destroy(p);
    sb_source_destroy(s);
}

/* A dense solver's fit is not marked (only solvers with exact tails are). */
SB_TEST(dense_fit_not_exact) {
    sb_source_t *s = fx_model("microfacet:base=gold,roughness=0.5");
    sb_param_t *p = fx_layout(SB_PARAM_IO, 6);
    sb_matrix_t d;
    build(s, p, 0, &d);
    sb_factors_t *f = fit(&d, p, 4, 1, SB_METHOD_FULL);
    CHECK(strcmp(sb_factors_get_meta(f, "method"), "circulant") != 0);
    CHECK(!sb_factors_exact(f));
    sb_factors_destroy(f);
    sb_matrix_free(&d);
    sb_param_destroy(p);
    sb_source_destroy(s);
}

/* The stamp: the same while nothing changes (reading, the errors), a new
 * one after each change of texels, sigma, meta or terms, never one that
 * other factors had. */
SB_TEST(factors_stamp) {
    sb_factors_t *f = NULL, *g = NULL;
    CHECK(sb_factors_create(NULL, 3, 3, 4, 2, 4, 2, &f) == SB_OK);
    CHECK(sb_factors_create(NULL, 3, 3, 4, 2, 4, 2, &g) == SB_OK);
    unsigned long long a = sb_factors_stamp(f), b = sb_factors_stamp(g);
    CHECK(a != 0 && b != 0 && a != b);
    CHECK(sb_factors_stamp(f) == a);
    sb_factors_tex_const(f, SB_SIDE_G, 1, 2);
    sb_factors_errors_mut(f)->rel_rms[0] = 0.5;
    CHECK(sb_factors_stamp(f) == a);
    unsigned long long seen[6] = {a, b, 0, 0, 0, 0};
    for (int k = 0; k < 4; k++) {
        if (k == 0) sb_factors_tex(f, SB_SIDE_H, 0, 0)[0] = 1;
        if (k == 1) sb_factors_set_sigma(f, 1, 1, 2.0);
        if (k == 2) CHECK(sb_factors_set_meta(f, "key", "value") == SB_OK);
        if (k == 3) sb_factors_truncate(f, 2);
        unsigned long long t = sb_factors_stamp(f);
        for (int i = 0; i < k + 2; i++)
            CHECKF(t != seen[i], "change %d: stamp %llu seen before", k, t);
        seen[k + 2] = t;
    }
    sb_factors_destroy(f);
    sb_factors_destroy(g);
}
