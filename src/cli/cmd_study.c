/* sepbrdf study: error against J for several sources x parameterisations.
 *
 * Each source x parameterisation is sampled once.  When the fit is a plain
 * truncated SVD (no invalid cells, or --zero-fill), it is factored once with
 * the largest J: by Eckart-Young the leading J' terms of the rank-J SVD are
 * the best rank-J' approximation, so one factorisation gives every J' (the
 * plan's error arrays and the metric hold all of them).  A masked fit
 * (invalid cells excluded by iterative imputation) has no such nesting: the
 * imputed values depend on the rank, so its leading J' terms are not the
 * rank-J' fit; those runs are factored again for every J of the list, on the
 * same sampled matrix.  The "fit" column says which ("nested" or "refit").
 *
 * Outputs in the folder: study.csv, study.json, study.dat + study.gp (the
 * gnuplot data and script) and study.png (headline error vs J, log y). */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "cli.h"
#include "pipeline.h"

#define DEFAULT_OUT "sepbrdf-study"
#define MAX_J 256 /* sb_metric_t holds 256 terms */

static void help(void) {
    printf("usage: sepbrdf study SOURCE... [OPTIONS]\n"
           "\n"
           "For every SOURCE x parameterisation x J, factor and measure: headline error\n"
           "(f cos theta_i as the shader returns it, out of sample; the one to compare\n"
           "across parameterisations), comparable (f cos cos), native relative RMS and max error of the matrix, the\n"
           "fraction of pairs reconstructed negative, and times. Writes into the folder:\n"
           "  study.csv            one row per source x parameterisation x J\n"
           "  study.json           the same with settings, failures and fit details\n"
           "  study.png            headline error vs J, log scale, one line per\n"
           "                       source/parameterisation (needs gnuplot; study.gp and\n"
           "                       study.dat are the script and data it ran)\n"
           "and prints a table on stdout.\n"
           "\n"
           "SOURCE  MODEL[:key=value,...] (see `sepbrdf list`) or a measured file.\n"
           "\n"
           "options:\n"
           "  -o, --out DIR        output folder, created if missing (default ./" DEFAULT_OUT ")\n"
           "  -J, --terms LIST     the J to study: N (= 1..N), A..B, or a comma list of\n"
           "                       numbers and ranges (1..4,8,16); 1..256 (default 1..8)\n"
           "      --param LIST     parameterisations, comma separated (io,io-area,hd,iso),\n"
           "                       or all (default): every one this build supports, iso\n"
           "                       only for isotropic sources\n"
           "  -r, --res R          cells per angular axis, 2..512 (default 32)\n"
           "      --form F         f (default), cos, cos2: what is factored\n"
           "      --weighted       solid-angle weighted fit\n"
           "      --zero-fill      factor invalid cells as zeros instead of a masked fit\n"
           "      --method M       auto (default), full, topk, randomized\n"
           "      --metric-res R   reference grid of the comparable error (default 32)\n" CLI_MEASURED_HELP
               CLI_VERBOSITY_HELP "\n"
           "Each source x parameterisation is sampled once and, unless the fit is masked,\n"
           "factored once with the largest J: the leading J' terms of a truncated SVD are\n"
           "the rank-J' SVD, so every J' <= J is read from it (fit \"nested\"). A masked\n"
           "fit (cells outside the domain or unmeasured, without --zero-fill) is refitted\n"
           "for every J (fit \"refit\"): its leading terms are not the lower-rank fit.\n"
           "\n"
           "A source or parameterisation that fails is reported and skipped; the others'\n"
           "results are still written, and the exit status is then 2.\n"
           "\n" CLI_EXIT_HELP);
}

typedef struct study_opts {
    const char **sources;
    size_t nsources;
    const char *out;
    size_t res, metric_res;
    unsigned char want_j[MAX_J + 1]; /* want_j[J] = 1 if J is studied */
    size_t jmax, nj;
    int param_all;
    unsigned params; /* bit per sb_param_kind_t when not all */
    sb_form_t form;
    int weighted, zero_fill;
    sb_method_t method;
    sb_measured_opts_t mo; /* measured tables among the sources */
} study_opts_t;

/* Errors after J terms of one run. */
typedef struct row {
    size_t terms;
    double headline, comparable, rel_rms, max_abs, neg_frac;
    double t_factor, t_metric; /* of the factorisation the row was read from */
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

static char *dup_str(const char *s) {
    if (!s) return NULL;
    size_t n = strlen(s) + 1;
    char *d = malloc(n);
    if (d) memcpy(d, s, n);
    return d;
}

static run_t *runs_add(runs_t *rs, const char *spec, int kind) {
    if (rs->n == rs->cap) {
        size_t cap = rs->cap ? 2 * rs->cap : 16;
        run_t *v = realloc(rs->v, cap * sizeof *v);
        if (!v) return NULL;
        rs->v = v;
        rs->cap = cap;
    }
    run_t *r = &rs->v[rs->n++];
    memset(r, 0, sizeof *r);
    r->spec = spec;
    r->kind = kind;
    return r;
}

static void runs_free(runs_t *rs) {
    for (size_t i = 0; i < rs->n; i++) {
        free(rs->v[i].source);
        free(rs->v[i].param_spec);
        free(rs->v[i].error);
        free(rs->v[i].r);
    }
    free(rs->v);
}

static void run_fail(run_t *r, const char *msg) {
    r->ok = 0;
    free(r->error);
    r->error = dup_str(msg && *msg ? msg : "failed");
}

/* ---- options ----------------------------------------------------------- */

/* "N" (1..N), or a comma list of "J" and "A..B" items. */
static int parse_terms(const char *s, study_opts_t *o) {
    memset(o->want_j, 0, sizeof o->want_j);
    char *end;
    int single = strchr(s, ',') == NULL && strstr(s, "..") == NULL;
    const char *p = s;
    for (;;) {
        errno = 0;
        if (*p < '0' || *p > '9') goto bad;
        unsigned long a = strtoul(p, &end, 10), b = a;
        if (end == p || errno) goto bad;
        p = end;
        if (p[0] == '.' && p[1] == '.') {
            p += 2;
            if (*p < '0' || *p > '9') goto bad;
            b = strtoul(p, &end, 10);
            if (end == p || errno) goto bad;
            p = end;
        } else if (single) {
            b = a;
            a = 1;
        }
        if (a < 1 || b > MAX_J || a > b) {
            cli_error("study", "--terms '%s': %lu..%lu out of range, need 1 <= A <= B <= %d", s, a, b, MAX_J);
            return -1;
        }
        for (unsigned long j = a; j <= b; j++)
            o->want_j[j] = 1;
        if (*p == 0) break;
        if (*p != ',') goto bad;
        p++;
    }
    o->jmax = o->nj = 0;
    for (size_t j = 1; j <= MAX_J; j++)
        if (o->want_j[j]) {
            o->jmax = j;
            o->nj++;
        }
    return 0;
bad:
    cli_error("study", "--terms '%s' is not a J list: need N (1..N), A..B, or a comma list such as 1..4,8,16", s);
    return -1;
}

static int parse_params(const char *s, study_opts_t *o) {
    if (strcmp(s, "all") == 0) {
        o->param_all = 1;
        return 0;
    }
    o->param_all = 0;
    o->params = 0;
    char buf[256];
    if (strlen(s) >= sizeof buf || !*s) goto bad;
    strcpy(buf, s);
    for (char *save = NULL, *t = strtok_r(buf, ",", &save); t; t = strtok_r(NULL, ",", &save)) {
        sb_param_kind_t k;
        if (sb_param_kind_parse(t, &k) != SB_OK) {
            cli_error("study", "--param '%s' unknown, need a comma list of %s, or all", t, cli_param_names());
            return -1;
        }
        o->params |= 1u << k;
    }
    if (o->params) return 0;
bad:
    cli_error("study", "--param '%s': need a comma list of %s, or all", s, cli_param_names());
    return -1;
}

static int parse(int argc, char **argv, study_opts_t *o) {
    static const char *const n_res[] = {"-r", "--res", NULL}, *const n_terms[] = {"-J", "--terms", NULL},
                             *const n_param[] = {"--param", NULL}, *const n_form[] = {"--form", NULL},
                             *const n_method[] = {"--method", NULL}, *const n_help[] = {"-h", "--help", NULL},
                             *const n_weighted[] = {"--weighted", NULL}, *const n_zero[] = {"--zero-fill", NULL},
                             *const n_mres[] = {"--metric-res", NULL};
    cli_args_t a = {argc, 1, argv, "study"};
    for (; a.i < argc; a.i++) {
        const char *v = NULL;
        int m;
        if (cli_opt(&a, n_help, 0, &v)) {
            help();
            return EXIT_OK;
        }
        if ((m = cli_out_opt(&a, "folder", &o->out))) {
            if (m < 0) return EXIT_USAGE;
        } else if ((m = cli_opt(&a, n_res, 1, &v))) {
            if (m < 0 || cli_parse_size("study", "--res", v, 2, 512, &o->res)) return EXIT_USAGE;
        } else if ((m = cli_opt(&a, n_terms, 1, &v))) {
            if (m < 0 || parse_terms(v, o)) return EXIT_USAGE;
        } else if ((m = cli_opt(&a, n_param, 1, &v))) {
            if (m < 0 || parse_params(v, o)) return EXIT_USAGE;
        } else if ((m = cli_opt(&a, n_form, 1, &v))) {
            if (m < 0) return EXIT_USAGE;
            if (sb_form_parse(v, &o->form) != SB_OK) {
                cli_error("study", "--form '%s' unknown, need one of f, cos, cos2", v);
                return EXIT_USAGE;
            }
        } else if ((m = cli_opt(&a, n_method, 1, &v))) {
            if (m < 0) return EXIT_USAGE;
            if (sb_method_parse(v, &o->method) != SB_OK) {
                cli_error("study", "--method '%s' unknown, need one of auto, full, topk, randomized", v);
                return EXIT_USAGE;
            }
        } else if ((m = cli_opt(&a, n_mres, 1, &v))) {
            if (m < 0 || cli_parse_size("study", "--metric-res", v, 2, 256, &o->metric_res)) return EXIT_USAGE;
        } else if (cli_opt(&a, n_weighted, 0, &v)) {
            o->weighted = 1;
        } else if (cli_opt(&a, n_zero, 0, &v)) {
            o->zero_fill = 1;
        } else if ((m = cli_measured_opt(&a, &o->mo))) {
            if (m < 0) return EXIT_USAGE;
        } else if (cli_verbosity_opt(argv[a.i])) {
        } else if (argv[a.i][0] == '-' && argv[a.i][1]) {
            cli_error("study", "unknown option '%s' (see `sepbrdf study --help`)", argv[a.i]);
            return EXIT_USAGE;
        } else {
            o->sources[o->nsources++] = argv[a.i];
        }
    }
    if (o->nsources == 0) {
        cli_error("study", "no SOURCE given (see `sepbrdf study --help`)");
        return EXIT_USAGE;
    }
    return -1; /* go on */
}

/* ---- running ----------------------------------------------------------- */

/* Fill run r from the metric and errors of a factorisation with J terms:
 * the rows for every studied J' <= J (nested), or only J itself (refit). */
static int take_rows(run_t *r, const study_opts_t *o, const attempt_t *a, size_t J, int only_j) {
    const sb_factor_errors_t *e = sb_factors_errors(a->f);
    size_t have = sb_factors_terms(a->f);
    for (size_t j = only_j ? J : 1; j <= J; j++) {
        if (!o->want_j[j] || j > have) continue;
        row_t *w = &r->r[r->nr++];
        w->terms = j;
        w->headline = attempt_headline(a, j);
        w->comparable = attempt_comparable(a, j);
        w->rel_rms = e->rel_rms[sb_err_at(j - 1, SB_CH_ALL)];
        w->max_abs = e->max_abs[sb_err_at(j - 1, SB_CH_ALL)];
        w->neg_frac = attempt_negative(a, j);
        w->t_factor = a->t_factor;
        w->t_metric = a->t_metric;
    }
    if (a->stats.fit_iterations > r->iterations) r->iterations = a->stats.fit_iterations;
    if (a->stats.masked && !a->stats.fit_converged) r->converged = 0;
    return 0;
}

/* Sample once, factor once (nested) or once per J (masked). */
static void run_one(sb_context_t *ctx, const sb_source_t *src, const study_opts_t *o, run_t *r, size_t task,
                    size_t ntasks) {
    char label[64];
    snprintf(label, sizeof label, "study %zu/%zu %s", task + 1, ntasks, sb_param_kind_name((sb_param_kind_t)r->kind));
    double base = (double)task / (double)ntasks, span = 1.0 / (double)ntasks;
    pipe_opts_t po = {o->res, o->jmax, o->metric_res, 90, 0, o->method, 1, o->zero_fill, label, base, 0.3 * span, 0,
                      0,      0,       NULL,          0,  0};
    attempt_t a;
    sb_context_clear_error(ctx);
    sb_result_t res = sb_pairs_create(ctx, src, NULL, &po.pairs); /* shared by every J */
    if (res == SB_OK)
        res = attempt_sample(ctx, src, &po, (sb_param_kind_t)r->kind, o->form, &a);
    else
        memset(&a, 0, sizeof a);
    if (a.param) r->param_spec = dup_str(sb_param_spec(a.param));
    r->r = calloc(o->nj, sizeof *r->r);
    if (res == SB_OK && !r->r) res = sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    if (res != SB_OK) {
        run_fail(r, sb_context_last_error(ctx));
        attempt_free(&a);
        sb_pairs_destroy(po.pairs);
        return;
    }
    r->rows = a.m.rows;
    r->cols = a.m.cols;
    r->t_sample = a.t_sample;
    r->masked = attempt_masked(&a);
    r->converged = 1;
    if (!r->masked) {
        cli_progress(label, base + 0.3 * span);
        res = attempt_factor(ctx, src, &po, o->jmax, o->weighted, &a);
        if (res == SB_OK) take_rows(r, o, &a, o->jmax, 0);
    } else {
        size_t done = 0;
        for (size_t j = 1; j <= o->jmax && res == SB_OK; j++) {
            if (!o->want_j[j]) continue;
            cli_progress(label, base + span * (0.3 + 0.7 * (double)done++ / (double)o->nj));
            res = attempt_factor(ctx, src, &po, j, o->weighted, &a);
            if (res == SB_OK) take_rows(r, o, &a, j, 1);
        }
    }
    cli_progress(label, base + span);
    if (res != SB_OK)
        run_fail(r, sb_context_last_error(ctx));
    else
        r->ok = 1;
    attempt_free(&a);
    sb_pairs_destroy(po.pairs);
}

/* ---- outputs ----------------------------------------------------------- */

static void csv_field(FILE *fp, const char *s) {
    if (!s) s = "";
    if (!strpbrk(s, ",\"\n\r")) {
        fputs(s, fp);
        return;
    }
    fputc('"', fp);
    for (; *s; s++) {
        if (*s == '"') fputc('"', fp);
        fputc(*s, fp);
    }
    fputc('"', fp);
}

static void write_csv(FILE *fp, const study_opts_t *o, const runs_t *rs) {
    fprintf(fp, "source,param,param_spec,form,weighted,fit,terms,comparable,rel_rms,max_abs,negative_fraction,"
                "sample_s,factor_s,metric_s,headline\n");
    for (size_t i = 0; i < rs->n; i++) {
        const run_t *r = &rs->v[i];
        if (!r->ok) continue;
        for (size_t k = 0; k < r->nr; k++) {
            const row_t *w = &r->r[k];
            csv_field(fp, r->spec);
            fprintf(fp, ",%s,", sb_param_kind_name((sb_param_kind_t)r->kind));
            csv_field(fp, r->param_spec);
            fprintf(fp, ",%s,%d,%s,%zu,%.9g,%.9g,%.9g,%.9g,%.6f,%.6f,%.6f,%.9g\n", sb_form_name(o->form), o->weighted,
                    r->masked ? "refit" : "nested", w->terms, w->comparable, w->rel_rms, w->max_abs, w->neg_frac,
                    r->t_sample, w->t_factor, w->t_metric, w->headline);
        }
    }
}

static void write_json(FILE *fp, const study_opts_t *o, const runs_t *rs, size_t failed, const char *plot) {
    json_t j = {fp, 0, {0}};
    json_begin_object(&j, NULL);
    json_string(&j, "sepbrdf_version", SB_VERSION_STRING);
    json_string(&j, "command", "study");
    json_begin_object(&j, "settings");
    json_int(&j, "resolution", (long long)o->res);
    json_begin_array(&j, "terms");
    for (size_t J = 1; J <= MAX_J; J++)
        if (o->want_j[J]) json_int(&j, NULL, (long long)J);
    json_end_array(&j);
    json_begin_array(&j, "params");
    if (o->param_all) json_string(&j, NULL, "all");
    for (int k = 0; k < SB_PARAM_KIND_COUNT_ && !o->param_all; k++)
        if (o->params & (1u << k)) json_string(&j, NULL, sb_param_kind_name((sb_param_kind_t)k));
    json_end_array(&j);
    json_string(&j, "form", sb_form_name(o->form));
    json_bool(&j, "weighted", o->weighted);
    json_bool(&j, "zero_fill", o->zero_fill);
    json_string(&j, "method", sb_method_name(o->method));
    json_int(&j, "metric_resolution", (long long)o->metric_res);
    json_end_object(&j);
    json_begin_array(&j, "runs");
    for (size_t i = 0; i < rs->n; i++) {
        const run_t *r = &rs->v[i];
        json_begin_object(&j, NULL);
        json_string(&j, "source_spec", r->spec);
        json_string(&j, "source", r->source);
        json_string(&j, "param", r->kind >= 0 ? sb_param_kind_name((sb_param_kind_t)r->kind) : NULL);
        json_string(&j, "param_spec", r->param_spec);
        json_bool(&j, "ok", r->ok);
        if (!r->ok) {
            json_string(&j, "error", r->error);
            json_end_object(&j);
            continue;
        }
        json_int(&j, "rows", (long long)r->rows);
        json_int(&j, "cols", (long long)r->cols);
        json_string(&j, "fit", r->masked ? "refit" : "nested");
        json_bool(&j, "masked", r->masked);
        if (r->masked) {
            json_int(&j, "fit_iterations", r->iterations);
            json_bool(&j, "fit_converged", r->converged);
        }
        json_number(&j, "sample_s", r->t_sample);
        json_begin_array(&j, "results");
        for (size_t k = 0; k < r->nr; k++) {
            const row_t *w = &r->r[k];
            json_begin_object(&j, NULL);
            json_int(&j, "terms", (long long)w->terms);
            json_number(&j, "headline", w->headline);
            json_number(&j, "comparable", w->comparable);
            json_number(&j, "rel_rms", w->rel_rms);
            json_number(&j, "max_abs", w->max_abs);
            json_number(&j, "negative_fraction", w->neg_frac);
            json_number(&j, "factor_s", w->t_factor);
            json_number(&j, "metric_s", w->t_metric);
            json_end_object(&j);
        }
        json_end_array(&j);
        json_end_object(&j);
    }
    json_end_array(&j);
    json_int(&j, "failed", (long long)failed);
    json_begin_object(&j, "files");
    json_string(&j, "csv", "study.csv");
    json_string(&j, "plot", plot);
    json_string(&j, "gnuplot_script", "study.gp");
    json_string(&j, "gnuplot_data", "study.dat");
    json_end_object(&j);
    json_end_object(&j);
}

/* Smallest value drawn on the log axis (an exact fit has error 0). */
#define PLOT_FLOOR 1e-16

static void write_dat(FILE *fp, const runs_t *rs) {
    int block = 0;
    for (size_t i = 0; i < rs->n; i++) {
        const run_t *r = &rs->v[i];
        if (!r->ok || !r->nr) continue;
        if (block++) fputs("\n\n", fp); /* gnuplot: two blank lines end an index block */
        fprintf(fp, "# %s (%s)\n# J headline rel_rms\n", r->spec, sb_param_kind_name((sb_param_kind_t)r->kind));
        for (size_t k = 0; k < r->nr; k++)
            fprintf(fp, "%zu %.9g %.9g\n", r->r[k].terms, fmax(r->r[k].headline, PLOT_FLOOR),
                    fmax(r->r[k].rel_rms, PLOT_FLOOR));
    }
}

/* gnuplot single-quoted string: no escapes, '' is a quote. */
static void gp_quote(FILE *fp, const char *s) {
    fputc('\'', fp);
    for (; *s; s++) {
        if (*s == '\'') fputc('\'', fp);
        fputc(*s, fp);
    }
    fputc('\'', fp);
}

static void write_gp(FILE *fp, const study_opts_t *o, const runs_t *rs) {
    fprintf(fp,
            "# sepbrdf study: headline error vs J. Re-run with `gnuplot study.gp` in this\n"
            "# folder; `gnuplot -e \"outfile='x.png'\" study.gp` writes elsewhere.\n"
            "# Errors below %g (exact fits) are drawn at %g.\n"
            "if (!exists(\"outfile\")) outfile = 'study.png'\n"
            "if (strstrt(GPVAL_TERMINALS, 'pngcairo') > 0) {\n"
            "    set terminal pngcairo size 1000,640 noenhanced font ',10'\n"
            "} else {\n"
            "    set terminal png size 1000,640 noenhanced\n"
            "}\n"
            "set output outfile\n"
            "set title 'sepbrdf study: R = %zu, form %s%s'\n"
            "set xlabel 'J (terms)'\n"
            "set ylabel 'headline error (relative L2 of f cos theta_i, out of sample)'\n"
            "set logscale y\n"
            "set format y '%%.0e'\n"
            "set grid\n"
            "set key below height 1.5 spacing 1.2\n"
            "set xtics 1\n"
            "set xrange [0.5:%zu.5]\n",
            PLOT_FLOOR, PLOT_FLOOR, o->res, sb_form_name(o->form), o->weighted ? ", weighted" : "", o->jmax);
    if (o->jmax > 20) fprintf(fp, "set xtics %zu\n", (o->jmax + 9) / 10);
    int block = 0;
    for (size_t i = 0; i < rs->n; i++) {
        const run_t *r = &rs->v[i];
        if (!r->ok || !r->nr) continue;
        fputs(block ? ", \\\n     " : "plot ", fp);
        fprintf(fp, "'study.dat' index %d using 1:2 with linespoints lw 2 title ", block);
        char title[512];
        snprintf(title, sizeof title, "%.200s (%s)", r->spec, sb_param_kind_name((sb_param_kind_t)r->kind));
        gp_quote(fp, title);
        block++;
    }
    fputs(block ? "\n" : "print 'no results to plot'\n", fp);
}

/* Write one output through a temporary name; 0 on success. */
typedef void (*writer_fn)(FILE *fp, const void *arg);
typedef struct out_args {
    const study_opts_t *o;
    const runs_t *rs;
    size_t failed;
    const char *plot;
} out_args_t;
static void w_csv(FILE *fp, const void *p) {
    const out_args_t *a = p;
    write_csv(fp, a->o, a->rs);
}
static void w_json(FILE *fp, const void *p) {
    const out_args_t *a = p;
    write_json(fp, a->o, a->rs, a->failed, a->plot);
}
static void w_dat(FILE *fp, const void *p) {
    const out_args_t *a = p;
    write_dat(fp, a->rs);
}
static void w_gp(FILE *fp, const void *p) {
    const out_args_t *a = p;
    write_gp(fp, a->o, a->rs);
}

/* One file of the set; messages name it in the target folder. */
static int write_file(sb_outset_t *set, const char *name, writer_fn fn, const void *arg) {
    char path[4200], tmp[4300];
    int e = cli_set_file(set, name, path, sizeof path) ? ENAMETOOLONG : 0;
    FILE *fp = e ? NULL : cli_open_tmp(path, tmp, sizeof tmp);
    if (!e && !fp) e = errno;
    if (fp) {
        fn(fp, arg);
        e = cli_commit(fp, tmp, path, 1);
    }
    if (e) cli_error("study", "%s/%s: cannot write: %s", sb_outset_target(set), name, sb_io_why(e));
    return e ? -1 : 0;
}

/* Run gnuplot on study.gp in `dir`, output to a temporary, renamed to
 * study.png on success.  1 plotted, 0 skipped (warning printed). */
static int run_gnuplot(const char *dir, const char *target) {
    const char *exe = getenv("SEPBRDF_GNUPLOT");
    if (!exe || !*exe) exe = "gnuplot";
    char tmpname[64], tmp[4300], path[4200], expr[128];
    snprintf(tmpname, sizeof tmpname, "study.png.tmp-%ld", (long)getpid());
    snprintf(tmp, sizeof tmp, "%s/%s", dir, tmpname);
    snprintf(path, sizeof path, "%s/study.png", dir);
    snprintf(expr, sizeof expr, "outfile='%s'", tmpname);
    cli_guard(tmp);
    fflush(NULL);
    pid_t pid = fork();
    if (pid == 0) { /* child: only async-signal-safe calls until exec */
        int null = open("/dev/null", O_WRONLY);
        if (null >= 0) dup2(null, 1);
        if (chdir(dir) != 0) _exit(126);
        execlp(exe, exe, "-e", expr, "study.gp", (char *)NULL);
        _exit(127);
    }
    int st = 0, ok = 0;
    if (pid < 0) {
        cli_error("study", "warning: cannot start %s (%s); study.png skipped", exe, strerror(errno));
    } else if (waitpid(pid, &st, 0) < 0) {
        cli_error("study", "warning: %s: %s; study.png skipped", exe, strerror(errno));
    } else if (WIFEXITED(st) && WEXITSTATUS(st) == 127) {
        cli_error("study",
                  "warning: %s not found (install gnuplot); study.png skipped, study.gp and study.dat "
                  "are written",
                  exe);
    } else if (!WIFEXITED(st) || WEXITSTATUS(st) != 0) {
        cli_error("study", "warning: %s failed on %s/study.gp; study.png skipped", exe, target);
    } else if (rename(tmp, path) != 0) {
        cli_error("study", "warning: %s/study.png: cannot rename: %s", target, strerror(errno));
    } else {
        ok = 1;
    }
    if (!ok) unlink(tmp);
    cli_unguard(tmp);
    return ok;
}

static void print_table(const runs_t *rs) {
    printf("%-30s %-7s %4s  %11s  %11s  %11s  %11s  %8s  %8s  %s\n", "source", "param", "J", "headline", "comparable",
           "rel_rms", "max_abs", "negative", "time_s", "fit");
    for (size_t i = 0; i < rs->n; i++) {
        const run_t *r = &rs->v[i];
        const char *pn = r->kind >= 0 ? sb_param_kind_name((sb_param_kind_t)r->kind) : "-";
        if (!r->ok) {
            printf("%-30.30s %-7s  failed: %s\n", r->spec, pn, r->error ? r->error : "");
            continue;
        }
        for (size_t k = 0; k < r->nr; k++) {
            const row_t *w = &r->r[k];
            printf("%-30.30s %-7s %4zu  %11.4e  %11.4e  %11.4e  %11.4e  %7.2f%%  %8.3f  %s\n", r->spec, pn, w->terms,
                   w->headline, w->comparable, w->rel_rms, w->max_abs, 100 * w->neg_frac,
                   r->t_sample + w->t_factor + w->t_metric, r->masked ? "refit" : "nested");
        }
    }
}

int cmd_study(int argc, char **argv) {
    study_opts_t o = {0};
    o.sources = calloc((size_t)argc + 1, sizeof *o.sources);
    if (!o.sources) {
        cli_error("study", "out of memory");
        return EXIT_IO;
    }
    o.out = DEFAULT_OUT;
    o.res = 32;
    o.metric_res = 32;
    o.param_all = 1;
    o.form = SB_FORM_F;
    o.method = SB_METHOD_AUTO;
    parse_terms("1..8", &o);
    int rc = parse(argc, argv, &o);
    if (rc >= 0) {
        free(o.sources);
        return rc;
    }
    if ((rc = cli_check_outdir("study", "--out", o.out)) != EXIT_OK) {
        free(o.sources);
        return rc;
    }

    sb_context_t *ctx = NULL;
    sb_outset_t *set = NULL;
    runs_t rs = {0};
    sb_source_t **srcs = calloc(o.nsources, sizeof *srcs);
    size_t *first_run = calloc(o.nsources + 1, sizeof *first_run);
    if (!srcs || !first_run || sb_context_create(&ctx) != SB_OK) {
        cli_error("study", "out of memory");
        rc = EXIT_IO;
        goto out;
    }
    double t0 = cli_now();

    /* Open every source and list its runs first: bad files and specs are
     * reported before the long work, and the progress bar knows its end. */
    for (size_t s = 0; s < o.nsources; s++) {
        first_run[s] = rs.n;
        sb_context_clear_error(ctx);
        sb_result_t r = pipe_source_open(ctx, o.sources[s], &o.mo, &srcs[s]);
        if (r != SB_OK) {
            run_t *ru = runs_add(&rs, o.sources[s], -1);
            if (!ru) goto nomem;
            run_fail(ru, sb_context_last_error(ctx));
            cli_error("study", "%s (skipped)", ru->error); /* the message names the source */
            continue;
        }
        unsigned flags = sb_source_flags(srcs[s]);
        for (int k = 0; k < SB_PARAM_KIND_COUNT_; k++) {
            if (!o.param_all && !(o.params & (1u << k))) continue;
            int iso_ok = sb_param_kind_applies((sb_param_kind_t)k, flags);
            sb_param_t *probe = NULL;
            sb_param_opts_t pp = {0};
            pp.res = o.res;
            sb_context_clear_error(ctx);
            sb_result_t pr = iso_ok ? sb_param_create(ctx, (sb_param_kind_t)k, &pp, &probe) : SB_ERR_UNSUPPORTED;
            sb_param_destroy(probe);
            if (o.param_all && pr != SB_OK) continue; /* all = those that apply */
            run_t *ru = runs_add(&rs, o.sources[s], k);
            if (!ru) goto nomem;
            ru->source = dup_str(sb_source_description(srcs[s]));
            if (!iso_ok) {
                run_fail(ru, "iso needs an isotropic source");
            } else if (pr != SB_OK) {
                run_fail(ru, sb_context_last_error(ctx));
            } else {
                ru->ok = -1; /* to run */
                continue;
            }
            cli_error("study", "%s on %s: %s (skipped)", o.sources[s], sb_param_kind_name((sb_param_kind_t)k),
                      ru->error);
        }
    }
    first_run[o.nsources] = rs.n;
    size_t ntasks = 0, task = 0;
    for (size_t i = 0; i < rs.n; i++)
        ntasks += rs.v[i].ok == -1;
    for (size_t s = 0; s < o.nsources; s++)
        for (size_t i = first_run[s]; i < first_run[s + 1]; i++) {
            run_t *ru = &rs.v[i];
            if (ru->ok != -1) continue;
            run_one(ctx, srcs[s], &o, ru, task++, ntasks);
            if (!ru->ok) {
                cli_error("study", "%s on %s: %s (skipped)", ru->spec, sb_param_kind_name((sb_param_kind_t)ru->kind),
                          ru->error);
                continue;
            }
            cli_info(2, "study: %s on %s done (%s)", ru->spec, ru->param_spec, ru->masked ? "refit" : "nested");
        }
    cli_progress_done();

    size_t failed = 0, good = 0;
    for (size_t i = 0; i < rs.n; i++) {
        if (rs.v[i].ok)
            good++;
        else
            failed++;
    }
    /* The files go into a staging folder published in one step (outset.h),
     * so the folder never mixes files of two studies. */
    if (!(set = cli_outset_begin(ctx, "study", o.out, &rc))) goto out;
    out_args_t oa = {&o, &rs, failed, NULL};
    int plotted = 0;
    if (write_file(set, "study.csv", w_csv, &oa) || write_file(set, "study.dat", w_dat, &oa) ||
        write_file(set, "study.gp", w_gp, &oa)) {
        rc = EXIT_IO;
        goto out;
    }
    if (good) plotted = run_gnuplot(sb_outset_dir(set), o.out);
    oa.plot = plotted ? "study.png" : NULL;
    if (write_file(set, "study.json", w_json, &oa)) {
        rc = EXIT_IO;
        goto out;
    }
    rc = cli_outset_end(ctx, "study", set, 1);
    set = NULL;
    if (rc != EXIT_OK) goto out;
    if (g_verbosity >= 1) {
        print_table(&rs);
        printf("wrote study.csv, study.json%s to %s/ (%zu runs ok, %zu failed, %.3f s)\n", plotted ? ", study.png" : "",
               o.out, good, failed, cli_now() - t0);
    }
    if (failed)
        cli_error("study", "%zu of %zu runs failed; the results of the other %zu are written", failed, rs.n, good);
    rc = failed ? EXIT_IO : EXIT_OK;
    goto out;
nomem:
    cli_progress_done();
    cli_error("study", "out of memory");
    rc = EXIT_IO;
out:
    cli_outset_end(ctx, "study", set, 0); /* a set not published: discarded */
    for (size_t s = 0; srcs && s < o.nsources; s++)
        sb_source_destroy(srcs[s]);
    free(srcs);
    free(first_run);
    runs_free(&rs);
    sb_context_destroy(ctx);
    free(o.sources);
    return rc;
}
