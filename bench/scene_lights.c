/* sepbrdf_bench_scene_lights: a lights scene's errors (issue 33,
 * docs/scene.md "A lights scene's pairs drawn toward the highlights") on a
 * written output set, three ways: the library's scene estimator
 * (sb_scene_estimate, its defaults, as the job measures a --scene) over
 * seeds 1..K; the same estimator with the pairs drawn plainly, uniform
 * over the sphere's pixels and the lights (sb_scene_draw, weight 1: what
 * main drew), over the same seeds; and that plain draw grown to N pairs
 * (the reference).
 *
 *   sepbrdf_bench_scene_lights SOURCE DIR J SCENE [K [N]]
 *
 * SOURCE: a model spec or a measured file; DIR: `sepbrdf factor -o DIR`;
 * J: the terms; SCENE: a --scene spec (lights=...); K seeds (default 8);
 * N: the reference's pairs (default 0: none).  Prints per seed "scene
 * seed k headline se pairs" and "plain seed k headline se pairs", then
 * for each draw the mean over the seeds, the spread (standard deviation
 * over the seeds over the mean), the mean standard error over the mean
 * and the mean pairs, and "reference headline se pairs". */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sepbrdf/sepbrdf.h"

static double plain(const void *user, const double x[6], double wi[3], double wo[3]) {
    return sb_scene_draw(user, x, wi, wo);
}

/* The headline at J over the scene's pairs (drawn toward the highlights,
 * or plainly), its standard error and the pairs used. */
static int measure(const sb_scene_t *s, const sb_source_t *src, const sb_factors_t *f, const sb_param_t *p,
                   sb_form_t form, size_t J, int uniform, const sb_estimate_opts_t *o, double out[3]) {
    sb_pairs_t *P = NULL;
    sb_estimate_t *e = malloc(sizeof *e);
    sb_result_t r = !e        ? SB_ERR_NOMEM
                    : uniform ? sb_pairs_create_drawn(NULL, src, o, plain, s, &P)
                              : sb_scene_pairs_create(NULL, s, src, o, &P);
    if (r == SB_OK) r = sb_estimate_compute(NULL, P, f, NULL, p, form, o, e);
    if (r == SB_OK) {
        out[0] = e->rel[J - 1][SB_EST_FCOS][SB_CH_ALL];
        out[1] = e->se[J - 1][SB_EST_FCOS][SB_CH_ALL];
        out[2] = (double)e->pairs;
    }
    sb_pairs_destroy(P);
    free(e);
    return r == SB_OK;
}

int main(int argc, char **argv) {
    if (argc < 5) {
        fprintf(stderr, "usage: %s SOURCE DIR J SCENE [K [N]]\n", argv[0]);
        return 2;
    }
    size_t J = strtoul(argv[3], NULL, 10), K = argc > 5 ? strtoul(argv[5], NULL, 10) : 8;
    size_t N = argc > 6 ? strtoul(argv[6], NULL, 10) : 0;
    sb_source_t *src = NULL;
    sb_factors_t *f = NULL;
    sb_param_t *p = NULL;
    sb_scene_t *s = NULL;
    sb_form_t form;
    if (sb_job_source_open(NULL, argv[1], NULL, &src) != SB_OK || sb_factors_read_exr(NULL, argv[2], &f) != SB_OK ||
        sb_factors_param(NULL, f, &p, &form) != SB_OK || J < 1 || J > sb_factors_terms(f) ||
        sb_scene_parse(NULL, argv[4], &s) != SB_OK) {
        fprintf(stderr, "%s: cannot open %s, %s, the scene %s or J = %zu\n", argv[0], argv[1], argv[2], argv[4], J);
        return 1;
    }
    static const char *const names[2] = {"scene", "plain"};
    const char *pl = getenv("SB_SCENE_LIGHTS_PLAIN");
    for (int u = 0; u < (pl && !strcmp(pl, "0") ? 1 : 2); u++) {
        double sum = 0, sum2 = 0, se = 0, pairs = 0, v[3];
        for (size_t k = 1; k <= K; k++) {
            sb_estimate_opts_t o = {0};
            o.seed = k;
            o.headline_only = 1;
            if (!measure(s, src, f, p, form, J, u, &o, v)) return 1;
            printf("%s seed %zu %.6e %.3e %.0f\n", names[u], k, v[0], v[1], v[2]);
            fflush(stdout);
            sum += v[0], sum2 += v[0] * v[0], se += v[1], pairs += v[2];
        }
        double m = sum / (double)K, sd = K > 1 ? sqrt(fmax(0, (sum2 - sum * m) / (double)(K - 1))) : 0;
        printf("%s mean %.6e spread %.4f se %.4f pairs %.0f\n", names[u], m, sd / m, se / (double)K / m,
               pairs / (double)K);
    }
    if (N) {
        sb_estimate_opts_t o = {0};
        double v[3];
        o.max_pairs = N;
        o.rel_se = 1e-9; /* grow to N */
        o.headline_only = 1;
        o.seed = 0x5eed;
        if (!measure(s, src, f, p, form, J, 1, &o, v)) return 1;
        printf("reference %.6e %.3e %.0f\n", v[0], v[1], v[2]);
    }
    sb_scene_destroy(s);
    sb_param_destroy(p);
    sb_factors_destroy(f);
    sb_source_destroy(src);
    return 0;
}
