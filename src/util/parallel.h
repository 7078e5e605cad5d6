/* Private: the one parallel-for of the library.
 *
 * Work is cut into n jobs (n <= SB_THREADS_MAX, usually sb_thread_count()
 * capped by the amount of work); job 0 runs on the caller's thread, the
 * others on the library's persistent workers (started at the first call
 * that needs them, living for the process), or on threads started for the
 * call when another call holds the workers; a job with no thread runs on
 * the caller, so the result never depends on how many threads started.
 * Every job has finished when the call returns.  Jobs write only to their
 * own slots; callers add per-job partial results in job order, so sums
 * are the same bits on every run. */
#ifndef SEPBRDF_PARALLEL_H
#define SEPBRDF_PARALLEL_H

#include <stddef.h>

/* Run fn(jobs + t * job_size) for t = 0..n-1 in parallel (job_size 0: every
 * call gets `jobs` itself, for work shared through an atomic counter).
 * If idle is not NULL it is called on the caller's thread, after its own
 * job, until the other jobs are done (progress reports; it should sleep a
 * little).  n < 1 counts as 1. */
void sb_parallel_run(void *(*fn)(void *), void *jobs, size_t job_size, int n, void (*idle)(void *), void *idle_arg);

/* Whether this thread runs a job of a parallel call (sb_thread_count is
 * then 1, and a call runs its jobs on this thread in turn). */
int sb_parallel_nested(void);

/* Part t of n contiguous parts of [0, count): [*begin, *end). */
void sb_part(size_t count, int t, int n, size_t *begin, size_t *end);

/* Threads for `units` independent units of work: sb_thread_count(requested)
 * capped to the units (at least 1), and 1 when the work (in flops or
 * cells) is below `min_work`, where a thread costs more than it saves. */
int sb_threads_for(int requested, size_t units, size_t work, size_t min_work);

/* A small job on one thread.  On the 2-core VM of docs/performance.md a
 * second thread bought `factor --param io -r 64 -J 8` 9 % of its wall
 * time for 35 % more CPU at load 0.7 (47 short parallel calls), and
 * nothing in wall or CPU at loads 3-5.  The job's work is counted in
 * cells: its candidates' fits times R^3 (the distinct values of an
 * isotropic table at resolution R, as the floor program counts them,
 * bench/floor.c).  Below SB_SMALL_JOB_CELLS (io's two forms up to
 * R = 101; the default's five candidates at R = 32) the job runs on one
 * thread; above it every parallel region decides by its own work
 * (sb_threads_for). */
#define SB_SMALL_JOB_CELLS ((size_t)1 << 21)
/* The cap for a job of `cells` cells: 1 below SB_SMALL_JOB_CELLS, else 0
 * (no cap). */
int sb_small_job_threads(size_t cells);
/* Cap the count sb_thread_count gives this thread where neither its
 * caller (`requested`) nor SEPBRDF_THREADS names one (0: no cap); returns
 * the cap before, for the caller to put back.  Per thread: jobs run side
 * by side on other threads keep theirs. */
int sb_thread_cap(int cap);

#endif
