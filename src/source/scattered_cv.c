/* Cross-validation of the scattered-sample source: the leave-one-position-
 * out error of every interpolation method, and the choice among them. */
#include <math.h>

#include "source/scattered_impl.h"

/* Cross-validation holds out at most this many samples (evenly spread):
 * enough for a 1 % estimate, bounded time on large tables. */
#define CV_MAX 2000

/* Leave-one-position-out error of method m (k neighbours): each held-out
 * sample (at most CV_MAX, evenly spread over the table) is predicted from
 * the others, every point at its position (repeats, and the swapped copy
 * of a reciprocal anisotropic table) left out, and compared with its
 * measured value in the norm of the comparable error:
 *   e = sqrt( sum (f~ - f)^2 c_i^2 c_o^2 / sum f^2 c_i^2 c_o^2 ).
 * Samples with no neighbour left within the radius are not predicted
 * (*missing); NAN when none was. */
static double cv_error(const table_t *t, sb_interp_t m, size_t k, size_t *held, size_t *missing) {
    size_t n = t->ns < CV_MAX ? t->ns : CV_MAX;
    double num = 0, den = 0;
    *held = n;
    *missing = 0;
    for (size_t h = 0; h < n; h++) {
        const double *s = t->smp + (h * t->ns / n) * SB_SAMPLE_DOUBLES;
        double x[2 * MAX_DIM] = {0}, rgb[3];
        sb_scat_embed_(t->iso, t->recip, s, s + 3, x);
        int nskip = 1;
        if (!t->iso && t->recip) sb_scat_embed_(t->iso, t->recip, s + 3, s, x + MAX_DIM), nskip = 2;
        if (!sb_table_at_(t, m, k, x, x, nskip, rgb)) {
            (*missing)++;
            continue;
        }
        double w = s[2] * s[5];
        for (int c = 0; c < 3; c++) {
            num += (rgb[c] - s[6 + c]) * (rgb[c] - s[6 + c]) * w * w;
            den += s[6 + c] * s[6 + c] * w * w;
        }
    }
    return *missing < n && den > 0 ? sqrt(num / den) : NAN;
}

/* Cross-validate every method; with interp DEFAULT keep the one of lowest
 * error (on ties the earlier of quadratic, linear, idw, nearest). */
void sb_table_cv_choose_(table_t *t, const sb_measured_opts_t *o, size_t kfit, sb_measured_info_t *info) {
    static const sb_interp_t order[4] = {SB_INTERP_QUADRATIC, SB_INTERP_LINEAR, SB_INTERP_IDW, SB_INTERP_NEAREST};
    sb_interp_t best = SB_INTERP_QUADRATIC;
    double best_e = INFINITY;
    size_t miss[SB_INTERP_COUNT_] = {0};
    for (int k = 0; k < SB_INTERP_COUNT_; k++)
        info->interp_cv[k] = NAN;
    for (int i = 0; i < 4; i++) {
        sb_interp_t m = order[i];
        size_t kk = o->neighbours ? o->neighbours : m == SB_INTERP_IDW ? (size_t)t->dim + 1 : kfit;
        double e = cv_error(t, m, kk, &info->cv_held_out, &miss[m]);
        info->interp_cv[m] = e;
        if (isfinite(e) && e < best_e) {
            best_e = e;
            best = m;
        }
    }
    t->interp = o->interp == SB_INTERP_DEFAULT ? best : o->interp;
    t->k = o->neighbours ? o->neighbours : t->interp == SB_INTERP_IDW ? (size_t)t->dim + 1 : kfit;
    info->cv_missing = miss[t->interp];
}
