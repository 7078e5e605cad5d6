/* CPU renderer, images, PNG, texture previews and `sepbrdf render`. */
#include <png.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"

#define GOLD "microfacet:base=gold,roughness=0.5"

static char out[65536];

static double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static sb_result_t factor(const char *spec, sb_param_kind_t kind, size_t res, size_t J, sb_form_t form,
                          sb_param_t **param, sb_factors_t **f) {
    sb_source_t *src = NULL;
    sb_matrix_t m = {0};
    sb_plan_t *plan = NULL;
    sb_param_opts_t po = {0};
    po.res = res;
    *f = NULL;
    sb_result_t r = sb_param_create(NULL, kind, &po, param);
    if (r) return r;
    sb_plan_opts_t pl = {0};
    pl.terms = J;
    sb_matrix_opts_t mo = {0};
    mo.form = form;
    if (!(r = sb_source_open(NULL, spec, &src)) && !(r = sb_matrix_build(NULL, src, *param, &mo, &m)) &&
        !(r = sb_plan_create(NULL, m.rows, m.cols, &pl, &plan)))
        r = sb_plan_execute(plan, &m, *param, f);
    sb_plan_destroy(plan);
    sb_matrix_free(&m);
    sb_source_destroy(src);
    return r;
}

/* ---- scene ----------------------------------------------------------- */

/* The frame is orthonormal, right-handed and t is dP/dphi of the sphere
 * with its pole on +y, by finite differences of P(theta, phi). */
SB_TEST(frame) {
    sb_render_opts_t o = {0};
    o.size = 64;
    size_t covered = 0;
    for (size_t y = 0; y < 64; y++)
        for (size_t x = 0; x < 64; x++) {
            double n[3], t[3], b[3];
            if (!sb_render_frame(&o, x, y, n, t, b)) continue;
            covered++;
            CHECK_ABS(dot3(n, n), 1, 1e-12);
            CHECK_ABS(dot3(t, t), 1, 1e-12);
            CHECK_ABS(dot3(b, b), 1, 1e-12);
            CHECK_ABS(dot3(n, t), 0, 1e-12);
            CHECK_ABS(dot3(n, b), 0, 1e-12);
            double c[3] = {t[1] * b[2] - t[2] * b[1], t[2] * b[0] - t[0] * b[2], t[0] * b[1] - t[1] * b[0]};
            CHECK_ABS(dot3(c, n), 1, 1e-12); /* t x b = n */
            double th = acos(n[1]), ph = atan2(n[0], n[2]), h = 1e-6;
            double p1[3] = {sin(th) * sin(ph + h), cos(th), sin(th) * cos(ph + h)};
            double p0[3] = {sin(th) * sin(ph - h), cos(th), sin(th) * cos(ph - h)};
            double d[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
            double len = sqrt(dot3(d, d));
            CHECK_ABS(dot3(d, t) / len, 1, 1e-8);
            /* the pixel centre is where render.h says */
            double px = (2 * (x + 0.5) / 64 - 1) * SB_RENDER_EXTENT, py = (1 - 2 * (y + 0.5) / 64) * SB_RENDER_EXTENT;
            CHECK_ABS(n[0], px, 1e-15);
            CHECK_ABS(n[1], py, 1e-15);
        }
    /* the disc covers pi / (4 e^2) of the image */
    CHECK_REL((double)covered / (64.0 * 64.0), SB_PI / (4 * SB_RENDER_EXTENT * SB_RENDER_EXTENT), 0.02);
    double n[3], t[3], b[3];
    CHECK(sb_render_frame(&o, 32, 32, n, t, b) == 1);
    CHECK(t[0] > 0.999 && b[1] > 0.999); /* centre: t right, b up */
    CHECK(sb_render_frame(&o, 0, 0, n, t, b) == 0);
}

/* Lambert: radiance = albedo/pi * E * max(n.L, 0) with E = pi by default. */
SB_TEST(lambert_formula) {
    sb_source_t *src;
    CHECK(sb_source_open(NULL, "lambert:albedo=0.8", &src) == SB_OK);
    sb_render_opts_t o = {0};
    o.size = 48;
    sb_image_t img;
    CHECK(sb_render_source(NULL, &o, src, &img) == SB_OK);
    CHECK(img.width == 48 && img.height == 48);
    sb_light_t l;
    sb_light_from_angles(45, 45, 0, &l);
    for (size_t y = 0; y < 48; y++)
        for (size_t x = 0; x < 48; x++) {
            double n[3], t[3], b[3];
            size_t i = y * 48 + x;
            int cov = sb_render_frame(&o, x, y, n, t, b);
            CHECK(img.mask[i] == cov);
            double want = cov ? 0.8 * fmax(dot3(n, l.dir), 0) : 0;
            for (int c = 0; c < 3; c++)
                CHECK_ABS(img.rgb[3 * i + c], want, 1e-12);
        }
    sb_image_free(&img);
    sb_source_destroy(src);
}

/* Radiance is linear in the lights: two lights render as the sum. */
SB_TEST(lights_add) {
    sb_source_t *src;
    CHECK(sb_source_open(NULL, GOLD, &src) == SB_OK);
    sb_render_opts_t a = {0}, b = {0}, ab = {0};
    a.size = b.size = ab.size = 40;
    a.light_count = b.light_count = 1;
    ab.light_count = 2;
    sb_light_from_angles(30, 10, 1, &a.lights[0]);
    sb_light_from_angles(60, 250, 2, &b.lights[0]);
    ab.lights[0] = a.lights[0];
    ab.lights[1] = b.lights[0];
    ab.lights[1].dir[0] *= 3; /* directions are normalised */
    ab.lights[1].dir[1] *= 3;
    ab.lights[1].dir[2] *= 3;
    sb_image_t ia, ib, iab;
    CHECK(sb_render_source(NULL, &a, src, &ia) == SB_OK);
    CHECK(sb_render_source(NULL, &b, src, &ib) == SB_OK);
    CHECK(sb_render_source(NULL, &ab, src, &iab) == SB_OK);
    double m = 0;
    for (size_t i = 0; i < 40 * 40 * 3; i++)
        m = fmax(m, fabs(ia.rgb[i] + ib.rgb[i] - iab.rgb[i]));
    CHECK(m < 1e-12);
    CHECK(sb_image_max(&iab) > 0);
    sb_image_free(&ia);
    sb_image_free(&ib);
    sb_image_free(&iab);
    sb_source_destroy(src);
}

/* A rank-1 BRDF is reconstructed exactly by one term: Lambert in every
 * parameterisation of this build, form f (constant textures, so bilinear
 * lookups are exact too; the cos forms interpolate cos theta between cell
 * centres and are exact only there). */
SB_TEST(lambert_one_term_exact) {
    sb_source_t *src;
    CHECK(sb_source_open(NULL, "lambert:albedo=0.6", &src) == SB_OK);
    sb_render_opts_t o = {0};
    o.size = 64;
    sb_image_t orig;
    CHECK(sb_render_source(NULL, &o, src, &orig) == SB_OK);
    for (int k = 0; k < SB_TEST_KINDS; k++) {
        sb_param_t *p = NULL;
        sb_factors_t *f = NULL;
        sb_result_t r = factor("lambert:albedo=0.6", (sb_param_kind_t)k, 16, 1, SB_FORM_F, &p, &f);
        if (r == SB_ERR_UNSUPPORTED) {
            sb_param_destroy(p);
            continue;
        }
        CHECK(r == SB_OK);
        sb_image_t rec;
        CHECK(sb_render_factors(NULL, &o, f, p, SB_FORM_F, 1, &rec) == SB_OK);
        sb_tonemap_t tm = {1 / sb_image_max(&orig), SB_TONEMAP_CLAMP};
        sb_image_diff_t d;
        CHECK(sb_image_compare(NULL, &orig, &rec, &tm, &d) == SB_OK);
        /* exact up to rounding, or to the masked fit's tolerance for
         * parameterisations with cells outside the domain */
        CHECKF(d.rmse_linear < 1e-8 * sb_image_max(&orig) && (isinf(d.psnr) || d.psnr > 150), "%s: rmse %g, PSNR %g",
               sb_param_spec(p), d.rmse_linear, d.psnr);
        CHECK(d.pixels > 0);
        sb_image_free(&rec);
        sb_factors_destroy(f);
        sb_param_destroy(p);
    }
    sb_image_free(&orig);
    sb_source_destroy(src);
}

/* The default gold: the display PSNR against the original rises with J
 * (as `sepbrdf render` shows it: exposure 1 / peak, clamp, sRGB). */
SB_TEST(psnr_rises_with_terms) {
    sb_param_t *p;
    sb_factors_t *f;
    CHECK(factor(GOLD, SB_PARAM_IO, 32, 16, SB_FORM_F, &p, &f) == SB_OK);
    sb_source_t *src;
    CHECK(sb_source_open(NULL, GOLD, &src) == SB_OK);
    sb_render_opts_t o = {0};
    o.size = 128;
    sb_image_t orig;
    CHECK(sb_render_source(NULL, &o, src, &orig) == SB_OK);
    sb_tonemap_t tm = {1 / sb_image_max(&orig), SB_TONEMAP_CLAMP};
    static const size_t Js[4] = {1, 2, 4, 16};
    double prev = 0, prev_lin = INFINITY;
    for (int i = 0; i < 4; i++) {
        sb_image_t rec;
        sb_image_diff_t d;
        CHECK(sb_render_factors(NULL, &o, f, p, SB_FORM_F, Js[i], &rec) == SB_OK);
        CHECK(sb_image_compare(NULL, &orig, &rec, &tm, &d) == SB_OK);
        printf("  J=%2zu  PSNR %.2f dB  rmse_linear %.4g\n", Js[i], d.psnr, d.rmse_linear);
        CHECKF(d.psnr > prev, "J=%zu: PSNR %.2f not above %.2f", Js[i], d.psnr, prev);
        CHECKF(d.rmse_linear < prev_lin, "J=%zu: linear RMSE %.4g not below %.4g", Js[i], d.rmse_linear, prev_lin);
        prev = d.psnr;
        prev_lin = d.rmse_linear;
        sb_image_free(&rec);
    }
    sb_image_free(&orig);
    sb_source_destroy(src);
    sb_factors_destroy(f);
    sb_param_destroy(p);
}

static int eval_zero(const void *user, const double wi[3], const double wo[3], double rgb[3]) {
    (void)user, (void)wi, (void)wo;
    rgb[0] = rgb[1] = rgb[2] = 0;
    return 1;
}

SB_TEST(render_errors) {
    sb_context_t *ctx;
    CHECK(sb_context_create(&ctx) == SB_OK);
    sb_image_t img;
    sb_render_opts_t o = {0};
    CHECK(sb_render(ctx, &o, NULL, NULL, &img) == SB_ERR_ARG);
    CHECK(sb_render(ctx, &o, eval_zero, NULL, NULL) == SB_ERR_ARG);
    o.size = 20000;
    CHECK(sb_render(ctx, &o, eval_zero, NULL, &img) == SB_ERR_RANGE);
    CHECK(strstr(sb_context_last_error(ctx), "size") != NULL);
    o.size = 8;
    o.light_count = SB_RENDER_MAX_LIGHTS + 1;
    CHECK(sb_render(ctx, &o, eval_zero, NULL, &img) == SB_ERR_ARG);
    o.light_count = 1; /* lights[0] all zero: no direction */
    CHECK(sb_render(ctx, &o, eval_zero, NULL, &img) == SB_ERR_ARG);
    sb_light_from_angles(45, 0, -1, &o.lights[0]);
    CHECK(sb_render(ctx, &o, eval_zero, NULL, &img) == SB_ERR_ARG);
    o.lights[0].irradiance = 0;
    CHECK(sb_render(ctx, &o, eval_zero, NULL, &img) == SB_OK);
    CHECK(sb_image_max(&img) == 0);
    sb_image_free(&img);
    CHECK(sb_render_source(ctx, &o, NULL, &img) == SB_ERR_ARG);
    sb_param_t *p;
    sb_factors_t *f;
    CHECK(factor("lambert", SB_PARAM_IO, 8, 2, SB_FORM_F, &p, &f) == SB_OK);
    CHECK(sb_render_factors(ctx, &o, f, p, SB_FORM_F, 3, &img) == SB_ERR_ARG);
    CHECK(sb_render_factors(ctx, &o, f, p, SB_FORM_COUNT_, 1, &img) == SB_ERR_ARG);
    CHECK(sb_render_factors(ctx, &o, NULL, p, SB_FORM_F, 1, &img) == SB_ERR_ARG);
    CHECK(sb_render_factors(ctx, &o, f, p, SB_FORM_F, 0, &img) == SB_OK); /* 0 = all */
    sb_image_free(&img);
    sb_image_free(NULL);
    sb_factors_destroy(f);
    sb_param_destroy(p);
    sb_context_destroy(ctx);
}

/* ---- the parameterisation from metadata --------------------------------- */

SB_TEST(factors_param) {
    sb_context_t *ctx;
    CHECK(sb_context_create(&ctx) == SB_OK);
    int tried = 0;
    for (int k = 0; k < SB_TEST_KINDS; k++) {
        static const double tmax[2] = {0, 60 * SB_PI / 180};
        for (int t = 0; t < 2; t++) {
            sb_param_opts_t po = {0};
            po.res = 12;
            po.theta_max = tmax[t];
            sb_param_t *p;
            if (sb_param_create(NULL, (sb_param_kind_t)k, &po, &p) != SB_OK) continue;
            tried++;
            size_t gw, gh, hw, hh;
            sb_param_texture_size(p, SB_SIDE_G, &gw, &gh);
            sb_param_texture_size(p, SB_SIDE_H, &hw, &hh);
            sb_factors_t *f;
            CHECK(sb_factors_create(NULL, 1, 3, gw, gh, hw, hh, &f) == SB_OK);
            sb_factors_set_meta(f, "param", sb_param_spec(p));
            sb_factors_set_meta(f, "form", "cos2");
            sb_param_t *q = NULL;
            sb_form_t form;
            CHECKF(sb_factors_param(ctx, f, &q, &form) == SB_OK, "%s: %s", sb_param_spec(p),
                   sb_context_last_error(ctx));
            if (q) {
                CHECK(strcmp(sb_param_spec(q), sb_param_spec(p)) == 0);
                CHECK(sb_param_kind(q) == sb_param_kind(p));
                CHECK(form == SB_FORM_COS2);
            }
            sb_param_destroy(q);
            sb_factors_destroy(f);
            sb_param_destroy(p);
        }
    }
    CHECK(tried >= 2);

    /* errors: every one is SB_ERR_FORMAT or SB_ERR_UNSUPPORTED */
    sb_factors_t *f;
    CHECK(sb_factors_create(NULL, 1, 3, 12, 12, 12, 12, &f) == SB_OK);
    sb_param_t *q;
    sb_form_t form;
    CHECK(sb_factors_param(ctx, f, &q, &form) == SB_ERR_FORMAT); /* no meta */
    CHECK(sb_factors_param(ctx, NULL, &q, &form) == SB_ERR_ARG);
    static const char *const bad[] = {"nope:res=12",        "io:res",   "io:res=x",
                                      "io:res=12.5",        "io:res=0", "io:res=12,theta_max=100",
                                      "io:res=12,colour=3", "io:res=1"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        sb_factors_set_meta(f, "param", bad[i]);
        CHECKF(sb_factors_param(ctx, f, &q, &form) == SB_ERR_FORMAT, "'%s' accepted", bad[i]);
    }
    sb_factors_set_meta(f, "param", "io:res=16"); /* textures are 12 x 12 */
    CHECK(sb_factors_param(ctx, f, &q, &form) == SB_ERR_FORMAT);
    CHECK(strstr(sb_context_last_error(ctx), "12 x 12") != NULL);
    sb_factors_set_meta(f, "param", "io:res=12");
    sb_factors_set_meta(f, "form", "cos3");
    CHECK(sb_factors_param(ctx, f, &q, &form) == SB_ERR_FORMAT);
    sb_factors_set_meta(f, "form", "f");
    CHECK(sb_factors_param(ctx, f, &q, &form) == SB_OK && form == SB_FORM_F);
    sb_param_destroy(q);
    /* a kind this build lacks */
    for (int k = 0; k < SB_TEST_KINDS; k++) {
        sb_param_t *p;
        if (sb_param_create(NULL, (sb_param_kind_t)k, NULL, &p) != SB_ERR_UNSUPPORTED) {
            sb_param_destroy(p);
            continue;
        }
        char spec[64];
        snprintf(spec, sizeof spec, "%s:res=12", sb_param_kind_name((sb_param_kind_t)k));
        sb_factors_set_meta(f, "param", spec);
        CHECK(sb_factors_param(ctx, f, &q, &form) == SB_ERR_UNSUPPORTED);
    }
    sb_factors_destroy(f);
    sb_context_destroy(ctx);
}

/* ---- tone mapping and comparison ---------------------------------------- */

SB_TEST(tonemap) {
    CHECK_ABS(sb_srgb_oetf(0), 0, 0);
    CHECK_ABS(sb_srgb_oetf(1), 1, 0);
    CHECK_ABS(sb_srgb_oetf(0.0031308), 0.04045, 1e-5); /* the two pieces meet */
    CHECK_ABS(sb_srgb_oetf(0.5), 1.055 * pow(0.5, 1 / 2.4) - 0.055, 1e-15);
    CHECK_ABS(sb_srgb_oetf(-1), 0, 0);
    CHECK_ABS(sb_srgb_oetf(7), 1, 0);
    sb_tonemap_t clamp = {2, SB_TONEMAP_CLAMP}, rh = {1, SB_TONEMAP_REINHARD};
    CHECK_ABS(sb_tonemap_apply(&clamp, 0.25), sb_srgb_oetf(0.5), 1e-15);
    CHECK_ABS(sb_tonemap_apply(&clamp, 3), 1, 0);
    CHECK_ABS(sb_tonemap_apply(&rh, 1), sb_srgb_oetf(0.5), 1e-15);
    CHECK_ABS(sb_tonemap_apply(&rh, INFINITY), 1, 0);
    CHECK_ABS(sb_tonemap_apply(NULL, NAN), 0, 0);
    CHECK_ABS(sb_tonemap_apply(NULL, 0.5), sb_srgb_oetf(0.5), 0);
    sb_tonemap_op_t op;
    CHECK(sb_tonemap_parse("reinhard", &op) == SB_OK && op == SB_TONEMAP_REINHARD);
    CHECK(sb_tonemap_parse("clamp", &op) == SB_OK && op == SB_TONEMAP_CLAMP);
    CHECK(sb_tonemap_parse("aces", &op) == SB_ERR_UNKNOWN);
    CHECK(strcmp(sb_tonemap_name(SB_TONEMAP_REINHARD), "reinhard") == 0);
    CHECK(strcmp(sb_tonemap_name(SB_TONEMAP_COUNT_), "?") == 0);
}

SB_TEST(compare) {
    sb_image_t a, b, c;
    CHECK(sb_image_alloc(NULL, 4, 3, &a) == SB_OK);
    CHECK(sb_image_alloc(NULL, 4, 3, &b) == SB_OK);
    CHECK(sb_image_alloc(NULL, 3, 4, &c) == SB_OK);
    sb_image_diff_t d;
    CHECK(sb_image_compare(NULL, &a, &b, NULL, &d) == SB_OK);
    CHECK(d.pixels == 0 && isinf(d.psnr));
    /* two covered pixels, one differing by display 0.5 in one channel:
     * MSE = 0.25 / 6, PSNR = 10 log10(24) */
    a.mask[0] = a.mask[5] = 1;
    b.mask[0] = 1;
    sb_tonemap_t tm = {1, SB_TONEMAP_CLAMP};
    b.rgb[3 * 5 + 1] = 0.21404114048223255; /* oetf^-1(0.5), against a's 0 */
    CHECK(sb_image_compare(NULL, &a, &b, &tm, &d) == SB_OK);
    CHECK(d.pixels == 2);
    CHECK_REL(d.rmse, sqrt(0.25 / 6), 1e-9);
    CHECK_REL(d.psnr, 10 * log10(24.0), 1e-9);
    CHECK_REL(d.rmse_linear, 0.21404114048223255 / sqrt(6), 1e-12);
    CHECK_REL(d.max_linear, 0.21404114048223255, 1e-15);
    CHECK(sb_image_max(&b) == 0); /* pixel 5 is not covered in b: its value does not count */
    CHECK_REL(sb_image_max(&a), 0, 0);
    b.mask[5] = 1;
    CHECK_REL(sb_image_max(&b), 0.21404114048223255, 0);
    CHECK(sb_image_compare(NULL, &a, &c, &tm, &d) == SB_ERR_ARG);
    CHECK(sb_image_compare(NULL, NULL, &c, &tm, &d) == SB_ERR_ARG);
    sb_image_free(&c);
    CHECK(sb_image_alloc(NULL, 0, 3, &c) == SB_ERR_ARG);
    CHECK(sb_image_alloc(NULL, SIZE_MAX, 3, &c) == SB_ERR_OVERFLOW);
    sb_image_free(&a);
    sb_image_free(&b);
    sb_image_free(&c);
}

/* ---- PNG ---------------------------------------------------------------- */

/* Read an 8-bit RGB PNG (libpng, independent of our writer's code). */
static unsigned char *read_png(const char *path, size_t *w, size_t *h, char *text_scale, size_t ts) {
    png_image img;
    memset(&img, 0, sizeof img);
    img.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&img, path)) return NULL;
    img.format = PNG_FORMAT_RGB;
    unsigned char *buf = malloc(PNG_IMAGE_SIZE(img));
    if (!buf || !png_image_finish_read(&img, NULL, buf, 0, NULL)) {
        free(buf);
        return NULL;
    }
    *w = img.width;
    *h = img.height;
    if (text_scale) { /* tEXt chunks through the classic API */
        text_scale[0] = 0;
        FILE *fp = fopen(path, "rb");
        png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
        png_infop info = png_create_info_struct(png);
        if (fp && png && info && !setjmp(png_jmpbuf(png))) {
            png_init_io(png, fp);
            png_read_info(png, info);
            png_textp t;
            int n = 0;
            png_get_text(png, info, &t, &n);
            for (int i = 0; i < n; i++)
                if (strcmp(t[i].key, "sepbrdf.scale") == 0) snprintf(text_scale, ts, "%s", t[i].text);
        }
        png_destroy_read_struct(&png, &info, NULL);
        if (fp) fclose(fp);
    }
    return buf;
}

SB_TEST(png_round_trip) {
    const char *dir = sb_tmpdir("render");
    char path[4200];
    snprintf(path, sizeof path, "%s/x.png", dir);
    unsigned char px[5 * 3 * 3];
    for (size_t i = 0; i < sizeof px; i++)
        px[i] = (unsigned char)(i * 17);
    CHECK(sb_png_write_rgb8(NULL, path, 5, 3, px, NULL) == SB_OK);
    size_t w, h;
    unsigned char *back = read_png(path, &w, &h, NULL, 0);
    CHECK(back && w == 5 && h == 3 && memcmp(back, px, sizeof px) == 0);
    free(back);
    snprintf(path, sizeof path, "%s/no/such/x.png", dir);
    sb_context_t *ctx;
    CHECK(sb_context_create(&ctx) == SB_OK);
    CHECK(sb_png_write_rgb8(ctx, path, 5, 3, px, NULL) == SB_ERR_IO);
    CHECK(strstr(sb_context_last_error(ctx), "cannot write") != NULL);
    CHECK(sb_png_write_rgb8(ctx, path, 0, 3, px, NULL) == SB_ERR_ARG);
    CHECK(sb_png_write_rgb8(ctx, NULL, 5, 3, px, NULL) == SB_ERR_ARG);
    sb_context_destroy(ctx);
}

/* The strip: a | b | |d(a) - d(b)| * scale, 4-pixel gaps. */
SB_TEST(strip) {
    const char *dir = sb_tmpdir("render");
    char path[4200];
    snprintf(path, sizeof path, "%s/s.png", dir);
    sb_image_t a, b;
    CHECK(sb_image_alloc(NULL, 6, 2, &a) == SB_OK);
    CHECK(sb_image_alloc(NULL, 6, 2, &b) == SB_OK);
    for (size_t i = 0; i < 36; i++) {
        a.rgb[i] = 0.5;
        b.rgb[i] = 0.4;
    }
    sb_tonemap_t tm = {1, SB_TONEMAP_CLAMP};
    CHECK(sb_image_write_strip_png(NULL, path, &a, &b, &tm, 3) == SB_OK);
    size_t w, h;
    unsigned char *px = read_png(path, &w, &h, NULL, 0);
    CHECK(px && w == 3 * 6 + 8 && h == 2);
    if (px) {
        double da = sb_srgb_oetf(0.5), db = sb_srgb_oetf(0.4);
        CHECK(px[0] == (unsigned char)floor(da * 255 + 0.5));
        CHECK(px[(6 + 4) * 3] == (unsigned char)floor(db * 255 + 0.5));
        CHECK(px[(12 + 8) * 3] == (unsigned char)floor(3 * (da - db) * 255 + 0.5));
        CHECK(px[6 * 3] == 64); /* gap */
    }
    free(px);
    CHECK(sb_image_write_strip_png(NULL, path, &a, &b, &tm, 0) == SB_ERR_RANGE);
    sb_image_t c;
    CHECK(sb_image_alloc(NULL, 5, 2, &c) == SB_OK);
    CHECK(sb_image_write_strip_png(NULL, path, &a, &c, &tm, 1) == SB_ERR_ARG);
    CHECK(sb_image_write_png(NULL, path, &c, &tm) == SB_OK);
    sb_image_free(&c);
    CHECK(sb_image_write_png(NULL, path, &c, &tm) == SB_ERR_ARG);
    sb_image_free(&a);
    sb_image_free(&b);
}

SB_TEST(colormap) {
    unsigned char w[3], lo[3], hi[3], q[3];
    sb_colormap_diverging(0, w);
    sb_colormap_diverging(-1, lo);
    sb_colormap_diverging(1, hi);
    CHECK(w[0] == 247 && w[1] == 247 && w[2] == 247);
    CHECK(lo[2] > lo[0]); /* blue */
    CHECK(hi[0] > hi[2]); /* red */
    sb_colormap_diverging(-5, q);
    CHECK(memcmp(q, lo, 3) == 0);
    sb_colormap_diverging(NAN, q);
    CHECK(memcmp(q, w, 3) == 0);
    /* lightness falls away from 0 on both sides */
    double prev = 3 * 255;
    for (int i = 0; i <= 10; i++) {
        sb_colormap_diverging(i / 10.0, q);
        double s = q[0] + q[1] + q[2];
        CHECK(s <= prev);
        prev = s;
    }
}

/* Previews: names carry the scale, pixels the colour map of value/scale. */
SB_TEST(previews) {
    char dir[512];
    snprintf(dir, sizeof dir, "%s", sb_tmpdir("render"));
    sb_param_t *p;
    sb_factors_t *f;
    CHECK(factor(GOLD, SB_PARAM_IO, 8, 2, SB_FORM_F, &p, &f) == SB_OK);
    CHECK(sb_factors_write_previews(NULL, f, dir) == SB_OK);
    for (size_t j = 0; j < 2; j++)
        for (int side = 0; side < 2; side++) {
            double s = 0;
            for (size_t c = 0; c < 3; c++) {
                const double *t = sb_factors_tex_const(f, side, j, c);
                for (size_t i = 0; i < 64; i++)
                    s = fmax(s, fabs(t[i]));
            }
            char path[4200], ts[64];
            snprintf(path, sizeof path, "%s/%s_%02zu_scale-%.2e.png", dir, side ? "h" : "g", j, s);
            size_t w, h;
            unsigned char *px = read_png(path, &w, &h, ts, sizeof ts);
            CHECKF(px != NULL, "missing %s", path);
            if (!px) continue;
            CHECK_REL(atof(ts), s, 1e-8);
            size_t k = 256 / 8, pw = 8 * k; /* 8 texels magnified to 256 pixels */
            CHECK(w == 3 * pw + 8 && h == pw);
            /* texel (x, y) of channel c at panel pixel (x k + k/2, y k + k/2) */
            for (size_t c = 0; c < 3; c++)
                for (size_t y = 0; y < 8; y++)
                    for (size_t x = 0; x < 8; x++) {
                        unsigned char want[3];
                        sb_colormap_diverging(sb_factors_tex_const(f, side, j, c)[y * 8 + x] / s, want);
                        const unsigned char *got = px + ((y * k + k / 2) * w + c * (pw + 4) + x * k + k / 2) * 3;
                        CHECK(memcmp(got, want, 3) == 0);
                    }
            free(px);
        }
    /* rewriting other values replaces the previews: no stale scales left */
    for (size_t c = 0; c < 3; c++)
        sb_factors_tex(f, SB_SIDE_G, 0, c)[0] = 1e3;
    CHECK(sb_factors_write_previews(NULL, f, dir) == SB_OK);
    char cmd[8192];
    snprintf(cmd, sizeof cmd, "ls %s | grep -c '^g_00_scale-'", dir);
    CHECK(sb_run(cmd, out, sizeof out) == 0 && atoi(out) == 1);
    snprintf(cmd, sizeof cmd, "test -f %s/g_00_scale-1.00e+03.png", dir);
    CHECK(sb_run(cmd, NULL, 0) == 0);
    snprintf(cmd, sizeof cmd, "%s/missing", dir);
    CHECK(sb_factors_write_previews(NULL, f, cmd) == SB_ERR_IO);
    CHECK(sb_factors_write_previews(NULL, NULL, dir) == SB_ERR_ARG);
    sb_factors_destroy(f);
    sb_param_destroy(p);
}

/* ---- CLI ---------------------------------------------------------------- */

static int run(const char *fmt, const char *a, const char *b) {
    char cmd[8192], tail[4096];
    snprintf(tail, sizeof tail, fmt, a, b);
    snprintf(cmd, sizeof cmd, "%s %s", SB_CLI, tail);
    return sb_run(cmd, out, sizeof out);
}

static int exists_in(const char *dir, const char *name) {
    char path[4200];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    return sb_file_exists(path);
}

SB_TEST(cli_render_source) {
    char dir[512];
    snprintf(dir, sizeof dir, "%s", sb_tmpdir("render"));
    int rc = run("render -r 16 -J 1,2,4 -s 64 -o %s%s", dir, "");
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    CHECK(strstr(out, "psnr_dB") != NULL);
    CHECK(exists_in(dir, "original.png") && exists_in(dir, "render_J01.png") && exists_in(dir, "render_J02.png") &&
          exists_in(dir, "render_J04.png") && exists_in(dir, "render.json"));
    CHECK(!exists_in(dir, "render_J03.png"));
    char path[4200];
    snprintf(path, sizeof path, "%s/render_J04.png", dir);
    size_t w, h;
    unsigned char *px = read_png(path, &w, &h, NULL, 0);
    CHECK(px && w == 3 * 64 + 8 && h == 64);
    free(px);
    /* the default (--param auto) factorisation of the default gold: PSNR
     * rises from J = 1 to 2 and holds at 4 (a masked fit's prefixes are
     * fits whose errors on the cells do not rise; between the cells, where
     * the render looks, J = 4 may stay within 0.5 dB of J = 2) */
    snprintf(path, sizeof path, "grep '\"psnr_db\"' %s/render.json | sed 's/.*: //; s/,//'", dir);
    CHECK(sb_run(path, out, sizeof out) == 0);
    double db[3] = {0, 0, 0};
    CHECK(sscanf(out, "%lf %lf %lf", &db[0], &db[1], &db[2]) == 3);
    CHECKF(db[0] > 20 && db[1] > db[0] && db[2] > db[1] - 0.5, "PSNR %g, %g, %g dB", db[0], db[1], db[2]);
    /* Lambert, one term: exact; PSNR printed as inf or very high */
    rc = run("render lambert -r 8 -J 1 -s 32 -q -o %s%s", dir, "");
    CHECKF(rc == 0 && out[0] == 0, "rc %d: %s", rc, out);
}

SB_TEST(cli_render_folder) {
    char fdir[512], rdir[600];
    snprintf(fdir, sizeof fdir, "%s", sb_tmpdir("render"));
    snprintf(rdir, sizeof rdir, "%s/r", fdir);
    int rc = run("factor " GOLD " --param io -r 12 -J 3 --previews -q -o %s%s", fdir, "");
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    char cmd[8192];
    snprintf(cmd, sizeof cmd, "ls %s | grep -c '^[gh]_0[0-2]_scale-.*\\.png$'", fdir);
    CHECK(sb_run(cmd, out, sizeof out) == 0 && atoi(out) == 6);
    rc = run("render %s -s 32 -o %s", fdir, rdir);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    CHECK(strstr(out, "io:res=12") != NULL);
    CHECK(exists_in(rdir, "render_J01.png") && exists_in(rdir, "render_J02.png") && exists_in(rdir, "render_J03.png"));
    /* --source overrides the recorded one */
    rc = run("render %s --source lambert -J 2 -s 32 -o %s", fdir, rdir);
    CHECKF(rc == 0 && strstr(out, "lambert") != NULL, "rc %d: %s", rc, out);
    /* usage errors, nothing written */
    char bad[700];
    snprintf(bad, sizeof bad, "%s/bad", fdir);
    CHECK(run("render %s -J 4 -o %s", fdir, bad) == 1);
    CHECK(strstr(out, "holds 3 terms") != NULL);
    CHECK(run("render %s --res 16 -o %s", fdir, bad) == 1);
    CHECK(strstr(out, "--res") != NULL);
    CHECK(run("render %s --source nope:x=1 -o %s", fdir, bad) == 1);
    CHECK(!sb_file_exists(bad));
    /* a folder without factors */
    CHECK(run("render %s -o %s", rdir, bad) == 2);
    CHECK(!sb_file_exists(bad));
}

/* A folder of `factor --channels G` holds G alone (R and B written as
 * zero): render compares the channels factored, as report.json's errors
 * do, and says which it left out (on main: R and B counted as error, 6 dB
 * PSNR where G alone reads 65 dB). */
SB_TEST(cli_render_channels_factored) {
    char fdir[512], rdir[600];
    snprintf(fdir, sizeof fdir, "%s", sb_tmpdir("render"));
    snprintf(rdir, sizeof rdir, "%s/r", fdir);
    int rc = run("factor " GOLD " --param io -r 8 -J 2 --channels G -q -o %s%s", fdir, "");
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    rc = run("render %s -J 2 -s 32 -o %s", fdir, rdir);
    CHECKF(rc == 0 && strstr(out, "channels RB left out of the original"), "rc %d: %s", rc, out);
    char path[700];
    snprintf(path, sizeof path, "%s/render.json", rdir);
    char *json = sb_read_file(path, NULL);
    CHECKF(json && strstr(json, "\"channels\": [\n    \"G\"\n  ]"), "%s", json ? json : "(none)");
    free(json);
    /* the same source factored in every channel: the same G, a like PSNR */
    double psnr_g = 0, psnr_all = 0;
    const char *at = strstr(out, "\n   2  ");
    CHECK(at && sscanf(at, " 2 %*g %*g %*g %lf", &psnr_g) == 1);
    rc = run("factor " GOLD " --param io -r 8 -J 2 -q -o %s/all%s", fdir, "");
    CHECK(rc == 0);
    rc = run("render %s/all -J 2 -s 32 -o %s", fdir, rdir);
    at = strstr(out, "\n   2  ");
    CHECKF(rc == 0 && at && sscanf(at, " 2 %*g %*g %*g %lf", &psnr_all) == 1 && !strstr(out, "left out"), "%s", out);
    CHECKF(psnr_g > psnr_all - 6, "G alone %.2f dB, all channels %.2f dB", psnr_g, psnr_all);
}

SB_TEST(cli_render_usage) {
    char dir[512], bad[600];
    snprintf(dir, sizeof dir, "%s", sb_tmpdir("render"));
    snprintf(bad, sizeof bad, "%s/o", dir);
    CHECK(run("render --help%s%s", "", "") == 0);
    CHECK(strstr(out, "--light-elev") != NULL);
    CHECK(run("render --bogus -o %s%s", bad, "") == 1);
    CHECK(strstr(out, "--bogus") != NULL);
    CHECK(run("render -J 1,,2 -o %s%s", bad, "") == 1);
    CHECK(run("render -J 0 -o %s%s", bad, "") == 1);
    CHECK(run("render --light 30 -o %s%s", bad, "") == 1);
    CHECK(run("render --light 95,10 -o %s%s", bad, "") == 1);
    CHECK(run("render --light-elev 91 -o %s%s", bad, "") == 1);
    CHECK(run("render --tonemap aces -o %s%s", bad, "") == 1);
    CHECK(run("render --param nope -o %s%s", bad, "") == 1);
    CHECK(strstr(out, "auto, io") != NULL);
    CHECK(run("render --exposure -1 -o %s%s", bad, "") == 1);
    CHECK(run("render --size 4 -o %s%s", bad, "") == 1);
    CHECK(run("render --source lambert -o %s%s", bad, "") == 1); /* --source needs a DIR */
    CHECK(run("render nope:x=1 -o %s%s", bad, "") == 1);
    CHECK(run("render lambert -r 4 -J 17 -o %s%s", bad, "") == 1);
    CHECK(strstr(out, "--terms 17") != NULL);
    CHECK(!sb_file_exists(bad));
    /* several lights and the Reinhard operator */
    int rc = run("render lambert -r 8 -J 1 -s 32 --light 20,180 --light 60,-90,2 --tonemap reinhard "
                 "--exposure 2 -o %s%s",
                 bad, "");
    CHECKF(rc == 0 && strstr(out, "3 lights") != NULL, "rc %d: %s", rc, out);
}

/* A measured table's source description is no spec; the factors keep
 * SOURCE as given ("source_spec" in the EXR headers), which render opens
 * instead, with or without report.json. */
SB_TEST(cli_render_measured_folder) {
    char table[1024], fdir[512], rdir[600];
    snprintf(table, sizeof table, "%s/cornell_acryl_blue.brdf", SB_MEASURED_DIR);
    CHECKF(sb_file_exists(table), "%s: the shipped measured table is missing", table);
    if (sb_test_failed_now()) return;
    snprintf(fdir, sizeof fdir, "%s", sb_tmpdir("render"));
    snprintf(rdir, sizeof rdir, "%s/r", fdir);
    int rc = run("factor %s --param hd -r 8 -J 2 -q -o %s", table, fdir);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    rc = run("render %s -s 32 -o %s", fdir, rdir);
    CHECKF(rc == 0 && exists_in(rdir, "render_J02.png"), "rc %d: %s", rc, out);
    /* without report.json: the EXR headers hold the spec */
    char cmd[2048];
    snprintf(cmd, sizeof cmd, "rm %s/report.json %s/render_J02.png", fdir, rdir);
    CHECK(sb_run(cmd, NULL, 0) == 0);
    rc = run("render %s -s 32 -o %s", fdir, rdir);
    CHECKF(rc == 0 && exists_in(rdir, "render_J02.png"), "rc %d: %s", rc, out);
    CHECKF(strstr(out, "cornell") != NULL, "render did not name the measured original: %s", out);
    char tail[2048];
    snprintf(tail, sizeof tail, "-o %s --source %s", rdir, table);
    rc = run("render %s -s 32 -q %s", fdir, tail);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
}

/* render's default exposure: the log-average luminance of the covered
 * pixels (black ones count through delta = 1e-4 of the largest Y). */
SB_TEST(log_average_luminance) {
    sb_image_t img = {0};
    CHECK(sb_image_alloc(NULL, 3, 1, &img) == SB_OK);
    if (!img.rgb) return;
    double px[3][3] = {{1, 1, 1}, {4, 4, 4}, {0, 0, 0}};
    for (int i = 0; i < 3; i++)
        for (int c = 0; c < 3; c++)
            img.rgb[3 * i + c] = px[i][c];
    img.mask[0] = img.mask[1] = 1; /* the black pixel is not covered */
    CHECK_REL(sb_image_log_average(&img), sqrt((1 + 4e-4) * (4 + 4e-4)), 1e-12);
    img.mask[2] = 1;
    CHECK_REL(sb_image_log_average(&img), cbrt((1 + 4e-4) * (4 + 4e-4) * 4e-4), 1e-12);
    img.rgb[3] = -8;                                    /* a negative channel counts as 0 */
    double y1 = 0.7152 * 4 + 0.0722 * 4, d = 1e-4 * y1; /* now the largest Y */
    CHECK_REL(sb_image_log_average(&img), cbrt((1 + d) * (y1 + d) * d), 1e-12);
    sb_image_free(&img);
    CHECK(sb_image_log_average(NULL) == 0 && sb_image_log_average(&img) == 0);
}
