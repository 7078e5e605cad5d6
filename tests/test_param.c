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
    for (size_t k = 0; k < 81; k++)
        s += sb_param_row_measure(p, k);
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

/* ---- io-area, hd, iso -------------------------------------------------- */

#include <stdlib.h>
#include <string.h>

static const sb_param_kind_t all_kinds[] = {SB_PARAM_IO, SB_PARAM_IO_AREA, SB_PARAM_HD, SB_PARAM_ISO, SB_PARAM_VH};
#define NKINDS (sizeof all_kinds / sizeof all_kinds[0])

static sb_param_t *make(sb_param_kind_t kind, size_t res) {
    sb_param_opts_t o = {0};
    o.res = res;
    sb_param_t *p = NULL;
    sb_context_t *ctx;
    sb_context_create(&ctx);
    sb_result_t r = sb_param_create(ctx, kind, &o, &p);
    CHECKF(r == SB_OK, "%s: %s", sb_param_kind_name(kind), sb_context_last_error(ctx));
    sb_context_destroy(ctx);
    return p;
}

static double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
static double dist3(const double a[3], const double b[3]) {
    double d[3] = {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
    return sqrt(dot3(d, d));
}
static void normalize3(double a[3]) {
    double n = sqrt(dot3(a, a));
    for (int i = 0; i < 3; i++)
        a[i] /= n;
}
static void cross3(const double a[3], const double b[3], double c[3]) {
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}
/* Uniform on the upper hemisphere (z > 0). */
static void rand_hemi(unsigned long long *s, double w[3]) {
    double z = 1 - sb_rand01(s), ph = 2 * SB_PI * sb_rand01(s), r = sqrt(1 - z * z);
    w[0] = r * cos(ph);
    w[1] = r * sin(ph);
    w[2] = z;
}
/* Distance of texture coordinates on an axis, modulo 1 when it repeats. */
static double st_dist(double a, double b, int wrap) {
    double d = fabs(a - b);
    if (wrap == SB_WRAP_REPEAT) d = fmin(d, 1 - d);
    return d;
}

SB_TEST(sizes_wraps_specs) {
    struct {
        sb_param_kind_t kind;
        size_t rows, cols, gw, gh, hw, hh;
        int wg[2], wh[2];
        const char *spec;
    } want[] = {
        {SB_PARAM_IO, 49, 49, 7, 7, 7, 7, {0, 1}, {0, 1}, "io:res=7"},
        {SB_PARAM_IO_AREA, 49, 49, 7, 7, 7, 7, {0, 0}, {0, 0}, "io-area:res=7"},
        {SB_PARAM_HD, 49, 49, 7, 7, 7, 7, {0, 1}, {0, 1}, "hd:res=7"},
        {SB_PARAM_ISO, 14, 36, 14, 1, 12, 3, {0, 0}, {0, 1}, "iso:th=14,td=12,pd=3"},
        {SB_PARAM_VH, 7, 42, 7, 1, 14, 3, {0, 0}, {0, 0}, "vh:tv=7,th=14,ph=3"},
    };
    for (size_t i = 0; i < NKINDS; i++) {
        sb_param_t *p = make(want[i].kind, 7);
        size_t gw, gh, hw, hh;
        int wg[2], wh[2];
        sb_param_texture_size(p, SB_SIDE_G, &gw, &gh);
        sb_param_texture_size(p, SB_SIDE_H, &hw, &hh);
        sb_param_wrap(p, SB_SIDE_G, wg);
        sb_param_wrap(p, SB_SIDE_H, wh);
        CHECK(sb_param_rows(p) == want[i].rows && sb_param_cols(p) == want[i].cols);
        CHECK(gw * gh == want[i].rows && hw * hh == want[i].cols);
        CHECK(gw == want[i].gw && gh == want[i].gh && hw == want[i].hw && hh == want[i].hh);
        CHECK(wg[0] == want[i].wg[0] && wg[1] == want[i].wg[1] && wh[0] == want[i].wh[0] && wh[1] == want[i].wh[1]);
        CHECKF(strcmp(sb_param_spec(p), want[i].spec) == 0, "spec %s", sb_param_spec(p));
        CHECK(strcmp(sb_param_name(p), sb_param_kind_name(want[i].kind)) == 0);
        sb_param_destroy(p);
    }
}

/* iso's own shape at even R spends R^2 + R texels a term (g + h), as
 * th = R, td = 2R, pd = R/2 did, with th = 2R rows of theta_h. */
SB_TEST(iso_default_texels) {
    for (size_t R = 4; R <= 128; R *= 2) {
        sb_param_t *p = make(SB_PARAM_ISO, R);
        size_t gw, gh, hw, hh;
        sb_param_texture_size(p, SB_SIDE_G, &gw, &gh);
        sb_param_texture_size(p, SB_SIDE_H, &hw, &hh);
        CHECKF(gw * gh + hw * hh == R * R + R && gw == 2 * R && sb_param_rows(p) == 2 * R, "R %zu: %s", R,
               sb_param_spec(p));
        sb_param_destroy(p);
    }
}

SB_TEST(iso_resolutions_per_axis) {
    sb_param_opts_t o = {0};
    o.res = 5;
    o.res_theta_h = 9;
    o.res_phi_d = 3;
    sb_param_t *p;
    CHECK(sb_param_create(NULL, SB_PARAM_ISO, &o, &p) == SB_OK);
    CHECK(sb_param_rows(p) == 9 && sb_param_cols(p) == 24);
    CHECK(strcmp(sb_param_spec(p), "iso:th=9,td=8,pd=3") == 0);
    sb_param_destroy(p);
    o.res_theta_d = 1;
    sb_context_t *ctx;
    sb_context_create(&ctx);
    CHECK(sb_param_create(ctx, SB_PARAM_ISO, &o, &p) == SB_ERR_RANGE && p == NULL);
    CHECK(strstr(sb_context_last_error(ctx), "theta_d") != NULL);
    o.res_theta_d = 0;
    o.res_phi_d = 100000;
    CHECK(sb_param_create(ctx, SB_PARAM_ISO, &o, &p) == SB_ERR_RANGE);
    CHECK(strstr(sb_context_last_error(ctx), "phi_d") != NULL);
    sb_context_destroy(ctx);
}

SB_TEST(parse_spec) {
    const char *specs[] = {"io:res=7",           "io-area:res=12",        "hd:res=5",
                           "iso:th=9,td=5,pd=3", "hd:res=6,theta_max=80", "iso:th=4,td=6,pd=8,theta_max=75"};
    for (size_t i = 0; i < sizeof specs / sizeof specs[0]; i++) {
        sb_param_kind_t k;
        sb_param_opts_t o;
        sb_param_t *p;
        CHECK(sb_param_parse_spec(NULL, specs[i], &k, &o) == SB_OK);
        CHECK(sb_param_create(NULL, k, &o, &p) == SB_OK);
        CHECKF(strcmp(sb_param_spec(p), specs[i]) == 0, "%s -> %s", specs[i], sb_param_spec(p));
        sb_param_destroy(p);
    }
    sb_param_kind_t k;
    sb_param_opts_t o;
    CHECK(sb_param_parse_spec(NULL, "hd", &k, &o) == SB_OK && k == SB_PARAM_HD && o.res == 0);
    CHECK(sb_param_parse_spec(NULL, "hd:", &k, &o) == SB_OK && k == SB_PARAM_HD);
    CHECK(sb_param_parse_spec(NULL, "xy:res=3", &k, &o) == SB_ERR_UNKNOWN);
    CHECK(sb_param_parse_spec(NULL, "hd:th=3", &k, &o) == SB_ERR_UNKNOWN); /* iso keys only */
    CHECK(sb_param_parse_spec(NULL, "io:size=3", &k, &o) == SB_ERR_UNKNOWN);
    CHECK(sb_param_parse_spec(NULL, "io:res", &k, &o) == SB_ERR_PARSE);
    CHECK(sb_param_parse_spec(NULL, "io:=3", &k, &o) == SB_ERR_PARSE);
    CHECK(sb_param_parse_spec(NULL, "io:res=3x", &k, &o) == SB_ERR_PARSE);
    CHECK(sb_param_parse_spec(NULL, "io:res=2.5", &k, &o) == SB_ERR_PARSE);
    CHECK(sb_param_parse_spec(NULL, "io:res=0", &k, &o) == SB_ERR_RANGE);
    CHECK(sb_param_parse_spec(NULL, "io:theta_max=91", &k, &o) == SB_ERR_RANGE);
    CHECK(sb_param_parse_spec(NULL, NULL, &k, &o) == SB_ERR_ARG);
    /* a spec of any length is judged by its content (issue 34): 4000
     * characters of an unknown kind are unknown, io:res=000...08 is res 8 */
    char longspec[4000];
    memset(longspec, 'x', sizeof longspec - 1);
    longspec[sizeof longspec - 1] = 0;
    CHECK(sb_param_parse_spec(NULL, longspec, &k, &o) == SB_ERR_UNKNOWN);
    memset(longspec, '0', sizeof longspec - 1);
    memcpy(longspec, "io:res=", 7);
    longspec[sizeof longspec - 2] = '8';
    CHECK(sb_param_parse_spec(NULL, longspec, &k, &o) == SB_OK && k == SB_PARAM_IO && o.res == 8);
}

/* Cell (r, c) -> its directions -> coords: exactly the texel centres of
 * texel r of g and texel c of h (a round trip through both maps). */
SB_TEST(cell_centres_are_texel_centres) {
    for (size_t i = 0; i < NKINDS; i++) {
        for (int limited = 0; limited < 2; limited++) {
            sb_param_opts_t o = {0};
            o.res = 9;
            o.theta_max = limited ? 70 * SB_PI / 180 : 0;
            sb_param_t *p;
            CHECK(sb_param_create(NULL, all_kinds[i], &o, &p) == SB_OK);
            size_t gw, gh, hw, hh, rows = sb_param_rows(p), cols = sb_param_cols(p), nvalid = 0;
            int wg[2], wh[2];
            sb_param_texture_size(p, SB_SIDE_G, &gw, &gh);
            sb_param_texture_size(p, SB_SIDE_H, &hw, &hh);
            sb_param_wrap(p, SB_SIDE_G, wg);
            sb_param_wrap(p, SB_SIDE_H, wh);
            for (size_t r = 0; r < rows; r++)
                for (size_t c = 0; c < cols; c++) {
                    double wi[3], wo[3], sg[2], sh[2];
                    if (!sb_param_cell_dirs(p, r, c, wi, wo)) continue;
                    nvalid++;
                    CHECK_ABS(dot3(wi, wi), 1, 1e-14);
                    CHECK_ABS(dot3(wo, wo), 1, 1e-14);
                    CHECKF(sb_param_coords(p, wi, wo, sg, sh) == 1, "%s cell %zu %zu", sb_param_spec(p), r, c);
                    CHECK_ABS(st_dist(sg[0], ((r % gw) + 0.5) / gw, wg[0]), 0, 1e-12);
                    CHECK_ABS(st_dist(sg[1], ((r / gw) + 0.5) / gh, wg[1]), 0, 1e-12);
                    CHECK_ABS(st_dist(sh[0], ((c % hw) + 0.5) / hw, wh[0]), 0, 1e-12);
                    CHECK_ABS(st_dist(sh[1], ((c / hw) + 0.5) / hh, wh[1]), 0, 1e-12);
                }
            CHECK(nvalid > rows * cols / 3);
            sb_param_destroy(p);
        }
    }
}

/* A random pair falls in some texel; the directions of that cell are within
 * about one cell of the pair.  For iso the cell has phi_h = 0 and may be the
 * swapped pair (the fold), so the pair is rotated by -phi_h first and both
 * orders are tried.  hd's frame turns fast where h nears T (grazing, along
 * x), so there the bound is checked on 99 % of the pairs only. */
SB_TEST(random_pairs_land_near_their_cell) {
    for (size_t i = 0; i < NKINDS; i++) {
        size_t R = 32;
        sb_param_t *p = make(all_kinds[i], R);
        size_t gw, gh, hw, hh;
        sb_param_texture_size(p, SB_SIDE_G, &gw, &gh);
        sb_param_texture_size(p, SB_SIDE_H, &hw, &hh);
        unsigned long long st = 11 + i;
        int n = 20000, far = 0, used = 0;
        double bound = 1.1 * SB_PI / (double)R, worst = 0;
        for (int k = 0; k < n; k++) {
            double l[3], v[3], sg[2], sh[2], wi[3], wo[3];
            rand_hemi(&st, l);
            rand_hemi(&st, v);
            CHECK(sb_param_coords(p, l, v, sg, sh) == 1);
            CHECK(sg[0] >= 0 && sg[0] <= 1 && sg[1] >= 0 && sg[1] <= 1);
            CHECK(sh[0] >= 0 && sh[0] <= 1 && sh[1] >= 0 && sh[1] <= 1);
            size_t x = (size_t)fmin(sg[0] * gw, gw - 1), y = (size_t)fmin(sg[1] * gh, gh - 1);
            size_t x2 = (size_t)fmin(sh[0] * hw, hw - 1), y2 = (size_t)fmin(sh[1] * hh, hh - 1);
            if (!sb_param_cell_dirs(p, y * gw + x, y2 * hw + x2, wi, wo)) {
                /* only layouts with a partial domain have invalid cells, on the horizon's edge */
                CHECK(sb_param_caps(p) & SB_CAP_PARTIAL_DOMAIN);
                continue;
            }
            used++;
            double d;
            if (all_kinds[i] == SB_PARAM_ISO) {
                double ph = atan2(l[1] + v[1], l[0] + v[0]), c = cos(ph), s = sin(ph);
                double l2[3] = {c * l[0] + s * l[1], -s * l[0] + c * l[1], l[2]};
                double v2[3] = {c * v[0] + s * v[1], -s * v[0] + c * v[1], v[2]};
                d = fmin(fmax(dist3(l2, wi), dist3(v2, wo)), fmax(dist3(v2, wi), dist3(l2, wo)));
            } else if (all_kinds[i] == SB_PARAM_VH) { /* V at phi = 0, phi folded by the mirror y -> -y */
                double ph = atan2(v[1], v[0]), c = cos(ph), s = sin(ph);
                double l2[3] = {c * l[0] + s * l[1], -s * l[0] + c * l[1], l[2]};
                double v2[3] = {c * v[0] + s * v[1], -s * v[0] + c * v[1], v[2]};
                double l3[3] = {l2[0], -l2[1], l2[2]}, v3[3] = {v2[0], -v2[1], v2[2]};
                d = fmin(fmax(dist3(l2, wi), dist3(v2, wo)), fmax(dist3(l3, wi), dist3(v3, wo)));
            } else {
                d = fmax(dist3(l, wi), dist3(v, wo));
            }
            /* vh: a phi cell of pi / (R/2) moves h by up to that, and L twice as far */
            if (d > bound * (all_kinds[i] == SB_PARAM_HD ? 1.5 : all_kinds[i] == SB_PARAM_VH ? 4 : 1)) far++;
            if (d > worst) worst = d;
        }
        CHECK(used > n * 9 / 10);
        CHECKF(all_kinds[i] == SB_PARAM_HD ? far <= used / 100 : far == 0, "%s: %d of %d pairs far, worst %g",
               sb_param_spec(p), far, used, worst);
        sb_param_destroy(p);
    }
}

/* Row and column measures sum to their domains; over valid cells the
 * products approximate the (wi, wo) integrals: of 1, (2pi)^2, and of
 * cos cos, pi^2 (smooth at the horizon: second-order accurate). */
SB_TEST(measures) {
    for (size_t i = 0; i < NKINDS; i++) {
        sb_param_t *p = make(all_kinds[i], 24);
        int hd_like = all_kinds[i] == SB_PARAM_HD || all_kinds[i] == SB_PARAM_ISO;
        if (all_kinds[i] == SB_PARAM_VH) { /* columns weigh dw_h by 4 cos theta_h: V.h at the normal view */
            double sc = 0;
            for (size_t c = 0; c < sb_param_cols(p); c++)
                sc += sb_param_col_measure(p, c);
            CHECK_REL(sc, 4 * SB_PI, 2e-3);
            sb_param_destroy(p);
            continue;
        }
        size_t rows = sb_param_rows(p), cols = sb_param_cols(p);
        double sr = 0, sc = 0, s1 = 0, scos = 0;
        for (size_t r = 0; r < rows; r++)
            sr += sb_param_row_measure(p, r);
        for (size_t c = 0; c < cols; c++)
            sc += sb_param_col_measure(p, c);
        CHECK_REL(sr, 2 * SB_PI, 1e-12);
        CHECK_REL(sc, hd_like ? 4 * SB_PI : 2 * SB_PI, 1e-12); /* int 4 cos over the hemisphere */
        for (size_t r = 0; r < rows; r++)
            for (size_t c = 0; c < cols; c++) {
                double wi[3], wo[3];
                if (!sb_param_cell_dirs(p, r, c, wi, wo)) continue;
                double m = sb_param_row_measure(p, r) * sb_param_col_measure(p, c);
                CHECK(m > 0);
                s1 += m;
                scos += m * wi[2] * wo[2];
            }
        CHECK_REL(s1, 4 * SB_PI * SB_PI, hd_like ? 0.01 : 1e-11);
        /* io-area's midpoint rule sees the concentric map's kinks on the diagonals */
        CHECK_REL(scos, SB_PI * SB_PI, all_kinds[i] == SB_PARAM_IO_AREA ? 1e-2 : 2e-3);
        sb_param_destroy(p);
    }
    /* io-area: every cell the same solid angle, also on a cap */
    sb_param_opts_t o = {0};
    o.res = 5;
    o.theta_max = SB_PI / 3;
    sb_param_t *p;
    CHECK(sb_param_create(NULL, SB_PARAM_IO_AREA, &o, &p) == SB_OK);
    for (size_t k = 0; k < 25; k++)
        CHECK_REL(sb_param_row_measure(p, k), 2 * SB_PI * 0.5 / 25, 1e-14);
    sb_param_destroy(p);
}

/* Independent construction of the hd / iso cell directions (written out
 * from the formulas, not the library's algebra): the cell is valid exactly
 * when both directions are above the horizon (and in the cap). */
static void ref_hd_cell(size_t R, double tmax, size_t row, size_t col, double l[3], double v[3]) {
    double th = (row % R + 0.5) * tmax / R, ph = (row / R + 0.5) * 2 * SB_PI / R;
    double td = (col % R + 0.5) * tmax / R, pd = (col / R + 0.5) * 2 * SB_PI / R;
    double h[3] = {sin(th) * cos(ph), sin(th) * sin(ph), cos(th)};
    double d[3] = {sin(td) * cos(pd), sin(td) * sin(pd), cos(td)};
    double T[3] = {1, 0, 0}, t[3], b[3], th_ = dot3(T, h);
    for (int k = 0; k < 3; k++)
        t[k] = T[k] - th_ * h[k];
    normalize3(t);
    cross3(h, t, b);
    for (int k = 0; k < 3; k++)
        l[k] = d[0] * t[k] + d[1] * b[k] + d[2] * h[k];
    double hl = dot3(h, l);
    for (int k = 0; k < 3; k++)
        v[k] = 2 * hl * h[k] - l[k];
}
/* Rusinkiewicz inverse: rotate d by theta_h about the binormal y, phi_h = 0;
 * v is l reflected about h. */
static void ref_iso_cell(size_t th_n, size_t td_n, size_t pd_n, double tmax, size_t row, size_t col, double l[3],
                         double v[3]) {
    double u = (row + 0.5) / th_n, th = u * u * tmax, td = (col % td_n + 0.5) * tmax / td_n; /* MERL sqrt rows */
    double pd = (col / td_n + 0.5) * SB_PI / pd_n;
    double d[3] = {sin(td) * cos(pd), sin(td) * sin(pd), cos(td)};
    double Ry[3][3] = {{cos(th), 0, sin(th)}, {0, 1, 0}, {-sin(th), 0, cos(th)}};
    for (int k = 0; k < 3; k++)
        l[k] = Ry[k][0] * d[0] + Ry[k][1] * d[1] + Ry[k][2] * d[2];
    double h[3] = {sin(th), 0, cos(th)}, hl = dot3(h, l);
    for (int k = 0; k < 3; k++)
        v[k] = 2 * hl * h[k] - l[k];
}

SB_TEST(invalid_cells_are_below_the_horizon) {
    for (int limited = 0; limited < 2; limited++) {
        double tmax = limited ? 80 * SB_PI / 180 : SB_PI / 2;
        sb_param_opts_t o = {0};
        o.res = 12;
        o.theta_max = tmax;
        sb_param_t *hd, *iso;
        CHECK(sb_param_create(NULL, SB_PARAM_HD, &o, &hd) == SB_OK);
        o.res_theta_h = 12;
        o.res_theta_d = 24;
        o.res_phi_d = 17;
        CHECK(sb_param_create(NULL, SB_PARAM_ISO, &o, &iso) == SB_OK);
        size_t nvalid[2] = {0, 0}, ncells[2] = {144 * 144, 12 * 24 * 17};
        for (int which = 0; which < 2; which++) {
            sb_param_t *p = which ? iso : hd;
            for (size_t r = 0; r < sb_param_rows(p); r++)
                for (size_t c = 0; c < sb_param_cols(p); c++) {
                    double wi[3], wo[3], l[3], v[3];
                    int ok = sb_param_cell_dirs(p, r, c, wi, wo);
                    if (which)
                        ref_iso_cell(12, 24, 17, tmax, r, c, l, v);
                    else
                        ref_hd_cell(12, tmax, r, c, l, v);
                    int above = l[2] > 0 && v[2] > 0 && acos(l[2]) <= tmax && acos(v[2]) <= tmax;
                    CHECKF(ok == above, "%s cell %zu %zu: %d, l_z %g v_z %g", sb_param_spec(p), r, c, ok, l[2], v[2]);
                    CHECK(dist3(wi, l) < 1e-13 && dist3(wo, v) < 1e-13);
                    nvalid[which] += (size_t)ok;
                }
        }
        /* a bit over half of the (h, d) square is a BRDF pair (more in iso, whose
         * square-root theta_h rows crowd near the normal) */
        for (int which = 0; which < 2; which++)
            CHECKF(nvalid[which] > ncells[which] / 3 && nvalid[which] < ncells[which] * 17 / 20, "%zu of %zu valid",
                   nvalid[which], ncells[which]);
        sb_param_destroy(hd);
        sb_param_destroy(iso);
    }
}

/* ---- independent coordinate formulas (from REFERENCE.md) --------------- */

static double ref_phi(const double w[3]) {
    double ph = atan2(w[1], w[0]);
    return ph < 0 ? ph + 2 * SB_PI : ph;
}
static void ref_coords(sb_param_kind_t kind, const double l[3], const double v[3], double sg[2], double sh[2]) {
    double h[3] = {l[0] + v[0], l[1] + v[1], l[2] + v[2]};
    normalize3(h);
    if (kind == SB_PARAM_IO) {
        sg[0] = acos(l[2]) / (SB_PI / 2), sg[1] = ref_phi(l) / (2 * SB_PI);
        sh[0] = acos(v[2]) / (SB_PI / 2), sh[1] = ref_phi(v) / (2 * SB_PI);
    } else if (kind == SB_PARAM_IO_AREA) {
        /* Shirley-Chiu's inverse by octant region, r = sqrt(1 - cos theta) */
        const double *w[2] = {l, v};
        double *out[2] = {sg, sh};
        for (int k = 0; k < 2; k++) {
            double r = sqrt(1 - w[k][2]), ph = atan2(w[k][1], w[k][0]), a, b;
            if (ph < -SB_PI / 4) ph += 2 * SB_PI; /* [-pi/4, 7pi/4) */
            if (ph < SB_PI / 4) {
                a = r, b = ph * 4 / SB_PI * r;
            } else if (ph < 3 * SB_PI / 4) {
                b = r, a = -(ph - SB_PI / 2) * 4 / SB_PI * r;
            } else if (ph < 5 * SB_PI / 4) {
                a = -r, b = -(ph - SB_PI) * 4 / SB_PI * r;
            } else {
                b = -r, a = (ph - 3 * SB_PI / 2) * 4 / SB_PI * r;
            }
            out[k][0] = (a + 1) / 2, out[k][1] = (b + 1) / 2;
        }
    } else if (kind == SB_PARAM_HD) {
        double T[3] = {1, 0, 0}, t[3], b[3], th = dot3(T, h);
        for (int k = 0; k < 3; k++)
            t[k] = T[k] - th * h[k];
        normalize3(t);
        cross3(h, t, b);
        double d[3] = {dot3(l, t), dot3(l, b), dot3(l, h)};
        sg[0] = acos(h[2]) / (SB_PI / 2), sg[1] = ref_phi(h) / (2 * SB_PI);
        sh[0] = acos(d[2]) / (SB_PI / 2), sh[1] = ref_phi(d) / (2 * SB_PI);
    } else if (kind == SB_PARAM_VH) {
        /* explicit angles: |phi_h - phi_v| brought into [0, pi] */
        double dp = fabs(ref_phi(h) - ref_phi(v));
        if (dp > SB_PI) dp = 2 * SB_PI - dp;
        sg[0] = acos(v[2]) / (SB_PI / 2), sg[1] = 0.5;
        sh[0] = sqrt(acos(h[2]) / (SB_PI / 2)), sh[1] = dp / SB_PI;
    } else {
        /* d = Ry(-theta_h) Rz(-phi_h) l with explicit angles */
        double th = acos(h[2]), ph = atan2(h[1], h[0]);
        double x1 = cos(-ph) * l[0] - sin(-ph) * l[1], y1 = sin(-ph) * l[0] + cos(-ph) * l[1], z1 = l[2];
        double d[3] = {cos(-th) * x1 + sin(-th) * z1, y1, -sin(-th) * x1 + cos(-th) * z1};
        double pd = fmod(atan2(d[1], d[0]) + 2 * SB_PI, SB_PI);
        sg[0] = sqrt(th / (SB_PI / 2)), sg[1] = 0.5;
        sh[0] = acos(d[2]) / (SB_PI / 2), sh[1] = pd / SB_PI;
    }
}

SB_TEST(coords_match_independent_formulas) {
    for (size_t i = 0; i < NKINDS; i++) {
        sb_param_t *p = make(all_kinds[i], 16);
        int wg[2], wh[2];
        sb_param_wrap(p, SB_SIDE_G, wg);
        sb_param_wrap(p, SB_SIDE_H, wh);
        unsigned long long st = 99 + i;
        for (int k = 0; k < 20000; k++) {
            double l[3], v[3], sg[2], sh[2], rg[2], rh[2];
            rand_hemi(&st, l);
            rand_hemi(&st, v);
            CHECK(sb_param_coords(p, l, v, sg, sh) == 1);
            ref_coords(all_kinds[i], l, v, rg, rh);
            for (int a = 0; a < 2; a++) {
                CHECKF(st_dist(sg[a], rg[a], wg[a]) < 1e-9, "%s g[%d] %.17g vs %.17g", sb_param_spec(p), a, sg[a],
                       rg[a]);
                CHECKF(st_dist(sh[a], rh[a], wh[a]) < 1e-9, "%s h[%d] %.17g vs %.17g", sb_param_spec(p), a, sh[a],
                       rh[a]);
            }
            if (sb_test_failed_now() > 10) break;
        }
        sb_param_destroy(p);
    }
}

/* io-area: coords inverts the forward concentric map written out here. */
SB_TEST(io_area_inverts_concentric_map) {
    sb_param_t *p = make(SB_PARAM_IO_AREA, 8);
    unsigned long long st = 5;
    for (int k = 0; k < 5000; k++) {
        double l[3], v[3], sg[2], sh[2];
        rand_hemi(&st, l);
        rand_hemi(&st, v);
        CHECK(sb_param_coords(p, l, v, sg, sh) == 1);
        double a = 2 * sg[0] - 1, b = 2 * sg[1] - 1, r, ph;
        if (a * a > b * b)
            r = a, ph = SB_PI / 4 * (b / a);
        else
            r = b, ph = SB_PI / 2 - SB_PI / 4 * (a / b);
        /* disk (r, ph) -> hemisphere, z = 1 - r^2 */
        double s = r * sqrt(2 - r * r), w[3] = {s * cos(ph), s * sin(ph), 1 - r * r};
        CHECK(dist3(w, l) < 1e-12);
    }
    /* the rim of the square is the horizon, the centre the normal */
    double n[3] = {0, 0, 1}, sg[2], sh[2];
    CHECK(sb_param_coords(p, n, n, sg, sh) == 1 && sg[0] == 0.5 && sg[1] == 0.5);
    double g[3] = {1e-9, 1, 1e-12};
    normalize3(g);
    CHECK(sb_param_coords(p, g, n, sg, sh) == 1);
    CHECK_ABS(sg[1], 1, 1e-6);
    sb_param_destroy(p);
}

/* Degenerate pairs: finite coordinates in [0, 1], the documented
 * conventions, and the domain test. */
SB_TEST(degenerate_pairs) {
    double s45 = sqrt(0.5);
    const double pairs[][2][3] = {
        {{0, 0, 1}, {0, 0, 1}},           /* l = v = n: theta_h = theta_d = 0 */
        {{0.6, 0, 0.8}, {0.6, 0, 0.8}},   /* l = v: theta_d = 0 */
        {{0.6, 0, 0.8}, {-0.6, 0, 0.8}},  /* h = n: theta_h = 0 */
        {{s45, s45, 0}, {s45, s45, 0}},   /* grazing */
        {{1, 0, 0}, {1, 0, 0}},           /* h = T: hd frame fallback */
        {{-1, 0, 0}, {-1, 0, 0}},         /* h = -T */
        {{1, 0, 0}, {-1, 0, 0}},          /* l = -v on the horizon: h undefined */
        {{0.6, 0, 0.8}, {-0.6, 0, -0.8}}, /* l = -v */
        {{0, 0, 1}, {0, 0, -1}},          {{0, 1e-300, 1}, {0, 0, 1}}, {{1e-170, 0, 1}, {-1e-170, 0, 1}},
    };
    const int inside[] = {1, 1, 1, 0, 0, 0, 0, 0, 0, 1, 1};
    for (size_t i = 0; i < NKINDS; i++) {
        sb_param_t *p = make(all_kinds[i], 8);
        for (size_t k = 0; k < sizeof pairs / sizeof pairs[0]; k++) {
            double sg[2] = {NAN, NAN}, sh[2] = {NAN, NAN};
            int ok = sb_param_coords(p, pairs[k][0], pairs[k][1], sg, sh);
            CHECKF(ok == inside[k], "%s pair %zu: %d", sb_param_spec(p), k, ok);
            if (all_kinds[i] == SB_PARAM_IO && !ok) continue; /* io leaves st unset */
            for (int a = 0; a < 2; a++)
                CHECKF(isfinite(sg[a]) && isfinite(sh[a]) && sg[a] >= 0 && sg[a] <= 1 && sh[a] >= 0 && sh[a] <= 1,
                       "%s pair %zu: st %g %g %g %g", sb_param_spec(p), k, sg[0], sg[1], sh[0], sh[1]);
        }
        sb_param_destroy(p);
    }
    /* iso conventions: theta_h = 0 -> phi_h = 0, so d = l and phi_d = phi_l
     * mod pi; theta_d = 0 -> phi_d = 0. */
    sb_param_t *p = make(SB_PARAM_ISO, 8);
    double sg[2], sh[2];
    double l[3] = {0.48, 0.36, 0.8}, v[3] = {-0.48, -0.36, 0.8};
    CHECK(sb_param_coords(p, l, v, sg, sh) == 1);
    CHECK(sg[0] == 0);
    CHECK_ABS(sh[0], acos(0.8) / (SB_PI / 2), 1e-15);
    CHECK_ABS(sh[1], atan2(0.36, 0.48) / SB_PI, 1e-15);
    CHECK(sb_param_coords(p, v, l, sg, sh) == 1); /* swapped: same folded phi_d */
    CHECK_ABS(sh[1], atan2(0.36, 0.48) / SB_PI, 1e-15);
    CHECK(sb_param_coords(p, l, l, sg, sh) == 1 && sh[0] == 0 && sh[1] == 0);
    sb_param_destroy(p);
    /* hd: same conventions for phi of h and d at the poles */
    p = make(SB_PARAM_HD, 8);
    CHECK(sb_param_coords(p, l, l, sg, sh) == 1 && sh[0] == 0 && sh[1] == 0);
    sb_param_destroy(p);
}

/* Reciprocity and isotropy: iso coords do not change when the pair is
 * swapped or rotated about the normal. */
SB_TEST(iso_invariances) {
    sb_param_t *p = make(SB_PARAM_ISO, 10);
    unsigned long long st = 3;
    for (int k = 0; k < 2000; k++) {
        double l[3], v[3], sg[2], sh[2], sg2[2], sh2[2];
        rand_hemi(&st, l);
        rand_hemi(&st, v);
        CHECK(sb_param_coords(p, l, v, sg, sh) == 1);
        CHECK(sb_param_coords(p, v, l, sg2, sh2) == 1);
        CHECK_ABS(sg2[0], sg[0], 1e-12);
        CHECK_ABS(sh2[0], sh[0], 1e-12);
        CHECK_ABS(st_dist(sh2[1], sh[1], SB_WRAP_REPEAT), 0, 1e-9);
        double a = 2 * SB_PI * sb_rand01(&st), c = cos(a), s = sin(a);
        double l2[3] = {c * l[0] - s * l[1], s * l[0] + c * l[1], l[2]};
        double v2[3] = {c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]};
        CHECK(sb_param_coords(p, l2, v2, sg2, sh2) == 1);
        CHECK_ABS(sg2[0], sg[0], 1e-12);
        CHECK_ABS(sh2[0], sh[0], 1e-12);
        CHECK_ABS(st_dist(sh2[1], sh[1], SB_WRAP_REPEAT), 0, 1e-9);
    }
    sb_param_destroy(p);
}

/* theta_max limits the domain: pairs beyond it are outside, and the grids
 * span [0, theta_max]. */
SB_TEST(theta_max_cap) {
    for (size_t i = 1; i < NKINDS; i++) {
        sb_param_opts_t o = {0};
        o.res = 6;
        o.theta_max = SB_PI / 3;
        sb_param_t *p;
        CHECK(sb_param_create(NULL, all_kinds[i], &o, &p) == SB_OK);
        CHECK(strstr(sb_param_spec(p), ",theta_max=60") != NULL);
        double in[3] = {sin(1.0), 0, cos(1.0)}, out[3] = {sin(1.1), 0, cos(1.1)}, sg[2], sh[2];
        CHECK(sb_param_coords(p, in, in, sg, sh) == 1);
        CHECK(sb_param_coords(p, out, in, sg, sh) == 0);
        CHECK(sb_param_coords(p, in, out, sg, sh) == 0);
        sb_param_destroy(p);
    }
}

/* The registry: every kind parses back from its name and is listed; the
 * capabilities hold as geometric facts (separable coordinates, a partial
 * domain), and NEEDS_ISOTROPY decides which sources a kind applies to. */
SB_TEST(registry_caps) {
    char list[256];
    size_t n = sb_param_kind_list(list, sizeof list, ", ");
    CHECK(n == strlen(list) && n > 0 && sb_param_kind_count() >= 5);
    char tiny[4];
    CHECK(sb_param_kind_list(tiny, sizeof tiny, ", ") == n && strlen(tiny) == 3);
    for (int k = 0; k < (int)sb_param_kind_count(); k++) {
        sb_param_kind_t back;
        const char *name = sb_param_kind_name((sb_param_kind_t)k);
        CHECK(sb_param_kind_parse(name, &back) == SB_OK && back == (sb_param_kind_t)k);
        CHECK(strstr(list, name) != NULL && strlen(sb_param_kind_description((sb_param_kind_t)k)) > 0);
        unsigned caps = sb_param_kind_caps((sb_param_kind_t)k);
        if (caps & SB_CAP_TABLES) { /* built on a source's tables: test_vndf.c */
            CHECK(!sb_param_kind_applies((sb_param_kind_t)k, SB_SOURCE_ISOTROPIC));
            continue;
        }
        CHECK(sb_param_kind_applies((sb_param_kind_t)k, SB_SOURCE_ISOTROPIC));
        CHECK(sb_param_kind_applies((sb_param_kind_t)k, 0) == !(caps & SB_CAP_NEEDS_ISOTROPY));
        sb_param_opts_t o = {0};
        o.res = 5;
        sb_param_t *p;
        CHECK(sb_param_create(NULL, (sb_param_kind_t)k, &o, &p) == SB_OK);
        CHECK(sb_param_caps(p) == caps);
        size_t outside = 0;
        double wi[3], wo[3];
        for (size_t r = 0; r < sb_param_rows(p); r++)
            for (size_t c = 0; c < sb_param_cols(p); c++)
                outside += !sb_param_cell_dirs(p, r, c, wi, wo);
        CHECKF((outside > 0) == !!(caps & SB_CAP_PARTIAL_DOMAIN), "%s: %zu cells outside", name, outside);
        /* separable: st_g follows wi alone and st_h wo alone */
        double a[3] = {0.3, 0.2, 0.93}, b[3] = {-0.5, 0.1, 0.86}, c2[3] = {0.1, -0.6, 0.79};
        double g1[2], h1[2], g2[2], h2[2], g3[2], h3[2];
        CHECK(sb_param_coords(p, a, b, g1, h1) && sb_param_coords(p, a, c2, g2, h2) &&
              sb_param_coords(p, c2, b, g3, h3));
        int sep = g1[0] == g2[0] && g1[1] == g2[1] && h1[0] == h3[0] && h1[1] == h3[1];
        CHECKF(sep == !!(caps & SB_CAP_SEPARABLE), "%s: separable %d", name, sep);
        sb_param_destroy(p);
    }
    sb_param_kind_t past = (sb_param_kind_t)sb_param_kind_count();
    CHECK(sb_param_kind_caps(past) == 0 && !sb_param_kind_applies(past, ~0u));
    CHECK(sb_param_kind_caps(SB_PARAM_NONE) == 0 && !sb_param_kind_applies(SB_PARAM_NONE, ~0u));
}

/* The domain's edge: on the whole hemisphere (theta_max 90 degrees) a
 * direction is in exactly when its z > 0, however close to grazing; under
 * a smaller theta_max the angle decides.  Every kind, both sides. */
SB_TEST(domain_edge_at_grazing) {
    for (int kind = 0; kind < SB_TEST_KINDS; kind++)
        for (int capped = 0; capped < 2; capped++) {
            sb_param_opts_t o = {0};
            o.res = 8;
            if (capped) o.theta_max = 80 * SB_PI / 180;
            sb_param_t *p;
            CHECK(sb_param_create(NULL, (sb_param_kind_t)kind, &o, &p) == SB_OK);
            double in[3] = {0.3, 0.2, 0.9}, sg[2], sh[2];
            double n = sqrt(in[0] * in[0] + in[1] * in[1] + in[2] * in[2]);
            for (int i = 0; i < 3; i++)
                in[i] /= n;
            const double zs[] = {1e-300, 1e-17, 1e-9, 0.0, -1e-300, -1e-9};
            for (size_t k = 0; k < sizeof zs / sizeof zs[0]; k++) {
                double c = sqrt(1 - zs[k] * zs[k]), w[3] = {0.6 * c, 0.8 * c, zs[k]};
                int want = zs[k] > 0 && !capped;
                CHECK(sb_param_coords(p, w, in, sg, sh) == want);
                CHECK(sb_param_coords(p, in, w, sg, sh) == want);
            }
            for (int deg = 70; deg <= 89; deg += 19) { /* 70: inside the cap, 89: outside it */
                double t = deg * SB_PI / 180, w[3] = {sin(t), 0, cos(t)};
                int want = !capped || deg < 80;
                CHECK(sb_param_coords(p, w, in, sg, sh) == want);
                CHECK(sb_param_coords(p, in, w, sg, sh) == want);
            }
            sb_param_destroy(p);
        }
}
