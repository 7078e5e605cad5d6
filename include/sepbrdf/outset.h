/* sepbrdf: output sets, published as one unit.
 *
 * An output set is the files one run writes into one folder DIR (textures,
 * report.json, the GLSL snippet, previews; a study's tables and plot; a
 * render's images).  A reader of DIR always sees one complete set, never
 * parts of two runs:
 *
 *   sb_outset_begin   locks DIR (flock on the folder itself: a second run
 *                     into DIR waits, or fails with SB_ERR_IO when asked),
 *                     removes what crashed runs left beside it (staging
 *                     folders whose process is gone) and creates the
 *                     staging folder PARENT/.NAME.sepbrdf-new-CMD-PID, NAME
 *                     the last component of DIR, CMD the command;
 *   (caller)          writes every file of the set into sb_outset_dir()
 *                     (sb_outset_add names those that must be there);
 *   sb_outset_commit  writes the manifest DIR/sepbrdf-set-CMD.txt (every file in
 *                     sb_outset_dir(), one per line after a '#' header line;
 *                     hidden names there are writers' leftovers, removed),
 *                     hard-links into the staging folder every entry of DIR
 *                     that the previous set did not write (its manifest says
 *                     which it did), swaps the staging folder with DIR in one
 *                     step (Linux renameat2 RENAME_EXCHANGE) and removes the
 *                     previous set, now under the staging name.
 *
 * Each command has its own set and manifest: a `render` into the folder of a
 * `factor` set adds its set beside it and replaces only an earlier render
 * set; a set named in opts.supersedes (a `view` page of the `factor` set
 * being replaced) is removed with the previous set.  So files the project did not write are never deleted (a user's
 * notes.txt or g_05.exr stays when a 4-term set replaces a 6-term one), while every file of the previous set that the
 * new one does not write (g_05.exr of the earlier 6-term set, its previews) is gone.  A file of the new set replaces an
 * entry of the same name.  A run that dies at any point (any signal, SIGKILL included, a full disk, a file-size limit)
 * leaves DIR holding either the previous set or the new one; its staging folder is removed by the next sb_outset_begin
 * for DIR (or sb_outset_cleanup) once its process is gone.
 *
 * Limits, checked by sb_outset_check before any computation: DIR must be a
 * folder of its own, i.e. not a mount point, not the current folder or one
 * above it, and holding no subfolder the project did not write (the swap
 * moves whole folders; subfolders cannot be hard-linked); the file system
 * must support hard links and RENAME_EXCHANGE (ext4, xfs, btrfs, tmpfs do);
 * NAME plus 32 characters must fit the file system's name length.
 *
 * While a set is open, messages of the library that name a path inside the
 * staging folder name the path inside DIR instead (the staging folder is an
 * implementation detail; its name never reaches a user). */
#ifndef SEPBRDF_OUTSET_H
#define SEPBRDF_OUTSET_H

#include "common.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The manifest's file name inside DIR of a set begun without a command;
 * with command CMD it is "sepbrdf-set-CMD.txt". */
#define SB_OUTSET_MANIFEST "sepbrdf-set.txt"

typedef struct sb_outset sb_outset_t;

typedef struct sb_outset_opts {
    const char *command; /* names the set and its manifest ("factor": 1..16 of a-z, 0-9); NULL = none */
    int no_wait;         /* 1: fail with SB_ERR_IO while another run writes DIR; 0: wait for it */
    /* Called with the staging folder's path just before it is created, so
     * that a signal handler knows it from its first moment; NULL = none. */
    void (*staging_fn)(void *user, const char *staging);
    void *staging_user;
    /* Commands whose sets in DIR are made from this one and go stale when it
     * is replaced (a `view` page embeds a `factor` set's textures): NULL-
     * terminated, each as `command`; NULL = none.  Publishing removes those
     * sets (their manifests' files and the manifests) with the previous set. */
    const char *const *supersedes;
} sb_outset_opts_t;

/* Check, without changing anything, that a set could be published in DIR
 * (limits above): DIR is an existing folder satisfying them, or can be
 * created (its nearest existing ancestor is a folder we can write in), and
 * its parent accepts the staging folder.  Errors: SB_ERR_ARG (NULL or empty
 * DIR), SB_ERR_IO (name too long, not a folder, cannot write, a mount point,
 * the current folder, a foreign subfolder; the message names DIR and why). */
SB_API sb_result_t sb_outset_check(sb_context_t *ctx, const char *dir);

/* Begin a set in DIR (created with its parents if missing); opts may be
 * NULL (defaults).  *out is new; destroy it with sb_outset_destroy.
 * Errors: those of sb_outset_check, SB_ERR_IO (also: no_wait and another
 * run writes DIR), SB_ERR_NOMEM. */
SB_API sb_result_t sb_outset_begin(sb_context_t *ctx, const char *dir, const sb_outset_opts_t *opts, sb_outset_t **out);

/* The folder to write the set's files into (the staging folder); owned by
 * s, valid until sb_outset_destroy. */
SB_API const char *sb_outset_dir(const sb_outset_t *s);

/* The target folder DIR as given to sb_outset_begin (for messages). */
SB_API const char *sb_outset_target(const sb_outset_t *s);

/* Name a file the set must hold (sb_outset_commit fails without it):
 * `name` is a plain file name (no '/', not starting with '.', no control
 * characters, at most 56 bytes, not beginning "sepbrdf-set") written into
 * sb_outset_dir().  Adding a name twice is harmless.  Errors: SB_ERR_ARG,
 * SB_ERR_NOMEM. */
SB_API sb_result_t sb_outset_add(sb_outset_t *s, const char *name);

/* Publish the set (see above).  Every added name must exist in
 * sb_outset_dir() as a regular file.  On success DIR holds the new set; on
 * failure DIR is untouched and the staging folder is removed.  Either way
 * s can only be destroyed afterwards.  Errors: SB_ERR_ARG (committed twice),
 * SB_ERR_IO (a file missing, disk full writing the manifest, a foreign
 * subfolder that appeared meanwhile, no hard links or RENAME_EXCHANGE). */
SB_API sb_result_t sb_outset_commit(sb_outset_t *s);

/* Release the lock; a set not committed is discarded (staging folder
 * removed, DIR untouched).  Accepts NULL. */
SB_API void sb_outset_destroy(sb_outset_t *s);

/* Remove what crashed runs left beside DIR (staging folders of processes
 * that are gone) without starting a set; DIR is locked meanwhile when it
 * exists.  Errors: SB_ERR_ARG, SB_ERR_IO. */
SB_API sb_result_t sb_outset_cleanup(sb_context_t *ctx, const char *dir);

/* Remove the staging folder `staging` and the entries directly in it, using
 * only async-signal-safe system calls (open, getdents64, unlinkat, rmdir,
 * close): for a signal handler that ends the run while a set is open
 * (sb_outset_dir() gives the name to keep).  Never touches DIR. */
SB_API void sb_outset_discard_signal_safe(const char *staging);

/* Whether process `pid`, named in a staging folder or a temporary file,
 * may still run: 1 when a signal could reach it and it is not a zombie
 * (a killed run's workers stay zombies where nothing reaps orphans). */
SB_API int sb_outset_pid_alive(long pid);

#ifdef __cplusplus
}
#endif

#endif
