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

/* While from is set, sb_error writes `to` for every occurrence of `from` in
 * its messages (an output set names its target, not its staging folder).
 * Both strings stay owned by the caller; from NULL ends it. */
void sb_context_alias(sb_context_t *ctx, const char *from, const char *to);

/* Number of worker threads to use (env SEPBRDF_THREADS or online cores). */
int sb_thread_count(int requested);

#endif
