/* sepbrdf_bench_floor: the physical floor of `sepbrdf factor` on an
 * isotropic source at io resolution R (issue 36).  The least any program
 * must do to produce that output: one pass over the R^3 distinct values
 * f_r(theta_i, theta_o, phi_o - phi_i) of the same BRDF (three channels,
 * through the same sb_source_eval), and the bytes of the 2 J textures the
 * command writes (w x h texels x 3 channels x 4 bytes, float storage),
 * written raw, each texel a copy of a value read, so nothing is optimised
 * away.  No SVD, no error estimate, no EXR encoding.
 *
 *   sepbrdf_bench_floor [--source SPEC] [-r R] [-J J] [--size WxH] [--hsize WxH] -o DIR
 *
 * defaults: the command's default source, R = 64, J = 8, textures R x R
 * (--size: g's and h's, --hsize: h's alone).
 * bench/floor.sh times it against the whole command in alternation. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sepbrdf/sepbrdf.h"

typedef struct floor_opts {
    const char *source, *out;
    size_t R, J, w[2], h[2]; /* g's and h's texels */
} floor_opts_t;

static int parse(int argc, char **argv, floor_opts_t *o) {
    *o = (floor_opts_t){"microfacet:base=gold,roughness=0.5", NULL, 64, 8, {0, 0}, {0, 0}};
    int ok = argc % 2 == 1;
    for (int i = 1; ok && i + 1 < argc; i += 2) {
        const char *a = argv[i], *v = argv[i + 1];
        if (!strcmp(a, "--source"))
            o->source = v;
        else if (!strcmp(a, "-r"))
            o->R = strtoul(v, NULL, 10);
        else if (!strcmp(a, "-J"))
            o->J = strtoul(v, NULL, 10);
        else if (!strcmp(a, "-o"))
            o->out = v;
        else if (!strcmp(a, "--size"))
            ok = sscanf(v, "%zux%zu", &o->w[0], &o->h[0]) == 2;
        else
            ok = !strcmp(a, "--hsize") && sscanf(v, "%zux%zu", &o->w[1], &o->h[1]) == 2;
    }
    if (!ok || !o->out || o->R < 2 || o->J < 1)
        fprintf(stderr, "usage: sepbrdf_bench_floor [--source SPEC] [-r R] [-J J] [--size WxH] [--hsize WxH] -o DIR\n");
    return ok && o->out && o->R >= 2 && o->J >= 1;
}

static void dir_of(double theta, double phi, double d[3]) {
    d[0] = sin(theta) * cos(phi);
    d[1] = sin(theta) * sin(phi);
    d[2] = cos(theta);
}

/* One pass over the distinct values (theta_i, theta_o, dphi) on the io
 * grid's cell centres, every channel, the R^2 outgoing directions
 * computed once; returns the table (R^3 x 3 floats). */
static float *distinct_values(const sb_source_t *src, size_t R) {
    float *t = malloc(R * R * R * 3 * sizeof *t);
    double *wo = malloc(R * R * 3 * sizeof *wo);
    const double dt = SB_PI / 2 / (double)R, dp = 2 * SB_PI / (double)R;
    for (size_t k = 0; wo && k < R; k++)
        for (size_t o = 0; o < R; o++)
            dir_of((o + 0.5) * dt, (double)k * dp, wo + 3 * (o + R * k));
    for (size_t i = 0; t && wo && i < R; i++) {
        double wi[3], rgb[3];
        dir_of((i + 0.5) * dt, 0, wi);
        for (size_t ko = 0; ko < R * R; ko++) {
            sb_source_eval(src, wi, wo + 3 * ko, rgb);
            float *cell = t + 3 * (ko + R * R * i);
            for (int c = 0; c < 3; c++)
                cell[c] = (float)rgb[c];
        }
    }
    free(wo);
    return t;
}

/* The 2 J textures, w x h x 3 floats each, filled from the table. */
static int write_textures(const floor_opts_t *o, const float *t) {
    size_t big = o->w[0] * o->h[0] > o->w[1] * o->h[1] ? o->w[0] * o->h[0] : o->w[1] * o->h[1];
    size_t cells = o->R * o->R * o->R * 3;
    float *img = malloc(big * 3 * sizeof *img);
    if (!img) return 1;
    char path[4096];
    for (size_t j = 0; j < 2 * o->J; j++) {
        size_t n = o->w[j >= o->J] * o->h[j >= o->J] * 3;
        for (size_t x = 0; x < n; x++)
            img[x] = t[(x + j * 7919) % cells];
        snprintf(path, sizeof path, "%s/%c_%02zu.raw", o->out, j < o->J ? 'g' : 'h', j % o->J);
        FILE *fp = fopen(path, "wb");
        if (!fp || fwrite(img, sizeof *img, n, fp) != n || fclose(fp) != 0) {
            fprintf(stderr, "sepbrdf_bench_floor: cannot write %s\n", path);
            free(img);
            return 1;
        }
    }
    free(img);
    return 0;
}

int main(int argc, char **argv) {
    floor_opts_t o;
    if (!parse(argc, argv, &o)) return 1;
    if (!o.w[0]) o.w[0] = o.h[0] = o.R;
    if (!o.w[1]) o.w[1] = o.w[0], o.h[1] = o.h[0];
    sb_source_t *src = NULL;
    if (sb_source_open(NULL, o.source, &src) != SB_OK) {
        fprintf(stderr, "sepbrdf_bench_floor: cannot open the source %s\n", o.source);
        return 1;
    }
    float *t = distinct_values(src, o.R);
    int rc = t ? write_textures(&o, t) : 1;
    free(t);
    sb_source_destroy(src);
    return rc;
}
