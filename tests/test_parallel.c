/* The library's parallel-for (src/util/parallel.h) on its persistent
 * workers: every job runs exactly once per call and has finished when the
 * call returns, across many consecutive calls, calls from inside a job,
 * calls from two threads at once and calls in a child of fork(); the idle
 * callback runs while other jobs are still at work. */
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "../src/util/internal.h"
#include "../src/util/parallel.h"
#include "harness.h"

#define NJOB 6

typedef struct job {
    atomic_int *runs; /* runs[t]: times job t ran */
    int t;
    int nested; /* run a parallel call of its own inside */
    long sleep_us;
    int done; /* set by the job: read by the caller after the call */
} job_t;

static void *count_job(void *arg);

static void nested_call(atomic_int *runs) {
    job_t in[NJOB];
    for (int t = 0; t < NJOB; t++)
        in[t] = (job_t){runs, t, 0, 0, 0};
    sb_parallel_run(count_job, in, sizeof in[0], NJOB, NULL, NULL);
    for (int t = 0; t < NJOB; t++)
        CHECKF(in[t].done == 1, "inner job %d not done on return", t);
}

static void *count_job(void *arg) {
    job_t *j = arg;
    if (j->sleep_us > 0) {
        struct timespec ts = {0, j->sleep_us * 1000};
        nanosleep(&ts, NULL);
    }
    if (j->nested) nested_call(j->runs + NJOB);
    atomic_fetch_add(&j->runs[j->t], 1);
    j->done = 1; /* plain write: visible to the caller once the call returns */
    return NULL;
}

/* `calls` calls of n jobs; every job ran once per call and was done on return. */
static int run_calls(atomic_int *runs, int calls, int n, int nested) {
    int bad = 0;
    for (int c = 0; c < calls; c++) {
        job_t jobs[NJOB];
        for (int t = 0; t < n; t++)
            jobs[t] = (job_t){runs, t, nested, 0, 0};
        sb_parallel_run(count_job, jobs, sizeof jobs[0], n, NULL, NULL);
        for (int t = 0; t < n; t++)
            bad += jobs[t].done != 1;
    }
    return bad;
}

SB_TEST(every_job_once_per_call) {
    atomic_int runs[2 * NJOB];
    for (int n = 1; n <= NJOB; n++) {
        for (int t = 0; t < 2 * NJOB; t++)
            atomic_init(&runs[t], 0);
        int bad = run_calls(runs, 400, n, 0);
        CHECKF(bad == 0, "n = %d: %d jobs not done when the call returned", n, bad);
        for (int t = 0; t < NJOB; t++)
            CHECKF(atomic_load(&runs[t]) == (t < n ? 400 : 0), "n = %d: job %d ran %d times", n, t,
                   atomic_load(&runs[t]));
    }
}

SB_TEST(calls_from_inside_a_job) {
    atomic_int runs[2 * NJOB];
    for (int t = 0; t < 2 * NJOB; t++)
        atomic_init(&runs[t], 0);
    CHECK(run_calls(runs, 200, 3, 1) == 0);
    for (int t = 0; t < 3; t++)
        CHECKF(atomic_load(&runs[t]) == 200, "outer job %d ran %d times", t, atomic_load(&runs[t]));
    for (int t = 0; t < NJOB; t++) /* 3 outer jobs, each one inner call of NJOB jobs */
        CHECKF(atomic_load(&runs[NJOB + t]) == 600, "inner job %d ran %d times", t, atomic_load(&runs[NJOB + t]));
}

/* A call from inside a job runs its jobs on the job's thread, one after
 * the other, and sees one thread (sb_thread_count): the outer call has the
 * cores. */
typedef struct where {
    pthread_t self, inner[NJOB];
    int nested, count;
} where_t;

static void *inner_where(void *arg) {
    where_t *w = arg;
    w->self = pthread_self();
    return NULL;
}

static void *outer_where(void *arg) {
    where_t *w = arg;
    w->self = pthread_self();
    w->nested = sb_parallel_nested();
    w->count = sb_thread_count(0);
    where_t in[NJOB];
    sb_parallel_run(inner_where, in, sizeof in[0], NJOB, NULL, NULL);
    for (int t = 0; t < NJOB; t++)
        w->inner[t] = in[t].self;
    return NULL;
}

SB_TEST(nested_call_runs_on_its_thread) {
    CHECK(!sb_parallel_nested());
    where_t w[3];
    sb_parallel_run(outer_where, w, sizeof w[0], 3, NULL, NULL);
    CHECK(!sb_parallel_nested());
    for (int t = 0; t < 3; t++) {
        CHECKF(w[t].nested == 1 && w[t].count == 1, "job %d: nested %d, threads %d", t, w[t].nested, w[t].count);
        for (int u = 0; u < NJOB; u++)
            CHECKF(pthread_equal(w[t].inner[u], w[t].self), "job %d: inner job %d ran on another thread", t, u);
    }
}

typedef struct caller {
    atomic_int runs[NJOB];
    int bad;
} caller_t;

static void *caller_thread(void *arg) {
    caller_t *c = arg;
    c->bad = run_calls(c->runs, 300, 2, 0);
    return NULL;
}

SB_TEST(calls_from_two_threads) {
    static caller_t c[2];
    pthread_t th[2];
    for (int k = 0; k < 2; k++) {
        for (int t = 0; t < NJOB; t++)
            atomic_init(&c[k].runs[t], 0);
        CHECK(pthread_create(&th[k], NULL, caller_thread, &c[k]) == 0);
    }
    for (int k = 0; k < 2; k++) {
        pthread_join(th[k], NULL);
        CHECKF(c[k].bad == 0, "caller %d: %d jobs not done on return", k, c[k].bad);
        for (int t = 0; t < 2; t++)
            CHECKF(atomic_load(&c[k].runs[t]) == 300, "caller %d job %d ran %d times", k, t,
                   atomic_load(&c[k].runs[t]));
    }
}

SB_TEST(call_in_a_forked_child) {
    atomic_int runs[2 * NJOB];
    for (int t = 0; t < 2 * NJOB; t++)
        atomic_init(&runs[t], 0);
    CHECK(run_calls(runs, 10, 4, 0) == 0); /* the parent's workers exist */
    pid_t pid = fork();
    CHECK(pid >= 0);
    if (pid == 0) {
        alarm(20); /* a child waiting for the parent's workers would hang here */
        for (int t = 0; t < 2 * NJOB; t++)
            atomic_store(&runs[t], 0);
        int bad = run_calls(runs, 100, 4, 0);
        for (int t = 0; t < 4; t++)
            bad += atomic_load(&runs[t]) != 100;
        _exit(bad == 0 ? 0 : 3);
    }
    int st = 0;
    CHECK(waitpid(pid, &st, 0) == pid);
    CHECKF(WIFEXITED(st) && WEXITSTATUS(st) == 0, "child: status %d", st);
    CHECK(run_calls(runs, 10, 4, 0) == 0); /* and the parent's still work */
}

static void idle_tick(void *arg) {
    atomic_fetch_add((atomic_int *)arg, 1);
    struct timespec ts = {0, 200000};
    nanosleep(&ts, NULL);
}

SB_TEST(idle_while_others_work) {
    atomic_int runs[2 * NJOB], ticks;
    atomic_init(&ticks, 0);
    for (int t = 0; t < 2 * NJOB; t++)
        atomic_init(&runs[t], 0);
    job_t jobs[2] = {{runs, 0, 0, 0, 0}, {runs, 1, 0, 30000, 0}}; /* job 1 sleeps 30 ms */
    sb_parallel_run(count_job, jobs, sizeof jobs[0], 2, idle_tick, &ticks);
    CHECK(jobs[0].done == 1 && jobs[1].done == 1);
    CHECKF(atomic_load(&ticks) >= 1, "idle called %d times", atomic_load(&ticks));
}
