/* sepbrdf study: its output files, written into the study's output set:
 * study.csv, study.json, study.dat + study.gp (the gnuplot data and script)
 * and study.png (comparable error vs J, log y). */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "study.h"

void study_csv_field(FILE *fp, const char *s) {
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

const char *study_kind_name(int kind) {
    return kind == STUDY_AUTO ? "auto" : sb_param_kind_name((sb_param_kind_t)kind);
}

static void write_csv(FILE *fp, const study_opts_t *o, const runs_t *rs) {
    fprintf(fp,
            "source,param,param_spec,form,weighted,fit,terms,comparable,rel_rms,max_abs,negative_fraction,"
            "sample_s,factor_s,metric_s,headline%s\n",
            o->nmf ? ",nmf_headline,nmf_rel_rms" : "");
    for (size_t i = 0; i < rs->n; i++) {
        const run_t *r = &rs->v[i];
        if (!r->ok) continue;
        for (size_t k = 0; k < r->nr; k++) {
            const row_t *w = &r->r[k];
            study_csv_field(fp, r->spec);
            fprintf(fp, ",%s,", study_kind_name(r->kind));
            study_csv_field(fp, w->spec ? w->spec : r->param_spec);
            fprintf(fp, ",%s,%d,%s,%zu,%.9g,%.9g,%.9g,%.9g,%.6f,%.6f,%.6f,%.9g",
                    w->form ? w->form : sb_form_name(o->form), w->form ? w->weighted : o->weighted > 0,
                    r->masked ? "refit" : "nested", w->terms, w->comparable, w->rel_rms, w->max_abs, w->neg_frac,
                    r->t_sample, w->t_factor, w->t_metric, w->headline);
            if (o->nmf) fprintf(fp, ",%.9g,%.9g", w->nmf_headline, w->nmf_rel_rms);
            fputc('\n', fp);
        }
    }
}

/* One run of "runs": its source and layout, then the results per J. */
static void json_run(json_t *j, const study_opts_t *o, const run_t *r) {
    json_begin_object(j, NULL);
    json_string(j, "source_spec", r->spec);
    json_string(j, "source", r->source);
    json_string(j, "param", r->kind >= 0 ? study_kind_name(r->kind) : NULL);
    json_string(j, "param_spec", r->param_spec);
    json_bool(j, "ok", r->ok);
    json_begin_array(j, "warnings");
    for (size_t k = 0; k < r->nwarn; k++)
        json_string(j, NULL, r->warn[k]);
    json_end_array(j);
    if (!r->ok) {
        json_string(j, "error", r->error);
        json_end_object(j);
        return;
    }
    json_int(j, "rows", (long long)r->rows);
    json_int(j, "cols", (long long)r->cols);
    json_string(j, "fit", r->masked ? "refit" : "nested");
    json_bool(j, "masked", r->masked);
    if (r->masked) {
        json_int(j, "fit_iterations", r->iterations);
        json_bool(j, "fit_converged", r->converged);
    }
    json_number(j, "sample_s", r->t_sample);
    json_begin_array(j, "results");
    for (size_t k = 0; k < r->nr; k++) {
        const row_t *w = &r->r[k];
        json_begin_object(j, NULL);
        json_int(j, "terms", (long long)w->terms);
        if (w->form) { /* a factor run per J: what it fitted there, as study.csv says */
            json_string(j, "param_spec", w->spec);
            json_string(j, "form", w->form);
            json_bool(j, "weighted", w->weighted);
        }
        json_number(j, "headline", w->headline);
        json_number(j, "comparable", w->comparable);
        json_number(j, "rel_rms", w->rel_rms);
        json_number(j, "max_abs", w->max_abs);
        json_number(j, "negative_fraction", w->neg_frac);
        json_number(j, "factor_s", w->t_factor);
        json_number(j, "metric_s", w->t_metric);
        if (o->nmf) {
            json_number(j, "nmf_headline", w->nmf_headline);
            json_number(j, "nmf_rel_rms", w->nmf_rel_rms);
        }
        json_end_object(j);
    }
    json_end_array(j);
    json_end_object(j);
}

static void write_json(FILE *fp, const study_opts_t *o, const runs_t *rs, size_t failed, const char *plot) {
    json_t j = {fp, 0, {0}};
    json_begin_object(&j, NULL);
    json_string(&j, "sepbrdf_version", sb_version());
    json_string(&j, "command", "study");
    json_begin_object(&j, "settings");
    json_int(&j, "resolution", (long long)o->res);
    json_begin_array(&j, "terms");
    for (size_t J = 1; J <= MAX_J; J++)
        if (o->want_j[J]) json_int(&j, NULL, (long long)J);
    json_end_array(&j);
    json_begin_array(&j, "params");
    if (o->param_auto) json_string(&j, NULL, "auto");
    if (o->param_all) json_string(&j, NULL, "all");
    for (int k = 0; k < (int)sb_param_kind_count() && !o->param_all; k++)
        if (o->params & (1u << k)) json_string(&j, NULL, sb_param_kind_name((sb_param_kind_t)k));
    json_end_array(&j);
    /* as given; null: each run's own choice (results[].form, .weighted) */
    json_string(&j, "form", o->job.form ? sb_form_name(o->form) : NULL);
    if (o->weighted)
        json_bool(&j, "weighted", o->weighted > 0);
    else
        json_string(&j, "weighted", NULL);
    json_bool(&j, "zero_fill", o->zero_fill);
    json_string(&j, "method", sb_method_name(o->method));
    json_int(&j, "metric_resolution", (long long)o->metric_res);
    /* --theta-max below 90: the sampled cap, and every error measured within it */
    double cap = o->job.theta_max_deg > 0 ? o->job.theta_max_deg : 90;
    json_number(&j, "theta_max", cap);
    json_string(&j, "domain", o->job.scene ? "scene" : (cap < 90 - 1e-9 ? "cap" : "hemisphere"));
    json_end_object(&j);
    json_begin_array(&j, "runs");
    for (size_t i = 0; i < rs->n; i++)
        json_run(&j, o, &rs->v[i]);
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
        fprintf(fp, "# %s (%s)\n# J headline rel_rms\n", r->spec, study_kind_name(r->kind));
        for (size_t k = 0; k < r->nr; k++)
            fprintf(fp, "%zu %.9g %.9g\n", r->r[k].terms, fmax(r->r[k].headline, PLOT_FLOOR),
                    fmax(r->r[k].rel_rms, PLOT_FLOOR));
    }
}

void study_gp_quote(FILE *fp, const char *s) {
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
            "# Errors below %g (exact fits) are drawn at %g.\n" STUDY_GP_OUTPUT
            "set title 'sepbrdf study: R = %zu, form %s%s'\n"
            "set xlabel 'J (terms)'\n"
            "set ylabel 'headline error (relative L2 of f cos theta_i, out of sample)'\n"
            "set logscale y\n"
            "set format y '%%.0e'\n"
            "set grid\n"
            "set key below height 1.5 spacing 1.2\n"
            "set xtics 1\n"
            "set xrange [0.5:%zu.5]\n",
            PLOT_FLOOR, PLOT_FLOOR, o->res, o->job.form ? sb_form_name(o->form) : "per run",
            o->weighted > 0   ? ", weighted"
            : o->weighted < 0 ? ", unweighted"
                              : "",
            o->jmax);
    if (o->jmax > 20) fprintf(fp, "set xtics %zu\n", (o->jmax + 9) / 10);
    double lo = INFINITY, hi = 0; /* all errors within a decade (a Lambert source: equal): a decade each side */
    for (size_t i = 0; i < rs->n; i++)
        for (size_t k = 0; rs->v[i].ok && k < rs->v[i].nr; k++) {
            double e = fmax(rs->v[i].r[k].headline, PLOT_FLOOR);
            lo = fmin(lo, e), hi = fmax(hi, e);
        }
    if (hi > 0 && hi < 10 * lo) fprintf(fp, "set yrange [%.3g:%.3g]\n", lo / 10, hi * 10);
    int block = 0;
    for (size_t i = 0; i < rs->n; i++) {
        const run_t *r = &rs->v[i];
        if (!r->ok || !r->nr) continue;
        fputs(block ? ", \\\n     " : "plot ", fp);
        fprintf(fp, "'study.dat' index %d using 1:2 with linespoints lw 2 title ", block);
        char title[512];
        snprintf(title, sizeof title, "%.200s (%s)", r->spec, study_kind_name(r->kind));
        study_gp_quote(fp, title);
        block++;
    }
    fputs(block ? "\n" : "print 'no results to plot'\n", fp);
}

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

int study_write_file(sb_outset_t *set, const char *name, study_writer_fn fn, const void *arg) {
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

int study_gnuplot(const char *dir, const char *target) {
    const char *exe = getenv("SEPBRDF_GNUPLOT");
    if (!exe || !*exe) exe = "gnuplot";
    char tmpname[64], tmp[4300], path[4200], expr[128];
    snprintf(tmpname, sizeof tmpname, "study.png.tmp-%ld", (long)getpid());
    snprintf(tmp, sizeof tmp, "%s/%s", dir, tmpname);
    snprintf(path, sizeof path, "%s/study.png", dir);
    snprintf(expr, sizeof expr, "outfile='%s'", tmpname);
    cli_guard(tmp);
    fflush(NULL);
    int verbose = g_verbosity >= 2;
    pid_t pid = fork();
    if (pid == 0) { /* child: only async-signal-safe calls until exec */
        int null = open("/dev/null", O_WRONLY);
        if (null >= 0) dup2(null, 1);
        if (null >= 0 && !verbose) dup2(null, 2); /* "Warning: empty y range" on one point: not ours to say */
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
        cli_error("study", "warning: %s failed on %s/study.gp; study.png skipped%s", exe, target,
                  verbose ? "" : " (-v shows its messages)");
    } else if (rename(tmp, path) != 0) {
        cli_error("study", "warning: %s/study.png: cannot rename: %s", target, strerror(errno));
    } else {
        ok = 1;
    }
    if (!ok) unlink(tmp);
    cli_unguard(tmp);
    return ok;
}

int study_write_set(sb_outset_t *set, const study_opts_t *o, const runs_t *rs, size_t failed, size_t good,
                    int *plotted) {
    out_args_t oa = {o, rs, failed, NULL};
    *plotted = 0;
    if (study_write_file(set, "study.csv", w_csv, &oa) || study_write_file(set, "study.dat", w_dat, &oa) ||
        study_write_file(set, "study.gp", w_gp, &oa))
        return -1;
    if (good) *plotted = study_gnuplot(sb_outset_dir(set), o->out);
    oa.plot = *plotted ? "study.png" : NULL;
    return study_write_file(set, "study.json", w_json, &oa);
}
