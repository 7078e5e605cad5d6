/* Colour differences (src/util/colour.c) against published data, and the
 * estimator's colour error (estimate.h: chroma_de) on sources with known
 * answers. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../src/util/colour.h"
#include "harness.h"
#include "sepbrdf/sepbrdf.h"

/* Sharma, Wu & Dalal (2005), Table 1: pairs 1-3, 7-8, 13-38 (pairs 4-6
 * and 9-12 repeat the same cases with the colours swapped or hues on the
 * other side, and are covered by the symmetry check). */
SB_TEST(ciede2000_sharma_pairs) {
    static const double t[][7] = {
        {50, 2.6772, -79.7751, 50, 0, -82.7485, 2.0425},
        {50, 3.1571, -77.2803, 50, 0, -82.7485, 2.8615},
        {50, 2.8361, -74.0200, 50, 0, -82.7485, 3.4412},
        {50, 0, 0, 50, -1, 2, 2.3669},
        {50, -1, 2, 50, 0, 0, 2.3669},
        {50, 2.4900, -0.0010, 50, -2.4900, 0.0009, 7.1792},
        {50, 2.4900, -0.0010, 50, -2.4900, 0.0010, 7.1792},
        {50, 2.4900, -0.0010, 50, -2.4900, 0.0011, 7.2195},
        {50, 2.4900, -0.0010, 50, -2.4900, 0.0012, 7.2195},
        {50, -0.0010, 2.4900, 50, 0.0009, -2.4900, 4.8045},
        {50, -0.0010, 2.4900, 50, 0.0011, -2.4900, 4.7461},
        {50, 2.5, 0, 50, 0, -2.5, 4.3065},
        {50, 2.5, 0, 73, 25, -18, 27.1492},
        {50, 2.5, 0, 61, -5, 29, 22.8977},
        {50, 2.5, 0, 56, -27, -3, 31.9030},
        {50, 2.5, 0, 58, 24, 15, 19.4535},
        {50, 2.5, 0, 50, 3.1736, 0.5854, 1.0000},
        {50, 2.5, 0, 50, 3.2972, 0, 1.0000},
        {50, 2.5, 0, 50, 1.8634, 0.5757, 1.0000},
        {50, 2.5, 0, 50, 3.2592, 0.3350, 1.0000},
        {60.2574, -34.0099, 36.2677, 60.4626, -34.1751, 39.4387, 1.2644},
        {63.0109, -31.0961, -5.8663, 62.8187, -29.7946, -4.0864, 1.2630},
        {61.2901, 3.7196, -5.3901, 61.4292, 2.2480, -4.9620, 1.8731},
        {35.0831, -44.1164, 3.7933, 35.0232, -40.0716, 1.5901, 1.8645},
        {22.7233, 20.0904, -46.6940, 23.0331, 14.9730, -42.5619, 2.0373},
        {36.4612, 47.8580, 18.3852, 36.2715, 50.5065, 21.2231, 1.4146},
        {90.8027, -2.0831, 1.4410, 91.1528, -1.6435, 0.0447, 1.4441},
        {90.9257, -0.5406, -0.9208, 88.6381, -0.8985, -0.7239, 1.5381},
        {6.7747, -0.2908, -2.4247, 5.8714, -0.0985, -2.2286, 0.6377},
        {2.0776, 0.0795, -1.1350, 0.9033, -0.0636, -0.5514, 0.9082},
    };
    for (size_t i = 0; i < sizeof t / sizeof t[0]; i++) {
        double d = sb_ciede2000(t[i], t[i] + 3), e = sb_ciede2000(t[i] + 3, t[i]);
        CHECKF(fabs(d - t[i][6]) < 1e-4, "pair %zu: %.5f, published %.4f", i, d, t[i][6]);
        CHECKF(fabs(d - e) < 1e-12, "pair %zu not symmetric: %g %g", i, d, e);
    }
    CHECK(sb_ciede2000(t[0], t[0]) == 0);
}

/* sRGB white is Lab (100, 0, 0), black (0, 0, 0); sRGB primaries have the
 * Lab values of IEC 61966-2-1 with D65 (red 53.24, 80.09, 67.20). */
SB_TEST(srgb_to_lab) {
    double lab[3];
    sb_srgb_to_lab((const double[3]){1, 1, 1}, lab);
    CHECK(fabs(lab[0] - 100) < 1e-3 && fabs(lab[1]) < 0.02 && fabs(lab[2]) < 0.02);
    sb_srgb_to_lab((const double[3]){0, 0, 0}, lab);
    CHECK(lab[0] == 0 && lab[1] == 0 && lab[2] == 0);
    sb_srgb_to_lab((const double[3]){1, 0, 0}, lab);
    CHECKF(fabs(lab[0] - 53.24) < 0.05 && fabs(lab[1] - 80.09) < 0.1 && fabs(lab[2] - 67.20) < 0.1, "red %g %g %g",
           lab[0], lab[1], lab[2]);
    /* exposure: clipped channels, equal colours give 0 */
    CHECK(sb_delta_e_exposed((const double[3]){0.2, 0.3, 0.4}, (const double[3]){0.2, 0.3, 0.4}, 2) == 0);
    CHECK(sb_delta_e_exposed((const double[3]){0.2, 0.3, 0.4}, (const double[3]){0.2, 0.3, -5}, 1) > 10);
}

/* CIELAB's cube root (colour.c computes it inline, not by libm's cbrt)
 * to the last bits: for grey (r = g = b = y, so Y = y to 1 ulp) above
 * (6/29)^3, L = 116 cbrt(y) - 16, and the root from L cubed gives y back
 * within a few ulp, over y from 0.009 to 1e4 (12 decades of exponents:
 * every residue of the exponent mod 3); and against libm within 4 ulp. */
SB_TEST(lab_cube_root_to_the_last_bits) {
    double worst = 0;
    for (int i = 0; i <= 3000; i++) {
        double y = 0.009 * pow(10, i / 500.0), lab[3];
        sb_srgb_to_lab((const double[3]){y, y, y}, lab);
        double fy = (lab[0] + 16) / 116, yy = 0.2126 * y + 0.7152 * y + 0.0722 * y;
        double rel = fabs(fy - cbrt(yy)) / cbrt(yy);
        worst = rel > worst ? rel : worst;
    }
    /* L = 116 fy - 16 and back cost about 2 ulp of fy (L < 116 fy) */
    CHECKF(worst < 8 * 2.2e-16, "largest relative difference to libm's cbrt %.3g", worst);
}

/* A grey source factored in full keeps its colour (chroma_de near 0); the
 * same factors read as the tinted source's reconstruction miss its tint by
 * the CIEDE2000 of grey against that tint at equal luminance. */
static int tint_eval(const void *self, const double wi[3], const double wo[3], double rgb[3]) {
    const double *tint = self;
    (void)wo;
    for (int c = 0; c < 3; c++)
        rgb[c] = tint[c] * (0.3 + wi[2]) / SB_PI;
    return 1;
}

SB_TEST(estimator_chroma) {
    static const double grey[3] = {0.5, 0.5, 0.5}, blue[3] = {0.2, 0.3, 0.9};
    sb_source_ops_t ops = {0};
    ops.eval = tint_eval;
    sb_source_t *sg = NULL, *sb = NULL;
    CHECK(sb_source_create(NULL, &ops, (void *)grey, SB_SOURCE_ISOTROPIC, "grey", &sg) == SB_OK);
    CHECK(sb_source_create(NULL, &ops, (void *)blue, SB_SOURCE_ISOTROPIC, "blue", &sb) == SB_OK);
    sb_param_opts_t po = {0};
    po.res = 8;
    sb_param_t *p = NULL;
    CHECK(sb_param_create(NULL, SB_PARAM_IO, &po, &p) == SB_OK);
    sb_matrix_opts_t mo = {0};
    sb_matrix_t m;
    CHECK(sb_matrix_build(NULL, sg, p, &mo, &m) == SB_OK);
    sb_plan_opts_t pl = {0};
    pl.terms = 1;
    sb_plan_t *plan = NULL;
    sb_factors_t *f = NULL;
    CHECK(sb_plan_create_for(NULL, &m, &pl, &plan) == SB_OK);
    CHECK(sb_plan_execute(plan, &m, p, &f) == SB_OK);
    sb_estimate_opts_t eo = {0};
    eo.max_pairs = 1; /* the first replicates only */
    sb_pairs_t *pg = NULL, *pb = NULL;
    sb_estimate_t eg, eb;
    CHECK(sb_pairs_create(NULL, sg, &eo, &pg) == SB_OK && sb_pairs_create(NULL, sb, &eo, &pb) == SB_OK);
    CHECK(sb_estimate_compute(NULL, pg, f, NULL, p, SB_FORM_F, &eo, &eg) == SB_OK);
    CHECK(sb_estimate_compute(NULL, pb, f, NULL, p, SB_FORM_F, &eo, &eb) == SB_OK);
    CHECKF(eg.chroma_de[0] < 1e-3, "grey kept: %g", eg.chroma_de[0]);
    double lb[3], lg[3], y = 0.2126 * blue[0] + 0.7152 * blue[1] + 0.0722 * blue[2];
    double b5[3] = {blue[0] * 0.5 / y, blue[1] * 0.5 / y, blue[2] * 0.5 / y};
    sb_srgb_to_lab(b5, lb);
    sb_srgb_to_lab((const double[3]){0.5, 0.5, 0.5}, lg);
    double want = sb_ciede2000(lb, lg);
    CHECKF(fabs(eb.chroma_de[0] - want) < 1e-3 * want, "tint lost: %g, want %g", eb.chroma_de[0], want);
    sb_pairs_destroy(pg);
    sb_pairs_destroy(pb);
    sb_factors_destroy(f);
    sb_plan_destroy(plan);
    sb_matrix_free(&m);
    sb_param_destroy(p);
    sb_source_destroy(sg);
    sb_source_destroy(sb);
}
