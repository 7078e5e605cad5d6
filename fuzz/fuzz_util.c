/* Helpers of the fuzz harnesses: setup once, files in a private folder. */
#include <dirent.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "fuzz.h"
#include "sepbrdf/common.h"

static char tmp_dir[4096];

/* Remove the folder and what the harnesses wrote into it (one level of
 * subfolders). */
static void remove_tree(const char *dir, int depth) {
    DIR *d = opendir(dir);
    if (!d) return;
    struct dirent *e;
    char path[8192];
    while ((e = readdir(d))) {
        if (strcmp(e->d_name, ".") == 0 || strcmp(e->d_name, "..") == 0) continue;
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        if (remove(path) != 0 && depth > 0) remove_tree(path, depth - 1);
    }
    closedir(d);
    rmdir(dir);
}

static void cleanup(void) {
    if (tmp_dir[0]) remove_tree(tmp_dir, 1);
}

const char *sb_fuzz_setup(void) {
    if (tmp_dir[0]) return tmp_dir;
    sb_set_memory_limit((size_t)256 << 20);
    const char *base = getenv("TMPDIR");
    snprintf(tmp_dir, sizeof tmp_dir, "%s/sbfuzz-XXXXXX", base && *base ? base : "/tmp");
    if (!mkdtemp(tmp_dir)) {
        perror("sb_fuzz_setup: mkdtemp");
        abort();
    }
    atexit(cleanup);
    return tmp_dir;
}

int sb_fuzz_mkdir(const char *path) { return mkdir(path, 0777) == 0 || errno == EEXIST ? 0 : -1; }

int sb_fuzz_write(const char *dir, const char *name, const uint8_t *data, size_t size) {
    char path[8192];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *fp = fopen(path, "wb");
    if (!fp) return -1;
    size_t n = size ? fwrite(data, 1, size, fp) : 0;
    return (fclose(fp) != 0 || n != size) ? -1 : 0;
}
