/* The non-negative solver's carry (src/solve/nmf_carry.c): an execute
 * asking for two rounds toward the headline's ratios starts from the
 * state a one-round execute of another plan kept, and gives the terms the
 * two rounds made from the start give, bit for bit; a fit made again from
 * the same inputs takes the kept one whole; a carry made from other data
 * or other ratios is not taken. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "job/job_impl.h" /* not exported, in the static archive */
#include "sepbrdf/sepbrdf.h"
#include "solve/nmf_state.h" /* the same */
#include "solve/solver.h"

/* Made-up headline ratios, two rounds of J = 4 (the job's are each fit's
 * estimate over the SVD's): far enough from 1 that the rounds move the fit. */
static const double rho_a[8] = {1.3, 1.9, 1.2, 1.7, 1.1, 1.6, 1.4, 1.5};
static const double rho_b[8] = {1.3, 1.9, 1.2, 1.6, 1.1, 1.6, 1.4, 1.5}; /* round 0 differs */

typedef struct fitted {
    double *buf;
    sb_solve_out_t out;
} fitted_t;

/* One channel of mat fitted with `rounds` rounds of rho on a plan of its
 * own, with carry (NULL: none). */
static fitted_t fit(const sb_matrix_t *mat, const double *x, const sb_param_t *p, const double *rho, size_t rounds,
                    sb_nmf_carry_t *carry) {
    size_t m = mat->rows, n = mat->cols, J = 4;
    sb_solve_problem_t pb = {0};
    pb.rows = m, pb.cols = n, pb.terms = J;
    pb.masked = mat->mask != NULL, pb.zero_fill = 1;  /* as the job fits vndf in cos */
    pb.nonneg_ratio = rho, pb.nonneg_rounds = rounds; /* rho NULL: a fit without ratios */
    void *state = NULL;
    CHECK(sb_solver_nmf.plan(NULL, &pb, &state) == SB_OK);
    fitted_t f = {calloc(J + (m + n) * J, sizeof(double)), {0}};
    CHECK(f.buf != NULL);
    f.out = (sb_solve_out_t){f.buf, f.buf + J, f.buf + J + m * J, 0, 1, 0};
    CHECKF(((nmf_state_t *)state)->w0 != NULL, "%zu x %zu: no mixes, no rounds to carry", m, n);
    sb_solver_nmf_carry(state, carry);
    sb_solve_in_t in = {x, mat->ld, x, mat->ld, mat->mask, NULL, NULL, 1, p, mat, 1};
    CHECK(sb_solver_nmf.execute(state, &in, &f.out) == SB_OK);
    sb_solver_nmf.destroy(state);
    return f;
}

static int same(const fitted_t *a, const fitted_t *b, size_t m, size_t n) {
    size_t J = 4;
    return !memcmp(a->buf, b->buf, (J + (m + n) * J) * sizeof *a->buf) && a->out.iterations == b->out.iterations &&
           a->out.converged == b->out.converged;
}

/* The green channel of src on p in form `form` (cells out of the data, if
 * any, fitted as zeros, as the job's refits have them): resumed where it
 * should be, the same terms as the rounds made again, and not taken from
 * other data or another round 0; a fit without ratios taken whole on a
 * layout on the source's tables (p2: the same layout, another object),
 * and not kept on the others. */
static void case_on(const char *what, sb_source_t *src, sb_param_t *p, sb_param_t *p2, sb_form_t form) {
    sb_matrix_t mat;
    sb_matrix_opts_t mo = {0};
    mo.form = form;
    CHECK(sb_matrix_build(NULL, src, p, &mo, &mat) == SB_OK);
    CHECKF(mat.data[1] != NULL, "%s: no green", what);
    size_t m = mat.rows, n = mat.cols, cells = mat.ld * n;
    int tables = (sb_param_caps(p) & SB_CAP_TABLES) != 0;
    sb_nmf_carry_t *carry = sb_nmf_carry_create();
    CHECK(carry != NULL);
    fitted_t one = fit(&mat, mat.data[1], p, rho_a, 1, carry);
    fitted_t two = fit(&mat, mat.data[1], p, rho_a, 2, carry);
    CHECKF(sb_nmf_carry_resumed(carry) == 1, "%s: the two-round fit did not start from the carry", what);
    fitted_t again = fit(&mat, mat.data[1], p, rho_a, 2, NULL);
    CHECKF(same(&two, &again, m, n), "%s: resumed, the terms differ from the two rounds made again", what);
    CHECKF(!same(&one, &again, m, n), "%s: round 1 changed nothing: the check above tested nothing", what);
    fprintf(stderr, "%s %zu x %zu: %d sweeps in one round, %d in two, the same resumed\n", what, m, n,
            one.out.iterations, again.out.iterations);
    /* other data (green times 1 + 1e-9): the carry is not taken */
    double *y = malloc(cells * sizeof *y);
    CHECK(y != NULL);
    for (size_t k = 0; k < cells; k++)
        y[k] = mat.data[1][k] * (1 + 1e-9);
    fitted_t other = fit(&mat, y, p, rho_a, 2, carry);
    fitted_t other_fresh = fit(&mat, y, p, rho_a, 2, NULL);
    CHECKF(sb_nmf_carry_resumed(carry) == 1 && sb_nmf_carry_reused(carry) == 0, "%s: a fit of other data was taken",
           what);
    CHECKF(same(&other, &other_fresh, m, n), "%s: other data: not the fit made without the carry", what);
    /* another round 0: not taken either; the same round 0 again: taken whole */
    fitted_t keep = fit(&mat, mat.data[1], p, rho_a, 1, carry);
    fitted_t moved = fit(&mat, mat.data[1], p, rho_b, 2, carry);
    CHECKF(sb_nmf_carry_resumed(carry) == 1, "%s: a fit toward other ratios was taken", what);
    fitted_t moved_fresh = fit(&mat, mat.data[1], p, rho_b, 2, NULL);
    CHECKF(same(&moved, &moved_fresh, m, n), "%s: other ratios: not the fit made without the carry", what);
    fitted_t keep2 = fit(&mat, mat.data[1], p, rho_a, 1, carry);
    CHECKF(sb_nmf_carry_reused(carry) == 1 && same(&keep, &keep2, m, n) && same(&keep, &one, m, n),
           "%s: the one-round fit again: not taken whole, or not the same", what);
    /* without ratios (the screening's and the kept fit): kept on the tables alone */
    fitted_t plain = fit(&mat, mat.data[1], p, NULL, 0, carry);
    fitted_t plain2 = fit(&mat, mat.data[1], p2, NULL, 0, carry);
    CHECKF(sb_nmf_carry_reused(carry) == 1 + (size_t)tables, "%s: a fit without ratios %s", what,
           tables ? "not taken on the source's tables" : "taken off the source's tables");
    CHECKF(same(&plain, &plain2, m, n), "%s: a fit without ratios again: not the same", what);
    fitted_t *all[] = {&one, &two, &again, &other, &other_fresh, &keep, &moved, &moved_fresh, &keep2, &plain, &plain2};
    for (size_t k = 0; k < sizeof all / sizeof all[0]; k++)
        free(all[k]->buf);
    free(y);
    sb_nmf_carry_destroy(carry);
    sb_matrix_free(&mat);
}

/* io at 8 cells (64 x 64: every mix), and RGL chm_orange on its own
 * tables in cos (vndf: the rounds' minimax in the spread weights,
 * calibrated), as the factor job's refits fit them. */
SB_TEST(carry_resumes_the_same_terms) {
    sb_source_t *src = NULL;
    CHECK(sb_model_create(NULL, "cook-torrance:roughness=0.2", &src) == SB_OK);
    sb_param_t *p = NULL, *p2 = NULL;
    sb_param_opts_t po = {0};
    po.res = 8;
    CHECK(sb_param_create(NULL, SB_PARAM_IO, &po, &p) == SB_OK &&
          sb_param_create(NULL, SB_PARAM_IO, &po, &p2) == SB_OK);
    case_on("cook-torrance 0.2 on io", src, p, p2, SB_FORM_F);
    sb_param_destroy(p);
    sb_param_destroy(p2);
    sb_source_destroy(src);

    CHECK(sb_measured_open(NULL, SB_MEASURED_DIR "/rgl_chm_orange_rgb.bsdf", NULL, &src, NULL) == SB_OK);
    sb_param_kind_t k;
    sb_param_opts_t vo = {0};
    vo.tables = sb_source_layout_tables(src);
    CHECK(sb_param_kind_parse("vndf", &k) == SB_OK && sb_param_create(NULL, k, &vo, &p) == SB_OK);
    vo.res = 32; /* as the kept fit's; the screening's at 8 */
    CHECK(sb_param_create(NULL, k, &vo, &p2) == SB_OK);
    case_on("RGL chm_orange on vndf, cos", src, p, p2, SB_FORM_COS);
    sb_param_destroy(p);
    sb_param_destroy(p2);
    sb_source_destroy(src);
}

/* `factor PATH -J 4 --method nmf` as a library call, job_nonneg_same_check
 * as given. */
static sb_job_t *nmf_job(const char *path, int check) {
    sb_context_t *ctx = NULL;
    CHECK(sb_context_create(&ctx) == SB_OK);
    sb_job_opts_t o = {.source = path, .terms = 4, .method = SB_METHOD_NMF};
    sb_job_t *job = NULL;
    job_nonneg_same_check = check;
    CHECKF(sb_job_run(ctx, &o, &job) == SB_OK, "%s: %s", path, sb_context_last_error(ctx));
    job_nonneg_same_check = 1;
    sb_context_destroy(ctx);
    return job;
}

/* Whether two jobs kept the same factors and estimate, bit for bit. */
static int jobs_same(const sb_job_t *a, const sb_job_t *b) {
    const sb_factors_t *fa = sb_job_factors(a), *fb = sb_job_factors(b);
    size_t J = sb_factors_terms(fa), C = sb_factors_channels(fa);
    if (J != sb_factors_terms(fb) || C != sb_factors_channels(fb)) return 0;
    for (size_t j = 0; j < J; j++)
        for (size_t c = 0; c < C; c++)
            for (int s = 0; s < 2; s++) {
                size_t w, h;
                sb_factors_size(fa, s, &w, &h);
                double sa = sb_factors_sigma(fa, j, c), sb = sb_factors_sigma(fb, j, c);
                const double *ta = sb_factors_tex_const(fa, s, j, c), *tb = sb_factors_tex_const(fb, s, j, c);
                if (memcmp(&sa, &sb, sizeof sa) != 0 || (ta == NULL) != (tb == NULL) ||
                    (ta && memcmp(ta, tb, w * h * sizeof *ta) != 0))
                    return 0;
            }
    const sb_estimate_t *ea = sb_job_estimate(a), *eb = sb_job_estimate(b);
    if (!ea || !eb || ea->replicates != eb->replicates || ea->pairs != eb->pairs ||
        memcmp(ea->reps, eb->reps, sizeof ea->reps) != 0 || memcmp(ea->rel, eb->rel, sizeof ea->rel) != 0 ||
        memcmp(ea->se, eb->se, sizeof ea->se) != 0 || memcmp(ea->p99, eb->p99, sizeof ea->p99) != 0)
        return 0;
    for (size_t j = 1; j <= J; j++) {
        double sa = sb_job_svd_headline(a, j), sb = sb_job_svd_headline(b, j);
        if (memcmp(&sa, &sb, sizeof sa) != 0) return 0;
    }
    return 1;
}

/* The job's last refit (job_screen.c nonneg_refit_once) where it gives the
 * refit before's factors bit for bit (RGL paper_white: its second round
 * moves nothing) is not measured in full nor refined, and dropped: the job
 * keeps the same factors and figures as with the refit made in full.
 * Where it differs (RGL aurora_white: kept) it is made in full. */
#define PAPER SB_MEASURED_DIR "/rgl_paper_white_rgb.bsdf"
SB_TEST(last_refit_the_same_not_measured_again) {
    sb_job_t *skip = nmf_job(PAPER, 1), *full = nmf_job(PAPER, 0);
    CHECKF(skip && skip->nonneg_same == 1, "paper: the second refit not found the same as the first (%d)",
           skip ? skip->nonneg_same : -1);
    CHECKF(full && full->nonneg_same == 0, "paper, made in full: the second refit found the same");
    CHECKF(skip && full && jobs_same(skip, full), "paper: the job kept other factors or figures than made in full");
    sb_job_destroy(skip);
    sb_job_destroy(full);
    sb_job_t *aurora = nmf_job(SB_MEASURED_DIR "/rgl_aurora_white_rgb.bsdf", 1);
    CHECKF(aurora && aurora->nonneg_same == 0, "aurora: its second refit (kept) taken for the first");
    sb_job_destroy(aurora);
}
