/* `sepbrdf bench --pareto`: the real binary writes pareto.csv and
 * pareto.png, and the points it marks are exactly those that no other
 * point beats on both CPU seconds and headline error. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"

#define MAXROWS 16

typedef struct row {
    int ok, front;
    double cpu, headline;
} row_t;

/* The rows of pareto.csv (header checked); -1 when it cannot be read. */
static int read_csv(const char *path, row_t *rows) {
    FILE *fp = fopen(path, "r");
    char line[512];
    int n = 0;
    if (!fp || !fgets(line, sizeof line, fp) ||
        strcmp(line, "layout,method,used,res,terms,ok,cpu_s,headline,peak_mib,front\n") != 0) {
        if (fp) fclose(fp);
        return -1;
    }
    while (n < MAXROWS && fgets(line, sizeof line, fp)) {
        char *f[10], *save = NULL, *tok = strtok_r(line, ",", &save);
        int k = 0;
        for (; tok && k < 10; tok = strtok_r(NULL, ",", &save))
            f[k++] = tok;
        if (k != 10 && k != 9) break; /* a failed run has no method used: 9 fields */
        int o = k - 10;               /* 0, or -1 without `used` */
        rows[n] = (row_t){atoi(f[5 + o]), atoi(f[9 + o]), atof(f[6 + o]), atof(f[7 + o])};
        n++;
    }
    fclose(fp);
    return n;
}

/* Point i is dominated: another costs no more and errs no more, and is
 * better in one of them. */
static int dominated(const row_t *r, int n, int i) {
    for (int j = 0; j < n; j++)
        if (j != i && r[j].ok && r[j].cpu <= r[i].cpu && r[j].headline <= r[i].headline &&
            (r[j].cpu < r[i].cpu || r[j].headline < r[i].headline))
            return 1;
    return 0;
}

SB_TEST(pareto_front_and_files) {
    const char *dir = sb_tmpdir("bench_pareto");
    char cmd[4096], out[8192];
    snprintf(cmd, sizeof cmd, "%s bench --pareto --layouts io,iso --methods auto --res 8 --terms 1,2 -q -o %s 2>&1",
             SB_CLI, dir);
    CHECKF(sb_run(cmd, out, sizeof out) == 0, "%s", out);
    char path[4096];
    snprintf(path, sizeof path, "%s/pareto.csv", dir);
    row_t r[MAXROWS];
    int n = read_csv(path, r), fronts = 0;
    CHECKF(n == 4, "%d rows", n);
    for (int i = 0; i < n; i++) {
        CHECK(r[i].ok && r[i].cpu > 0 && r[i].headline > 0 && r[i].headline < 10);
        CHECKF(r[i].front == !dominated(r, n, i), "row %d: front %d", i, r[i].front);
        fronts += r[i].front;
    }
    CHECK(fronts >= 1);
    /* the plot: a PNG of 640 x 420 */
    snprintf(path, sizeof path, "%s/pareto.png", dir);
    FILE *fp = fopen(path, "rb");
    unsigned char h[24] = {0};
    CHECK(fp && fread(h, 1, sizeof h, fp) == sizeof h);
    if (fp) fclose(fp);
    CHECK(memcmp(h, "\x89PNG\r\n\x1a\n", 8) == 0 && memcmp(h + 12, "IHDR", 4) == 0);
    CHECK(((h[16] << 24) | (h[17] << 16) | (h[18] << 8) | h[19]) == 640);
    CHECK(((h[20] << 24) | (h[21] << 16) | (h[22] << 8) | h[23]) == 420);
}

SB_TEST(pareto_bad_options) {
    char cmd[4096], out[8192];
    snprintf(cmd, sizeof cmd, "%s bench --pareto --methods nosuch 2>&1", SB_CLI);
    CHECKF(sb_run(cmd, out, sizeof out) == 1 && strstr(out, "nosuch"), "%s", out);
    snprintf(cmd, sizeof cmd, "%s bench --pareto --res 0 2>&1", SB_CLI);
    CHECKF(sb_run(cmd, out, sizeof out) == 1 && strstr(out, "--res"), "%s", out);
    snprintf(cmd, sizeof cmd, "%s bench --pareto --frobnicate 2>&1", SB_CLI);
    CHECKF(sb_run(cmd, out, sizeof out) == 1 && strstr(out, "--frobnicate"), "%s", out);
}

/* bench takes what the other commands take: a measured file as --model
 * and -J for --terms; the full method's error is the Eckart-Young optimum
 * (dgesdd, excess ~ 0); a J list without 8 still plots (the left panel
 * shows the largest J), without gnuplot's "empty range" warnings. */
SB_TEST(measured_model_and_J) {
    const char *dir = sb_tmpdir("bench_measured");
    char cmd[4096], out[8192];
    snprintf(cmd, sizeof cmd,
             "%s bench --model %s/rgl_chm_orange_rgb.bsdf -J 2 --sizes 16 --methods full --min-time 0 -o %s 2>&1",
             SB_CLI, SB_MEASURED_DIR, dir);
    CHECKF(sb_run(cmd, out, sizeof out) == 0, "%s", out);
    CHECKF(!strstr(out, "gnuplot failed"), "%s", out);
    CHECKF(!strstr(out, " range ["), "%s", out); /* one size, an excess of 0: gnuplot's "empty range" */
    char path[4200], line[512];
    snprintf(path, sizeof path, "%s/results.csv", dir);
    FILE *fp = fopen(path, "r");
    int rows = 0;
    while (fp && fgets(line, sizeof line, fp)) {
        char *f[21], *save = NULL, *tok = strtok_r(line, ",", &save);
        int k = 0;
        for (; tok && k < 21; tok = strtok_r(NULL, ",", &save))
            f[k++] = tok;
        if (k < 17 || strcmp(f[0], "n") == 0) continue;
        rows++;
        double rel = atof(f[14]), opt = atof(f[15]);
        CHECKF(atoi(f[0]) == 16 && atoi(f[2]) == 2 && rel > 0 && rel < 1, "%s %s %s", f[0], f[2], f[14]);
        CHECKF(fabs(rel - opt) <= 1e-9 * opt, "full %.12g against dgesdd %.12g", rel, opt);
    }
    if (fp) fclose(fp);
    CHECK(rows == 1);
    /* --no-baseline: the excess is nan in results.csv, the right panel shows the error itself, the
       table says "-" (it printed "nan": fourteenth outside pass) */
    snprintf(cmd, sizeof cmd, "%s bench -J 2 --sizes 16 --methods full --min-time 0 --no-baseline -o %s/nb 2>&1",
             SB_CLI, dir);
    CHECKF(sb_run(cmd, out, sizeof out) == 0 && !strstr(out, "gnuplot failed"), "%s", out);
    CHECKF(strstr(out, "         - ") && !strstr(out, "nan"), "%s", out); /* %9s after rel_err */
}

/* bench's -o as every writing command's: a folder created with its parents
 * (was "cannot create the folder", exit 2, naming no reason), a file
 * refused as "exists and is not a folder", an empty name a usage error;
 * --pareto the same. */
SB_TEST(out_folder_as_other_commands) {
    const char *dir = sb_tmpdir("bench_out");
    char cmd[8400], out[8192], path[4200];
    snprintf(cmd, sizeof cmd, "%s bench -J 1 --sizes 16 --methods full --min-time 0 --no-baseline -o %s/a/b/c 2>&1",
             SB_CLI, dir);
    CHECKF(sb_run(cmd, out, sizeof out) == 0, "%s", out);
    snprintf(path, sizeof path, "%s/a/b/c/results.csv", dir);
    CHECKF(sb_file_exists(path), "%s missing: %s", path, out);
    snprintf(path, sizeof path, "%s/file", dir);
    FILE *fp = fopen(path, "w");
    if (fp) fclose(fp);
    static const char *const modes[2] = {"", "--pareto "};
    for (int m = 0; m < 2; m++) {
        snprintf(cmd, sizeof cmd, "%s bench %s--quick -o %s 2>&1", SB_CLI, modes[m], path);
        CHECKF(sb_run(cmd, out, sizeof out) == 2 && strstr(out, "exists and is not a folder"), "%s", out);
        snprintf(cmd, sizeof cmd, "%s bench %s--quick -o '' 2>&1", SB_CLI, modes[m]);
        CHECKF(sb_run(cmd, out, sizeof out) == 1 && strstr(out, "--out: empty folder name"), "%s", out);
    }
}

/* A --model file that cannot be read is an input error as in every
 * command: exit 2, the file named, no table header and no --out folder
 * (it was exit 1 after the header, an empty folder left); an unknown spec
 * stays a usage error (1). */
SB_TEST(unreadable_model_leaves_nothing) {
    const char *dir = sb_tmpdir("bench_badmodel");
    char cmd[8400], out[8192], path[4200];
    snprintf(cmd, sizeof cmd, "head -c 200 %s/rgl_chm_orange_rgb.bsdf > %s/cut.bsdf", SB_MEASURED_DIR, dir);
    CHECK(sb_run(cmd, NULL, 0) == 0);
    snprintf(cmd, sizeof cmd, "%s bench --model %s/cut.bsdf --quick -o %s/o 2>&1", SB_CLI, dir, dir);
    int rc = sb_run(cmd, out, sizeof out);
    CHECKF(rc == 2 && strstr(out, "cut.bsdf") && strstr(out, "past the end") && !strstr(out, "# model"), "rc %d: %s",
           rc, out);
    snprintf(path, sizeof path, "%s/o", dir);
    CHECKF(!sb_file_exists(path), "%s left behind", path);
    snprintf(cmd, sizeof cmd, "%s bench --model nosuchmodel --quick -o %s/o 2>&1", SB_CLI, dir);
    rc = sb_run(cmd, out, sizeof out);
    CHECKF(rc == 1 && strstr(out, "nosuchmodel") && !sb_file_exists(path), "rc %d: %s", rc, out);
}

/* --matrices DIR that cannot be a folder (a file, under a file) is
 * refused before anything is written, naming the option and why, with
 * no --out folder left (twelfth outside pass: the table's header was
 * printed, "cannot write" without a reason after the sampling, exit 2,
 * an empty --out folder left). */
SB_TEST(unwritable_matrices_leaves_nothing) {
    const char *dir = sb_tmpdir("bench_matrices");
    char cmd[8400], out[8192], path[4200];
    snprintf(cmd, sizeof cmd, "touch %s/afile", dir);
    CHECK(sb_run(cmd, NULL, 0) == 0);
    static const char *const bad[2] = {"afile", "afile/m"};
    for (int k = 0; k < 2; k++) {
        snprintf(cmd, sizeof cmd, "cd %s && %s bench --quick --sizes 16 --terms 1 --matrices %s -o o 2>&1", dir, SB_CLI,
                 bad[k]);
        int rc = sb_run(cmd, out, sizeof out);
        CHECKF(rc == 2 && strstr(out, "--matrices") && strstr(out, bad[k]) && !strstr(out, "# model") &&
                   (strstr(out, "not a folder") || strstr(out, "Not a directory")),
               "%s: rc %d: %s", bad[k], rc, out);
        snprintf(path, sizeof path, "%s/o", dir);
        CHECKF(!sb_file_exists(path), "%s left behind", path);
    }
    snprintf(cmd, sizeof cmd, "cd %s && %s bench --quick --sizes 16 --terms 1 --matrices m -o o -q 2>&1", dir, SB_CLI);
    CHECK(sb_run(cmd, out, sizeof out) == 0);
    snprintf(path, sizeof path, "%s/m/io16_g.f64", dir);
    CHECK(sb_file_exists(path));
}
