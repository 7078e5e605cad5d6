/* examples/use_library runs the same factor job as `sepbrdf factor`: the
 * example's main() (compiled in here as it is) and the real binary, given
 * the same source, R and J (auto included), write the same report.json
 * (every key but the wall-clock times) and the same textures. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"

#define main use_library_main
#include "../examples/use_library/main.c"
#undef main

static char *slurp(const char *dir, const char *name, size_t *len) {
    char path[4200];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *fp = fopen(path, "rb");
    if (!fp) return NULL;
    fseek(fp, 0, SEEK_END);
    long n = ftell(fp);
    fseek(fp, 0, SEEK_SET);
    char *buf = malloc((size_t)n + 1);
    if (buf && fread(buf, 1, (size_t)n, fp) != (size_t)n) n = 0;
    if (buf) buf[n] = 0;
    fclose(fp);
    if (len) *len = (size_t)n;
    return buf;
}

/* report.json without the lines of wall-clock times ("..._s": number). */
static void drop_times(char *s) {
    char *w = s;
    for (char *line = s; *line;) {
        char *end = strchr(line, '\n');
        size_t n = end ? (size_t)(end - line + 1) : strlen(line);
        int is_time = 0;
        for (char *q = line; q + 4 < line + n; q++)
            if (q[0] == '_' && q[1] == 's' && q[2] == '"' && q[3] == ':') is_time = 1;
        if (!is_time) {
            memmove(w, line, n);
            w += n;
        }
        line += n;
    }
    *w = 0;
}

static void same_set(const char *spec, const char *res, const char *terms) {
    const char *base = sb_tmpdir("cli-library");
    char lib[4096], cli[4096], cmd[8192];
    snprintf(lib, sizeof lib, "%s/lib", base);
    snprintf(cli, sizeof cli, "%s/cli", base);
    char *argv[] = {"use_library", (char *)spec, (char *)res, (char *)terms, lib, NULL};
    FILE *keep = stdout;
    stdout = fopen("/dev/null", "w"); /* the example prints its table */
    int rc = use_library_main(5, argv);
    fclose(stdout);
    stdout = keep;
    CHECKF(rc == 0, "use_library %s %s %s: exit %d", spec, res, terms, rc);
    snprintf(cmd, sizeof cmd, "%s factor %s -r %s -J %s -q -o %s", SB_CLI, spec, res, terms, cli);
    CHECKF(sb_run(cmd, NULL, 0) == 0, "%s failed", cmd);
    char *a = slurp(lib, "report.json", NULL), *b = slurp(cli, "report.json", NULL);
    CHECKF(a && b, "report.json missing (library %p, CLI %p)", (void *)a, (void *)b);
    if (a && b) {
        drop_times(a);
        drop_times(b);
        CHECKF(strcmp(a, b) == 0, "%s: the reports differ:\n%s\n---\n%s", spec, a, b);
        CHECKF(strstr(a, "\"auto_tried\"") != NULL, "%s: not an auto run", spec);
    }
    free(a);
    free(b);
    static const char *const files[] = {"g_00.exr", "h_00.exr", "sepbrdf.glsl"};
    for (int i = 0; i < 3; i++) {
        size_t na = 0, nb = 0;
        char *x = slurp(lib, files[i], &na), *y = slurp(cli, files[i], &nb);
        CHECKF(x && y && na == nb && memcmp(x, y, na) == 0, "%s: %s differs", spec, files[i]);
        free(x);
        free(y);
    }
}

SB_TEST(same_as_factor) { same_set("microfacet:roughness=0.4", "8", "3"); }

SB_TEST(same_as_factor_measured) {
    char table[1024];
    snprintf(table, sizeof table, "%s/cornell_acryl_blue.brdf", SB_MEASURED_DIR);
    CHECKF(sb_file_exists(table), "%s: the shipped measured table is missing", table);
    if (!sb_test_failed_now()) same_set(table, "8", "2");
}
