/* Tiny test harness: SB_TEST(name) { ... } declares a case; the test binary
 * runs the case named on its command line (or all of them) and prints
 * "FAIL: file:line ..." for each failed check and, at the end,
 * "N passed, N failed, N skipped".  Exit 0 ok, 1 failed, 77 skipped. */
#ifndef SB_TEST_HARNESS_H
#define SB_TEST_HARNESS_H

#include <math.h>
#include <stdio.h>

typedef void (*sb_test_fn)(void);
void sb_test_register(const char *name, sb_test_fn fn);
void sb_test_fail(const char *file, int line, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
void sb_test_skip(const char *why);
int sb_test_failed_now(void);

/* The layouts a test can make from options alone, looped over as kinds
 * 0 .. SB_TEST_KINDS - 1: the numbered kinds io .. vh (param.h); vndf,
 * the next, is built on an RGL file's own tables (tests/test_vndf.c). */
#define SB_TEST_KINDS (SB_PARAM_VH + 1)
#define SB_TEST(name)                                                                                                  \
    static void sb_test_##name(void);                                                                                  \
    __attribute__((constructor)) static void sb_test_reg_##name(void) { sb_test_register(#name, sb_test_##name); }     \
    static void sb_test_##name(void)

#define CHECK(cond)                                                                                                    \
    do {                                                                                                               \
        if (!(cond)) sb_test_fail(__FILE__, __LINE__, "%s", #cond);                                                    \
    } while (0)
#define CHECKF(cond, ...)                                                                                              \
    do {                                                                                                               \
        if (!(cond)) sb_test_fail(__FILE__, __LINE__, __VA_ARGS__);                                                    \
    } while (0)
/* |a - b| <= tol * max(1, |b|) style checks */
#define CHECK_REL(a, b, tol)                                                                                           \
    do {                                                                                                               \
        double a_ = (a), b_ = (b);                                                                                     \
        double d_ = fabs(a_ - b_), s_ = fabs(b_) > 1e-300 ? fabs(b_) : 1.0;                                            \
        if (!(d_ <= (tol)*s_))                                                                                         \
            sb_test_fail(__FILE__, __LINE__, "%s = %.17g vs %s = %.17g (rel %.3g > %.3g)", #a, a_, #b, b_, d_ / s_,    \
                         (double)(tol));                                                                               \
    } while (0)
#define CHECK_ABS(a, b, tol)                                                                                           \
    do {                                                                                                               \
        double a_ = (a), b_ = (b);                                                                                     \
        if (!(fabs(a_ - b_) <= (tol)))                                                                                 \
            sb_test_fail(__FILE__, __LINE__, "%s = %.17g vs %s = %.17g (abs %.3g > %.3g)", #a, a_, #b, b_,             \
                         fabs(a_ - b_), (double)(tol));                                                                \
    } while (0)
#define SKIP(why)                                                                                                      \
    do {                                                                                                               \
        sb_test_skip(why);                                                                                             \
        return;                                                                                                        \
    } while (0)

/* Helpers for CLI tests: run a shell command, capture stdout+stderr. */
int sb_run(const char *cmd, char *out, size_t out_size);
/* Make a fresh empty temporary directory; returns a static buffer.  It is
 * removed when the executable ends with every case passed (kept on a
 * failure, or always with SB_KEEP_TMP=1). */
const char *sb_tmpdir(const char *tag);
int sb_file_exists(const char *path);
/* A whole file, NUL-terminated (malloc'd; the caller frees), its length
 * in *len when len is not NULL; NULL when it cannot be read. */
char *sb_read_file(const char *path, size_t *len);
/* Deterministic uniform random numbers in [0, 1). */
double sb_rand01(unsigned long long *state);

#endif
