/* A small job on one thread (src/util/parallel.h: SB_SMALL_JOB_CELLS): the
 * thread cap's rule and scope, and a job's source evaluated on the calling
 * thread alone where its cells (candidates x R^3) are few, on the pool's
 * threads as well where they are many, with the same factors either way. */
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "../src/util/internal.h"
#include "../src/util/parallel.h"
#include "harness.h"
#include "sepbrdf/factor.h"
#include "sepbrdf/job.h"
#include "sepbrdf/source.h"

static void *count_on_thread(void *arg) {
    *(int *)arg = sb_thread_count(0);
    return NULL;
}

SB_TEST(cap_rule_and_scope) {
    unsetenv("SEPBRDF_THREADS");
    int all = sb_thread_count(0), other = -1;
    CHECK(sb_small_job_threads(0) == 1);
    CHECK(sb_small_job_threads(SB_SMALL_JOB_CELLS - 1) == 1);
    CHECK(sb_small_job_threads(SB_SMALL_JOB_CELLS) == 0);
    CHECK(sb_small_job_threads(2 * (size_t)256 * 256 * 256) == 0); /* io -r 256: two forms */
    CHECK(sb_small_job_threads(2 * (size_t)64 * 64 * 64) == 1);    /* io -r 64 */
    CHECK(sb_thread_cap(1) == 0);
    CHECK(sb_thread_count(0) == 1);
    CHECK(sb_thread_count(3) == (3 < SB_THREADS_MAX ? 3 : SB_THREADS_MAX)); /* asked for: not capped */
    setenv("SEPBRDF_THREADS", "2", 1);
    CHECK(sb_thread_count(0) == 2); /* the user's setting wins */
    unsetenv("SEPBRDF_THREADS");
    pthread_t th; /* another thread (a job beside this one) keeps its count */
    CHECK(pthread_create(&th, NULL, count_on_thread, &other) == 0 && pthread_join(th, NULL) == 0);
    CHECK(other == all);
    CHECK(sb_thread_cap(0) == 1);
    CHECK(sb_thread_count(0) == all);
}

/* The default model, evaluated through a source that counts the calls made
 * on threads other than the job's. */
typedef struct {
    sb_source_t *inner;
    pthread_t caller;
    atomic_long elsewhere, calls;
} counting_t;

static int counting_eval(const void *self, const double wi[3], const double wo[3], double rgb[3]) {
    counting_t *c = (counting_t *)self;
    atomic_fetch_add(&c->calls, 1);
    if (!pthread_equal(pthread_self(), c->caller)) atomic_fetch_add(&c->elsewhere, 1);
    return sb_source_eval(c->inner, wi, wo, rgb);
}

/* io at R, J = 4, on the counting source: the job (NULL on failure) and
 * the source's calls off the calling thread. */
static sb_job_t *io_job(counting_t *c, sb_source_t *src, size_t R) {
    atomic_store(&c->elsewhere, 0);
    atomic_store(&c->calls, 0);
    c->caller = pthread_self();
    sb_job_opts_t o = {0};
    o.param = "io";
    o.res = R;
    o.terms = 4;
    sb_job_t *job = NULL;
    CHECK(sb_job_run_source(NULL, src, &o, &job) == SB_OK);
    return job;
}

static int same_factors(const sb_job_t *a, const sb_job_t *b) {
    const sb_factors_t *fa = sb_job_factors(a), *fb = sb_job_factors(b);
    if (!fa || !fb || sb_factors_terms(fa) != sb_factors_terms(fb) ||
        sb_factors_channels(fa) != sb_factors_channels(fb))
        return 0;
    for (int s = 0; s < 2; s++) {
        size_t w, h, w2, h2;
        sb_factors_size(fa, s, &w, &h);
        sb_factors_size(fb, s, &w2, &h2);
        if (w != w2 || h != h2) return 0;
        for (size_t j = 0; j < sb_factors_terms(fa); j++)
            for (size_t ch = 0; ch < sb_factors_channels(fa); ch++)
                if (memcmp(sb_factors_tex_const(fa, s, j, ch), sb_factors_tex_const(fb, s, j, ch),
                           w * h * sizeof(double)))
                    return 0;
    }
    return 1;
}

SB_TEST(small_job_on_the_calling_thread) {
    unsetenv("SEPBRDF_THREADS");
    if (sb_thread_count(0) < 2) SKIP("one core: every job runs on one thread");
    static const sb_source_ops_t ops = {counting_eval, NULL};
    counting_t c = {0};
    sb_source_t *src = NULL;
    CHECK(sb_source_open(NULL, SB_JOB_DEFAULT_SOURCE, &c.inner) == SB_OK);
    CHECK(c.inner && sb_source_create(NULL, &ops, &c, sb_source_flags(c.inner), "counting", &src) == SB_OK);
    if (!src) return;
    /* io -r 64: 2 x 64^3 cells, below SB_SMALL_JOB_CELLS */
    sb_job_t *one = io_job(&c, src, 64);
    long calls = atomic_load(&c.calls), off = atomic_load(&c.elsewhere);
    CHECKF(calls > 0 && off == 0, "R = 64: %ld of %ld calls off the job's thread", off, calls);
    setenv("SEPBRDF_THREADS", "2", 1); /* the user's count wins: the same job on two threads */
    sb_job_t *two = io_job(&c, src, 64);
    unsetenv("SEPBRDF_THREADS");
    off = atomic_load(&c.elsewhere);
    CHECKF(off > 0, "R = 64, SEPBRDF_THREADS=2: no call off the job's thread");
    CHECK(one && two && same_factors(one, two));
    CHECK(one && two &&
          memcmp(sb_job_estimate(one)->rel, sb_job_estimate(two)->rel, sizeof sb_job_estimate(one)->rel) == 0);
    /* io -r 128: 2 x 128^3 cells, the pool's threads too */
    sb_job_t *big = io_job(&c, src, 128);
    off = atomic_load(&c.elsewhere);
    CHECKF(big && off > 0, "R = 128: no call off the job's thread");
    sb_job_destroy(one);
    sb_job_destroy(two);
    sb_job_destroy(big);
    sb_source_destroy(src);
    sb_source_destroy(c.inner);
}
