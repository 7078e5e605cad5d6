/* CLI: `sepbrdf study` with the real binary (SB_CLI): files, nesting of J,
 * failures that keep the other results, gnuplot missing. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "harness.h"

static char out[65536];

static int run(const char *fmt, const char *a, const char *b) {
    char cmd[8192], tail[6000];
    snprintf(tail, sizeof tail, fmt, a, b);
    snprintf(cmd, sizeof cmd, "%s %s", SB_CLI, tail);
    return sb_run(cmd, out, sizeof out);
}

static char *slurp(const char *dir, const char *name) {
    char path[8400];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *fp = fopen(path, "rb");
    if (!fp) return NULL;
    static char buf[1 << 20];
    size_t n = fread(buf, 1, sizeof buf - 1, fp);
    buf[n] = 0;
    fclose(fp);
    return buf;
}

static int count_lines(const char *s) {
    int n = 0;
    for (; s && *s; s++)
        n += *s == '\n';
    return n;
}

/* Value of CSV column `col` (0-based) in the row whose source starts with
 * `source` and whose terms column (6) is J; NAN if absent.  Sources in
 * these tests hold no commas; quoted fields may. */
static double csv_value(const char *csv, const char *source, int J, int col) {
    for (const char *line = csv; line && *line; line = strchr(line, '\n') ? strchr(line, '\n') + 1 : NULL) {
        if (strncmp(line, source, strlen(source)) != 0) continue;
        const char *f[16];
        int n = 0;
        f[n++] = line;
        int quoted = 0; /* commas inside a quoted field (a layout spec) do not split */
        for (const char *p = line; *p && *p != '\n' && n < 16; p++) {
            if (*p == '"') quoted = !quoted;
            if (*p == ',' && !quoted) f[n++] = p + 1;
        }
        if (n >= 14 && atoi(f[6]) == J) return atof(f[col]);
    }
    return NAN;
}

static double json_number_after(const char *text, const char *anchor, const char *key) {
    const char *p = strstr(text, anchor);
    if (!p) return NAN;
    char pat[128];
    snprintf(pat, sizeof pat, "\"%s\": ", key);
    p = strstr(p, pat);
    return p ? atof(p + strlen(pat)) : NAN;
}

/* `sepbrdf factor SOURCE ARGS -q -o DIR/f`: its report.json (NULL after a
 * failed check) and the anchor of errors[J - 1] in it. */
static const char *factor_report(const char *source_args, const char *dir, int J, char anchor[64]) {
    int rc = run("factor %s -q -o %s/f", source_args, dir);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    char fdir[4200];
    snprintf(fdir, sizeof fdir, "%s/f", dir);
    const char *rep = slurp(fdir, "report.json");
    CHECK(rep != NULL);
    snprintf(anchor, 64, "\"terms\": %d,\n      \"rel_rms\"", J);
    return rep;
}

SB_TEST(three_sources) {
    const char *dir = sb_tmpdir("study");
    /* the plain fit (--form f --unweighted): sampled once, its truncations nested */
    int rc = run("study lambert:albedo=0.5 microfacet:roughness=0.5 microfacet:base=gold,roughness=0.3 --param io "
                 "--form f --unweighted --terms 1..4 --res 8 --metric-res 8 -o %s%s",
                 dir, "");
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    const char *csv = slurp(dir, "study.csv");
    CHECK(csv != NULL);
    if (!csv) return;
    const char *head = "source,param,param_spec,form,weighted,fit,terms,comparable,rel_rms,max_abs,negative_fraction,";
    CHECK(strncmp(csv, head, strlen(head)) == 0);
    CHECKF(count_lines(csv) == 1 + 3 * 4, "%d lines", count_lines(csv));
    CHECK(strstr(csv, "\"microfacet:base=gold,roughness=0.3\",io,io:res=8,f,0,nested,4,") != NULL);
    /* errors do not grow with J (nested truncations of one SVD) */
    for (int J = 2; J <= 4; J++)
        CHECK(csv_value(csv, "microfacet:roughness=0.5", J, 8) <= csv_value(csv, "microfacet:roughness=0.5", J - 1, 8));
    CHECK(csv_value(csv, "lambert:albedo=0.5", 1, 8) < 1e-12);
    const char *json = slurp(dir, "study.json");
    CHECK(json && strstr(json, "\"command\": \"study\"") && strstr(json, "\"fit\": \"nested\"") &&
          strstr(json, "\"failed\": 0"));
    CHECK(strstr(out, "comparable") && strstr(out, "microfacet:roughness=0.5")); /* the table */
    CHECK(slurp(dir, "study.gp") && slurp(dir, "study.dat"));
    if (sb_run("command -v gnuplot", NULL, 0) != 0) SKIP("gnuplot not installed: study.png not checked");
    json = slurp(dir, "study.json");
    CHECK(json && strstr(json, "\"plot\": \"study.png\""));
    const char *png = slurp(dir, "study.png"); /* (the same static buffer) */
    CHECKF(png && memcmp(png, "\x89PNG", 4) == 0, "no PNG: %s", out);
}

/* Errors all within a decade (a Lambert source: the same at every J) get a
 * y range a decade either side, so gnuplot draws them without its "empty y
 * range" warning on the user's terminal. */
SB_TEST(flat_curve_plotted_quietly) {
    const char *dir = sb_tmpdir("study");
    int rc = run("study lambert:albedo=0.5 --param io --terms 1..3 --res 8 --metric-res 8 -o %s%s", dir, "");
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    const char *gp = slurp(dir, "study.gp");
    const char *y = gp ? strstr(gp, "set yrange [") : NULL;
    CHECKF(y != NULL, "no y range in study.gp");
    if (!y) return;
    double lo = atof(y + strlen("set yrange [")), hi = atof(strchr(y, ':') + 1);
    const char *dat = slurp(dir, "study.dat"); /* (slurp's buffer: gp is not read below) */
    CHECK(dat != NULL);
    for (const char *l = dat; l && *l; l = strchr(l, '\n') ? strchr(l, '\n') + 1 : NULL) {
        if (*l == '#' || *l == '\n') continue;
        double e = atof(strchr(l, ' ') + 1); /* J headline rel_rms */
        CHECKF(lo <= e / 9.99 && e * 9.99 <= hi, "%g outside [%g, %g]/10", e, lo, hi);
    }
    CHECKF(!strstr(out, "empty y range"), "%s", out);
}

/* A budget study of one point (a model: no measured samples): gnuplot's
 * "empty x range" warnings stayed off the terminal only for the J plot,
 * and the CSV held "nan" where a failed row's fields are empty. */
SB_TEST(budget_point_plotted_quietly) {
    const char *dir = sb_tmpdir("study");
    int rc = run("study lambert --param io --budget 2K -o %s%s", dir, "");
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    CHECKF(!strstr(out, "range"), "%s", out);
    const char *csv = slurp(dir, "study.csv");
    CHECK(csv != NULL);
    CHECKF(csv && !strstr(csv, "nan"), "%s", csv);
}

/* Rows read from the one largest-J factorisation equal separate runs. */
SB_TEST(nested_equals_separate) {
    const char *dir = sb_tmpdir("study");
    int rc = run("study microfacet:roughness=0.4 --param io --terms 5 --res 8 --method full -o %s/s%s", dir, "");
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    char sdir[4200];
    snprintf(sdir, sizeof sdir, "%s/s", dir);
    const char *csv = slurp(sdir, "study.csv");
    CHECK(csv != NULL);
    if (!csv) return;
    static char csvcopy[1 << 20];
    snprintf(csvcopy, sizeof csvcopy, "%s", csv);
    for (int J = 1; J <= 5; J += 2) {
        char args[256], anchor[64];
        snprintf(args, sizeof args, "microfacet:roughness=0.4 --param io --res 8 --method full -J %d", J);
        const char *rep = factor_report(args, dir, J, anchor);
        if (!rep) return;
        CHECK_REL(csv_value(csvcopy, "microfacet:roughness=0.4", J, 8), json_number_after(rep, anchor, "rel_rms"),
                  1e-7);
        CHECK_REL(csv_value(csvcopy, "microfacet:roughness=0.4", J, 7), json_number_after(rep, anchor, "comparable"),
                  1e-7);
        CHECK_REL(csv_value(csvcopy, "microfacet:roughness=0.4", J, 9), json_number_after(rep, anchor, "max_abs"),
                  1e-7);
    }
}

/* `study SRC OPTS --terms J0,J1` has at J0 and J1 the headline that
 * `factor SRC OPTS -J J` writes, and its CSV holds `expect`. */
static void study_equals_factor(const char *src, const char *opts, int J0, int J1, const char *expect) {
    const char *dir = sb_tmpdir("study");
    char args[4400];
    snprintf(args, sizeof args, "%s %s --terms %d,%d", src, opts, J0, J1);
    int rc = run("study %s -q -o %s/s", args, dir);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    char sdir[4200];
    snprintf(sdir, sizeof sdir, "%s/s", dir);
    const char *csv = slurp(sdir, "study.csv");
    CHECK(csv != NULL);
    if (!csv) return;
    static char csvcopy[1 << 20];
    snprintf(csvcopy, sizeof csvcopy, "%s", csv);
    CHECKF(strstr(csvcopy, expect) != NULL, "%s", csvcopy);
    for (int J = J0; J <= J1; J += J1 - J0) {
        char anchor[64];
        snprintf(args, sizeof args, "%s %s -J %d", src, opts, J);
        const char *rep = factor_report(args, dir, J, anchor);
        if (!rep) return;
        CHECK_REL(csv_value(csvcopy, src, J, 14), json_number_after(rep, anchor, "headline"), 1e-7);
    }
}

/* By default study measures what factor builds: at every J the headline
 * of `factor SOURCE -J J` (auto layout, form, weighting, warps and term
 * weights), here on a measured table; the row names the layout kept
 * (J = 3 keeps vh). */
SB_TEST(auto_equals_factor) {
    char src[4200];
    snprintf(src, sizeof src, "%s/rgl_paper_white_rgb.bsdf", SB_MEASURED_DIR);
    study_equals_factor(src, "--res 12", 1, 3, "vh:tv=");
}

/* A layout named alone is studied as `factor --param P` fits it (auto
 * restricted to it: its form, weighting, warps and term weights), one
 * whole run per J: here vndf on an RGL file (on main: refused, the probe
 * had no tables; factor --param vndf fitted form f unweighted, 0.298 at
 * J = 4 against auto's 0.0231). */
SB_TEST(layout_equals_factor) {
    char src[4200];
    snprintf(src, sizeof src, "%s/rgl_paper_white_rgb.bsdf", SB_MEASURED_DIR);
    study_equals_factor(src, "--param vndf", 2, 4, ",vndf,vndf,cos,1,");
}

/* --form and --unweighted without --warp on a layout that takes one: factor
 * tries the adaptive warp where the layout's own leaves over 5 %, so study
 * runs factor per J as well (on main it sampled once with the uniform
 * warp: GGX 0.3 on hd, R = 12, 0.326 at J = 4 against factor's 0.0192). */
SB_TEST(plain_fit_without_warp_equals_factor) {
    study_equals_factor("microfacet:roughness=0.3", "--param hd --res 12 --form f --unweighted", 2, 4,
                        ",hd,\"hd:res=12,warp_h=");
}

/* study.json says what each run fitted, as study.csv does: a layout named
 * alone keeps auto's choice of form per J, so the settings hold the form
 * given (null here) and every result its form, weighting and layout (on
 * main: settings "form": "f", "weighted": false, results without them,
 * where study.csv said cos, 1). */
SB_TEST(json_says_what_was_fitted) {
    const char *dir = sb_tmpdir("study");
    int rc = run("study microfacet:roughness=0.3 --param io --terms 2 --res 8 -q -o %s%s", dir, "");
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    const char *csv = slurp(dir, "study.csv");
    const char *row = csv ? strstr(csv, "\nmicrofacet:roughness=0.3,io,io:res=8,") : NULL;
    CHECKF(row != NULL, "%s", csv ? csv : "(none)");
    if (!row) return;
    char form[16] = "", want[64];
    sscanf(row + strlen("\nmicrofacet:roughness=0.3,io,io:res=8,"), "%15[a-z0-9]", form);
    const char *json = slurp(dir, "study.json");
    CHECK(json != NULL);
    if (!json) return;
    CHECKF(strstr(json, "\"form\": null") && strstr(json, "\"weighted\": null"), "%s", json);
    const char *res = strstr(json, "\"results\"");
    snprintf(want, sizeof want, "\"form\": \"%s\"", form);
    CHECKF(res && strstr(res, want) && strstr(res, "\"weighted\": true") && strstr(res, "\"param_spec\": \"io:res=8\""),
           "%s", json);
}

SB_TEST(terms_list) {
    const char *dir = sb_tmpdir("study");
    int rc = run("study lambert --param io --terms 1..2,4 --res 4 -q -o %s%s", dir, "");
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    const char *csv = slurp(dir, "study.csv");
    CHECK(csv && count_lines(csv) == 4);
    CHECK(!isnan(csv_value(csv, "lambert", 4, 8)) && isnan(csv_value(csv, "lambert", 3, 8)));
}

/* study --theta-max (on main: "unknown option"): its errors measured
 * within the cap, as factor's, and study.json says the cap.  GGX 0.5 on
 * iso at 60 degrees: within the cap below 1 %, over the whole hemisphere
 * (factor before the seventh pass) 0.65. */
SB_TEST(theta_max_cap) {
    const char *dir = sb_tmpdir("study");
    int rc = run("study cook-torrance:roughness=0.5 --param iso --terms 2 --res 8 --theta-max 60 -q -o %s%s", dir, "");
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    const char *json = slurp(dir, "study.json");
    CHECKF(json && strstr(json, "\"theta_max\": 60") && strstr(json, "\"domain\": \"cap\""), "%s",
           json ? json : "(none)");
    const char *csv = slurp(dir, "study.csv");
    double h = csv ? csv_value(csv, "cook-torrance:roughness=0.5", 2, 14) : NAN; /* headline */
    CHECKF(h < 0.01, "headline at J = 2 within the cap: %g", h);
}

/* A bad file, a bad spec and a run that cannot be done do not lose the
 * good source's rows; exit 2, each failure named. */
SB_TEST(failures_keep_others) {
    const char *dir = sb_tmpdir("study");
    int rc = run("study /nonexistent/table.binary lambert:albedo=0.3 nosuchmodel --param io --terms 1..3 --res 4 "
                 "-o %s%s",
                 dir, "");
    CHECKF(rc == 2, "rc %d: %s", rc, out);
    CHECK(strstr(out, "/nonexistent/table.binary") && strstr(out, "nosuchmodel") && strstr(out, "2 of 3 runs failed"));
    const char *csv = slurp(dir, "study.csv");
    CHECKF(csv && count_lines(csv) == 1 + 3, "csv: %s", csv ? csv : "(none)");
    const char *json = slurp(dir, "study.json");
    CHECK(json && strstr(json, "\"failed\": 2") && strstr(json, "\"ok\": false") && strstr(json, "\"ok\": true"));
    /* every run failed, one after sampling started (J above the matrix
     * size): said, nothing written, and the folder keeps its earlier set */
    char b[4200];
    snprintf(b, sizeof b, "%s/b", dir);
    rc = run("study lambert --param io --terms 1..2 --res 4 -o %s/b%s", dir, "");
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    rc = run("study lambert --param io --terms 5..6 --res 2 -o %s/b%s", dir, "");
    CHECKF(rc == 2 && strstr(out, "--terms 5 exceeds") && strstr(out, "every run failed (1); nothing written"),
           "rc %d: %s", rc, out);
    const char *kept = slurp(b, "study.csv");
    CHECKF(kept && count_lines(kept) == 1 + 2, "the earlier set is gone: %s", kept ? kept : "(none)");
    /* J beyond the rows after some that fit: those rows are written and
     * the rest said skipped (sixth outside pass: on main the whole run
     * failed, nothing written) */
    rc = run("study lambert --param io --terms 1..5 --res 2 -o %s/c%s", dir, "");
    CHECKF(rc == 0 && strstr(out, "J = 5..5 skipped: 5 terms exceed"), "rc %d: %s", rc, out);
    snprintf(b, sizeof b, "%s/c", dir);
    const char *rows = slurp(b, "study.csv");
    CHECKF(rows && count_lines(rows) == 1 + 4, "study.csv: %s", rows ? rows : "(none)");
}

/* A layout that does not apply is named in the failure with its own
 * reason (on main: "iso needs an isotropic source" for vndf on a model,
 * and for vh on an anisotropic one). */
SB_TEST(layout_not_applying_named) {
    const char *dir = sb_tmpdir("study");
    int rc = run("study microfacet:roughness=0.3 --param vndf --terms 1 --res 4 -o %s%s", dir, "");
    CHECKF(rc == 2 && strstr(out, "vndf is built on an RGL file's own tables") && !strstr(out, "iso needs"),
           "rc %d: %s", rc, out);
    rc = run("study microfacet:roughness=0.3,anisotropy=0.5 --param vh --terms 1 --res 4 -o %s%s", dir, "");
    CHECKF(rc == 2 && strstr(out, "vh needs an isotropic source"), "rc %d: %s", rc, out);
}

SB_TEST(param_all) {
    const char *dir = sb_tmpdir("study");
    int rc = run("study lambert --param all --terms 2 --res 4 -q -o %s%s", dir, "");
    CHECKF(rc == 0, "rc %d: %s", rc, out); /* parameterisations not in this build are left out, not failures */
    const char *csv = slurp(dir, "study.csv");
    CHECK(csv && strstr(csv, ",io,io:res=4,"));
}

SB_TEST(gnuplot_missing) {
    const char *dir = sb_tmpdir("study");
    int rc = run("study lambert --param io --terms 2 --res 4 -o %s%s", dir, "");
    CHECKF(rc == 0, "rc %d", rc);
    char cmd[8192];
    snprintf(cmd, sizeof cmd,
             "SEPBRDF_GNUPLOT=/nonexistent/gnuplot %s study lambert --param io --terms 2 --res 4 -o %s/n", SB_CLI, dir);
    rc = sb_run(cmd, out, sizeof out);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    CHECKF(strstr(out, "not found") && strstr(out, "study.png skipped"), "%s", out);
    char n[4200];
    snprintf(n, sizeof n, "%s/n", dir);
    CHECK(slurp(n, "study.csv") && slurp(n, "study.gp"));
    const char *json = slurp(n, "study.json");
    CHECK(json && strstr(json, "\"plot\": null"));
    CHECK(!slurp(n, "study.png"));
}

/* The CLI starts with its own malloc tunables (src/cli/blas_env.c) unless
 * the user set GLIBC_TUNABLES; the programs it starts (here the plotter)
 * get the user's environment: no GLIBC_TUNABLES of ours, the user's own
 * passed through unchanged. */
SB_TEST(children_get_user_environment) {
    const char *dir = sb_tmpdir("study");
    char script[4200], cmd[8192], path[4300];
    snprintf(script, sizeof script, "%s/fake-gnuplot.sh", dir);
    FILE *fp = fopen(script, "w");
    CHECK(fp);
    fprintf(fp, "#!/bin/sh\necho \"tunables=${GLIBC_TUNABLES-unset}\" > \"%s/env.txt\"\nexit 1\n", dir);
    fclose(fp);
    snprintf(cmd, sizeof cmd, "chmod +x %s", script);
    CHECK(system(cmd) == 0);
    const char *user[] = {"", "GLIBC_TUNABLES=glibc.malloc.check=0 "};
    const char *want[] = {"tunables=unset\n", "tunables=glibc.malloc.check=0\n"};
    for (int k = 0; k < 2; k++) {
        snprintf(cmd, sizeof cmd, "%sSEPBRDF_GNUPLOT=%s %s study lambert --param io --terms 1 --res 4 -o %s/r%d",
                 user[k], script, SB_CLI, dir, k);
        int rc = sb_run(cmd, out, sizeof out);
        CHECKF(rc == 0, "rc %d: %s", rc, out);
        const char *env = slurp(dir, "env.txt");
        CHECKF(env && strcmp(env, want[k]) == 0, "case %d: %s", k, env ? env : "(no env.txt)");
        snprintf(path, sizeof path, "%s/env.txt", dir);
        unlink(path);
    }
}
