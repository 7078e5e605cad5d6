/* A memo of byte strings on a context (ctx_memo.h): a list of entries
 * under one lock, each found by its key's length, an FNV-1a hash and the
 * bytes themselves. */
#include "util/ctx_memo.h"

#include "util/internal.h"

#include <pthread.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

typedef struct entry {
    struct entry *next;
    uint64_t hash;
    size_t klen, vlen;
    unsigned char *bytes; /* key, then value */
} entry_t;

struct sb_ctx_memo {
    pthread_mutex_t mu;
    int depth; /* open pairs */
    size_t bytes;
    entry_t *head;
};

static uint64_t fnv1a(const void *p, size_t n) {
    const unsigned char *b = p;
    uint64_t h = 1469598103934665603ull;
    for (size_t i = 0; i < n; i++)
        h = (h ^ b[i]) * 1099511628211ull;
    return h;
}

static void memo_free(void *p) {
    sb_ctx_memo_t *m = p;
    if (!m) return;
    for (entry_t *e = m->head, *nx; e; e = nx) {
        nx = e->next;
        free(e->bytes);
        free(e);
    }
    pthread_mutex_destroy(&m->mu);
    free(m);
}

void sb_ctx_memo_open(sb_context_t *ctx) {
    void **slot = ctx ? sb_context_memo_slot(ctx, memo_free) : NULL;
    if (!slot) return;
    if (!*slot) {
        sb_ctx_memo_t *m = calloc(1, sizeof *m);
        if (!m || pthread_mutex_init(&m->mu, NULL) != 0) {
            free(m);
            return;
        }
        *slot = m;
    }
    ((sb_ctx_memo_t *)*slot)->depth++;
}

void sb_ctx_memo_close(sb_context_t *ctx) {
    void **slot = ctx ? sb_context_memo_slot(ctx, NULL) : NULL;
    if (!slot || !*slot || --((sb_ctx_memo_t *)*slot)->depth > 0) return;
    memo_free(*slot);
    *slot = NULL;
}

/* The entry of key (NULL: none); under the lock. */
static entry_t *lookup(const sb_ctx_memo_t *m, uint64_t h, const void *key, size_t klen) {
    for (entry_t *e = m->head; e; e = e->next)
        if (e->hash == h && e->klen == klen && memcmp(e->bytes, key, klen) == 0) return e;
    return NULL;
}

int sb_ctx_memo_find(sb_context_t *ctx, const void *key, size_t klen, void *val, size_t vlen) {
    sb_ctx_memo_t *m = ctx ? *sb_context_memo_slot(ctx, NULL) : NULL;
    if (!m) return 0;
    uint64_t h = fnv1a(key, klen);
    pthread_mutex_lock(&m->mu);
    const entry_t *e = lookup(m, h, key, klen);
    int hit = e && e->vlen == vlen;
    if (hit) memcpy(val, e->bytes + klen, vlen);
    pthread_mutex_unlock(&m->mu);
    return hit;
}

/* What the memo may hold: SB_CTX_MEMO_BYTES, less under a low memory
 * limit (--memory-limit): an eighth of it, the rest for the work itself. */
static size_t memo_cap(void) {
    size_t lim = sb_memory_limit() / 8;
    return lim < SB_CTX_MEMO_BYTES ? lim : SB_CTX_MEMO_BYTES;
}

void sb_ctx_memo_store(sb_context_t *ctx, const void *key, size_t klen, const void *val, size_t vlen) {
    sb_ctx_memo_t *m = ctx ? *sb_context_memo_slot(ctx, NULL) : NULL;
    size_t cap = memo_cap();
    if (!m || klen > cap || vlen > cap - klen) return;
    uint64_t h = fnv1a(key, klen);
    entry_t *e = calloc(1, sizeof *e);
    unsigned char *b = e ? malloc(klen + vlen) : NULL;
    if (!b) {
        free(e);
        return;
    }
    memcpy(b, key, klen);
    memcpy(b + klen, val, vlen);
    *e = (entry_t){NULL, h, klen, vlen, b};
    pthread_mutex_lock(&m->mu);
    int keep = m->bytes + klen + vlen <= cap && !lookup(m, h, key, klen);
    if (keep) {
        e->next = m->head;
        m->head = e;
        m->bytes += klen + vlen;
    }
    pthread_mutex_unlock(&m->mu);
    if (!keep) {
        free(b);
        free(e);
    }
}
