/* Warps of the elevation axes (param.h): names, the maps, the spec's
 * values and the GLSL that computes the same map.
 *
 * A table's forward map finds the segment by a binary search over the
 * knots, lo = 0, hi = K; while hi - lo > 1: mid = (lo + hi) / 2, lo = mid
 * if x >= x_mid else hi = mid; then s = (lo + clamp((x - x_lo) / (x_hi -
 * x_lo), 0, 1)) / K.  The GLSL runs the same search with a fixed number of
 * steps (ceil(log2 K), the extra ones doing nothing), so C and the shader
 * pick the same segment for every x that is not within rounding of a
 * knot, where W is continuous anyway. */
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "param/param_impl.h"
#include "util/shared.h"

static const char *const warp_names[SB_WARP_KIND_COUNT_] = {"default", "uniform", "merl", "table"};

const char *sb_warp_kind_name(sb_warp_kind_t kind) {
    return (unsigned)kind < SB_WARP_KIND_COUNT_ ? warp_names[kind] : "?";
}

sb_result_t sb_warp_kind_parse(const char *name, sb_warp_kind_t *out) {
    if (!out) return SB_ERR_ARG;
    int k = sb_name_find(warp_names, SB_WARP_KIND_COUNT_, name);
    if (k < 0) return SB_ERR_UNKNOWN;
    *out = (sb_warp_kind_t)k;
    return SB_OK;
}

/* Segment lo of x (binary search above). */
static size_t table_segment(const sb_warp_t *w, double x) {
    size_t lo = 0, hi = w->knots;
    while (hi - lo > 1) {
        size_t mid = (lo + hi) / 2;
        if (x >= w->x[mid])
            lo = mid;
        else
            hi = mid;
    }
    return lo;
}

double sb_warp_map(const sb_warp_t *w, double x) {
    if (!w) return NAN;
    switch (w->kind) {
    case SB_WARP_MERL:
        return sqrt(x);
    case SB_WARP_TABLE: {
        size_t k = table_segment(w, x);
        double t = (x - w->x[k]) / (w->x[k + 1] - w->x[k]);
        t = t < 0 ? 0 : (t > 1 ? 1 : t);
        return ((double)k + t) / (double)w->knots;
    }
    default:
        return x;
    }
}

double sb_warp_inverse(const sb_warp_t *w, double s) {
    if (!w) return NAN;
    switch (w->kind) {
    case SB_WARP_MERL:
        return s * s;
    case SB_WARP_TABLE: {
        double u = (s < 0 ? 0 : (s > 1 ? 1 : s)) * (double)w->knots;
        size_t k = (size_t)u;
        if (k >= w->knots) k = w->knots - 1;
        return w->x[k] + (u - (double)k) * (w->x[k + 1] - w->x[k]);
    }
    default:
        return s;
    }
}

double sb_warp_theta(const sb_warp_t *w, double i, size_t n, double tmax) {
    if (!w || w->kind == SB_WARP_UNIFORM || w->kind == SB_WARP_DEFAULT) return i * tmax / (double)n;
    if (w->kind == SB_WARP_MERL) {
        double u = i / (double)n;
        return u * u * tmax;
    }
    return sb_warp_inverse(w, i / (double)n) * tmax;
}

sb_result_t sb_warp_check(sb_context_t *ctx, const sb_warp_t *w) {
    if (!w) return sb_error(ctx, SB_ERR_ARG, "warp: none given");
    if ((unsigned)w->kind >= SB_WARP_KIND_COUNT_) return sb_error(ctx, SB_ERR_RANGE, "warp: unknown kind %d", w->kind);
    if (w->kind != SB_WARP_TABLE) return SB_OK;
    if (w->knots < 2 || w->knots > SB_WARP_MAX_KNOTS)
        return sb_error(ctx, SB_ERR_RANGE, "warp table: %zu segments, need 2..%d", w->knots, SB_WARP_MAX_KNOTS);
    if (w->x[0] != 0 || w->x[w->knots] != 1)
        return sb_error(ctx, SB_ERR_RANGE, "warp table: knots run from %g to %g, need 0 to 1", w->x[0], w->x[w->knots]);
    for (size_t k = 0; k < w->knots; k++)
        if (!(w->x[k + 1] > w->x[k]))
            return sb_error(ctx, SB_ERR_RANGE, "warp table: knot %zu (%g) not above knot %zu (%g)", k + 1, w->x[k + 1],
                            k, w->x[k]);
    return SB_OK;
}

void sb_warp_round(sb_warp_t *w) {
    if (w->kind != SB_WARP_TABLE) return;
    for (size_t k = 1; k < w->knots && k < SB_WARP_MAX_KNOTS; k++) {
        char b[32];
        snprintf(b, sizeof b, "%.6g", w->x[k]);
        w->x[k] = strtod(b, NULL);
    }
}

/* printf into buf at *n, bounded by size; *n counts every byte asked for. */
__attribute__((format(printf, 4, 5))) static void append(char *buf, size_t size, size_t *n, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    int m = vsnprintf(*n < size ? buf + *n : NULL, *n < size ? size - *n : 0, fmt, ap);
    va_end(ap);
    if (m > 0) *n += (size_t)m;
}

void sb_warp_spec_append(const sb_warp_t *w, const char *name, char *buf, size_t size, size_t *n) {
    append(buf, size, n, ",%s=", name);
    if (w->kind != SB_WARP_TABLE) {
        append(buf, size, n, "%s", sb_warp_kind_name(w->kind));
        return;
    }
    for (size_t k = 1; k < w->knots; k++)
        append(buf, size, n, "%s%.6g", k > 1 ? "/" : "", w->x[k]);
}

sb_result_t sb_warp_parse_value(sb_context_t *ctx, const char *value, sb_warp_t *out) {
    memset(out, 0, sizeof *out);
    sb_warp_kind_t k;
    if (sb_warp_kind_parse(value, &k) == SB_OK && (k == SB_WARP_UNIFORM || k == SB_WARP_MERL)) {
        out->kind = k;
        return SB_OK;
    }
    out->kind = SB_WARP_TABLE;
    size_t K = 1;
    for (const char *v = value; *v;) {
        char *end;
        errno = 0;
        double x = strtod(v, &end);
        if (end == v || (*end && *end != '/') || errno == ERANGE || !isfinite(x))
            return sb_error(ctx, SB_ERR_PARSE, "warp '%s': need uniform, merl or knots x1/x2/... in (0, 1)", value);
        if (K >= SB_WARP_MAX_KNOTS)
            return sb_error(ctx, SB_ERR_RANGE, "warp '%s': more than %d knots", value, SB_WARP_MAX_KNOTS - 1);
        out->x[K++] = x;
        v = *end ? end + 1 : end;
    }
    out->knots = K;
    out->x[K] = 1;
    return sb_warp_check(ctx, out);
}

/* A GLSL float literal (GLSL ES converts no int to float). */
static void glsl_float(char *buf, size_t size, size_t *n, double v) {
    char s[40];
    snprintf(s, sizeof s, "%.9g", v);
    append(buf, size, n, "%s%s", s, strpbrk(s, ".eEn") ? "" : ".0");
}

size_t sb_warp_glsl(const sb_warp_t *w, const char *name, char *buf, size_t size, size_t *n) {
    size_t n0 = *n;
    if (w->kind != SB_WARP_TABLE) {
        int merl = w->kind == SB_WARP_MERL;
        append(buf, size, n, "float %s(float x) { return %s; }\n", name, merl ? "sqrt(x)" : "x");
        append(buf, size, n, "float %s_inv(float s) { return %s; }\n", name, merl ? "s * s" : "s");
        append(buf, size, n, "float %s_dinv(float s) { return %s; }\n", name, merl ? "2.0 * s" : "1.0");
        return *n - n0;
    }
    int steps = 0;
    while (((size_t)1 << steps) < w->knots)
        steps++;
    append(buf, size, n, "const float %s_x[%zu] = float[%zu](", name, w->knots + 1, w->knots + 1);
    for (size_t k = 0; k <= w->knots; k++) {
        if (k) append(buf, size, n, ", ");
        glsl_float(buf, size, n, w->x[k]);
    }
    append(buf, size, n,
           ");\n"
           "float %s(float x) {\n"
           "    int lo = 0, hi = %zu;\n"
           "    for (int i = 0; i < %d; i++) {\n"
           "        int mid = (lo + hi) / 2;\n"
           "        if (hi - lo > 1) {\n"
           "            if (x >= %s_x[mid]) lo = mid; else hi = mid;\n"
           "        }\n"
           "    }\n"
           "    float t = clamp((x - %s_x[lo]) / (%s_x[hi] - %s_x[lo]), 0.0, 1.0);\n"
           "    return (float(lo) + t) / %zu.0;\n"
           "}\n"
           "float %s_inv(float s) {\n" /* sb_warp_inverse */
           "    float u = clamp(s, 0.0, 1.0) * %zu.0;\n"
           "    int k = min(int(u), %zu);\n"
           "    return %s_x[k] + (u - float(k)) * (%s_x[k + 1] - %s_x[k]);\n"
           "}\n"
           "float %s_dinv(float s) {\n" /* the slope of NAME_inv */
           "    int k = min(int(clamp(s, 0.0, 1.0) * %zu.0), %zu);\n"
           "    return %zu.0 * (%s_x[k + 1] - %s_x[k]);\n"
           "}\n",
           name, w->knots, steps, name, name, name, name, w->knots, name, w->knots, w->knots - 1, name, name, name,
           name, w->knots, w->knots - 1, w->knots, name, name);
    return *n - n0;
}
