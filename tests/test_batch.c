/* CLI: `sepbrdf batch` with the real binary (SB_CLI): every material of a
 * folder plus a manifest in the summary, textures equal to `sepbrdf factor`
 * of the same settings, -j 2 equal to -j 1, an interrupted run resumed equal
 * to an uninterrupted one, a bad source reported while the others finish. */
#define _DEFAULT_SOURCE /* flock */
#include <fcntl.h>
#include <math.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "batch_util.h"
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

/* The summary.csv of run `o` without its time_s column (13th), quotes
 * respected: the only column that differs between equal runs. */
static char *summary_sans_time(const char *dir, const char *o) {
    char *s = slurp(dir, o, "summary.csv", NULL);
    if (!s) return NULL;
    char *w = s;
    int field = 0, quoted = 0;
    for (const char *r = s; *r; r++) {
        if (*r == '"') quoted = !quoted;
        int sep = !quoted && (*r == ',' || *r == '\n');
        if (field != 12 || (sep && *r == '\n')) *w++ = *r;
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
    CHECK(csv && strstr(csv, "name,source,param,form,weighted,J,headline,comparable,rel_rms,max_abs,negative,bytes,"));
    for (int i = 0; i < 5 && csv && json; i++) {
        char row[256], key[256];
        snprintf(row, sizeof row, "\n%s,", names[i]);
        snprintf(key, sizeof key, "\"name\": \"%s\"", names[i]);
        const char *at = strstr(csv, row);
        /* io named alone: auto's form for it, f or cos (an RGL file: cos) */
        const char *io = at ? strstr(at, ",io:res=8,") : NULL;
        CHECKF(io && (strncmp(io, ",io:res=8,f,1,2,", 16) == 0 || strncmp(io, ",io:res=8,cos,1,2,", 18) == 0) &&
                   strstr(at, ",ok,") < strchr(at + 1, '\n'),
               "row %s", names[i]);
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

/* Run the batch (OPTS, then `more`) into o in its own process group, kill
 * the group with SIGKILL as soon as the first material is published (its
 * batch.txt exists, or holds `want` when not NULL); 1 if that happened
 * before the run ended. */
static int interrupted_run(const char *dir, const char *o, const char *more, const char *want) {
    char cmd[8192], first[8400];
    snprintf(cmd, sizeof cmd, "cd %s && exec %s batch m.csv tables " OPTS " %s -o %s -j 1 -q >/dev/null 2>&1", dir,
             SB_CLI, more, o);
    snprintf(first, sizeof first, "%s/%s/%s/batch.txt", dir, o, names[0]);
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
        char rel[512];
        snprintf(rel, sizeof rel, "%s/batch.txt", names[0]);
        char *txt = want ? slurp(dir, o, rel, NULL) : NULL;
        int ready = want ? txt && strstr(txt, want) : access(first, F_OK) == 0;
        free(txt);
        if (ready) {
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
    if (!interrupted_run(dir, "cut", "", NULL)) SKIP("the run ended before it could be interrupted");
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

/* ---- the batch folder is one consistent thing (issue 34) ---------------- */

/* The next CSV cell of *p (quotes undone) into buf; 1 while the row goes on. */
static int csv_cell(const char **p, char *buf, size_t size) {
    const char *s = *p;
    size_t k = 0;
    int quoted = *s == '"';
    for (s += quoted; *s && (quoted || (*s != ',' && *s != '\n')); s++) {
        if (quoted && *s == '"' && s[1] != '"') {
            quoted = 0;
            continue;
        }
        s += quoted && *s == '"';
        if (k + 1 < size) buf[k++] = *s;
    }
    buf[k] = 0;
    *p = *s ? s + 1 : s;
    return *s == ',';
}

/* The number of rows of o/summary.csv whose layout and J are not those of
 * the set their folder holds (report.json), or whose status is ok without
 * a set; -1 without a summary.  *rows: the rows read. */
static int summary_disagrees(const char *dir, const char *o, int *rows) {
    char *csv = slurp(dir, o, "summary.csv", NULL);
    if (!csv) return -1;
    static char cell[16][8192], want[8192];
    const char *p = strchr(csv, '\n');
    int bad = 0;
    *rows = 0;
    while (p && *++p) {
        int n = 0;
        while (n < 16 && csv_cell(&p, cell[n], sizeof cell[n]))
            n++;
        (*rows)++;
        char sub[8400];
        snprintf(sub, sizeof sub, "%s/%s", o, cell[0]);
        char *json = slurp(dir, sub, "report.json", NULL);
        int held = json != NULL, same = 1;
        if (held) {
            same = report_value(json, "param_spec", want, sizeof want) && strcmp(want, cell[2]) == 0;
            same &= report_value(json, "terms", want, sizeof want) && strcmp(want, cell[5]) == 0;
            same &=
                report_value(json, "weighted", want, sizeof want) && !strcmp(cell[4], strcmp(want, "true") ? "0" : "1");
        } else {
            same = !cell[2][0] && !cell[5][0] && strcmp(cell[13], "ok") != 0;
        }
        if (!same)
            fprintf(stderr, "row %s: param %.60s J %s, its folder %s\n", cell[0], cell[2], cell[5],
                    held ? "holds another set" : "holds none");
        bad += !same;
        free(json);
        p--; /* at the row's last character */
    }
    free(csv);
    return bad;
}

/* A second batch into a folder a batch is writing is refused, with a
 * message naming the folder, and writes nothing there; the folder's own
 * lock holder here is this test (as a running batch holds it). */
SB_TEST(second_batch_refused) {
    const char *dir = setup("batch_lock", "");
    char path[8400];
    snprintf(path, sizeof path, "%s/busy", dir);
    CHECK(mkdir(path, 0777) == 0);
    int fd = open(path, O_RDONLY | O_DIRECTORY);
    CHECK(fd >= 0 && flock(fd, LOCK_EX | LOCK_NB) == 0);
    int rc = batch(dir, "busy", "-j 2");
    CHECKF(rc == 2, "rc %d: %s", rc, out);
    CHECKF(strstr(out, "--out busy") && strstr(out, "another batch"), "%s", out);
    snprintf(path, sizeof path, "ls -A %s/busy | wc -l", dir);
    sb_run(path, out, sizeof out);
    CHECKF(atoi(out) == 0, "the refused batch wrote %s entries", out);
    close(fd); /* the lock ends with its holder */
    rc = batch(dir, "busy", "-j 2 -q");
    CHECKF(rc == 0, "rc %d: %s", rc, out);
}

/* Two batches of other settings started together into one folder: one is
 * refused while the other runs (or they ran one after the other), and the
 * summary agrees with every folder. */
SB_TEST(concurrent_batches_agree) {
    const char *dir = setup("batch_conc", "");
    char cmd[16384];
    snprintf(cmd, sizeof cmd,
             "cd %s && { %s batch m.csv tables --param io -r 8 -J 2 -o c -j 1 -q 2>a.err; echo a=$?; } & "
             "{ cd %s && %s batch m.csv tables --param io -r 8 -J 3 -o c -j 1 -q 2>b.err; echo b=$?; } & wait",
             dir, SB_CLI, dir, SB_CLI);
    sb_run(cmd, out, sizeof out);
    const char *a = strstr(out, "a="), *b = strstr(out, "b=");
    CHECKF(a && b, "%s", out);
    if (!a || !b) return;
    int ra = atoi(a + 2), rb = atoi(b + 2), rows = 0;
    CHECKF((ra == 0 && rb == 0) || (ra == 0 && rb == 2) || (ra == 2 && rb == 0), "exit codes %d %d", ra, rb);
    if (ra == 2 || rb == 2) {
        char *err = slurp(dir, ra == 2 ? "a.err" : "b.err", NULL, NULL);
        CHECKF(err && strstr(err, "another batch"), "%s", err ? err : "");
        free(err);
    }
    CHECK(summary_disagrees(dir, "c", &rows) == 0);
    CHECK(rows == 5);
}

/* A batch rerun with other settings in which one material fails: the
 * summary says what every folder holds (the failed one's earlier set,
 * with a message saying so), not what the run meant to write. */
SB_TEST(summary_from_folders) {
    const char *dir = setup("batch_refold", "");
    int rows = 0;
    CHECK(batch(dir, "s", "-j 2 -q") == 0);
    CHECK(summary_disagrees(dir, "s", &rows) == 0 && rows == 5);
    char cmd[8192];
    snprintf(cmd, sizeof cmd, "printf 'not a table\\n' > %s/tables/cornell_acryl_blue.brdf", dir);
    CHECK(sb_run(cmd, out, sizeof out) == 0);
    snprintf(cmd, sizeof cmd, "cd %s && %s batch m.csv tables --param io -r 8 -J 3 -o s -j 2", dir, SB_CLI);
    int rc = sb_run(cmd, out, sizeof out);
    CHECKF(rc == 2, "rc %d: %s", rc, out);
    CHECK(summary_disagrees(dir, "s", &rows) == 0 && rows == 5);
    char *csv = slurp(dir, "s", "summary.csv", NULL);
    const char *row = csv ? strstr(csv, "\ncornell_acryl_blue,") : NULL;
    CHECKF(row && strstr(row, ",io:res=8,cos,1,2,") && strstr(row, ",error,") && strstr(row, "earlier set"), "%s",
           csv ? csv : "");
    free(csv);
}

/* A layout of about 4 000 characters (warp tables written with 28 digits)
 * given in a manifest: the summaries hold the whole canonical spec, the
 * results are real, a rerun reuses the set, and the table shortens it. */
SB_TEST(long_layout_spec) {
    const char *dir = sb_tmpdir("batch_long");
    static char spec[9000], knots[4096], cmd[16384];
    size_t k = 0;
    for (int i = 1; i < 64; i++)
        k += (size_t)snprintf(knots + k, sizeof knots - k, "%s%.28f", i > 1 ? "/" : "", pow(i / 64.0, 1.5));
    snprintf(spec, sizeof spec, "hd:res=8,warp_h=%s,warp_d=%s", knots, knots);
    CHECK(strlen(spec) > 3800);
    snprintf(cmd, sizeof cmd, "%s/w.csv", dir);
    FILE *fp = fopen(cmd, "w");
    CHECK(fp != NULL);
    if (!fp) return;
    fprintf(fp, "source,param\nlambert,\"%s\"\n", spec);
    fclose(fp);
    snprintf(cmd, sizeof cmd, "cd %s && %s batch w.csv -J 2 -o w -q", dir, SB_CLI);
    int rc = sb_run(cmd, out, sizeof out), rows = 0;
    CHECKF(rc == 0, "rc %d: %.300s", rc, out);
    CHECK(summary_disagrees(dir, "w", &rows) == 0 && rows == 1);
    char *csv = slurp(dir, "w", "summary.csv", NULL), *json = slurp(dir, "w", "summary.json", NULL);
    const char *row = csv ? strchr(csv, '\n') + 1 : NULL;
    static char cell[16][8192];
    int n = 0;
    while (row && n < 16 && csv_cell(&row, cell[n], sizeof cell[n]))
        n++;
    CHECKF(strlen(cell[2]) > 1100 && strstr(cell[2], "0.976654,warp_d=") && strcmp(cell[5], "2") == 0,
           "param %zu characters, J %s", strlen(cell[2]), cell[5]);
    CHECK(atof(cell[6]) > 0 && atof(cell[11]) > 0 && strcmp(cell[13], "ok") == 0);
    CHECK(json && strstr(json, cell[2]) != NULL); /* the whole spec there too */
    free(csv), free(json);
    snprintf(cmd, sizeof cmd, "cd %s && %s batch w.csv -J 2 -o w", dir, SB_CLI);
    rc = sb_run(cmd, out, sizeof out);
    CHECKF(rc == 0 && strstr(out, "1 materials, 1 reused"), "rc %d: %.300s", rc, out);
    /* the table on stdout names the warp, not its 63 texel bounds (on main:
     * the whole spec in the param column, a line of 3900 characters) */
    CHECKF(strstr(out, " hd:res=8,warp_h=table,warp_d=table ") && !strstr(out, "0.976654"), "%.600s", out);
}

/* A batch killed while its workers run (SIGKILL to the batch alone, as a
 * job control or a cluster might): the workers keep OUT locked, so a
 * batch of other settings started then is refused; once they end, it runs
 * and its summary agrees with every folder. */
SB_TEST(orphaned_workers_keep_the_lock) {
    const char *dir = setup("batch_orphan", "");
    char cmd[8192];
    snprintf(cmd, sizeof cmd,
             "cd %s && { %s batch m.csv tables --param io -r 32 -J 3 -o w -j 2 -q & P=$!; i=0; "
             "while [ -z \"$(pgrep -P $P)\" ] && [ $i -lt 500 ]; do sleep 0.01; i=$((i+1)); done; "
             /* a forked worker takes the lock over as it starts: give it that moment on a loaded machine */
             "sleep 0.3; K=$(pgrep -P $P | tr '\\n' ' '); kill -KILL $P; wait $P 2>/dev/null; "
             "%s batch m.csv tables --param io -r 8 -J 2 -o w -j 1 -q 2>second.err; echo second=$?; alive=0; "
             "for k in $K; do kill -0 $k 2>/dev/null && alive=1; done; echo alive=$alive; "
             "for k in $K; do while kill -0 $k 2>/dev/null; do sleep 0.05; done; done; }",
             dir, SB_CLI, SB_CLI);
    sb_run(cmd, out, sizeof out);
    const char *s = strstr(out, "second="), *a = strstr(out, "alive=");
    CHECKF(s && a, "%s", out);
    if (!s || !a) return;
    if (atoi(a + 6) != 1) SKIP("the workers ended before the second batch could start");
    CHECKF(atoi(s + 7) == 2, "second batch: %s", out);
    char *err = slurp(dir, "second.err", NULL, NULL);
    CHECKF(err && strstr(err, "another batch"), "%s", err ? err : "");
    free(err);
    int rc = batch(dir, "w", "--param io -r 8 -J 2 -j 2 -q"), rows = 0;
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    CHECK(summary_disagrees(dir, "w", &rows) == 0 && rows == 5);
}

/* Two materials whose file names share their first 150 characters: two
 * folders (long names keep their start and a hash of the whole), the
 * summary naming each whole source, both reused by a rerun. */
SB_TEST(long_names_kept_apart) {
    const char *dir = sb_tmpdir("batch_names");
    char cmd[8192], stem[160];
    memset(stem, 'm', 150);
    stem[150] = 0;
    snprintf(cmd, sizeof cmd,
             "cd %s && mkdir in && cp %s/cornell_acryl_blue.brdf in/%s_a.brdf && cp in/%s_a.brdf in/%s_b.brdf", dir,
             SB_MEASURED_DIR, stem, stem, stem);
    CHECK(sb_run(cmd, out, sizeof out) == 0);
    snprintf(cmd, sizeof cmd, "cd %s && %s batch in -r 8 -J 1 --param io -o o -q", dir, SB_CLI);
    int rc = sb_run(cmd, out, sizeof out), rows = 0;
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    CHECK(summary_disagrees(dir, "o", &rows) == 0 && rows == 2);
    char *csv = slurp(dir, "o", "summary.csv", NULL);
    for (int k = 0; k < 2 && csv; k++) {
        char whole[200];
        snprintf(whole, sizeof whole, ",in/%s_%c.brdf,", stem, 'a' + k);
        CHECKF(strstr(csv, whole) != NULL, "source %c not whole in %s", 'a' + k, csv);
    }
    free(csv);
    snprintf(cmd, sizeof cmd, "cd %s && %s batch in -r 8 -J 1 --param io -o o", dir, SB_CLI);
    rc = sb_run(cmd, out, sizeof out);
    CHECKF(rc == 0 && strstr(out, "2 materials, 2 reused"), "rc %d: %.300s", rc, out);
}

/* The case: a complete batch, then one of other settings (J = 3)
 * killed after its first material: the folder then holds sets of both,
 * and no summary may say otherwise (the run removed the old one before it
 * changed a folder); the rerun's summary agrees with every folder. */
SB_TEST(interrupted_other_settings_no_stale_summary) {
    const char *dir = setup("batch_stale", "");
    int rows = 0;
    CHECK(batch(dir, "s", "-j 2 -q") == 0);
    if (!interrupted_run(dir, "s", "-J 3", "terms=3 ")) SKIP("the run ended before it could be interrupted");
    int bad = summary_disagrees(dir, "s", &rows);
    CHECKF(bad == -1, "a summary is left after the interrupted run (%d rows disagree)", bad);
    CHECK(batch(dir, "s", "-J 3 -j 2 -q") == 0);
    CHECK(summary_disagrees(dir, "s", &rows) == 0 && rows == 5);
    char *csv = slurp(dir, "s", "summary.csv", NULL);
    const char *row = csv ? strstr(csv, "\nmicrofacet_base_gold_roughness_0.3,") : NULL;
    /* J = 3 on io (its form: the better of f and cos at R = 8, io named alone) */
    const char *at = row ? strstr(row, ",io:res=8,") : NULL;
    CHECK(at && at < strchr(row + 1, '\n') && (!strncmp(at + 10, "f,1,3,", 6) || !strncmp(at + 10, "cos,1,3,", 8)));
    free(csv);
}

/* A gonio table written as CSV is a material, in a folder and given by its
 * path (before: skipped in a folder without a word, read as a manifest
 * when given); the files a folder's expansion skips are named on stderr. */
SB_TEST(gonio_csv_tables_batched) {
    const char *dir = sb_tmpdir("batch_csv");
    char cmd[8192];
    snprintf(cmd, sizeof cmd,
             "cd %s && mkdir t && %s sample lambert --gonio 4,2,4,8 -o t/lam.csv && echo notes > t/README.md && "
             "printf 'source\\nlambert\\n' > t/list.csv",
             dir, SB_CLI);
    int rc = sb_run(cmd, out, sizeof out);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    snprintf(cmd, sizeof cmd, "cd %s && %s batch t -r 8 -J 1 -o o", dir, SB_CLI);
    rc = sb_run(cmd, out, sizeof out);
    CHECKF(rc == 0 && strstr(out, "batch: 1 materials") && strstr(out, "2 files skipped") &&
               strstr(out, "README.md, list.csv"),
           "rc %d: %s", rc, out);
    char *s = slurp(dir, "o", "summary.csv", NULL);
    CHECKF(s && strstr(s, "lam,"), "summary: %s", s ? s : "(none)");
    free(s);
    snprintf(cmd, sizeof cmd, "cd %s && %s batch t/lam.csv -r 8 -J 1 -o p", dir, SB_CLI);
    rc = sb_run(cmd, out, sizeof out);
    CHECKF(rc == 0 && strstr(out, "batch: 1 materials"), "rc %d: %s", rc, out);
}

/* Runs "full" and "w" of the materials in a new folder `tag`, then
 * `damage` (a shell command) in w/, then w again, which must fit the four
 * damaged materials again and reuse the fifth: textures and summary equal
 * to full's.  The folder (out: the last run's output). */
static const char *damaged_rerun(const char *tag, const char *damage) {
    const char *dir = setup(tag, "");
    CHECK(batch(dir, "full", "-j 2 -q") == 0);
    CHECK(batch(dir, "w", "-j 2 -q") == 0);
    char cmd[8192];
    snprintf(cmd, sizeof cmd, "cd %s/w && %s", dir, damage);
    CHECKF(sb_run(cmd, out, sizeof out) == 0, "%s", out);
    int rc = batch(dir, "w", "-j 2");
    CHECKF(rc == 0 && strstr(out, "5 materials, 1 reused"), "rc %d: %s", rc, out);
    same_textures(dir, "full", "w");
    char *a = summary_sans_time(dir, "full"), *b = summary_sans_time(dir, "w");
    CHECK(a && b && strcmp(a, b) == 0);
    free(a), free(b);
    return dir;
}

/* A set whose folder lost a file its set list names, or holds a texture
 * cut short (a user's rm, an interrupted copy of OUT), is not a complete
 * set: it is fitted again, not reused and counted ok (twelfth outside
 * pass: all three were reused, exit 0, the summary saying ok). */
SB_TEST(incomplete_set_not_reused) {
    char damage[4096], path[8192];
    snprintf(damage, sizeof damage,
             "rm %s/g_01.exr && truncate -s 100 %s/h_00.exr && rm %s/sepbrdf.glsl && truncate -s -1 %s/h_01.exr",
             names[2], names[3], names[4], names[0]);
    const char *dir = damaged_rerun("batch_whole", damage);
    snprintf(path, sizeof path, "%s/w/%s/sepbrdf.glsl", dir, names[4]);
    CHECK(sb_file_exists(path));
}

/* A set whose files were changed in place after batch wrote it (report.json
 * or a texture of the same size, batch.txt's fields, the snippet) is not
 * the set batch.txt describes: fitted again, and the run says which file
 * (thirteenth outside pass: all reused, the summary reading batch.txt while
 * report.json said otherwise).  A batch.txt of two lines (written before
 * the sums) is still reused. */
SB_TEST(edited_set_not_reused) {
    char damage[4096];
    snprintf(damage, sizeof damage,
             "sed -i '0,/\"headline\": 0/s//\"headline\": 1/' %s/report.json && sed -i '2s/^/x/' %s/batch.txt && "
             "printf x | dd of=%s/g_00.exr bs=1 seek=400 conv=notrunc && echo '// note' >> %s/sepbrdf.glsl && "
             "cp %s/batch.txt b && head -n 2 b > %s/batch.txt",
             names[0], names[1], names[2], names[3], names[4], names[4]);
    const char *dir = damaged_rerun("batch_edited", damage);
    const char *said[4] = {"report.json was changed", "batch.txt was changed", "g_00.exr was changed",
                           "sepbrdf.glsl holds"};
    for (int i = 0; i < 4; i++) {
        char line[512];
        snprintf(line, sizeof line, "batch: %s: %s", names[i], said[i]);
        CHECKF(strstr(out, line) != NULL, "not said: %s in %s", line, out);
    }
    /* the report fitted again: its headline that of the undamaged run */
    char *a = slurp(dir, "full", "microfacet_base_gold_roughness_0.3/report.json", NULL);
    char *b = slurp(dir, "w", "microfacet_base_gold_roughness_0.3/report.json", NULL);
    const char *ha = a ? strstr(a, "\"headline\": ") : NULL, *hb = b ? strstr(b, "\"headline\": ") : NULL;
    CHECK(ha && hb && strncmp(ha, hb, (size_t)(strchr(ha, '\n') - ha)) == 0 && !strncmp(ha, "\"headline\": 0.9", 15));
    free(a), free(b);
    int rc = batch(dir, "w", "-j 2"); /* every set now as batch wrote it */
    CHECKF(rc == 0 && strstr(out, "5 materials, 5 reused") && !strstr(out, "fitted again"), "rc %d: %s", rc, out);
}
