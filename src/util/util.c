/* Allocation with limits, strings, thread counts, scaling. */
#define _DEFAULT_SOURCE /* madvise, MADV_HUGEPAGE */
#include <ctype.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include "util/internal.h"

char *sb_strdup(const char *s) {
    size_t n = strlen(s) + 1;
    char *d = malloc(n);
    if (d) memcpy(d, s, n);
    return d;
}

FILE *sb_fopen_regular(sb_context_t *ctx, const char *path, const char *what, unsigned long long max, sb_result_t *r) {
    int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC), e = fd < 0 ? errno : 0;
    struct stat st;
    if (!e && fstat(fd, &st) != 0) e = errno;
    FILE *fp = NULL;
    if (e) {
        *r = sb_error(ctx, SB_ERR_IO, "%s %s: cannot open: %s", what, path, strerror(e));
    } else if (!S_ISREG(st.st_mode)) {
        *r = sb_error(ctx, SB_ERR_IO, "%s %s: not a regular file (a device, FIFO or folder is not read)", what, path);
    } else if ((unsigned long long)st.st_size > max) {
        *r = sb_error(ctx, SB_ERR_FORMAT, "%s %s: %lld bytes, more than the %llu this kind of file may have", what,
                      path, (long long)st.st_size, max);
    } else if (fcntl(fd, F_SETFL, fcntl(fd, F_GETFL) & ~O_NONBLOCK) != 0 || !(fp = fdopen(fd, "rb"))) {
        *r = sb_error(ctx, SB_ERR_IO, "%s %s: cannot open: %s", what, path, strerror(errno));
    }
    if (!fp && fd >= 0) close(fd);
    return fp;
}

char *sb_format(const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(NULL, 0, fmt, ap);
    va_end(ap);
    char *s = n >= 0 ? malloc((size_t)n + 1) : NULL;
    if (!s) return NULL;
    va_start(ap, fmt);
    vsnprintf(s, (size_t)n + 1, fmt, ap);
    va_end(ap);
    return s;
}

static void *alloc_impl(sb_context_t *ctx, size_t count, size_t size, const char *what, int zero) {
    size_t bytes;
    if (sb_size_mul(count, size, &bytes)) {
        sb_error(ctx, SB_ERR_OVERFLOW, "%s: size %zu x %zu overflows", what, count, size);
        return NULL;
    }
    if (bytes > sb_memory_limit()) {
        sb_error(ctx, SB_ERR_OVERFLOW, "%s: needs %zu bytes, more than the memory limit of %zu bytes", what, bytes,
                 sb_memory_limit());
        return NULL;
    }
    void *p = zero ? calloc(count ? count : 1, size ? size : 1) : malloc(bytes ? bytes : 1);
    if (!p) sb_error(ctx, SB_ERR_NOMEM, "%s: cannot allocate %zu bytes", what, bytes);
    return p;
}

void *sb_alloc(sb_context_t *ctx, size_t count, size_t size, const char *what) {
    return alloc_impl(ctx, count, size, what, 0);
}
void *sb_calloc(sb_context_t *ctx, size_t count, size_t size, const char *what) {
    return alloc_impl(ctx, count, size, what, 1);
}

/* Up to what size glibc's malloc serves a block from a heap on transparent
 * huge pages, by the GLIBC_TUNABLES it started with (`tunables`, colon-
 * separated name=value): glibc.malloc.mmap_threshold where
 * glibc.malloc.hugetlb is 1, else 0.  The CLI's launcher sets hugetlb=1 and a
 * 32 MiB threshold (src/cli/env_plan.c). */
size_t sb_heap_huge_below(const char *tunables) {
    static const char hp[] = "glibc.malloc.hugetlb=", mt[] = "glibc.malloc.mmap_threshold=";
    int thp = 0;
    size_t below = 0;
    for (const char *t = tunables; t && *t; t += *t == ':') {
        size_t n = strcspn(t, ":");
        if (n >= sizeof hp && strncmp(t, hp, sizeof hp - 1) == 0) {
            thp = n == sizeof hp && t[n - 1] == '1';
        } else if (n >= sizeof mt && strncmp(t, mt, sizeof mt - 1) == 0 && isdigit((unsigned char)t[sizeof mt - 1])) {
            char *end;
            unsigned long long v = strtoull(t + sizeof mt - 1, &end, 0); /* glibc's bases: 0x, 0 and decimal */
            below = end == t + n && v <= SIZE_MAX ? (size_t)v : 0;
        }
        t += n;
    }
    return thp ? below : 0;
}

/* Read while the program starts: the CLI takes GLIBC_TUNABLES out of the
 * environment again once running (sb_cli_malloc_env_restore). */
static size_t heap_huge;
__attribute__((constructor)) static void heap_huge_read(void) {
    heap_huge = sb_heap_huge_below(getenv("GLIBC_TUNABLES"));
}

/* First touch of a 4 KiB page costs a fault; on the VMs measured a matrix
 * of 400 MiB took 0.6 s of faults, 2.5x less on 2 MiB pages.  With
 * transparent huge pages in "madvise" mode a buffer must ask for them:
 * align it to 2 MiB (posix_memalign, so free() releases it), round its
 * size up to whole huge pages and advise.  From 1 MiB on: a fault there
 * costs about 6 us (io -r 64 spent 630 of its 1050 faults on the 2 MiB
 * isotropic tables, which plain malloc put on 4 KiB pages), and zeroing a
 * whole huge page costs less than 256 of them; the rounding adds at most
 * 1 MiB a buffer.  Where malloc's heap is on huge pages itself (the CLI:
 * glibc.malloc.hugetlb=1) a buffer it serves from there needs none of
 * this, and the rounding and alignment only spread the job over more huge
 * pages, each zeroed by the kernel on first touch (io -r 64: 13 -> 9 huge
 * pages a run with the heap's start aligned too, src/cli/blas_env.c). */
void *sb_alloc_large(sb_context_t *ctx, size_t count, size_t size, const char *what) {
    const size_t huge = (size_t)2 << 20;
    size_t bytes;
    if (sb_size_mul(count, size, &bytes) || bytes < huge / 2 || bytes < heap_huge)
        return sb_alloc(ctx, count, size, what);
    if (bytes > sb_memory_limit()) return sb_alloc(ctx, count, size, what); /* reports the limit */
    size_t whole = (bytes + huge - 1) / huge * huge;
    void *p = NULL;
    if (posix_memalign(&p, huge, whole) != 0) {
        sb_error(ctx, SB_ERR_NOMEM, "%s: cannot allocate %zu bytes", what, bytes);
        return NULL;
    }
#ifdef MADV_HUGEPAGE
    madvise(p, whole, MADV_HUGEPAGE); /* advice: a refusal changes nothing */
#endif
    return p;
}

double sb_pow2_scale(double amax) {
    if (!(amax > 0) || !isfinite(amax)) return 1;
    int e;
    frexp(amax, &e);
    return ldexp(1, e > 1020 ? -1020 : (e < -1020 ? 1020 : -e));
}

int sb_write_atomic(const char *path, const void *const *parts, const size_t *sizes, size_t n) {
    char tmp[4200];
    int len = snprintf(tmp, sizeof tmp, "%s.tmp-%ld", path, (long)getpid());
    if (len < 0 || (size_t)len >= sizeof tmp) return ENAMETOOLONG;
    FILE *fp = fopen(tmp, "wb");
    if (!fp) return errno;
    int e = 0;
    errno = 0;
    for (size_t i = 0; i < n && !e; i++)
        if (fwrite(parts[i], 1, sizes[i], fp) != sizes[i]) e = errno ? errno : EIO;
    if (!e && fflush(fp) != 0) e = errno ? errno : EIO;
    if (fclose(fp) != 0 && !e) e = errno ? errno : EIO;
    if (!e && rename(tmp, path) != 0) e = errno;
    if (e) remove(tmp);
    return e;
}

int sb_name_find(const char *const *names, int n, const char *name) {
    for (int k = 0; name && k < n; k++)
        if (strcmp(name, names[k]) == 0) return k;
    return -1;
}
