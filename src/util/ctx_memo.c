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
    unsigned char *key, *val;
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
        free(e->key);
        free(e->val);
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

/* The entry of key (NULL: none; key NULL: the first of hash h and length
 * klen); under the lock. */
static entry_t *lookup(const sb_ctx_memo_t *m, uint64_t h, const void *key, size_t klen) {
    for (entry_t *e = m->head; e; e = e->next)
        if (e->hash == h && e->klen == klen && (!key || memcmp(e->key, key, klen) == 0)) return e;
    return NULL;
}

static sb_ctx_memo_t *memo_of(sb_context_t *ctx) { return ctx ? *sb_context_memo_slot(ctx, NULL) : NULL; }

int sb_ctx_memo_find_hashed(sb_context_t *ctx, uint64_t h, const void *key, size_t klen, void *val, size_t vlen) {
    sb_ctx_memo_t *m = memo_of(ctx);
    if (!m) return 0;
    pthread_mutex_lock(&m->mu);
    const entry_t *e = lookup(m, h, key, klen);
    int hit = e && e->vlen == vlen;
    if (hit) memcpy(val, e->val, vlen);
    pthread_mutex_unlock(&m->mu);
    return hit;
}

int sb_ctx_memo_find(sb_context_t *ctx, const void *key, size_t klen, void *val, size_t vlen) {
    return sb_ctx_memo_find_hashed(ctx, fnv1a(key, klen), key, klen, val, vlen);
}

int sb_ctx_memo_holds(sb_context_t *ctx, uint64_t h, size_t klen) {
    sb_ctx_memo_t *m = memo_of(ctx);
    if (!m) return 0;
    pthread_mutex_lock(&m->mu);
    int held = lookup(m, h, NULL, klen) != NULL;
    pthread_mutex_unlock(&m->mu);
    return held;
}

/* What the memo may hold: SB_CTX_MEMO_BYTES, less under a low memory
 * limit (--memory-limit): an eighth of it, the rest for the work itself. */
static size_t memo_cap(void) {
    size_t lim = sb_memory_limit() / 8;
    return lim < SB_CTX_MEMO_BYTES ? lim : SB_CTX_MEMO_BYTES;
}

int sb_ctx_memo_room(sb_context_t *ctx, size_t bytes) {
    sb_ctx_memo_t *m = memo_of(ctx);
    if (!m) return 0;
    size_t cap = memo_cap();
    pthread_mutex_lock(&m->mu);
    int room = bytes <= cap && m->bytes <= cap - bytes;
    pthread_mutex_unlock(&m->mu);
    return room;
}

void sb_ctx_memo_store_hashed(sb_context_t *ctx, uint64_t h, void *key, size_t klen, const void *val, size_t vlen) {
    sb_ctx_memo_t *m = memo_of(ctx);
    size_t cap = memo_cap();
    entry_t *e = m && klen <= cap && vlen <= cap - klen ? calloc(1, sizeof *e) : NULL;
    unsigned char *v = e ? malloc(vlen ? vlen : 1) : NULL;
    if (!v) {
        free(e);
        free(key);
        return;
    }
    memcpy(v, val, vlen);
    *e = (entry_t){NULL, h, klen, vlen, key, v};
    pthread_mutex_lock(&m->mu);
    int keep = m->bytes + klen + vlen <= cap && !lookup(m, h, key, klen);
    if (keep) {
        e->next = m->head;
        m->head = e;
        m->bytes += klen + vlen;
    }
    pthread_mutex_unlock(&m->mu);
    if (!keep) {
        free(key);
        free(v);
        free(e);
    }
}

void sb_ctx_memo_store(sb_context_t *ctx, const void *key, size_t klen, const void *val, size_t vlen) {
    unsigned char *k = memo_of(ctx) ? malloc(klen ? klen : 1) : NULL;
    if (!k) return;
    memcpy(k, key, klen);
    sb_ctx_memo_store_hashed(ctx, fnv1a(key, klen), k, klen, val, vlen);
}
