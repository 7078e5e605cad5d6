/* The matrix builder's storage: a structured matrix (the distinct values
 * of an isotropic source on the io grid) against the dense build of the
 * same source, cell by cell, through every accessor, and the factor plan
 * and error routines on both. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../src/sample/stream.h"
#include "../src/util/rdft.h"
#include "fixtures.h"
#include "harness.h"
#include "sepbrdf/sepbrdf.h"

static void build(const sb_source_t *s, const sb_param_t *p, sb_form_t form, int structured, sb_matrix_t *m) {
    sb_matrix_opts_t mo = {0};
    mo.form = form;
    mo.structured = structured;
    CHECK(sb_matrix_build(NULL, s, p, &mo, m) == SB_OK);
}

/* Every cell, column and the dense copy equal the dense build bit for bit
 * (the same table values, only stored once). */
SB_TEST(structured_cells) {
    const char *specs[] = {"microfacet:base=gold,roughness=0.4", "lambert:albedo=0.5", "blinn-phong:n=30"};
    for (size_t t = 0; t < 3; t++) {
        sb_source_t *s = fx_model(specs[t]);
        size_t R = 6 + t;
        sb_param_t *p = fx_layout(SB_PARAM_IO, R);
        sb_matrix_t d, m, e;
        build(s, p, t == 1 ? SB_FORM_COS : SB_FORM_COS2, 0, &d);
        build(s, p, t == 1 ? SB_FORM_COS : SB_FORM_COS2, 1, &m);
        CHECKF(m.structured == 1 && m.phi_period == R && m.ld == R && !m.mask, "%s: structured %d period %zu", specs[t],
               m.structured, m.phi_period);
        CHECK(d.structured == 0 && d.phi_period == R && d.ld == d.rows);
        CHECK(m.valid_count == d.valid_count && m.rows == d.rows && m.cols == d.cols);
        CHECK(sb_matrix_expand(NULL, &m, &e) == SB_OK);
        double *buf = malloc(m.rows * sizeof *buf);
        size_t bad = 0;
        for (int c = 0; c < 3; c++) {
            for (size_t col = 0; col < m.cols; col++) {
                const double *x = sb_matrix_col(&m, c, col, buf);
                for (size_t r = 0; r < m.rows; r++) {
                    double want = d.data[c][r + col * d.ld];
                    bad += sb_matrix_at(&m, c, r, col) != want || x[r] != want || e.data[c][r + col * e.ld] != want;
                    bad += sb_matrix_at(&d, c, r, col) != want;
                }
            }
        }
        CHECKF(bad == 0, "%s: %zu cells differ", specs[t], bad);
        free(buf);
        sb_matrix_free(&e);
        sb_matrix_free(&m);
        sb_matrix_free(&d);
        sb_param_destroy(p);
        sb_source_destroy(s);
    }
}

/* Whether a and b hold the same cells bit for bit (every channel, the
 * mask, the storage and the counts). */
static int same_matrix(const sb_matrix_t *a, const sb_matrix_t *b) {
    if (a->rows != b->rows || a->cols != b->cols || a->ld != b->ld || a->form != b->form ||
        a->structured != b->structured || a->phi_period != b->phi_period || a->valid_count != b->valid_count ||
        a->channels != b->channels || !a->mask != !b->mask)
        return 0;
    size_t n = (a->structured ? a->rows * a->ld : a->ld * a->cols) * sizeof(double);
    for (int c = 0; c < 3; c++)
        if (!a->data[c] != !b->data[c] || (a->data[c] && memcmp(a->data[c], b->data[c], n) != 0)) return 0;
    return !a->mask || memcmp(a->mask, b->mask, a->ld * a->cols) == 0;
}

/* sb_matrix_build_two: both forms from one evaluation of the table, each
 * the same bits as its own build (structured and dense, every pair of
 * forms, a reciprocal even model and a grey one); a layout without the
 * table (hd) builds the first alone and leaves the second empty. */
SB_TEST(two_forms_as_built_alone) {
    const char *specs[] = {"microfacet:base=gold,roughness=0.4", "lambert:albedo=0.5", "blinn-phong:n=30"};
    const sb_form_t pairs[][2] = {{SB_FORM_COS, SB_FORM_F}, {SB_FORM_F, SB_FORM_COS}, {SB_FORM_COS2, SB_FORM_COS}};
    for (size_t t = 0; t < 3; t++) {
        sb_source_t *s = fx_model(specs[t]);
        sb_param_t *p = fx_layout(SB_PARAM_IO, 6 + t);
        for (int k = 0; k < 3; k++)
            for (int st = 0; st < 2; st++) {
                sb_matrix_opts_t mo = {0};
                mo.form = pairs[k][0];
                mo.structured = st;
                sb_matrix_t a, b, a1, b1;
                CHECK(sb_matrix_build_two(NULL, s, p, &mo, pairs[k][1], &b, &a) == SB_OK);
                build(s, p, pairs[k][0], st, &a1);
                build(s, p, pairs[k][1], st, &b1);
                CHECKF(same_matrix(&a, &a1) && same_matrix(&b, &b1), "%s forms %d/%d structured %d: differ", specs[t],
                       (int)pairs[k][0], (int)pairs[k][1], st);
                CHECK(a.structured == st && b.structured == st);
                sb_matrix_free(&a), sb_matrix_free(&b), sb_matrix_free(&a1), sb_matrix_free(&b1);
            }
        sb_param_destroy(p);
        sb_source_destroy(s);
    }
    sb_source_t *s = fx_model(specs[0]);
    sb_param_t *p = fx_layout(SB_PARAM_HD, 6);
    sb_matrix_t a, b, a1;
    sb_matrix_opts_t mo = {0};
    mo.form = SB_FORM_COS;
    CHECK(sb_matrix_build_two(NULL, s, p, &mo, SB_FORM_F, &b, &a) == SB_OK);
    build(s, p, SB_FORM_COS, 0, &a1);
    CHECK(b.rows == 0 && !b.data[0] && same_matrix(&a, &a1));
    sb_matrix_free(&a), sb_matrix_free(&a1);
    sb_param_destroy(p);
    sb_source_destroy(s);
}

/* The directions of table cell k = it + (d R + ot) R of an io table of
 * resolution R: wi at the first azimuth cell's centre, wo d cells on. */
static void table_dirs(const sb_param_t *p, size_t R, size_t k, double wi[3], double wo[3]) {
    double dt = sb_param_theta_max(p) / (double)R, dp = 2 * SB_PI / (double)R;
    size_t it = k % R, ot = k / R % R, d = k / (R * R);
    sb_dir_from_angles((it + 0.5) * dt, 0.5 * dp, wi);
    sb_dir_from_angles((ot + 0.5) * dt, (d + 0.5) * dp, wo);
}

/* An even source's table (SB_SOURCE_EVEN: evaluated for azimuth
 * differences d <= R / 2, mirrored to R - d) holds at every cell the
 * source's own value at that cell's directions (wi at the first azimuth
 * cell's centre, wo d cells on), and plane d equals plane R - d bit for
 * bit; odd and even R, with and without reciprocity (classic Phong). */
SB_TEST(even_table_mirrors) {
    const char *specs[] = {"microfacet:base=gold,roughness=0.4", "phong:n=20", "lambert:albedo=0.5"};
    for (size_t t = 0; t < 3; t++) {
        sb_source_t *s = fx_model(specs[t]);
        CHECKF(sb_source_flags(s) & SB_SOURCE_EVEN, "%s: not even", specs[t]);
        for (size_t R = 5; R <= 8; R += 3) {
            sb_param_t *p = fx_layout(SB_PARAM_IO, R);
            sb_matrix_t m;
            build(s, p, SB_FORM_F, 1, &m);
            CHECK(m.structured == 1 && m.phi_period == R);
            double worst = 0;
            size_t mirrored = 0, R2 = R * R;
            for (size_t k = 0; k < R2 * R; k++) {
                double wi[3], wo[3], rgb[3];
                table_dirs(p, R, k, wi, wo);
                CHECK(sb_source_eval(s, wi, wo, rgb) == 1);
                for (int c = 0; c < 3; c++) { /* k's plane d > 0 against plane R - d */
                    double x = m.data[c][k];
                    worst = fmax(worst, fabs(x - rgb[c]) / fmax(fabs(rgb[c]), 1e-300));
                    mirrored += k >= R2 && x == m.data[c][k % R2 + (R - k / R2) * R2];
                }
            }
            CHECKF(worst < 1e-12, "%s R %zu: %g from the source", specs[t], R, worst);
            CHECKF(mirrored == 3 * R2 * (R - 1), "%s R %zu: %zu of %zu mirrored", specs[t], R, mirrored,
                   3 * R2 * (R - 1));
            sb_matrix_free(&m);
            sb_param_destroy(p);
        }
        sb_source_destroy(s);
    }
}

/* A reciprocal source that is not even in the azimuth difference d:
 * f = k_c (1 + 0.3 cos d + 0.2 sin d (theta_o - theta_i)) is the same
 * with wi and wo swapped (d -> -d), not at -d alone; `self` non-NULL
 * drops the odd part (an even one). */
static int recip_eval(const void *self, const double wi[3], const double wo[3], double rgb[3]) {
    double ti = acos(wi[2]), to = acos(wo[2]), d = atan2(wo[1], wo[0]) - atan2(wi[1], wi[0]);
    double f = 1 + 0.3 * cos(d) + (self ? 0 : 0.2 * sin(d) * (to - ti));
    for (int c = 0; c < 3; c++)
        rgb[c] = (1 + 0.25 * c) * f;
    return 1;
}

/* A reciprocal source's table (the cells theta_i > theta_o written from
 * their mirrors theta_i < theta_o, the cosine moved across in the form
 * cos) holds at every cell the source's own value times the form's weight
 * at that cell's directions: even and not even, forms f and cos, R below
 * and above a block of the mirror's (64 theta_i). */
SB_TEST(reciprocal_table_mirrors) {
    static const sb_source_ops_t ops = {recip_eval, NULL};
    static int even_tag;
    const size_t Rs[] = {7, 70};
    for (int even = 0; even < 2; even++) {
        sb_source_t *s = NULL;
        unsigned flags = SB_SOURCE_ISOTROPIC | SB_SOURCE_RECIPROCAL | (even ? SB_SOURCE_EVEN : 0u);
        CHECK(sb_source_create(NULL, &ops, even ? &even_tag : NULL, flags, "reciprocal", &s) == SB_OK);
        for (size_t r = 0; s && r < 2; r++)
            for (int form = SB_FORM_F; form <= SB_FORM_COS; form++) {
                size_t R = Rs[r];
                sb_param_t *p = fx_layout(SB_PARAM_IO, R);
                sb_matrix_t m;
                build(s, p, (sb_form_t)form, 1, &m);
                CHECK(m.structured == 1 && m.phi_period == R);
                double worst = 0;
                for (size_t k = 0; k < R * R * R; k++) {
                    double wi[3], wo[3], rgb[3];
                    table_dirs(p, R, k, wi, wo);
                    recip_eval(even ? &even_tag : NULL, wi, wo, rgb);
                    for (int c = 0; c < 3; c++) {
                        double want = rgb[c] * (form == SB_FORM_COS ? wi[2] : 1);
                        worst = fmax(worst, fabs(m.data[c][k] - want) / want);
                    }
                }
                CHECKF(worst < 1e-12, "even %d form %d R %zu: %g from the source", even, form, R, worst);
                sb_matrix_free(&m);
                sb_param_destroy(p);
            }
        sb_source_destroy(s);
    }
}

/* Only the distinct values are stored where the structure applies: a
 * masked or anisotropic matrix is built dense even when asked. */
SB_TEST(structured_only_where_it_applies) {
    sb_source_t *s = fx_model("microfacet:base=gold,roughness=0.4");
    sb_param_t *hd = fx_layout(SB_PARAM_HD, 6);
    sb_matrix_t m;
    build(s, hd, SB_FORM_F, 1, &m);
    CHECK(m.structured == 0 && m.ld == m.rows && m.phi_period == 0);
    sb_matrix_free(&m);
    sb_param_destroy(hd);
    sb_source_destroy(s);
}

/* The largest difference of sb_matrix_mul's Y = M Z (channel c, k
 * columns) from the product written out cell by cell with sb_matrix_at,
 * relative to the largest |Y|. */
static double product_off(const sb_matrix_t *m, int c, size_t k, const double *z, size_t ldz) {
    size_t N = m->cols, ldy = N + 1;
    double *y = calloc(ldy * k, sizeof *y), worst = 0, scale = 0;
    CHECK(sb_matrix_mul(NULL, m, c, k, z, ldz, y, ldy) == SB_OK);
    for (size_t j = 0; j < k; j++)
        for (size_t r = 0; r < N; r++) {
            double want = 0;
            for (size_t col = 0; col < N; col++)
                want += sb_matrix_at(m, c, r, col) * z[col + j * ldz];
            worst = fmax(worst, fabs(y[r + j * ldy] - want));
            scale = fmax(scale, fabs(want));
        }
    free(y);
    return worst / scale;
}

/* The structured product of a table even to the bit (an even source's:
 * no sine part) and of one that is not (a plane changed by hand, block
 * circulant but not even: the sine part taken), against the sums. */
SB_TEST(product_even_and_not) {
    sb_source_t *s = fx_model("microfacet:base=copper,roughness=0.3");
    for (size_t R = 3; R <= 8; R++) {
        sb_param_t *p = fx_layout(SB_PARAM_IO, R);
        sb_matrix_t m;
        build(s, p, SB_FORM_F, 1, &m);
        size_t N = m.cols, k = 3;
        double *z = malloc(N * k * sizeof *z);
        for (size_t i = 0; i < N * k; i++)
            z[i] = cos(0.91 * (double)i + 0.3);
        double even = product_off(&m, 1, k, z, N);
        for (size_t i = 0; i < R * R; i++) /* plane d = 1 only: T_1 != T_(R-1) */
            m.data[1][R * R + i] *= 1.0 + 0.5 * (double)(i % 3);
        double odd = product_off(&m, 1, k, z, N);
        CHECKF(even <= 1e-13 && odd <= 1e-13, "R %zu: product off by %g (even), %g (not)", R, even, odd);
        free(z);
        sb_matrix_free(&m);
        sb_param_destroy(p);
    }
    sb_source_destroy(s);
}

/* Y = M Z against the product written out cell by cell. */
SB_TEST(product) {
    sb_source_t *s = fx_model("microfacet:base=copper,roughness=0.3");
    static const size_t Rs[] = {3, 4, 6, 8, 9}; /* 4, 8: the transform by FFT (util/rdft.h) */
    for (size_t ri = 0; ri < sizeof Rs / sizeof Rs[0]; ri++) {
        size_t R = Rs[ri];
        sb_param_t *p = fx_layout(SB_PARAM_IO, R);
        sb_matrix_t m, d;
        build(s, p, SB_FORM_F, 1, &m);
        build(s, p, SB_FORM_F, 0, &d);
        size_t N = m.cols, k = 5, ldz = N + 3, ldy = N + 1;
        double *z = calloc(ldz * k, sizeof *z), *y = calloc(ldy * k, sizeof *y), *yd = calloc(ldy * k, sizeof *yd);
        for (size_t i = 0; i < ldz * k; i++)
            z[i] = sin(0.37 * (double)i + 1.0);
        for (int c = 0; c < 3; c++) {
            CHECK(sb_matrix_mul(NULL, &m, c, k, z, ldz, y, ldy) == SB_OK);
            CHECK(sb_matrix_mul(NULL, &d, c, k, z, ldz, yd, ldy) == SB_OK);
            double worst = 0, scale = 0;
            for (size_t j = 0; j < k; j++)
                for (size_t r = 0; r < N; r++) {
                    double want = 0;
                    for (size_t col = 0; col < N; col++)
                        want += d.data[c][r + col * d.ld] * z[col + j * ldz];
                    worst = fmax(worst, fmax(fabs(y[r + j * ldy] - want), fabs(yd[r + j * ldy] - want)));
                    scale = fmax(scale, fabs(want));
                }
            CHECKF(worst <= 1e-13 * scale, "R %zu ch %d: product off by %g of %g", R, c, worst, scale);
        }
        CHECK(sb_matrix_mul(NULL, &m, 0, k, z, N - 1, y, ldy) == SB_ERR_ARG);
        free(z);
        free(y);
        free(yd);
        sb_matrix_free(&m);
        sb_matrix_free(&d);
        sb_param_destroy(p);
    }
    sb_source_destroy(s);
}

static sb_factors_t *factor(const sb_matrix_t *m, const sb_param_t *p, size_t J, sb_method_t method, int weighted) {
    sb_plan_opts_t po = {0};
    po.terms = J;
    po.svd.method = method;
    po.weighted = weighted;
    sb_plan_t *plan;
    sb_factors_t *f = NULL;
    CHECK(sb_plan_create_for(NULL, m, &po, &plan) == SB_OK);
    CHECK(sb_plan_execute(plan, m, p, &f) == SB_OK);
    sb_plan_destroy(plan);
    return f;
}

/* The plan gives the same factors and errors on both storages: the
 * circulant method reads the stored values, the dense methods an expanded
 * copy; the stored-precision errors (sb_factors_errors_near) agree too. */
SB_TEST(plan_on_structured) {
    sb_source_t *s = fx_model("microfacet:base=gold,roughness=0.5");
    sb_param_t *p = fx_layout(SB_PARAM_IO, 8);
    sb_matrix_t m, d;
    build(s, p, SB_FORM_F, 1, &m);
    build(s, p, SB_FORM_F, 0, &d);
    sb_method_t methods[] = {SB_METHOD_AUTO, SB_METHOD_FULL};
    for (int w = 0; w < 2; w++)
        for (int k = 0; k < 2; k++) {
            size_t J = 6;
            sb_factors_t *fm = factor(&m, p, J, methods[k], w), *fd = factor(&d, p, J, methods[k], w);
            CHECK(strcmp(sb_factors_get_meta(fm, "method"), sb_factors_get_meta(fd, "method")) == 0);
            const sb_factor_errors_t *em = sb_factors_errors(fm), *ed = sb_factors_errors(fd);
            for (size_t i = 0; i < J * 4; i++) {
                CHECKF(fabs(em->rel_rms[i] - ed->rel_rms[i]) <= 1e-12, "w %d method %d: rel_rms %zu %.17g vs %.17g", w,
                       k, i, em->rel_rms[i], ed->rel_rms[i]);
                CHECKF(fabs(em->max_abs[i] - ed->max_abs[i]) <= 1e-12 * (1 + ed->max_abs[i]), "max_abs %zu", i);
            }
            sb_exr_opts_t eo = {1};
            sb_factors_t *q = NULL;
            CHECK(sb_factors_quantize(NULL, fm, &eo, &q, NULL) == SB_OK);
            double *rm = malloc(J * 4 * sizeof *rm), *rd = malloc(J * 4 * sizeof *rd), *mx = malloc(J * 4 * sizeof *mx);
            CHECK(sb_factors_errors_near(NULL, fm, q, &m, w ? p : NULL, rm) == SB_OK);
            CHECK(sb_factors_errors_against(NULL, q, &d, w ? p : NULL, rd, mx) == SB_OK);
            for (size_t i = 0; i < J * 4; i++)
                CHECKF(fabs(rm[i] - rd[i]) <= 1e-9 * rd[i] + 1e-13, "stored %zu: %.17g vs explicit %.17g", i, rm[i],
                       rd[i]);
            CHECK(sb_factors_errors_against(NULL, q, &m, w ? p : NULL, rm, mx) == SB_OK);
            for (size_t i = 0; i < J * 4; i++)
                CHECKF(fabs(rm[i] - rd[i]) <= 1e-12 * rd[i] + 1e-15, "explicit %zu: %.17g vs %.17g", i, rm[i], rd[i]);
            free(rm);
            free(rd);
            free(mx);
            sb_factors_destroy(q);
            sb_factors_destroy(fm);
            sb_factors_destroy(fd);
        }
    sb_matrix_free(&m);
    sb_matrix_free(&d);
    sb_param_destroy(p);
    sb_source_destroy(s);
}

/* Proportional channels: the same answer from the stored values. */
SB_TEST(channels_on_structured) {
    sb_source_t *s = fx_model("lambert:albedo=0.2/0.4/0.8");
    sb_param_t *p = fx_layout(SB_PARAM_IO, 7);
    sb_matrix_t m, d;
    build(s, p, SB_FORM_COS2, 1, &m);
    build(s, p, SB_FORM_COS2, 0, &d);
    sb_channels_t a, b;
    CHECK(sb_channels_proportional(NULL, &m, 0, &a) == SB_OK);
    CHECK(sb_channels_proportional(NULL, &d, 0, &b) == SB_OK);
    CHECK(a.proportional && b.proportional && a.base == b.base);
    for (int c = 0; c < 3; c++) {
        CHECKF(fabs(a.norm[c] - b.norm[c]) <= 1e-13 * b.norm[c], "norm %d: %.17g vs %.17g", c, a.norm[c], b.norm[c]);
        CHECK(fabs(a.scale[c] - b.scale[c]) <= 1e-13);
    }
    sb_matrix_free(&m);
    sb_matrix_free(&d);
    sb_param_destroy(p);
    sb_source_destroy(s);
}

/* The memory check counts what is stored: a limit below the dense size
 * but above the distinct values lets the structured build through. */
SB_TEST(memory_follows_storage) {
    sb_context_t *ctx;
    sb_context_create(&ctx);
    sb_source_t *s = fx_model("lambert");
    sb_param_t *p = fx_layout(SB_PARAM_IO, 32);
    sb_set_memory_limit((size_t)4 << 20); /* dense: 24 MiB + 1 MiB mask; distinct values: 768 KiB */
    sb_matrix_t m;
    sb_matrix_opts_t mo = {0};
    CHECK(sb_matrix_build(ctx, s, p, &mo, &m) == SB_ERR_OVERFLOW);
    mo.structured = 1;
    CHECK(sb_matrix_build(ctx, s, p, &mo, &m) == SB_OK && m.structured);
    sb_plan_t *plan = NULL;
    CHECK(sb_plan_create_for(ctx, &m, NULL, &plan) == SB_OK);
    sb_factors_t *f = NULL;
    CHECK(sb_plan_execute(plan, &m, p, &f) == SB_OK);
    CHECK(strcmp(sb_factors_get_meta(f, "method"), "circulant") == 0);
    CHECK(sb_factors_errors(f)->rel_rms[3] < 1e-12); /* Lambert: rank 1 */
    sb_set_memory_limit(0);
    sb_factors_destroy(f);
    sb_plan_destroy(plan);
    sb_matrix_free(&m);
    sb_param_destroy(p);
    sb_source_destroy(s);
    sb_context_destroy(ctx);
}

/* The real DFT by FFT (util/rdft.h) against its sums, cos and sin, with
 * leading dimensions wider than the rows, odd row counts (a lane's second
 * row missing) and on two threads; sizes it does not take are refused. */
SB_TEST(rdft_against_sums) {
    static const size_t Rs[] = {4, 8, 32, 64};
    static const size_t rows_of[] = {1, 7, 200, 301};
    for (size_t a = 0; a < sizeof Rs / sizeof Rs[0]; a++)
        for (size_t b = 0; b < sizeof rows_of / sizeof rows_of[0]; b++) {
            size_t R = Rs[a], rows = rows_of[b], nb = R / 2 + 1, ldx = rows + 3, ldc = rows + 1;
            double *x = malloc(ldx * R * sizeof *x), *c = calloc(ldc * nb, sizeof *c),
                   *sn = calloc(ldc * nb, sizeof *sn);
            for (size_t i = 0; i < ldx * R; i++)
                x[i] = sin(0.61 * (double)i + 0.3) + (double)(i % 5);
            CHECK(sb_rdft_cols(R, nb, rows, x, ldx, c, ldc, sn, ldc, 2) == 1);
            double worst = 0, scale = 0;
            for (size_t f = 0; f < nb; f++)
                for (size_t r = 0; r < rows; r++) {
                    double wc = 0, ws = 0;
                    for (size_t d = 0; d < R; d++) {
                        double ang = 2 * SB_PI * (double)((f * d) % R) / (double)R;
                        wc += x[r + d * ldx] * cos(ang);
                        ws += x[r + d * ldx] * sin(ang);
                        scale = fmax(scale, fabs(x[r + d * ldx]));
                    }
                    worst = fmax(worst, fmax(fabs(c[r + f * ldc] - wc), fabs(sn[r + f * ldc] - ws)));
                }
            CHECKF(worst <= 1e-14 * (double)R * scale, "R %zu, %zu rows: off by %g of %g", R, rows, worst, scale);
            free(x);
            free(c);
            free(sn);
        }
    double one = 1, out[4];
    CHECK(!sb_rdft_cols(6, 4, 1, &one, 1, out, 1, NULL, 1, 1) && !sb_rdft_cols(2, 2, 1, &one, 1, out, 1, NULL, 1, 1));
    CHECK(sb_rdft_fits(1024) && !sb_rdft_fits(12) && !sb_rdft_fits(2));
}
