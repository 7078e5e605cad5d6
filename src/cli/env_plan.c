/* The CLI's environment, decided before OpenBLAS and the C library start.
 *
 * OpenBLAS's thread count under a memory limit: OpenBLAS starts one worker
 * thread per core in its library constructor, and each worker at once
 * allocates a 128 MiB working buffer, retrying forever (100 % CPU) when that
 * fails; at exit the main thread joins the workers.  Under `ulimit -v` of a
 * few hundred MB this hung runs that had finished (or had already reported
 * "cannot allocate"), and at 60 MB the constructor failed before main
 * (`sepbrdf --version` exited 130).  When the limit does not hold every
 * worker's buffer plus room for the data, OPENBLAS_NUM_THREADS=1 is added,
 * and OpenBLAS then runs on the calling thread only (the library checks
 * that thread's buffer before its first BLAS call, sb_blas_reserve).
 *
 * OpenBLAS's idle workers spin (sched_yield) for 2^28 cycles, about 0.1 s,
 * after they start and after every threaded call before they sleep; that
 * took the second core from our own threads for the whole of a short run
 * (`factor --param io -r 64 -J 8`: 0.12 s wall, 0.09 s of it system time in
 * sched_yield; 0.10 s with 0.02 s).  OPENBLAS_THREAD_TIMEOUT=4 (2^4 cycles)
 * makes them sleep at once; a wake-up costs microseconds.  Set unless the
 * user set it.
 *
 * The C library's allocator: every page a run touches first is a page
 * fault, and on the 2-core AMD EPYC VM of docs/performance.md a fault costs
 * about 9 us (io -r 64: 9 100 faults, 0.09 s of system time in a 0.165 s
 * run).  sb_env_malloc_tunables asks glibc (2.35 and later) to back its heap
 * with transparent huge pages (hugetlb=1: madvise, used where the kernel's
 * THP mode is `madvise` or `always`), to serve blocks up to 32 MiB from that
 * heap instead of fresh mmap()s, and to keep 32 MiB of freed heap before
 * returning it: io -r 64 0.165 -> 0.088 s (1 800 faults), io -r 256 5.5 ->
 * 2.6 s, the default 0.32 -> 0.26 s, at +5 MiB and +21 MiB peak.  One
 * arena (arena_max=1): a thread's own arena is a heap glibc does not put
 * on huge pages, and trims to the page what it frees, so the work of the
 * pool's threads (a scattered table's cross-validation refits, each
 * reading its table, memo and matrix) took its pages one 4 KiB fault at a
 * time, again for every refit: the Cornell acrylic's default run 4 800-5 300
 * faults, 470-500 with one arena (issue 32 item 5, docs/measured.md;
 * the threads allocate outside their loops, so they seldom wait on the
 * arena's lock).  Set unless the user set GLIBC_TUNABLES; sb_cli_malloc_env_restore() takes it out
 * again once running, so that programs the CLI starts (a browser, gnuplot,
 * mpirun) do not inherit it. */
#include "env_plan.h"

#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <unistd.h>

/* per OpenBLAS thread: buffer 128 MiB + its page, and the thread's stack */
#define BLAS_THREAD_BYTES ((unsigned long long)136 << 20)
/* room for the program, its libraries and a small factorisation */
#define BLAS_BASE_BYTES ((unsigned long long)512 << 20)

const char sb_env_malloc_tunables[] =
    "glibc.malloc.hugetlb=1:glibc.malloc.mmap_threshold=33554432:glibc.malloc.trim_threshold=33554432:"
    "glibc.malloc.arena_max=1";

static unsigned long long limit_bytes(void) {
    unsigned long long lim = ~0ull;
    struct rlimit r;
    if (getrlimit(RLIMIT_AS, &r) == 0 && r.rlim_cur != RLIM_INFINITY) lim = r.rlim_cur;
    if (getrlimit(RLIMIT_DATA, &r) == 0 && r.rlim_cur != RLIM_INFINITY && r.rlim_cur < lim) lim = r.rlim_cur;
    return lim;
}

static int tight(char **envp) {
    unsigned long long lim = limit_bytes();
    if (lim == ~0ull) return 0;
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    for (char **e = envp; *e; e++)
        if (strncmp(*e, "OPENBLAS_NUM_THREADS=", 21) == 0) n = atol(*e + 21) > 0 ? atol(*e + 21) : n;
    if (n <= 1) return 0;
    return lim < BLAS_BASE_BYTES || (lim - BLAS_BASE_BYTES) / BLAS_THREAD_BYTES < (unsigned long long)n;
}

static int has(char **envp, const char *name) {
    for (char **e = envp; *e; e++)
        if (strncmp(*e, name, strlen(name)) == 0) return 1;
    return 0;
}

int sb_env_plan(char **envp, char **out) {
    static char one[] = "OPENBLAS_NUM_THREADS=1", timeout[] = "OPENBLAS_THREAD_TIMEOUT=4";
    static char tunables[sizeof "GLIBC_TUNABLES=" + sizeof sb_env_malloc_tunables];
    int one_thread = tight(envp), sleep_at_once = !has(envp, "OPENBLAS_THREAD_TIMEOUT="),
        tune = !has(envp, "GLIBC_TUNABLES=");
    size_t k = 0;
    for (char **e = envp; *e && k + 4 < SB_ENV_MAX; e++)
        if (!one_thread || strncmp(*e, "OPENBLAS_NUM_THREADS=", 21) != 0) out[k++] = *e;
    if (one_thread) out[k++] = one;
    if (sleep_at_once) out[k++] = timeout;
    if (tune) {
        strcpy(tunables, "GLIBC_TUNABLES=");
        strcat(tunables, sb_env_malloc_tunables);
        out[k++] = tunables;
    }
    out[k] = NULL;
    return one_thread || sleep_at_once || tune;
}
