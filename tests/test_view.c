/* sepbrdf view: the viewer page, run in a real browser (headless Chromium,
 * WebGL2 on SwiftShader), against the CPU renderer (render.h).
 *
 * The page's test mode (viewer.h) renders sb_render()'s sphere into a
 * float framebuffer and writes the linear radiance into the DOM, which
 * --dump-dom prints.  Without Chromium the browser cases are skipped
 * (exit 77), except in CI (CI set), where scripts/setup-deps.sh installs it
 * and a missing browser fails. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"
#include "view_page.h"

#define PSNR_MIN 40.0 /* the bar for page against CPU */
#define SIZE 64

static char g_out[1 << 16];

typedef struct page_view {
    char status[512];
    sb_image_t rec, orig; /* orig: zero-size without a reference table */
} page_view_t;

static void view_free(page_view_t *v) {
    sb_image_free(&v->rec);
    sb_image_free(&v->orig);
}

/* Render DIR/index.html in test mode; returns 0 when the page said ok and
 * the browser logged no console error (status says why not). */
static int page_render(const char *dir, double el, double az, size_t J, page_view_t *v) {
    char query[256], *t = NULL;
    memset(v, 0, sizeof *v);
    snprintf(query, sizeof query, "test=1&size=%d&el=%g&az=%g&J=%zu", SIZE, el, az, J);
    if (view_page_run(dir, query, v->status, sizeof v->status, &t) == 0) {
        if (view_decode_image(t, "rec", SIZE, SIZE, &v->rec) != 0)
            snprintf(v->status, sizeof v->status, "no readable rec= image");
        else if (strstr(t, "\norig=") && view_decode_image(t, "orig", SIZE, SIZE, &v->orig) != 0)
            snprintf(v->status, sizeof v->status, "no readable orig= image");
    }
    free(t);
    return strcmp(v->status, "status=ok") == 0 ? 0 : -1;
}

/* ---- the CPU side ------------------------------------------------------ */

/* sb_render_factors of the folder's factors (read back from the EXR
 * files), the same view as the page's test mode. */
static int cpu_render(const char *dir, double el, double az, size_t J, sb_image_t *img) {
    sb_factors_t *f = NULL;
    sb_param_t *p = NULL;
    sb_form_t form;
    sb_render_opts_t o;
    memset(&o, 0, sizeof o);
    o.size = SIZE;
    o.light_count = 1;
    sb_light_from_angles(el, az, 0, &o.lights[0]);
    sb_result_t r = sb_factors_read_exr(NULL, dir, &f);
    if (r == SB_OK) r = sb_factors_param(NULL, f, &p, &form);
    if (r == SB_OK) r = sb_render_factors(NULL, &o, f, p, form, J, img);
    sb_param_destroy(p);
    sb_factors_destroy(f);
    return r == SB_OK ? 0 : -1;
}

/* The page's sphere against the CPU's for J terms and one light. */
static double page_psnr(const char *dir, double el, double az, size_t J, page_view_t *v) {
    sb_image_t cpu = {0};
    double db = -1;
    if (page_render(dir, el, az, J, v) != 0) {
        CHECKF(0, "%s J=%zu el=%g az=%g: %s", dir, J, el, az, v->status);
    } else if (cpu_render(dir, el, az, J, &cpu) != 0) {
        CHECKF(0, "%s: CPU render failed", dir);
    } else {
        db = view_psnr(&cpu, &v->rec);
        CHECKF(db >= PSNR_MIN, "%s J=%zu el=%g az=%g: page vs CPU %.2f dB < %.0f", dir, J, el, az, db, PSNR_MIN);
    }
    sb_image_free(&cpu);
    return db;
}

static void check_folder(const char *args, size_t J) {
    const char *dir = view_make_folder(args);
    if (!dir) return;
    page_view_t v;
    double db = page_psnr(dir, 45, 45, J, &v);
    printf("  %-40s J=%zu: page vs CPU %.1f dB\n", args, J, db);
    view_free(&v);
}

/* ---- cases ------------------------------------------------------------- */

SB_TEST(cli_errors) {
    char cmd[20000];
    const char *dir = sb_tmpdir("viewcli");
    snprintf(cmd, sizeof cmd, "%s view --help", SB_CLI);
    CHECK(sb_run(cmd, g_out, sizeof g_out) == 0 && strstr(g_out, "usage: sepbrdf view"));
    snprintf(cmd, sizeof cmd, "%s view --bogus", SB_CLI);
    CHECK(sb_run(cmd, g_out, sizeof g_out) == 1 && strstr(g_out, "--bogus"));
    snprintf(cmd, sizeof cmd, "%s view '%s' --source lambert --no-original", SB_CLI, dir);
    CHECK(sb_run(cmd, g_out, sizeof g_out) == 1);
    snprintf(cmd, sizeof cmd, "%s view '%s/missing'", SB_CLI, dir);
    CHECK(sb_run(cmd, g_out, sizeof g_out) == 2 && strstr(g_out, "not a folder"));
    /* an empty folder: no factors */
    snprintf(cmd, sizeof cmd, "%s view '%s'", SB_CLI, dir);
    CHECK(sb_run(cmd, g_out, sizeof g_out) == 2);
    /* factors without their snippet: the page must run the folder's own */
    snprintf(cmd, sizeof cmd,
             "%s factor lambert -r 4 -J 1 --param io -o '%s' -q && rm '%s/sepbrdf.glsl' && %s view '%s'", SB_CLI, dir,
             dir, SB_CLI, dir);
    CHECK(sb_run(cmd, g_out, sizeof g_out) == 2 && strstr(g_out, "sepbrdf.glsl"));
    /* a --source that cannot be opened */
    snprintf(cmd, sizeof cmd, "%s factor lambert -r 4 -J 1 --param io -o '%s' -q && %s view '%s' --source nosuchmodel",
             SB_CLI, dir, SB_CLI, dir);
    CHECK(sb_run(cmd, g_out, sizeof g_out) == 1);
    char page[4200];
    snprintf(page, sizeof page, "%s/index.html", dir);
    CHECK(!sb_file_exists(page));
    /* -o FOLDER: the page as an output set of its own there; no original */
    snprintf(cmd, sizeof cmd,
             "%s view '%s' -o '%s/elsewhere' --no-original -q && grep -c '\"ref\":null' '%s/elsewhere/index.html'",
             SB_CLI, dir, dir, dir);
    CHECK(sb_run(cmd, g_out, sizeof g_out) == 0 && atoi(g_out) == 1);
    snprintf(cmd, sizeof cmd, "%s view '%s' -o ''", SB_CLI, dir);
    CHECK(sb_run(cmd, g_out, sizeof g_out) == 1);
}

/* The page holds the folder's snippet and nothing from the network; as a
 * person opens it (no test mode) it runs without an error on the page or
 * on the console. */
SB_TEST(page_offline_no_errors) {
    const char *dir = view_make_folder("-r 8 -J 2");
    if (!dir) return;
    char path[4200], glsl[4200];
    snprintf(path, sizeof path, "%s/index.html", dir);
    snprintf(glsl, sizeof glsl, "%s/sepbrdf.glsl", dir);
    FILE *fp = fopen(path, "rb");
    static char page[1 << 22];
    size_t n = fp ? fread(page, 1, sizeof page - 1, fp) : 0;
    page[n] = 0;
    if (fp) fclose(fp);
    CHECK(n > 0);
    CHECK(!strstr(page, "http://") && !strstr(page, "https://") && !strstr(page, "<script src"));
    CHECK(strstr(page, "// Generated by sepbrdf") && strstr(page, "vec3 sb_brdf(vec3 L, vec3 V)"));
    NEED_BROWSER();
    char *dom = NULL, log[1 << 15];
    CHECK(view_open_page(path, NULL, &dom, log, sizeof log) == 0);
    CHECKF(dom && strstr(dom, "<div id=\"status\"></div>"), "the page reports an error");
    CHECKF(!view_console_error(log), "console: %.400s", view_console_error(log));
    CHECK(dom && strstr(dom, "<td>2</td>")); /* the error table has J = 2 */
    free(dom);
}

/* The default (the lecture's gold, --param auto) at every J. */
SB_TEST(default_every_j) {
    NEED_BROWSER();
    const char *dir = view_make_folder("-r 16 -J 4");
    if (!dir) return;
    for (size_t J = 1; J <= 4; J++) {
        page_view_t v;
        double db = page_psnr(dir, 45, 45, J, &v);
        printf("  default J=%zu: page vs CPU %.1f dB\n", J, db);
        view_free(&v);
    }
}

SB_TEST(every_param) {
    NEED_BROWSER();
    check_folder("--param io -r 8 -J 2", 2);
    check_folder("--param io-area -r 8 -J 2", 2);
    check_folder("--param hd -r 8 -J 2", 2);
    check_folder("--param iso -r 8 -J 2", 2);
}

SB_TEST(forms_and_half) {
    NEED_BROWSER();
    check_folder("--param io -r 8 -J 3 --form cos", 3);
    check_folder("--param iso -r 8 -J 3 --form cos2", 3);
    check_folder("--param io -r 8 -J 3 --half", 3);
    check_folder("--param iso -r 8 -J 3 --half --form cos2", 3);
}

/* Scales other than those written (--half output carries its own, which
 * forms_and_half covers): the page gives the snippet g_j / sb_scale[j],
 * whatever they are, so the sum stays f. */
SB_TEST(snippet_scales) {
    NEED_BROWSER();
    const char *dir = view_make_folder("--param io -r 6 -J 2");
    if (!dir) return;
    char cmd[20000];
    snprintf(cmd, sizeof cmd,
             "sed -i 's/float\\[SB_TERMS\\]([^)]*)/float[SB_TERMS](0.5, 4.0)/' '%s/sepbrdf.glsl' && "
             "grep -c '(0.5, 4.0)' '%s/sepbrdf.glsl' && %s view '%s' -q",
             dir, dir, SB_CLI, dir);
    CHECKF(sb_run(cmd, g_out, sizeof g_out) == 0, "the scales of %s/sepbrdf.glsl: %s", dir, g_out);
    page_view_t v;
    double db = page_psnr(dir, 30, 60, 2, &v);
    printf("  scales x0.5, x4 in the snippet: page vs CPU %.1f dB\n", db);
    view_free(&v);
}

/* Moving the light and the J slider change the page's image as they
 * change the CPU's: each view agrees with the CPU, and differs from the
 * other views by much more than it differs from the CPU. */
SB_TEST(light_and_terms) {
    NEED_BROWSER();
    const char *dir = view_make_folder("--param io -r 12 -J 4");
    if (!dir) return;
    static const double views[3][3] = {{45, 45, 1}, {70, 200, 1}, {45, 45, 4}};
    page_view_t v[3];
    double db[3];
    for (int k = 0; k < 3; k++)
        db[k] = page_psnr(dir, views[k][0], views[k][1], (size_t)views[k][2], &v[k]);
    sb_image_t cpu[3] = {{0}};
    int ok = v[0].rec.rgb && v[1].rec.rgb && v[2].rec.rgb;
    for (int k = 0; ok && k < 3; k++)
        ok = cpu_render(dir, views[k][0], views[k][1], (size_t)views[k][2], &cpu[k]) == 0;
    if (ok) {
        double light = view_psnr(&v[0].rec, &v[1].rec), terms = view_psnr(&v[0].rec, &v[2].rec);
        double light_cpu = view_psnr(&cpu[0], &cpu[1]), terms_cpu = view_psnr(&cpu[0], &cpu[2]);
        printf("  page vs CPU %.1f %.1f %.1f dB; other light %.1f dB apart (CPU %.1f), J 1 -> 4 %.1f dB (CPU %.1f)\n",
               db[0], db[1], db[2], light, light_cpu, terms, terms_cpu);
        CHECKF(light < 25 && light < db[0] - 15, "moving the light changed little: %.1f dB", light);
        CHECKF(terms < db[0] - 10 && terms < db[2] - 10, "J 1 -> 4 changed little: %.1f dB", terms);
        CHECK_ABS(light, light_cpu, 0.5); /* the page changes as the CPU predicts */
        CHECK_ABS(terms, terms_cpu, 0.5);
    }
    for (int k = 0; k < 3; k++) {
        view_free(&v[k]);
        sb_image_free(&cpu[k]);
    }
}

/* The original panel (reference table) agrees with the CPU's original,
 * within what interpolating a table allows. */
SB_TEST(original_panel) {
    NEED_BROWSER();
    const char *dir = view_make_folder("-r 16 -J 2");
    if (!dir) return;
    page_view_t v;
    sb_source_t *src = NULL;
    sb_image_t cpu = {0};
    sb_render_opts_t o;
    memset(&o, 0, sizeof o);
    o.size = SIZE;
    o.light_count = 1;
    sb_light_from_angles(45, 45, 0, &o.lights[0]);
    if (page_render(dir, 45, 45, 2, &v) == 0 && v.orig.rgb &&
        sb_source_open(NULL, "microfacet:base=gold,roughness=0.5", &src) == SB_OK &&
        sb_render_source(NULL, &o, src, &cpu) == SB_OK) {
        double db = view_psnr(&cpu, &v.orig);
        printf("  original panel vs CPU original: %.1f dB\n", db);
        CHECKF(db >= 35, "original panel vs CPU: %.1f dB", db);
    } else {
        CHECKF(0, "no original panel: %s", v.status);
    }
    sb_image_free(&cpu);
    sb_source_destroy(src);
    view_free(&v);
}

SB_TEST(measured_cornell) {
    NEED_BROWSER();
    check_folder("'" SB_MEASURED_DIR "/cornell_acryl_blue.brdf' -r 8 -J 2", 2);
}

SB_TEST(measured_rgl) {
    char cmd[20000];
    snprintf(cmd, sizeof cmd, "%s info '" SB_MEASURED_DIR "/rgl_chm_orange_rgb.bsdf'", SB_CLI);
    if (sb_run(cmd, g_out, sizeof g_out) != 0) SKIP("this build reads no RGL .bsdf");
    NEED_BROWSER();
    check_folder("'" SB_MEASURED_DIR "/rgl_chm_orange_rgb.bsdf' --param vh -r 8 -J 2", 2);
}

/* The default on an RGL file, the vndf layout: the page binds vndf.exr's
 * tables (sb_vndf) and inverts the file's VNDF warp as the C code does.
 * Its h textures are the file's own 32 x 32 nodes with the orange film's
 * mirror peak in them, where the browser's bilinear filtering (weights of
 * limited precision) leaves the sphere 37.9 dB from the CPU's; a wrong
 * coordinate or gain would leave it below 20. */
SB_TEST(measured_rgl_vndf) {
    NEED_BROWSER();
    const char *dir = view_make_folder("'" SB_MEASURED_DIR "/rgl_chm_orange_rgb.bsdf' -J 2");
    if (!dir) return;
    page_view_t v;
    sb_image_t cpu = {0};
    CHECK(page_render(dir, 45, 45, 2, &v) == 0 && cpu_render(dir, 45, 45, 2, &cpu) == 0);
    double db = view_psnr(&cpu, &v.rec);
    CHECKF(db >= 35, "page vs CPU %.2f dB", db);
    printf("  vndf, J=2: page vs CPU %.1f dB\n", db);
    sb_image_free(&cpu);
    view_free(&v);
}

/* A snippet that does not compile fails the page, and so the test. */
SB_TEST(shader_error_detected) {
    NEED_BROWSER();
    const char *dir = view_make_folder("--param io -r 4 -J 1");
    if (!dir) return;
    char cmd[20000];
    snprintf(cmd, sizeof cmd, "echo 'vec3 broken(' >> '%s/sepbrdf.glsl' && %s view '%s' -q", dir, SB_CLI, dir);
    CHECK(sb_run(cmd, g_out, sizeof g_out) == 0);
    page_view_t v;
    CHECK(page_render(dir, 45, 45, 1, &v) != 0);
    CHECKF(strstr(v.status, "status=error") && strstr(v.status, "fragment shader"), "status: %s", v.status);
    view_free(&v);
}

/* ---- the library call, without a browser ------------------------------ */

/* The floats of "KEY":"BASE64" in the page (malloc'ed), *n of them. */
static float *page_floats(const char *page, const char *key, size_t *n) {
    char pat[64];
    snprintf(pat, sizeof pat, "\"%s\":\"", key);
    const char *p = strstr(page, pat);
    return p ? view_b64_floats(p + strlen(pat), n) : NULL;
}

static long page_int(const char *page, const char *key) {
    char pat[64];
    snprintf(pat, sizeof pat, "\"%s\":", key);
    const char *p = strstr(page, pat);
    return p ? strtol(p + strlen(pat), NULL, 10) : -1;
}

static char *slurp(const char *path) {
    FILE *fp = fopen(path, "rb");
    if (!fp) return NULL;
    fseek(fp, 0, SEEK_END);
    long n = ftell(fp);
    fseek(fp, 0, SEEK_SET);
    char *s = n >= 0 ? malloc((size_t)n + 1) : NULL;
    if (s) s[fread(s, 1, (size_t)n, fp)] = 0;
    fclose(fp);
    return s;
}

static double lum(const double rgb[3]) { return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]; }

/* What the page embeds, decoded, against the library: the texels (as
 * float), the in-plane slices (sb_factors_eval, sb_source_eval at the
 * directions of viewer.h) and the reference table (sb_source_eval at the
 * cell centres of the smaller parameterisation it names), its size capped. */
SB_TEST(page_data) {
    const char *made = view_make_folder("--param io -r 6 -J 2 phong:n=20");
    if (!made) return;
    char dir[4096], path[4200];
    snprintf(dir, sizeof dir, "%s", made);
    snprintf(path, sizeof path, "%s/lib.html", dir);
    sb_factors_t *f = NULL;
    sb_param_t *p = NULL, *ref = NULL;
    sb_source_t *src = NULL;
    sb_form_t form;
    char *page = NULL;
    CHECK(sb_factors_read_exr(NULL, dir, &f) == SB_OK && sb_factors_param(NULL, f, &p, &form) == SB_OK);
    CHECK(sb_source_open(NULL, "phong:n=20", &src) == SB_OK);
    sb_viewer_opts_t o = {src, NULL, NULL, 0, 300};
    if (!f || !p || !src || sb_viewer_write(NULL, path, f, p, form, &o) != SB_OK || !(page = slurp(path))) {
        CHECKF(0, "sb_viewer_write failed");
        goto out;
    }
    size_t n, W, H;
    /* texels: layer j, texel (x, y), channel c at ((j H + y) W + x) 3 + c */
    float *g = page_floats(page, "g_texels", &n);
    sb_factors_size(f, SB_SIDE_G, &W, &H);
    CHECK(g && n == 2 * W * H * 3);
    for (size_t j = 0; g && j < 2; j++)
        for (size_t i = 0; i < W * H; i++)
            for (size_t c = 0; c < 3; c++)
                CHECK(g[(j * W * H + i) * 3 + c] == (float)sb_factors_tex_const(f, SB_SIDE_G, j, c)[i]);
    free(g);
    /* slices [k][ti][to]: k = 0 original, k = J' the reconstruction */
    float *sl = page_floats(page, "data", &n);
    CHECK(sl && n == 3 * 36 * 179);
    for (size_t a = 0; sl && a < 36; a += 7)
        for (size_t b = 0; b < 179; b += 11) {
            double ti = a * 2.5 * SB_PI / 180, to = ((double)b - 89) * SB_PI / 180, rgb[3];
            double wi[3] = {sin(ti), 0, cos(ti)}, wo[3] = {-sin(to), 0, cos(to)};
            sb_source_eval(src, wi, wo, rgb);
            CHECK_REL(sl[a * 179 + b], lum(rgb), 1e-6);
            for (size_t k = 1; k <= 2; k++) {
                sb_factors_eval(f, p, form, k, wi, wo, rgb);
                CHECK_REL(sl[k * 36 * 179 + a * 179 + b], lum(rgb), 1e-6);
            }
        }
    free(sl);
    /* the reference table: io:res=6 has 1296 cells, over the cap of 300 */
    const char *spec = strstr(page, "\"ref\":{\"param\":\"");
    char rspec[128] = "";
    if (spec) sscanf(spec + strlen("\"ref\":{\"param\":\""), "%127[^\"]", rspec);
    long rows = page_int(page, "rows"), cols = page_int(page, "cols");
    sb_param_kind_t kind;
    sb_param_opts_t po;
    CHECKF(sb_param_parse_spec(NULL, rspec, &kind, &po) == SB_OK && sb_param_create(NULL, kind, &po, &ref) == SB_OK,
           "reference '%s'", rspec);
    CHECKF(rows > 0 && cols > 0 && rows * cols <= 300 && kind == SB_PARAM_IO, "%s: %ld x %ld", rspec, rows, cols);
    float *t = page_floats(page, "texels", &n);
    CHECK(t && ref && n >= (size_t)(rows * cols) * 4 && (size_t)rows == sb_param_rows(ref));
    for (long r = 0; t && ref && r < rows; r += 3)
        for (long c = 0; c < cols; c += 5) {
            double wi[3], wo[3], rgb[3];
            sb_param_cell_dirs(ref, (size_t)r, (size_t)c, wi, wo);
            sb_source_eval(src, wi, wo, rgb);
            for (int k = 0; k < 3; k++)
                CHECK_REL(t[(r * cols + c) * 4 + k], rgb[k], 1e-6);
            CHECK(t[(r * cols + c) * 4 + 3] == 1.0f);
        }
    free(t);
out:
    free(page);
    sb_param_destroy(ref);
    sb_param_destroy(p);
    sb_factors_destroy(f);
    sb_source_destroy(src);
}

/* Every error of sb_viewer_write; a failed write leaves nothing behind. */
SB_TEST(library_errors) {
    const char *made = view_make_folder("--param io -r 4 -J 1 lambert");
    if (!made) return;
    char dir[4096], path[4200];
    snprintf(dir, sizeof dir, "%s", made);
    sb_factors_t *f = NULL;
    sb_param_t *p = NULL, *other = NULL;
    sb_form_t form;
    sb_param_opts_t po = {.res = 6};
    CHECK(sb_factors_read_exr(NULL, dir, &f) == SB_OK && sb_factors_param(NULL, f, &p, &form) == SB_OK);
    CHECK(sb_param_create(NULL, SB_PARAM_IO, &po, &other) == SB_OK);
    snprintf(path, sizeof path, "%s/page.html", dir);
    CHECK(sb_viewer_write(NULL, NULL, f, p, form, NULL) == SB_ERR_ARG);
    CHECK(sb_viewer_write(NULL, path, NULL, p, form, NULL) == SB_ERR_ARG);
    CHECK(sb_viewer_write(NULL, path, f, NULL, form, NULL) == SB_ERR_ARG);
    CHECK(sb_viewer_write(NULL, path, f, other, form, NULL) == SB_ERR_ARG); /* 4 x 4 textures, io:res=6 */
    CHECK(!sb_file_exists(path));
    snprintf(path, sizeof path, "%s/no/such/folder/page.html", dir);
    CHECK(sb_viewer_write(NULL, path, f, p, form, NULL) == SB_ERR_IO);
    /* without a source or snippet: the page still comes, with the library's
     * snippet; text that would close the script is escaped */
    snprintf(path, sizeof path, "%s/page.html", dir);
    sb_viewer_opts_t o = {NULL, NULL, "{\"x\": \"</script><b>\"}", 0, 0};
    CHECK(sb_viewer_write(NULL, path, f, p, form, &o) == SB_OK);
    char *page = slurp(path);
    CHECK(page && strstr(page, "\"ref\":null") && strstr(page, "vec3 sb_brdf(vec3 L, vec3 V)"));
    CHECK(page && !strstr(page, "</script><b>") && strstr(page, "\\u003c/script>\\u003cb>"));
    free(page);
    char cmd[20000];
    snprintf(cmd, sizeof cmd, "ls -a '%s' | grep -c tmp", dir);
    CHECK(sb_run(cmd, g_out, sizeof g_out) != 0 || atoi(g_out) == 0);
    sb_param_destroy(other);
    sb_param_destroy(p);
    sb_factors_destroy(f);
}
