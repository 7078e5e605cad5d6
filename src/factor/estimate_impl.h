/* Private: what estimate.c (pairs, the estimate) and estimate_weights.c
 * (term weights) share: the pairs' storage, the reconstruction as the
 * shader computes it, and the units of work on threads. */
#ifndef SEPBRDF_ESTIMATE_IMPL_H
#define SEPBRDF_ESTIMATE_IMPL_H

#include <float.h>
#include <math.h>
#include <pthread.h>
#include <stdint.h>
#include <string.h>

#include "sample/divisor.h"
#include "sepbrdf/estimate.h"
#include "sepbrdf/matrix.h"
#include "util/tex_axis.h"

#define PD 10   /* doubles per pair */
#define NB 960  /* histogram bins: 40 per decade over [1e-12, 1e12] */
#define MAXT 64 /* threads */
#define QC (SB_EST_Q_COUNT_ * 4)
#define BQ (SB_BAND_COUNT_ * 4)      /* band sums per J': band, channel */
#define MM (SB_EST_MAP * SB_EST_MAP) /* band map cells */

/* The texture coordinates of the pairs under one parameterisation: the
 * estimator evaluates many factorisations of the same layout on the same
 * pairs (screening, texel fits, term weights), and the coordinates
 * (acos, atan2 per pair) were a tenth of a default run.  Filled once,
 * then read only while users > 0. */
typedef struct est_coords {
    unsigned long serial; /* sb_param_serial_ of the layout; 0: empty or being filled */
    size_t n, cap;        /* pairs covered (the first n), room */
    double *st;           /* cap x 4: s, t on side g, then on side h */
    unsigned char *in;    /* cap: the pair is in the layout's domain */
    int users;
    unsigned long used; /* when last acquired (eviction) */
} est_coords_t;

#define EST_COORD_SLOTS 4

struct sb_pairs {
    const sb_source_t *src;
    size_t rep, n, nrep; /* pairs per replicate, pairs, replicates */
    size_t start;        /* replicates drawn at first: where an estimate's doubling starts */
    uint64_t seed;
    unsigned channels;    /* the source's channels kept (1 R, 2 G, 4 B); the others read as 0 */
    sb_pair_draw_fn draw; /* NULL: the mixture of estimate.h */
    const void *draw_user;
    double *d;            /* n x PD */
    unsigned char *known; /* n */
    double e0[4];         /* headline energy of the first replicates per channel (R, G, B, all) */
    double m0;            /* pair measure (sum of 1/p) of the known pairs of the first replicates */
    pthread_mutex_t mu;   /* guards the slots' bookkeeping */
    est_coords_t coords[EST_COORD_SLOTS];
    unsigned long tick;
};

typedef struct eval {
    const sb_pairs_t *P;
    const sb_param_t *p;
    size_t J, C;
    const double **tex[2]; /* [side][j * C + c] */
    double *itex[2];       /* [side][texel * J * C + j * C + c]: a tap's J C values in a row */
    size_t tw[2], th[2];
    int wrap[2][2], edge[2][2];
    const double *scale; /* J per-term factors */
    const double *scs;   /* J C: scale[j] at j C + c, the itex rows' order */
    est_coords_t *co;    /* the pairs' coordinates under p (co_ready), or being filled, or NULL */
    int co_ready;
    sb_form_t form;
    int clamp;         /* sb_param_apply_gain takes max(0, sum) (not a plain sum) */
    int gain;          /* an SB_CAP_TABLES layout: sb_param_gain per pair (else 1) */
    int headline_only; /* no per-pair histograms or maxima (p99, max_rel 0) */
    int last_only;     /* sums of the prefix of all J terms only */
    int bands;         /* the band sums (estimate_bands.c) */
    /* per replicate: num [J][QC], den [QC], neg measure [J], measure */
    double *num, *den, *neg, *meas;
    /* colour (estimate_colour.c): the luminance threshold, 0 for none;
     * per replicate: sums of w CIEDE2000 [J], of w */
    double chroma_thr;
    double *de, *dew;
    /* per thread: histograms [J][4][NB], maxima [J][4], |f~| maxima [J] */
    uint64_t *hist;
    double *maxr, *maxv;
    /* where the error is (estimate_bands.c), not with headline_only: per
     * replicate band sums num [J][BQ], den [BQ], map sums at J num, den
     * [MM]; lit thresholds per channel (R, G, B, norm); per thread the
     * lit histograms [J][4][NB], their maxima (squares) and the smallest
     * reconstructed values [J][4] */
    double *bnum, *bden, *mnum, *mden;
    double lit_thr[4];
    uint64_t *hlit;
    double *maxl, *minv;
} eval_t;

/* Doubles from one thread's block of n per-thread values (maxima, minima:
 * written on every pair) to the next: whole cache lines and one more, so
 * that no two threads ever write one line (at J = 8 the blocks were 64 and
 * 256 bytes, end to end: two threads took as long as one, 2x the CPU). */
static inline size_t est_tstride(size_t n) { return (n + 7) / 8 * 8 + 8; }

/* Four doubles side by side (GCC's and clang's vector extension: one AVX
 * register in the AVX2 clones, two SSE2 halves in the baseline), loaded
 * and stored at any 8-byte address.  Each lane does the scalar code's
 * operations in its order: the same bits, a quarter of the instructions
 * (the per-pair sums were written one channel at a time). */
typedef double est_v4_t __attribute__((vector_size(32), aligned(8)));
typedef long long est_v4i_t __attribute__((vector_size(32), aligned(8)));

/* Where the error is (estimate_bands.c). */
void est_log2_init(void);

/* log2 x for x > 0 to about 2e-7 (a bin is 0.083 wide): the exponent
 * from the bits, log2 of the mantissa interpolated linearly in a table of
 * 1024 steps (error h^2 / (8 ln 2) = 1.7e-7; est_log2_init fills it).
 * Inline: called per pair, term and channel from two files. */
#define EST_LOG2_STEPS 1024
extern double est_log2_tab[EST_LOG2_STEPS + 1];
static inline double est_log2(double x) {
    if (!(x >= DBL_MIN) || !(x <= DBL_MAX)) return log2(x);
    uint64_t b;
    memcpy(&b, &x, sizeof b);
    int ex = (int)((b >> 52) & 0x7ff) - 1023;
    uint64_t mant = b & 0x000fffffffffffffULL;
    size_t i = (size_t)(mant >> 42); /* the top 10 of 52 bits */
    double frac = (double)(mant & ((1ULL << 42) - 1)) * 0x1.0p-42;
    return ex + est_log2_tab[i] + frac * (est_log2_tab[i + 1] - est_log2_tab[i]);
}

/* The histogram bin of relative error r = sqrt(d2 / f2), from the squares:
 * 40 bins a decade from 1e-12 (bin 0 below); lf2 = log2 f2. */
static inline size_t est_bin_of(double d2, double f2, double lf2) {
    if (!(d2 > 1e-24 * f2)) return 0;
    double b = 20 * 0.30102999566398120 * (est_log2(d2) - lf2) + 480;
    return b >= NB - 1 ? NB - 1 : (size_t)b;
}
/* The 99th percentile of the sum of nt histograms (stride apart), at most mx. */
double est_hist_p99(const uint64_t *hist, size_t stride, int nt, double mx);
/* Ratio estimate r = sqrt(sum num / sum den) over K replicates (num[k *
 * ns], den[k * ds]) and its standard error (delta method). */
void est_ratio(const double *num, size_t ns, const double *den, size_t ds, size_t K, double *r, double *se);
/* Allocate e's band sums for kmax replicates and nt threads; the lit
 * thresholds over P's first `reps` replicates.  SB_OK or SB_ERR_NOMEM. */
sb_result_t est_bands_alloc(sb_context_t *ctx, eval_t *e, size_t kmax, int nt, size_t reps);
/* Clear replicate k's band sums (est_bands_pair, estimate_pair.h, adds
 * to them). */
void est_bands_clear(const eval_t *e, size_t k);
/* Band errors, lit percentiles, smallest values (raw: finish divides) of
 * the prefixes from J' = jlo + 1 on, the shares and the map, from K
 * replicates and nt threads into out. */
void est_bands_combine(const eval_t *e, size_t K, int nt, size_t jlo, sb_estimate_t *out);
/* How many prefixes have every band of mask (1u << SB_BAND_*) at K
 * replicates with its standard error within rel_se of it (of all
 * channels); J where the mask is 0. */
size_t est_bands_met(const eval_t *e, size_t K, unsigned mask, double rel_se);
void est_bands_free(eval_t *e);
/* Draw and evaluate replicate k of P (estimate_draw.c). */
void est_draw_replicate(sb_pairs_t *P, size_t k);

/* Colour error (estimate_colour.c): pairs of the first EST_CHROMA_REPS
 * replicates, every EST_CHROMA_STRIDE-th. */
#define EST_CHROMA_REPS 16
#define EST_CHROMA_STRIDE 4
/* 1 % of the largest luminance of f cos theta_i over the pairs of the
 * first min(reps, EST_CHROMA_REPS) replicates. */
double est_chroma_threshold(const sb_pairs_t *P, size_t reps);
/* Add pair i's w CIEDE2000 at equal luminance of every prefix (rec as
 * est_reconstruct fills it) to de[J]; 1 when the pair counts, 0 (nothing
 * added) when it is not one of the colour error's. */
int est_chroma_pair(const eval_t *e, size_t i, const double *rec, double *de);

/* fn(user, unit, thread) for units first .. first + count - 1 on nt threads. */
void est_run_units(size_t first, size_t count, int nt, void (*fn)(void *, size_t, int), void *user);
/* GL bilinear footprint of st on a side of e: texel indices and weights. */
static inline void est_taps(const eval_t *e, int side, const double st[2], size_t at[4], double fw[4]) {
    sb_tex_footprint(st, e->tw[side], e->th[side], e->wrap[side], e->edge[side], at, fw);
}
/* The coordinates of P's first `need` pairs under p: *ready when a slot
 * has them (est_reconstruct reads them), else a slot est_reconstruct
 * fills as it goes (each pair by the unit that owns it); NULL when every
 * slot is in use or memory is short.  est_coords_release(.., filled)
 * publishes the first `filled` pairs (0: nothing was filled). */
est_coords_t *est_coords_acquire(const sb_pairs_t *P, const sb_param_t *p, size_t need, int *ready);
void est_coords_release(const sb_pairs_t *P, est_coords_t *co, const sb_param_t *p, size_t filled);
/* Room for every prefix's RGB at a pair: est_reconstruct stores whole
 * vectors, the last one a value beyond the J * 3. */
#define EST_REC_LEN (SB_EST_MAXJ * 3 + 4)

/* The prefix sums of t (J terms of 3 channels, t[3 J] readable) as
 * reconstructed values: rec[j * 3 + c] = max(0, sum) x gain / div (the
 * sum itself where !clamp), a vector a prefix (lane 3 a value rec's next
 * store overwrites, the last one rec[3 J]). */
static inline __attribute__((always_inline)) void est_prefix3(const double *t, size_t J, int clamp, double gain,
                                                              double div, double *rec) {
    est_v4_t acc = {0, 0, 0, 0}, z = {0, 0, 0, 0};
    est_v4i_t keep = {-1, -1, -1, -1};
    for (size_t j = 0; j < J; j++) {
        acc += *(const est_v4_t *)(t + j * 3);
        est_v4i_t m = clamp ? ~(est_v4i_t)(acc < z) : keep; /* clamp && v < 0: 0 (+0, as the scalar's) */
        *(est_v4_t *)(rec + j * 3) = (est_v4_t)((est_v4i_t)acc & m) * gain / div;
    }
}

/* Reconstructed RGB of every prefix at pair i: rec[j * 3 + c] (EST_REC_LEN
 * doubles; rec[J * 3] is written too); 0 outside.
 * Inline: in the per-pair loops' AVX2 clones (SB_AVX2_CLONES, on static
 * functions only) its product over terms and channels takes four doubles a
 * vector, the same operations and bits as the baseline's two. */
static inline __attribute__((always_inline)) void est_reconstruct(const eval_t *e, size_t i, double *rec) {
    double sg[2], sh[2], fg[4], fh[4];
    size_t ag[4], ah[4], J = e->J, C = e->C;
    const double *wi = e->P->d + i * PD, *wo = wi + 3;
    est_coords_t *co = e->co;
    int in;
    if (co && e->co_ready && i < co->n) {
        const double *st = co->st + 4 * i;
        sg[0] = st[0], sg[1] = st[1], sh[0] = st[2], sh[1] = st[3];
        in = co->in[i];
    } else {
        in = sb_param_coords(e->p, wi, wo, sg, sh);
        if (co && !e->co_ready && i < co->cap) { /* filling: each pair written by the unit that owns it */
            double *st = co->st + 4 * i;
            st[0] = sg[0], st[1] = sg[1], st[2] = sh[0], st[3] = sh[1];
            co->in[i] = (unsigned char)in;
        }
    }
    if (!in) {
        memset(rec, 0, (J * 3 + 1) * sizeof *rec);
        return;
    }
    est_taps(e, SB_SIDE_G, sg, ag, fg);
    est_taps(e, SB_SIDE_H, sh, ah, fh);
    double div = sb_form_divisor_inline(e->form, wi, wo), acc[3] = {0, 0, 0};
    double gain = e->gain ? sb_param_gain(e->p, wi, wo) : 1; /* 1 but on SB_CAP_TABLES layouts */
    size_t S = J * C; /* the interleaved texels: 8 runs of S values, not 8 J C scattered reads */
    const double *g[4], *h[4];
    for (int k = 0; k < 4; k++) {
        g[k] = e->itex[0] + ag[k] * S;
        h[k] = e->itex[1] + ah[k] * S;
    }
    /* every term and channel's product in one loop the compiler vectorises
     * (the same operations per value as one at a time, so the same bits),
     * then the prefix sums in term order */
    double t[EST_REC_LEN];
    for (size_t at = 0; at < S; at++)
        t[at] = (fg[0] * g[0][at] + fg[1] * g[1][at] + fg[2] * g[2][at] + fg[3] * g[3][at]) *
                (fh[0] * h[0][at] + fh[1] * h[1][at] + fh[2] * h[2][at] + fh[3] * h[3][at]) * e->scs[at];
    if (C == 3) {
        t[S] = 0;
        est_prefix3(t, J, e->clamp, gain, div, rec);
        return;
    }
    for (size_t j = 0; j < J; j++) {
        for (size_t c = 0, at = j * C; c < C; c++, at++)
            acc[c] += t[at];
        for (int c = 0; c < 3; c++) {
            double v = acc[C == 1 ? 0 : c];
            rec[j * 3 + c] = (e->clamp && v < 0 ? 0 : v) * gain / div;
        }
    }
    rec[J * 3] = 0;
}

/* e's textures, sizes, wraps and per-term scales (*ones: scales or 1) for
 * the first min(J, SB_EST_MAXJ) terms of f; SB_OK or SB_ERR_NOMEM. */
sb_result_t est_eval_setup(eval_t *e, const sb_factors_t *f, const double *scales, const sb_param_t *p, double **ones);
void est_eval_free(eval_t *e);

#endif
