/* CLI helpers: messages, option parsing, progress, JSON, atomic files,
 * cleanup on interruption. */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <signal.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stdint.h>
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
    case SB_ERR_UNSUPPORTED: /* a file variant or layout this build does not read */
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
    /* sizes beyond memory come from the resolution; an allocation that failed
     * from the resolution, the terms or the machine */
    const char *hint = r == SB_ERR_OVERFLOW ? " (lower --res)"
                       : r == SB_ERR_NOMEM  ? " (lower --res or --terms, or allow more memory)"
                                            : "";
    cli_error(cmd, "%s%s", detail && *detail ? detail : sb_result_message(r), hint);
    return cli_exit_code(r);
}

const char *cli_param_names(void) {
    static char names[256];
    if (!names[0]) sb_param_kind_list(names, sizeof names, ", ");
    return names;
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
                             *const n_gamut[] = {"--gamut", NULL}, *const n_lobe[] = {"--lobe", NULL};
    const char *v = NULL;
    int m;
    if ((m = cli_opt(a, n_interp, 1, &v))) {
        if (m < 0) return -1;
        if (sb_interp_parse(v, &mo->interp) != SB_OK) {
            cli_error(a->cmd, "--interp '%s' unknown, need one of nearest, linear, idw, quadratic", v);
            return -1;
        }
    } else if ((m = cli_opt(a, n_lobe, 1, &v))) {
        if (m < 0) return -1;
        if (sb_lobe_mode_parse(v, &mo->lobe) != SB_OK) {
            cli_error(a->cmd, "--lobe '%s' unknown, need auto, off or on", v);
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

int cli_check_outdir(const char *cmd, const char *opt, const char *path) {
    sb_context_t *ctx = NULL;
    if (sb_context_create(&ctx) != SB_OK) {
        cli_error(cmd, "out of memory");
        return EXIT_IO;
    }
    sb_result_t r = sb_outset_check(ctx, path);
    if (r != SB_OK) cli_error(cmd, "%s %s", opt, sb_context_last_error(ctx));
    sb_context_destroy(ctx);
    return cli_exit_code(r);
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

/* Remove PATH.tmp-PID files beside `path` whose process is gone (a run
 * killed while writing it); others' live temporaries stay. */
static void remove_stale_tmp(const char *path) {
    const char *slash = strrchr(path, '/'), *base = slash ? slash + 1 : path;
    char dir[4096], name[512];
    if (slash && (size_t)(slash - path) >= sizeof dir) return;
    snprintf(dir, sizeof dir, "%.*s", slash ? (int)(slash - path) + (slash == path) : 1, slash ? path : ".");
    int n = snprintf(name, sizeof name, "%s.tmp-", base);
    DIR *d = n > 0 && (size_t)n < sizeof name ? opendir(dir) : NULL;
    struct dirent *e;
    while (d && (e = readdir(d)) != NULL) {
        const char *pid = e->d_name + n;
        if (strncmp(e->d_name, name, (size_t)n) != 0 || !*pid || strspn(pid, "0123456789") != strlen(pid)) continue;
        long p = strtol(pid, NULL, 10);
        if (p > 0 && p != (long)getpid() && !sb_outset_pid_alive(p)) unlinkat(dirfd(d), e->d_name, 0);
    }
    if (d) closedir(d);
}

FILE *cli_open_tmp(const char *path, char *tmp, size_t tmp_size) {
    remove_stale_tmp(path);
    snprintf(tmp, tmp_size, "%s.tmp-%ld", path, (long)getpid());
    cli_guard(tmp); /* before it exists: a signal in between finds nothing */
    FILE *fp = fopen(tmp, "wb");
    if (!fp) cli_unguard(tmp);
    return fp;
}

int cli_commit(FILE *fp, const char *tmp, const char *path, int ok) {
    int e = ok ? 0 : ECANCELED;
    if (fp) {
        errno = 0;
        if ((fflush(fp) != 0 || ferror(fp)) && !e) e = errno ? errno : EIO;
        if (fclose(fp) != 0 && !e) e = errno ? errno : EIO;
    }
    if (!e && rename(tmp, path) != 0) e = errno;
    if (e) remove(tmp);
    cli_unguard(tmp);
    return e;
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

static char guard_set[GUARD_PATH]; /* staging folder of the open output set */
/* the name it is moved to before it is emptied: ".sepbrdf-new-CMD~gone-PID",
 * a staging name still (a run killed meanwhile leaves what the next run's
 * stale cleanup removes), whose manifest no command writes (removed whole) */
static char guard_doomed[GUARD_PATH + 8];
static atomic_int guard_set_on;
/* the output folder itself where this run created it: removed by the
 * handler if still empty (rmdir removes nothing else), as
 * sb_outset_destroy removes it on an error */
static char guard_created[GUARD_PATH];
static atomic_int guard_created_on;

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

static void on_signal(int sig) {
    int saved = errno;
    if (atomic_load(&guard_set_on)) {
        /* The writers share the set among threads: one may create a file
         * in the staging folder after the handler's last pass, and the
         * folder then outlives the process.  Moved first, the folder takes
         * no new entry (they open it by its old name), and is emptied. */
        if (guard_doomed[0] && rename(guard_set, guard_doomed) == 0)
            sb_outset_discard_signal_safe(guard_doomed);
        else
            sb_outset_discard_signal_safe(guard_set);
    }
    if (atomic_load(&guard_created_on)) rmdir(guard_created); /* only if empty */
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
    /* Past the file size limit write() then fails with EFBIG, and the
     * failing writer cleans up and reports, instead of a silent death. */
    signal(SIGXFSZ, SIG_IGN);
    for (size_t i = 0; i < sizeof sigs / sizeof sigs[0]; i++) {
        struct sigaction old, sa;
        if (sigaction(sigs[i], NULL, &old) != 0 || old.sa_handler == SIG_IGN) continue; /* nohup: keep ignoring */
        memset(&sa, 0, sizeof sa);
        sa.sa_handler = on_signal;
        sigfillset(&sa.sa_mask); /* one cleanup at a time */
        sigaction(sigs[i], &sa, NULL);
    }
}

/* ---- output sets --------------------------------------------------------- */

/* The staging folder the signal handler removes; with it, the output
 * folder where this run created it (user: the flag saying so).  Both are
 * known from before the staging folder exists: a signal that finds the
 * staging folder finds the folder guarded too. */
static void guard_staging(void *user, const char *staging) {
    const int *created = user;
    size_t n = strlen(staging);
    if (created && *created) atomic_store(&guard_created_on, 1);
    atomic_store(&guard_set_on, 0);
    if (n >= GUARD_PATH) return;
    memcpy(guard_set, staging, n + 1);
    const char *dash = strrchr(staging, '-'), *slash = strrchr(staging, '/');
    guard_doomed[0] = 0;
    if (dash && (!slash || dash > slash))
        snprintf(guard_doomed, sizeof guard_doomed, "%.*s~gone%s", (int)(dash - staging), staging, dash);
    atomic_store(&guard_set_on, 1);
}

sb_outset_t *cli_outset_begin(sb_context_t *ctx, const char *cmd, const char *dir, int *rc) {
    sb_outset_t *s = NULL;
    struct stat st;
    size_t n = strlen(dir);
    atomic_store(&guard_created_on, 0);
    int created = n < GUARD_PATH && stat(dir, &st) != 0 && errno == ENOENT;
    if (created) memcpy(guard_created, dir, n + 1);
    /* a factor set replaced makes the viewer page built from it stale */
    static const char *const factor_supersedes[] = {"view", NULL};
    sb_outset_opts_t so = {cmd, 0, guard_staging, &created, strcmp(cmd, "factor") == 0 ? factor_supersedes : NULL};
    sb_result_t r = sb_outset_begin(ctx, dir, &so, &s);
    if (r != SB_OK) {
        atomic_store(&guard_set_on, 0);
        atomic_store(&guard_created_on, 0);
        cli_error(cmd, "--out %s", sb_context_last_error(ctx));
        *rc = cli_exit_code(r);
        return NULL;
    }
    return s;
}

int cli_outset_end(sb_context_t *ctx, const char *cmd, sb_outset_t *s, int ok) {
    int rc = EXIT_OK;
    if (s && ok) {
        sb_result_t r = sb_outset_commit(s);
        if (r != SB_OK) rc = cli_fail(cmd, ctx, r);
    }
    sb_outset_destroy(s); /* discards a set not published */
    atomic_store(&guard_set_on, 0);
    atomic_store(&guard_created_on, 0);
    return rc;
}

int cli_set_file(sb_outset_t *s, const char *name, char *path, size_t size) {
    if (sb_outset_add(s, name) != SB_OK) return -1;
    int n = snprintf(path, size, "%s/%s", sb_outset_dir(s), name);
    return n < 0 || (size_t)n >= size ? -1 : 0;
}

/* "source_spec" of DIR/report.json (SOURCE as given to `factor`) into buf;
 * 0 on success.  The string is JSON-escaped by our writer: \" \\ \n \t. */
int cli_read_source_spec(const char *dir, char *buf, size_t size) {
    char path[4200];
    snprintf(path, sizeof path, "%s/report.json", dir);
    char *text = NULL;
    size_t n;
    if (cli_read_file(path, (size_t)1 << 26, &text, &n) != 0) return -1;
    const char *p = strstr(text, "\"source_spec\": \"");
    if (!p) {
        free(text);
        return -1;
    }
    p += strlen("\"source_spec\": \"");
    size_t k = 0;
    for (; *p && *p != '"' && k + 1 < size; p++) {
        if (*p == '\\' && p[1]) {
            p++;
            buf[k++] = *p == 'n' ? '\n' : *p == 't' ? '\t' : *p;
        } else {
            buf[k++] = *p;
        }
    }
    buf[k] = 0;
    int ok = *p == '"' && k > 0;
    free(text);
    return ok ? 0 : -1;
}

int cli_read_file(const char *path, size_t max, char **text, size_t *len) {
    *text = NULL;
    *len = 0;
    /* O_NONBLOCK: opening a FIFO with no writer does not wait */
    int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) return errno;
    struct stat st;
    int e = fstat(fd, &st) != 0 ? errno : !S_ISREG(st.st_mode) ? CLI_READ_NOT_FILE : 0;
    if (!e && (uintmax_t)st.st_size > (uintmax_t)max) e = CLI_READ_TOO_LARGE;
    char *buf = e ? NULL : malloc((size_t)st.st_size + 1);
    if (!e && !buf) e = ENOMEM;
    size_t n = 0;
    while (!e && n <= (size_t)st.st_size) { /* one byte past the size: a file that grew */
        ssize_t got = read(fd, buf + n, (size_t)st.st_size + 1 - n);
        if (got < 0 && errno == EINTR) continue;
        if (got < 0) e = errno;
        if (got <= 0) break;
        n += (size_t)got;
    }
    close(fd);
    if (!e && n > (size_t)st.st_size) e = EAGAIN; /* it changed while read */
    if (e) {
        free(buf);
        return e;
    }
    buf[n] = 0;
    *text = buf;
    *len = n;
    return 0;
}

const char *cli_read_why(int e) {
    if (e == CLI_READ_NOT_FILE) return "not a regular file (a device, FIFO or folder is not read)";
    if (e == CLI_READ_TOO_LARGE) return "too large for this kind of file";
    if (e == EAGAIN) return "it changed while it was read";
    return sb_io_why(e);
}
