/* sepbrdf_bench_scene: what a scene-weighted fit (--scene, scene.h) is
 * worth.  For each source, scene and layout (R, J), three fits of the same
 * size: plain (the layout's defaults), solid-angle weighted (--weighted)
 * and scene-weighted (--scene); for each the headline error (f cos
 * theta_i as a shader returns it) over the scene's pairs with its standard
 * error, the whole domain's headline, and for a lights scene the PSNR of
 * the render with those lights against the source's (128 x 128 pixels,
 * exposure 1 / the original's brightest channel).
 *
 *   sepbrdf_bench_scene [-o|--out DIR] [--quick]
 * writes the table to stdout and, with -o, DIR/scene.csv and, for the first
 * row, DIR/scene_plain.png and DIR/scene_fit.png (original | fit |
 * difference x 4). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "sepbrdf/sepbrdf.h"

#define LIGHTS "lights=45,45/30,150/60,270"

typedef struct row {
    const char *source, *scene, *param;
    size_t res, terms;
} row_t;

static const row_t ROWS[] = {
    {"microfacet:base=gold,roughness=0.3", LIGHTS, "io", 16, 2},
    {"microfacet:base=gold,roughness=0.3", LIGHTS, "iso", 16, 1},
    {"microfacet:base=gold,roughness=0.3", LIGHTS, "io-area", 16, 2},
    {"microfacet:base=gold,roughness=0.3", LIGHTS, "hd", 16, 2},
    {"microfacet:base=gold,roughness=0.3", LIGHTS, "iso", 16, 2},
    {"microfacet:base=gold,roughness=0.3", LIGHTS, "iso", 32, 4},
    {"microfacet:base=gold,roughness=0.3", "view=0..60;light=0..90", "io", 16, 2},
    {"microfacet:base=gold,roughness=0.3", "view=0..60;light=0..90", "iso", 16, 1},
    {"microfacet:base=gold,roughness=0.1", LIGHTS, "io", 16, 2},
    {"microfacet:base=gold,roughness=0.1", LIGHTS, "iso", 16, 1},
    {"microfacet:base=gold,roughness=0.1", LIGHTS, "iso", 32, 4},
};
#define QUICK_ROWS 2

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* One fit's figures. */
typedef struct fit {
    double scene, scene_se, domain, psnr, time_s;
    size_t cells, all;
} fit_t;

/* PSNR of the render of job's factors with the scene's lights (NAN: no
 * lights); with png, the strip original | fit | difference there. */
static double psnr(const sb_scene_t *s, const sb_source_t *src, const sb_job_t *job, const char *png) {
    sb_render_opts_t o = {0};
    o.size = 128;
    if (!(o.light_count = sb_scene_lights(s, o.lights, SB_RENDER_MAX_LIGHTS))) return NAN;
    sb_image_t orig = {0}, rec = {0};
    sb_image_diff_t d = {0};
    d.psnr = NAN;
    if (sb_render_source(NULL, &o, src, &orig) == SB_OK &&
        sb_render_factors(NULL, &o, sb_job_factors(job), sb_job_param(job), sb_job_form(job), 0, &rec) == SB_OK) {
        sb_tonemap_t tm = {1 / sb_image_max(&orig), SB_TONEMAP_CLAMP};
        if (sb_image_compare(NULL, &orig, &rec, &tm, &d) != SB_OK) d.psnr = NAN;
        if (png) sb_image_write_strip_png(NULL, png, &orig, &rec, &tm, 4);
    }
    sb_image_free(&orig);
    sb_image_free(&rec);
    return d.psnr;
}

/* Fit r (mode 0 plain, 1 solid-angle weighted, 2 scene) and measure it. */
static int run_fit(const row_t *r, const sb_scene_t *s, const sb_source_t *src, int mode, const char *png, fit_t *out) {
    sb_job_opts_t o = {0};
    o.param = r->param;
    o.res = r->res;
    o.terms = r->terms;
    o.weighted = mode == 1;
    o.scene = mode == 2 ? r->scene : NULL;
    sb_job_t *job = NULL;
    sb_estimate_t *e = malloc(sizeof *e);
    double t0 = now();
    int ok = e && sb_job_run_source(NULL, src, &o, &job) == SB_OK;
    out->time_s = now() - t0;
    ok = ok &&
         sb_scene_estimate(NULL, s, src, sb_job_factors(job), sb_job_param(job), sb_job_form(job), NULL, e) == SB_OK;
    if (ok) {
        const sb_estimate_t *d = mode == 2 ? sb_job_domain_estimate(job) : sb_job_estimate(job);
        out->scene = sb_estimate_headline(e, r->terms);
        out->scene_se = e->se[r->terms - 1][SB_EST_FCOS][SB_CH_ALL];
        out->domain = sb_estimate_headline(d, r->terms);
        out->psnr = psnr(s, src, job, png);
        out->cells = sb_job_matrix(job)->valid_count;
        out->all = sb_job_matrix(job)->rows * sb_job_matrix(job)->cols;
    }
    sb_job_destroy(job);
    free(e);
    return ok;
}

static void put_row(FILE *fp, const row_t *r, const fit_t f[3], const char *sep) {
    const char *q = strcmp(sep, ",") ? "" : "\""; /* CSV: the specs hold commas */
    fprintf(fp, "%s%s%s%s%s%s%s%s%s%s%zu%s%zu", q, r->source, q, sep, q, r->scene, q, sep, r->param, sep, r->res, sep,
            r->terms);
    for (int m = 0; m < 3; m++)
        fprintf(fp, "%s%.4f%s%.4f", sep, f[m].scene, sep, f[m].scene_se);
    fprintf(fp, "%s%.4f%s%.4f%s%.2f%s%.2f%s%zu%s%zu%s%.2f%s%.2f\n", sep, f[0].domain, sep, f[2].domain, sep, f[0].psnr,
            sep, f[2].psnr, sep, f[2].cells, sep, f[2].all, sep, f[0].time_s, sep, f[2].time_s);
}

int main(int argc, char **argv) {
    const char *dir = NULL;
    int quick = 0;
    for (int i = 1; i < argc; i++) {
        if ((!strcmp(argv[i], "-o") || !strcmp(argv[i], "--out")) && i + 1 < argc)
            dir = argv[++i];
        else if (!strcmp(argv[i], "--quick"))
            quick = 1;
        else {
            fprintf(stderr, "usage: sepbrdf_bench_scene [-o|--out DIR] [--quick]\n");
            return 1;
        }
    }
    char path[4096];
    FILE *csv = NULL;
    if (dir) {
        snprintf(path, sizeof path, "%s/scene.csv", dir);
        if (!(csv = fopen(path, "w"))) {
            fprintf(stderr, "sepbrdf_bench_scene: cannot write %s\n", path);
            return 2;
        }
        fprintf(csv, "source,scene,param,res,terms,plain,plain_se,weighted,weighted_se,scene_fit,scene_fit_se,"
                     "domain_plain,domain_scene_fit,psnr_plain,psnr_scene_fit,fit_cells,cells,time_plain_s,"
                     "time_scene_s\n");
    }
    printf("source | scene | param | R | J | over the scene's pairs: plain, weighted, scene fit (+- se) | whole "
           "domain: plain, scene fit | PSNR dB: plain, scene fit | fit cells | time s: plain, scene\n");
    size_t n = quick ? QUICK_ROWS : sizeof ROWS / sizeof ROWS[0];
    for (size_t i = 0; i < n; i++) {
        const row_t *r = &ROWS[i];
        sb_scene_t *s = NULL;
        sb_source_t *src = NULL;
        fit_t f[3] = {{0}};
        int ok = sb_scene_parse(NULL, r->scene, &s) == SB_OK && sb_source_open(NULL, r->source, &src) == SB_OK;
        for (int m = 0; m < 3 && ok; m++) {
            char png[4200];
            snprintf(png, sizeof png, "%s/scene_%s.png", dir ? dir : ".", m == 2 ? "fit" : "plain");
            ok = run_fit(r, s, src, m, dir && i == 0 && m != 1 ? png : NULL, &f[m]);
        }
        if (ok) put_row(stdout, r, f, " | ");
        if (ok && csv) put_row(csv, r, f, ",");
        if (!ok) fprintf(stderr, "sepbrdf_bench_scene: row %zu failed\n", i + 1);
        sb_source_destroy(src);
        sb_scene_destroy(s);
    }
    if (csv) fclose(csv);
    return 0;
}
