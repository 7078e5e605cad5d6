/* Scenes (scene.h): the spec, its three kinds of pair distributions and
 * drawing pairs from them.
 *
 * Drawing maps a point x of [0,1)^6 to a pair with density proportional
 * to the scene's, so every drawn pair has weight 1:
 *   ranges  cos(theta) uniform over each range, phi = 2 pi x: uniform in
 *           solid angle (x0, x1 for wo, x2, x3 for wi);
 *   lights  p = sqrt(x0) (cos 2 pi x1, sin 2 pi x1), uniform over the unit
 *           disk, the sphere's image (render.h: every covered pixel
 *           alike), light floor(x2 n); L and V into the frame (t, b, n)
 *           of that point;
 *   pairs   the line whose cumulative weight first exceeds x0 times the
 *           total (binary search). */
#include "sepbrdf/scene.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "output/scene_impl.h"
#include "util/internal.h"

#define SPEC_MAX 4096

struct sb_scene {
    sb_scene_kind_t kind;
    char spec[SPEC_MAX];
    double cview[2], clight[2]; /* ranges: cos(theta) at the upper and lower end */
    double range[2][2];         /* ranges: view, light in degrees */
    size_t nlights;
    double light_deg[SB_RENDER_MAX_LIGHTS][2];
    sb_light_t lights[SB_RENDER_MAX_LIGHTS];
    size_t npairs;
    double *pairs; /* pairs: wi, wo (6 doubles a pair) */
    double *cdf;   /* pairs: cumulative weights */
    char *file;
    double floor; /* mass floor of the cells the scene never touches (scene.h) */
};

/* ---- parsing ----------------------------------------------------------- */

/* Where the item at s ends: at ';', at the end, or at a ',' followed by
 * KEY= (a letter, then letters or '_', then '='). */
static size_t item_end(const char *s) {
    for (size_t i = 0;; i++) {
        if (!s[i] || s[i] == ';') return i;
        if (s[i] != ',') continue;
        size_t k = i + 1;
        while ((s[k] >= 'a' && s[k] <= 'z') || s[k] == '_')
            k++;
        if (k > i + 1 && s[k] == '=') return i;
    }
}

/* A number spanning exactly [s, s + n)? */
static int number(const char *s, size_t n, double *out) {
    char buf[64];
    if (n == 0 || n >= sizeof buf) return 0;
    memcpy(buf, s, n);
    buf[n] = 0;
    char *end = NULL;
    errno = 0;
    *out = strtod(buf, &end);
    return end == buf + n && errno == 0 && isfinite(*out);
}

static sb_result_t parse_range(sb_context_t *ctx, const char *key, const char *v, size_t n, double out[2]) {
    const char *dots = strstr(v, "..");
    if (!dots || dots >= v + n || !number(v, (size_t)(dots - v), &out[0]) ||
        !number(dots + 2, (size_t)(v + n - dots - 2), &out[1]))
        return sb_error(ctx, SB_ERR_PARSE, "scene: %s='%.*s' is not a range A..B of degrees (e.g. %s=0..60)", key,
                        (int)n, v, key);
    if (!(out[0] >= 0 && out[0] < out[1] && out[1] <= 90))
        return sb_error(ctx, SB_ERR_RANGE, "scene: %s=%.*s, need 0 <= A < B <= 90 (theta from the normal, degrees)",
                        key, (int)n, v);
    return SB_OK;
}

static sb_result_t parse_lights(sb_context_t *ctx, sb_scene_t *s, const char *v, size_t n) {
    for (const char *p = v, *end = v + n; p <= end;) {
        const char *slash = memchr(p, '/', (size_t)(end - p)), *stop = slash ? slash : end;
        const char *comma = memchr(p, ',', (size_t)(stop - p));
        double el, az;
        if (!comma || !number(p, (size_t)(comma - p), &el) || !number(comma + 1, (size_t)(stop - comma - 1), &az))
            return sb_error(ctx, SB_ERR_PARSE, "scene: light '%.*s' is not EL,AZ (degrees; lights=EL,AZ/EL,AZ/...)",
                            (int)(stop - p), p);
        if (!(el >= 0 && el <= 90) || !(fabs(az) <= 360))
            return sb_error(ctx, SB_ERR_RANGE, "scene: light '%.*s': elevation must be in 0..90, azimuth in -360..360",
                            (int)(stop - p), p);
        if (s->nlights == SB_RENDER_MAX_LIGHTS)
            return sb_error(ctx, SB_ERR_RANGE, "scene: more than %d lights", SB_RENDER_MAX_LIGHTS);
        s->light_deg[s->nlights][0] = el;
        s->light_deg[s->nlights][1] = az;
        sb_light_from_angles(el, az, 0, &s->lights[s->nlights++]);
        p = stop + 1;
    }
    return SB_OK;
}

/* One line of a pairs file into s (grown as needed); 0 for a blank or
 * comment line, 1 for a pair, -1 for a malformed line. */
static int pairs_line(char *line, double v[5]) {
    char *hash = strchr(line, '#');
    if (hash) *hash = 0;
    int k = 0;
    for (char *p = line, *end;; p = end) {
        while (*p == ' ' || *p == '\t' || *p == '\r' || *p == '\n')
            p++;
        if (!*p) break;
        if (k == 5) return -1;
        errno = 0;
        v[k] = strtod(p, &end);
        if (end == p || errno || !isfinite(v[k])) return -1;
        k++;
    }
    if (k == 0) return 0;
    if (k < 4) return -1;
    if (k == 4) v[4] = 1;
    return 1;
}

static sb_result_t pairs_add(sb_context_t *ctx, sb_scene_t *s, const double v[5], size_t *cap) {
    if (s->npairs == *cap) {
        size_t nc = *cap ? 2 * *cap : 256;
        double *p = realloc(s->pairs, nc * 6 * sizeof *p), *c = p ? realloc(s->cdf, nc * sizeof *c) : NULL;
        if (p) s->pairs = p;
        if (c) s->cdf = c;
        if (!p || !c) return sb_error(ctx, SB_ERR_NOMEM, "scene: out of memory for %zu pairs", nc);
        *cap = nc;
    }
    double *w = s->pairs + 6 * s->npairs, d2r = SB_PI / 180;
    sb_dir_from_angles(v[0] * d2r, v[1] * d2r, w);
    sb_dir_from_angles(v[2] * d2r, v[3] * d2r, w + 3);
    s->cdf[s->npairs] = (s->npairs ? s->cdf[s->npairs - 1] : 0) + v[4];
    s->npairs++;
    return SB_OK;
}

static sb_result_t parse_pairs(sb_context_t *ctx, sb_scene_t *s, const char *path) {
    sb_result_t r = SB_OK;
    FILE *fp = sb_fopen_regular(ctx, path, "scene: pairs file", SB_SCENE_MAX_FILE, &r);
    if (!fp) return SB_ERR_IO; /* the message names the file and why */
    char line[1024];
    size_t cap = 0, ln = 0;
    while (r == SB_OK && fgets(line, sizeof line, fp)) {
        double v[5];
        ln++;
        int k = pairs_line(line, v);
        if (k < 0)
            r = sb_error(ctx, SB_ERR_PARSE, "scene: %s:%zu: not 'theta_i phi_i theta_o phi_o [weight]' (degrees)", path,
                         ln);
        else if (k > 0 && !(v[0] >= 0 && v[0] <= 90 && v[2] >= 0 && v[2] <= 90 && v[4] >= 0))
            r = sb_error(ctx, SB_ERR_RANGE, "scene: %s:%zu: theta must be in 0..90 and the weight >= 0", path, ln);
        else if (k > 0 && s->npairs == SB_SCENE_MAX_PAIRS)
            r = sb_error(ctx, SB_ERR_RANGE, "scene: %s:%zu: more than %d pairs", path, ln, SB_SCENE_MAX_PAIRS);
        else if (k > 0)
            r = pairs_add(ctx, s, v, &cap);
    }
    fclose(fp);
    if (r == SB_OK && !(s->npairs && s->cdf[s->npairs - 1] > 0))
        r = sb_error(ctx, SB_ERR_RANGE, "scene: pairs file %s holds no pair of positive weight", path);
    return r;
}

/* One item KEY=VALUE of n characters; seen[] marks keys given. */
/* floor=X: a number in [0, SB_SCENE_FLOOR_MAX]. */
static sb_result_t parse_floor(sb_context_t *ctx, sb_scene_t *s, const char *v, size_t vn) {
    char buf[64], *end = NULL;
    if (vn == 0 || vn >= sizeof buf)
        return sb_error(ctx, SB_ERR_PARSE, "scene: floor=X needs a number in 0..%g", SB_SCENE_FLOOR_MAX);
    memcpy(buf, v, vn);
    buf[vn] = 0;
    double x = strtod(buf, &end);
    if (*end || !(x >= 0 && x <= SB_SCENE_FLOOR_MAX))
        return sb_error(ctx, SB_ERR_RANGE, "scene: floor '%s' must be a number in 0..%g", buf, SB_SCENE_FLOOR_MAX);
    s->floor = x;
    return SB_OK;
}

static sb_result_t parse_item(sb_context_t *ctx, sb_scene_t *s, const char *it, size_t n, int seen[5]) {
    static const char *const keys[5] = {"view", "light", "lights", "pairs", "floor"};
    const char *eq = memchr(it, '=', n);
    size_t kn = eq ? (size_t)(eq - it) : n;
    int k = 0;
    while (k < 5 && !(strlen(keys[k]) == kn && strncmp(it, keys[k], kn) == 0))
        k++;
    if (!eq || k == 5)
        return sb_error(ctx, SB_ERR_PARSE,
                        "scene: '%.*s' is not one of view=A..B, light=A..B, lights=EL,AZ/..., pairs=FILE, floor=X",
                        (int)n, it);
    if (seen[k]++) return sb_error(ctx, SB_ERR_PARSE, "scene: %s given twice", keys[k]);
    const char *v = eq + 1;
    size_t vn = n - kn - 1;
    if (k == 4) return parse_floor(ctx, s, v, vn);
    if (k < 2) return parse_range(ctx, keys[k], v, vn, s->range[k]);
    if (k == 2) return parse_lights(ctx, s, v, vn);
    if (!(s->file = sb_alloc(ctx, vn + 1, 1, "scene"))) return SB_ERR_NOMEM;
    memcpy(s->file, v, vn);
    s->file[vn] = 0;
    return parse_pairs(ctx, s, s->file);
}

/* The kind from the keys given; the canonical spec. */
static sb_result_t settle(sb_context_t *ctx, sb_scene_t *s, const int seen[5]) {
    int kinds = (seen[0] || seen[1]) + seen[2] + seen[3];
    if (kinds != 1)
        return sb_error(ctx, SB_ERR_PARSE, "scene: %s",
                        kinds ? "one kind only: view/light ranges, lights= or pairs="
                              : "empty; need view=A..B;light=C..D, lights=EL,AZ/... "
                                "or pairs=FILE");
    s->kind = seen[2] ? SB_SCENE_LIGHTS : seen[3] ? SB_SCENE_PAIRS : SB_SCENE_RANGES;
    size_t at = 0;
    if (s->kind == SB_SCENE_RANGES) {
        for (int k = 0; k < 2; k++)
            if (!seen[k]) s->range[k][1] = 90;
        double d2r = SB_PI / 180;
        s->cview[0] = cos(s->range[0][1] * d2r), s->cview[1] = cos(s->range[0][0] * d2r);
        s->clight[0] = cos(s->range[1][1] * d2r), s->clight[1] = cos(s->range[1][0] * d2r);
        snprintf(s->spec, sizeof s->spec, "view=%g..%g;light=%g..%g", s->range[0][0], s->range[0][1], s->range[1][0],
                 s->range[1][1]);
    } else if (s->kind == SB_SCENE_LIGHTS) {
        at = (size_t)snprintf(s->spec, sizeof s->spec, "lights=");
        for (size_t i = 0; i < s->nlights; i++)
            at += (size_t)snprintf(s->spec + at, sizeof s->spec - at, "%s%g,%g", i ? "/" : "", s->light_deg[i][0],
                                   s->light_deg[i][1]);
    } else {
        at = (size_t)snprintf(s->spec, sizeof s->spec, "pairs=%s", s->file);
    }
    at = strlen(s->spec);
    if (s->floor >= 0) snprintf(s->spec + at, sizeof s->spec - at, ";floor=%g", s->floor);
    return SB_OK;
}

sb_result_t sb_scene_parse(sb_context_t *ctx, const char *spec, sb_scene_t **out) {
    if (!spec || !out) return sb_error(ctx, SB_ERR_ARG, "scene: NULL argument");
    *out = NULL;
    sb_scene_t *s = calloc(1, sizeof *s);
    if (!s) return sb_error(ctx, SB_ERR_NOMEM, "scene: out of memory");
    int seen[5] = {0, 0, 0, 0, 0};
    s->floor = -1; /* not given: sb_scene_mass_floor's default */
    sb_result_t r = SB_OK;
    for (const char *p = spec; *p && r == SB_OK;) {
        size_t n = item_end(p);
        if (n == 0) {
            r = sb_error(ctx, SB_ERR_PARSE, "scene: empty item in '%s'", spec);
            break;
        }
        r = parse_item(ctx, s, p, n, seen);
        p += n + (p[n] != 0);
    }
    if (r == SB_OK) r = settle(ctx, s, seen);
    if (r != SB_OK) {
        sb_scene_destroy(s);
        return r;
    }
    *out = s;
    return SB_OK;
}

void sb_scene_destroy(sb_scene_t *s) {
    if (!s) return;
    free(s->pairs);
    free(s->cdf);
    free(s->file);
    free(s);
}

sb_scene_kind_t sb_scene_kind(const sb_scene_t *s) { return s ? s->kind : SB_SCENE_RANGES; }
const char *sb_scene_spec(const sb_scene_t *s) { return s ? s->spec : ""; }
double sb_scene_floor(const sb_scene_t *s) { return s ? s->floor : -1; }

size_t sb_scene_lights(const sb_scene_t *s, sb_light_t *out, size_t max) {
    if (!s || !out || s->kind != SB_SCENE_LIGHTS) return 0;
    size_t n = s->nlights < max ? s->nlights : max;
    memcpy(out, s->lights, n * sizeof *out);
    return n;
}

/* ---- drawing ----------------------------------------------------------- */

/* cos(theta) = lo + (hi - lo) u, azimuth 2 pi v. */
static void dir_in(const double c[2], double u, double v, double w[3]) {
    double z = c[0] + (c[1] - c[0]) * u, sn = sqrt(fmax(0, 1 - z * z)), ph = 2 * SB_PI * v;
    w[0] = sn * cos(ph);
    w[1] = sn * sin(ph);
    w[2] = z;
}

static double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

int sb_scene_light_pair_(const sb_scene_t *s, double px, double py, size_t k, double wi[3], double wo[3]) {
    double n[3], t[3], b[3];
    if (!s || s->kind != SB_SCENE_LIGHTS || k >= s->nlights || !sb_render_frame_at(px, py, n, t, b)) return 0;
    const double *l = s->lights[k].dir;
    wi[0] = dot3(l, t), wi[1] = dot3(l, b), wi[2] = dot3(l, n);
    wo[0] = t[2], wo[1] = b[2], wo[2] = n[2]; /* the viewer (0, 0, 1) */
    return wi[2] > 0;
}

size_t sb_scene_light_count_(const sb_scene_t *s) { return s && s->kind == SB_SCENE_LIGHTS ? s->nlights : 0; }

const double *sb_scene_light_dir_(const sb_scene_t *s, size_t k) {
    return s && s->kind == SB_SCENE_LIGHTS && k < s->nlights ? s->lights[k].dir : NULL;
}

static double draw_lights(const sb_scene_t *s, const double x[6], double wi[3], double wo[3]) {
    double r = sqrt(x[0]), a = 2 * SB_PI * x[1];
    size_t k = (size_t)(x[2] * (double)s->nlights);
    return sb_scene_light_pair_(s, r * cos(a), r * sin(a), k < s->nlights ? k : s->nlights - 1, wi, wo);
}

static double draw_pairs(const sb_scene_t *s, const double x[6], double wi[3], double wo[3]) {
    double target = x[0] * s->cdf[s->npairs - 1];
    size_t lo = 0, hi = s->npairs - 1;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (s->cdf[mid] > target)
            hi = mid;
        else
            lo = mid + 1;
    }
    memcpy(wi, s->pairs + 6 * lo, 3 * sizeof *wi);
    memcpy(wo, s->pairs + 6 * lo + 3, 3 * sizeof *wo);
    return 1;
}

double sb_scene_draw(const sb_scene_t *s, const double x[6], double wi[3], double wo[3]) {
    if (!s || !x || !wi || !wo) return 0;
    if (s->kind == SB_SCENE_LIGHTS) return draw_lights(s, x, wi, wo);
    if (s->kind == SB_SCENE_PAIRS) return draw_pairs(s, x, wi, wo);
    dir_in(s->cview, x[0], x[1], wo);
    dir_in(s->clight, x[2], x[3], wi);
    return 1;
}

/* Within [c0, c1], up to rounding of the draw's c0 + (c1 - c0) u. */
static int within(const double c[2], double z) { return z >= c[0] - 1e-12 && z <= c[1] + 1e-12; }

double sb_scene_ranges_pdf_(const sb_scene_t *s, const double wi[3], const double wo[3]) {
    if (!s || s->kind != SB_SCENE_RANGES || !within(s->cview, wo[2]) || !within(s->clight, wi[2])) return 0;
    return 1 / (4 * SB_PI * SB_PI * (s->cview[1] - s->cview[0]) * (s->clight[1] - s->clight[0]));
}
