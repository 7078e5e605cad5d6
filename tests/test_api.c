/* The public API misused: every function declared in include/sepbrdf/ (every header)
 * called with NULL, zero, SIZE_MAX, out-of-range indices and unknown enum
 * values.  Each call must return the SB_ERR_* code its header documents,
 * or the documented safe value of a getter, and never crash or read
 * outside its buffers (this test runs under ASan and UBSan in CI).  One
 * case per header; `every_code` triggers each result code at least once. */
#include <errno.h>
#include <float.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include "api_check.h"

static sb_param_t *param_io(size_t res) {
    sb_param_opts_t o = {.res = res};
    sb_param_t *p = NULL;
    sb_param_create(ctx(), SB_PARAM_IO, &o, &p);
    return p;
}
static sb_source_t *lambert(void) {
    sb_source_t *s = NULL;
    sb_model_create(ctx(), "lambert", &s);
    return s;
}

SB_TEST(common) {
    CHECK(strcmp(sb_result_name((sb_result_t)-1), "SB_ERR_?") == 0);
    CHECK(strcmp(sb_result_name(SB_RESULT_COUNT_), "SB_ERR_?") == 0);
    CHECK(strcmp(sb_result_message((sb_result_t)BAD_ENUM), "unknown result code") == 0);
    CHECK(sb_context_create(NULL) == SB_ERR_ARG);
    sb_context_destroy(NULL);
    sb_context_set_error_callback(NULL, NULL, NULL);
    CHECK(strcmp(sb_context_last_error(NULL), "") == 0);
    sb_context_clear_error(NULL);
    CHECK(sb_error(NULL, SB_ERR_RANGE, "x %d", 1) == SB_ERR_RANGE);
    CHECK(sb_error(ctx(), SB_ERR_IO, NULL) == SB_ERR_IO);
    CHECK(strcmp(sb_context_last_error(ctx()), "") == 0);
    size_t s = 7;
    CHECK(sb_size_mul(SIZE_MAX, 2, &s) == 1 && s == 7);
    CHECK(sb_size_mul(2, 3, NULL) == 1);
    CHECK(sb_size_mul(0, SIZE_MAX, &s) == 0 && s == 0);
    CHECK(sb_size_mul3(SIZE_MAX, 1, 2, &s) == 1);
    CHECK(sb_size_mul3(1, 1, 1, NULL) == 1);
    CHECK(sb_size_add(SIZE_MAX, 1, &s) == 1);
    CHECK(sb_size_add(1, 1, NULL) == 1);
    sb_set_memory_limit(SIZE_MAX);
    CHECK(sb_memory_limit() == SIZE_MAX);
    sb_set_memory_limit(0);
    CHECK(sb_memory_limit() > 0 && sb_memory_limit() < SIZE_MAX);
}

SB_TEST(param) {
    sb_param_kind_t k = SB_PARAM_IO;
    CHECK_CODE(sb_param_kind_parse(NULL, &k), SB_ERR_UNKNOWN);
    CHECK_CODE(sb_param_kind_parse("io", NULL), SB_ERR_ARG);
    CHECK_CODE(sb_param_kind_parse("nope", &k), SB_ERR_UNKNOWN);
    CHECK(strcmp(sb_param_kind_name((sb_param_kind_t)-1), "?") == 0);
    CHECK(strcmp(sb_param_kind_description((sb_param_kind_t)BAD_ENUM), "?") == 0);
    CHECK(sb_param_kind_caps((sb_param_kind_t)-1) == 0 && sb_param_kind_applies((sb_param_kind_t)BAD_ENUM, ~0u) == 0);
    CHECK(sb_param_caps(NULL) == 0);
    char names[4] = "xyz";
    size_t len = sb_param_kind_list(NULL, 0, ", ");
    CHECK(len > 0 && sb_param_kind_list(NULL, 100, NULL) > 0 &&
          sb_param_kind_list(names, 0, ",") == len - (sb_param_kind_count() - 1));
    CHECK(sb_param_kind_list(names, sizeof names, ", ") == len && strlen(names) == 3); /* truncated, terminated */
    sb_param_opts_t o = {0};
    CHECK_CODE(sb_param_parse_spec(ctx(), NULL, &k, &o), SB_ERR_ARG);
    CHECK_CODE(sb_param_parse_spec(ctx(), "io", NULL, &o), SB_ERR_ARG);
    CHECK_CODE(sb_param_parse_spec(ctx(), "io", &k, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_param_parse_spec(ctx(), "io:res=18446744073709551616", &k, &o), SB_ERR_RANGE);
    CHECK_CODE(sb_param_parse_spec(ctx(), "io:res=x", &k, &o), SB_ERR_PARSE);
    sb_param_t *p = NULL;
    CHECK_CODE(sb_param_create(ctx(), SB_PARAM_IO, NULL, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_param_create(ctx(), (sb_param_kind_t)BAD_ENUM, NULL, &p), SB_ERR_ARG);
    CHECK(p == NULL);
    o.res = SIZE_MAX;
    CHECK_CODE(sb_param_create(ctx(), SB_PARAM_IO, &o, &p), SB_ERR_RANGE);
    o.res = 8;
    o.theta_max = -1;
    CHECK_CODE(sb_param_create(ctx(), SB_PARAM_HD, &o, &p), SB_ERR_RANGE);
    sb_param_destroy(NULL);
    /* getters on NULL: the documented safe values */
    CHECK(sb_param_kind(NULL) == SB_PARAM_NONE);
    CHECK(strcmp(sb_param_name(NULL), "") == 0 && strcmp(sb_param_spec(NULL), "") == 0);
    CHECK(sb_param_rows(NULL) == 0 && sb_param_cols(NULL) == 0);
    CHECK(isnan(sb_param_theta_max(NULL)));
    size_t w = 5, h = 5;
    sb_param_texture_size(NULL, 0, &w, &h);
    CHECK(w == 0 && h == 0);
    int wrap[2] = {5, 5};
    sb_param_wrap(NULL, 0, wrap);
    CHECK(wrap[0] == 0 && wrap[1] == 0);
    double a[3], b[3], st[2], st2[2];
    CHECK(sb_param_cell_dirs(NULL, 0, 0, a, b) == 0);
    CHECK(isnan(sb_param_row_measure(NULL, 0)) && isnan(sb_param_col_measure(NULL, 0)));
    CHECK(sb_param_coords(NULL, wi_up, wo_up, st, st2) == 0);
    CHECK(strcmp(sb_param_glsl(NULL), "") == 0);
    /* every kind: out-of-range cells, NULL outputs */
    for (int kind = 0; kind < SB_TEST_KINDS; kind++) {
        sb_param_opts_t po = {.res = 4};
        CHECK(sb_param_create(ctx(), (sb_param_kind_t)kind, &po, &p) == SB_OK);
        size_t R = sb_param_rows(p), C = sb_param_cols(p);
        CHECK(sb_param_cell_dirs(p, R, 0, a, b) == 0 && sb_param_cell_dirs(p, 0, SIZE_MAX, a, b) == 0);
        CHECK(sb_param_cell_dirs(p, 0, 0, NULL, b) == 0 && sb_param_cell_dirs(p, 0, 0, a, NULL) == 0);
        CHECK(isnan(sb_param_row_measure(p, R)) && isnan(sb_param_col_measure(p, C)));
        CHECK(isnan(sb_param_row_measure(p, SIZE_MAX)) && isnan(sb_param_col_measure(p, SIZE_MAX)));
        CHECK(sb_param_coords(p, NULL, wo_up, st, st2) == 0 && sb_param_coords(p, wi_up, NULL, st, st2) == 0);
        CHECK(sb_param_coords(p, wi_up, wo_up, NULL, st2) == 0 && sb_param_coords(p, wi_up, wo_up, st, NULL) == 0);
        sb_param_texture_size(p, 7, &w, &h);
        CHECK(w == 0 && h == 0);
        sb_param_texture_size(p, SB_SIDE_H, NULL, NULL);
        sb_param_wrap(p, -1, wrap);
        CHECK(wrap[0] == 0 && wrap[1] == 0);
        sb_param_wrap(p, SB_SIDE_G, NULL);
        sb_param_destroy(p);
    }
    sb_dir_from_angles(1, 2, NULL);
    sb_dir_to_angles(NULL, a, b);
    sb_dir_to_angles(wi_up, NULL, NULL);
}

static int eval_one(const void *self, const double wi[3], const double wo[3], double rgb[3]) {
    (void)self, (void)wi, (void)wo;
    rgb[0] = rgb[1] = rgb[2] = 1;
    return 1;
}

SB_TEST(source_models) {
    sb_source_t *s = NULL;
    sb_source_ops_t ops = {eval_one, NULL}, noeval = {NULL, NULL};
    CHECK_CODE(sb_source_create(ctx(), NULL, NULL, 0, "x", &s), SB_ERR_ARG);
    CHECK_CODE(sb_source_create(ctx(), &noeval, NULL, 0, "x", &s), SB_ERR_ARG);
    CHECK_CODE(sb_source_create(ctx(), &ops, NULL, 0, "x", NULL), SB_ERR_ARG);
    CHECK_CODE(sb_source_create(ctx(), &ops, NULL, 0, NULL, &s), SB_OK);
    CHECK(strcmp(sb_source_description(s), "") == 0);
    double rgb[3] = {5, 5, 5};
    CHECK(sb_source_eval(s, NULL, wo_up, rgb) == 0 && rgb[0] == 0);
    CHECK(sb_source_eval(s, wi_up, wo_up, NULL) == 0);
    sb_source_destroy(s);
    sb_source_destroy(NULL);
    rgb[0] = 5;
    CHECK(sb_source_eval(NULL, wi_up, wo_up, rgb) == 0 && rgb[0] == 0);
    CHECK(sb_source_flags(NULL) == 0 && sb_source_impl(NULL) == NULL);
    CHECK(strcmp(sb_source_description(NULL), "") == 0);
    CHECK_CODE(sb_source_open(ctx(), NULL, &s), SB_ERR_ARG);
    CHECK_CODE(sb_source_open(ctx(), "lambert", NULL), SB_ERR_ARG);
    CHECK_CODE(sb_source_open(ctx(), "no-such-model", &s), SB_ERR_UNKNOWN);
    CHECK_CODE(sb_model_create(ctx(), NULL, &s), SB_ERR_ARG);
    CHECK_CODE(sb_model_create(ctx(), "lambert", NULL), SB_ERR_ARG);
    CHECK_CODE(sb_model_create(ctx(), "lambert:albedo=x", &s), SB_ERR_PARSE);
    CHECK_CODE(sb_model_create(ctx(), "lambert:albedo=2", &s), SB_ERR_RANGE);
    CHECK(sb_model_at(sb_model_count()) == NULL && sb_model_at(SIZE_MAX) == NULL);
    CHECK(sb_preset_at(sb_preset_count()) == NULL && sb_preset_at(SIZE_MAX) == NULL);
    CHECK(sb_preset_find(NULL) == NULL && sb_preset_find("") == NULL);
}

SB_TEST(matrix) {
    sb_form_t form = SB_FORM_F;
    CHECK_CODE(sb_form_parse(NULL, &form), SB_ERR_UNKNOWN);
    CHECK_CODE(sb_form_parse("f", NULL), SB_ERR_ARG);
    CHECK_CODE(sb_form_parse("cos3", &form), SB_ERR_UNKNOWN);
    CHECK(strcmp(sb_form_name((sb_form_t)BAD_ENUM), "?") == 0);
    CHECK(isnan(sb_form_weight((sb_form_t)BAD_ENUM, wi_up, wo_up)));
    CHECK(isnan(sb_form_weight(SB_FORM_COS, NULL, wo_up)) && isnan(sb_form_weight(SB_FORM_COS2, wi_up, NULL)));
    sb_source_t *src = lambert();
    sb_param_t *p = param_io(4);
    sb_matrix_t m;
    memset(&m, 0, sizeof m);
    CHECK_CODE(sb_matrix_build(ctx(), NULL, p, NULL, &m), SB_ERR_ARG);
    CHECK_CODE(sb_matrix_build(ctx(), src, NULL, NULL, &m), SB_ERR_ARG);
    CHECK_CODE(sb_matrix_build(ctx(), src, p, NULL, NULL), SB_ERR_ARG);
    sb_matrix_opts_t mo = {.form = (sb_form_t)BAD_ENUM};
    CHECK_CODE(sb_matrix_build(ctx(), src, p, &mo, &m), SB_ERR_ARG);
    mo.form = SB_FORM_F;
    mo.channels = 8;
    CHECK_CODE(sb_matrix_build(ctx(), src, p, &mo, &m), SB_ERR_ARG);
    mo.channels = 0;
    mo.threads = INT32_MAX; /* capped by the library */
    CHECK_CODE(sb_matrix_build(ctx(), src, p, &mo, &m), SB_OK);
    sb_matrix_free(&m);
    sb_matrix_free(NULL);
    sb_matrix_free(&m);
    sb_param_destroy(p);
    sb_source_destroy(src);
}

SB_TEST(svd) {
    sb_method_t me = SB_METHOD_AUTO;
    CHECK_CODE(sb_method_parse(NULL, &me), SB_ERR_UNKNOWN);
    CHECK_CODE(sb_method_parse("full", NULL), SB_ERR_ARG);
    CHECK(strcmp(sb_method_name((sb_method_t)BAD_ENUM), "?") == 0);
    sb_svd_opts_t so = {.method = (sb_method_t)BAD_ENUM};
    CHECK((size_t)sb_svd_auto_method(SIZE_MAX, SIZE_MAX, SIZE_MAX, NULL) < sb_method_count());
    CHECK(sb_svd_auto_method(0, 0, 0, &so) == SB_METHOD_NONE);
    sb_svd_t *s = NULL;
    CHECK_CODE(sb_svd_create(ctx(), 4, 4, 2, NULL, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_svd_create(ctx(), 0, 4, 2, NULL, &s), SB_ERR_ARG);
    CHECK_CODE(sb_svd_create(ctx(), 4, 4, 0, NULL, &s), SB_ERR_RANGE);
    CHECK_CODE(sb_svd_create(ctx(), 4, 4, SIZE_MAX, NULL, &s), SB_ERR_RANGE);
    CHECK_CODE(sb_svd_create(ctx(), SIZE_MAX, SIZE_MAX, 1, NULL, &s), SB_ERR_OVERFLOW);
    CHECK_CODE(sb_svd_create(ctx(), 4, 4, 2, &so, &s), SB_ERR_ARG);
    sb_svd_opts_t wild = {.method = SB_METHOD_RANDOMIZED, .oversample = INT32_MAX, .power_iters = INT32_MAX};
    CHECK_CODE(sb_svd_create(ctx(), 4, 4, 2, &wild, &s), SB_ERR_RANGE);
    wild.power_iters = SB_SVD_MAX_POWER_ITERS;
    wild.block = SIZE_MAX;
    CHECK_CODE(sb_svd_create(ctx(), 4, 4, 2, &wild, &s), SB_OK); /* the sketch is capped at min(m, n) */
    sb_svd_destroy(s);
    sb_svd_destroy(NULL);
    CHECK(sb_svd_method(NULL) == SB_METHOD_NONE && sb_svd_rank(NULL) == 0 && sb_svd_workspace_bytes(NULL) == 0);
    sb_svd_info_t info = sb_svd_last_info(NULL);
    CHECK(info.rank == 0 && info.sketch == 0);
    double A[16] = {1, 0, 0, 0, 0, 2, 0, 0, 0, 0, 3, 0, 0, 0, 0, 4}, sv[2], U[8], V[8];
    CHECK_CODE(sb_svd_execute(NULL, A, 4, sv, U, V, NULL, NULL), SB_ERR_ARG);
    CHECK(sb_svd_create(ctx(), 4, 4, 2, NULL, &s) == SB_OK);
    CHECK_CODE(sb_svd_execute(s, NULL, 4, sv, U, V, NULL, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_svd_execute(s, A, 4, NULL, U, V, NULL, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_svd_execute(s, A, 3, sv, U, V, NULL, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_svd_execute(s, A, SIZE_MAX, sv, U, V, NULL, NULL), SB_ERR_OVERFLOW);
    CHECK_CODE(sb_svd_execute_adaptive(NULL, A, 4, 0.1, 0, 1, sv, U, V, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_svd_execute_adaptive(s, A, 4, 2, 0, 1, sv, U, V, NULL), SB_ERR_RANGE);
    CHECK_CODE(sb_svd_execute_adaptive(s, A, 4, 0.1, 0, SIZE_MAX, sv, U, V, NULL), SB_ERR_RANGE);
    CHECK_CODE(sb_svd_execute_adaptive(s, A, SIZE_MAX, 0.1, 0, 1, sv, U, V, NULL), SB_ERR_OVERFLOW);
    A[5] = NAN;
    CHECK_CODE(sb_svd_execute(s, A, 4, sv, U, V, NULL, NULL), SB_ERR_NUMERIC);
    sb_svd_destroy(s);
}

/* Factors of 2 terms, 3 channels, 2x2 textures (all zero). */
static sb_factors_t *small_factors(void) {
    sb_factors_t *f = NULL;
    sb_factors_create(ctx(), 2, 3, 2, 2, 2, 2, &f);
    return f;
}

SB_TEST(factors) {
    sb_factors_t *f = NULL;
    CHECK_CODE(sb_factors_create(ctx(), 1, 1, 1, 1, 1, 1, NULL), SB_ERR_ARG);
    CHECK_CODE(sb_factors_create(ctx(), 0, 1, 1, 1, 1, 1, &f), SB_ERR_RANGE);
    CHECK_CODE(sb_factors_create(ctx(), 1, 2, 1, 1, 1, 1, &f), SB_ERR_RANGE);
    CHECK_CODE(sb_factors_create(ctx(), 1, 1, 0, 1, 1, 1, &f), SB_ERR_RANGE);
    CHECK_CODE(sb_factors_create(ctx(), SIZE_MAX, 3, 1, 1, 1, 1, &f), SB_ERR_OVERFLOW);
    CHECK_CODE(sb_factors_create(ctx(), 1, 1, SIZE_MAX, SIZE_MAX, 1, 1, &f), SB_ERR_OVERFLOW);
    CHECK(f == NULL);
    sb_factors_destroy(NULL);
    size_t w = 9, h = 9;
    CHECK(sb_factors_terms(NULL) == 0 && sb_factors_channels(NULL) == 0);
    sb_factors_size(NULL, 0, &w, &h);
    CHECK(w == 0 && h == 0);
    CHECK(sb_factors_tex(NULL, 0, 0, 0) == NULL && sb_factors_tex_const(NULL, 0, 0, 0) == NULL);
    CHECK(isnan(sb_factors_sigma(NULL, 0, 0)));
    sb_factors_set_sigma(NULL, 0, 0, 1);
    CHECK(sb_factors_set_meta(NULL, "k", "v") == SB_ERR_ARG);
    CHECK(sb_factors_get_meta(NULL, "k") == NULL && sb_factors_meta_count(NULL) == 0);
    const char *key = "x", *value = "y";
    sb_factors_meta_at(NULL, 0, &key, &value);
    CHECK(key == NULL && value == NULL);
    CHECK(sb_factors_errors(NULL) == NULL && sb_factors_errors_mut(NULL) == NULL);
    CHECK(isnan(sb_factors_cell(NULL, 1, 0, 0, 0)));

    f = small_factors();
    CHECK(f != NULL);
    /* out of range: term, channel, side */
    CHECK(sb_factors_tex(f, 0, 2, 0) == NULL && sb_factors_tex(f, 0, 0, 3) == NULL);
    CHECK(sb_factors_tex(f, 2, 0, 0) == NULL && sb_factors_tex_const(f, -1, 0, 0) == NULL);
    CHECK(sb_factors_tex_const(f, 1, SIZE_MAX, SIZE_MAX) == NULL);
    sb_factors_size(f, 5, &w, &h);
    CHECK(w == 0 && h == 0);
    sb_factors_set_sigma(f, 2, 0, 7);
    sb_factors_set_sigma(f, 0, 3, 7);
    sb_factors_set_sigma(f, SIZE_MAX, SIZE_MAX, 7);
    CHECK(isnan(sb_factors_sigma(f, 2, 0)) && isnan(sb_factors_sigma(f, 0, 3)));
    CHECK(isnan(sb_factors_sigma(f, SIZE_MAX / 3 + 1, 0)));
    for (size_t t = 0; t < 2; t++)
        for (size_t c = 0; c < 3; c++)
            CHECK(sb_factors_sigma(f, t, c) == 0); /* nothing written out of range landed here */
    CHECK(sb_factors_set_meta(f, NULL, "v") == SB_ERR_ARG && sb_factors_set_meta(f, "k", NULL) == SB_ERR_ARG);
    CHECK(sb_factors_get_meta(f, NULL) == NULL);
    key = value = "x";
    sb_factors_meta_at(f, 0, &key, &value);
    CHECK(key == NULL && value == NULL);
    CHECK(sb_factors_set_meta(f, "k", "v") == SB_OK);
    sb_factors_meta_at(f, SIZE_MAX, &key, &value);
    CHECK(key == NULL && value == NULL);
    sb_factors_meta_at(f, 0, NULL, NULL);
    /* cells and lookups out of range */
    CHECK(isnan(sb_factors_cell(f, 1, 3, 0, 0)) && isnan(sb_factors_cell(f, 1, 0, 4, 0)));
    CHECK(isnan(sb_factors_cell(f, 1, 0, 0, SIZE_MAX)));
    CHECK(sb_factors_cell(f, SIZE_MAX, 0, 0, 0) == 0); /* terms clamp to the available */
    sb_param_t *p = param_io(2);
    double st[2] = {0.5, 0.5}, wild[2] = {1e300, -1e300}, nan2[2] = {NAN, 0};
    CHECK(isnan(sb_factors_lookup(NULL, p, 0, 0, 0, st)) && isnan(sb_factors_lookup(f, NULL, 0, 0, 0, st)));
    CHECK(isnan(sb_factors_lookup(f, p, 0, 0, 0, NULL)) && isnan(sb_factors_lookup(f, p, 0, 2, 0, st)));
    CHECK(isnan(sb_factors_lookup(f, p, 0, 0, 3, st)) && isnan(sb_factors_lookup(f, p, 3, 0, 0, st)));
    CHECK(sb_factors_lookup(f, p, 0, 0, 0, wild) == 0 && sb_factors_lookup(f, p, 1, 1, 2, wild) == 0);
    CHECK(isnan(sb_factors_lookup(f, p, 0, 0, 0, nan2)));
    double rgb[3] = {5, 5, 5};
    CHECK(sb_factors_eval(NULL, p, SB_FORM_F, 1, wi_up, wo_up, rgb) == 0 && rgb[0] == 0);
    CHECK(sb_factors_eval(f, NULL, SB_FORM_F, 1, wi_up, wo_up, rgb) == 0);
    CHECK(sb_factors_eval(f, p, (sb_form_t)BAD_ENUM, 1, wi_up, wo_up, rgb) == 0);
    CHECK(sb_factors_eval(f, p, SB_FORM_F, 1, NULL, wo_up, rgb) == 0);
    CHECK(sb_factors_eval(f, p, SB_FORM_F, 1, wi_up, wo_up, NULL) == 0);
    CHECK(sb_factors_eval(f, p, SB_FORM_F, SIZE_MAX, wi_up, wo_up, rgb) == 1 && rgb[0] == 0);
    sb_param_destroy(p);
    sb_factors_destroy(f);
}

/* The version at run time: the headers' macros, CMake's project version,
 * the number MAJOR * 10000 + MINOR * 100 + PATCH of the string's parts,
 * and what `sepbrdf --version` prints. */
SB_TEST(version) {
    CHECK(strcmp(sb_version(), SB_VERSION_STRING) == 0 && strcmp(sb_version(), SB_PROJECT_VERSION) == 0);
    unsigned major = 0, minor = 0, patch = 0;
    CHECK(sscanf(sb_version(), "%u.%u.%u", &major, &minor, &patch) == 3);
    CHECK(sb_version_number() == major * 10000 + minor * 100 + patch);
    CHECK(major == SB_VERSION_MAJOR && minor == SB_VERSION_MINOR && patch == SB_VERSION_PATCH);
    char out[256], want[64];
    CHECK(sb_run(SB_CLI " --version", out, sizeof out) == 0);
    snprintf(want, sizeof want, "sepbrdf %s\n", sb_version());
    CHECKF(strcmp(out, want) == 0, "--version printed '%s'", out);
}

/* Versioned options: size 0 (a zeroed struct), SB_JOB_OPTS_INIT and the
 * 0.1 size run the same job; a size beyond the library's struct (newer
 * headers) or below the size field is refused, naming the sizes; the
 * plan's options alike. */
SB_TEST(job_opts_size) {
    sb_job_opts_t zero = {0}, init = SB_JOB_OPTS_INIT;
    CHECK(init.size == sizeof(sb_job_opts_t) && SB_JOB_OPTS_SIZE_0_1 <= sizeof(sb_job_opts_t));
    double e[3];
    size_t sizes[3] = {0, sizeof(sb_job_opts_t), SB_JOB_OPTS_SIZE_0_1};
    for (int i = 0; i < 3; i++) {
        sb_job_opts_t o = i ? init : zero;
        o.size = sizes[i];
        o.source = "cook-torrance:roughness=0.4";
        o.param = "io";
        o.res = 6;
        o.terms = 2;
        sb_job_t *job = NULL;
        CHECK(sb_job_run(ctx(), &o, &job) == SB_OK);
        e[i] = sb_job_headline(job, 2);
        sb_job_destroy(job);
    }
    CHECK(e[0] == e[1] && e[1] == e[2] && e[0] > 0);
    sb_job_t *job = NULL;
    init.size = sizeof(sb_job_opts_t) + 8;
    CHECK_CODE(sb_job_run(ctx(), &init, &job), SB_ERR_ARG);
    CHECK(job == NULL && strstr(sb_context_last_error(ctx()), "bytes") != NULL);
    init.size = 1;
    sb_source_t *src = lambert();
    CHECK_CODE(sb_job_run_source(ctx(), src, &init, &job), SB_ERR_ARG);
    sb_source_destroy(src);
    /* the plan's options alike */
    sb_plan_opts_t po = SB_PLAN_OPTS_INIT;
    CHECK(po.size == sizeof po && SB_PLAN_OPTS_SIZE_0_1 <= sizeof po);
    sb_plan_t *plan = NULL;
    po.terms = 2;
    CHECK(sb_plan_create(ctx(), 4, 4, &po, &plan) == SB_OK);
    sb_plan_destroy(plan);
    po.size = 0;
    CHECK(sb_plan_create(ctx(), 4, 4, &po, &plan) == SB_OK);
    sb_plan_destroy(plan);
    po.size = sizeof po + 1;
    CHECK_CODE(sb_plan_create(ctx(), 4, 4, &po, &plan), SB_ERR_ARG);
    CHECK(plan == NULL);
}
