/* GPU vs CPU: the shipped GLSL snippet, run by Mesa (OSMesa, llvmpipe) in
 * the shaders of examples/gl_render.c, renders the same sphere as the CPU
 * reference (sb_render_factors -> sb_factors_eval) from the same EXR
 * factors, to within PSNR >= 45 dB on display values; and a half-texel shift
 * of the texel-centre convention on one side falls below that. */
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"

#define PSNR_MIN 45.0
#define SIZE 192

#ifdef SB_HAVE_GL
#include "gl_render.h"

#define NEED_GL()                                                                                                      \
    gl_sphere_t *gl = NULL;                                                                                            \
    char gl_err[2048];                                                                                                 \
    do {                                                                                                               \
        if (gl_sphere_open(&gl, gl_err, sizeof gl_err) != 0) {                                                         \
            sb_test_fail(__FILE__, __LINE__, "OSMesa found at build time but no context: %s", gl_err);                 \
            return;                                                                                                    \
        }                                                                                                              \
    } while (0)
#else
#define NEED_GL() SKIP("built without OSMesa (Debian: libosmesa6-dev), no GL agreement test")
#endif

#ifdef SB_HAVE_GL
#define GOLD "microfacet:base=gold,roughness=0.5"

/* Factor `spec` on (kind, res) with J terms and form, write the EXR files to
 * a fresh folder and read them back: the textures a shader would load. */
static sb_result_t factor_via_exr(const char *spec, sb_param_kind_t kind, size_t res, size_t J, sb_form_t form,
                                  sb_param_t **param, sb_factors_t **out) {
    sb_source_t *src = NULL;
    sb_matrix_t m = {0};
    sb_plan_t *plan = NULL;
    sb_factors_t *f = NULL;
    sb_param_opts_t po = {0};
    po.res = res;
    *out = NULL;
    *param = NULL;
    sb_result_t r = sb_param_create(NULL, kind, &po, param);
    if (r) return r;
    sb_plan_opts_t pl = {0};
    pl.terms = J;
    sb_matrix_opts_t mo = {0};
    mo.form = form;
    if ((r = sb_source_open(NULL, spec, &src)) || (r = sb_matrix_build(NULL, src, *param, &mo, &m)) ||
        (r = sb_plan_create(NULL, m.rows, m.cols, &pl, &plan)) || (r = sb_plan_execute(plan, &m, *param, &f)))
        goto out;
    sb_factors_set_meta(f, "source", spec);
    const char *dir = sb_tmpdir("rendergl");
    if ((r = sb_factors_write_exr(NULL, f, dir, NULL))) goto out;
    r = sb_factors_read_exr(NULL, dir, out);
out:
    sb_factors_destroy(f);
    sb_plan_destroy(plan);
    sb_matrix_free(&m);
    sb_source_destroy(src);
    return r;
}

/* Display PSNR of b against a, exposure from a's brightest channel (as
 * `sepbrdf render` does). */
static double psnr(const sb_image_t *a, const sb_image_t *b) {
    double peak = sb_image_max(a);
    sb_tonemap_t tm = {peak > 0 ? 1 / peak : 1, SB_TONEMAP_CLAMP};
    sb_image_diff_t d;
    if (sb_image_compare(NULL, a, b, &tm, &d) != SB_OK) return -1;
    return d.psnr;
}

/* GL render of the first J terms through sb_glsl_snippet(). */
static int gl_render(gl_sphere_t *gl, const sb_factors_t *f, const sb_param_t *p, sb_form_t form, size_t J,
                     const sb_render_opts_t *o, sb_image_t *img, char *err, size_t err_size) {
    char *snippet = sb_glsl_snippet(p, form, J, NULL);
    if (!snippet) return -1;
    int rc = gl_sphere_render(gl, snippet, f, p, o, img, err, err_size);
    free(snippet);
    return rc;
}

/* ---- negative test: a wrong texel-centre convention is caught ----------- */

/* Bilinear lookup as sb_factors_lookup, but texel x centred at
 * (x + 0.5 - shift) / w: shift = 0.5 is the "s * w" error (no -0.5). */
static double lookup_shifted(const sb_factors_t *f, const sb_param_t *p, int side, size_t term, size_t c,
                             const double st[2], double shift) {
    size_t w, h;
    sb_factors_size(f, side, &w, &h);
    int wrap[2];
    sb_param_wrap(p, side, wrap);
    const double *t = sb_factors_tex_const(f, side, term, c);
    double u = st[0] * (double)w - 0.5 + shift, v = st[1] * (double)h - 0.5 + shift;
    double fu = floor(u), fv = floor(v), a = u - fu, b = v - fv;
    long xs[2] = {(long)fu, (long)fu + 1}, ys[2] = {(long)fv, (long)fv + 1};
    for (int i = 0; i < 2; i++) {
        long n[2] = {(long)w, (long)h}, *q[2] = {&xs[i], &ys[i]};
        for (int ax = 0; ax < 2; ax++) {
            long x = *q[ax];
            if (wrap[ax] == SB_WRAP_REPEAT)
                x = ((x % n[ax]) + n[ax]) % n[ax];
            else
                x = x < 0 ? 0 : x >= n[ax] ? n[ax] - 1 : x;
            *q[ax] = x;
        }
    }
    return (1 - b) * ((1 - a) * t[ys[0] * (long)w + xs[0]] + a * t[ys[0] * (long)w + xs[1]]) +
           b * ((1 - a) * t[ys[1] * (long)w + xs[0]] + a * t[ys[1] * (long)w + xs[1]]);
}

typedef struct shifted {
    const sb_factors_t *f;
    const sb_param_t *p;
    size_t terms;
    double shift_g, shift_h; /* texel shifts of the g and h lookups */
} shifted_t;

static int eval_shifted(const void *user, const double wi[3], const double wo[3], double rgb[3]) {
    const shifted_t *s = user;
    double sg[2], sh[2];
    rgb[0] = rgb[1] = rgb[2] = 0;
    if (!sb_param_coords(s->p, wi, wo, sg, sh)) return 0;
    for (size_t j = 0; j < s->terms; j++)
        for (size_t c = 0; c < 3; c++)
            rgb[c] += lookup_shifted(s->f, s->p, 0, j, c, sg, s->shift_g) *
                      lookup_shifted(s->f, s->p, 1, j, c, sh, s->shift_h);
    return 1;
}
#endif /* SB_HAVE_GL */

SB_TEST(agrees_every_param) {
    NEED_GL();
#ifdef SB_HAVE_GL
    sb_render_opts_t o = {0};
    o.size = SIZE;
    int tried = 0;
    for (int k = 0; k < (int)sb_param_kind_count(); k++) {
        sb_param_t *p = NULL;
        sb_factors_t *f = NULL;
        sb_result_t r = factor_via_exr(GOLD, (sb_param_kind_t)k, 16, 4, SB_FORM_F, &p, &f);
        if (r == SB_ERR_UNSUPPORTED) {
            printf("  %-8s not in this build, skipped\n", sb_param_kind_name((sb_param_kind_t)k));
            sb_param_destroy(p);
            continue;
        }
        CHECKF(r == SB_OK, "%s: factor/EXR: %s", sb_param_kind_name((sb_param_kind_t)k), sb_result_name(r));
        if (r != SB_OK) continue;
        tried++;
        static const size_t Js[2] = {1, 4};
        for (int i = 0; i < 2; i++) {
            sb_image_t cpu = {0}, gpu = {0};
            CHECK(sb_render_factors(NULL, &o, f, p, SB_FORM_F, Js[i], &cpu) == SB_OK);
            int rc = gl_render(gl, f, p, SB_FORM_F, Js[i], &o, &gpu, gl_err, sizeof gl_err);
            CHECKF(rc == 0, "%s J=%zu: GL: %s", sb_param_spec(p), Js[i], gl_err);
            if (rc == 0) {
                double db = psnr(&cpu, &gpu);
                printf("  %-20s J=%zu  GL vs CPU PSNR %.2f dB\n", sb_param_spec(p), Js[i], db);
                CHECKF(db >= PSNR_MIN, "%s J=%zu: PSNR %.2f dB < %.0f", sb_param_spec(p), Js[i], db, PSNR_MIN);
            }
            sb_image_free(&cpu);
            sb_image_free(&gpu);
        }
        sb_factors_destroy(f);
        sb_param_destroy(p);
    }
    CHECK(tried >= 1);
    gl_sphere_close(gl);
#endif
}

/* The division by the form weight and several lights, in GL as on the CPU. */
SB_TEST(agrees_forms_and_lights) {
    NEED_GL();
#ifdef SB_HAVE_GL
    sb_render_opts_t o = {0};
    o.size = SIZE;
    o.light_count = 3;
    sb_light_from_angles(45, 45, 0, &o.lights[0]);
    sb_light_from_angles(10, 200, 1.5, &o.lights[1]);
    sb_light_from_angles(80, -60, 0.5, &o.lights[2]);
    for (int form = 0; form < SB_FORM_COUNT_; form++) {
        sb_param_t *p = NULL;
        sb_factors_t *f = NULL;
        CHECK(factor_via_exr(GOLD, SB_PARAM_IO, 16, 4, (sb_form_t)form, &p, &f) == SB_OK);
        sb_image_t cpu = {0}, gpu = {0};
        CHECK(sb_render_factors(NULL, &o, f, p, (sb_form_t)form, 4, &cpu) == SB_OK);
        int rc = gl_render(gl, f, p, (sb_form_t)form, 4, &o, &gpu, gl_err, sizeof gl_err);
        CHECKF(rc == 0, "GL: %s", gl_err);
        if (rc == 0) {
            double db = psnr(&cpu, &gpu);
            printf("  form %-4s 3 lights  GL vs CPU PSNR %.2f dB\n", sb_form_name((sb_form_t)form), db);
            CHECKF(db >= PSNR_MIN, "form %s: PSNR %.2f dB", sb_form_name((sb_form_t)form), db);
        }
        sb_image_free(&cpu);
        sb_image_free(&gpu);
        sb_factors_destroy(f);
        sb_param_destroy(p);
    }
    gl_sphere_close(gl);
#endif
}

SB_TEST(half_texel_shift_detected) {
    NEED_GL();
#ifdef SB_HAVE_GL
    sb_render_opts_t o = {0};
    o.size = SIZE;
    for (int k = 0; k < (int)sb_param_kind_count(); k++) {
        sb_param_t *p = NULL;
        sb_factors_t *f = NULL;
        sb_result_t r = factor_via_exr(GOLD, (sb_param_kind_t)k, 16, 4, SB_FORM_F, &p, &f);
        if (r == SB_ERR_UNSUPPORTED) {
            sb_param_destroy(p);
            continue;
        }
        CHECK(r == SB_OK);
        if (r != SB_OK) continue;
        sb_image_t gpu = {0}, ok = {0}, bad = {0};
        int rc = gl_render(gl, f, p, SB_FORM_F, 4, &o, &gpu, gl_err, sizeof gl_err);
        CHECKF(rc == 0, "GL: %s", gl_err);
        shifted_t s = {f, p, 4, 0, 0};
        CHECK(sb_render(NULL, &o, eval_shifted, &s, &ok) == SB_OK);
        /* the shift on the side that carries the lobe: g, or h where g is
         * a line of view elevations (vh) along which gold varies slowly */
        int on_h = k == SB_PARAM_VH;
        (on_h ? &s.shift_h : &s.shift_g)[0] = 0.5;
        CHECK(sb_render(NULL, &o, eval_shifted, &s, &bad) == SB_OK);
        if (rc == 0) {
            double db_ok = psnr(&ok, &gpu), db_bad = psnr(&bad, &gpu);
            printf("  %-20s GL vs CPU, texel centres (x+0.5)/w: %.2f dB; %s side at x/w: %.2f dB\n", sb_param_spec(p),
                   db_ok, on_h ? "h" : "g", db_bad);
            CHECKF(db_ok >= PSNR_MIN, "%s: unshifted PSNR %.2f dB", sb_param_spec(p), db_ok);
            CHECKF(db_bad < PSNR_MIN, "%s: half-texel shift not caught: PSNR %.2f dB", sb_param_spec(p), db_bad);
        }
        sb_image_free(&gpu);
        sb_image_free(&ok);
        sb_image_free(&bad);
        sb_factors_destroy(f);
        sb_param_destroy(p);
    }
    gl_sphere_close(gl);
#endif
}

/* The real thing: `sepbrdf factor` output (whatever --param auto chose),
 * its sepbrdf.glsl file as the shader text, as examples/gl_sphere uses
 * them. */
SB_TEST(factor_folder) {
    NEED_GL();
#ifdef SB_HAVE_GL
    char dir[4096], cmd[8192], out[8192];
    snprintf(dir, sizeof dir, "%s", sb_tmpdir("rendergl"));
    snprintf(cmd, sizeof cmd, "%s factor -q -r 16 -o %s", SB_CLI, dir); /* --param auto */
    int rc = sb_run(cmd, out, sizeof out);
    CHECKF(rc == 0, "factor rc %d: %s", rc, out);
    sb_factors_t *f = NULL;
    sb_param_t *p = NULL;
    sb_form_t form;
    CHECK(sb_factors_read_exr(NULL, dir, &f) == SB_OK);
    CHECK(f && sb_factors_param(NULL, f, &p, &form) == SB_OK);
    if (!p) return;
    snprintf(cmd, sizeof cmd, "%s/sepbrdf.glsl", dir);
    FILE *fp = fopen(cmd, "rb");
    CHECK(fp != NULL);
    if (!fp) return;
    static char text[1 << 16];
    size_t n = fread(text, 1, sizeof text - 1, fp);
    text[n] = 0;
    fclose(fp);
    char *mine = sb_glsl_snippet(p, form, sb_factors_terms(f), NULL);
    CHECK(mine && strcmp(mine, text) == 0); /* the file is the snippet */
    free(mine);
    sb_render_opts_t o = {0};
    o.size = SIZE;
    sb_image_t cpu = {0}, gpu = {0};
    CHECK(sb_render_factors(NULL, &o, f, p, form, 0, &cpu) == SB_OK);
    rc = gl_sphere_render(gl, text, f, p, &o, &gpu, gl_err, sizeof gl_err);
    CHECKF(rc == 0, "GL: %s", gl_err);
    if (rc == 0) {
        double db = psnr(&cpu, &gpu);
        printf("  %s J=%zu (sepbrdf.glsl)  GL vs CPU PSNR %.2f dB\n", sb_param_spec(p), sb_factors_terms(f), db);
        CHECKF(db >= PSNR_MIN, "PSNR %.2f dB", db);
    }
    sb_image_free(&cpu);
    sb_image_free(&gpu);
    sb_param_destroy(p);
    sb_factors_destroy(f);
    gl_sphere_close(gl);
#endif
}

/* --half end to end: the texels as a program loads them from the EXR
 * files (stored = value / sepbrdf.scale, the scale read with exrheader),
 * the sepbrdf.glsl that `factor --half` wrote (its sb_scale carries the
 * scales), rendered on the GPU, against the CPU render of the FLOAT output
 * of the same run; and the same textures through a snippet with the
 * scales all 1 are far off. */
SB_TEST(half_through_snippet) {
    NEED_GL();
#ifdef SB_HAVE_GL
    if (sb_run("command -v exrheader", NULL, 0) != 0) {
        gl_sphere_close(gl);
        SKIP("exrheader not installed (Debian: openexr)");
    }
    char dir[2][4096], cmd[8400], out[8192];
    for (int half = 0; half < 2; half++) {
        snprintf(dir[half], sizeof dir[half], "%s", sb_tmpdir("rendergl"));
        snprintf(cmd, sizeof cmd, "%s factor -q --param io -r 16 -J 4 %s -o %s", SB_CLI, half ? "--half" : "",
                 dir[half]);
        int rc = sb_run(cmd, out, sizeof out);
        CHECKF(rc == 0, "factor rc %d: %s", rc, out);
    }
    sb_factors_t *ff = NULL, *fh = NULL;
    sb_param_t *p = NULL;
    sb_form_t form;
    CHECK(sb_factors_read_exr(NULL, dir[0], &ff) == SB_OK && sb_factors_read_exr(NULL, dir[1], &fh) == SB_OK);
    CHECK(ff && fh && sb_factors_param(NULL, ff, &p, &form) == SB_OK);
    if (!p || !fh) return;
    size_t J = sb_factors_terms(fh), C = sb_factors_channels(fh);
    for (size_t j = 0; j < J; j++)
        for (int side = 0; side < 2; side++) {
            char name[64];
            sb_exr_name(side, j, name, sizeof name);
            snprintf(cmd, sizeof cmd, "exrheader %s/%s", dir[1], name);
            CHECK(sb_run(cmd, out, sizeof out) == 0);
            const char *at = strstr(out, "sepbrdf.scale (type float):");
            double scale = at ? atof(at + strlen("sepbrdf.scale (type float):")) : 0;
            CHECKF(scale > 0 && scale < 1, "%s: sepbrdf.scale %g", name, scale);
            size_t w, h;
            sb_factors_size(fh, side, &w, &h);
            for (size_t c = 0; c < C && scale > 0; c++) {
                double *t = sb_factors_tex(fh, side, j, c);
                for (size_t i = 0; i < w * h; i++)
                    t[i] /= scale; /* the stored value, as a texture upload sees it */
            }
        }
    snprintf(cmd, sizeof cmd, "%s/sepbrdf.glsl", dir[1]);
    FILE *fp = fopen(cmd, "rb");
    CHECK(fp != NULL);
    if (!fp) return;
    static char text[1 << 16];
    size_t n = fread(text, 1, sizeof text - 1, fp);
    text[n] = 0;
    fclose(fp);
    sb_render_opts_t o = {0};
    o.size = SIZE;
    sb_image_t cpu = {0}, gpu = {0}, ones = {0};
    CHECK(sb_render_factors(NULL, &o, ff, p, form, 0, &cpu) == SB_OK);
    int rc = gl_sphere_render(gl, text, fh, p, &o, &gpu, gl_err, sizeof gl_err);
    CHECKF(rc == 0, "GL: %s", gl_err);
    char *unscaled = sb_glsl_snippet(p, form, J, NULL);
    CHECK(unscaled && gl_sphere_render(gl, unscaled, fh, p, &o, &ones, gl_err, sizeof gl_err) == 0);
    free(unscaled);
    if (rc == 0) {
        double db = psnr(&cpu, &gpu), bad = psnr(&cpu, &ones);
        printf("  --half through sepbrdf.glsl vs FLOAT on the CPU: %.2f dB; scales left at 1: %.2f dB\n", db, bad);
        CHECKF(db >= PSNR_MIN, "PSNR %.2f dB", db);
        CHECKF(bad < 20, "PSNR without scales %.2f dB", bad);
    }
    sb_image_free(&cpu);
    sb_image_free(&gpu);
    sb_image_free(&ones);
    sb_param_destroy(p);
    sb_factors_destroy(ff);
    sb_factors_destroy(fh);
    gl_sphere_close(gl);
#endif
}
