/* The importance sampler of the rv layout (the light's elevation and the
 * view about the mirror direction, SB_CAP_COL_SAMPLE | SB_CAP_COL_FOLD;
 * sampler.h): the non-negative fit `sepbrdf factor SRC --method nmf
 * --param rv` (the job, J = 4) of analytic sources (Phong n = 100,
 * rv's own lobe; the job's default gold; Cook-Torrance 0.3), tested as
 * test_sampler_vh.c tests vh: chi2 of the drawn directions against sb_pdf
 * integrated over the bins at four view elevations; the pdf integrating
 * to the share of draws that succeed and the estimator of int Y(f) cos
 * unbiased against a quadrature (a sampler keeping one half of the fold,
 * or a density without the fold's 1/2, fails both); |ds/dwi| against the
 * solid angle that sb_param_col_sample maps a small square of s to (on
 * both halves, s.y in [0, 2]); factor writing sampler.bin and the
 * report's sampler block.  rv's rows are lights: the sampler reads g at
 * the view's elevation and draws the light about the view's mirror
 * direction (the forward map with the roles swapped, exact for
 * reciprocal sources; Phong's lobe (r.v)^n is symmetric in l and v). */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"

#include "sampler_cols_check.h"

#define GOLD "microfacet:base=gold,roughness=0.5"
#define PHONG "phong:n=100"
/* the lobe alone (with the default kd 0.5 the lobe is 2 % of int f cos) */
#define PHONG_LOBE "phong:n=100,kd=0"

/* the lobe about the view's mirror direction passes the horizon at
 * grazing views: at theta_o 75 half of it (n / 4 must succeed) */
SB_TEST(chi2_phong) { cfix_chi2(PHONG, "rv", 200000, 0x38f1ULL, 4); }
SB_TEST(chi2_gold) { cfix_chi2(GOLD, "rv", 200000, 0x38f1ULL, 4); }
SB_TEST(chi2_cook_torrance) { cfix_chi2("cook-torrance:roughness=0.3", "rv", 200000, 0x38f1ULL, 4); }

SB_TEST(integrals_phong) { cfix_integrals(PHONG, "rv"); }
SB_TEST(integrals_gold) { cfix_integrals(GOLD, "rv"); }

/* |ds/dwi| against the solid angle of the image of a small square of s
 * (both halves of the fold; sampler_cols_check.h). */
SB_TEST(jacobian) { cfix_jacobian("rv", 150); }

/* The draws land on the source's lobe: Phong n = 100 (kd 0)'s f cos
 * peaks at the view's mirror direction (cos^100: 78 % of the lobe within
 * 10 degrees of it), and more than half of the draws at theta_o 30 lie
 * that close; a map placing s about another direction passes chi2 and
 * the integrals but not this. */
SB_TEST(draws_on_the_lobe) {
    cfix_t x;
    if (!cfix_open(PHONG_LOBE, "rv", &x)) {
        cfix_close(&x);
        return;
    }
    double wo[3], wi[3], pdf, r[3];
    cfix_dir(30, 30, wo);
    r[0] = -wo[0], r[1] = -wo[1], r[2] = wo[2];
    size_t n = 20000, near = 0, ok = 0;
    unsigned long long rng = 17;
    for (size_t i = 0; i < n; i++) {
        double u[2] = {sb_rand01(&rng), sb_rand01(&rng)};
        if (!sb_sample(x.s, wo, u, wi, &pdf, NULL)) continue;
        ok++;
        near += wi[0] * r[0] + wi[1] * r[1] + wi[2] * r[2] > cos(10 * SB_PI / 180);
    }
    fprintf(stderr, "rv phong: %zu of %zu draws within 10 degrees of the mirror direction\n", near, ok);
    CHECKF(near > ok / 2, "only %zu of %zu draws within 10 degrees of the mirror direction", near, ok);
    cfix_close(&x);
}

/* `factor gold --method nmf --param rv --shader all`: sampler.bin (cells
 * between the h textures' nodes, J C + 1 layers), the report's sampler
 * block with the share sampler.bin holds, no warning that a sampler is
 * missing, and the sampler block (sb_col_dir) in every language. */
SB_TEST(factor_writes_sampler) {
    const char *const need[] = {"sb_col_dir", "sb_col_weight"};
    cfix_factor_writes(GOLD, "rv", need, 2);
}
