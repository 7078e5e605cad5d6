/* Private: the band sums of one pair (estimate_bands.c: where the error
 * is), inline in the per-pair loop of estimate.c, so that its AVX2 clone
 * (SB_AVX2_CLONES, on static functions only) takes them too: the same
 * operations and bits as the baseline. */
#ifndef SEPBRDF_ESTIMATE_PAIR_H
#define SEPBRDF_ESTIMATE_PAIR_H

#include <math.h>

#include "factor/estimate_impl.h"

/* cos of the map's edges (est_log2_init): theta >= edge where cos theta <=
 * cos edge, no acos per pair. */
extern double est_map_cos[SB_EST_MAP + 1];

/* sb_band_mask of a pair (inlined into the per-pair sums: an exported
 * function is called, not inlined, from its own file). */
static inline unsigned est_band_mask(const double wi[3], const double wo[3]) {
    /* cos 60, cos 80, cos 89 degrees; cos of the cone */
    static const double cz[3] = {0.5, 0.17364817766693041, 0.017452406437283376};
    const double cc = cos(SB_BAND_CONE_DEG * SB_PI / 180);
    unsigned m = 0;
    for (int k = 0; k < 3; k++) {
        m |= wi[2] < cz[k] ? 1u << (SB_BAND_TI60 + k) : 0;
        m |= wo[2] < cz[k] ? 1u << (SB_BAND_TO60 + k) : 0;
    }
    double mirror = -wi[0] * wo[0] - wi[1] * wo[1] + wi[2] * wo[2],
           retro = wi[0] * wo[0] + wi[1] * wo[1] + wi[2] * wo[2];
    m |= mirror > cc ? 1u << SB_BAND_SPECULAR : 0;
    m |= retro > cc ? 1u << SB_BAND_RETRO : 0;
    return m;
}

/* The map cell of cos theta (NaN: the last, as theta = 180 degrees). */
static inline size_t est_map_cell(double c) {
    size_t k = 0;
    c = c == c ? c : -1;
    while (k + 1 < SB_EST_MAP && c <= est_map_cos[k + 1])
        k++;
    return k;
}

/* The denominators of pair i: bands (mask) and its map cell (*cell). */
static inline void pair_dens(const eval_t *e, const double *d, unsigned mask, size_t k, const double f2[4],
                             size_t *cell) {
    double q = d[2] * d[2] * d[6], *bden = e->bden + k * BQ;
    est_v4_t v = *(const est_v4_t *)f2 * q;
    for (unsigned m = mask; m; m &= m - 1)
        *(est_v4_t *)(bden + __builtin_ctz(m) * 4) += v;
    *cell = est_map_cell(d[2]) * SB_EST_MAP + est_map_cell(d[5]);
    e->mden[k * MM + *cell] += f2[3] * q;
}

/* The squared differences d2[J][4] (add_pair's) of prefixes j0..J-1 to
 * the bands of mask: band by band (one bit found a band, not a prefix),
 * d2[c] q per channel, as one at a time. */
static inline void bands_add(double *bnum, unsigned mask, const double *d2, double q, size_t j0, size_t J) {
    for (unsigned m = mask; m; m &= m - 1) {
        double *bb = bnum + __builtin_ctz(m) * 4;
        for (size_t j = j0; j < J; j++)
            *(est_v4_t *)(bb + j * BQ) += *(const est_v4_t *)(d2 + j * 4) * q;
    }
}

/* Add known pair i (rec as est_reconstruct fills it; d2 its squared
 * differences per prefix and channel R, G, B, all [J][4]; bin their
 * histogram bins, est_bin_of, where f > 0 and not headline_only) of
 * replicate k to the band sums (cleared by est_bands_clear(e, k) first),
 * on thread t. */
static inline __attribute__((always_inline)) void
est_bands_pair(const eval_t *e, size_t i, const double *rec, const double *d2, const uint32_t *bin, size_t k, int t) {
    const double *d = e->P->d + i * PD, *f = d + 7, q = d[2] * d[2] * d[6];
    size_t J = e->J, cell;
    unsigned mask = est_band_mask(d, d + 3);
    double f2[4] = {f[0] * f[0], f[1] * f[1], f[2] * f[2], 0};
    f2[3] = f2[0] + f2[1] + f2[2];
    pair_dens(e, d, mask, k, f2, &cell);
    double *bnum = e->bnum + k * J * BQ;
    if (e->headline_only) { /* the bands only (of all J terms with last_only) */
        bands_add(bnum, mask, d2, q, e->last_only ? J - 1 : 0, J);
        return;
    }
    int lit[4];
    for (int c = 0; c < 4; c++) /* lit: f > 0, so add_pair has the bin */
        lit[c] = f2[c] > 0 && sqrt(f2[c]) * d[2] > e->lit_thr[c];
    uint64_t lw = e->P->m0 > 0 ? (uint64_t)(d[6] / e->P->m0 * 0x1.0p40) : 0;
    uint64_t *hist = e->hlit + (size_t)t * J * 4 * NB;
    double *maxl = e->maxl + (size_t)t * est_tstride(J * 4), *minv = e->minv + (size_t)t * est_tstride(J * 4);
    for (size_t j = 0; j < J; j++) {
        const double *r = rec + j * 3, *dj = d2 + j * 4;
        double *mv = minv + j * 4;
        for (int c = 0; c < 3; c++) { /* fmin's result: a NaN r leaves the minimum */
            mv[c] = r[c] < mv[c] ? r[c] : mv[c];
            mv[3] = r[c] < mv[3] ? r[c] : mv[3];
        }
        for (int c = 0; c < 4; c++) {
            if (!lit[c]) continue;
            hist[(j * 4 + c) * NB + bin[j * 4 + c]] += lw;
            if (dj[c] > maxl[j * 4 + c] * f2[c]) maxl[j * 4 + c] = dj[c] / f2[c];
        }
    }
    bands_add(bnum, mask, d2, q, 0, J);
    e->mnum[k * MM + cell] += d2[(J - 1) * 4 + 3] * q;
}

#endif
