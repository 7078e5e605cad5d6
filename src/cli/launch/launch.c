/* `sepbrdf`: the launcher.  OpenBLAS and the C library read their settings
 * at process start, before main (env_plan.c), so the CLI needs them in its
 * environment when it starts.  This small program (the C library only)
 * adds them and executes the CLI proper, sepbrdf-main, found next to it (the
 * build tree) or in SB_LIBEXEC_REL relative to it (an installed tree).
 * Started directly, sepbrdf-main re-executes itself with the same
 * environment instead (blas_env.c), which costs a second start of the
 * libraries: about 10 ms on the 2-core VM, a tenth of `factor --param io
 * -r 64`. */
#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "env_plan.h"

#ifndef SB_LIBEXEC_REL
#define SB_LIBEXEC_REL "../libexec/sepbrdf"
#endif

/* The folder of this executable, with a trailing '/', into dir: from
 * /proc/self/exe, else from argv[0] (a path, or a name looked up in PATH
 * as the shell did).  0 when it cannot be found. */
static int own_folder(const char *argv0, char *dir, size_t size) {
    ssize_t n = readlink("/proc/self/exe", dir, size - 1);
    if (n > 0) {
        dir[n] = '\0';
    } else if (argv0 && strchr(argv0, '/')) {
        snprintf(dir, size, "%s", argv0);
    } else if (argv0 && *argv0) {
        const char *path = getenv("PATH"), *p = path ? path : "";
        int found = 0;
        while (!found && *p) {
            size_t len = strcspn(p, ":");
            snprintf(dir, size, "%.*s/%s", (int)len, len ? p : ".", argv0);
            found = access(dir, X_OK) == 0;
            p += len + (p[len] == ':');
        }
        if (!found) return 0;
    } else {
        return 0;
    }
    char *slash = strrchr(dir, '/');
    if (!slash) return 0;
    slash[1] = '\0';
    return 1;
}

/* Whether path is this executable (the same file as /proc/self/exe). */
static int is_self(const char *path) {
    struct stat a, b;
    return stat(path, &a) == 0 && stat("/proc/self/exe", &b) == 0 && a.st_dev == b.st_dev && a.st_ino == b.st_ino;
}

int main(int argc, char **argv, char **envp) {
    static char *env[SB_ENV_MAX];
    char self[PATH_MAX], path[PATH_MAX + 64];
    (void)argc;
    if (!own_folder(argv[0], self, sizeof self)) {
        fprintf(stderr, "sepbrdf: cannot find its own folder (/proc/self/exe: %s)\n", strerror(errno));
        return 127;
    }
    char **use = sb_env_plan(envp, env) ? env : envp; /* envp itself when nothing is added */
    const char *where[] = {"", SB_LIBEXEC_REL "/"};
    for (int i = 0; i < 2; i++) {
        snprintf(path, sizeof path, "%s%ssepbrdf-main", self, where[i]);
        if (access(path, X_OK) == 0) {
            if (is_self(path)) { /* a copy of the launcher under the CLI's name would run itself forever */
                fprintf(stderr, "sepbrdf: %s is this launcher, not the CLI proper (a broken installation)\n", path);
                return 127;
            }
            execve(path, argv, use);
            fprintf(stderr, "sepbrdf: cannot run %s: %s\n", path, strerror(errno));
            return 127;
        }
    }
    fprintf(stderr, "sepbrdf: the CLI sepbrdf-main is neither in %s nor in %s%s (a broken installation)\n", self, self,
            SB_LIBEXEC_REL);
    return 127;
}
