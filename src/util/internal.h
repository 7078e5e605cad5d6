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
/* sb_alloc for large buffers: backed by huge pages where the system offers
 * them (fewer page faults on first touch); released with free(). */
void *sb_alloc_large(sb_context_t *ctx, size_t count, size_t size, const char *what);

/* Number of worker threads to use (env SEPBRDF_THREADS or online cores). */
int sb_thread_count(int requested);

#endif
