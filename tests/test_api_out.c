/* The public API misused, second half (test_api.c has the first): plan,
 * errors, metric, EXR, GLSL, images, renderer, measured tables and channel
 * grouping, called with NULL, zero, SIZE_MAX, out-of-range and unknown
 * values; each returns its documented code or safe value.  `every_code`
 * triggers every result code at least once. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include "api_check.h"

/* A lambert source, io grid res 4, its matrix and factors of 2 terms. */
typedef struct fixture {
    sb_source_t *src;
    sb_param_t *p;
    sb_matrix_t m;
    sb_plan_t *plan;
    sb_factors_t *f;
} fixture_t;

static void fixture(fixture_t *x) {
    memset(x, 0, sizeof *x);
    sb_param_opts_t po = {.res = 4};
    sb_plan_opts_t pl = {.terms = 2};
    CHECK(sb_model_create(ctx(), "lambert", &x->src) == SB_OK);
    CHECK(sb_param_create(ctx(), SB_PARAM_IO, &po, &x->p) == SB_OK);
    CHECK(sb_matrix_build(ctx(), x->src, x->p, NULL, &x->m) == SB_OK);
    CHECK(sb_plan_create(ctx(), x->m.rows, x->m.cols, &pl, &x->plan) == SB_OK);
    CHECK(sb_plan_execute(x->plan, &x->m, x->p, &x->f) == SB_OK);
}
static void fixture_free(fixture_t *x) {
    sb_factors_destroy(x->f);
    sb_plan_destroy(x->plan);
    sb_matrix_free(&x->m);
    sb_param_destroy(x->p);
    sb_source_destroy(x->src);
}

SB_TEST(plan) {
    sb_plan_t *plan = NULL;
    sb_plan_opts_t o = {.terms = SIZE_MAX};
    CHECK_CODE(sb_plan_create(ctx(), 4, 4, NULL, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_plan_create(ctx(), 0, 4, NULL, &plan), SB_ERR_ARG);
    CHECK_CODE(sb_plan_create(ctx(), 4, 4, &o, &plan), SB_ERR_RANGE);
    o.terms = 1;
    CHECK_CODE(sb_plan_create(ctx(), SIZE_MAX, SIZE_MAX, &o, &plan), SB_ERR_OVERFLOW);
    o.max_error = -1;
    CHECK_CODE(sb_plan_create(ctx(), 4, 4, &o, &plan), SB_ERR_RANGE);
    o.max_error = 0;
    o.svd.method = (sb_method_t)BAD_ENUM;
    CHECK_CODE(sb_plan_create(ctx(), 4, 4, &o, &plan), SB_ERR_ARG);
    CHECK(plan == NULL);
    sb_plan_destroy(NULL);
    CHECK_CODE(sb_plan_create_for(ctx(), NULL, NULL, &plan), SB_ERR_ARG);
    sb_matrix_t narrow_m;
    memset(&narrow_m, 0, sizeof narrow_m);
    narrow_m.rows = narrow_m.cols = 4; /* no data, ld 0 */
    CHECK_CODE(sb_plan_create_for(ctx(), &narrow_m, NULL, NULL), SB_ERR_ARG);
    CHECK(sb_solver_count() > 0 && sb_solver_name(sb_solver_count()) == NULL);
    CHECK(sb_solver_description(SIZE_MAX) == NULL && sb_solver_caps(SIZE_MAX) == 0);
    sb_plan_stats_t st;
    memset(&st, 0xff, sizeof st);
    sb_plan_stats(NULL, &st);
    CHECK(st.masked == 0 && st.fit_iterations == 0);
    fixture_t x;
    fixture(&x);
    sb_plan_stats(x.plan, NULL);
    sb_factors_t *f = NULL;
    CHECK_CODE(sb_plan_execute(NULL, &x.m, x.p, &f), SB_ERR_ARG);
    CHECK_CODE(sb_plan_execute(x.plan, NULL, x.p, &f), SB_ERR_ARG);
    CHECK_CODE(sb_plan_execute(x.plan, &x.m, NULL, &f), SB_ERR_ARG);
    CHECK_CODE(sb_plan_execute(x.plan, &x.m, x.p, NULL), SB_ERR_ARG);
    sb_param_opts_t po = {.res = 5};
    sb_param_t *other = NULL;
    CHECK(sb_param_create(ctx(), SB_PARAM_IO, &po, &other) == SB_OK);
    CHECK_CODE(sb_plan_execute(x.plan, &x.m, other, &f), SB_ERR_ARG); /* textures are not the matrix's */
    CHECK(f == NULL);
    /* errors and metric */
    double rel[8], mx[8];
    CHECK_CODE(sb_factors_errors_against(ctx(), NULL, &x.m, NULL, rel, mx), SB_ERR_ARG);
    CHECK_CODE(sb_factors_errors_against(ctx(), x.f, &x.m, other, rel, mx), SB_ERR_ARG);
    CHECK_CODE(sb_factors_errors_near(ctx(), x.f, NULL, &x.m, NULL, rel), SB_ERR_ARG);
    CHECK_CODE(sb_factors_errors_near(ctx(), x.f, x.f, &x.m, other, rel), SB_ERR_ARG);
    sb_metric_t met;
    sb_metric_opts_t mo = {.res = SIZE_MAX};
    CHECK_CODE(sb_metric_compute(ctx(), x.src, x.f, x.p, SB_FORM_F, NULL, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_metric_compute(ctx(), x.src, x.f, x.p, (sb_form_t)BAD_ENUM, NULL, &met), SB_ERR_ARG);
    CHECK_CODE(sb_metric_compute(ctx(), x.src, x.f, x.p, SB_FORM_F, &mo, &met), SB_ERR_RANGE);
    CHECK_CODE(sb_metric_compute(ctx(), x.src, x.f, other, SB_FORM_F, NULL, &met), SB_ERR_ARG);
    sb_param_destroy(other);
    fixture_free(&x);
}

SB_TEST(exr_glsl) {
    fixture_t x;
    fixture(&x);
    const char *dir = sb_tmpdir("api-exr");
    char path[4200], name[16] = "";
    sb_factors_t *f = NULL;
    CHECK_CODE(sb_factors_write_exr(ctx(), NULL, dir, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_factors_write_exr(ctx(), x.f, NULL, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_factors_write_exr(ctx(), x.f, "/nonexistent/dir", NULL), SB_ERR_IO);
    CHECK_CODE(sb_factors_read_exr(ctx(), NULL, &f), SB_ERR_ARG);
    CHECK_CODE(sb_factors_read_exr(ctx(), dir, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_factors_read_exr(ctx(), dir, &f), SB_ERR_IO); /* no files */
    CHECK_CODE(sb_factors_quantize(ctx(), NULL, NULL, &f, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_factors_quantize(ctx(), x.f, NULL, NULL, NULL), SB_ERR_ARG);
    sb_exr_name(SB_SIDE_H, SIZE_MAX, name, sizeof name);
    CHECK(strncmp(name, "h_", 2) == 0);
    sb_exr_name(SB_SIDE_G, 1, NULL, 16);
    sb_exr_name(SB_SIDE_G, 1, name, 0);
    /* GLSL */
    CHECK(sb_glsl_library() != NULL);
    CHECK(sb_glsl_snippet(NULL, SB_FORM_F, 2, NULL) == NULL);
    CHECK(sb_glsl_snippet(x.p, SB_FORM_F, 0, NULL) == NULL);
    CHECK(sb_glsl_snippet(x.p, SB_FORM_F, SIZE_MAX, NULL) == NULL);
    CHECK(sb_glsl_snippet(x.p, (sb_form_t)BAD_ENUM, 2, NULL) == NULL);
    snprintf(path, sizeof path, "%s/s.glsl", dir);
    CHECK_CODE(sb_glsl_write(ctx(), NULL, x.p, SB_FORM_F, 2, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_glsl_write(ctx(), path, NULL, SB_FORM_F, 2, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_glsl_write(ctx(), path, x.p, SB_FORM_F, 0, NULL), SB_ERR_RANGE);
    CHECK_CODE(sb_glsl_write(ctx(), path, x.p, (sb_form_t)BAD_ENUM, 2, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_glsl_write(ctx(), path, x.p, SB_FORM_F, SIZE_MAX, NULL), SB_ERR_RANGE);
    CHECK_CODE(sb_glsl_write(ctx(), "/nonexistent/dir/s.glsl", x.p, SB_FORM_F, 2, NULL), SB_ERR_IO);
    CHECK(!sb_file_exists(path));
    /* previews and the parameterisation from metadata */
    CHECK_CODE(sb_factors_write_previews(ctx(), NULL, dir), SB_ERR_ARG);
    CHECK_CODE(sb_factors_write_previews(ctx(), x.f, NULL), SB_ERR_ARG);
    sb_param_t *p = NULL;
    sb_form_t form;
    CHECK_CODE(sb_factors_param(ctx(), NULL, &p, &form), SB_ERR_ARG);
    CHECK_CODE(sb_factors_param(ctx(), x.f, NULL, &form), SB_ERR_ARG);
    CHECK_CODE(sb_factors_param(ctx(), x.f, &p, NULL), SB_ERR_ARG);
    sb_factors_t *bare = NULL;
    CHECK(sb_factors_create(ctx(), 1, 1, 2, 2, 2, 2, &bare) == SB_OK);
    CHECK_CODE(sb_factors_param(ctx(), bare, &p, &form), SB_ERR_FORMAT);
    sb_factors_destroy(bare);
    char rm[4300];
    snprintf(rm, sizeof rm, "rm -rf %s", dir);
    CHECK(system(rm) == 0);
    fixture_free(&x);
}

static int brdf_one(const void *user, const double wi[3], const double wo[3], double rgb[3]) {
    (void)user, (void)wi, (void)wo;
    rgb[0] = rgb[1] = rgb[2] = 1;
    return 1;
}

SB_TEST(image_render) {
    sb_image_t img, img2;
    memset(&img, 0, sizeof img);
    CHECK_CODE(sb_image_alloc(ctx(), 4, 4, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_image_alloc(ctx(), 0, 4, &img), SB_ERR_ARG);
    CHECK_CODE(sb_image_alloc(ctx(), SIZE_MAX, SIZE_MAX, &img), SB_ERR_OVERFLOW);
    sb_image_free(NULL);
    sb_image_free(&img);
    sb_tonemap_op_t op;
    CHECK_CODE(sb_tonemap_parse(NULL, &op), SB_ERR_UNKNOWN);
    CHECK_CODE(sb_tonemap_parse("clamp", NULL), SB_ERR_ARG);
    CHECK(strcmp(sb_tonemap_name((sb_tonemap_op_t)BAD_ENUM), "?") == 0);
    sb_tonemap_t bad = {.exposure = 1, .op = (sb_tonemap_op_t)BAD_ENUM};
    CHECK(sb_srgb_oetf(NAN) == 0 && sb_tonemap_apply(NULL, NAN) == 0 && sb_tonemap_apply(&bad, 0.5) >= 0);
    CHECK(sb_image_max(NULL) == 0 && sb_image_max(&img) == 0);
    sb_image_diff_t d;
    CHECK_CODE(sb_image_compare(ctx(), NULL, &img, NULL, &d), SB_ERR_ARG);
    CHECK(sb_image_alloc(ctx(), 4, 4, &img) == SB_OK && sb_image_alloc(ctx(), 5, 4, &img2) == SB_OK);
    CHECK_CODE(sb_image_compare(ctx(), &img, &img2, NULL, &d), SB_ERR_ARG);
    CHECK_CODE(sb_image_compare(ctx(), &img, &img, NULL, NULL), SB_ERR_ARG);
    const char *dir = sb_tmpdir("api-png");
    char path[4200];
    snprintf(path, sizeof path, "%s/a.png", dir);
    unsigned char px[12] = {0};
    CHECK_CODE(sb_png_write_rgb8(ctx(), NULL, 2, 2, px, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_png_write_rgb8(ctx(), path, 2, 2, NULL, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_png_write_rgb8(ctx(), path, SIZE_MAX, 2, px, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_png_write_rgb8(ctx(), "/nonexistent/dir/a.png", 2, 2, px, NULL), SB_ERR_IO);
    CHECK_CODE(sb_image_write_png(ctx(), path, NULL, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_image_write_png(ctx(), NULL, &img, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_image_write_strip_png(ctx(), path, &img, NULL, NULL, 1), SB_ERR_ARG);
    CHECK_CODE(sb_image_write_strip_png(ctx(), path, &img, &img2, NULL, 1), SB_ERR_ARG);
    CHECK(!sb_file_exists(path));
    sb_colormap_diverging(NAN, NULL);
    sb_image_free(&img2);
    sb_image_free(&img); /* the renderer's outputs are overwritten, not freed */
    /* renderer */
    sb_light_from_angles(45, 45, 0, NULL);
    double n[3], t[3], b[3];
    CHECK(sb_render_frame(NULL, SIZE_MAX, SIZE_MAX, n, t, b) == 0);
    CHECK(sb_render_frame(NULL, 128, 128, NULL, t, b) == 0 && sb_render_frame(NULL, 128, 128, n, NULL, NULL) == 0);
    sb_render_opts_t ro = {.size = SIZE_MAX};
    CHECK_CODE(sb_render(ctx(), NULL, NULL, NULL, &img), SB_ERR_ARG);
    CHECK_CODE(sb_render(ctx(), NULL, brdf_one, NULL, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_render(ctx(), &ro, brdf_one, NULL, &img), SB_ERR_RANGE);
    ro.size = 8;
    ro.light_count = SIZE_MAX;
    CHECK_CODE(sb_render(ctx(), &ro, brdf_one, NULL, &img), SB_ERR_ARG);
    CHECK_CODE(sb_render_source(ctx(), NULL, NULL, &img), SB_ERR_ARG);
    fixture_t x;
    fixture(&x);
    CHECK_CODE(sb_render_source(ctx(), NULL, x.src, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_render_factors(ctx(), NULL, NULL, x.p, SB_FORM_F, 1, &img), SB_ERR_ARG);
    CHECK_CODE(sb_render_factors(ctx(), NULL, x.f, x.p, SB_FORM_F, 3, &img), SB_ERR_ARG);
    CHECK_CODE(sb_render_factors(ctx(), NULL, x.f, x.p, (sb_form_t)BAD_ENUM, 1, &img), SB_ERR_ARG);
    CHECK_CODE(sb_render_factors(ctx(), NULL, x.f, x.p, SB_FORM_F, 1, NULL), SB_ERR_ARG);
    sb_image_free(&img);
    char rm[4300];
    snprintf(rm, sizeof rm, "rm -rf %s", dir);
    CHECK(system(rm) == 0);
    fixture_free(&x);
}

SB_TEST(measured_channels) {
    sb_interp_t in;
    size_t nf = sb_measured_format_count();
    CHECK(nf > 0 && sb_measured_format_name(nf) == NULL && sb_measured_format_title(SIZE_MAX) == NULL);
    CHECK(sb_measured_format_exts(nf) == NULL);
    CHECK(strcmp(sb_interp_name((sb_interp_t)-1), "?") == 0);
    CHECK_CODE(sb_interp_parse(NULL, &in), SB_ERR_UNKNOWN);
    CHECK_CODE(sb_interp_parse("idw", NULL), SB_ERR_ARG);
    sb_source_t *s = NULL;
    sb_measured_opts_t mo = {.format = "no-such-format"};
    CHECK_CODE(sb_measured_open(ctx(), NULL, NULL, &s, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_measured_open(ctx(), "x.csv", NULL, NULL, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_measured_open(ctx(), "/nonexistent/x.csv", NULL, &s, NULL), SB_ERR_IO);
    CHECK_CODE(sb_measured_open(ctx(), SB_CLI, &mo, &s, NULL), SB_ERR_UNKNOWN);
    mo.format = "csv";
    mo.neighbours = SIZE_MAX;
    CHECK_CODE(sb_measured_open(ctx(), SB_CLI, &mo, &s, NULL), SB_ERR_RANGE);
    fixture_t x;
    fixture(&x);
    size_t known = 0, cells = 0;
    CHECK_CODE(sb_measured_coverage(ctx(), NULL, x.p, &known, &cells), SB_ERR_ARG);
    CHECK_CODE(sb_measured_coverage(ctx(), x.src, NULL, &known, &cells), SB_ERR_ARG);
    CHECK_CODE(sb_measured_coverage(ctx(), x.src, x.p, NULL, NULL), SB_OK);
    double a, b, c, w1[3], w2[3];
    size_t idx = 7;
    CHECK(sb_half_diff_angles(NULL, wo_up, &a, &b, &c) == 0 && sb_half_diff_angles(wi_up, wo_up, NULL, &b, &c) == 0);
    CHECK(sb_half_diff_dirs(0.1, 0.1, 0.1, NULL, w2) == 0 && sb_half_diff_dirs(0.1, 0.1, 0.1, w1, NULL) == 0);
    CHECK(sb_merl_index(NULL, wo_up, &idx) == 0 && sb_merl_index(wi_up, wo_up, NULL) == 0 && idx == 7);
    CHECK(sb_merl_cell_dirs(SB_MERL_CELLS, w1, w2) == 0 && sb_merl_cell_dirs(SIZE_MAX, w1, w2) == 0);
    CHECK(sb_merl_cell_dirs(0, NULL, w2) == 0);
    CHECK_CODE(sb_merl_write(ctx(), NULL, x.src), SB_ERR_ARG);
    CHECK_CODE(sb_merl_write(ctx(), "/nonexistent/dir/x.binary", x.src), SB_ERR_IO);
    FILE *fp = tmpfile();
    sb_gonio_opts_t go = {.n_theta_i = SIZE_MAX};
    CHECK_CODE(sb_gonio_write_csv(ctx(), NULL, x.src, NULL, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_gonio_write_csv(ctx(), fp, NULL, NULL, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_gonio_write_csv(ctx(), fp, x.src, &go, NULL), SB_ERR_RANGE);
    go.n_theta_i = 2;
    go.noise = NAN;
    CHECK_CODE(sb_gonio_write_csv(ctx(), fp, x.src, &go, NULL), SB_ERR_RANGE);
    fclose(fp);
    sb_cie_cmf(550, NULL);
    double nm[2] = {400, 500}, wts[6];
    CHECK_CODE(sb_spectral_weights(ctx(), NULL, 2, SB_WHITE_E, wts), SB_ERR_ARG);
    CHECK_CODE(sb_spectral_weights(ctx(), nm, 0, SB_WHITE_E, wts), SB_ERR_RANGE);
    CHECK_CODE(sb_spectral_weights(ctx(), nm, SIZE_MAX, SB_WHITE_E, wts), SB_ERR_OVERFLOW);
    CHECK_CODE(sb_spectral_weights(ctx(), nm, 2, (sb_white_t)BAD_ENUM, wts), SB_ERR_ARG);
    /* channels */
    sb_channels_t ch;
    sb_matrix_t empty;
    memset(&empty, 0, sizeof empty);
    CHECK_CODE(sb_channels_proportional(ctx(), NULL, 0, &ch), SB_ERR_ARG);
    CHECK_CODE(sb_channels_proportional(ctx(), &x.m, 0, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_channels_proportional(ctx(), &x.m, 2, &ch), SB_ERR_RANGE);
    CHECK_CODE(sb_channels_proportional(ctx(), &empty, 0, &ch), SB_ERR_ARG);
    sb_matrix_t narrow = x.m; /* a leading dimension below the rows */
    narrow.ld = narrow.rows - 1;
    double rel[8], mx[8];
    CHECK_CODE(sb_channels_proportional(ctx(), &narrow, 0, &ch), SB_ERR_ARG);
    CHECK_CODE(sb_factors_errors_against(ctx(), x.f, &narrow, NULL, rel, mx), SB_ERR_ARG);
    CHECK_CODE(sb_factors_errors_near(ctx(), x.f, x.f, &narrow, NULL, rel), SB_ERR_ARG);
    sb_factors_t *g = NULL;
    CHECK_CODE(sb_plan_execute(x.plan, &narrow, x.p, &g), SB_ERR_ARG);
    CHECK(g == NULL);

    fixture_free(&x);
}

SB_TEST(outset) {
    sb_outset_t *s = NULL;
    char longname[8192];
    memset(longname, 'a', sizeof longname - 1);
    longname[sizeof longname - 1] = 0;
    CHECK_CODE(sb_outset_check(ctx(), NULL), SB_ERR_ARG);
    CHECK_CODE(sb_outset_check(ctx(), ""), SB_ERR_ARG);
    CHECK_CODE(sb_outset_check(ctx(), longname), SB_ERR_IO);
    CHECK_CODE(sb_outset_begin(ctx(), NULL, NULL, &s), SB_ERR_ARG);
    CHECK_CODE(sb_outset_begin(ctx(), "x", NULL, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_outset_cleanup(ctx(), NULL), SB_ERR_ARG);
    CHECK(sb_outset_dir(NULL) == NULL && sb_outset_target(NULL) == NULL);
    CHECK(sb_outset_add(NULL, "a") == SB_ERR_ARG && sb_outset_commit(NULL) == SB_ERR_ARG);
    sb_outset_destroy(NULL);
    sb_outset_discard_signal_safe(NULL);
    CHECK(sb_io_why(-1) != NULL && sb_io_why(INT32_MAX) != NULL);
    char dir[4200];
    snprintf(dir, sizeof dir, "%s/set", sb_tmpdir("api-outset"));
    CHECK(sb_outset_begin(ctx(), dir, NULL, &s) == SB_OK);
    CHECK_CODE(sb_outset_add(s, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_outset_add(s, "../up"), SB_ERR_ARG);
    CHECK_CODE(sb_outset_add(s, ".hidden"), SB_ERR_ARG);
    CHECK_CODE(sb_outset_add(s, longname), SB_ERR_ARG);
    CHECK_CODE(sb_outset_add(s, "missing.txt"), SB_OK);
    CHECK_CODE(sb_outset_commit(s), SB_ERR_IO); /* the named file was never written */
    CHECK_CODE(sb_outset_commit(s), SB_ERR_ARG);
    sb_outset_destroy(s);
    char rm[4300];
    snprintf(rm, sizeof rm, "rm -rf %s", dir);
    CHECK(system(rm) == 0);
}

SB_TEST(estimate_viewer) {
    fixture_t x;
    fixture(&x);
    sb_pairs_t *pairs = NULL;
    CHECK_CODE(sb_pairs_create(ctx(), NULL, NULL, &pairs), SB_ERR_ARG);
    CHECK_CODE(sb_pairs_create(ctx(), x.src, NULL, NULL), SB_ERR_ARG);
    sb_pairs_destroy(NULL);
    CHECK(sb_pairs_count(NULL) == 0);
    sb_estimate_t est;
    CHECK_CODE(sb_estimate_compute(ctx(), NULL, x.f, NULL, x.p, SB_FORM_F, NULL, &est), SB_ERR_ARG);
    sb_estimate_opts_t eo = {.start = 64, .max_pairs = 64};
    CHECK(sb_pairs_create(ctx(), x.src, &eo, &pairs) == SB_OK);
    CHECK_CODE(sb_estimate_compute(ctx(), pairs, x.f, NULL, x.p, (sb_form_t)BAD_ENUM, &eo, &est), SB_ERR_ARG);
    CHECK_CODE(sb_estimate_compute(ctx(), pairs, NULL, NULL, x.p, SB_FORM_F, &eo, &est), SB_ERR_ARG);
    sb_pairs_destroy(pairs);
    CHECK(isnan(sb_estimate_headline(NULL, 1)) && isnan(sb_estimate_headline(&est, 0)));
    CHECK(isnan(sb_estimate_headline(&est, SIZE_MAX)));
    double scales[2];
    CHECK_CODE(sb_exr_term_scales(ctx(), NULL, NULL, scales), SB_ERR_ARG);
    CHECK_CODE(sb_exr_term_scales(ctx(), x.f, NULL, NULL), SB_ERR_ARG);
    CHECK(sb_param_kind_count() >= 5 && sb_err_at(1, 2) == 6);
    char path[4200];
    snprintf(path, sizeof path, "%s/v.html", sb_tmpdir("api-viewer"));
    CHECK_CODE(sb_viewer_write(ctx(), NULL, x.f, x.p, SB_FORM_F, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_viewer_write(ctx(), path, NULL, x.p, SB_FORM_F, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_viewer_write(ctx(), path, x.f, NULL, SB_FORM_F, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_viewer_write(ctx(), path, x.f, x.p, (sb_form_t)BAD_ENUM, NULL), SB_ERR_ARG);
    CHECK(!sb_file_exists(path));
    fixture_free(&x);
}

/* Every result code is returned by some public function. */
SB_TEST(every_code) {
    sb_param_kind_t k;
    sb_param_opts_t o;
    sb_source_t *s = NULL;
    sb_svd_t *svd = NULL;
    CHECK_CODE(sb_param_parse_spec(ctx(), "io", NULL, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_param_parse_spec(ctx(), "io:res=0", &k, &o), SB_ERR_RANGE);
    CHECK_CODE(sb_param_parse_spec(ctx(), "io:res", &k, &o), SB_ERR_PARSE);
    CHECK_CODE(sb_param_parse_spec(ctx(), "xyz", &k, &o), SB_ERR_UNKNOWN);
    CHECK_CODE(sb_svd_create(ctx(), SIZE_MAX, 4, 1, NULL, &svd), SB_ERR_OVERFLOW);
    CHECK_CODE(sb_measured_open(ctx(), "/nonexistent", NULL, &s, NULL), SB_ERR_IO);
    CHECK_CODE(sb_measured_open(ctx(), SB_CLI, NULL, &s, NULL), SB_ERR_FORMAT); /* a binary is no table */
    double A[4] = {1, NAN, 0, 1}, sv[1];
    CHECK(sb_svd_create(ctx(), 2, 2, 1, NULL, &svd) == SB_OK);
    CHECK_CODE(sb_svd_execute(svd, A, 2, sv, NULL, NULL, NULL, NULL), SB_ERR_NUMERIC);
    sb_svd_destroy(svd);
    char path[4200];
    snprintf(path, sizeof path, "%s/t.alta", sb_tmpdir("api-codes"));
    /* an ALTA table of another parameterisation is recognised, not supported */
    FILE *fp = fopen(path, "w");
    CHECK(fp && fputs("#DIM 2 1\n#PARAM_IN RUSIN_TH_TD\n", fp) >= 0 && fclose(fp) == 0);
    CHECK_CODE(sb_measured_open(ctx(), path, NULL, &s, NULL), SB_ERR_UNSUPPORTED);
    remove(path);
    /* NOMEM: a real allocation failure, in a child under an address-space
     * limit (or, under ASan, beyond its largest allocation) */
    pid_t pid = fork();
    if (pid == 0) {
#if !defined(__SANITIZE_ADDRESS__)
        struct rlimit rl = {(rlim_t)1 << 30, (rlim_t)1 << 30};
        setrlimit(RLIMIT_AS, &rl);
#endif
        sb_set_memory_limit(SIZE_MAX);
        sb_image_t img;
        _exit(sb_image_alloc(NULL, (size_t)1 << 21, (size_t)1 << 20, &img) == SB_ERR_NOMEM ? 0 : 1);
    }
    int st = 0;
    CHECK(pid > 0 && waitpid(pid, &st, 0) == pid);
    CHECKF(WIFEXITED(st) && WEXITSTATUS(st) == 0, "no SB_ERR_NOMEM from a failed allocation (status %d)", st);
}

#if defined(__SANITIZE_ADDRESS__)
/* the NOMEM case asks ASan for more than it allocates: a NULL, not an abort */
const char *__asan_default_options(void);
const char *__asan_default_options(void) { return "allocator_may_return_null=1"; }
#endif

/* Values the textures cannot store are refused before any file exists,
 * with their real cause and the target file: a BRDF below or above the
 * storage range (SB_ERR_NUMERIC), a later term below it (J above the
 * numerical rank: SB_ERR_RANGE). */
static void expect_refusal(sb_factors_t *f, int half, sb_result_t code, const char *cause, const char *file) {
    const char *dir = sb_tmpdir("api-store");
    sb_exr_opts_t o = {half};
    CHECK_CODE(sb_factors_write_exr(ctx(), f, dir, &o), code);
    const char *msg = sb_context_last_error(ctx());
    CHECKF(strstr(msg, cause) && strstr(msg, file) && !strstr(msg, ".tmp-"), "message: %s", msg);
    char rm[4300];
    snprintf(rm, sizeof rm, "rmdir %s", dir); /* fails unless the folder stayed empty */
    CHECKF(system(rm) == 0, "%s holds files after a refused write", dir);
}

SB_TEST(storage_messages) {
    sb_factors_t *f = NULL;
    CHECK(sb_factors_create(ctx(), 2, 1, 2, 2, 2, 2, &f) == SB_OK);
    for (int t = 0; t < 2; t++)
        for (int s = 0; s < 2; s++)
            for (int i = 0; i < 4; i++)
                sb_factors_tex(f, s, (size_t)t, 0)[i] = t ? 1e-50 : 1e-300;
    sb_factors_set_sigma(f, 0, 0, 1e-300);
    expect_refusal(f, 0, SB_ERR_NUMERIC, "below the range", "g_00.exr");
    expect_refusal(f, 1, SB_ERR_NUMERIC, "below the range", "g_00.exr");
    for (int s = 0; s < 2; s++)
        for (int i = 0; i < 4; i++)
            sb_factors_tex(f, s, 0, 0)[i] = 1e-40; /* FLOAT subnormal: HALF's scale cannot reach it */
    expect_refusal(f, 1, SB_ERR_NUMERIC, "FLOAT stores down to", "g_00.exr");
    for (int s = 0; s < 2; s++)
        for (int i = 0; i < 4; i++)
            sb_factors_tex(f, s, 0, 0)[i] = 1;
    sb_factors_set_sigma(f, 0, 0, 1);
    sb_factors_set_sigma(f, 1, 0, 1e-100);
    expect_refusal(f, 0, SB_ERR_RANGE, "numerical rank is exhausted; ask for at most 1 term", "g_01.exr");
    sb_factors_tex(f, SB_SIDE_H, 0, 0)[3] = 1e39;
    expect_refusal(f, 0, SB_ERR_NUMERIC, "above the FLOAT range", "h_00.exr");
    sb_factors_tex(f, SB_SIDE_H, 0, 0)[3] = 1e300;
    expect_refusal(f, 1, SB_ERR_NUMERIC, "beyond the range", "h_00.exr");
    sb_factors_destroy(f);
}
