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
#include <stddef.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "cli.h"
#include "pipeline.h"
#include "study.h"

#define DEFAULT_OUT "sepbrdf-study"

static int set_terms(const char *cmd, const cli_option_t *op, const char *v, void *dst);
static int set_params(const char *cmd, const cli_option_t *op, const char *v, void *dst);
static int set_budgets(const char *cmd, const cli_option_t *op, const char *v, void *dst);
/* The options of `study` alone (stored into its study_opts_t). */
static const cli_option_t study_only[] = {
    {"-J", "--terms", "LIST",
     "the J to study: N (= 1..N), A..B, or a comma list of\nnumbers and ranges (1..4,8,16); 1..256 (default 1..8)",
     set_terms, 0, 0, 0, CLI_STUDY},
    {NULL, "--param", "LIST",
     "parameterisations, comma separated (auto,io,hd,...):\nauto (default) studies what `factor SOURCE -J J` builds\n"
     "at every J (its layout, form, weighting, warps and term\nweights, one run per J; the table names the layout "
     "kept);\n"
     "all: every one this build supports, as `factor --param P`\n(iso only for isotropic sources)",
     set_params, 0, 0, 0, CLI_STUDY},
    {NULL, "--nmf", NULL,
     "also fit non-negative factors (--method nmf) with every J\nstudied and show their errors beside (nmf_headline,\n"
     "nmf_rel_rms): what positivity costs at each J",
     cli_set_flag, offsetof(study_opts_t, nmf), 0, 0, CLI_STUDY},
    {NULL, "--budget", "LIST",
     "byte budgets, comma separated (e.g. 4K,16K,48KiB): per\n"
     "source x layout (auto, or each of --param's list) x budget\n"
     "the choice of `factor --budget` and its headline error;\n"
     "study.png plots error against bytes (not with --terms)",
     set_budgets, 0, 0, 0, CLI_STUDY},
    {0},
};

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
           "  -o, --out DIR        output folder, created if missing (default ./" DEFAULT_OUT ")\n");
    cli_table_help(study_only, CLI_STUDY);
    cli_table_help(cli_factor_options, CLI_STUDY);
    printf(CLI_MEASURED_HELP CLI_VERBOSITY_HELP
           "\n"
           "A layout named (and auto) is fitted as `factor --param P -J J` fits it, one\n"
           "whole run per J (its forms, weighting, warps and term weights as auto's).\n"
           "With --form and --unweighted given (the plain fit), and --warp on iso, hd\n"
           "and vh (without it factor may try the adaptive warp), each source x\n"
           "parameterisation is sampled once and, unless the fit is masked,\n"
           "factored once with the largest J: the leading J' terms of a truncated SVD are\n"
           "the rank-J' SVD, so every J' <= J is read from it (fit \"nested\"). A masked\n"
           "fit (cells outside the domain or unmeasured, without --zero-fill) is refitted\n"
           "for every J (fit \"refit\"): its leading terms are not the lower-rank fit.\n"
           "\n"
           "A source or parameterisation that fails is reported and skipped; the others'\n"
           "results are still written, and the exit status is then 2.\n"
           "\n" CLI_EXIT_HELP);
}

char *study_dup(const char *s) {
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
        for (size_t k = 0; k < rs->v[i].nwarn; k++)
            free(rs->v[i].warn[k]);
        for (size_t k = 0; k < rs->v[i].nr; k++)
            free(rs->v[i].r[k].spec);
        free(rs->v[i].r);
    }
    free(rs->v);
}

void study_run_fail(run_t *r, const char *msg) {
    r->ok = 0;
    free(r->error);
    r->error = study_dup(msg && *msg ? msg : "failed");
}

/* Print the job's warnings and keep them for study.json: after the last
 * refactor, which checks again what the run asks of a measured table. */
void study_run_warnings(run_t *r, const sb_job_t *job, const char *param) {
    for (size_t i = 0; job && i < sb_job_warning_count(job); i++) {
        cli_error("study", "warning: %s on %s: %s", r->spec, param, sb_job_warning(job, i));
        if (r->nwarn < sizeof r->warn / sizeof r->warn[0]) r->warn[r->nwarn++] = study_dup(sb_job_warning(job, i));
    }
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
    o->param_auto = 0;
    if (strcmp(s, "all") == 0) {
        o->param_all = 1;
        return 0;
    }
    o->param_all = 0;
    o->params = 0;
    char buf[256];
    if (strlen(s) >= sizeof buf || !*s) goto bad;
    if (cli_list_items("study", "--param", s)) return -1;
    strcpy(buf, s);
    for (char *save = NULL, *t = strtok_r(buf, ",", &save); t; t = strtok_r(NULL, ",", &save)) {
        sb_param_kind_t k;
        if (strcmp(t, "auto") == 0) {
            o->param_auto = 1;
            continue;
        }
        if (sb_param_kind_parse(t, &k) != SB_OK) {
            cli_error("study", "--param '%s' unknown, need a comma list of auto, %s, or all", t, cli_param_names());
            return -1;
        }
        o->params |= 1u << k;
    }
    if (o->params || o->param_auto) return 0;
bad:
    cli_error("study", "--param '%s': need a comma list of auto, %s, or all", s, cli_param_names());
    return -1;
}

static int set_terms(const char *cmd, const cli_option_t *op, const char *v, void *dst) {
    (void)cmd, (void)op;
    ((study_opts_t *)dst)->terms_given = 1;
    return parse_terms(v, dst);
}

static int set_budgets(const char *cmd, const cli_option_t *op, const char *v, void *dst) {
    (void)cmd, (void)op;
    return study_parse_budgets(v, dst);
}

static int set_params(const char *cmd, const cli_option_t *op, const char *v, void *dst) {
    (void)cmd, (void)op;
    return parse_params(v, dst);
}

static int parse(int argc, char **argv, study_opts_t *o) {
    cli_parser_t p = {.cmd = "study",
                      .help = help,
                      .out_what = "folder",
                      .out = &o->out,
                      .tables = {{study_only, CLI_STUDY, o, NULL}, {cli_factor_options, CLI_STUDY, &o->job, NULL}},
                      .measured = &o->job.measured,
                      .what = "SOURCE",
                      .args = o->sources,
                      .max_args = (size_t)argc,
                      .nargs = &o->nsources};
    int rc = cli_parse(argc, argv, &p);
    if (rc < 0 && o->nsources == 0) {
        cli_error("study", "no SOURCE given (see `sepbrdf study --help`)");
        return EXIT_USAGE;
    }
    return rc; /* -1: go on */
}

/* ---- running ----------------------------------------------------------- */

/* Fill run r from the metric and errors of the job's factorisation with J
 * terms: the rows for every studied J' <= J (nested), or only J (refit). */
void study_take_rows(run_t *r, const study_opts_t *o, const sb_job_t *job, size_t J, int only_j) {
    const sb_factors_t *f = sb_job_factors(job);
    const sb_factor_errors_t *e = sb_factors_errors(f);
    size_t have = sb_factors_terms(f);
    sb_job_timings_t t;
    sb_job_timings(job, &t);
    for (size_t j = only_j ? J : 1; j <= J; j++) {
        if (!o->want_j[j] || j > have) continue;
        row_t *w = &r->r[r->nr++];
        w->terms = j;
        w->headline = sb_job_headline(job, j);
        w->comparable = sb_job_comparable(job, j);
        w->rel_rms = e->rel_rms[sb_err_at(j - 1, SB_CH_ALL)];
        w->max_abs = e->max_abs[sb_err_at(j - 1, SB_CH_ALL)];
        w->neg_frac = sb_job_negative(job, j);
        w->t_factor = t.factor_s;
        w->t_metric = t.metric_s;
    }
    sb_plan_stats_t st;
    sb_job_stats(job, &st);
    if (st.fit_iterations > r->iterations) r->iterations = st.fit_iterations;
    if (st.masked && !st.fit_converged) r->converged = 0;
}

/* --nmf: the non-negative fit with each studied J (its terms are not
 * nested: one fit per J), its headline and rel_rms beside the row of that
 * J; NaN where it fails (reported, the run stays good). */
void study_nmf_rows(sb_context_t *ctx, const sb_source_t *src, run_t *r, const sb_job_opts_t *base) {
    sb_job_opts_t jo = *base;
    jo.method = SB_METHOD_NMF;
    sb_job_t *job = NULL;
    sb_result_t res = sb_job_run_source(ctx, src, &jo, &job);
    for (size_t k = 0; k < r->nr; k++) {
        row_t *w = &r->r[k];
        w->nmf_headline = w->nmf_rel_rms = NAN;
        if (res == SB_OK && (res = sb_job_refactor(ctx, job, w->terms)) == SB_OK) {
            w->nmf_headline = sb_job_headline(job, w->terms);
            w->nmf_rel_rms = sb_factors_errors(sb_job_factors(job))->rel_rms[sb_err_at(w->terms - 1, SB_CH_ALL)];
        }
    }
    if (res != SB_OK) cli_error("study", "%s on %s: nmf: %s", r->spec, jo.param, sb_context_last_error(ctx));
    sb_job_destroy(job);
}

/* Sample once (the job on one parameterisation), factor once (nested) or
 * once per J (masked). */
static void run_one(sb_context_t *ctx, const sb_source_t *src, const study_opts_t *o, run_t *r, size_t task,
                    size_t ntasks) {
    char label[64];
    snprintf(label, sizeof label, "study %zu/%zu %s", task + 1, ntasks, study_kind_name(r->kind));
    double base = (double)task / (double)ntasks, span = 1.0 / (double)ntasks;
    /* a layout named alone is fitted as `factor --param P` fits it, one
     * run per J; sampled once only for the plain fit (--form and
     * --unweighted given, and --warp on a layout that takes one: factor
     * tries the adaptive warp where the layout's own leaves over 5 %;
     * GGX 0.3 on hd --form f --unweighted, R = 16: 0.278 sampled once
     * against factor's 0.0086), whose truncations nest */
    int warp_set = o->job.warp || !(sb_param_kind_caps((sb_param_kind_t)r->kind) & SB_CAP_WARPS);
    if (r->kind == STUDY_AUTO || !(o->job.form && o->job.weighted < 0 && warp_set)) {
        study_run_auto(ctx, src, o, r, label, base, span);
        cli_progress(label, base + span);
        return;
    }
    sb_job_opts_t jo = o->job;
    jo.param = sb_param_kind_name((sb_param_kind_t)r->kind);
    jo.terms = o->jmax;
    jo.sample_only = 1;
    sb_job_t *job = NULL;
    sb_context_clear_error(ctx);
    cli_progress(label, base);
    sb_result_t res = sb_job_run_source(ctx, src, &jo, &job);
    if (job) r->param_spec = study_dup(sb_param_spec(sb_job_param(job)));
    r->r = calloc(o->nj, sizeof *r->r);
    if (res == SB_OK && !r->r) res = sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    if (res != SB_OK) {
        char msg[1024];
        cli_job_message(msg, sizeof msg, ctx, res, jo.terms);
        study_run_fail(r, msg);
        study_run_warnings(r, job, jo.param);
        sb_job_destroy(job);
        return;
    }
    r->rows = sb_job_matrix(job)->rows;
    r->cols = sb_job_matrix(job)->cols;
    sb_job_timings_t t;
    sb_job_timings(job, &t);
    r->t_sample = t.sample_s;
    r->masked = sb_job_masked(job);
    r->converged = 1;
    size_t done = 0, failed_j = 0;
    for (size_t j = r->masked ? 1 : o->jmax; j <= o->jmax && res == SB_OK; j++) {
        if (r->masked && !o->want_j[j]) continue;
        cli_progress(label, base + span * (0.3 + 0.7 * (double)done++ / (double)o->nj));
        if ((res = sb_job_refactor(ctx, job, j)) == SB_OK) study_take_rows(r, o, job, j, r->masked);
        failed_j = j;
    }
    if (res == SB_OK && o->nmf) study_nmf_rows(ctx, src, r, &jo);
    cli_progress(label, base + span);
    if (res != SB_OK) {
        char msg[1024];
        cli_job_message(msg, sizeof msg, ctx, res, failed_j);
        study_run_fail(r, msg);
    } else {
        r->ok = 1;
    }
    study_run_warnings(r, job, jo.param);
    sb_job_destroy(job);
}

/* ---- outputs ----------------------------------------------------------- */

static void print_table(const study_opts_t *o, const runs_t *rs) {
    printf("%-30s %-12s %4s  %11s  %11s  %11s  %11s  %8s  %8s  %s", "source", "param", "J", "headline", "comparable",
           "rel_rms", "max_abs", "negative", "time_s", "fit");
    printf(o->nmf ? "   %12s  %11s\n" : "\n", "nmf_headline", "nmf_rel_rms");
    for (size_t i = 0; i < rs->n; i++) {
        const run_t *r = &rs->v[i];
        const char *pn = r->kind >= 0 ? study_kind_name(r->kind) : "-";
        if (!r->ok) {
            printf("%-30.30s %-12s  failed: %s\n", r->spec, pn, r->error ? r->error : "");
            continue;
        }
        for (size_t k = 0; k < r->nr; k++) {
            const row_t *w = &r->r[k];
            char kept[24]; /* auto: the layout kept at this J */
            int choice = w->spec && r->kind == STUDY_AUTO;
            snprintf(kept, sizeof kept, "%s%s%.*s", pn, choice ? ">" : "", choice ? (int)strcspn(w->spec, ":") : 0,
                     choice ? w->spec : "");
            printf("%-30.30s %-12s %4zu  %11.4e  %11.4e  %11.4e  %11.4e  %7.2f%%  %8.3f  %-6s", r->spec, kept, w->terms,
                   w->headline, w->comparable, w->rel_rms, w->max_abs, 100 * w->neg_frac,
                   r->t_sample + w->t_factor + w->t_metric, r->masked ? "refit" : "nested");
            if (o->nmf) printf("  %12.4e  %11.4e", w->nmf_headline, w->nmf_rel_rms);
            printf("\n");
        }
    }
}

/* The runs of one opened source: every parameterisation asked for (all:
 * those that apply), failed ones reported at once; 0, or -1 when out of
 * memory. */
static int list_layouts(sb_context_t *ctx, const study_opts_t *o, const sb_source_t *src, const char *spec,
                        runs_t *rs) {
    unsigned flags = sb_source_flags(src);
    if (o->param_auto) {
        run_t *ru = runs_add(rs, spec, STUDY_AUTO);
        if (!ru) return -1;
        ru->source = study_dup(sb_source_description(src));
        ru->ok = -1; /* to run */
    }
    for (int k = 0; k < (int)sb_param_kind_count(); k++) {
        if (!o->param_all && !(o->params & (1u << k))) continue;
        int iso_ok = sb_param_kind_applies((sb_param_kind_t)k, flags);
        sb_param_t *probe = NULL;
        sb_param_opts_t pp = {0};
        pp.res = o->res;
        pp.tables = sb_source_layout_tables(src); /* vndf: an RGL file's own */
        sb_context_clear_error(ctx);
        sb_result_t pr = iso_ok ? sb_param_create(ctx, (sb_param_kind_t)k, &pp, &probe) : SB_ERR_UNSUPPORTED;
        sb_param_destroy(probe);
        /* all = those that apply (job.h: iso only for reciprocal sources too) */
        if (o->param_all && (pr != SB_OK || !sb_job_param_applies((sb_param_kind_t)k, src, NULL))) continue;
        run_t *ru = runs_add(rs, spec, k);
        if (!ru) return -1;
        ru->source = study_dup(sb_source_description(src));
        if (!iso_ok) { /* vh, rv, iso on an anisotropic source; vndf on a source without its tables */
            const char *why = "";
            char msg[160];
            sb_job_param_applies((sb_param_kind_t)k, src, &why);
            snprintf(msg, sizeof msg, "%s %s", sb_param_kind_name((sb_param_kind_t)k), why ? why : "does not apply");
            study_run_fail(ru, msg);
        } else if (pr != SB_OK) {
            study_run_fail(ru, sb_context_last_error(ctx));
        } else {
            ru->ok = -1; /* to run */
            continue;
        }
        cli_error("study", "%s on %s: %s (skipped)", spec, sb_param_kind_name((sb_param_kind_t)k), ru->error);
    }
    return 0;
}

/* Open every source (srcs) and list its runs (those of source s are
 * first_run[s] .. first_run[s + 1] - 1); 0, or -1 when out of memory. */
static int list_runs(sb_context_t *ctx, const study_opts_t *o, sb_source_t **srcs, size_t *first_run, runs_t *rs) {
    for (size_t s = 0; s < o->nsources; s++) {
        first_run[s] = rs->n;
        sb_context_clear_error(ctx);
        sb_result_t r = sb_job_source_open(ctx, o->sources[s], &o->job.measured, &srcs[s]);
        if (r == SB_OK) {
            if (list_layouts(ctx, o, srcs[s], o->sources[s], rs) != 0) return -1;
            continue;
        }
        run_t *ru = runs_add(rs, o->sources[s], -1);
        if (!ru) return -1;
        study_run_fail(ru, sb_context_last_error(ctx));
        cli_error("study", "%s (skipped)", ru->error); /* the message names the source */
    }
    first_run[o->nsources] = rs->n;
    return 0;
}

/* Run every listed run, source by source (one open source each). */
static void run_all(sb_context_t *ctx, const study_opts_t *o, sb_source_t **srcs, const size_t *first_run, runs_t *rs) {
    size_t ntasks = 0, task = 0;
    for (size_t i = 0; i < rs->n; i++)
        ntasks += rs->v[i].ok == -1;
    for (size_t s = 0; s < o->nsources; s++)
        for (size_t i = first_run[s]; i < first_run[s + 1]; i++) {
            run_t *ru = &rs->v[i];
            if (ru->ok != -1) continue;
            run_one(ctx, srcs[s], o, ru, task++, ntasks);
            if (!ru->ok) {
                cli_error("study", "%s on %s: %s (skipped)", ru->spec, study_kind_name(ru->kind), ru->error);
                continue;
            }
            cli_info(2, "study: %s on %s done (%s)", ru->spec, ru->param_spec, ru->masked ? "refit" : "nested");
        }
}

/* The settings as the job resolves them, for the outputs. */
static void settle(study_opts_t *o) {
    o->res = o->job.res ? o->job.res : 32;
    o->metric_res = o->job.metric_res ? o->job.metric_res : 32;
    o->form = SB_FORM_F;
    if (o->job.form) sb_form_parse(o->job.form, &o->form);
    o->weighted = o->job.weighted;
    o->zero_fill = o->job.zero_fill;
    o->method = o->job.method;
}

/* Write the output set of the runs (a staging folder published in one
 * step, outset.h, so the folder never mixes files of two studies), print
 * the table; the exit code. */
static int publish(sb_context_t *ctx, const study_opts_t *o, const runs_t *rs, double t0) {
    size_t failed = 0, good = 0;
    for (size_t i = 0; i < rs->n; i++) {
        if (rs->v[i].ok)
            good++;
        else
            failed++;
    }
    int rc, plotted = 0;
    if (!good) { /* nothing to show: the folder keeps what it held */
        if (g_verbosity >= 1) print_table(o, rs);
        cli_error("study", "every run failed (%zu); nothing written to %s", failed, o->out);
        return EXIT_IO;
    }
    sb_outset_t *set = cli_outset_begin(ctx, "study", o->out, &rc);
    if (!set) return rc;
    if (study_write_set(set, o, rs, failed, good, &plotted) != 0) {
        cli_outset_end(ctx, "study", set, 0); /* a set not published: discarded */
        return EXIT_IO;
    }
    if ((rc = cli_outset_end(ctx, "study", set, 1)) != EXIT_OK) return rc;
    if (g_verbosity >= 1) {
        print_table(o, rs);
        printf("wrote study.csv, study.json%s to %s/ (%zu runs ok, %zu failed, %.3f s)\n", plotted ? ", study.png" : "",
               o->out, good, failed, cli_now() - t0);
    }
    if (failed)
        cli_error("study", "%zu of %zu runs failed; the results of the other %zu are written", failed, rs->n, good);
    return failed ? EXIT_IO : EXIT_OK;
}

/* study --budget: a sweep over budgets (study_budget.c); J is each
 * budget's choice, so --terms and --nmf do not apply. */
static int run_budgets(const study_opts_t *o) {
    if (o->terms_given || o->nmf) {
        cli_error("study", "--budget chooses J itself: %s does not apply (drop it, or --budget)",
                  o->terms_given ? "--terms" : "--nmf");
        return EXIT_USAGE;
    }
    sb_context_t *ctx = NULL;
    if (sb_context_create(&ctx) != SB_OK) {
        cli_error("study", "out of memory");
        return EXIT_IO;
    }
    int rc = study_budgets(ctx, o, cli_now());
    sb_context_destroy(ctx);
    return rc;
}

int cmd_study(int argc, char **argv) {
    study_opts_t o = {0};
    o.sources = calloc((size_t)argc + 1, sizeof *o.sources);
    if (!o.sources) {
        cli_error("study", "out of memory");
        return EXIT_IO;
    }
    o.out = DEFAULT_OUT;
    o.param_auto = 1; /* what `factor` builds */
    parse_terms("1..8", &o);
    int rc = parse(argc, argv, &o);
    if (rc >= 0) {
        free(o.sources);
        return rc;
    }
    settle(&o);
    if ((rc = cli_check_outdir("study", "--out", o.out)) != EXIT_OK) {
        free(o.sources);
        return rc;
    }

    if (o.nbudgets) {
        rc = run_budgets(&o);
        free(o.sources);
        return rc;
    }
    sb_context_t *ctx = NULL;
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
    if (list_runs(ctx, &o, srcs, first_run, &rs) != 0) goto nomem;
    run_all(ctx, &o, srcs, first_run, &rs);
    cli_progress_done();
    rc = publish(ctx, &o, &rs, t0);
    goto out;
nomem:
    cli_progress_done();
    cli_error("study", "out of memory");
    rc = EXIT_IO;
out:
    for (size_t s = 0; srcs && s < o.nsources; s++)
        sb_source_destroy(srcs[s]);
    free(srcs);
    free(first_run);
    runs_free(&rs);
    sb_context_destroy(ctx);
    free(o.sources);
    return rc;
}
