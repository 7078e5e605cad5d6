/* The lobe a scattered table is interpolated relative to (sb_lobe_mode_t).
 *
 * Model: f_c(l, v) = kd_c + ks_c S(l, v), one shape for all channels:
 *   S = min(D(h), d_cap) F(v.h) / (4 ((n.l (1 - k) + k)(n.v (1 - k) + k))^p)
 * with p = 1 the microfacet model D G F / (4 n.l n.v), the Smith-Schlick G
 * cancelling the cosines (finite up to the horizon), k = alpha / 2 or the
 * remapped (sqrt(alpha) + 1)^2 / 8; p = 1/2 or 0 for peaks that grow less
 * towards the horizon (a near-mirror coat measured through an aperture).
 * D is GGX (alpha) or exp(-(tan theta_h / alpha)^q) / (pi alpha^2 cos^4),
 * q = 2 (Beckmann), 4 or 8 (flat-topped); F is Schlick's with one F0 for
 * all channels (0.04, 0.25 or 1), or one per channel (fitted with kd and ks:
 * scattered_lobe_solve.c), for a coloured metal whose highlight whitens
 * towards grazing.  The diffuse term is kd, or kd (1 - (1 - v.h)^5) (fd:
 * the light Schlick's F reflects does not reach the diffuse layer; the
 * microfacet model's (1 - F) base / pi, which a constant kd misses by 4 %
 * at a glossy table's grazing mirror rows).
 * The shape's parameters are searched on grids (alpha log-spaced, then
 * refined by golden section); for each shape kd and ks of every channel
 * are the non-negative least-squares solution in the norm of f cos theta_i
 * (the headline's), a 2 x 2 problem closed in form from five sums.
 * Tables of more than FIT_MAX samples search on FIT_MAX evenly spread ones.
 * d_cap is CAP times the shape's largest D at a sample (the cap applies
 * to the base, not to the search).
 *
 * The interpolation then sees q = f / (lobe + floor), floor the channel's
 * median sample value (so q stays of order one away from the highlight
 * whatever the diffuse fit), and the source returns q times that base: the
 * base carries the highlight's shape, q what the lobe gets wrong, and it is
 * q, smooth and of order one, that is spread between samples. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "source/scattered_impl.h"
#include "util/internal.h"

#define FIT_MAX 4000
#define ALPHA_MIN 1e-3
#define ALPHA_MAX 1.0
#define ALPHA_STEPS 40
#define GOLDEN_STEPS 24
#define NDFS 4
/* denominators: cosine powers 0, 1/2, 1, each with Smith k = alpha/2 or
 * the remapped (sqrt(alpha) + 1)^2 / 8 */
#define COSP 6
/* A shape's D never exceeds this many times its largest at a sample: a
 * lobe narrower than the samples resolve would otherwise claim any height
 * between them. */
#define CAP 16.0
/* Shapes within this much of the best cost (log_cost: squared ln
 * errors summed over samples) fit about as well: one sample off by a
 * factor e costs 1. */
#define ALT_MARGIN 1.0
/* ... and within this fraction of it: where the best shape fits the
 * samples closely (a clean table of a microfacet material: GGX alpha 0.3
 * sampled at 1536 positions, best 0.45, the next shapes 0.53 and 0.60)
 * the others are worse shapes, not equal ones, and the lowest of them put
 * the held-out mirror rows 10-20 % low; a measured coat's shapes part by
 * under 1 % of a large cost (Cornell acrylic: 72.8, 73.3, 73.6). */
#define ALT_REL 0.05

static const double f0_grid[] = {0.04, 0.25, 1.0};
#define NF0 3 /* f0_grid's entries; family index NF0: F0 per channel */
/* The per-channel F0 is kept over the best grey one only when it lowers
 * log_cost by this fraction and by PC_MIN (three more weights fit any
 * table a little better, and two exact fits part by rounding; gold's grey
 * shapes cost 4.4, its per-channel one 0.006). */
#define PC_GAIN 0.25
#define PC_MIN 0.1
static const char *const ndf_names[NDFS] = {"ggx", "beckmann", "exp4", "exp8"};

/* What the shape needs of a pair (l, v), apart from its parameters:
 * cos^2 and sin^2 of theta_h, m = 1 - v.h clamped, and the cosines; ok 0
 * where the shape is 0 (below the horizon, or l = -v). */
typedef struct geo {
    double c2, s2, m, l2, v2;
    int ok;
} geo_t;

static geo_t lobe_geo(const double l[3], const double v[3]) {
    geo_t g = {0, 0, 0, l[2], v[2], 0};
    double h[3] = {l[0] + v[0], l[1] + v[1], l[2] + v[2]};
    double n = sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
    if (!(n > 0) || !(l[2] > 0) || !(v[2] > 0)) return g;
    double c = h[2] / n, vh = (v[0] * h[0] + v[1] * h[1] + v[2] * h[2]) / n;
    g.c2 = c * c;
    g.s2 = 1 - g.c2;
    g.m = 1 - fmin(fmax(vh, 0), 1);
    g.ok = 1;
    return g;
}

/* D of distribution ndf at width alpha. */
static double ndf_at(const geo_t *gm, int ndf, double alpha) {
    double c2 = gm->c2, s2 = gm->s2, a2 = alpha * alpha, d;
    if (ndf == 0) {
        double b = s2 + c2 * a2;
        d = a2 / (SB_PI * b * b);
    } else { /* exp(-(tan^2 / alpha^2)^(p/2)), p = 2 (Beckmann), 4, 8 */
        double x = c2 > 0 ? (s2 / c2) / a2 : INFINITY;
        x = ndf == 1 ? x : ndf == 2 ? x * x : x * x * x * x;
        /* exp(-x) is 0 beyond 745.2: not asked (libm's underflow path was
         * a tenth of `info` on a Cornell table) */
        d = c2 > 0 && x < 746 ? exp(-x) / (SB_PI * a2 * c2 * c2) : 0;
    }
    return d;
}

/* The shape with its D at most dcap (INFINITY: uncapped). */
static double shape_capped(const geo_t *gm, int ndf, double alpha, double f0, int cosp, double dcap) {
    if (!gm->ok) return 0;
    double m = gm->m, fr = f0 + (1 - f0) * m * m * m * m * m, r = sqrt(alpha) + 1;
    double k = cosp >= 3 ? r * r / 8 : alpha / 2;
    cosp %= 3;
    double g = (gm->l2 * (1 - k) + k) * (gm->v2 * (1 - k) + k);
    return fmin(ndf_at(gm, ndf, alpha), dcap) * fr / (4 * (cosp == 2 ? g : cosp == 1 ? sqrt(g) : 1));
}

static double shape_at(const geo_t *gm, int ndf, double alpha, double f0, int cosp) {
    return shape_capped(gm, ndf, alpha, f0, cosp, INFINITY);
}

/* The diffuse term's factor: 1, or 1 - (1 - v.h)^5 (fd). */
static double diffuse_at(const geo_t *gm, int fd) {
    double m = gm->m;
    return fd ? 1 - m * m * m * m * m : 1.0;
}

/* Add a sample of weight w, diffuse factor B, shape values S and T and
 * values f to m's sums of S and T (those of w and f alone are the
 * caller's). */
static void sums_add(lobe_sums_t *m, double w, double B, double S, double T, const double f[3]) {
    m->ws += w * B * S;
    m->wss += w * S * S;
    m->wt += w * B * T;
    m->wst += w * S * T;
    m->wtt += w * T * T;
    for (int c = 0; c < 3; c++) {
        m->wsf[c] += w * S * f[c];
        m->wtf[c] += w * T * f[c];
    }
}

/* Residual of the best linear weights of shape s (its ndf, alpha, cosp,
 * fd and f0, or pc) over the samples 0, step, 2 step, ... (geo[i] the
 * geometry of sample i * step); its kd, ks and f0c into s. */
static double shape_cost(const double *smp, size_t ns, size_t step, const geo_t *geo, lobe_alt_t *s) {
    lobe_sums_t m;
    memset(&m, 0, sizeof m);
    for (size_t i = 0, j = 0; i < ns; i += step, j++) {
        const double *x = smp + i * SB_SAMPLE_DOUBLES;
        double S = shape_at(&geo[j], s->ndf, s->alpha, s->pc ? 1.0 : s->f0, s->cosp), w = x[2] * x[2];
        double T = s->pc ? shape_at(&geo[j], s->ndf, s->alpha, 0.0, s->cosp) : 0; /* S (1 - v.h)^5 */
        double B = diffuse_at(&geo[j], s->fd);
        m.w += w * B * B;
        sums_add(&m, w, B, S, T, x + 6);
        for (int c = 0; c < 3; c++) {
            m.wf[c] += w * B * x[6 + c];
            m.wff[c] += w * x[6 + c] * x[6 + c];
        }
    }
    double r = 0;
    for (int c = 0; c < 3; c++) {
        s->f0c[c] = s->f0;
        r += s->pc ? sb_lobe_solve3_(&m, c, &s->kd[c], &s->ks[c], &s->f0c[c])
                   : sb_lobe_solve2_(&m, c, &s->kd[c], &s->ks[c]);
    }
    return r;
}

/* How far the base kd B + ks S + floor is from the samples, as a factor:
 * the sum over samples and channels of ln^2((f+ + floor) / base), kd and
 * ks the least-squares weights of the shape.  The interpolation spreads
 * q = f / base between the samples, so the shape to keep is the one that
 * leaves q nearest one everywhere, the highlight's tail as much as its
 * peak (the squares of f cos theta_i alone see the peak only: a family
 * whose tail overshoots the first samples beside a narrow peak by 10x
 * cost less there than one that misses the peak's shoulder by 20 %). */
static double log_cost(const double *smp, size_t ns, size_t step, const geo_t *geo, lobe_alt_t s,
                       const double floor_[3]) {
    double r = 0;
    shape_cost(smp, ns, step, geo, &s);
    const double *kd = s.kd, *ks = s.ks;
    for (size_t i = 0, j = 0; i < ns; i += step, j++) {
        const double *x = smp + i * SB_SAMPLE_DOUBLES;
        double S = shape_at(&geo[j], s.ndf, s.alpha, s.f0c[0], s.cosp), B = diffuse_at(&geo[j], s.fd);
        for (int c = 0; c < 3; c++) {
            if (s.pc && c > 0) S = shape_at(&geo[j], s.ndf, s.alpha, s.f0c[c], s.cosp);
            double l = log((fmax(x[6 + c], 0) + floor_[c]) / (kd[c] * B + ks[c] * S + floor_[c]));
            r += l * l;
        }
    }
    return r;
}

/* The search's samples (0, step, 2 step, ...), laid out for passes over
 * one shape at a time: the parts of the geometry at those where the shape
 * is not 0 (ok), their weights and values, and the sums no shape changes.
 * A shape's residual from them is shape_cost's to the bit: the same
 * operations in the same order, where the samples left out (shape 0) add
 * exactly 0.  The grid of alpha shares D across the families (F0, cosine
 * power) and the denominators across the distributions. */
typedef struct fitset {
    size_t n;                                 /* samples where the shape is not 0 */
    double *c2, *s2, *t2, *l2, *v2, *fr[NF0]; /* t2: s2 / c2 (INFINITY at c2 = 0); fr: Schlick's F per f0_grid */
    double *m5, *b1;                          /* (1 - v.h)^5 (the per-channel F0's second term), 1 - m5 */
    double *w, *f, *D, *den[COSP];            /* f: 3 per sample; D and den: one shape's (scratch) */
    lobe_sums_t base[2];                      /* w, wf and wff over all the samples, diffuse 1 and b1 */
} fitset_t;

/* fs for the samples 0, step, ... (geometry geo); 0 on no memory. */
static int fitset_init(fitset_t *fs, const double *smp, size_t ns, size_t step, const geo_t *geo) {
    memset(fs, 0, sizeof *fs);
    size_t m = (ns + step - 1) / step, nf = sizeof f0_grid / sizeof *f0_grid;
    double *p = malloc(m * (9 + nf + COSP + 3) * sizeof *p); /* the columns below, f's 3 last */
    if (!p) return 0;
    double **col[] = {&fs->c2, &fs->s2, &fs->t2, &fs->l2, &fs->v2, &fs->w, &fs->D, &fs->m5, &fs->b1};
    for (size_t a = 0; a < sizeof col / sizeof *col; a++, p += m)
        *col[a] = p;
    for (size_t a = 0; a < nf; a++, p += m)
        fs->fr[a] = p;
    for (int a = 0; a < COSP; a++, p += m)
        fs->den[a] = p;
    fs->f = p;
    for (size_t i = 0, j = 0; i < ns; i += step, j++) {
        const double *s = smp + i * SB_SAMPLE_DOUBLES;
        const geo_t *g = &geo[j];
        double w = s[2] * s[2], m = g->m;
        for (int fd = 0; fd < 2; fd++) {
            double B = diffuse_at(g, fd);
            fs->base[fd].w += w * B * B;
            for (int c = 0; c < 3; c++) {
                fs->base[fd].wf[c] += w * B * s[6 + c];
                fs->base[fd].wff[c] += w * s[6 + c] * s[6 + c];
            }
        }
        if (!g->ok) continue;
        size_t k = fs->n++;
        fs->c2[k] = g->c2, fs->s2[k] = g->s2, fs->l2[k] = g->l2, fs->v2[k] = g->v2, fs->w[k] = w;
        fs->t2[k] = g->c2 > 0 ? g->s2 / g->c2 : INFINITY;
        for (size_t a = 0; a < nf; a++)
            fs->fr[a][k] = f0_grid[a] + (1 - f0_grid[a]) * m * m * m * m * m;
        fs->m5[k] = m * m * m * m * m;
        fs->b1[k] = diffuse_at(g, 1);
        for (int c = 0; c < 3; c++)
            fs->f[3 * k + (size_t)c] = s[6 + c];
    }
    return 1;
}

/* D of distribution ndf at width alpha into D (shape_at's D). */
static void fitset_d(const fitset_t *fs, int ndf, double alpha, double *D) {
    double a2 = alpha * alpha;
    if (ndf == 0) {
        for (size_t j = 0; j < fs->n; j++) {
            double b = fs->s2[j] + fs->c2[j] * a2;
            D[j] = a2 / (SB_PI * b * b);
        }
        return;
    }
    for (size_t j = 0; j < fs->n; j++) {
        double x = fs->t2[j] / a2;
        x = ndf == 1 ? x : ndf == 2 ? x * x : x * x * x * x;
        D[j] = x < 746 ? exp(-x) / (SB_PI * a2 * fs->c2[j] * fs->c2[j]) : 0; /* t2 = INFINITY at c2 = 0 */
    }
}

/* 4 times the denominator of cosine power cosp at width alpha into den
 * (where D is not 0 when D is given). */
static void fitset_den(const fitset_t *fs, int cosp, double alpha, const double *D, double *den) {
    double r = sqrt(alpha) + 1, k = cosp >= 3 ? r * r / 8 : alpha / 2;
    int p = cosp % 3;
    for (size_t j = 0; j < fs->n; j++) {
        if (D && D[j] == 0) continue;
        double g = (fs->l2[j] * (1 - k) + k) * (fs->v2[j] * (1 - k) + k);
        den[j] = 4 * (p == 2 ? g : p == 1 ? sqrt(g) : 1);
    }
}

/* shape_cost's residual of the per-channel F0 family: S = D / den, T =
 * D m^5 / den. */
static double fitset_cost_pc(const fitset_t *fs, const double *D, const double *den, int fd) {
    lobe_sums_t m = fs->base[fd];
    for (size_t j = 0; j < fs->n; j++) {
        if (D[j] == 0) continue;
        double B = fd ? fs->b1[j] : 1.0;
        sums_add(&m, fs->w[j], B, D[j] * 1.0 / den[j], D[j] * fs->m5[j] / den[j], fs->f + 3 * j);
    }
    double r = 0, a, b, e;
    for (int c = 0; c < 3; c++)
        r += sb_lobe_solve3_(&m, c, &a, &b, &e);
    return r;
}

/* shape_cost's residual of the shape D fr / den (fr NULL: F0 per
 * channel), diffuse factor 1 or b1 (fd).  Where D is 0 (an exp family's
 * far tail) the sample adds exactly 0: skipped. */
static double fitset_cost(const fitset_t *fs, const double *D, const double *fr, const double *den, int fd) {
    if (!fr) return fitset_cost_pc(fs, D, den, fd);
    lobe_sums_t m = fs->base[fd];
    for (size_t j = 0; j < fs->n; j++) {
        if (D[j] == 0) continue;
        double S = D[j] * fr[j] / den[j], wS = fs->w[j] * S;
        m.ws += fd ? fs->w[j] * fs->b1[j] * S : wS;
        m.wss += wS * S;
        for (int c = 0; c < 3; c++)
            m.wsf[c] += wS * fs->f[3 * j + (size_t)c];
    }
    double r = 0, a, b;
    for (int c = 0; c < 3; c++)
        r += sb_lobe_solve2_(&m, c, &a, &b);
    return r;
}

/* A family cf of one distribution: the cosines' power cf % COSP, F0
 * (cf / COSP) % (NF0 + 1) (NF0: per channel), diffuse factor fd. */
#define FCS (COSP * (NF0 + 1) * 2) /* the families of one distribution */
#define FAMILIES (NDFS * FCS)
#define CF_COSP(cf) ((cf) % COSP)
#define CF_F0(cf) ((size_t)(cf) / COSP % (NF0 + 1))
#define CF_FD(cf) ((cf) / (COSP * (NF0 + 1)))

/* fitset_cost of family cf with D and den given. */
static double fitset_family(const fitset_t *fs, const double *D, int cf, const double *den) {
    size_t fi = CF_F0(cf);
    return fitset_cost(fs, D, fi < NF0 ? fs->fr[fi] : NULL, den, CF_FD(cf));
}

/* The residual of one shape (shape_cost's). */
static double fitset_shape(fitset_t *fs, int ndf, double alpha, int cf) {
    fitset_d(fs, ndf, alpha, fs->D);
    fitset_den(fs, CF_COSP(cf), alpha, fs->D, fs->den[0]);
    return fitset_family(fs, fs->D, cf, fs->den[0]);
}

/* Golden-section refinement of log alpha in [lo, hi] for one (ndf, cf). */
static double refine_alpha(fitset_t *fs, int ndf, int cf, double lo, double hi, double *cost) {
    const double g = 0.6180339887498949;
    double a = lo, b = hi, x1 = b - g * (b - a), x2 = a + g * (b - a);
    double c1 = fitset_shape(fs, ndf, exp(x1), cf), c2 = fitset_shape(fs, ndf, exp(x2), cf);
    for (int it = 0; it < GOLDEN_STEPS; it++) {
        if (c1 < c2) {
            b = x2, x2 = x1, c2 = c1, x1 = b - g * (b - a);
            c1 = fitset_shape(fs, ndf, exp(x1), cf);
        } else {
            a = x1, x1 = x2, c1 = c2, x2 = a + g * (b - a);
            c2 = fitset_shape(fs, ndf, exp(x2), cf);
        }
    }
    *cost = c1 < c2 ? c1 : c2;
    return exp(c1 < c2 ? x1 : x2);
}

/* The index of family name `ndf` (0 when unknown). */
static int ndf_index(const char *ndf) {
    for (int k = 0; ndf && k < NDFS; k++)
        if (strcmp(ndf, ndf_names[k]) == 0) return k;
    return 0;
}

/* The geometry of samples 0, step, 2 step, ... (NULL on no memory). */
static geo_t *geo_of(const double *smp, size_t ns, size_t step) {
    geo_t *g = malloc(((ns + step - 1) / step) * sizeof *g);
    for (size_t i = 0, j = 0; g && i < ns; i += step, j++)
        g[j] = lobe_geo(smp + i * SB_SAMPLE_DOUBLES, smp + i * SB_SAMPLE_DOUBLES + 3);
    return g;
}

/* A shape tried, with its cost (log_cost). */
typedef struct cand {
    double cost;
    lobe_alt_t s;
} cand_t;

/* Shapes whose cost is within ALT_MARGIN of the best fit the samples about
 * as well; between the samples they can still part (one lobe's shoulder
 * reaches where another's has fallen 100x).  The base takes the lowest
 * of them: a highlight is not claimed where no sample shows it, and a
 * prediction too low there is off by at most the value, one too high by
 * any multiple of it.  alt[0] is the best; up to LOBE_ALTS - 1 more, the
 * cheapest first, each a different shape (cosine power 0 has no Smith k). */
static void pick_alternatives(const double *smp, size_t ns, const geo_t *geo, cand_t *c, int nc, double best,
                              lobe_t *L) {
    L->alt[0] = (lobe_alt_t){L->ndf, L->cosp, L->alpha, L->f0, {0}, {0}, INFINITY, L->pc, {0}, L->fd};
    memcpy(L->alt[0].kd, L->kd, sizeof L->kd);
    memcpy(L->alt[0].ks, L->ks, sizeof L->ks);
    memcpy(L->alt[0].f0c, L->f0c, sizeof L->f0c);
    L->nalt = 1;
    while (L->nalt < LOBE_ALTS) {
        int at = -1;
        for (int i = 0; i < nc; i++) {
            if (!(c[i].cost < best + fmin(ALT_MARGIN, ALT_REL * best)) || (at >= 0 && c[i].cost >= c[at].cost) ||
                c[i].s.pc != L->pc)
                continue;
            int same = 0;
            for (int a = 0; a < L->nalt && !same; a++)
                same = L->alt[a].ndf == c[i].s.ndf && L->alt[a].f0 == c[i].s.f0 && L->alt[a].pc == c[i].s.pc &&
                       L->alt[a].fd == c[i].s.fd &&
                       (L->alt[a].cosp == c[i].s.cosp || (L->alt[a].cosp % 3 == 0 && c[i].s.cosp % 3 == 0));
            if (!same) at = i;
        }
        if (at < 0) break;
        lobe_alt_t *a = &L->alt[L->nalt++];
        *a = c[at].s;
        shape_cost(smp, ns, 1, geo, a);
        c[at].cost = INFINITY;
    }
}

/* Whether family (ndf, cf) is searched: all, or keep's alone. */
static int family_wanted(const sb_lobe_fit_t *keep, int ndf, int cf) {
    int cosp = CF_COSP(cf);
    size_t fi = CF_F0(cf);
    if (keep && CF_FD(cf) != keep->diffuse_fresnel) return 0;
    int f0_kept = fi == NF0 ? keep && keep->f0_per_channel : keep && !keep->f0_per_channel && f0_grid[fi] == keep->f0;
    return !keep || (ndf == ndf_index(keep->ndf) && f0_kept &&
                     cosp == (int)(2 * keep->cos_power) + (keep->smith_k_remapped ? 3 : 0));
}

/* The grid's residuals of the families of one distribution and cosine
 * power cosp, D and den given, in one pass (cost[cf], cf = cosp, cosp +
 * COSP, ...): each family's sums are fitset_cost's to the bit (the same
 * operations in the same order), the diffuse factors sharing all but ws
 * and wt, the grey F0s the loads. */
static void fitset_group(const fitset_t *fs, const double *D, int cosp, const double *den, double cost[FCS]) {
    double gs[2][NF0], gss[NF0], gsf[NF0][3]; /* grey: ws by fd, wss, wsf */
    double ps[2] = {0, 0}, pt[2] = {0, 0}, pss = 0, pst = 0, ptt = 0, psf[3] = {0, 0, 0}, ptf[3] = {0, 0, 0};
    memset(gs, 0, sizeof gs), memset(gss, 0, sizeof gss), memset(gsf, 0, sizeof gsf);
    for (size_t j = 0; j < fs->n; j++) {
        if (D[j] == 0) continue;
        double w = fs->w[j], wb = w * fs->b1[j];
        const double *f = fs->f + 3 * j;
        for (int a = 0; a < NF0; a++) {
            double S = D[j] * fs->fr[a][j] / den[j], wS = w * S;
            gs[0][a] += wS;
            gs[1][a] += wb * S;
            gss[a] += wS * S;
            for (int c = 0; c < 3; c++)
                gsf[a][c] += wS * f[c];
        }
        double S = D[j] * 1.0 / den[j], T = D[j] * fs->m5[j] / den[j]; /* sums_add's, B = 1 or b1 */
        ps[0] += w * 1.0 * S, ps[1] += wb * S;
        pss += w * S * S;
        pt[0] += w * 1.0 * T, pt[1] += wb * T;
        pst += w * S * T;
        ptt += w * T * T;
        for (int c = 0; c < 3; c++) {
            psf[c] += w * S * f[c];
            ptf[c] += w * T * f[c];
        }
    }
    for (int cf = cosp; cf < FCS; cf += COSP) {
        size_t fi = CF_F0(cf);
        int fd = CF_FD(cf);
        lobe_sums_t m = fs->base[fd];
        double r = 0, a, b, e;
        if (fi < NF0) {
            m.ws = gs[fd][fi], m.wss = gss[fi];
            memcpy(m.wsf, gsf[fi], sizeof m.wsf);
            for (int c = 0; c < 3; c++)
                r += sb_lobe_solve2_(&m, c, &a, &b);
        } else {
            m.ws = ps[fd], m.wss = pss, m.wt = pt[fd], m.wst = pst, m.wtt = ptt;
            memcpy(m.wsf, psf, sizeof m.wsf);
            memcpy(m.wtf, ptf, sizeof m.wtf);
            for (int c = 0; c < 3; c++)
                r += sb_lobe_solve3_(&m, c, &a, &b, &e);
        }
        cost[cf] = r;
    }
}

/* For each family wanted, the grid's alpha of the lowest residual (the
 * first of equals) into at[ndf * FCS + cf], costed by fitset_group. */
static void grid_search(fitset_t *fs, const sb_lobe_fit_t *keep, double la, double dl, int at[FAMILIES]) {
    double cb[FAMILIES], gc[FCS];
    int wanted[FAMILIES], nw[NDFS][COSP];
    memset(nw, 0, sizeof nw);
    for (int i = 0; i < FAMILIES; i++) {
        cb[i] = INFINITY, at[i] = 0;
        wanted[i] = family_wanted(keep, i / FCS, i % FCS);
        nw[i / FCS][CF_COSP(i % FCS)] += wanted[i];
    }
    for (int k = 0; k < ALPHA_STEPS; k++) {
        double alpha = exp(la + k * dl);
        for (int cosp = 0; cosp < COSP; cosp++)
            fitset_den(fs, cosp, alpha, NULL, fs->den[cosp]);
        for (int ndf = 0, d = 0; ndf < NDFS; ndf++, d = 0)
            for (int cosp = 0; cosp < COSP; cosp++) {
                if (!nw[ndf][cosp]) continue;
                if (!d) fitset_d(fs, ndf, alpha, fs->D), d = 1;
                fitset_group(fs, fs->D, cosp, fs->den[cosp], gc);
                for (int cf = cosp, i = ndf * FCS + cf; cf < FCS; cf += COSP, i += COSP)
                    if (wanted[i] && gc[cf] < cb[i]) cb[i] = gc[cf], at[i] = k;
            }
    }
}

/* Every family wanted: alpha on the grid, refined, costed by log_cost
 * into cands (*nc of them); the best into L's shape; returns its cost. */
static double search(const double *smp, size_t ns, size_t step, const geo_t *geo, const sb_lobe_fit_t *keep,
                     cand_t *cands, int *nc, lobe_t *L) {
    fitset_t fs;
    if (!fitset_init(&fs, smp, ns, step, geo)) return INFINITY;
    double grey = INFINITY, pc = INFINITY, la = log(ALPHA_MIN), lb = log(ALPHA_MAX), dl = (lb - la) / (ALPHA_STEPS - 1);
    int at[FAMILIES], gi = -1, pi = -1;
    grid_search(&fs, keep, la, dl, at);
    for (int ndf = 0; ndf < NDFS; ndf++)
        for (int cf = 0; cf < FCS; cf++) {
            if (!family_wanted(keep, ndf, cf)) continue;
            int cosp = CF_COSP(cf), k = at[ndf * FCS + cf];
            size_t fi = CF_F0(cf);
            double lo = la + (k > 0 ? k - 1 : 0) * dl, hi = la + (k < ALPHA_STEPS - 1 ? k + 1 : k) * dl, c;
            double alpha = refine_alpha(&fs, ndf, cf, lo, hi, &c);
            lobe_alt_t s = {ndf,       cosp, alpha,    fi < NF0 ? f0_grid[fi] : 1.0, {0}, {0}, INFINITY,
                            fi == NF0, {0},  CF_FD(cf)};
            c = log_cost(smp, ns, step, geo, s, L->floor);
            if (fi < NF0 && c < grey) grey = c, gi = *nc;
            if (fi == NF0 && c < pc) pc = c, pi = *nc;
            cands[(*nc)++] = (cand_t){c, s};
        }
    free(fs.c2);
    int b = pi >= 0 && (gi < 0 || (pc < grey * (1 - PC_GAIN) && pc < grey - PC_MIN)) ? pi : gi;
    if (b < 0) return INFINITY;
    const lobe_alt_t *s = &cands[b].s;
    L->ndf = s->ndf, L->alpha = s->alpha, L->f0 = s->f0, L->cosp = s->cosp, L->pc = s->pc, L->fd = s->fd;
    return cands[b].cost;
}

void sb_lobe_fit_(const double *smp, size_t ns, const sb_lobe_fit_t *keep, lobe_t *L) {
    memset(L, 0, sizeof *L);
    if (ns == 0) return;
    size_t step = ns > FIT_MAX ? (ns + FIT_MAX - 1) / FIT_MAX : 1;
    geo_t *geo = geo_of(smp, ns, step);
    if (!geo) return; /* no memory: not fitted, the table interpolates f itself */
    sb_lobe_floor_(smp, ns, L->floor);
    int nc = 0;
    cand_t cands[FAMILIES];
    double best = search(smp, ns, step, geo, keep, cands, &nc, L);
    if (step > 1) { /* the weights from every sample */
        free(geo);
        geo = geo_of(smp, ns, 1);
    }
    if (!geo || !(best < INFINITY) || !(L->alpha > 0)) { /* no finite fit (values near overflow): not fitted */
        free(geo);
        return;
    }
    lobe_alt_t s = {L->ndf, L->cosp, L->alpha, L->f0, {0}, {0}, INFINITY, L->pc, {0}, L->fd};
    shape_cost(smp, ns, 1, geo, &s);
    memcpy(L->kd, s.kd, sizeof L->kd);
    memcpy(L->ks, s.ks, sizeof L->ks);
    memcpy(L->f0c, s.f0c, sizeof L->f0c);
    pick_alternatives(smp, ns, geo, cands, nc, best, L);
    /* Each shape's D is capped at CAP x its largest at a sample: a lobe
     * narrower than the samples resolve claims no higher peak between them.
     * F, the cosines and the shadowing still grow towards the horizon as
     * the shape says (a cap on f itself clipped a glossy table's grazing
     * peak beyond its last elevation: the retro band of its fit 17 % where
     * the model's own is 1.2 %). */
    for (int a = 0; a < L->nalt; a++) {
        double dm = 0;
        for (size_t i = 0; i < ns; i++)
            if (geo[i].ok) dm = fmax(dm, ndf_at(&geo[i], L->alt[a].ndf, L->alt[a].alpha));
        L->alt[a].dcap = CAP * dm;
    }
    free(geo);
    L->fitted = 1;
}

void sb_lobe_base_(const lobe_t *L, const double wi[3], const double wo[3], double b[3]) {
    geo_t g = lobe_geo(wi, wo);
    double m[3] = {INFINITY, INFINITY, INFINITY};
    for (int a = 0; a < L->nalt; a++) {
        const lobe_alt_t *s = &L->alt[a];
        double S = shape_capped(&g, s->ndf, s->alpha, s->f0c[0], s->cosp, s->dcap), B = diffuse_at(&g, s->fd);
        for (int c = 0; c < 3; c++) {
            if (s->pc && c > 0) S = shape_capped(&g, s->ndf, s->alpha, s->f0c[c], s->cosp, s->dcap);
            m[c] = fmin(m[c], s->kd[c] * B + s->ks[c] * S);
        }
    }
    for (int c = 0; c < 3; c++)
        b[c] = m[c] + L->floor[c];
}

void sb_lobe_report_(const lobe_t *L, int used, sb_lobe_fit_t *out) {
    out->fitted = L->fitted;
    out->used = used;
    out->ndf = ndf_names[L->ndf];
    out->alpha = L->alpha;
    out->f0 = L->pc ? (L->f0c[0] + L->f0c[1] + L->f0c[2]) / 3 : L->f0;
    out->f0_per_channel = L->pc;
    out->diffuse_fresnel = L->fd;
    memcpy(out->f0_rgb, L->f0c, sizeof out->f0_rgb);
    memcpy(out->kd, L->kd, sizeof out->kd);
    memcpy(out->ks, L->ks, sizeof out->ks);
    memcpy(out->floor, L->floor, sizeof out->floor);
    out->d_cap = L->alt[0].dcap;
    out->cos_power = (L->cosp % 3) / 2.0;
    out->smith_k_remapped = L->cosp >= 3;
}
