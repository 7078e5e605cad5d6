/* Replay of the fuzz harnesses (fuzz/fuzz_*.c, compiled into this test with
 * SB_FUZZ_REGRESS): every input that once crashed, kept in
 * tests/data/fuzz/<name>/, and every seed of fuzz/corpus/<name>/, through
 * the same entry points and invariants.  A broken invariant aborts, which
 * fails the case; under SEPBRDF_SANITIZE the replay also runs under ASan
 * and UBSan. */
#include <dirent.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"

int sb_fuzz_spec(const uint8_t *data, size_t size);
int sb_fuzz_exr(const uint8_t *data, size_t size);
int sb_fuzz_measured(const uint8_t *data, size_t size);

/* Feed every file of SB_SOURCE_DIR/<folder>/<name>/ to fn; returns the count. */
static int replay_dir(const char *folder, const char *name, int (*fn)(const uint8_t *, size_t)) {
    char dir[4096], path[8192];
    snprintf(dir, sizeof dir, "%s/%s/%s", SB_SOURCE_DIR, folder, name);
    DIR *d = opendir(dir);
    if (!d) return 0;
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d))) {
        if (e->d_name[0] == '.') continue;
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        FILE *fp = fopen(path, "rb");
        if (!fp) continue;
        static uint8_t buf[1 << 20];
        size_t len = fread(buf, 1, sizeof buf, fp);
        fclose(fp);
        /* a copy of exactly len bytes, so that ASan sees reads past the end */
        uint8_t *copy = malloc(len ? len : 1);
        memcpy(copy, buf, len);
        fprintf(stderr, "replay %s/%s\n", name, e->d_name);
        CHECK(fn(copy, len) == 0);
        free(copy);
        n++;
    }
    closedir(d);
    return n;
}

static void replay(const char *name, int (*fn)(const uint8_t *, size_t)) {
    int crashes = replay_dir("tests/data/fuzz", name, fn), seeds = replay_dir("fuzz/corpus", name, fn);
    fprintf(stderr, "%s: %d former crashes, %d seeds replayed\n", name, crashes, seeds);
    CHECK(seeds > 0);
}

SB_TEST(spec) { replay("spec", sb_fuzz_spec); }
SB_TEST(exr) { replay("exr", sb_fuzz_exr); }
SB_TEST(measured) { replay("measured", sb_fuzz_measured); }
