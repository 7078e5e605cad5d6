/* sepbrdf study: the runs of a study and its output files (study_out.c). */
#ifndef SEPBRDF_CLI_STUDY_H
#define SEPBRDF_CLI_STUDY_H

#include "cli.h"

#define MAX_J 256 /* sb_metric_t holds 256 terms */
#define STUDY_MAX_BUDGETS 32

typedef struct study_opts {
    const char **sources;
    size_t nsources;
    const char *out;
    size_t res, metric_res;
    unsigned char want_j[MAX_J + 1]; /* want_j[J] = 1 if J is studied */
    size_t jmax, nj;
    int param_all;
    int param_auto;    /* study what `factor` builds: the auto layout per J (the default) */
    unsigned params;   /* bit per sb_param_kind_t when not all */
    sb_job_opts_t job; /* the factor group's options, as parsed */
    sb_form_t form;    /* resolved from job for the outputs */
    int weighted, zero_fill;
    sb_method_t method;
    int nmf;                           /* --nmf: also the non-negative fit for every J (row_t.nmf_*) */
    int terms_given;                   /* --terms was given */
    size_t budgets[STUDY_MAX_BUDGETS]; /* --budget LIST: bytes, ascending; nbudgets 0: a study over J */
    size_t nbudgets;
} study_opts_t;

/* Errors after J terms of one run. */
typedef struct row {
    size_t terms;
    double headline, comparable, rel_rms, max_abs, neg_frac;
    double t_factor, t_metric;        /* of the factorisation the row was read from */
    double nmf_headline, nmf_rel_rms; /* --nmf: the J-term non-negative fit (NaN when it failed) */
    char *spec;                       /* auto runs: the layout kept at this J (owned), else NULL */
    const char *form;                 /* auto runs: its form, else NULL */
    int weighted;
} row_t;

/* run_t.kind of the auto runs (factor's own choice at every J). */
#define STUDY_AUTO 0x7fff
/* "auto" or the parameterisation's name. */
const char *study_kind_name(int kind);

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
    char *warn[8]; /* the job's warnings (sb_job_warning), as printed */
    size_t nwarn;
    double t_sample;
    row_t *r;
    size_t nr;
} run_t;

typedef struct runs {
    run_t *v;
    size_t n, cap;
} runs_t;

/* cmd_study.c: a copy of s (NULL for NULL or no memory); a failed run
 * with msg; the job's warnings printed and kept; the rows of J (only_j)
 * or every J' <= J from the job's factorisation. */
char *study_dup(const char *s);
void study_run_fail(run_t *r, const char *msg);
void study_run_warnings(run_t *r, const sb_job_t *job, const char *param);
void study_take_rows(run_t *r, const study_opts_t *o, const sb_job_t *job, size_t J, int only_j);
/* --nmf: the non-negative fit with each studied J of run r beside its rows
 * (base: the run's options, terms the largest J). */
void study_nmf_rows(sb_context_t *ctx, const sb_source_t *src, run_t *r, const sb_job_opts_t *base);
/* study_auto.c: an auto run (STUDY_AUTO): factor's whole job at every J. */
void study_run_auto(sb_context_t *ctx, const sb_source_t *src, const study_opts_t *o, run_t *r, const char *label,
                    double base, double span);

/* Write study.csv, study.dat, study.gp, study.png (when some run worked
 * and gnuplot is there: *plotted = 1) and study.json into the open set;
 * 0 on success, -1 after a message. */
int study_write_set(sb_outset_t *set, const study_opts_t *o, const runs_t *rs, size_t failed, size_t good,
                    int *plotted);

/* One output file of the set, through a temporary name (study_out.c);
 * messages name it in the target folder; 0 on success, -1 after a
 * message. */
/* study.gp's output: study.png, or outfile given with -e; pngcairo where
 * there is one. */
#define STUDY_GP_OUTPUT                                                                                                \
    "if (!exists(\"outfile\")) outfile = 'study.png'\n"                                                                \
    "if (strstrt(GPVAL_TERMINALS, 'pngcairo') > 0) {\n"                                                                \
    "    set terminal pngcairo size 1000,640 noenhanced font ',10'\n"                                                  \
    "} else {\n"                                                                                                       \
    "    set terminal png size 1000,640 noenhanced\n"                                                                  \
    "}\n"                                                                                                              \
    "set output outfile\n"

/* A CSV field, quoted where it must be; a gnuplot single-quoted string
 * ('' is a quote). */
void study_csv_field(FILE *fp, const char *s);
void study_gp_quote(FILE *fp, const char *s);
typedef void (*study_writer_fn)(FILE *fp, const void *arg);
int study_write_file(sb_outset_t *set, const char *name, study_writer_fn fn, const void *arg);
/* Run gnuplot on study.gp in `dir`, output to a temporary, renamed to
 * study.png on success.  1 plotted, 0 skipped (warning printed). */
int study_gnuplot(const char *dir, const char *target);

/* study --budget LIST (study_budget.c): per source x layout asked (auto,
 * or each of --param's list) x budget, one factor job with that budget;
 * writes study.csv, study.json, study.dat, study.gp, study.png (headline
 * error against bytes) and prints the table.  Returns the exit code. */
int study_budgets(sb_context_t *ctx, const study_opts_t *o, double t0);
/* --budget LIST: comma separated byte counts (cli_parse_bytes), sorted,
 * duplicates dropped; -1 after a message. */
int study_parse_budgets(const char *s, study_opts_t *o);

#endif
