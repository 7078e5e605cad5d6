/* Output sets published as one unit (outset.h).
 *
 * The set is built in a staging folder beside the target, PARENT/.NAME
 * .sepbrdf-new-PID, and swapped with the target DIR by one
 * renameat2(RENAME_EXCHANGE): before the swap DIR holds the previous set,
 * after it the new one, with nothing in between that a reader or a crash
 * could see.  The manifest of a set (DIR/sepbrdf-set-CMD.txt) says which files
 * the set wrote; everything else in DIR is the user's and is hard-linked
 * into the new folder before the swap, so it is never lost.
 *
 * Recovering a staging folder whose process is gone (recover_folder):
 *   - without a manifest it holds only files of a set still being written:
 *     all are removed;
 *   - with one it is either a complete new set (crash before the swap) or
 *     the previous set (crash after it).  Entries the manifest lists are
 *     removed; any other entry is a user's file: removed when DIR has an
 *     entry of that name (the hard link DIR shares), otherwise moved back
 *     into DIR.
 * The same routine removes the previous set after a successful swap. */
#define _GNU_SOURCE
#include "sepbrdf/outset.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <unistd.h>

#include "outset_impl.h"
#include "util/internal.h"

#ifndef RENAME_EXCHANGE
#define RENAME_EXCHANGE (1 << 1)
#endif

typedef struct names {
    char **v;
    size_t n, cap;
} names_t;

struct sb_outset {
    sb_context_t *ctx;
    char *target;      /* DIR as given (messages) */
    char *dir;         /* DIR as used: PARENT/NAME, symbolic links resolved */
    char *parent;      /* PARENT */
    char *base;        /* NAME */
    char *staging;     /* PARENT/.NAME.sepbrdf-new-PID */
    char manifest[64]; /* sepbrdf-set[-CMD].txt */
    char *command;
    int lock_fd;
    int created; /* DIR did not exist: removed again if still empty and nothing was published */
    int done;    /* committed or discarded */
    int published;
    names_t files;
    names_t stale; /* manifests of the sets this one supersedes (opts.supersedes) */
};

/* ---- names ---------------------------------------------------------------- */

static int names_has(const names_t *l, const char *name) {
    for (size_t i = 0; i < l->n; i++)
        if (strcmp(l->v[i], name) == 0) return 1;
    return 0;
}

static int names_push(names_t *l, const char *name) {
    if (names_has(l, name)) return 0;
    if (l->n == l->cap) {
        size_t cap = l->cap ? 2 * l->cap : 16;
        char **v = realloc(l->v, cap * sizeof *v);
        if (!v) return -1;
        l->v = v;
        l->cap = cap;
    }
    if (!(l->v[l->n] = sb_strdup(name))) return -1;
    l->n++;
    return 0;
}

static void names_free(names_t *l) {
    for (size_t i = 0; i < l->n; i++)
        free(l->v[i]);
    free(l->v);
    memset(l, 0, sizeof *l);
}

/* The manifest `manifest` of folder fd (one name per line, '#' lines are
 * comments) into *l.  1 read, 0 none there, -1 no memory. */
static int manifest_read(int fd, const char *manifest, names_t *l) {
    int mfd = openat(fd, manifest, O_RDONLY | O_CLOEXEC | O_NOFOLLOW);
    if (mfd < 0) return 0;
    FILE *fp = fdopen(mfd, "r");
    if (!fp) {
        close(mfd);
        return 0;
    }
    char line[1024];
    int rc = 1;
    while (rc == 1 && fgets(line, sizeof line, fp)) {
        line[strcspn(line, "\r\n")] = 0;
        if (line[0] && line[0] != '#' && names_push(l, line) != 0) rc = -1;
    }
    fclose(fp);
    return rc;
}

/* ---- removal ------------------------------------------------------------- */

struct sb_dirent64 {
    uint64_t d_ino;
    int64_t d_off;
    unsigned short d_reclen;
    unsigned char d_type;
    char d_name[];
};

/* Raw system calls only (see outset.h).  Entries removed while the folder
 * is read may hide others from that pass, so passes repeat until one
 * removes nothing. */
void sb_outset_discard_signal_safe(const char *staging) {
    if (!staging || !*staging) return;
    int fd = open(staging, O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
    if (fd >= 0) {
        _Alignas(8) char buf[4096];
        for (int pass = 0, removed = 1; removed && pass < 16; pass++) {
            removed = 0;
            if (lseek(fd, 0, SEEK_SET) != 0) break;
            long n;
            while ((n = syscall(SYS_getdents64, fd, buf, sizeof buf)) > 0)
                for (long off = 0; off < n;) {
                    struct sb_dirent64 *e = (struct sb_dirent64 *)(void *)(buf + off);
                    off += e->d_reclen;
                    const char *nm = e->d_name;
                    if (nm[0] == '.' && (!nm[1] || (nm[1] == '.' && !nm[2]))) continue;
                    if (unlinkat(fd, nm, 0) == 0) removed = 1;
                }
        }
        close(fd);
    }
    rmdir(staging);
}

/* Remove a staging folder with its manifest (file header): `owned` are
 * the names its set wrote. */
static void recover_entries(const char *folder, const char *dir, const char *manifest, const names_t *owned) {
    DIR *d = opendir(folder);
    int tfd = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (!d || tfd < 0) goto out;
    int fd = dirfd(d);
    struct dirent *e;
    while ((e = readdir(d)) != NULL) {
        const char *nm = e->d_name;
        if (strcmp(nm, ".") == 0 || strcmp(nm, "..") == 0) continue;
        struct stat st;
        int ours = names_has(owned, nm) || strcmp(nm, manifest) == 0;
        if (ours || fstatat(tfd, nm, &st, AT_SYMLINK_NOFOLLOW) == 0)
            unlinkat(fd, nm, 0); /* a user's folder there fails: kept */
        else
            renameat(fd, nm, tfd, nm); /* a user's entry only here: back into DIR */
    }
out:
    if (tfd >= 0) close(tfd);
    if (d) closedir(d);
}

/* `stale`: manifests of other sets in the folder that go with it (NULL:
 * none); their files count as the set's own. */
static void recover_folder(const char *folder, const char *dir, const char *manifest, int trust_missing_manifest,
                           const names_t *stale) {
    names_t owned = {0};
    int fd = open(folder, O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
    if (fd < 0) return;
    int m = manifest_read(fd, manifest, &owned);
    for (size_t i = 0; m >= 0 && stale && i < stale->n; i++)
        if (manifest_read(fd, stale->v[i], &owned) < 0 || names_push(&owned, stale->v[i]) != 0) m = -1;
    close(fd);
    if (m < 0) {
        names_free(&owned);
        return; /* no memory: leave it for the next run */
    }
    if (m == 0 && !trust_missing_manifest)
        sb_outset_discard_signal_safe(folder);
    else
        recover_entries(folder, dir, manifest, &owned);
    rmdir(folder);
    names_free(&owned);
}

/* The manifest of command cmd (its first n bytes; none: n = 0). */
static void manifest_name(const char *cmd, size_t n, char out[64]) {
    if (n)
        snprintf(out, 64, "sepbrdf-set-%.*s.txt", (int)n, cmd);
    else
        snprintf(out, 64, "%s", SB_OUTSET_MANIFEST);
}

/* kill(pid, 0) succeeds on a zombie, and a killed run's workers stay
 * zombies for good where nothing reaps orphans (a container whose first
 * process is a plain shell): /proc tells them apart. */
int sb_outset_pid_alive(long pid) {
    if (pid <= 0 || (kill((pid_t)pid, 0) != 0 && errno != EPERM)) return 0;
    char path[64], buf[512];
    snprintf(path, sizeof path, "/proc/%ld/stat", pid);
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0) return 1; /* no /proc: assume it runs */
    ssize_t n = read(fd, buf, sizeof buf - 1);
    close(fd);
    if (n <= 0) return 1;
    buf[n] = 0;
    const char *paren = strrchr(buf, ')'); /* "PID (COMM) STATE ...", COMM may hold ')' */
    return !(paren && paren[1] == ' ' && (paren[2] == 'Z' || paren[2] == 'X'));
}

/* Recover every staging folder of DIR whose process is gone. */
static void cleanup_stale(const char *parent, const char *base, const char *dir) {
    DIR *d = opendir(parent);
    if (!d) return;
    size_t nb = strlen(base), nt = strlen(STAGE_TAG);
    struct dirent *e;
    while ((e = readdir(d)) != NULL) {
        const char *nm = e->d_name, *digits = nm + 1 + nb + nt;
        if (nm[0] != '.' || strncmp(nm + 1, base, nb) != 0 || strncmp(nm + 1 + nb, STAGE_TAG, nt) != 0) continue;
        char manifest[64];
        const char *dash = strrchr(digits, '-');
        size_t nc = dash ? (size_t)(dash - digits) : 0;
        if (dash) digits = dash + 1;
        if (!*digits || strspn(digits, "0123456789") != strlen(digits) || strlen(digits) > 12 || nc > 16) continue;
        long pid = strtol(digits, NULL, 10);
        if (pid == (long)getpid() || sb_outset_pid_alive(pid)) continue;
        manifest_name(nm + 1 + nb + nt, nc, manifest);
        char *path = outset_join(parent, nm);
        if (!path) break;
        recover_folder(path, dir, manifest, 0, NULL);
        free(path);
    }
    closedir(d);
}

/* ---- the set ------------------------------------------------------------- */

/* mkdir -p; 0 or errno. */
static int make_dirs(const char *path) {
    char *buf = sb_strdup(path);
    if (!buf) return ENOMEM;
    int e = 0;
    for (char *p = buf + 1; !e; p++) {
        if (*p != '/' && *p) continue;
        char c = *p;
        *p = 0;
        if (mkdir(buf, 0777) != 0 && errno != EEXIST) e = errno;
        *p = c;
        if (!c) break;
    }
    free(buf);
    return e;
}

/* Lock DIR: flock on the folder itself.  The folder a waiting run locked
 * may have been swapped away meanwhile: then lock the one DIR names now. */
static sb_result_t lock_dir(sb_outset_t *s, int no_wait) {
    for (int tries = 0; tries < 1000; tries++) {
        int e = make_dirs(s->dir);
        if (e) return sb_error(s->ctx, SB_ERR_IO, "%s: cannot create the output folder: %s", s->target, sb_io_why(e));
        int fd = open(s->dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
        if (fd < 0) {
            if (errno == ENOENT) continue;
            return sb_error(s->ctx, SB_ERR_IO, "%s: %s", s->target, sb_io_why(errno));
        }
        int rc = flock(fd, LOCK_EX | LOCK_NB);
        if (rc != 0 && errno == EWOULDBLOCK && no_wait) {
            close(fd);
            return sb_error(s->ctx, SB_ERR_IO, "%s: another sepbrdf run is writing this folder; try again when it ends",
                            s->target);
        }
        while (rc != 0 && (errno == EWOULDBLOCK || errno == EINTR))
            rc = flock(fd, LOCK_EX);
        if (rc != 0) {
            e = errno;
            close(fd);
            return sb_error(s->ctx, SB_ERR_IO, "%s: cannot lock the folder: %s", s->target, sb_io_why(e));
        }
        struct stat a, b;
        if (fstat(fd, &a) == 0 && stat(s->dir, &b) == 0 && a.st_ino == b.st_ino && a.st_dev == b.st_dev) {
            s->lock_fd = fd;
            return SB_OK;
        }
        close(fd);
    }
    return sb_error(s->ctx, SB_ERR_IO, "%s: cannot lock the folder: it keeps being replaced", s->target);
}

/* The staging folder, with DIR's permissions (it becomes DIR). */
static sb_result_t make_staging(sb_outset_t *s, const sb_outset_opts_t *opts) {
    size_t len = strlen(s->parent) + strlen(s->base) + strlen(STAGE_TAG) + 48;
    if (!(s->staging = malloc(len))) return sb_error(s->ctx, SB_ERR_NOMEM, "out of memory");
    snprintf(s->staging, len, "%s/.%s%s%s%s%ld", s->parent, s->base, STAGE_TAG, s->command ? s->command : "",
             s->command ? "-" : "", (long)getpid());
    if (opts && opts->staging_fn) opts->staging_fn(opts->staging_user, s->staging);
    sb_outset_discard_signal_safe(s->staging); /* an earlier set of this process */
    struct stat st;
    if (mkdir(s->staging, 0700) != 0 || stat(s->dir, &st) != 0 || chmod(s->staging, st.st_mode & 07777) != 0) {
        int e = errno;
        rmdir(s->staging);
        return sb_error(s->ctx, SB_ERR_IO, "%s: cannot write beside the folder, in %s: %s", s->target, s->parent,
                        sb_io_why(e));
    }
    return SB_OK;
}

sb_result_t sb_outset_begin(sb_context_t *ctx, const char *dir, const sb_outset_opts_t *opts, sb_outset_t **out) {
    if (!out) return sb_error(ctx, SB_ERR_ARG, "sb_outset_begin: out is NULL");
    *out = NULL;
    if (!dir || !*dir) return sb_error(ctx, SB_ERR_ARG, "output folder: empty name");
    const char *cmd = opts ? opts->command : NULL;
    if (cmd && (!*cmd || strlen(cmd) > 16 || strspn(cmd, "abcdefghijklmnopqrstuvwxyz0123456789") != strlen(cmd)))
        return sb_error(ctx, SB_ERR_ARG, "output set: command '%s' is not 1..16 of a-z, 0-9", cmd);
    sb_outset_t *s = calloc(1, sizeof *s);
    if (!s) return sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    s->ctx = ctx;
    s->lock_fd = -1;
    s->target = sb_strdup(dir);
    manifest_name(cmd, cmd ? strlen(cmd) : 0, s->manifest);
    s->command = cmd ? sb_strdup(cmd) : NULL;
    sb_result_t r = !s->target || (cmd && !s->command) ? sb_error(ctx, SB_ERR_NOMEM, "out of memory")
                                                       : outset_split(ctx, dir, &s->parent, &s->base);
    for (const char *const *o = opts ? opts->supersedes : NULL; r == SB_OK && o && *o; o++) {
        char m[64];
        if (!**o || strlen(*o) > 16 || strspn(*o, "abcdefghijklmnopqrstuvwxyz0123456789") != strlen(*o)) {
            r = sb_error(ctx, SB_ERR_ARG, "output set: superseded command '%s' is not 1..16 of a-z, 0-9", *o);
            break;
        }
        manifest_name(*o, strlen(*o), m);
        if (strcmp(m, s->manifest) != 0 && names_push(&s->stale, m) != 0)
            r = sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    }
    if (r == SB_OK && !(s->dir = outset_join(s->parent, s->base))) r = sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    if (r == SB_OK) r = outset_check_paths(ctx, dir, s->parent, s->base);
    struct stat st;
    s->created = r == SB_OK && stat(s->dir, &st) != 0;
    if (r == SB_OK) r = lock_dir(s, opts && opts->no_wait);
    if (r == SB_OK) {
        cleanup_stale(s->parent, s->base, s->dir);
        r = outset_check_existing(ctx, dir, s->dir, s->parent); /* under the lock now */
    }
    if (r == SB_OK) r = make_staging(s, opts);
    if (r != SB_OK) {
        s->done = 1;
        sb_outset_destroy(s);
        return r;
    }
    sb_context_alias(ctx, s->staging, s->target);
    *out = s;
    return SB_OK;
}

const char *sb_outset_dir(const sb_outset_t *s) { return s ? s->staging : NULL; }
const char *sb_outset_target(const sb_outset_t *s) { return s ? s->target : NULL; }

sb_result_t sb_outset_add(sb_outset_t *s, const char *name) {
    if (!s) return SB_ERR_ARG;
    int bad = !name || !*name || name[0] == '.' || strchr(name, '/') || strncmp(name, "sepbrdf-set", 11) == 0 ||
              strlen(name) > NAME_ROOM - 8;
    for (const char *p = name; !bad && *p; p++)
        bad = (unsigned char)*p < 0x20 || *p == 0x7f;
    if (bad) return sb_error(s->ctx, SB_ERR_ARG, "output set: '%s' is not a plain file name", name ? name : "(null)");
    if (s->done) return sb_error(s->ctx, SB_ERR_ARG, "output set %s: already published", s->target);
    return names_push(&s->files, name) ? sb_error(s->ctx, SB_ERR_NOMEM, "out of memory") : SB_OK;
}

static int cmp_names(const void *a, const void *b) { return strcmp(*(char *const *)a, *(char *const *)b); }

/* Every file in the staging folder joins the set (hidden leftovers of a
 * writer are removed); every added name must be there. */
static sb_result_t collect_files(sb_outset_t *s, int fd) {
    for (size_t i = 0; i < s->files.n; i++) {
        struct stat st;
        if (fstatat(fd, s->files.v[i], &st, AT_SYMLINK_NOFOLLOW) != 0 || !S_ISREG(st.st_mode))
            return sb_error(s->ctx, SB_ERR_IO, "%s/%s: missing from the output set", s->target, s->files.v[i]);
    }
    int dfd = dup(fd);
    DIR *d = dfd >= 0 ? fdopendir(dfd) : NULL;
    if (!d) {
        if (dfd >= 0) close(dfd);
        return sb_error(s->ctx, SB_ERR_IO, "%s: %s", s->target, sb_io_why(errno));
    }
    sb_result_t r = SB_OK;
    struct dirent *e;
    while (r == SB_OK && (e = readdir(d)) != NULL) {
        struct stat st;
        if (e->d_name[0] == '.')
            unlinkat(fd, e->d_name, 0); /* "." and ".." fail harmlessly */
        else if (fstatat(fd, e->d_name, &st, AT_SYMLINK_NOFOLLOW) == 0 && S_ISREG(st.st_mode) &&
                 names_push(&s->files, e->d_name) != 0)
            r = sb_error(s->ctx, SB_ERR_NOMEM, "out of memory");
    }
    closedir(d);
    if (r == SB_OK) qsort(s->files.v, s->files.n, sizeof *s->files.v, cmp_names);
    return r;
}

/* The manifest into the staging folder, listing the set's files. */
static sb_result_t write_manifest(sb_outset_t *s) {
    int fd = open(s->staging, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd < 0) return sb_error(s->ctx, SB_ERR_IO, "%s: %s", s->target, sb_io_why(errno));
    sb_result_t r = collect_files(s, fd);
    if (r != SB_OK) {
        close(fd);
        return r;
    }
    int mfd = openat(fd, s->manifest, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
    close(fd);
    FILE *fp = mfd >= 0 ? fdopen(mfd, "w") : NULL;
    int e = 0;
    if (!fp) {
        e = errno;
        if (mfd >= 0) close(mfd);
    } else {
        fprintf(fp, "# sepbrdf output set 1%s%s: the files this run wrote, one per line\n", s->command ? ", " : "",
                s->command ? s->command : "");
        for (size_t i = 0; i < s->files.n; i++)
            fprintf(fp, "%s\n", s->files.v[i]);
        if (fflush(fp) != 0 || ferror(fp)) e = errno ? errno : EIO;
        if (fclose(fp) != 0 && !e) e = errno;
    }
    if (e) return sb_error(s->ctx, SB_ERR_IO, "%s/%s: cannot write: %s", s->target, s->manifest, sb_io_why(e));
    return SB_OK;
}

/* Hard-link every entry of DIR the previous set did not write into the
 * staging folder (a name the new set writes is replaced by it). */
static sb_result_t keep_foreign(sb_outset_t *s) {
    names_t old = {0};
    DIR *d = opendir(s->dir);
    int sfd = open(s->staging, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    sb_result_t r = SB_OK;
    if (!d || sfd < 0 || manifest_read(dirfd(d), s->manifest, &old) < 0)
        r = sb_error(s->ctx, SB_ERR_IO, "%s: cannot read the folder: %s", s->target, sb_io_why(errno));
    for (size_t i = 0; r == SB_OK && i < s->stale.n; i++) /* superseded sets go with the previous one */
        if (manifest_read(dirfd(d), s->stale.v[i], &old) < 0 || names_push(&old, s->stale.v[i]) != 0)
            r = sb_error(s->ctx, SB_ERR_NOMEM, "out of memory");
    struct dirent *e;
    while (r == SB_OK && (e = readdir(d)) != NULL) {
        const char *nm = e->d_name;
        if (strcmp(nm, ".") == 0 || strcmp(nm, "..") == 0 || strcmp(nm, s->manifest) == 0 || names_has(&old, nm) ||
            names_has(&s->files, nm))
            continue;
        struct stat st;
        if (fstatat(dirfd(d), nm, &st, AT_SYMLINK_NOFOLLOW) == 0 && S_ISDIR(st.st_mode))
            r = sb_error(s->ctx, SB_ERR_IO, "%s: holds the folder %s, which sepbrdf did not write; nothing written",
                         s->target, nm);
        else if (linkat(dirfd(d), nm, sfd, nm, 0) != 0 && errno != EEXIST)
            r = sb_error(s->ctx, SB_ERR_IO, "%s/%s: cannot keep it in the new set (hard link): %s", s->target, nm,
                         sb_io_why(errno));
    }
    if (sfd >= 0) close(sfd);
    if (d) closedir(d);
    names_free(&old);
    return r;
}

sb_result_t sb_outset_commit(sb_outset_t *s) {
    if (!s) return SB_ERR_ARG;
    if (s->done) return sb_error(s->ctx, SB_ERR_ARG, "output set %s: already published or discarded", s->target);
    sb_result_t r = write_manifest(s);
    if (r == SB_OK) r = keep_foreign(s);
    if (r == SB_OK && syscall(SYS_renameat2, AT_FDCWD, s->staging, AT_FDCWD, s->dir, RENAME_EXCHANGE) != 0) {
        int e = errno;
        r = sb_error(s->ctx, SB_ERR_IO, "%s: cannot publish the output set: %s", s->target,
                     e == EINVAL || e == ENOSYS ? "this file system cannot swap folders atomically (renameat2 "
                                                  "RENAME_EXCHANGE)"
                                                : sb_io_why(e));
    }
    s->done = 1;
    sb_context_alias(s->ctx, NULL, NULL);
    if (r != SB_OK) {
        sb_outset_discard_signal_safe(s->staging);
        return r;
    }
    s->published = 1;
    recover_folder(s->staging, s->dir, s->manifest, 1, &s->stale); /* the previous set, now under the staging name */
    return SB_OK;
}

void sb_outset_destroy(sb_outset_t *s) {
    if (!s) return;
    if (!s->done && s->staging) sb_outset_discard_signal_safe(s->staging);
    if (s->created && !s->published) rmdir(s->dir); /* only if still empty */
    if (s->staging) sb_context_alias(s->ctx, NULL, NULL);
    if (s->lock_fd >= 0) close(s->lock_fd);
    names_free(&s->files);
    names_free(&s->stale);
    free(s->target);
    free(s->dir);
    free(s->parent);
    free(s->base);
    free(s->staging);
    free(s->command);
    free(s);
}

sb_result_t sb_outset_cleanup(sb_context_t *ctx, const char *dir) {
    if (!dir || !*dir) return sb_error(ctx, SB_ERR_ARG, "output folder: empty name");
    sb_outset_t s = {ctx, (char *)dir, NULL, NULL, NULL, NULL, "", NULL, -1, 0, 1, 0, {0}, {0}};
    sb_result_t r = outset_split(ctx, dir, &s.parent, &s.base);
    struct stat st;
    if (r == SB_OK && !(s.dir = outset_join(s.parent, s.base))) r = sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    if (r == SB_OK && stat(s.dir, &st) == 0) r = lock_dir(&s, 0);
    if (r == SB_OK) cleanup_stale(s.parent, s.base, s.dir);
    if (s.lock_fd >= 0) close(s.lock_fd);
    free(s.dir);
    free(s.parent);
    free(s.base);
    return r;
}
