/* The GGX lobe of the sampler's mixture (src/factor/sampler_lobe.c,
 * sepbrdf/sampler.h): its own density against a numerical integral and
 * its draws' histogram; the mixture with the lobe on, sb_sample against
 * sb_pdf (chi2) and the pdf integrating to the success rate on a
 * half-vector, a light-direction and a column layout; the choice taking a
 * lobe for a GGX alpha 0.1 highlight, and the setters' errors. */
#include <math.h>
#include <stdlib.h>

#include "factor/sampler_impl.h"
#include "harness.h"
#include "sampler_chi2.h"
#include "sampler_fixture.h"
#include "sepbrdf/sepbrdf.h"

/* GGX's D written apart from the library's: 1 / (pi a^2 cos^4 (1 +
 * tan^2 / a^2)^2). */
static double ggx_d(double a, const double h[3]) {
    double c2 = h[2] * h[2], t2 = (h[0] * h[0] + h[1] * h[1]) / c2;
    return 1 / (SB_PI * a * a * c2 * c2 * (1 + t2 / (a * a)) * (1 + t2 / (a * a)));
}

/* The half vector at (t, phi) of the map tan(theta_h) = a sqrt(t / (1 - t)),
 * under which D(h) cos(theta_h) dw_h = dt dphi / (2 pi): a grid even in
 * the lobe's own mass, however sharp. */
static void h_at(double a, double t, double phi, double h[3]) {
    double th = atan(a * sqrt(t / (1 - t)));
    sb_dir_from_angles(th, phi, h);
}

#define LT 16 /* histogram bins in t and phi of the half vector */
#define LP 16
#define LQ 12 /* midpoint points a bin and axis */

/* The mass of lobe alpha_pdf's density in every (t, phi) bin of the half
 * vector (the map of alpha_map): int p(wi(h)) 4 (wo.h) dw_h, dw_h = dt
 * dphi / (2 pi D(h) cos theta_h), midpoint in v = sqrt(1 - t) (dt = 2 v
 * dv: the integrand's 1 / sqrt(1 - t) at grazing h made smooth).
 * Returns the whole. */
static double lobe_masses(double alpha_pdf, double alpha_map, const double wo[3], double *mass) {
    double whole = 0;
    for (int b = 0; b < LT * LP; b++) {
        double sum = 0, vhi = sqrt(1 - (double)(b / LP) / LT), vlo = sqrt(1 - (double)(b / LP + 1) / LT);
        for (int i = 0; i < LQ; i++)
            for (int k = 0; k < LQ; k++) {
                double v = vlo + (i + 0.5) * (vhi - vlo) / LQ, t = 1 - v * v, h[3];
                double phi = 2 * SB_PI * ((b % LP) + (k + 0.5) / LQ) / LP;
                h_at(alpha_map, t, phi, h);
                double d = h[0] * wo[0] + h[1] * wo[1] + h[2] * wo[2], wi[3];
                if (!(d > 0)) continue;
                for (int c = 0; c < 3; c++)
                    wi[c] = 2 * d * h[c] - wo[c];
                sum += sb_lobe_pdf_(alpha_pdf, wo, wi) * 4 * d / (2 * SB_PI * ggx_d(alpha_map, h) * h[2]) * 2 * v *
                       (vhi - vlo);
            }
        mass[b] = sum * 2 * SB_PI / (LQ * LQ * LP); /* dphi = 2 pi / (LP LQ) */
        whole += mass[b];
    }
    return whole;
}

static int lobe_bin(double a, const double wo[3], const double wi[3]) {
    double h[3] = {wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]}, t2 = (h[0] * h[0] + h[1] * h[1]) / (h[2] * h[2]);
    double q = t2 / (a * a), t = q / (1 + q), phi = atan2(h[1], h[0]);
    if (phi < 0) phi += 2 * SB_PI;
    if (!(t <= 1)) t = 1; /* h in the horizon */
    int i = (int)(t * LT), k = (int)(phi / (2 * SB_PI) * LP);
    return (i < LT ? i : LT - 1) * LP + (k < LP ? k : LP - 1);
}

/* chi2 p of n draws of the lobe alpha against the masses of the pdf at
 * alpha_pdf (bins of the half vector; the pooling of sampler_chi2.h). */
static double lobe_chi2(double alpha, double alpha_pdf, const double wo[3], size_t n, double *whole) {
    double mass[LT * LP], obs[LT * LP] = {0}, stat;
    unsigned long long rng = 4242;
    size_t drawn = 0;
    for (size_t t = 0; t < n; t++) {
        double u[2] = {sb_rand01(&rng), sb_rand01(&rng)}, wi[3];
        if (!sb_lobe_dir_(alpha, wo, u[0], u[1], wi)) continue;
        obs[lobe_bin(alpha, wo, wi)] += 1;
        drawn++;
    }
    CHECKF(drawn == n, "%zu of %zu drawn", drawn, n);
    *whole = lobe_masses(alpha_pdf, alpha, wo, mass);
    double rest_m = 0, rest_o = 0, chi = 0;
    int dof = -1;
    for (int b = 0; b < LT * LP; b++) {
        if (mass[b] * (double)n >= MIN_EXP) {
            chi += (obs[b] - mass[b] * (double)n) * (obs[b] - mass[b] * (double)n) / (mass[b] * (double)n), dof++;
        } else {
            rest_m += mass[b], rest_o += obs[b];
        }
    }
    if (rest_m * (double)n >= MIN_EXP) chi += pow(rest_o - rest_m * (double)n, 2) / (rest_m * (double)n), dof++;
    stat = chi;
    return gamma_q(0.5 * dof, 0.5 * stat);
}

/* The lobe's density integrates to 1 over the sphere of wi and its draws
 * follow it, from a sharp lobe (0.05) to a broad one (0.7), wo from near
 * the normal to grazing; with the density at an alpha 10 % off, the
 * histogram rejects it. */
SB_TEST(lobe_pdf_and_draws) {
    const double alphas[4] = {0.05, 0.1, 0.3, 0.7}, thetas[3] = {5, 45, 80};
    for (int a = 0; a < 4; a++)
        for (int o = 0; o < 3; o++) {
            double wo[3], whole, wrong;
            sb_dir_from_angles(thetas[o] * SB_PI / 180, 0.4 + o, wo);
            double p = lobe_chi2(alphas[a], alphas[a], wo, 100000, &whole);
            double q = lobe_chi2(alphas[a], 1.1 * alphas[a], wo, 100000, &wrong);
            fprintf(stderr, "alpha %.2f theta_o %2.0f: integral %.6f, chi2 p %.3g; pdf at 1.1 alpha: p %.3g\n",
                    alphas[a], thetas[o], whole, p, q);
            CHECKF(fabs(whole - 1) < 2e-3, "alpha %g theta_o %g: the pdf integrates to %g", alphas[a], thetas[o],
                   whole);
            CHECKF(p > 1e-3, "alpha %g theta_o %g: chi2 p %g", alphas[a], thetas[o], p);
            CHECKF(q < 1e-6, "alpha %g theta_o %g: the pdf at 1.1 alpha passes (p %g)", alphas[a], thetas[o], q);
        }
}

/* A sampler of gold (iso, io, vh) with the lobe on at s = 0.1, s_l = 0.5. */
static int lobe_fixture(sb_param_kind_t kind, double alpha, fixture_t *x) {
    if (!fixture_sampler("microfacet:base=gold,roughness=0.5", kind, 8, 2, x)) return 0;
    CHECK(sb_sampler_set_cosine_share(x->s, 0.1) == SB_OK);
    CHECK(sb_sampler_set_lobe(x->s, 0.5, alpha) == SB_OK);
    double a;
    CHECK(sb_sampler_lobe(x->s, &a) == 0.5 && a == (float)alpha);
    return 1;
}

/* sb_sample's directions against sb_pdf (chi2, 40 000 draws per view) and
 * the pdf integrating to the share of draws that succeed. */
static double pdf_of(const fixture_t *x, const double wo[3], const double wi[3]) { return sb_pdf(x->s, wo, wi); }

static void mixture_checks(sb_param_kind_t kind) {
    fixture_t x;
    if (lobe_fixture(kind, 0.15, &x)) {
        const double thetas[2] = {20, 60};
        for (int o = 0; o < 2; o++) {
            double wo[3], *mass = malloc(NT * NP * sizeof *mass), *obs = calloc(NT * NP, sizeof *obs), stat;
            sb_dir_from_angles(thetas[o] * SB_PI / 180, 0.7, wo);
            size_t n = 40000, ok = 0;
            unsigned long long rng = 99 + (unsigned long long)o;
            for (size_t t = 0; t < n; t++) {
                double u[2] = {sb_rand01(&rng), sb_rand01(&rng)}, wi[3], pdf;
                if (!sb_sample(x.s, wo, u, wi, &pdf, NULL)) continue;
                CHECK_REL(pdf, sb_pdf(x.s, wo, wi), 1e-12);
                obs[bin_of(wi)] += 1;
                ok++;
            }
            expected_mass(x.s, wo, (double)n, mass);
            int dof;
            double p = chi2_p(mass, obs, (double)n, &stat, &dof);
            double integral = hemi_integral(&x, wo, pdf_of, 600), rate = (double)ok / (double)n;
            double se = sqrt(rate * (1 - rate) / (double)n);
            fprintf(stderr, "%s theta_o %2.0f: chi2 p %.3g (dof %d); pdf integral %.5f, success rate %.5f +- %.5f\n",
                    sb_param_kind_name(kind), thetas[o], p, dof, integral, rate, se);
            CHECKF(p > 1e-3, "%s theta_o %g: chi2 p %g", sb_param_kind_name(kind), thetas[o], p);
            CHECKF(fabs(integral - rate) < 4 * se + 2e-3, "%s theta_o %g: pdf integrates to %g, %g succeed",
                   sb_param_kind_name(kind), thetas[o], integral, rate);
            free(mass);
            free(obs);
        }
    }
    fixture_free(&x);
}

SB_TEST(mixture_iso) { mixture_checks(SB_PARAM_ISO); }
SB_TEST(mixture_io) { mixture_checks(SB_PARAM_IO); }
SB_TEST(mixture_vh) { mixture_checks(SB_PARAM_VH); }

/* Without the lobe (s_l = 0) the draws are those of the cosine and
 * factored mixture alone: the same wi and pdf as a sampler never given a
 * lobe, bit for bit. */
SB_TEST(off_is_unchanged) {
    fixture_t x, y;
    if (fixture_sampler("blinn-phong:n=50", SB_PARAM_HD, 8, 2, &x) &&
        fixture_sampler("blinn-phong:n=50", SB_PARAM_HD, 8, 2, &y)) {
        CHECK(sb_sampler_set_cosine_share(x.s, 0.2) == SB_OK && sb_sampler_set_cosine_share(y.s, 0.2) == SB_OK);
        CHECK(sb_sampler_set_lobe(y.s, 0.3, 0.2) == SB_OK && sb_sampler_set_lobe(y.s, 0, 0) == SB_OK);
        unsigned long long rng = 5;
        double wo[3];
        sb_dir_from_angles(0.8, 0.3, wo);
        size_t same = 0, n = 2000;
        for (size_t t = 0; t < n; t++) {
            double u[2] = {sb_rand01(&rng), sb_rand01(&rng)}, a[3], b[3], pa, pb;
            int ra = sb_sample(x.s, wo, u, a, &pa, NULL), rb = sb_sample(y.s, wo, u, b, &pb, NULL);
            same += ra == rb && a[0] == b[0] && a[1] == b[1] && a[2] == b[2] && pa == pb;
        }
        CHECKF(same == n, "%zu of %zu draws the same", same, n);
    }
    fixture_free(&x);
    fixture_free(&y);
}

/* The variance of one-sample estimates of int Y(f_r) cos of the source
 * at wo (s == NULL: cosine sampling). */
static double variance(const fixture_t *x, const sb_sampler_t *s, const double wo[3], size_t n) {
    unsigned long long rng = 31337;
    double s1 = 0, s2 = 0;
    for (size_t i = 0; i < n; i++) {
        double u[2] = {sb_rand01(&rng), sb_rand01(&rng)}, wi[3], pdf = 0, rgb[3], v = 0;
        if (s) {
            if (!sb_sample(s, wo, u, wi, &pdf, NULL)) pdf = 0;
        } else {
            double r = sqrt(u[0]), phi = 2 * SB_PI * u[1];
            wi[0] = r * cos(phi), wi[1] = r * sin(phi), wi[2] = sqrt(fmax(1 - u[0], 0)), pdf = wi[2] / SB_PI;
        }
        if (pdf > 0 && sb_source_eval(x->src, wi, wo, rgb))
            v = (0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]) * wi[2] / pdf;
        s1 += v, s2 += v * v;
    }
    return s2 / (double)n - (s1 / (double)n) * (s1 / (double)n);
}

/* GGX alpha 0.1 over a white diffuse base, on hd at 8 cells: without the
 * lobe the choice fell back to cosine sampling; now it takes a lobe
 * near alpha 0.1 and beats cosine at every elevation with new draws. */
SB_TEST(choice_takes_the_lobe) {
    fixture_t x;
    if (fixture_sampler("microfacet:roughness=0.316", SB_PARAM_HD, 8, 2, &x)) {
        sb_sampler_choice_t ch;
        CHECK(sb_sampler_choose_share(NULL, x.s, x.src, 2048, &ch) == SB_OK);
        double a;
        fprintf(stderr, "share %.3f, lobe %.3f alpha %.3f; ratios %.3g %.3g %.3g %.3g\n", ch.share, ch.lobe_share,
                ch.lobe_alpha, ch.ratio[0], ch.ratio[1], ch.ratio[2], ch.ratio[3]);
        CHECKF(ch.lobe_share > 0 && ch.lobe_alpha >= 0.06 && ch.lobe_alpha <= 0.18, "lobe %g alpha %g", ch.lobe_share,
               ch.lobe_alpha);
        CHECK(sb_sampler_lobe(x.s, &a) == ch.lobe_share && a == ch.lobe_alpha);
        for (int e = 0; e < SB_SAMPLER_CHOICE_WO; e++) {
            double wo[3];
            sb_dir_from_angles(ch.theta_o_deg[e] * SB_PI / 180, 1.3, wo);
            double vc = variance(&x, NULL, wo, 20000), vs = variance(&x, x.s, wo, 20000);
            fprintf(stderr, "theta_o %2.0f: cosine / sampler %.3g (reported %.3g)\n", ch.theta_o_deg[e], vc / vs,
                    ch.ratio[e]);
            CHECKF(ch.ratio[e] >= 1.1 && vc > 2 * vs, "theta_o %g: ratio %g, measured %g", ch.theta_o_deg[e],
                   ch.ratio[e], vc / vs);
        }
    }
    fixture_free(&x);
}

SB_TEST(errors) {
    fixture_t x;
    if (fixture_sampler("blinn-phong:n=20", SB_PARAM_IO, 6, 1, &x)) {
        double a = 1;
        CHECK(sb_sampler_lobe(x.s, &a) == 0 && a == 0); /* none by default */
        CHECK(sb_sampler_set_lobe(NULL, 0.5, 0.1) == SB_ERR_ARG);
        CHECK(isnan(sb_sampler_lobe(NULL, &a)) && isnan(a));
        CHECK(sb_sampler_set_lobe(x.s, -0.1, 0.1) == SB_ERR_ARG);
        CHECK(sb_sampler_set_lobe(x.s, NAN, 0.1) == SB_ERR_ARG);
        CHECK(sb_sampler_set_lobe(x.s, 0.5, 0.001) == SB_ERR_ARG);
        CHECK(sb_sampler_set_lobe(x.s, 0.5, 1.5) == SB_ERR_ARG);
        CHECK(sb_sampler_set_lobe(x.s, 0.5, NAN) == SB_ERR_ARG);
        CHECK(sb_sampler_set_cosine_share(x.s, 0.5) == SB_OK);
        CHECK(sb_sampler_set_lobe(x.s, 0.6, 0.1) == SB_ERR_ARG); /* s + s_l > 1 */
        CHECK(sb_sampler_set_lobe(x.s, 0.5, 0.1) == SB_OK);
        CHECK(sb_sampler_set_cosine_share(x.s, 0.7) == SB_ERR_ARG); /* likewise */
        CHECK(sb_sampler_cosine_share(x.s) == 0.5 && sb_sampler_lobe(x.s, &a) == 0.5 && a == (float)0.1);
    }
    fixture_free(&x);
}
