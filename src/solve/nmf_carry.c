/* The non-negative solver's carry (solver.h, nmf_state.h): fits the
 * factor job repeats, kept per channel for an execute of another plan.
 *  - Its refits: refit k runs k rounds toward the headline's ratios from
 *    the kept fit (job_screen.c job_nonneg_refit), so refit 2's round 0
 *    repeated refit 1's bit for bit; it now starts at round 1 from refit
 *    1's state.  What a round reads from the rounds before is out's terms,
 *    the reference (uref, vref: the SVD's or the masked fit's, taken once
 *    per fit), the kept mix and the damped corrections; the rest (the
 *    cells' weights, the headline's, the reference's errors) it makes
 *    again from the data, as every round does.
 *  - A layout on the source's own tables (vndf): its matrix is the same at
 *    every resolution, so the fit the screening made of it was the kept
 *    fit, made again bit for bit; the kept fit now takes its terms.
 * RGL cc_green_malachite: the two a third of `factor --method nmf`'s
 * instructions (docs/positive.md, rounds h38t2 and h38t3).
 *
 * A fit is taken only from the same inputs: the data and cells (x, ext),
 * the headline's weights of the layout and form (hw, hwr; with the
 * textures' sizes and wraps, all the solver reads of the layout), the
 * settings, and the ratios of the rounds held. */
#include <stdlib.h>
#include <string.h>

#include "sepbrdf/param.h"
#include "solve/nmf_state.h"
#include "solve/solver.h"

/* Fits held at most, the least recently used replaced: the screening's
 * vndf in f and cos (3 channels each) and a refit's 3 channels. */
#define SB_NMF_CARRY_FITS 9

/* What a fit depends on besides the data, the headline's weights and the
 * ratios: the solver's settings and the layout's textures. */
typedef struct carry_key {
    size_t m, n, J;
    int channel, max_iters, polish_steps, first_fit, zero_fill, masked, nt, tables, hw_ok, has_rho;
    int fit_iters, wrap[2][2]; /* fit_iters, fit_tol, seed: the masked fit's (fo), where masked */
    size_t tex[2][2];
    double tol, fill, fit_tol;
    unsigned long long seed;
} carry_key_t;

typedef struct carry_rec {
    carry_key_t key;
    unsigned long used;          /* when last saved or taken (0: empty) */
    size_t rounds;               /* rounds of the fit held (1 without ratios) */
    size_t cells, mj, nj, nr;    /* the buffers' sizes */
    double *x, *hw, *hwr;        /* m x n: its data and targets, the headline's weights */
    unsigned char *ext;          /* m x n: its cells' kinds */
    double *rho;                 /* rounds x J: the ratios of its rounds */
    double *u, *v, *uref, *vref; /* m x J, n x J: its terms after the rounds; the reference */
    double kept_mix;
    int iterations, converged;
    double cpprev[SB_NMF_MAX_TERMS], calprev[SB_NMF_MAX_TERMS];
} carry_rec_t;

struct sb_nmf_carry {
    carry_rec_t rec[SB_NMF_CARRY_FITS];
    unsigned long clock;
    size_t resumed, reused; /* executes that started from a fit held, or took it whole */
};

static void rec_free(carry_rec_t *r) {
    void *bufs[] = {r->x, r->hw, r->hwr, r->ext, r->rho, r->u, r->v, r->uref, r->vref};
    for (size_t i = 0; i < sizeof bufs / sizeof bufs[0]; i++)
        free(bufs[i]);
    memset(r, 0, sizeof *r);
}

sb_nmf_carry_t *sb_nmf_carry_create(void) { return calloc(1, sizeof(sb_nmf_carry_t)); }

void sb_nmf_carry_destroy(sb_nmf_carry_t *c) {
    if (!c) return;
    for (int i = 0; i < SB_NMF_CARRY_FITS; i++)
        rec_free(&c->rec[i]);
    free(c);
}

size_t sb_nmf_carry_resumed(const sb_nmf_carry_t *c) { return c ? c->resumed : 0; }
size_t sb_nmf_carry_reused(const sb_nmf_carry_t *c) { return c ? c->reused : 0; }

/* Only where sb_nmf_fit_mixes makes the fit with a first mix's weights
 * (s->w0: the weights a round starts from are those, not the ones the
 * round before left) and damp's corrections fit in the state. */
void sb_solver_nmf_carry(void *state, sb_nmf_carry_t *c) {
    nmf_state_t *s = state;
    if (s) s->carry = c && s->w0 && s->J <= SB_NMF_MAX_TERMS ? c : NULL;
}

static carry_key_t key_of(const nmf_state_t *s, const sb_solve_in_t *in) {
    carry_key_t k;
    memset(&k, 0, sizeof k); /* padding too: compared with memcmp */
    k.m = s->m, k.n = s->n, k.J = s->J;
    k.channel = s->channel, k.max_iters = s->max_iters, k.polish_steps = s->polish_steps;
    k.first_fit = s->first_fit && s->fit; /* only a masked fit keeps its first (nmf_mixes.c) */
    k.zero_fill = s->zero_fill, k.masked = s->fit != NULL, k.nt = s->nt, k.tables = s->tables;
    k.hw_ok = s->hw_ok, k.has_rho = s->rho_all != NULL;
    k.tol = s->tol, k.fill = s->fill;
    if (s->fit) k.fit_iters = s->fo.max_iters, k.fit_tol = s->fo.tol, k.seed = s->fo.seed;
    for (int side = 0; in->param && side < 2; side++) {
        sb_param_texture_size(in->param, side, &k.tex[side][0], &k.tex[side][1]);
        sb_param_wrap(in->param, side, k.wrap[side]);
    }
    return k;
}

/* Whether r holds a fit from s's inputs (its ratios as far as it went). */
static int same_inputs(const carry_rec_t *r, const nmf_state_t *s, const carry_key_t *key) {
    size_t cells = s->m * s->n;
    if (!r->used || memcmp(&r->key, key, sizeof *key) != 0 || memcmp(r->x, s->x, cells * sizeof *r->x) != 0 ||
        memcmp(r->ext, s->ext, cells) != 0)
        return 0;
    if (s->hw_ok && (memcmp(r->hw, s->hw, cells * sizeof *r->hw) != 0 ||
                     (s->hwr && memcmp(r->hwr, s->hwr, cells * sizeof *r->hwr) != 0)))
        return 0;
    for (size_t k = 0; key->has_rho && k < r->rounds && k < s->rounds; k++)
        if (memcmp(r->rho + k * s->J, sb_nmf_rho(s, k), s->J * sizeof *r->rho) != 0) return 0;
    return 1;
}

/* Step: r's buffers for s's sizes (the ones it has where large enough);
 * 0 when out of memory, r then empty. */
static int rec_size(carry_rec_t *r, const nmf_state_t *s) {
    size_t cells = s->m * s->n, mj = s->m * s->J, nj = s->n * s->J, nr = s->rounds * s->J;
    int ok = 1;
    if (r->cells < cells || !r->x) {
        free(r->x), free(r->hw), free(r->hwr), free(r->ext);
        r->x = malloc(cells * sizeof *r->x), r->hw = malloc(cells * sizeof *r->hw);
        r->hwr = malloc(cells * sizeof *r->hwr), r->ext = malloc(cells);
        r->cells = cells;
        ok = r->x && r->hw && r->hwr && r->ext;
    }
    if (ok && r->mj < mj) {
        free(r->u), free(r->uref);
        r->u = malloc(mj * sizeof *r->u), r->uref = malloc(mj * sizeof *r->uref);
        r->mj = mj;
        ok = r->u && r->uref;
    }
    if (ok && r->nj < nj) {
        free(r->v), free(r->vref);
        r->v = malloc(nj * sizeof *r->v), r->vref = malloc(nj * sizeof *r->vref);
        r->nj = nj;
        ok = r->v && r->vref;
    }
    if (ok && r->nr < nr) {
        free(r->rho);
        r->rho = malloc(nr * sizeof *r->rho);
        r->nr = nr;
        ok = r->rho != NULL;
    }
    if (!ok) rec_free(r);
    return ok;
}

/* The fits kept: the rounds of a fit toward the headline's ratios (a
 * refit asks for more) and a fit on a layout on the source's tables (the
 * screening's, the kept fit's again); no other fit is made twice. */
void sb_nmf_carry_save(nmf_state_t *s, const sb_solve_in_t *in, const sb_solve_out_t *out) {
    sb_nmf_carry_t *c = s->carry;
    if (!c || !s->w0 || s->channel < 0 || s->channel > 2 || !(s->rho_all || s->tables)) return;
    carry_key_t key = key_of(s, in);
    carry_rec_t *r = NULL;
    for (int i = 0; i < SB_NMF_CARRY_FITS && !r; i++)
        if (same_inputs(&c->rec[i], s, &key)) r = &c->rec[i]; /* the same fit, fewer rounds */
    for (int i = 0; i < SB_NMF_CARRY_FITS && !r; i++)
        if (!c->rec[i].used) r = &c->rec[i];
    carry_rec_t *lru = &c->rec[0];
    for (int i = 1; i < SB_NMF_CARRY_FITS; i++)
        lru = c->rec[i].used < lru->used ? &c->rec[i] : lru;
    r = r ? r : lru;
    if (!rec_size(r, s)) return;
    size_t m = s->m, n = s->n, J = s->J;
    memcpy(r->x, s->x, m * n * sizeof *r->x);
    memcpy(r->ext, s->ext, m * n);
    if (s->hw_ok) memcpy(r->hw, s->hw, m * n * sizeof *r->hw);
    if (s->hw_ok && s->hwr) memcpy(r->hwr, s->hwr, m * n * sizeof *r->hwr);
    memcpy(r->u, out->u, m * J * sizeof *r->u);
    memcpy(r->v, out->v, n * J * sizeof *r->v);
    memcpy(r->uref, s->uref, m * J * sizeof *r->uref);
    memcpy(r->vref, s->vref, n * J * sizeof *r->vref);
    for (size_t k = 0; s->rho_all && k < s->rounds; k++)
        memcpy(r->rho + k * J, sb_nmf_rho(s, k), J * sizeof *r->rho);
    memcpy(r->cpprev, s->cpprev, sizeof r->cpprev);
    memcpy(r->calprev, s->calprev, sizeof r->calprev);
    r->kept_mix = s->kept_mix;
    r->iterations = out->iterations;
    r->converged = out->converged;
    r->key = key;
    r->rounds = s->rounds;
    r->used = ++c->clock;
}

size_t sb_nmf_carry_take(nmf_state_t *s, const sb_solve_in_t *in, sb_solve_out_t *out) {
    sb_nmf_carry_t *c = s->carry;
    if (!c || !s->w0 || s->channel < 0 || s->channel > 2) return 0;
    carry_key_t key = key_of(s, in);
    carry_rec_t *r = NULL;
    for (int i = 0; i < SB_NMF_CARRY_FITS; i++) {
        carry_rec_t *q = &c->rec[i];
        if (q->rounds <= s->rounds && same_inputs(q, s, &key) && (!r || q->rounds > r->rounds)) r = q;
    }
    if (!r) return 0;
    size_t m = s->m, n = s->n, J = s->J;
    memcpy(out->u, r->u, m * J * sizeof *r->u);
    memcpy(out->v, r->v, n * J * sizeof *r->v);
    memcpy(s->uref, r->uref, m * J * sizeof *r->uref);
    memcpy(s->vref, r->vref, n * J * sizeof *r->vref);
    memcpy(s->cpprev, r->cpprev, sizeof r->cpprev);
    memcpy(s->calprev, r->calprev, sizeof r->calprev);
    s->kept_mix = r->kept_mix;
    out->iterations = r->iterations;
    out->converged = r->converged;
    r->used = ++c->clock;
    if (r->rounds == s->rounds)
        c->reused++;
    else
        c->resumed++;
    return r->rounds;
}
