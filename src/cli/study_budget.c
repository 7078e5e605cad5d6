/* sepbrdf study --budget LIST: headline error against bytes.
 *
 * Per source x layout asked (auto, or each of --param's list) x budget,
 * one factor job with that budget (job.h "Byte budgets": the layout,
 * texture shape, warp, J and storage of the lowest screened headline
 * within it, fitted in full).  Outputs in the folder: study.csv,
 * study.json, study.dat + study.gp and study.png (the full fit's headline
 * against the chosen textures' bytes, log-log, one line per source and
 * layout asked). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "pipeline.h"
#include "sepbrdf/experimental/layout.h"
#include "study.h"

/* One source x layout asked x budget. */
typedef struct brow {
    const char *spec;  /* the source as given */
    const char *asked; /* "auto" or a layout name */
    size_t budget;
    int ok;
    char error[512];
    sb_job_budget_t b; /* the choice */
    char param_spec[512];
    double headline, comparable; /* the full fit's, at the chosen J */
    double sample_rel;           /* measured tables: relative L2 at the measured samples, at J; NAN elsewhere */
    double time_s;
} brow_t;

typedef struct brows {
    brow_t *v;
    size_t n;
    const study_opts_t *o;
} brows_t;

int study_parse_budgets(const char *s, study_opts_t *o) {
    char buf[1024];
    o->nbudgets = 0;
    if (!*s || strlen(s) >= sizeof buf) {
        cli_error("study", "--budget '%s': need a comma list of sizes such as 4K,16K,48KiB", s);
        return -1;
    }
    if (cli_list_items("study", "--budget", s)) return -1;
    strcpy(buf, s);
    for (char *save = NULL, *t = strtok_r(buf, ",", &save); t; t = strtok_r(NULL, ",", &save)) {
        size_t v, k;
        if (cli_parse_bytes("study", "--budget", t, &v)) return -1;
        for (k = 0; k < o->nbudgets && o->budgets[k] < v; k++)
            ;
        if (k < o->nbudgets && o->budgets[k] == v) continue;
        if (o->nbudgets == STUDY_MAX_BUDGETS) {
            cli_error("study", "--budget '%s': more than %d budgets", s, STUDY_MAX_BUDGETS);
            return -1;
        }
        memmove(o->budgets + k + 1, o->budgets + k, (o->nbudgets - k) * sizeof *o->budgets);
        o->budgets[k] = v;
        o->nbudgets++;
    }
    return 0;
}

/* The job of one row; its numbers, or its failure, into w. */
static void run_row(sb_context_t *ctx, const sb_source_t *src, const study_opts_t *o, brow_t *w) {
    sb_job_opts_t jo = o->job;
    jo.param = strcmp(w->asked, "auto") == 0 ? NULL : w->asked;
    jo.budget = w->budget;
    sb_job_t *job = NULL;
    double t0 = cli_now();
    sb_context_clear_error(ctx);
    sb_result_t r = sb_job_run_source(ctx, src, &jo, &job);
    w->time_s = cli_now() - t0;
    w->ok = r == SB_OK;
    if (!w->ok) {
        snprintf(w->error, sizeof w->error, "%s", sb_context_last_error(ctx));
        sb_job_destroy(job);
        return;
    }
    sb_job_budget(job, &w->b);
    size_t J = sb_factors_terms(sb_job_factors(job));
    snprintf(w->param_spec, sizeof w->param_spec, "%s", sb_param_spec(sb_job_param(job)));
    w->headline = sb_job_headline(job, J);
    w->comparable = sb_job_comparable(job, J);
    sb_sample_errors_t se;
    w->sample_rel = NAN;
    if (sb_measured_sample_errors_channels(NULL, src, sb_job_factors(job), sb_job_param(job), sb_job_form(job),
                                           jo.channels, &se) == SB_OK &&
        se.terms >= J)
        w->sample_rel = se.rel_l2[J - 1];
    sb_job_destroy(job);
}

static void write_csv(FILE *fp, const void *arg) {
    const brows_t *rs = arg;
    fprintf(fp, "source,asked,budget,ok,param,param_spec,form,warp,resolution,terms,storage,bytes,bytes_float,"
                "bytes_half,headline,screened_headline,comparable,sample_rel_l2,fits,time_s\n");
    for (size_t i = 0; i < rs->n; i++) {
        const brow_t *w = &rs->v[i];
        const sb_job_budget_try_t *c = &w->b.chosen;
        study_csv_field(fp, w->spec);
        fprintf(fp, ",%s,%zu,%d", w->asked, w->budget, w->ok);
        if (!w->ok) {
            fprintf(fp, ",,,,,,,,,,,,,,,,\n");
            continue;
        }
        fprintf(fp, ",%s,", sb_param_kind_name(c->kind));
        study_csv_field(fp, w->param_spec);
        fprintf(fp, ",%s,%s,%zu,%zu,%s,%zu,%zu,%zu,%.9g,%.9g,%.9g,", sb_form_name(c->form),
                c->adaptive ? "adaptive" : "own", c->res, c->terms, c->half ? "half" : "float", c->bytes,
                w->b.bytes_float, w->b.bytes_half, w->headline, c->headline, w->comparable);
        if (isfinite(w->sample_rel)) fprintf(fp, "%.9g", w->sample_rel); /* empty for a model, as a failed row's */
        fprintf(fp, ",%zu,%.3f\n", w->b.fits, w->time_s);
    }
}

static void json_row(json_t *j, const brow_t *w) {
    const sb_job_budget_try_t *c = &w->b.chosen;
    json_begin_object(j, NULL);
    json_string(j, "source_spec", w->spec);
    json_string(j, "asked", w->asked);
    json_int(j, "budget", (long long)w->budget);
    json_bool(j, "ok", w->ok);
    if (!w->ok) {
        json_string(j, "error", w->error);
        json_end_object(j);
        return;
    }
    json_string(j, "param", sb_param_kind_name(c->kind));
    json_string(j, "param_spec", w->param_spec);
    json_string(j, "form", sb_form_name(c->form));
    json_string(j, "warp", c->adaptive ? "adaptive" : "own");
    json_int(j, "resolution", (long long)c->res);
    json_int(j, "terms", (long long)c->terms);
    json_string(j, "storage", c->half ? "half" : "float");
    json_int(j, "bytes", (long long)c->bytes);
    json_int(j, "bytes_float", (long long)w->b.bytes_float);
    json_int(j, "bytes_half", (long long)w->b.bytes_half);
    json_number(j, "headline", w->headline);
    json_number(j, "screened_headline", c->headline);
    json_number(j, "comparable", w->comparable);
    json_number(j, "sample_rel_l2", w->sample_rel);
    json_int(j, "fits", (long long)w->b.fits);
    json_number(j, "time_s", w->time_s);
    json_end_object(j);
}

static void write_json(FILE *fp, const void *arg) {
    const brows_t *rs = arg;
    json_t j = {fp, 0, {0}};
    json_begin_object(&j, NULL);
    json_string(&j, "sepbrdf_version", sb_version());
    json_string(&j, "command", "study");
    json_begin_object(&j, "settings");
    json_begin_array(&j, "budgets");
    for (size_t k = 0; k < rs->o->nbudgets; k++)
        json_int(&j, NULL, (long long)rs->o->budgets[k]);
    json_end_array(&j);
    json_end_object(&j);
    json_begin_array(&j, "runs");
    for (size_t i = 0; i < rs->n; i++)
        json_row(&j, &rs->v[i]);
    json_end_array(&j);
    json_begin_object(&j, "files");
    json_string(&j, "csv", "study.csv");
    json_string(&j, "gnuplot_script", "study.gp");
    json_string(&j, "gnuplot_data", "study.dat");
    json_end_object(&j);
    json_end_object(&j);
}

/* A line of the plot: the rows of one source x layout asked (budgets
 * consecutive), from row i; returns the row after it. */
static size_t line_end(const brows_t *rs, size_t i) {
    size_t k = i + 1;
    while (k < rs->n && rs->v[k].spec == rs->v[i].spec && rs->v[k].asked == rs->v[i].asked)
        k++;
    return k;
}

static void write_dat(FILE *fp, const void *arg) {
    const brows_t *rs = arg;
    int block = 0;
    for (size_t i = 0, e; i < rs->n; i = e) {
        e = line_end(rs, i);
        if (block++) fputs("\n\n", fp);
        fprintf(fp, "# %s (%s)\n# bytes headline budget\n", rs->v[i].spec, rs->v[i].asked);
        for (size_t k = i; k < e; k++)
            if (rs->v[k].ok)
                fprintf(fp, "%zu %.9g %zu\n", rs->v[k].b.chosen.bytes, fmax(rs->v[k].headline, 1e-16), rs->v[k].budget);
    }
}

static void write_gp(FILE *fp, const void *arg) {
    const brows_t *rs = arg;
    fprintf(fp, "# sepbrdf study --budget: headline error against bytes. Re-run with\n"
                "# `gnuplot study.gp` in this folder.\n" STUDY_GP_OUTPUT
                "set title 'sepbrdf study: headline error within byte budgets (choice of factor --budget)'\n"
                "set xlabel 'bytes of the textures written (all terms, g and h, RGB)'\n"
                "set ylabel 'headline error (relative L2 of f cos theta_i, out of sample)'\n"
                "set logscale xy\n"
                "set format y '%%.0e'\n"
                "set grid\n"
                "set key below height 1.5 spacing 1.2\n");
    int block = 0;
    for (size_t i = 0, e; i < rs->n; i = e) {
        e = line_end(rs, i);
        fputs(block ? ", \\\n     " : "plot ", fp);
        fprintf(fp, "'study.dat' index %d using 1:2 with linespoints lw 2 title ", block++);
        char title[512];
        snprintf(title, sizeof title, "%.200s (%s)", rs->v[i].spec, rs->v[i].asked);
        study_gp_quote(fp, title);
    }
    fputs(block ? "\n" : "print 'no results to plot'\n", fp);
}

static void print_rows(const brows_t *rs) {
    printf("%-30s %-7s %9s  %-7s %-9s %4s %4s %-5s %9s  %11s  %11s\n", "source", "asked", "budget", "param", "warp",
           "R", "J", "store", "bytes", "headline", "sample_rel");
    for (size_t i = 0; i < rs->n; i++) {
        const brow_t *w = &rs->v[i];
        const sb_job_budget_try_t *c = &w->b.chosen;
        if (!w->ok) {
            printf("%-30.30s %-7s %9zu  failed: %s\n", w->spec, w->asked, w->budget, w->error);
            continue;
        }
        printf("%-30.30s %-7s %9zu  %-7s %-9s %4zu %4zu %-5s %9zu  %11.4e", w->spec, w->asked, w->budget,
               sb_param_kind_name(c->kind), c->adaptive ? "adaptive" : "own", c->res, c->terms,
               c->half ? "half" : "float", c->bytes, w->headline);
        if (isfinite(w->sample_rel))
            printf("  %11.4e\n", w->sample_rel);
        else
            printf("  %11s\n", "-");
    }
}

/* Write the set (published whole) and print; the exit code. */
static int publish(sb_context_t *ctx, const brows_t *rs, double t0) {
    size_t failed = 0;
    for (size_t i = 0; i < rs->n; i++)
        failed += !rs->v[i].ok;
    int rc;
    sb_outset_t *set = cli_outset_begin(ctx, "study", rs->o->out, &rc);
    if (!set) return rc;
    int bad = study_write_file(set, "study.csv", write_csv, rs) || study_write_file(set, "study.dat", write_dat, rs) ||
              study_write_file(set, "study.gp", write_gp, rs) || study_write_file(set, "study.json", write_json, rs);
    if (!bad && failed < rs->n) study_gnuplot(sb_outset_dir(set), rs->o->out);
    if (bad) {
        cli_outset_end(ctx, "study", set, 0);
        return EXIT_IO;
    }
    if ((rc = cli_outset_end(ctx, "study", set, 1)) != EXIT_OK) return rc;
    if (g_verbosity >= 1) {
        print_rows(rs);
        printf("wrote study.csv, study.json, study.png to %s/ (%zu runs, %zu failed, %.3f s)\n", rs->o->out, rs->n,
               failed, cli_now() - t0);
    }
    if (failed) cli_error("study", "%zu of %zu runs failed; the results of the others are written", failed, rs->n);
    return failed ? EXIT_IO : EXIT_OK;
}

/* The layouts asked: auto, or each of --param's list. */
static size_t layouts_asked(const study_opts_t *o, const char **names) {
    if (o->param_all) {
        names[0] = "auto";
        return 1;
    }
    size_t n = 0;
    if (o->param_auto) names[n++] = "auto"; /* the default, as `factor --budget` chooses */
    for (int k = 0; k < (int)sb_param_kind_count(); k++)
        if (o->params & (1u << k)) names[n++] = sb_param_kind_name((sb_param_kind_t)k);
    return n;
}

int study_budgets(sb_context_t *ctx, const study_opts_t *o, double t0) {
    const char *names[SB_LAYOUTS_MAX + 1];
    size_t nl = layouts_asked(o, names), total = o->nsources * nl * o->nbudgets, done = 0;
    brows_t rs = {calloc(total, sizeof(brow_t)), 0, o};
    if (!rs.v) {
        cli_error("study", "out of memory");
        return EXIT_IO;
    }
    for (size_t s = 0; s < o->nsources; s++) {
        sb_source_t *src = NULL;
        sb_context_clear_error(ctx);
        sb_result_t r = sb_job_source_open(ctx, o->sources[s], &o->job.measured, &src);
        if (r != SB_OK) cli_error("study", "%s (skipped)", sb_context_last_error(ctx));
        for (size_t l = 0; l < nl; l++)
            for (size_t k = 0; k < o->nbudgets; k++) {
                brow_t *w = &rs.v[rs.n++];
                w->spec = o->sources[s];
                w->asked = names[l];
                w->budget = o->budgets[k];
                cli_progress("study --budget", (double)done++ / (double)total);
                if (src) run_row(ctx, src, o, w);
                if (!src) snprintf(w->error, sizeof w->error, "%s", "the source could not be opened");
                if (src && !w->ok) cli_error("study", "%s (%s, %zu bytes): %s", w->spec, w->asked, w->budget, w->error);
            }
        sb_source_destroy(src);
    }
    cli_progress_done();
    int rc = publish(ctx, &rs, t0);
    free(rs.v);
    return rc;
}
