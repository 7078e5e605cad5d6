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
#include "factor/estimate_pair.h"
#include "util/internal.h"
#include "util/parallel.h"
#include "util/rng.h"

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
    est_draw_replicate(user, k);
}

static sb_estimate_opts_t opts_or_default(const sb_estimate_opts_t *opts) {
    sb_estimate_opts_t o = {0};
    if (opts) o = *opts;
    if (!o.replicate) o.replicate = 4096;
    if (!o.start) o.start = 16;
    if (!o.max_pairs) o.max_pairs = (size_t)1 << 19;
    if (!(o.rel_se > 0)) o.rel_se = SB_EST_REL_SE;
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
    P->start = o.start;
    P->seed = o.seed;
    P->channels = o.channels & 7u ? o.channels & 7u : 7u;
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
        P->m0 += d[6];
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

/* Add one known pair's errors for every prefix to the replicate sums. */
/* d2s, bins: each prefix's squared differences [J][4] and the bins of the
 * channels with f > 0 [J][4] (not with headline_only), which the band sums
 * read again. */
static inline __attribute__((always_inline)) void add_pair(const eval_t *e, const double *d, const double *rec,
                                                           double *num, double *neg, int t, double *d2s,
                                                           uint32_t *bins) {
    const double *f = d + 7, w = d[6];
    double ci2 = d[2] * d[2], qw[SB_EST_Q_COUNT_] = {ci2, ci2 * d[5] * d[5], 1};
    double f2[4] = {f[0] * f[0], f[1] * f[1], f[2] * f[2], 0}, lf2[4] = {0, 0, 0, 0};
    f2[3] = f2[0] + f2[1] + f2[2];
    uint64_t ew[4] = {0, 0, 0, 0};
    for (int c = 0; c < 4 && !e->headline_only; c++) { /* the histograms' logs and weights */
        lf2[c] = f2[c] > 0 ? est_log2(f2[c]) : 0;
        ew[c] = e->P->e0[c] > 0 ? (uint64_t)(f2[c] * ci2 * w / e->P->e0[c] * 0x1.0p40) : 0;
    }
    size_t J = e->J;
    uint64_t *hist = e->hist + (size_t)t * J * 4 * NB;
    double *maxr = e->maxr + (size_t)t * est_tstride(J * 4), *maxv = e->maxv + (size_t)t * est_tstride(J);
    est_v4_t f4 = {f[0], f[1], f[2], 0}, z = {0, 0, 0, 0};
    const est_v4i_t nosign = {INT64_MAX, INT64_MAX, INT64_MAX, INT64_MAX};
    for (size_t j = e->last_only ? J - 1 : 0; j < J; j++) {
        est_v4_t r = *(const est_v4_t *)(rec + j * 3), dc = r - f4, sq = dc * dc; /* lane 3: not read */
        est_v4_t a = (est_v4_t)((est_v4i_t)r & nosign);                           /* fabs: the sign bit cleared */
        est_v4i_t lt = (est_v4i_t)(r < z);
        double d2[4] = {sq[0], sq[1], sq[2], 0}, vmax = 0;
        int below = (lt[0] | lt[1] | lt[2]) != 0;
        for (int c = 0; c < 3; c++) {
            d2[3] += d2[c];
            vmax = a[c] > vmax ? a[c] : vmax; /* fmax's result, inline (a NaN leaves vmax) */
        }
        est_v4_t d2v = {d2[0], d2[1], d2[2], d2[3]};
        for (int q = 0; q < SB_EST_Q_COUNT_; q++) /* (d2 qw) w per channel, as one at a time */
            *(est_v4_t *)(num + j * QC + q * 4) += d2v * qw[q] * w;
        neg[j] += below ? w : 0;
        maxv[j] = vmax > maxv[j] ? vmax : maxv[j];
        memcpy(d2s + j * 4, d2, sizeof d2);
        for (int c = 0; c < 4 && !e->headline_only; c++) {
            if (!(f2[c] > 0)) continue;
            size_t bin = est_bin_of(d2[c], f2[c], lf2[c]);
            bins[j * 4 + c] = (uint32_t)bin;
            hist[(j * 4 + c) * NB + bin] += ew[c];
            if (d2[c] > maxr[j * 4 + c] * f2[c]) /* a division only for a new maximum */
                maxr[j * 4 + c] = d2[c] / f2[c]; /* maxr holds squares: roots taken in combine() */
        }
    }
}

SB_AVX2_CLONES static void eval_unit(void *user, size_t k, int t) {
    eval_t *e = user;
    const sb_pairs_t *P = e->P;
    size_t J = e->J;
    /* the sums in local arrays (nothing else can alias them), copied out
     * at the end */
    double num[SB_EST_MAXJ * QC], den[QC], neg[SB_EST_MAXJ], meas = 0, rec[EST_REC_LEN];
    double de[SB_EST_MAXJ], dew = 0, d2s[SB_EST_MAXJ * 4];
    uint32_t bins[SB_EST_MAXJ * 4];
    memset(de, 0, J * sizeof *de);
    memset(num, 0, J * QC * sizeof *num);
    memset(den, 0, sizeof den);
    memset(neg, 0, J * sizeof *neg);
    if (e->bands) est_bands_clear(e, k);
    for (size_t i = k * P->rep; i < (k + 1) * P->rep; i++) {
        if (!P->known[i]) continue;
        const double *d = P->d + i * PD, *f = d + 7;
        double ci2 = d[2] * d[2], qw[SB_EST_Q_COUNT_] = {ci2, ci2 * d[5] * d[5], 1};
        est_v4_t ff = {f[0] * f[0], f[1] * f[1], f[2] * f[2], 0};
        ff[3] = ff[0] + ff[1] + ff[2];
        for (int q = 0; q < SB_EST_Q_COUNT_; q++) /* ((f f) qw) 1/p per channel, as one at a time */
            *(est_v4_t *)(den + q * 4) += ff * qw[q] * d[6];
        meas += d[6];
        est_reconstruct(e, i, rec);
        add_pair(e, d, rec, num, neg, t, d2s, bins);
        if (e->bands) est_bands_pair(e, i, rec, d2s, bins, k, t);
        if (!e->headline_only && est_chroma_pair(e, i, rec, de)) dew += d[6];
    }
    memcpy(e->de + k * J, de, J * sizeof *de);
    e->dew[k] = dew;
    memcpy(e->num + k * J * QC, num, J * QC * sizeof *num);
    memcpy(e->den + k * QC, den, sizeof den);
    memcpy(e->neg + k * J, neg, J * sizeof *neg);
    e->meas[k] = meas;
}

/* The one-sided 95 % upper confidence bound of a standard deviation from
 * K samples, in units of the estimate: sqrt(nu / chi2_0.05(nu)), nu = K - 1,
 * the chi-square quantile by Wilson and Hilferty's cube
 * nu (1 - 2 / (9 nu) - 1.6449 sqrt(2 / (9 nu)))^3 (3.02 at K = 4 against
 * the exact 2.92, 2.15 against 2.17 at K = 8: on the safe side). */
static double se_upper(size_t K) {
    double nu = K > 1 ? (double)(K - 1) : 1, a = 2 / (9 * nu), c = 1 - a - 1.6448536269514722 * sqrt(a);
    return c > 0 ? sqrt(1 / (c * c * c)) : INFINITY;
}

/* How many prefixes met the target at K replicates: the largest m with
 * the headline's standard error (its upper bound, se_upper) at most rel_se
 * of it at every J' <= m. */
static size_t prefixes_met(const eval_t *e, size_t K, double rel_se) {
    size_t J = e->J, at = SB_EST_FCOS * 4 + 3;
    double up = se_upper(K);
    for (size_t j = 0; j < J; j++) {
        double h, se;
        est_ratio(e->num + j * QC + at, J * QC, e->den + at, QC, K, &h, &se);
        if (!(se * up <= rel_se * h)) return j;
    }
    return J;
}

/* The sums of K replicates and nt threads into out: the prefixes from
 * J' = jlo + 1 on (those below are kept from fewer replicates). */
static void combine(const eval_t *e, size_t K, int nt, size_t jlo, sb_estimate_t *out) {
    size_t J = e->J;
    out->replicates = K;
    double msum = 0;
    for (size_t k = 0; k < K; k++)
        msum += e->meas[k];
    for (size_t j = jlo; j < J; j++) {
        double ng = 0;
        for (size_t k = 0; k < K; k++)
            ng += e->neg[k * J + j];
        out->neg_frac[j] = msum > 0 ? ng / msum : 0;
        double ds = 0, dw = 0;
        for (size_t k = 0; k < K; k++)
            ds += e->de[k * J + j], dw += e->dew[k];
        out->chroma_de[j] = dw > 0 ? ds / dw : NAN;
        for (int i = 0; i < QC; i++)
            est_ratio(e->num + j * QC + (size_t)i, J * QC, e->den + i, QC, K, &out->rel[j][i / 4][i % 4],
                      &out->se[j][i / 4][i % 4]);
        double vmax = 0;
        for (int t = 0; t < nt; t++)
            vmax = fmax(vmax, e->maxv[(size_t)t * est_tstride(J) + j]);
        out->overshoot[j] = vmax;
        for (int c = 0; c < 4; c++) {
            double mx = 0;
            for (int t = 0; t < nt; t++)
                mx = fmax(mx, sqrt(e->maxr[(size_t)t * est_tstride(J * 4) + j * 4 + (size_t)c]));
            out->p99[j][c] = est_hist_p99(e->hist + (j * 4 + (size_t)c) * NB, J * 4 * NB, nt, mx);
            out->max_rel[j][c] = mx;
        }
    }
    if (e->bands) est_bands_combine(e, K, nt, jlo, out);
}

/* Sums for kmax replicates and nt threads (the lit thresholds over the
 * first `reps`); SB_OK or SB_ERR_NOMEM. */
static sb_result_t eval_alloc(sb_context_t *ctx, eval_t *e, size_t kmax, int nt, size_t reps) {
    size_t J = e->J, T = (size_t)nt;
    e->num = sb_alloc(ctx, kmax * J, QC * sizeof *e->num, "estimator sums");
    e->den = sb_alloc(ctx, kmax, QC * sizeof *e->den, "estimator sums");
    e->neg = sb_alloc(ctx, kmax, J * sizeof *e->neg, "estimator sums");
    e->meas = sb_alloc(ctx, kmax, sizeof *e->meas, "estimator sums");
    e->de = sb_alloc(ctx, kmax, J * sizeof *e->de, "estimator sums");
    e->dew = sb_alloc(ctx, kmax, sizeof *e->dew, "estimator sums");
    e->hist = sb_calloc(ctx, T * J * 4, NB * sizeof *e->hist, "estimator histograms");
    e->maxr = sb_calloc(ctx, T, est_tstride(J * 4) * sizeof *e->maxr, "estimator sums");
    e->maxv = sb_calloc(ctx, T, est_tstride(J) * sizeof *e->maxv, "estimator sums");
    if (!(e->num && e->den && e->neg && e->meas && e->de && e->dew && e->hist && e->maxr && e->maxv))
        return SB_ERR_NOMEM;
    return e->bands ? est_bands_alloc(ctx, e, kmax, nt, reps) : SB_OK;
}

/* Pair counts and the denominators of the overshoot and of min_rel of
 * the prefixes from J' = jlo + 1 on, the largest |f| over the first n
 * pairs (per channel and of all). */
static void finish(const sb_pairs_t *P, size_t n, size_t jlo, sb_estimate_t *out) {
    double fm[4] = {0, 0, 0, 0};
    size_t known = 0;
    for (size_t i = 0; i < n; i++) {
        if (!P->known[i]) continue;
        known++;
        for (int c = 0; c < 3; c++) { /* fmax's result inline (a known f is finite; fmax was a call) */
            double a = fabs(P->d[i * PD + 7 + c]);
            fm[c] = a > fm[c] ? a : fm[c];
        }
    }
    fm[3] = fmax(fm[0], fmax(fm[1], fm[2]));
    for (size_t j = jlo; j < out->terms; j++) {
        out->overshoot[j] = fm[3] > 0 ? out->overshoot[j] / fm[3] : 0;
        for (int c = 0; c < 4; c++)
            out->min_rel[j][c] = fm[c] > 0 ? out->min_rel[j][c] / fm[c] : 0;
    }
    out->known = known;
    out->pairs = n;
}

/* e's textures, sizes, wraps and per-term scales (*ones, J values: scales
 * or 1) for the first min(J, SB_EST_MAXJ) terms of f; SB_OK or
 * SB_ERR_NOMEM (then e's arrays and *ones are freed). */
sb_result_t est_eval_setup(eval_t *e, const sb_factors_t *f, const double *scales, const sb_param_t *p, double **ones) {
    est_log2_init();
    size_t J = sb_factors_terms(f), C = sb_factors_channels(f);
    if (J > SB_EST_MAXJ) J = SB_EST_MAXJ;
    e->J = J;
    e->C = C;
    e->clamp = sb_param_apply_gain(p, -1, 1) == 0; /* max(0, sum) unless plain */
    e->gain = (sb_param_caps(p) & SB_CAP_TABLES) != 0;
    *ones = malloc(J * (1 + C) * sizeof **ones); /* scale, then scs */
    e->tex[0] = malloc(J * C * sizeof *e->tex[0]);
    e->tex[1] = malloc(J * C * sizeof *e->tex[1]);
    if (!*ones || !e->tex[0] || !e->tex[1]) {
        free(*ones);
        est_eval_free(e);
        return SB_ERR_NOMEM;
    }
    for (size_t j = 0; j < J; j++) {
        (*ones)[j] = scales ? scales[j] : 1;
        for (size_t c = 0; c < C; c++)
            (*ones)[J + j * C + c] = (*ones)[j];
    }
    e->scale = *ones;
    e->scs = *ones + J;
    for (int s = 0; s < 2; s++) {
        sb_factors_size(f, s, &e->tw[s], &e->th[s]);
        sb_param_wrap(p, s, e->wrap[s]);
        sb_param_edge(p, s, e->edge[s]);
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
    e.bands = !o.headline_only || o.bands;
    double *ones = NULL;
    if (est_eval_setup(&e, f, scales, p, &ones) != SB_OK) return sb_error(ctx, SB_ERR_NOMEM, "estimate: out of memory");
    size_t J = e.J, rep = pairs->rep;
    /* the counts: the first replicates, doubled up to cap (max_pairs; the
     * pairs there are when max_pairs allows no growth) */
    size_t cap = o.max_pairs / rep > pairs->start ? o.max_pairs / rep : pairs->nrep;
    size_t K = pairs->start < cap ? pairs->start : cap;
    if (o.replicates) { /* the first ones only, no growth */
        K = o.replicates < 4 ? 4 : o.replicates;
        cap = K = K < pairs->nrep ? K : pairs->nrep;
    }
    size_t have = pairs->nrep < cap ? pairs->nrep : cap;
    e.co = est_coords_acquire(pairs, p, have * rep, &e.co_ready);
    e.chroma_thr = o.headline_only ? 0 : est_chroma_threshold(pairs, K);
    sb_result_t r = eval_alloc(ctx, &e, cap, nt, K);
    /* evaluate the replicates up to K and take the prefixes that met the
     * target there (with every shorter one: where an estimate of that many
     * terms stops), then double K (drawing replicates where needed) until
     * every prefix is taken or K is cap */
    size_t done = 0, jlo = 0;
    out->terms = J;
    while (r == SB_OK && (r = pairs_grow(ctx, pairs, K, nt)) == SB_OK) {
        est_run_units(done, K - done, nt, eval_unit, &e);
        done = K;
        size_t met = prefixes_met(&e, K, o.rel_se);
        if (e.bands && o.stop_bands) {
            size_t bm = est_bands_met(&e, K, o.stop_bands & ((1u << SB_BAND_COUNT_) - 1), o.rel_se);
            met = bm < met ? bm : met;
        }
        combine(&e, K, nt, jlo, out);
        finish(pairs, K * rep, jlo, out);
        for (; jlo < met; jlo++)
            out->reps[jlo] = K;
        if (jlo == J || K >= cap) break;
        K = 2 * K < cap ? 2 * K : cap;
    }
    out->converged = jlo == J;
    for (size_t j = jlo; j < J; j++)
        out->reps[j] = done; /* not met: at the most replicates */
    size_t filled = e.co && !e.co_ready && r == SB_OK ? done * rep : 0;
    est_coords_release(pairs, e.co, p, e.co && filled > e.co->cap ? e.co->cap : filled);
    free(ones);
    est_eval_free(&e);
    return r == SB_OK ? SB_OK : sb_error(ctx, r, "estimate: out of memory");
}

double sb_estimate_headline(const sb_estimate_t *est, size_t j) {
    return est && j >= 1 && j <= est->terms ? est->rel[j - 1][SB_EST_FCOS][3] : NAN;
}
