/* Proportional channels: positive and negative cases, scales against
 * the values they were built from, and the claim that factoring the base
 * once serves every channel. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"

/* A matrix with channels a_c * M (M random), ld > rows. */
static sb_matrix_t synthetic(size_t rows, size_t cols, const double a[3], unsigned long long seed) {
    sb_matrix_t m = {0};
    m.rows = rows;
    m.cols = cols;
    m.ld = rows + 3;
    double *base = malloc(m.ld * cols * sizeof *base);
    for (size_t i = 0; i < m.ld * cols; i++)
        base[i] = sb_rand01(&seed) - 0.3;
    for (int c = 0; c < 3; c++) {
        m.data[c] = malloc(m.ld * cols * sizeof(double));
        for (size_t i = 0; i < m.ld * cols; i++)
            m.data[c][i] = a[c] * base[i];
        m.channels |= 1u << c;
    }
    free(base);
    return m;
}

static sb_matrix_t from_model(const char *spec, size_t R) {
    sb_source_t *s = NULL;
    sb_param_t *p = NULL;
    sb_param_opts_t po = {0};
    po.res = R;
    sb_matrix_t m = {0};
    CHECK(sb_model_create(NULL, spec, &s) == SB_OK);
    CHECK(sb_param_create(NULL, SB_PARAM_IO, &po, &p) == SB_OK);
    CHECK(sb_matrix_build(NULL, s, p, NULL, &m) == SB_OK);
    sb_param_destroy(p);
    sb_source_destroy(s);
    return m;
}

SB_TEST(lambert_is_proportional) {
    sb_matrix_t m = from_model("lambert:albedo=0.8/0.5/0.2", 8);
    sb_channels_t ch;
    CHECK(sb_channels_proportional(NULL, &m, 0, &ch) == SB_OK);
    CHECK(ch.proportional == 1 && ch.base == 0);
    CHECK_REL(ch.scale[0], 1, 0);
    CHECK_REL(ch.scale[1], 0.5 / 0.8, 1e-14);
    CHECK_REL(ch.scale[2], 0.2 / 0.8, 1e-14);
    CHECK_REL(ch.norm[0], 0.8 / SB_PI * (double)m.rows, 1e-13); /* constant albedo / pi over N^2 cells */
    CHECK(ch.dev[1] < 1e-14 && ch.dev[2] < 1e-14);
    sb_matrix_free(&m);
}

SB_TEST(gold_is_not) {
    /* Fresnel colour shift: the channels differ in shape, not only scale */
    sb_matrix_t m = from_model("microfacet:base=gold,roughness=0.5", 8);
    sb_channels_t ch;
    CHECK(sb_channels_proportional(NULL, &m, 0, &ch) == SB_OK);
    CHECK(ch.proportional == 0);
    CHECK(ch.dev[0] + ch.dev[1] + ch.dev[2] > 1e-6);
    /* but a loose enough tolerance accepts it, and reports the deviation */
    CHECK(sb_channels_proportional(NULL, &m, 0.5, &ch) == SB_OK);
    CHECK(ch.proportional == 1);
    for (int c = 0; c < 3; c++)
        CHECK(ch.dev[c] < 0.5);
    sb_matrix_free(&m);
}

SB_TEST(synthetic_scales) {
    const double a[3] = {0.3, 1.7, -0.9}; /* base: G, the largest norm; a negative scale is fine */
    sb_matrix_t m = synthetic(37, 23, a, 5);
    sb_channels_t ch;
    CHECK(sb_channels_proportional(NULL, &m, 0, &ch) == SB_OK);
    CHECK(ch.proportional == 1 && ch.base == 1);
    CHECK_REL(ch.scale[0], 0.3 / 1.7, 1e-14);
    CHECK_REL(ch.scale[2], -0.9 / 1.7, 1e-14);
    /* a perturbation of 1e-9 relative in one cell is caught ... */
    double keep = m.data[2][100];
    m.data[2][100] *= 1 + 1e-9;
    CHECK(sb_channels_proportional(NULL, &m, 0, &ch) == SB_OK);
    CHECK(ch.proportional == 0);
    /* ... one of 1e-15 is rounding */
    m.data[2][100] = keep * (1 + 1e-15);
    CHECK(sb_channels_proportional(NULL, &m, 0, &ch) == SB_OK);
    CHECK(ch.proportional == 1);
    /* the padding beyond rows (ld > rows) is not part of the matrix */
    m.data[0][m.rows + 1] = 12345;
    CHECK(sb_channels_proportional(NULL, &m, 0, &ch) == SB_OK);
    CHECK(ch.proportional == 1);
    sb_matrix_free(&m);
}

SB_TEST(zero_and_missing_channels) {
    const double a[3] = {1, 0, 2};
    sb_matrix_t m = synthetic(10, 12, a, 9);
    sb_channels_t ch;
    CHECK(sb_channels_proportional(NULL, &m, 0, &ch) == SB_OK);
    CHECK(ch.proportional == 1 && ch.base == 2 && ch.scale[1] == 0 && ch.dev[1] == 0);
    /* only one channel built */
    free(m.data[0]);
    free(m.data[2]);
    m.data[0] = m.data[2] = NULL;
    m.channels = 2;
    CHECK(sb_channels_proportional(NULL, &m, 0, &ch) == SB_OK);
    CHECK(ch.proportional == 1 && ch.base == 1 && ch.scale[1] == 1 && ch.scale[0] == 0);
    sb_matrix_free(&m);
}

/* Factoring the base once is optimal for every channel: sigma(M_c) =
 * |a_c| sigma(M_base), same singular vectors. */
SB_TEST(factor_once_serves_all) {
    const double a[3] = {0.25, 1, 0.5};
    sb_matrix_t m = synthetic(30, 30, a, 17);
    sb_channels_t ch;
    CHECK(sb_channels_proportional(NULL, &m, 0, &ch) == SB_OK && ch.proportional);
    sb_svd_opts_t o = {.method = SB_METHOD_FULL};
    sb_svd_t *svd;
    double s[3][4];
    CHECK(sb_svd_create(NULL, 30, 30, 4, &o, &svd) == SB_OK);
    for (int c = 0; c < 3; c++)
        CHECK(sb_svd_execute(svd, m.data[c], m.ld, s[c], NULL, NULL, NULL, NULL) == SB_OK);
    for (int c = 0; c < 3; c++)
        for (int j = 0; j < 4; j++)
            CHECK_REL(s[c][j], ch.scale[c] * s[ch.base][j], 1e-13);
    sb_svd_destroy(svd);
    sb_matrix_free(&m);
}

SB_TEST(errors) {
    sb_channels_t ch;
    sb_matrix_t empty = {0};
    empty.rows = empty.cols = empty.ld = 4;
    const double a[3] = {1, 2, 3};
    sb_matrix_t m = synthetic(4, 4, a, 1);
    CHECK(sb_channels_proportional(NULL, NULL, 0, &ch) == SB_ERR_ARG);
    CHECK(sb_channels_proportional(NULL, &m, 0, NULL) == SB_ERR_ARG);
    CHECK(sb_channels_proportional(NULL, &empty, 0, &ch) == SB_ERR_ARG);
    CHECK(sb_channels_proportional(NULL, &m, -1e-3, &ch) == SB_ERR_RANGE);
    CHECK(sb_channels_proportional(NULL, &m, 1, &ch) == SB_ERR_RANGE);
    CHECK(sb_channels_proportional(NULL, &m, NAN, &ch) == SB_ERR_RANGE);
    m.data[1][9] = NAN;
    CHECK(sb_channels_proportional(NULL, &m, 0, &ch) == SB_ERR_NUMERIC);
    m.data[1][9] = INFINITY;
    CHECK(sb_channels_proportional(NULL, &m, 0, &ch) == SB_ERR_NUMERIC);
    sb_matrix_free(&m);
}

/* A fit of some channels (--channels, sb_job_opts_t.channels) is measured
 * on them only: the channels written as 0 are no error (they were 2.4 %
 * of the pooled headline's 0.809 on the default gold with G alone, G
 * itself 0.00093).  Headline, band errors and prefixes all equal G's. */
SB_TEST(job_errors_over_factored_channels) {
    sb_context_t *ctx = NULL;
    CHECK(sb_context_create(&ctx) == SB_OK);
    sb_job_opts_t o = {0};
    o.channels = 2; /* G */
    sb_job_t *job = NULL;
    CHECKF(sb_job_run(ctx, &o, &job) == SB_OK, "%s", sb_context_last_error(ctx));
    const sb_estimate_t *e = job ? sb_job_estimate(job) : NULL;
    CHECK(e && e->terms >= 1);
    for (size_t k = 0; e && k < e->terms; k++) {
        CHECKF(fabs(sb_job_headline(job, k + 1) - e->rel[k][SB_EST_FCOS][1]) <= 1e-9 * e->rel[k][SB_EST_FCOS][1],
               "J = %zu: pooled %g, G %g", k + 1, sb_job_headline(job, k + 1), e->rel[k][SB_EST_FCOS][1]);
        CHECK(e->rel[k][SB_EST_FCOS][0] == 0 && e->rel[k][SB_EST_FCOS][2] == 0);
        for (int b = 0; b < SB_BAND_COUNT_; b++)
            CHECKF(!(e->band[k][b][3] > 0) || fabs(e->band[k][b][3] - e->band[k][b][1]) <= 1e-9 * e->band[k][b][1],
                   "J = %zu band %s: %g, G %g", k + 1, sb_band_name(b), e->band[k][b][3], e->band[k][b][1]);
    }
    CHECK(e && sb_job_headline(job, e->terms) < 0.01);
    sb_job_destroy(job);
    sb_context_destroy(ctx);
}

/* The RGL orange film fitted in G alone: the layout of the full fit, no
 * warning that the layout misses the measured samples (was "layout vndf
 * does not hold this table's values", the pooled error 0.952 against G's
 * 0.035), the headline G's of the full fit, the sample error over G. */
SB_TEST(rgl_fit_of_one_channel) {
    sb_context_t *ctx = NULL;
    CHECK(sb_context_create(&ctx) == SB_OK);
    sb_job_opts_t o = {0};
    o.source = SB_MEASURED_DIR "/rgl_chm_orange_rgb.bsdf";
    sb_job_t *all = NULL, *g = NULL;
    CHECKF(sb_job_run(ctx, &o, &all) == SB_OK, "%s", sb_context_last_error(ctx));
    o.channels = 2;
    CHECKF(sb_job_run(ctx, &o, &g) == SB_OK, "%s", sb_context_last_error(ctx));
    if (all && g) {
        CHECK(sb_param_kind(sb_job_param(all)) == sb_param_kind(sb_job_param(g)));
        for (size_t i = 0; i < sb_job_warning_count(g); i++)
            CHECKF(!strstr(sb_job_warning(g, i), "does not hold") && !strstr(sb_job_warning(g, i), "do not lower"),
                   "warning: %s", sb_job_warning(g, i));
        const sb_estimate_t *ea = sb_job_estimate(all), *eg = sb_job_estimate(g);
        size_t J = eg->terms;
        CHECKF(J == ea->terms &&
                   fabs(sb_job_headline(g, J) - ea->rel[J - 1][SB_EST_FCOS][1]) <= 2 * ea->se[J - 1][SB_EST_FCOS][1],
               "G alone %g, G of the full fit %g", sb_job_headline(g, J), ea->rel[J - 1][SB_EST_FCOS][1]);
        sb_source_t *s = NULL;
        sb_sample_errors_t se_g, se_all;
        CHECK(sb_source_open(ctx, o.source, &s) == SB_OK);
        const sb_factors_t *f = sb_job_factors(g);
        CHECK(sb_measured_sample_errors_channels(ctx, s, f, sb_job_param(g), sb_job_form(g), 2, &se_g) == SB_OK);
        CHECK(sb_measured_sample_errors(ctx, s, f, sb_job_param(g), sb_job_form(g), &se_all) == SB_OK);
        CHECKF(se_g.rel_l2[J - 1] < 0.6 * se_all.rel_l2[J - 1], "at the samples: G %g, all channels %g",
               se_g.rel_l2[J - 1], se_all.rel_l2[J - 1]);
        sb_source_destroy(s);
    }
    sb_job_destroy(all);
    sb_job_destroy(g);
    sb_context_destroy(ctx);
}
