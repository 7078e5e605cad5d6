/* CLI: values the textures cannot store end the run before any output is
 * written, with the real cause, the target file and the exit status of the
 * README's table: 3 for a BRDF outside the storage range, 1 for a number
 * of terms above the BRDF's numerical rank (lower -J).  A reference grid
 * that would take minutes (--metric-res 256) is refused at once. */
#include <dirent.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"

static char out[1 << 15];

/* No file in the output folder (it may have been created empty). */
static int no_files(const char *path) {
    DIR *d = opendir(path);
    if (!d) return 1;
    struct dirent *e;
    int n = 0;
    while ((e = readdir(d)))
        n += strcmp(e->d_name, ".") != 0 && strcmp(e->d_name, "..") != 0;
    closedir(d);
    return n == 0;
}

static int run_factor(const char *args, const char *dir) {
    char cmd[8192];
    snprintf(cmd, sizeof cmd, "%s factor %s -r 8 --param io -q -o %s/out", SB_CLI, args, dir);
    return sb_run(cmd, out, sizeof out);
}

SB_TEST(below_range) {
    const char *dir = sb_tmpdir("cli-storage");
    char sub[4200];
    snprintf(sub, sizeof sub, "%s/out", dir);
    for (int half = 0; half < 2; half++) {
        int rc = run_factor(half ? "lambert:albedo=1e-300 -J 1 --half" : "lambert:albedo=1e-300 -J 1", dir);
        CHECKF(rc == 3 && strstr(out, "below the range") && strstr(out, "g_00.exr") && !strstr(out, ".tmp-"),
               "exit %d: %s", rc, out);
        CHECK(no_files(sub));
    }
}

SB_TEST(rank_exhausted) {
    const char *dir = sb_tmpdir("cli-storage");
    char sub[4200];
    snprintf(sub, sizeof sub, "%s/out", dir);
    int rc = run_factor("lambert:albedo=1e-60 -J 3 --half", dir);
    CHECKF(rc == 1 && strstr(out, "numerical rank is exhausted") && strstr(out, "g_01.exr"), "exit %d: %s", rc, out);
    CHECK(no_files(sub));
}

SB_TEST(metric_res_bounded) {
    char cmd[8192];
    const char *dir = sb_tmpdir("cli-storage");
    snprintf(cmd, sizeof cmd, "%s factor -r 8 --metric-res 256 -o %s/out", SB_CLI, dir);
    int rc = sb_run(cmd, out, sizeof out);
    CHECKF(rc == 1 && strstr(out, "--metric-res") && strstr(out, "2..128"), "exit %d: %s", rc, out);
    snprintf(cmd, sizeof cmd, "%s study lambert -r 8 --metric-res 129 -o %s/out", SB_CLI, dir);
    rc = sb_run(cmd, out, sizeof out);
    CHECKF(rc == 1 && strstr(out, "--metric-res"), "exit %d: %s", rc, out);
}
