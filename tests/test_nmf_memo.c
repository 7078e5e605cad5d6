/* What a non-negative run no longer makes twice or whole (round h38y):
 * the memo of a job's repeated masked fits (src/util/ctx_memo.c,
 * src/solve/fit_memo.c: the solver's masked fit beside each channel is the
 * fit the SVD beside makes of the same matrix, the second taking the very
 * bits of the first), and the screening's first fit alone (the plan's
 * nonneg_first_fit). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fixtures.h"
#include "harness.h"
#include "sepbrdf/sepbrdf.h"
#include "solve/fit_impl.h" /* not exported, in the static archive */
#include "util/ctx_memo.h"

/* Bytes stored are found only between open and the last close, and are
 * the bytes stored; a key of other bytes or length misses. */
SB_TEST(ctx_memo_open_while_a_job_runs) {
    sb_context_t *ctx = NULL;
    CHECK(sb_context_create(&ctx) == SB_OK);
    const double key[3] = {1, 2, 3}, val[2] = {4.5, -0.0};
    double got[2] = {0, 0};
    sb_ctx_memo_store(ctx, key, sizeof key, val, sizeof val); /* not open: nothing stored */
    sb_ctx_memo_open(ctx);
    CHECK(!sb_ctx_memo_find(ctx, key, sizeof key, got, sizeof got));
    sb_ctx_memo_store(ctx, key, sizeof key, val, sizeof val);
    CHECK(sb_ctx_memo_find(ctx, key, sizeof key, got, sizeof got) && !memcmp(got, val, sizeof val));
    const double other[3] = {1, 2, 3.0000000000000004};
    CHECK(!sb_ctx_memo_find(ctx, other, sizeof other, got, sizeof got));
    CHECK(!sb_ctx_memo_find(ctx, key, 2 * sizeof(double), got, sizeof got));
    sb_ctx_memo_open(ctx); /* a run inside the run (the SVD beside) shares it */
    CHECK(sb_ctx_memo_find(ctx, key, sizeof key, got, sizeof got));
    sb_ctx_memo_close(ctx);
    CHECK(sb_ctx_memo_find(ctx, key, sizeof key, got, sizeof got));
    sb_ctx_memo_close(ctx); /* the last close frees it */
    CHECK(!sb_ctx_memo_find(ctx, key, sizeof key, got, sizeof got));
    sb_context_destroy(ctx);
}

/* By the caller's hash (fit_memo.c: a masked fit's key built only where
 * the memo holds one of its hash): a key is told apart by its bytes, not
 * its hash, and the store takes the key it is given. */
SB_TEST(ctx_memo_by_callers_hash) {
    sb_context_t *ctx = NULL;
    CHECK(sb_context_create(&ctx) == SB_OK);
    const double key[3] = {1, 2, 3}, other[3] = {1, 2, 4}, val[2] = {4.5, -0.0};
    double got[2] = {0, 0};
    CHECK(!sb_ctx_memo_room(ctx, 0)); /* not open */
    sb_ctx_memo_open(ctx);
    CHECK(sb_ctx_memo_room(ctx, 0) && sb_ctx_memo_room(ctx, SB_CTX_MEMO_BYTES) &&
          !sb_ctx_memo_room(ctx, SB_CTX_MEMO_BYTES + 1));
    CHECK(!sb_ctx_memo_holds(ctx, 7, sizeof key));
    double *k = malloc(sizeof key);
    CHECK(k != NULL);
    memcpy(k, key, sizeof key);
    sb_ctx_memo_store_hashed(ctx, 7, k, sizeof key, val, sizeof val);
    CHECK(sb_ctx_memo_holds(ctx, 7, sizeof key) && !sb_ctx_memo_holds(ctx, 8, sizeof key) &&
          !sb_ctx_memo_holds(ctx, 7, sizeof key - 1));
    CHECK(sb_ctx_memo_find_hashed(ctx, 7, key, sizeof key, got, sizeof got) && !memcmp(got, val, sizeof val));
    CHECK(!sb_ctx_memo_find_hashed(ctx, 7, other, sizeof other, got, sizeof got)); /* same hash, other bytes */
    CHECK(!sb_ctx_memo_find_hashed(ctx, 8, key, sizeof key, got, sizeof got));
    CHECK(!sb_ctx_memo_room(ctx, SB_CTX_MEMO_BYTES)); /* what it holds counts */
    sb_ctx_memo_close(ctx);
    CHECK(!sb_ctx_memo_holds(ctx, 7, sizeof key));
    sb_context_destroy(ctx);
}

#define M 24
#define N 40
#define K 3

/* A smooth matrix of rank > K with a wedge of cells out of the data. */
static void masked(double *a, unsigned char *mask) {
    for (size_t c = 0; c < N; c++)
        for (size_t r = 0; r < M; r++) {
            double x = (double)r / M, y = (double)c / N;
            a[r + c * M] = exp(-3 * x * y) + 0.3 * sin(5 * x + 2 * y) + 0.1 * cos(9 * x * x - 4 * y);
            mask[r + c * M] = (unsigned char)(r + c / 3 < 30 ? 1 : 0);
        }
}

/* A second fit of the same matrix, mask and options in a job takes the
 * first's terms without fitting (its fit object never gathers the cells)
 * and they are the bits a fit of its own gives; a value changed on a
 * valid cell is a new fit, one out of the data is not. */
SB_TEST(masked_fit_repeated_same_bits) {
    sb_context_t *ctx = NULL;
    CHECK(sb_context_create(&ctx) == SB_OK);
    double *a = malloc(M * N * sizeof *a);
    unsigned char *mask = malloc(M * N);
    masked(a, mask);
    sb_fit_opts_t o = {40, 1e-6, 7, 0, {{0, 0}, {0, 0}}, {{0, 0}, {0, 0}}};
    double s[3][K], u[3][M * K], v[3][N * K];
    sb_fit_info_t fi[3];
    sb_fit_t *f[3] = {NULL, NULL, NULL};
    for (int i = 0; i < 3; i++)
        CHECK(sb_fit_create(ctx, M, N, K, &f[i]) == SB_OK);
    CHECK(sb_fit_execute(f[0], a, M, mask, &o, s[0], u[0], v[0], &fi[0]) == SB_OK);
    CHECK(f[0]->cells != NULL); /* a fit of its own gathers the cells */
    sb_ctx_memo_open(ctx);
    CHECK(fit_memo_execute(f[1], a, M, mask, &o, s[1], u[1], v[1], &fi[1]) == SB_OK);
    a[M * N - 1] = 1e3; /* out of the data */
    CHECK(!mask[M * N - 1]);
    CHECK(fit_memo_execute(f[2], a, M, mask, &o, s[2], u[2], v[2], &fi[2]) == SB_OK);
    CHECK(f[2]->cells == NULL); /* taken from the memo */
    for (int i = 1; i < 3; i++)
        CHECK(!memcmp(s[i], s[0], sizeof s[0]) && !memcmp(u[i], u[0], sizeof u[0]) &&
              !memcmp(v[i], v[0], sizeof v[0]) && fi[i].iterations == fi[0].iterations &&
              fi[i].rel_err == fi[0].rel_err && fi[i].conv_terms == fi[0].conv_terms);
    a[0] += 1e-3; /* a valid cell: fitted again */
    CHECK(mask[0]);
    sb_fit_destroy(f[2]);
    CHECK(sb_fit_create(ctx, M, N, K, &f[2]) == SB_OK);
    CHECK(fit_memo_execute(f[2], a, M, mask, &o, s[2], u[2], v[2], &fi[2]) == SB_OK);
    CHECK(f[2]->cells != NULL && memcmp(u[2], u[0], sizeof u[0]) != 0);
    sb_ctx_memo_close(ctx);
    for (int i = 0; i < 3; i++)
        sb_fit_destroy(f[i]);
    free(a);
    free(mask);
    sb_context_destroy(ctx);
}

/* Factor m (J = 4) non-negative, with the plan's nonneg_first_fit or not. */
static sb_factors_t *nmf_fit(const sb_matrix_t *m, const sb_param_t *p, int first, sb_plan_stats_t *st) {
    sb_plan_opts_t po = {0};
    po.size = sizeof po;
    po.terms = 4;
    po.weighted = 1;
    po.svd.method = SB_METHOD_NMF;
    po.nonneg_first_fit = first;
    sb_plan_t *plan = NULL;
    sb_factors_t *f = NULL;
    CHECK(sb_plan_create_for(NULL, m, &po, &plan) == SB_OK);
    CHECK(sb_plan_execute(plan, m, p, &f) == SB_OK);
    sb_plan_stats(plan, st);
    sb_plan_destroy(plan);
    return f;
}

/* The screening's fit (nonneg_first_fit): on a masked layout (hd) the
 * first fit alone, fewer sweeps than the whole fit (its refits toward the
 * headline), non-negative and within 1.5x of the whole fit's error; on a
 * layout without masked cells (io) the same bits as the whole fit. */
SB_TEST(first_fit_for_ranking) {
    sb_source_t *s = fx_model("microfacet:base=gold,roughness=0.548");
    for (int k = 0; k < 2; k++) {
        sb_param_t *p = fx_layout(k ? SB_PARAM_IO : SB_PARAM_HD, 8);
        sb_matrix_t m;
        CHECK(sb_matrix_build(NULL, s, p, NULL, &m) == SB_OK);
        CHECK((m.mask != NULL) == !k);
        sb_plan_stats_t a, b;
        sb_factors_t *whole = nmf_fit(&m, p, 0, &a), *first = nmf_fit(&m, p, 1, &b);
        if (whole && first) {
            double ew = sb_factors_errors(whole)->rel_rms[sb_err_at(3, SB_CH_ALL)];
            double ef = sb_factors_errors(first)->rel_rms[sb_err_at(3, SB_CH_ALL)];
            size_t neg = 0, same = 1;
            for (size_t j = 0; j < 4; j++)
                for (size_t c = 0; c < 3; c++)
                    for (int side = 0; side < 2; side++) {
                        size_t w, h;
                        sb_factors_size(first, side, &w, &h);
                        const double *t = sb_factors_tex_const(first, side, j, c);
                        const double *u = sb_factors_tex_const(whole, side, j, c);
                        for (size_t i = 0; i < w * h; i++)
                            neg += !(t[i] >= 0);
                        same &= !memcmp(t, u, w * h * sizeof *t);
                    }
            CHECK(neg == 0);
            if (k)
                CHECK(same && a.fit_iterations == b.fit_iterations);
            else
                CHECKF(b.fit_iterations < a.fit_iterations && ef <= 1.5 * ew, "sweeps %d vs %d, error %g vs %g",
                       b.fit_iterations, a.fit_iterations, ef, ew);
        }
        sb_factors_destroy(whole);
        sb_factors_destroy(first);
        sb_matrix_free(&m);
        sb_param_destroy(p);
    }
    sb_source_destroy(s);
}
