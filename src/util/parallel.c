/* The parallel-for (parallel.h): fork/join over at most SB_THREADS_MAX
 * threads, the caller's included. */
#include "util/parallel.h"

#include <pthread.h>
#include <stdatomic.h>

#include "util/internal.h"

typedef struct run {
    void *(*fn)(void *);
    void *arg;
    atomic_int *left; /* jobs on other threads not yet finished */
} run_t;

static void *run_one(void *p) {
    run_t *r = p;
    r->fn(r->arg);
    atomic_fetch_sub(r->left, 1);
    return NULL;
}

void sb_parallel_run(void *(*fn)(void *), void *jobs, size_t job_size, int n, void (*idle)(void *), void *idle_arg) {
    if (n < 1) n = 1;
    if (n > SB_THREADS_MAX) n = SB_THREADS_MAX;
    pthread_t th[SB_THREADS_MAX];
    run_t runs[SB_THREADS_MAX];
    int started[SB_THREADS_MAX] = {0};
    atomic_int left;
    atomic_init(&left, n - 1);
    for (int t = 1; t < n; t++) {
        runs[t] = (run_t){fn, (char *)jobs + (size_t)t * job_size, &left};
        started[t] = pthread_create(&th[t], NULL, run_one, &runs[t]) == 0;
    }
    fn(jobs);
    for (int t = 1; t < n; t++)
        if (!started[t]) run_one(&runs[t]); /* no thread: do it here */
    while (idle && atomic_load(&left) > 0)
        idle(idle_arg);
    for (int t = 1; t < n; t++)
        if (started[t]) pthread_join(th[t], NULL);
}

void sb_part(size_t count, int t, int n, size_t *begin, size_t *end) {
    *begin = count * (size_t)t / (size_t)n;
    *end = count * (size_t)(t + 1) / (size_t)n;
}

int sb_threads_for(int requested, size_t units, size_t work, size_t min_work) {
    int nt = sb_thread_count(requested);
    if ((size_t)nt > units) nt = (int)units;
    if (work < min_work || nt < 1) nt = 1;
    return nt;
}
