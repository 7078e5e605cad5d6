/* CLI: an interrupted run leaves the folder's previous set untouched.
 * Starts the real binary (SB_CLI) on a job into a folder that already holds
 * a complete set, sends a signal, and checks the folder: if the run died of
 * the signal, it holds exactly the previous set (same report, same files)
 * and nothing of the run is left beside it (the staging folder); if it had
 * already finished, the new set is complete.  Either way the test holds,
 * however fast the machine.  (Random signals, SIGKILL, full disks and
 * concurrent runs: test_reliability.c.) */
#include <dirent.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "harness.h"

static void sleep_s(double s) {
    struct timespec ts = {(time_t)s, (long)((s - (double)(time_t)s) * 1e9)};
    nanosleep(&ts, NULL);
}

/* Start `SB_CLI args...` (NULL-terminated), stdout/stderr to /dev/null. */
static pid_t start(const char *const *args) {
    char *argv[32];
    int n = 0;
    argv[n++] = (char *)SB_CLI;
    for (; *args && n < 31; args++)
        argv[n++] = (char *)*args;
    argv[n] = NULL;
    pid_t pid = fork();
    if (pid == 0) {
        FILE *null = freopen("/dev/null", "w", stdout);
        (void)null;
        null = freopen("/dev/null", "w", stderr);
        (void)null;
        execv(SB_CLI, argv);
        _exit(127);
    }
    return pid;
}

/* Entries of dir: how many, how many EXR, and whether a name contains
 * `part` (NULL: none asked). */
static int count_dir(const char *dir, int *exr, const char *part, int *has) {
    int n = 0;
    if (exr) *exr = 0;
    if (has) *has = 0;
    DIR *d = opendir(dir);
    if (!d) return 0;
    struct dirent *e;
    while ((e = readdir(d))) {
        if (strcmp(e->d_name, ".") == 0 || strcmp(e->d_name, "..") == 0) continue;
        n++;
        if (exr && strstr(e->d_name, ".exr")) ++*exr;
        if (part && has && strstr(e->d_name, part)) *has = 1;
    }
    closedir(d);
    return n;
}

static char *slurp(const char *path) {
    FILE *fp = fopen(path, "rb");
    if (!fp) return NULL;
    char *buf = calloc(1, 1 << 20);
    if (buf && fread(buf, 1, (1 << 20) - 1, fp) == 0) buf[0] = 0;
    fclose(fp);
    return buf;
}

/* A previous set in DIR/out: `factor lambert -J 1` (4 files and a manifest). */
static void previous_set(const char *dir, char *out, size_t n, char **report) {
    char cmd[8400], msg[2048], path[4300];
    snprintf(out, n, "%s/out", dir);
    snprintf(cmd, sizeof cmd, "%s factor lambert --res 4 -J 1 --param io -q -o %s", SB_CLI, out);
    CHECK(sb_run(cmd, msg, sizeof msg) == 0);
    snprintf(path, sizeof path, "%s/report.json", out);
    *report = slurp(path);
    CHECKF(*report != NULL, "no previous set in %s: the trial could not check anything", out);
}

/* Wait for the run; the folder holds the previous set (died of sig) or
 * the new one of `terms` terms (finished), and no staging folder of the
 * run is left in `dir`.  Returns 1 if it died of sig. */
static int check_outcome(pid_t pid, int sig, const char *dir, const char *out, const char *old_report, int terms) {
    int st = 0, exr = 0, staging = 0;
    CHECK(waitpid(pid, &st, 0) == pid);
    count_dir(dir, NULL, ".sepbrdf-new-", &staging);
    CHECKF(!staging, "the staging folder of the run is left in %s", dir);
    char path[4300];
    snprintf(path, sizeof path, "%s/report.json", out);
    char *report = slurp(path);
    int n = count_dir(out, &exr, NULL, NULL);
    int died = WIFSIGNALED(st);
    if (died) CHECKF(WTERMSIG(st) == sig, "died of signal %d, sent %d", WTERMSIG(st), sig);
    if (died && report && strcmp(report, old_report) == 0) {
        CHECKF(n == 5 && exr == 2, "the previous set (5 files) became %d files, %d EXR", n, exr);
    } else { /* finished, or died after the swap: the new set, complete */
        CHECKF(died || (WIFEXITED(st) && WEXITSTATUS(st) == 0), "status %d", st);
        CHECKF(exr == 2 * terms && n == exr + 3, "finished run: %d files, %d EXR (want %d + 3)", n, exr, 2 * terms);
    }
    free(report);
    return died;
}

/* Killed during the long stages (sampling, factorisation). */
SB_TEST(sigterm_while_computing) {
    const char *tmp = sb_tmpdir("signal");
    char dir[4096], out[4200], *old = NULL;
    snprintf(dir, sizeof dir, "%s", tmp);
    previous_set(dir, out, sizeof out, &old);
    if (!old) return; /* failed in previous_set: without it the trial checks nothing */
    const char *args[] = {"factor", "--res", "64", "--param", "io", "--method", "full", "-o", out, NULL};
    pid_t pid = start(args);
    CHECK(pid > 0);
    sleep_s(0.5);
    kill(pid, SIGTERM);
    if (!check_outcome(pid, SIGTERM, dir, out, old, 4)) fprintf(stderr, "note: the run finished first\n");
    free(old);
}

/* Killed while writing many files: poll until the staging folder of the
 * set appears beside the folder, then interrupt. */
static void kill_while_writing(int sig) {
    const char *tmp = sb_tmpdir("signal");
    char dir[4096], out[4200], *old = NULL;
    snprintf(dir, sizeof dir, "%s", tmp);
    previous_set(dir, out, sizeof out, &old);
    if (!old) return; /* failed in previous_set: without it the trial checks nothing */
    const char *args[] = {"factor",   "lambert", "--res",        "24", "-J", "400", "--param", "io",
                          "--method", "full",    "--metric-res", "4",  "-o", out,   NULL};
    pid_t pid = start(args);
    CHECK(pid > 0);
    for (int i = 0; i < 200000; i++) { /* at most ~20 s */
        int staging = 0;
        siginfo_t info = {0};
        count_dir(dir, NULL, ".sepbrdf-new-", &staging);
        /* ended? (WNOWAIT: check_outcome still reaps it, and the signal
         * below cannot reach another process that took its pid) */
        if (staging || (waitid(P_PID, (id_t)pid, &info, WEXITED | WNOHANG | WNOWAIT) == 0 && info.si_pid == pid)) break;
        sleep_s(0.0001);
    }
    kill(pid, sig);
    check_outcome(pid, sig, dir, out, old, 400);
    free(old);
}

SB_TEST(sigterm_while_writing) { kill_while_writing(SIGTERM); }
SB_TEST(sigint_while_writing) { kill_while_writing(SIGINT); }
SB_TEST(sighup_while_writing) { kill_while_writing(SIGHUP); }

/* A study interrupted leaves nothing: no files, no staging folder. */
SB_TEST(sigterm_study) {
    const char *dir = sb_tmpdir("signal");
    char out[4200];
    snprintf(out, sizeof out, "%s/out", dir);
    const char *args[] = {"study",    "microfacet", "lambert", "--res", "48", "--param", "io",
                          "--method", "full",       "-J",      "1..4",  "-o", out,       NULL};
    pid_t pid = start(args);
    CHECK(pid > 0);
    sleep_s(0.3);
    kill(pid, SIGTERM);
    int st = 0, staging = 0;
    CHECK(waitpid(pid, &st, 0) == pid);
    count_dir(dir, NULL, ".sepbrdf-new-", &staging);
    CHECKF(!staging, "the staging folder of the study is left in %s", dir);
    int n = count_dir(out, NULL, NULL, NULL);
    if (WIFSIGNALED(st))
        CHECKF(n == 0, "interrupted study left %d files", n);
    else
        CHECKF(WIFEXITED(st) && WEXITSTATUS(st) == 0 && n >= 5, "status %d, %d files", st, n);
}

/* `sepbrdf bench -o DIR` interrupted while it measures (results.csv's
 * temporary open) leaves no results.csv.tmp-PID: it was not registered
 * with the signal cleanup, and every interrupted bench left one. */
SB_TEST(sigterm_bench) {
    const char *dir = sb_tmpdir("signal");
    char out[4200], tmp[4300];
    snprintf(out, sizeof out, "%s/bench", dir);
    const char *args[] = {"bench", "--quick", "--no-fork", "-o", out, NULL};
    pid_t pid = start(args);
    CHECK(pid > 0);
    snprintf(tmp, sizeof tmp, "results.csv.tmp-%ld", (long)pid);
    int has = 0;
    for (int i = 0; i < 400 && !has; i++) { /* the temporary exists: the run is measuring */
        sleep_s(0.02);
        count_dir(out, NULL, tmp, &has);
    }
    CHECKF(has, "no %s in %s", tmp, out);
    kill(pid, SIGTERM);
    int st = 0;
    CHECK(waitpid(pid, &st, 0) == pid);
    count_dir(out, NULL, ".tmp-", &has);
    CHECKF(!has, "an interrupted bench left %s in %s", tmp, out);
    if (!WIFSIGNALED(st)) CHECKF(WIFEXITED(st) && WEXITSTATUS(st) == 0, "status %d", st);
}

/* The first run into a folder, interrupted, leaves no folder: the run
 * created it (for its lock) before computing, and an interrupted run left
 * it behind empty, where an error removes it (sixth outside pass). */
SB_TEST(sigint_first_run_leaves_no_folder) {
    const char *dir = sb_tmpdir("signal");
    char out[4200];
    snprintf(out, sizeof out, "%s/new", dir);
    const char *args[] = {"factor",   "lambert", "--res",        "24", "-J", "400", "--param", "io",
                          "--method", "full",    "--metric-res", "4",  "-o", out,   NULL};
    pid_t pid = start(args);
    CHECK(pid > 0);
    int staging = 0;
    for (int i = 0; i < 200000 && !staging; i++) { /* the staging folder: DIR exists and is locked */
        siginfo_t info = {0};
        count_dir(dir, NULL, ".sepbrdf-new-", &staging);
        if (waitid(P_PID, (id_t)pid, &info, WEXITED | WNOHANG | WNOWAIT) == 0 && info.si_pid == pid) break;
        sleep_s(0.0001);
    }
    kill(pid, SIGINT);
    int st = 0;
    CHECK(waitpid(pid, &st, 0) == pid);
    count_dir(dir, NULL, ".sepbrdf-new-", &staging);
    CHECKF(!staging, "the staging folder of the run is left in %s", dir);
    struct stat sb;
    if (WIFSIGNALED(st))
        CHECKF(stat(out, &sb) != 0, "an interrupted first run left the folder %s (%d entries)", out,
               count_dir(out, NULL, NULL, NULL));
    else
        CHECKF(WIFEXITED(st) && WEXITSTATUS(st) == 0 && count_dir(out, NULL, NULL, NULL) == 803, "status %d", st);
}
