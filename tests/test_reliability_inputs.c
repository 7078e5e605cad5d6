/* Reliability of reading (issue 34): every file the CLI and the library
 * read is bounded, and devices and FIFOs are refused at once with a
 * message naming the file (each run under `timeout`: a hang fails). */
#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"

static char out[65536];

/* Run `sepbrdf ARGS` in dir under a 30 s timeout; the exit code (124: it
 * hung). */
static int run_in(const char *dir, const char *args) {
    char cmd[8192];
    snprintf(cmd, sizeof cmd, "cd %s && OPENBLAS_NUM_THREADS=1 timeout 30 %s %s", dir, SB_CLI, args);
    return sb_run(cmd, out, sizeof out);
}

/* --scene pairs= a device, a FIFO without a writer, a file beyond the
 * size limit (sparse: nothing is read); a source, a table or texture for
 * info, a factor folder for render and view whose files are FIFOs or
 * devices: exit 2, the file named. */
SB_TEST(devices_and_fifos_refused) {
    const char *dir = sb_tmpdir("rel_fifo");
    char path[4200];
    snprintf(path, sizeof path, "%s/fifo", dir);
    CHECK(mkfifo(path, 0600) == 0);
    snprintf(path, sizeof path, "%s/t.exr", dir);
    CHECK(mkfifo(path, 0600) == 0);
    snprintf(path, sizeof path, "%s/set", dir);
    CHECK(mkdir(path, 0700) == 0);
    snprintf(path, sizeof path, "%s/set/report.json", dir);
    CHECK(mkfifo(path, 0600) == 0);
    snprintf(path, sizeof path, "%s/set/g_00.exr", dir);
    CHECK(mkfifo(path, 0600) == 0);
    snprintf(path, sizeof path, "%s/huge.txt", dir);
    FILE *fp = fopen(path, "w");
    CHECK(fp != NULL);
    if (fp) fclose(fp);
    CHECK(truncate(path, (off_t)300 << 20) == 0);
    static const char *const cases[][2] = {
        {"factor -r 8 -J 1 --scene pairs=/dev/zero -o o", "/dev/zero"},
        {"factor -r 8 -J 1 --scene pairs=fifo -o o", "fifo"},
        {"factor -r 8 -J 1 --scene pairs=huge.txt -o o", "huge.txt"},
        {"factor fifo -r 8 -J 1 -o o", "fifo"},
        {"factor /dev/zero -r 8 -J 1 -o o", "/dev/zero"},
        {"info fifo", "fifo"},
        {"batch fifo -r 8 -J 1 -o b", "fifo"},
        {"info t.exr", "t.exr"},
        {"render set --size 16 -o r.png", "set/"},
        {"view set -o v.html", "set/"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        int rc = run_in(dir, cases[i][0]);
        CHECKF(rc == 2 && strstr(out, cases[i][1]), "%s: rc %d: %s", cases[i][0], rc, out);
    }
    snprintf(path, sizeof path, "%s/o", dir);
    CHECK(!sb_file_exists(path)); /* nothing was written */
}

/* The library's readers refuse devices and FIFOs with SB_ERR_IO and a
 * message naming the file. */
SB_TEST(library_readers_refuse_devices) {
    const char *dir = sb_tmpdir("rel_lib");
    char fifo[4200], spec[4300];
    snprintf(fifo, sizeof fifo, "%s/t.binary", dir);
    CHECK(mkfifo(fifo, 0600) == 0);
    sb_context_t *ctx = NULL;
    CHECK(sb_context_create(&ctx) == SB_OK);
    const char *paths[2] = {"/dev/zero", fifo};
    for (int i = 0; i < 2; i++) {
        sb_source_t *src = NULL;
        sb_scene_t *s = NULL;
        CHECK(sb_measured_open(ctx, paths[i], NULL, &src, NULL) == SB_ERR_IO && !src);
        CHECKF(strstr(sb_context_last_error(ctx), paths[i]) != NULL, "%s", sb_context_last_error(ctx));
        snprintf(spec, sizeof spec, "pairs=%s", paths[i]);
        CHECK(sb_scene_parse(ctx, spec, &s) == SB_ERR_IO && !s);
        CHECKF(strstr(sb_context_last_error(ctx), "not a regular file"), "%s", sb_context_last_error(ctx));
    }
    sb_context_destroy(ctx);
}

/* Each bad value is named by the option (or the SOURCE) that carried it:
 * a model key out of range is not blamed on --terms, J too large is, the
 * pairs file of --scene names --scene; every option of the factor group
 * with a bad value names itself (exit 1). */
SB_TEST(option_errors_name_the_option) {
    const char *dir = sb_tmpdir("rel_opts");
    int rc = run_in(dir, "factor microfacet:roughness=-1 -r 8 -J 1 -o o");
    CHECKF(rc == 1 && strstr(out, "roughness") && !strstr(out, "--terms"), "rc %d: %s", rc, out);
    rc = run_in(dir, "factor lambert --param io -r 8 -J 100 -o o");
    CHECKF(rc == 1 && strstr(out, "--terms 100"), "rc %d: %s", rc, out);
    rc = run_in(dir, "factor lambert -r 8 -J 1 --scene pairs=nowhere.txt -o o");
    CHECKF(rc == 2 && strstr(out, "--scene") && strstr(out, "nowhere.txt"), "rc %d: %s", rc, out);
    static const char *const bad[][2] = {
        {"--res", "abc"},
        {"--terms", "0"},
        {"--form", "x"},
        {"--warp", "q"},
        {"--method", "zz"},
        {"--channels", "Q"},
        {"--seed", "-1"},
        {"--memory-limit", "3Q"},
        {"--budget", "0"},
        {"--theta-max", "100"},
        {"--metric-res", "1"},
        {"--interp", "bogus"},
        {"--neighbours", "0"},
        {"--radius", "-1"},
        {"--white", "x"},
        {"--gamut", "x"},
        {"--param", "'hd:res=8,warp_h=0.5/0.2'"},
        {"--scene", "'lights=100,0'"},
        {"--max-error", "2"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        char args[512];
        snprintf(args, sizeof args, "factor lambert %s %s -o o", bad[i][0], bad[i][1]);
        rc = run_in(dir, args);
        CHECKF(rc == 1 && strstr(out, bad[i][0]), "%s: rc %d: %s", args, rc, out);
    }
    /* render --exposure: a bad value names what it takes, the words too */
    static const char *const exposures[] = {"0", "-1", "nan", "inf", "2x", "1e7"};
    for (size_t i = 0; i < sizeof exposures / sizeof *exposures; i++) {
        char args[512];
        snprintf(args, sizeof args, "render lambert -r 4 -J 1 -s 8 --exposure %s -o r", exposures[i]);
        rc = run_in(dir, args);
        CHECKF(rc == 1 && strstr(out, "--exposure") && strstr(out, "auto or peak"), "%s: rc %d: %s", args, rc, out);
    }
    rc = run_in(dir, "render lambert -r 4 -J 1 -s 8 --exposure 2 -q -o r");
    CHECKF(rc == 0, "--exposure 2: rc %d: %s", rc, out);
}

/* A probe folder left by a process killed while it checked the output's
 * parent (.sepbrdf-probe-PID of a process that is gone) is removed by the
 * next run there; a live process's probe stays. */
SB_TEST(stale_probe_removed) {
    const char *dir = sb_tmpdir("rel_probe");
    pid_t p = fork();
    if (p == 0) _exit(0);
    waitpid(p, NULL, 0); /* p is gone */
    char stale[4200], live[4200];
    snprintf(stale, sizeof stale, "%s/.sepbrdf-probe-%ld", dir, (long)p);
    snprintf(live, sizeof live, "%s/.sepbrdf-probe-%ld", dir, (long)getppid());
    CHECK(mkdir(stale, 0700) == 0 && mkdir(live, 0700) == 0);
    int rc = run_in(dir, "factor lambert -r 8 -J 1 --param io -q -o out");
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    CHECK(!sb_file_exists(stale));
    CHECK(sb_file_exists(live));
    rmdir(live);
}

/* sample where no gonioreflectometer position meets the table (its rows
 * all near one pair of directions, far from the one position asked): exit
 * 2 naming --gonio, no file left (info refuses a table of no rows); the
 * same position on a model writes its one row. */
SB_TEST(sample_no_rows_refused) {
    const char *dir = sb_tmpdir("rel_sample");
    char path[4200];
    snprintf(path, sizeof path, "%s/t.csv", dir);
    FILE *fp = fopen(path, "w");
    CHECK(fp != NULL);
    if (!fp) return;
    fputs("theta_i,phi_i,theta_o,phi_o,r,g,b\n", fp);
    for (int k = 0; k < 8; k++)
        fprintf(fp, "%d,0,%d,180,0.2,0.3,0.4\n", 70 + k % 2, 70 + k / 2);
    fclose(fp);
    int rc = run_in(dir, "sample t.csv --gonio 1,1,1,1 -o s.csv");
    CHECKF(rc == 2 && strstr(out, "--gonio 1,1,1,1") && strstr(out, "0 rows"), "rc %d: %s", rc, out);
    snprintf(path, sizeof path, "%s/s.csv", dir);
    CHECK(!sb_file_exists(path));
    rc = run_in(dir, "sample t.csv --gonio 1,1,1,1");
    CHECKF(rc == 2, "stdout: rc %d: %s", rc, out);
    rc = run_in(dir, "sample lambert --gonio 1,1,1,1 -o s.csv");
    CHECKF(rc == 0 && sb_file_exists(path), "rc %d: %s", rc, out);
}

/* Copy the gonio table `from` to `to` with the values of every `every`-th
 * row negated (-x; every 1: all of them). */
static int negate_rows(const char *from, const char *to, int every) {
    FILE *in = fopen(from, "r"), *o = fopen(to, "w");
    char line[512];
    int k = 0, header = 0;
    while (in && o && fgets(line, sizeof line, in)) {
        double a[4], v[3];
        if (line[0] == '#' || !header) {
            header |= line[0] != '#';
            fputs(line, o);
            continue;
        }
        if (sscanf(line, "%lf,%lf,%lf,%lf,%lf,%lf,%lf", a, a + 1, a + 2, a + 3, v, v + 1, v + 2) != 7) break;
        double s = k++ % every == 0 ? -1 : 1;
        fprintf(o, "%g,%g,%g,%g,%.17g,%.17g,%.17g\n", a[0], a[1], a[2], a[3], s * v[0], s * v[1], s * v[2]);
    }
    int ok = in && o && k > 0;
    if (in) fclose(in);
    if (o) fclose(o);
    return ok;
}

/* A table whose values are negated (a sign or unit error) is refused
 * naming the mean and the negative rows, nothing written (before: exit 0,
 * headline 1.0, no word); one with a fifth of its rows negative is fitted
 * with a warning that says how many. */
SB_TEST(negative_values_refused_or_warned) {
    const char *dir = sb_tmpdir("rel_negative");
    char from[4200], to[4200], path[4200];
    int rc = run_in(dir, "sample lambert --gonio 6,4,6,8 -o t.csv");
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    snprintf(from, sizeof from, "%s/t.csv", dir);
    snprintf(to, sizeof to, "%s/neg.csv", dir);
    CHECK(negate_rows(from, to, 1));
    rc = run_in(dir, "factor neg.csv -r 8 -J 1 -q -o n");
    CHECKF(rc == 2 && strstr(out, "neg.csv") && strstr(out, "is not negative") && strstr(out, "1152 of 1152 rows"),
           "rc %d: %s", rc, out);
    snprintf(path, sizeof path, "%s/n", dir);
    CHECK(!sb_file_exists(path));
    snprintf(to, sizeof to, "%s/some.csv", dir);
    CHECK(negate_rows(from, to, 5));
    rc = run_in(dir, "factor some.csv -r 8 -J 1 -q -o s");
    CHECKF(rc == 0 && strstr(out, "231 of 1152 rows (20%) hold a negative value"), "rc %d: %s", rc, out);
    rc = run_in(dir, "factor t.csv -r 8 -J 1 -q -o t");
    CHECKF(rc == 0 && !strstr(out, "negative"), "rc %d: %s", rc, out);
}

/* sample takes the table options as info, convert, factor and view do
 * (before: "--interp" was an unknown option): the interpolation asked
 * for is the one that measures the table between its rows, a bad value
 * exits 1 naming the option. */
SB_TEST(sample_table_options) {
    const char *dir = sb_tmpdir("rel_sample_opts");
    char a[4200], b[4200];
    int rc = run_in(dir, "sample microfacet:base=gold,roughness=0.5 --gonio 6,1,6,12 -o t.csv");
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    rc = run_in(dir, "sample t.csv --gonio 5,1,5,10 --interp nearest -o n.csv");
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    rc = run_in(dir, "sample t.csv --gonio 5,1,5,10 --interp idw --neighbours 6 -o i.csv");
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    snprintf(a, sizeof a, "%s/n.csv", dir);
    snprintf(b, sizeof b, "%s/i.csv", dir);
    FILE *fa = fopen(a, "r"), *fb = fopen(b, "r");
    int differ = 0, lines = 0;
    char la[512], lb[512];
    while (fa && fb && fgets(la, sizeof la, fa) && fgets(lb, sizeof lb, fb))
        differ += strcmp(la, lb) != 0, lines++;
    if (fa) fclose(fa);
    if (fb) fclose(fb);
    CHECKF(lines > 100 && differ > 50, "%d of %d lines differ", differ, lines);
    rc = run_in(dir, "sample t.csv --interp cubic -o c.csv");
    CHECKF(rc == 1 && strstr(out, "--interp"), "rc %d: %s", rc, out);
}
