/* Private helpers shared by the library modules. */
#ifndef SEPBRDF_INTERNAL_H
#define SEPBRDF_INTERNAL_H

#include <stddef.h>

#include "sepbrdf/common.h"

char *sb_strdup(const char *s);
/* malloc with the overflow-checked product count * size and the memory
 * limit; reports through ctx naming `what`.  NULL on failure. */
void *sb_alloc(sb_context_t *ctx, size_t count, size_t size, const char *what);
void *sb_calloc(sb_context_t *ctx, size_t count, size_t size, const char *what);

/* Number of worker threads to use (env SEPBRDF_THREADS or online cores). */
int sb_thread_count(int requested);

/* Before the first BLAS call of the calling thread (plan creation): under
 * a memory limit (ulimit -v / -d), check that OpenBLAS's working buffer
 * fits and make it allocate it now, so that it cannot hang later retrying
 * the allocation (blas_guard.c).  SB_ERR_NOMEM names the bytes. */
sb_result_t sb_blas_reserve(sb_context_t *ctx);

#endif
