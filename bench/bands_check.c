/* sepbrdf_bench_bands: the band errors of a written output set measured
 * without the library's estimator (issue 33), for bench/bands.py --check:
 * plain Monte Carlo with pairs drawn uniformly in solid angle inside each
 * band by the band's own definition (docs/bands.md), the source's values,
 * the textures read back from the folder's EXR files and evaluated as the
 * snippet evaluates them (sb_factors_eval, bilinear lookups).
 *
 *   sepbrdf_bench_bands SOURCE DIR J [N [M]]
 *
 * SOURCE: a model spec or a measured file; DIR: `sepbrdf factor -o DIR`;
 * J: the terms evaluated; N: pairs per band (default 1000000).  Prints one
 * line per band, "name error standard_error", the headline ("all") first:
 * the relative L2 error of f cos theta_i over the band, all channels.
 * With M, then the library's estimator on the same files grown to M pairs
 * ("estimator name error standard_error").  Environment: SB_BANDS_ONLY=name
 * measures that band alone, SB_BANDS_SEED=k draws another sequence,
 * SB_BANDS_MIX=a draws wo of "all" and the theta_i bands from a mixture instead (a
 * third uniform over the hemisphere, a third each reflected about a half
 * vector of a GGX distribution of roughness a and 3a), each pair weighted
 * by the uniform density over the mixture's: still no estimator, but the
 * mirror peaks where a sharp lobe's error sits (GGX 0.1 and 0.3 at grazing
 * incidence, docs/bands.md) drawn often enough for their band to come out
 * with a small standard error; SB_BANDS_SUMS=1 appends to each band's line
 * the sum of the squared errors, the sum of the squared values and the
 * pairs drawn, so that draws can be pooled exactly (bench/bands.py --seeds);
 * SB_BANDS_NEG=1 adds per band a line "negative name v": the most negative
 * reconstructed channel where the source's is positive, over the largest
 * |f| drawn in the band (0: none; bench/issue33.py); SB_BANDS_SCENE=V0,V1,L0,L1
 * restricts every band to a ranges scene (--scene 'view=V0..V1;light=L0..L1',
 * degrees): pairs with theta_o or theta_i outside add zeros, so each ratio
 * is that over the band within the scene (issue 33, the scene's draw). */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "band_draw.h"
#include "sepbrdf/sepbrdf.h"

static double rnd(uint64_t *s) { /* splitmix64, 53 bits */
    uint64_t z = (*s += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return (double)((z ^ (z >> 31)) >> 11) * 0x1.0p-53;
}

static const char *const names[] = {"all",        "theta_i_60", "theta_i_80", "theta_i_89", "theta_o_60",
                                    "theta_o_80", "theta_o_89", "specular",   "retro"};

int main(int argc, char **argv) {
    if (argc < 4) {
        fprintf(stderr, "usage: %s SOURCE DIR J [N]\n", argv[0]);
        return 2;
    }
    size_t J = strtoul(argv[3], NULL, 10), n = argc > 4 ? strtoul(argv[4], NULL, 10) : 1000000;
    sb_source_t *src = NULL;
    sb_factors_t *f = NULL;
    sb_param_t *p = NULL;
    sb_form_t form;
    if (sb_job_source_open(NULL, argv[1], NULL, &src) != SB_OK || sb_factors_read_exr(NULL, argv[2], &f) != SB_OK ||
        sb_factors_param(NULL, f, &p, &form) != SB_OK || J < 1 || J > sb_factors_terms(f)) {
        fprintf(stderr, "%s: cannot open %s, %s or J = %zu\n", argv[0], argv[1], argv[2], J);
        return 1;
    }
    const char *only = getenv("SB_BANDS_ONLY"), *seed = getenv("SB_BANDS_SEED"), *mix = getenv("SB_BANDS_MIX");
    double ma = mix ? atof(mix) : 0, sc[4] = {0, 90, 0, 90}; /* view, light ranges (degrees) */
    const char *scene = getenv("SB_BANDS_SCENE");
    if (scene && sscanf(scene, "%lf,%lf,%lf,%lf", &sc[0], &sc[1], &sc[2], &sc[3]) != 4) {
        fprintf(stderr, "%s: SB_BANDS_SCENE=%s is not V0,V1,L0,L1 (degrees)\n", argv[0], scene);
        return 2;
    }
    double cs[4];
    for (int k = 0; k < 4; k++)
        cs[k] = cos(sc[k] * 3.14159265358979323846 / 180);
    for (int b = 0; b < 9; b++) {
        if (only && strcmp(only, names[b]) != 0) continue;
        uint64_t s = 0x5eed + (uint64_t)b + (seed ? strtoull(seed, NULL, 10) << 8 : 0);
        band_sums_t sums = {0};
        /* SB_BANDS_HALF=1: the share of the band's squared error and value,
         * and the uniform probability, at theta_h below each of ht (how
         * rare the pairs that carry the band are for a uniform draw) */
        static const double ht[5] = {0.25, 0.5, 1, 2, 5};
        double hs[5][3] = {{0}};
        int half = getenv("SB_BANDS_HALF") != NULL;
        double neg = 0, fmx = 0; /* the most negative reconstruction where f > 0, the largest |f| */
        for (size_t i = 0; i < n; i++) {
            double wi[3], wo[3], v[3] = {0, 0, 0}, r[3] = {0, 0, 0}, u[6], w = 1;
            for (int k = 0; k < 6; k++)
                u[k] = rnd(&s);
            int in = band_draw(b - 1, u, wi, wo);
            if (ma > 0 && b <= 3) in = (w = band_mix_draw(ma, wi, u + 3, wo)) > 0; /* all, theta_i bands */
            if (in && scene) in = wo[2] <= cs[0] && wo[2] >= cs[1] && wi[2] <= cs[2] && wi[2] >= cs[3];
            if (in && sb_source_eval(src, wi, wo, v) && !sb_factors_eval(f, p, form, J, wi, wo, r))
                r[0] = r[1] = r[2] = 0;
            for (int c = 0; in && c < 3; c++) {
                fmx = fmax(fmx, fabs(v[c]));
                if (v[c] > 0) neg = fmin(neg, r[c]);
            }
            double sa0 = sums.sa, sd0 = sums.sd;
            band_add_w(&sums, v, r, wi[2], w);
            double hz = wi[2] + wo[2],
                   hn = sqrt((wi[0] + wo[0]) * (wi[0] + wo[0]) + (wi[1] + wo[1]) * (wi[1] + wo[1]) + hz * hz);
            double th = hn > 0 ? acos(fmin(1, hz / hn)) * 180 / 3.14159265358979323846 : 90;
            for (int q = 0; half && in && q < 5; q++)
                if (th < ht[q]) hs[q][0] += sums.sa - sa0, hs[q][1] += sums.sd - sd0, hs[q][2] += w;
        }
        for (int q = 0; half && q < 5; q++)
            printf("%s theta_h<%g: error share %.4f, value share %.4f, uniform probability %.3g\n", names[b], ht[q],
                   hs[q][0] / sums.sa, hs[q][1] / sums.sd, hs[q][2] / (double)n);
        double se, q = band_ratio(&sums, &se);
        printf("%s %.6e %.3e", names[b], q, se);
        if (getenv("SB_BANDS_SUMS")) /* the sums, for pooling draws exactly */
            printf(" %.17g %.17g %zu", sums.sa, sums.sd, sums.n);
        printf("\n");
        if (getenv("SB_BANDS_NEG")) printf("negative %s %.6e\n", names[b], fmx > 0 ? neg / fmx : 0);
        fflush(stdout);
    }
    /* SB_BANDS_SCENE_SEEDS=K: the library's scene estimator (sb_scene_estimate,
     * its defaults, as the job measures a --scene) with seeds 1..K: its
     * spread against its own standard errors */
    const char *seeds = getenv("SB_BANDS_SCENE_SEEDS");
    for (unsigned long k = 1; scene && seeds && k <= strtoul(seeds, NULL, 10); k++) {
        char spec[128];
        snprintf(spec, sizeof spec, "view=%g..%g;light=%g..%g", sc[0], sc[1], sc[2], sc[3]);
        sb_scene_t *sn = NULL;
        sb_estimate_t *es = malloc(sizeof *es);
        sb_estimate_opts_t so = {0};
        so.seed = k;
        if (es && sb_scene_parse(NULL, spec, &sn) == SB_OK &&
            sb_scene_estimate(NULL, sn, src, f, p, form, &so, es) == SB_OK)
            printf("scene seed %lu all %.6e %.3e specular %.6e %.3e retro %.6e %.3e (%zu pairs, %zu known)\n", k,
                   es->rel[J - 1][SB_EST_FCOS][3], es->se[J - 1][SB_EST_FCOS][3], es->band[J - 1][SB_BAND_SPECULAR][3],
                   es->band_se[J - 1][SB_BAND_SPECULAR][3], es->band[J - 1][SB_BAND_RETRO][3],
                   es->band_se[J - 1][SB_BAND_RETRO][3], es->pairs, es->known);
        sb_scene_destroy(sn);
        free(es);
    }
    size_t m = argc > 5 ? strtoul(argv[5], NULL, 10) : 0;
    sb_estimate_opts_t eo = {0};
    eo.max_pairs = m;
    eo.rel_se = 1e-9; /* grow to max_pairs */
    sb_pairs_t *P = NULL;
    sb_estimate_t *e = malloc(sizeof *e);
    if (m && e && sb_pairs_create(NULL, src, &eo, &P) == SB_OK &&
        sb_estimate_compute(NULL, P, f, NULL, p, form, &eo, e) == SB_OK) {
        printf("estimator all %.6e %.3e (%zu pairs)\n", e->rel[J - 1][SB_EST_FCOS][3], e->se[J - 1][SB_EST_FCOS][3],
               e->pairs);
        for (int b = 0; b < SB_BAND_COUNT_; b++)
            printf("estimator %s %.6e %.3e\n", sb_band_name(b), e->band[J - 1][b][3], e->band_se[J - 1][b][3]);
    }
    free(e);
    sb_pairs_destroy(P);
    sb_param_destroy(p);
    sb_factors_destroy(f);
    sb_source_destroy(src);
    return 0;
}
