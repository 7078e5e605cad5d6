/* CLI: an interrupted run leaves no half files.  Starts the real binary
 * (SB_CLI) on a job, sends a signal, and checks the output folder: if the
 * run died of the signal, no texture, report, snippet or temporary may be
 * left; if it had already finished, the set must be complete (and still no
 * temporary).  Either way the test holds, however fast the machine. */
#include <dirent.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
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

typedef struct scan {
    int exr, tmp, report, glsl, other;
    char first_tmp[256];
} scan_t;

static scan_t scan_dir(const char *dir) {
    scan_t s;
    memset(&s, 0, sizeof s);
    DIR *d = opendir(dir);
    if (!d) return s; /* never created: nothing left */
    struct dirent *e;
    while ((e = readdir(d))) {
        const char *n = e->d_name;
        if (strcmp(n, ".") == 0 || strcmp(n, "..") == 0) continue;
        if (strstr(n, ".tmp-")) {
            if (!s.tmp++) snprintf(s.first_tmp, sizeof s.first_tmp, "%s", n);
        } else if (strstr(n, ".exr")) {
            s.exr++;
        } else if (strcmp(n, "report.json") == 0) {
            s.report++;
        } else if (strcmp(n, "sepbrdf.glsl") == 0) {
            s.glsl++;
        } else {
            s.other++;
        }
    }
    closedir(d);
    return s;
}

/* Wait for the run and check the folder as described above; `terms` is
 * the J of the run.  Returns 1 if it died of `sig`, 0 if it finished. */
static int check_outcome(pid_t pid, int sig, const char *dir, int terms) {
    int st = 0;
    CHECK(waitpid(pid, &st, 0) == pid);
    scan_t s = scan_dir(dir);
    CHECKF(s.tmp == 0, "temporary left in %s: %s", dir, s.first_tmp);
    CHECKF(s.other == 0, "%d unexpected files in %s", s.other, dir);
    if (WIFSIGNALED(st)) {
        CHECKF(WTERMSIG(st) == sig, "died of signal %d, sent %d", WTERMSIG(st), sig);
        CHECKF(s.exr == 0 && s.report == 0 && s.glsl == 0,
               "interrupted run left %d EXR, %d report.json, %d sepbrdf.glsl in %s", s.exr, s.report, s.glsl, dir);
        return 1;
    }
    /* finished before the signal: a complete set */
    CHECKF(WIFEXITED(st) && WEXITSTATUS(st) == 0, "status %d", st);
    CHECKF(s.exr == 2 * terms && s.report == 1 && s.glsl == 1,
           "finished run wrote %d EXR (want %d), %d report, %d glsl", s.exr, 2 * terms, s.report, s.glsl);
    return 0;
}

/* Killed during the long stages (sampling, factorisation). */
SB_TEST(sigterm_while_computing) {
    const char *dir = sb_tmpdir("signal");
    char out[4200];
    snprintf(out, sizeof out, "%s/out", dir);
    const char *args[] = {"factor", "--res", "64", "--param", "io", "--method", "full", "-o", out, NULL};
    pid_t pid = start(args);
    CHECK(pid > 0);
    sleep_s(0.5);
    kill(pid, SIGTERM);
    int died = check_outcome(pid, SIGTERM, out, 4);
    if (!died) fprintf(stderr, "note: the run finished before SIGTERM\n");
}

/* Killed while writing many files: poll until the first file of the set
 * appears (a temporary, or already a finished texture), then interrupt. */
static void kill_while_writing(int sig) {
    const char *dir = sb_tmpdir("signal");
    char out[4200];
    snprintf(out, sizeof out, "%s/out", dir);
    const char *args[] = {"factor",   "lambert", "--res",        "24", "-J", "400", "--param", "io",
                          "--method", "full",    "--metric-res", "4",  "-o", out,   NULL};
    pid_t pid = start(args);
    CHECK(pid > 0);
    for (int i = 0; i < 200000; i++) { /* at most ~20 s */
        scan_t s = scan_dir(out);
        if (s.tmp || s.exr) break;
        int st;
        if (waitpid(pid, &st, WNOHANG) == pid) { /* finished already: put it back for check_outcome */
            scan_t f = scan_dir(out);
            CHECKF(WIFEXITED(st) && WEXITSTATUS(st) == 0, "status %d", st);
            CHECKF(f.tmp == 0 && f.exr == 800 && f.report == 1, "finished run: %d tmp, %d EXR", f.tmp, f.exr);
            return;
        }
        sleep_s(0.0001);
    }
    kill(pid, sig);
    check_outcome(pid, sig, out, 400);
}

SB_TEST(sigterm_while_writing) { kill_while_writing(SIGTERM); }
SB_TEST(sigint_while_writing) { kill_while_writing(SIGINT); }
SB_TEST(sighup_while_writing) { kill_while_writing(SIGHUP); }

/* A study interrupted leaves none of its files. */
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
    int st = 0;
    CHECK(waitpid(pid, &st, 0) == pid);
    scan_t s = scan_dir(out);
    CHECKF(s.tmp == 0, "temporary left: %s", s.first_tmp);
    if (WIFSIGNALED(st))
        CHECKF(s.other == 0, "interrupted study left %d files", s.other);
    else
        CHECKF(WIFEXITED(st) && WEXITSTATUS(st) == 0 && s.other >= 4, "status %d, %d files", st, s.other);
}
