/* Checks shared by the tests of the layouts that sample their columns
 * (SB_CAP_COL_SAMPLE: test_sampler_vndf.c, test_sampler_vh.c): the
 * non-negative fit `sepbrdf factor SRC --method nmf --param P` (the job,
 * J = 4) and its sampler; chi2 of the drawn directions against sb_pdf at
 * four view elevations; the pdf integrating to the share of draws that
 * succeed and the estimator of int Y(f) cos against a quadrature; the
 * area of a spherical triangle; sampler.bin's little-endian numbers.
 * Include after harness.h. */
#ifndef SB_TEST_SAMPLER_COLS_CHECK_H
#define SB_TEST_SAMPLER_COLS_CHECK_H

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sampler_chi2.h"
#include "sepbrdf/sepbrdf.h"

typedef struct cfix {
    sb_context_t *ctx;
    sb_job_t *job;
    sb_sampler_t *s;
} cfix_t;

/* The fit of src (a model spec, or a file name under tests/data/measured
 * when it ends in .bsdf) on layout param, J = 4, and its sampler. */
static inline int cfix_open(const char *src, const char *param, cfix_t *x) {
    memset(x, 0, sizeof *x);
    char path[1024];
    if (strstr(src, ".bsdf")) snprintf(path, sizeof path, "%s/%s", SB_MEASURED_DIR, src);
    sb_job_opts_t o = {0};
    o.source = strstr(src, ".bsdf") ? path : src, o.param = param, o.terms = 4, o.method = SB_METHOD_NMF;
    sb_context_create(&x->ctx);
    sb_result_t r = sb_job_run(x->ctx, &o, &x->job);
    if (!r) r = sb_sampler_create(x->ctx, sb_job_factors(x->job), sb_job_param(x->job), sb_job_form(x->job), &x->s);
    CHECKF(r == SB_OK, "%s: %s", src, sb_context_last_error(x->ctx));
    return r == SB_OK;
}

static inline void cfix_close(cfix_t *x) {
    sb_sampler_destroy(x->s);
    sb_job_destroy(x->job);
    sb_context_destroy(x->ctx);
}

static inline void cfix_dir(double theta_deg, double phi_deg, double w[3]) {
    sb_dir_from_angles(theta_deg * SB_PI / 180, phi_deg * SB_PI / 180, w);
}

static const double CFIX_THETAS[4] = {10, 30, 55, 75};

/* chi2 of n draws at each elevation (phi_o = 30) from the stream seed,
 * every draw's pdf that of sb_pdf, at least n / min_div draws succeeding. */
static inline void cfix_chi2(const char *src, const char *param, size_t n, unsigned long long rng, size_t min_div) {
    cfix_t x;
    if (!cfix_open(src, param, &x)) {
        cfix_close(&x);
        return;
    }
    double *mass = malloc(NT * NP * sizeof *mass), *obs = malloc(NT * NP * sizeof *obs);
    for (size_t o = 0; o < 4; o++) {
        double wo[3], wi[3], pdf, stat;
        cfix_dir(CFIX_THETAS[o], 30, wo);
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
        fprintf(stderr, "%s %s theta_o %2.0f: %zu/%zu draws, chi2 %.1f dof %d p %.3f\n", param, src, CFIX_THETAS[o], ok,
                n, stat, dof, p);
        CHECKF(p >= 0.001, "%s theta_o %g: chi2 %g, dof %d, p %g < 0.001", src, CFIX_THETAS[o], stat, dof, p);
        CHECKF(bad == 0, "%s: %zu draws whose pdf is not sb_pdf's", src, bad);
        CHECKF(ok >= n / min_div, "%s theta_o %g: only %zu of %zu draws succeed", src, CFIX_THETAS[o], ok, n);
    }
    free(mass);
    free(obs);
    cfix_close(&x);
}

/* Integral of the pdf (fcos 0) or of Y(f) cos over the upper
 * hemisphere, midpoint rule in (cos theta, phi) on n x 2n cells. */
static inline double cfix_hemi(const cfix_t *x, const double wo[3], int fcos, size_t n) {
    double dz = 1.0 / (double)n, dp = SB_PI / (double)n, sum = 0;
    for (size_t i = 0; i < n; i++)
        for (size_t k = 0; k < 2 * n; k++) {
            double z = 1 - (i + 0.5) * dz, phi = (k + 0.5) * dp, r = sqrt(1 - z * z), rgb[3];
            double w[3] = {r * cos(phi), r * sin(phi), z};
            if (!fcos) {
                sum += sb_pdf(x->s, wo, w);
                continue;
            }
            sb_factors_eval(sb_job_factors(x->job), sb_job_param(x->job), sb_job_form(x->job), 4, w, wo, rgb);
            sum += (0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]) * w[2];
        }
    return sum * dz * dp;
}

/* The pdf integrates to the share of draws that succeed (within 4
 * standard errors and the quadrature's change from 256 to 512 steps); the
 * estimate of int Y(f) cos within 4 standard errors (and that change) of
 * the quadrature: no region where f > 0 and the pdf is 0. */
static inline void cfix_integrals(const char *src, const char *param) {
    cfix_t x;
    if (!cfix_open(src, param, &x)) {
        cfix_close(&x);
        return;
    }
    unsigned long long rng = 11;
    for (int o = 0; o < 4; o++) {
        double wo[3], wi[3], pdf, rgb[3], s1 = 0, s2 = 0;
        cfix_dir(CFIX_THETAS[o], 30, wo);
        double mass = cfix_hemi(&x, wo, 0, 512), coarse = cfix_hemi(&x, wo, 0, 256);
        double ref = cfix_hemi(&x, wo, 1, 512), ref_c = cfix_hemi(&x, wo, 1, 256);
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
                "%s %s theta_o %2.0f: pdf integral %.5f (%.5f at 256), successes %.5f; MC %.5f +- %.5f vs %.5f\n",
                param, src, CFIX_THETAS[o], mass, coarse, frac, mean, se, ref);
        CHECK_ABS(mass, frac, 4 * sqrt(frac * (1 - frac) / n) + 2e-3 + fabs(mass - coarse));
        CHECK_ABS(mean, ref, 4 * se + fabs(ref - ref_c) + 1e-3 * ref);
    }
    cfix_close(&x);
}

/* The solid angle of the spherical triangle a b c. */
static inline double tri_area(const double a[3], const double b[3], const double c[3]) {
    double bc[3] = {b[1] * c[2] - b[2] * c[1], b[2] * c[0] - b[0] * c[2], b[0] * c[1] - b[1] * c[0]};
    double num = a[0] * bc[0] + a[1] * bc[1] + a[2] * bc[2];
    double den = 1 + (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) + (b[0] * c[0] + b[1] * c[1] + b[2] * c[2]) +
                 (c[0] * a[0] + c[1] * a[1] + c[2] * a[2]);
    return 2 * fabs(atan2(num, den));
}

/* sampler.bin's little-endian numbers. */
static inline uint32_t u32_at(const unsigned char *b) {
    return (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
}
static inline float f32_at(const unsigned char *b) {
    uint32_t v = u32_at(b);
    float f;
    memcpy(&f, &v, sizeof f);
    return f;
}

/* The set a column sampler's `factor --shader all` wrote into dir:
 * sampler.bin's header (the h texture W x H, J C + 1 layers, 3
 * channels), every row's CDF ending at 1, the share in its last layer
 * equal to report.json's cosine_share (and the report naming
 * sampler.bin), and each language's snippet holding sb_sample( and the
 * names in need[] (n of them). */
static inline void cfix_written_set(const char *dir, size_t W, size_t H, size_t terms, const char *const *need,
                                    size_t n_need) {
    char file[1200];
    snprintf(file, sizeof file, "%s/sampler.bin", dir);
    size_t n = 0;
    unsigned char *b = (unsigned char *)sb_read_file(file, &n);
    CHECKF(b && n >= 24 && !memcmp(b, "sbsampl1", 8), "%s: not a sampler file", file);
    if (b && n >= 24 && W >= 2) {
        uint32_t w1 = u32_at(b + 8), h1 = u32_at(b + 12), layers = u32_at(b + 16), C = u32_at(b + 20);
        CHECKF(w1 == W && h1 == H && layers == terms * C + 1 && C == 3, "header %u x %u, %u layers, %u channels", w1,
               h1, layers, C);
        int whole = n == 24 + (size_t)layers * w1 * h1 * 4;
        CHECK(whole);
        const unsigned char *t = b + 24;
        size_t ends = 0;
        for (size_t k = 0; whole && k + 1 < layers; k++)
            for (size_t y = 0; y + 1 < h1; y++)
                ends += f32_at(t + 4 * ((k * h1 + y) * w1 + w1 - 2)) == 1 &&
                        (y + 2 < h1 || f32_at(t + 4 * ((k * h1 + y) * w1 + w1 - 1)) == 1);
        CHECKF(ends == (layers - 1) * (h1 - 1), "%zu of %zu rows' CDFs end at 1", ends,
               (size_t)(layers - 1) * (h1 - 1));
        if (whole) {
            float share = f32_at(t + 4 * ((layers - 1) * h1 * w1 + (h1 - 1) * w1));
            snprintf(file, sizeof file, "%s/report.json", dir);
            char *rep = sb_read_file(file, NULL), key[64];
            snprintf(key, sizeof key, "\"cosine_share\": %.17g", (double)share);
            CHECKF(rep && share >= (float)SB_SAMPLER_MIN_SHARE && share <= 1 &&
                       strstr(rep, "\"sampler\": \"sampler.bin\"") && strstr(rep, key),
                   "share %g, report %s", share, rep ? "without sampler.bin or that share" : "missing");
            free(rep);
        }
    }
    free(b);
    const char *exts[4] = {"glsl", "hlsl", "metal", "wgsl"};
    for (int i = 0; i < 4; i++) {
        snprintf(file, sizeof file, "%s/sepbrdf.%s", dir, exts[i]);
        char *text = sb_read_file(file, NULL);
        int has = text && strstr(text, "sb_sample(");
        for (size_t k = 0; has && k < n_need; k++)
            has = strstr(text, need[k]) != NULL;
        CHECKF(has, "%s", file);
        free(text);
    }
}

/* |ds/dwi| of layout spec (a SB_CAP_COL_FOLD one) against the solid angle
 * of the image of a square of side 1e-4 around s (its corners mapped by
 * sb_param_col_sample, the spherical quadrilateral's area as two
 * triangles, times 2 for the fold's 1/2): within 2 %, and col_density's s
 * the folded position; 100 positions at each of 4 view elevations, at
 * least min_tried above the horizon and 50 of them on the mirror half. */
static inline void cfix_jacobian(const char *spec, size_t min_tried) {
    sb_context_t *ctx = NULL;
    sb_param_t *p = NULL;
    sb_context_create(&ctx);
    sb_param_opts_t po;
    sb_param_kind_t kind;
    sb_result_t r = sb_param_parse_spec(ctx, spec, &kind, &po);
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
    fprintf(stderr, "%s: %zu positions (%zu on the mirror half), %zu off\n", spec, tried, mirrored, bad);
    CHECKF(tried >= min_tried && mirrored >= 50, "only %zu positions map above the horizon (%zu mirrored)", tried,
           mirrored);
    CHECKF(bad == 0, "%zu of %zu positions: |ds/dwi| or the inverse off", bad, tried);
    sb_param_destroy(p);
    sb_context_destroy(ctx);
}

/* `factor SRC --method nmf --param P -J 2 --shader all` (the job): no
 * warning that a sampler is missing, and cfix_written_set on what it
 * wrote (need: the names each language's snippet must hold). */
static inline void cfix_factor_writes(const char *src, const char *param, const char *const *need, size_t n_need) {
    const char *dir = sb_tmpdir("sampler_cols");
    sb_job_opts_t o = {0};
    o.source = src, o.param = param, o.terms = 2, o.method = SB_METHOD_NMF, o.out = dir, o.shaders = "all";
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
    CHECKF(said == 0, "%zu warnings say %s has no sampler", said, param);
    cfix_written_set(dir, W, H, o.terms, need, n_need);
    sb_job_destroy(job);
    sb_context_destroy(ctx);
}

#endif
