/* The memo of a job's repeated masked fits (src/util/ctx_memo.c,
 * src/solve/fit_memo.c): the non-negative solver's masked fit beside each
 * channel is the fit the SVD beside makes of the same matrix; made once
 * while a job runs, the second taking the very bits of the first. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

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
