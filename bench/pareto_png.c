/* The Pareto plot of `sepbrdf bench --pareto` (pareto.h): CPU seconds
 * (x) against the headline error (y), both logarithmic, every point a
 * dot, the points on the front red and joined; decade grid lines with
 * their labels in a 3 x 5 pixel font (scaled 2x), written with libpng
 * through sb_png_write_rgb8. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "pareto.h"
#include "sepbrdf/sepbrdf.h"

#define W 640
#define H 420
#define ML 70 /* margins: left, right, top, bottom */
#define MR 20
#define MT 20
#define MB 50

typedef struct canvas {
    unsigned char *px;
} canvas_t;

static void dot(canvas_t *c, int x, int y, const unsigned char rgb[3]) {
    if (x < 0 || y < 0 || x >= W || y >= H) return;
    memcpy(c->px + 3 * ((size_t)y * W + (size_t)x), rgb, 3);
}

static void rect(canvas_t *c, int x0, int y0, int x1, int y1, const unsigned char rgb[3]) {
    for (int y = y0; y <= y1; y++)
        for (int x = x0; x <= x1; x++)
            dot(c, x, y, rgb);
}

static void line(canvas_t *c, int x0, int y0, int x1, int y1, const unsigned char rgb[3]) {
    int n = abs(x1 - x0) > abs(y1 - y0) ? abs(x1 - x0) : abs(y1 - y0);
    for (int i = 0; i <= n; i++) {
        double t = n ? (double)i / n : 0;
        dot(c, (int)lround(x0 + t * (x1 - x0)), (int)lround(y0 + t * (y1 - y0)), rgb);
    }
}

/* 3 x 5 glyphs, rows top to bottom, 3 bits a row (MSB left). */
static unsigned glyph(char ch) {
    static const char *const keys = "0123456789.-eCPUshadlinr";
    static const unsigned rows[] = {
        075557, 026227, 071747, 071717, 055711, 074717, 074757, 071111, 075757, 075717, 000002, 000700,
        035743, 074447, 075744, 055557, 034216, 044755, 003553, 013553, 022222, 020222, 000755, 000644,
    };
    const char *p = strchr(keys, ch);
    return p && ch ? rows[p - keys] : 0;
}

static void text(canvas_t *c, int x, int y, const char *s, const unsigned char rgb[3]) {
    for (; *s; s++, x += 8) {
        unsigned g = glyph(*s);
        for (int r = 0; r < 5; r++)
            for (int b = 0; b < 3; b++)
                if (g >> (3 * (4 - r) + (2 - b)) & 1) rect(c, x + 2 * b, y + 2 * r, x + 2 * b + 1, y + 2 * r + 1, rgb);
    }
}

typedef struct axes {
    double x0, x1, y0, y1; /* log10 ranges */
} axes_t;

static int px_x(const axes_t *a, double v) {
    return ML + (int)lround((log10(v) - a->x0) / (a->x1 - a->x0) * (W - ML - MR));
}
static int px_y(const axes_t *a, double v) {
    return H - MB - (int)lround((log10(v) - a->y0) / (a->y1 - a->y0) * (H - MT - MB));
}

/* Decade ranges that hold every point. */
static axes_t fit_axes(const pareto_point_t *p, size_t n) {
    axes_t a = {INFINITY, -INFINITY, INFINITY, -INFINITY};
    for (size_t i = 0; i < n; i++) {
        if (!p[i].ok) continue;
        a.x0 = fmin(a.x0, floor(log10(p[i].cpu_s))), a.x1 = fmax(a.x1, ceil(log10(p[i].cpu_s)));
        a.y0 = fmin(a.y0, floor(log10(p[i].headline))), a.y1 = fmax(a.y1, ceil(log10(p[i].headline)));
    }
    if (!(a.x1 > a.x0)) a.x1 = a.x0 + 1;
    if (!(a.y1 > a.y0)) a.y1 = a.y0 + 1;
    return a;
}

static void grid(canvas_t *c, const axes_t *a) {
    static const unsigned char grey[3] = {220, 220, 220}, black[3] = {0, 0, 0};
    char lab[16];
    for (double e = a->x0; e <= a->x1 + 0.5; e++) {
        int x = px_x(a, pow(10, e));
        line(c, x, MT, x, H - MB, grey);
        snprintf(lab, sizeof lab, "%g", pow(10, e));
        text(c, x - 4 * (int)strlen(lab), H - MB + 8, lab, black);
    }
    for (double e = a->y0; e <= a->y1 + 0.5; e++) {
        int y = px_y(a, pow(10, e));
        line(c, ML, y, W - MR, y, grey);
        snprintf(lab, sizeof lab, "1e%d", (int)e);
        text(c, ML - 8 - 8 * (int)strlen(lab), y - 5, lab, black);
    }
    line(c, ML, H - MB, W - MR, H - MB, black);
    line(c, ML, MT, ML, H - MB, black);
    text(c, W / 2 - 20, H - 18, "CPU s", black);
    text(c, ML + 6, 4, "headline", black);
}

int pareto_plot(const char *path, const pareto_point_t *p, size_t n, const size_t *front, size_t nfront) {
    canvas_t c = {malloc((size_t)W * H * 3)};
    if (!c.px) return 2;
    memset(c.px, 255, (size_t)W * H * 3);
    axes_t a = fit_axes(p, n);
    grid(&c, &a);
    static const unsigned char blue[3] = {60, 90, 200}, red[3] = {220, 30, 30};
    for (size_t i = 0; i < n; i++)
        if (p[i].ok)
            rect(&c, px_x(&a, p[i].cpu_s) - 2, px_y(&a, p[i].headline) - 2, px_x(&a, p[i].cpu_s) + 2,
                 px_y(&a, p[i].headline) + 2, blue);
    for (size_t k = 0; k < nfront; k++) {
        const pareto_point_t *q = &p[front[k]];
        int x = px_x(&a, q->cpu_s), y = px_y(&a, q->headline);
        if (k > 0) line(&c, px_x(&a, p[front[k - 1]].cpu_s), px_y(&a, p[front[k - 1]].headline), x, y, red);
        rect(&c, x - 3, y - 3, x + 3, y + 3, red);
    }
    const char *const meta[] = {"Title", "sepbrdf bench --pareto: CPU seconds against headline error", NULL};
    int rc = sb_png_write_rgb8(NULL, path, W, H, c.px, meta) == SB_OK ? 0 : 2;
    free(c.px);
    return rc;
}
