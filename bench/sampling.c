/* sepbrdf_bench_sampling: what the factored sampler (sepbrdf/sampler.h) is
 * worth in a renderer.  For each source and outgoing direction wo, the
 * reflected radiance under a constant white environment,
 *     L(wo) = int Y(f_r(wi, wo)) cos(theta_i) dwi     (Y: Rec. 709 luminance),
 * is estimated with one sample x = Y(f) cos / pdf of each strategy; the
 * table gives the variance of x relative to L^2 (the samples needed for a
 * relative error e are about that over e^2), averaged over wo:
 *   cosine    cosine-weighted hemisphere sampling;
 *   vndf      GGX visible-normal sampling (Heitz 2018) with the best of a
 *             sweep of alpha (the best-fitting lobe, chosen by the variance
 *             itself: an upper bound on what a fitted GGX lobe gives);
 *   mix       one-sample mixture of half cosine, half that VNDF (best alpha
 *             of the sweep again);
 *   io/hd/iso the factored sampler of non-negative factors (--method nmf,
 *             J = 4, form cos, solid-angle weights) on that layout.
 * The BRDF evaluated is always the source itself, not the factors.
 *
 *   sepbrdf_bench_sampling [-o|--out DIR] [--samples N] [--res R] [--quick]
 * writes the table to stdout and, with -o, DIR/sampling.csv. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "sepbrdf/sepbrdf.h"

#define NALPHA 7
static const double ALPHAS[NALPHA] = {0.01, 0.03, 0.06, 0.1, 0.2, 0.35, 0.6};
#define NWO 4
static const double WO_DEG[NWO] = {10, 30, 50, 70};
static const sb_param_kind_t LAYOUTS[3] = {SB_PARAM_IO, SB_PARAM_HD, SB_PARAM_ISO};

typedef struct opts {
    const char *out;
    size_t samples, res;
} opts_t;

static double rnd(unsigned long long *s) { /* splitmix64 -> [0, 1) */
    unsigned long long z = (*s += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return (double)((z ^ (z >> 31)) >> 11) * (1.0 / 9007199254740992.0);
}

static double lum(const double rgb[3]) { return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]; }

/* ---- the analytic strategies --------------------------------------------- */

static double ggx_d(double a, double cz) {
    double t = cz * cz * (a * a - 1) + 1;
    return a * a / (SB_PI * t * t);
}
static double ggx_g1(double a, const double w[3]) {
    double t2 = (w[0] * w[0] + w[1] * w[1]) / (w[2] * w[2]);
    return 2 / (1 + sqrt(1 + a * a * t2));
}

/* Density of wi under VNDF sampling for wo: G1(wo) D(h) / (4 wo.z). */
static double vndf_pdf(double a, const double wo[3], const double wi[3]) {
    double h[3] = {wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]}, n = sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
    if (!(n > 0) || wi[2] <= 0) return 0;
    return ggx_g1(a, wo) * ggx_d(a, h[2] / n) / (4 * wo[2]);
}

/* Heitz 2018, "Sampling the GGX distribution of visible normals". */
static void vndf_sample(double a, const double wo[3], double u1, double u2, double wi[3]) {
    double vh[3] = {a * wo[0], a * wo[1], wo[2]}, n = sqrt(vh[0] * vh[0] + vh[1] * vh[1] + vh[2] * vh[2]);
    for (int i = 0; i < 3; i++)
        vh[i] /= n;
    double l2 = vh[0] * vh[0] + vh[1] * vh[1], t1[3] = {1, 0, 0};
    if (l2 > 0) {
        t1[0] = -vh[1] / sqrt(l2);
        t1[1] = vh[0] / sqrt(l2);
    }
    double t2[3] = {vh[1] * t1[2] - vh[2] * t1[1], vh[2] * t1[0] - vh[0] * t1[2], vh[0] * t1[1] - vh[1] * t1[0]};
    double r = sqrt(u1), phi = 2 * SB_PI * u2, p1 = r * cos(phi), p2 = r * sin(phi), s = 0.5 * (1 + vh[2]);
    p2 = (1 - s) * sqrt(1 - p1 * p1) + s * p2;
    double pz = sqrt(fmax(0, 1 - p1 * p1 - p2 * p2)), nh[3];
    for (int i = 0; i < 3; i++)
        nh[i] = p1 * t1[i] + p2 * t2[i] + pz * vh[i];
    double ne[3] = {a * nh[0], a * nh[1], fmax(0, nh[2])};
    n = sqrt(ne[0] * ne[0] + ne[1] * ne[1] + ne[2] * ne[2]);
    double c = (wo[0] * ne[0] + wo[1] * ne[1] + wo[2] * ne[2]) / n;
    for (int i = 0; i < 3; i++)
        wi[i] = 2 * c * ne[i] / n - wo[i];
}

static void cosine_sample(double u1, double u2, double wi[3]) {
    double r = sqrt(u1), phi = 2 * SB_PI * u2;
    wi[0] = r * cos(phi);
    wi[1] = r * sin(phi);
    wi[2] = sqrt(fmax(0, 1 - u1));
}

/* ---- estimators ------------------------------------------------------------ */

enum { S_COSINE, S_VNDF, S_MIX, S_FACTORED };

typedef struct strategy {
    int kind;
    double alpha;
    const sb_sampler_t *sampler;
} strategy_t;

/* One sample: wi and its pdf (0: no direction). */
static double draw(const strategy_t *st, const double wo[3], double u1, double u2, double wi[3]) {
    double pdf = 0;
    switch (st->kind) {
    case S_COSINE:
        cosine_sample(u1, u2, wi);
        return wi[2] / SB_PI;
    case S_VNDF:
        vndf_sample(st->alpha, wo, u1, u2, wi);
        return vndf_pdf(st->alpha, wo, wi);
    case S_MIX:
        if (u1 < 0.5)
            cosine_sample(2 * u1, u2, wi);
        else
            vndf_sample(st->alpha, wo, 2 * u1 - 1, u2, wi);
        return wi[2] > 0 ? 0.5 * wi[2] / SB_PI + 0.5 * vndf_pdf(st->alpha, wo, wi) : 0;
    default: {
        double u[2] = {u1, u2};
        return sb_sample(st->sampler, wo, u, wi, &pdf, NULL) ? pdf : 0;
    }
    }
}

/* Mean and variance of x = Y(f) cos / pdf over n samples. */
static void estimate(const sb_source_t *src, const strategy_t *st, const double wo[3], size_t n, double *mean,
                     double *var) {
    unsigned long long rng = 0x5A3D1E5ULL;
    double s1 = 0, s2 = 0;
    for (size_t i = 0; i < n; i++) {
        double u1 = rnd(&rng), u2 = rnd(&rng), wi[3], rgb[3], x = 0;
        double pdf = draw(st, wo, u1, u2, wi);
        if (pdf > 0 && wi[2] > 0 && sb_source_eval(src, wi, wo, rgb)) x = lum(rgb) * wi[2] / pdf;
        s1 += x;
        s2 += x * x;
    }
    *mean = s1 / (double)n;
    *var = fmax(s2 / (double)n - *mean * *mean, 0);
}

/* Relative variance var / L^2 averaged over the outgoing directions, L
 * from the cosine estimate with 16x the samples. */
static double rel_var(const sb_source_t *src, const strategy_t *st, const double *ref, size_t n) {
    double sum = 0;
    for (int o = 0; o < NWO; o++) {
        double wo[3], mean, var;
        sb_dir_from_angles(WO_DEG[o] * SB_PI / 180, 0.3, wo);
        estimate(src, st, wo, n, &mean, &var);
        sum += var / (ref[o] * ref[o]);
    }
    return sum / NWO;
}

/* Best alpha of the sweep for kind (VNDF or mixture). */
static double best_alpha(const sb_source_t *src, int kind, const double *ref, size_t n, double *alpha) {
    double best = INFINITY;
    for (int a = 0; a < NALPHA; a++) {
        strategy_t st = {kind, ALPHAS[a], NULL};
        double v = rel_var(src, &st, ref, n);
        if (v < best) {
            best = v;
            *alpha = ALPHAS[a];
        }
    }
    return best;
}

/* ---- the factored sampler ------------------------------------------------- */

typedef struct fit {
    sb_param_t *p;
    sb_factors_t *f;
    sb_sampler_t *s;
} fit_t;

static void fit_free(fit_t *x) {
    sb_sampler_destroy(x->s);
    sb_factors_destroy(x->f);
    sb_param_destroy(x->p);
}

static sb_result_t fit_make(sb_context_t *ctx, const sb_source_t *src, sb_param_kind_t kind, size_t res, fit_t *x) {
    memset(x, 0, sizeof *x);
    sb_param_opts_t po = {0};
    po.res = res;
    sb_matrix_opts_t mo = {0};
    mo.form = SB_FORM_COS;
    sb_plan_opts_t pl = {0};
    pl.terms = 4;
    pl.weighted = 1;
    pl.svd.method = SB_METHOD_NMF;
    sb_matrix_t m = {0};
    sb_plan_t *plan = NULL;
    sb_result_t r = sb_param_create(ctx, kind, &po, &x->p);
    if (!r) r = sb_matrix_build(ctx, src, x->p, &mo, &m);
    if (!r) r = sb_plan_create_for(ctx, &m, &pl, &plan);
    if (!r) r = sb_plan_execute(plan, &m, x->p, &x->f);
    if (!r) r = sb_sampler_create(ctx, x->f, x->p, SB_FORM_COS, &x->s);
    sb_plan_destroy(plan);
    sb_matrix_free(&m);
    return r;
}

/* ---- driver ----------------------------------------------------------------- */

static const char *const SOURCES[] = {
    "cook-torrance:d=ggx,roughness=0.5",
    "cook-torrance:d=ggx,roughness=0.3",
    "cook-torrance:d=ggx,roughness=0.3,kd=0.05,ks=0.95",
    "blinn-phong:n=200",
    "tests/data/measured/cornell_acryl_blue.brdf",
    "tests/data/measured/rgl_paper_white_rgb.bsdf",
    "tests/data/measured/rgl_chm_orange_rgb.bsdf",
};
#define NSRC (sizeof SOURCES / sizeof SOURCES[0])

static int run_source(sb_context_t *ctx, const char *spec, const opts_t *o, FILE *csv) {
    sb_source_t *src = NULL;
    if (sb_source_open(ctx, spec, &src) != SB_OK) {
        fprintf(stderr, "sepbrdf_bench_sampling: %s: %s\n", spec, sb_context_last_error(ctx));
        return 2;
    }
    double ref[NWO];
    for (int w = 0; w < NWO; w++) {
        double wo[3], var;
        sb_dir_from_angles(WO_DEG[w] * SB_PI / 180, 0.3, wo);
        strategy_t st = {S_COSINE, 0, NULL};
        estimate(src, &st, wo, 16 * o->samples, &ref[w], &var);
    }
    strategy_t cos_st = {S_COSINE, 0, NULL};
    double v[6], a_vndf = 0, a_mix = 0;
    v[0] = rel_var(src, &cos_st, ref, o->samples);
    v[1] = best_alpha(src, S_VNDF, ref, o->samples, &a_vndf);
    v[2] = best_alpha(src, S_MIX, ref, o->samples, &a_mix);
    int rc = 0;
    for (int l = 0; l < 3; l++) {
        fit_t x;
        v[3 + l] = NAN;
        int applies = sb_param_kind_applies(LAYOUTS[l], sb_source_flags(src));
        if (applies && fit_make(ctx, src, LAYOUTS[l], o->res, &x) == SB_OK) {
            strategy_t st = {S_FACTORED, 0, x.s};
            v[3 + l] = rel_var(src, &st, ref, o->samples);
        } else if (applies) {
            fprintf(stderr, "sepbrdf_bench_sampling: %s on %s: %s\n", spec, sb_param_kind_name(LAYOUTS[l]),
                    sb_context_last_error(ctx));
            rc = 3;
        }
        if (applies) fit_free(&x);
    }
    double best = fmin(v[3], fmin(v[4], v[5]));
    const char *name = strrchr(spec, '/') ? strrchr(spec, '/') + 1 : spec;
    printf("| %-48s | %8.3g | %8.3g (%.2g) | %8.3g (%.2g) | %8.3g | %8.3g | %8.3g | %6.1fx |\n", name, v[0], v[1],
           a_vndf, v[2], a_mix, v[3], v[4], v[5], v[0] / best);
    fflush(stdout);
    if (csv)
        fprintf(csv, "\"%s\",%.6g,%.6g,%g,%.6g,%g,%.6g,%.6g,%.6g\n", name, v[0], v[1], a_vndf, v[2], a_mix, v[3], v[4],
                v[5]);
    sb_source_destroy(src);
    return rc;
}

static int parse(int argc, char **argv, opts_t *o) {
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        int has = i + 1 < argc;
        if ((!strcmp(a, "-o") || !strcmp(a, "--out")) && has)
            o->out = argv[++i];
        else if (!strcmp(a, "--samples") && has)
            o->samples = strtoul(argv[++i], NULL, 10);
        else if (!strcmp(a, "--res") && has)
            o->res = strtoul(argv[++i], NULL, 10);
        else if (!strcmp(a, "--quick"))
            o->samples = 20000, o->res = 16;
        else if (!strcmp(a, "-h") || !strcmp(a, "--help")) {
            printf("usage: sepbrdf_bench_sampling [-o|--out DIR] [--samples N] [--res R] [--quick]\n"
                   "Relative variance of one-sample estimates of the reflected radiance under a constant\n"
                   "environment: cosine, GGX VNDF, cosine+VNDF and the factored sampler (io, hd, iso).\n"
                   "Run from the source tree (measured files under tests/data/measured).\n");
            return 0;
        } else {
            fprintf(stderr, "sepbrdf_bench_sampling: unknown option or missing value: %s\n", a);
            return 1;
        }
    }
    if (o->samples < 100 || o->res < 2) {
        fprintf(stderr, "sepbrdf_bench_sampling: --samples must be >= 100 and --res >= 2\n");
        return 1;
    }
    return -1;
}

int main(int argc, char **argv) {
    opts_t o = {NULL, 200000, 32};
    int rc = parse(argc, argv, &o);
    if (rc >= 0) return rc;
    FILE *csv = NULL;
    if (o.out) {
        char path[4200];
        snprintf(path, sizeof path, "%s/sampling.csv", o.out);
        if (!(csv = fopen(path, "w"))) {
            fprintf(stderr, "sepbrdf_bench_sampling: %s: cannot write\n", path);
            return 2;
        }
        fprintf(csv, "source,cosine,vndf,vndf_alpha,mix,mix_alpha,io,hd,iso\n");
    }
    sb_context_t *ctx = NULL;
    sb_context_create(&ctx);
    printf("Relative variance var(x)/L^2 of one sample, mean over theta_o = 10, 30, 50, 70 deg; %zu samples each; "
           "factors: nmf, J = 4, form cos, res %zu\n\n",
           o.samples, o.res);
    printf("| %-48s | %8s | %-15s | %-15s | %8s | %8s | %8s | %7s |\n", "source", "cosine", "vndf (alpha)",
           "mix (alpha)", "io", "hd", "iso", "cos/best");
    printf("|---|---|---|---|---|---|---|---|\n");
    double t0 = (double)clock();
    for (size_t k = 0; k < NSRC && rc <= 0; k++) {
        int r = run_source(ctx, SOURCES[k], &o, csv);
        if (r) rc = r;
    }
    printf("\n%.0f s CPU\n", ((double)clock() - t0) / CLOCKS_PER_SEC);
    if (csv && fclose(csv) != 0 && rc <= 0) rc = 2;
    sb_context_destroy(ctx);
    return rc < 0 ? 0 : rc;
}
