/* Output sets (outset.h): the paths of a set and the checks made before
 * any computation. */
#define _GNU_SOURCE
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "outset_impl.h"
#include "util/internal.h"

char *outset_join(const char *a, const char *b) {
    size_t len = strlen(a) + strlen(b) + 2;
    char *p = malloc(len);
    if (p) snprintf(p, len, "%s/%s", a, b);
    return p;
}

/* ---- paths and checks ---------------------------------------------------- */

sb_result_t outset_split(sb_context_t *ctx, const char *target, char **parent, char **base) {
    size_t n = strlen(target);
    if (n >= PATH_MAX - NAME_ROOM) return sb_error(ctx, SB_ERR_IO, "%.80s...: %s", target, sb_io_why(ENAMETOOLONG));
    char *p = sb_strdup(target), *real = NULL;
    if (!p) return sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    while (n > 1 && p[n - 1] == '/')
        p[--n] = 0;
    char *slash = strrchr(p, '/');
    const char *last = slash ? slash + 1 : p;
    struct stat st;
    if (strcmp(last, ".") == 0 || strcmp(last, "..") == 0 || !*last || (lstat(p, &st) == 0 && S_ISLNK(st.st_mode))) {
        if (!(real = realpath(p, NULL))) {
            int e = errno;
            free(p);
            return sb_error(ctx, SB_ERR_IO, "%s: %s", target, sb_io_why(e));
        }
        free(p);
        p = real;
        if (strcmp(p, "/") == 0) {
            free(p);
            return sb_error(ctx, SB_ERR_IO, "%s: the root folder cannot be an output folder", target);
        }
        slash = strrchr(p, '/');
    }
    if (!slash) {
        *parent = sb_strdup(".");
        *base = sb_strdup(p);
    } else {
        *slash = 0;
        *parent = sb_strdup(slash == p ? "/" : p);
        *base = sb_strdup(slash + 1);
    }
    free(p);
    if (!*parent || !*base) return sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    return SB_OK;
}

/* The staging name must fit the file system's limit on one name. */
static sb_result_t check_name_length(sb_context_t *ctx, const char *target, const char *parent, const char *base) {
    long max = pathconf(parent, _PC_NAME_MAX);
    if (max <= 0) max = 255;
    size_t need = strlen(base) + 1 + strlen(STAGE_TAG) + 17 + 12;
    if (need > (size_t)max)
        return sb_error(ctx, SB_ERR_IO, "%s: folder name too long (%zu characters; at most %ld here)", target,
                        strlen(base), max - (long)(need - strlen(base)));
    return SB_OK;
}

#define PROBE ".sepbrdf-probe-"

/* Probe folders of processes that are gone (one killed between creating
 * and removing its probe) in `dir`: removed. */
static void remove_stale_probes(const char *dir) {
    DIR *d = opendir(dir);
    struct dirent *e;
    size_t n = strlen(PROBE);
    while (d && (e = readdir(d)) != NULL) {
        const char *pid = e->d_name + n;
        if (strncmp(e->d_name, PROBE, n) != 0 || !*pid || strspn(pid, "0123456789") != strlen(pid)) continue;
        long p = strtol(pid, NULL, 10);
        if (p > 0 && p != (long)getpid() && !sb_outset_pid_alive(p)) unlinkat(dirfd(d), e->d_name, AT_REMOVEDIR);
    }
    if (d) closedir(d);
}

/* Whether we can create entries in folder `dir`: try it (access() says yes
 * to root everywhere) with a probe folder removed at once, with INT, TERM
 * and HUP held back on this thread in between; a probe left by a process
 * killed all the same is removed by the next probe there.  0 or errno. */
static int probe_dir(const char *dir) {
    char *probe = outset_join(dir, PROBE);
    size_t len = probe ? strlen(probe) + 24 : 0;
    char *full = probe ? malloc(len) : NULL;
    int e = ENOMEM;
    remove_stale_probes(dir);
    if (full) {
        sigset_t hold, old;
        sigemptyset(&hold);
        sigaddset(&hold, SIGINT);
        sigaddset(&hold, SIGTERM);
        sigaddset(&hold, SIGHUP);
        pthread_sigmask(SIG_BLOCK, &hold, &old);
        snprintf(full, len, "%s%ld", probe, (long)getpid());
        e = mkdir(full, 0700) == 0 ? 0 : errno;
        if (!e) rmdir(full);
        pthread_sigmask(SIG_SETMASK, &old, NULL);
    }
    free(probe);
    free(full);
    return e;
}

sb_result_t outset_check_existing(sb_context_t *ctx, const char *target, const char *dir, const char *parent) {
    struct stat sd, sp;
    if (stat(dir, &sd) != 0 || !S_ISDIR(sd.st_mode))
        return sb_error(ctx, SB_ERR_IO, "%s: exists and is not a folder", target);
    if (stat(parent, &sp) == 0 && sp.st_dev != sd.st_dev)
        return sb_error(ctx, SB_ERR_IO, "%s: is a mount point; name a folder inside it", target);
    char *real = realpath(dir, NULL), *cwd = getcwd(NULL, 0);
    size_t n = real ? strlen(real) : 0;
    int holds_cwd = real && cwd && strncmp(cwd, real, n) == 0 && (cwd[n] == 0 || cwd[n] == '/');
    free(real);
    free(cwd);
    if (holds_cwd)
        return sb_error(ctx, SB_ERR_IO,
                        "%s: is the current folder or holds it; the output set replaces the whole folder, "
                        "so name a folder of its own (e.g. %s/out)",
                        target, target);
    DIR *d = opendir(dir);
    if (!d) return sb_error(ctx, SB_ERR_IO, "%s: %s", target, sb_io_why(errno));
    sb_result_t r = SB_OK;
    struct dirent *e;
    while (r == SB_OK && (e = readdir(d)) != NULL) { /* a set holds no folders: any is a user's */
        struct stat st;
        if (strcmp(e->d_name, ".") == 0 || strcmp(e->d_name, "..") == 0) continue;
        if (fstatat(dirfd(d), e->d_name, &st, AT_SYMLINK_NOFOLLOW) == 0 && S_ISDIR(st.st_mode))
            r = sb_error(ctx, SB_ERR_IO,
                         "%s: holds the folder %s, which sepbrdf did not write; an output set replaces the "
                         "whole folder, so name a folder of its own",
                         target, e->d_name);
    }
    closedir(d);
    return r;
}

/* A missing DIR: its nearest existing ancestor must be a writable folder. */
static sb_result_t check_creatable(sb_context_t *ctx, const char *target, const char *parent) {
    char *anc = sb_strdup(parent);
    if (!anc) return sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    struct stat st;
    while (stat(anc, &st) != 0) {
        char *slash = strrchr(anc, '/');
        if (strcmp(anc, ".") == 0 || strcmp(anc, "/") == 0) {
            free(anc);
            return sb_error(ctx, SB_ERR_IO, "%s: cannot create the output folder: %s", target, sb_io_why(errno));
        }
        if (!slash)
            strcpy(anc, ".");
        else if (slash == anc)
            anc[1] = 0;
        else
            *slash = 0;
    }
    sb_result_t r = SB_OK;
    int e = 0;
    if (!S_ISDIR(st.st_mode))
        r = sb_error(ctx, SB_ERR_IO, "%s: cannot create the output folder, %s is not a folder", target, anc);
    else if ((e = probe_dir(anc)) != 0)
        r = sb_error(ctx, SB_ERR_IO, "%s: cannot create the output folder in %s: %s", target, anc, sb_io_why(e));
    free(anc);
    return r;
}

sb_result_t outset_check_paths(sb_context_t *ctx, const char *target, const char *parent, const char *base) {
    char *dir = outset_join(parent, base);
    if (!dir) return sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    struct stat st;
    sb_result_t r;
    int e;
    if (stat(dir, &st) != 0)
        r = check_creatable(ctx, target, parent);
    else if ((r = outset_check_existing(ctx, target, dir, parent)) != SB_OK)
        ;
    else if ((e = probe_dir(parent)) != 0 || (e = access(dir, W_OK | X_OK) == 0 ? 0 : errno) != 0)
        r = sb_error(ctx, SB_ERR_IO, "%s: cannot write into the folder: %s", target, sb_io_why(e));
    if (r == SB_OK) r = check_name_length(ctx, target, stat(parent, &st) == 0 ? parent : ".", base);
    free(dir);
    return r;
}

sb_result_t sb_outset_check(sb_context_t *ctx, const char *dir) {
    if (!dir || !*dir) return sb_error(ctx, SB_ERR_ARG, "output folder: empty name");
    char *parent = NULL, *base = NULL;
    sb_result_t r = outset_split(ctx, dir, &parent, &base);
    if (r == SB_OK) r = outset_check_paths(ctx, dir, parent, base);
    free(parent);
    free(base);
    return r;
}
