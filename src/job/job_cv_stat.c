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
 * table's rows, S_1 .. S_M, the same subsets at every J', a row no refit
 * held out given the relative error of the held-out row nearest to it in
 * energy (impute: the refits held out half the table, and how many of its
 * few bright rows fell in that half was chance).  The
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

/* The table's rows, brightest first (energy t_all), and which held-out
 * row each is (SIZE_MAX: none): the donors' order of impute(). */
typedef struct table_rows {
    const double *t;     /* t_all[r], r < n */
    size_t n, *order;    /* order[p]: the table row of energy rank p */
    size_t *held;        /* held[r]: its held-out row h, or SIZE_MAX */
    size_t *prev, *next; /* work: the nearest donor at or before / after rank p */
} table_rows_t;

typedef struct keyed {
    double t;
    size_t i;
} keyed_t;

static int by_energy(const void *a, const void *b) { /* brightest first, then the table's order */
    const keyed_t *x = a, *y = b;
    return x->t != y->t ? (x->t < y->t) - (x->t > y->t) : (x->i > y->i) - (x->i < y->i);
}

/* Every table row's squared errors ea[r * J + j]: a held-out row in use
 * (use[h]) its own, any other the relative squared error of the held-out
 * row in use nearest to it in energy rank (the mean of two equally near)
 * times its own energy:
 *     ea_r = t_r e_d / t_d   (e_d itself where t_d = 0).
 * The refits hold out half the table; its brightest rows, whose errors
 * set a split's, are then as many in the pool as chance put there (the
 * acrylic's four plateau rows: 0 to 4), and splits drawn from the pool
 * alone held them at that rate.  Drawn from every row of the table they
 * hold them at the table's own rate, each with an error its nearest
 * held-out peer had. */
static void impute(const double *e, const double *t, const unsigned char *use, const table_rows_t *tr, size_t J,
                   double *ea) {
    size_t n = tr->n, none = SIZE_MAX;
    for (size_t p = 0, last = none; p < n; p++) { /* the nearest donor at or before each rank */
        size_t h = tr->held[tr->order[p]];
        if (h != none && use[h]) last = p;
        tr->prev[p] = last;
    }
    for (size_t p = n, last = none; p-- > 0;) {
        size_t h = tr->held[tr->order[p]];
        if (h != none && use[h]) last = p;
        tr->next[p] = last;
    }
    for (size_t p = 0; p < n; p++) {
        size_t r = tr->order[p], a = tr->prev[p], b = tr->next[p], d[2], nd = 0;
        if (a != none && (b == none || p - a <= b - p)) d[nd++] = tr->held[tr->order[a]];
        if (b != none && (a == none || b - p <= p - a) && b != a) d[nd++] = tr->held[tr->order[b]];
        for (size_t j = 0; j < J; j++) {
            double s = 0;
            for (size_t k = 0; k < nd; k++)
                s += t[d[k]] > 0 ? tr->t[r] * e[d[k] * J + j] / t[d[k]] : e[d[k] * J + j];
            ea[r * J + j] = nd ? s / (double)nd : 0;
        }
    }
}

/* The figure with the rows in use (use[h], h < n held-out rows): drawn
 * from them, or with tr from every table row (impute). */
static void figure_from(const double *e, const double *t, const unsigned char *use, size_t n, const table_rows_t *tr,
                        double *ea, size_t *idx, size_t n_split, size_t J, double w, size_t draws, double *r,
                        double *es, double *fig) {
    size_t m = 0;
    if (tr) {
        impute(e, t, use, tr, J, ea);
        for (size_t i = 0; i < tr->n; i++)
            idx[i] = i;
        figure_of(ea, tr->t, idx, tr->n, n_split, J, w, draws, r, es, fig);
        return;
    }
    for (size_t i = 0; i < n; i++)
        if (use[i]) idx[m++] = i;
    figure_of(e, t, idx, m, n_split < m ? n_split : m, J, w, draws, r, es, fig);
}

/* tr's order and held-out rows (NULL: no table rows given, or no memory). */
static table_rows_t *table_rows(const size_t *row, size_t n, const double *t_all, size_t n_all) {
    table_rows_t *tr = row && t_all && n_all ? calloc(1, sizeof *tr) : NULL;
    keyed_t *k = tr ? malloc(n_all * sizeof *k) : NULL;
    if (k) tr->order = malloc(4 * n_all * sizeof *tr->order);
    if (!tr || !k || !tr->order) {
        free(k), free(tr);
        return NULL;
    }
    tr->t = t_all, tr->n = n_all;
    tr->held = tr->order + n_all, tr->prev = tr->held + n_all, tr->next = tr->prev + n_all;
    for (size_t i = 0; i < n_all; i++)
        k[i].t = t_all[i], k[i].i = i, tr->held[i] = SIZE_MAX;
    for (size_t h = 0; h < n; h++)
        if (row[h] < n_all) tr->held[row[h]] = h;
    qsort(k, n_all, sizeof *k, by_energy);
    for (size_t i = 0; i < n_all; i++)
        tr->order[i] = k[i].i;
    free(k);
    return tr;
}

/* The jackknife over the folds: each left out in turn, the figure drawn
 * again from the others: sqrt((K - 1) / K sum_k (fig_k - mean)^2). */
static void jackknife(const double *e, const double *t, unsigned char *use, const size_t *fold_end, size_t folds,
                      const table_rows_t *tr, double *ea, size_t *idx, size_t n_split, size_t J, double w, size_t draws,
                      double *r, double *es, double *fk, double *sum, double *se) {
    size_t n = fold_end[folds - 1];
    double *all = malloc(folds * J * sizeof *all);
    memset(sum, 0, J * sizeof *sum);
    for (size_t j = 0; j < J; j++)
        se[j] = all ? 0 : NAN;
    for (size_t k = 0; all && k < folds; k++) {
        size_t lo = k ? fold_end[k - 1] : 0;
        for (size_t i = 0; i < n; i++)
            use[i] = i < lo || i >= fold_end[k];
        figure_from(e, t, use, n, tr, ea, idx, n_split, J, w, draws, r, es, fk);
        memcpy(all + k * J, fk, J * sizeof *fk);
        for (size_t j = 0; j < J; j++)
            sum[j] += fk[j];
    }
    for (size_t k = 0; all && k < folds; k++)
        for (size_t j = 0; j < J; j++) {
            double d = all[k * J + j] - sum[j] / (double)folds;
            se[j] += d * d;
        }
    for (size_t j = 0; all && j < J; j++)
        se[j] = sqrt((double)(folds - 1) / (double)folds * se[j]);
    free(all);
}

void job_cv_split_figure(const double *e, const double *t, const size_t *fold_end, size_t folds, const size_t *row,
                         const double *t_all, size_t n_all, size_t n_split, size_t J, double w, double *fig,
                         double *se) {
    size_t n = folds ? fold_end[folds - 1] : 0;
    for (size_t j = 0; j < J; j++) {
        fig[j] = NAN;
        if (se) se[j] = NAN;
    }
    table_rows_t *tr = n ? table_rows(row, n, t_all, n_all) : NULL;
    size_t rows = tr ? n_all : n, draws = n_split ? WORK / (n_split * (J + 1)) : DRAWS;
    draws = draws > DRAWS ? DRAWS : draws < DRAWS_MIN ? DRAWS_MIN : draws;
    size_t *idx = malloc((rows ? rows : 1) * sizeof *idx);
    unsigned char *use = malloc(n ? n : 1);
    double *r = malloc((draws + 3) * J * sizeof *r), *es = r ? r + draws * J : NULL;
    double *fk = es ? es + J : NULL, *sum = fk ? fk + J : NULL;
    double *ea = tr ? malloc(n_all * J * sizeof *ea) : NULL;
    if (idx && use && r && (!tr || ea) && n_split && n_split <= n) {
        memset(use, 1, n);
        figure_from(e, t, use, n, tr, ea, idx, n_split, J, w, draws, r, es, fig);
        if (se && folds > 1)
            jackknife(e, t, use, fold_end, folds, tr, ea, idx, n_split, J, w, draws, r, es, fk, sum, se);
    }
    if (tr) free(tr->order);
    free(tr), free(idx), free(use), free(r), free(ea);
}
