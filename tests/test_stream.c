/* Streamed matrices and the matrix-free solver: a streamed matrix reads
 * exactly as the stored one; the stream solver's errors against the dense
 * SVD (Eckart-Young: never below it, and within its stated tolerance
 * above it), its streamed residual against the explicit one, and the
 * automatic choice beyond the memory limit. */
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"

#define ANISO "microfacet:base=0.9/0.6/0.3,metallic=0.5,roughness=0.4,anisotropy=0.8"

static sb_source_t *model(const char *spec) {
    sb_source_t *s = NULL;
    CHECKF(sb_model_create(NULL, spec, &s) == SB_OK, "model %s", spec);
    return s;
}

static sb_param_t *layout(sb_param_kind_t kind, size_t R) {
    sb_param_t *p = NULL;
    sb_param_opts_t o = {0};
    o.res = R;
    CHECK(sb_param_create(NULL, kind, &o, &p) == SB_OK);
    return p;
}

static void build(const sb_source_t *s, const sb_param_t *p, sb_form_t form, int stream, sb_matrix_t *m) {
    sb_matrix_opts_t mo = {0};
    mo.form = form;
    mo.stream = stream;
    CHECK(sb_matrix_build(NULL, s, p, &mo, m) == SB_OK);
    CHECK(m->streamed == stream);
}

static sb_factors_t *factor(const sb_matrix_t *m, const sb_param_t *p, size_t J, sb_method_t method, int weighted) {
    sb_plan_opts_t po = {0};
    po.terms = J;
    po.svd.method = method;
    po.weighted = weighted;
    sb_plan_t *plan = NULL;
    sb_factors_t *f = NULL;
    CHECK(sb_plan_create_for(NULL, m, &po, &plan) == SB_OK);
    CHECK(sb_plan_execute(plan, m, p, &f) == SB_OK);
    sb_plan_destroy(plan);
    return f;
}

/* Every way of reading a streamed matrix gives the stored matrix's bits. */
SB_TEST(reads_as_stored) {
    sb_source_t *s = model(ANISO);
    static const sb_param_kind_t kinds[] = {SB_PARAM_IO, SB_PARAM_IO_AREA};
    for (int k = 0; k < 2; k++) {
        sb_param_t *p = layout(kinds[k], 6);
        sb_matrix_t d, m, e;
        build(s, p, SB_FORM_COS, 0, &d);
        build(s, p, SB_FORM_COS, 1, &m);
        CHECK(!d.mask && !m.mask && !m.data[0] && m.valid_count == d.valid_count);
        size_t n = d.rows, bad = 0;
        double *col = malloc(n * sizeof *col), *z = malloc(n * 3 * sizeof *z), *y1 = malloc(n * 3 * sizeof *y1),
               *y2 = malloc(n * 3 * sizeof *y2);
        for (size_t i = 0; i < n * 3; i++)
            z[i] = sin(0.37 * (double)i);
        for (int c = 0; c < 3; c++) {
            CHECK(sb_matrix_has(&m, c));
            for (size_t j = 0; j < d.cols; j++) {
                const double *got = sb_matrix_col(&m, c, j, col);
                for (size_t i = 0; i < n; i++)
                    bad += got[i] != d.data[c][i + j * n] || sb_matrix_at(&m, c, i, j) != d.data[c][i + j * n];
            }
            CHECK(sb_matrix_mul(NULL, &m, c, 3, z, n, y1, n) == SB_OK);
            CHECK(sb_matrix_mul(NULL, &d, c, 3, z, n, y2, n) == SB_OK);
            for (size_t i = 0; i < n * 3; i++)
                CHECK_REL(y1[i], y2[i], 1e-13);
        }
        CHECK(sb_matrix_expand(NULL, &m, &e) == SB_OK);
        for (int c = 0; c < 3; c++)
            bad += memcmp(e.data[c], d.data[c], n * d.cols * sizeof(double)) != 0;
        CHECKF(bad == 0, "%zu cells differ", bad);
        free(col), free(z), free(y1), free(y2);
        sb_matrix_free(&e), sb_matrix_free(&m), sb_matrix_free(&d);
        sb_param_destroy(p);
    }
    sb_source_destroy(s);
}

/* The stream solver against dgesdd on the stored matrix, weighted and
 * not: rel_rms never below the optimum (Eckart-Young) and at most 0.1 %
 * above it for every J' (the stated tolerance; 5 passes, p = 10); its
 * streamed residual equals the explicit one of sb_factors_errors_against,
 * which on the streamed matrix (a blocked pass) gives the dense errors. */
SB_TEST(matches_dense_svd) {
    sb_source_t *s = model(ANISO);
    sb_param_t *p = layout(SB_PARAM_IO, 12);
    sb_matrix_t d, m;
    build(s, p, SB_FORM_F, 0, &d);
    build(s, p, SB_FORM_F, 1, &m);
    size_t J = 8;
    for (int w = 0; w < 2; w++) {
        sb_factors_t *full = factor(&d, p, J, SB_METHOD_FULL, w), *st = factor(&m, p, J, SB_METHOD_AUTO, w);
        CHECK(strcmp(sb_factors_get_meta(st, "method"), "stream") == 0);
        const sb_factor_errors_t *ef = sb_factors_errors(full), *es = sb_factors_errors(st);
        double rel[4 * 8], mx[4 * 8], rel_s[4 * 8], mx_s[4 * 8];
        CHECK(sb_factors_errors_against(NULL, st, &d, w ? p : NULL, rel, mx) == SB_OK);
        CHECK(sb_factors_errors_against(NULL, st, &m, w ? p : NULL, rel_s, mx_s) == SB_OK); /* blocked, streamed */
        for (size_t j = 0; j < J; j++)
            for (size_t c = 0; c <= SB_CH_ALL; c++) {
                double opt = ef->rel_rms[sb_err_at(j, c)], got = es->rel_rms[sb_err_at(j, c)];
                CHECKF(got >= opt * (1 - 1e-12) && got <= opt * (1 + 1e-3), "J' %zu ch %zu: %.9g vs optimum %.9g",
                       j + 1, c, got, opt);
                CHECK_REL(got, rel[sb_err_at(j, c)], 1e-9);
                CHECK_REL(rel_s[sb_err_at(j, c)], rel[sb_err_at(j, c)], 1e-12);
                CHECK(mx_s[sb_err_at(j, c)] == mx[sb_err_at(j, c)]);
                CHECK_REL(es->max_abs[sb_err_at(j, c)], mx[sb_err_at(j, c)], 1e-9);
            }
        CHECK_REL(es->norm[SB_CH_ALL], ef->norm[SB_CH_ALL], 1e-12);
        sb_factors_destroy(full), sb_factors_destroy(st);
    }
    sb_matrix_free(&m), sb_matrix_free(&d);
    sb_param_destroy(p);
    sb_source_destroy(s);
}

/* A rank-1 source (Lambert on io, f = albedo/pi) is reconstructed exactly
 * by one term; method stream on a stored matrix gives the bits of the
 * streamed one (the same blocks, the same products). */
SB_TEST(rank_one_and_stored) {
    sb_source_t *s = model("lambert:albedo=0.2/0.5/0.8");
    sb_param_t *p = layout(SB_PARAM_IO, 8);
    sb_matrix_t d, m;
    build(s, p, SB_FORM_COS2, 0, &d);
    build(s, p, SB_FORM_COS2, 1, &m);
    sb_factors_t *a = factor(&m, p, 2, SB_METHOD_AUTO, 1), *b = factor(&d, p, 2, SB_METHOD_STREAM, 1);
    CHECK(strcmp(sb_factors_get_meta(b, "method"), "stream") == 0);
    CHECK(sb_factors_errors(a)->rel_rms[sb_err_at(0, SB_CH_ALL)] < 1e-12);
    for (size_t c = 0; c < 3; c++)
        CHECK(sb_factors_sigma(a, 0, c) == sb_factors_sigma(b, 0, c));
    sb_factors_destroy(a), sb_factors_destroy(b);
    sb_matrix_free(&m), sb_matrix_free(&d);
    sb_param_destroy(p);
    sb_source_destroy(s);
}

/* Beyond the memory limit a build that reads through the plan
 * (structured) streams instead of failing; a plain build still refuses;
 * layouts with cells outside the domain (hd) never stream. */
SB_TEST(streams_beyond_limit) {
    sb_source_t *s = model(ANISO);
    sb_param_t *p = layout(SB_PARAM_IO, 24), *hd = layout(SB_PARAM_HD, 24);
    sb_matrix_opts_t mo = {0};
    mo.structured = 1;
    size_t dense = sb_matrix_bytes(s, p, &mo);
    CHECK(dense == 576 * 576 * (3 * sizeof(double) + 1));
    sb_set_memory_limit((size_t)4 << 20);
    CHECK(sb_matrix_bytes(s, p, &mo) == 3 * 1152 * sizeof(double));
    sb_matrix_t m;
    CHECK(sb_matrix_build(NULL, s, p, &mo, &m) == SB_OK);
    CHECK(m.streamed && m.valid_count == 576 * 576);
    sb_factors_t *f = factor(&m, p, 4, SB_METHOD_FULL, 0); /* a stored method cannot: stream takes it */
    CHECK(f && strcmp(sb_factors_get_meta(f, "method"), "stream") == 0);
    sb_factors_destroy(f);
    sb_matrix_free(&m);
    sb_matrix_opts_t plain = {0};
    CHECK(sb_matrix_build(NULL, s, p, &plain, &m) == SB_ERR_OVERFLOW);
    CHECK(sb_matrix_build(NULL, s, hd, &mo, &m) == SB_ERR_OVERFLOW);
    sb_set_memory_limit(0);
    sb_param_destroy(p), sb_param_destroy(hd);
    sb_source_destroy(s);
}

/* The CLI's --memory-limit: a size with a binary suffix; a bad one is a
 * usage error naming the option; method stream is named in the report. */
SB_TEST(cli_memory_limit_and_method) {
    static char out[8192];
    const char *dir = sb_tmpdir("stream_cli");
    char cmd[4096];
    static const char *const bad[] = {"2x", "0", "-5G", "1K"};
    for (int i = 0; i < 4; i++) {
        snprintf(cmd, sizeof cmd, "%s factor --memory-limit %s -o %s/bad 2>&1", SB_CLI, bad[i], dir);
        int rc = sb_run(cmd, out, sizeof out);
        CHECKF(rc == 1 && strstr(out, "--memory-limit"), "%s: rc %d: %s", bad[i], rc, out);
    }
    snprintf(cmd, sizeof cmd,
             "%s factor '" ANISO "' --param io -r 8 -J 3 --method stream --memory-limit 1G -q -o %s/ok", SB_CLI, dir);
    CHECKF(sb_run(cmd, out, sizeof out) == 0, "%s", out);
    snprintf(cmd, sizeof cmd, "grep -c '\"method\": \"stream\"' %s/ok/report.json", dir);
    CHECK(sb_run(cmd, out, sizeof out) == 0 && atoi(out) == 1);
}
