/* Reliability of output sets (outset.h) with the real binary (SB_CLI):
 * full disks (a small tmpfs when this process may mount one, and a file
 * size limit), concurrent runs into one folder, signals at random points
 * (INT, TERM, HUP, KILL, XFSZ), memory limits, files of the user, and the
 * recovery of what a killed run left.  After every trial the folder holds
 * exactly one complete, self-consistent set, the new one or the previous
 * one untouched: the manifest's files all exist, report.json is complete,
 * every EXR's sepbrdf.source and term count equal report.json's, and the
 * snippet's SB_TERMS too; no staging folder or temporary remains after the
 * next run; every wait is bounded.  Random choices are seeded. */
#define _GNU_SOURCE
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <sched.h>
#include <signal.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mount.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"
#include "util/shared.h" /* sizes, file errors: not exported, in the static archive */

static void sleep_s(double s) {
    struct timespec ts = {(time_t)s, (long)((s - (double)(time_t)s) * 1e9)};
    nanosleep(&ts, NULL);
}

static double now_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

/* ---- files --------------------------------------------------------------- */

/* The whole file (NUL-terminated, malloc'd) or NULL. */
static char *slurp(const char *dir, const char *name) {
    char path[1024];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *fp = fopen(path, "rb");
    if (!fp) return NULL;
    size_t cap = 1 << 16, n = 0, r;
    char *buf = malloc(cap + 1);
    while (buf && (r = fread(buf + n, 1, cap - n, fp)) > 0)
        if ((n += r) == cap) {
            char *b = realloc(buf, 2 * cap + 1);
            if (!b) break;
            buf = b;
            cap *= 2;
        }
    fclose(fp);
    if (buf) buf[n] = 0;
    return buf;
}

static void put(const char *dir, const char *name, const char *text) {
    char path[1024];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *fp = fopen(path, "wb");
    CHECK(fp != NULL);
    if (fp) {
        fputs(text, fp);
        fclose(fp);
    }
}

/* Entries of dir whose name contains part. */
static int count_named(const char *dir, const char *part) {
    int n = 0;
    DIR *d = opendir(dir);
    struct dirent *e;
    while (d && (e = readdir(d)))
        n += strstr(e->d_name, part) != NULL;
    if (d) closedir(d);
    return n;
}

/* No staging folder of OUT beside it, no temporary in it. */
static int clean(const char *parent, const char *out) {
    return count_named(parent, ".sepbrdf-new-") == 0 && count_named(out, ".tmp-") == 0;
}

/* The factor set in dir: 1 if it is one complete, self-consistent set (its
 * J and source in *terms and source), else 0 with the reason in why. */
static int factor_set(const char *dir, int *terms, char *source, size_t ns, char *why, size_t nw) {
    char *man = slurp(dir, "sepbrdf-set-factor.txt"), *rep = slurp(dir, "report.json");
    char *gl = slurp(dir, "sepbrdf.glsl");
    int ok = 0, exr = 0;
    *terms = 0;
    source[0] = 0;
    snprintf(why, nw, "no manifest, report.json or sepbrdf.glsl");
    if (man && rep && gl) {
        size_t n = strlen(rep);
        char *t = strstr(rep, "\n  \"terms\": "), *s = strstr(rep, "\n  \"source\": \"");
        ok = n > 2 && strcmp(rep + n - 2, "}\n") == 0 && t && s;
        snprintf(why, nw, "report.json incomplete");
        if (ok) {
            *terms = atoi(t + 12);
            s += 14;
            snprintf(source, ns, "%.*s", (int)(strchr(s, '"') ? strchr(s, '"') - s : 0), s);
        }
        for (char *line = strtok(man, "\n"); ok && line; line = strtok(NULL, "\n")) {
            if (line[0] == '#') continue;
            char path[1024];
            snprintf(path, sizeof path, "%s/%s", dir, line);
            exr += strstr(line, ".exr") != NULL;
            if (!sb_file_exists(path)) {
                snprintf(why, nw, "%s listed in the manifest is missing", line);
                ok = 0;
            }
        }
        char def[64];
        snprintf(def, sizeof def, "#define SB_TERMS %d\n", *terms);
        if (ok && (exr != 2 * *terms || !strstr(gl, def))) {
            snprintf(why, nw, "%d EXR listed, snippet %s, report says J = %d", exr, strstr(gl, def) ? "agrees" : "not",
                     *terms);
            ok = 0;
        }
    }
    if (ok) { /* every EXR: same source and J as the report (the reader checks they agree) */
        sb_context_t *ctx = NULL;
        sb_factors_t *f = NULL;
        sb_context_create(&ctx);
        const char *fs = NULL;
        if (sb_factors_read_exr(ctx, dir, &f) != SB_OK || (int)sb_factors_terms(f) != *terms ||
            !(fs = sb_factors_get_meta(f, "source")) || strcmp(fs, source) != 0) {
            snprintf(why, nw, "EXR set: %s, source %s vs report %s", sb_context_last_error(ctx), fs ? fs : "-", source);
            ok = 0;
        }
        sb_factors_destroy(f);
        sb_context_destroy(ctx);
    }
    free(man);
    free(rep);
    free(gl);
    return ok;
}

/* Assert that dir holds the set (J, source) of `a` or of `b` (b may be
 * NULL: only a), naming the trial in messages; returns 0 for a, 1 for b. */
static int expect_set(const char *dir, const char *what, int ja, const char *sa, int jb, const char *sb) {
    int J;
    char src[512], why[512];
    int ok = factor_set(dir, &J, src, sizeof src, why, sizeof why);
    CHECKF(ok, "%s: %s holds no complete set: %s", what, dir, why);
    int is_a = J == ja && strcmp(src, sa) == 0, is_b = sb && J == jb && strcmp(src, sb) == 0;
    CHECKF(!ok || is_a || is_b, "%s: set of J = %d from %s is neither run's", what, J, src);
    return is_b && !is_a;
}

/* ---- running the binary -------------------------------------------------- */

typedef struct limits {
    long fsize; /* RLIMIT_FSIZE bytes, 0 = none */
    long as;    /* RLIMIT_AS bytes, 0 = none */
} limits_t;

/* Start SB_CLI with the words of `cmd` (space separated), output to /dev/null. */
static pid_t spawn(const char *cmd, const limits_t *lim) {
    char buf[8192], *argv[48];
    int n = 0;
    snprintf(buf, sizeof buf, "%s", cmd);
    argv[n++] = (char *)SB_CLI;
    for (char *w = strtok(buf, " "); w && n < 47; w = strtok(NULL, " "))
        argv[n++] = w;
    argv[n] = NULL;
    pid_t pid = fork();
    if (pid == 0) {
        int null = open("/dev/null", O_WRONLY);
        dup2(null, 1);
        dup2(null, 2);
        struct rlimit r;
        if (lim && lim->fsize) {
            r.rlim_cur = r.rlim_max = (rlim_t)lim->fsize;
            setrlimit(RLIMIT_FSIZE, &r);
        }
        if (lim && lim->as) {
            r.rlim_cur = r.rlim_max = (rlim_t)lim->as;
            setrlimit(RLIMIT_AS, &r);
        }
        execv(SB_CLI, argv);
        _exit(127);
    }
    return pid;
}

/* Wait at most `limit` seconds; a run still going then is killed and
 * reported as a hang.  Returns the wait status. */
static int reap(pid_t pid, double limit, const char *what) {
    int st = 0;
    for (double t = 0; t < limit; t += 0.005) {
        if (waitpid(pid, &st, WNOHANG) == pid) return st;
        sleep_s(0.005);
    }
    kill(pid, SIGKILL);
    waitpid(pid, &st, 0);
    CHECKF(0, "%s: still running after %.0f s (hang)", what, limit);
    return st;
}

/* Run SB_CLI cmd (printf format) with output captured; the exit code. */
static int cli(char *out, size_t n, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static int cli(char *out, size_t n, const char *fmt, ...) {
    char cmd[8192], full[8400];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(cmd, sizeof cmd, fmt, ap);
    va_end(ap);
    snprintf(full, sizeof full, "OPENBLAS_NUM_THREADS=1 %s %s", SB_CLI, cmd);
    return sb_run(full, out, n);
}

/* A process id that is certainly gone: a child that exited and was reaped. */
static long dead_pid(void) {
    pid_t p = fork();
    if (p == 0) _exit(0);
    waitpid(p, NULL, 0);
    return (long)p;
}

#define PREV_SRC "lambert:albedo=0.5"
#define PREV_CMD "factor " PREV_SRC " --res 8 -J 1 --param io -q -o %s"

/* The previous set of a trial in out: kept when a trial left it, else
 * written again. */
static void ensure_prev(const char *out) {
    char src[512], why[512], msg[4096];
    int J;
    if (factor_set(out, &J, src, sizeof src, why, sizeof why) && J == 1 && strcmp(src, PREV_SRC) == 0) return;
    CHECK(cli(msg, sizeof msg, PREV_CMD, out) == 0);
}

/* ---- cases --------------------------------------------------------------- */

/* Files the project did not write stay; a rerun with fewer terms leaves
 * nothing of the earlier set (textures, previews). */
SB_TEST(user_files_and_fewer_terms) {
    char parent[512], out[600], msg[4096];
    snprintf(parent, sizeof parent, "%s", sb_tmpdir("rel-user"));
    snprintf(out, sizeof out, "%s/out", parent);
    mkdir(out, 0777);
    put(out, "g_05.exr", "my own file\n");
    put(out, "notes.txt", "mine\n");
    CHECK(cli(msg, sizeof msg, "factor lambert --res 8 -J 5 --param io -q -o %s", out) == 0);
    char *mine = slurp(out, "g_05.exr");
    CHECKF(mine && strcmp(mine, "my own file\n") == 0, "a -J 5 run changed the user's g_05.exr");
    free(mine);
    CHECK(cli(msg, sizeof msg, "factor lambert --res 8 -J 4 --param io --previews -q -o %s", out) == 0);
    CHECK(count_named(out, ".png") == 8);
    CHECK(cli(msg, sizeof msg, "factor lambert --res 8 -J 2 --param io --previews -q -o %s", out) == 0);
    expect_set(out, "J 4 then 2", 2, "lambert:albedo=0.8", 0, NULL);
    CHECKF(count_named(out, ".png") == 4, "%d previews left, want those of J = 2 only", count_named(out, ".png"));
    CHECK(!sb_file_exists(strcat(strcpy(msg, out), "/g_03.exr")));
    CHECK(sb_file_exists(strcat(strcpy(msg, out), "/notes.txt")));
    CHECK(sb_file_exists(strcat(strcpy(msg, out), "/g_05.exr")));
    /* a render into the same folder adds its own set and keeps the factor set */
    CHECK(cli(msg, sizeof msg, "render %s --size 16 -q -o %s", out, out) == 0);
    expect_set(out, "render beside", 2, "lambert:albedo=0.8", 0, NULL);
    CHECK(count_named(out, "render_J") == 2);
    CHECK(clean(parent, out));
}

/* A viewer page embeds the factor set it was made from: a new factor set in
 * the folder takes the page with it (the user's files and a render set
 * stay); a page written into another folder is not touched. */
SB_TEST(view_goes_with_its_factor_set) {
    char parent[512], out[600], other[600], msg[4096], path[1400];
    snprintf(parent, sizeof parent, "%s", sb_tmpdir("rel-view"));
    snprintf(out, sizeof out, "%s/out", parent);
    snprintf(other, sizeof other, "%s/page", parent);
    CHECK(cli(msg, sizeof msg, "factor lambert --res 8 -J 4 --param io -q -o %s", out) == 0);
    CHECK(cli(msg, sizeof msg, "view %s -q", out) == 0);
    CHECK(cli(msg, sizeof msg, "view %s -q -o %s", out, other) == 0);
    CHECK(cli(msg, sizeof msg, "render %s --size 16 -J 1 -q -o %s", out, out) == 0);
    put(out, "notes.txt", "mine\n");
    snprintf(path, sizeof path, "%s/index.html", out);
    CHECK(sb_file_exists(path));
    CHECK(cli(msg, sizeof msg, "factor lambert --res 8 -J 2 --param io -q -o %s", out) == 0);
    CHECKF(!sb_file_exists(path), "the J = 4 page stayed beside the J = 2 set");
    snprintf(path, sizeof path, "%s/sepbrdf-set-view.txt", out);
    CHECK(!sb_file_exists(path));
    expect_set(out, "after view", 2, "lambert:albedo=0.8", 0, NULL);
    snprintf(path, sizeof path, "%s/notes.txt", out);
    CHECK(sb_file_exists(path));
    snprintf(path, sizeof path, "%s/render.json", out);
    CHECK(sb_file_exists(path));
    snprintf(path, sizeof path, "%s/index.html", other);
    CHECK(sb_file_exists(path));
    snprintf(path, sizeof path, "%s/sepbrdf-set-view.txt", other);
    CHECK(sb_file_exists(path));
    CHECK(clean(parent, out) && clean(parent, other));
    /* the option itself: a malformed command name is refused */
    sb_context_t *ctx = NULL;
    sb_outset_t *s = NULL;
    sb_context_create(&ctx);
    static const char *const bad[] = {"view", "Bad!", NULL};
    sb_outset_opts_t o = {.command = "factor", .supersedes = bad};
    CHECK(sb_outset_begin(ctx, out, &o, &s) == SB_ERR_ARG && s == NULL);
    CHECKF(strstr(sb_context_last_error(ctx), "Bad!"), "%s", sb_context_last_error(ctx));
    sb_context_destroy(ctx);
}

/* Folders a swap cannot handle are refused before any computation. */
SB_TEST(refused_folders) {
    char parent[512], out[600], msg[4096];
    snprintf(parent, sizeof parent, "%s", sb_tmpdir("rel-refuse"));
    snprintf(out, sizeof out, "%s/out", parent);
    snprintf(msg, sizeof msg, "%s/sub", out);
    CHECK(mkdir(out, 0777) == 0 && mkdir(msg, 0777) == 0);
    CHECK(cli(msg, sizeof msg, "factor lambert --res 512 -J 1 -o %s", out) == 2);
    CHECKF(strstr(msg, "holds the folder sub") && strstr(msg, out), "message: %s", msg);
    CHECK(cli(msg, sizeof msg, "factor lambert --res 512 -J 1 -o %s/%0250d", parent, 0) == 2);
    CHECKF(strstr(msg, "name too long"), "message: %s", msg);
    char cmd[8400];
    snprintf(cmd, sizeof cmd, "cd %s && %s factor lambert --res 512 -J 1 -o .", out, SB_CLI);
    CHECK(sb_run(cmd, msg, sizeof msg) == 2);
    CHECKF(strstr(msg, "current folder"), "message: %s", msg);
    CHECK(clean(parent, out));
}

/* Whether process pid has exited and waits to be reaped. */
static int zombie_state(pid_t pid) {
    char path[64], buf[512];
    snprintf(path, sizeof path, "/proc/%ld/stat", (long)pid);
    FILE *fp = fopen(path, "r");
    size_t n = fp ? fread(buf, 1, sizeof buf - 1, fp) : 0;
    if (fp) fclose(fp);
    buf[n] = 0;
    const char *paren = strrchr(buf, ')');
    return paren && paren[1] == ' ' && paren[2] == 'Z';
}

/* Staging folders of runs that died are recovered by the next run: files
 * of their set removed, a user's file only there moved back; a live
 * process's staging folder is left alone. */
SB_TEST(stale_staging_recovered) {
    char parent[512], out[600], st1[700], st2[700], st3[700], live[700], msg[4096];
    snprintf(parent, sizeof parent, "%s", sb_tmpdir("rel-stale"));
    snprintf(out, sizeof out, "%s/out", parent);
    CHECK(cli(msg, sizeof msg, PREV_CMD, out) == 0);
    snprintf(st1, sizeof st1, "%s/.out.sepbrdf-new-factor-%ld", parent, dead_pid());
    snprintf(st2, sizeof st2, "%s/.out.sepbrdf-new-render-%ld", parent, dead_pid());
    snprintf(live, sizeof live, "%s/.out.sepbrdf-new-factor-%ld", parent, (long)getpid());
    /* a killed worker nothing has reaped yet (a zombie answers kill(pid, 0),
     * as orphans do for good where no init reaps them) is gone too */
    pid_t zombie = fork();
    if (zombie == 0) _exit(0);
    CHECK(zombie > 0);
    snprintf(st3, sizeof st3, "%s/.out.sepbrdf-new-factor-%ld", parent, (long)zombie);
    for (int i = 0; i < 1000 && !zombie_state(zombie); i++)
        usleep(1000);
    CHECK(zombie_state(zombie));
    CHECK(mkdir(st1, 0777) == 0 && mkdir(st2, 0777) == 0 && mkdir(live, 0777) == 0 && mkdir(st3, 0777) == 0);
    put(st3, "g_00.exr", "half written by a killed worker");
    put(st1, "g_00.exr", "half written");
    put(st2, "sepbrdf-set-render.txt", "# sepbrdf output set 1, render\nrender_J01.png\n");
    put(st2, "render_J01.png", "old render");
    put(st2, "lost.txt", "a user's file only here");
    CHECK(cli(msg, sizeof msg, "factor lambert --res 8 -J 2 --param io -q -o %s", out) == 0);
    CHECK(!sb_file_exists(st1) && !sb_file_exists(st2) && sb_file_exists(live));
    CHECK(!sb_file_exists(st3));
    waitpid(zombie, NULL, 0);
    char *lost = slurp(out, "lost.txt");
    CHECKF(lost && strcmp(lost, "a user's file only here") == 0, "the user's file was not moved back");
    free(lost);
    CHECK(count_named(out, "render_J") == 0);
    expect_set(out, "after recovery", 2, "lambert:albedo=0.8", 0, NULL);
    rmdir(live);
    CHECK(clean(parent, out));
    /* sample's single file: a temporary of a dead run beside it goes, a
     * live run's stays */
    char tmp[64], keep[64], path[1024];
    snprintf(tmp, sizeof tmp, "t.csv.tmp-%ld", dead_pid());
    snprintf(keep, sizeof keep, "t.csv.tmp-%ld", (long)getpid());
    put(parent, tmp, "cut");
    put(parent, keep, "being written");
    CHECK(cli(msg, sizeof msg, "sample lambert --gonio 2,2,2,2 -q -o %s/t.csv", parent) == 0);
    CHECK(count_named(parent, tmp) == 0 && count_named(parent, keep) == 1);
    snprintf(path, sizeof path, "%s/%s", parent, keep);
    unlink(path);
}

/* The source description of `spec` as report.json records it, from a
 * reference run into parent/ref. */
static void reference(const char *parent, const char *args, char *src, size_t n, int *terms) {
    char ref[700], msg[4096], why[256];
    snprintf(ref, sizeof ref, "%s/ref", parent);
    CHECK(cli(msg, sizeof msg, "%s -q -o %s", args, ref) == 0);
    CHECKF(factor_set(ref, terms, src, n, why, sizeof why), "reference run: %s", why);
}

#define NEW_ARGS "factor microfacet --res 12 -J 6 --param io --metric-res 8 --previews"

/* One trial under a full disk or a file size limit (`limit`: shell words
 * before the command): the previous set, then the new run, which either
 * succeeds or fails with a message naming the cause and the target. */
static void limited_trial(const char *parent, const char *out, const char *limit, const char *nsrc) {
    char msg[4096], cmd[8400];
    ensure_prev(out);
    snprintf(cmd, sizeof cmd, "%s OPENBLAS_NUM_THREADS=1 timeout 30 %s " NEW_ARGS " -q -o %s", limit, SB_CLI, out);
    int rc = sb_run(cmd, msg, sizeof msg);
    CHECKF(rc == 0 || rc == 2, "%s: exit %d: %s", limit, rc, msg);
    if (rc == 2)
        CHECKF((strstr(msg, "disk full") || strstr(msg, "file too large")) && strstr(msg, out) &&
                   !strstr(msg, ".sepbrdf-new") && !strstr(msg, ".tmp-"),
               "%s: message: %s", limit, msg);
    int is_new = expect_set(out, limit, 1, PREV_SRC, 6, nsrc);
    CHECKF(is_new == (rc == 0), "%s: exit %d with the %s set", limit, rc, is_new ? "new" : "previous");
    fprintf(stderr, "note: %s exit %d%s%.*s\n", limit, rc, rc ? ": " : "", (int)strcspn(msg, "\n"), msg);
    CHECKF(clean(parent, out), "%s: staging folder or temporary left", limit);
}

/* A file size limit (RLIMIT_FSIZE, SIGXFSZ ignored: EFBIG) from one
 * 512-byte block on: failures at every kind of file, then success.  The
 * same for `sample`'s single file. */
SB_TEST(file_size_limit) {
    char parent[512], out[600], nsrc[512], limit[64], msg[4096];
    int J;
    snprintf(parent, sizeof parent, "%s", sb_tmpdir("rel-fsize"));
    snprintf(out, sizeof out, "%s/out", parent);
    reference(parent, NEW_ARGS, nsrc, sizeof nsrc, &J);
    static const int blocks[] = {1, 2, 4, 8, 64};
    for (size_t i = 0; i < sizeof blocks / sizeof blocks[0]; i++) {
        snprintf(limit, sizeof limit, "ulimit -f %d;", blocks[i]);
        limited_trial(parent, out, limit, nsrc);
    }
    char csv[700], cmd[8400];
    snprintf(csv, sizeof csv, "%s/t.csv", parent);
    CHECK(cli(msg, sizeof msg, "sample lambert --gonio 2,2,2,2 -q -o %s", csv) == 0);
    char *before = slurp(parent, "t.csv");
    snprintf(cmd, sizeof cmd, "ulimit -f 1; %s sample lambert -q -o %s", SB_CLI, csv);
    CHECK(sb_run(cmd, msg, sizeof msg) == 2);
    CHECKF(strstr(msg, "file too large") && strstr(msg, csv) && !strstr(msg, ".tmp-"), "sample: %s", msg);
    char *after = slurp(parent, "t.csv");
    CHECKF(before && after && strcmp(before, after) == 0, "sample changed the previous file");
    CHECK(count_named(parent, ".tmp-") == 0);
    free(before);
    free(after);
}

/* A full disk: a small tmpfs in a private mount namespace (needs the right
 * to mount; skipped without it, file_size_limit covers the writers). */
SB_TEST(full_disk) {
    char parent[512], out[600], nsrc[512], mnt[560];
    int J;
    snprintf(parent, sizeof parent, "%s", sb_tmpdir("rel-full"));
    reference(parent, NEW_ARGS, nsrc, sizeof nsrc, &J);
    snprintf(mnt, sizeof mnt, "%s/disk", parent);
    snprintf(out, sizeof out, "%s/out", mnt);
    mkdir(mnt, 0777);
    static const int kib[] = {32, 64, 96, 128, 512};
    int mounted = 0;
    for (size_t i = 0; i < sizeof kib / sizeof kib[0]; i++) {
        pid_t pid = fork();
        if (pid == 0) {
            char opt[32];
            snprintf(opt, sizeof opt, "size=%dk", kib[i]);
            if (unshare(CLONE_NEWNS) != 0 || mount(NULL, "/", NULL, MS_REC | MS_PRIVATE, NULL) != 0 ||
                mount("tmpfs", mnt, "tmpfs", 0, opt) != 0)
                _exit(77);
            limited_trial(mnt, out, opt, nsrc);
            _exit(sb_test_failed_now() ? 1 : 0);
        }
        int st = reap(pid, 60, "tmpfs trial");
        if (WIFEXITED(st) && WEXITSTATUS(st) == 77) break;
        mounted = 1;
        CHECKF(WIFEXITED(st) && WEXITSTATUS(st) == 0, "tmpfs of %d KiB: failed (status %d)", kib[i], st);
    }
    if (!mounted) SKIP("cannot mount a tmpfs here (no CAP_SYS_ADMIN); file_size_limit covers the write errors");
}

/* Runs into one folder at once are serialised: all succeed, the folder
 * ends with one complete set of one of them.  A set begun with no_wait
 * while another is open is refused with a clear message. */
SB_TEST(concurrent_runs) {
    char parent[512], out[600], cmd[4][1024], src[4][64];
    snprintf(parent, sizeof parent, "%s", sb_tmpdir("rel-conc"));
    snprintf(out, sizeof out, "%s/out", parent);
    unsigned long long seed = 15;
    for (int round = 0; round < 2; round++) {
        ensure_prev(out);
        pid_t pid[4];
        for (int k = 0; k < 4; k++) {
            int J = 1 + (int)(sb_rand01(&seed) * 4);
            snprintf(src[k], sizeof src[k], "lambert:albedo=0.%d", k + 1);
            snprintf(cmd[k], sizeof cmd[k], "factor %s --res 8 -J %d --param io --previews -q -o %s", src[k], J, out);
            pid[k] = spawn(cmd[k], NULL);
        }
        int st[4];
        for (int k = 0; k < 4; k++) {
            st[k] = reap(pid[k], 30, cmd[k]);
            CHECKF(WIFEXITED(st[k]) && WEXITSTATUS(st[k]) == 0, "%s: status %d", cmd[k], st[k]);
        }
        int J;
        char got[512], why[512];
        CHECKF(factor_set(out, &J, got, sizeof got, why, sizeof why), "round %d: %s", round, why);
        int which = -1;
        for (int k = 0; k < 4; k++)
            if (strcmp(got, src[k]) == 0) which = k;
        CHECKF(which >= 0 && strstr(cmd[which], " -J ") && atoi(strstr(cmd[which], " -J ") + 4) == J,
               "round %d: set of %s, J = %d, is none of the runs", round, got, J);
        CHECKF(count_named(out, ".png") == 2 * J, "round %d: %d previews for J = %d", round, count_named(out, ".png"),
               J);
        CHECK(clean(parent, out));
    }
    sb_context_t *ctx = NULL;
    sb_outset_t *a = NULL, *b = NULL;
    sb_context_create(&ctx);
    sb_outset_opts_t nw = {.command = "factor", .no_wait = 1};
    CHECK(sb_outset_begin(ctx, out, NULL, &a) == SB_OK);
    CHECK(sb_outset_begin(ctx, out, &nw, &b) == SB_ERR_IO && b == NULL);
    CHECKF(strstr(sb_context_last_error(ctx), "another sepbrdf run is writing"), "%s", sb_context_last_error(ctx));
    sb_outset_destroy(a);
    sb_context_destroy(ctx);
    CHECK(clean(parent, out));
}

/* Signals at seeded random moments of a run that writes 120 textures:
 * afterwards the previous set or the new one; INT, TERM and HUP leave no
 * staging folder, KILL's is removed by the next run; XFSZ is ignored once
 * main() has begun. */
SB_TEST(signals_random) {
    static const int sigs[] = {SIGINT, SIGTERM, SIGHUP, SIGKILL, SIGXFSZ};
    char parent[512], out[600], nsrc[512], what[128];
    snprintf(parent, sizeof parent, "%s", sb_tmpdir("rel-sig"));
    snprintf(out, sizeof out, "%s/out", parent);
    const char *args = "factor lambert --res 16 -J 60 --param io --method full --metric-res 4";
    int J;
    double t0 = now_s();
    reference(parent, args, nsrc, sizeof nsrc, &J);
    double span = 1.5 * (now_s() - t0) + 0.02;
    unsigned long long seed = 7;
    sb_context_t *ctx = NULL;
    sb_context_create(&ctx);
    int died_n = 0, new_n = 0;
    for (int trial = 0; trial < 10; trial++) {
        int sig = sigs[trial % 5];
        double delay = span * sb_rand01(&seed);
        snprintf(what, sizeof what, "signal %d after %.3f s", sig, delay);
        ensure_prev(out);
        char cmd[1500];
        snprintf(cmd, sizeof cmd, "%s -q -o %s", args, out);
        pid_t pid = spawn(cmd, NULL);
        sleep_s(delay);
        kill(pid, sig);
        int st = reap(pid, 30, what);
        int died = WIFSIGNALED(st);
        /* (SIGXFSZ kills only before main() ignores it: the run had not begun) */
        CHECKF(died ? WTERMSIG(st) == sig : WIFEXITED(st) && WEXITSTATUS(st) == 0, "%s: status %d", what, st);
        if (died && sig != SIGKILL) CHECKF(clean(parent, out), "%s: staging folder left", what);
        int is_new = expect_set(out, what, 1, PREV_SRC, J, nsrc);
        if (!died) CHECKF(is_new, "%s: finished, but the previous set is there", what);
        died_n += died;
        new_n += is_new;
        CHECK(sb_outset_cleanup(ctx, out) == SB_OK); /* what the next run does first */
        CHECKF(clean(parent, out), "%s: left over after the next run", what);
    }
    fprintf(stderr, "note: %d of 10 runs died of the signal, %d published the new set\n", died_n, new_n);
    sb_context_destroy(ctx);
}

/* A set of another command (study, render): its manifest lists files that
 * all exist and its JSON is complete.  Returns the JSON (malloc'd) or NULL. */
static char *other_set(const char *dir, const char *cmd, const char *json, const char *what) {
    char name[64];
    snprintf(name, sizeof name, "sepbrdf-set-%s.txt", cmd);
    char *man = slurp(dir, name), *js = slurp(dir, json);
    size_t n = js ? strlen(js) : 0;
    CHECKF(man && js && n > 2 && strcmp(js + n - 2, "}\n") == 0, "%s: no complete %s set in %s", what, cmd, dir);
    for (char *line = man ? strtok(man, "\n") : NULL; line; line = strtok(NULL, "\n")) {
        char path[1024];
        snprintf(path, sizeof path, "%s/%s", dir, line);
        CHECKF(line[0] == '#' || sb_file_exists(path), "%s: %s listed but missing", what, line);
    }
    free(man);
    return js;
}

/* study and render killed at seeded random moments: the previous set
 * (same JSON) or a complete new one. */
SB_TEST(signals_study_render) {
    static const char *const cmds[2][3] = {
        {"study", "study.json", "study lambert microfacet --res 8 --param io -J 1..3 -q -o %s"},
        {"render", "render.json", "render lambert --res 8 --size 24 -J 1,2 -q -o %s"}};
    static const int sigs[] = {SIGTERM, SIGKILL, SIGINT};
    char parent[512], out[600], msg[4096], cmd[1500], what[128];
    snprintf(parent, sizeof parent, "%s", sb_tmpdir("rel-sig2"));
    snprintf(out, sizeof out, "%s/out", parent);
    unsigned long long seed = 11;
    sb_context_t *ctx = NULL;
    sb_context_create(&ctx);
    for (int c = 0; c < 2; c++) {
        double t0 = now_s();
        CHECK(cli(msg, sizeof msg, cmds[c][2], out) == 0);
        double span = 1.5 * (now_s() - t0) + 0.02;
        for (int trial = 0; trial < 3; trial++) {
            char *prev = other_set(out, cmds[c][0], cmds[c][1], "previous");
            double delay = span * sb_rand01(&seed);
            snprintf(what, sizeof what, "%s, signal %d after %.3f s", cmds[c][0], sigs[trial], delay);
            snprintf(cmd, sizeof cmd, cmds[c][2], out);
            pid_t pid = spawn(cmd, NULL);
            sleep_s(delay);
            kill(pid, sigs[trial]);
            int st = reap(pid, 30, what);
            /* the previous set, or the new one complete (also when the
             * signal came after the swap, while the old set was removed) */
            char *now = other_set(out, cmds[c][0], cmds[c][1], what);
            if (!WIFSIGNALED(st)) CHECKF(WIFEXITED(st) && WEXITSTATUS(st) == 0, "%s: status %d", what, st);
            CHECK(sb_outset_cleanup(ctx, out) == SB_OK);
            CHECKF(clean(parent, out), "%s: left over after the next run", what);
            free(prev);
            free(now);
        }
    }
    sb_context_destroy(ctx);
}

/* Memory limits (RLIMIT_AS, one OpenBLAS thread): the run succeeds, or
 * fails with exit 2 naming the memory, leaving the previous set; within
 * 30 s.  (Below ~150 MB OpenBLAS retries its buffer allocation forever:
 * issue 15 item 2, not tried here.) */
SB_TEST(memory_limits) {
#if defined(__SANITIZE_ADDRESS__)
    SKIP("AddressSanitizer needs terabytes of address space");
#else
    static const int mib[] = {4096, 200}; /* the first succeeds: the reference */
    char parent[512], out[600], msg[4096], nsrc[512] = "", cmd[8400], why[512];
    int J;
    snprintf(parent, sizeof parent, "%s", sb_tmpdir("rel-mem"));
    snprintf(out, sizeof out, "%s/out", parent);
    for (size_t i = 0; i < sizeof mib / sizeof mib[0]; i++) {
        ensure_prev(out);
        snprintf(cmd, sizeof cmd,
                 "ulimit -v %d; OPENBLAS_NUM_THREADS=1 timeout 30 %s factor microfacet --res 16 -J 4 -q -o %s",
                 mib[i] * 1024, SB_CLI, out);
        int rc = sb_run(cmd, msg, sizeof msg);
        CHECKF(rc == 0 || (rc == 2 && strstr(msg, "memory")), "ulimit -v %d MiB: exit %d: %s", mib[i], rc, msg);
        if (i == 0) CHECKF(rc == 0 && factor_set(out, &J, nsrc, sizeof nsrc, why, sizeof why), "reference: %s", why);
        int is_new = expect_set(out, "memory limit", 1, PREV_SRC, 4, nsrc);
        CHECKF(is_new == (rc == 0), "ulimit -v %d MiB: exit %d with the %s set", mib[i], rc, is_new ? "new" : "old");
        CHECK(clean(parent, out));
    }
#endif
}

/* The library API: every error path, and a set published by a program. */
SB_TEST(api) {
    char parent[512], out[600], path[1024];
    snprintf(parent, sizeof parent, "%s", sb_tmpdir("rel-api"));
    snprintf(out, sizeof out, "%s/out", parent);
    sb_context_t *ctx = NULL;
    sb_outset_t *s = NULL;
    sb_context_create(&ctx);
    CHECK(sb_outset_check(ctx, NULL) == SB_ERR_ARG && sb_outset_check(ctx, "") == SB_ERR_ARG);
    CHECK(sb_outset_begin(ctx, out, NULL, NULL) == SB_ERR_ARG);
    CHECK(sb_outset_cleanup(ctx, NULL) == SB_ERR_ARG);
    sb_outset_opts_t bad = {.command = "Bad!"};
    CHECK(sb_outset_begin(ctx, out, &bad, &s) == SB_ERR_ARG && s == NULL);
    CHECK(sb_outset_add(NULL, "a") == SB_ERR_ARG && sb_outset_commit(NULL) == SB_ERR_ARG);
    CHECK(sb_outset_dir(NULL) == NULL && sb_outset_target(NULL) == NULL);
    sb_outset_destroy(NULL);
    sb_outset_discard_signal_safe(NULL);
    CHECK(strstr(sb_io_why(ENOSPC), "disk full") != NULL);
    put(parent, "file", "x");
    snprintf(path, sizeof path, "%s/file", parent);
    CHECK(sb_outset_check(ctx, path) == SB_ERR_IO && strstr(sb_context_last_error(ctx), "not a folder"));
    /* a program's set: a file written into the staging folder */
    CHECK(sb_outset_begin(ctx, out, NULL, &s) == SB_OK);
    CHECK(strcmp(sb_outset_target(s), out) == 0);
    static const char *const bad_names[] = {".hidden", "a/b", "sepbrdf-set-x.txt", "a\nb", ""};
    for (size_t i = 0; i < sizeof bad_names / sizeof bad_names[0]; i++)
        CHECKF(sb_outset_add(s, bad_names[i]) == SB_ERR_ARG, "name '%s' accepted", bad_names[i]);
    put(sb_outset_dir(s), "x.txt", "set 1\n");
    CHECK(sb_outset_add(s, "x.txt") == SB_OK && sb_outset_add(s, "x.txt") == SB_OK);
    /* messages name the target, never the staging folder */
    snprintf(path, sizeof path, "%s/no/such.png", sb_outset_dir(s));
    unsigned char px[3] = {0, 0, 0};
    CHECK(sb_png_write_rgb8(ctx, path, 1, 1, px, NULL) == SB_ERR_IO);
    CHECKF(strstr(sb_context_last_error(ctx), out) && !strstr(sb_context_last_error(ctx), ".sepbrdf-new"), "%s",
           sb_context_last_error(ctx));
    snprintf(path, sizeof path, "%s", sb_outset_dir(s));
    CHECK(sb_outset_commit(s) == SB_OK && sb_outset_commit(s) == SB_ERR_ARG);
    sb_outset_destroy(s);
    char *x = slurp(out, "x.txt"), *man = slurp(out, SB_OUTSET_MANIFEST);
    CHECK(x && strcmp(x, "set 1\n") == 0 && man && strstr(man, "\nx.txt\n") && !sb_file_exists(path));
    free(x);
    free(man);
    /* a set missing a named file is refused; the folder keeps its set */
    CHECK(sb_outset_begin(ctx, out, NULL, &s) == SB_OK);
    put(sb_outset_dir(s), "y.txt", "set 2\n");
    CHECK(sb_outset_add(s, "missing.txt") == SB_OK);
    CHECK(sb_outset_commit(s) == SB_ERR_IO && strstr(sb_context_last_error(ctx), "missing.txt"));
    CHECK(sb_outset_add(s, "late.txt") == SB_ERR_ARG);
    sb_outset_destroy(s);
    CHECK(sb_file_exists(strcat(strcpy(path, out), "/x.txt")) && !sb_file_exists(strcat(strcpy(path, out), "/y.txt")));
    /* a set discarded without commit leaves nothing */
    CHECK(sb_outset_begin(ctx, out, NULL, &s) == SB_OK);
    put(sb_outset_dir(s), "z.txt", "set 3\n");
    sb_outset_destroy(s);
    CHECK(!sb_file_exists(strcat(strcpy(path, out), "/z.txt")) && clean(parent, out));
    sb_context_destroy(ctx);
}
