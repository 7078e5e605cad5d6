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
    double *s = w->sums + (k - w->first) * tw_len(J, C), rec[SB_EST_MAXJ * 3], tj[SB_EST_MAXJ];
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

sb_result_t sb_estimate_term_weights(sb_context_t *ctx, const sb_pairs_t *pairs, const sb_factors_t *f,
                                     const double *scales, const sb_param_t *p, sb_form_t form, double *w) {
    if (!pairs || !f || !p || !w) return sb_error(ctx, SB_ERR_ARG, "term weights: missing argument");
    if ((unsigned)form >= SB_FORM_COUNT_) return sb_error(ctx, SB_ERR_ARG, "term weights: unknown form %d", (int)form);
    eval_t e = {.P = pairs, .p = p, .form = form};
    double *ones = NULL;
    if (est_eval_setup(&e, f, scales, p, &ones) != SB_OK)
        return sb_error(ctx, SB_ERR_NOMEM, "term weights: out of memory");
    size_t J = e.J, C = e.C, L = J * (J + 1) / 2, len = tw_len(J, C), block = 8;
    int nt = sb_thread_count(0);
    if (nt > MAXT) nt = MAXT;
    double *tot = sb_calloc(ctx, len, sizeof *tot, "term weights");
    tw_sums_t ts = {&e, 0, sb_alloc(ctx, block * len, sizeof(double), "term weights")};
    e.co = tot && ts.sums ? est_coords_acquire(pairs, p, pairs->n, &e.co_ready) : NULL;
    if (!tot || !ts.sums) {
        free(tot);
        free(ts.sums);
        free(ones);
        est_eval_free(&e);
        return SB_ERR_NOMEM;
    }
    /* blocks of replicates, added in replicate order: the same to the bit
     * on any thread count */
    for (size_t k0 = 0; k0 < pairs->nrep; k0 += block) {
        size_t nk = pairs->nrep - k0 < block ? pairs->nrep - k0 : block;
        ts.first = k0;
        est_run_units(k0, nk, nt, tw_unit, &ts);
        for (size_t k = 0; k < nk; k++)
            for (size_t i = 0; i < len; i++)
                tot[i] += ts.sums[k * len + i];
    }
    /* in term order, given w_0..j-1: w_j = 1 when the term lowers the
     * channel's error sum, else the w in [0, 1] that minimises it (0: the
     * term is not used, the prefix keeps the shorter one's error) */
    size_t Jall = sb_factors_terms(f);
    for (size_t c = 0; c < C; c++) {
        const double *G = tot + c * (L + J), *b = G + L;
        for (size_t j = 0; j < Jall; j++) {
            double *wj = &w[j * C + c];
            if (j >= J) {
                *wj = 1;
                continue;
            }
            const double *Gj = G + j * (j + 1) / 2; /* row j: G[j][0..j] */
            double num = b[j];
            for (size_t i = 0; i < j; i++)
                num -= w[i * C + c] * Gj[i];
            /* the error sum changes by G_jj w^2 - 2 num w: kept at w = 1
             * unless that raises it, then the least-squares w */
            *wj = Gj[j] - 2 * num > 0 ? fmin(fmax(num / Gj[j], 0), 1) : 1;
        }
    }
    est_coords_release(pairs, e.co, p, e.co_ready ? 0 : pairs->n);
    free(tot);
    free(ts.sums);
    free(ones);
    est_eval_free(&e);
    return SB_OK;
}
