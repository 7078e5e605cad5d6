/* Result codes, the context and overflow-checked sizes. */
#include "sepbrdf/common.h"

#include "util/internal.h"

#include <stdarg.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

struct sb_context {
    sb_error_fn fn;
    void *user;
    char last[1024];
    const char *alias_from, *alias_to; /* sb_context_alias */
    sb_group_t group;                  /* sb_context_set_group; size 0: alone */
    void *memo;                        /* ctx_memo.c: open while a job runs */
    void (*memo_free)(void *);         /* frees it */
};

static const char *const names[SB_RESULT_COUNT_] = {
    "SB_OK",           "SB_ERR_ARG", "SB_ERR_RANGE",  "SB_ERR_PARSE",   "SB_ERR_UNKNOWN",     "SB_ERR_NOMEM",
    "SB_ERR_OVERFLOW", "SB_ERR_IO",  "SB_ERR_FORMAT", "SB_ERR_NUMERIC", "SB_ERR_UNSUPPORTED",
};
static const char *const messages[SB_RESULT_COUNT_] = {
    "success",       "invalid argument", "value out of range", "malformed input",      "unknown name",
    "out of memory", "size too large",   "input/output error", "invalid file content", "numerical failure",
    "not supported",
};

const char *sb_result_name(sb_result_t r) { return (unsigned)r < SB_RESULT_COUNT_ ? names[r] : "SB_ERR_?"; }
const char *sb_result_message(sb_result_t r) {
    return (unsigned)r < SB_RESULT_COUNT_ ? messages[r] : "unknown result code";
}

sb_result_t sb_context_create(sb_context_t **out) {
    if (!out) return SB_ERR_ARG;
    *out = calloc(1, sizeof **out);
    return *out ? SB_OK : SB_ERR_NOMEM;
}
void sb_context_destroy(sb_context_t *ctx) {
    if (ctx && ctx->memo && ctx->memo_free) ctx->memo_free(ctx->memo);
    free(ctx);
}
void **sb_context_memo_slot(sb_context_t *ctx, void (*memo_free)(void *)) {
    if (memo_free) ctx->memo_free = memo_free;
    return &ctx->memo;
}
void sb_context_set_error_callback(sb_context_t *ctx, sb_error_fn fn, void *user) {
    if (!ctx) return;
    ctx->fn = fn;
    ctx->user = user;
}
const char *sb_context_last_error(const sb_context_t *ctx) { return ctx ? ctx->last : ""; }
void sb_context_clear_error(sb_context_t *ctx) {
    if (ctx) ctx->last[0] = 0;
}

sb_result_t sb_context_set_group(sb_context_t *ctx, const sb_group_t *group) {
    if (!ctx) return SB_ERR_ARG;
    if (group && group->size > 1 && (group->rank < 0 || group->rank >= group->size || !group->reduce))
        return sb_error(ctx, SB_ERR_ARG, "group: rank %d of %d, or no reduce function", group->rank, group->size);
    memset(&ctx->group, 0, sizeof ctx->group);
    if (group && group->size > 1) ctx->group = *group;
    return SB_OK;
}

int sb_group_owns(const sb_context_t *ctx, size_t block) {
    return !ctx || ctx->group.size < 2 || block % (size_t)ctx->group.size == (size_t)ctx->group.rank;
}

int sb_group_active(const sb_context_t *ctx) { return ctx && ctx->group.size > 1; }

sb_result_t sb_group_reduce(sb_context_t *ctx, double *buf, size_t n, int op) {
    if (!sb_group_active(ctx) || n == 0) return SB_OK;
    if (ctx->group.reduce(ctx->group.user, buf, n, op) != 0)
        return sb_error(ctx, SB_ERR_IO, "group: combining %zu values over %d processes failed", n, ctx->group.size);
    return SB_OK;
}

void sb_context_alias(sb_context_t *ctx, const char *from, const char *to) {
    if (!ctx) return;
    ctx->alias_from = from && *from && to ? from : NULL;
    ctx->alias_to = to;
}

/* Every occurrence of alias_from in the message becomes alias_to. */
static void replace_alias(sb_context_t *ctx) {
    char out[sizeof ctx->last];
    size_t n = 0, lf = strlen(ctx->alias_from), lt = strlen(ctx->alias_to);
    const char *p = ctx->last, *hit;
    while ((hit = strstr(p, ctx->alias_from)) != NULL) {
        size_t pre = (size_t)(hit - p);
        if (n + pre + lt >= sizeof out) break;
        memcpy(out + n, p, pre);
        memcpy(out + n + pre, ctx->alias_to, lt);
        n += pre + lt;
        p = hit + lf;
    }
    snprintf(out + n, sizeof out - n, "%s", p);
    memcpy(ctx->last, out, sizeof out);
}

sb_result_t sb_error(sb_context_t *ctx, sb_result_t code, const char *fmt, ...) {
    if (!ctx) return code;
    ctx->last[0] = 0;
    if (fmt) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(ctx->last, sizeof ctx->last, fmt, ap);
        va_end(ap);
    }
    if (ctx->alias_from) replace_alias(ctx);
    if (ctx->fn) ctx->fn(ctx->user, code, ctx->last);
    return code;
}

int sb_size_mul(size_t a, size_t b, size_t *out) {
    if (!out || (a && b > SIZE_MAX / a)) return 1;
    *out = a * b;
    return 0;
}
int sb_size_mul3(size_t a, size_t b, size_t c, size_t *out) {
    size_t t;
    return !out || sb_size_mul(a, b, &t) || sb_size_mul(t, c, out);
}
int sb_size_add(size_t a, size_t b, size_t *out) {
    if (!out || b > SIZE_MAX - a) return 1;
    *out = a + b;
    return 0;
}

static size_t mem_limit;

/* Three quarters of the physical memory, asked once: sysconf(_SC_PHYS_PAGES)
 * is a sysinfo() system call, and every allocation checked against the
 * limit made one (126 of them in `factor --param io -r 64`). */
static size_t physical_limit(void) {
    static _Atomic size_t cached;
    size_t v = atomic_load_explicit(&cached, memory_order_relaxed);
    if (v) return v;
    long pages = sysconf(_SC_PHYS_PAGES), psize = sysconf(_SC_PAGE_SIZE);
    v = pages <= 0 || psize <= 0 ? (size_t)8 << 30 : (size_t)((double)pages * (double)psize * 0.75);
    atomic_store_explicit(&cached, v, memory_order_relaxed);
    return v;
}

void sb_set_memory_limit(size_t bytes) { mem_limit = bytes; }
size_t sb_memory_limit(void) { return mem_limit ? mem_limit : physical_limit(); }

const char *sb_version(void) { return SB_VERSION_STRING; }
unsigned sb_version_number(void) { return SB_VERSION_MAJOR * 10000u + SB_VERSION_MINOR * 100u + SB_VERSION_PATCH; }

sb_result_t sb_opts_take(sb_context_t *ctx, const void *in, size_t given, size_t size0, void *out, size_t size,
                         const char *what) {
    size_t n = given ? given : size0;
    if (n < sizeof(size_t) || n > size)
        return sb_error(ctx, SB_ERR_ARG, "%s of %zu bytes, this library (sepbrdf %s) takes %zu at most", what, given,
                        SB_VERSION_STRING, size);
    memset(out, 0, size);
    memcpy(out, in, n);
    return SB_OK;
}
