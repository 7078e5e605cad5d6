/* CLI helpers: messages, option parsing, progress, JSON, atomic files. */
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "cli.h"

int g_verbosity = 1;
const char *g_prog = "sepbrdf";

void cli_error(const char *cmd, const char *fmt, ...) {
    va_list ap;
    cli_progress_done();
    fprintf(stderr, "%s%s%s: ", g_prog, cmd ? " " : "", cmd ? cmd : "");
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fputc('\n', stderr);
}

void cli_info(int level, const char *fmt, ...) {
    if (g_verbosity < level) return;
    va_list ap;
    cli_progress_done();
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fputc('\n', stderr);
}

int cli_exit_code(sb_result_t r) {
    switch (r) {
    case SB_OK: return EXIT_OK;
    case SB_ERR_IO:
    case SB_ERR_FORMAT:
    case SB_ERR_NOMEM: return EXIT_IO;
    case SB_ERR_NUMERIC: return EXIT_NUMERIC;
    default: return EXIT_USAGE;
    }
}

int cli_fail(const char *cmd, sb_context_t *ctx, sb_result_t r) {
    const char *detail = sb_context_last_error(ctx);
    cli_error(cmd, "%s", detail && *detail ? detail : sb_result_message(r));
    return cli_exit_code(r);
}

int cli_opt(cli_args_t *a, const char *const *names, int takes_value, const char **value) {
    const char *arg = a->argv[a->i];
    for (const char *const *n = names; *n; n++) {
        size_t len = strlen(*n);
        if (strncmp(arg, *n, len) != 0) continue;
        if (arg[len] == 0) {
            if (!takes_value) return 1;
            if (a->i + 1 >= a->argc) {
                cli_error(a->cmd, "option %s needs a value", *n);
                return -1;
            }
            a->i++;
            *value = a->argv[a->i];
            return 1;
        }
        if (arg[len] == '=' && takes_value && (*n)[1] == '-') {
            *value = arg + len + 1;
            return 1;
        }
    }
    return 0;
}

int cli_parse_size(const char *cmd, const char *opt, const char *s, size_t lo, size_t hi, size_t *out) {
    char *end;
    errno = 0;
    while (*s == ' ') s++;
    if (*s == '-' || *s == '+' || !*s) {
        long long v = strtoll(s, &end, 10);
        if (*s && *end == 0 && end != s)
            cli_error(cmd, "%s %s out of range, need an integer in %zu..%zu", opt, s, lo, hi);
        else
            cli_error(cmd, "%s '%s' is not an integer (need %zu..%zu)", opt, s, lo, hi);
        (void)v;
        return -1;
    }
    unsigned long long v = strtoull(s, &end, 10);
    if (end == s || *end || errno == ERANGE) {
        cli_error(cmd, "%s '%s' is not an integer (need %zu..%zu)", opt, s, lo, hi);
        return -1;
    }
    if (v < lo || v > hi) {
        cli_error(cmd, "%s %llu out of range, need an integer in %zu..%zu", opt, v, lo, hi);
        return -1;
    }
    *out = (size_t)v;
    return 0;
}

int cli_parse_double(const char *cmd, const char *opt, const char *s, double lo, double hi, double *out) {
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (end == s || *end || errno == ERANGE || !isfinite(v)) {
        cli_error(cmd, "%s '%s' is not a number (need %g..%g)", opt, s, lo, hi);
        return -1;
    }
    if (v < lo || v > hi) {
        cli_error(cmd, "%s %g out of range, need %g..%g", opt, v, lo, hi);
        return -1;
    }
    *out = v;
    return 0;
}

int cli_mkdirs(const char *path) {
    char buf[4096];
    size_t n = strlen(path);
    if (n == 0 || n >= sizeof buf) return -1;
    memcpy(buf, path, n + 1);
    for (size_t i = 1; i <= n; i++) {
        if (buf[i] == '/' || buf[i] == 0) {
            char c = buf[i];
            buf[i] = 0;
            if (mkdir(buf, 0777) != 0 && errno != EEXIST) return -1;
            buf[i] = c;
        }
    }
    struct stat st;
    return (stat(path, &st) == 0 && S_ISDIR(st.st_mode)) ? 0 : -1;
}

double cli_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

static double prog_last;
static int prog_shown;

void cli_progress(const char *label, double fraction) {
    if (g_verbosity < 1 || !isatty(2)) return;
    double t = cli_now();
    if (fraction < 1 && t - prog_last < 0.1) return;
    prog_last = t;
    int w = 30, fill = (int)(fraction * w + 0.5);
    if (fill > w) fill = w;
    fprintf(stderr, "\r%-24.24s [", label);
    for (int i = 0; i < w; i++) fputc(i < fill ? '#' : '.', stderr);
    fprintf(stderr, "] %3d%%", (int)(fraction * 100 + 0.5));
    fflush(stderr);
    prog_shown = 1;
}

void cli_progress_done(void) {
    if (!prog_shown) return;
    fprintf(stderr, "\r%*s\r", 64, "");
    prog_shown = 0;
}

/* ---- JSON -------------------------------------------------------------- */

static void json_escape(FILE *fp, const char *s) {
    fputc('"', fp);
    for (; *s; s++) {
        unsigned char c = (unsigned char)*s;
        if (c == '"' || c == '\\') fprintf(fp, "\\%c", c);
        else if (c == '\n') fputs("\\n", fp);
        else if (c == '\t') fputs("\\t", fp);
        else if (c < 0x20) fprintf(fp, "\\u%04x", c);
        else fputc(c, fp);
    }
    fputc('"', fp);
}

static void json_key(json_t *j, const char *key) {
    if (j->depth > 0) {
        if (!j->first[j->depth]) fputc(',', j->fp);
        fputc('\n', j->fp);
        for (int i = 0; i < j->depth; i++) fputs("  ", j->fp);
    }
    j->first[j->depth] = 0;
    if (key) {
        json_escape(j->fp, key);
        fputs(": ", j->fp);
    }
}

void json_begin_object(json_t *j, const char *key) {
    json_key(j, key);
    fputc('{', j->fp);
    j->depth++;
    j->first[j->depth] = 1;
}
void json_end_object(json_t *j) {
    j->depth--;
    fputc('\n', j->fp);
    for (int i = 0; i < j->depth; i++) fputs("  ", j->fp);
    fputc('}', j->fp);
    if (j->depth == 0) fputc('\n', j->fp);
}
void json_begin_array(json_t *j, const char *key) {
    json_key(j, key);
    fputc('[', j->fp);
    j->depth++;
    j->first[j->depth] = 1;
}
void json_end_array(json_t *j) {
    j->depth--;
    fputc('\n', j->fp);
    for (int i = 0; i < j->depth; i++) fputs("  ", j->fp);
    fputc(']', j->fp);
}
void json_string(json_t *j, const char *key, const char *value) {
    json_key(j, key);
    if (value) json_escape(j->fp, value);
    else fputs("null", j->fp);
}
void json_number(json_t *j, const char *key, double v) {
    json_key(j, key);
    if (isfinite(v)) fprintf(j->fp, "%.17g", v);
    else fputs("null", j->fp);
}
void json_int(json_t *j, const char *key, long long v) {
    json_key(j, key);
    fprintf(j->fp, "%lld", v);
}
void json_bool(json_t *j, const char *key, int v) {
    json_key(j, key);
    fputs(v ? "true" : "false", j->fp);
}

FILE *cli_open_tmp(const char *path, char *tmp, size_t tmp_size) {
    snprintf(tmp, tmp_size, "%s.tmp-%ld", path, (long)getpid());
    return fopen(tmp, "wb");
}

int cli_commit(FILE *fp, const char *tmp, const char *path, int ok) {
    if (fp) {
        if (fflush(fp) != 0 || ferror(fp)) ok = 0;
        if (fclose(fp) != 0) ok = 0;
    }
    if (ok && rename(tmp, path) == 0) return 0;
    remove(tmp);
    return -1;
}
