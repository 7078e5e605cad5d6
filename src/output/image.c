/* Images: tone mapping, comparison, PNG output (libpng), texture previews.
 *
 * libpng reports errors through callbacks; ours keep the message and
 * longjmp back to the writer, so nothing is printed and no error aborts. */
#include "sepbrdf/image.h"

#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <png.h>
#include <setjmp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "sepbrdf/outset.h"
#include "util/internal.h"

/* ---- buffers ------------------------------------------------------------ */

sb_result_t sb_image_alloc(sb_context_t *ctx, size_t width, size_t height, sb_image_t *out) {
    if (!out) return sb_error(ctx, SB_ERR_ARG, "image: no output");
    memset(out, 0, sizeof *out);
    if (!width || !height) return sb_error(ctx, SB_ERR_ARG, "image: empty size %zu x %zu", width, height);
    size_t n;
    if (sb_size_mul(width, height, &n))
        return sb_error(ctx, SB_ERR_OVERFLOW, "image: %zu x %zu overflows", width, height);
    out->rgb = sb_calloc(ctx, n, 3 * sizeof(double), "image");
    if (!out->rgb) return SB_ERR_NOMEM;
    out->mask = sb_calloc(ctx, n, 1, "image mask");
    if (!out->mask) {
        sb_image_free(out);
        return SB_ERR_NOMEM;
    }
    out->width = width;
    out->height = height;
    return SB_OK;
}

void sb_image_free(sb_image_t *img) {
    if (!img) return;
    free(img->rgb);
    free(img->mask);
    memset(img, 0, sizeof *img);
}

/* ---- tone mapping ------------------------------------------------------- */

static const char *const tonemap_names[SB_TONEMAP_COUNT_] = {"clamp", "reinhard"};

sb_result_t sb_tonemap_parse(const char *name, sb_tonemap_op_t *out) {
    if (!out) return SB_ERR_ARG;
    for (int i = 0; i < SB_TONEMAP_COUNT_; i++)
        if (name && out && strcmp(name, tonemap_names[i]) == 0) {
            *out = (sb_tonemap_op_t)i;
            return SB_OK;
        }
    return SB_ERR_UNKNOWN;
}
const char *sb_tonemap_name(sb_tonemap_op_t op) { return (unsigned)op < SB_TONEMAP_COUNT_ ? tonemap_names[op] : "?"; }

double sb_srgb_oetf(double u) {
    if (!(u > 0)) return 0;
    if (u >= 1) return 1;
    return u <= 0.0031308 ? 12.92 * u : 1.055 * pow(u, 1 / 2.4) - 0.055;
}

double sb_tonemap_apply(const sb_tonemap_t *tm, double x) {
    double e = tm && tm->exposure > 0 ? tm->exposure : 1;
    double u = e * x;
    if (!(u > 0)) return 0; /* negative and NaN */
    if (tm && tm->op == SB_TONEMAP_REINHARD) u = isinf(u) ? 1 : u / (1 + u);
    return sb_srgb_oetf(u);
}

static unsigned char to_byte(double d) {
    double v = floor(d * 255 + 0.5);
    return (unsigned char)(v < 0 ? 0 : v > 255 ? 255 : v);
}

/* ---- comparison --------------------------------------------------------- */

double sb_image_max(const sb_image_t *img) {
    double m = 0;
    if (!img || !img->rgb) return 0;
    for (size_t i = 0; i < img->width * img->height; i++) {
        if (img->mask && !img->mask[i]) continue;
        for (size_t c = 0; c < 3; c++)
            if (img->rgb[3 * i + c] > m) m = img->rgb[3 * i + c];
    }
    return m;
}

static double pixel_y(const double *c) {
    return 0.2126 * fmax(c[0], 0) + 0.7152 * fmax(c[1], 0) + 0.0722 * fmax(c[2], 0);
}

double sb_image_log_average(const sb_image_t *img) {
    if (!img || !img->rgb) return 0;
    double ymax = 0, sum = 0;
    size_t n = 0, N = img->width * img->height;
    for (size_t i = 0; i < N; i++)
        if ((!img->mask || img->mask[i]) && pixel_y(img->rgb + 3 * i) > ymax) ymax = pixel_y(img->rgb + 3 * i);
    if (!(ymax > 0) || !isfinite(ymax)) return 0;
    for (size_t i = 0; i < N; i++) {
        if (img->mask && !img->mask[i]) continue;
        double y = pixel_y(img->rgb + 3 * i);
        if (!isfinite(y)) continue;
        sum += log(1e-4 * ymax + y);
        n++;
    }
    return n ? exp(sum / (double)n) : 0;
}

sb_result_t sb_image_compare(sb_context_t *ctx, const sb_image_t *a, const sb_image_t *b, const sb_tonemap_t *tm,
                             sb_image_diff_t *out) {
    if (!a || !b || !out || !a->rgb || !b->rgb) return sb_error(ctx, SB_ERR_ARG, "image compare: NULL image");
    memset(out, 0, sizeof *out);
    if (a->width != b->width || a->height != b->height)
        return sb_error(ctx, SB_ERR_ARG, "image compare: sizes differ (%zu x %zu vs %zu x %zu)", a->width, a->height,
                        b->width, b->height);
    size_t n = a->width * a->height, count = 0;
    double s_lin = 0, s_disp = 0, m_lin = 0;
    for (size_t i = 0; i < n; i++) {
        int ca = a->mask ? a->mask[i] : 1, cb = b->mask ? b->mask[i] : 1;
        if (!ca && !cb) continue;
        count++;
        for (int c = 0; c < 3; c++) {
            double x = a->rgb[3 * i + (size_t)c], y = b->rgb[3 * i + (size_t)c];
            double dl = x - y, dd = sb_tonemap_apply(tm, x) - sb_tonemap_apply(tm, y);
            s_lin += dl * dl;
            s_disp += dd * dd;
            if (fabs(dl) > m_lin || isnan(dl)) m_lin = fabs(dl);
        }
    }
    out->pixels = count;
    if (count) {
        out->rmse_linear = sqrt(s_lin / (3.0 * (double)count));
        out->rmse = sqrt(s_disp / (3.0 * (double)count));
    }
    out->max_linear = m_lin;
    out->psnr = out->rmse > 0 ? -20 * log10(out->rmse) : INFINITY;
    return SB_OK;
}

/* ---- PNG ---------------------------------------------------------------- */

typedef struct png_err {
    jmp_buf jmp;
    char msg[200];
    int err; /* errno when libpng gave up: a failed fwrite's ("Write Error") */
} png_err_t;

static void png_on_error(png_structp png, png_const_charp msg) {
    png_err_t *e = png_get_error_ptr(png);
    e->err = errno;
    snprintf(e->msg, sizeof e->msg, "%s", msg);
    longjmp(e->jmp, 1);
}
static void png_on_warning(png_structp png, png_const_charp msg) {
    (void)png;
    (void)msg; /* the library never prints */
}

/* Encode into an open file; 0 on success, message in e->msg otherwise.
 * Separate function so that no local of the caller lives across setjmp. */
static int png_encode(FILE *fp, size_t w, size_t h, const unsigned char *rgb, const char *const *text, png_err_t *e) {
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, e, png_on_error, png_on_warning);
    if (!png) {
        snprintf(e->msg, sizeof e->msg, "out of memory");
        return -1;
    }
    png_infop info = png_create_info_struct(png);
    if (!info) {
        png_destroy_write_struct(&png, NULL);
        snprintf(e->msg, sizeof e->msg, "out of memory");
        return -1;
    }
    if (setjmp(e->jmp)) {
        png_destroy_write_struct(&png, &info);
        return -1;
    }
    png_init_io(png, fp);
    png_set_IHDR(png, info, (png_uint_32)w, (png_uint_32)h, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_set_sRGB_gAMA_and_cHRM(png, info, PNG_sRGB_INTENT_PERCEPTUAL);
    png_text txt[8];
    int nt = 0;
    for (; text && text[2 * nt] && text[2 * nt + 1] && nt < 8; nt++) {
        memset(&txt[nt], 0, sizeof txt[nt]);
        txt[nt].compression = PNG_TEXT_COMPRESSION_NONE;
        txt[nt].key = (png_charp)text[2 * nt];
        txt[nt].text = (png_charp)text[2 * nt + 1];
    }
    if (nt) png_set_text(png, info, txt, nt);
    png_write_info(png, info);
    for (size_t y = 0; y < h; y++)
        png_write_row(png, rgb + y * w * 3);
    png_write_end(png, info);
    png_destroy_write_struct(&png, &info);
    return 0;
}

sb_result_t sb_png_write_rgb8(sb_context_t *ctx, const char *path, size_t width, size_t height,
                              const unsigned char *rgb, const char *const *text) {
    if (!path || !rgb) return sb_error(ctx, SB_ERR_ARG, "png: no path or pixels");
    if (!width || !height || width > 0x7fffffffu / 3 || height > 0x7fffffffu)
        return sb_error(ctx, SB_ERR_ARG, "%s: image size %zu x %zu not writable as PNG", path, width, height);
    char tmp[4200];
    if ((size_t)snprintf(tmp, sizeof tmp, "%s.tmp-%ld", path, (long)getpid()) >= sizeof tmp)
        return sb_error(ctx, SB_ERR_ARG, "png: path too long");
    FILE *fp = fopen(tmp, "wb");
    if (!fp) return sb_error(ctx, SB_ERR_IO, "%s: cannot write: %s", path, sb_io_why(errno));
    png_err_t e;
    e.msg[0] = 0;
    e.err = 0;
    errno = 0;
    int ok = png_encode(fp, width, height, rgb, text, &e) == 0;
    if (ok && fflush(fp) != 0) e.err = errno ? errno : EIO;
    if (fclose(fp) != 0 && !e.err) e.err = errno ? errno : EIO;
    if (!e.err && ok && rename(tmp, path) != 0) e.err = errno;
    if (ok && !e.err) return SB_OK;
    remove(tmp);
    if (e.err) return sb_error(ctx, SB_ERR_IO, "%s: cannot write: %s", path, sb_io_why(e.err));
    return sb_error(ctx, SB_ERR_IO, "%s: cannot write%s%s", path, e.msg[0] ? ": " : "", e.msg);
}

static sb_result_t check_image(sb_context_t *ctx, const sb_image_t *img) {
    size_t n;
    if (!img || !img->rgb || !img->width || !img->height) return sb_error(ctx, SB_ERR_ARG, "png: empty image");
    if (sb_size_mul3(img->width, img->height, 3, &n))
        return sb_error(ctx, SB_ERR_ARG, "png: image size %zu x %zu overflows", img->width, img->height);
    return SB_OK;
}

/* Display-encode img into the panel at column x0 of a `stride`-wide buffer. */
static void put_panel(unsigned char *buf, size_t stride, size_t x0, const sb_image_t *img, const sb_tonemap_t *tm) {
    for (size_t y = 0; y < img->height; y++)
        for (size_t x = 0; x < img->width; x++)
            for (size_t c = 0; c < 3; c++)
                buf[(y * stride + x0 + x) * 3 + c] =
                    to_byte(sb_tonemap_apply(tm, img->rgb[(y * img->width + x) * 3 + c]));
}

sb_result_t sb_image_write_png(sb_context_t *ctx, const char *path, const sb_image_t *img, const sb_tonemap_t *tm) {
    sb_result_t r = check_image(ctx, img);
    if (r) return r;
    unsigned char *buf = sb_alloc(ctx, img->width * img->height, 3, "png");
    if (!buf) return SB_ERR_NOMEM;
    put_panel(buf, img->width, 0, img, tm);
    r = sb_png_write_rgb8(ctx, path, img->width, img->height, buf, NULL);
    free(buf);
    return r;
}

#define STRIP_GAP 4

sb_result_t sb_image_write_strip_png(sb_context_t *ctx, const char *path, const sb_image_t *a, const sb_image_t *b,
                                     const sb_tonemap_t *tm, double diff_scale) {
    sb_result_t r;
    if ((r = check_image(ctx, a)) || (r = check_image(ctx, b))) return r;
    if (a->width != b->width || a->height != b->height)
        return sb_error(ctx, SB_ERR_ARG, "png strip: image sizes differ");
    if (!(diff_scale > 0 && isfinite(diff_scale)))
        return sb_error(ctx, SB_ERR_RANGE, "png strip: difference scale %g, need > 0", diff_scale);
    size_t w = a->width, h = a->height, stride = 3 * w + 2 * STRIP_GAP;
    unsigned char *buf = sb_calloc(ctx, stride * h, 3, "png strip");
    if (!buf) return SB_ERR_NOMEM;
    memset(buf, 64, stride * h * 3); /* gaps: dark grey */
    put_panel(buf, stride, 0, a, tm);
    put_panel(buf, stride, w + STRIP_GAP, b, tm);
    size_t x0 = 2 * (w + STRIP_GAP);
    for (size_t y = 0; y < h; y++)
        for (size_t x = 0; x < w; x++)
            for (size_t c = 0; c < 3; c++) {
                size_t i = (y * w + x) * 3 + c;
                double d = fabs(sb_tonemap_apply(tm, a->rgb[i]) - sb_tonemap_apply(tm, b->rgb[i]));
                buf[(y * stride + x0 + x) * 3 + c] = to_byte(fmin(1, diff_scale * d));
            }
    r = sb_png_write_rgb8(ctx, path, stride, h, buf, NULL);
    free(buf);
    return r;
}

/* ---- texture previews --------------------------------------------------- */

/* ColorBrewer RdBu control points at u = -1, -0.5, 0, 0.5, 1 (sRGB bytes),
 * linearly interpolated: a diverging map with white at 0. */
void sb_colormap_diverging(double u, unsigned char rgb[3]) {
    static const double cp[5][3] = {{33, 102, 172}, {146, 197, 222}, {247, 247, 247}, {244, 165, 130}, {178, 24, 43}};
    if (!rgb) return;
    if (!(u > -1)) u = isnan(u) ? 0 : -1;
    if (u > 1) u = 1;
    double t = (u + 1) * 2; /* 0..4 */
    int k = (int)floor(t);
    if (k > 3) k = 3;
    double a = t - k;
    for (int c = 0; c < 3; c++)
        rgb[c] = to_byte(((1 - a) * cp[k][c] + a * cp[k + 1][c]) / 255);
}

#define PREVIEW_TARGET 256 /* longest panel side aimed at, pixels */
#define PREVIEW_MIN 16     /* shortest panel side at least, pixels */

/* Remove DIR/<stem>_scale-*.png other than `keep`. */
static void remove_stale(const char *dir, const char *stem, const char *keep) {
    DIR *d = opendir(dir);
    if (!d) return;
    char prefix[64], path[4200];
    snprintf(prefix, sizeof prefix, "%s_scale-", stem);
    size_t lp = strlen(prefix);
    struct dirent *ent;
    while ((ent = readdir(d)) != NULL) {
        const char *n = ent->d_name;
        size_t ln = strlen(n);
        if (ln <= lp + 4 || strncmp(n, prefix, lp) != 0 || strcmp(n + ln - 4, ".png") != 0) continue;
        if (strcmp(n, keep) == 0) continue;
        snprintf(path, sizeof path, "%s/%s", dir, n);
        remove(path);
    }
    closedir(d);
}

static sb_result_t write_preview(sb_context_t *ctx, const sb_factors_t *f, const char *dir, int side, size_t term) {
    size_t w, h, C = sb_factors_channels(f);
    sb_factors_size(f, side, &w, &h);
    /* scale: max |value| over the channels of this texture */
    double s = 0;
    for (size_t c = 0; c < C; c++) {
        const double *t = sb_factors_tex_const(f, side, term, c);
        for (size_t i = 0; i < w * h; i++)
            if (fabs(t[i]) > s) s = fabs(t[i]);
    }
    size_t longest = w > h ? w : h, k = longest < PREVIEW_TARGET ? PREVIEW_TARGET / longest : 1;
    size_t kx = k, ky = k;
    if (h * ky < PREVIEW_MIN) ky = (PREVIEW_MIN + h - 1) / h;
    size_t pw = w * kx, ph = h * ky, stride, total;
    if (sb_size_mul(pw, C, &stride) || sb_size_add(stride, (C - 1) * STRIP_GAP, &stride) ||
        sb_size_mul(stride, ph, &total))
        return sb_error(ctx, SB_ERR_OVERFLOW, "preview: size overflows");
    unsigned char *buf = sb_alloc(ctx, total, 3, "preview");
    if (!buf) return SB_ERR_NOMEM;
    memset(buf, 64, total * 3);
    for (size_t c = 0; c < C; c++) {
        const double *t = sb_factors_tex_const(f, side, term, c);
        size_t x0 = c * (pw + STRIP_GAP);
        for (size_t y = 0; y < ph; y++)
            for (size_t x = 0; x < pw; x++)
                sb_colormap_diverging(s > 0 ? t[(y / ky) * w + x / kx] / s : 0, buf + (y * stride + x0 + x) * 3);
    }
    char stem[32], name[96], path[4200], scale[32];
    snprintf(stem, sizeof stem, "%s_%02zu", side == SB_SIDE_H ? "h" : "g", term);
    snprintf(scale, sizeof scale, "%.2e", s);
    snprintf(name, sizeof name, "%s_scale-%s.png", stem, scale);
    if ((size_t)snprintf(path, sizeof path, "%s/%s", dir, name) >= sizeof path) {
        free(buf);
        return sb_error(ctx, SB_ERR_ARG, "preview: folder name too long");
    }
    char full[40];
    snprintf(full, sizeof full, "%.9g", s);
    const char *const text[] = {"sepbrdf.scale", full, "sepbrdf.texture", stem, NULL};
    sb_result_t r = sb_png_write_rgb8(ctx, path, stride, ph, buf, text);
    free(buf);
    if (r == SB_OK) remove_stale(dir, stem, name);
    return r;
}

sb_result_t sb_factors_write_previews(sb_context_t *ctx, const sb_factors_t *f, const char *dir) {
    if (!f || !dir) return sb_error(ctx, SB_ERR_ARG, "previews: no factors or folder");
    for (size_t j = 0; j < sb_factors_terms(f); j++)
        for (int side = 0; side < 2; side++) {
            sb_result_t r = write_preview(ctx, f, dir, side, j);
            if (r) return r;
        }
    return SB_OK;
}
