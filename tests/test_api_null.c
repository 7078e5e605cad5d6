/* Misuse of the public API never crashes (issue 34): every function of the
 * public headers (include/sepbrdf), found by tests/api_null_gen.cmake at
 * build time (a function added to a header is called the day it is added),
 * is called in five passes: every argument zero (NULL pointers, 0 sizes,
 * enum 0); huge (SIZE_MAX, INT_MAX, 1e300, enums past their last value;
 * pointers NULL); negative or NaN; real handles (a context, source, layout,
 * factored job and its factors and matrix, scene, JSON writer) beside zero
 * numbers and NULL other pointers; real handles beside huge numbers.  Each
 * call runs in a child process under a time limit: a signal (SIGSEGV,
 * SIGABRT), a sanitizer's report (exit 1 under ASan/UBSan in CI) or a hang
 * names the function and the pass.
 *
 * The null_accessors case checks the documented safe values of the
 * accessors the issue names, so a "no crash" that returns garbage fails
 * too. */
#include <limits.h>
#include <math.h>
#include <signal.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "harness.h"
#include "sepbrdf/experimental/layout.h"
#include "sepbrdf/experimental/solver.h"
#include "sepbrdf/sepbrdf.h"
#include "util/shared.h" /* sizes, JSON: not exported, in the static archive */

/* An argument of type T for pass 0 (zero), 1 (huge) or 2 (negative, NaN);
 * pointers and structs are zero in every pass. */
#define SB_HUGE(T)                                                                                                     \
    _Generic((T){0}, size_t                                                                                            \
             : (size_t)SIZE_MAX, long                                                                                  \
             : LONG_MAX, int                                                                                           \
             : INT_MAX, unsigned                                                                                       \
             : UINT_MAX, long long                                                                                     \
             : LLONG_MAX, unsigned long long                                                                           \
             : ULLONG_MAX, double : 1e300, float : 1e30f, default                                                      \
             : (T){0})
#define SB_NEG(T)                                                                                                      \
    _Generic((T){0}, size_t                                                                                            \
             : (size_t)SIZE_MAX / 2 + 1, long                                                                          \
             : -1L, int                                                                                                \
             : -1, unsigned                                                                                            \
             : UINT_MAX / 2 + 1, long long                                                                             \
             : -1LL, unsigned long long                                                                                \
             : ULLONG_MAX / 2 + 1, double                                                                              \
             : NAN, float                                                                                              \
             : NAN, default                                                                                            \
             : (T){0})
/* Pass 3: valid handles (made once, before the children fork), every
 * other argument zero or NULL: a function given a real object and no
 * output must not crash either. */
static struct {
    sb_context_t *ctx;
    sb_source_t *src;
    sb_param_t *param;
    sb_job_t *job;
    sb_scene_t *scene;
    sb_json_t json;
} h;
#define SB_VALID(T)                                                                                                    \
    _Generic((T){0}, sb_context_t *: h.ctx, const sb_source_t *: h.src, const sb_param_t *: h.param,                  \
             const sb_job_t *: h.job, sb_job_t *: h.job, const sb_factors_t *: sb_job_factors(h.job),                 \
             const sb_matrix_t *: sb_job_matrix(h.job), const sb_scene_t *: h.scene, sb_json_t *: &h.json,            \
             FILE *: h.json.fp, default: (T){0})
/* Pass 4: valid handles and huge numbers (sizes, indices, counts out of
 * every range), other pointers NULL. */
#define SB_ARG(T, pass)                                                                                                \
    ((pass) == 0   ? (T){0}                                                                                            \
     : (pass) == 1 ? (T)SB_HUGE(T)                                                                                     \
     : (pass) == 2 ? (T)SB_NEG(T)                                                                                      \
     : (pass) == 3 ? (T)SB_VALID(T)                                                                                    \
                   : (T)(_Generic((T){0}, size_t : 1, long : 1, int : 1, unsigned : 1, long long : 1,                  \
                                  unsigned long long : 1, double : 1, float : 1, default : 0)                          \
                             ? SB_HUGE(T)                                                                              \
                             : SB_VALID(T)))

#include "api_null_calls.h"

/* Run call(pass) in a child, 20 s at most; 0 when it returned. */
static int survives(void (*call)(int), int pass, char *why, size_t size) {
    fflush(stdout);
    fflush(stderr);
    pid_t pid = fork();
    if (pid == 0) {
        alarm(20);
        call(pass);
        _exit(0);
    }
    int st = 0;
    if (pid < 0 || waitpid(pid, &st, 0) != pid) {
        snprintf(why, size, "could not run it");
        return -1;
    }
    if (WIFSIGNALED(st))
        snprintf(why, size, "%s", WTERMSIG(st) == SIGALRM ? "hung (20 s)" : strsignal(WTERMSIG(st)));
    else if (WEXITSTATUS(st) != 0)
        snprintf(why, size, "exit %d (a sanitizer's report above)", WEXITSTATUS(st));
    return WIFEXITED(st) && WEXITSTATUS(st) == 0 ? 0 : -1;
}

/* The handles of pass 3: lambert on an io grid of 8, factored with J = 1. */
static int make_handles(void) {
    sb_job_opts_t o = {0};
    o.source = "lambert";
    o.param = "io";
    o.res = 8;
    o.terms = 1;
    h.json.fp = fopen("/dev/null", "w");
    return sb_context_create(&h.ctx) == SB_OK && sb_model_create(h.ctx, "lambert", &h.src) == SB_OK &&
           sb_param_create(h.ctx, SB_PARAM_IO, NULL, &h.param) == SB_OK && sb_job_run(h.ctx, &o, &h.job) == SB_OK &&
           sb_scene_parse(h.ctx, "view=0..60;light=0..60", &h.scene) == SB_OK && h.json.fp;
}

SB_TEST(every_public_function) {
    static const char *const passes[5] = {"zero/NULL", "huge", "negative/NaN", "valid handles, zero/NULL others",
                                          "valid handles, huge numbers"};
    CHECKF(SB_API_COUNT > 200, "only %d public functions found", SB_API_COUNT);
    CHECKF(make_handles(), "the handles of pass 3: %s", h.ctx ? sb_context_last_error(h.ctx) : "no context");
    /* the passes give what they say */
    CHECK(SB_ARG(const sb_job_t *, 0) == NULL && SB_ARG(size_t, 1) == SIZE_MAX && isnan(SB_ARG(double, 2)));
    CHECK(SB_ARG(const sb_job_t *, 3) == h.job && SB_ARG(size_t, 3) == 0 && SB_ARG(double *, 3) == NULL);
    CHECK(SB_ARG(const sb_param_t *, 4) == h.param && SB_ARG(size_t, 4) == SIZE_MAX && SB_ARG(int, 4) == INT_MAX);
    for (int i = 0; i < SB_API_COUNT; i++)
        for (int pass = 0; pass < 5; pass++) {
            char why[128] = "";
            int ok = survives(sb_api_calls[i].call, pass, why, sizeof why) == 0;
            CHECKF(ok, "%s(%s arguments): %s", sb_api_calls[i].name, passes[pass], why);
        }
}

/* The harness itself can fail: a call that crashes is reported. */
static void crash(int pass) {
    (void)pass;
    raise(SIGSEGV);
}

SB_TEST(harness_sees_a_crash) {
    char why[128] = "";
    CHECK(survives(crash, 0, why, sizeof why) != 0 && why[0]);
}

/* The documented safe values for a NULL job, JSON writer or colour. */
SB_TEST(null_accessors) {
    CHECK(strcmp(sb_job_source_spec(NULL), "") == 0);
    CHECK(sb_job_param(NULL) == NULL && sb_job_metric(NULL) == NULL && sb_job_scene(NULL) == NULL);
    CHECK(sb_job_form(NULL) == SB_FORM_F && sb_job_masked(NULL) == 0);
    CHECK(isnan(sb_job_headline(NULL, 1)) && isnan(sb_job_comparable(NULL, 1)));
    CHECK(isnan(sb_job_rel_stored(NULL, 1, 3)) && isnan(sb_job_svd_rel_rms(NULL, 1)));
    CHECK(sb_job_candidate_count(NULL) == 0 && sb_job_warning_count(NULL) == 0);
    sb_job_timings_t t;
    memset(&t, 0xff, sizeof t);
    sb_job_timings(NULL, &t);
    CHECK(t.total_s == 0 && t.sample_s == 0);
    sb_job_timings(NULL, NULL);
    sb_json_t j = {NULL, 0, {0}};
    sb_json_begin_object(NULL, "a");
    sb_json_begin_array(&j, "a"); /* no FILE: nothing written, depth unchanged */
    sb_json_string(&j, "a", "b");
    sb_json_int(NULL, "a", 1);
    CHECK(j.depth == 0);
    CHECK(sb_gamut_map(SB_GAMUT_CLIP, NULL) == 0);
    double rgb[3] = {-1, 0.5, 0.5};
    CHECK(sb_gamut_map(SB_GAMUT_CLIP, rgb) == 1 && rgb[0] == 0);
}
