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

#include "sampler_chi2.h"

typedef struct vfix {
    sb_context_t *ctx;
    sb_job_t *job;
    sb_sampler_t *s;
} vfix_t;

static int vfix_open(const char *file, vfix_t *x) {
    memset(x, 0, sizeof *x);
    char path[1024];
    snprintf(path, sizeof path, "%s/%s", SB_MEASURED_DIR, file);
    sb_job_opts_t o = {0};
    o.source = path, o.param = "vndf", o.terms = 4, o.method = SB_METHOD_NMF;
    sb_context_create(&x->ctx);
    sb_result_t r = sb_job_run(x->ctx, &o, &x->job);
    if (!r) r = sb_sampler_create(x->ctx, sb_job_factors(x->job), sb_job_param(x->job), sb_job_form(x->job), &x->s);
    CHECKF(r == SB_OK, "%s: %s", file, sb_context_last_error(x->ctx));
    return r == SB_OK;
}

static void vfix_close(vfix_t *x) {
    sb_sampler_destroy(x->s);
    sb_job_destroy(x->job);
    sb_context_destroy(x->ctx);
}

static void dir(double theta_deg, double phi_deg, double w[3]) {
    sb_dir_from_angles(theta_deg * SB_PI / 180, phi_deg * SB_PI / 180, w);
}

static const double THETAS[4] = {10, 30, 55, 75};

/* chi2 of n draws at each elevation (phi_o = 30), every draw's pdf that
 * of sb_pdf. */
static void chi2_file(const char *file, size_t n) {
    vfix_t x;
    if (!vfix_open(file, &x)) {
        vfix_close(&x);
        return;
    }
    double *mass = malloc(NT * NP * sizeof *mass), *obs = malloc(NT * NP * sizeof *obs);
    unsigned long long rng = 0x38d5ULL;
    for (size_t o = 0; o < 4; o++) {
        double wo[3], wi[3], pdf, stat;
        dir(THETAS[o], 30, wo);
        memset(obs, 0, NT * NP * sizeof *obs);
        size_t ok = 0, bad = 0;
        for (size_t i = 0; i < n; i++) {
            double u[2] = {sb_rand01(&rng), sb_rand01(&rng)};
            if (!sb_sample(x.s, wo, u, wi, &pdf, NULL)) continue;
            ok++;
            obs[bin_of(wi)] += 1;
            bad += !(fabs(sb_pdf(x.s, wo, wi) - pdf) <= 1e-12 * pdf);
        }
        expected_mass(x.s, wo, (double)n, mass);
        int dof;
        double p = chi2_p(mass, obs, (double)n, &stat, &dof);
        fprintf(stderr, "vndf %s theta_o %2.0f: %zu/%zu draws, chi2 %.1f dof %d p %.3f\n", file, THETAS[o], ok, n, stat,
                dof, p);
        CHECKF(p >= 0.001, "%s theta_o %g: chi2 %g, dof %d, p %g < 0.001", file, THETAS[o], stat, dof, p);
        CHECKF(bad == 0, "%s: %zu draws whose pdf is not sb_pdf's", file, bad);
        CHECKF(ok >= n / 2, "%s theta_o %g: only %zu of %zu draws succeed", file, THETAS[o], ok, n);
    }
    free(mass);
    free(obs);
    vfix_close(&x);
}

SB_TEST(chi2_orange) { chi2_file("rgl_chm_orange_rgb.bsdf", 200000); }
SB_TEST(chi2_paper) { chi2_file("rgl_paper_white_rgb.bsdf", 200000); }
SB_TEST(chi2_aurora) { chi2_file("rgl_aurora_white_rgb.bsdf", 200000); }

/* Integral of g over the upper hemisphere, midpoint rule in (cos theta,
 * phi) on n x 2n cells. */
static double hemi(const vfix_t *x, const double wo[3], int fcos, size_t n) {
    double dz = 1.0 / (double)n, dp = SB_PI / (double)n, sum = 0;
    for (size_t i = 0; i < n; i++)
        for (size_t k = 0; k < 2 * n; k++) {
            double z = 1 - (i + 0.5) * dz, phi = (k + 0.5) * dp, r = sqrt(1 - z * z), rgb[3];
            double w[3] = {r * cos(phi), r * sin(phi), z};
            if (!fcos) {
                sum += sb_pdf(x->s, wo, w);
                continue;
            }
            sb_factors_eval(sb_job_factors(x->job), sb_job_param(x->job), SB_FORM_COS, 4, w, wo, rgb);
            sum += (0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]) * w[2];
        }
    return sum * dz * dp;
}

/* The pdf integrates to the share of draws that succeed (within 4
 * standard errors and the quadrature's change from 256 to 512 steps); the
 * estimate of int Y(f) cos within 4 standard errors (and that change) of
 * the quadrature: no region where f > 0 and the pdf is 0. */
SB_TEST(integrals) {
    vfix_t x;
    if (!vfix_open("rgl_paper_white_rgb.bsdf", &x)) {
        vfix_close(&x);
        return;
    }
    unsigned long long rng = 11;
    for (int o = 0; o < 4; o++) {
        double wo[3], wi[3], pdf, rgb[3], s1 = 0, s2 = 0;
        dir(THETAS[o], 30, wo);
        double mass = hemi(&x, wo, 0, 512), coarse = hemi(&x, wo, 0, 256);
        double ref = hemi(&x, wo, 1, 512), ref_c = hemi(&x, wo, 1, 256);
        size_t n = 200000, ok = 0;
        for (size_t i = 0; i < n; i++) {
            double u[2] = {sb_rand01(&rng), sb_rand01(&rng)}, v = 0;
            if (sb_sample(x.s, wo, u, wi, &pdf, rgb)) {
                ok++;
                v = (0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]) * wi[2] / pdf;
            }
            s1 += v, s2 += v * v;
        }
        double mean = s1 / n, se = sqrt(fmax(s2 / n - mean * mean, 0) / n), frac = (double)ok / n;
        fprintf(stderr,
                "vndf paper theta_o %2.0f: pdf integral %.5f (%.5f at 256), successes %.5f; MC %.5f +- %.5f vs %.5f\n",
                THETAS[o], mass, coarse, frac, mean, se, ref);
        CHECK_ABS(mass, frac, 4 * sqrt(frac * (1 - frac) / n) + 2e-3 + fabs(mass - coarse));
        CHECK_ABS(mean, ref, 4 * se + fabs(ref - ref_c) + 1e-3 * ref);
    }
    vfix_close(&x);
}

/* |ds/dwi| against the solid angle of the image of a square of side h
 * around s (its corners mapped by sb_param_col_sample, the spherical
 * quadrilateral's area as two triangles): within 2 %. */
static double tri_area(const double a[3], const double b[3], const double c[3]) {
    double bc[3] = {b[1] * c[2] - b[2] * c[1], b[2] * c[0] - b[0] * c[2], b[0] * c[1] - b[1] * c[0]};
    double num = a[0] * bc[0] + a[1] * bc[1] + a[2] * bc[2];
    double den = 1 + (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) + (b[0] * c[0] + b[1] * c[1] + b[2] * c[2]) +
                 (c[0] * a[0] + c[1] * a[1] + c[2] * a[2]);
    return 2 * fabs(atan2(num, den));
}

SB_TEST(jacobian) {
    vfix_t x;
    if (!vfix_open("rgl_chm_orange_rgb.bsdf", &x)) {
        vfix_close(&x);
        return;
    }
    const sb_param_t *p = sb_job_param(x.job);
    const double h = 1e-4;
    size_t tried = 0, bad = 0;
    unsigned long long rng = 5;
    for (int o = 0; o < 4; o++) {
        double wo[3];
        dir(THETAS[o], 70, wo);
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
                        THETAS[o], s[0], s[1], jac, num, back[0], back[1]);
            bad += wrong;
        }
    }
    fprintf(stderr, "vndf orange: %zu positions, %zu off\n", tried, bad);
    CHECKF(tried >= 100, "only %zu positions map above the horizon", tried);
    CHECKF(bad == 0, "%zu of %zu positions: |ds/dwi| or the inverse off", bad, tried);
    vfix_close(&x);
}

/* `factor RGL --method nmf --shaders all` (the job): sampler.bin of the
 * header's sizes (cells between the h textures' nodes, J C + 1 layers),
 * the chosen share at layer J C's texel (0, H) and in report.json, every
 * conditional row and the marginal ending at 1; the snippets in every
 * language with the sampler block (test_sampler_gl.c runs the GLSL's),
 * no warning that one is missing. */
static uint32_t u32_at(const unsigned char *b) {
    return (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
}
static float f32_at(const unsigned char *b) {
    uint32_t v = u32_at(b);
    float f;
    memcpy(&f, &v, sizeof f);
    return f;
}

SB_TEST(factor_writes_sampler) {
    char path[1024], file[1200];
    snprintf(path, sizeof path, "%s/rgl_chm_orange_rgb.bsdf", SB_MEASURED_DIR);
    const char *dir = sb_tmpdir("sampler_vndf");
    sb_job_opts_t o = {0};
    o.source = path, o.param = "vndf", o.terms = 2, o.method = SB_METHOD_NMF, o.out = dir, o.shaders = "all";
    sb_context_t *ctx = NULL;
    sb_job_t *job = NULL;
    sb_context_create(&ctx);
    sb_result_t r = sb_job_run(ctx, &o, &job);
    CHECKF(r == SB_OK, "%s", sb_context_last_error(ctx));
    size_t W = 0, H = 0, said = 0;
    if (r == SB_OK) sb_param_texture_size(sb_job_param(job), SB_SIDE_H, &W, &H);
    for (size_t i = 0; job && i < sb_job_warning_count(job); i++)
        said += strstr(sb_job_warning(job, i), "no GLSL sampler") != NULL;
    CHECKF(said == 0, "%zu warnings say the snippet has no sampler", said);
    snprintf(file, sizeof file, "%s/sampler.bin", dir);
    size_t n = 0;
    unsigned char *b = (unsigned char *)sb_read_file(file, &n);
    CHECKF(b && n >= 24 && !memcmp(b, "sbsampl1", 8), "%s: not a sampler file", file);
    if (b && n >= 24 && W >= 2) {
        uint32_t w1 = u32_at(b + 8), h1 = u32_at(b + 12), layers = u32_at(b + 16), C = u32_at(b + 20);
        CHECKF(w1 == W && h1 == H && layers == o.terms * C + 1 && C == 3, "header %u x %u, %u layers, %u channels", w1,
               h1, layers, C);
        CHECK(n == 24 + (size_t)layers * w1 * h1 * 4);
        const unsigned char *t = b + 24;
        size_t ends = 0;
        for (size_t k = 0; n == 24 + (size_t)layers * w1 * h1 * 4 && k + 1 < layers; k++)
            for (size_t y = 0; y + 1 < h1; y++)
                ends += f32_at(t + 4 * ((k * h1 + y) * w1 + w1 - 2)) == 1 &&
                        (y + 2 < h1 || f32_at(t + 4 * ((k * h1 + y) * w1 + w1 - 1)) == 1);
        CHECKF(ends == (layers - 1) * (h1 - 1), "%zu of %zu rows' CDFs end at 1", ends,
               (size_t)(layers - 1) * (h1 - 1));
        float share = f32_at(t + 4 * ((layers - 1) * h1 * w1 + (h1 - 1) * w1));
        snprintf(file, sizeof file, "%s/report.json", dir);
        char *rep = sb_read_file(file, NULL), key[64];
        snprintf(key, sizeof key, "\"cosine_share\": %.17g", (double)share);
        CHECKF(rep && share >= (float)SB_SAMPLER_MIN_SHARE && share <= 1 &&
                   strstr(rep, "\"sampler\": \"sampler.bin\"") && strstr(rep, key),
               "share %g, report %s", share, rep ? "without sampler.bin or that share" : "missing");
        free(rep);
    }
    free(b);
    const char *exts[4] = {"glsl", "hlsl", "metal", "wgsl"};
    for (int i = 0; i < 4; i++) {
        snprintf(file, sizeof file, "%s/sepbrdf.%s", dir, exts[i]);
        char *text = sb_read_file(file, NULL);
        CHECKF(text && strstr(text, "sb_vndf") && strstr(text, "sb_sample(") && strstr(text, "sb_col_dir"), "%s", file);
        free(text);
    }
    sb_job_destroy(job);
    sb_context_destroy(ctx);
}
