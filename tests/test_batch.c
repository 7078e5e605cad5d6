/* CLI: `sepbrdf batch` with the real binary (SB_CLI): every material of a
 * folder plus a manifest in the summary, textures equal to `sepbrdf factor`
 * of the same settings, -j 2 equal to -j 1, an interrupted run resumed equal
 * to an uninterrupted one, a bad source reported while the others finish. */
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "harness.h"

#define OPTS "--param io -r 8 -J 2"

static char out[65536];

/* The materials: three measured tables (copied into a folder) and two
 * analytic specs (in a manifest beside it). */
static const char *const measured[3] = {"rgl_paper_white_rgb.bsdf", "cornell_acryl_blue.brdf",
                                        "alta_retro-3M-jaune.dat"};
static const char *const names[5] = {"microfacet_base_gold_roughness_0.3", "lambert_albedo_0.5_J2",
                                     "alta_retro-3M-jaune", "cornell_acryl_blue", "rgl_paper_white_rgb"};

/* A folder `tag` with the manifest m.csv and the folder tables/; returns it. */
static const char *setup(const char *tag, const char *extra_row) {
    const char *dir = sb_tmpdir(tag);
    char cmd[8192];
    snprintf(cmd, sizeof cmd, "mkdir %s/tables && cp %s/%s %s/%s %s/%s %s/tables/", dir, SB_MEASURED_DIR, measured[0],
             SB_MEASURED_DIR, measured[1], SB_MEASURED_DIR, measured[2], dir);
    CHECK(sb_run(cmd, out, sizeof out) == 0);
    snprintf(cmd, sizeof cmd, "%s/m.csv", dir);
    FILE *fp = fopen(cmd, "w");
    CHECK(fp != NULL);
    if (!fp) return dir;
    fprintf(fp, "source,terms\n\"microfacet:base=gold,roughness=0.3\",\nlambert:albedo=0.5,2\n%s", extra_row);
    fclose(fp);
    return dir;
}

static int batch(const char *dir, const char *outdir, const char *more) {
    char cmd[8192];
    snprintf(cmd, sizeof cmd, "cd %s && %s batch m.csv tables " OPTS " -o %s %s", dir, SB_CLI, outdir, more);
    return sb_run(cmd, out, sizeof out);
}

static char *slurp(const char *dir, const char *a, const char *b, size_t *size) {
    char path[8400];
    snprintf(path, sizeof path, "%s/%s%s%s", dir, a, b ? "/" : "", b ? b : "");
    FILE *fp = fopen(path, "rb");
    if (!fp) return NULL;
    char *buf = malloc(1 << 20);
    size_t n = buf ? fread(buf, 1, (1 << 20) - 1, fp) : 0;
    fclose(fp);
    if (buf) buf[n] = 0;
    if (size) *size = n;
    return buf;
}

/* The summary.csv of run `o` without its time_s column (12th), quotes
 * respected: the only column that differs between equal runs. */
static char *summary_sans_time(const char *dir, const char *o) {
    char *s = slurp(dir, o, "summary.csv", NULL);
    if (!s) return NULL;
    char *w = s;
    int field = 0, quoted = 0;
    for (const char *r = s; *r; r++) {
        if (*r == '"') quoted = !quoted;
        int sep = !quoted && (*r == ',' || *r == '\n');
        if (field != 11 || (sep && *r == '\n')) *w++ = *r;
        if (sep) field = *r == '\n' ? 0 : field + 1;
    }
    *w = 0;
    return s;
}

/* Whether the texture files of every material are equal in a/ and b/. */
static int same_textures(const char *dir, const char *a, const char *b) {
    static const char *const tex[4] = {"g_00.exr", "g_01.exr", "h_00.exr", "h_01.exr"};
    int same = 1;
    for (int i = 0; i < 5; i++)
        for (int t = 0; t < 4; t++) {
            char pa[512], pb[512];
            size_t na = 0, nb = 0;
            snprintf(pa, sizeof pa, "%s/%s", a, names[i]);
            snprintf(pb, sizeof pb, "%s/%s", b, names[i]);
            char *x = slurp(dir, pa, tex[t], &na), *y = slurp(dir, pb, tex[t], &nb);
            if (!x || !y || na != nb || memcmp(x, y, na) != 0) {
                sb_test_fail(__FILE__, __LINE__, "%s/%s differs between %s and %s", names[i], tex[t], a, b);
                same = 0;
            }
            free(x), free(y);
        }
    return same;
}

static int count_lines(const char *s) {
    int n = 0;
    for (; s && *s; s++)
        n += *s == '\n';
    return n;
}

SB_TEST(every_material_in_summary) {
    const char *dir = setup("batch_all", "");
    int rc = batch(dir, "o", "-j 2");
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    char *csv = slurp(dir, "o", "summary.csv", NULL), *json = slurp(dir, "o", "summary.json", NULL);
    CHECK(csv && json);
    CHECK(count_lines(csv) == 6); /* header + 5 */
    CHECK(csv && strstr(csv, "name,source,param,form,J,headline,comparable,rel_rms,max_abs,negative,bytes,"));
    for (int i = 0; i < 5 && csv && json; i++) {
        char row[256], key[256];
        snprintf(row, sizeof row, "\n%s,", names[i]);
        snprintf(key, sizeof key, "\"name\": \"%s\"", names[i]);
        const char *at = strstr(csv, row);
        CHECKF(at && strstr(at, ",io:res=8,f,2,") && strstr(at, ",ok,") < strchr(at + 1, '\n'), "row %s", names[i]);
        CHECKF(strstr(json, key) != NULL, "%s not in summary.json", names[i]);
        CHECKF(strstr(out, names[i]) != NULL, "%s not in the table on stdout", names[i]);
    }
    free(csv), free(json);
    /* a material's textures are those `sepbrdf factor` writes with its settings */
    char cmd[8192];
    snprintf(cmd, sizeof cmd, "cd %s && %s factor tables/cornell_acryl_blue.brdf " OPTS " -o f -q", dir, SB_CLI);
    CHECK(sb_run(cmd, out, sizeof out) == 0);
    size_t na = 0, nb = 0;
    char *x = slurp(dir, "f", "h_01.exr", &na), *y = slurp(dir, "o/cornell_acryl_blue", "h_01.exr", &nb);
    CHECK(x && y && na == nb && memcmp(x, y, na) == 0);
    free(x), free(y);
}

/* One source under several layouts and J in a manifest: a folder each
 * (NAME_PARAM_JN), every one in the summary with its layout and J. */
SB_TEST(manifest_layouts_and_terms) {
    const char *dir = sb_tmpdir("batch_grid");
    char cmd[8192];
    snprintf(cmd, sizeof cmd, "%s/grid.csv", dir);
    FILE *fp = fopen(cmd, "w");
    CHECK(fp != NULL);
    if (!fp) return;
    fprintf(fp, "source,param,terms\n");
    for (int k = 0; k < 4; k++)
        fprintf(fp, "lambert:albedo=0.5,%s,%d\n", k < 2 ? "io" : "hd", 2 + k % 2);
    fclose(fp);
    snprintf(cmd, sizeof cmd, "cd %s && %s batch grid.csv -r 8 -q -o g", dir, SB_CLI);
    int rc = sb_run(cmd, out, sizeof out);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    char *csv = slurp(dir, "g", "summary.csv", NULL);
    CHECK(csv && count_lines(csv) == 5);
    for (int k = 0; k < 4 && csv; k++) {
        char row[128], want[64];
        snprintf(row, sizeof row, "\nlambert_albedo_0.5_%s_J%d,", k < 2 ? "io" : "hd", 2 + k % 2);
        snprintf(want, sizeof want, ",%s:res=8,", k < 2 ? "io" : "hd");
        const char *at = strstr(csv, row), *eol = at ? strchr(at + 1, '\n') : NULL;
        CHECKF(at && strstr(at, want) && strstr(at, want) < eol, "row %s", row + 1);
        snprintf(want, sizeof want, ",%d,", 2 + k % 2);
        CHECKF(at && strstr(at, want) && strstr(at, want) < eol, "J of %s", row + 1);
    }
    free(csv);
}

SB_TEST(parallel_equals_sequential) {
    const char *dir = setup("batch_par", "");
    CHECK(batch(dir, "one", "-j 1 -q") == 0);
    CHECK(batch(dir, "two", "-j 2 -q") == 0);
    same_textures(dir, "one", "two");
    char *a = summary_sans_time(dir, "one"), *b = summary_sans_time(dir, "two");
    CHECK(a && b && strcmp(a, b) == 0);
    free(a), free(b);
}

/* Run the batch in its own process group, kill the group with SIGKILL as
 * soon as the first material is published; 1 if that happened before the
 * run ended. */
static int interrupted_run(const char *dir) {
    char cmd[8192], first[8400];
    snprintf(cmd, sizeof cmd, "cd %s && exec %s batch m.csv tables " OPTS " -o cut -j 1 -q >/dev/null 2>&1", dir,
             SB_CLI);
    snprintf(first, sizeof first, "%s/cut/%s/batch.txt", dir, names[0]);
    pid_t pid = fork();
    if (pid == 0) {
        setpgid(0, 0);
        execl("/bin/sh", "sh", "-c", cmd, (char *)NULL);
        _exit(127);
    }
    int status = 0, cut = 0;
    struct timespec ts = {0, 2000000};
    for (;;) {
        if (waitpid(pid, &status, WNOHANG) == pid) break;
        if (access(first, F_OK) == 0) {
            kill(-pid, SIGKILL);
            waitpid(pid, &status, 0);
            /* the batch's worker processes die with it, but a killed
             * process still counts as running until its exit is through
             * (seconds for a large address space, e.g. under ASan), and the
             * resumed run leaves the staging folders of running processes
             * alone: wait until none of the group is left (10 s at most) */
            for (int i = 0; i < 1000 && kill(-pid, 0) == 0; i++) {
                struct timespec w = {0, 10000000};
                nanosleep(&w, NULL);
            }
            cut = 1;
            break;
        }
        nanosleep(&ts, NULL);
    }
    return cut;
}

SB_TEST(interrupted_run_resumes) {
    const char *dir = setup("batch_resume", "");
    CHECK(batch(dir, "full", "-j 1 -q") == 0);
    if (!interrupted_run(dir)) SKIP("the run ended before it could be interrupted");
    char path[8400];
    snprintf(path, sizeof path, "%s/cut/summary.csv", dir);
    CHECK(!sb_file_exists(path)); /* it was cut before the end */
    int rc = batch(dir, "cut", "-j 1");
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    CHECK(strstr(out, "(reused)") != NULL); /* the first material was not done again */
    CHECK(strstr(out, "5 materials, 0 reused") == NULL);
    same_textures(dir, "full", "cut");
    char *a = summary_sans_time(dir, "full"), *b = summary_sans_time(dir, "cut");
    CHECK(a && b && strcmp(a, b) == 0);
    free(a), free(b);
    /* no staging folder of the killed run is left */
    snprintf(path, sizeof path, "ls -a %s/cut | grep -c sepbrdf-new", dir);
    sb_run(path, out, sizeof out);
    CHECK(atoi(out) == 0);
}

/* A set is reused only under the same settings, those given since the
 * key first existed (--plain-terms, --scene, --warp) included. */
SB_TEST(other_settings_not_reused) {
    const char *dir = setup("batch_key", "");
    CHECK(batch(dir, "k", "-j 2 -q") == 0);
    const char *runs[][2] = {{"-j 2 --plain-terms", "5 materials, 0 reused"},
                             {"-j 2 --plain-terms", "5 materials, 5 reused"},
                             {"-j 2 --scene 'view=0..60;light=0..60'", "5 materials, 0 reused"},
                             {"-j 2", "5 materials, 0 reused"},
                             {"-j 2", "5 materials, 5 reused"}};
    for (size_t i = 0; i < sizeof runs / sizeof *runs; i++) {
        int rc = batch(dir, "k", runs[i][0]);
        CHECKF(rc == 0 && strstr(out, runs[i][1]), "%s: rc %d: %.300s", runs[i][0], rc, out);
    }
}

SB_TEST(bad_source_reported_others_finish) {
    const char *dir = setup("batch_bad", "missing/nowhere.binary,\n");
    char cmd[8192];
    snprintf(cmd, sizeof cmd, "printf 'not a table\\n' > %s/tables/broken.bsdf", dir);
    CHECK(sb_run(cmd, out, sizeof out) == 0);
    int rc = batch(dir, "o", "-j 2");
    CHECKF(rc == 2, "rc %d: %s", rc, out);
    CHECK(strstr(out, "broken") && strstr(out, "nowhere.binary"));
    char *csv = slurp(dir, "o", "summary.csv", NULL);
    CHECK(csv != NULL);
    CHECK(count_lines(csv) == 8); /* header, 5 materials, broken.bsdf, nowhere.binary */
    for (int i = 0; i < 5 && csv; i++) {
        char row[256];
        snprintf(row, sizeof row, "\n%s,", names[i]);
        const char *at = strstr(csv, row);
        CHECKF(at && strstr(at, ",ok,") < strchr(at + 1, '\n'), "row %s", names[i]);
    }
    CHECK(csv && strstr(csv, "\nbroken,") && strstr(strstr(csv, "\nbroken,"), ",error,"));
    CHECK(csv && strstr(csv, "\nnowhere,") && strstr(strstr(csv, "\nnowhere,"), "No such file"));
    free(csv);
}

/* mpirun -np 3 sepbrdf-mpi: ranks 1 and 2 factor the materials rank 0
 * hands out; every texture has the bits of the single-process run, and
 * the summaries are equal but for time_s. */
SB_TEST(mpi_equals_single) {
#ifndef SB_CLI_MPI
    sb_test_skip("sepbrdf-mpi is not built (CMake found no MPI)");
#else
    const char *dir = setup("batch_mpi", "");
    CHECK(batch(dir, "one", "-j 1 -q") == 0);
    char cmd[8192];
    snprintf(cmd, sizeof cmd,
             "cd %s && OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 ASAN_OPTIONS=detect_leaks=0 "
             "%s -np 3 --oversubscribe %s batch m.csv tables " OPTS " -o mpi 2>&1",
             dir, SB_MPIEXEC, SB_CLI_MPI);
    int rc = sb_run(cmd, out, sizeof out);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    CHECKF(strstr(out, "over 2 ranks") != NULL, "%s", out);
    same_textures(dir, "one", "mpi");
    char *a = summary_sans_time(dir, "one"), *b = summary_sans_time(dir, "mpi"),
         *j = slurp(dir, "mpi", "summary.json", 0);
    CHECK(a && b && strcmp(a, b) == 0);
    CHECK(j && count_lines(j) > 5);
    free(a), free(b), free(j);
#endif
}
