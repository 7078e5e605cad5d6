/* Masked fit, part 2 (fit.c has the whole picture): the nested stages of
 * alternating least squares that add one term at a time (the sweeps are
 * fit_sweep.c's), on the valid cells gathered once per execute in both
 * orders by fit_cells.c. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "solve/fit_impl.h"

/* Squared error on valid cells of each prefix of the first ka terms:
 * e2[j] for the terms 0..j. */
static void prefix_errors(const sb_fit_t *f, const als_cells_t *cl, size_t ka, double *e2) {
    size_t m = f->m, n = f->n;
    for (size_t j = 0; j < ka; j++)
        e2[j] = 0;
    for (size_t c = 0; c < n; c++)
        for (size_t t = cl->cp[c]; t < cl->cp[c + 1]; t++) {
            size_t r = cl->cr[t];
            double d = cl->cv[t];
            for (size_t j = 0; j < ka; j++) {
                d -= f->P[r + j * m] * f->Q[c + j * n];
                e2[j] += d * d;
            }
        }
}

/* Whether stage ka refits its terms jointly: every stage up to
 * SB_JOINT_ALL terms, none beyond (the stages there add their term on the
 * residual, which keeps every prefix's error non-increasing).  A joint
 * sweep costs ka^2 per cell; the joint refits at 16, 32 and the last
 * stage that earlier versions ran were never kept on the default gold at
 * J = 32, GGX 0.1, Blinn-Phong, the Cornell and RGL tables at J = 16
 * (the same factors to the bit) and took half the time (J = 32: 5.1 ->
 * 2.1 s; Cornell J = 16: 45 -> 28 s); on explicit layouts, fitted to
 * convergence too, the same errors (gold iso J = 16, GGX 0.3 iso J = 12,
 * anisotropic GGX hd J = 12) or lower (Cornell hd J = 12 at 16 cells:
 * 22.3 % -> 19.9 %) at 40-50 % less time. */
static int joint_stage(size_t ka) { return ka > 1 && ka <= SB_JOINT_ALL; }

/* The staged ALS from the warm start in f->P, f->Q on the cells of X with
 * mask != 0 (nvalid of them); *err the last stage's error; *stretched 1
 * when the last stage kept a joint refit that made a shorter prefix more
 * than SB_PREFIX_SLACK times worse (not strict only); *converged 0
 * when the run that gave the last stage's kept result stopped at
 * max_iters.  f->tconv[j]: whether the run that last set term j did not
 * (a joint refit kept at stage ka sets terms 0..ka-1, a new term alone
 * only itself; terms never fitted, past --max-error, count as set), so
 * that a prefix written alone is known converged or not (H5 in
 * docs/measured.md: the last stage, cut away by the job's J, made every
 * fit "not converged").  SB_OK or SB_ERR_NOMEM. */
/* A run of the stages: what every stage reads, the copies a rejected
 * joint refit is restored from, and the accepted prefix errors. */
typedef struct als_run {
    sb_fit_t *f;
    als_cells_t *cl; /* f->cells */
    const sb_fit_opts_t *o;
    int strict, *total, *stretched;
    double norm2, *saveP, *saveQ;
    double acc[SB_ALS_MAX_K];
    als_resume_t *rs;
} als_run_t;

/* Step: the new term ka - 1 alone on the residual of the others: the error
 * can only go down (its first half-sweep is a least-squares step from the
 * warm start).  replay: the strict run's last stage computes what the
 * recorded one did (the same start and cells), taken from the record;
 * record: keep it there.  Returns the error. */
static double stage_new_term(als_run_t *ru, size_t ka, int replay, int record, int *c1) {
    sb_fit_t *f = ru->f;
    als_resume_t *rs = ru->rs;
    size_t m = f->m, n = f->n, k = f->k;
    double err;
    if (replay) {
        memcpy(f->P, rs->P1, m * k * sizeof *f->P);
        memcpy(f->Q, rs->Q1, n * k * sizeof *f->Q);
        err = rs->err1, *c1 = rs->c1;
    } else {
        err = fit_als_until(f, ru->cl, ka - 1, ka, ru->o, sqrt(ru->norm2), ru->total, c1);
    }
    if (record) {
        memcpy(rs->P1, f->P, m * k * sizeof *f->P);
        memcpy(rs->Q1, f->Q, n * k * sizeof *f->Q);
        rs->err1 = err, rs->c1 = *c1;
    }
    return err;
}

/* Step: then all ka jointly: a joint refit may trade the prefixes'
 * accuracy for cancelling terms that are large outside the domain, which
 * also spoil interpolated lookups near its edge.  Kept only if no shorter
 * prefix gets more than SB_PREFIX_SLACK times worse (at the last stage: no
 * worse than no term at all); strict: and the prefixes' errors stay
 * non-increasing.  Returns 1 when kept (*err is then the joint error),
 * else 0 with the terms restored. */
static int stage_joint(als_run_t *ru, size_t ka, int replay, int record, double *err, int *cj) {
    sb_fit_t *f = ru->f;
    als_resume_t *rs = ru->rs;
    size_t m = f->m, n = f->n, k = f->k;
    double e2[SB_ALS_MAX_K], *acc = ru->acc, norm2 = ru->norm2;
    memcpy(ru->saveP, f->P, m * ka * sizeof *ru->saveP);
    memcpy(ru->saveQ, f->Q, n * ka * sizeof *ru->saveQ);
    double ej;
    if (replay) {
        memcpy(f->P, rs->Pj, m * k * sizeof *f->P);
        memcpy(f->Q, rs->Qj, n * k * sizeof *f->Q);
        memcpy(e2, rs->e2, sizeof e2);
        ej = rs->errj, *cj = rs->cj;
    } else {
        ej = fit_als_until(f, ru->cl, 0, ka, ru->o, sqrt(norm2), ru->total, cj);
        prefix_errors(f, ru->cl, ka, e2);
    }
    if (record) {
        memcpy(rs->Pj, f->P, m * k * sizeof *f->P);
        memcpy(rs->Qj, f->Q, n * k * sizeof *f->Q);
        memcpy(rs->e2, e2, sizeof e2);
        rs->errj = ej, rs->cj = *cj, rs->last = 1;
    }
    int keep = ej <= *err;
    double slack = ka == k && !ru->strict ? INFINITY : SB_PREFIX_SLACK;
    int within = 1, monotone = 1;
    for (size_t j = 0; keep && j + 1 < ka; j++) {
        keep = sqrt(e2[j]) <= fmin(acc[j] * slack, sqrt(norm2)) && (!ru->strict || e2[j + 1] <= e2[j]);
        within &= sqrt(e2[j]) <= acc[j] * SB_PREFIX_SLACK;
        monotone &= e2[j + 1] <= e2[j];
    }
    if (keep && !monotone && rs && rs->save && ka < k) rs->same = 0; /* strict would not keep it */
    if (keep && !within) *ru->stretched = 1;
    if (keep) {
        *err = ej;
        for (size_t j = 0; j + 1 < ka; j++)
            acc[j] = fmax(acc[j], sqrt(e2[j]));
    } else {
        memcpy(f->P, ru->saveP, m * ka * sizeof *ru->saveP);
        memcpy(f->Q, ru->saveQ, n * ka * sizeof *ru->saveQ);
    }
    return keep;
}

sb_result_t fit_als_stages(sb_fit_t *f, const double *As, size_t lda, const unsigned char *mask, size_t nvalid,
                           const sb_fit_opts_t *o, int strict, double norm2, int *total, int *converged, double *err,
                           int *stretched, als_resume_t *rs) {
    size_t m = f->m, n = f->n, k = f->k;
    /* Nested stages: terms are added one at a time and the first ka
     * are refitted jointly, so every prefix of the result is itself a
     * masked fit of its rank (the terms are not re-orthogonalised over
     * the whole matrix: that would mix in the unconstrained values the
     * fit implies outside the domain). */
    als_run_t ru = {.f = f, .o = o, .strict = strict, .total = total, .stretched = stretched, .norm2 = norm2, .rs = rs};
    ru.saveP = malloc(m * k * sizeof *ru.saveP);
    ru.saveQ = malloc(n * k * sizeof *ru.saveQ);
    if (!f->cells) f->cells = calloc(1, sizeof *f->cells);
    ru.cl = f->cells;
    if (!ru.saveP || !ru.saveQ || !ru.cl || fit_cells_build(f->ctx, ru.cl, As, m, n, lda, mask, nvalid) != 0) {
        int saved = ru.saveP && ru.saveQ && ru.cl; /* else fit_cells_build failed and named its bytes */
        free(ru.saveP);
        free(ru.saveQ);
        if (saved) return SB_ERR_NOMEM;
        return sb_error(f->ctx, SB_ERR_NOMEM, "fit: cannot allocate %zu bytes", (m + n) * k * sizeof(double));
    }
    size_t ka0 = 1;
    if (rs && rs->resume) { /* the non-strict run's state before its last stage */
        memcpy(f->P, rs->P, m * k * sizeof *f->P);
        memcpy(f->Q, rs->Q, n * k * sizeof *f->Q);
        memcpy(ru.acc, rs->acc, sizeof ru.acc);
        *err = rs->err;
        *converged = rs->converged;
        memcpy(f->tconv, rs->tconv, sizeof f->tconv);
        ka0 = k;
    } else if (f->warm) { /* a warm start (fit.h init_*): the last stage alone, from the start's prefixes */
        double e2[SB_ALS_MAX_K];
        prefix_errors(f, ru.cl, k, e2);
        for (size_t j = 0; j < k; j++)
            ru.acc[j] = sqrt(e2[j]);
        memset(f->tconv, 1, sizeof f->tconv);
        *err = ru.acc[k - 1];
        *converged = 1;
        ka0 = k;
    } else {
        memset(f->tconv, 1, sizeof f->tconv);
    }
    if (rs && rs->save) rs->same = 1, rs->valid = 0, rs->last = 0;
    for (size_t ka = ka0; ka <= k; ka++) {
        if (rs && rs->save && ka == k && k > 1) {
            memcpy(rs->P, f->P, m * k * sizeof *f->P);
            memcpy(rs->Q, f->Q, n * k * sizeof *f->Q);
            memcpy(rs->acc, ru.acc, sizeof ru.acc);
            rs->err = *err;
            rs->converged = *converged;
            memcpy(rs->tconv, f->tconv, sizeof rs->tconv);
            rs->valid = 1;
        }
        int c1 = 1, cj = 1, keep = 0;
        int replay = rs && rs->resume && rs->last && ka == k, record = rs && rs->save && ka == k && k > 1;
        *err = stage_new_term(&ru, ka, replay, record, &c1);
        if (joint_stage(ka)) keep = stage_joint(&ru, ka, replay, record, err, &cj);
        ru.acc[ka - 1] = *err;
        *converged = keep ? cj : c1;
        memset(f->tconv + (keep ? 0 : ka - 1), *converged, keep ? ka : 1);
        if (o->target > 0 && *err <= o->target * sqrt(norm2)) { /* --max-error reached: stop adding terms */
            memset(f->P + ka * m, 0, (k - ka) * m * sizeof *f->P);
            memset(f->Q + ka * n, 0, (k - ka) * n * sizeof *f->Q);
            break;
        }
    }
    free(ru.saveP);
    free(ru.saveQ); /* the cells stay for the next run (sb_fit_destroy frees them) */
    return SB_OK;
}

/* Squared errors of the prefixes on the valid cells (mask) of X: e2[j]
 * after the terms 0..j. */
void fit_valid_prefix_e2(const sb_fit_t *f, const double *X, size_t lda, const unsigned char *mask, double *e2) {
    size_t m = f->m, n = f->n, k = f->k;
    for (size_t j = 0; j < k; j++)
        e2[j] = 0;
    for (size_t c = 0; c < n; c++)
        for (size_t r = 0; r < m; r++) {
            if (!mask[r + c * lda]) continue;
            double d = X[r + c * lda];
            for (size_t j = 0; j < k; j++) {
                d -= f->P[r + j * m] * f->Q[c + j * n];
                e2[j] += d * d;
            }
        }
}

size_t fit_conv_terms(const sb_fit_t *f) {
    size_t j = 0;
    while (j < f->k && j < SB_ALS_MAX_K && f->tconv[j])
        j++;
    return j;
}

int fit_e2_monotone(const double *e2, size_t k) {
    for (size_t j = 1; j < k; j++)
        if (e2[j] > e2[j - 1]) return 0;
    return 1;
}

int fit_prefixes_monotone(const sb_fit_t *f, const double *X, size_t lda, const unsigned char *mask) {
    double e2[SB_ALS_MAX_K];
    fit_valid_prefix_e2(f, X, lda, mask, e2);
    return fit_e2_monotone(e2, f->k);
}
