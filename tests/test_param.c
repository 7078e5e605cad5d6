/* Parameterisations: cell directions, coordinates, measures. */
#include "harness.h"
#include "sepbrdf/sepbrdf.h"

SB_TEST(io_cells_and_coords) {
    sb_param_opts_t o = {0};
    o.res = 7;
    sb_param_t *p;
    CHECK(sb_param_create(NULL, SB_PARAM_IO, &o, &p) == SB_OK);
    CHECK(sb_param_rows(p) == 49 && sb_param_cols(p) == 49);
    size_t w, h;
    sb_param_texture_size(p, SB_SIDE_G, &w, &h);
    CHECK(w == 7 && h == 7);
    int wrap[2];
    sb_param_wrap(p, SB_SIDE_H, wrap);
    CHECK(wrap[0] == SB_WRAP_CLAMP && wrap[1] == SB_WRAP_REPEAT);
    double wi[3], wo[3], sg[2], sh[2];
    for (size_t k = 0; k < 49; k++) {
        size_t l = (k * 13 + 5) % 49;
        CHECK(sb_param_cell_dirs(p, k, l, wi, wo) == 1);
        CHECK_REL(wi[0] * wi[0] + wi[1] * wi[1] + wi[2] * wi[2], 1.0, 1e-14);
        CHECK(sb_param_coords(p, wi, wo, sg, sh) == 1);
        /* the centre of cell k is the centre of texel (k % R, k / R) */
        CHECK_ABS(sg[0], ((k % 7) + 0.5) / 7, 1e-12);
        CHECK_ABS(sg[1], ((k / 7) + 0.5) / 7, 1e-12);
        CHECK_ABS(sh[0], ((l % 7) + 0.5) / 7, 1e-12);
        CHECK_ABS(sh[1], ((l / 7) + 0.5) / 7, 1e-12);
    }
    double below[3] = {0.6, 0, -0.8};
    CHECK(sb_param_coords(p, below, wo, sg, sh) == 0);
    sb_param_destroy(p);
}

SB_TEST(io_measure_sums_to_hemisphere) {
    sb_param_opts_t o = {0};
    o.res = 9;
    sb_param_t *p;
    CHECK(sb_param_create(NULL, SB_PARAM_IO, &o, &p) == SB_OK);
    double s = 0;
    for (size_t k = 0; k < 81; k++) s += sb_param_row_measure(p, k);
    CHECK_REL(s, 2 * SB_PI, 1e-12);
    sb_param_destroy(p);
}

SB_TEST(angles_roundtrip) {
    unsigned long long st = 7;
    for (int i = 0; i < 1000; i++) {
        double t = sb_rand01(&st) * SB_PI, ph = sb_rand01(&st) * 2 * SB_PI, w[3], t2, p2;
        sb_dir_from_angles(t, ph, w);
        sb_dir_to_angles(w, &t2, &p2);
        CHECK_ABS(t2, t, 1e-9);
        if (t > 1e-6 && t < SB_PI - 1e-6) CHECK_ABS(p2, ph, 1e-9);
    }
}

SB_TEST(kind_names) {
    sb_param_kind_t k;
    CHECK(sb_param_kind_parse("io", &k) == SB_OK && k == SB_PARAM_IO);
    CHECK(sb_param_kind_parse("nope", &k) == SB_ERR_UNKNOWN);
    sb_form_t f;
    CHECK(sb_form_parse("cos2", &f) == SB_OK && f == SB_FORM_COS2);
    CHECK(sb_form_parse("x", &f) == SB_ERR_UNKNOWN);
}
