/* Private: the interpolated source of scattered samples, shared by its
 * files: scattered.c (building the source), scattered_kd.c (embedding,
 * k-d tree, nearest neighbours), scattered_fit.c (local fits, evaluation)
 * and scattered_cv.c (cross-validation of the methods).  The maths of the
 * embedding and of the fits is in scattered.c's opening comment. */
#ifndef SEPBRDF_SCATTERED_IMPL_H
#define SEPBRDF_SCATTERED_IMPL_H

#include "source/measured_impl.h"
#include "util/memo.h"

#define KNN_MAX 64
#define MAX_DIM 4

/* Two configurations closer than this (radians of the embedding) are the
 * same measurement position: text tables print angles to about 6 decimals
 * and rounding leaves copies 1e-16 apart. */
#define SAME_POSITION 1e-6

/* The lobe a table's values are interpolated relative to
 * (scattered_lobe.c): f = kd B + ks S(l, v), S of width alpha, Schlick F0,
 * B 1 or 1 - (1 - v.h)^5. */
#define LOBE_ALTS 4 /* the best shape and up to three that fit about as well */
typedef struct lobe_alt {
    int ndf, cosp;
    double alpha, f0, kd[3], ks[3], dcap; /* dcap: D at most CAP x its largest at a sample */
    int pc;                               /* Schlick's F0 per channel (f0c), else f0 for all */
    double f0c[3];                        /* channel c's F0 (f0 in every channel when !pc) */
    int fd;                               /* the diffuse term kd (1 - (1 - v.h)^5), else kd */
} lobe_alt_t;
typedef struct lobe {
    int fitted, ndf; /* ndf: 0 GGX, 1 Beckmann, 2 exp4, 3 exp8 */
    int cosp;        /* the cosines' power in the denominator: (cosp % 3) / 2; cosp >= 3: remapped Smith k */
    double alpha, f0, kd[3], ks[3], floor[3];
    int pc; /* F0 per channel (f0c) */
    double f0c[3];
    int fd;                    /* diffuse kd (1 - (1 - v.h)^5) */
    int nalt;                  /* shapes in alt (alt[0] the one above) */
    lobe_alt_t alt[LOBE_ALTS]; /* the base takes the lowest of them (sb_lobe_fit_) */
} lobe_t;

typedef struct table {
    size_t n; /* points in the tree */
    int dim;  /* 3 (isotropic) or 4 */
    int iso, recip;
    double *pts;          /* n * MAX_DIM (unused coordinates 0), tree order */
    double *val;          /* n * 4: f_r (RGB, the mean over repeats) and
                           * the number of samples merged into the point */
    unsigned char *split; /* split axis of the node whose median is at i */
    size_t k;
    double r2; /* squared radius: nearest farther = missing */
    double s2; /* squared support: neighbours used */
    sb_interp_t interp;
    double *smp; /* the samples (sorted: sort_rows), SB_SAMPLE_DOUBLES each */
    size_t ns;
    lobe_t lobe;
    int lobe_on;     /* val holds f / base (sb_lobe_base_), eval multiplies back */
    double *raw;     /* with lobe_on: the values as measured (n * 4), returned at measured positions */
    double *lb;      /* with lobe_on: ln of the base's channel sum at each point (n), NULL without */
    sb_memo_t *memo; /* values by embedded position, and pole means before the lobe's factor (scattered_fit.c) */
} table_t;

/* The k nearest within sqrt(r2): a max-heap on d2 while searching
 * (d2[0] the farthest kept), sorted ascending by sb_knn_sort_ afterwards. */
typedef struct knn {
    size_t k, n;
    double r2;
    double d2[KNN_MAX];
    size_t at[KNN_MAX];
    const double *skip; /* cross-validation: nskip positions (MAX_DIM each) held out */
    int nskip;
} knn_t;

/* scattered_kd.c */
/* Embedded position x (MAX_DIM doubles, unused ones left as they are) of
 * the pair (wi, wo), symmetries folded. */
void sb_scat_embed_(int iso, int recip, const double wi[3], const double wo[3], double *x);
/* Build the implicit tree over the points p (MAX_DIM each) of idx[lo, hi),
 * split axes into split[]. */
void sb_kd_build_(size_t *idx, const double *p, unsigned char *split, size_t lo, size_t hi);
/* Push the points of the tree's [lo, hi) near x into q (q->k nearest
 * within sqrt(q->r2), held-out positions skipped). */
void sb_kd_query_(const table_t *t, const double *x, size_t lo, size_t hi, knn_t *q);
/* Sort q ascending by distance. */
void sb_knn_sort_(knn_t *q);
/* Sort q descending by (distance, index): one order for one set of
 * neighbours, whatever the search's path. */
void sb_knn_canon_(knn_t *q);
/* Median spacing of the tree's points (see scattered_kd.c); < 0 on no memory. */
double sb_table_spacing_(sb_context_t *ctx, const table_t *t);

/* scattered_fit.c */
/* The value at embedded position x by method interp with k neighbours,
 * leaving out the nskip positions of skip: 0 missing, 1 known, 2 known at
 * a measured position; lx as for sb_table_from_knn_. */
int sb_table_at_(const table_t *t, sb_interp_t interp, size_t k, const double *x, const double *skip, int nskip,
                 double lx, double rgb[3]);
/* The value at x by method interp from its neighbours q, as sb_table_at_
 * finds them (the k nearest within the method's radius).  lx: with the
 * lobe, ln of the base's channel sum at x (sb_lobe_level_), NAN to have
 * it computed. */
int sb_table_from_knn_(const table_t *t, sb_interp_t interp, const double *x, const knn_t *q, double lx, double rgb[3]);
/* The source's eval: f_r of (wi, wo), with the pole blend. */
int sb_table_eval_(const void *self, const double wi[3], const double wo[3], double rgb[3]);

/* scattered_lobe_solve.c */
/* A shape's least-squares sums over the samples (weights w = cos^2
 * theta_i): S the shape (grey F0, or F = 1 with a per-channel F0), T = S
 * (1 - v.h)^5 (per-channel F0 only), f the values; the diffuse term's
 * factor B (1, or 1 - (1 - v.h)^5) in those of the diffuse weight: w is
 * sum w B^2, ws sum w B S, wt sum w B T, wf sum w B f. */
typedef struct lobe_sums {
    double w, ws, wss, wf[3], wsf[3], wff[3];
    double wt, wst, wtt, wtf[3];
} lobe_sums_t;
/* Non-negative (kd, ks) of channel c minimising sum w (kd + ks S - f)^2;
 * returns the residual sum. */
double sb_lobe_solve2_(const lobe_sums_t *m, int c, double *kd, double *ks);
/* Non-negative kd, a, b of channel c minimising sum w (kd + a S + b T -
 * f)^2, as kd, ks = a + b and Schlick's F0 = a / ks (1 when ks = 0);
 * returns the residual sum. */
double sb_lobe_solve3_(const lobe_sums_t *m, int c, double *kd, double *ks, double *f0);

/* The channel's median sample value (the floor under the lobe's base), at
 * least 1e-3 of its largest and 1e-12 (1e-12 alone on no memory). */
void sb_lobe_floor_(const double *smp, size_t ns, double floor_[3]);

/* scattered_lobe.c */
/* Fit the lobe to ns samples (SB_SAMPLE_DOUBLES each) into L; keep: NULL
 * or a lobe whose family (ndf, f0, cos_power) is kept.  L->fitted stays 0
 * when no fit is finite. */
void sb_lobe_fit_(const double *smp, size_t ns, const sb_lobe_fit_t *keep, lobe_t *L);
/* The base b = kd + ks S + floor of the pair (wi, wo). */
void sb_lobe_base_(const lobe_t *L, const double wi[3], const double wo[3], double b[3]);
/* A direction pair at embedded position x (its symmetric representative). */
void sb_table_dirs_(const table_t *t, const double *x, double wi[3], double wo[3]);
/* The points' values relative to the base at their positions, (f +
 * floor) / base (n * 4, the counts kept; malloc'd; NULL when L is not
 * fitted, on no memory or when a quotient is not finite), and into *lb
 * (malloc'd, n) ln of the base's channel sum at each point. */
double *sb_lobe_values_(const table_t *t, const lobe_t *L, double **lb);
/* ln of the base's channel sum at embedded position x. */
double sb_lobe_level_(const table_t *t, const double *x);
/* The public description of L. */
void sb_lobe_report_(const lobe_t *L, int used, sb_lobe_fit_t *out);

/* scattered_cv.c */
/* Cross-validate every method into info; set t->interp and t->k from o
 * (the lowest error when o->interp is DEFAULT). */
void sb_table_cv_choose_(table_t *t, const sb_measured_opts_t *o, size_t kfit, sb_measured_info_t *info);

#endif
