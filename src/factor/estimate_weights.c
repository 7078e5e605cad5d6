/* Term weights of the error estimator (estimate.h
 * sb_estimate_term_weights): per term and channel, the weight that keeps
 * the headline on the estimator's pairs from rising with J'. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "factor/estimate_impl.h"
#include "util/internal.h"

/* Sums of one replicate for the term weights: per factor channel c (C of
 * them), the lower triangle of G_c[i][j] = sum q t_ic t_jc and b_c[j] = sum
 * q f t_jc, with t_jc the term's contribution to the shader's output (the
 * difference of consecutive prefixes) and q the headline's measure. */
typedef struct tw_sums {
    const eval_t *e;
    size_t first;
    double *sums; /* per replicate of the block: C (J(J+1)/2 + J) */
} tw_sums_t;

static size_t tw_len(size_t J, size_t C) { return C * (J * (J + 1) / 2 + J); }

static void tw_unit(void *user, size_t k, int t) {
    (void)t;
    const tw_sums_t *w = user;
    const eval_t *e = w->e;
    const sb_pairs_t *P = e->P;
    size_t J = e->J, C = e->C, L = J * (J + 1) / 2;
    double *s = w->sums + (k - w->first) * tw_len(J, C), rec[EST_REC_LEN], tj[SB_EST_MAXJ];
    memset(s, 0, tw_len(J, C) * sizeof *s);
    for (size_t i = k * P->rep; i < (k + 1) * P->rep; i++) {
        if (!P->known[i]) continue;
        const double *d = P->d + i * PD, *f = d + 7;
        double q = d[6] * d[2] * d[2];
        est_reconstruct(e, i, rec);
        for (int c = 0; c < 3; c++) {
            size_t fc = C == 1 ? 0 : (size_t)c;
            double *G = s + fc * (L + J), *b = G + L;
            for (size_t j = 0; j < J; j++)
                tj[j] = rec[j * 3 + c] - (j ? rec[(j - 1) * 3 + c] : 0);
            for (size_t j = 0, at = 0; j < J; j++) {
                b[j] += q * f[c] * tj[j];
                for (size_t i2 = 0; i2 <= j; i2++, at++)
                    G[at] += q * tj[i2] * tj[j];
            }
        }
    }
}

/* In term order, given w_0..j-1: w_j = 1 when the term lowers the
 * channel's error sum, else the w in [0, 1] that minimises it (0: the term
 * is not used, the prefix keeps the shorter one's error); terms j0..j1-1
 * from the sums tot (C blocks of G's lower triangle and b). */
static void weights_from(const double *tot, size_t J, size_t C, size_t j0, size_t j1, double *w) {
    size_t L = J * (J + 1) / 2;
    for (size_t c = 0; c < C; c++) {
        const double *G = tot + c * (L + J), *b = G + L;
        for (size_t j = j0; j < j1; j++) {
            const double *Gj = G + j * (j + 1) / 2; /* row j: G[j][0..j] */
            double num = b[j];
            for (size_t i = 0; i < j; i++)
                num -= w[i * C + c] * Gj[i];
            /* the error sum changes by G_jj w^2 - 2 num w: kept at w = 1
             * unless that raises it, then the least-squares w */
            w[j * C + c] = Gj[j] - 2 * num > 0 ? fmin(fmax(num / Gj[j], 0), 1) : 1;
        }
    }
}

/* The replicates term j's weight comes from: reps[j] (NULL: all), at most
 * those there are. */
static size_t reps_of(const sb_pairs_t *P, const size_t *reps, size_t j) {
    return reps && reps[j] < P->nrep ? reps[j] : P->nrep;
}

sb_result_t sb_estimate_term_weights(sb_context_t *ctx, const sb_pairs_t *pairs, const sb_factors_t *f,
                                     const double *scales, const sb_param_t *p, sb_form_t form, const size_t *reps,
                                     double *w) {
    if (!pairs || !f || !p || !w) return sb_error(ctx, SB_ERR_ARG, "term weights: missing argument");
    if ((unsigned)form >= SB_FORM_COUNT_) return sb_error(ctx, SB_ERR_ARG, "term weights: unknown form %d", (int)form);
    eval_t e = {.P = pairs, .p = p, .form = form};
    double *ones = NULL;
    if (est_eval_setup(&e, f, scales, p, &ones) != SB_OK)
        return sb_error(ctx, SB_ERR_NOMEM, "term weights: out of memory");
    size_t J = e.J, C = e.C, len = tw_len(J, C), block = 8, nrep = J ? reps_of(pairs, reps, J - 1) : 0;
    int ordered = 1;
    for (size_t j = 0; j < J; j++)
        ordered &= reps_of(pairs, reps, j) >= (j ? reps_of(pairs, reps, j - 1) : 1);
    if (!ordered) {
        free(ones);
        est_eval_free(&e);
        return sb_error(ctx, SB_ERR_ARG,
                        "term weights: replicate counts must be at least 1 and non-decreasing in the term");
    }
    int nt = sb_thread_count(0);
    if (nt > MAXT) nt = MAXT;
    double *tot = sb_calloc(ctx, len, sizeof *tot, "term weights");
    tw_sums_t ts = {&e, 0, sb_alloc(ctx, block * len, sizeof(double), "term weights")};
    e.co = tot && ts.sums ? est_coords_acquire(pairs, p, nrep * pairs->rep, &e.co_ready) : NULL;
    if (!tot || !ts.sums) {
        free(tot);
        free(ts.sums);
        free(ones);
        est_eval_free(&e);
        return SB_ERR_NOMEM;
    }
    /* blocks of replicates, added in replicate order (the same to the bit
     * on any thread count), cut where a term's count is reached: then its
     * weights */
    size_t j = 0;
    for (size_t k0 = 0; k0 < nrep;) {
        size_t end = k0 + block < reps_of(pairs, reps, j) ? k0 + block : reps_of(pairs, reps, j);
        ts.first = k0;
        est_run_units(k0, end - k0, nt, tw_unit, &ts);
        for (size_t k = 0; k < end - k0; k++)
            for (size_t i = 0; i < len; i++)
                tot[i] += ts.sums[k * len + i];
        k0 = end;
        size_t j1 = j;
        while (j1 < J && reps_of(pairs, reps, j1) == k0)
            j1++;
        weights_from(tot, J, C, j, j1, w);
        j = j1;
    }
    for (size_t i = J * C; i < sb_factors_terms(f) * C; i++)
        w[i] = 1; /* beyond SB_EST_MAXJ */
    est_coords_release(pairs, e.co, p, e.co_ready ? 0 : nrep * pairs->rep);
    free(tot);
    free(ts.sums);
    free(ones);
    est_eval_free(&e);
    return SB_OK;
}
