/* Shared by the libFuzzer harnesses (fuzz/fuzz_*.c) and their ctest replay
 * (tests/test_fuzz_regress.c).  Each harness defines its entry with
 * SB_FUZZ_ENTRY(name): LLVMFuzzerTestOneInput in a fuzzing build,
 * sb_fuzz_<name>() when compiled into the replay test (SB_FUZZ_REGRESS).
 * A broken invariant aborts with a message, which libFuzzer reports as a
 * crash and saves the input. */
#ifndef SB_FUZZ_H
#define SB_FUZZ_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#ifdef SB_FUZZ_REGRESS
#define SB_FUZZ_ENTRY(name) int sb_fuzz_##name(const uint8_t *data, size_t size)
#else
#define SB_FUZZ_ENTRY(name) int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
#endif

#define SB_FUZZ_CHECK(cond)                                                                                            \
    do {                                                                                                               \
        if (!(cond)) {                                                                                                 \
            fprintf(stderr, "fuzz invariant broken: %s:%d: %s\n", __FILE__, __LINE__, #cond);                          \
            abort();                                                                                                   \
        }                                                                                                              \
    } while (0)

/* Once per process: a memory limit well under the fuzzer's RSS limit (so
 * forged sizes are refused by the library, not killed by libFuzzer) and a
 * private temporary folder; returns that folder. */
const char *sb_fuzz_setup(void);
/* mkdir that accepts an existing folder; 0 on success. */
int sb_fuzz_mkdir(const char *path);
/* Write bytes to dir/name; 0 on success. */
int sb_fuzz_write(const char *dir, const char *name, const uint8_t *data, size_t size);

#endif
