/* The non-negative solver's last steps (src/solve/nmf_mixes.c polish):
 * the kept fit moved by safeguarded steps toward the least worst prefix
 * against the reference, in the headline's weights.  The fit with the
 * steps is never worse by that measure than the same fit without them. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"
#include "solve/nmf_state.h" /* not exported, in the static archive */
#include "solve/nmf_weights.h"

extern const sb_solver_t sb_solver_nmf;

/* The worst prefix of the terms in out (s_j u_j, v_j) against the
 * solver's reference, in the headline's weights it fitted with. */
static double worst(const nmf_state_t *s, const sb_solve_out_t *out) {
    size_t m = s->m, n = s->n, J = s->J;
    double *U = malloc(m * J * sizeof *U);
    CHECK(U != NULL);
    for (size_t j = 0; j < J; j++)
        for (size_t i = 0; i < m; i++)
            U[i + j * m] = out->s[j] * out->u[i + j * m];
    double w = sb_nmf_worst_ratio(s->x, s->hw, m, n, J, U, out->v, s->uref, s->vref, s->floor2);
    free(U);
    return w;
}

/* One channel of spec on kind at R cells, J = 4: the matrix, the solver's
 * plan (state) and its input. */
typedef struct {
    sb_source_t *src;
    sb_param_t *p;
    sb_matrix_t mat;
    sb_context_t *ctx;
    void *state;
    sb_solve_in_t in;
    size_t m, n, J;
} nmf_case_t;

static void case_open(nmf_case_t *c, const char *spec, sb_param_kind_t kind, size_t R) {
    memset(c, 0, sizeof *c);
    CHECKF(sb_model_create(NULL, spec, &c->src) == SB_OK, "model %s", spec);
    sb_param_opts_t po = {0};
    po.res = R;
    CHECK(sb_param_create(NULL, kind, &po, &c->p) == SB_OK);
    CHECK(sb_matrix_build(NULL, c->src, c->p, NULL, &c->mat) == SB_OK);
    c->m = c->mat.rows, c->n = c->mat.cols, c->J = 4;
    sb_solve_problem_t pb = {0};
    pb.rows = c->m, pb.cols = c->n, pb.terms = c->J, pb.masked = c->mat.mask != NULL;
    sb_context_create(&c->ctx);
    CHECK(sb_solver_nmf.plan(c->ctx, &pb, &c->state) == SB_OK);
    int ch = c->mat.data[1] ? 1 : 0;
    c->in = (sb_solve_in_t){c->mat.data[ch], c->mat.ld, c->mat.data[ch], c->mat.ld, c->mat.mask, NULL, NULL, 1, c->p,
                            &c->mat,         ch};
}

static void case_close(nmf_case_t *c) {
    sb_solver_nmf.destroy(c->state);
    sb_context_destroy(c->ctx);
    sb_matrix_free(&c->mat);
    sb_param_destroy(c->p);
    sb_source_destroy(c->src);
}

/* Fit k of a case's fits in buf (J + (m + n) J numbers each). */
static sb_solve_out_t case_out(const nmf_case_t *c, double *buf, int k) {
    size_t size = c->J + (c->m + c->n) * c->J;
    return (sb_solve_out_t){buf + k * size, buf + k * size + c->J, buf + k * size + c->J + c->m * c->J, 0, 1, 0};
}

/* One channel of spec on kind at R cells, J = 4, fitted without the steps
 * twice (the same fit: the solver is deterministic) and with them;
 * returns how much the steps lowered the worst prefix. */
static double case_at(const char *spec, sb_param_kind_t kind, size_t R) {
    nmf_case_t c;
    case_open(&c, spec, kind, R);
    size_t m = c.m, n = c.n, J = c.J;
    nmf_state_t *s = c.state;
    CHECKF(s && s->u1, "%s: no polish on %zu x %zu cells", spec, m, n);
    double *buf = malloc(3 * (J + (m + n) * J) * sizeof *buf);
    CHECK(buf != NULL);
    sb_solve_out_t out[3];
    double w[3];
    for (int k = 0; k < 3; k++) {
        out[k] = case_out(&c, buf, k);
        s->polish_steps = k < 2 ? 0 : SB_NMF_POLISH_STEPS;
        CHECK(sb_solver_nmf.execute(c.state, &c.in, &out[k]) == SB_OK);
        w[k] = worst(s, &out[k]);
    }
    fprintf(stderr, "%-40s %zu x %zu: worst prefix (squared ratio) %.4f without the steps, %.4f with\n", spec, m, n,
            w[0], w[2]);
    CHECKF(w[0] == w[1], "%s: the fit without the steps is not reproduced (%g, %g)", spec, w[0], w[1]);
    CHECKF(isfinite(w[2]) && w[2] <= w[0], "%s: the steps raised the worst prefix %g -> %g", spec, w[0], w[2]);
    for (size_t k = 0; k < (m + n) * J; k++)
        CHECKF(out[2].u[k] >= 0, "%s: a negative factor entry after the steps", spec);
    free(buf);
    case_close(&c);
    return w[0] - w[2];
}

/* Cases where the steps move the fit (at 8 cells: on hd a worst squared
 * ratio 4.70 -> 3.04, on io 1.18 -> 1.00), masked and not. */
SB_TEST(polish_never_raises_the_worst_prefix) {
    double gain = case_at("cook-torrance:d=ggx,roughness=0.3", SB_PARAM_HD, 8);
    gain = fmax(gain, case_at("cook-torrance:roughness=0.2", SB_PARAM_IO, 8));
    CHECKF(gain > 0, "no case where the steps lower the worst prefix: the check above tested nothing");
}

/* The solver's whole fit of one channel of spec on kind at R cells, J = 4,
 * with its sweeps fused (nmf_sweeps.c sweep: a term's columns and the next
 * term's rows in one pass over each column) and pass by pass (s->apart):
 * the same bits, terms and sweeps, in two column parts where the matrix is
 * large enough (SEPBRDF_THREADS=2 unless set).  Returns the sweeps. */
static int fused_case(const char *spec, sb_param_kind_t kind, size_t R) {
    nmf_case_t c;
    case_open(&c, spec, kind, R);
    size_t size = c.J + (c.m + c.n) * c.J;
    nmf_state_t *s = c.state;
    double *buf = calloc(2 * size, sizeof *buf);
    CHECK(buf != NULL);
    sb_solve_out_t out[2];
    for (int k = 0; k < 2; k++) {
        out[k] = case_out(&c, buf, k);
        s->apart = k;
        CHECK(sb_solver_nmf.execute(c.state, &c.in, &out[k]) == SB_OK);
    }
    fprintf(stderr, "%-40s %zu x %zu: %d sweeps, fused and apart\n", spec, c.m, c.n, out[0].iterations);
    CHECKF(out[0].iterations == out[1].iterations && out[0].converged == out[1].converged,
           "%s: %d sweeps fused, %d apart", spec, out[0].iterations, out[1].iterations);
    CHECKF(!memcmp(buf, buf + size, size * sizeof *buf), "%s: the fused sweeps' terms are not the same bits", spec);
    int sweeps = out[0].iterations;
    free(buf);
    case_close(&c);
    return sweeps;
}

/* Masked (iso: the default gold at 32 cells, 64 x 992, its minimax; hd)
 * and not (io). */
SB_TEST(fused_sweeps_same_bits) {
    setenv("SEPBRDF_THREADS", "2", 0);
    int sweeps = fused_case(SB_JOB_DEFAULT_SOURCE, SB_PARAM_ISO, 32);
    sweeps += fused_case("cook-torrance:d=ggx,roughness=0.3", SB_PARAM_HD, 8);
    sweeps += fused_case("cook-torrance:roughness=0.2", SB_PARAM_IO, 8);
    CHECKF(sweeps > 0, "no sweep ran: the comparison tested nothing");
}
