/* Private: what estimate.c (pairs, the estimate) and estimate_weights.c
 * (term weights) share: the pairs' storage, the reconstruction as the
 * shader computes it, and the units of work on threads. */
#ifndef SEPBRDF_ESTIMATE_IMPL_H
#define SEPBRDF_ESTIMATE_IMPL_H

#include "sepbrdf/estimate.h"

#define PD 10   /* doubles per pair */
#define NB 960  /* histogram bins: 40 per decade over [1e-12, 1e12] */
#define MAXT 64 /* threads */
#define QC (SB_EST_Q_COUNT_ * 4)

struct sb_pairs {
    const sb_source_t *src;
    size_t rep, n, nrep; /* pairs per replicate, pairs, replicates */
    uint64_t seed;
    sb_pair_draw_fn draw; /* NULL: the mixture of estimate.h */
    const void *draw_user;
    double *d;            /* n x PD */
    unsigned char *known; /* n */
    double e0[4];         /* headline energy of the first replicates per channel (R, G, B, all) */
};

typedef struct eval {
    const sb_pairs_t *P;
    const sb_param_t *p;
    size_t J, C;
    const double **tex[2]; /* [side][j * C + c] */
    size_t tw[2], th[2];
    int wrap[2][2];
    const double *scale; /* J per-term factors */
    sb_form_t form;
    int headline_only; /* no per-pair histograms or maxima (p99, max_rel 0) */
    /* per replicate: num [J][QC], den [QC], neg measure [J], measure */
    double *num, *den, *neg, *meas;
    /* per thread: histograms [J][4][NB], maxima [J][4], |f~| maxima [J] */
    uint64_t *hist;
    double *maxr, *maxv;
} eval_t;

/* fn(user, unit, thread) for units first .. first + count - 1 on nt threads. */
void est_run_units(size_t first, size_t count, int nt, void (*fn)(void *, size_t, int), void *user);
/* Reconstructed RGB of every prefix at one pair: rec[j * 3 + c]; 0 outside. */
void est_reconstruct(const eval_t *e, const double *wi, const double *wo, double *rec);
/* e's textures, sizes, wraps and per-term scales (*ones: scales or 1) for
 * the first min(J, SB_EST_MAXJ) terms of f; SB_OK or SB_ERR_NOMEM. */
sb_result_t est_eval_setup(eval_t *e, const sb_factors_t *f, const double *scales, const sb_param_t *p, double **ones);
void est_eval_free(eval_t *e);

#endif
