/* The comparable metric: resample the reconstruction on a reference io
 * grid and integrate the error of f cos(theta_i) cos(theta_o) over solid
 * angle, so that parameterisations and forms are compared on the same work.
 *
 * Reference direction n = R i_phi + i_theta at theta = (i_theta + 1/2) dt,
 * phi = (i_phi + 1/2) dp (dt = pi/2 / R, dp = 2pi / R); a pair (k, l) has
 * weight w = m_k c_k^2 m_l c_l^2 with m = dp (cos th_lo - cos th_hi).  For
 * each pair the sums for every J' = 1..J are accumulated in one pass:
 *     rec_c = sum_{j <= J'} (g_jc(st_g) / s_i) (h_jc(st_h) / s_o)
 * with s_i, s_o the form's grazing guards (fmax(cos, 0.001), or 1), so the
 * form weight is divided back on each side before the products.
 *
 * Three exact reductions of the R^4 pairs (results change by rounding only):
 * - Isotropic source: its value depends on (i_theta, o_theta, (l_phi -
 *   k_phi) mod R) only, so the R^3 distinct values are evaluated once into a
 *   table (wi at phi dp/2), as matrix.c does for the io matrix.
 * - io and io-area: st_g is a function of wi alone, st_h of wo alone, and the
 *   domain is "both directions in the cap", so the looked-up values of every
 *   term and channel are tabulated per reference direction and side
 *   (N x J C each, guard divided out); a pair costs J C multiply-adds.
 * - iso with an isotropic source: the coordinates are invariant under a
 *   common rotation of wi and wo about z, so a pair depends on (i_theta,
 *   o_theta, d) only and the R^3 classes are evaluated once with weight R.
 *   Two kinds of class are not invariant in floating point and are evaluated
 *   at all R rotations, as the per-pair path would: wo = wi and wo the
 *   mirror of wi (h or d at the pole, where phi_h / phi_d come from
 *   rounding), and rings whose cap test differs between rotations (a ring
 *   centre on theta_max).
 * Anything else (hd, any non-isotropic source with hd or iso) takes the
 * per-pair path: coordinates, bilinear footprints and lookups per pair.
 *
 * Work is split into R fixed units (one phi ring of wi rows, or one theta_i
 * for the iso classes) that threads take in turn; each unit sums in a fixed
 * order into its own slot and the slots are added in unit order, so the
 * result does not depend on the thread count. */
#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "sepbrdf/factor.h"
#include "util/internal.h"
#include "util/parallel.h"
#include "util/tex_axis.h"

#define MAXJ 256

/* What the units share: set up before the first phase, except dir, inside,
 * tab and side, which the first phases fill (each unit its own slice). */
typedef struct work {
    const sb_source_t *src;
    const sb_param_t *p;
    size_t R, N, J, C;
    int clamp;             /* the reconstruction is max(0, sum) (sb_param_apply_gain) */
    unsigned channels;     /* the source's channels measured (1 R, 2 G, 4 B); the others read as 0 */
    const double **tex[2]; /* [side][j * C + c] */
    size_t tw[2], th[2];   /* texture sizes per side */
    int wrap[2][2], edge[2][2];
    double *dir;                   /* N x 3: reference directions */
    double wt[256], guard[2][256]; /* per theta: m c^2; divisor per side */
    unsigned char *inside;         /* N: direction in the domain's cap */
    double *tab;                   /* isotropic source: [((it R + ot) R + d) * 3 + c]; NULL: evaluate */
    unsigned char *tknown;         /* with tab: the value is known and finite */
    double *side[2];               /* io / io-area: N x (J C) looked-up values / guard; NULL: per pair */
    int ring_ok[256];              /* iso classes: inside[] equal over the ring of that theta */
    double *num;                   /* R x (J + 1): per unit, sum w e2(J') for J' = 1..J, then sum w f^2 */
    size_t *neg;                   /* R x (J + 1): per unit, negative pairs per J', then known pairs */
    atomic_size_t next;            /* next unit to take */
    void (*fn)(struct work *, size_t);
} work_t;

/* Values of every term and channel of one side at st (the snippet's
 * lookup, util/tex_axis.h: sb_factors_lookup_brdf up to rounding), divided by div. */
static void lookups(const work_t *w, int side, const double st[2], double div, double *out) {
    size_t at[4];
    double fw[4];
    sb_tex_footprint(st, w->tw[side], w->th[side], w->wrap[side], w->edge[side], at, fw);
    for (size_t i = 0; i < w->J * w->C; i++) {
        const double *t = w->tex[side][i];
        out[i] = (fw[0] * t[at[0]] + fw[1] * t[at[1]] + fw[2] * t[at[2]] + fw[3] * t[at[3]]) / div;
    }
}

/* Add `mult` pairs of source value f and weight wgt (each) to the sums
 * num, neg of a unit (J + 1 each, see work_t); gv, hv: the looked-up values
 * of both sides ([j C + c]), NULL outside the domain (the reconstruction
 * is 0 there). */
static inline void add_pair(double *restrict num, size_t *restrict neg, size_t J, size_t C, int clamp,
                            const double f[3], double wgt, size_t mult, const double *restrict gv,
                            const double *restrict hv) {
    double f2 = f[0] * f[0] + f[1] * f[1] + f[2] * f[2];
    num[J] += wgt * f2;
    neg[J] += mult;
    if (!gv) {
        for (size_t j = 0; j < J; j++)
            num[j] += wgt * f2;
        return;
    }
    double acc[3] = {0, 0, 0};
    for (size_t j = 0; j < J; j++) {
        for (size_t c = 0; c < C; c++)
            acc[c] += gv[j * C + c] * hv[j * C + c];
        double e2 = 0;
        int below = 0;
        for (int c = 0; c < 3; c++) {
            double rec = acc[C == 1 ? 0 : c];
            rec = clamp && rec < 0 ? 0 : rec;
            double d = rec - f[c];
            e2 += d * d;
            below |= rec < 0;
        }
        num[j] += wgt * e2;
        neg[j] += below ? mult : 0;
    }
}

/* Source value of the pair (k, l) with classes it, ot, d; 0 if unknown. */
static int source_at(const work_t *w, size_t k, size_t l, size_t it, size_t ot, size_t d, double f[3]) {
    int known;
    if (w->tab) {
        size_t at = (it * w->R + ot) * w->R + d;
        memcpy(f, w->tab + at * 3, 3 * sizeof *f);
        known = w->tknown[at];
    } else {
        known = sb_source_eval(w->src, w->dir + 3 * k, w->dir + 3 * l, f) && isfinite(f[0] + f[1] + f[2]);
    }
    for (int c = 0; c < 3; c++)
        f[c] = w->channels >> c & 1u ? f[c] : 0;
    return known;
}

/* One pair (k, l) through the parameterisation's coordinates, counted mult times. */
static void add_dirs(const work_t *w, double *num, size_t *neg, size_t k, size_t l, size_t d, size_t mult) {
    size_t R = w->R, it = k % R, ot = l % R;
    double f[3], sg[2], sh[2], gv[MAXJ * 3], hv[MAXJ * 3];
    if (!source_at(w, k, l, it, ot, d, f)) return;
    double wgt = w->wt[it] * w->wt[ot] * (double)mult;
    int in = sb_param_coords(w->p, w->dir + 3 * k, w->dir + 3 * l, sg, sh);
    if (in) {
        lookups(w, SB_SIDE_G, sg, w->guard[0][it], gv);
        lookups(w, SB_SIDE_H, sh, w->guard[1][ot], hv);
    }
    add_pair(num, neg, w->J, w->C, w->clamp, f, wgt, mult, in ? gv : NULL, hv);
}

/* ---- units of work ---------------------------------------------------- */

/* Sums of one unit are kept on its thread's stack (no false sharing) and
 * stored when the unit is done. */
static void store(work_t *w, size_t unit, const double *num, const size_t *neg) {
    memcpy(w->num + unit * (w->J + 1), num, (w->J + 1) * sizeof *num);
    memcpy(w->neg + unit * (w->J + 1), neg, (w->J + 1) * sizeof *neg);
}

/* Source table slice theta_i = it. */
static void unit_table(work_t *w, size_t it) {
    size_t R = w->R;
    for (size_t ot = 0; ot < R; ot++)
        for (size_t d = 0; d < R; d++) {
            size_t at = (it * R + ot) * R + d;
            double *f = w->tab + at * 3;
            int known = sb_source_eval(w->src, w->dir + 3 * it, w->dir + 3 * (d * R + ot), f);
            w->tknown[at] = (unsigned char)(known && isfinite(f[0] + f[1] + f[2]));
        }
}

/* Directions of phi ring ip: cap flags, and for separable
 * parameterisations the looked-up values of both sides. */
static void unit_dirs(work_t *w, size_t ip) {
    size_t R = w->R, JC = w->J * w->C;
    double dt = SB_PI / 2 / (double)R, dp = 2 * SB_PI / (double)R;
    for (size_t it = 0; it < R; it++) {
        size_t n = ip * R + it;
        double *wd = w->dir + 3 * n, st[2][2];
        sb_dir_from_angles((it + 0.5) * dt, (ip + 0.5) * dp, wd);
        /* the domain is both directions in the cap: (w, w) tests w */
        w->inside[n] = (unsigned char)sb_param_coords(w->p, wd, wd, st[0], st[1]);
        if (w->side[0] && w->inside[n])
            for (int s = 0; s < 2; s++)
                lookups(w, s, st[s], w->guard[s][it], w->side[s] + n * JC);
    }
}

/* Pairs with wi on phi ring ip, per pair. */
static void unit_pairs(work_t *w, size_t ip) {
    size_t R = w->R, N = w->N, neg[MAXJ + 1] = {0};
    double num[MAXJ + 1] = {0};
    for (size_t k = ip * R; k < (ip + 1) * R; k++)
        for (size_t l = 0; l < N; l++)
            add_dirs(w, num, neg, k, l, (l / R + R - ip) % R, 1);
    store(w, ip, num, neg);
}

/* Pairs with wi = direction k, separable parameterisation: tabulated sides.
 * Inlined with C constant (1 or 3), so the channel loops unroll. */
static inline void separable_row(const work_t *w, double *num, size_t *neg, size_t k, size_t C) {
    size_t R = w->R, J = w->J, JC = J * C, it = k % R, ip = k / R;
    const double *gv = w->inside[k] ? w->side[0] + k * JC : NULL;
    for (size_t op = 0, l = 0; op < R; op++)
        for (size_t ot = 0; ot < R; ot++, l++) {
            double f[3];
            if (!source_at(w, k, l, it, ot, (op + R - ip) % R, f)) continue;
            add_pair(num, neg, J, C, w->clamp, f, w->wt[it] * w->wt[ot], 1, w->inside[l] ? gv : NULL,
                     w->side[1] + l * JC);
        }
}

static void unit_separable(work_t *w, size_t ip) {
    size_t neg[MAXJ + 1] = {0};
    double num[MAXJ + 1] = {0};
    for (size_t k = ip * w->R; k < (ip + 1) * w->R; k++) {
        if (w->C == 3)
            separable_row(w, num, neg, k, 3);
        else
            separable_row(w, num, neg, k, 1);
    }
    store(w, ip, num, neg);
}

/* iso parameterisation, isotropic source: classes (it, ot, d), wi at
 * phi ring 0, weight R, except the classes that are evaluated at every
 * rotation (see the top of the file). */
static void unit_iso(work_t *w, size_t it) {
    size_t R = w->R, neg[MAXJ + 1] = {0};
    double num[MAXJ + 1] = {0};
    for (size_t ot = 0; ot < R; ot++)
        for (size_t d = 0; d < R; d++) {
            int pole = ot == it && (d == 0 || 2 * d == R);
            if (pole || !w->ring_ok[it] || !w->ring_ok[ot]) {
                for (size_t ip = 0; ip < R; ip++)
                    add_dirs(w, num, neg, ip * R + it, ((ip + d) % R) * R + ot, d, 1);
            } else {
                add_dirs(w, num, neg, it, d * R + ot, d, R);
            }
        }
    store(w, it, num, neg);
}

static void *worker(void *arg) {
    work_t *w = arg;
    for (;;) {
        size_t i = atomic_fetch_add(&w->next, 1);
        if (i >= w->R) break;
        w->fn(w, i);
    }
    return NULL;
}

/* Run fn on units 0..R-1, on nt threads (the caller's included). */
static void run_units(work_t *w, void (*fn)(work_t *, size_t), int nt) {
    w->fn = fn;
    atomic_store(&w->next, 0);
    sb_parallel_run(worker, w, 0, nt, NULL, NULL);
}

static void work_free(work_t *w) {
    free(w->tex[0]);
    free(w->tex[1]);
    free(w->dir);
    free(w->inside);
    free(w->tab);
    free(w->tknown);
    free(w->side[0]);
    free(w->side[1]);
    free(w->num);
    free(w->neg);
}

/* The arguments of sb_metric_compute: textures of the parameterisation's
 * sizes, a known form, a reference resolution in range (into *o). */
static sb_result_t check_args(sb_context_t *ctx, const sb_factors_t *f, const sb_param_t *p, sb_form_t form,
                              const sb_metric_opts_t *opts, sb_metric_opts_t *o) {
    if ((unsigned)form >= SB_FORM_COUNT_) return sb_error(ctx, SB_ERR_ARG, "metric: unknown form %d", (int)form);
    for (int side = SB_SIDE_G; side <= SB_SIDE_H; side++) {
        size_t fw, fh, pw, ph;
        sb_factors_size(f, side, &fw, &fh);
        sb_param_texture_size(p, side, &pw, &ph);
        if (fw != pw || fh != ph)
            return sb_error(ctx, SB_ERR_ARG, "metric: textures of %zu x %zu, the parameterisation has %zu x %zu", fw,
                            fh, pw, ph);
    }
    memset(o, 0, sizeof *o);
    if (opts) *o = *opts;
    if (o->res == 0) o->res = 32;
    if (o->res < 2 || o->res > SB_METRIC_MAX_RES)
        return sb_error(ctx, SB_ERR_RANGE,
                        "metric: reference resolution %zu, need 2..%d (the work grows as its fourth power: %d takes "
                        "seconds)",
                        o->res, SB_METRIC_MAX_RES, SB_METRIC_MAX_RES);
    return SB_OK;
}

/* The buffers of w: the required ones (-1 when out of memory), and the
 * speed-ups' tables, optional: without them (too large), the per-pair path
 * computes the same sums. */
static int work_alloc(sb_context_t *ctx, work_t *w, int iso_src, unsigned caps) {
    size_t J = w->J, C = w->C, R = w->R, N = w->N;
    w->tex[0] = malloc((J * C + 1) * sizeof *w->tex[0]);
    w->tex[1] = malloc((J * C + 1) * sizeof *w->tex[1]);
    w->dir = sb_alloc(ctx, N, 3 * sizeof *w->dir, "metric directions");
    w->inside = sb_alloc(ctx, N, 1, "metric directions");
    w->num = sb_calloc(ctx, R, (J + 1) * sizeof *w->num, "metric sums");
    w->neg = sb_calloc(ctx, R, (J + 1) * sizeof *w->neg, "metric sums");
    if (!w->tex[0] || !w->tex[1] || !w->dir || !w->inside || !w->num || !w->neg) return -1;
    if (iso_src) {
        w->tab = sb_alloc(NULL, N * R, 3 * sizeof *w->tab, "");
        w->tknown = sb_alloc(NULL, N * R, 1, "");
        if (!w->tab || !w->tknown) {
            free(w->tab);
            free(w->tknown);
            w->tab = NULL;
            w->tknown = NULL;
        }
    }
    if (caps & SB_CAP_SEPARABLE) {
        for (int s = 0; s < 2; s++)
            w->side[s] = sb_alloc(NULL, N, J * C * sizeof *w->side[s], "");
        if (!w->side[0] || !w->side[1]) {
            free(w->side[0]);
            free(w->side[1]);
            w->side[0] = w->side[1] = NULL;
        }
    }
    return 0;
}

/* Per side: textures, sizes, wrap; per theta: weight m c^2 and guards. */
static void work_setup(work_t *w, const sb_factors_t *f, const sb_param_t *p, sb_form_t form) {
    size_t R = w->R;
    for (int s = 0; s < 2; s++) {
        sb_factors_size(f, s, &w->tw[s], &w->th[s]);
        sb_param_wrap(p, s, w->wrap[s]);
        sb_param_edge(p, s, w->edge[s]);
        for (size_t j = 0; j < w->J; j++)
            for (size_t c = 0; c < w->C; c++)
                w->tex[s][j * w->C + c] = sb_factors_tex_const(f, s, j, c);
    }
    double dt = SB_PI / 2 / (double)R, dp = 2 * SB_PI / (double)R;
    for (size_t t = 0; t < R; t++) {
        double c = cos((t + 0.5) * dt), g = fmax(c, 0.001);
        w->wt[t] = dp * (cos(t * dt) - cos((t + 1) * dt)) * c * c;
        w->guard[0][t] = form == SB_FORM_COS || form == SB_FORM_COS2 ? g : 1;
        w->guard[1][t] = form == SB_FORM_COS2 ? g : 1;
    }
}

/* The phases: directions, the source table, then the sums by the fastest
 * path the parameterisation and the source allow. */
static void work_run(work_t *w, unsigned caps, int iso_src, int nt) {
    size_t R = w->R;
    run_units(w, unit_dirs, nt);
    if (w->tab) run_units(w, unit_table, nt);
    if (w->side[0]) {
        run_units(w, unit_separable, nt);
    } else if ((caps & SB_CAP_ROTATION_INVARIANT) && iso_src) {
        for (size_t t = 0; t < R; t++) {
            w->ring_ok[t] = 1;
            for (size_t ip = 1; ip < R; ip++)
                w->ring_ok[t] &= w->inside[ip * R + t] == w->inside[t];
        }
        run_units(w, unit_iso, nt);
    } else {
        run_units(w, unit_pairs, nt);
    }
}

/* The units' sums into out: relative L2 error and negative fraction per J. */
static void work_sums(const work_t *w, sb_metric_t *out) {
    size_t J = w->J;
    double num[MAXJ] = {0}, den = 0;
    size_t neg[MAXJ] = {0}, known = 0;
    for (size_t i = 0; i < w->R; i++) {
        const double *un = w->num + i * (J + 1);
        const size_t *ug = w->neg + i * (J + 1);
        for (size_t j = 0; j < J; j++) {
            num[j] += un[j];
            neg[j] += ug[j];
        }
        den += un[J];
        known += ug[J];
    }
    out->terms = J;
    out->pairs = w->N * w->N;
    out->known = known;
    for (size_t j = 0; j < J; j++) {
        out->rel_l2[j] = den > 0 ? sqrt(num[j] / den) : (num[j] > 0 ? INFINITY : 0);
        out->neg_frac[j] = known ? (double)neg[j] / (double)known : 0;
    }
}

/* The fraction of negative texels over every texture of the first J terms. */
double sb_factors_negative_fraction(const sb_factors_t *f, size_t J) {
    if (!f) return NAN;
    if (J > sb_factors_terms(f)) J = sb_factors_terms(f);
    size_t nneg = 0, ntex = 0, C = sb_factors_channels(f);
    for (int side = 0; side < 2; side++) {
        size_t tw, th;
        sb_factors_size(f, side, &tw, &th);
        for (size_t j = 0; j < J; j++)
            for (size_t c = 0; c < C; c++) {
                const double *t = sb_factors_tex_const(f, side, j, c);
                for (size_t i = 0; i < tw * th; i++)
                    nneg += t[i] < 0;
                ntex += tw * th;
            }
    }
    return ntex ? (double)nneg / (double)ntex : 0;
}

sb_result_t sb_metric_compute(sb_context_t *ctx, const sb_source_t *src, const sb_factors_t *f, const sb_param_t *p,
                              sb_form_t form, const sb_metric_opts_t *opts, sb_metric_t *out) {
    if (!src || !f || !p || !out) return sb_error(ctx, SB_ERR_ARG, "metric: missing argument");
    memset(out, 0, sizeof *out);
    sb_metric_opts_t o;
    sb_result_t r = check_args(ctx, f, p, form, opts, &o);
    if (r != SB_OK) return r;
    size_t J = sb_factors_terms(f), C = sb_factors_channels(f), R = o.res, N = R * R;
    if (J > MAXJ) J = MAXJ;
    int iso_src = (sb_source_flags(src) & SB_SOURCE_ISOTROPIC) != 0;
    unsigned caps = sb_param_caps(p);

    work_t w = {.src = src,
                .p = p,
                .R = R,
                .N = N,
                .J = J,
                .C = C,
                .clamp = sb_param_apply_gain(p, -1, 1) == 0,
                .channels = o.channels & 7u ? o.channels & 7u : 7u};
    if (work_alloc(ctx, &w, iso_src, caps) != 0) {
        work_free(&w);
        return sb_error(ctx, SB_ERR_NOMEM, "metric: out of memory");
    }
    work_setup(&w, f, p, form);
    work_run(&w, caps, iso_src, sb_threads_for(o.threads, R, R, 0));
    work_sums(&w, out);
    work_free(&w);
    out->neg_texels = sb_factors_negative_fraction(f, J);
    return SB_OK;
}
