/* The viewer's 3D lobe, slices and sky-lit sphere (data/viewer3d.js), in
 * headless Chromium against the CPU: the page's test mode writes the
 * lobe's grid f(L, V) (?lobe=1: V at the cell centres of LOBE_N x LOBE_N in
 * theta_o x phi_o) and a slice (?slice=1&psi=DEG: SLICE_N^2 theta_o in a
 * plane psi from the plane of incidence), and ?shape=2 lights the sphere
 * by the procedural sky through a fixed quadrature; all are repeated here
 * with sb_factors_eval (the reconstruction) and sb_source_eval (the
 * original). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"
#include "view_page.h"

/* Page against CPU at the same directions (no rasterisation between them):
 * float rounding and texture filtering give 85-92 dB under SwiftShader; a
 * 2 % error in the lobe's theta_o or in the sky gave 47 and 37 dB.  The
 * original (the page's reference table, interpolated) against the source:
 * 51-61 dB. */
#define PSNR_MIN 60.0
#define PSNR_ORIG_MIN 45.0
#define SIZE 64
#define LOBE_N 48  /* viewer3d.js */
#define SLICE_N 16 /* viewer3d.js: a slice's SLICE_N^2 samples */
#define SKY_NT 12  /* viewer3d.js: the sky's quadrature */
#define SKY_NP 24
#define EXTENT 1.05                                 /* SB_RENDER_EXTENT, as the page rounds it */
#define SOURCE "microfacet:base=gold,roughness=0.5" /* the CLI's default source */

/* ---- f as the CPU has it ----------------------------------------------- */

typedef struct brdf {
    sb_factors_t *f;
    sb_param_t *p;
    sb_form_t form;
    size_t J;
    sb_source_t *src; /* when set: the original, not the reconstruction */
} brdf_t;

static void brdf_eval(const brdf_t *b, const double wi[3], const double wo[3], double rgb[3]) {
    rgb[0] = rgb[1] = rgb[2] = 0;
    if (b->src)
        sb_source_eval(b->src, wi, wo, rgb);
    else
        sb_factors_eval(b->f, b->p, b->form, b->J, wi, wo, rgb);
}

static int brdf_open(const char *dir, size_t J, brdf_t *b) {
    memset(b, 0, sizeof *b);
    b->J = J;
    return sb_factors_read_exr(NULL, dir, &b->f) == SB_OK && sb_factors_param(NULL, b->f, &b->p, &b->form) == SB_OK &&
                   sb_source_open(NULL, SOURCE, &b->src) == SB_OK
               ? 0
               : -1;
}

static void brdf_close(brdf_t *b) {
    sb_source_destroy(b->src);
    sb_param_destroy(b->p);
    sb_factors_destroy(b->f);
}

static void light_dir(double el, double az, double L[3]) {
    double e = el * SB_PI / 180, a = az * SB_PI / 180;
    L[0] = cos(e) * cos(a), L[1] = cos(e) * sin(a), L[2] = sin(e);
}

static double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* The grids of viewer3d.js, f(L, V) at cell (i, j) of n x n.  The lobe
 * (sb_lobe_cell): theta_o = (i + 1/2) / n 90 degrees, phi_o = (j + 1/2) / n
 * 360 degrees.  A slice (sb_slice_cell, slice_phi >= 0): sample k = i n + j
 * at signed theta_o = ((k + 1/2) / n^2 2 - 1) 90 degrees, azimuth slice_phi. */
static int cpu_grid(const brdf_t *b, const double L[3], size_t n, double slice_phi, sb_image_t *img) {
    if (sb_image_alloc(NULL, n, n, img) != SB_OK) return -1;
    for (size_t i = 0; i < n; i++)
        for (size_t j = 0; j < n; j++) {
            double th = (i + 0.5) / n * SB_PI / 2, ph = (j + 0.5) / n * 2 * SB_PI;
            if (slice_phi >= 0) th = ((i * n + j + 0.5) / (double)(n * n) * 2 - 1) * SB_PI / 2, ph = slice_phi;
            double V[3] = {sin(th) * cos(ph), sin(th) * sin(ph), cos(th)};
            brdf_eval(b, L, V, &img->rgb[(i * n + j) * 3]);
            img->mask[i * n + j] = 1;
        }
    return 0;
}

/* sb_sky of viewer3d.js: horizon-to-zenith gradient, ground, a soft sun. */
static void sky(const double d[3], const double sun[3], double rgb[3]) {
    static const double hor[3] = {1.0, 0.9, 0.75}, zen[3] = {0.25, 0.45, 1.0}, gnd[3] = {0.25, 0.22, 0.2};
    static const double sunc[3] = {1.0, 0.95, 0.85};
    double s = pow(fmax(dot3(d, sun), 0), 8);
    for (int c = 0; c < 3; c++)
        rgb[c] = 0.4 * (d[2] > 0 ? hor[c] + (zen[c] - hor[c]) * d[2] : gnd[c]) + 3.0 * sunc[c] * s;
}

/* One sphere pixel under the sky (sb_sky_radiance): frame t, b, n; cells
 * (SKY_NT x SKY_NP RGB) the dropped HDR's, NULL the procedural sky. */
static void sky_pixel(const brdf_t *b, const double sun[3], const double *cells, const double t[3], const double bt[3],
                      const double n[3], double out[3]) {
    double V[3] = {t[2], bt[2], n[2]}, dw = (SB_PI / SKY_NT) * (2 * SB_PI / SKY_NP);
    out[0] = out[1] = out[2] = 0;
    for (int i = 0; i < SKY_NT; i++) {
        double th = (i + 0.5) * SB_PI / SKY_NT;
        for (int j = 0; j < SKY_NP; j++) {
            double ph = (j + 0.5) * 2 * SB_PI / SKY_NP, f[3], e[3];
            double d[3] = {sin(th) * cos(ph), sin(th) * sin(ph), cos(th)};
            double L[3] = {dot3(d, t), dot3(d, bt), dot3(d, n)};
            if (!(dot3(d, n) > 0) || !(L[2] > 0)) continue;
            brdf_eval(b, L, V, f);
            sky(d, sun, e);
            if (cells) memcpy(e, &cells[(i * SKY_NP + j) * 3], sizeof e);
            for (int c = 0; c < 3; c++)
                out[c] += f[c] * L[2] * e[c] * sin(th) * dw;
        }
    }
}

/* The page's sphere (sb_scene, shape 0) under the sky, rows from the top. */
static int cpu_sky_sphere(const brdf_t *b, const double sun[3], const double *cells, sb_image_t *img) {
    if (sb_image_alloc(NULL, SIZE, SIZE, img) != SB_OK) return -1;
    for (size_t r = 0; r < SIZE; r++)
        for (size_t x = 0; x < SIZE; x++) {
            double px = (2 * (x + 0.5) / SIZE - 1) * EXTENT, py = (2 * (SIZE - 1 - r + 0.5) / SIZE - 1) * EXTENT;
            double r2 = px * px + py * py, *rgb = &img->rgb[(r * SIZE + x) * 3];
            img->mask[r * SIZE + x] = r2 < 1;
            rgb[0] = rgb[1] = rgb[2] = 0;
            if (!(r2 < 1)) continue;
            double n[3] = {px, py, sqrt(1 - r2)}, k = hypot(n[2], n[0]);
            double t[3] = {n[2] / k, 0, -n[0] / k};
            double bt[3] = {n[1] * t[2] - n[2] * t[1], n[2] * t[0] - n[0] * t[2], n[0] * t[1] - n[1] * t[0]};
            sky_pixel(b, sun, cells, t, bt, n, rgb);
        }
    return 0;
}

/* ---- the page ---------------------------------------------------------- */

/* The page's images KEY (n x n) for the query; 0 on success. */
static int page_images(const char *dir, const char *query, size_t n, const char *const keys[2], sb_image_t img[2]) {
    char status[512], *text = NULL;
    int ok = view_page_run(dir, query, status, sizeof status, &text) == 0;
    CHECKF(ok, "%s?%s: %s", dir, query, status);
    for (int k = 0; ok && k < 2; k++) {
        ok = view_decode_image(text, keys[k], n, n, &img[k]) == 0;
        CHECKF(ok, "%s?%s: no readable %s=", dir, query, keys[k]);
    }
    free(text);
    return ok ? 0 : -1;
}

/* The lobe (psi < 0) or the slice psi degrees from the plane of incidence
 * for one light and J: reconstruction against sb_factors_eval, original
 * (the page's reference table, interpolated) against the source.  Returns
 * the page's reconstruction (for comparing lights and planes). */
static void grid_case(const char *dir, double el, double az, size_t J, double psi, sb_image_t *page_rec) {
    const char *const lobe[2] = {"lobe_rec", "lobe_orig"}, *const slice[2] = {"slice_rec", "slice_orig"};
    const char *what = psi < 0 ? "lobe" : "slice";
    size_t n = psi < 0 ? LOBE_N : SLICE_N;
    char query[256];
    sb_image_t pg[2] = {{0}}, cpu[2] = {{0}};
    brdf_t b;
    double L[3], phi = -1;
    light_dir(el, az, L);
    if (psi >= 0) phi = fmod(atan2(L[1], L[0]) + SB_PI + psi * SB_PI / 180 + 4 * SB_PI, 2 * SB_PI);
    snprintf(query, sizeof query, "test=1&size=8&%s=1&el=%g&az=%g&J=%zu&psi=%g", what, el, az, J, psi);
    if (page_images(dir, query, n, psi < 0 ? lobe : slice, pg) == 0 && brdf_open(dir, J, &b) == 0) {
        sb_source_t *src = b.src;
        b.src = NULL;
        CHECK(cpu_grid(&b, L, n, phi, &cpu[0]) == 0);
        b.src = src;
        CHECK(cpu_grid(&b, L, n, phi, &cpu[1]) == 0);
        double rec = view_psnr(&cpu[0], &pg[0]), orig = view_psnr(&cpu[1], &pg[1]);
        printf("  %s el=%g az=%g J=%zu psi=%g: page vs CPU %.1f dB, original vs source %.1f dB\n", what, el, az, J, psi,
               rec, orig);
        CHECKF(rec >= PSNR_MIN, "%s el=%g az=%g J=%zu: page vs CPU %.1f dB", what, el, az, J, rec);
        CHECKF(orig >= PSNR_ORIG_MIN, "%s el=%g az=%g: original vs source %.1f dB", what, el, az, orig);
        CHECKF(sb_image_max(&cpu[0]) > 0, "an empty lobe proves nothing");
        brdf_close(&b);
        *page_rec = pg[0];
        pg[0] = (sb_image_t){0};
    }
    for (int k = 0; k < 2; k++) {
        sb_image_free(&pg[k]);
        sb_image_free(&cpu[k]);
    }
}

/* ---- cases ------------------------------------------------------------- */

/* The 3D lobe for two lights and two J agrees with the CPU, and moving
 * the light moves it (much more than page and CPU differ). */
SB_TEST(lobe_matches_cpu) {
    NEED_BROWSER();
    const char *made = view_make_folder("-r 16 -J 3");
    if (!made) return;
    char dir[4096];
    snprintf(dir, sizeof dir, "%s", made);
    sb_image_t a = {0}, b = {0}, c = {0};
    grid_case(dir, 45, 45, 3, -1, &a);
    grid_case(dir, 70, 200, 3, -1, &b);
    grid_case(dir, 30, 120, 1, -1, &c);
    if (a.rgb && b.rgb) {
        double apart = view_psnr(&a, &b);
        printf("  the lobes of two lights: %.1f dB apart\n", apart);
        CHECKF(apart < 25, "moving the light changed the lobe little: %.1f dB", apart);
    }
    sb_image_free(&a);
    sb_image_free(&b);
    sb_image_free(&c);
}

/* Slices for the light: in the plane of incidence, out of it and
 * perpendicular to it agree with the CPU; turning the plane changes the
 * slice (the mirror peak leaves it). */
SB_TEST(slices_match_cpu) {
    NEED_BROWSER();
    const char *made = view_make_folder("-r 16 -J 3");
    if (!made) return;
    char dir[4096];
    snprintf(dir, sizeof dir, "%s", made);
    sb_image_t s[3] = {{0}};
    grid_case(dir, 45, 45, 3, 0, &s[0]);
    grid_case(dir, 45, 45, 3, 90, &s[1]);
    grid_case(dir, 60, 300, 2, 35, &s[2]);
    if (s[0].rgb && s[1].rgb) {
        double apart = view_psnr(&s[0], &s[1]);
        printf("  in-plane and perpendicular slices: %.1f dB apart\n", apart);
        CHECKF(apart < 25, "turning the slice's plane changed little: %.1f dB", apart);
    }
    for (int k = 0; k < 3; k++)
        sb_image_free(&s[k]);
}

/* The sphere under the sky: reconstruction and original against the same
 * quadrature on the CPU; and not the point-lit sphere. */
SB_TEST(sky_sphere_matches_cpu) {
    NEED_BROWSER();
    const char *made = view_make_folder("-r 16 -J 2");
    if (!made) return;
    char dir[4096];
    snprintf(dir, sizeof dir, "%s", made);
    static const char *const keys[2] = {"rec", "orig"};
    sb_image_t pg[2] = {{0}}, point[2] = {{0}}, cpu[2] = {{0}};
    brdf_t b;
    double sun[3];
    light_dir(45, 45, sun);
    char query[256];
    snprintf(query, sizeof query, "test=1&size=%d&el=45&az=45&J=2", SIZE);
    int ok = page_images(dir, query, SIZE, keys, point) == 0;
    snprintf(query, sizeof query, "test=1&size=%d&el=45&az=45&J=2&shape=2", SIZE);
    ok = ok && page_images(dir, query, SIZE, keys, pg) == 0 && brdf_open(dir, 2, &b) == 0;
    if (ok) {
        CHECK(cpu_sky_sphere(&b, sun, NULL, &cpu[1]) == 0);
        sb_source_destroy(b.src);
        b.src = NULL;
        CHECK(cpu_sky_sphere(&b, sun, NULL, &cpu[0]) == 0);
        brdf_close(&b);
        double rec = view_psnr(&cpu[0], &pg[0]), orig = view_psnr(&cpu[1], &pg[1]),
               apart = view_psnr(&pg[0], &point[0]);
        printf("  sky: page vs CPU %.1f dB, original vs source %.1f dB; point light %.1f dB apart\n", rec, orig, apart);
        CHECKF(rec >= PSNR_MIN, "sky-lit sphere: page vs CPU %.1f dB", rec);
        CHECKF(orig >= PSNR_ORIG_MIN, "sky-lit original: page vs source %.1f dB", orig);
        CHECKF(apart < 25, "the sky lit the sphere as the point light does: %.1f dB apart", apart);
    }
    for (int k = 0; k < 2; k++) {
        sb_image_free(&pg[k]);
        sb_image_free(&point[k]);
        sb_image_free(&cpu[k]);
    }
}

/* As a person opens it, under the sky and with the lobe drawn: no error
 * on the page or on the console. */
SB_TEST(page_sky_no_errors) {
    NEED_BROWSER();
    const char *dir = view_make_folder("-r 8 -J 2");
    if (!dir) return;
    char path[4200], *dom = NULL, log[1 << 15];
    snprintf(path, sizeof path, "%s/index.html", dir);
    CHECK(view_open_page(path, "shape=2&el=30", &dom, log, sizeof log) == 0);
    CHECKF(dom && strstr(dom, "<div id=\"status\"></div>"), "the page reports an error");
    CHECKF(dom && strstr(dom, "id=\"lobe\""), "no lobe canvas");
    CHECKF(!view_console_error(log), "console: %.400s", view_console_error(log));
    free(dom);
}

/* ---- a dropped HDR ----------------------------------------------------- */

#define HDR_W 32
#define HDR_H 16

/* An equirectangular test sky: smooth colours and one bright pixel. */
static void hdr_pixel(int x, int y, double rgb[3]) {
    rgb[0] = 0.5 + 0.5 * sin(x * 0.4), rgb[1] = 0.3 + y * 0.05, rgb[2] = 1.0 - y * 0.03;
    if (x == 5 && y == 4) rgb[0] = rgb[1] = rgb[2] = 20;
}

/* Scanline channel bytes v[0..n) in the RLE form: runs of 3 or more, else
 * single literals; returns the bytes written. */
static size_t rle_channel(const unsigned char *v, size_t n, unsigned char *out) {
    size_t k = 0;
    for (size_t x = 0; x < n;) {
        size_t run = 1;
        while (x + run < n && run < 127 && v[x + run] == v[x])
            run++;
        if (run < 3) run = 1;
        out[k++] = (unsigned char)(run > 1 ? 128 + run : 1);
        out[k++] = v[x];
        x += run;
    }
    return k;
}

/* The test sky as a .hdr (even rows RLE, odd rows flat) into buf; *decoded
 * what a reader gets back (float RGB); the file's length. */
static size_t hdr_file(unsigned char *buf, double *decoded) {
    size_t k = (size_t)sprintf((char *)buf, "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y %d +X %d\n", HDR_H, HDR_W);
    for (int y = 0; y < HDR_H; y++) {
        unsigned char px[HDR_W][4], ch[4][HDR_W];
        for (int x = 0; x < HDR_W; x++) {
            double rgb[3], v;
            int e;
            hdr_pixel(x, y, rgb);
            v = frexp(fmax(rgb[0], fmax(rgb[1], rgb[2])), &e) * 256 / fmax(rgb[0], fmax(rgb[1], rgb[2]));
            for (int c = 0; c < 4; c++) {
                px[x][c] = (unsigned char)(c < 3 ? rgb[c] * v : e + 128);
                ch[c][x] = px[x][c];
            }
            for (int c = 0; c < 3; c++)
                decoded[(y * HDR_W + x) * 3 + c] = px[x][c] * ldexp(1, px[x][3] - 136);
        }
        if (y % 2) {
            memcpy(buf + k, px, sizeof px);
            k += sizeof px;
            continue;
        }
        unsigned char head[4] = {2, 2, HDR_W >> 8, HDR_W & 255};
        memcpy(buf + k, head, 4);
        k += 4;
        for (int c = 0; c < 4; c++)
            k += rle_channel(ch[c], HDR_W, buf + k);
    }
    return k;
}

/* skyCells of viewer3d.js: 4 x 4 points a cell, sin theta weights. */
static void hdr_cells(const double *img, double *cells) {
    for (int i = 0; i < SKY_NT; i++)
        for (int j = 0; j < SKY_NP; j++) {
            double w = 0, *o = &cells[(i * SKY_NP + j) * 3];
            o[0] = o[1] = o[2] = 0;
            for (int a = 0; a < 16; a++) {
                double th = (i + (a / 4 + 0.5) / 4) * SB_PI / SKY_NT, ph = (j + (a % 4 + 0.5) / 4) * 2 * SB_PI / SKY_NP;
                int x = (int)fmin(HDR_W - 1, floor(ph / (2 * SB_PI) * HDR_W)),
                    y = (int)fmin(HDR_H - 1, floor(th / SB_PI * HDR_H));
                for (int c = 0; c < 3; c++)
                    o[c] += sin(th) * img[(y * HDR_W + x) * 3 + c];
                w += sin(th);
            }
            for (int c = 0; c < 3; c++)
                o[c] /= w;
        }
}

/* base64url of n bytes (the page's ?hdr=) into out. */
static void b64url(const unsigned char *in, size_t n, char *out) {
    static const char abc[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789-_";
    size_t k = 0;
    for (size_t i = 0; i < n; i += 3) {
        unsigned w = (unsigned)in[i] << 16 | (i + 1 < n ? in[i + 1] << 8 : 0) | (i + 2 < n ? in[i + 2] : 0);
        for (int c = 0; c < 4; c++)
            out[k++] = c <= (int)(n - i) ? abc[(w >> (18 - 6 * c)) & 63] : '=';
    }
    out[k] = 0;
}

/* An .hdr as if dropped (RLE and flat scanlines) lights the sphere as the
 * same cell means do on the CPU; a file that is not one is an error the
 * page reports. */
SB_TEST(hdr_sky_matches_cpu) {
    NEED_BROWSER();
    const char *made = view_make_folder("-r 16 -J 2");
    if (!made) return;
    char dir[4096], status[512], *text = NULL;
    snprintf(dir, sizeof dir, "%s", made);
    static unsigned char file[1 << 14];
    static double img[HDR_W * HDR_H * 3], cells[SKY_NT * SKY_NP * 3];
    static char query[1 << 15];
    static const char *const keys[2] = {"rec", "orig"};
    size_t len = hdr_file(file, img);
    hdr_cells(img, cells);
    int q = snprintf(query, sizeof query, "test=1&size=%d&el=45&az=45&J=2&hdr=", SIZE);
    b64url(file, len, query + q);
    sb_image_t pg[2] = {{0}}, cpu[2] = {{0}};
    brdf_t b;
    double sun[3];
    light_dir(45, 45, sun);
    if (page_images(dir, query, SIZE, keys, pg) == 0 && brdf_open(dir, 2, &b) == 0) {
        CHECK(cpu_sky_sphere(&b, sun, cells, &cpu[1]) == 0);
        sb_source_destroy(b.src);
        b.src = NULL;
        CHECK(cpu_sky_sphere(&b, sun, cells, &cpu[0]) == 0);
        brdf_close(&b);
        double rec = view_psnr(&cpu[0], &pg[0]), orig = view_psnr(&cpu[1], &pg[1]);
        printf("  dropped HDR: page vs CPU %.1f dB, original vs source %.1f dB\n", rec, orig);
        CHECKF(rec >= PSNR_MIN, "HDR-lit sphere: page vs CPU %.1f dB", rec);
        CHECKF(orig >= PSNR_ORIG_MIN, "HDR-lit original: page vs source %.1f dB", orig);
    }
    for (int k = 0; k < 2; k++) {
        sb_image_free(&pg[k]);
        sb_image_free(&cpu[k]);
    }
    CHECK(view_page_run(dir, "test=1&size=8&hdr=bm90IGFuIGhkcgo", status, sizeof status, &text) != 0);
    CHECKF(strstr(status, "status=error") && strstr(status, "Radiance"), "status: %s", status);
    free(text);
}
