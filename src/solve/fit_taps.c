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

/* An invalid cell (ext 0) with valid cells among the rows and columns
 * its taps share, and their range [lo, hi]. */
typedef struct taps_cell {
    size_t at; /* r + c m */
    double lo, hi;
} taps_cell_t;

/* The texel coordinates within two steps of x on an axis of w texels
 * (CLAMP stops at the edge, REPEAT wraps; a coordinate may repeat there,
 * which no minimum or maximum minds). */
static size_t window(size_t w, int wrap, long x, long out[5]) {
    size_t k = 0;
    for (long d = -2; d <= 2; d++) {
        long xs = x + d;
        if (wrap == SB_WRAP_REPEAT) xs = (xs % (long)w + (long)w) % (long)w;
        if (xs >= 0 && xs < (long)w) out[k++] = xs;
    }
    return k;
}

/* Step: hl, hh (m x n) the range of the data (ext 1) of each row among
 * the columns in the same texel row of the column texture within two
 * steps along it (INFINITY, -INFINITY where none): the first half of the
 * 5 x 5 window, which is the product of a window along each axis. */
static void taps_along(const sb_fit_opts_t *o, size_t m, size_t n, const double *x, const unsigned char *ext,
                       double *hl, double *hh) {
    size_t w = o->tex[1][0];
    for (size_t c = 0; c < n; c++) {
        long xs[5];
        size_t k = window(w, o->wrap[1][0], (long)(c % w), xs), y0 = c - c % w;
        for (size_t r = 0; r < m; r++) {
            double a = INFINITY, b = -INFINITY;
            for (size_t q = 0; q < k; q++) {
                size_t at = r + (y0 + (size_t)xs[q]) * m;
                if (ext[at] != 1) continue;
                a = x[at] < a ? x[at] : a;
                b = x[at] > b ? x[at] : b;
            }
            hl[r + c * m] = a;
            hh[r + c * m] = b;
        }
    }
}

/* For each cell that is not data (ext 0), the range [lo, hi] of the data
 * (ext 1) among rows N(r) x columns N(c) (what taps sharing the cell
 * read): into the m x n arrays lo, hi where given (lo = INFINITY where
 * none, and at data), and where a range exists into the list *cells (*nc
 * of them; realloc'd) where given.  Per column the column neighbours are
 * reduced first, separably (along the texel row, then across: 10 reads a
 * cell where the 25 texels of the window took 25), then the row
 * neighbours.  The minima and maxima are written inline (fmin / fmax
 * library calls were a tenth of the default run's fit); the values read
 * are data, never NaN.  Returns 0, or -1 without memory. */
static int taps_scan(const sb_fit_opts_t *o, size_t m, size_t n, const double *x, const unsigned char *ext, double *lo,
                     double *hi, taps_cell_t **cells, size_t *nc) {
    size_t *nrs = malloc(m * 26 * sizeof *nrs), cap = 0; /* row r's neighbours: count, then the list */
    double *l1 = malloc(2 * m * sizeof *l1), *h1 = l1 ? l1 + m : NULL;
    double *hl = malloc(2 * m * n * sizeof *hl), *hh = hl ? hl + m * n : NULL;
    size_t w = o->tex[1][0], h = o->tex[1][1];
    int ok = nrs && l1 && hl;
    for (size_t r = 0; ok && r < m; r++)
        nrs[r * 26] = neighbours(o->tex[0], o->wrap[0], r, nrs + r * 26 + 1);
    if (ok) taps_along(o, m, n, x, ext, hl, hh);
    for (size_t c = 0; ok && c < n; c++) {
        long ys[5];
        size_t ky = window(h, o->wrap[1][1], (long)(c / w), ys), xc = c % w;
        for (size_t r = 0; r < m; r++) {
            double a1 = INFINITY, b1 = -INFINITY;
            for (size_t q = 0; q < ky; q++) {
                size_t at = r + (xc + (size_t)ys[q] * w) * m;
                a1 = hl[at] < a1 ? hl[at] : a1;
                b1 = hh[at] > b1 ? hh[at] : b1;
            }
            l1[r] = a1;
            h1[r] = b1;
        }
        for (size_t r = 0; r < m; r++) {
            double a = INFINITY, b = -INFINITY;
            const size_t kr = ext[r + c * m] ? 0 : nrs[r * 26], *nr = nrs + r * 26 + 1;
            for (size_t q = 0; q < kr; q++) {
                a = l1[nr[q]] < a ? l1[nr[q]] : a;
                b = h1[nr[q]] > b ? h1[nr[q]] : b;
            }
            if (lo) lo[r + c * m] = a, hi[r + c * m] = b;
            if (!cells || !(a <= b)) continue;
            if (*nc == cap) {
                taps_cell_t *g = realloc(*cells, (cap = cap ? 2 * cap : 256) * sizeof *g);
                if (!g) {
                    ok = 0;
                    break;
                }
                *cells = g;
            }
            (*cells)[(*nc)++] = (taps_cell_t){r + c * m, a, b};
        }
    }
    free(nrs);
    free(l1);
    free(hl);
    return ok ? 0 : -1;
}

int fit_taps_range(const sb_fit_opts_t *o, size_t m, size_t n, const double *x, const unsigned char *ext, double *lo,
                   double *hi) {
    return taps_scan(o, m, n, x, ext, lo, hi, NULL, NULL);
}

/* Cells that bilinear taps of in-domain pairs reach, kept bounded by the
 * data around them: an invalid cell (r, c) of the list (its range [lo,
 * hi] of data, taps_scan) whose fitted value sum_j P_rj Q_cj lies outside
 * [lo - d, hi + d], d = hi - lo + max(|lo|, |hi|) / 2, joins the data
 * (ext = 2) with the value clamped into [lo, hi]; cells already joined
 * keep their targets.  (Joining every such cell, or pulling it to its
 * neighbours' mean, fits the data worse and breaks exact recovery of
 * low-rank data with holes.)  Returns the cells added. */
static size_t constrain_taps(const sb_fit_t *f, const taps_cell_t *cells, size_t nc, double *x, unsigned char *ext) {
    size_t m = f->m, n = f->n, k = f->k, added = 0;
    for (size_t i = 0; i < nc; i++) {
        size_t at = cells[i].at, r = at % m, c = at / m;
        if (ext[at]) continue;
        double lo = cells[i].lo, hi = cells[i].hi, v = 0;
        for (size_t j = 0; j < k; j++)
            v += f->P[r + j * m] * f->Q[c + j * n];
        double d = hi - lo + 0.5 * fmax(fabs(lo), fabs(hi));
        if (v >= lo - d && v <= hi + d) continue;
        x[at] = fmin(fmax(v, lo), hi);
        ext[at] = 2; /* data from now on, not a neighbour's source */
        added++;
    }
    return added;
}

/* Whether the fit costs the valid cells (mask) more than SB_TAPS_COST
 * times the squared error `before` the taps' constraints; its prefixes'
 * squared errors on them into e2. */
static int taps_cost(const sb_fit_t *f, const double *As, size_t lda, const unsigned char *mask, double before,
                     double norm2, double *e2) {
    fit_valid_prefix_e2(f, As, lda, mask, e2);
    return sqrt(e2[f->k - 1]) > SB_TAPS_COST * sqrt(before) + 1e-12 * sqrt(norm2);
}

/* The taps' cells of a fit: the data (ext 1) are the mask in every pass
 * and round, so one scan serves them all. */
typedef struct taps_list {
    taps_cell_t *cells;
    size_t n;
    int scanned; /* the data (ext 1) are the mask in every pass: one scan */
} taps_list_t;

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
                               int *converged, double *err, int *stretched, double *P1, double *Q1, taps_list_t *tl,
                               double *e2) {
    size_t m = f->m, n = f->n, k = f->k;
    double e2b[SB_ALS_MAX_K]; /* the prefixes' errors before, e2 those of the fit now */
    fit_valid_prefix_e2(f, As, lda, mask, e2b);
    memcpy(e2, e2b, k * sizeof *e2);
    double before = e2b[k - 1];
    int cost = 0;
    memcpy(P1, f->P, m * k * sizeof *P1);
    memcpy(Q1, f->Q, n * k * sizeof *Q1);
    size_t constrained = 0;
    unsigned char tconv[SB_ALS_MAX_K]; /* the flags of the terms in P1, Q1 */
    memcpy(tconv, f->tconv, sizeof tconv);
    sb_result_t r = SB_OK;
    if (!tl->scanned && taps_scan(o, m, n, f->x, ext, NULL, NULL, &tl->cells, &tl->n) != 0) /* taps: As is f->x */
        return sb_error(f->ctx, SB_ERR_NOMEM, "fit: cannot allocate the taps' ranges");
    tl->scanned = 1;
    for (int round = 0; r == SB_OK && round < 2; round++) {
        size_t added = constrain_taps(f, tl->cells, tl->n, f->x, ext);
        if (added == 0) break;
        nvalid += added;
        constrained += added;
        r = fit_als_stages(f, As, lda, ext, nvalid, o, strict, norm2, total, converged, err, stretched, NULL);
        if (r == SB_OK && (cost = taps_cost(f, As, lda, mask, before, norm2, e2))) break;
    }
    /* cost: the last round's, of the fit now (every round made one) */
    if (r == SB_OK && constrained && cost) {
        memcpy(f->P, P1, m * k * sizeof *P1);
        memcpy(f->Q, Q1, n * k * sizeof *Q1);
        memcpy(e2, e2b, k * sizeof *e2);
        memcpy(f->tconv, tconv, sizeof tconv);
    }
    return r;
}

/* The ALS part of a fit from the warm start in f->P, f->Q: the stages
 * (joint refits kept under SB_PREFIX_SLACK), the taps' constraints
 * (constrain_taps, twice at most, warm), and when the prefixes' errors on
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
    taps_list_t tl = {NULL, 0, 0};
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
        double e2[SB_ALS_MAX_K]; /* with taps: the prefixes' errors of the fit now, from the rounds */
        if (r == SB_OK && taps)
            r = taps_rounds(f, As, lda, mask, ext, nvalid, o, strict, norm2, total, converged, err, &stretched, P1, Q1,
                            &tl, e2);
        if (r != SB_OK || (!stretched && (taps ? fit_e2_monotone(e2, k) : fit_prefixes_monotone(f, As, lda, mask))))
            break;
    }
    free(ext);
    free(tl.cells);
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
