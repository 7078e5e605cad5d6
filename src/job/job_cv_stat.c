/* The figure a random split lands near (job_cv.c, docs/measured.md,
 * "Random splits against the reported figure").
 *
 * A user checks a scattered table's fit by holding out a random part of
 * its rows (a tenth), refitting and measuring the error there:
 *     r_S = sqrt(sum_{i in S} e_i / sum_{i in S} t_i),
 * e_i the squared error of f cos theta_i at held-out row i, t_i its
 * energy.  On a glossy table r_S is a heavy-tailed draw: a split that
 * holds one of the highlight's few brightest rows is off by 3-7x the
 * others.  The refits give e_i for every row of the folds they left out
 * (each row predicted by a fit that did not see it), so random splits of
 * the table's size can be drawn from them: subsets of n_split of the
 * n_pool held-out rows, S_1 .. S_M, the same subsets at every J'.  The
 * figure reported is the one most of them land near: the geometric centre
 * of the window [a, a w^2] (w = 1.5) that holds the most r_S (ties: the
 * window whose centre is nearest their median), so that it is within w of
 * as many splits as any single figure can be. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "job_impl.h"
#include "util/rng.h"

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* The centre of the fullest window of ratio w^2 over r[0..m) (sorted in
 * place), as the header says. */
static double modal_centre(double *r, size_t m, double w) {
    qsort(r, m, sizeof *r, cmp_double);
    size_t z = 0, most = 0, k = 0;
    while (z < m && !(r[z] > 0)) /* exact splits: within any ratio of 0 alone */
        z++;
    if (z == m) return 0;
    double med = r[(z + m) / 2], best = NAN;
    for (size_t i = z; i < m; i++) {
        if (k < i) k = i;
        while (k + 1 < m && r[k + 1] <= r[i] * w * w)
            k++;
        double c = sqrt(r[i] * r[k]);
        if (k - i + 1 > most || (k - i + 1 == most && fabs(log(c / med)) < fabs(log(best / med)))) {
            most = k - i + 1;
            best = c;
        }
    }
    return z > most ? 0 : best;
}

/* Random splits drawn per figure: DRAWS, fewer (not below DRAWS_MIN)
 * where their rows times J + 1 pass WORK: a large table's splits hold
 * thousands of rows and vary less (the figure and its jackknife for
 * 23 328 rows, 2333 per split: J = 8 0.20 s CPU with 1024 draws, 0.08 s
 * with 400; J = 32 0.53 s, 0.12 s with 256; a Cornell paint at J = 4:
 * 1024 draws, 9 ms). */
enum { DRAWS = 1024, DRAWS_MIN = 256, WORK = 1 << 23 };

/* fig[j] from `draws` random splits of n_split of the rows idx[0..n)
 * (shuffled in place); r (draws * J) and es (J) are work space. */
static void figure_of(const double *e, const double *t, size_t *idx, size_t n, size_t n_split, size_t J, double w,
                      size_t draws, double *r, double *es, double *fig) {
    sb_rng_t g;
    sb_rng_seed(&g, 0x5eedc0de); /* fixed: the same pool gives the same figure */
    for (size_t s = 0; s < draws; s++) {
        double ts = 0;
        memset(es, 0, J * sizeof *es);
        for (size_t a = 0; a < n_split; a++) { /* a partial Fisher-Yates shuffle: n_split distinct rows */
            size_t b = a + (size_t)(sb_unit(sb_rng_next(&g)) * (double)(n - a)), x = idx[b];
            idx[b] = idx[a], idx[a] = x;
            ts += t[x];
            for (size_t j = 0; j < J; j++)
                es[j] += e[x * J + j];
        }
        for (size_t j = 0; j < J; j++)
            r[j * draws + s] = ts > 0 ? sqrt(es[j] / ts) : 0; /* no energy held: nothing to miss */
    }
    for (size_t j = 0; j < J; j++)
        fig[j] = modal_centre(r + j * draws, draws, w);
}

/* The figure from all the folds' rows; its standard error by the
 * jackknife over the folds (each left out in turn, the figure drawn again
 * from the others): sqrt((K - 1) / K sum_k (fig_k - mean)^2). */
void job_cv_split_figure(const double *e, const double *t, const size_t *fold_end, size_t folds, size_t n_split,
                         size_t J, double w, double *fig, double *se) {
    size_t n = folds ? fold_end[folds - 1] : 0;
    size_t *idx = malloc((n ? n : 1) * sizeof *idx);
    size_t draws = n_split ? WORK / (n_split * (J + 1)) : DRAWS;
    draws = draws > DRAWS ? DRAWS : draws < DRAWS_MIN ? DRAWS_MIN : draws;
    double *r = malloc((draws + 3) * J * sizeof *r), *es = r ? r + draws * J : NULL;
    double *fk = es ? es + J : NULL, *sum = fk ? fk + J : NULL;
    for (size_t j = 0; j < J; j++) {
        fig[j] = NAN;
        if (se) se[j] = NAN;
    }
    if (!idx || !r || n_split == 0 || n_split > n) {
        free(idx), free(r);
        return;
    }
    for (size_t i = 0; i < n; i++)
        idx[i] = i;
    figure_of(e, t, idx, n, n_split, J, w, draws, r, es, fig);
    if (se && folds > 1) {
        memset(sum, 0, J * sizeof *sum);
        for (size_t j = 0; j < J; j++)
            se[j] = 0;
        double *all = malloc(folds * J * sizeof *all);
        for (size_t k = 0; all && k < folds; k++) {
            size_t m = 0, lo = k ? fold_end[k - 1] : 0;
            for (size_t i = 0; i < n; i++)
                if (i < lo || i >= fold_end[k]) idx[m++] = i;
            figure_of(e, t, idx, m, n_split < m ? n_split : m, J, w, draws, r, es, all + k * J);
            for (size_t j = 0; j < J; j++)
                sum[j] += all[k * J + j];
        }
        for (size_t k = 0; all && k < folds; k++)
            for (size_t j = 0; j < J; j++) {
                double d = all[k * J + j] - sum[j] / (double)folds;
                se[j] += d * d;
            }
        for (size_t j = 0; j < J; j++)
            se[j] = all ? sqrt((double)(folds - 1) / (double)folds * se[j]) : NAN;
        free(all);
    }
    free(idx), free(r);
}
