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

/* |ds/dwi| against the solid angle of the image of a square of side h
 * around s (its corners mapped by sb_param_col_sample, the spherical
 * quadrilateral's area as two triangles, times 2 for the fold's 1/2):
 * within 2 %, and col_density's s the folded position. */
SB_TEST(jacobian) {
    sb_context_t *ctx = NULL;
    sb_param_t *p = NULL;
    sb_context_create(&ctx);
    sb_param_opts_t po;
    sb_param_kind_t kind;
    sb_result_t r = sb_param_parse_spec(ctx, "vh", &kind, &po);
    if (r == SB_OK) r = sb_param_create(ctx, kind, &po, &p);
    CHECKF(r == SB_OK, "%s", sb_context_last_error(ctx));
    const double h = 1e-4;
    size_t tried = 0, bad = 0, mirrored = 0;
    unsigned long long rng = 5;
    for (int o = 0; r == SB_OK && o < 4; o++) {
        double wo[3];
        cfix_dir(CFIX_THETAS[o], 70, wo);
        for (int t = 0; t < 100; t++) {
            double s[2] = {0.05 + 0.9 * sb_rand01(&rng), 0.05 + 1.9 * sb_rand01(&rng)}, c[4][3], wi[3], back[2];
            if (fabs(s[1] - 1) < 0.01) continue;
            int ok = sb_param_col_sample(p, wo, s, wi);
            for (int k = 0; k < 4; k++) {
                const double sk[2] = {s[0] + (k == 1 || k == 2 ? h : -h) / 2, s[1] + (k >= 2 ? h : -h) / 2};
                ok = ok && sb_param_col_sample(p, wo, sk, c[k]);
            }
            if (!ok) continue;
            double jac = sb_param_col_density(p, wi, wo, back), fold = s[1] > 1 ? 2 - s[1] : s[1];
            double area = tri_area(c[0], c[1], c[2]) + tri_area(c[0], c[2], c[3]), num = h * h / (2 * area);
            tried++;
            mirrored += s[1] > 1;
            int wrong =
                !(fabs(jac - num) <= 0.02 * num) || !(fabs(back[0] - s[0]) < 1e-7 && fabs(back[1] - fold) < 1e-7);
            if (wrong && bad < 5)
                fprintf(stderr, "theta_o %g s (%.4f, %.4f): |ds/dwi| %g, by the mapped square %g; back (%.6f, %.6f)\n",
                        CFIX_THETAS[o], s[0], s[1], jac, num, back[0], back[1]);
            bad += wrong;
        }
    }
    fprintf(stderr, "vh: %zu positions (%zu on the mirror half), %zu off\n", tried, mirrored, bad);
    CHECKF(tried >= 200 && mirrored >= 50, "only %zu positions map above the horizon (%zu mirrored)", tried, mirrored);
    CHECKF(bad == 0, "%zu of %zu positions: |ds/dwi| or the inverse off", bad, tried);
    sb_param_destroy(p);
    sb_context_destroy(ctx);
}

/* `factor gold --method nmf --param vh --shader all`: sampler.bin (cells
 * between the h textures' nodes, J C + 1 layers), the report's sampler
 * block with the share sampler.bin holds, no warning that a sampler is
 * missing, and the sampler block (sb_col_dir) in every language. */
SB_TEST(factor_writes_sampler) {
    const char *dir = sb_tmpdir("sampler_vh");
    sb_job_opts_t o = {0};
    o.source = GOLD, o.param = "vh", o.terms = 2, o.method = SB_METHOD_NMF, o.out = dir;
    o.shaders = "all";
    sb_context_t *ctx = NULL;
    sb_job_t *job = NULL;
    sb_context_create(&ctx);
    sb_result_t r = sb_job_run(ctx, &o, &job);
    CHECKF(r == SB_OK, "%s", sb_context_last_error(ctx));
    size_t W = 0, H = 0, said = 0;
    if (r == SB_OK) sb_param_texture_size(sb_job_param(job), SB_SIDE_H, &W, &H);
    for (size_t i = 0; job && i < sb_job_warning_count(job); i++) {
        const char *w = sb_job_warning(job, i);
        said += strstr(w, "no sampler") != NULL || strstr(w, "has no") != NULL || strstr(w, "no GLSL sampler") != NULL;
    }
    CHECKF(said == 0, "%zu warnings say vh has no sampler", said);
    const char *const need[] = {"sb_col_dir", "sb_col_weight"};
    cfix_written_set(dir, W, H, o.terms, need, 2);
    sb_job_destroy(job);
    sb_context_destroy(ctx);
}
