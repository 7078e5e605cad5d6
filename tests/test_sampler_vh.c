/* The importance sampler of the vh layout (the view's elevation and the
 * half vector in the view's azimuthal frame, SB_CAP_COL_SAMPLE |
 * SB_CAP_COL_FOLD; sampler.h): the non-negative fit `sepbrdf factor SRC
 * --method nmf --param vh` (the job, J = 4) of analytic sources (gold,
 * the job's default microfacet:base=gold,roughness=0.5; Cook-Torrance
 * 0.3) and an RGL file, tested as test_sampler_vndf.c
 * tests vndf: chi2 of the drawn directions against sb_pdf integrated over
 * the bins at four view elevations; the pdf integrating to the share of
 * draws that succeed and the estimator of int Y(f) cos unbiased against a
 * quadrature (both halves of the fold are drawn: a sampler keeping one
 * half of phi fails both); |ds/dwi| against the solid angle that
 * sb_param_col_sample maps a small square of s to (on both halves, s.y in
 * [0, 2]); factor writing sampler.bin and the report's sampler block. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"

#include "sampler_cols_check.h"

#define GOLD "microfacet:base=gold,roughness=0.5"

/* the half vector drawn for every view alike: at theta_o 75 a third of
 * the draws land above the horizon (n / 4 must) */
SB_TEST(chi2_gold) { cfix_chi2(GOLD, "vh", 200000, 0x38f0ULL, 4); }
SB_TEST(chi2_cook_torrance) { cfix_chi2("cook-torrance:roughness=0.3", "vh", 200000, 0x38f0ULL, 4); }
SB_TEST(chi2_paper) { cfix_chi2("rgl_paper_white_rgb.bsdf", "vh", 200000, 0x38f0ULL, 4); }

SB_TEST(integrals_gold) { cfix_integrals(GOLD, "vh"); }
SB_TEST(integrals_paper) { cfix_integrals("rgl_paper_white_rgb.bsdf", "vh"); }

/* |ds/dwi| against the solid angle of the image of a small square of s
 * (both halves of the fold; sampler_cols_check.h). */
SB_TEST(jacobian) { cfix_jacobian("vh", 200); }

/* `factor gold --method nmf --param vh --shader all`: sampler.bin (cells
 * between the h textures' nodes, J C + 1 layers), the report's sampler
 * block with the share sampler.bin holds, no warning that a sampler is
 * missing, and the sampler block (sb_col_dir) in every language. */
SB_TEST(factor_writes_sampler) {
    const char *const need[] = {"sb_col_dir", "sb_col_weight"};
    cfix_factor_writes(GOLD, "vh", need, 2);
}
