/* Block-circulant factorisation of isotropic sources on the io grid: the
 * exact structured SVD against dense LAPACK on the same matrix, its errors
 * against an explicit residual, and the fall-backs to the dense path. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fixtures.h"
#include "harness.h"
#include "sepbrdf/sepbrdf.h"
#include "solve/circulant.h" /* sb_circ_is_even: not exported, in the static archive */

static sb_param_t *io(size_t R, double theta_max_deg) {
    sb_param_t *p = NULL;
    sb_param_opts_t o = {0};
    o.res = R;
    o.theta_max = theta_max_deg * SB_PI / 180;
    CHECK(sb_param_create(NULL, SB_PARAM_IO, &o, &p) == SB_OK);
    return p;
}

static sb_factors_t *factor(const sb_matrix_t *m, const sb_param_t *p, size_t J, sb_method_t method, int weighted) {
    sb_plan_opts_t po = {0};
    po.terms = J;
    po.svd.method = method;
    po.weighted = weighted;
    sb_plan_t *plan;
    sb_factors_t *f = NULL;
    CHECK(sb_plan_create(NULL, m->rows, m->cols, &po, &plan) == SB_OK);
    CHECK(sb_plan_execute(plan, m, p, &f) == SB_OK);
    sb_plan_destroy(plan);
    return f;
}

static double max_abs_entry(const sb_matrix_t *m) {
    double big = 0;
    for (int c = 0; c < 3; c++)
        for (size_t i = 0; m->data[c] && i < m->rows * m->cols; i++)
            big = fmax(big, fabs(m->data[c][i]));
    return big;
}

/* Same singular values and errors as dgesdd on the dense matrix; the
 * textures reproduce the errors the plan reports when the residual is
 * formed explicitly (sb_factors_errors_against reads every cell), which
 * also checks max_abs at truncations that split a cos/sin pair. */
SB_TEST(matches_dense_full) {
    struct {
        const char *spec;
        size_t R, J;
        int weighted;
        sb_form_t form;
        double tmax;
    } cases[] = {
        {"microfacet:base=gold,roughness=0.5", 8, 12, 0, SB_FORM_F, 90},
        {"microfacet:base=gold,roughness=0.3", 5, 9, 1, SB_FORM_COS2, 90},
        {"cook-torrance:roughness=0.4,kd=0", 7, 10, 1, SB_FORM_F, 70}, /* grey: proportional channels */
        {"lambert:albedo=0.8", 6, 5, 0, SB_FORM_F, 90},                /* rank 1 */
        {"blinn-phong:n=20", 6, 36, 0, SB_FORM_COS, 90},               /* J = N */
        /* few terms of many blocks: the blocks whose norm is below the
         * J-th value are not decomposed, their energy enters the tails */
        {"microfacet:base=gold,roughness=0.5", 16, 3, 1, SB_FORM_F, 90},
        {"cook-torrance:roughness=0.2", 12, 5, 0, SB_FORM_F, 90},
    };
    for (size_t t = 0; t < sizeof cases / sizeof *cases; t++) {
        sb_source_t *s = fx_model(cases[t].spec);
        sb_param_t *p = io(cases[t].R, cases[t].tmax);
        sb_matrix_opts_t mo = {0};
        mo.form = cases[t].form;
        sb_matrix_t m;
        CHECK(sb_matrix_build(NULL, s, p, &mo, &m) == SB_OK);
        CHECKF(m.phi_period == cases[t].R, "%s: period %zu", cases[t].spec, m.phi_period);
        size_t J = cases[t].J;
        sb_factors_t *fc = factor(&m, p, J, SB_METHOD_AUTO, cases[t].weighted);
        sb_factors_t *fd = factor(&m, p, J, SB_METHOD_FULL, cases[t].weighted);
        CHECKF(strcmp(sb_factors_get_meta(fc, "method"), "circulant") == 0, "%s: method %s", cases[t].spec,
               sb_factors_get_meta(fc, "method"));
        CHECK(strcmp(sb_factors_get_meta(fd, "method"), "full") == 0);
        const sb_factor_errors_t *ec = sb_factors_errors(fc), *ed = sb_factors_errors(fd);
        for (int c = 0; c < 3; c++) {
            double s1 = sb_factors_sigma(fd, 0, (size_t)c);
            for (size_t j = 0; j < J; j++) {
                double a = sb_factors_sigma(fc, j, (size_t)c), b = sb_factors_sigma(fd, j, (size_t)c);
                CHECKF(fabs(a - b) <= 1e-11 * s1, "%s: sigma %zu ch %d: %.17g vs %.17g", cases[t].spec, j, c, a, b);
            }
        }
        double *rel = malloc(J * 4 * sizeof *rel), *mx = malloc(J * 4 * sizeof *mx);
        CHECK(sb_factors_errors_against(NULL, fc, &m, cases[t].weighted ? p : NULL, rel, mx) == SB_OK);
        double big = max_abs_entry(&m);
        for (size_t j = 0; j < J; j++)
            for (int c = 0; c < 4; c++) {
                size_t k = j * 4 + (size_t)c;
                /* both exact: the optimum, to the rounding of an explicit residual (~1e-15) */
                CHECKF(fabs(ec->rel_rms[k] - ed->rel_rms[k]) <= 1e-9 * ed->rel_rms[k] + 1e-13,
                       "%s J'=%zu ch %d: %.17g vs dense %.17g", cases[t].spec, j + 1, c, ec->rel_rms[k],
                       ed->rel_rms[k]);
                CHECKF(fabs(ec->rel_rms[k] - rel[k]) <= 1e-9 * rel[k] + 1e-13, "%s J'=%zu ch %d: %.17g vs %.17g",
                       cases[t].spec, j + 1, c, ec->rel_rms[k], rel[k]);
                CHECKF(fabs(ec->max_abs[k] - mx[k]) <= 1e-12 * big, "%s J'=%zu ch %d: max %.17g vs explicit %.17g",
                       cases[t].spec, j + 1, c, ec->max_abs[k], mx[k]);
            }
        free(rel);
        free(mx);
        sb_factors_destroy(fc);
        sb_factors_destroy(fd);
        sb_matrix_free(&m);
        sb_param_destroy(p);
        sb_source_destroy(s);
    }
}

/* The plan falls back to the dense path when the structure is not
 * declared, not even, or another method is asked for; results agree. */
SB_TEST(fallbacks) {
    sb_source_t *s = fx_model("microfacet:base=copper,roughness=0.4");
    sb_param_t *p = io(6, 90);
    sb_matrix_t m;
    CHECK(sb_matrix_build(NULL, s, p, NULL, &m) == SB_OK);
    CHECK(m.phi_period == 6);
    size_t J = 4;
    sb_factors_t *fc = factor(&m, p, J, SB_METHOD_AUTO, 0);
    CHECK(strcmp(sb_factors_get_meta(fc, "method"), "circulant") == 0);
    /* another method: dense */
    sb_factors_t *ft = factor(&m, p, J, SB_METHOD_TOPK, 0);
    CHECK(strcmp(sb_factors_get_meta(ft, "method"), "topk") == 0);
    /* not declared: dense, same optimum */
    m.phi_period = 0;
    sb_factors_t *fa = factor(&m, p, J, SB_METHOD_AUTO, 0);
    CHECK(strcmp(sb_factors_get_meta(fa, "method"), "circulant") != 0);
    for (size_t j = 0; j < J; j++)
        CHECK_REL(sb_factors_errors(fa)->rel_rms[j * 4 + 3], sb_factors_errors(fc)->rel_rms[j * 4 + 3], 1e-9);
    /* declared but not even in the azimuth difference: refused, dense */
    m.phi_period = 6;
    m.data[1][2 + (1 * 6 + 3) * m.ld] *= 1.5; /* theta_i 2, phi_o - phi_i = 1, theta_o 3 */
    sb_factors_t *fb = factor(&m, p, J, SB_METHOD_AUTO, 0);
    CHECK(strcmp(sb_factors_get_meta(fb, "method"), "circulant") != 0);
    sb_factors_destroy(fa);
    sb_factors_destroy(fb);
    sb_factors_destroy(fc);
    sb_factors_destroy(ft);
    sb_matrix_free(&m);
    /* not isotropic, or a grid without the structure: not declared */
    sb_param_t *hd = NULL;
    sb_param_opts_t ho = {0};
    ho.res = 6;
    CHECK(sb_param_create(NULL, SB_PARAM_HD, &ho, &hd) == SB_OK);
    CHECK(sb_matrix_build(NULL, s, hd, NULL, &m) == SB_OK);
    CHECK(m.phi_period == 0);
    sb_matrix_free(&m);
    sb_param_destroy(hd);
    sb_param_destroy(p);
    sb_source_destroy(s);
}

/* Same result for the same input, run twice (no hidden state). */
SB_TEST(deterministic) {
    sb_source_t *s = fx_model("microfacet:base=gold,roughness=0.25");
    sb_param_t *p = io(10, 90);
    sb_matrix_t m;
    CHECK(sb_matrix_build(NULL, s, p, NULL, &m) == SB_OK);
    sb_factors_t *a = factor(&m, p, 7, SB_METHOD_AUTO, 1), *b = factor(&m, p, 7, SB_METHOD_AUTO, 1);
    for (size_t j = 0; j < 7; j++)
        for (size_t c = 0; c < 3; c++) {
            CHECK(memcmp(sb_factors_tex_const(a, 0, j, c), sb_factors_tex_const(b, 0, j, c), 100 * sizeof(double)) ==
                  0);
            CHECK(memcmp(sb_factors_tex_const(a, 1, j, c), sb_factors_tex_const(b, 1, j, c), 100 * sizeof(double)) ==
                  0);
        }
    sb_factors_destroy(a);
    sb_factors_destroy(b);
    sb_matrix_free(&m);
    sb_param_destroy(p);
    sb_source_destroy(s);
}

/* The evenness test in the azimuth difference (two lanes at a time, the
 * scalar tail at odd R) against the definition entry by entry: mirrored
 * tables with and without theta weights are even; one entry moved by more
 * than the tolerance, or an entry not finite, makes it not even; a move
 * below the tolerance keeps it even. */
static int even_by_definition(const double *a, size_t R, const double *w, double tol) {
    double big = 0, diff = 0;
    for (size_t m = 0; m < R; m++)
        for (size_t ot = 0; ot < R; ot++)
            for (size_t it = 0; it < R; it++) {
                double wt = w ? w[it] * w[ot] : 1, x = wt * a[it + (m * R + ot) * R * R];
                double y = wt * a[it + (((R - m) % R) * R + ot) * R * R];
                if (!isfinite(x)) return 0;
                big = fmax(big, fabs(x)), diff = fmax(diff, fabs(x - y));
            }
    return diff <= tol * big;
}

SB_TEST(is_even_against_definition) {
    for (size_t R = 5; R <= 8; R++) {
        size_t n = R * R * R * R; /* ld = R^2, R^2 columns */
        double *a = calloc(n, sizeof *a), w[8];
        sb_circ_t *c = NULL;
        CHECK(a && sb_circ_create(NULL, R, &c) == SB_OK);
        unsigned long long s = 7 + R;
        for (size_t m = 0; m <= R / 2; m++) /* mirrored: x(m) = x(R - m), at rows it < R of column m R + ot */
            for (size_t k = 0; k < R * R; k++) {
                s = s * 6364136223846793005ULL + 1442695040888963407ULL;
                size_t it = k % R, ot = k / R;
                a[it + (m * R + ot) * R * R] = a[it + (((R - m) % R) * R + ot) * R * R] =
                    (double)(s >> 11) / 9007199254740992.0;
            }
        for (size_t i = 0; i < R; i++)
            w[i] = 0.5 + (double)i / (double)R;
        for (int wi = 0; wi < 2; wi++) {
            const double *ww = wi ? w : NULL;
            CHECK(sb_circ_is_even(c, a, R * R, ww, 1e-9) == 1 && even_by_definition(a, R, ww, 1e-9) == 1);
            size_t at = (R - 1) + ((1 * R + 2) * R * R); /* the last theta_i (the tail at odd R), m = 1 */
            double keep = a[at], moves[] = {1e-6, 1e-12, NAN, INFINITY};
            for (int k = 0; k < 4; k++) {
                a[at] = keep + moves[k];
                CHECKF(sb_circ_is_even(c, a, R * R, ww, 1e-9) == even_by_definition(a, R, ww, 1e-9),
                       "R %zu weights %d move %g", R, wi, moves[k]);
                CHECK(sb_circ_is_even(c, a, R * R, ww, 1e-9) == (k == 1));
            }
            a[at] = keep;
        }
        sb_circ_destroy(c);
        free(a);
    }
}

/* Largest |(W A W) x - s y| over the N rows (W = diag(w) over theta, A
 * the dense channel, column-major with ld; trans: A^T). */
static double triplet_residual(const double *a, size_t ld, size_t R, const double *w, int trans, const double *x,
                               double s, const double *y) {
    size_t N = R * R;
    double worst = 0;
    for (size_t r = 0; r < N; r++) {
        double acc = 0;
        for (size_t k = 0; k < N; k++) {
            double wt = w ? w[r % R] * w[k % R] : 1;
            acc += wt * (trans ? a[k + r * ld] : a[r + k * ld]) * x[k];
        }
        worst = fmax(worst, fabs(acc - s * y[r]));
    }
    return worst;
}

/* Reciprocal sources in the symmetric forms (f, f cos cos) give
 * symmetric blocks, decomposed as such (eigenvalues and MRRR vectors);
 * the form f cos theta_i does not: dgesdd's steps, the bidiagonal
 * reduction kept from the values to the vectors.  Either way every
 * triplet satisfies A v = s u and A^T u = s v to 1e-12 s_1, the vectors
 * are orthonormal and the values decrease: with theta weights, odd R,
 * rank 1 (zero eigenvalues), J = N (every block's every vector, from
 * both ends of each spectrum). */
SB_TEST(symmetric_blocks_are_eigendecomposed) {
    struct {
        const char *spec;
        size_t R, J;
        int weighted, sym;
        sb_form_t form;
    } cases[] = {
        {"microfacet:base=gold,roughness=0.5", 8, 12, 1, 1, SB_FORM_F},
        {"microfacet:base=gold,roughness=0.3", 7, 10, 0, 1, SB_FORM_COS2},
        {"microfacet:base=gold,roughness=0.5", 8, 12, 1, 0, SB_FORM_COS},
        {"lambert:albedo=0.8", 6, 5, 0, 1, SB_FORM_F},
        {"blinn-phong:n=20", 6, 36, 1, 1, SB_FORM_F},
        /* blocks above LAPACK's sizes for a direct bidiagonal SVD (25) and
         * for blocked back-transforms (32): the reduction kept from the
         * values to the vectors (circulant_gen.c) on its longer paths */
        {"microfacet:base=gold,roughness=0.3", 40, 12, 1, 0, SB_FORM_COS},
    };
    for (size_t t = 0; t < sizeof cases / sizeof *cases; t++) {
        sb_source_t *s = fx_model(cases[t].spec);
        size_t R = cases[t].R, J = cases[t].J, N = R * R;
        sb_param_t *p = io(R, 90);
        sb_matrix_opts_t mo = {0};
        mo.form = cases[t].form;
        sb_matrix_t m;
        CHECK(sb_matrix_build(NULL, s, p, &mo, &m) == SB_OK);
        double w[64], *sv = malloc(J * sizeof *sv), *u = malloc(N * J * sizeof *u), *v = malloc(N * J * sizeof *v);
        double *tails = malloc(J * sizeof *tails);
        for (size_t i = 0; i < R; i++)
            w[i] = 0.5 + (double)i / (double)R;
        const double *ww = cases[t].weighted ? w : NULL;
        sb_circ_t *c = NULL;
        CHECK(sv && u && v && tails && sb_circ_create(NULL, R, &c) == SB_OK);
        CHECK(sb_circ_is_even(c, m.data[0], m.ld, ww, 1e-9));
        CHECK(sb_circ_svd(c, m.data[0], m.ld, ww, J, 1, sv, u, v, tails) == SB_OK);
        CHECKF((sb_circ_sym_blocks(c) > 0) == cases[t].sym, "%s R %zu: %zu symmetric blocks", cases[t].spec, R,
               sb_circ_sym_blocks(c));
        for (size_t j = 0; j < J; j++) {
            double tol = 1e-12 * sv[0];
            CHECK(j == 0 || sv[j] <= sv[j - 1]);
            CHECKF(triplet_residual(m.data[0], m.ld, R, ww, 0, v + j * N, sv[j], u + j * N) <= tol, "%s: A v %zu",
                   cases[t].spec, j);
            CHECKF(triplet_residual(m.data[0], m.ld, R, ww, 1, u + j * N, sv[j], v + j * N) <= tol, "%s: A^T u %zu",
                   cases[t].spec, j);
            for (size_t i = 0; i <= j; i++) {
                double uu = 0, vv = 0;
                for (size_t r = 0; r < N; r++)
                    uu += u[i * N + r] * u[j * N + r], vv += v[i * N + r] * v[j * N + r];
                CHECKF(fabs(uu - (i == j)) <= 1e-12 && fabs(vv - (i == j)) <= 1e-12, "%s: vectors %zu, %zu",
                       cases[t].spec, i, j);
            }
        }
        sb_circ_destroy(c);
        free(sv), free(u), free(v), free(tails);
        sb_matrix_free(&m);
        sb_param_destroy(p);
        sb_source_destroy(s);
    }
}

/* The errors of factors against a structured matrix (its R^3 distinct
 * values) come from the blocks of its azimuthal DFT (Parseval,
 * sb_circ_resid) instead of a pass over the R^4 cells: rel_rms equals the
 * dense residual pass on the expanded matrix to rounding, for the fit's
 * own terms, terms weighted one by one (as the job's term weights do) and
 * factors that are no single frequency at all; max_abs, taken on 4 of
 * the R block rows, never exceeds the dense maximum and equals it for the
 * fit's own first term (frequency 0: its residual is block-circulant). */
SB_TEST(errors_by_blocks_match_dense) {
    struct {
        const char *spec;
        size_t R, J;
        int weighted;
    } cases[] = {
        {"microfacet:base=gold,roughness=0.3", 8, 6, 1},
        {"cook-torrance:roughness=0.4,kd=0", 6, 5, 0}, /* grey: one channel of factors */
        {"microfacet:roughness=0.2", 5, 4, 1},         /* odd R: the DFT's sums, no FFT */
        {"blinn-phong:n=30", 16, 7, 1},
    };
    for (size_t t = 0; t < sizeof cases / sizeof *cases; t++) {
        sb_source_t *s = fx_model(cases[t].spec);
        sb_param_t *p = io(cases[t].R, 90);
        sb_matrix_opts_t mo = {0};
        mo.structured = 1;
        sb_matrix_t m, d;
        CHECK(sb_matrix_build(NULL, s, p, &mo, &m) == SB_OK);
        CHECK(m.structured == 1 && m.phi_period == cases[t].R);
        CHECK(sb_matrix_expand(NULL, &m, &d) == SB_OK);
        size_t J = cases[t].J, C;
        sb_factors_t *f = factor(&d, p, J, SB_METHOD_AUTO, cases[t].weighted);
        C = sb_factors_channels(f);
        double *rs = malloc(J * 16 * sizeof *rs), *ms = rs + 4 * J, *rd = ms + 4 * J, *md = rd + 4 * J;
        unsigned rng = 12345;
        for (int pass = 0; pass < 3; pass++) {
            /* pass 1: terms weighted one by one; pass 2: noise on every texel */
            for (size_t j = 0; pass && j < J; j++)
                for (size_t c = 0; c < C; c++)
                    for (int side = 0; side < 2; side++) {
                        double *x = sb_factors_tex(f, side, j, c);
                        for (size_t i = 0; i < m.rows; i++) {
                            rng = rng * 1103515245u + 12345u;
                            double u = (double)(rng >> 8) / 16777216.0 - 0.5;
                            x[i] *= pass == 1 ? 0.9 - 0.05 * (double)j : 1 + 0.1 * u;
                        }
                    }
            CHECK(sb_factors_errors_against(NULL, f, &m, cases[t].weighted ? p : NULL, rs, ms) == SB_OK);
            CHECK(sb_factors_errors_against(NULL, f, &d, cases[t].weighted ? p : NULL, rd, md) == SB_OK);
            for (size_t k = 0; k < 4 * J; k++) {
                CHECKF(fabs(rs[k] - rd[k]) <= 1e-12 * rd[k] + 1e-15, "%s pass %d J'=%zu ch %zu: %.17g vs dense %.17g",
                       cases[t].spec, pass, k / 4 + 1, k % 4, rs[k], rd[k]);
                CHECKF(ms[k] <= md[k] * (1 + 1e-12), "%s pass %d: max %.17g above dense %.17g", cases[t].spec, pass,
                       ms[k], md[k]);
                if (pass == 0 && k < 4)
                    CHECKF(fabs(ms[k] - md[k]) <= 1e-12 * md[k], "%s J'=%zu: max %.17g vs dense %.17g", cases[t].spec,
                           k / 4 + 1, ms[k], md[k]);
            }
        }
        free(rs);
        sb_factors_destroy(f);
        sb_matrix_free(&d);
        sb_matrix_free(&m);
        sb_param_destroy(p);
        sb_source_destroy(s);
    }
}

/* The norm of the last channel decomposed, from its blocks (Parseval over
 * the azimuth), against the sum over the table's cells (sb_circ_norm2):
 * equal to rounding with and without theta weights and at odd R (the
 * DFT's sums); none (-1) for another table, or where one mirror entry
 * moved by an ulp (even within the solver's tolerance, not to the bit:
 * the blocks are then of the symmetrised table, not of A). */
SB_TEST(last_norm2_by_parseval) {
    struct {
        size_t R;
        int weighted;
    } cases[] = {{8, 0}, {8, 1}, {7, 1}, {32, 1}};
    for (size_t t = 0; t < sizeof cases / sizeof *cases; t++) {
        size_t R = cases[t].R;
        sb_source_t *s = fx_model("microfacet:base=gold,roughness=0.3");
        sb_param_t *p = io(R, 90);
        sb_matrix_t m;
        CHECK(sb_matrix_build(NULL, s, p, NULL, &m) == SB_OK);
        double w[32], sv[3], tails[3], *u = malloc(R * R * 3 * sizeof *u), *v = malloc(R * R * 3 * sizeof *v);
        for (size_t i = 0; i < R; i++)
            w[i] = 0.25 + (double)i / (double)R;
        const double *ww = cases[t].weighted ? w : NULL;
        sb_circ_t *c = NULL;
        CHECK(u && v && sb_circ_create(NULL, R, &c) == SB_OK);
        CHECK(sb_circ_svd(c, m.data[1], m.ld, ww, 3, 0.5, sv, u, v, tails) == SB_OK);
        double got = sb_circ_last_norm2(c, m.data[1]), want = sb_circ_norm2(R, m.data[1], m.ld, ww, 0.5);
        CHECKF(fabs(got - want) <= 1e-13 * want, "R %zu w %d: %.17g vs cells %.17g", R, cases[t].weighted, got, want);
        CHECK(sb_circ_last_norm2(c, m.data[0]) == -1);
        m.data[1][2 + (1 * R + 3) * m.ld] = nextafter(m.data[1][2 + (1 * R + 3) * m.ld], 1); /* m = 1: mirror R - 1 */
        CHECK(sb_circ_is_even(c, m.data[1], m.ld, ww, 1e-9));
        CHECK(sb_circ_svd(c, m.data[1], m.ld, ww, 3, 0.5, sv, u, v, tails) == SB_OK);
        CHECK(sb_circ_last_norm2(c, m.data[1]) == -1);
        sb_circ_destroy(c);
        free(u), free(v);
        sb_matrix_free(&m);
        sb_param_destroy(p);
        sb_source_destroy(s);
    }
}
