#include "harness.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#define MAX_TESTS 512

static struct {
    const char *name;
    sb_test_fn fn;
} tests[MAX_TESTS];
static int ntests;
static int cur_failed, cur_skipped;
static char **tmpdirs; /* made by sb_tmpdir, removed at the end */
static size_t ntmpdirs;

void sb_test_register(const char *name, sb_test_fn fn) {
    if (ntests < MAX_TESTS) {
        tests[ntests].name = name;
        tests[ntests].fn = fn;
        ntests++;
    }
}

void sb_test_fail(const char *file, int line, const char *fmt, ...) {
    va_list ap;
    fprintf(stderr, "FAIL: %s:%d ", file, line);
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fputc('\n', stderr);
    cur_failed++;
}

void sb_test_skip(const char *why) {
    fprintf(stderr, "SKIP: %s\n", why);
    cur_skipped = 1;
}

int sb_test_failed_now(void) { return cur_failed; }

int sb_run(const char *cmd, char *out, size_t out_size) {
    char full[8192];
    snprintf(full, sizeof full, "%s 2>&1", cmd);
    FILE *p = popen(full, "r");
    if (!p) return -1;
    size_t n = 0;
    if (out && out_size) {
        size_t r;
        while (n + 1 < out_size && (r = fread(out + n, 1, out_size - 1 - n, p)) > 0)
            n += r;
        out[n] = 0;
    }
    char sink[4096];
    while (fread(sink, 1, sizeof sink, p) > 0) {
    }
    int st = pclose(p);
    if (WIFEXITED(st)) return WEXITSTATUS(st);
    return -1;
}

const char *sb_tmpdir(const char *tag) {
    static char buf[4096];
    const char *base = getenv("TMPDIR");
    if (!base) base = "/tmp";
    snprintf(buf, sizeof buf, "%s/sbtest-%s-XXXXXX", base, tag);
    if (!mkdtemp(buf)) {
        perror("mkdtemp");
        exit(2);
    }
    char **v = realloc(tmpdirs, (ntmpdirs + 1) * sizeof *v);
    if (v && (v[ntmpdirs] = strdup(buf)) != NULL)
        tmpdirs = v, ntmpdirs++;
    else if (v)
        tmpdirs = v;
    return buf;
}

/* Remove the folders sb_tmpdir made (when every case passed; a failure
 * keeps them to look at, or SB_KEEP_TMP=1 keeps them always). */
static void remove_tmpdirs(int keep) {
    for (size_t i = 0; i < ntmpdirs; i++) {
        if (keep) {
            fprintf(stderr, "kept: %s\n", tmpdirs[i]);
        } else if (!strchr(tmpdirs[i], '\'')) {
            char cmd[4300];
            snprintf(cmd, sizeof cmd, "chmod -R u+rwX '%s' 2>/dev/null; rm -rf '%s'", tmpdirs[i], tmpdirs[i]);
            if (system(cmd) != 0) fprintf(stderr, "note: could not remove %s\n", tmpdirs[i]);
        }
        free(tmpdirs[i]);
    }
    free(tmpdirs);
    tmpdirs = NULL;
    ntmpdirs = 0;
}

int sb_file_exists(const char *path) {
    struct stat st;
    return stat(path, &st) == 0;
}

char *sb_read_file(const char *path, size_t *len) {
    FILE *fp = fopen(path, "rb");
    if (!fp) return NULL;
    char *buf = NULL;
    long n = fseek(fp, 0, SEEK_END) == 0 ? ftell(fp) : -1;
    if (n >= 0 && fseek(fp, 0, SEEK_SET) == 0 && (buf = malloc((size_t)n + 1)) != NULL) {
        if (fread(buf, 1, (size_t)n, fp) != (size_t)n) n = 0;
        buf[n] = 0;
        if (len) *len = (size_t)n;
    }
    fclose(fp);
    return buf;
}

double sb_rand01(unsigned long long *s) {
    *s = *s * 6364136223846793005ULL + 1442695040888963407ULL;
    return (double)(*s >> 11) * (1.0 / 9007199254740992.0);
}

int main(int argc, char **argv) {
    int passed = 0, failed = 0, skipped = 0, ran = 0;
    for (int i = 0; i < ntests; i++) {
        int wanted = argc < 2;
        for (int a = 1; a < argc; a++)
            if (strcmp(argv[a], tests[i].name) == 0) wanted = 1;
        if (!wanted) continue;
        ran++;
        cur_failed = 0;
        cur_skipped = 0;
        tests[i].fn();
        if (cur_failed) {
            failed++;
            fprintf(stderr, "case %s: FAILED\n", tests[i].name);
        } else if (cur_skipped) {
            skipped++;
        } else {
            passed++;
        }
    }
    if (argc >= 2 && ran == 0) {
        fprintf(stderr, "no such test case: %s\n", argv[1]);
        return 1;
    }
    const char *keep = getenv("SB_KEEP_TMP");
    remove_tmpdirs(failed > 0 || (keep && *keep && strcmp(keep, "0") != 0));
    printf("%d passed, %d failed, %d skipped\n", passed, failed, skipped);
    if (failed) return 1;
    if (skipped && !passed) return 77;
    return 0;
}
