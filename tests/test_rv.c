/* The rv layout (param_rv.c): the light's elevation and the view about the
 * mirror direction.  Its geometry against formulas written out here
 * (the angle between V and the mirror direction, the rows' texel centres
 * from the normal to the top), its measures, Phong's lobe as a column
 * function alone, and its continuation past the view's horizon (the band
 * bounds it keeps for classic Phong n = 100: test_bands.c). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"

#define PI 3.14159265358979323846
#define EDGE_DEG 89.9 /* the last row on the whole hemisphere */

static sb_param_kind_t rv_kind(void) {
    sb_param_kind_t k = SB_PARAM_NONE;
    CHECK(sb_param_kind_parse("rv", &k) == SB_OK);
    return k;
}

static sb_param_t *rv_make(size_t res, double theta_max) {
    sb_param_opts_t o = {0};
    o.res = res;
    o.theta_max = theta_max;
    sb_param_t *p = NULL;
    CHECK(sb_param_create(NULL, rv_kind(), &o, &p) == SB_OK);
    return p;
}

static double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static void rand_hemi(unsigned long long *s, double w[3]) {
    double z = sb_rand01(s), ph = 2 * PI * sb_rand01(s), r = sqrt(1 - z * z);
    w[0] = r * cos(ph), w[1] = r * sin(ph), w[2] = z;
}

/* Forward map, written from its definition: theta_r = the angle between
 * V and r = (-l_x, -l_y, l_z), s = sqrt(theta_r / pi); theta_i's texel
 * centres at theta_i = i top / (ti - 1). */
SB_TEST(coords_match_the_mirror_angle) {
    for (int limited = 0; limited < 2; limited++) {
        double tmax = limited ? 70 * PI / 180 : PI / 2, top = limited ? tmax : EDGE_DEG * PI / 180;
        sb_param_t *p = rv_make(16, limited ? tmax : 0);
        if (!p) continue;
        size_t gw, gh;
        sb_param_texture_size(p, SB_SIDE_G, &gw, &gh);
        CHECK(gw == 16 && gh == 1);
        unsigned long long st = 5;
        for (int k = 0; k < 20000; k++) {
            double l[3], v[3], sg[2], sh[2];
            rand_hemi(&st, l);
            rand_hemi(&st, v);
            int in = sb_param_coords(p, l, v, sg, sh);
            CHECK(in == (acos(l[2]) <= tmax && acos(v[2]) <= tmax));
            double r[3] = {-l[0], -l[1], l[2]}, tr = acos(fmax(-1, fmin(1, dot3(r, v))));
            double u = fmin(acos(l[2]) / top, 1);
            CHECK_ABS(sh[0] * sh[0] * PI, tr, 1e-9);
            CHECK_ABS(sg[0], (u * (double)(gw - 1) + 0.5) / (double)gw, 1e-12);
            CHECK(sh[1] >= 0 && sh[1] <= 1 && sg[1] == 0.5);
        }
        sb_param_destroy(p);
    }
}

/* Cell centres are texel centres; a valid cell's pair has r.v = cos of its
 * column's theta_r whatever its row (Phong's lobe is a column function);
 * invalid cells are those with V below the horizon (or outside the cap). */
SB_TEST(cells_are_texel_centres) {
    for (int limited = 0; limited < 2; limited++) {
        double tmax = limited ? 70 * PI / 180 : PI / 2;
        sb_param_t *p = rv_make(9, limited ? tmax : 0);
        if (!p) continue;
        size_t gw, gh, hw, hh, valid = 0;
        sb_param_texture_size(p, SB_SIDE_G, &gw, &gh);
        sb_param_texture_size(p, SB_SIDE_H, &hw, &hh);
        for (size_t row = 0; row < sb_param_rows(p); row++)
            for (size_t col = 0; col < sb_param_cols(p); col++) {
                double wi[3], wo[3], sg[2], sh[2];
                int in = sb_param_cell_dirs(p, row, col, wi, wo);
                CHECK_ABS(dot3(wi, wi), 1, 1e-14);
                CHECK_ABS(dot3(wo, wo), 1, 1e-14);
                CHECK(acos(wi[2]) <= tmax + 1e-12); /* every row a light in the cap */
                CHECK(in == (wo[2] > 0 && acos(wo[2]) <= tmax + 1e-12));
                double u = ((double)(col % hw) + 0.5) / (double)hw, r[3] = {-wi[0], -wi[1], wi[2]};
                CHECK_ABS(dot3(r, wo), cos(u * u * PI), 1e-12);
                if (!in) continue;
                valid++;
                CHECK(sb_param_coords(p, wi, wo, sg, sh) == 1);
                CHECK_ABS(sg[0], ((double)row + 0.5) / (double)gw, 1e-12);
                CHECK_ABS(sh[0], u, 1e-12);
                CHECK_ABS(sh[1], ((double)(col / hw) + 0.5) / (double)hh, 1e-12);
            }
        CHECK(valid > sb_param_rows(p) * sb_param_cols(p) / 3);
        sb_param_destroy(p);
    }
}

/* Rows sum to the cap's solid angle, columns to the sphere's (4 pi: the
 * view ranges over all directions about r); over the valid cells the
 * products integrate 1 and cos theta_i cos theta_o over the pairs. */
SB_TEST(measures) {
    sb_param_t *p = rv_make(24, 0);
    if (!p) return;
    double sr = 0, sc = 0, s1 = 0, scos = 0;
    for (size_t r = 0; r < sb_param_rows(p); r++)
        sr += sb_param_row_measure(p, r);
    for (size_t c = 0; c < sb_param_cols(p); c++)
        sc += sb_param_col_measure(p, c);
    CHECK_REL(sr, 2 * PI, 1e-12);
    CHECK_REL(sc, 4 * PI, 1e-12);
    for (size_t r = 0; r < sb_param_rows(p); r++)
        for (size_t c = 0; c < sb_param_cols(p); c++) {
            double wi[3], wo[3];
            if (!sb_param_cell_dirs(p, r, c, wi, wo)) continue;
            double m = sb_param_row_measure(p, r) * sb_param_col_measure(p, c);
            s1 += m;
            scos += m * wi[2] * wo[2];
        }
    CHECK_REL(s1, 4 * PI * PI, 0.02);
    CHECK_REL(scos, PI * PI, 0.02);
    sb_param_destroy(p);
}

/* Beyond the view's horizon an analytic source continues by its value at
 * the edge (SB_CAP_VIEW_EDGE, a plain SVD): Phong's kd cos theta_i does not
 * fall to 0 there, so zeros (--zero-fill) leave a jump that the lookups
 * beside it blend into pairs at grazing views. */
SB_TEST(view_edge_continued) {
    sb_job_opts_t o = {0};
    o.source = "phong:n=100";
    o.param = "rv";
    o.form = "cos";
    o.res = 16;
    o.terms = 4;
    double head[2] = {0, 0};
    for (int z = 0; z < 2; z++) {
        sb_job_t *job = NULL;
        o.zero_fill = z;
        CHECK(sb_job_run(NULL, &o, &job) == SB_OK);
        if (!job) continue;
        CHECK(!sb_job_masked(job));
        head[z] = sb_estimate_headline(sb_job_estimate(job), 4);
        sb_job_destroy(job);
    }
    printf("  headline continued %.4g, zeros %.4g\n", head[0], head[1]);
    CHECK(head[0] > 0 && 3 * head[0] < head[1]);
}
