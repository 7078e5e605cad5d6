/* Batched sources (source.h: sb_source_create_batched, sb_source_eval_many):
 * the contract, and a factor job on a batched source gives the same bits
 * as on the source it wraps, with the matrix's columns and the estimator's
 * pairs in one call each. */
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"

/* A batched source over another source: counts calls and pairs. */
typedef struct wrap {
    const sb_source_t *inner;
    atomic_size_t calls, pairs;
    int destroyed;
} wrap_t;

static void wrap_many(const void *self, size_t n, const double *wi, const double *wo, double *rgb,
                      unsigned char *known) {
    wrap_t *w = (wrap_t *)self;
    atomic_fetch_add(&w->calls, 1);
    atomic_fetch_add(&w->pairs, n);
    for (size_t k = 0; k < n; k++)
        known[k] = (unsigned char)sb_source_eval(w->inner, wi + 3 * k, wo + 3 * k, rgb + 3 * k);
}

static void wrap_destroy(void *self) { ((wrap_t *)self)->destroyed = 1; }

static const sb_source_batch_ops_t wrap_ops = {wrap_many, wrap_destroy};

SB_TEST(contract) {
    sb_source_t *model = NULL, *b = NULL;
    CHECK(sb_source_open(NULL, "phong-glsl", &model) == SB_OK);
    wrap_t w = {.inner = model};
    sb_source_batch_ops_t none = {NULL, NULL};
    CHECK(sb_source_create_batched(NULL, &none, &w, 0, "x", &b) == SB_ERR_ARG && b == NULL);
    CHECK(sb_source_create_batched(NULL, NULL, &w, 0, "x", &b) == SB_ERR_ARG);
    CHECK(sb_source_create_batched(NULL, &wrap_ops, &w, sb_source_flags(model), "wrapped", &b) == SB_OK);
    CHECK(sb_source_batched(b) && !sb_source_batched(model) && !sb_source_batched(NULL));
    CHECK(strcmp(sb_source_description(b), "wrapped") == 0 && sb_source_impl(b) == &w);
    /* pairs above and below the horizon: the same through either route */
    double wi[9] = {0, 0, 1, 0.6, 0, 0.8, 0, 0.6, -0.8}, wo[9] = {0, 0.6, 0.8, 0, 0, 1, 0, 0, 1};
    double f1[9], f2[9], one[3];
    unsigned char k1[3], k2[3];
    CHECK(sb_source_eval_many(model, 3, wi, wo, f1, k1) == 3); /* analytic: below the horizon is a known 0 */
    CHECK(sb_source_eval_many(b, 3, wi, wo, f2, k2) == 3);
    CHECK(memcmp(f1, f2, sizeof f1) == 0 && memcmp(k1, k2, sizeof k1) == 0);
    CHECK(f1[6] == 0 && f1[0] > 0);
    CHECK(atomic_load(&w.calls) == 1 && atomic_load(&w.pairs) == 3); /* one call for the three */
    CHECK(sb_source_eval(b, wi + 3, wo + 3, one) == 1 && memcmp(one, f1 + 3, sizeof one) == 0);
    CHECK(atomic_load(&w.calls) == 2 && atomic_load(&w.pairs) == 4);
    CHECK(sb_source_eval_many(NULL, 3, wi, wo, f1, k1) == 0 && sb_source_eval_many(b, 3, NULL, wo, f1, k1) == 0);
    CHECK(sb_source_eval_many(b, 0, wi, wo, f1, k1) == 0);
    sb_source_destroy(b);
    CHECK(w.destroyed == 1);
    sb_source_destroy(model);
}

/* The job on the wrapper equals the job on the model, bit for bit, with
 * far fewer calls than pairs. */
SB_TEST(job_equals_pairwise) {
    static const char *const params[] = {"iso", "hd", "io"};
    for (int i = 0; i < 3; i++) {
        sb_source_t *model = NULL, *b = NULL;
        CHECK(sb_source_open(NULL, "modified-phong:n=12", &model) == SB_OK);
        wrap_t w = {.inner = model};
        CHECK(sb_source_create_batched(NULL, &wrap_ops, &w, sb_source_flags(model), "wrapped", &b) == SB_OK);
        sb_job_opts_t o = {0};
        o.param = params[i];
        o.res = 8;
        o.terms = 2;
        sb_job_t *ja = NULL, *jb = NULL;
        CHECK(sb_job_run_source(NULL, model, &o, &ja) == SB_OK);
        CHECK(sb_job_run_source(NULL, b, &o, &jb) == SB_OK);
        if (ja && jb) {
            const sb_factors_t *fa = sb_job_factors(ja), *fb = sb_job_factors(jb);
            for (int side = 0; side < 2; side++)
                for (size_t j = 0; j < 2; j++)
                    for (size_t c = 0; c < sb_factors_channels(fa); c++) {
                        size_t tw, th;
                        sb_factors_size(fa, side, &tw, &th);
                        CHECKF(memcmp(sb_factors_tex_const(fa, side, j, c), sb_factors_tex_const(fb, side, j, c),
                                      tw * th * sizeof(double)) == 0,
                               "%s: texture %d %zu %zu differs", params[i], side, j, c);
                    }
            CHECK(sb_job_headline(ja, 2) == sb_job_headline(jb, 2));
            size_t calls = atomic_load(&w.calls), pairs = atomic_load(&w.pairs);
            CHECKF(pairs > 1000 && calls * 8 < pairs, "%s: %zu pairs in %zu calls", params[i], pairs, calls);
            printf("  %-4s %zu pairs in %zu calls\n", params[i], pairs, calls);
        }
        sb_job_destroy(ja);
        sb_job_destroy(jb);
        sb_source_destroy(b);
        sb_source_destroy(model);
    }
}
