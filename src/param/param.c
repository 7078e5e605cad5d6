/* Parameterisations: spec parsing, dispatch, shared grid
 * helpers, spherical angles. */
#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "param/param_impl.h"
#include "param/serial.h"
#include "sepbrdf/source.h"
#include "util/internal.h"

/* 1 if `key` is one of the comma-separated `keys`. */
static int key_listed(const char *keys, const char *key) {
    size_t n = strlen(key);
    for (const char *k = keys; k && *k;) {
        const char *end = strchr(k, ',');
        size_t len = end ? (size_t)(end - k) : strlen(k);
        if (len == n && strncmp(k, key, n) == 0) return 1;
        k = end ? end + 1 : NULL;
    }
    return 0;
}

/* The option a count key sets (res, th, td, pd), NULL for another key. */
static size_t *count_key(sb_param_opts_t *o, const char *key) {
    if (strcmp(key, "res") == 0) return &o->res;
    if (strcmp(key, "th") == 0) return &o->res_theta_h;
    if (strcmp(key, "td") == 0) return &o->res_theta_d;
    if (strcmp(key, "pd") == 0 || strcmp(key, "ph") == 0) return &o->res_phi_d;
    if (strcmp(key, "tv") == 0 || strcmp(key, "ti") == 0) return &o->res_theta_v;
    if (strcmp(key, "tr") == 0) return &o->res_theta_h;
    if (strcmp(key, "pr") == 0) return &o->res_phi_d;
    return NULL;
}

/* "KIND[:key=value,...]" in buf (split in place on ':' and ','), numbers
 * by strtod. */
static sb_result_t parse_spec(sb_context_t *ctx, char *buf, sb_param_kind_t *kind, sb_param_opts_t *opts) {
    char *args = strchr(buf, ':');
    if (args) *args++ = 0;
    sb_param_kind_t k;
    if (sb_param_kind_parse(buf, &k) != SB_OK) {
        char names[128];
        sb_param_kind_list(names, sizeof names, ", ");
        return sb_error(ctx, SB_ERR_UNKNOWN, "unknown parameterisation '%s' (%s)", buf, names);
    }
    sb_param_opts_t o = {0};
    while (args && *args) {
        char *comma = strchr(args, ',');
        if (comma) *comma = 0;
        char *eq = strchr(args, '=');
        if (!eq || eq == args) return sb_error(ctx, SB_ERR_PARSE, "%s: '%s' is not key=value", buf, args);
        *eq = 0;
        const char *key = args, *val = eq + 1;
        int axis = strcmp(key, "warp_h") == 0 ? SB_AXIS_THETA_H : (strcmp(key, "warp_d") == 0 ? SB_AXIS_THETA_D : -1);
        if (axis >= 0 && (sb_param_desc_of(k)->caps & SB_CAP_WARPS)) {
            sb_result_t r = sb_warp_parse_value(ctx, val, &o.warp[axis]);
            if (r != SB_OK) return r;
            args = comma ? comma + 1 : NULL;
            continue;
        }
        char *end;
        errno = 0;
        double v = strtod(val, &end);
        if (end == val || *end || errno == ERANGE || !isfinite(v))
            return sb_error(ctx, SB_ERR_PARSE, "%s: key '%s': '%s' is not a number", buf, key, val);
        size_t *count = key_listed(sb_param_desc_of(k)->keys, key) ? count_key(&o, key) : NULL;
        if (!count && strcmp(key, "plain") == 0) {
            if (v != 0 && v != 1) return sb_error(ctx, SB_ERR_RANGE, "%s: plain %s, need 0 or 1", buf, val);
            o.plain = (int)v;
        } else if (!count && strcmp(key, "theta_max") == 0) {
            if (!(v > 0 && v <= 90)) return sb_error(ctx, SB_ERR_RANGE, "%s: theta_max %s not in (0, 90]", buf, val);
            o.theta_max = v * SB_PI / 180;
        } else if (!count)
            return sb_error(ctx, SB_ERR_UNKNOWN, "%s: unknown key '%s'", buf, key);
        if (count) {
            if (v != floor(v))
                return sb_error(ctx, SB_ERR_PARSE, "%s: key '%s': '%s' is not a whole number", buf, key, val);
            if (!(v >= 1 && v <= 1e9))
                return sb_error(ctx, SB_ERR_RANGE, "%s: key '%s' = %s out of range", buf, key, val);
            *count = (size_t)v;
        }
        args = comma ? comma + 1 : NULL;
    }
    *kind = k;
    *opts = o;
    return SB_OK;
}

/* A copy of spec of any length (warp tables written with many digits run
 * to thousands of characters), parsed. */
sb_result_t sb_param_parse_spec(sb_context_t *ctx, const char *spec, sb_param_kind_t *kind, sb_param_opts_t *opts) {
    if (!spec || !kind || !opts) return sb_error(ctx, SB_ERR_ARG, "param: no spec or output");
    char *buf = malloc(strlen(spec) + 1);
    if (!buf) return sb_error(ctx, SB_ERR_NOMEM, "param: out of memory");
    sb_result_t r = parse_spec(ctx, strcpy(buf, spec), kind, opts);
    free(buf);
    return r;
}

/* The layout's own warp where opts name none; tables rounded to the
 * spec's digits and checked; none at all on a layout without warps. */
static sb_result_t resolve_warps(sb_context_t *ctx, sb_param_t *p, const sb_param_desc_t *d) {
    for (int a = 0; a < SB_AXIS_COUNT_; a++) {
        sb_warp_t *w = &p->opts.warp[a];
        if (!(d->caps & SB_CAP_WARPS)) {
            if (w->kind != SB_WARP_DEFAULT)
                return sb_error(ctx, SB_ERR_UNSUPPORTED, "%s has no axis that takes a warp", d->name);
            continue;
        }
        if (w->kind == SB_WARP_DEFAULT) w->kind = d->warp[a];
        sb_warp_round(w);
        sb_result_t r = sb_warp_check(ctx, w);
        if (r != SB_OK) return r;
    }
    return SB_OK;
}

/* p->glsl: the warp functions sb_warp_h, sb_warp_d (SB_CAP_WARPS), then
 * the layout's coordinate functions. */
static sb_result_t build_glsl(sb_context_t *ctx, sb_param_t *p) {
    static const char *const names[SB_AXIS_COUNT_] = {"sb_warp_h", "sb_warp_d"};
    if (p->glsl) return SB_OK; /* the layout's init built its own */
    int warps = (p->desc->caps & SB_CAP_WARPS) != 0;
    size_t need = strlen(p->vt->glsl) + 1, n = 0;
    for (int a = 0; a < SB_AXIS_COUNT_ && warps; a++)
        need += sb_warp_glsl(&p->opts.warp[a], names[a], NULL, 0, &n);
    if (!(p->glsl = malloc(need))) return sb_error(ctx, SB_ERR_NOMEM, "param: out of memory");
    n = 0;
    for (int a = 0; a < SB_AXIS_COUNT_ && warps; a++)
        sb_warp_glsl(&p->opts.warp[a], names[a], p->glsl, need, &n);
    snprintf(p->glsl + n, need - n, "%s", p->vt->glsl);
    return SB_OK;
}

/* What sb_param_coords of a layout depends on, padding zeroed (compared
 * with memcmp). */
typedef struct layout_id {
    int kind, wrap[2][2], warp_kind[SB_AXIS_COUNT_];
    size_t rows, cols, tex_w[2], tex_h[2], res[5], knots[SB_AXIS_COUNT_];
    double theta_max, x[SB_AXIS_COUNT_][SB_WARP_MAX_KNOTS + 1];
} layout_id_t;

#define LAYOUTS_MAX 4096 /* layouts remembered; beyond, a new number each */
static layout_id_t *layouts;
static size_t nlayouts, caplayouts;
static pthread_mutex_t layouts_mu = PTHREAD_MUTEX_INITIALIZER;

/* The number of p's layout: the same for every parameterisation created
 * with the same resolved layout (the estimator's pairs keep coordinates
 * under it: auto's candidates of one layout and several forms share
 * them), a new one for a layout not seen before. */
static unsigned long layout_serial(const sb_param_t *p) {
    static atomic_ulong fresh = LAYOUTS_MAX;               /* numbers 1..LAYOUTS_MAX name the remembered layouts */
    if (p->tables) return atomic_fetch_add(&fresh, 1) + 1; /* its coordinates depend on its tables */
    layout_id_t id;
    memset(&id, 0, sizeof id);
    id.kind = (int)p->kind;
    memcpy(id.wrap, p->wrap, sizeof id.wrap);
    id.rows = p->rows, id.cols = p->cols;
    memcpy(id.tex_w, p->tex_w, sizeof id.tex_w);
    memcpy(id.tex_h, p->tex_h, sizeof id.tex_h);
    id.res[0] = p->opts.res;
    if (strcmp(p->desc->keys ? p->desc->keys : "", "res") != 0) { /* their own cell counts; the others ignore them */
        id.res[1] = p->opts.res_theta_h, id.res[2] = p->opts.res_theta_d;
        id.res[3] = p->opts.res_phi_d, id.res[4] = p->opts.res_theta_v;
    }
    id.theta_max = p->opts.theta_max;
    for (int a = 0; a < SB_AXIS_COUNT_; a++) {
        const sb_warp_t *w = &p->opts.warp[a];
        id.warp_kind[a] = (int)w->kind;
        id.knots[a] = w->kind == SB_WARP_TABLE ? w->knots : 0;
        for (size_t k = 0; w->kind == SB_WARP_TABLE && k <= w->knots && k <= SB_WARP_MAX_KNOTS; k++)
            id.x[a][k] = w->x[k];
    }
    unsigned long serial = 0;
    pthread_mutex_lock(&layouts_mu);
    for (size_t i = 0; i < nlayouts && !serial; i++)
        if (memcmp(&layouts[i], &id, sizeof id) == 0) serial = (unsigned long)i + 1;
    if (!serial && nlayouts < LAYOUTS_MAX) {
        if (nlayouts == caplayouts) {
            size_t cap = caplayouts ? 2 * caplayouts : 16;
            layout_id_t *grown = realloc(layouts, cap * sizeof *grown);
            if (grown) layouts = grown, caplayouts = cap;
        }
        if (nlayouts < caplayouts) {
            layouts[nlayouts++] = id;
            serial = (unsigned long)nlayouts;
        }
    }
    pthread_mutex_unlock(&layouts_mu);
    return serial ? serial : atomic_fetch_add(&fresh, 1) + 1;
}

sb_result_t sb_param_create(sb_context_t *ctx, sb_param_kind_t kind, const sb_param_opts_t *opts, sb_param_t **out) {
    if (!out) return sb_error(ctx, SB_ERR_ARG, "param: no output pointer");
    *out = NULL;
    sb_param_t *p = calloc(1, sizeof *p);
    if (!p) return sb_error(ctx, SB_ERR_NOMEM, "param: out of memory");
    if (opts) p->opts = *opts;
    if (!(sb_param_kind_caps(kind) & SB_CAP_TABLES)) p->opts.tables = NULL; /* only those layouts keep them */
    if (p->opts.res == 0) p->opts.res = 32;
    /* 0 and pi/2 up to rounding (e.g. 90 degrees converted) mean the hemisphere */
    if (p->opts.theta_max == 0 || fabs(p->opts.theta_max - SB_PI / 2) < 1e-12) p->opts.theta_max = SB_PI / 2;
    p->kind = kind;
    sb_result_t r;
    if (p->opts.res < 2 || p->opts.res > 4096) {
        r = sb_error(ctx, SB_ERR_RANGE, "resolution %zu out of range, need 2..4096", p->opts.res);
    } else if (!(p->opts.theta_max > 0 && p->opts.theta_max <= SB_PI / 2 + 1e-12)) {
        r = sb_error(ctx, SB_ERR_RANGE, "theta_max %g out of range, need (0, pi/2]", p->opts.theta_max);
    } else if (!(p->desc = sb_param_desc_of(kind))) {
        r = sb_error(ctx, SB_ERR_ARG, "param: unknown kind %d", (int)kind);
    } else if ((r = resolve_warps(ctx, p, p->desc)) == SB_OK) {
        const sb_param_desc_t *d = p->desc;
        if (d->init) {
            p->vt = d->vt; /* the library's own may set another */
            p->in_init = 1;
            r = d->init(ctx, p);
            p->in_init = 0;
            if (r == SB_OK && !p->rows) r = sb_error(ctx, SB_ERR_ARG, "param: %s's init gave no shape", d->name);
        } else {
            sb_param_square_grids(p, d->vt, d->name, d->wrap_y);
            r = SB_OK;
        }
        if (r == SB_OK) r = build_glsl(ctx, p);
    }
    if (r != SB_OK) {
        sb_param_destroy(p);
        return r;
    }
    p->serial = layout_serial(p);
    *out = p;
    return SB_OK;
}

unsigned long sb_param_serial_(const sb_param_t *p) { return p ? p->serial : 0; }

void sb_param_destroy(sb_param_t *p) {
    if (!p) return;
    sb_layout_tables_destroy(p->tables);
    free(p->glsl);
    free(p);
}

/* Getters: safe values on NULL and out-of-range arguments (common.h). */
sb_param_kind_t sb_param_kind(const sb_param_t *p) { return p ? p->kind : SB_PARAM_NONE; }
const char *sb_param_name(const sb_param_t *p) { return p ? p->desc->name : ""; }
const char *sb_param_spec(const sb_param_t *p) { return p ? p->spec : ""; }
size_t sb_param_rows(const sb_param_t *p) { return p ? p->rows : 0; }
size_t sb_param_cols(const sb_param_t *p) { return p ? p->cols : 0; }
double sb_param_theta_max(const sb_param_t *p) { return p ? p->opts.theta_max : NAN; }
void sb_param_texture_size(const sb_param_t *p, int side, size_t *w, size_t *h) {
    int ok = p && (side == SB_SIDE_G || side == SB_SIDE_H);
    if (w) *w = ok ? p->tex_w[side] : 0;
    if (h) *h = ok ? p->tex_h[side] : 0;
}
void sb_param_wrap(const sb_param_t *p, int side, int wrap[2]) {
    if (!wrap) return;
    int ok = p && (side == SB_SIDE_G || side == SB_SIDE_H);
    wrap[0] = ok ? p->wrap[side][0] : 0;
    wrap[1] = ok ? p->wrap[side][1] : 0;
}
void sb_param_edge(const sb_param_t *p, int side, int edge[2]) {
    if (!edge) return;
    int ok = p && (side == SB_SIDE_G || side == SB_SIDE_H);
    edge[0] = ok ? p->edge[side][0] : SB_EDGE_CLAMP;
    edge[1] = ok ? p->edge[side][1] : SB_EDGE_CLAMP;
}
int sb_param_cell_dirs(const sb_param_t *p, size_t row, size_t col, double wi[3], double wo[3]) {
    if (!p || !wi || !wo || row >= p->rows || col >= p->cols) return 0;
    return p->vt->cell_dirs(p, row, col, wi, wo);
}
double sb_param_row_measure(const sb_param_t *p, size_t row) {
    return p && row < p->rows ? p->vt->row_measure(p, row) : NAN;
}
double sb_param_col_measure(const sb_param_t *p, size_t col) {
    return p && col < p->cols ? p->vt->col_measure(p, col) : NAN;
}
int sb_param_coords(const sb_param_t *p, const double wi[3], const double wo[3], double st_g[2], double st_h[2]) {
    if (!p || !wi || !wo || !st_g || !st_h) return 0;
    return p->vt->coords(p, wi, wo, st_g, st_h);
}
const char *sb_param_glsl(const sb_param_t *p) { return p ? p->glsl : ""; }
double sb_param_gain(const sb_param_t *p, const double wi[3], const double wo[3]) {
    return p && wi && wo && p->vt->gain ? p->vt->gain(p, wi, wo) : 1;
}
const sb_layout_tables_t *sb_param_tables(const sb_param_t *p) { return p ? p->tables : NULL; }
int sb_param_cell_value(const sb_param_t *p, size_t row, size_t col, double rgb[3]) {
    if (!p || !rgb || row >= p->rows || col >= p->cols || !p->vt->cell_value) return 0;
    return p->vt->cell_value(p, row, col, rgb);
}
double sb_param_apply_gain(const sb_param_t *p, double sum, double gain) {
    if (!p) return sum;
    return (p->desc->caps & SB_CAP_TABLES) || !p->opts.plain ? (sum > 0 ? sum : 0) * gain : sum;
}
int sb_param_warps_default(const sb_param_t *p) {
    if (!p || !(p->desc->caps & SB_CAP_WARPS)) return 1;
    for (int a = 0; a < SB_AXIS_COUNT_; a++)
        if (p->opts.warp[a].kind != p->desc->warp[a]) return 0;
    return 1;
}
const sb_warp_t *sb_param_warp(const sb_param_t *p, int axis) {
    if (!p || !(p->desc->caps & SB_CAP_WARPS) || axis < 0 || axis >= SB_AXIS_COUNT_) return NULL;
    return &p->opts.warp[axis];
}
sb_result_t sb_param_line_by_grid(sb_context_t *ctx, sb_param_t *p, const sb_param_vt_t *vt, const char *name,
                                  const size_t n[3], const char *const axes[3], const char *const keys[3], size_t max,
                                  int wrap_y) {
    for (int i = 0; i < 3; i++)
        if (n[i] < 2 || n[i] > max)
            return sb_error(ctx, SB_ERR_RANGE, "%s: %s cells %zu out of range, need 2..%zu", name, axes[i], n[i], max);
    p->vt = vt;
    p->rows = n[0];
    p->cols = n[1] * n[2];
    p->tex_w[SB_SIDE_G] = n[0];
    p->tex_h[SB_SIDE_G] = 1;
    p->tex_w[SB_SIDE_H] = n[1];
    p->tex_h[SB_SIDE_H] = n[2];
    p->wrap[SB_SIDE_G][0] = p->wrap[SB_SIDE_G][1] = SB_WRAP_CLAMP;
    p->wrap[SB_SIDE_H][0] = SB_WRAP_CLAMP;
    p->wrap[SB_SIDE_H][1] = wrap_y;
    char body[128];
    snprintf(body, sizeof body, "%s:%s=%zu,%s=%zu,%s=%zu", name, keys[0], n[0], keys[1], n[1], keys[2], n[2]);
    sb_param_spec_set(p, body);
    return SB_OK;
}

size_t sb_param_warp_cells(const sb_param_t *p, int axis) {
    if (!p || !(p->desc->caps & SB_CAP_WARPS) || axis < 0 || axis >= SB_AXIS_COUNT_) return 0;
    if (p->desc->warp_cells) return p->desc->warp_cells(p, axis);
    return p->tex_w[axis == SB_AXIS_THETA_H ? SB_SIDE_G : SB_SIDE_H];
}
int sb_param_row_sample(const sb_param_t *p, size_t row, const double u[2], double w[3]) {
    if (!p || !u || !w || row >= p->rows || !p->desc->row_sample) return 0;
    p->desc->row_sample(p, row, u, w);
    return 1;
}
int sb_param_row_cell(const sb_param_t *p, const float *const edge[2], const double wi[3], const double wo[3],
                      size_t cell[2]) {
    if (!p || !edge || !wi || !wo || !cell || !p->desc->row_cell || !p->desc->row_edge) return 0;
    p->desc->row_cell(p, edge, wi, wo, cell);
    return 1;
}
float sb_param_row_edge(const sb_param_t *p, int axis, size_t i) {
    return p && p->desc->row_edge && p->desc->row_cell ? p->desc->row_edge(p, axis, i) : NAN;
}
int sb_param_col_sample(const sb_param_t *p, const double wo[3], const double s[2], double wi[3]) {
    return p && wo && s && wi && p->desc->col_sample ? p->desc->col_sample(p, wo, s, wi) : 0;
}
double sb_param_col_density(const sb_param_t *p, const double wi[3], const double wo[3], double s[2]) {
    return p && wi && wo && s && p->desc->col_density ? p->desc->col_density(p, wi, wo, s) : 0;
}
double sb_param_col_weight(const sb_param_t *p, const double s[2]) {
    if (!p || !s) return 0;
    return p->desc->col_weight ? p->desc->col_weight(p, s) : 1;
}
const char *sb_param_sample_glsl(const sb_param_t *p) { return p && p->desc->sample_glsl ? p->desc->sample_glsl : ""; }

void sb_dirs_from_halfdiff(double theta_h, double phi_h, double theta_d, double phi_d, double wi[3], double wo[3]) {
    if (!wi || !wo) return;
    double d[3], ct = cos(theta_h), st = sin(theta_h), h[3] = {st, 0, ct}, l[3], v[3];
    sb_dir_from_angles(theta_d, phi_d, d);
    l[0] = d[0] * ct + d[2] * st;
    l[1] = d[1];
    l[2] = -d[0] * st + d[2] * ct;
    for (int i = 0; i < 3; i++)
        v[i] = 2 * d[2] * h[i] - l[i];
    if (phi_h == 0) { /* no rotation: the values as computed */
        memcpy(wi, l, sizeof l);
        memcpy(wo, v, sizeof v);
        return;
    }
    double cp = cos(phi_h), sp = sin(phi_h);
    wi[0] = cp * l[0] - sp * l[1], wi[1] = sp * l[0] + cp * l[1], wi[2] = l[2];
    wo[0] = cp * v[0] - sp * v[1], wo[1] = sp * v[0] + cp * v[1], wo[2] = v[2];
}

void sb_dir_from_angles(double theta, double phi, double w[3]) {
    if (!w) return;
    double s = sin(theta);
    w[0] = s * cos(phi);
    w[1] = s * sin(phi);
    w[2] = cos(theta);
}

void sb_dir_to_angles(const double w[3], double *theta, double *phi) {
    if (!w || !theta || !phi) return;
    double z = w[2] > 1 ? 1 : (w[2] < -1 ? -1 : w[2]);
    *theta = acos(z);
    double ph = atan2(w[1], w[0]);
    if (ph < 0) ph += 2 * SB_PI;
    if (ph >= 2 * SB_PI) ph -= 2 * SB_PI;
    *phi = ph;
}

/* Grid cell k = R * i_phi + i_theta; centre theta = W^-1((i_theta + 1/2) / R) tmax,
 * phi = (i_phi + 1/2) 2pi / R. */
void sb_grid_dir(size_t R, double tmax, const sb_warp_t *w, size_t k, double dir[3]) {
    size_t it = k % R, ip = k / R;
    sb_dir_from_angles(sb_warp_theta(w, (double)it + 0.5, R, tmax), (ip + 0.5) * 2 * SB_PI / (double)R, dir);
}

void sb_grid_st(double tmax, const double w[3], double st[2]) {
    double th, ph;
    sb_dir_to_angles(w, &th, &ph);
    st[0] = th / tmax;
    st[1] = ph / (2 * SB_PI);
}

/* Solid angle of a cell: dphi (cos th_lo - cos th_hi). */
double sb_grid_measure(size_t R, double tmax, const sb_warp_t *w, size_t k) {
    double it = (double)(k % R);
    return 2 * SB_PI / (double)R * (cos(sb_warp_theta(w, it, R, tmax)) - cos(sb_warp_theta(w, it + 1, R, tmax)));
}

/* 1 - cos(theta) = 2 sin^2(theta / 2) stays accurate near the pole, where
 * cos(theta) rounds to 1; sin(theta) = sqrt(z (2 - z)) for z = 1 - cos. */
void sb_grid_row_sample(const sb_param_t *p, size_t k, const double u[2], double w[3]) {
    size_t R = p->opts.res;
    double tmax = p->opts.theta_max;
    size_t it = k % R, ip = k / R;
    const sb_warp_t *wt = sb_param_warp(p, SB_AXIS_THETA_H); /* hd's theta_h; none on io */
    double dt = tmax / (double)R, slo = sin(0.5 * (double)it * dt), shi = sin(0.5 * (double)(it + 1) * dt);
    if (wt && wt->kind != SB_WARP_UNIFORM) {
        slo = sin(0.5 * sb_warp_theta(wt, (double)it, R, tmax));
        shi = sin(0.5 * sb_warp_theta(wt, (double)(it + 1), R, tmax));
    }
    double zlo = 2 * slo * slo, zhi = 2 * shi * shi, z = zlo + u[0] * (zhi - zlo);
    double s = sqrt(fmax(z * (2 - z), 0)), phi = ((double)ip + u[1]) * 2 * SB_PI / (double)R;
    w[0] = s * cos(phi);
    w[1] = s * sin(phi);
    w[2] = 1 - z;
}

const char sb_grid_sample_glsl[] =
    "// theta-phi cell (x = theta, y = phi): 1 - cos(theta) and phi linear in u\n"
    "vec3 sb_row_dir(ivec2 cell, vec2 u) {\n"
    "    vec2 n = vec2(textureSize(sb_g, 0).xy);\n"
    "    float dt = SB_THETA_MAX / n.x;\n"
    "    float slo = sin(0.5 * float(cell.x) * dt), shi = sin(0.5 * float(cell.x + 1) * dt);\n"
    "    float z = 2.0 * (slo * slo + u.x * (shi * shi - slo * slo));\n"
    "    float s = sqrt(max(z * (2.0 - z), 0.0)), phi = (float(cell.y) + u.y) * 2.0 * SB_PI / n.y;\n"
    "    return vec3(s * cos(phi), s * sin(phi), 1.0 - z);\n"
    "}\n"
    "// the cell of L by tan^2 theta and cot phi against the edges (src/param/row_cell.c)\n"
    "#define SB_ROW_CELL 1\n"
    "ivec2 sb_row_cell(vec3 L, vec3 V) {\n"
    "    ivec2 n = textureSize(sb_g, 0).xy;\n"
    "    return ivec2(sb_cell_tan2(L, n.x), sb_cell_phi(L.xy, n.y));\n"
    "}\n";

/* Integral of 4 cos(theta) dw over the cell: 4 dphi int cos sin dtheta. */
double sb_grid_measure_4cos(size_t R, double tmax, const sb_warp_t *w, size_t k) {
    double it = (double)(k % R), lo = sin(sb_warp_theta(w, it, R, tmax)), hi = sin(sb_warp_theta(w, it + 1, R, tmax));
    return 2 * (2 * SB_PI / (double)R) * (hi * hi - lo * lo);
}

double sb_dir_theta(const double w[3]) { return atan2(hypot(w[0], w[1]), w[2]); }

/* The whole hemisphere (tmax = pi/2, the default) needs no angle: with
 * w[2] > 0, atan2 returns at most the double nearest pi/2 (a quarter of
 * the default run's estimator went to this atan2 and its hypot). */
int sb_dir_in_cap(double tmax, const double w[3]) { return w[2] > 0 && (tmax >= SB_PI / 2 || sb_dir_theta(w) <= tmax); }

void sb_dir_half(const double l[3], const double v[3], double h[3]) {
    double s[3] = {l[0] + v[0], l[1] + v[1], l[2] + v[2]};
    double n = sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]);
    if (n > 0) {
        for (int i = 0; i < 3; i++)
            h[i] = s[i] / n;
    } else {
        h[0] = h[1] = 0;
        h[2] = 1;
    }
}

void sb_param_spec_set(sb_param_t *p, const char *body) {
    static const char *const keys[SB_AXIS_COUNT_] = {"warp_h", "warp_d"};
    const sb_param_desc_t *d = p->desc;
    size_t n = (size_t)snprintf(p->spec, sizeof p->spec, "%s", body);
    if (p->opts.theta_max != SB_PI / 2)
        n += (size_t)snprintf(p->spec + n, sizeof p->spec - n, ",theta_max=%.6g", p->opts.theta_max * 180 / SB_PI);
    for (int a = 0; a < SB_AXIS_COUNT_ && (d->caps & SB_CAP_WARPS); a++)
        if (p->opts.warp[a].kind != d->warp[a])
            sb_warp_spec_append(&p->opts.warp[a], keys[a], p->spec, sizeof p->spec, &n);
    if (p->opts.plain && !(d->caps & SB_CAP_TABLES)) snprintf(p->spec + n, sizeof p->spec - n, ",plain=1");
}

void sb_param_square_grids(sb_param_t *p, const sb_param_vt_t *vt, const char *name, int wrap_y) {
    size_t R = p->opts.res;
    p->vt = vt;
    p->rows = p->cols = R * R;
    for (int s = 0; s < 2; s++) {
        p->tex_w[s] = p->tex_h[s] = R;
        p->wrap[s][0] = SB_WRAP_CLAMP;
        p->wrap[s][1] = wrap_y;
    }
    char body[64];
    snprintf(body, sizeof body, "%s:res=%zu", name, R);
    sb_param_spec_set(p, body);
}
