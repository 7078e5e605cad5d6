/* The parallel-for (parallel.h): fork/join over at most SB_THREADS_MAX
 * threads, the caller's included.
 *
 * The jobs beyond the caller's run on workers that live for the process:
 * starting a thread costs about 60 us on the 2-core VMs we measure on
 * (pthread_create + join), as much as a half-sweep of the default masked
 * fit, and every new thread that calls BLAS gets OpenBLAS's working buffer
 * afresh (first-touch page faults on every call of the thin products).  A
 * worker waits for the next call spinning for a while (consecutive calls
 * come microseconds apart), then sleeps on a condition variable.  Every
 * worker acknowledges every call, so the caller returns only when none of
 * them still reads the call's fields.  The caller, once done with its own
 * jobs, spins as briefly and then sleeps until the last worker wakes it:
 * it used to call sched_yield in a loop, and on a loaded machine, where a
 * worker waits for a core, those calls were CPU time of the caller's own
 * (SEPBRDF_THREADS=1 took 5 % less CPU than two threads on io -r 64).  The pool serves one call at a
 * time: a call made from another thread while it is busy starts threads
 * of its own; a call made from inside a job runs its jobs on that job's
 * thread, one after the other (sb_parallel_nested). */
#include "util/parallel.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>
#include <unistd.h>

#include "util/internal.h"

/* Set while this thread runs a job of a parallel call: a call made from
 * inside a job runs its jobs on that thread, one after the other (the
 * cores are busy with the outer call's jobs already). */
static _Thread_local int in_job;

int sb_parallel_nested(void) { return in_job; }

/* fn(arg) with in_job set. */
static void run_job(void *(*fn)(void *), void *arg) {
    int was = in_job;
    in_job = 1;
    fn(arg);
    in_job = was;
}

typedef struct run {
    void *(*fn)(void *);
    void *arg;
    atomic_int *left; /* jobs on other threads not yet finished */
} run_t;

static void *run_one(void *p) {
    run_t *r = p;
    run_job(r->fn, r->arg);
    atomic_fetch_sub(r->left, 1);
    return NULL;
}

/* A call on threads started for it (the pool is busy). */
static void run_started(void *(*fn)(void *), void *jobs, size_t job_size, int n, void (*idle)(void *), void *idle_arg) {
    pthread_t th[SB_THREADS_MAX];
    run_t runs[SB_THREADS_MAX];
    int started[SB_THREADS_MAX] = {0};
    atomic_int left;
    atomic_init(&left, n - 1);
    for (int t = 1; t < n; t++) {
        runs[t] = (run_t){fn, (char *)jobs + (size_t)t * job_size, &left};
        started[t] = pthread_create(&th[t], NULL, run_one, &runs[t]) == 0;
    }
    run_job(fn, jobs);
    for (int t = 1; t < n; t++)
        if (!started[t]) run_one(&runs[t]); /* no thread: do it here */
    while (idle && atomic_load(&left) > 0)
        idle(idle_arg);
    for (int t = 1; t < n; t++)
        if (started[t]) pthread_join(th[t], NULL);
}

/* ---- the pool ---------------------------------------------------------- */

#define SB_POOL_SPIN 300 /* pause loops a worker spins before it sleeps (a few us) */

static struct {
    pthread_mutex_t mu;
    pthread_cond_t wake;
    pthread_cond_t done; /* the caller sleeps on it for the last acknowledgement */
    int waiting;         /* the caller sleeps on `done` (under mu) */
    int workers;         /* started; worker w runs job w (1-based) */
    int sleepers;        /* workers waiting on `wake` (under mu) */
    atomic_uint gen;     /* bumped by every call, under mu */
    atomic_int left;     /* workers that have not yet acknowledged the call */
    void *(*fn)(void *);
    char *jobs;
    size_t job_size;
    int n;
} pool = {
    PTHREAD_MUTEX_INITIALIZER, PTHREAD_COND_INITIALIZER, PTHREAD_COND_INITIALIZER, 0, 0, 0, 0, 0, NULL, NULL, 0, 0};
static atomic_flag pool_busy = ATOMIC_FLAG_INIT;
static pthread_once_t pool_once = PTHREAD_ONCE_INIT;
static int pool_cores = 1; /* online cores, at the first call */
static struct {
    int index;
    unsigned gen;
} worker_arg[SB_THREADS_MAX];

static inline void relax(void) {
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#elif defined(__aarch64__)
    __asm__ __volatile__("yield");
#endif
}

static void *worker(void *arg) {
    int me = *(int *)arg;
    unsigned seen = worker_arg[me].gen;
    /* more threads than cores (SEPBRDF_THREADS above them): spinning would
     * take the cores from the jobs, so sleep at once */
    int spin = me < pool_cores ? SB_POOL_SPIN : 0;
    for (;;) {
        unsigned g;
        for (int spins = 0; (g = atomic_load_explicit(&pool.gen, memory_order_acquire)) == seen; spins++) {
            if (spins < spin) {
                relax();
                continue;
            }
            pthread_mutex_lock(&pool.mu);
            pool.sleepers++;
            while ((g = atomic_load_explicit(&pool.gen, memory_order_acquire)) == seen)
                pthread_cond_wait(&pool.wake, &pool.mu);
            pool.sleepers--;
            pthread_mutex_unlock(&pool.mu);
            break;
        }
        seen = g;
        if (me < pool.n) run_job(pool.fn, pool.jobs + (size_t)me * pool.job_size);
        if (atomic_fetch_sub_explicit(&pool.left, 1, memory_order_acq_rel) == 1) { /* the last: wake the caller */
            pthread_mutex_lock(&pool.mu);
            if (pool.waiting) pthread_cond_signal(&pool.done);
            pthread_mutex_unlock(&pool.mu);
        }
    }
    return NULL;
}

/* In a child of fork() only the forking thread exists: the pool starts
 * empty there. */
static void pool_after_fork(void) {
    pthread_mutex_t mu = PTHREAD_MUTEX_INITIALIZER;
    pthread_cond_t wake = PTHREAD_COND_INITIALIZER, done = PTHREAD_COND_INITIALIZER;
    pool.mu = mu;
    pool.wake = wake;
    pool.done = done;
    pool.workers = pool.sleepers = pool.waiting = 0;
    atomic_store(&pool.left, 0);
    atomic_flag_clear(&pool_busy);
}

static void pool_init(void) {
    long c = sysconf(_SC_NPROCESSORS_ONLN);
    pool_cores = c > 0 ? (int)c : 1;
    pthread_atfork(NULL, NULL, pool_after_fork);
}

/* Start workers up to `want` (the pool is held); returns how many run. */
static int pool_grow(int want) {
    while (pool.workers < want) {
        int w = pool.workers + 1;
        worker_arg[w].index = w;
        worker_arg[w].gen = atomic_load(&pool.gen);
        pthread_t th;
        pthread_attr_t at;
        if (pthread_attr_init(&at) != 0) break;
        int ok = pthread_attr_setdetachstate(&at, PTHREAD_CREATE_DETACHED) == 0 &&
                 pthread_create(&th, &at, worker, &worker_arg[w].index) == 0;
        pthread_attr_destroy(&at);
        if (!ok) break;
        pool.workers = w;
    }
    return pool.workers;
}

void sb_parallel_run(void *(*fn)(void *), void *jobs, size_t job_size, int n, void (*idle)(void *), void *idle_arg) {
    if (n < 1) n = 1;
    if (n > SB_THREADS_MAX) n = SB_THREADS_MAX;
    if (n == 1 || in_job) {
        for (int t = 0; t < n; t++) /* job_size 0: the first call takes all the shared work */
            fn((char *)jobs + (size_t)t * job_size);
        return;
    }
    pthread_once(&pool_once, pool_init);
    if (atomic_flag_test_and_set_explicit(&pool_busy, memory_order_acquire)) {
        run_started(fn, jobs, job_size, n, idle, idle_arg);
        return;
    }
    int workers = pool_grow(n - 1);
    pool.fn = fn;
    pool.jobs = jobs;
    pool.job_size = job_size;
    pool.n = n < workers + 1 ? n : workers + 1;
    atomic_store_explicit(&pool.left, workers, memory_order_relaxed);
    pthread_mutex_lock(&pool.mu);
    atomic_fetch_add_explicit(&pool.gen, 1, memory_order_release);
    if (pool.sleepers > 0) pthread_cond_broadcast(&pool.wake);
    pthread_mutex_unlock(&pool.mu);
    run_job(fn, jobs);
    for (int t = workers + 1; t < n; t++) /* no worker for it: done here */
        run_job(fn, (char *)jobs + (size_t)t * job_size);
    for (int spins = 0; atomic_load_explicit(&pool.left, memory_order_acquire) > 0; spins++) {
        if (idle) {
            idle(idle_arg);
        } else if (spins < SB_POOL_SPIN) {
            relax();
        } else { /* a long job: sleep until the last worker is done */
            pthread_mutex_lock(&pool.mu);
            pool.waiting = 1;
            while (atomic_load_explicit(&pool.left, memory_order_acquire) > 0)
                pthread_cond_wait(&pool.done, &pool.mu);
            pool.waiting = 0;
            pthread_mutex_unlock(&pool.mu);
        }
    }
    atomic_flag_clear_explicit(&pool_busy, memory_order_release);
}

/* The processors online, asked once: glibc reads sysfs on every call,
 * which cost 3 % of a scattered table's default run (one call per
 * parallel loop). */
static long cpus_online(void) {
    static _Atomic long online;
    long n = atomic_load_explicit(&online, memory_order_relaxed);
    if (n == 0) {
        n = sysconf(_SC_NPROCESSORS_ONLN);
        atomic_store_explicit(&online, n > 0 ? n : 1, memory_order_relaxed);
    }
    return n;
}

/* The cap of this thread's default count (sb_thread_cap; 0: none). */
static _Thread_local int thread_cap;

int sb_thread_cap(int cap) {
    int was = thread_cap;
    thread_cap = cap > 0 ? cap : 0;
    return was;
}

int sb_small_job_threads(size_t cells) { return cells < SB_SMALL_JOB_CELLS ? 1 : 0; }

int sb_thread_count(int requested) {
    if (in_job) return 1; /* the outer call has the cores */
    long n = requested;
    const char *e = getenv("SEPBRDF_THREADS");
    if (n <= 0 && e && atoi(e) > 0) n = atoi(e);
    if (n <= 0) n = thread_cap > 0 && thread_cap < cpus_online() ? thread_cap : cpus_online();
    return n > 0 ? (int)(n > SB_THREADS_MAX ? SB_THREADS_MAX : n) : 1;
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
