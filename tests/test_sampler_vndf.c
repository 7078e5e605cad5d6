/* The importance sampler of the vndf layout (an RGL file's own grid,
 * SB_CAP_COL_SAMPLE; sampler.h): the non-negative fit `sepbrdf factor
 * RGL --method nmf` makes (the job, vndf, J = 4) on the RGL files of
 * tests/data/measured, tested as test_sampler.c tests the other layouts:
 * chi2 of the drawn directions against sb_pdf integrated over the bins
 * (sampler_chi2.h) at four view elevations; the pdf integrating to the
 * share of draws that succeed (a reflected wi below the horizon fails);
 * the estimator of int Y(f) cos unbiased against a quadrature; and the
 * layout's |ds/dwi| (sb_param_col_density) against the solid angle that
 * sb_param_col_sample maps a small square of s to, an independent check
 * of the Jacobian. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"

#include "sampler_cols_check.h"

SB_TEST(chi2_orange) { cfix_chi2("rgl_chm_orange_rgb.bsdf", "vndf", 200000, 0x38d5ULL, 2); }
SB_TEST(chi2_paper) { cfix_chi2("rgl_paper_white_rgb.bsdf", "vndf", 200000, 0x38d5ULL, 2); }
SB_TEST(chi2_aurora) { cfix_chi2("rgl_aurora_white_rgb.bsdf", "vndf", 200000, 0x38d5ULL, 2); }

SB_TEST(integrals) { cfix_integrals("rgl_paper_white_rgb.bsdf", "vndf"); }

/* |ds/dwi| against the solid angle of the image of a square of side h
 * around s (its corners mapped by sb_param_col_sample, the spherical
 * quadrilateral's area as two triangles): within 2 %. */
SB_TEST(jacobian) {
    cfix_t x;
    if (!cfix_open("rgl_chm_orange_rgb.bsdf", "vndf", &x)) {
        cfix_close(&x);
        return;
    }
    const sb_param_t *p = sb_job_param(x.job);
    const double h = 1e-4;
    size_t tried = 0, bad = 0;
    unsigned long long rng = 5;
    for (int o = 0; o < 4; o++) {
        double wo[3];
        cfix_dir(CFIX_THETAS[o], 70, wo);
        for (int t = 0; t < 50; t++) {
            double s[2] = {0.05 + 0.9 * sb_rand01(&rng), 0.05 + 0.9 * sb_rand01(&rng)}, c[4][3], wi[3], back[2];
            int ok = sb_param_col_sample(p, wo, s, wi);
            for (int k = 0; k < 4; k++) {
                const double sk[2] = {s[0] + (k == 1 || k == 2 ? h : -h) / 2, s[1] + (k >= 2 ? h : -h) / 2};
                ok = ok && sb_param_col_sample(p, wo, sk, c[k]);
            }
            if (!ok) continue;
            double jac = sb_param_col_density(p, wi, wo, back);
            double area = tri_area(c[0], c[1], c[2]) + tri_area(c[0], c[2], c[3]), num = h * h / area;
            tried++;
            int wrong =
                !(fabs(jac - num) <= 0.02 * num) || !(fabs(back[0] - s[0]) < 1e-7 && fabs(back[1] - s[1]) < 1e-7);
            if (wrong && bad < 5)
                fprintf(stderr, "theta_o %g s (%.4f, %.4f): |ds/dwi| %g, by the mapped square %g; back (%.6f, %.6f)\n",
                        CFIX_THETAS[o], s[0], s[1], jac, num, back[0], back[1]);
            bad += wrong;
        }
    }
    fprintf(stderr, "vndf orange: %zu positions, %zu off\n", tried, bad);
    CHECKF(tried >= 100, "only %zu positions map above the horizon", tried);
    CHECKF(bad == 0, "%zu of %zu positions: |ds/dwi| or the inverse off", bad, tried);
    cfix_close(&x);
}

/* `factor RGL --method nmf --shaders all` (the job): sampler.bin of the
 * header's sizes (cells between the h textures' nodes, J C + 1 layers),
 * the chosen share at layer J C's texel (0, H) and in report.json, every
 * conditional row and the marginal ending at 1; the snippets in every
 * language with the sampler block (test_sampler_gl.c runs the GLSL's),
 * no warning that one is missing. */
SB_TEST(factor_writes_sampler) {
    char path[1024];
    snprintf(path, sizeof path, "%s/rgl_chm_orange_rgb.bsdf", SB_MEASURED_DIR);
    const char *const need[] = {"sb_vndf", "sb_col_dir"};
    cfix_factor_writes(path, "vndf", need, 2);
}
