/* CLI of the measured tables: `sepbrdf sample`, `sepbrdf info`, and
 * `sepbrdf factor` on measured files (the real binary, SB_CLI). */
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"

static char out[1 << 16];

/* Run "SB_CLI args" (args built with printf), capturing stdout + stderr. */
__attribute__((format(printf, 1, 2))) static int cli(const char *fmt, ...) {
    char args[8192], cmd[8400];
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(args, sizeof args, fmt, ap);
    va_end(ap);
    CHECK(n > 0 && (size_t)n < sizeof args);
    n = snprintf(cmd, sizeof cmd, "%s %s", SB_CLI, args);
    CHECK(n > 0 && (size_t)n < sizeof cmd);
    return sb_run(cmd, out, sizeof out);
}

static int has_measured_dir(void) {
    struct stat st;
    return stat(SB_MEASURED_DIR, &st) == 0 && S_ISDIR(st.st_mode);
}

static int dir_is_empty_or_missing(const char *dir) {
    char cmd[9000];
    int n = snprintf(cmd, sizeof cmd, "test ! -e '%s' || test -z \"$(ls -A '%s')\"", dir, dir);
    CHECK(n > 0 && (size_t)n < sizeof cmd);
    return sb_run(cmd, NULL, 0) == 0;
}

static size_t count_lines(const char *path, int data_only) {
    FILE *fp = fopen(path, "r");
    if (!fp) return 0;
    char line[4096];
    size_t n = 0;
    int header = 0;
    while (fgets(line, sizeof line, fp)) {
        if (data_only && line[0] == '#') continue;
        if (data_only && !header) {
            header = 1;
            continue;
        }
        n++;
    }
    fclose(fp);
    return n;
}

/* The text of a file (up to 1 MiB, a static buffer), NULL if unreadable. */
static char *slurp(const char *path) {
    FILE *fp = fopen(path, "rb");
    if (!fp) return NULL;
    static char buf[1 << 20];
    size_t n = fread(buf, 1, sizeof buf - 1, fp);
    buf[n] = 0;
    fclose(fp);
    return buf;
}

/* The J-th "rel_rms" of report.json (the error after J terms), NaN if absent. */
static double report_rel_rms(const char *path, int J) {
    const char *p = slurp(path);
    if (!p) return NAN;
    for (int k = 0; k < J; k++) {
        p = strstr(p, "\"rel_rms\": ");
        if (!p) return NAN;
        if (k + 1 < J) p++;
    }
    return atof(p + 11);
}

/* Every "rel_rms": value in report.json is a finite number. */
static int report_finite(const char *path, int *count) {
    const char *buf = slurp(path);
    if (!buf) return 0;
    *count = 0;
    for (const char *p = buf; (p = strstr(p, "\"rel_rms\": ")); p++) {
        double v = atof(p + 11);
        if (strncmp(p + 11, "null", 4) == 0 || !isfinite(v) || v < 0 || v > 1) return 0;
        (*count)++;
    }
    return *count > 0;
}

SB_TEST(sample_writes_table) {
    const char *dir = sb_tmpdir("mcli");
    char p[4200], q[4200];
    snprintf(p, sizeof p, "%s/t.csv", dir);
    int rc = cli("sample microfacet:base=gold,roughness=0.5 --gonio 6,1,6,12 -o %s", p);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    CHECK(count_lines(p, 1) == 6 * 6 * 12);
    CHECK(strstr(out, "432 rows") != NULL);
    FILE *fp = fopen(p, "r");
    char line[512] = "";
    while (fp && fgets(line, sizeof line, fp) && line[0] == '#') {
    }
    if (fp) fclose(fp);
    CHECK(strcmp(line, "theta_i,phi_i,theta_o,phi_o,r,g,b\n") == 0);
    /* deterministic noise; standard output */
    snprintf(q, sizeof q, "%s/u.csv", dir);
    CHECK(cli("sample lambert --gonio 3,2,3,4 --noise 0.05 --seed 3 -q -o %s", p) == 0);
    CHECK(out[0] == 0);
    CHECK(cli("sample lambert --gonio=3,2,3,4 --noise=0.05 --seed=3 > %s", q) == 0);
    char cmd[9000];
    snprintf(cmd, sizeof cmd, "cmp -s %s %s", p, q);
    CHECK(sb_run(cmd, NULL, 0) == 0);
    /* the table reads back */
    rc = cli("info %s", p);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    CHECK(strstr(out, "format        csv") != NULL);
    CHECK(strstr(out, "rows          72 ") != NULL);
    CHECK(strstr(out, "coverage") != NULL);
    rc = cli("info %s --json --res 8", p);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    CHECK(strstr(out, "\"format\": \"csv\"") != NULL && strstr(out, "\"fraction\": ") != NULL);
}

SB_TEST(sample_bad_options) {
    const char *dir = sb_tmpdir("mcli");
    char sub[4200], p[4300];
    snprintf(sub, sizeof sub, "%s/o", dir);
    snprintf(p, sizeof p, "%s/t.csv", sub);
    CHECK(cli("sample lambert --gonio 6,1,6 -o %s", p) == 1);
    CHECK(strstr(out, "--gonio") != NULL);
    CHECK(cli("sample lambert --gonio 6,0,6,12 -o %s", p) == 1);
    CHECK(strstr(out, "N_phi_i") != NULL);
    CHECK(cli("sample lambert --noise -1 -o %s", p) == 1);
    CHECK(strstr(out, "--noise") != NULL);
    CHECK(cli("sample lambert --frobnicate -o %s", p) == 1);
    CHECK(strstr(out, "--frobnicate") != NULL);
    CHECK(cli("sample -o %s", p) == 1);
    CHECK(strstr(out, "no SOURCE") != NULL);
    CHECK(cli("sample nosuchmodel -o %s", p) == 1);
    CHECK(dir_is_empty_or_missing(sub));
    /* an unwritable output: I/O error, nothing left */
    CHECK(cli("sample lambert -o %s/no/such/dir/t.csv", dir) == 2);
    CHECK(cli("sample --help") == 0 && strstr(out, "--gonio") != NULL);
}

SB_TEST(info_errors) {
    const char *dir = sb_tmpdir("mcli");
    char p[4200];
    CHECK(cli("info %s/missing.csv", dir) == 2);
    CHECK(strstr(out, "missing.csv") != NULL);
    snprintf(p, sizeof p, "%s/bad.csv", dir);
    FILE *fp = fopen(p, "w");
    fputs("theta_i,phi_i,theta_o,phi_o,value\n10,0,10,180,1\n10,0,oops,180,1\n", fp);
    fclose(fp);
    CHECK(cli("info %s", p) == 2);
    CHECKF(strstr(out, "bad.csv:3: theta_o 'oops' is not a number") != NULL, "%s", out);
    /* out-of-range angles and float overflow: input errors, file and line named */
    snprintf(p, sizeof p, "%s/range.csv", dir);
    fp = fopen(p, "w");
    fputs("# units: degrees\ntheta_i,phi_i,theta_o,phi_o,value\n10,0,10,180,1\n1000,0,10,180,1\n", fp);
    fclose(fp);
    CHECK(cli("factor %s --res 4 --terms 1 -q -o %s/o", p, dir) == 2);
    CHECKF(strstr(out, "range.csv:4: theta_i '1000' (1000 deg) is outside 0..180 deg") != NULL, "%s", out);
    snprintf(p, sizeof p, "%s/huge.csv", dir);
    fp = fopen(p, "w");
    fputs("theta_i,phi_i,theta_o,phi_o,value\n10,0,10,180,1e308\n", fp);
    fclose(fp);
    CHECK(cli("info %s", p) == 2);
    CHECKF(strstr(out, "huge.csv:2: f_r = 1e+308 (1/sr) overflows float storage") != NULL, "%s", out);
    CHECK(cli("info") == 1);
    CHECK(cli("info %s --res 1", p) == 1);
    CHECK(cli("info %s --interp cubic", p) == 1);
    CHECK(cli("info --help") == 0 && strstr(out, "coverage") != NULL);
}

/* Truncated, oversized, wrong-dims MERL files: factor and info refuse them
 * before writing anything. */
SB_TEST(merl_bad_files) {
    const char *dir = sb_tmpdir("mcli");
    static const struct {
        const char *name;
        int32_t dims[3];
        size_t bytes;
        const char *want;
    } cases[] = {
        {"trunc.binary", {90, 90, 180}, 1000, "expected 34992012"},
        {"over.binary", {90, 90, 180}, 34992012 - 12 + 8, "file size 34992020"},
        {"dims.binary", {90, 90, 90}, 100, "expected 90 x 90 x 180"},
        {"huge.binary", {INT32_MAX, 2, 2}, 100, "dims 2147483647 x 2 x 2"},
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        char p[4200], o[4200];
        snprintf(p, sizeof p, "%s/%s", dir, cases[k].name);
        snprintf(o, sizeof o, "%s/out%zu", dir, k);
        FILE *fp = fopen(p, "wb");
        for (int d = 0; d < 3; d++)
            for (int b = 0; b < 4; b++)
                fputc((int)(((uint32_t)cases[k].dims[d] >> (8 * b)) & 0xff), fp);
        for (size_t i = 0; i < cases[k].bytes; i++)
            fputc(0, fp);
        fclose(fp);
        int rc = cli("factor %s --res 8 --terms 1 -o %s", p, o);
        CHECKF(rc == 1 || rc == 2, "%s: rc %d", cases[k].name, rc);
        CHECKF(strstr(out, cases[k].want) != NULL, "%s: %s", cases[k].name, out);
        CHECK(dir_is_empty_or_missing(o));
        CHECK(cli("info %s", p) == 2);
    }
}

/* report.json's measured.cv.theta_h_bands against the rest of the report
 * and the warning: the held-out counts add up to measured.cv.held_out,
 * the shares to 1, the bands' errors combine into cv_pooled at J
 * (cv^2 = 1 / sum_b share_b / cv_b^2, as each band's energy is
 * E_b / cv_b^2), and the warning names the band of the largest share. */
static void check_cv_bands(const char *rep, const char *msg, size_t J) {
    const char *b = strstr(rep, "\"theta_h_bands\": [");
    CHECK(b != NULL);
    if (!b) return;
    double share_sum = 0, inv = 0, best = -1, lo = 0, hi = 0;
    long held = 0;
    const char *p = b;
    for (int k = 0; k < 5; k++) {
        const char *d = strstr(p, "\"theta_h_deg\": ["), *h = d ? strstr(d, "\"held_out\": ") : NULL;
        const char *c = h ? strstr(h, "\"cv\": ") : NULL, *s = c ? strstr(c, "\"share\": ") : NULL;
        CHECKF(s != NULL, "band %d missing", k);
        if (!s) return;
        double a = strtod(d + 16, NULL), z = strtod(strchr(d, ',') + 1, NULL), cv = strtod(c + 6, NULL),
               sh = strtod(s + 9, NULL);
        held += strtol(h + 12, NULL, 10);
        share_sum += sh;
        if (sh > 0) inv += sh / (cv * cv);
        if (sh > best) best = sh, lo = a, hi = z;
        p = s;
    }
    const char *e = strstr(rep, "\"errors\"");
    for (size_t j = 0; e && j < J; j++)
        e = strstr(e + 1, "\"cv_pooled\": ");
    double cvj = e ? strtod(e + 13, NULL) : NAN;
    const char *ho = strstr(rep, "\"cv\": {");
    ho = ho ? strstr(ho, "\"held_out\": ") : NULL;
    CHECKF(ho && held == strtol(ho + 12, NULL, 10), "bands hold %ld measurements", held);
    CHECKF(fabs(share_sum - 1) < 1e-9, "shares add up to %.12f", share_sum);
    CHECKF(inv > 0 && fabs(1 / sqrt(inv) - cvj) < 1e-6 * cvj, "bands give %g, cv_pooled at J %g", 1 / sqrt(inv), cvj);
    char want[64];
    snprintf(want, sizeof want, "where theta_h is %g-%g deg", lo, hi);
    CHECKF(strstr(msg, want) != NULL, "'%s' not in: %s", want, msg);
}

/* The shared Cornell acrylic factorises end to end with finite outputs. */
SB_TEST(cornell_factor) {
    CHECKF(has_measured_dir(), "%s: the shipped measured tables are missing", SB_MEASURED_DIR);
    if (sb_test_failed_now()) return;
    const char *dir = sb_tmpdir("mcli");
    char o[4200], p[4300];
    snprintf(o, sizeof o, "%s/out", dir);
    int rc = cli("factor %s/cornell_acryl_blue.brdf --res 16 --terms 8 -o %s", SB_MEASURED_DIR, o);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    int n = 0;
    snprintf(p, sizeof p, "%s/report.json", o);
    CHECKF(report_finite(p, &n), "rel_rms not finite in %s", p);
    CHECK(n >= 4);
    /* its interpolation cannot predict its held-out samples (interp cv
     * 0.82): the warning says so and where */
    const char *rep = slurp(p);
    CHECK(rep != NULL);
    if (rep) check_cv_bands(rep, out, 8);
    /* relative to its fitted lobe: the error at the measurements falls
     * with every term (terms 6-8 raised it as fitted: job_sample_weights
     * scales them), and beside the highlight (theta_h 5-15 deg) the
     * refits predict better than zero (the values themselves, spread by
     * the interpolation, gave 12x the energy there) */
    const char *sr = rep ? strstr(rep, "\"sample_rel_l2\": [") : NULL;
    double prev = INFINITY;
    for (int j = 0; sr && j < 8; j++) {
        char *end;
        sr += j ? strspn(sr, " ,\n") : 18;
        double e = strtod(sr, &end);
        CHECKF(end != sr && e <= prev * (1 + 1e-9), "sample_rel_l2[%d] = %g after %g", j, e, prev);
        prev = e;
        sr = end;
    }
    const char *fl = rep ? strstr(rep, "\"theta_h_bands\": [") : NULL;
    fl = fl ? strstr(fl, "\"theta_h_deg\": [") : NULL;
    fl = fl ? strstr(fl + 1, "\"theta_h_deg\": [") : NULL; /* the second band, 5-15 deg */
    fl = fl ? strstr(fl, "\"cv\": ") : NULL;
    CHECKF(fl && strtod(fl + 6, NULL) < 1, "theta_h 5-15 deg: %.40s", fl ? fl : "missing");
    CHECK(rep && strstr(rep, "\"used\": true"));
    for (int j = 0; j < 4; j++) {
        snprintf(p, sizeof p, "%s/h_%02d.exr", o, j);
        CHECK(sb_file_exists(p));
    }
    rc = cli("info %s/cornell_acryl_blue.brdf --res 16", SB_MEASURED_DIR);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    CHECK(strstr(out, "rows          1439 ") != NULL && strstr(out, "wavelengths   31 (400..700 nm)") != NULL);
}

SB_TEST(alta_info_factor) {
    CHECKF(has_measured_dir(), "%s: the shipped measured tables are missing", SB_MEASURED_DIR);
    if (sb_test_failed_now()) return;
    int rc = cli("info %s/alta_retro-3M-jaune.dat --res 16", SB_MEASURED_DIR);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    CHECK(strstr(out, "rows          7397 ") != NULL);
    const char *dir = sb_tmpdir("mcli");
    char o[4200], p[4300];
    snprintf(o, sizeof o, "%s/out", dir);
    rc = cli("factor %s/alta_retro-3M-jaune.dat --res 16 --terms 2 -q -o %s", SB_MEASURED_DIR, o);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    int n = 0;
    snprintf(p, sizeof p, "%s/report.json", o);
    CHECK(report_finite(p, &n));
    /* RGL tensor files are read now (tests/test_measured_rgl.c) */
    CHECK(cli("info %s/rgl_paper_white_rgb.bsdf", SB_MEASURED_DIR) == 0);
    CHECK(strstr(out, "format        rgl") != NULL);
}

/* sample -> factor: the simulated table factorises like the model. */
SB_TEST(sample_then_factor) {
    const char *dir = sb_tmpdir("mcli");
    char t[4200], a[4200], b[4200], p[4300];
    snprintf(t, sizeof t, "%s/t.csv", dir);
    snprintf(a, sizeof a, "%s/a", dir);
    snprintf(b, sizeof b, "%s/b", dir);
    CHECK(cli("sample microfacet:base=gold,roughness=0.5 --gonio 18,1,18,72 -q -o %s", t) == 0);
    /* one parameterisation for both: auto ranks by the headline (f cos theta_i), in which every candidate of
     * form cos2 is off by > 40 % (its division by cos theta_o), so which one wins is no property of the table */
    /* --plain-terms: the matrices' fits are compared; the term weights
     * chase the headline, whose division by cos^2 theta dominates on cos2 */
    CHECK(cli("factor %s --param iso --res 16 --terms 4 --form cos2 --plain-terms -q -o %s", t, a) == 0);
    CHECK(cli("factor microfacet:base=gold,roughness=0.5 --param iso --res 16 --terms 4 --form cos2 --plain-terms -q "
              "-o %s",
              b) == 0);
    int n;
    snprintf(p, sizeof p, "%s/report.json", a);
    CHECK(report_finite(p, &n));
    double ea = report_rel_rms(p, 4);
    snprintf(p, sizeof p, "%s/report.json", b);
    double eb = report_rel_rms(p, 4);
    CHECKF(fabs(ea - eb) < 0.02, "rel_rms at J = 4: table %g, model %g", ea, eb);
    CHECK(cli("info %s --res 16", t) == 0);
    CHECKF(strstr(out, "65536 of 65536 cells (100.00 %)") != NULL, "%s", out);
}

/* A noise-free glossy table sampled coarsely: the lobe makes the table
 * predict its own samples (interp cv below 1 %), and the error at held-out
 * measurements is the 4-term fit's, not the table's.  The warning must say
 * whose it is (it once said the table did not predict itself). */
SB_TEST(cv_warning_names_the_fit) {
    const char *dir = sb_tmpdir("mcli");
    char t[4200], o[4200], p[4300];
    snprintf(t, sizeof t, "%s/g.csv", dir);
    snprintf(o, sizeof o, "%s/g", dir);
    CHECK(cli("sample microfacet:base=0.5/0.1/0.05,metallic=0,roughness=0.15 --gonio 6,1,12,24 -q -o %s", t) == 0);
    int rc = cli("factor %s --res 16 --terms 4 -o %s", t, o);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    snprintf(p, sizeof p, "%s/report.json", o);
    const char *rep = slurp(p);
    const char *ic = rep ? strstr(rep, "\"interp_cv_with\": ") : NULL,
               *cv = rep ? strstr(rep, "\"cv_headline\": ") : NULL;
    for (int j = 1; cv && j < 4; j++) /* errors[3] */
        cv = strstr(cv + 1, "\"cv_headline\": ");
    CHECK(ic && cv);
    if (!ic || !cv) return;
    double icv = strtod(ic + 18, NULL), c = strtod(cv + 15, NULL);
    CHECKF(icv < 0.01 && c > 3 * icv, "interp cv %g, cv_headline %g", icv, c);
    CHECKF(strstr(out, "the table predicts them") && strstr(out, "4 terms do not reproduce it there") &&
               !strstr(out, "does not predict itself"),
           "%s", out);
}

/* The table options mean the same in factor, study, render and info: the
 * interpolation asked for is the one used (named in the report's source),
 * and a bad value stops the command before anything is written. */
SB_TEST(table_options_everywhere) {
    const char *dir = sb_tmpdir("mcli");
    char t[4200], a[4200], b[4200], p[4300], s[4200];
    snprintf(t, sizeof t, "%s/t.csv", dir);
    snprintf(a, sizeof a, "%s/a", dir);
    snprintf(b, sizeof b, "%s/b", dir);
    snprintf(s, sizeof s, "%s/s", dir);
    CHECK(cli("sample microfacet:base=gold,roughness=0.5 --gonio 18,1,18,72 -q -o %s", t) == 0);
    CHECK(cli("factor %s --param io --res 8 --terms 2 -q -o %s", t, a) == 0);
    CHECK(cli("factor %s --param io --res 8 --terms 2 --interp idw --neighbours 6 -q -o %s", t, b) == 0);
    snprintf(p, sizeof p, "%s/report.json", a);
    double ea = report_rel_rms(p, 2);
    snprintf(p, sizeof p, "%s/report.json", b);
    double eb = report_rel_rms(p, 2);
    CHECKF(isfinite(ea) && isfinite(eb) && ea != eb, "quadratic %g, idw %g", ea, eb);
    CHECK(cli("info %s --interp idw --neighbours 6 --json", t) == 0);
    CHECKF(strstr(out, "\"idw\"") != NULL, "%s", out);
    CHECK(cli("study %s --res 8 --terms 1,2 --param io --interp idw -q -o %s", t, s) == 0);
    /* bad values: exit 1, the option named, nothing written */
    const char *bad[] = {"--interp cubic", "--neighbours 0", "--radius -1", "--white d50", "--gamut purple"};
    const char *name[] = {"--interp", "--neighbours", "--radius", "--white", "--gamut"};
    for (size_t k = 0; k < 5; k++) {
        char o2[4300];
        snprintf(o2, sizeof o2, "%s/bad%zu", dir, k);
        CHECKF(cli("factor %s --res 8 %s -q -o %s", t, bad[k], o2) == 1, "%s: %s", bad[k], out);
        CHECKF(strstr(out, name[k]) != NULL, "%s: %s", bad[k], out);
        CHECK(dir_is_empty_or_missing(o2));
        CHECKF(cli("render %s --res 8 %s -q -o %s", t, bad[k], o2) == 1, "render %s: %s", bad[k], out);
        CHECK(dir_is_empty_or_missing(o2));
    }
}

/* report.json's errors at the measured samples agree with an independent
 * evaluation: the CSV rows read here, the stored textures read back, the
 * reconstruction through sb_factors_eval, the relative L2 of f cos cos
 * written out. */
SB_TEST(sample_errors_reported) {
    const char *dir = sb_tmpdir("mcli");
    char t[4200], o[4200], p[4300];
    snprintf(t, sizeof t, "%s/t.csv", dir);
    snprintf(o, sizeof o, "%s/o", dir);
    CHECK(cli("sample microfacet:base=gold,roughness=0.5 --gonio 9,1,9,24 -q -o %s", t) == 0);
    int rc = cli("factor %s --param iso --form cos2 --res 8 -J 3 -q -o %s", t, o);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    snprintf(p, sizeof p, "%s/report.json", o);
    FILE *fp = fopen(p, "r");
    static char rep[1 << 20];
    size_t n = fp ? fread(rep, 1, sizeof rep - 1, fp) : 0;
    rep[n] = 0;
    if (fp) fclose(fp);
    const char *a = strstr(rep, "\"sample_rel_l2\": [");
    CHECKF(a != NULL, "no sample_rel_l2 in %s", p);
    CHECK(strstr(rep, "\"format\": \"csv\"") && strstr(rep, "\"interp_cv\": {"));
    if (!a) return;
    double reported[3];
    a += strlen("\"sample_rel_l2\": [");
    for (int k = 0; k < 3; k++)
        reported[k] = strtod(a, (char **)&a), a += strspn(a, ", \n");
    sb_factors_t *f = NULL;
    sb_param_t *param = NULL;
    sb_param_kind_t kind;
    sb_param_opts_t po;
    sb_form_t form;
    CHECK(sb_factors_read_exr(NULL, o, &f) == SB_OK);
    if (!f) return;
    CHECK(sb_param_parse_spec(NULL, sb_factors_get_meta(f, "param"), &kind, &po) == SB_OK);
    CHECK(sb_param_create(NULL, kind, &po, &param) == SB_OK);
    CHECK(sb_form_parse(sb_factors_get_meta(f, "form"), &form) == SB_OK && form == SB_FORM_COS2);
    double num[3] = {0, 0, 0}, den = 0;
    size_t rows = 0;
    char line[1024];
    fp = fopen(t, "r");
    while (fp && fgets(line, sizeof line, fp)) {
        double ti, pi_, to, po_, v[3], wi[3], wo[3];
        if (sscanf(line, "%lf,%lf,%lf,%lf,%lf,%lf,%lf", &ti, &pi_, &to, &po_, &v[0], &v[1], &v[2]) != 7) continue;
        ti *= SB_PI / 180, pi_ *= SB_PI / 180, to *= SB_PI / 180, po_ *= SB_PI / 180;
        wi[0] = sin(ti) * cos(pi_), wi[1] = sin(ti) * sin(pi_), wi[2] = cos(ti);
        wo[0] = sin(to) * cos(po_), wo[1] = sin(to) * sin(po_), wo[2] = cos(to);
        double w2 = wi[2] * wi[2] * wo[2] * wo[2];
        for (int j = 0; j < 3; j++) {
            double r[3];
            sb_factors_eval(f, param, form, (size_t)j + 1, wi, wo, r);
            for (int c = 0; c < 3; c++)
                num[j] += (r[c] - v[c]) * (r[c] - v[c]) * w2;
        }
        for (int c = 0; c < 3; c++)
            den += v[c] * v[c] * w2;
        rows++;
    }
    if (fp) fclose(fp);
    CHECK(rows == 9 * 9 * 24);
    for (int j = 0; j < 3; j++)
        CHECKF(fabs(reported[j] - sqrt(num[j] / den)) <= 1e-4 * sqrt(num[j] / den),
               "J = %d: reported %g, independent %g", j + 1, reported[j], sqrt(num[j] / den));
    CHECK(reported[2] < reported[0]); /* more terms fit the measurements better here */
    sb_param_destroy(param);
    sb_factors_destroy(f);
}

/* ---- sepbrdf convert ------------------------------------------------------- */

static sb_source_t *open_file(const char *path) {
    sb_source_t *s = NULL;
    sb_context_t *ctx;
    sb_context_create(&ctx);
    CHECKF(sb_measured_open(ctx, path, NULL, &s, NULL) == SB_OK, "%s: %s", path, sb_context_last_error(ctx));
    sb_context_destroy(ctx);
    return s;
}

/* Samples k of a and b agree: directions to 1e-12, values to 1e-14. */
static int same_samples(const sb_source_t *a, const sb_source_t *b, size_t ka, size_t kb) {
    double ai[3], ao[3], af[3], bi[3], bo[3], bf[3];
    int ha = sb_source_sample(a, ka, ai, ao, af), hb = sb_source_sample(b, kb, bi, bo, bf);
    if (ha != hb) return 0;
    for (int c = 0; ha && c < 3; c++)
        if (fabs(ai[c] - bi[c]) > 1e-12 || fabs(ao[c] - bo[c]) > 1e-12 ||
            fabs(af[c] - bf[c]) > 1e-14 * fmax(1, fabs(af[c])))
            return 0;
    return 1;
}

/* A sample in a scattered table's order (sort_rows in scattered.c):
 * theta_i, phi_i, theta_o, phi_o on a grid of 1e-9 rad, then the values. */
typedef struct cell {
    double k[7], wi[3], wo[3], f[3];
} cell_t;

static int cell_cmp(const void *a, const void *b) {
    const cell_t *x = a, *y = b;
    for (int k = 0; k < 7; k++)
        if (x->k[k] != y->k[k]) return x->k[k] < y->k[k] ? -1 : 1;
    return 0;
}

static void cell_key(cell_t *c) {
    const double *w[2] = {c->wi, c->wo};
    for (int d = 0; d < 2; d++) {
        double t = acos(fmin(1, fmax(-1, w[d][2]))), p = atan2(w[d][1], w[d][0]);
        if (p < 0) p += 2 * SB_PI;
        c->k[2 * d] = (double)llround(t * 1e9);
        c->k[2 * d + 1] = (double)(llround(p * 1e9) % llround(2 * SB_PI * 1e9));
    }
    for (int i = 0; i < 3; i++)
        c->k[4 + i] = c->f[i] + 0.0;
}

/* Cornell -> CSV: the same samples, in order; CSV -> CSV: the same again;
 * CSV -> MERL -> CSV: the MERL's measured cells, one row each (a table's
 * samples are in its own order, whatever the file's). */
SB_TEST(convert_csv_roundtrip) {
    CHECKF(has_measured_dir(), "%s: the shipped measured tables are missing", SB_MEASURED_DIR);
    const char *dir = sb_tmpdir("conv");
    char a[4200], b[4200], m[4200];
    snprintf(a, sizeof a, "%s/a.csv", dir);
    snprintf(b, sizeof b, "%s/b.dat", dir);
    snprintf(m, sizeof m, "%s/m.binary", dir);
    int rc = cli("convert %s/cornell_acryl_blue.brdf -o %s -q", SB_MEASURED_DIR, a);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    CHECK(cli("convert %s --out %s --format csv -q", a, b) == 0);
    sb_source_t *orig = open_file(SB_MEASURED_DIR "/cornell_acryl_blue.brdf"), *sa = open_file(a), *sb = open_file(b);
    if (orig && sa && sb) {
        size_t n = sb_source_sample_count(orig), bad = 0;
        CHECK(n == 1439 && sb_source_sample_count(sa) == n && sb_source_sample_count(sb) == n);
        for (size_t k = 0; k < n; k++)
            bad += !same_samples(orig, sa, k, k) + !same_samples(sa, sb, k, k);
        CHECKF(bad == 0, "%zu samples differ", bad);
        CHECK((sb_source_flags(sa) & (SB_SOURCE_ISOTROPIC | SB_SOURCE_RECIPROCAL)) ==
              (SB_SOURCE_ISOTROPIC | SB_SOURCE_RECIPROCAL));
    }
    sb_source_destroy(orig);
    sb_source_destroy(sa);
    sb_source_destroy(sb);
    /* to MERL and back to CSV: every measured cell a row at its centre */
    CHECK(cli("convert %s -o %s -q", a, m) == 0);
    CHECK(cli("convert %s -o %s -q", m, a) == 0);
    sb_source_t *sm = open_file(m), *sc = open_file(a);
    size_t n = sm ? sb_source_sample_count(sm) : 0;
    cell_t *cells = n ? malloc(n * sizeof *cells) : NULL;
    if (sm && sc && cells) {
        size_t measured = 0, bad = 0;
        for (size_t k = 0; k < n; k++)
            if (sb_source_sample(sm, k, cells[measured].wi, cells[measured].wo, cells[measured].f))
                cell_key(&cells[measured++]);
        qsort(cells, measured, sizeof *cells, cell_cmp);
        CHECK(measured > 100000 && sb_source_sample_count(sc) == measured);
        for (size_t k = 0; k < measured; k++) {
            double bi[3], bo[3], bf[3];
            int same = sb_source_sample(sc, k, bi, bo, bf);
            for (int c = 0; same && c < 3; c++)
                same = fabs(cells[k].wi[c] - bi[c]) <= 1e-12 && fabs(cells[k].wo[c] - bo[c]) <= 1e-12 &&
                       fabs(cells[k].f[c] - bf[c]) <= 1e-14 * fmax(1, fabs(bf[c]));
            bad += !same;
        }
        CHECKF(bad == 0, "%zu rows differ from their cells", bad);
    }
    free(cells);
    sb_source_destroy(sm);
    sb_source_destroy(sc);
}

/* MERL -> MERL keeps every cell (values to rounding of the channel
 * scales, missing cells missing); a model writes the default grid. */
SB_TEST(convert_merl_roundtrip) {
    const char *dir = sb_tmpdir("conv");
    char a[4200], b[4200], c[4200];
    snprintf(a, sizeof a, "%s/a.binary", dir);
    snprintf(b, sizeof b, "%s/b.merl", dir);
    snprintf(c, sizeof c, "%s/c.csv", dir);
    CHECK(cli("convert microfacet:base=gold,roughness=0.3 -o %s -q", a) == 0);
    CHECK(cli("convert %s -o %s --format merl -q", a, b) == 0);
    sb_source_t *sa = open_file(a), *sb = open_file(b);
    if (sa && sb) {
        size_t bad = 0;
        for (size_t k = 0; k < sb_source_sample_count(sa); k++)
            bad += !same_samples(sa, sb, k, k);
        CHECKF(bad == 0, "%zu cells differ", bad);
    }
    sb_source_destroy(sa);
    sb_source_destroy(sb);
    CHECK(cli("convert lambert -o %s -q", c) == 0);
    sb_source_t *sc = open_file(c);
    CHECK(sc && sb_source_sample_count(sc) == 18 * 18 * 72);
    sb_source_destroy(sc);
}

/* Usage errors exit 1, input errors 2; nothing is left behind. */
SB_TEST(convert_errors) {
    const char *dir = sb_tmpdir("conv");
    char p[4200];
    CHECK(cli("convert lambert") == 1 && strstr(out, "-o FILE"));
    CHECK(cli("convert -o %s/x.csv", dir) == 1 && strstr(out, "no SOURCE"));
    CHECK(cli("convert lambert -o %s/x.txt", dir) == 1 && strstr(out, "--format"));
    CHECK(cli("convert lambert -o %s/x.csv --format exr", dir) == 1 && strstr(out, "'exr'"));
    CHECK(cli("convert lambert -o %s/no/such/x.csv", dir) == 2);
    /* the file asked for, not its temporary name (on main: "x.binary.tmp-PID: cannot create") */
    CHECKF(cli("convert lambert -o %s/no/such/x.binary", dir) == 2 && strstr(out, "no/such/x.binary: cannot write") &&
               !strstr(out, ".tmp-"),
           "%s", out);
    snprintf(p, sizeof p, "%s/bad.csv", dir);
    FILE *fp = fopen(p, "w");
    fputs("theta_i,phi_i,theta_o,phi_o,value\n10,0,oops,180,1\n", fp);
    fclose(fp);
    CHECK(cli("convert %s -o %s/y.binary", p, dir) == 2 && strstr(out, "bad.csv:2"));
    snprintf(p, sizeof p, "%s/y.binary", dir);
    CHECK(!sb_file_exists(p));
    CHECK(cli("convert --help") == 0 && strstr(out, "--format"));
    /* an existing folder as the CSV: why it cannot be written is said, as
     * for MERL and sample (twelfth outside pass: "--out DIR: cannot write") */
    CHECKF(cli("convert lambert -o %s --format csv", dir) == 2 && strstr(out, "cannot write: Is a directory"), "%s",
           out);
}

/* Copy `from` to `to`, byte `at` set to `value` (at < 0: none); the first
 * `keep` bytes only when keep > 0. */
static void copy_patched(const char *from, const char *to, long at, int value, long keep) {
    FILE *in = fopen(from, "rb"), *o = fopen(to, "wb");
    CHECK(in && o);
    if (!in || !o) {
        if (in) fclose(in);
        if (o) fclose(o);
        return;
    }
    int c;
    for (long k = 0; (c = getc(in)) != EOF && (keep <= 0 || k < keep); k++)
        putc(k == at ? value : c, o);
    fclose(in);
    fclose(o);
}

/* A malformed or unsupported file is input, exit 2, from every command that
 * reads one (a bad option is usage, exit 1); the message names the file and
 * what is wrong, and no output file is left. */
SB_TEST(bad_files_exit_2) {
    CHECKF(has_measured_dir(), "%s: the shipped measured tables are missing", SB_MEASURED_DIR);
    const char *dir = sb_tmpdir("mbad");
    static const struct {
        const char *name, *from; /* from: a shipped file to patch, or NULL: text */
        long at;
        int value;
        long keep;
        const char *text, *want;
    } files[] = {
        {"version2.bsdf", "rgl_paper_white_rgb.bsdf", 12, 2, 0, NULL, "tensor_file version 2.0"},
        {"short.bsdf", "rgl_chm_orange_rgb.bsdf", -1, 0, 300, NULL, "past the end"},
        {"felt1d.alta", "alta_merl_pink-felt-1d.alta", -1, 0, 0, NULL, "#DIM 1 3: a table of 1 input (a slice"},
        {"stereo.alta", NULL, 0, 0, 0, "#DIM 3 1\n#PARAM_IN STEREOGRAPHIC\n1 2 3 4\n",
         "#PARAM_IN STEREOGRAPHIC not supported"},
        {"waves.brdf", NULL, 0, 0, 0, "# num wls\n2\n# wls\n500 450\n", "wavelengths not increasing"},
        {"noise.xyz", NULL, 0, 0, 0, "\x01\x02\x03 hello", "unrecognised measured table"},
    };
    static const char *const cmds[] = {
        "info %s --res 4",
        "factor %s --res 8 -J 1 -o %s/out",
        "render %s --res 8 -J 1 --size 16 -o %s/out",
        "study %s --res 8 --terms 1..1 -o %s/out",
        "convert %s -o %s/out.csv",
        "batch %s --res 8 -J 1 -o %s/out",
    };
    for (size_t f = 0; f < sizeof files / sizeof files[0]; f++) {
        char p[4200], from[4200], o[4200];
        snprintf(p, sizeof p, "%s/%s", dir, files[f].name);
        if (files[f].from) {
            snprintf(from, sizeof from, "%s/%s", SB_MEASURED_DIR, files[f].from);
            copy_patched(from, p, files[f].at, files[f].value, files[f].keep);
        } else {
            FILE *fp = fopen(p, "wb");
            CHECK(fp != NULL);
            if (!fp) continue;
            fputs(files[f].text, fp);
            fclose(fp);
        }
        for (size_t c = 0; c < sizeof cmds / sizeof cmds[0]; c++) {
            snprintf(o, sizeof o, "%s/run%zu_%zu", dir, f, c);
            CHECK(mkdir(o, 0755) == 0);
            int rc = cli(cmds[c], p, o);
            CHECKF(rc == 2, "%s on %s: rc %d: %s", cmds[c], files[f].name, rc, out);
            CHECKF(strstr(out, files[f].name) && strstr(out, files[f].want), "%s on %s: %s", cmds[c], files[f].name,
                   out);
            if (c == 1 || c == 2 || c == 4) CHECKF(dir_is_empty_or_missing(o), "%s left output", cmds[c]);
        }
    }
}

/* The numbers of the JSON array `key` in the text buf (up to max); the count. */
static size_t json_numbers(const char *buf, const char *key, double *v, size_t max) {
    char pat[128];
    snprintf(pat, sizeof pat, "\"%s\": [", key);
    const char *p = strstr(buf, pat);
    if (!p) return 0;
    p += strlen(pat);
    size_t n = 0;
    for (char *end;; p = end + 1) {
        double x = strtod(p, &end);
        if (end == p) break;
        if (n < max) v[n++] = x;
        while (*end == ' ' || *end == '\n')
            end++;
        if (*end != ',') break;
    }
    return n;
}

/* When J or the resolution ask for more than a measured table supports,
 * factor and study warn (stderr, report.json / study.json "warnings").
 * The rules, written out here: the last J' whose term takes more than
 * 0.1 % off the error at the measured samples (report.json
 * measured.sample_rel_l2) is what the data support; cells of 90/R deg
 * finer than half the samples' median spacing (sb_measured_open) hold
 * only interpolation. */
SB_TEST(support_warnings) {
    CHECKF(has_measured_dir(), "%s: the shipped measured tables are missing", SB_MEASURED_DIR);
    const char *dir = sb_tmpdir("msup");
    static const struct {
        const char *file, *args;
        int terms_warn; /* the data support fewer terms than asked */
    } runs[] = {
        /* --cv-folds 1: the support warnings, not the cross-validation, are tested here */
        {"alta_retro-3M-jaune.dat", "--param iso --res 8 -J 8 --cv-folds 1",
         1}, /* at R = 16 its 32 theta_h rows use all 8 */
        {"cornell_acryl_blue.brdf", "--param iso --form cos2 --weighted --res 64 -J 4 --cv-folds 1", 0},
        {"cornell_acryl_blue.brdf", "--param iso --form cos2 --weighted --res 16 -J 2 --cv-folds 1", 0},
    };
    for (size_t k = 0; k < sizeof runs / sizeof runs[0]; k++) {
        char src[4200], o[4200];
        snprintf(src, sizeof src, "%s/%s", SB_MEASURED_DIR, runs[k].file);
        snprintf(o, sizeof o, "%s/f%zu", dir, k);
        int rc = cli("factor %s %s -o %s", src, runs[k].args, o);
        CHECKF(rc == 0, "rc %d: %s", rc, out);
        char msg[sizeof out];
        memcpy(msg, out, sizeof out);
        /* the expected warnings from the data */
        sb_context_t *ctx;
        sb_context_create(&ctx);
        sb_source_t *s = NULL;
        sb_measured_info_t in;
        CHECK(sb_measured_open(ctx, src, NULL, &s, &in) == SB_OK);
        sb_source_destroy(s);
        sb_context_destroy(ctx);
        size_t res = (size_t)atoi(strstr(runs[k].args, "--res ") + 6);
        int res_warn = 90.0 / (double)res < 0.5 * in.spacing * 180 / 3.14159265358979323846;
        snprintf(o + strlen(o), sizeof o - strlen(o), "/report.json");
        const char *rep = slurp(o);
        CHECK(rep != NULL);
        if (!rep) continue;
        double e[64];
        size_t n = json_numbers(rep, "sample_rel_l2", e, 64), best = 0;
        CHECK(n == (size_t)atoi(strstr(runs[k].args, "-J ") + 3));
        for (size_t j = 1; j < n; j++)
            if (e[j] < e[best] * 0.999) best = j;
        char want[128];
        snprintf(want, sizeof want, "terms beyond J = %zu do not lower the error at the", best + 1);
        const char *w = strstr(rep, "\"warnings\"");
        CHECK(w != NULL);
        if (!w) continue;
        CHECKF(!strstr(w, want) == !(best + 1 < n), "%s: J' = %zu of %zu: %s", runs[k].file, best + 1, n, w);
        CHECKF(!strstr(msg, want) == !(best + 1 < n), "%s: %s", runs[k].file, msg);
        CHECKF((best + 1 < n) == runs[k].terms_warn, "%s: the data support J' = %zu of %zu", runs[k].file, best + 1, n);
        snprintf(want, sizeof want, "resolution %zu: cells of", res);
        CHECKF(!strstr(w, want) == !res_warn && !strstr(msg, want) == !res_warn, "%s: %s", runs[k].file, w);
        CHECK(res_warn == (res == 64)); /* Cornell's median spacing is 3.8 deg */
    }
    /* study: the warnings of each run after its last J, in study.json */
    /* the plain fit (form f, unweighted): its 8 terms are more than the table supports */
    int rc = cli("study %s/alta_retro-3M-jaune.dat --param iso --form f --unweighted --res 16 --terms 1..8 -o %s/s",
                 SB_MEASURED_DIR, dir);
    CHECKF(rc == 0 && strstr(out, "on iso: terms beyond J = "), "rc %d: %s", rc, out);
    char p[4300];
    snprintf(p, sizeof p, "%s/s/study.json", dir);
    const char *st = slurp(p);
    const char *ws = st ? strstr(st, "\"warnings\": [") : NULL;
    CHECK(ws && strstr(ws, "terms beyond J = ") && strstr(ws, "terms beyond J = ") < strstr(ws, "]"));
}

/* The cross-validated error bounds the error at measurements nobody
 * fitted: a GGX table from a simulated gonioreflectometer (12 x 48
 * detector positions), factored with the defaults, and a second table of
 * the same model at other positions (11 x 43, never fitted): the kept
 * fit's error of f cos theta_i at the second table's measurements is
 * below 2x the cv_headline the first run reports, and small (the table is
 * interpolated relative to its fitted lobe). */
SB_TEST(cv_predicts_unseen_measurements) {
    const char *dir = sb_tmpdir("mcli");
    char t[4200], u[4200];
    snprintf(t, sizeof t, "%s/t.csv", dir);
    snprintf(u, sizeof u, "%s/u.csv", dir);
    const char *model = "cook-torrance:d=ggx,roughness=0.3";
    CHECK(cli("sample %s --gonio 12,1,12,48 -q -o %s", model, t) == 0);
    CHECK(cli("sample %s --gonio 11,1,11,43 -q -o %s", model, u) == 0);
    sb_job_opts_t o = {0};
    o.source = t;
    o.res = 16;
    o.terms = 4;
    sb_job_t *job = NULL;
    sb_source_t *other = NULL;
    CHECK(sb_job_run(NULL, &o, &job) == SB_OK && sb_source_open(NULL, u, &other) == SB_OK);
    if (!job || !other) return;
    double se, cv = sb_job_cv(job, 4, &se, NULL), e2 = 0, t2 = 0;
    for (size_t i = 0; i < sb_source_sample_count(other); i++) {
        double wi[3], wo[3], v[3], r[3];
        if (!sb_source_sample(other, i, wi, wo, v)) continue;
        if (!sb_factors_eval(sb_job_factors(job), sb_job_param(job), sb_job_form(job), 4, wi, wo, r))
            r[0] = r[1] = r[2] = 0;
        for (int c = 0; c < 3; c++)
            e2 += (r[c] - v[c]) * (r[c] - v[c]) * wi[2] * wi[2], t2 += v[c] * v[c] * wi[2] * wi[2];
    }
    double unseen = sqrt(e2 / t2);
    printf("cv_headline %g +- %g, unseen measurements %g, headline %g\n", cv, se, unseen, sb_job_headline(job, 4));
    /* its splits are two clusters (about 0.001, and 0.011 where a split
     * holds a grazing peak row): the figure is the larger one's, and a
     * refit left out moves it to the other (jackknife 0.0094) */
    CHECKF(isfinite(cv) && se > 0 && isfinite(se), "cv %g +- %g", cv, se);
    /* The refits never see a fold's samples, and this table's energy sits
     * in a few grazing peak samples that a refit without them predicts to
     * 10-20 %: the cross-validated figure may be above the error at the
     * second table's samples (0.1 against 0.014 with the lobe), never far
     * below it. */
    CHECKF(unseen < 2 * cv, "cv_headline %g, unseen measurements %g (headline %g)", cv, unseen,
           sb_job_headline(job, 4));
    CHECKF(unseen < 0.05, "unseen measurements %g (without the lobe 0.33)", unseen);
    /* the refits run side by side on the cores: on one thread, in turn,
     * the figures are the same bits */
    sb_job_t *one = NULL;
    setenv("SEPBRDF_THREADS", "1", 1);
    CHECK(sb_job_run(NULL, &o, &one) == SB_OK);
    unsetenv("SEPBRDF_THREADS");
    for (size_t j = 1; one && j <= 4; j++) {
        double se1, cv1 = sb_job_cv(one, j, &se1, NULL), se2, cv2 = sb_job_cv(job, j, &se2, NULL);
        CHECKF(memcmp(&cv1, &cv2, sizeof cv1) == 0 && memcmp(&se1, &se2, sizeof se1) == 0,
               "J' = %zu: cv %.17g +- %.17g on one thread, %.17g +- %.17g on all", j, cv1, se1, cv2, se2);
    }
    sb_job_destroy(one);
    /* an analytic source has none */
    sb_job_t *an = NULL;
    o.source = model;
    CHECK(sb_job_run(NULL, &o, &an) == SB_OK && isnan(sb_job_cv(an, 1, NULL, NULL)));
    sb_job_destroy(an);
    sb_job_destroy(job);
    sb_source_destroy(other);
}

/* convert to MERL writes only what the table measured: an RGL file's f
 * cos theta divided by grazing cosines (cells above its largest measured
 * value, cells with the light within 1 deg of the horizon) is written as
 * missing and counted; --extrapolated keep / --horizon 0 write them (the
 * old behaviour: values up to 1e4-1e7), with a warning; a model has no
 * measured range. */
SB_TEST(convert_merl_reports_extrapolation) {
    const char *dir = sb_tmpdir("mcli");
    char src[4200], bin[4300];
    snprintf(src, sizeof src, "%s/rgl_paper_white_rgb.bsdf", SB_MEASURED_DIR);
    snprintf(bin, sizeof bin, "%s/p.binary", dir);
    sb_source_t *s = NULL, *m = NULL;
    CHECK(sb_source_open(NULL, src, &s) == SB_OK && sb_source_open(NULL, "lambert", &m) == SB_OK);
    if (!s || !m) return;
    sb_merl_write_stats_t st, kept;
    CHECK(sb_merl_write_stats(NULL, bin, s, NULL, &st) == SB_OK);
    const sb_measured_info_t *in = sb_measured_source_info(s);
    CHECK(st.cells == SB_MERL_CELLS && st.written > 0 && st.written < st.cells);
    double vm = fmax(in->value_max[0], fmax(in->value_max[1], in->value_max[2]));
    CHECKF(st.above > 0 && st.above_max > vm && st.value_max <= vm && st.value_measured == vm,
           "above %zu (up to %g), written max %g, measured %g (table %g)", st.above, st.above_max, st.value_max,
           st.value_measured, vm);
    CHECKF(st.grazing > 0 && st.horizon_deg == 1, "grazing %zu at %g deg", st.grazing, st.horizon_deg);
    /* the file holds no cell above the measured range, none with a grazing light */
    sb_source_t *b = NULL;
    CHECK(sb_source_open(NULL, bin, &b) == SB_OK);
    size_t bad = 0, cells = 0;
    for (size_t k = 0; b && k < sb_source_sample_count(b); k++) {
        double wi[3], wo[3], f[3];
        if (!sb_source_sample(b, k, wi, wo, f)) continue;
        cells++;
        bad += fmax(f[0], fmax(f[1], f[2])) > vm * (1 + 1e-12) || wi[2] <= sin(SB_PI / 180);
    }
    CHECKF(bad == 0 && cells == st.written, "%zu of %zu cells beyond the table (%zu written)", bad, cells, st.written);
    sb_source_destroy(b);
    sb_write_opts_t keep = {1, -1};
    CHECK(sb_merl_write_stats(NULL, bin, s, &keep, &kept) == SB_OK);
    CHECKF(kept.grazing == 0 && kept.above > st.above && kept.value_max == kept.above_max &&
               kept.value_max > 1e3 * vm && kept.written == st.written + st.above + st.grazing,
           "kept: above %zu, max %g, written %zu (default: %zu + %zu + %zu)", kept.above, kept.value_max, kept.written,
           st.written, st.above, st.grazing);
    CHECK(sb_merl_write_stats(NULL, bin, m, NULL, &st) == SB_OK && st.above == 0 && st.grazing == 0 &&
          isnan(st.value_measured) && st.written > 1000000);
    CHECK(cli("convert %s -o %s", src, bin) == 0);
    CHECKF(strstr(out, "written as missing (-1); --extrapolated keep") && strstr(out, "within 1 deg of the horizon") &&
               !strstr(out, "warning"),
           "%s", out);
    CHECK(cli("convert %s -o %s --extrapolated keep --horizon 0", src, bin) == 0);
    CHECKF(strstr(out, "warning") && strstr(out, "extrapolated, not measured"), "%s", out);
    CHECK(cli("convert %s -o %s --extrapolated maybe", src, bin) == 1 && strstr(out, "keep or drop"));
    CHECK(cli("convert %s -o %s/p.csv --extrapolated keep", src, dir) == 1 && strstr(out, "MERL output"));
    CHECK(cli("convert %s -o %s --horizon 90", src, bin) == 1 && strstr(out, "--horizon"));
    sb_source_destroy(s);
    sb_source_destroy(m);
}

/* The largest value of a CSV's rows (max over r, g, b) and its largest
 * theta_i (degrees). */
static void csv_extent(const char *path, double *vmax, double *ti_max) {
    FILE *fp = fopen(path, "r");
    char line[1024];
    *vmax = *ti_max = -1;
    while (fp && fgets(line, sizeof line, fp)) {
        double a[7];
        if (sscanf(line, "%lf,%lf,%lf,%lf,%lf,%lf,%lf", a, a + 1, a + 2, a + 3, a + 4, a + 5, a + 6) != 7) continue;
        *ti_max = fmax(*ti_max, a[0]);
        *vmax = fmax(*vmax, fmax(a[4], fmax(a[5], a[6])));
    }
    if (fp) fclose(fp);
}

/* Factoring the MERL file that convert writes from an RGL file spends its
 * terms on the material, not on extrapolated grazing cells: the headline
 * at J = 2 (default otherwise) is far below the 0.99 it was when those
 * cells were written (up to 8.6e4 1/sr, the file's measured range 6.3),
 * 0.17 now. */
SB_TEST(convert_rgl_merl_factors) {
    const char *dir = sb_tmpdir("mcli");
    char bin[4300], set[4300], rep[4400];
    snprintf(bin, sizeof bin, "%s/a.binary", dir);
    snprintf(set, sizeof set, "%s/a", dir);
    snprintf(rep, sizeof rep, "%s/report.json", set);
    CHECK(cli("convert %s/rgl_paper_white_rgb.bsdf -o %s -q", SB_MEASURED_DIR, bin) == 0);
    int rc = cli("factor %s -J 2 -o %s -q", bin, set);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    const char *p = slurp(rep);
    double h = NAN;
    for (int k = 0; p && k < 2 && (p = strstr(p, "\"headline\": ")); k++)
        h = atof(p += 12);
    CHECKF(h < 0.4, "headline at J = 2: %g (0.99 with the extrapolated cells)", h);
}

/* RGL to CSV keeps the colour nodes only: said, with their count, and
 * every row is one of the file's nodes (the reader's samples). */
SB_TEST(convert_rgl_csv_warns) {
    const char *dir = sb_tmpdir("mcli");
    char src[4200], csv[4300];
    snprintf(src, sizeof src, "%s/rgl_paper_white_rgb.bsdf", SB_MEASURED_DIR);
    snprintf(csv, sizeof csv, "%s/p.csv", dir);
    CHECK(cli("convert %s -o %s", src, csv) == 0);
    CHECKF(strstr(out, "VNDF warp") && strstr(out, "factor the .bsdf itself"), "%s", out);
    sb_source_t *s = NULL;
    CHECK(sb_source_open(NULL, src, &s) == SB_OK);
    char want[64];
    snprintf(want, sizeof want, "of the RGL file's %zu colour nodes", sb_source_sample_count(s));
    CHECKF(strstr(out, want) != NULL, "%s", out);
    size_t rows = count_lines(csv, 1);
    CHECK(rows > 0 && rows < sb_source_sample_count(s));
    /* no row with the light within 1 deg of the horizon, where f is the
     * stored f cos theta_i over a cosine near 0: said, with the count and
     * the largest value left out; --horizon 0 writes them (up to 5e6) */
    double vmax, ti_max, v0, t0;
    csv_extent(csv, &vmax, &ti_max);
    CHECKF(ti_max < 89 && vmax < 1e3, "theta_i up to %g deg, values up to %g", ti_max, vmax);
    CHECKF(strstr(out, "samples with the light within 1 deg of the horizon left out") != NULL, "%s", out);
    char csv0[4300];
    snprintf(csv0, sizeof csv0, "%s/p0.csv", dir);
    CHECK(cli("convert %s -o %s --horizon 0 -q", src, csv0) == 0);
    csv_extent(csv0, &v0, &t0);
    size_t rows0 = count_lines(csv0, 1);
    CHECKF(t0 > 89 && v0 > 1e5 && rows0 > rows, "--horizon 0: theta_i up to %g, values up to %g, %zu rows", t0, v0,
           rows0);
    snprintf(want, sizeof want, "%zu samples with", rows0 - rows);
    CHECKF(strstr(out, want) == NULL, "-q: %s", out);
    CHECK(cli("convert %s -o %s", src, csv) == 0 && strstr(out, want));
    sb_source_destroy(s);
}

/* cv_headline is what the whole pipeline's refits err by: each refit is
 * fitted as the kept fit was (its texel filters and term weights replayed),
 * and on a glossy noisy paint the figure from the five folds agrees with
 * whole runs on the same folds (sb_measured_opts_t cv_folds / cv_fold)
 * evaluated at the rows each left out.  The plain refits (no texel filter)
 * reported 1.3x what the whole runs err by. */
SB_TEST(cv_is_the_pipelines_refit) {
    const char *dir = sb_tmpdir("mcli");
    char t[4200];
    snprintf(t, sizeof t, "%s/gloss.csv", dir);
    CHECK(cli("sample microfacet:base=0.8/0.15/0.08,metallic=0,roughness=0.15 --gonio 8,1,16,32 --noise 0.03 -q -o "
              "%s",
              t) == 0);
    sb_job_opts_t o = {0};
    o.source = t;
    o.terms = 4;
    sb_job_t *job = NULL;
    CHECK(sb_job_run(NULL, &o, &job) == SB_OK);
    if (!job) return;
    double cv = sb_job_cv(job, 4, NULL, NULL), e[5];
    o.param = sb_param_spec(sb_job_param(job)); /* the kept layout, as the refits keep it */
    o.weighted = 1;
    o.measured.cv_folds = 10;
    for (size_t k = 0; k < 5; k++) {
        o.measured.cv_fold = k;
        sb_job_t *fk = NULL;
        CHECK(sb_job_run(NULL, &o, &fk) == SB_OK);
        double e2 = 0, t2 = 0;
        for (size_t i = 0; fk && i < sb_source_sample_count(sb_job_source(job)); i++) {
            double wi[3], wo[3], v[3], r[3];
            if (sb_measured_fold(i, 10) != k || !sb_source_sample(sb_job_source(job), i, wi, wo, v)) continue;
            if (!sb_factors_eval(sb_job_factors(fk), sb_job_param(fk), sb_job_form(fk), 4, wi, wo, r))
                r[0] = r[1] = r[2] = 0;
            for (int c = 0; c < 3; c++)
                e2 += (r[c] - v[c]) * (r[c] - v[c]) * wi[2] * wi[2], t2 += v[c] * v[c] * wi[2] * wi[2];
        }
        e[k] = fk ? sqrt(e2 / t2) : NAN;
        sb_job_destroy(fk);
    }
    for (int a = 0; a < 5; a++) /* sort */
        for (int b = a + 1; b < 5; b++)
            if (e[b] < e[a]) {
                double x = e[a];
                e[a] = e[b], e[b] = x;
            }
    printf("cv_headline %g; whole runs on the same folds %g %g %g %g %g (median %g)\n", cv, e[0], e[1], e[2], e[3],
           e[4], e[2]);
    CHECKF(cv < 1.15 * e[2] && e[2] < 1.15 * cv, "cv_headline %g, the whole runs' median %g", cv, e[2]);
    sb_job_destroy(job);
}

/* A sparse table whose near-peak rows its lobe cannot follow: RGL
 * chm_orange evaluated at the Cornell acrylic's 1439 directions.  The
 * refits' own tables err there by more than 0.3 (the leave-one-out interp
 * cv, with the lobe fitted on every sample, said 0.29 and the warning once
 * blamed the 4-term fit), report.json says so in measured.cv.table, and
 * the warning names the table, and fewer terms exactly where they predict
 * the held-out rows better. */
SB_TEST(cv_names_the_table_and_fewer_terms) {
    const char *dir = sb_tmpdir("mcli");
    char src[4200], ac[4200], t[4200], o[4200], p[4300];
    snprintf(src, sizeof src, "%s/rgl_chm_orange_rgb.bsdf", SB_MEASURED_DIR);
    snprintf(ac, sizeof ac, "%s/cornell_acryl_blue.brdf", SB_MEASURED_DIR);
    snprintf(t, sizeof t, "%s/orange_at_cornell.csv", dir);
    snprintf(o, sizeof o, "%s/oc", dir);
    sb_source_t *s = NULL, *a = NULL;
    CHECK(sb_source_open(NULL, src, &s) == SB_OK && sb_source_open(NULL, ac, &a) == SB_OK);
    FILE *f = fopen(t, "w");
    CHECK(f != NULL);
    if (!s || !a || !f) return;
    fprintf(f, "# symmetry: isotropic\ntheta_i,phi_i,theta_o,phi_o,r,g,b\n");
    size_t rows = 0;
    for (size_t i = 0; i < sb_source_sample_count(a); i++) {
        double wi[3], wo[3], v[3];
        if (!sb_source_sample(a, i, wi, wo, v) || !sb_source_eval(s, wi, wo, v)) continue;
        fprintf(f, "%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g\n", acos(wi[2]) * 180 / SB_PI, atan2(wi[1], wi[0]) * 180 / SB_PI,
                acos(wo[2]) * 180 / SB_PI, atan2(wo[1], wo[0]) * 180 / SB_PI, v[0], v[1], v[2]);
        rows++;
    }
    fclose(f);
    sb_source_destroy(s);
    sb_source_destroy(a);
    CHECKF(rows > 1400, "%zu rows", rows);
    int rc = cli("factor %s --terms 4 -o %s", t, o);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    CHECKF(strstr(out, "the table does not predict them"), "%s", out);
    /* "fewer terms" where the held-out line says so (1.25x lower: JOB_CV_FEWER;
     * which J' is lower depends on the folds: on the rows in the Cornell
     * file's order J' = 3 was, in the table's order J' = 3 and 4 agree) */
    const char *ho = strstr(out, "held-out measurements (");
    double cv[4] = {0, 0, 0, 0};
    for (int j = 0; ho && j < 4; j++) {
        char key[16];
        snprintf(key, sizeof key, "J %d ", j + 1);
        const char *at = strstr(ho, key);
        cv[j] = at ? strtod(at + strlen(key), NULL) : 0;
    }
    CHECKF(cv[3] > 0, "%s", out);
    int fewer = 0;
    for (int j = 0; j < 3; j++)
        fewer |= cv[j] * 1.25 < cv[3];
    CHECKF(fewer == (strstr(out, "fewer terms predict them better") != NULL), "%s", out);
    snprintf(p, sizeof p, "%s/report.json", o);
    const char *rep = slurp(p);
    const char *tb = rep ? strstr(rep, "\"table\": ") : NULL;
    CHECK(tb != NULL);
    if (tb) CHECKF(strtod(tb + 9, NULL) > 0.3, "measured.cv.table %g", strtod(tb + 9, NULL));
}

/* A layout that does not hold the table at any J is named as such: the
 * RGL paper on hd (its nodes with the light at grazing hold values up to
 * 3e10 that only vndf reproduces) errs by 98 % at its samples at J = 1 and
 * 2, and the warning blamed the terms beyond J = 1 ("they fit the
 * interpolation, not the data"). */
SB_TEST(layout_missing_the_table_named) {
    const char *dir = sb_tmpdir("mmiss");
    /* form f (hd named alone takes form cos on an RGL file now, and holds it) */
    int rc = cli("factor %s/rgl_paper_white_rgb.bsdf --param hd --form f -r 8 -J 2 -o %s/hd", SB_MEASURED_DIR, dir);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    CHECKF(strstr(out, "the textures miss the") && strstr(out, "at every J") &&
               strstr(out, "layout hd does not hold this table's values") && strstr(out, "--param auto keeps") &&
               !strstr(out, "terms beyond J"),
           "%s", out);
}

/* Below --theta-max 90 the errors at the measured samples are those within
 * the cap, as the headline's (seventh outside pass): the samples beyond
 * (the snippet returns 0 there) are counted in measured.outside and left
 * out.  On main they counted as error: the Cornell acrylic on iso, R = 8,
 * J = 2 at 60 degrees read 0.53 at every J (892 of 1439 samples beyond)
 * and warned that terms beyond J = 1 did not lower it; 0.022 within. */
/* The cross-validated error within a --theta-max cap counts the held-out
 * measurements within it only, as the errors at the samples do: beyond the
 * cap the snippet returns 0 and every refit "errs" by the measurement
 * itself (on main the acrylic at 60 deg read cv 0.70, 85x its headline,
 * from its 892 of 1439 samples beyond the cap). */
SB_TEST(cv_within_cap) {
    const char *dir = sb_tmpdir("mcap");
    int rc =
        cli("factor %s/cornell_acryl_blue.brdf --param iso -r 8 -J 2 --theta-max 60 -o %s/a", SB_MEASURED_DIR, dir);
    const char *h = strstr(out, "held-out measurements (");
    size_t held = h ? strtoul(h + strlen("held-out measurements ("), NULL, 10) : 0;
    CHECKF(rc == 0 && held > 0 && held <= 1439 - 892, "rc %d, %zu held out within the cap: %s", rc, held, out);
    char path[4200];
    snprintf(path, sizeof path, "%s/a/report.json", dir);
    char *rep = slurp(path), *p, *end = rep ? strstr(rep, "\n  \"measured\": {") : NULL;
    if (end) *end = 0;         /* errors[] comes before it */
    double cv = NAN, hl = NAN; /* the last of errors[]: J = 2 */
    for (p = rep ? strstr(rep, "\n  \"errors\": [") : NULL; p && (p = strstr(p, "\"cv_headline\": ")) != NULL; p++)
        cv = atof(p + strlen("\"cv_headline\": "));
    for (p = rep ? strstr(rep, "\n  \"errors\": [") : NULL; p && (p = strstr(p, "\"headline\": ")) != NULL; p++)
        hl = atof(p + strlen("\"headline\": "));
    CHECKF(cv < 0.15 && cv < 8 * hl, "cv %g against the headline %g at J = 2", cv, hl);
}

SB_TEST(sample_errors_within_cap) {
    const char *dir = sb_tmpdir("mcap");
    int rc = cli("factor %s/cornell_acryl_blue.brdf --param iso -r 8 -J 2 --cv-folds 1 --theta-max 60 -o %s/a",
                 SB_MEASURED_DIR, dir);
    CHECKF(rc == 0 && !strstr(out, "do not lower the error at the"), "rc %d: %s", rc, out);
    char path[4200];
    snprintf(path, sizeof path, "%s/a/report.json", dir);
    const char *rep = slurp(path); /* a static buffer */
    double e[2] = {NAN, NAN}, n = NAN, o = NAN;
    const char *m = rep ? strstr(rep, "\"measured\": {") : NULL;
    if (m) json_numbers(m, "sample_rel_l2", e, 2);
    if (m && strstr(m, "\"samples\": ")) n = atof(strstr(m, "\"samples\": ") + 11);
    if (m && strstr(m, "\"outside\": ")) o = atof(strstr(m, "\"outside\": ") + 11);
    CHECKF(o > 0 && n > 0 && n + o == 1439 && e[1] < 0.1, "samples %g, outside %g, e(2) %g", n, o, e[1]);
}

/* --max-error out of reach on a scattered table whose held-out error rises
 * past a few terms (the acrylic: lowest at J = 4, 0.141; 0.183 at J = 12):
 * the warning named "raise --terms or --res", which fits the interpolation
 * further and predicts the measurements worse.  It names the terms that
 * err least there instead, as report.json's cv_headline has them. */
SB_TEST(max_error_unmet_names_fewer_terms) {
    const char *dir = sb_tmpdir("mmax");
    int rc = cli("factor %s/cornell_acryl_blue.brdf --terms 12 --max-error 1e-4 -q -o %s/a", SB_MEASURED_DIR, dir);
    const char *w = strstr(out, "--max-error 0.0001 not reached"), *k = w ? strstr(w, "left out of the fit ") : NULL;
    size_t jb = k ? strtoul(k + strlen("left out of the fit "), NULL, 10) : 0;
    CHECKF(rc == 0 && w && !strstr(w, "raise --terms") && jb >= 1 && jb < 12, "rc %d, J %zu: %s", rc, jb, out);
    char path[4200];
    snprintf(path, sizeof path, "%s/a/report.json", dir);
    char *rep = slurp(path), *p, *end = rep ? strstr(rep, "\n  \"measured\": {") : NULL;
    if (end) *end = 0; /* errors[] comes before it */
    double cv[12];
    size_t n = 0;
    for (p = rep ? strstr(rep, "\n  \"errors\": [") : NULL; p && n < 12 && (p = strstr(p, "\"cv_headline\": ")) != NULL;
         p++)
        cv[n++] = atof(p + strlen("\"cv_headline\": "));
    CHECKF(n == 12 && jb >= 1 && jb < 12, "%zu cv figures", n);
    if (n == 12 && jb >= 1 && jb < 12) { /* the terms named err least, and clearly less than J = 12 */
        for (size_t j = 0; j < 12; j++)
            CHECKF(cv[jb - 1] <= cv[j], "cv %g at J = %zu below the %g named at J = %zu", cv[j], j + 1, cv[jb - 1], jb);
        CHECKF(cv[jb - 1] * 1.25 < cv[11], "cv %g at J = %zu against %g at J = 12", cv[jb - 1], jb, cv[11]);
    }
}
