/* sepbrdf batch: the batch folder OUT as one consistent thing.
 *
 * One batch at a time: the folder itself is locked (flock on OUT, or on
 * OUT/.sepbrdf-batch.lock where a file system locks no folders) for the
 * whole run, and the lock is inherited by the worker processes, so a batch
 * killed while its workers still publish keeps OUT locked until they end.
 *
 * What a material's folder holds is read back from the folder: batch.txt,
 * published inside the set, holds its settings key (line 1), its result
 * fields (line 2, BATCH_FIELDS) and its sums (line 3: a hash of lines 1-2,
 * then the name, size and hash of every other file of the set).  A set is
 * reused when its key is the item's and every file is as it was written,
 * and the summary is rebuilt from these files after the run, so it
 * describes what the folders hold whatever happened during the run.  Keys
 * and fields have no length limit (a layout spec with warp tables runs to
 * thousands of characters). */
#define _DEFAULT_SOURCE /* flock (BSD, Linux, macOS) */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include "batch.h"

#define LOCK_FILE ".sepbrdf-batch.lock"
#define MAX_BATCH_FILE (16u << 20) /* batch.txt: a key and one line of fields */

int batch_lock(const char *dir) {
    int fd = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    int r = fd >= 0 ? flock(fd, LOCK_EX | LOCK_NB) : -1;
    if (r != 0 && fd >= 0 && errno != EWOULDBLOCK) { /* no folder locks here (NFS): a lock file */
        char path[4200];
        close(fd);
        snprintf(path, sizeof path, "%s/" LOCK_FILE, dir);
        fd = open(path, O_RDWR | O_CREAT | O_CLOEXEC, 0666);
        r = fd >= 0 ? flock(fd, LOCK_EX | LOCK_NB) : -1;
    }
    if (r == 0) return fd;
    int e = errno;
    if (fd >= 0) close(fd);
    if (e == EWOULDBLOCK)
        cli_error("batch",
                  "--out %s: another batch is writing into this folder (or its worker processes still are); "
                  "wait until it ends or choose another --out",
                  dir);
    else if (e == ENOTDIR)
        cli_error("batch", "--out %s: exists and is not a folder", dir);
    else
        cli_error("batch", "--out %s: cannot lock the folder: %s", dir, sb_io_why(e));
    return -1;
}

void batch_unlock(int fd) {
    if (fd >= 0) close(fd); /* releases the lock once the workers have closed their copies too */
}

/* printf into a new string (a memory stream: any length); NULL when out
 * of memory. */
static char *format(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
static char *format(const char *fmt, ...) {
    char *s = NULL;
    size_t n = 0;
    FILE *fp = open_memstream(&s, &n);
    if (!fp) return NULL;
    va_list ap;
    va_start(ap, fmt);
    int bad = vfprintf(fp, fmt, ap) < 0;
    va_end(ap);
    if (fclose(fp) != 0 || bad) {
        free(s);
        return NULL;
    }
    return s;
}

int batch_key(batch_item_t *it) {
    const sb_job_opts_t *o = &it->o;
    const sb_measured_opts_t *m = &o->measured;
    char budget[40] = "";
    if (o->budget) snprintf(budget, sizeof budget, " budget=%zu", o->budget);
    /* settings added later only when given: the keys of sets without them stay as they were */
    free(it->key);
    it->key = format("source=%s param=%s form=%s weighted=%d zero_fill=%d res=%zu terms=%zu metric_res=%zu "
                     "max_error=%.17g theta_max=%.17g method=%d seed=%llu channels=%u half=%d previews=%d format=%s "
                     "interp=%d neighbours=%zu radius=%.17g white=%d%s%s%s%s%s%s",
                     it->source, o->param ? o->param : "auto", o->form ? o->form : "-", o->weighted, o->zero_fill,
                     o->res, o->terms, o->metric_res, o->max_error, o->theta_max_deg, (int)o->method, o->seed,
                     o->channels, o->half, o->previews, m->format ? m->format : "auto", (int)m->interp, m->neighbours,
                     m->radius, (int)m->white, budget, o->warp ? " warp=" : "", o->warp ? o->warp : "",
                     o->scene ? " scene=" : "", o->scene ? o->scene : "", o->plain_terms ? " plain_terms=1" : "");
    for (char *c = it->key; c && *c; c++) /* one line of batch.txt, whatever the names hold */
        if (*c == '\n' || *c == '\r') *c = '\t';
    return it->key ? 0 : -1;
}

/* A folder written before `weighted` joined BATCH_FIELDS holds one field
 * fewer: an empty weighted cell is put in its place (the report in that
 * folder says it), so the later fields keep their columns. */
static void old_fields(char **fields) {
    size_t tabs = 0;
    for (const char *c = *fields; *c; c++)
        tabs += *c == '\t';
    char *second = strchr(*fields, '\t');
    second = second ? strchr(second + 1, '\t') : NULL;
    if (tabs != BATCH_NF - 2 || !second) return;
    char *up = format("%.*s\t%s", (int)(second - *fields), *fields, second);
    if (!up) return;
    free(*fields);
    *fields = up;
}

uint64_t batch_fnv1a(uint64_t h, const void *data, size_t n) {
    const unsigned char *p = data;
    for (size_t i = 0; i < n; i++)
        h = (h ^ p[i]) * 0x100000001b3ull;
    return h;
}

/* Size and hash of the file at path; -1 when it is not a regular file or
 * cannot be read whole. */
static int file_sum(const char *path, long long *size, uint64_t *h) {
    int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC); /* a FIFO put in its place does not wait */
    FILE *fp = fd >= 0 ? fdopen(fd, "rb") : NULL;
    struct stat st;
    if (!fp || fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
        if (fp)
            fclose(fp);
        else if (fd >= 0)
            close(fd);
        return -1;
    }
    unsigned char buf[1 << 16];
    size_t got;
    long long total = 0;
    *h = BATCH_FNV_START;
    while ((got = fread(buf, 1, sizeof buf, fp)) > 0) {
        *h = batch_fnv1a(*h, buf, got);
        total += (long long)got;
    }
    int bad = ferror(fp);
    fclose(fp);
    *size = total;
    return bad ? -1 : 0;
}

int batch_sums_write(FILE *fp, const char *dir, const char *head) {
    DIR *d = opendir(dir);
    if (!d) return -1;
    fprintf(fp, "sums\t%016llx", (unsigned long long)batch_fnv1a(BATCH_FNV_START, head, strlen(head)));
    struct dirent *e;
    int rc = 0;
    while (rc == 0 && (e = readdir(d)) != NULL) {
        if (e->d_name[0] == '.' || strcmp(e->d_name, BATCH_FILE) == 0) continue; /* hidden: not of the set */
        char *path = format("%s/%s", dir, e->d_name);
        struct stat st;
        long long size;
        uint64_t h;
        if (!path || lstat(path, &st) != 0)
            rc = -1;
        else if (S_ISREG(st.st_mode) && file_sum(path, &size, &h) == 0)
            fprintf(fp, "\t%s\t%lld\t%016llx", e->d_name, size, (unsigned long long)h);
        else if (S_ISREG(st.st_mode))
            rc = -1;
        free(path);
    }
    closedir(d);
    fputc('\n', fp);
    return rc;
}

/* Whether a file of the set list, at path, is the one `sums` recorded
 * (name, size, hash); 1 yes, 0 no (why says how), -1 not recorded. */
static int sum_matches(const char *sums, const char *name, const char *path, char *why, size_t wsize) {
    size_t len = strlen(name);
    const char *p = strchr(sums + 5, '\t'); /* past "sums", the hash of lines 1-2 */
    for (int k = 0; p; k++, p = strchr(p + 1, '\t')) {
        if (k % 3 != 0 || strncmp(p + 1, name, len) != 0 || p[1 + len] != '\t') continue;
        char *end;
        long long size = strtoll(p + 2 + len, &end, 10), got_size;
        unsigned long long h = *end == '\t' ? strtoull(end + 1, NULL, 16) : 0;
        uint64_t got;
        if (file_sum(path, &got_size, &got) != 0)
            snprintf(why, wsize, "%s cannot be read", name);
        else if (got_size != size)
            snprintf(why, wsize, "%s holds %lld bytes, %lld when the set was written", name, got_size, size);
        else if (got != h)
            snprintf(why, wsize, "%s was changed after the set was written", name);
        else
            return 1;
        return 0;
    }
    return -1;
}

/* Whether line 3 of batch.txt (sums) holds the hash of lines 1-2 (head). */
static int head_matches(const char *sums, const char *head, size_t n) {
    char want[24];
    snprintf(want, sizeof want, "%016llx", (unsigned long long)batch_fnv1a(BATCH_FNV_START, head, n));
    return strncmp(sums + 5, want, 16) == 0 && (sums[21] == '\t' || sums[21] == '\n');
}

/* Whether DIR/NAME still holds every file its set list names, each as
 * `sums` (line 3 of batch.txt) recorded it; a folder written before the
 * sums (sums NULL): its textures (g_*.exr, h_*.exr) of the bytes `fields`
 * recorded.  A set that lost a file or holds one cut short or edited (a
 * user's rm or editor, an interrupted copy of OUT) is not the set batch
 * wrote, so not reused; why says which file. */
static int set_whole(const char *dir, const char *name, const char *fields, const char *sums, char *why, size_t wsize) {
    char *path = format("%s/%s/sepbrdf-set-factor.txt", dir, name), *text = NULL;
    size_t n = 0;
    int whole = path && cli_read_file(path, MAX_BATCH_FILE, &text, &n) == 0;
    free(path);
    long long sum = 0;
    size_t listed = 0, recorded = 0;
    for (const char *c = sums ? strchr(sums + 5, '\t') : NULL; c; c = strchr(c + 1, '\t'))
        recorded++;
    for (char *line = text, *eol; whole && line < text + n; line = eol + 1) {
        eol = memchr(line, '\n', (size_t)(text + n - line));
        if (!eol) eol = text + n;
        *eol = 0;
        size_t len = strlen(line);
        if (!len || line[0] == '#') continue;
        struct stat st;
        char *file = format("%s/%s/%s", dir, name, line);
        whole = file && stat(file, &st) == 0 && S_ISREG(st.st_mode);
        if (!whole) snprintf(why, wsize, "%s is missing", line);
        if (whole && sums && strcmp(line, BATCH_FILE) != 0) {
            int m = sum_matches(sums, line, file, why, wsize);
            if (m < 0) snprintf(why, wsize, "%s was not written by batch", line);
            whole = m == 1;
            listed++;
        }
        free(file);
        if (whole && (line[0] == 'g' || line[0] == 'h') && len > 4 && strcmp(line + len - 4, ".exr") == 0)
            sum += st.st_size;
    }
    free(text);
    if (whole && sums && listed * 3 != recorded) snprintf(why, wsize, "its set list lost files batch wrote");
    if (sums) return whole && listed * 3 == recorded;
    const char *p = fields; /* bytes, the tenth field (BATCH_FIELDS) */
    for (int k = 0; k < 9 && p; k++)
        p = strchr(p, '\t') ? strchr(p, '\t') + 1 : NULL;
    char *end = NULL;
    long long bytes = p ? strtoll(p, &end, 10) : 0;
    int same = !p || end == p || *end != '\t' || bytes == sum;
    if (whole && !same) snprintf(why, wsize, "its textures hold %lld bytes, %lld when the set was written", sum, bytes);
    return whole && same;
}

int batch_folder_read(const char *dir, const char *name, char **key, char **fields, char *why, size_t wsize) {
    char *path = format("%s/%s/sepbrdf-set-factor.txt", dir, name), *text = NULL, scratch[1];
    *key = *fields = NULL;
    if (!why) why = scratch, wsize = sizeof scratch;
    why[0] = 0;
    int held = path && access(path, F_OK) == 0;
    free(path);
    path = held ? format("%s/%s/" BATCH_FILE, dir, name) : NULL;
    size_t n = 0;
    if (!path || cli_read_file(path, MAX_BATCH_FILE, &text, &n) != 0) {
        if (held) snprintf(why, wsize, BATCH_FILE " is missing or cannot be read");
        free(path);
        return 0;
    }
    free(path);
    char *eol = memchr(text, '\n', n), *eol2 = eol ? memchr(eol + 1, '\n', n - (size_t)(eol + 1 - text)) : NULL;
    char *sums = eol2 && eol2 + 1 < text + n ? eol2 + 1 : NULL; /* line 3; none: written before the sums */
    if (!eol2 || memchr(text, 0, n) ||
        (sums && (strncmp(sums, "sums\t", 5) != 0 || text[n - 1] != '\n' ||
                  memchr(sums, '\n', n - (size_t)(sums - text)) != text + n - 1 ||
                  !head_matches(sums, text, (size_t)(sums - text))))) {
        snprintf(why, wsize, BATCH_FILE " was changed after the set was written");
        free(text);
        return 0;
    }
    *eol = *eol2 = 0;
    if (sums) text[n - 1] = 0;
    *key = text;
    *fields = malloc(strlen(eol + 1) + 1);
    if (!*fields) {
        free(text);
        *key = NULL;
        return 0;
    }
    strcpy(*fields, eol + 1);
    old_fields(fields);
    if (set_whole(dir, name, *fields, sums, why, wsize)) return 1;
    free(text), free(*fields);
    *key = *fields = NULL;
    return 0;
}

/* it->headline from the fifth of its fields. */
static void set_headline(batch_item_t *it) {
    const char *p = it->fields;
    for (int k = 0; k < 4 && p; k++)
        p = strchr(p, '\t') ? strchr(p, '\t') + 1 : NULL;
    it->headline = p ? strtod(p, NULL) : NAN;
}

int batch_done(const char *dir, batch_item_t *it) {
    char *key, *fields, why[600];
    if (!batch_folder_read(dir, it->name, &key, &fields, why, sizeof why)) {
        if (why[0]) cli_info(1, "batch: %s: %s; fitted again", it->name, why);
        return 0;
    }
    int same = strcmp(key, it->key) == 0;
    free(key);
    if (!same) {
        free(fields);
        return 0;
    }
    free(it->fields);
    it->fields = fields;
    set_headline(it);
    it->ok = 1;
    /* a run killed between publishing this set and removing its staging
     * folder left that folder beside it: gone now that the set is reused
     * (only folders whose process has ended) */
    char *path = format("%s/%s", dir, it->name);
    if (path) (void)sb_outset_cleanup(NULL, path);
    free(path);
    return 1;
}

void batch_reread(const char *dir, batch_item_t *items, size_t n) {
    for (size_t i = 0; i < n; i++) {
        batch_item_t *it = &items[i];
        char *key, *fields;
        int held = batch_folder_read(dir, it->name, &key, &fields, NULL, 0), same = held && strcmp(key, it->key) == 0;
        free(key);
        free(it->fields);
        it->fields = fields; /* what the folder holds, whatever this run did */
        it->other = held && !same;
        if (same) {
            it->ok = 1;
            set_headline(it);
            continue;
        }
        if (it->ok) /* its process said it published, yet the folder holds no such set */
            snprintf(it->msg, sizeof it->msg, "its folder does not hold the set this run wrote (%s)",
                     held ? "another process replaced it" : "it was removed");
        it->ok = 0;
        it->headline = NAN;
    }
}
