/* sepbrdf batch: running the materials, one process each (fork), and the
 * summary.  Each material's folder is an output set of the factor job
 * (outset.h), published whole with batch.txt (its settings and results),
 * so a set found complete with the same settings is reused as it is. */
#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "batch.h"
#include "pipeline.h"

/* Sum of the sizes of the EXR textures in folder `dir`. */
static long long texture_bytes(const char *dir) {
    long long sum = 0;
    DIR *d = opendir(dir);
    struct dirent *e;
    struct stat st;
    while (d && (e = readdir(d)) != NULL) {
        size_t n = strlen(e->d_name);
        if ((e->d_name[0] == 'g' || e->d_name[0] == 'h') && n > 4 && strcmp(e->d_name + n - 4, ".exr") == 0 &&
            fstatat(dirfd(d), e->d_name, &st, 0) == 0)
            sum += st.st_size;
    }
    if (d) closedir(d);
    return sum;
}

/* The results of job (BATCH_FIELDS, tab-separated) to fp. */
static void job_fields(FILE *fp, const sb_job_t *job, long long bytes) {
    const sb_factors_t *f = sb_job_factors(job);
    const sb_factor_errors_t *e = sb_factors_errors(f);
    size_t J = sb_factors_terms(f);
    sb_job_timings_t t;
    sb_job_timings(job, &t);
    fprintf(fp, "%s\t%s\t%d\t%zu\t%.9g\t%.9g\t%.9g\t%.9g\t%.9g\t%lld\t%.3f\n", sb_param_spec(sb_job_param(job)),
            sb_form_name(sb_job_form(job)), sb_job_weighted(job) ? 1 : 0, J, sb_job_headline(job, J),
            sb_job_comparable(job, J), e->rel_rms[sb_err_at(J - 1, SB_CH_ALL)], e->max_abs[sb_err_at(J - 1, SB_CH_ALL)],
            sb_job_negative(job, J), bytes, t.total_s);
}

/* batch.txt of it into the staging folder of set: its key, the fields of
 * job and the sums of the set's other files (written before it); 0 or -1. */
static int write_record(sb_outset_t *set, const batch_item_t *it, const sb_job_t *job) {
    char *head = NULL, tmp[4200];
    size_t hn = 0;
    FILE *mem = open_memstream(&head, &hn), *fp = NULL;
    if (!mem) return -1;
    fprintf(mem, "%s\n", it->key);
    job_fields(mem, job, texture_bytes(sb_outset_dir(set)));
    int rc = fclose(mem) == 0 && cli_set_file(set, BATCH_FILE, tmp, sizeof tmp) == 0 && (fp = fopen(tmp, "w")) ? 0 : -1;
    if (fp) {
        fputs(head, fp);
        rc = batch_sums_write(fp, sb_outset_dir(set), head);
        int werr = ferror(fp);
        rc = fclose(fp) == 0 && !werr ? rc : -1;
    }
    free(head);
    return rc;
}

/* Write the set of job plus batch.txt into DIR/NAME; 0 or -1 (it->msg). */
static int publish(sb_context_t *ctx, const char *dir, batch_item_t *it, sb_job_t *job) {
    char path[4096];
    int rc = EXIT_OK;
    snprintf(path, sizeof path, "%s/%s", dir, it->name);
    sb_outset_t *set = cli_outset_begin(ctx, "factor", path, &rc);
    if (!set) {
        snprintf(it->msg, sizeof it->msg, "%.400s: cannot begin the output set", path);
        return -1;
    }
    sb_result_t r = sb_job_write_set(ctx, job, set);
    if (r == SB_OK && write_record(set, it, job) == 0) {
        if (cli_outset_end(ctx, "factor", set, 1) == EXIT_OK) return 0;
        set = NULL;
    }
    if (r != SB_OK)
        cli_job_message(it->msg, sizeof it->msg, ctx, r, it->o.terms);
    else
        snprintf(it->msg, sizeof it->msg, "%.400s: cannot write the output set", path);
    cli_outset_end(ctx, "factor", set, 0);
    return -1;
}

int batch_work(const char *dir, batch_item_t *it, char *line, size_t size) {
    sb_context_t *ctx = NULL;
    sb_job_t *job = NULL;
    int rc = EXIT_IO;
    if (sb_context_create(&ctx) != SB_OK) {
        snprintf(it->msg, sizeof it->msg, "out of memory");
    } else {
        sb_job_opts_t o = it->o;
        o.source = it->source;
        sb_result_t r = sb_job_run(ctx, &o, &job);
        if (r != SB_OK) {
            cli_job_message(it->msg, sizeof it->msg, ctx, r, o.terms);
            rc = cli_exit_code(r);
        } else if (publish(ctx, dir, it, job) == 0) {
            rc = EXIT_OK;
        }
    }
    snprintf(line, size, "%s%s", rc == EXIT_OK ? "ok" : "error\t", rc == EXIT_OK ? "" : it->msg);
    sb_job_destroy(job);
    sb_context_destroy(ctx);
    return rc;
}

int batch_take(batch_item_t *it, const char *line) {
    if (strncmp(line, "ok", 2) == 0 && (!line[2] || line[2] == '\t')) {
        it->ok = 1; /* the fields: batch_reread, from its folder */
    } else if (strncmp(line, "error\t", 6) == 0) {
        snprintf(it->msg, sizeof it->msg, "%.511s", line + 6);
    } else {
        return 0;
    }
    return 1;
}

/* In the child: factor item `it` and write its result line to fd; the
 * exit code. */
static int work(const char *dir, batch_item_t *it, int fd) {
    char line[BATCH_LINE];
    int rc = batch_work(dir, it, line, sizeof line);
    if (write(fd, line, strlen(line)) < 0) rc = EXIT_IO;
    return rc;
}

/* Read the child's line from fd into it. */
static void collect(batch_item_t *it, int fd, int status) {
    char line[BATCH_LINE];
    ssize_t n, got = 0;
    while (got < (ssize_t)sizeof line - 1 && (n = read(fd, line + got, sizeof line - 1 - (size_t)got)) > 0)
        got += n;
    line[got > 0 ? got : 0] = 0;
    close(fd);
    int exited = WIFEXITED(status) && WEXITSTATUS(status) == 0;
    if ((strncmp(line, "ok", 2) != 0 || exited) && batch_take(it, line)) return;
    if (WIFSIGNALED(status)) {
        snprintf(it->msg, sizeof it->msg, "its process was killed by signal %d", WTERMSIG(status));
    } else {
        snprintf(it->msg, sizeof it->msg, "its process ended without a result");
    }
}

/* Start the child of item it; its pid (-1: failed, it->msg set). */
static pid_t spawn(const char *dir, batch_item_t *it, int *fd) {
    int p[2];
    if (pipe(p) != 0) {
        snprintf(it->msg, sizeof it->msg, "cannot start a process: %s", strerror(errno));
        return -1;
    }
    fflush(stdout);
    fflush(stderr);
    pid_t pid = fork();
    if (pid == 0) {
        close(p[0]);
        g_verbosity = g_verbosity > 0 ? 0 : g_verbosity; /* the parent reports */
        _exit(work(dir, it, p[1]));
    }
    close(p[1]);
    if (pid < 0) {
        close(p[0]);
        snprintf(it->msg, sizeof it->msg, "cannot start a process: %s", strerror(errno));
        return -1;
    }
    *fd = p[0];
    return pid;
}

void batch_run(const char *dir, batch_item_t *items, size_t n, size_t jobs) {
    pid_t pid[64];
    int fd[64];
    size_t idx[64], running = 0, next = 0, done = 0, todo = 0, failed = 0;
    if (jobs > 64) jobs = 64;
    for (size_t i = 0; i < n; i++)
        todo += !items[i].skipped;
    while (done < todo) {
        while (running < jobs && next < n) {
            batch_item_t *it = &items[next++];
            if (it->skipped) continue;
            if ((pid[running] = spawn(dir, it, &fd[running])) < 0) {
                done++, failed++;
                continue;
            }
            idx[running++] = (size_t)(it - items);
        }
        if (!running) break;
        int status;
        pid_t w = waitpid(-1, &status, 0);
        if (w < 0) {
            if (errno == EINTR) continue;
            break;
        }
        for (size_t k = 0; k < running; k++) {
            if (pid[k] != w) continue;
            collect(&items[idx[k]], fd[k], status);
            failed += !items[idx[k]].ok;
            pid[k] = pid[running - 1], fd[k] = fd[running - 1], idx[k] = idx[running - 1];
            running--, done++;
            break;
        }
        char label[64];
        snprintf(label, sizeof label, "batch %zu/%zu%s", done, todo, failed ? " (failed)" : "");
        cli_progress(label, (double)done / (double)todo);
    }
    cli_progress_done();
}

/* The tab-separated fields of it (BATCH_FIELDS, those its folder holds)
 * into f[BATCH_NF], "" where none (a folder written before a field was
 * added holds fewer); a copy the caller frees (NULL: out of memory). */
static char *split(const batch_item_t *it, const char *f[BATCH_NF]) {
    const char *from = it->fields ? it->fields : "";
    char *buf = malloc(strlen(from) + 1), *p = buf;
    if (!buf) return NULL;
    strcpy(buf, from);
    for (int k = 0; k < BATCH_NF; k++) {
        f[k] = p;
        p += strcspn(p, "\t");
        if (*p) *p++ = 0;
    }
    return buf;
}

/* The message of a failed item, and what its folder still holds. */
static void item_message(const batch_item_t *it, char *buf, size_t size) {
    snprintf(buf, size, "%s%s", it->msg, it->other ? " (its folder keeps an earlier set of other settings)" : "");
}

/* A CSV field: quoted when it holds a comma, quote or newline. */
static void csv_field(FILE *fp, const char *s, const char *sep) {
    if (strpbrk(s, ",\"\n")) {
        fputc('"', fp);
        for (; *s; s++)
            fprintf(fp, *s == '"' ? "\"\"" : "%c", *s);
        fputc('"', fp);
    } else {
        fputs(s, fp);
    }
    fputs(sep, fp);
}

static void row_csv(FILE *fp, json_t *j, const batch_item_t *it, const char *const f[BATCH_NF], const char *msg) {
    (void)j;
    csv_field(fp, it->name, ",");
    csv_field(fp, it->source, ",");
    for (int k = 0; k < BATCH_NF; k++)
        csv_field(fp, f[k], ",");
    csv_field(fp, it->ok ? "ok" : "error", ",");
    csv_field(fp, it->ok ? "" : msg, "\n");
}

static void row_json(FILE *fp, json_t *j, const batch_item_t *it, const char *const f[BATCH_NF], const char *msg) {
    static const char *const names[BATCH_NF] = {"param",   "form",    "weighted", "terms", "headline", "comparable",
                                                "rel_rms", "max_abs", "negative", "bytes", "time_s"};
    (void)fp;
    json_begin_object(j, NULL);
    json_string(j, "name", it->name);
    json_string(j, "source", it->source);
    json_bool(j, "ok", it->ok);
    if (it->fields) { /* the set its folder holds */
        json_string(j, names[0], f[0]);
        json_string(j, names[1], f[1]);
        if (f[2][0]) json_bool(j, names[2], strcmp(f[2], "1") == 0);
        for (int k = 3; k < BATCH_NF; k++)
            json_number(j, names[k], strtod(f[k], NULL));
    }
    if (!it->ok) json_string(j, "message", msg);
    json_end_object(j);
}

/* summary.csv (json 0) or summary.json at path, written whole then renamed
 * into place; 0 or an errno. */
static int write_summary(const char *path, const batch_item_t *items, size_t n, int json) {
    char tmp[4200], msg[600];
    const char *f[BATCH_NF];
    FILE *fp = cli_open_tmp(path, tmp, sizeof tmp);
    if (!fp) return errno ? errno : EIO;
    json_t j = {fp, 0, {0}};
    if (json) {
        json_begin_object(&j, NULL);
        json_begin_array(&j, "materials");
    } else {
        fprintf(fp, "name,source," BATCH_FIELDS ",status,message\n");
    }
    int e = 0;
    for (size_t i = 0; i < n && !e; i++) {
        char *buf = split(&items[i], f);
        if (!buf) {
            e = ENOMEM;
            break;
        }
        item_message(&items[i], msg, sizeof msg);
        (json ? row_json : row_csv)(fp, &j, &items[i], f, msg);
        free(buf);
    }
    if (json) {
        json_end_array(&j);
        json_end_object(&j);
        fputc('\n', fp);
    }
    int c = cli_commit(fp, tmp, path, !e);
    return e ? e : c;
}

static const char *const summary_files[2] = {"summary.csv", "summary.json"};

int batch_summary_remove(const char *dir) {
    for (int k = 0; k < 2; k++) {
        char path[4200];
        snprintf(path, sizeof path, "%s/%s", dir, summary_files[k]);
        if (unlink(path) != 0 && errno != ENOENT) {
            cli_error("batch", "%s: cannot remove the summary of the last run: %s", path, sb_io_why(errno));
            return EXIT_IO;
        }
    }
    return EXIT_OK;
}

int batch_summary(const char *dir, const batch_item_t *items, size_t n) {
    for (int k = 0; k < 2; k++) {
        char path[4200];
        snprintf(path, sizeof path, "%s/%s", dir, summary_files[k]);
        int e = write_summary(path, items, n, k);
        if (e) {
            cli_error("batch", "%s: cannot write: %s", path, sb_io_why(e));
            return EXIT_IO;
        }
    }
    return EXIT_OK;
}

static int by_headline(const void *a, const void *b) {
    const batch_item_t *x = *(const batch_item_t *const *)a, *y = *(const batch_item_t *const *)b;
    if (x->ok != y->ok) return y->ok - x->ok;
    double hx = isnan(x->headline) ? INFINITY : x->headline, hy = isnan(y->headline) ? INFINITY : y->headline;
    return (hx > hy) - (hx < hy);
}

/* A layout's spec as the table shows it: a warp's list of
 * texel bounds (warp_h=0.0021/0.0050/..., 1500 characters on hd; what
 * --warp adaptive builds) as
 * "table" (report.json warp kind); summary.csv and report.json keep
 * the whole spec. */
static void spec_short(const char *spec, char *buf, size_t size) {
    size_t n = 0;
    buf[0] = 0;
    while (*spec && n + 1 < size) {
        size_t len = strcspn(spec, ","), key = strcspn(spec, "=");
        int list = key < len && memchr(spec + key, '/', len - key) != NULL;
        n += (size_t)snprintf(buf + n, size - n, "%.*s%s", (int)(list ? key + 1 : len), spec, list ? "table" : "");
        spec += len;
        if (*spec == ',' && n + 1 < size) buf[n++] = *spec++, buf[n] = 0;
        if (n >= size) n = size - 1;
    }
}

void batch_table(const batch_item_t *items, size_t n) {
    const batch_item_t **order = malloc(n * sizeof *order);
    if (!order) return;
    for (size_t i = 0; i < n; i++)
        order[i] = &items[i];
    qsort(order, n, sizeof *order, by_headline);
    printf("%4s  %-32s %-20s %-4s %4s  %12s  %12s  %10s  %8s\n", "rank", "material", "param", "form", "J", "headline",
           "rel_rms", "bytes", "time_s");
    for (size_t i = 0; i < n; i++) {
        const char *f[BATCH_NF];
        char *buf = split(order[i], f), spec[256];
        if (buf) spec_short(f[0], spec, sizeof spec);
        if (buf && order[i]->ok)
            printf("%4zu  %-32s %-20s %-4s %4s  %12.4e  %12.4e  %10s  %8s%s\n", i + 1, order[i]->name, spec, f[1], f[3],
                   strtod(f[4], NULL), strtod(f[6], NULL), f[9], f[10], order[i]->skipped ? "  (reused)" : "");
        else
            printf("%4s  %-32s failed: %s\n", "-", order[i]->name, order[i]->msg);
        free(buf);
    }
    free(order);
}
