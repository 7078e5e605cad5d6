/* Proportional channels: positive and negative cases, scales against
 * the values they were built from, and the claim that factoring the base
 * once serves every channel. */
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
