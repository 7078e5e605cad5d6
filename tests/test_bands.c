/* Where the error is (estimate.h: band, min_rel, map): the estimator's
 * band errors against a brute-force evaluation written here (plain Monte
 * Carlo drawn uniformly inside each band by its own definition, the
 * source's values, the written factors through sb_factors_eval), and the
 * band membership against pairs whose bands are known. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../bench/band_draw.h"
#include "harness.h"
#include "sepbrdf/sepbrdf.h"

#define PI 3.14159265358979323846

/* A pair drawn uniformly (solid angle) inside band b, written out from the
 * band's definition (bench/band_draw.h); 0 when the draw falls outside the
 * hemisphere. */
static int draw_in_band(int b, unsigned long long *rng, double wi[3], double wo[3]) {
    double u[4];
    for (int k = 0; k < 4; k++)
        u[k] = sb_rand01(rng);
    return band_draw(b, u, wi, wo);
}

/* Brute force: relative L2 error of f cos theta_i (all channels) over band
 * b from n draws, and its standard error (delta method). */
static double brute_band(const sb_job_t *job, int b, size_t J, size_t n, double *se) {
    const sb_source_t *src = sb_job_source(job);
    unsigned long long rng = 777 + (unsigned long long)b;
    band_sums_t s = {0};
    for (size_t i = 0; i < n; i++) {
        double wi[3], wo[3], f[3] = {0, 0, 0}, rec[3] = {0, 0, 0};
        if (draw_in_band(b, &rng, wi, wo) && sb_source_eval(src, wi, wo, f) &&
            !sb_factors_eval(sb_job_factors(job), sb_job_param(job), sb_job_form(job), J, wi, wo, rec))
            rec[0] = rec[1] = rec[2] = 0;
        band_add(&s, f, rec, wi[2]);
    }
    return band_ratio(&s, se);
}

/* A job of J terms at R = 16 on layout param and form (NULL on failure). */
static sb_job_t *job_at_16(const char *spec, const char *param, const char *form, size_t J) {
    sb_job_opts_t o = {0};
    o.source = spec;
    o.param = param;
    o.form = form;
    o.res = 16;
    o.terms = J;
    sb_job_t *job = NULL;
    CHECK(sb_job_run(NULL, &o, &job) == SB_OK);
    return job;
}

static void check_bands(const char *spec, const char *param, const char *form, size_t J) {
    sb_job_t *job = job_at_16(spec, param, form, J);
    if (!job) return;
    const sb_estimate_t *e = sb_job_estimate(job);
    for (int b = 0; b < SB_BAND_COUNT_; b++) {
        double se, ref = brute_band(job, b, J, b == SB_BAND_TI89 ? 400000 : 100000, &se);
        double est = e->band[J - 1][b][3], ese = e->band_se[J - 1][b][3];
        printf("  %s %s %s J=%zu %-10s estimator %.4e +- %.1e, brute force %.4e +- %.1e\n", spec ? spec : "default",
               param, form, J, sb_band_name(b), est, ese, ref, se);
        CHECKF(fabs(est - ref) <= 3 * hypot(ese, se) + 0.05 * ref, "%s: estimator %.4g, brute force %.4g",
               sb_band_name(b), est, ref);
    }
    /* the worst band is the largest; the most negative value is a value */
    int w = sb_estimate_worst_band(e, J);
    CHECK(w >= 0);
    for (int b = 0; w >= 0 && b < SB_BAND_COUNT_; b++)
        CHECK(e->band[J - 1][b][3] <= e->band[J - 1][w][3]);
    CHECK(e->min_rel[J - 1][3] <= 0 && e->min_rel[J - 1][3] >= -e->overshoot[J - 1] - 1e-12);
    sb_job_destroy(job);
}

/* cos form: the division by cos theta_i makes the grazing bands differ
 * from the headline by orders of magnitude; iso f on the default. */
SB_TEST(bands_agree_with_brute_force_cos) { check_bands("cook-torrance:roughness=0.3", "hd", "cos", 2); }
SB_TEST(bands_agree_with_brute_force_iso) { check_bands(NULL, "iso", "f", 2); }

/* The reported theta_i bands b0..theta_i > 89 degrees of spec (iso, f,
 * R = 16, J = 2) against 200 000 pairs with wi uniform in the band and wo
 * from a mixture aimed at the mirror peak (bench/band_draw.h band_mix_draw,
 * GGX alpha a), weighted back to the uniform measure: no estimator code.
 * Within 10 % or two standard errors.  With theta_h: the share of the
 * band's f^2 cos^2 theta_i at theta_h < 1 degree, and the uniform
 * probability of landing there (*share, *p_uniform for b = theta_i > 89). */
static void mirror_peak_check(const char *spec, double a, int b0, double *share, double *p_uniform) {
    sb_job_t *job = job_at_16(spec, "iso", "f", 2);
    if (!job) return;
    const sb_estimate_t *e = sb_job_estimate(job);
    for (int b = b0; b <= SB_BAND_TI89; b++) {
        unsigned long long rng = 4242 + (unsigned long long)b;
        band_sums_t sums = {0};
        double peak = 0, hits = 0;
        for (size_t i = 0; i < 200000; i++) {
            double u[6], wi[3], wo[3], f[3] = {0, 0, 0}, rec[3] = {0, 0, 0};
            for (int k = 0; k < 6; k++)
                u[k] = sb_rand01(&rng);
            band_draw(b, u, wi, wo); /* wi uniform in the band; wo drawn again */
            double w = band_mix_draw(a, wi, u + 3, wo);
            if (w > 0 && sb_source_eval(sb_job_source(job), wi, wo, f) &&
                !sb_factors_eval(sb_job_factors(job), sb_job_param(job), sb_job_form(job), 2, wi, wo, rec))
                rec[0] = rec[1] = rec[2] = 0;
            double sd = sums.sd, h[3] = {wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]};
            band_add_w(&sums, f, rec, wi[2], w);
            if (w > 0 && h[2] > cos(PI / 180) * sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]))
                peak += sums.sd - sd, hits += w;
        }
        double se, ref = band_ratio(&sums, &se), est = e->band[1][b][3], ese = e->band_se[1][b][3];
        printf("  %s iso J=2 %s: reported %.4e +- %.1e, mixture draw %.4e +- %.1e; theta_h < 1 deg: %.3f of the "
               "value, uniform probability %.2g\n",
               spec, sb_band_name(b), est, ese, ref, se, peak / sums.sd, hits / 200000);
        CHECKF(fabs(est - ref) <= 0.1 * ref || fabs(est - ref) <= 2 * hypot(ese, se), "%s: reported %.4g, drawn %.4g",
               sb_band_name(b), est, ref);
        if (b == SB_BAND_TI89) *share = peak / sums.sd, *p_uniform = hits / 200000;
    }
    sb_job_destroy(job);
}

/* The grazing bands of a sharp lobe: GGX 0.3 on iso at R = 16, whose
 * error at theta_i > 89 degrees sits in a few pairs near the mirror
 * direction past the last theta_d texel centre (88.5 degrees here; f
 * keeps rising there, which the lookup follows linearly since the eighth
 * pass), which a uniform draw meets too rarely to check the report
 * against (docs/bands.md, seventh pass). */
SB_TEST(grazing_mirror_peak_reported) {
    double share = 0, p = 0;
    mirror_peak_check("cook-torrance:roughness=0.3", 0.3, SB_BAND_TI80, &share, &p);
}

/* Sharper: GGX alpha 0.01 (cook-torrance roughness 0.1), every theta_i
 * band, wo about the lobe's own alpha.  Nearly all of theta_i > 89
 * degrees' value lies within 1 degree of the mirror half vector, where a
 * uniform pair lands with probability below 1e-4: a uniform check of
 * 60 000 pairs misses it and reads the rest (docs/bands.md, ninth pass),
 * while the report agrees with the draw that meets it. */
SB_TEST(sharp_lobe_grazing_reported) {
    double share = 0, p = 1;
    mirror_peak_check("cook-torrance:roughness=0.1", 0.01, SB_BAND_TI60, &share, &p);
    CHECKF(share > 0.9 && p < 1e-4, "theta_h < 1 deg: %.3g of the value, uniform probability %.2g", share, p);
}

/* Pairs whose bands are known by construction. */
SB_TEST(band_mask) {
    double s = sin(85 * PI / 180), c = cos(85 * PI / 180);
    double wi[3] = {s, 0, c}, mirror[3] = {-s, 0, c}, up[3] = {0, 0, 1};
    unsigned m = sb_band_mask(wi, mirror);
    CHECK(m ==
          (1u << SB_BAND_TI60 | 1u << SB_BAND_TI80 | 1u << SB_BAND_TO60 | 1u << SB_BAND_TO80 | 1u << SB_BAND_SPECULAR));
    CHECK(sb_band_mask(wi, wi) ==
          (1u << SB_BAND_TI60 | 1u << SB_BAND_TI80 | 1u << SB_BAND_TO60 | 1u << SB_BAND_TO80 | 1u << SB_BAND_RETRO));
    CHECK(sb_band_mask(up, up) == (1u << SB_BAND_SPECULAR | 1u << SB_BAND_RETRO));
    double g[3] = {sin(89.5 * PI / 180), 0, cos(89.5 * PI / 180)};
    CHECK(sb_band_mask(g, up) == (1u << SB_BAND_TI60 | 1u << SB_BAND_TI80 | 1u << SB_BAND_TI89));
    CHECK(sb_band_mask(NULL, up) == 0);
    for (int b = 0; b < SB_BAND_COUNT_; b++)
        CHECK(sb_band_name(b) != NULL);
    CHECK(sb_band_name(SB_BAND_COUNT_) == NULL && sb_band_name(-1) == NULL);
}

/* Selection (issue 33): auto ranks the candidates keeping the band bounds
 * first, even where one breaking them is lower in both bands.  At J = 1
 * the lowest screened headline breaks them, another keeps them; the kept fit keeps them at
 * the requested settings, and its report says so. */
static void auto_keeps_band_bounds_of(const char *source, size_t res) {
    sb_job_opts_t o = {0};
    o.source = source;
    o.res = res;
    o.terms = 1;
    sb_job_t *job = NULL;
    CHECK(sb_job_run(NULL, &o, &job) == SB_OK);
    if (!job) return;
    const sb_job_candidate_t *c, *kept = NULL, *lowest = NULL;
    int any = 0;
    for (size_t i = 0; (c = sb_job_candidate(job, i)) != NULL; i++) {
        if (!c->ok) continue;
        any |= c->bands_ok == 1;
        if (c->kept) kept = c;
        if (!lowest || c->res > lowest->res || (c->res == lowest->res && c->error < lowest->error)) lowest = c;
    }
    CHECK(any && kept && lowest);
    if (kept && lowest) {
        printf("  %s: kept %s %s (screened %.4f, bands %d); lowest screened %s %s %.4f (bands %d)\n", source,
               sb_param_kind_name(kept->kind), sb_form_name(kept->form), kept->error, kept->bands_ok,
               sb_param_kind_name(lowest->kind), sb_form_name(lowest->form), lowest->error, lowest->bands_ok);
        CHECK(kept->bands_ok == 1);
        CHECK(lowest->bands_ok == 0 && lowest != kept); /* the rule decided here */
        CHECK(sb_estimate_bands_bounded(sb_job_estimate(job), 1) == 1);
    }
    sb_job_destroy(job);
}

SB_TEST(auto_keeps_band_bounds) {
    auto_keeps_band_bounds_of("cook-torrance:roughness=0.3", 16);
    /* RGL paper at J = 1: io cos breaks theta_i > 80 degrees, though lower
     * in both bands than vndf, which keeps them: the bounds are not traded */
    auto_keeps_band_bounds_of(SB_MEASURED_DIR "/rgl_paper_white_rgb.bsdf", 16);
}

/* Scene fits degrade gracefully (issue 33): on a layout with a partial
 * domain (and for ranges on io) the cells the scene never touches keep a floor of the mass, so
 * over the whole domain the fit is at most 2x the unweighted one, while
 * inside the scene it is as good as the fit that leaves them out
 * (floor=0).  A term that spoils the whole domain is dropped (iso at J = 4:
 * the fourth term, fitted where the weights barely see, took the whole
 * domain from 0.69 % to 22 %); the report gives its weight 0. */
static void scene_floor_outside_on(const char *param, size_t J) {
    static const char *const scenes[2] = {"view=0..40;light=0..60", "view=0..40;light=0..60;floor=0"};
    sb_job_opts_t o = {0};
    o.source = "cook-torrance:roughness=0.3";
    o.param = param;
    o.res = 16;
    o.terms = J;
    sb_job_t *plain = NULL, *fit[2] = {NULL, NULL};
    CHECK(sb_job_run(NULL, &o, &plain) == SB_OK);
    for (int k = 0; k < 2; k++) {
        o.scene = scenes[k];
        CHECK(sb_job_run(NULL, &o, &fit[k]) == SB_OK);
    }
    if (plain && fit[0] && fit[1]) {
        const sb_estimate_t *in[2] = {sb_job_estimate(fit[0]), sb_job_estimate(fit[1])};
        const sb_estimate_t *all[2] = {sb_job_domain_estimate(fit[0]), sb_job_domain_estimate(fit[1])};
        double whole_plain = sb_estimate_headline(sb_job_estimate(plain), J);
        printf("  %s J = %zu: inside %.4e (floor=0: %.4e), whole domain %.4e (floor=0: %.4e, unweighted %.4e)\n", param,
               J, sb_estimate_headline(in[0], J), sb_estimate_headline(in[1], J), sb_estimate_headline(all[0], J),
               sb_estimate_headline(all[1], J), whole_plain);
        CHECK(sb_estimate_headline(in[0], J) <=
              1.02 * sb_estimate_headline(in[1], J) +
                  2 * hypot(in[0]->se[J - 1][SB_EST_FCOS][3], in[1]->se[J - 1][SB_EST_FCOS][3]));
        CHECK(sb_estimate_headline(all[0], J) <= 2 * whole_plain);
        CHECK(sb_estimate_headline(all[1], J) > 2 * whole_plain); /* what the floor mends */
    }
    sb_job_destroy(plain);
    sb_job_destroy(fit[0]);
    sb_job_destroy(fit[1]);
}

/* The scene fit of o with `scene` at J = 2 against the fit without it:
 * over the whole domain within 2x, inside the scene better than no fit. */
static void scene_within_2x_outside(sb_job_opts_t o, const char *scene) {
    sb_job_t *plain = NULL, *fit = NULL;
    CHECK(sb_job_run(NULL, &o, &plain) == SB_OK);
    o.scene = scene;
    CHECK(sb_job_run(NULL, &o, &fit) == SB_OK);
    if (plain && fit) {
        double whole_plain = sb_estimate_headline(sb_job_estimate(plain), 2);
        double inside = sb_estimate_headline(sb_job_estimate(fit), 2);
        double whole = sb_estimate_headline(sb_job_domain_estimate(fit), 2);
        printf("  %s: inside %.4g, whole domain %.4g (unweighted %.4g)\n", o.source, inside, whole, whole_plain);
        CHECK(whole <= 2 * whole_plain);
        CHECK(inside < 1);
    }
    sb_job_destroy(plain);
    sb_job_destroy(fit);
}

/* Lights (not separable on io, floor 0 there): GGX 0.1 at J = 2 is a poor
 * fit inside and the unweighted one is no better than nothing (100 %);
 * the scene fit's first term took the whole domain to 4.8x that, against
 * a gain of 3 % inside.  A term is measured against no term at all too,
 * so that one is dropped: the whole domain within 2x the unweighted fit,
 * and inside still below 1 (better than no fit). */
SB_TEST(scene_lights_outside) {
    sb_job_opts_t o = {.source = "cook-torrance:roughness=0.1", .param = "io", .res = 16, .terms = 2};
    scene_within_2x_outside(o, "lights=45,45/30,150/60,270");
}

/* A scene fit far worse than the unweighted one over the whole domain is
 * replaced (job_scene_guard.c; docs/bands.md, tenth pass): Phong n = 100
 * on rv (the floor changes nothing there) was 10x, RGL orange on vndf (no
 * floor: the slices outside the scene unconstrained) 2 200x. */
SB_TEST(scene_outside_unweighted) {
    sb_job_opts_t o = {.source = "phong:n=100", .res = 16, .terms = 2};
    scene_within_2x_outside(o, "view=0..40;light=0..60");
    o.source = SB_MEASURED_DIR "/rgl_chm_orange_rgb.bsdf";
    scene_within_2x_outside(o, "view=0..40;light=0..60");
}

/* Where the guard replaces a scene fit, the fit kept is better inside the
 * scene than the unweighted one and within 2x of it over the whole domain
 * (job_scene_guard.c's walk of floors; docs/scene.md, "Where the guard
 * fires").  RGL aurora on vndf, J = 4: the scene fit 84x outside; floors
 * 1 and 10 were 1.99x and 4.3 % inside, so the unweighted fit was kept
 * (3.3 % inside, as the unweighted fit itself); floor 2 is 2.3 % / 1.6x. */
SB_TEST(scene_fallback_keeps_inside) {
    sb_job_opts_t o = {.source = SB_MEASURED_DIR "/rgl_aurora_white_rgb.bsdf", .terms = 4};
    sb_job_t *plain = NULL, *fit = NULL;
    CHECK(sb_job_run(NULL, &o, &plain) == SB_OK);
    o.scene = "view=0..40;light=0..60";
    CHECK(sb_job_run(NULL, &o, &fit) == SB_OK);
    sb_estimate_t *e = malloc(sizeof *e);
    CHECK(e != NULL);
    if (plain && fit && e) {
        CHECK(sb_scene_estimate(NULL, sb_job_scene(fit), sb_job_source(plain), sb_job_factors(plain),
                                sb_job_param(plain), sb_job_form(plain), NULL, e) == SB_OK);
        const sb_estimate_t *in = sb_job_estimate(fit);
        double inside = sb_estimate_headline(in, 4), se = in->se[3][SB_EST_FCOS][SB_CH_ALL];
        double plain_in = sb_estimate_headline(e, 4), plain_se = e->se[3][SB_EST_FCOS][SB_CH_ALL];
        double whole = sb_estimate_headline(sb_job_domain_estimate(fit), 4);
        double whole_plain = sb_estimate_headline(sb_job_estimate(plain), 4);
        printf("  inside %.4g +- %.2g (unweighted %.4g +- %.2g), whole domain %.4g (unweighted %.4g)\n", inside, se,
               plain_in, plain_se, whole, whole_plain);
        CHECK(inside + 2 * hypot(se, plain_se) < plain_in);
        CHECK(whole <= 2 * whole_plain);
    }
    free(e);
    sb_job_destroy(plain);
    sb_job_destroy(fit);
}

/* io: view and light ranges are rows x columns there, held exactly by the
 * fit's separable weights, so the floor is on by default too. */
SB_TEST(scene_floor_outside) {
    scene_floor_outside_on("iso", 4);
    scene_floor_outside_on("io", 2);
}

/* vh's zero fill (SB_CAP_LIGHT_EDGE) continues f cos theta_i beyond the
 * light's horizon by its value at the edge (sample/edge.h).  Classic Phong
 * keeps ks (r.v)^n there: against zeros (--zero-fill) the grazing band
 * theta_i > 89 degrees, measured by brute force, is lower; GGX falls to 0
 * at the horizon, so its fit is the zero-filled one up to rounding. */
SB_TEST(light_edge_continued) {
    static const char *const src[2] = {"phong:n=100", "cook-torrance:roughness=0.3"};
    for (int s = 0; s < 2; s++) {
        sb_job_opts_t o = {0};
        o.source = src[s];
        o.param = "vh";
        o.form = "cos";
        o.res = 16;
        o.terms = 4;
        sb_job_t *job[2] = {NULL, NULL};
        double band[2] = {0, 0}, se[2] = {0, 0}, head[2] = {0, 0};
        for (int z = 0; z < 2; z++) {
            o.zero_fill = z;
            CHECK(sb_job_run(NULL, &o, &job[z]) == SB_OK);
            if (!job[z]) continue;
            band[z] = brute_band(job[z], SB_BAND_TI89, 4, 100000, &se[z]);
            head[z] = sb_estimate_headline(sb_job_estimate(job[z]), 4);
        }
        printf("  %s: theta_i > 89 %.4f +- %.4f (zeros %.4f +- %.4f), headline %.4e (zeros %.4e)\n", src[s], band[0],
               se[0], band[1], se[1], head[0], head[1]);
        if (s == 0) CHECK(band[0] + 2 * hypot(se[0], se[1]) < band[1]);
        if (s == 1) CHECK(fabs(head[0] - head[1]) <= 0.03 * head[1]);
        sb_job_destroy(job[0]);
        sb_job_destroy(job[1]);
    }
}

/* No negative reconstruction (issue 33): by default the reconstruction is
 * max(0, sum), the snippet's SB_CLAMP 1, so the most negative value
 * (min_rel) is 0 and no pair drawn here evaluates below 0; the plain
 * truncated SVD (plain_terms: spec plain=1, SB_CLAMP 0) keeps its negative
 * lobes, and min_rel says so. */
SB_TEST(no_negative_unless_plain) {
    for (int plain = 0; plain < 2; plain++) {
        sb_job_opts_t o = {0};
        o.param = "iso";
        o.res = 16;
        o.terms = 4;
        o.plain_terms = plain;
        sb_job_t *job = NULL;
        CHECK(sb_job_run(NULL, &o, &job) == SB_OK);
        if (!job) continue;
        const sb_estimate_t *e = sb_job_estimate(job);
        const sb_param_t *p = sb_job_param(job);
        char *glsl = sb_glsl_snippet(p, sb_job_form(job), 4, NULL);
        CHECK(glsl && strstr(glsl, plain ? "#define SB_CLAMP 0" : "#define SB_CLAMP 1"));
        free(glsl);
        CHECK((strstr(sb_param_spec(p), "plain=1") != NULL) == plain);
        unsigned long long rng = 99;
        double lowest = 0;
        for (int i = 0; i < 100000; i++) {
            double wi[3], wo[3], rec[3];
            draw_in_band(SB_BAND_TI80, &rng, wi, wo);
            if (sb_factors_eval(sb_job_factors(job), p, sb_job_form(job), 4, wi, wo, rec))
                for (int c = 0; c < 3; c++)
                    lowest = fmin(lowest, rec[c]);
        }
        printf("  plain %d: min_rel %.4g, lowest value drawn %.4g\n", plain, e->min_rel[3][3], lowest);
        CHECK(plain ? e->min_rel[3][3] < 0 && lowest < 0 : e->min_rel[3][3] == 0 && lowest == 0);
        sb_job_destroy(job);
    }
}

/* Classic Phong n = 100 (issue 33): auto keeps rv (param_rv.c) at J = 4
 * and the band bounds hold, by the report and by brute force: theta_i >
 * 80 degrees at most max(3 x headline, 1 %), > 89 at most max(10 x
 * headline, 5 %) (vh, kept before: 22 % and 85 % against a 2.8 %
 * headline at R = 32). */
SB_TEST(phong_keeps_band_bounds) {
    sb_job_opts_t o = {0};
    o.source = "phong:n=100";
    o.res = 32;
    o.terms = 4;
    sb_job_t *job = NULL;
    CHECK(sb_job_run(NULL, &o, &job) == SB_OK);
    if (!job) return;
    CHECK(strcmp(sb_param_kind_name(sb_param_kind(sb_job_param(job))), "rv") == 0);
    const sb_estimate_t *e = sb_job_estimate(job);
    double h = sb_estimate_headline(e, 4), se80, se89;
    double b80 = brute_band(job, SB_BAND_TI80, 4, 200000, &se80), b89 = brute_band(job, SB_BAND_TI89, 4, 200000, &se89);
    printf("  headline %.4g; theta_i > 80: %.4g +- %.2g (report %.4g), > 89: %.4g +- %.2g (report %.4g)\n", h, b80,
           se80, e->band[3][SB_BAND_TI80][3], b89, se89, e->band[3][SB_BAND_TI89][3]);
    CHECK(sb_estimate_bands_bounded(e, 4) == 1);
    CHECK(b80 <= fmax(3 * h, 0.01));
    CHECK(b89 <= fmax(10 * h, 0.05));
    sb_job_destroy(job);
}

/* RGL paper on vndf at J = 4 (issue 33): the plain fit breaks theta_i > 80
 * degrees (9.3 % against 3 x 1.8 %): its rows are the view's slices, the
 * light's band runs across the columns, and no separable weight reaches
 * it.  The fit weighted cell by cell toward the light's band
 * (job_bandfit.c) keeps the bounds, with a lower band error than the plain
 * truncated SVD (--plain-terms, which is never refitted) and a headline at
 * most 1.5x its. */
SB_TEST(vndf_band_weighted) {
    sb_job_opts_t o = {0};
    o.source = SB_MEASURED_DIR "/rgl_paper_white_rgb.bsdf";
    o.param = "vndf";
    o.form = "cos";
    o.terms = 4;
    sb_job_t *fit = NULL, *plain = NULL;
    CHECK(sb_job_run(NULL, &o, &fit) == SB_OK);
    o.plain_terms = 1;
    CHECK(sb_job_run(NULL, &o, &plain) == SB_OK);
    if (fit && plain) {
        const sb_estimate_t *e = sb_job_estimate(fit), *p = sb_job_estimate(plain);
        double b = e->band[3][SB_BAND_TI80][3], bp = p->band[3][SB_BAND_TI80][3];
        printf("  weighted: headline %.4f, theta_i > 80: %.4f; plain: %.4f, %.4f\n", sb_estimate_headline(e, 4), b,
               sb_estimate_headline(p, 4), bp);
        CHECK(sb_estimate_bands_bounded(p, 4) == 0); /* what the weighted fit mends */
        CHECK(sb_estimate_bands_bounded(e, 4) == 1);
        CHECK(b + 2 * hypot(e->band_se[3][SB_BAND_TI80][3], p->band_se[3][SB_BAND_TI80][3]) < bp);
        CHECK(sb_estimate_headline(e, 4) <= 1.5 * sb_estimate_headline(p, 4));
    }
    sb_job_destroy(fit);
    sb_job_destroy(plain);
}

/* --max-error on RGL paper (issue 33): auto keeps a fit that meets it and
 * keeps the band bounds (by the report and by brute force), with fewer
 * terms than the first plain prefix of vndf (the layout on the file's own
 * slices) that does.  Before, vndf (8 rows) was left out for the 32 terms
 * allowed, and vh cos at J = 5 was kept: 2.2 %, theta_i > 80 degrees 16 %
 * against a bound of 6.6 %. */
SB_TEST(max_error_keeps_band_bounds) {
    const double max_error = 0.03;
    sb_job_opts_t o = {0};
    o.source = SB_MEASURED_DIR "/rgl_paper_white_rgb.bsdf";
    o.max_error = max_error;
    sb_job_t *job = NULL, *plain = NULL;
    CHECK(sb_job_run(NULL, &o, &job) == SB_OK);
    o.max_error = 0;
    o.param = "vndf";
    o.form = "cos";
    o.terms = 8;
    o.plain_terms = 1;
    CHECK(sb_job_run(NULL, &o, &plain) == SB_OK);
    if (!job || !plain) goto done;
    const sb_estimate_t *e = sb_job_estimate(job), *p = sb_job_estimate(plain);
    size_t J = sb_factors_terms(sb_job_factors(job)), first = 0;
    for (size_t k = 8; k >= 1; k--)
        if (sb_estimate_headline(p, k) <= max_error && sb_estimate_bands_bounded(p, k) == 1) first = k;
    double h = sb_estimate_headline(e, J), se80, se89;
    double b80 = brute_band(job, SB_BAND_TI80, J, 100000, &se80), b89 = brute_band(job, SB_BAND_TI89, J, 100000, &se89);
    printf("  kept %s J = %zu: headline %.4g; theta_i > 80: %.4g +- %.2g (report %.4g), > 89: %.4g +- %.2g (report "
           "%.4g); the first plain vndf prefix meeting both: J = %zu\n",
           sb_param_spec(sb_job_param(job)), J, h, b80, se80, e->band[J - 1][SB_BAND_TI80][3], b89, se89,
           e->band[J - 1][SB_BAND_TI89][3], first);
    CHECK(h <= max_error);
    CHECK(sb_estimate_bands_bounded(e, J) == 1);
    CHECK(b80 - 2 * se80 <= fmax(3 * h, 0.01));
    CHECK(b89 - 2 * se89 <= fmax(10 * h, 0.05));
    CHECK(first > 0 && J < first);
done:
    sb_job_destroy(job);
    sb_job_destroy(plain);
}

/* Beyond the last theta_d texel centre of iso (88.5 degrees at R = 16) the
 * reconstruction follows the line through the last two centres
 * (SB_EDGE_LINEAR; the snippet's SB_EDGE_H_S): GGX 0.3's grazing mirror
 * peak keeps rising there, which the edge texel's value (sb_factors_lookup,
 * CLAMP_TO_EDGE) held flat.  Mirror pairs theta_i = theta_o = theta_d, the
 * source against sb_factors_eval and against the clamped sum. */
SB_TEST(horizon_follows_source) {
    sb_job_t *job = job_at_16("cook-torrance:roughness=0.3", "iso", "f", 2);
    if (!job) return;
    const sb_factors_t *f = sb_job_factors(job);
    const sb_param_t *p = sb_job_param(job);
    static const double deg[] = {88.5, 89.0, 89.5, 89.9};
    for (size_t k = 0; k < sizeof deg / sizeof deg[0]; k++) {
        double t = deg[k] * PI / 180, wi[3] = {sin(t), 0, cos(t)}, wo[3] = {-sin(t), 0, cos(t)};
        double src[3] = {0, 0, 0}, rec[3] = {0, 0, 0}, sg[2], sh[2], flat = 0;
        CHECK(sb_source_eval(sb_job_source(job), wi, wo, src) && sb_factors_eval(f, p, SB_FORM_F, 2, wi, wo, rec));
        CHECK(sb_param_coords(p, wi, wo, sg, sh));
        for (size_t j = 0; j < 2; j++)
            flat += sb_factors_lookup(f, p, SB_SIDE_G, j, 1, sg) * sb_factors_lookup(f, p, SB_SIDE_H, j, 1, sh);
        double e = fabs(rec[1] - src[1]) / src[1], e_flat = fabs(fmax(flat, 0) - src[1]) / src[1];
        printf("  theta_d %.1f: f %.4g, reconstruction %.4g (rel %.3g), clamped lookup %.4g (rel %.3g)\n", deg[k],
               src[1], rec[1], e, flat, e_flat);
        if (k == 0) CHECKF(e < 0.01, "at the last texel centre: rel %.3g", e); /* the fit's own value */
        if (k > 0) CHECKF(e < 0.1 && e < 0.5 * e_flat, "theta_d %.1f: rel %.3g, clamped %.3g", deg[k], e, e_flat);
    }
    sb_job_destroy(job);
}

/* The specular and retro bands of the kept fit (J = 4, R = 32, auto) as
 * reported, against the brute force above (400 000 pairs drawn uniformly
 * in the band): within 10 % or two combined standard errors (issue 33's
 * agreement).  The estimate's own pairs read them low where their sums are
 * heavy-tailed (the default gold at seed 3, specular: 5.19e-4 +- 3.7e-5
 * against 7.11e-4; the RGL aurora, retro: 2.71e-2 +- 1.0e-3 against
 * 3.33e-2); the pairs drawn inside the cones (job_bandpairs.c) do not. */
static void cone_band_agrees(const char *spec, unsigned long long seed, int b) {
    sb_job_opts_t o = {.source = spec, .terms = 4, .seed = seed};
    sb_job_t *job = NULL;
    CHECK(sb_job_run(NULL, &o, &job) == SB_OK);
    if (!job) return;
    const sb_estimate_t *e = sb_job_estimate(job);
    double se, ref = brute_band(job, b, 4, 400000, &se), est = e->band[3][b][3], ese = e->band_se[3][b][3];
    printf("  %s seed %llu %s: reported %.4e +- %.1e, brute force %.4e +- %.1e\n", spec ? spec : "default", seed,
           sb_band_name(b), est, ese, ref, se);
    CHECKF(fabs(est - ref) <= fmax(0.1 * ref, 2 * hypot(ese, se)), "%s: reported %.4g, brute force %.4g",
           sb_band_name(b), est, ref);
    sb_job_destroy(job);
}

SB_TEST(cone_bands_drawn_in_their_cones) {
    cone_band_agrees(NULL, 3, SB_BAND_SPECULAR);
    cone_band_agrees(SB_MEASURED_DIR "/rgl_aurora_white_rgb.bsdf", 1, SB_BAND_RETRO);
}
