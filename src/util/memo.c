/* The memo of memo.h: open addressing with linear probing, FNV-style
 * hashing of the keys' bits, and no lock.  A slot is claimed by a
 * compare-and-swap of its tag from empty to WRITING, its key and values
 * are written, and its tag is published with release order; a reader
 * that loads a published tag with acquire order sees the key and values
 * whole.  A slot still being written counts as a miss: the caller computes
 * the value itself, which the memo's functions allow (they are
 * deterministic).  Two threads evaluating side by side no longer wait for
 * each other (with a mutex, the Cornell acrylic's default run took 1.09x
 * the CPU of no memo on two threads). */
#include "util/memo.h"

#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* A slot's tag: 0 empty, WRITING while claimed, else the high half of
 * the key's hash (bit 0 set: never 0) in its high 32 bits and the index of
 * the slot's entry in its low 32.  The tags are an array of their own, 8
 * bytes a slot: a probe reads them (a 10 MiB table's tags fit in 1 MiB of
 * cache) and an entry only where the hashes agree.  Entries are taken in
 * order from the front of their array (the index is the count of slots
 * claimed), so a memo that stores n values touches n entries' pages, not
 * every page of its capacity: a fold's table (job_cv.c) stores 63 000
 * values of the Cornell acrylic's iso layout, and the kernel zeroed all
 * 20 MiB of the entries for them when an entry sat at its slot (clear_page
 * a few % of the default run's CPU, issue 32 item 5). */
#define WRITING 1u

typedef struct memo_entry {
    double key[SB_MEMO_KEY];
    double val[3];
    int state;
} memo_entry_t;

struct sb_memo {
    size_t cap;         /* a power of two */
    atomic_size_t used; /* slots claimed; none beyond 3/4 */
    _Atomic uint64_t *tag;
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

sb_memo_t *sb_memo_create(size_t cap) {
    sb_memo_t *m = calloc(1, sizeof *m);
    if (!m) return NULL;
    for (m->cap = 4; m->cap < cap && m->cap < ((size_t)1 << 32); m->cap *= 2) { /* an entry's index: 32 bits */
    }
    m->tag = calloc(m->cap, sizeof *m->tag);      /* zero: every slot empty */
    m->t = malloc(m->cap / 4 * 3 * sizeof *m->t); /* at most 3/4 of the slots hold one */
    if (!m->tag || !m->t) {
        sb_memo_destroy(m);
        return NULL;
    }
    atomic_init(&m->used, 0);
    return m;
}

void sb_memo_destroy(sb_memo_t *m) {
    if (!m) return;
    free((void *)m->tag);
    free(m->t);
    free(m);
}

/* The high half of a tag: the key's fingerprint (bit 0 set). */
static uint64_t fingerprint(uint64_t h) { return (h >> 32) | 1u; }

int sb_memo_find(sb_memo_t *m, const double key[SB_MEMO_KEY], double val[3]) {
    uint64_t h = hash_key(key), fp = fingerprint(h);
    for (size_t i = (size_t)h & (m->cap - 1);; i = (i + 1) & (m->cap - 1)) {
        uint64_t g = atomic_load_explicit(&m->tag[i], memory_order_acquire);
        if (g <= WRITING) return 0; /* empty, or being written (perhaps this key): a miss */
        const memo_entry_t *e = &m->t[g & 0xffffffffu];
        if (g >> 32 == fp && memcmp(e->key, key, sizeof e->key) == 0) {
            memcpy(val, e->val, sizeof e->val);
            return e->state;
        }
    }
}

void sb_memo_store(sb_memo_t *m, const double key[SB_MEMO_KEY], const double val[3], int state) {
    if (4 * (atomic_load_explicit(&m->used, memory_order_relaxed) + 1) > 3 * m->cap) return;
    uint64_t h = hash_key(key), fp = fingerprint(h);
    for (size_t i = (size_t)h & (m->cap - 1);; i = (i + 1) & (m->cap - 1)) {
        uint64_t g = atomic_load_explicit(&m->tag[i], memory_order_acquire), empty = 0;
        if (g == WRITING) return; /* perhaps this key, by another thread: leave it */
        if (g > WRITING) {
            if (g >> 32 == fp && memcmp(m->t[g & 0xffffffffu].key, key, sizeof m->t->key) == 0) return; /* stored */
            continue;
        }
        if (!atomic_compare_exchange_strong_explicit(&m->tag[i], &empty, WRITING, memory_order_acquire,
                                                     memory_order_relaxed)) {
            i = (i - 1) & (m->cap - 1); /* claimed meanwhile: look at it again */
            continue;
        }
        size_t at = atomic_fetch_add_explicit(&m->used, 1, memory_order_relaxed); /* the next entry */
        if (4 * (at + 1) > 3 * m->cap) {
            atomic_store_explicit(&m->tag[i], 0, memory_order_release); /* full: give the slot back */
            return;
        }
        memo_entry_t *e = &m->t[at];
        memcpy(e->key, key, sizeof e->key);
        memcpy(e->val, val, sizeof e->val);
        e->state = state;
        atomic_store_explicit(&m->tag[i], fp << 32 | at, memory_order_release);
        return;
    }
}
