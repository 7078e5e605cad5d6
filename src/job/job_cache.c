/* A memo of a source's values for screening: the candidates' comparable
 * errors evaluate the source at the same reference pairs again and again,
 * and a measured table's interpolation (k-d tree query and local fit) is
 * what costs there.  The memo answers a pair it has seen with the very
 * values the source gave, so results do not change. */
#include <pthread.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "job_impl.h"
#include "util/internal.h"

typedef struct memo_entry {
    double key[6];
    double rgb[3];
    int state; /* 0 empty, 1 known, 2 missing */
} memo_entry_t;

typedef struct memo {
    const sb_source_t *src;
    pthread_mutex_t mu;
    size_t cap, used; /* cap a power of two; no insertion beyond 3/4 */
    memo_entry_t *t;
} memo_t;

static uint64_t hash_key(const double k[6]) {
    uint64_t h = 1469598103934665603ull, w;
    for (int i = 0; i < 6; i++) {
        memcpy(&w, &k[i], sizeof w);
        h = (h ^ w) * 1099511628211ull;
        h ^= h >> 29;
    }
    return h;
}

/* The slot of key k: its entry, or the empty one where it would go. */
static memo_entry_t *slot(const memo_t *m, const double k[6], uint64_t h) {
    for (size_t i = (size_t)h & (m->cap - 1);; i = (i + 1) & (m->cap - 1))
        if (m->t[i].state == 0 || memcmp(m->t[i].key, k, sizeof m->t[i].key) == 0) return &m->t[i];
}

static int memo_eval(const void *self, const double wi[3], const double wo[3], double rgb[3]) {
    memo_t *m = (memo_t *)self;
    double k[6] = {wi[0], wi[1], wi[2], wo[0], wo[1], wo[2]};
    uint64_t h = hash_key(k);
    pthread_mutex_lock(&m->mu);
    const memo_entry_t *e = slot(m, k, h);
    int state = e->state;
    if (state) memcpy(rgb, e->rgb, sizeof e->rgb);
    pthread_mutex_unlock(&m->mu);
    if (state) return state == 1;
    int known = sb_source_eval(m->src, wi, wo, rgb);
    pthread_mutex_lock(&m->mu);
    memo_entry_t *s = slot(m, k, h);
    if (s->state == 0 && 4 * (m->used + 1) <= 3 * m->cap) {
        memcpy(s->key, k, sizeof k);
        memcpy(s->rgb, rgb, sizeof s->rgb);
        s->state = known ? 1 : 2;
        m->used++;
    }
    pthread_mutex_unlock(&m->mu);
    return known;
}

static void memo_destroy(void *self) {
    memo_t *m = self;
    pthread_mutex_destroy(&m->mu);
    free(m->t);
    free(m);
}

sb_result_t job_memo_create(sb_context_t *ctx, const sb_source_t *src, size_t cap, sb_source_t **out) {
    memo_t *m = calloc(1, sizeof *m);
    if (!m) return sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    m->src = src;
    m->cap = cap;
    m->t = sb_calloc(ctx, cap, sizeof *m->t, "screening memo");
    if (!m->t || pthread_mutex_init(&m->mu, NULL) != 0) {
        free(m->t);
        free(m);
        return SB_ERR_NOMEM;
    }
    static const sb_source_ops_t ops = {memo_eval, memo_destroy};
    sb_result_t r = sb_source_create(ctx, &ops, m, sb_source_flags(src), sb_source_description(src), out);
    if (r != SB_OK) memo_destroy(m);
    return r;
}
