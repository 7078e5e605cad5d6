/* A memo of a source's values for screening: the candidates' comparable
 * errors evaluate the source at the same reference pairs again and again,
 * and a measured table's interpolation (k-d tree query and local fit) is
 * what costs there.  The memo answers a pair it has seen with the very
 * values the source gave, so results do not change. */
#include <stdlib.h>

#include "job_impl.h"
#include "util/internal.h"
#include "util/memo.h"

typedef struct memo {
    const sb_source_t *src;
    sb_memo_t *m;
} memo_t;

static int memo_eval(const void *self, const double wi[3], const double wo[3], double rgb[3]) {
    const memo_t *m = self;
    const double k[SB_MEMO_KEY] = {wi[0], wi[1], wi[2], wo[0], wo[1], wo[2]};
    int state = sb_memo_find(m->m, k, rgb);
    if (state) return state == 1;
    int known = sb_source_eval(m->src, wi, wo, rgb);
    sb_memo_store(m->m, k, rgb, known ? 1 : 2);
    return known;
}

static void memo_destroy(void *self) {
    memo_t *m = self;
    sb_memo_destroy(m->m);
    free(m);
}

sb_result_t job_memo_create(sb_context_t *ctx, const sb_source_t *src, size_t cap, sb_source_t **out) {
    memo_t *m = calloc(1, sizeof *m);
    if (m) m->m = sb_memo_create(cap);
    if (!m || !m->m) {
        free(m);
        return sb_error(ctx, SB_ERR_NOMEM, "screening memo: out of memory");
    }
    m->src = src;
    static const sb_source_ops_t ops = {memo_eval, memo_destroy};
    sb_result_t r = sb_source_create(ctx, &ops, m, sb_source_flags(src), sb_source_description(src), out);
    if (r != SB_OK) memo_destroy(m);
    return r;
}
