/* Measured tables: format detection, the source_open hook, coverage, and
 * the small text helpers the readers share. */
#include "sepbrdf/measured.h"

#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "source/measured_impl.h"
#include "util/internal.h"

static const char *const format_names[SB_TABLE_FORMAT_COUNT_] = {"auto", "merl", "cornell", "alta", "csv"};
static const char *const interp_names[SB_INTERP_COUNT_] = {"default", "nearest", "linear", "idw", "quadratic"};

const char *sb_table_format_name(sb_table_format_t f) {
    return (unsigned)f < SB_TABLE_FORMAT_COUNT_ ? format_names[f] : "?";
}
sb_result_t sb_table_format_parse(const char *name, sb_table_format_t *out) {
    if (!out) return SB_ERR_ARG;
    for (int k = 0; k < SB_TABLE_FORMAT_COUNT_; k++)
        if (name && strcmp(name, format_names[k]) == 0) {
            *out = (sb_table_format_t)k;
            return SB_OK;
        }
    return SB_ERR_UNKNOWN;
}
const char *sb_interp_name(sb_interp_t m) { return (unsigned)m < SB_INTERP_COUNT_ ? interp_names[m] : "?"; }
sb_result_t sb_interp_parse(const char *name, sb_interp_t *out) {
    if (!out) return SB_ERR_ARG;
    for (int k = 0; k < SB_INTERP_COUNT_; k++)
        if (name && strcmp(name, interp_names[k]) == 0) {
            *out = (sb_interp_t)k;
            return SB_OK;
        }
    return SB_ERR_UNKNOWN;
}

/* ---- text helpers ------------------------------------------------------ */

int sb_lines_next(sb_context_t *ctx, sb_lines_t *lr, char **out, sb_result_t *err) {
    size_t len = 0;
    int c = EOF;
    for (;;) {
        c = getc_unlocked(lr->fp);
        if (c == EOF || c == '\n') break;
        if (c == 0) {
            *err =
                sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: binary data (NUL byte) in a text table", lr->path, lr->line + 1);
            return -1;
        }
        if (len + 2 > lr->cap) {
            if (lr->cap >= SB_LINE_MAX) {
                *err = sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: line longer than %zu bytes", lr->path, lr->line + 1,
                                SB_LINE_MAX);
                return -1;
            }
            size_t cap = lr->cap ? 2 * lr->cap : 256;
            char *b = realloc(lr->buf, cap);
            if (!b) {
                *err = sb_error(ctx, SB_ERR_NOMEM, "%s: out of memory reading line %zu", lr->path, lr->line + 1);
                return -1;
            }
            lr->buf = b;
            lr->cap = cap;
        }
        lr->buf[len++] = (char)c;
    }
    if (ferror(lr->fp)) {
        *err = sb_error(ctx, SB_ERR_IO, "%s:%zu: read error: %s", lr->path, lr->line + 1, strerror(errno));
        return -1;
    }
    if (c == EOF && len == 0) return 0;
    if (!lr->buf) { /* empty line before any allocation */
        lr->buf = malloc(256);
        if (!lr->buf) {
            *err = sb_error(ctx, SB_ERR_NOMEM, "%s: out of memory", lr->path);
            return -1;
        }
        lr->cap = 256;
    }
    while (len && lr->buf[len - 1] == '\r')
        len--;
    lr->buf[len] = 0;
    lr->line++;
    *out = lr->buf;
    return 1;
}

char *sb_trim(char *s) {
    while (*s == ' ' || *s == '\t')
        s++;
    size_t n = strlen(s);
    while (n && (s[n - 1] == ' ' || s[n - 1] == '\t' || s[n - 1] == '\r'))
        s[--n] = 0;
    return s;
}

size_t sb_split_fields(char *s, char sep, char **fields, size_t max) {
    size_t n = 0;
    if (sep == 0) {
        char *p = s;
        for (;;) {
            while (*p == ' ' || *p == '\t')
                p++;
            if (!*p) break;
            if (n < max) fields[n] = p;
            n++;
            while (*p && *p != ' ' && *p != '\t')
                p++;
            if (*p) *p++ = 0;
        }
        return n;
    }
    char *p = s;
    for (;;) {
        char *e = strchr(p, sep);
        if (e) *e = 0;
        if (n < max) fields[n] = sb_trim(p);
        n++;
        if (!e) break;
        p = e + 1;
    }
    return n;
}

int sb_parse_number(const char *s, double *out) {
    char *end;
    errno = 0;
    if (!*s) return -1;
    double v = strtod(s, &end);
    if (end == s || *end) return -1;
    /* ERANGE: underflow gives a tiny or zero value (kept), overflow HUGE_VAL
     * (an infinity the caller rejects). */
    *out = v;
    return 0;
}

int sb_tmp_name(const char *path, char *buf, size_t size) {
    int n = snprintf(buf, size, "%s.tmp-%ld", path, (long)getpid());
    return (n < 0 || (size_t)n >= size) ? -1 : 0;
}

/* ---- format detection --------------------------------------------------- */

static int has_ext(const char *path, const char *ext) {
    size_t n = strlen(path), e = strlen(ext);
    if (n <= e) return 0;
    const char *p = path + n - e;
    for (size_t i = 0; i < e; i++)
        if ((p[i] | 0x20) != (ext[i] | 0x20)) return 0;
    return 1;
}

static int32_t le_i32(const unsigned char *b) {
    uint32_t u = (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
    return (int32_t)u;
}

/* A line of head[] (not NUL-terminated) starting with `prefix`. */
static int head_has_line(const char *head, size_t n, const char *prefix) {
    size_t m = strlen(prefix);
    for (size_t i = 0; i + m <= n; i++)
        if ((i == 0 || head[i - 1] == '\n') && memcmp(head + i, prefix, m) == 0) return 1;
    return 0;
}

/* Content first (a MERL header, the Cornell or ALTA keywords, a CSV header
 * naming theta_i), then the extension; 0 when nothing matches. */
static sb_table_format_t detect(const unsigned char *head, size_t n, const char *path) {
    if (n >= 12 && le_i32(head) == SB_MERL_TH && le_i32(head + 4) == SB_MERL_TD && le_i32(head + 8) == SB_MERL_PD)
        return SB_TABLE_MERL;
    const char *h = (const char *)head;
    size_t i = 0;
    while (i < n && (h[i] == ' ' || h[i] == '\t' || h[i] == '\r' || h[i] == '\n'))
        i++;
    if (n - i >= 9 && memcmp(h + i, "# num wls", 9) == 0) return SB_TABLE_CORNELL;
    if (head_has_line(h, n, "#PARAM_IN") || head_has_line(h, n, "#DIM")) return SB_TABLE_ALTA;
    if (has_ext(path, ".binary")) return SB_TABLE_MERL;
    if (has_ext(path, ".brdf")) return SB_TABLE_CORNELL;
    if (has_ext(path, ".alta")) return SB_TABLE_ALTA;
    if (has_ext(path, ".csv")) return SB_TABLE_CSV;
    for (size_t k = 0; k + 7 <= n; k++)
        if (memcmp(h + k, "theta_i", 7) == 0) return SB_TABLE_CSV;
    return SB_TABLE_AUTO;
}

sb_result_t sb_measured_open(sb_context_t *ctx, const char *path, const sb_measured_opts_t *opts, sb_source_t **out,
                             sb_measured_info_t *info) {
    if (!path || !out) return sb_error(ctx, SB_ERR_ARG, "measured: missing path or output");
    *out = NULL;
    sb_measured_opts_t o = {0};
    if (opts) o = *opts;
    if ((unsigned)o.format >= SB_TABLE_FORMAT_COUNT_)
        return sb_error(ctx, SB_ERR_ARG, "%s: unknown table format %d", path, (int)o.format);
    if ((unsigned)o.interp >= SB_INTERP_COUNT_)
        return sb_error(ctx, SB_ERR_ARG, "%s: unknown interpolation %d", path, (int)o.interp);
    if ((unsigned)o.white >= SB_WHITE_COUNT_)
        return sb_error(ctx, SB_ERR_ARG, "%s: unknown white %d", path, (int)o.white);
    if (o.neighbours > 64)
        return sb_error(ctx, SB_ERR_RANGE, "%s: %zu neighbours out of range, need 1..64", path, o.neighbours);
    if (isnan(o.radius)) return sb_error(ctx, SB_ERR_RANGE, "%s: radius is NaN", path);

    sb_table_format_t fmt = o.format;
    if (fmt == SB_TABLE_AUTO) {
        FILE *fp = fopen(path, "rb");
        if (!fp) return sb_error(ctx, SB_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
        unsigned char head[4096];
        size_t n = fread(head, 1, sizeof head, fp);
        int bad = ferror(fp);
        fclose(fp);
        if (bad) return sb_error(ctx, SB_ERR_IO, "%s: read error", path);
        if (n >= 11 && memcmp(head, "tensor_file", 11) == 0)
            return sb_error(ctx, SB_ERR_UNSUPPORTED,
                            "%s: Mitsuba/RGL tensor_file (.bsdf) tables are not supported; "
                            "use MERL .binary, Cornell .brdf, ALTA or sepbrdf CSV",
                            path);
        fmt = detect(head, n, path);
        if (fmt == SB_TABLE_AUTO)
            return sb_error(ctx, SB_ERR_FORMAT,
                            "%s: unrecognised measured table (%s); expected MERL .binary, Cornell .brdf "
                            "(\"# num wls\"), ALTA (\"#PARAM_IN\") or sepbrdf CSV (header with theta_i)",
                            path, n ? "unknown content" : "empty file");
    }
    sb_measured_info_t inf;
    memset(&inf, 0, sizeof inf);
    inf.format = fmt;
    sb_result_t r = fmt == SB_TABLE_MERL ? sb_merl_open_(ctx, path, &o, out, &inf)
                                         : sb_scattered_open_(ctx, path, fmt, &o, out, &inf);
    if (r == SB_OK && info) *info = inf;
    return r;
}

sb_result_t sb_measured_open_hook(sb_context_t *ctx, const char *path, sb_source_t **out) {
    return sb_measured_open(ctx, path, NULL, out, NULL);
}

/* ---- coverage ---------------------------------------------------------- */

typedef struct cov_job {
    const sb_source_t *src;
    const sb_param_t *param;
    size_t rows, c0, c1, known, cells;
} cov_job_t;

static void *cov_cols(void *arg) {
    cov_job_t *j = arg;
    double wi[3], wo[3], rgb[3];
    for (size_t c = j->c0; c < j->c1; c++)
        for (size_t r = 0; r < j->rows; r++) {
            if (!sb_param_cell_dirs(j->param, r, c, wi, wo) || wi[2] <= 0 || wo[2] <= 0) continue;
            j->cells++;
            if (sb_source_eval(j->src, wi, wo, rgb) && isfinite(rgb[0]) && isfinite(rgb[1]) && isfinite(rgb[2]))
                j->known++;
        }
    return NULL;
}

sb_result_t sb_measured_coverage(sb_context_t *ctx, const sb_source_t *src, const sb_param_t *param, size_t *known,
                                 size_t *cells) {
    if (!src || !param) return sb_error(ctx, SB_ERR_ARG, "coverage: missing source or parameterisation");
    size_t rows = sb_param_rows(param), cols = sb_param_cols(param), total;
    if (sb_size_mul(rows, cols, &total)) return sb_error(ctx, SB_ERR_OVERFLOW, "coverage: cell count overflows");
    int nt = sb_thread_count(0);
    if ((size_t)nt > cols) nt = (int)cols;
    if (nt < 1) nt = 1;
    cov_job_t *jobs = calloc((size_t)nt, sizeof *jobs);
    pthread_t *th = calloc((size_t)nt, sizeof *th);
    char *started = calloc((size_t)nt, 1);
    if (!jobs || !th || !started) {
        free(jobs);
        free(th);
        free(started);
        return sb_error(ctx, SB_ERR_NOMEM, "coverage: out of memory");
    }
    for (int t = 0; t < nt; t++) {
        jobs[t] =
            (cov_job_t){src, param, rows, cols * (size_t)t / (size_t)nt, cols * (size_t)(t + 1) / (size_t)nt, 0, 0};
        if (t > 0) started[t] = pthread_create(&th[t], NULL, cov_cols, &jobs[t]) == 0;
    }
    cov_cols(&jobs[0]);
    size_t k = 0, n = 0;
    for (int t = 0; t < nt; t++) {
        if (t > 0) {
            if (started[t])
                pthread_join(th[t], NULL);
            else
                cov_cols(&jobs[t]); /* no thread: do it here */
        }
        k += jobs[t].known;
        n += jobs[t].cells;
    }
    free(jobs);
    free(th);
    free(started);
    if (known) *known = k;
    if (cells) *cells = n;
    return SB_OK;
}
