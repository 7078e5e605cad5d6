/* CLI golden tests: the real binary (SB_CLI) on bad input.  Each case
 * checks the documented exit code (0 ok, 1 usage, 2 input/output) and that
 * the message names the problem (the option, value, file or folder). */
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "harness.h"

static char out[65536];

/* Run "SB_CLI ARGS" with stdout and stderr together into `out`; with
 * keep = 1 or 2 only that stream. */
static int run_keep(int keep, const char *fmt, va_list ap) {
    char args[6000], cmd[8192];
    vsnprintf(args, sizeof args, fmt, ap);
    if (keep == 1)
        snprintf(cmd, sizeof cmd, "{ %s %s 2>/dev/null; }", SB_CLI, args);
    else if (keep == 2)
        snprintf(cmd, sizeof cmd, "{ %s %s >/dev/null; }", SB_CLI, args);
    else
        snprintf(cmd, sizeof cmd, "%s %s", SB_CLI, args);
    return sb_run(cmd, out, sizeof out);
}
static int cli(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
static int cli(const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    int rc = run_keep(0, fmt, ap);
    va_end(ap);
    return rc;
}
static int cli_stdout(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
static int cli_stdout(const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    int rc = run_keep(1, fmt, ap);
    va_end(ap);
    return rc;
}
static int cli_stderr(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
static int cli_stderr(const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    int rc = run_keep(2, fmt, ap);
    va_end(ap);
    return rc;
}

#define EXPECT(rc_expr, code, ...)                                                                                     \
    do {                                                                                                               \
        int rc_ = (rc_expr);                                                                                           \
        CHECKF(rc_ == (code), "exit %d, want %d: %s", rc_, (code), out);                                               \
        const char *const want_[] = {__VA_ARGS__};                                                                     \
        for (size_t k_ = 0; k_ < sizeof want_ / sizeof want_[0]; k_++)                                                 \
            CHECKF(strstr(out, want_[k_]) != NULL, "message lacks \"%s\": %s", want_[k_], out);                        \
    } while (0)

/* The commands `sepbrdf --help` lists (lines "  NAME  summary" after
 * "commands:"), so a new command is covered without editing this file. */
static int commands(char names[][32], int max) {
    if (cli("--help") != 0) return -1;
    const char *p = strstr(out, "commands:\n");
    if (!p) return -1;
    p += strlen("commands:\n");
    int n = 0;
    while (n < max && p[0] == ' ' && p[1] == ' ' && p[2] != ' ') {
        sscanf(p, " %31s", names[n++]);
        p = strchr(p, '\n');
        if (!p) break;
        p++;
    }
    return n;
}

SB_TEST(help_every_command) {
    char names[32][32];
    int n = commands(names, 32);
    CHECKF(n >= 4, "found %d commands in --help: %s", n, out);
    EXPECT(cli("--help"), 0, "usage: sepbrdf", "exit status", "0 ok", "1 usage", "2 input/output", "3 numerical");
    EXPECT(cli("-h"), 0, "usage: sepbrdf");
    for (int i = 0; i < n; i++) {
        char usage[1100];
        snprintf(usage, sizeof usage, "usage: sepbrdf %s", names[i]);
        EXPECT(cli("%s --help", names[i]), 0, usage, "exit status", "--quiet", "--verbose");
        EXPECT(cli("%s -h", names[i]), 0, usage);
    }
}

/* A set's manifest as every command's --help names it is the file that
 * command writes, sepbrdf-set-CMD.txt (factor's help named
 * sepbrdf-set.txt, which no command writes). */
SB_TEST(help_names_the_manifest) {
    char names[32][32];
    int n = commands(names, 32);
    CHECK(n >= 4);
    for (int i = 0; i < n; i++) {
        CHECK(cli("%s --help", names[i]) == 0);
        char want[64];
        snprintf(want, sizeof want, "sepbrdf-set-%s.txt", names[i]);
        for (const char *at = strstr(out, "sepbrdf-set"); at; at = strstr(at + 1, "sepbrdf-set"))
            CHECKF(strncmp(at, want, strlen(want)) == 0, "%s --help names %.24s, the set's manifest is %s", names[i],
                   at, want);
    }
    const char *dir = sb_tmpdir("golden");
    CHECK(cli("factor lambert --param io -r 8 -J 1 -q -o %s/set", dir) == 0);
    char path[4200];
    snprintf(path, sizeof path, "%s/set/sepbrdf-set-factor.txt", dir);
    CHECKF(sb_file_exists(path), "%s missing", path);
}

SB_TEST(version) {
    EXPECT(cli("--version"), 0, "sepbrdf 0.");
    EXPECT(cli("-V"), 0, "sepbrdf 0.");
}

SB_TEST(bad_option) {
    char names[32][32];
    int n = commands(names, 32);
    CHECK(n >= 4);
    for (int i = 0; i < n; i++)
        EXPECT(cli("%s --bogus-option", names[i]), 1, "--bogus-option", "unknown option");
    EXPECT(cli("--bogus-option"), 1, "--bogus-option");
    EXPECT(cli("nosuchcommand"), 1, "nosuchcommand", "unknown command");
    EXPECT(cli("factor --res"), 1, "--res", "needs a value");
}

SB_TEST(bad_value) {
    const char *dir = sb_tmpdir("golden");
    EXPECT(cli("factor --res abc -o %s/o", dir), 1, "--res", "abc");
    EXPECT(cli("factor --res 1 -o %s/o", dir), 1, "--res", "out of range");
    EXPECT(cli("factor --terms 0 -o %s/o", dir), 1, "--terms");
    EXPECT(cli("factor --form cos3 -o %s/o", dir), 1, "--form", "cos3");
    EXPECT(cli("factor --method magic -o %s/o", dir), 1, "--method", "magic");
    EXPECT(cli("factor --param xyz -o %s/o", dir), 1, "--param", "xyz");
    EXPECT(cli("factor --max-error 2 -o %s/o", dir), 1, "--max-error");
    EXPECT(cli("factor lambert:albedo=7 -o %s/o", dir), 1, "albedo");
    EXPECT(cli("factor nosuchmodel -o %s/o", dir), 1, "nosuchmodel");
    EXPECT(cli("study lambert --terms 5..2 -o %s/o", dir), 1, "--terms", "5..2");
    EXPECT(cli("study lambert --terms 1..999 -o %s/o", dir), 1, "--terms");
    EXPECT(cli("study lambert --terms x -o %s/o", dir), 1, "--terms");
    EXPECT(cli("study lambert --param io,xyz -o %s/o", dir), 1, "--param", "xyz");
    EXPECT(cli("study -o %s/o", dir), 1, "no SOURCE");
    EXPECT(cli("info"), 1, "no FILE");
    char path[4200];
    snprintf(path, sizeof path, "%s/o", dir);
    CHECKF(!sb_file_exists(path), "%s created by a failed run", path);
}

SB_TEST(missing_file) {
    const char *dir = sb_tmpdir("golden");
    EXPECT(cli("factor /nonexistent/brdf.binary -o %s/o", dir), 2, "/nonexistent/brdf.binary", "No such file");
    EXPECT(cli("factor ./no-such-table.csv -o %s/o", dir), 2, "no-such-table.csv");
    EXPECT(cli("factor %s -o %s/o", dir, dir), 2, "not a regular file");
    EXPECT(cli("info /nonexistent/g_00.exr"), 2, "/nonexistent/g_00.exr");
    char path[4200];
    snprintf(path, sizeof path, "%s/o", dir);
    CHECKF(!sb_file_exists(path), "%s created by a failed run", path);
    /* a folder named like a model (a factor set in the current folder) is
     * said to be a folder, exit 2: it was "unknown model 'myset'", exit 1;
     * one that is a model's name (batch writes such folders) is the model */
    char cmd[8600], msg[2048];
    snprintf(path, sizeof path, "%s/myset", dir);
    CHECK(mkdir(path, 0777) == 0);
    snprintf(path, sizeof path, "%s/lambert", dir);
    CHECK(mkdir(path, 0777) == 0);
    snprintf(cmd, sizeof cmd, "cd %s && %s factor myset -o o", dir, SB_CLI);
    int rc = sb_run(cmd, msg, sizeof msg);
    CHECKF(rc == 2 && strstr(msg, "myset: a folder, not a model or a measured file"), "rc %d: %s", rc, msg);
    snprintf(cmd, sizeof cmd, "cd %s && %s factor lambert --res 4 -J 1 -q -o o", dir, SB_CLI);
    rc = sb_run(cmd, msg, sizeof msg);
    CHECKF(rc == 0, "a folder named lambert beside: rc %d: %s", rc, msg);
}

SB_TEST(unwritable_output) {
    const char *dir = sb_tmpdir("golden");
    char file[4200];
    snprintf(file, sizeof file, "%s/plain-file", dir);
    FILE *fp = fopen(file, "w");
    CHECK(fp != NULL);
    if (fp) fclose(fp);
    /* refused up front, before any work: a large job fails at once */
    EXPECT(cli("factor --res 512 -o /proc/nope/out"), 2, "/proc/nope/out", "--out");
    EXPECT(cli("factor lambert --res 4 -J 1 -o %s", file), 2, "plain-file", "not a folder");
    EXPECT(cli("factor lambert --res 4 -J 1 -o %s/sub", file), 2, "plain-file", "not a folder");
    EXPECT(cli("study lambert --res 4 -J 1 -o %s/sub", file), 2, "plain-file");
    EXPECT(cli("factor lambert --res 4 -J 1 -o ''"), 1, "--out");
    if (getuid() != 0) { /* root writes anywhere */
        char ro[4200];
        snprintf(ro, sizeof ro, "%s/read-only", dir);
        CHECK(mkdir(ro, 0555) == 0);
        EXPECT(cli("factor lambert --res 4 -J 1 -o %s/sub", ro), 2, "read-only");
    }
}

SB_TEST(quiet_and_verbose) {
    const char *dir = sb_tmpdir("golden");
    EXPECT(cli("factor lambert --res 4 -J 1 -q -o %s/a", dir), 0, "");
    CHECKF(out[0] == 0, "-q printed: %s", out);
    EXPECT(cli("-q factor lambert --res 4 -J 1 -o %s/b", dir), 0, "");
    CHECKF(out[0] == 0, "-q before the command printed: %s", out);
    EXPECT(cli("factor lambert --res 4 -J 1 --param io -v -o %s/c", dir), 0, "sampling", "rel_rms");
    EXPECT(cli_stdout("factor lambert --res 4 -J 1 -v -o %s/d", dir), 0, "rel_rms"); /* table: stdout */
    CHECKF(strstr(out, "sampling") == NULL, "detail went to stdout: %s", out);
    EXPECT(cli_stderr("factor lambert --res 4 -J 1 -v -o %s/e", dir), 0, "sampling"); /* detail: stderr */
    CHECKF(strstr(out, "rel_rms") == NULL, "the table went to stderr: %s", out);
}
