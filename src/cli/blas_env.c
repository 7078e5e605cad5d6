/* The CLI's environment (env_plan.c) when the CLI is started directly,
 * not through the launcher (launch/launch.c), e.g. from the build tree or
 * as libexec/sepbrdf/sepbrdf-main.  A function in .preinit_array runs
 * before the constructors of the shared libraries (but before the C library
 * has set up `environ`, so setenv there is lost): when the environment
 * lacks what the CLI wants, it executes the program again with it.  That
 * second start costs about 10 ms on the 2-core VM (the libraries are mapped
 * and relocated twice), which is why `sepbrdf` is a launcher. */
#define _DEFAULT_SOURCE /* sbrk */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "env_plan.h"

/* A page of the stack below the caller's frame, zeroed. */
static __attribute__((noinline)) void stack_zero_below(void) {
    volatile char page[4096];
    for (size_t i = 0; i < sizeof page; i++)
        page[i] = 0;
}

/* The program break moved up to a 2 MiB boundary before malloc starts, so
 * that the heap begins on a huge page.  glibc (hugetlb=1) grows the heap to
 * 2 MiB boundaries and advises each growth of 2 MiB or more, but the break
 * starts at a random 4 KiB page: its first growth, up to 2 MiB from there,
 * was advised where it held no whole huge page, and the next one, shorter
 * than 2 MiB, not at all, so the first two 2 MiB stretches of the heap
 * stayed on 4 KiB pages.  io -r 64 faulted 340-700 of its 4 KiB pages
 * there (450-930 in all, 320-330 after this); the 2 MiB or less skipped
 * is address space, never touched. */
static void heap_start_aligned(void) {
    const uintptr_t huge = (uintptr_t)2 << 20;
    uintptr_t brk = (uintptr_t)sbrk(0);
    if (brk != (uintptr_t)-1 && brk % huge) sbrk((intptr_t)(huge - brk % huge)); /* a refusal changes nothing */
}

/* glibc's heap on transparent huge pages (glibc.malloc.hugetlb=1, set by
 * env_plan.c) is decided once, when malloc starts: glibc 2.36 (Debian 12)
 * reads /sys/kernel/mm/transparent_hugepage/enabled, 23 bytes, into a
 * 24-byte stack buffer that it compares with strcmp without terminating
 * it (later releases terminate it).  So the huge-page heap was on or off
 * by whatever byte the stack held there: on in sepbrdf-main as built, off
 * in the same program linked with OpenBLAS's static archive (io -r 64:
 * 3 000 page faults instead of 600; a heap on 4 KiB pages costs it 1.3-1.65x
 * the CPU, docs/performance.md).  Malloc is
 * started here, before any library's constructor, from a zeroed stack:
 * the buffer's last byte is then 0 and the mode is read as written. */
static void malloc_start_clean(void) {
    stack_zero_below();
    heap_start_aligned();
    void *volatile p = malloc(1); /* volatile: the pair is not optimised away */
    free(p);
}

static void env_for_blas(int argc, char **argv, char **envp) {
    static char *env[SB_ENV_MAX];
    (void)argc;
    if (envp && sb_env_plan(envp, env)) execve("/proc/self/exe", argv, env); /* returns only on failure */
    malloc_start_clean();
}

void sb_cli_malloc_env_restore(void) {
    const char *v = getenv("GLIBC_TUNABLES");
    if (v && strcmp(v, sb_env_malloc_tunables) == 0) unsetenv("GLIBC_TUNABLES");
}

__attribute__((used, section(".preinit_array"))) static void (*const sb_preinit_blas)(int, char **,
                                                                                      char **) = env_for_blas;
