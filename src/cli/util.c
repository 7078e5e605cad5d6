/* CLI helpers: messages, option parsing, progress, JSON, atomic files,
 * cleanup on interruption. */
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdarg.h>
#include <stdatomic.h>
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
    case SB_OK:
        return EXIT_OK;
    case SB_ERR_IO:
    case SB_ERR_FORMAT:
    case SB_ERR_NOMEM:
        return EXIT_IO;
    case SB_ERR_NUMERIC:
        return EXIT_NUMERIC;
    default:
        return EXIT_USAGE;
    }
}

int cli_fail(const char *cmd, sb_context_t *ctx, sb_result_t r) {
    const char *detail = sb_context_last_error(ctx);
    cli_error(cmd, "%s", detail && *detail ? detail : sb_result_message(r));
    return cli_exit_code(r);
}

int cli_verbosity_opt(const char *arg) {
    if (strcmp(arg, "-q") == 0 || strcmp(arg, "--quiet") == 0) {
        g_verbosity = 0;
        return 1;
    }
    if (strcmp(arg, "-v") == 0 || strcmp(arg, "--verbose") == 0) {
        g_verbosity++;
        return 1;
    }
    if (strcmp(arg, "-vv") == 0) {
        g_verbosity += 2;
        return 1;
    }
    return 0;
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

int cli_out_opt(cli_args_t *a, const char *what, const char **out) {
    static const char *const names[] = {"-o", "--out", NULL};
    const char *v = NULL;
    int m = cli_opt(a, names, 1, &v);
    if (m <= 0) return m;
    if (!*v) {
        cli_error(a->cmd, "--out: empty %s name", what);
        return -1;
    }
    *out = v;
    return 1;
}

int cli_measured_opt(cli_args_t *a, sb_measured_opts_t *mo) {
    static const char *const n_interp[] = {"--interp", NULL}, *const n_k[] = {"--neighbours", NULL},
                             *const n_rad[] = {"--radius", NULL}, *const n_white[] = {"--white", NULL},
                             *const n_gamut[] = {"--gamut", NULL};
    const char *v = NULL;
    int m;
    if ((m = cli_opt(a, n_interp, 1, &v))) {
        if (m < 0) return -1;
        if (sb_interp_parse(v, &mo->interp) != SB_OK) {
            cli_error(a->cmd, "--interp '%s' unknown, need one of nearest, linear, idw, quadratic", v);
            return -1;
        }
    } else if ((m = cli_opt(a, n_k, 1, &v))) {
        if (m < 0 || cli_parse_size(a->cmd, "--neighbours", v, 1, 64, &mo->neighbours)) return -1;
    } else if ((m = cli_opt(a, n_rad, 1, &v))) {
        double deg;
        if (m < 0 || cli_parse_double(a->cmd, "--radius", v, 1e-6, 360, &deg)) return -1;
        mo->radius = deg * SB_PI / 180;
    } else if ((m = cli_opt(a, n_white, 1, &v))) {
        if (m < 0) return -1;
        if (strcmp(v, "e") == 0)
            mo->white = SB_WHITE_E;
        else if (strcmp(v, "d65") == 0)
            mo->white = SB_WHITE_D65;
        else {
            cli_error(a->cmd, "--white '%s' unknown, need e or d65", v);
            return -1;
        }
    } else if ((m = cli_opt(a, n_gamut, 1, &v))) {
        if (m < 0) return -1;
        if (sb_gamut_parse(v, &mo->gamut) != SB_OK) {
            cli_error(a->cmd, "--gamut '%s' unknown, need keep, clip or desaturate", v);
            return -1;
        }
    } else {
        return 0;
    }
    return 1;
}

int cli_parse_size(const char *cmd, const char *opt, const char *s, size_t lo, size_t hi, size_t *out) {
    char *end;
    errno = 0;
    while (*s == ' ')
        s++;
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

/* Whether we can create entries in folder `dir`: try it (access() says
 * yes to root everywhere, even in /proc) with a probe folder removed at
 * once.  0 or an errno. */
static int probe_dir(const char *dir) {
    char probe[4200];
    snprintf(probe, sizeof probe, "%s/.sepbrdf-probe-%ld", dir, (long)getpid());
    if (mkdir(probe, 0700) != 0) return errno;
    rmdir(probe);
    return 0;
}

/* The nearest existing ancestor of a missing folder decides whether it can
 * be created: it must be a folder we can create entries in. */
int cli_check_outdir(const char *cmd, const char *opt, const char *path) {
    char buf[4096];
    struct stat st;
    size_t n = strlen(path);
    if (n == 0 || n >= sizeof buf) {
        cli_error(cmd, "%s '%s': bad folder name", opt, path);
        return EXIT_USAGE;
    }
    memcpy(buf, path, n + 1);
    while (n > 1 && buf[n - 1] == '/')
        buf[--n] = 0;
    int exists = stat(buf, &st) == 0;
    while (!exists) { /* walk up to the first component that exists */
        char *slash = strrchr(buf, '/');
        if (!slash)
            strcpy(buf, ".");
        else if (slash == buf)
            buf[1] = 0;
        else
            *slash = 0;
        if (stat(buf, &st) == 0) break;
        if (strcmp(buf, ".") == 0 || strcmp(buf, "/") == 0) {
            cli_error(cmd, "%s %s: cannot create the output folder", opt, path);
            return EXIT_IO;
        }
    }
    if (!S_ISDIR(st.st_mode)) {
        if (exists)
            cli_error(cmd, "%s %s: exists and is not a folder", opt, path);
        else
            cli_error(cmd, "%s %s: cannot create the output folder, %s is not a folder", opt, path, buf);
        return EXIT_IO;
    }
    int e = probe_dir(buf);
    if (e) {
        if (exists)
            cli_error(cmd, "%s %s: cannot write into the folder: %s", opt, path, strerror(e));
        else
            cli_error(cmd, "%s %s: cannot create the output folder in %s: %s", opt, path, buf, strerror(e));
        return EXIT_IO;
    }
    return EXIT_OK;
}

double cli_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

static double prog_last;
static volatile sig_atomic_t prog_shown; /* read by the signal handler */

void cli_progress(const char *label, double fraction) {
    static int tty = -1; /* stderr does not change: ask once */
    if (tty < 0) tty = isatty(2);
    if (g_verbosity < 1 || !tty) return;
    double t = cli_now();
    if (fraction < 1 && t - prog_last < 0.1) return;
    prog_last = t;
    int w = 30, fill = (int)(fraction * w + 0.5);
    if (fill > w) fill = w;
    fprintf(stderr, "\r%-24.24s [", label);
    for (int i = 0; i < w; i++)
        fputc(i < fill ? '#' : '.', stderr);
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
        if (c == '"' || c == '\\')
            fprintf(fp, "\\%c", c);
        else if (c == '\n')
            fputs("\\n", fp);
        else if (c == '\t')
            fputs("\\t", fp);
        else if (c < 0x20)
            fprintf(fp, "\\u%04x", c);
        else
            fputc(c, fp);
    }
    fputc('"', fp);
}

static void json_key(json_t *j, const char *key) {
    if (j->depth > 0) {
        if (!j->first[j->depth]) fputc(',', j->fp);
        fputc('\n', j->fp);
        for (int i = 0; i < j->depth; i++)
            fputs("  ", j->fp);
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
    for (int i = 0; i < j->depth; i++)
        fputs("  ", j->fp);
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
    for (int i = 0; i < j->depth; i++)
        fputs("  ", j->fp);
    fputc(']', j->fp);
}
void json_string(json_t *j, const char *key, const char *value) {
    json_key(j, key);
    if (value)
        json_escape(j->fp, value);
    else
        fputs("null", j->fp);
}
void json_number(json_t *j, const char *key, double v) {
    json_key(j, key);
    if (isfinite(v))
        fprintf(j->fp, "%.17g", v);
    else
        fputs("null", j->fp);
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
    cli_guard(tmp); /* before it exists: a signal in between finds nothing */
    FILE *fp = fopen(tmp, "wb");
    if (!fp) cli_unguard(tmp);
    return fp;
}

int cli_commit(FILE *fp, const char *tmp, const char *path, int ok) {
    if (fp) {
        if (fflush(fp) != 0 || ferror(fp)) ok = 0;
        if (fclose(fp) != 0) ok = 0;
    }
    int rc = 0;
    if (!(ok && rename(tmp, path) == 0)) {
        remove(tmp);
        rc = -1;
    }
    cli_unguard(tmp);
    return rc;
}

/* ---- cleanup on SIGINT, SIGTERM, SIGHUP ---------------------------------
 * The handler may run on any thread (LAPACK and the samplers start some)
 * at any point of the main thread's work, so the registry is a fixed table
 * written before it is published: a slot's path is complete before its
 * atomic flag says so, and a slot is reused only after its flag is
 * cleared.  The handler only reads flags, formats names into a stack
 * buffer and calls unlink(), which are async-signal-safe. */

#define GUARD_SLOTS 32
#define GUARD_PATH 4096

static char guard_path[GUARD_SLOTS][GUARD_PATH];
static atomic_int guard_used[GUARD_SLOTS];

static char guard_exr_dir[GUARD_PATH];
static atomic_size_t guard_exr_terms; /* 0 = no EXR set guarded */
static atomic_int guard_exr_finals;

int cli_guard(const char *path) {
    size_t n = strlen(path);
    if (n >= GUARD_PATH) return -1;
    for (int i = 0; i < GUARD_SLOTS; i++) {
        if (atomic_load(&guard_used[i])) continue;
        memcpy(guard_path[i], path, n + 1);
        atomic_store(&guard_used[i], 1);
        return 0;
    }
    return -1;
}

void cli_unguard(const char *path) {
    for (int i = 0; i < GUARD_SLOTS; i++)
        if (atomic_load(&guard_used[i]) && strcmp(guard_path[i], path) == 0) {
            atomic_store(&guard_used[i], 0);
            return;
        }
}

int cli_guard_exr(const char *dir, size_t terms, int finals) {
    size_t n = strlen(dir);
    if (n + 64 >= GUARD_PATH || terms == 0) return -1;
    atomic_store(&guard_exr_terms, 0);
    memcpy(guard_exr_dir, dir, n + 1);
    atomic_store(&guard_exr_finals, finals);
    atomic_store(&guard_exr_terms, terms);
    return 0;
}

void cli_unguard_exr(void) { atomic_store(&guard_exr_terms, 0); }

/* Append s to buf (capacity cap, length *n), always terminated. */
static void sig_cat(char *buf, size_t *n, size_t cap, const char *s) {
    while (*s && *n + 1 < cap)
        buf[(*n)++] = *s++;
    buf[*n] = 0;
}

/* Append v in decimal with at least `width` digits. */
static void sig_num(char *buf, size_t *n, size_t cap, unsigned long long v, int width) {
    char d[24];
    int k = 0;
    do {
        d[k++] = (char)('0' + v % 10);
        v /= 10;
    } while (v && k < 20);
    while (k < width && k < 20)
        d[k++] = '0';
    while (k > 0 && *n + 1 < cap)
        buf[(*n)++] = d[--k];
    buf[*n] = 0;
}

/* The names sb_factors_write_exr uses (exr.h): DIR/.g_KK.exr.tmp-PID and
 * DIR/g_KK.exr, the same for h; K is the 0-based term, two digits at least. */
static void sig_unlink_exr(void) {
    size_t terms = atomic_load(&guard_exr_terms);
    int finals = atomic_load(&guard_exr_finals);
    unsigned long long pid = (unsigned long long)getpid();
    char buf[GUARD_PATH + 64];
    for (size_t k = 0; k < terms; k++)
        for (int side = 0; side < 2; side++)
            for (int tmp = 0; tmp < 2; tmp++) {
                if (!tmp && !finals) continue;
                size_t n = 0;
                buf[0] = 0;
                sig_cat(buf, &n, sizeof buf, guard_exr_dir);
                sig_cat(buf, &n, sizeof buf, tmp ? "/." : "/");
                sig_cat(buf, &n, sizeof buf, side ? "h_" : "g_");
                sig_num(buf, &n, sizeof buf, k, 2);
                sig_cat(buf, &n, sizeof buf, ".exr");
                if (tmp) {
                    sig_cat(buf, &n, sizeof buf, ".tmp-");
                    sig_num(buf, &n, sizeof buf, pid, 1);
                }
                unlink(buf);
            }
}

static void on_signal(int sig) {
    int saved = errno;
    sig_unlink_exr();
    for (int i = 0; i < GUARD_SLOTS; i++)
        if (atomic_load(&guard_used[i])) unlink(guard_path[i]);
    if (prog_shown) {
        ssize_t w = write(2, "\n", 1);
        (void)w;
    }
    errno = saved;
    /* die of the same signal so the parent sees what happened */
    signal(sig, SIG_DFL);
    raise(sig);
}

void cli_signals_install(void) {
    static const int sigs[] = {SIGINT, SIGTERM, SIGHUP};
    for (size_t i = 0; i < sizeof sigs / sizeof sigs[0]; i++) {
        struct sigaction old, sa;
        if (sigaction(sigs[i], NULL, &old) != 0 || old.sa_handler == SIG_IGN) continue; /* nohup: keep ignoring */
        memset(&sa, 0, sizeof sa);
        sa.sa_handler = on_signal;
        sigfillset(&sa.sa_mask); /* one cleanup at a time */
        sigaction(sigs[i], &sa, NULL);
    }
}
