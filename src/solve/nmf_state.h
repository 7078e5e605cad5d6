/* The non-negative solver's state, shared by its three files: from the
 * bottom, nmf_sweeps.c (the cells' weights, the sweeps and the stages),
 * nmf_mixes.c (the fits toward the headline and the choice among them)
 * and solver_nmf.c (the method: plan, holes, execute). */
#ifndef SB_SOLVE_NMF_STATE_H
#define SB_SOLVE_NMF_STATE_H

#include <stddef.h>

#include "solve/fit_impl.h"
#include "solve/solver.h"

/* Matrices of at most this many cells take more than one fit (fit_mixes:
 * vndf 8 x 1024; iso at 32 cells 64 x 992; not hd, 1024^2, where a
 * second fit costs seconds). */
#define SB_NMF_MIX_CELLS ((size_t)1 << 17)
/* A kept fit's safeguarded steps at most (nmf_mixes.c polish). */
#define SB_NMF_POLISH_STEPS 40
/* Terms a fit toward the headline's own ratios takes at most (cp). */
#define SB_NMF_MAX_TERMS 32

typedef struct nmf_state {
    size_t m, n, J;
    int max_iters, zero_fill;
    double tol, fill;     /* fill: the weight of the cells out of the data (ext 2) */
    double floor2;        /* the least ||E_p||^2 a prefix weight takes: 1e-24 of the data's */
    double *e;            /* m x n: masked residual of all the terms fitted */
    double *r;            /* m x n: the weighted sum of the prefixes' residuals a term is fitted to */
    double *alpha;        /* J: the prefixes' weights 1 / ||E_p||^2 (prefix_weights) */
    double *cq;           /* J: the terms' weights in a term's target (nested_term) */
    double *tw;           /* nt x (3 m + J): the parts' numbers (nmf_job_t) */
    int nt;               /* parts at most */
    double *x;            /* m x n: the data, and the targets of the cells within the taps' reach */
    double *w;            /* m x n: the cells' weights (cell_weights) */
    unsigned char *ext;   /* m x n: 1 data, 2 within the taps' reach, 0 beyond */
    double *t;            /* 2 m + J numbers (prefix_weights) */
    double *uref, *vref;  /* m x J, n x J: the reference's terms (toward_headline) */
    double *sref;         /* J: the reference's prefixes' errors, in the fit's weights */
    double gam;           /* SB_NMF_RATIO_POWER where a reference is known, else 0 */
    double *hw;           /* m x n: the headline's weights of the data cells (toward_headline) */
    double *hwr;          /* m x n: the same unclipped, where w0 is (fit_mixes) */
    double *w0, *ub, *vb; /* m x n, m x J, n x J: the weights of the first mix, the terms kept (fit_mixes, reorder) */
    int hw_ok;            /* hw holds them for hw_key (the channels of a matrix share them) */
    double *u1, *v1;      /* m x J, n x J: a sweep's end (polish; where hw is) */
    int polish_steps;     /* SB_NMF_POLISH_STEPS (0 in a test: no polish) */
    double kept_mix;      /* the mix of the fit in ub, vb (fit_mix) */
    int conv;             /* whether the fit in ub, vb converged (fit_mix) */
    double hw_key[3];     /* the layout's address, the form, a sum over the data cells */
    sb_fit_t *fit;        /* masked: the masked fit whose extension fills the cells out of the data */
    sb_fit_opts_t fo;
    /* J: the headline's ratios of the fit made without them to the default
     * method's (the plan's nonneg_ratio); NULL: none */
    const double *rho;
    const double *rho_all, *rho_ch; /* the plan's nonneg_ratio and nonneg_ratio_channel (rho: the channel's) */
    /* each prefix's ratio in the headline's weights times this: rho^2 over
     * that ratio of the fit made without rho (to_headline), else 1 */
    double cp[SB_NMF_MAX_TERMS];
    /* rho^2 over each prefix's squared ratio in the headline's weights of
     * the fit before to_headline's: the headline's ratios predicted from
     * those weights' (nmf_mixes.c minimax on vndf) */
    double cal[SB_NMF_MAX_TERMS];
    double *hws; /* m x n: hw spread to the nodes beside (vndf, where w0 is) */
    int tables, hws_ok;
    /* m x J, n x J: the first candidate toward rho (to_headline; with rho) */
    double *uc, *vc;
    /* the last prefix's squared ratio r above last_tau2 counts
     * min(r / last_tau2, last_kap2) times (sb_nmf_last_boost; 0: not) */
    double last_tau2, last_kap2;
    /* where mm: the sweeps' prefix weights alpha_p = mmc_p / sref_p, the
     * minimax's multiplicative weights with exponent mm_eta (the last
     * prefix's squared ratio counted mm_last times), and the least
     * worst squared ratio so far, its terms in ub, vb (nmf_mixes.c minimax,
     * nmf_sweeps.c minimax_weights) */
    int mm;
    double mmc[SB_NMF_MAX_TERMS], mm_eta, mm_last, mm_best;
    int first_fit; /* the plan's nonneg_first_fit: masked, the first mix's fit kept alone */
    size_t rounds; /* the plan's nonneg_rounds, at least 1 */
    int channel;   /* the channel solved (sb_solve_in_t), for sb_nmf_rho */
    size_t round;  /* the round of rho (sb_nmf_rho) */
    /* the round before's corrections of to_headline and calibrate (nmf_mixes.c damp) */
    double cpprev[SB_NMF_MAX_TERMS], calprev[SB_NMF_MAX_TERMS];
    struct sb_nmf_carry *carry; /* the rounds' state kept for a later execute (nmf_carry.c); NULL: none */
} nmf_state_t;

/* Round k's ratios of the plan's nonneg_ratio (the channel's where given). */
static inline const double *sb_nmf_rho(const nmf_state_t *s, size_t k) {
    if (!s->rho_all) return NULL;
    if (s->rho_ch && s->channel >= 0 && s->channel < 3) return s->rho_ch + (k * 3 + (size_t)s->channel) * s->J;
    return s->rho_all + k * s->J;
}

/* The factor on the last prefix's squared ratio r to the reference, in
 * the sweeps' weights (ratio_weights) and in the measure the fits are
 * chosen and polished by (nmf_mixes.c worst_ratio): 1 up to last_tau2,
 * then r / last_tau2 up to last_kap2 (SB_NMF_LAST_TARGET, _WEIGHT). */
static inline double sb_nmf_last_boost(const nmf_state_t *s, double r) {
    if (!(s->last_tau2 > 0) || !(r > s->last_tau2)) return 1;
    double b = r / s->last_tau2;
    return b < s->last_kap2 ? b : s->last_kap2;
}

/* Sweeps of a stage before the last (joint refit of the terms so far),
 * and rank-one updates seeding a term. */
#define SB_NMF_STAGE_SWEEPS 50
#define SB_NMF_SEED_SWEEPS 10
/* The weight of a cell out of the data and beyond the taps' reach,
 * pulled towards 0, against 1 for a data cell: no lookup reads such a
 * cell, but nothing else bounds a product u_i v_c whose row and column
 * are fitted only elsewhere.  Small, since these cells are many (the
 * default gold on iso: the terms' values there 0.6-0.9 of the data's
 * norm) and every one of them pulls the terms away from the data: the
 * default gold's prefixes at 1e-4 2.05, 2.52, 1.69, 1.92x the SVD's
 * headline (J' = 1-4), at 1e-6 (and SB_NMF_FILL_WEIGHT 0.01) 2.27, 1.38,
 * 1.25, 1.35x (docs/positive.md, "The cells no lookup reads"). */
#define SB_NMF_HOLE_WEIGHT 1e-6
/* Step: the weight of every cell in the fit (s->w, nmf_sweeps.c). */
void sb_nmf_cell_weights(nmf_state_t *s);
/* E = M o (X - U V^T) of the first k terms into s->e; returns the
 * weighted ||E||^2 (nmf_sweeps.c). */
double sb_nmf_residual(nmf_state_t *s, const double *U, const double *V, size_t k);

/* The stages of a fit in s's weights: term k seeded from the positive part
 * of the residual of the k - 1 before it, then the k terms refitted
 * (nested sweeps), into out->u, out->v (nmf_sweeps.c). */
void sb_nmf_stages(nmf_state_t *s, sb_solve_out_t *out);

/* Nested sweeps of all J terms from out's, until the fit's tolerance or
 * max_iters (sb_nmf_refit) or at most n (sb_nmf_refit_n); added to
 * out->iterations (nmf_sweeps.c). */
void sb_nmf_refit(nmf_state_t *s, sb_solve_out_t *out);
void sb_nmf_refit_n(nmf_state_t *s, sb_solve_out_t *out, int n);

/* The fits toward the headline (nmf_mixes.c): at SB_NMF_HEADLINE_MIX and,
 * on small matrices with a reference, at other mixes, the one kept whose
 * worst prefix in the headline's weights is the lowest against the
 * reference; out->iterations counts every sweep. */
void sb_nmf_fit_mixes(nmf_state_t *s, const sb_solve_in_t *in, sb_solve_out_t *out);

/* The fits the carry keeps (nmf_carry.c, solver.h sb_solver_nmf_carry):
 * sb_nmf_carry_save, at the end of a fit (s->carry and s->w0 set; with
 * the plan's ratios, or on a layout on the source's tables), keeps
 * channel s->channel's terms, iterations and convergence and s's
 * reference, kept mix and corrections (cpprev, calprev), with what they
 * were made from.  sb_nmf_carry_take, at the start of sb_nmf_fit_mixes
 * (s->w0 and the headline's weights just made), gives back those of a fit
 * from the same data, headline's weights, settings and ratios of its
 * rounds, with at most s->rounds rounds (the most held), and returns its
 * rounds: s->rounds, the whole fit; fewer, the state after them; 0: none
 * (the fit then starts as without it).  Everything else the rounds read is
 * remade from the data. */
void sb_nmf_carry_save(nmf_state_t *s, const sb_solve_in_t *in, const sb_solve_out_t *out);
size_t sb_nmf_carry_take(nmf_state_t *s, const sb_solve_in_t *in, sb_solve_out_t *out);

#endif
