/* sb_warp_measure (param.h), in sample/ because it evaluates a source over
 * a layout's axis as the matrix build does: an adaptive warp table from a scan of the
 * source along one elevation axis.
 *
 * Pairs are built from Rusinkiewicz angles (theta_h, phi_h, theta_d,
 * phi_d): h = dir(theta_h, phi_h), l = Rz(phi_h) Ry(theta_h) dir(theta_d,
 * phi_d), v = 2 (l.h) h - l, with the pair measure dw_l dw_v = 4 cos
 * theta_d sin theta_d sin theta_h dtheta_h dphi_h dtheta_d dphi_d.  hd's
 * axes have the same elevations (its frame differs only in phi), so one
 * scan serves iso and hd.
 *
 * A line is the axis' fine grid x_0 < ... < x_{M-1} (the floor's spacing:
 * MERL's for theta_h, uniform for theta_d) at one setting of the other
 * angles (LINES_T elevations of the other axis, LINES_P phi_d, and
 * LINES_H phi_h for an anisotropic source).  A line holds f (what the
 * textures store for the form f) and cos^2 theta_i at its points; lines
 * are evaluated on threads, each writing its own.  The rounds
 * (equalise_round) then run on the caller's thread. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "param/param_impl.h"
#include "util/internal.h"
#include "util/parallel.h"

#define FINE 512   /* points along the axis */
#define LINES_T 32 /* elevations of the other axis */
#define LINES_P 16 /* phi_d over [0, 2pi) */
#define LINES_H 4  /* phi_h over [0, 2pi), anisotropic sources */
/* A scattered table of fewer samples than this (a Cornell or ALTA
 * gonioreflectometer table) is scanned on half the elevations and half
 * the phi_d: its interpolant has no detail between 512 lines that 128
 * lines miss, and each of its values costs a neighbour search. */
#define FEW_SAMPLES 4096
#define ROUNDS 12 /* equalisation rounds */
#define MIN_GAP 1e-4

typedef struct scan {
    const sb_source_t *src;
    int axis;
    double tmax;
    size_t nt, np, nh;     /* elevations, phi_d and phi_h values of the lines */
    size_t lines;          /* nt np nh */
    const sb_warp_t *base; /* the fine grid's spacing: the floor's warp */
    double x[FINE];        /* fine grid, normalised */
    double e[FINE + 1];    /* fine cells' edges: 0, midpoints, 1 */
    double m[FINE];        /* the axis' share of the measure on each fine cell */
    double *q;             /* lines x FINE x 3: f */
    double *c2;            /* lines x FINE: cos^2 theta_i, the headline's weight */
    unsigned char *ok;     /* lines x FINE: a BRDF pair with known, finite f */
    double *w;             /* lines: the other angles' share of the measure */
} scan_t;

typedef struct scan_job {
    scan_t *s;
    int t, n;
    size_t known;
} scan_job_t;

/* Direction pair of Rusinkiewicz angles; 1 when both are in the cap. */
static int rusink_pair(double tmax, double th, double ph, double td, double pd, double l[3], double v[3]) {
    double d[3], ct = cos(th), st = sin(th), cp = cos(ph), sp = sin(ph);
    sb_dir_from_angles(td, pd, d);
    double x = d[0] * ct + d[2] * st, z = -d[0] * st + d[2] * ct;
    double h[3] = {st * cp, st * sp, ct};
    l[0] = x * cp - d[1] * sp;
    l[1] = x * sp + d[1] * cp;
    l[2] = z;
    for (int i = 0; i < 3; i++)
        v[i] = 2 * d[2] * h[i] - l[i];
    return sb_dir_in_cap(tmax, l) && sb_dir_in_cap(tmax, v);
}

/* One line: q along the axis and the line's weight. */
static size_t scan_line(scan_t *s, size_t line) {
    size_t it = line % s->nt, ip = (line / s->nt) % s->np, ih = line / (s->nt * s->np), known = 0;
    const sb_warp_t other = {s->axis == SB_AXIS_THETA_H ? SB_WARP_UNIFORM : SB_WARP_MERL, 0, {0}};
    double to = sb_warp_theta(&other, (double)it + 0.5, s->nt, s->tmax);
    double lo = sb_warp_theta(&other, (double)it, s->nt, s->tmax);
    double hi = sb_warp_theta(&other, (double)it + 1, s->nt, s->tmax);
    double pd = (ip + 0.5) * 2 * SB_PI / (double)s->np, ph = (ih + 0.5) * 2 * SB_PI / (double)s->nh;
    /* the other elevation's share: int 4 cos sin dtheta_d, or int sin dtheta_h */
    s->w[line] = s->axis == SB_AXIS_THETA_H ? 2 * (sin(hi) * sin(hi) - sin(lo) * sin(lo)) : cos(lo) - cos(hi);
    double *q = s->q + line * FINE * 3, *c2 = s->c2 + line * FINE;
    unsigned char *ok = s->ok + line * FINE;
    /* a batched source (sb_source_create_batched): the line's pairs in one call */
    double *ls = sb_source_batched(s->src) ? malloc(FINE * 9 * sizeof *ls) : NULL;
    double *vs = ls ? ls + 3 * FINE : NULL, *fs = ls ? ls + 6 * FINE : NULL;
    unsigned char kn[FINE];
    size_t n = 0;
    for (size_t i = 0; ls && i < FINE; i++) {
        double th = s->x[i] * s->tmax;
        n += (size_t)(s->axis == SB_AXIS_THETA_H ? rusink_pair(s->tmax, th, ph, to, pd, ls + 3 * n, vs + 3 * n)
                                                 : rusink_pair(s->tmax, to, ph, th, pd, ls + 3 * n, vs + 3 * n));
    }
    if (ls) sb_source_eval_many(s->src, n, ls, vs, fs, kn);
    for (size_t i = 0, m = 0; i < FINE; i++) {
        double th = s->x[i] * s->tmax, l[3], v[3], f[3];
        int in = s->axis == SB_AXIS_THETA_H ? rusink_pair(s->tmax, th, ph, to, pd, l, v)
                                            : rusink_pair(s->tmax, to, ph, th, pd, l, v);
        int got = ls ? in && kn[m] : in && sb_source_eval(s->src, l, v, f);
        if (ls && in) memcpy(f, fs + 3 * m++, sizeof f);
        ok[i] = (unsigned char)(got && isfinite(f[0] + f[1] + f[2]));
        known += ok[i];
        c2[i] = l[2] * l[2];
        for (int c = 0; c < 3; c++)
            q[i * 3 + c] = ok[i] ? f[c] : 0;
    }
    free(ls);
    return known;
}

static void *scan_run(void *arg) {
    scan_job_t *j = arg;
    size_t b, e;
    sb_part(j->s->lines, j->t, j->n, &b, &e);
    for (size_t line = b; line < e; line++)
        j->known += scan_line(j->s, line);
    return NULL;
}

/* Where the reconstruction of fine point i reads: nodes lo[i], hi[i] with
 * weight t[i] on hi (clamped outside the first and last node), and its
 * segment seg[i] (0 below node 0, k between nodes k-1 and k, n above). */
typedef struct taps {
    size_t lo[FINE], hi[FINE], seg[FINE];
    double t[FINE];
} taps_t;

static void taps_of(const scan_t *s, const double *xc, size_t n, taps_t *tp) {
    size_t k = 0;
    for (size_t i = 0; i < FINE; i++) {
        while (k < n && xc[k] <= s->x[i])
            k++;
        tp->seg[i] = k;
        tp->lo[i] = k == 0 ? 0 : k - 1;
        tp->hi[i] = k == n ? n - 1 : k;
        tp->t[i] = tp->lo[i] == tp->hi[i] ? 0 : (s->x[i] - xc[k - 1]) / (xc[k] - xc[k - 1]);
    }
}

/* Where a line is read at node position xc: between the fine points j
 * and j1 with weight t on j1 (the same for every line: found once per
 * round, not per line). */
typedef struct node_at {
    size_t j, j1;
    double t;
} node_at_t;

static node_at_t node_at(const scan_t *s, double xc) {
    size_t j = 0;
    while (j + 1 < FINE && s->x[j + 1] <= xc)
        j++;
    size_t j1 = j + 1 < FINE ? j + 1 : j;
    double t = j1 == j ? 0 : (xc - s->x[j]) / (s->x[j1] - s->x[j]);
    return (node_at_t){j, j1, t < 0 ? 0 : (t > 1 ? 1 : t)};
}

/* Value of a line at node a: linear between the fine points around it
 * (the valid one when only one is); 0 in *valid when neither is. */
static void node_value(const double *q, const unsigned char *ok, node_at_t a, double v[3], int *valid) {
    size_t j = a.j, j1 = a.j1;
    double t = a.t;
    if (!ok[j]) t = 1;
    if (!ok[j1]) t = 0;
    *valid = ok[j] || ok[j1];
    for (int c = 0; c < 3; c++)
        v[c] = (1 - t) * q[j * 3 + c] + t * q[j1 * 3 + c];
}

/* Error of linear interpolation between the nodes xc (n of them) per
 * segment, summed over the lines with their measure, into err[0..n]. */
static void segment_errors(const scan_t *s, const double *xc, size_t n, double *err) {
    taps_t *tp = malloc(sizeof *tp);
    double(*nv)[3] = malloc(n * sizeof *nv);
    int *nok = malloc(n * sizeof *nok);
    node_at_t *at = malloc(n * sizeof *at);
    memset(err, 0, (n + 1) * sizeof *err);
    if (tp && nv && nok && at) {
        taps_of(s, xc, n, tp);
        for (size_t k = 0; k < n; k++)
            at[k] = node_at(s, xc[k]);
        for (size_t l = 0; l < s->lines; l++) {
            const double *q = s->q + l * FINE * 3, *c2 = s->c2 + l * FINE;
            const unsigned char *ok = s->ok + l * FINE;
            for (size_t k = 0; k < n; k++)
                node_value(q, ok, at[k], nv[k], &nok[k]);
            for (size_t i = 0; i < FINE; i++) {
                size_t a = tp->lo[i], b = tp->hi[i];
                if (!ok[i] || (!nok[a] && !nok[b])) continue;
                double t = !nok[a] ? 1 : (!nok[b] ? 0 : tp->t[i]), d2 = 0;
                for (int c = 0; c < 3; c++) {
                    double d = q[i * 3 + c] - ((1 - t) * nv[a][c] + t * nv[b][c]);
                    d2 += d * d;
                }
                err[tp->seg[i]] += s->w[l] * s->m[i] * c2[i] * d2;
            }
        }
    }
    free(tp);
    free(nv);
    free(nok);
    free(at);
}

/* Knots at the quantiles k / K of the masses mass[i] of the fine cells. */
static void knots_from(const scan_t *s, const double *mass, sb_warp_t *out) {
    double cdf[FINE + 1], c = 0;
    cdf[0] = 0;
    for (size_t i = 0; i < FINE; i++)
        cdf[i + 1] = c += mass[i];
    size_t K = out->knots, i = 0;
    out->x[0] = 0;
    out->x[K] = 1;
    for (size_t k = 1; k < K; k++) {
        double target = (double)k / (double)K * c;
        while (i + 1 < FINE && cdf[i + 1] <= target)
            i++;
        double x = mass[i] > 0 ? s->e[i] + (target - cdf[i]) / mass[i] * (s->e[i + 1] - s->e[i]) : s->e[i];
        double lo = out->x[k - 1] + MIN_GAP, hi = 1 - (double)(K - k) * MIN_GAP;
        out->x[k] = x < lo ? lo : (x > hi ? hi : x);
    }
    sb_warp_round(out);
}

/* One round: the nodes of warp w at n texels (w becomes a table of
 * `knots` segments), their segments' errors E_k,
 * and the new texel density: segment k (u-span 1/n, 1/2n at the ends)
 * gets the mass E_k^(1/5) (equal errors when each E_k ~ Delta_k^5), spread
 * over its fine cells by length, mixed with `floor_` of the base density. */
static void equalise_round(const scan_t *s, size_t n, size_t knots, double floor_, sb_warp_t *w) {
    double *xc = malloc(n * sizeof *xc), *err = malloc((n + 1) * sizeof *err), *len = calloc(n + 1, sizeof *len);
    double mass[FINE], total = 0;
    if (!xc || !err || !len) goto out;
    for (size_t i = 0; i < n; i++)
        xc[i] = sb_warp_inverse(w, (i + 0.5) / (double)n);
    segment_errors(s, xc, n, err);
    taps_t *tp = malloc(sizeof *tp);
    if (!tp) goto out;
    taps_of(s, xc, n, tp);
    for (size_t i = 0; i < FINE; i++)
        len[tp->seg[i]] += s->e[i + 1] - s->e[i];
    for (size_t k = 0; k <= n; k++)
        total += pow(err[k], 0.2) * (k == 0 || k == n ? 0.5 : 1);
    for (size_t i = 0; i < FINE; i++) {
        size_t k = tp->seg[i];
        double dx = s->e[i + 1] - s->e[i], span = k == 0 || k == n ? 0.5 : 1;
        double adaptive = total > 0 && len[k] > 0 ? pow(err[k], 0.2) * span / total * dx / len[k] : 0;
        double base = sb_warp_map(s->base, s->e[i + 1]) - sb_warp_map(s->base, s->e[i]);
        mass[i] = total > 0 ? (1 - floor_) * adaptive + floor_ * base : base;
    }
    free(tp);
    /* damped: the new knots half way from the old map's (at the same s) */
    sb_warp_t next = {SB_WARP_TABLE, knots, {0}};
    knots_from(s, mass, &next);
    for (size_t k = 1; k < knots; k++)
        next.x[k] = 0.5 * (next.x[k] + sb_warp_inverse(w, (double)k / (double)knots));
    sb_warp_round(&next);
    *w = next;
out:
    free(xc);
    free(err);
    free(len);
}

sb_result_t sb_warp_measure(sb_context_t *ctx, const sb_source_t *src, int axis, const sb_warp_measure_opts_t *opts,
                            sb_warp_t *out) {
    if (!src || !out) return sb_error(ctx, SB_ERR_ARG, "warp measure: no source or output");
    sb_warp_measure_opts_t o = {0};
    if (opts) o = *opts;
    if (!o.knots) o.knots = SB_WARP_MAX_KNOTS;
    if (!o.cells) o.cells = 32;
    if (!(o.theta_max > 0)) o.theta_max = SB_PI / 2;
    if (o.floor == 0) o.floor = 0.15;
    if (axis != SB_AXIS_THETA_H && axis != SB_AXIS_THETA_D)
        return sb_error(ctx, SB_ERR_RANGE, "warp measure: unknown axis %d", axis);
    if (o.knots < 2 || o.knots > SB_WARP_MAX_KNOTS || o.cells < 2 || o.cells > 8192 || !(o.floor > 0 && o.floor < 1) ||
        o.theta_max > SB_PI / 2 + 1e-12)
        return sb_error(ctx, SB_ERR_RANGE,
                        "warp measure: %zu knots (need 2..%d), %zu cells (need 2..8192), floor %g (need (0, 1)), "
                        "theta_max %g",
                        o.knots, SB_WARP_MAX_KNOTS, o.cells, o.floor, o.theta_max);
    const sb_warp_t base = {axis == SB_AXIS_THETA_H ? SB_WARP_MERL : SB_WARP_UNIFORM, 0, {0}};
    scan_t *s = calloc(1, sizeof *s);
    if (!s) return sb_error(ctx, SB_ERR_NOMEM, "warp measure: out of memory");
    *s = (scan_t){.src = src, .axis = axis, .tmax = o.theta_max, .base = &base};
    size_t ns = sb_source_sample_count(src);
    int few = ns > 0 && ns < FEW_SAMPLES && !(sb_source_flags(src) & SB_SOURCE_TABLES);
    s->nt = few ? LINES_T / 2 : LINES_T;
    s->np = few ? LINES_P / 2 : LINES_P;
    s->nh = (sb_source_flags(src) & SB_SOURCE_ISOTROPIC) ? 1 : LINES_H;
    s->lines = s->nt * s->np * s->nh;
    int nt = sb_threads_for(o.threads, s->lines, s->lines * FINE, 4096);
    scan_job_t *jobs = sb_calloc(ctx, (size_t)nt, sizeof *jobs, "warp scan");
    s->q = sb_alloc(ctx, s->lines * FINE, 3 * sizeof *s->q, "warp scan");
    s->ok = sb_alloc(ctx, s->lines, FINE, "warp scan");
    s->c2 = sb_alloc(ctx, s->lines * FINE, sizeof *s->c2, "warp scan");
    s->w = sb_alloc(ctx, s->lines, sizeof *s->w, "warp scan");
    size_t known = 0;
    int have = jobs && s->q && s->c2 && s->ok && s->w;
    if (have) {
        for (size_t i = 0; i < FINE; i++)
            s->x[i] = sb_warp_inverse(&base, (i + 0.5) / FINE);
        s->e[0] = 0;
        s->e[FINE] = 1;
        for (size_t i = 1; i < FINE; i++)
            s->e[i] = 0.5 * (s->x[i - 1] + s->x[i]);
        for (size_t i = 0; i < FINE; i++) {
            double th = s->x[i] * s->tmax, dx = s->e[i + 1] - s->e[i];
            s->m[i] = (axis == SB_AXIS_THETA_H ? sin(th) : 4 * cos(th) * sin(th)) * dx;
        }
        for (int t = 0; t < nt; t++)
            jobs[t] = (scan_job_t){.s = s, .t = t, .n = nt};
        sb_parallel_run(scan_run, jobs, sizeof *jobs, nt, NULL, NULL);
        for (int t = 0; t < nt; t++)
            known += jobs[t].known;
        *out = base;
        for (int r = 0; r < ROUNDS && known; r++)
            equalise_round(s, o.cells, o.knots, o.floor, out);
    }
    sb_result_t r = !have ? sb_error(ctx, SB_ERR_NOMEM, "warp measure: out of memory")
                    : !known
                        ? sb_error(ctx, SB_ERR_NUMERIC, "warp measure: the source is unknown wherever it was scanned")
                        : sb_warp_check(ctx, out);
    free(jobs);
    free(s->q);
    free(s->c2);
    free(s->ok);
    free(s->w);
    free(s);
    return r;
}
