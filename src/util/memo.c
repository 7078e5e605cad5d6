/* The memo of memo.h: open addressing with linear probing over a table
 * allocated on the first store, FNV-style hashing of the keys' bits. */
#include "util/memo.h"

#include <pthread.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

typedef struct memo_entry {
    double key[SB_MEMO_KEY];
    double val[3];
    int state; /* 0 empty */
} memo_entry_t;

struct sb_memo {
    pthread_mutex_t mu;
    size_t cap, used; /* cap a power of two; no insertion beyond 3/4 */
    int failed;       /* the table could not be allocated: store nothing */
    memo_entry_t *t;
};

static uint64_t hash_key(const double k[SB_MEMO_KEY]) {
    uint64_t h = 1469598103934665603ull, w;
    for (int i = 0; i < SB_MEMO_KEY; i++) {
        memcpy(&w, &k[i], sizeof w);
        h = (h ^ w) * 1099511628211ull;
        h ^= h >> 29;
    }
    return h;
}

/* The slot of key k: its entry, or the empty one where it would go. */
static memo_entry_t *slot(const sb_memo_t *m, const double k[SB_MEMO_KEY]) {
    for (size_t i = (size_t)hash_key(k) & (m->cap - 1);; i = (i + 1) & (m->cap - 1))
        if (m->t[i].state == 0 || memcmp(m->t[i].key, k, sizeof m->t[i].key) == 0) return &m->t[i];
}

sb_memo_t *sb_memo_create(size_t cap) {
    sb_memo_t *m = calloc(1, sizeof *m);
    if (!m) return NULL;
    if (pthread_mutex_init(&m->mu, NULL) != 0) {
        free(m);
        return NULL;
    }
    for (m->cap = 4; m->cap < cap; m->cap *= 2) {
    }
    return m;
}

void sb_memo_destroy(sb_memo_t *m) {
    if (!m) return;
    pthread_mutex_destroy(&m->mu);
    free(m->t);
    free(m);
}

int sb_memo_find(sb_memo_t *m, const double key[SB_MEMO_KEY], double val[3]) {
    int state = 0;
    pthread_mutex_lock(&m->mu);
    if (m->t) {
        const memo_entry_t *e = slot(m, key);
        state = e->state;
        if (state) memcpy(val, e->val, sizeof e->val);
    }
    pthread_mutex_unlock(&m->mu);
    return state;
}

void sb_memo_store(sb_memo_t *m, const double key[SB_MEMO_KEY], const double val[3], int state) {
    pthread_mutex_lock(&m->mu);
    if (!m->t && !m->failed) {
        m->t = calloc(m->cap, sizeof *m->t);
        m->failed = m->t == NULL;
    }
    if (m->t && 4 * (m->used + 1) <= 3 * m->cap) {
        memo_entry_t *s = slot(m, key);
        if (s->state == 0) {
            memcpy(s->key, key, sizeof s->key);
            memcpy(s->val, val, sizeof s->val);
            s->state = state;
            m->used++;
        }
    }
    pthread_mutex_unlock(&m->mu);
}
