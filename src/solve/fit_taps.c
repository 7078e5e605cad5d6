/* Masked fit, part 3 (fit.c has the whole picture): what bilinear taps
 * of in-domain pairs reach outside the data is kept bounded by the data
 * around it, and the ALS part of a fit puts the stages and these
 * constraints together. */
#include <assert.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sepbrdf/param.h"
#include "solve/fit_impl.h"

/* Texels within two steps of texel i (x +- 2, y +- 2: the cell holding an
 * in-domain pair may be one away from a valid centre, its taps one more;
 * CLAMP axes stop at the edge, REPEAT axes wrap), i included, each once. */
static size_t neighbours(const size_t wh[2], const int wrap[2], size_t i, size_t out[25]) {
    size_t w = wh[0], h = wh[1], k = 0;
    long x = (long)(i % w), y = (long)(i / w);
    for (long dy = -2; dy <= 2; dy++)
        for (long dx = -2; dx <= 2; dx++) {
            long xs = x + dx, ys = y + dy;
            if (wrap[0] == SB_WRAP_REPEAT) xs = (xs + (long)w) % (long)w;
            if (wrap[1] == SB_WRAP_REPEAT) ys = (ys + (long)h) % (long)h;
            if (xs < 0 || ys < 0 || xs >= (long)w || ys >= (long)h) continue;
            size_t at = (size_t)ys * w + (size_t)xs, dup = 0;
            for (size_t q = 0; q < k; q++)
                dup |= out[q] == at;
            if (!dup) out[k++] = at;
        }
    return k;
}

/* Cells that bilinear taps of in-domain pairs reach, kept bounded by the
 * data around them: an invalid cell (r, c) with valid cells among rows N(r)
 * x columns N(c) (lo..hi their values in x) whose fitted value
 * sum_j P_rj Q_cj lies outside [lo - d, hi + d], d = hi - lo +
 * max(|lo|, |hi|) / 2, joins the data (ext = 2) with the value clamped
 * into [lo, hi]; cells already joined keep their targets.  (Joining every
 * such cell, or pulling it to its neighbours' mean, fits the data worse
 * and breaks exact recovery of low-rank data with holes.)  Per column the
 * column neighbours are reduced first, then the row neighbours: 50 reads
 * per cell.  Returns the cells added, or (size_t)-1 without memory. */
size_t fit_constrain_taps(const sb_fit_opts_t *o, const sb_fit_t *f, double *x, unsigned char *ext) {
    size_t m = f->m, n = f->n, k = f->k, added = 0;
    double *lo1 = malloc(m * sizeof *lo1), *hi1 = malloc(m * sizeof *hi1);
    size_t *nrs = malloc(m * 26 * sizeof *nrs); /* row r's neighbours: count, then the list */
    if (!lo1 || !hi1 || !nrs) {
        free(lo1);
        free(hi1);
        free(nrs);
        return (size_t)-1;
    }
    for (size_t r = 0; r < m; r++)
        nrs[r * 26] = neighbours(o->tex[0], o->wrap[0], r, nrs + r * 26 + 1);
    /* the minima and maxima below are fmin / fmax written inline (the
     * library calls were a tenth of the default run's fit); the values
     * read are valid data, never NaN */
    for (size_t c = 0; c < n; c++) {
        size_t nc[25], kc = neighbours(o->tex[1], o->wrap[1], c, nc);
        for (size_t r = 0; r < m; r++) {
            double l1 = INFINITY, h1 = -INFINITY;
            for (size_t q = 0; q < kc; q++)
                if (ext[r + nc[q] * m] == 1) {
                    double a = x[r + nc[q] * m];
                    l1 = a < l1 ? a : l1;
                    h1 = a > h1 ? a : h1;
                }
            lo1[r] = l1;
            hi1[r] = h1;
        }
        for (size_t r = 0; r < m; r++) {
            if (ext[r + c * m]) continue;
            const size_t kr = nrs[r * 26], *nr = nrs + r * 26 + 1;
            double lo = INFINITY, hi = -INFINITY, v = 0;
            for (size_t q = 0; q < kr; q++) {
                lo = lo1[nr[q]] < lo ? lo1[nr[q]] : lo;
                hi = hi1[nr[q]] > hi ? hi1[nr[q]] : hi;
            }
            if (!(lo <= hi)) continue;
            for (size_t j = 0; j < k; j++)
                v += f->P[r + j * m] * f->Q[c + j * n];
            double d = hi - lo + 0.5 * fmax(fabs(lo), fabs(hi));
            if (v >= lo - d && v <= hi + d) continue;
            x[r + c * m] = fmin(fmax(v, lo), hi);
            ext[r + c * m] = 2; /* data from now on, not a neighbour's source */
            added++;
        }
    }
    free(lo1);
    free(hi1);
    free(nrs);
    return added;
}

/* For each cell that is not data (ext 0), the range [lo, hi] of the data
 * among rows N(r) x columns N(c) (what taps sharing the cell read, as
 * fit_constrain_taps), lo = INFINITY where none; lo, hi m x n.  Returns
 * 0, or -1 without memory. */
int fit_taps_range(const sb_fit_opts_t *o, size_t m, size_t n, const double *x, const unsigned char *ext, double *lo,
                   double *hi) {
    size_t *nrs = malloc(m * 26 * sizeof *nrs);
    double *l1 = malloc(2 * m * sizeof *l1), *h1 = l1 + m;
    if (!nrs || !l1) {
        free(nrs);
        free(l1);
        return -1;
    }
    for (size_t r = 0; r < m; r++)
        nrs[r * 26] = neighbours(o->tex[0], o->wrap[0], r, nrs + r * 26 + 1);
    for (size_t c = 0; c < n; c++) {
        size_t nc[25], kc = neighbours(o->tex[1], o->wrap[1], c, nc);
        for (size_t r = 0; r < m; r++) {
            l1[r] = INFINITY;
            h1[r] = -INFINITY;
            for (size_t q = 0; q < kc; q++)
                if (ext[r + nc[q] * m] == 1) {
                    l1[r] = fmin(l1[r], x[r + nc[q] * m]);
                    h1[r] = fmax(h1[r], x[r + nc[q] * m]);
                }
        }
        for (size_t r = 0; r < m; r++) {
            double a = INFINITY, b = -INFINITY;
            for (size_t q = 0; !ext[r + c * m] && q < nrs[r * 26]; q++) {
                a = fmin(a, l1[nrs[r * 26 + 1 + q]]);
                b = fmax(b, h1[nrs[r * 26 + 1 + q]]);
            }
            lo[r + c * m] = a;
            hi[r + c * m] = b;
        }
    }
    free(nrs);
    free(l1);
    return 0;
}

/* Whether the fit costs the valid cells (mask) more than SB_TAPS_COST
 * times the squared error `before` the taps' constraints. */
static int taps_cost(const sb_fit_t *f, const double *As, size_t lda, const unsigned char *mask, double before,
                     double norm2) {
    double e2[SB_ALS_MAX_K];
    fit_valid_prefix_e2(f, As, lda, mask, e2);
    return sqrt(e2[f->k - 1]) > SB_TAPS_COST * sqrt(before) + 1e-12 * sqrt(norm2);
}

/* Step, after a pass with taps: the taps reaching unconstrained cells that
 * overshoot are constrained (ext, nvalid cells so far) and the stages run
 * again from the fit found (twice at most; warm, each stage stops after a
 * few sweeps).  A round whose fit already costs the valid cells more than
 * SB_TAPS_COST ends the rounds: its constraints are dropped below, and a
 * next round adds constraints (the default gold at J = 4 and 32, GGX 0.1
 * and 0.3, Blinn-Phong, the Cornell, RGL and ALTA tables: the same factors
 * without it; in the default run it was a third of the fit's time).  Data
 * that the rank-k structure extends exactly (or nearly) are their own best
 * extrapolation: a constraint that costs the valid cells more than
 * SB_TAPS_COST in error is dropped (the pass's terms, kept in P1, Q1,
 * restored). */
static sb_result_t taps_rounds(sb_fit_t *f, const double *As, size_t lda, const unsigned char *mask, unsigned char *ext,
                               size_t nvalid, const sb_fit_opts_t *o, int strict, double norm2, int *total,
                               int *converged, double *err, int *stretched, double *P1, double *Q1) {
    size_t m = f->m, n = f->n, k = f->k;
    double e2[SB_ALS_MAX_K];
    fit_valid_prefix_e2(f, As, lda, mask, e2);
    double before = e2[k - 1];
    memcpy(P1, f->P, m * k * sizeof *P1);
    memcpy(Q1, f->Q, n * k * sizeof *Q1);
    size_t constrained = 0;
    sb_result_t r = SB_OK;
    for (int round = 0; r == SB_OK && round < 2; round++) {
        size_t added = fit_constrain_taps(o, f, f->x, ext); /* taps: As is f->x */
        if (added == (size_t)-1) r = SB_ERR_NOMEM;
        if (added == 0 || r != SB_OK) break;
        nvalid += added;
        constrained += added;
        r = fit_als_stages(f, As, lda, ext, nvalid, o, strict, norm2, total, converged, err, stretched, NULL);
        if (r == SB_OK && taps_cost(f, As, lda, mask, before, norm2)) break;
    }
    if (r == SB_OK && constrained && taps_cost(f, As, lda, mask, before, norm2)) {
        memcpy(f->P, P1, m * k * sizeof *P1);
        memcpy(f->Q, Q1, n * k * sizeof *Q1);
    }
    return r;
}

/* The ALS part of a fit from the warm start in f->P, f->Q: the stages
 * (joint refits kept under SB_PREFIX_SLACK), the taps' constraints
 * (fit_constrain_taps, twice at most, warm), and when the prefixes' errors on
 * the valid cells then rise anywhere, or the last stage made a prefix more
 * than SB_PREFIX_SLACK times worse, all of it again from the same start
 * with strict stages (a joint refit kept only if the prefixes' errors stay
 * non-increasing), so that every prefix is a fit no worse than the shorter
 * ones.  SB_OK or SB_ERR_NOMEM. */
sb_result_t fit_als(sb_fit_t *f, const double *As, size_t lda, const unsigned char *mask, size_t nvalid0,
                    const sb_fit_opts_t *o, double norm2, int *total, int *converged, double *err) {
    size_t m = f->m, n = f->n, k = f->k;
    int taps = lda == m && o->tex[0][0] * o->tex[0][1] == m && o->tex[1][0] * o->tex[1][1] == n;
    unsigned char *ext = taps ? malloc(m * n) : NULL;
    double *P0 = malloc(m * k * sizeof *P0), *Q0 = malloc(n * k * sizeof *Q0);
    double *P1 = malloc(m * k * sizeof *P1), *Q1 = malloc(n * k * sizeof *Q1);
    size_t pb = m * k * sizeof(double), qb = n * k * sizeof(double);
    als_resume_t rs = {
        .P = malloc(pb), .Q = malloc(qb), .P1 = malloc(pb), .Q1 = malloc(qb), .Pj = malloc(pb), .Qj = malloc(qb)};
    sb_result_t r = SB_OK;
    if ((taps && !ext) || !P0 || !Q0 || !P1 || !Q1 || !rs.P || !rs.Q || !rs.P1 || !rs.Q1 || !rs.Pj || !rs.Qj)
        r = sb_error(f->ctx, SB_ERR_NOMEM, "fit: cannot allocate %zu bytes", m * n + 5 * (pb + qb));
    if (r == SB_OK) {
        memcpy(P0, f->P, m * k * sizeof *P0);
        memcpy(Q0, f->Q, n * k * sizeof *Q0);
    }
    for (int strict = 0; strict < 2 && r == SB_OK; strict++) {
        size_t nvalid = nvalid0;
        int stretched = 0;
        memcpy(f->P, P0, m * k * sizeof *P0);
        memcpy(f->Q, Q0, n * k * sizeof *Q0);
        if (ext)
            for (size_t c = 0; c < n; c++)
                for (size_t i = 0; i < m; i++)
                    ext[i + c * m] = mask[i + c * lda] ? 1 : 0;
        /* the strict pass resumes from the first one's state before its
         * last stage where every decision before was the strict one (the
         * same result, without doing the stages again) */
        rs.save = !strict;
        rs.resume = strict && rs.valid && rs.same;
        r = fit_als_stages(f, As, lda, mask, nvalid, o, strict, norm2, total, converged, err, &stretched, &rs);
        /* a stretched pass is redone strictly whatever its taps give: go
         * there at once (the result is the same, a third of the cost) */
        if (r == SB_OK && stretched && !strict) continue;
        /* taps reaching unconstrained cells that overshoot: constrain
         * them and run the stages again from the fit found (twice at
         * most; warm, each stage stops after a few sweeps) */
        if (r == SB_OK && taps)
            r = taps_rounds(f, As, lda, mask, ext, nvalid, o, strict, norm2, total, converged, err, &stretched, P1, Q1);
        if (r != SB_OK || (!stretched && fit_prefixes_monotone(f, As, lda, mask))) break;
    }
    free(ext);
    free(rs.P);
    free(rs.Q);
    free(rs.P1);
    free(rs.Q1);
    free(rs.Pj);
    free(rs.Qj);
    free(P0);
    free(Q0);
    free(P1);
    free(Q1);
    return r;
}
