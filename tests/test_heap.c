/* The heap's huge pages (issue 36): the CLI's start aligns the heap to a
 * huge page (src/cli/blas_env.c, linked into this program, which therefore
 * starts as the CLI does: with its GLIBC_TUNABLES), and where malloc's heap
 * is on huge pages the library's large buffers come from it packed,
 * sharing huge pages, instead of each on 2 MiB pages of its own
 * (sb_alloc_large, src/util/util.c). */
#define _DEFAULT_SOURCE /* sbrk */
#include <malloc.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli/env_plan.h"
#include "harness.h"
#include "util/internal.h"

#define MIB ((size_t)1 << 20)

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define SB_OWN_MALLOC 0 /* the sanitizer's allocator, not glibc's heap */
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || __has_feature(memory_sanitizer)
#define SB_OWN_MALLOC 0
#else
#define SB_OWN_MALLOC 1
#endif
#else
#define SB_OWN_MALLOC 1
#endif

SB_TEST(tunables_read) {
    CHECK(sb_heap_huge_below(sb_env_malloc_tunables) == 32 * MIB); /* what the launcher sets */
    CHECK(sb_heap_huge_below(NULL) == 0);
    CHECK(sb_heap_huge_below("") == 0);
    CHECK(sb_heap_huge_below("glibc.malloc.mmap_threshold=33554432") == 0);                        /* 4 KiB heap */
    CHECK(sb_heap_huge_below("glibc.malloc.hugetlb=0:glibc.malloc.mmap_threshold=33554432") == 0); /* off */
    CHECK(sb_heap_huge_below("glibc.malloc.hugetlb=1") == 0); /* the dynamic threshold: 2 MiB may be an mmap */
    CHECK(sb_heap_huge_below("glibc.malloc.hugetlb=2:glibc.malloc.mmap_threshold=33554432") == 0); /* hugetlbfs */
    CHECK(sb_heap_huge_below("glibc.malloc.hugetlb=10:glibc.malloc.mmap_threshold=33554432") == 0);
    CHECK(sb_heap_huge_below("glibc.malloc.mmap_threshold=4096:glibc.malloc.hugetlb=1") == 4096); /* any order */
    CHECK(sb_heap_huge_below("glibc.malloc.hugetlb=1:glibc.malloc.mmap_threshold=0x100000") == MIB);
    CHECK(sb_heap_huge_below("glibc.malloc.hugetlb=1:glibc.malloc.mmap_threshold=1m") == 0); /* not a number */
    CHECK(sb_heap_huge_below("glibc.malloc.hugetlb=1:glibc.malloc.hugetlb=0:glibc.malloc.mmap_threshold=9") == 0);
    CHECK(sb_heap_huge_below("xglibc.malloc.hugetlb=1:glibc.malloc.mmap_threshold=9") == 0);
    CHECK(sb_heap_huge_below("glibc.malloc.hugetlb=1:glibc.malloc.mmap_threshold_x=9") == 0);
}

/* The size of glibc's main heap (malloc_info's heap 0, its current system
 * bytes); 0 where it cannot be read. */
static size_t main_heap_bytes(void) {
    char *buf = NULL;
    size_t len = 0, bytes = 0;
    FILE *fp = open_memstream(&buf, &len);
    if (!fp) return 0;
    int ok = malloc_info(0, fp) == 0;
    fclose(fp);
    const char *heap = ok && buf ? strstr(buf, "<heap nr=\"0\">") : NULL;
    const char *sys = heap ? strstr(heap, "<system type=\"current\" size=\"") : NULL;
    if (sys) bytes = strtoull(sys + strlen("<system type=\"current\" size=\""), NULL, 10);
    free(buf);
    return bytes;
}

/* The heap begins on a 2 MiB boundary, so all of it can be huge pages: at
 * a random start, its first two 2 MiB stretches stayed on 4 KiB pages
 * (hundreds of faults a run). */
SB_TEST(heap_starts_on_a_huge_page) {
    if (!SB_OWN_MALLOC) SKIP("a sanitizer's allocator");
    void *p = malloc(4096); /* the heap in use */
    size_t bytes = main_heap_bytes();
    uintptr_t top = (uintptr_t)sbrk(0);
    if (bytes == 0 || top == (uintptr_t)-1) SKIP("no main heap to read");
    uintptr_t start = top - bytes;
    CHECKF(start % (2 * MIB) == 0, "the heap starts at %#lx, %lu bytes past a 2 MiB boundary", (unsigned long)start,
           (unsigned long)(start % (2 * MIB)));
    CHECK((uintptr_t)p >= start && (uintptr_t)p < top);
    free(p);
}

/* With the CLI's tunables two buffers of 1.03 MiB (the circulant blocks at
 * R = 64) share huge pages: the second starts within 2 MiB of the first,
 * where 2 MiB-aligned buffers of their own each took a huge page and left
 * the rest of it to nothing the job allocated. */
SB_TEST(large_buffers_packed_on_a_huge_page_heap) {
    if (!SB_OWN_MALLOC) SKIP("a sanitizer's allocator");
    CHECK(sb_heap_huge_below(getenv("GLIBC_TUNABLES")) == 32 * MIB); /* started as the CLI starts */
    size_t n = 33 * 64 * 64;                                         /* doubles */
    double *a = sb_alloc_large(NULL, n, sizeof *a, "test"), *b = sb_alloc_large(NULL, n, sizeof *b, "test");
    CHECK(a && b);
    if (a && b) {
        memset(a, 1, n * sizeof *a);
        memset(b, 2, n * sizeof *b);
        uintptr_t lo = (uintptr_t)(a < b ? a : b), hi = (uintptr_t)(a < b ? b : a);
        CHECKF(hi - lo < 2 * MIB, "two %zu-byte buffers %lu bytes apart", n * sizeof *a, (unsigned long)(hi - lo));
        CHECK(((unsigned char *)a)[n * sizeof *a - 1] == 1 && ((unsigned char *)b)[0] == 2);
    }
    free(a);
    free(b);
}
