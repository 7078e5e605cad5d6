/* Measured tables checked as a scientist would (docs/measured.md, "Held
 * out at random"): a scattered table's rows are split at random, the rest
 * factored with the defaults at J, and the reconstruction (what the
 * shader returns) compared with the rows left out, f cos theta_i, next to
 * the cross-validated figure (cv_headline) the whole table's run reports.
 *
 *   sepbrdf_bench_holdout FILE [FRACTION [SEEDS [J]]]
 *     FILE      a Cornell .brdf or sepbrdf CSV table
 *     FRACTION  of the rows left out (default 0.1)
 *     SEEDS     splits 1..SEEDS (default 8)
 *     J         terms (default 8)
 *
 * SB_HOLDOUT_LOO=DEG instead holds out each row with theta_h below DEG
 * alone and prints the training table's value there (no factoring).
 * SB_HOLDOUT_FOLDS=K holds out, for seed s, the rows of fold s - 1 of K
 * (sb_measured_fold, the folds of cv_headline) instead of a random part:
 * the whole pipeline refitted on the folds the report's refits use.
 * With SB_HOLDOUT_FOLDS=K and SEEDS = K (every row held out once, each
 * predicted by the whole pipeline refitted without its fold) it then draws
 * SB_HOLDOUT_DRAWS (default 4000) random splits of FRACTION of the rows
 * from those errors and prints the share within 1.5x of cv_headline, the
 * share of the best single figure and the splits' quantiles: what ten
 * fixed splits estimate with a binomial's noise (docs/measured.md, "What
 * ten splits can say").
 * SB_HOLDOUT_PLAIN=1 refits without term weights or texel filters
 * (plain_terms); SB_HOLDOUT_PARAM=SPEC on a fixed layout (weighted).
 *
 * A data row is a line with the largest count of numbers in the file (a
 * Cornell file's wavelength lines have fewer); every other line goes to
 * both halves.  The halves are written beside each other in a temporary
 * folder and removed. */
#define _GNU_SOURCE
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "sepbrdf/sepbrdf.h"

static int numbers(const char *line) {
    int n = 0;
    const char *p = line;
    char *e;
    for (;;) {
        p += strspn(p, " \t,");
        strtod(p, &e);
        if (e == p) break;
        n++;
        p = e;
    }
    p += strspn(p, " \t,\r\n");
    return *p ? 0 : n; /* text after the numbers: not a data row */
}

/* The whole run's cv_headline at J (NAN when it fails). */
static sb_job_t *run(const char *path, size_t J) {
    sb_job_opts_t o = {0};
    o.source = path;
    o.terms = J;
    o.plain_terms = getenv("SB_HOLDOUT_PLAIN") != NULL; /* no term or sample weights */
    o.param = getenv("SB_HOLDOUT_PARAM");               /* a fixed layout instead of auto */
    o.weighted = o.param != NULL;
    sb_job_t *job = NULL;
    if (sb_job_run(NULL, &o, &job) != SB_OK) return NULL;
    return job;
}

/* Each held-out row's squared error and energy, over all splits (the
 * folds' pool, SB_HOLDOUT_FOLDS). */
typedef struct pool {
    double *e, *t;
    size_t n, cap;
} pool_t;

static void pool_add(pool_t *p, double e, double t) {
    if (p->n == p->cap) {
        size_t cap = p->cap ? 2 * p->cap : 1024;
        double *e2 = realloc(p->e, cap * sizeof *e2), *t2 = e2 ? realloc(p->t, cap * sizeof *t2) : NULL;
        if (e2) p->e = e2;
        if (!e2 || !t2) return;
        p->t = t2, p->cap = cap;
    }
    p->e[p->n] = e, p->t[p->n++] = t;
}

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Random splits (each row in with probability frac) drawn from the pool:
 * the share within w of cv, the best single figure's (the fullest window
 * of ratio w^2) and the quantiles. */
static void pool_draws(const pool_t *p, double frac, double cv, double w) {
    const char *d = getenv("SB_HOLDOUT_DRAWS");
    size_t m = d ? (size_t)atol(d) : 4000, in = 0, most = 0;
    double *r = malloc((m ? m : 1) * sizeof *r), best = NAN;
    if (!r || !m || !p->n) {
        free(r);
        return;
    }
    srand(12345);
    for (size_t s = 0; s < m; s++) {
        double a = 0, b = 0;
        for (size_t i = 0; i < p->n; i++)
            if ((double)rand() / RAND_MAX < frac) a += p->e[i], b += p->t[i];
        r[s] = b > 0 ? sqrt(a / b) : 0;
        in += r[s] >= cv / w && r[s] <= cv * w;
    }
    qsort(r, m, sizeof *r, cmp_double);
    for (size_t i = 0, k = 0; i < m; i++) {
        if (k < i) k = i;
        while (k + 1 < m && r[k + 1] <= r[i] * w * w)
            k++;
        if (k - i + 1 > most) most = k - i + 1, best = sqrt(r[i] * r[k]);
    }
    printf("# %zu random splits of %.0f %% drawn from the %zu rows the folds held out: %.1f %% within %gx of "
           "cv_headline %.4g; the best single figure %.4g: %.1f %%; splits' 10/50/90th percentiles %.4g %.4g %.4g\n",
           m, 100 * frac, p->n, 100.0 * (double)in / (double)m, w, cv, best, 100.0 * (double)most / (double)m,
           r[m / 10], r[m / 2], r[9 * m / 10]);
    free(r);
}

/* Relative L2 of f cos theta_i of job's reconstruction at held's samples
 * (each row's squared error and energy into pool, when given). */
static double held_error(const sb_job_t *job, const char *held, size_t J, int worst, pool_t *pool) {
    sb_source_t *h = NULL;
    if (sb_source_open(NULL, held, &h) != SB_OK) return NAN;
    double e2 = 0, t2 = 0, top[8] = {0}, row[8][13];
    if (worst > 8) worst = 8;
    for (size_t i = 0; i < sb_source_sample_count(h); i++) {
        double wi[3], wo[3], v[3], r[3], ei = 0;
        if (!sb_source_sample(h, i, wi, wo, v)) continue;
        if (!sb_factors_eval(sb_job_factors(job), sb_job_param(job), sb_job_form(job), J, wi, wo, r))
            r[0] = r[1] = r[2] = 0;
        for (int c = 0; c < 3; c++) {
            ei += (r[c] - v[c]) * (r[c] - v[c]) * wi[2] * wi[2];
            t2 += v[c] * v[c] * wi[2] * wi[2];
        }
        e2 += ei;
        if (pool)
            pool_add(pool, ei, v[0] * v[0] * wi[2] * wi[2] + v[1] * v[1] * wi[2] * wi[2] + v[2] * v[2] * wi[2] * wi[2]);
        for (int k = 0; k < worst; k++) /* keep the rows of the largest squared error, largest first */
            if (ei > top[k]) {
                memmove(top + k + 1, top + k, (size_t)(worst - k - 1) * sizeof *top);
                memmove(row + k + 1, row + k, (size_t)(worst - k - 1) * sizeof *row);
                top[k] = ei;
                double hv[3] = {wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]};
                double hn = sqrt(hv[0] * hv[0] + hv[1] * hv[1] + hv[2] * hv[2]);
                double t[3] = {0, 0, 0};
                sb_source_eval(sb_job_source(job), wi, wo, t); /* the training table's own value there */
                double d[13] = {acos(wi[2]) * 180 / M_PI,
                                acos(wo[2]) * 180 / M_PI,
                                acos(hv[2] / hn) * 180 / M_PI,
                                v[0] * wi[2],
                                v[1] * wi[2],
                                v[2] * wi[2],
                                r[0] * wi[2],
                                r[1] * wi[2],
                                r[2] * wi[2],
                                (double)i,
                                t[0] * wi[2],
                                t[1] * wi[2],
                                t[2] * wi[2]};
                memcpy(row[k], d, sizeof d);
                break;
            }
    }
    for (int k = 0; k < worst && top[k] > 0; k++)
        printf("#   held sample %4.0f: theta_i %5.1f theta_o %5.1f theta_h %5.2f  f cos %.3g %.3g %.3g  "
               "fit %.3g %.3g %.3g  table %.3g %.3g %.3g  (%.0f %% of the squared error)\n",
               row[k][9], row[k][0], row[k][1], row[k][2], row[k][3], row[k][4], row[k][5], row[k][6], row[k][7],
               row[k][8], row[k][10], row[k][11], row[k][12], 100 * top[k] / e2);
    sb_source_destroy(h);
    return sqrt(e2 / t2);
}

/* Every row with theta_h below `deg` held out alone: the training table's
 * own value there (its interpolation and lobe, no factoring), f cos theta_i.
 * Prints each row and the relative L2 over them (SB_HOLDOUT_LOO=DEG). */
static void loo_peak(FILE *f, int most, const char *tr, const char *he, double deg) {
    static char line[1 << 16];
    double e2 = 0, t2 = 0;
    int n = 0;
    for (long r = 0;; r++) {
        rewind(f);
        FILE *a = fopen(tr, "w"), *b = fopen(he, "w");
        long k = 0;
        int held = 0;
        while (fgets(line, sizeof line, f)) {
            int data = numbers(line) == most;
            if (data && k++ == r) {
                fputs(line, b);
                held = 1;
                continue;
            }
            fputs(line, a);
            if (!data) fputs(line, b);
        }
        fclose(a);
        fclose(b);
        if (!held) break;
        sb_source_t *h = NULL, *t = NULL;
        double wi[3], wo[3], v[3], p[3] = {0, 0, 0};
        if (sb_source_open(NULL, he, &h) != SB_OK || !sb_source_sample(h, 0, wi, wo, v)) {
            sb_source_destroy(h);
            continue;
        }
        sb_source_destroy(h);
        double hv[3] = {wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]};
        double th = acos(hv[2] / sqrt(hv[0] * hv[0] + hv[1] * hv[1] + hv[2] * hv[2])) * 180 / M_PI;
        if (th >= deg || sb_source_open(NULL, tr, &t) != SB_OK) continue;
        sb_source_eval(t, wi, wo, p);
        sb_source_destroy(t);
        double ei = 0, ti = 0;
        for (int c = 0; c < 3; c++) {
            ei += (p[c] - v[c]) * (p[c] - v[c]) * wi[2] * wi[2];
            ti += v[c] * v[c] * wi[2] * wi[2];
        }
        e2 += ei;
        t2 += ti;
        n++;
        printf("row %4ld theta_i %5.1f theta_o %5.1f theta_h %5.2f  f cos %.3g %.3g %.3g  table %.3g %.3g %.3g  rel "
               "%.3f\n",
               r, acos(wi[2]) * 180 / M_PI, acos(wo[2]) * 180 / M_PI, th, v[0] * wi[2], v[1] * wi[2], v[2] * wi[2],
               p[0] * wi[2], p[1] * wi[2], p[2] * wi[2], sqrt(ei / ti));
        fflush(stdout);
    }
    printf("# %d rows with theta_h below %g deg, each held out alone: relative L2 %.4f\n", n, deg, sqrt(e2 / t2));
}

int main(int argc, char **argv) {
    if (argc < 2) {
        fprintf(stderr, "usage: %s FILE [FRACTION [SEEDS [J]]]\n", argv[0]);
        return 2;
    }
    const char *path = argv[1], *ext = strrchr(path, '.');
    double frac = argc > 2 ? atof(argv[2]) : 0.1;
    int seeds = argc > 3 ? atoi(argv[3]) : 8;
    size_t J = argc > 4 ? (size_t)atoi(argv[4]) : 8;
    const char *w = getenv("SB_HOLDOUT_WORST"); /* print the N worst held-out rows of each split (N <= 8) */
    int worst = w ? atoi(w) : 0, first = 1;
    const char *o = getenv("SB_HOLDOUT_FIRST"); /* start at this seed */
    if (o) first = atoi(o);
    const char *fk = getenv("SB_HOLDOUT_FOLDS"); /* the report's folds instead of random parts */
    size_t folds = fk ? (size_t)atoi(fk) : 0;
    FILE *f = fopen(path, "r");
    if (!f || !(frac > 0 && frac < 1) || seeds < 1 || J < 1) {
        fprintf(stderr, "%s: cannot read, or FRACTION not in (0, 1), SEEDS or J below 1\n", path);
        return 2;
    }
    static char line[1 << 16];
    int most = 0;
    while (fgets(line, sizeof line, f)) {
        int n = numbers(line);
        if (n > most) most = n;
    }
    char dir[] = "/tmp/sb_holdoutXXXXXX", tr[4096], he[4096];
    if (!mkdtemp(dir)) return 1;
    snprintf(tr, sizeof tr, "%s/train%s", dir, ext ? ext : "");
    snprintf(he, sizeof he, "%s/held%s", dir, ext ? ext : "");
    const char *l = getenv("SB_HOLDOUT_LOO"); /* hold out each row below this theta_h alone, table only */
    if (l) {
        loo_peak(f, most, tr, he, atof(l));
        unlink(tr);
        unlink(he);
        rmdir(dir);
        return 0;
    }
    sb_job_t *whole = run(path, J);
    double se = NAN, cv = whole ? sb_job_cv(whole, J, &se, NULL) : NAN;
    sb_job_destroy(whole);
    printf("# %s: %.0f %% of the rows held out, J = %zu; cv_headline of the whole table %.4g +- %.2g\n", path,
           100 * frac, J, cv, se);
    printf("| seed | rows held out | error there | / cv_headline |\n|---|---|---|---|\n");
    pool_t pool = {0};
    for (int s = first; s < first + seeds; s++) {
        rewind(f);
        FILE *a = fopen(tr, "w"), *b = fopen(he, "w");
        size_t nh = 0, row = 0;
        srand((unsigned)s);
        while (fgets(line, sizeof line, f)) {
            int data = numbers(line) == most;
            int out =
                data && (folds ? sb_measured_fold(row, folds) == (size_t)(s - 1) : (double)rand() / RAND_MAX < frac);
            row += (size_t)data;
            if (out) {
                fputs(line, b);
                nh++;
            } else {
                fputs(line, a);
                if (numbers(line) != most) fputs(line, b);
            }
        }
        fclose(a);
        fclose(b);
        sb_job_t *job = run(tr, J);
        double e = job ? held_error(job, he, J, worst, folds ? &pool : NULL) : NAN;
        sb_job_destroy(job);
        printf("| %d | %zu | %.4g | %.2f |\n", s, nh, e, e / cv);
        fflush(stdout);
    }
    if (folds && first == 1 && (size_t)seeds == folds) pool_draws(&pool, frac, cv, 1.5);
    free(pool.e), free(pool.t);
    fclose(f);
    unlink(tr);
    unlink(he);
    rmdir(dir);
    return 0;
}
