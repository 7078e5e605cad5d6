/* sepbrdf study: the runs of a study and its output files (study_out.c). */
#ifndef SEPBRDF_CLI_STUDY_H
#define SEPBRDF_CLI_STUDY_H

#include "cli.h"

#define MAX_J 256 /* sb_metric_t holds 256 terms */

typedef struct study_opts {
    const char **sources;
    size_t nsources;
    const char *out;
    size_t res, metric_res;
    unsigned char want_j[MAX_J + 1]; /* want_j[J] = 1 if J is studied */
    size_t jmax, nj;
    int param_all;
    unsigned params;   /* bit per sb_param_kind_t when not all */
    sb_job_opts_t job; /* the factor group's options, as parsed */
    sb_form_t form;    /* resolved from job for the outputs */
    int weighted, zero_fill;
    sb_method_t method;
    int nmf; /* --nmf: also the non-negative fit for every J (row_t.nmf_*) */
} study_opts_t;

/* Errors after J terms of one run. */
typedef struct row {
    size_t terms;
    double headline, comparable, rel_rms, max_abs, neg_frac;
    double t_factor, t_metric;        /* of the factorisation the row was read from */
    double nmf_headline, nmf_rel_rms; /* --nmf: the J-term non-negative fit (NaN when it failed) */
} row_t;

/* One source x parameterisation (or a source that could not be opened,
 * kind < 0). */
typedef struct run {
    const char *spec;
    char *source;     /* description; NULL when the source failed */
    int kind;         /* sb_param_kind_t, -1 for a failed source */
    char *param_spec; /* NULL until created */
    size_t rows, cols;
    int ok, masked, converged, iterations;
    char *error;
    double t_sample;
    row_t *r;
    size_t nr;
} run_t;

typedef struct runs {
    run_t *v;
    size_t n, cap;
} runs_t;

/* Write study.csv, study.dat, study.gp, study.png (when some run worked
 * and gnuplot is there: *plotted = 1) and study.json into the open set;
 * 0 on success, -1 after a message. */
int study_write_set(sb_outset_t *set, const study_opts_t *o, const runs_t *rs, size_t failed, size_t good,
                    int *plotted);

#endif
