/* Private: a memo of byte strings on a context (ctx_memo.c), open while a
 * job runs.  A deterministic computation keyed by all of its input, as
 * bytes, stores its output; a later one with the same bytes reads the very
 * bytes stored, so results do not change.  What it saves: the non-negative
 * run's masked fit beside each channel is the fit the SVD beside makes of
 * the same matrix (solve/fit_memo.c).  Between sb_ctx_memo_open and the
 * matching close (nested pairs share one; the last close frees it), else
 * nothing is stored or found.  Thread-safe (one lock); it holds at most
 * SB_CTX_MEMO_BYTES (an eighth of sb_memory_limit where that is less) and
 * stores nothing beyond. */
#ifndef SEPBRDF_CTX_MEMO_H
#define SEPBRDF_CTX_MEMO_H

#include <stddef.h>
#include <stdint.h>

#include "sepbrdf/common.h"

#define SB_CTX_MEMO_BYTES ((size_t)64 << 20)

typedef struct sb_ctx_memo sb_ctx_memo_t;

/* Open (or enter) ctx's memo; a memo that cannot be allocated is none. */
void sb_ctx_memo_open(sb_context_t *ctx);
/* Leave it; the last close frees what it holds. */
void sb_ctx_memo_close(sb_context_t *ctx);
/* 1 and the value (exactly vlen bytes) in val when key was stored. */
int sb_ctx_memo_find(sb_context_t *ctx, const void *key, size_t klen, void *val, size_t vlen);
/* Store val for key, unless no memo is open, it holds the key or the
 * bytes would pass SB_CTX_MEMO_BYTES. */
void sb_ctx_memo_store(sb_context_t *ctx, const void *key, size_t klen, const void *val, size_t vlen);

/* The same by a hash of the caller's (any function of the key's bytes:
 * entries are told apart by their bytes, the hash only sorts them out),
 * so that a caller whose key is large (a masked fit's matrix) builds it
 * only where it is needed.  Whether a memo is open with room for `bytes`
 * more: */
int sb_ctx_memo_room(sb_context_t *ctx, size_t bytes);
/* Whether it holds a key of klen bytes stored with hash h: */
int sb_ctx_memo_holds(sb_context_t *ctx, uint64_t h, size_t klen);
/* sb_ctx_memo_find for key stored with hash h: */
int sb_ctx_memo_find_hashed(sb_context_t *ctx, uint64_t h, const void *key, size_t klen, void *val, size_t vlen);
/* sb_ctx_memo_store with hash h, taking key (malloc'd): kept, or freed. */
void sb_ctx_memo_store_hashed(sb_context_t *ctx, uint64_t h, void *key, size_t klen, const void *val, size_t vlen);

#endif
