/* The estimator's prefixes as runs of their own (estimate.h: reps): the
 * figures of J' = 1..J of an estimate of J terms, and the term weights of
 * its first J' terms, equal those of an estimate of the J' leading terms
 * alone, in a case where the replicates grow from one prefix to the next
 * (before, every prefix was computed from the replicates the J-term run
 * grew to, so `study`'s nested rows parted from separate `factor` runs). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"

/* The rank-J SVD of `spec` on io at R cells (f, weighted). */
static sb_factors_t *fit(const char *spec, size_t R, size_t J, sb_param_t **param, sb_source_t **src) {
    sb_param_opts_t po = {0};
    po.res = R;
    sb_matrix_opts_t mo = {0};
    sb_plan_opts_t pl = {0};
    pl.terms = J;
    pl.weighted = 1;
    sb_matrix_t m = {0};
    sb_plan_t *plan = NULL;
    sb_factors_t *f = NULL;
    CHECK(sb_source_open(NULL, spec, src) == SB_OK);
    CHECK(sb_param_create(NULL, SB_PARAM_IO, &po, param) == SB_OK);
    CHECK(sb_matrix_build(NULL, *src, *param, &mo, &m) == SB_OK);
    CHECK(sb_plan_create(NULL, m.rows, m.cols, &pl, &plan) == SB_OK);
    CHECK(sb_plan_execute(plan, &m, *param, &f) == SB_OK);
    sb_plan_destroy(plan);
    sb_matrix_free(&m);
    return f;
}

/* The first J terms of f (textures and sigma). */
static sb_factors_t *leading(const sb_factors_t *f, size_t J) {
    size_t C = sb_factors_channels(f), w[2], h[2];
    for (int s = 0; s < 2; s++)
        sb_factors_size(f, s, &w[s], &h[s]);
    sb_factors_t *g = NULL;
    CHECK(sb_factors_create(NULL, J, C, w[0], h[0], w[1], h[1], &g) == SB_OK);
    for (size_t j = 0; j < J; j++)
        for (size_t c = 0; c < C; c++) {
            for (int s = 0; s < 2; s++)
                memcpy(sb_factors_tex(g, s, j, c), sb_factors_tex_const(f, s, j, c), w[s] * h[s] * sizeof(double));
            sb_factors_set_sigma(g, j, c, sb_factors_sigma(f, j, c));
        }
    return g;
}

/* Row j of every per-prefix figure of a and b equal to the bit. */
static int same_row(const sb_estimate_t *a, const sb_estimate_t *b, size_t j) {
#define SAME(x) (memcmp(&a->x[j], &b->x[j], sizeof a->x[j]) == 0)
    return SAME(rel) && SAME(se) && SAME(p99) && SAME(max_rel) && SAME(neg_frac) && SAME(overshoot) &&
           SAME(chroma_de) && SAME(band) && SAME(band_se) && SAME(p99_lit) && SAME(max_rel_lit) && SAME(min_rel) &&
           SAME(reps);
#undef SAME
}

SB_TEST(prefixes_equal_their_own_runs) {
    enum { J = 5 };
    sb_param_t *p = NULL;
    sb_source_t *src = NULL;
    sb_factors_t *f = fit("microfacet:roughness=0.4", 8, J, &p, &src);
    sb_estimate_opts_t o = {0};
    o.replicate = 512; /* small replicates: the standard error needs more of them from one J' to another */
    o.start = 4;
    o.max_pairs = 64 * 512;
    static sb_estimate_t all, own;
    double w_all[J * 3], w_own[J * 3];
    sb_pairs_t *pairs = NULL;
    CHECK(f && sb_pairs_create(NULL, src, &o, &pairs) == SB_OK);
    CHECK(sb_estimate_compute(NULL, pairs, f, NULL, p, SB_FORM_F, &o, &all) == SB_OK);
    CHECK(sb_estimate_term_weights(NULL, pairs, f, NULL, p, SB_FORM_F, all.reps, w_all) == SB_OK);
    sb_pairs_destroy(pairs);
    size_t C = sb_factors_channels(f);
    for (size_t j = 0; j < J; j++)
        printf("  J'=%zu headline %.5f se %.5f replicates %zu weight %.4f\n", j + 1, all.rel[j][SB_EST_FCOS][3],
               all.se[j][SB_EST_FCOS][3], all.reps[j], w_all[j * C]);
    CHECKF(all.converged && all.reps[0] < all.reps[J - 1] && all.reps[J - 1] == all.replicates,
           "the case must grow the replicates from J' = 1 to %d: %zu, %zu", J, all.reps[0], all.reps[J - 1]);
    for (size_t jp = 1; jp <= J; jp++) {
        sb_factors_t *g = leading(f, jp);
        pairs = NULL;
        CHECK(sb_pairs_create(NULL, src, &o, &pairs) == SB_OK);
        CHECK(sb_estimate_compute(NULL, pairs, g, NULL, p, SB_FORM_F, &o, &own) == SB_OK);
        CHECK(sb_estimate_term_weights(NULL, pairs, g, NULL, p, SB_FORM_F, own.reps, w_own) == SB_OK);
        CHECK(own.replicates == all.reps[jp - 1] && own.converged);
        for (size_t j = 0; j < jp; j++) {
            CHECKF(same_row(&all, &own, j), "J' = %zu of %d terms against a run of %zu terms", j + 1, J, jp);
            /* the target met where the prefix was taken (the bound is above se) */
            CHECK(all.se[j][SB_EST_FCOS][3] <= SB_EST_REL_SE * all.rel[j][SB_EST_FCOS][3]);
        }
        CHECKF(memcmp(w_all, w_own, jp * C * sizeof *w_own) == 0, "the weights of %zu terms", jp);
        sb_pairs_destroy(pairs);
        sb_factors_destroy(g);
    }
    /* counts out of order are refused */
    size_t bad[J] = {4, 3, 4, 4, 4};
    pairs = NULL;
    CHECK(sb_pairs_create(NULL, src, &o, &pairs) == SB_OK);
    CHECK(sb_estimate_term_weights(NULL, pairs, f, NULL, p, SB_FORM_F, bad, w_own) == SB_ERR_ARG);
    sb_pairs_destroy(pairs);
    sb_factors_destroy(f);
    sb_param_destroy(p);
    sb_source_destroy(src);
}

/* A lean estimate (headline_only with bands, every J': what the factor
 * job's choice and refinement of a layout's two forms read, job_forms.c)
 * equals the whole one in every figure it has, to the bit, where the
 * replicates grow from one prefix to the next; the whole one is made
 * after it on the same pairs, as the job makes the kept fit's. */
SB_TEST(lean_equals_whole) {
    enum { J = 5 };
    sb_param_t *p = NULL;
    sb_source_t *src = NULL;
    sb_factors_t *f = fit("microfacet:roughness=0.4", 8, J, &p, &src);
    sb_estimate_opts_t o = {0}, lo;
    o.replicate = 512;
    o.start = 4;
    o.max_pairs = 64 * 512;
    lo = o;
    lo.headline_only = 1;
    lo.bands = 1;
    static sb_estimate_t whole, lean;
    sb_pairs_t *pairs = NULL;
    CHECK(f && sb_pairs_create(NULL, src, &o, &pairs) == SB_OK);
    CHECK(sb_estimate_compute(NULL, pairs, f, NULL, p, SB_FORM_F, &lo, &lean) == SB_OK);
    CHECK(sb_estimate_compute(NULL, pairs, f, NULL, p, SB_FORM_F, &o, &whole) == SB_OK);
    CHECKF(whole.reps[0] < whole.reps[J - 1], "the case must grow the replicates: %zu, %zu", whole.reps[0],
           whole.reps[J - 1]);
    CHECK(lean.converged == whole.converged && lean.replicates == whole.replicates && lean.terms == whole.terms);
    CHECK(memcmp(lean.band_share, whole.band_share, sizeof lean.band_share) == 0);
    for (size_t j = 0; j < J; j++) {
#define SAME(x) (memcmp(&lean.x[j], &whole.x[j], sizeof lean.x[j]) == 0)
        CHECKF(SAME(rel) && SAME(se) && SAME(reps) && SAME(band) && SAME(band_se), "J' = %zu", j + 1);
#undef SAME
        CHECK(sb_estimate_bands_bounded(&lean, j + 1) == sb_estimate_bands_bounded(&whole, j + 1));
        CHECK(lean.p99[j][3] == 0 && whole.p99[j][3] > 0); /* lean: no percentiles */
    }
    sb_pairs_destroy(pairs);
    sb_factors_destroy(f);
    sb_param_destroy(p);
    sb_source_destroy(src);
}
