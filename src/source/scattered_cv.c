/* Cross-validation of the scattered-sample source: the leave-one-position-
 * out error of every interpolation method, and the choice among them. */
#include <math.h>
#include <stdlib.h>

#include "source/scattered_impl.h"

/* Cross-validation holds out at most this many samples (evenly spread):
 * enough for a 1 % estimate, bounded time on large tables. */
#define CV_MAX 2000

/* auto keeps the lobe when it lowers the interpolation's error by at least
 * 10 %: a lobe that barely helps (a retro-reflector's peak is not where a
 * specular lobe sits) only adds its dynamic range. */
#define LOBE_GAIN 0.9

/* The prediction of the held-out sample s (embedded at x, its nskip
 * positions skipped) by each of the methods order[0..3] with kk[i]
 * neighbours: one query for the most neighbours within the larger radius,
 * sorted, each method reading the nearest kk[i] within its own radius
 * (the k nearest within a radius are the first k of a longer list within
 * a larger one).  Adds to num[i], den[i] in the norm of the comparable
 * error, or counts a miss. */
static void cv_sample(const table_t *t, const sb_interp_t order[4], const size_t kk[4], const double *s,
                      const double *x, int nskip, double num[4], double den[4], size_t miss[SB_INTERP_COUNT_]) {
    size_t kmax = 0;
    for (int i = 0; i < 4; i++)
        kmax = kk[i] > kmax ? kk[i] : kmax;
    knn_t all = {kmax, 0, fmax(t->r2, t->s2), {0}, {0}, x, nskip};
    sb_kd_query_(t, x, 0, t->n, &all);
    sb_knn_sort_(&all);
    double b[3] = {1, 1, 1}, w = s[2] * s[5];
    if (t->lobe_on) sb_lobe_base_(&t->lobe, s, s + 3, b);
    for (int i = 0; i < 4; i++) {
        knn_t q = {kk[i], 0, order[i] == SB_INTERP_NEAREST ? t->r2 : t->s2, {0}, {0}, x, nskip};
        for (size_t a = 0; a < all.n && q.n < q.k && all.d2[a] <= q.r2; a++, q.n++)
            q.d2[q.n] = all.d2[a], q.at[q.n] = all.at[a];
        double rgb[3];
        int known = sb_table_from_knn_(t, order[i], x, &q, NAN, rgb);
        if (!known) {
            miss[order[i]]++;
            continue;
        }
        for (int c = 0; c < 3; c++) {
            double v = known == 1 && t->lobe_on ? rgb[c] * b[c] - t->lobe.floor[c] : rgb[c];
            num[i] += (v - s[6 + c]) * (v - s[6 + c]) * w * w;
            den[i] += s[6 + c] * s[6 + c] * w * w;
        }
    }
}

/* Leave-one-position-out error of every method (k neighbours each, as
 * kfit, idw dim + 1 or o->neighbours): each held-out sample (at most
 * CV_MAX, evenly spread over the table) is predicted from the others,
 * every point at its position (repeats, and the swapped copy of a
 * reciprocal anisotropic table) left out, and compared with its measured
 * value in the norm of the comparable error:
 *   e = sqrt( sum (f~ - f)^2 c_i^2 c_o^2 / sum f^2 c_i^2 c_o^2 ).
 * Samples with no neighbour left within the radius are not predicted
 * (miss); NAN when none was.  cv[m] per method; the method of lowest error
 * (on ties the earlier of quadratic, linear, idw, nearest) into *best;
 * returns the error of the method that will be used (o->interp, or the
 * best). */
static double cv_all(const table_t *t, const sb_measured_opts_t *o, size_t kfit, double *cv, size_t *miss, size_t *held,
                     sb_interp_t *best) {
    static const sb_interp_t order[4] = {SB_INTERP_QUADRATIC, SB_INTERP_LINEAR, SB_INTERP_IDW, SB_INTERP_NEAREST};
    size_t kk[4], n = t->ns < CV_MAX ? t->ns : CV_MAX;
    for (int i = 0; i < 4; i++)
        kk[i] = order[i] == SB_INTERP_NEAREST ? 1
                : o->neighbours               ? o->neighbours
                : order[i] == SB_INTERP_IDW   ? (size_t)t->dim + 1
                                              : kfit;
    for (int k = 0; k < SB_INTERP_COUNT_; k++)
        cv[k] = NAN, miss[k] = 0;
    double num[4] = {0}, den[4] = {0};
    *held = n;
    for (size_t h = 0; h < n; h++) {
        const double *s = t->smp + (h * t->ns / n) * SB_SAMPLE_DOUBLES;
        double x[2 * MAX_DIM] = {0};
        sb_scat_embed_(t->iso, t->recip, s, s + 3, x);
        int nskip = 1;
        if (!t->iso && t->recip) sb_scat_embed_(t->iso, t->recip, s + 3, s, x + MAX_DIM), nskip = 2;
        cv_sample(t, order, kk, s, x, nskip, num, den, miss);
    }
    double best_e = INFINITY;
    *best = SB_INTERP_QUADRATIC;
    for (int i = 0; i < 4; i++) {
        sb_interp_t m = order[i];
        double e = miss[m] < n && den[i] > 0 ? sqrt(num[i] / den[i]) : NAN;
        cv[m] = e;
        if (isfinite(e) && e < best_e) {
            best_e = e;
            *best = m;
        }
    }
    double e = cv[o->interp == SB_INTERP_DEFAULT ? *best : o->interp];
    return isfinite(e) ? e : INFINITY;
}

/* Cross-validate every method, without the lobe and with it (as o->lobe
 * allows); keep the lobe when asked, or (auto) when it lowers the error
 * by LOBE_GAIN;
 * with interp DEFAULT keep the method of lowest error. */
void sb_table_cv_choose_(table_t *t, const sb_measured_opts_t *o, size_t kfit, sb_measured_info_t *info) {
    double cv_off[SB_INTERP_COUNT_], cv_on[SB_INTERP_COUNT_], e_off = INFINITY, e_on = INFINITY;
    size_t miss_off[SB_INTERP_COUNT_], miss_on[SB_INTERP_COUNT_];
    sb_interp_t best_off = SB_INTERP_QUADRATIC, best_on = SB_INTERP_QUADRATIC;
    /* a fold's table with the method and the lobe given (the refits of
     * the cross-validation at the measurements) uses them as given: its
     * own leave-one-out errors would choose nothing (interp_cv NAN) */
    int fixed = o->cv_folds >= 2 && o->interp != SB_INTERP_DEFAULT && o->lobe != SB_LOBE_AUTO;
    for (int k = 0; fixed && k < SB_INTERP_COUNT_; k++)
        cv_off[k] = cv_on[k] = NAN, miss_off[k] = miss_on[k] = 0;
    if (fixed) info->cv_held_out = 0;
    if (o->lobe != SB_LOBE_ON && !fixed) e_off = cv_all(t, o, kfit, cv_off, miss_off, &info->cv_held_out, &best_off);
    double *raw = t->val, *q = NULL, *lb = NULL;
    if (o->lobe != SB_LOBE_OFF) {
        sb_lobe_fit_(t->smp, t->ns, o->lobe == SB_LOBE_ON ? o->lobe_shape : NULL, &t->lobe);
        q = sb_lobe_values_(t, &t->lobe, &lb);
    }
    if (q) {
        t->val = q;
        t->lb = lb;
        t->lobe_on = 1;
        if (!fixed) e_on = cv_all(t, o, kfit, cv_on, miss_on, &info->cv_held_out, &best_on);
    }
    int use = q && (o->lobe == SB_LOBE_ON || e_on < LOBE_GAIN * e_off);
    if (q && !use) {
        t->val = raw;
        t->lobe_on = 0;
        t->lb = NULL;
        free(q);
        free(lb);
    } else if (use) {
        t->raw = raw; /* measured positions return their measurement */
    }
    const double *cv = use ? cv_on : cv_off;
    for (int k = 0; k < SB_INTERP_COUNT_; k++)
        info->interp_cv[k] = cv[k];
    sb_interp_t best = use ? best_on : best_off;
    t->interp = o->interp == SB_INTERP_DEFAULT ? best : o->interp;
    t->k = o->neighbours ? o->neighbours : t->interp == SB_INTERP_IDW ? (size_t)t->dim + 1 : kfit;
    info->cv_missing = (use ? miss_on : miss_off)[t->interp];
    if (t->lobe.fitted) sb_lobe_report_(&t->lobe, use, &info->lobe);
    info->lobe.cv_off = isfinite(e_off) ? e_off : NAN;
    info->lobe.cv_on = isfinite(e_on) ? e_on : NAN;
}
