/* The error estimator (estimate.h): randomised quasi-Monte Carlo pairs
 * drawn from a mixture density, the reconstruction evaluated as the shader
 * evaluates it, all prefixes J' = 1..J accumulated in one pass per pair.
 *
 * Storage: a pair is PD doubles {wi[3], wo[3], 1/p, f[3]} and a known flag
 * (0: outside the domain, unknown to the source or not finite; such a pair
 * adds 0 to every integral, which the ratio of sums handles exactly like a
 * zero sample).  Replicate k holds pairs k * rep .. (k + 1) * rep - 1.
 *
 * Work: one unit per replicate; its sums (numerators per J', quantity and
 * channel, denominators, negative measure) go to the replicate's own slot
 * and are added in replicate order.  Histograms of the per-pair relative
 * errors (integer energy weights: b / E0 * 2^40 with E0 the energy of the
 * first replicates, fixed when the pairs are created, so later replicates
 * add to the same histograms) and maxima are per thread
 * and merged by integer addition and max, so every result is the same to
 * the bit on any thread count. */
#include "sepbrdf/estimate.h"

#include <float.h>
#include <math.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "factor/estimate_impl.h"
#include "util/internal.h"
#include "util/parallel.h"
#include "util/rng.h"

#define NCOMP 7 /* wo mixture components: uniform, cosine, four GGX lobes, grazing */
#define GRAZE (NCOMP - 1)

static const double comp_w[NCOMP] = {0.18, 0.18, 0.135, 0.135, 0.135, 0.135, 0.1};
static const double lobe_alpha[NCOMP] = {0, 0, 0.005, 0.02, 0.08, 0.3, 0};
/* wi: uniform, cosine, grazing */
static const double wi_w[3] = {0.45, 0.45, 0.1};

/* ---- drawing the pairs ------------------------------------------------ */

/* The grazing component: cos(theta) = c with density 1 / (K (c + C0)^2)
 * on [0, 1], K = 1/C0 - 1/(1 + C0) (half of its pairs within 0.17 degrees
 * of the horizon), azimuth uniform.  Where a reconstruction grows as
 * 1 / cos theta towards the horizon (a form's division, a non-reciprocal
 * source folded by a reciprocal layout), the squared error grows as
 * 1 / cos^2 and the other components, bounded there, would leave an
 * estimate of unbounded variance that misses the tail; with this one the
 * ratio stays bounded down to the guard 0.001. */
#define C0 0.003
static double graze_pdf(double c) {
    const double K = 1 / C0 - 1 / (1 + C0);
    return c >= 0 && c <= 1 ? 1 / (K * (c + C0) * (c + C0) * 2 * SB_PI) : 0;
}
static double graze_z(double u) {
    const double K = 1 / C0 - 1 / (1 + C0);
    return fmin(1, fmax(0, 1 / (1 / C0 - u * K) - C0));
}

/* GGX normal distribution D(h) for cos(theta_h) = c. */
static double ggx_d(double alpha, double c) {
    double a2 = alpha * alpha, t = (a2 - 1) * c * c + 1;
    return a2 / (SB_PI * t * t);
}

/* Mixture density of wo given wi (both unit, wo.z > 0). */
static double pdf_o(const double wi[3], const double wo[3]) {
    double p = comp_w[0] / (2 * SB_PI) + comp_w[1] * wo[2] / SB_PI + comp_w[GRAZE] * graze_pdf(wo[2]), h[3];
    for (int i = 0; i < 3; i++)
        h[i] = wi[i] + wo[i];
    double nh = sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
    if (nh <= 0) return p;
    double hz = h[2] / nh, oh = (wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2]) / nh;
    if (hz <= 0 || oh <= 0) return p;
    for (int k = 2; k < GRAZE; k++)
        p += comp_w[k] * ggx_d(lobe_alpha[k], hz) * hz / (4 * oh);
    return p;
}

/* Direction with cos(theta) = z, azimuth 2 pi u. */
static void dir_z(double z, double u, double w[3]) {
    double s = sqrt(fmax(0, 1 - z * z)), ph = 2 * SB_PI * u;
    w[0] = s * cos(ph);
    w[1] = s * sin(ph);
    w[2] = z;
}

/* Map a point x of [0,1)^6 to a pair; returns its density (0: wo below the
 * horizon, no BRDF pair). */
static double draw_pair(const double x[6], double wi[3], double wo[3]) {
    dir_z(x[0] < wi_w[0] ? x[1] : x[0] < wi_w[0] + wi_w[1] ? sqrt(1 - x[1]) : graze_z(x[1]), x[2], wi);
    double pi_ = wi_w[0] / (2 * SB_PI) + wi_w[1] * wi[2] / SB_PI + wi_w[2] * graze_pdf(wi[2]);
    int k = 0;
    for (double acc = comp_w[0]; k < NCOMP - 1 && x[3] >= acc; acc += comp_w[++k])
        ;
    if (k == 0) {
        dir_z(x[4], x[5], wo);
    } else if (k == 1) {
        dir_z(sqrt(1 - x[4]), x[5], wo);
    } else if (k == GRAZE) {
        dir_z(graze_z(x[4]), x[5], wo);
    } else {
        double a = lobe_alpha[k], t2 = a * a * x[4] / (1 - x[4]), h[3];
        dir_z(1 / sqrt(1 + t2), x[5], h);
        double ih = wi[0] * h[0] + wi[1] * h[1] + wi[2] * h[2];
        for (int i = 0; i < 3; i++)
            wo[i] = 2 * ih * h[i] - wi[i];
    }
    if (!(wo[2] > 0) || !(wi[2] > 0)) return 0;
    return pi_ * pdf_o(wi, wo);
}

/* A batched source (sb_source_create_batched): the drawn pairs of
 * replicate k (density in d[6]) evaluated in one call. */
static void eval_replicate(sb_pairs_t *P, size_t k) {
    size_t n = 0, *idx = malloc(P->rep * sizeof *idx);
    double *buf = malloc(P->rep * 9 * sizeof *buf);
    unsigned char *known = malloc(P->rep);
    double *wi = buf, *wo = buf ? buf + 3 * P->rep : NULL, *f = buf ? buf + 6 * P->rep : NULL;
    int have = idx && buf && known; /* else (no memory) pair by pair */
    for (size_t i = 0; i < P->rep && have; i++) {
        const double *d = P->d + (k * P->rep + i) * PD;
        if (!(d[6] > 0)) continue;
        memcpy(wi + 3 * n, d, 3 * sizeof *d);
        memcpy(wo + 3 * n, d + 3, 3 * sizeof *d);
        idx[n++] = i;
    }
    if (have) sb_source_eval_many(P->src, n, wi, wo, f, known);
    for (size_t i = 0, m = 0; i < P->rep; i++) {
        size_t at = k * P->rep + i;
        double *d = P->d + at * PD;
        int ok = have ? m < n && idx[m] == i : d[6] > 0, kn;
        if (!have)
            kn = ok && sb_source_eval(P->src, d, d + 3, d + 7) && isfinite(d[7] + d[8] + d[9]);
        else
            kn = ok && known[m] && isfinite(f[3 * m] + f[3 * m + 1] + f[3 * m + 2]);
        if (have && ok) memcpy(d + 7, f + 3 * m++, 3 * sizeof *d);
        d[6] = kn ? 1 / d[6] : 0;
        P->known[at] = (unsigned char)kn;
    }
    free(idx);
    free(buf);
    free(known);
}

/* Pairs of replicate k: the Kronecker set i alpha (alpha_d = 1/phi^(d+1),
 * phi the root of x^7 = x + 1) shifted by the replicate's random vector. */
static void draw_replicate(sb_pairs_t *P, size_t k) {
    static const double phi6 = 1.1127756842787055;
    double alpha[6], shift[6], a = 1;
    uint64_t s = P->seed * 0x2545f4914f6cdd1dULL + k;
    int batched = sb_source_batched(P->src);
    for (int d = 0; d < 6; d++) {
        a /= phi6;
        alpha[d] = a;
        shift[d] = sb_unit(sb_splitmix64(&s));
    }
    for (size_t i = 0; i < P->rep; i++) {
        size_t at = k * P->rep + i;
        double x[6], *d = P->d + at * PD;
        for (int e = 0; e < 6; e++) {
            double v = shift[e] + (double)(i + 1) * alpha[e];
            x[e] = v - floor(v);
        }
        double pd = P->draw ? P->draw(P->draw_user, x, d, d + 3) : draw_pair(x, d, d + 3);
        if (batched) { /* evaluated below, all at once */
            d[6] = pd;
            continue;
        }
        int known = pd > 0 && sb_source_eval(P->src, d, d + 3, d + 7) && isfinite(d[7] + d[8] + d[9]);
        d[6] = known ? 1 / pd : 0;
        P->known[at] = (unsigned char)known;
    }
    if (batched) eval_replicate(P, k);
}

/* ---- units of work on threads ----------------------------------------- */

typedef struct runner {
    atomic_size_t next;
    size_t first, count;
    void (*fn)(void *, size_t, int);
    void *user;
} runner_t;

typedef struct worker_arg {
    runner_t *r;
    int t;
} worker_arg_t;

static void *worker(void *arg) {
    worker_arg_t *a = arg;
    for (;;) {
        size_t i = atomic_fetch_add(&a->r->next, 1);
        if (i >= a->r->count) break;
        a->r->fn(a->r->user, a->r->first + i, a->t);
    }
    return NULL;
}

/* fn(user, unit, thread) for units first .. first + count - 1 on nt threads. */
void est_run_units(size_t first, size_t count, int nt, void (*fn)(void *, size_t, int), void *user) {
    runner_t r = {.first = first, .count = count, .fn = fn, .user = user};
    atomic_store(&r.next, 0);
    worker_arg_t args[MAXT];
    for (int t = 0; t < nt; t++)
        args[t] = (worker_arg_t){&r, t};
    sb_parallel_run(worker, args, sizeof args[0], nt, NULL, NULL);
}

static void draw_unit(void *user, size_t k, int t) {
    (void)t;
    draw_replicate(user, k);
}

static sb_estimate_opts_t opts_or_default(const sb_estimate_opts_t *opts) {
    sb_estimate_opts_t o = {0};
    if (opts) o = *opts;
    if (!o.replicate) o.replicate = 4096;
    if (!o.start) o.start = 16;
    if (!o.max_pairs) o.max_pairs = (size_t)1 << 19;
    if (!(o.rel_se > 0)) o.rel_se = 0.05;
    if (!o.seed) o.seed = 1;
    return o;
}

/* Grow P to nrep replicates (new ones drawn on nt threads). */
static sb_result_t pairs_grow(sb_context_t *ctx, sb_pairs_t *P, size_t nrep, int nt) {
    if (nrep <= P->nrep) return SB_OK;
    size_t n = nrep * P->rep;
    double *d = sb_alloc_large(ctx, n, PD * sizeof *d, "estimator pairs"); /* 5 MiB at first: 2 MiB pages */
    unsigned char *kn = sb_alloc(ctx, n, 1, "estimator pairs");
    if (!d || !kn) {
        free(d);
        free(kn);
        return SB_ERR_NOMEM;
    }
    if (P->n) {
        memcpy(d, P->d, P->n * PD * sizeof *d);
        memcpy(kn, P->known, P->n);
    }
    free(P->d);
    free(P->known);
    P->d = d;
    P->known = kn;
    size_t old = P->nrep;
    P->nrep = nrep;
    P->n = n;
    est_run_units(old, nrep - old, nt, draw_unit, P);
    return SB_OK;
}

sb_result_t sb_pairs_create(sb_context_t *ctx, const sb_source_t *src, const sb_estimate_opts_t *opts,
                            sb_pairs_t **out) {
    return sb_pairs_create_drawn(ctx, src, opts, NULL, NULL, out);
}

sb_result_t sb_pairs_create_drawn(sb_context_t *ctx, const sb_source_t *src, const sb_estimate_opts_t *opts,
                                  sb_pair_draw_fn draw, const void *user, sb_pairs_t **out) {
    if (!out) return sb_error(ctx, SB_ERR_ARG, "estimate: no output pointer");
    *out = NULL;
    if (!src) return sb_error(ctx, SB_ERR_ARG, "estimate: no source");
    if (opts && ((opts->start && opts->start < 4) || opts->replicate > ((size_t)1 << 24)))
        return sb_error(ctx, SB_ERR_RANGE, "estimate: %zu replicates of %zu pairs, need at least 4 of at most 2^24",
                        opts->start, opts->replicate);
    sb_estimate_opts_t o = opts_or_default(opts);
    sb_pairs_t *P = calloc(1, sizeof *P);
    if (!P) return sb_error(ctx, SB_ERR_NOMEM, "estimate: out of memory");
    if (pthread_mutex_init(&P->mu, NULL) != 0) {
        free(P);
        return sb_error(ctx, SB_ERR_NOMEM, "estimate: cannot create a lock");
    }
    P->src = src;
    P->rep = o.replicate;
    P->seed = o.seed;
    P->draw = draw;
    P->draw_user = user;
    int nt = sb_thread_count(o.threads);
    if (pairs_grow(ctx, P, o.start, nt > MAXT ? MAXT : nt) != SB_OK) {
        sb_pairs_destroy(P);
        return sb_error(ctx, SB_ERR_NOMEM, "estimate: cannot allocate %zu bytes for %zu pairs",
                        o.start * o.replicate * PD * sizeof(double), o.start * o.replicate);
    }
    for (size_t i = 0; i < P->n; i++) {
        const double *d = P->d + i * PD, *f = d + 7, q = d[2] * d[2] * d[6];
        if (!P->known[i]) continue;
        for (int c = 0; c < 3; c++) {
            P->e0[c] += f[c] * f[c] * q;
            P->e0[3] += f[c] * f[c] * q;
        }
    }
    *out = P;
    return SB_OK;
}

void sb_pairs_destroy(sb_pairs_t *P) {
    if (!P) return;
    for (int s = 0; s < EST_COORD_SLOTS; s++) {
        free(P->coords[s].st);
        free(P->coords[s].in);
    }
    pthread_mutex_destroy(&P->mu);
    free(P->d);
    free(P->known);
    free(P);
}

size_t sb_pairs_count(const sb_pairs_t *P) { return P ? P->n : 0; }

/* log2 x for x > 0 to about 2e-7 (a bin is 0.083 wide): the exponent
 * from the bits, log2 of the mantissa interpolated linearly in a table of
 * 1024 steps (error h^2 / (8 ln 2) = 1.7e-7).  libm's log10 per pair, term
 * and channel was a quarter of a whole io run, a polynomial with its
 * division half of the estimator's loop. */
#define LOG2_STEPS 1024
static double log2_tab[LOG2_STEPS + 1];
static pthread_once_t log2_once = PTHREAD_ONCE_INIT;
static void log2_init(void) {
    for (int i = 0; i <= LOG2_STEPS; i++)
        log2_tab[i] = log2(1 + (double)i / LOG2_STEPS);
}

static double log2_fast(double x) {
    if (!(x >= DBL_MIN) || !(x <= DBL_MAX)) return log2(x);
    uint64_t b;
    memcpy(&b, &x, sizeof b);
    int ex = (int)((b >> 52) & 0x7ff) - 1023;
    uint64_t mant = b & 0x000fffffffffffffULL;
    size_t i = (size_t)(mant >> 42); /* the top 10 of 52 bits */
    double frac = (double)(mant & ((1ULL << 42) - 1)) * 0x1.0p-42;
    return ex + log2_tab[i] + frac * (log2_tab[i + 1] - log2_tab[i]);
}

/* The histogram bin of relative error r = sqrt(d2 / f2), from the squares:
 * 40 bins a decade from 1e-12 (bin 0 below); lf2 = log2 f2. */
static size_t bin_of(double d2, double f2, double lf2) {
    if (!(d2 > 1e-24 * f2)) return 0;
    double b = 20 * 0.30102999566398120 * (log2_fast(d2) - lf2) + 480;
    return b >= NB - 1 ? NB - 1 : (size_t)b;
}

/* Add one known pair's errors for every prefix to the replicate sums. */
static void add_pair(const eval_t *e, const double *d, const double *rec, double *num, double *neg, int t) {
    const double *f = d + 7, w = d[6];
    double ci2 = d[2] * d[2], qw[SB_EST_Q_COUNT_] = {ci2, ci2 * d[5] * d[5], 1};
    double f2[4] = {f[0] * f[0], f[1] * f[1], f[2] * f[2], 0}, lf2[4] = {0, 0, 0, 0};
    f2[3] = f2[0] + f2[1] + f2[2];
    uint64_t ew[4] = {0, 0, 0, 0};
    for (int c = 0; c < 4 && !e->headline_only; c++) { /* the histograms' logs and weights */
        lf2[c] = f2[c] > 0 ? log2_fast(f2[c]) : 0;
        ew[c] = e->P->e0[c] > 0 ? (uint64_t)(f2[c] * ci2 * w / e->P->e0[c] * 0x1.0p40) : 0;
    }
    size_t J = e->J;
    uint64_t *hist = e->hist + (size_t)t * J * 4 * NB;
    double *maxr = e->maxr + (size_t)t * J * 4, *maxv = e->maxv + (size_t)t * J;
    for (size_t j = e->last_only ? J - 1 : 0; j < J; j++) {
        const double *r = rec + j * 3;
        double d2[4] = {0, 0, 0, 0}, vmax = 0;
        int below = 0;
        for (int c = 0; c < 3; c++) {
            double dc = r[c] - f[c];
            d2[c] = dc * dc;
            d2[3] += d2[c];
            below |= r[c] < 0;
            double a = fabs(r[c]);
            vmax = a > vmax ? a : vmax; /* fmax's result, inline (a NaN leaves vmax) */
        }
        for (int q = 0; q < SB_EST_Q_COUNT_; q++)
            for (int c = 0; c < 4; c++)
                num[j * QC + q * 4 + c] += d2[c] * qw[q] * w;
        neg[j] += below ? w : 0;
        maxv[j] = vmax > maxv[j] ? vmax : maxv[j];
        for (int c = 0; c < 4 && !e->headline_only; c++) {
            if (!(f2[c] > 0)) continue;
            hist[(j * 4 + c) * NB + bin_of(d2[c], f2[c], lf2[c])] += ew[c];
            if (d2[c] > maxr[j * 4 + c] * f2[c]) /* a division only for a new maximum */
                maxr[j * 4 + c] = d2[c] / f2[c]; /* maxr holds squares: roots taken in combine() */
        }
    }
}

static void eval_unit(void *user, size_t k, int t) {
    eval_t *e = user;
    const sb_pairs_t *P = e->P;
    size_t J = e->J;
    /* the sums in local arrays (nothing else can alias them), copied out
     * at the end */
    double num[SB_EST_MAXJ * QC], den[QC], neg[SB_EST_MAXJ], meas = 0, rec[SB_EST_MAXJ * 3];
    double de[SB_EST_MAXJ], dew = 0;
    memset(de, 0, J * sizeof *de);
    memset(num, 0, J * QC * sizeof *num);
    memset(den, 0, sizeof den);
    memset(neg, 0, J * sizeof *neg);
    for (size_t i = k * P->rep; i < (k + 1) * P->rep; i++) {
        if (!P->known[i]) continue;
        const double *d = P->d + i * PD, *f = d + 7;
        double ci2 = d[2] * d[2], qw[SB_EST_Q_COUNT_] = {ci2, ci2 * d[5] * d[5], 1};
        for (int q = 0; q < SB_EST_Q_COUNT_; q++) {
            for (int c = 0; c < 3; c++)
                den[q * 4 + c] += f[c] * f[c] * qw[q] * d[6];
            den[q * 4 + 3] += (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]) * qw[q] * d[6];
        }
        meas += d[6];
        est_reconstruct(e, i, rec);
        add_pair(e, d, rec, num, neg, t);
        if (!e->headline_only && est_chroma_pair(e, i, rec, de)) dew += d[6];
    }
    memcpy(e->de + k * J, de, J * sizeof *de);
    e->dew[k] = dew;
    memcpy(e->num + k * J * QC, num, J * QC * sizeof *num);
    memcpy(e->den + k * QC, den, sizeof den);
    memcpy(e->neg + k * J, neg, J * sizeof *neg);
    e->meas[k] = meas;
}

/* The sums of the replicates and threads into out; returns whether the
 * headline met the target standard error at every J'. */
static int combine(const eval_t *e, size_t K, int nt, double rel_se, sb_estimate_t *out) {
    size_t J = e->J;
    int met = 1;
    double dsum[QC] = {0}, msum = 0;
    for (size_t k = 0; k < K; k++) {
        for (int i = 0; i < QC; i++)
            dsum[i] += e->den[k * QC + i];
        msum += e->meas[k];
    }
    for (size_t j = 0; j < J; j++) {
        double nsum[QC] = {0}, ng = 0;
        for (size_t k = 0; k < K; k++) {
            for (int i = 0; i < QC; i++)
                nsum[i] += e->num[(k * J + j) * QC + i];
            ng += e->neg[k * J + j];
        }
        out->neg_frac[j] = msum > 0 ? ng / msum : 0;
        double ds = 0, dw = 0;
        for (size_t k = 0; k < K; k++)
            ds += e->de[k * J + j], dw += e->dew[k];
        out->chroma_de[j] = dw > 0 ? ds / dw : NAN;
        for (int i = 0; i < QC; i++) {
            double r2 = dsum[i] > 0 ? nsum[i] / dsum[i] : (nsum[i] > 0 ? INFINITY : 0), v = 0;
            for (size_t k = 0; k < K && isfinite(r2); k++) {
                double x = e->num[(k * J + j) * QC + i] - r2 * e->den[k * QC + i];
                v += x * x;
            }
            /* se of r2 = sd / (sqrt(K) mean D) with sd^2 = v / (K - 1) */
            double se2 = dsum[i] > 0 ? sqrt(v / (double)(K - 1)) * sqrt((double)K) / dsum[i] : 0;
            double r = sqrt(r2);
            out->rel[j][i / 4][i % 4] = r;
            out->se[j][i / 4][i % 4] = r > 0 ? se2 / (2 * r) : sqrt(se2);
        }
        double h = out->rel[j][SB_EST_FCOS][3];
        met &= out->se[j][SB_EST_FCOS][3] <= rel_se * h;
        double vmax = 0;
        for (int t = 0; t < nt; t++)
            vmax = fmax(vmax, e->maxv[(size_t)t * J + j]);
        out->overshoot[j] = vmax;
        for (int c = 0; c < 4; c++) {
            uint64_t hb[NB] = {0}, total = 0, acc = 0;
            double mx = 0;
            for (int t = 0; t < nt; t++) {
                const uint64_t *src = e->hist + ((size_t)t * J * 4 + j * 4 + (size_t)c) * NB;
                for (size_t b = 0; b < NB; b++)
                    hb[b] += src[b];
                mx = fmax(mx, sqrt(e->maxr[((size_t)t * J + j) * 4 + (size_t)c]));
            }
            for (size_t b = 0; b < NB; b++)
                total += hb[b];
            size_t b = 0;
            while (b + 1 < NB && (acc += hb[b]) < total - total / 100)
                b++;
            out->p99[j][c] = total ? fmin(pow(10, (double)(b + 1) / 40 - 12), mx) : 0;
            out->max_rel[j][c] = mx;
        }
    }
    return met;
}

/* Sums for kmax replicates and nt threads; SB_OK or SB_ERR_NOMEM. */
static sb_result_t eval_alloc(sb_context_t *ctx, eval_t *e, size_t kmax, int nt) {
    size_t J = e->J, T = (size_t)nt;
    e->num = sb_alloc(ctx, kmax * J, QC * sizeof *e->num, "estimator sums");
    e->den = sb_alloc(ctx, kmax, QC * sizeof *e->den, "estimator sums");
    e->neg = sb_alloc(ctx, kmax, J * sizeof *e->neg, "estimator sums");
    e->meas = sb_alloc(ctx, kmax, sizeof *e->meas, "estimator sums");
    e->de = sb_alloc(ctx, kmax, J * sizeof *e->de, "estimator sums");
    e->dew = sb_alloc(ctx, kmax, sizeof *e->dew, "estimator sums");
    e->hist = sb_calloc(ctx, T * J * 4, NB * sizeof *e->hist, "estimator histograms");
    e->maxr = sb_calloc(ctx, T * J, 4 * sizeof *e->maxr, "estimator sums");
    e->maxv = sb_calloc(ctx, T, J * sizeof *e->maxv, "estimator sums");
    return e->num && e->den && e->neg && e->meas && e->de && e->dew && e->hist && e->maxr && e->maxv ? SB_OK
                                                                                                     : SB_ERR_NOMEM;
}

/* Pair counts and the overshoot's denominator, max |f| over the pairs. */
static void finish(const sb_pairs_t *P, size_t n, sb_estimate_t *out) {
    double fmax_ = 0;
    size_t known = 0;
    for (size_t i = 0; i < n; i++) {
        if (!P->known[i]) continue;
        known++;
        for (int c = 0; c < 3; c++)
            fmax_ = fmax(fmax_, fabs(P->d[i * PD + 7 + c]));
    }
    for (size_t j = 0; j < out->terms; j++)
        out->overshoot[j] = fmax_ > 0 ? out->overshoot[j] / fmax_ : 0;
    out->known = known;
    out->pairs = n;
}

/* e's textures, sizes, wraps and per-term scales (*ones, J values: scales
 * or 1) for the first min(J, SB_EST_MAXJ) terms of f; SB_OK or
 * SB_ERR_NOMEM (then e's arrays and *ones are freed). */
sb_result_t est_eval_setup(eval_t *e, const sb_factors_t *f, const double *scales, const sb_param_t *p, double **ones) {
    pthread_once(&log2_once, log2_init);
    size_t J = sb_factors_terms(f), C = sb_factors_channels(f);
    if (J > SB_EST_MAXJ) J = SB_EST_MAXJ;
    e->J = J;
    e->C = C;
    *ones = malloc(J * sizeof **ones);
    e->tex[0] = malloc(J * C * sizeof *e->tex[0]);
    e->tex[1] = malloc(J * C * sizeof *e->tex[1]);
    if (!*ones || !e->tex[0] || !e->tex[1]) {
        free(*ones);
        est_eval_free(e);
        return SB_ERR_NOMEM;
    }
    for (size_t j = 0; j < J; j++)
        (*ones)[j] = scales ? scales[j] : 1;
    e->scale = *ones;
    for (int s = 0; s < 2; s++) {
        sb_factors_size(f, s, &e->tw[s], &e->th[s]);
        sb_param_wrap(p, s, e->wrap[s]);
        for (size_t j = 0; j < J; j++)
            for (size_t c = 0; c < C; c++)
                e->tex[s][j * C + c] = sb_factors_tex_const(f, s, j, c);
        size_t n = e->tw[s] * e->th[s];
        if (!(e->itex[s] = malloc(n * J * C * sizeof *e->itex[s]))) {
            free(*ones);
            est_eval_free(e);
            return SB_ERR_NOMEM;
        }
        for (size_t k = 0; k < J * C; k++)
            for (size_t i = 0; i < n; i++)
                e->itex[s][i * J * C + k] = e->tex[s][k][i];
    }
    return SB_OK;
}

sb_result_t sb_estimate_compute(sb_context_t *ctx, sb_pairs_t *pairs, const sb_factors_t *f, const double *scales,
                                const sb_param_t *p, sb_form_t form, const sb_estimate_opts_t *opts,
                                sb_estimate_t *out) {
    if (!pairs || !f || !p || !out) return sb_error(ctx, SB_ERR_ARG, "estimate: missing argument");
    memset(out, 0, sizeof *out);
    if ((unsigned)form >= SB_FORM_COUNT_) return sb_error(ctx, SB_ERR_ARG, "estimate: unknown form %d", (int)form);
    sb_estimate_opts_t o = opts_or_default(opts);
    int nt = sb_thread_count(o.threads);
    if (nt > MAXT) nt = MAXT;
    eval_t e = {.P = pairs, .p = p, .form = form, .headline_only = o.headline_only};
    e.last_only = o.headline_only && o.last_only;
    double *ones = NULL;
    if (est_eval_setup(&e, f, scales, p, &ones) != SB_OK) return sb_error(ctx, SB_ERR_NOMEM, "estimate: out of memory");
    size_t J = e.J;
    size_t kmax = o.max_pairs / pairs->rep, use = pairs->nrep;
    if (o.replicates) { /* the first ones only, no growth */
        use = o.replicates < 4 ? 4 : o.replicates;
        use = use < pairs->nrep ? use : pairs->nrep;
        kmax = 0;
    }
    e.co = est_coords_acquire(pairs, p, use * pairs->rep, &e.co_ready);
    e.chroma_thr = o.headline_only ? 0 : est_chroma_threshold(pairs, use);
    sb_result_t r = eval_alloc(ctx, &e, kmax > use ? kmax : use, nt);
    /* evaluate the replicates not yet evaluated, then add replicates
     * (doubling) until the headline's standard error meets the target */
    for (size_t done = 0; r == SB_OK;) {
        est_run_units(done, use - done, nt, eval_unit, &e);
        done = use;
        out->terms = J;
        out->converged = combine(&e, done, nt, o.rel_se, out);
        if (out->converged || done >= kmax) break;
        r = pairs_grow(ctx, pairs, done * 2 < kmax ? done * 2 : kmax, nt);
        use = pairs->nrep;
    }
    if (r == SB_OK) finish(pairs, use * pairs->rep, out);
    size_t filled = e.co && !e.co_ready && r == SB_OK ? use * pairs->rep : 0;
    est_coords_release(pairs, e.co, p, e.co && filled > e.co->cap ? e.co->cap : filled);
    free(ones);
    est_eval_free(&e);
    return r == SB_OK ? SB_OK : sb_error(ctx, r, "estimate: out of memory");
}

double sb_estimate_headline(const sb_estimate_t *est, size_t j) {
    return est && j >= 1 && j <= est->terms ? est->rel[j - 1][SB_EST_FCOS][3] : NAN;
}
