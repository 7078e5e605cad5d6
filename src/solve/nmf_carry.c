/* The non-negative solver's carry (solver.h, nmf_state.h): the state of a
 * fit after its last round toward the headline's ratios, per channel, for
 * an execute of another plan that asks for more rounds.  The factor job's
 * refit k runs k rounds from the kept fit (job_screen.c job_nonneg_refit),
 * so refit 2's round 0 repeated refit 1's bit for bit: RGL
 * cc_green_malachite, a fifth of `factor --method nmf`'s instructions
 * (docs/positive.md, rounds h38t2 and h38t3).  What a round reads from
 * the rounds before is out's terms, the reference (uref, vref: the SVD's
 * or the masked fit's, taken once per fit), the kept mix and the damped
 * corrections; the rest (the cells' weights, the headline's, the
 * reference's errors) it makes again from the data, as every round does. */
#include <stdlib.h>
#include <string.h>

#include "solve/nmf_state.h"
#include "solve/solver.h"

/* What a fit's rounds depend on besides the data, the ratios and the
 * state kept: the layout and form (the headline's weights) and the
 * solver's settings. */
typedef struct carry_key {
    const void *param;
    int form, max_iters, polish_steps, first_fit, zero_fill, masked, nt;
    double tol, fill;
} carry_key_t;

typedef struct carry_ch {
    size_t rounds;             /* rounds held (0: none) */
    carry_key_t key;           /* of the fit held */
    double *x;                 /* m x n: its data and targets (s->x) */
    unsigned char *ext;        /* m x n: its cells' kinds (s->ext) */
    double *rho;               /* cap x J: the ratios of its rounds */
    double *u, *v, *uref, *vref; /* m x J, n x J: its terms after the rounds; the reference */
    double kept_mix;
    int iterations, converged;
    double cpprev[SB_NMF_MAX_TERMS], calprev[SB_NMF_MAX_TERMS];
} carry_ch_t;

struct sb_nmf_carry {
    size_t m, n, J, cap; /* the buffers' sizes: matrices m x n, J terms, cap rounds of ratios */
    size_t resumed;      /* executes that started from it */
    carry_ch_t ch[3];
};

static void clear(sb_nmf_carry_t *c) {
    for (int k = 0; k < 3; k++) {
        carry_ch_t *h = &c->ch[k];
        free(h->x);
        free(h->ext);
        free(h->rho);
        free(h->u);
        free(h->v);
        free(h->uref);
        free(h->vref);
    }
    size_t resumed = c->resumed;
    memset(c, 0, sizeof *c);
    c->resumed = resumed;
}

sb_nmf_carry_t *sb_nmf_carry_create(void) { return calloc(1, sizeof(sb_nmf_carry_t)); }

void sb_nmf_carry_destroy(sb_nmf_carry_t *c) {
    if (!c) return;
    clear(c);
    free(c);
}

size_t sb_nmf_carry_resumed(const sb_nmf_carry_t *c) { return c ? c->resumed : 0; }

/* Step: c's buffers for s's matrices and rounds (what it held is kept
 * where the sizes are the same); 0 when out of memory, c then empty. */
static int fit_to(sb_nmf_carry_t *c, const nmf_state_t *s) {
    size_t m = s->m, n = s->n, J = s->J, cells = m * n;
    if (c->m != m || c->n != n || c->J != J) {
        clear(c);
        c->m = m, c->n = n, c->J = J;
        for (int k = 0; k < 3; k++) {
            carry_ch_t *h = &c->ch[k];
            h->x = malloc(cells * sizeof *h->x);
            h->ext = malloc(cells);
            h->u = malloc(m * J * sizeof *h->u);
            h->uref = malloc(m * J * sizeof *h->uref);
            h->v = malloc(n * J * sizeof *h->v);
            h->vref = malloc(n * J * sizeof *h->vref);
            if (!h->x || !h->ext || !h->u || !h->uref || !h->v || !h->vref) {
                clear(c);
                return 0;
            }
        }
    }
    for (int k = 0; c->cap < s->rounds && k < 3; k++) {
        double *r = realloc(c->ch[k].rho, s->rounds * J * sizeof *r);
        if (!r) {
            clear(c);
            return 0;
        }
        c->ch[k].rho = r;
    }
    c->cap = c->cap < s->rounds ? s->rounds : c->cap;
    return 1;
}

/* Only where sb_nmf_fit_mixes makes the rounds with a first mix's
 * weights (s->w0: the weights a round starts from are those, not the
 * ones the round before left) and damp's corrections fit in the state. */
void sb_solver_nmf_carry(void *state, sb_nmf_carry_t *c) {
    nmf_state_t *s = state;
    if (s) s->carry = c && s->w0 && s->J <= SB_NMF_MAX_TERMS && fit_to(c, s) ? c : NULL;
}

static carry_key_t key_of(const nmf_state_t *s, const sb_solve_in_t *in) {
    carry_key_t k = {in->param,    in->m ? (int)in->m->form : -1, s->max_iters, s->polish_steps, s->first_fit,
                     s->zero_fill, s->fit != NULL,                s->nt,        s->tol,          s->fill};
    return k;
}

static int same_key(const carry_key_t *a, const carry_key_t *b) {
    return a->param == b->param && a->form == b->form && a->max_iters == b->max_iters &&
           a->polish_steps == b->polish_steps && a->first_fit == b->first_fit && a->zero_fill == b->zero_fill &&
           a->masked == b->masked && a->nt == b->nt && a->tol == b->tol && a->fill == b->fill;
}

/* The carry's channel for s's execute; NULL: none. */
static carry_ch_t *channel_of(const nmf_state_t *s) {
    if (!s->carry || !s->w0 || !s->rho_all || s->channel < 0 || s->channel > 2) return NULL;
    return &s->carry->ch[s->channel];
}

void sb_nmf_carry_save(nmf_state_t *s, const sb_solve_in_t *in, const sb_solve_out_t *out) {
    carry_ch_t *h = channel_of(s);
    if (!h) return;
    size_t m = s->m, n = s->n, J = s->J;
    memcpy(h->x, s->x, m * n * sizeof *h->x);
    memcpy(h->ext, s->ext, m * n);
    memcpy(h->u, out->u, m * J * sizeof *h->u);
    memcpy(h->v, out->v, n * J * sizeof *h->v);
    memcpy(h->uref, s->uref, m * J * sizeof *h->uref);
    memcpy(h->vref, s->vref, n * J * sizeof *h->vref);
    for (size_t k = 0; k < s->rounds; k++)
        memcpy(h->rho + k * J, sb_nmf_rho(s, k), J * sizeof *h->rho);
    memcpy(h->cpprev, s->cpprev, sizeof h->cpprev);
    memcpy(h->calprev, s->calprev, sizeof h->calprev);
    h->kept_mix = s->kept_mix;
    h->iterations = out->iterations;
    h->converged = out->converged;
    h->key = key_of(s, in);
    h->rounds = s->rounds;
}

size_t sb_nmf_carry_take(nmf_state_t *s, const sb_solve_in_t *in, sb_solve_out_t *out) {
    carry_ch_t *h = channel_of(s);
    size_t m = s->m, n = s->n, J = s->J, r = h ? h->rounds : 0;
    carry_key_t key = key_of(s, in);
    if (!(r >= 1 && r < s->rounds) || !same_key(&h->key, &key) || memcmp(h->x, s->x, m * n * sizeof *h->x) != 0 ||
        memcmp(h->ext, s->ext, m * n) != 0)
        return 0;
    for (size_t k = 0; k < r; k++)
        if (memcmp(h->rho + k * J, sb_nmf_rho(s, k), J * sizeof *h->rho) != 0) return 0;
    memcpy(out->u, h->u, m * J * sizeof *h->u);
    memcpy(out->v, h->v, n * J * sizeof *h->v);
    memcpy(s->uref, h->uref, m * J * sizeof *h->uref);
    memcpy(s->vref, h->vref, n * J * sizeof *h->vref);
    memcpy(s->cpprev, h->cpprev, sizeof h->cpprev);
    memcpy(s->calprev, h->calprev, sizeof h->calprev);
    s->kept_mix = h->kept_mix;
    out->iterations = h->iterations;
    out->converged = h->converged;
    s->carry->resumed++;
    return r;
}
