/* Private: how many leading terms of the plan's last execute come from
 * converged sweeps in every channel (plan.c), so that a caller keeping
 * fewer terms (the job's J, job_measure.c) reports the convergence of the
 * terms it writes; sb_plan_stats_t's fit_converged is every term's. */
#ifndef SEPBRDF_FACTOR_PLAN_CONV_H
#define SEPBRDF_FACTOR_PLAN_CONV_H

#include "sepbrdf/factor.h"

/* The terms when every solver converged; fewer when a masked fit's stage
 * stopped at its sweep cap (the terms before it are still converged);
 * 0 for a NULL plan. */
size_t sb_plan_converged_terms(const sb_plan_t *p);

/* A warm start for the plan's next execute (NULL: none; it must outlive
 * that execute): factors of the same layout and terms (the whole table's
 * fit, for a refit without one fold of it: job_cv.c) from which a masked
 * fit starts (fit.h sb_fit_set_start), each channel from its own terms,
 * undone into the solver's weighted unit vectors.  Other solvers, and a
 * channel with a term of sigma <= 0, start as without it. */
void sb_plan_set_start(sb_plan_t *p, const sb_factors_t *start);

/* The non-negative solver's carry for the plan's next executes (NULL:
 * none; it must outlive them): the state after the rounds toward the
 * headline's ratios, kept per channel and taken up by an execute of
 * another plan asking for more rounds from the same matrix and ratios
 * (solve/solver.h sb_nmf_carry_t; the factor job's refits). */
struct sb_nmf_carry;
void sb_plan_set_nonneg_carry(sb_plan_t *p, struct sb_nmf_carry *carry);

/* skip 1: the next executes leave max_abs of every channel NaN where the
 * solver knows its errors exactly (SB_CAP_EXACT_TAILS: the block-circulant
 * solver's largest-error sweeps, a fifth of its execute), the squared
 * errors and norms as before; skip 0 (the default): everything. */
void sb_plan_skip_max_(sb_plan_t *p, int skip);

#endif
