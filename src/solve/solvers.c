/* The registry of solvers (solver.h) and of methods, the solvers chosen
 * by name (svd.h).  The plan tries the solvers in the order of the rows
 * below and takes the first that takes the problem; adding a solver is
 * one file with its descriptor and one row here. */
#include <ctype.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stddef.h>
#include <string.h>

#include "solve/solver.h"

#define SB_BUILTIN_SOLVERS(X)                                                                                          \
    X(sb_solver_nmf)                                                                                                   \
    X(sb_solver_masked)                                                                                                \
    X(sb_solver_stream)                                                                                                \
    X(sb_solver_circulant)                                                                                             \
    X(sb_solver_full)                                                                                                  \
    X(sb_solver_topk)                                                                                                  \
    X(sb_solver_randomized)

#define SB_SOLVER_EXTERN(id) extern const sb_solver_t id;
#define SB_SOLVER_ROW(id) &id,
SB_BUILTIN_SOLVERS(SB_SOLVER_EXTERN)
static const sb_solver_t *const builtin[] = {SB_BUILTIN_SOLVERS(SB_SOLVER_ROW)};
#define NBUILTIN (sizeof builtin / sizeof builtin[0])
_Static_assert(NBUILTIN <= SB_SOLVERS_MAX, "raise SB_SOLVERS_MAX");

/* The methods svd.h numbers for programs written before methods were
 * chosen by name: these names keep these numbers.  Frozen: a new method
 * gets the next free number, never a row here. */
static const char *const numbered[] = {
    [SB_METHOD_AUTO] = "auto", [SB_METHOD_FULL] = "full",
    [SB_METHOD_TOPK] = "topk", [SB_METHOD_RANDOMIZED] = "randomized",
    [SB_METHOD_NMF] = "nmf",   [SB_METHOD_STREAM] = "stream",
};
#define NNUMBERED (sizeof numbered / sizeof numbered[0])

/* The process's registries: solver i is solvers[i], i < nsolvers; method
 * m > 0 is solver methods[m] (method 0 is auto).  Rows are written before
 * the counts count them (release), so readers need no lock; registrations
 * take reg_mu. */
static const sb_solver_t *solvers[SB_SOLVERS_MAX];
static const sb_solver_t *methods[SB_SOLVERS_MAX + 1];
static atomic_size_t nsolvers, nmethods;
static pthread_once_t reg_once = PTHREAD_ONCE_INIT;
static pthread_mutex_t reg_mu = PTHREAD_MUTEX_INITIALIZER;

/* The numbered methods at their numbers, the other built-in methods after
 * them in the order of their rows. */
static void registry_build(void) {
    size_t nm = NNUMBERED;
    for (size_t i = 0; i < NBUILTIN; i++) {
        solvers[i] = builtin[i];
        if (!(builtin[i]->caps & SB_CAP_METHOD)) continue;
        size_t at = nm;
        for (size_t k = 1; k < NNUMBERED; k++)
            if (strcmp(numbered[k], builtin[i]->name) == 0) at = k;
        methods[at] = builtin[i];
        if (at == nm) nm++;
    }
    atomic_store_explicit(&nmethods, nm, memory_order_release);
    atomic_store_explicit(&nsolvers, NBUILTIN, memory_order_release);
}

size_t sb_solver_count(void) {
    pthread_once(&reg_once, registry_build);
    return atomic_load_explicit(&nsolvers, memory_order_acquire);
}
const sb_solver_t *sb_solver_at(size_t i) { return i < sb_solver_count() ? solvers[i] : NULL; }

size_t sb_method_count(void) {
    pthread_once(&reg_once, registry_build);
    return atomic_load_explicit(&nmethods, memory_order_acquire);
}
int sb_method_known(sb_method_t m) { return (size_t)(unsigned)m < sb_method_count(); }

/* Solvers without takes are chosen by their method first (nmf before the
 * masked fit), then the first whose takes takes the problem. */
size_t sb_solver_index(const sb_solve_problem_t *pb) {
    size_t n = sb_solver_count();
    if (sb_method_known(pb->svd.method) && pb->svd.method != SB_METHOD_AUTO)
        for (size_t i = 0; i < n; i++)
            if (!solvers[i]->takes && solvers[i] == methods[pb->svd.method]) return i;
    size_t i = 0;
    while (i < n && !(solvers[i]->takes && solvers[i]->takes(pb)))
        i++;
    return i;
}

const char *sb_solver_name(size_t i) { return sb_solver_at(i) ? solvers[i]->name : NULL; }
const char *sb_solver_description(size_t i) { return sb_solver_at(i) ? solvers[i]->description : NULL; }
unsigned sb_solver_caps(size_t i) { return sb_solver_at(i) ? solvers[i]->caps : 0; }

sb_result_t sb_method_parse(const char *name, sb_method_t *out) {
    if (!out) return SB_ERR_ARG;
    size_t n = sb_method_count();
    for (size_t m = 0; m < n && name; m++)
        if (strcmp(name, sb_method_name((sb_method_t)m)) == 0) {
            *out = (sb_method_t)m;
            return SB_OK;
        }
    return SB_ERR_UNKNOWN;
}
const char *sb_method_name(sb_method_t m) {
    if (!sb_method_known(m)) return "?";
    return m == SB_METHOD_AUTO ? "auto" : methods[m]->name;
}
const char *sb_method_note(sb_method_t m) {
    if (!sb_method_known(m)) return "";
    return m == SB_METHOD_AUTO ? "default" : methods[m]->note ? methods[m]->note : "";
}

/* What a registered descriptor must hold (sb_solver_register). */
static const char *desc_problem(const sb_solver_t *d) {
    if (!d->name || !d->name[0] || strcmp(d->name, "auto") == 0) return "no name, or the name auto";
    for (const char *c = d->name; *c; c++)
        if (!isalnum((unsigned char)*c) && *c != '-' && *c != '_') return "a name of letters, digits, - and _ only";
    if (!d->plan || !d->destroy || !d->execute) return "plan, destroy and execute";
    if (!d->takes && !(d->caps & SB_CAP_METHOD)) return "takes, or SB_CAP_METHOD to be chosen by name";
    if ((d->caps & SB_CAP_EXACT_TAILS) && !d->exact) return "exact for SB_CAP_EXACT_TAILS";
    if ((d->caps & SB_CAP_STRUCTURED) && !d->distinct_rows) return "distinct_rows for SB_CAP_STRUCTURED";
    return NULL;
}

static int name_taken(const char *name) {
    size_t n = sb_solver_count();
    for (size_t i = 0; i < n; i++)
        if (strcmp(solvers[i]->name, name) == 0) return 1;
    return 0;
}

sb_result_t sb_solver_register(sb_context_t *ctx, const sb_solver_t *desc, sb_method_t *method) {
    if (!desc) return sb_error(ctx, SB_ERR_ARG, "solver: no solver to register");
    const char *need = desc_problem(desc);
    if (need) return sb_error(ctx, SB_ERR_ARG, "solver '%s' needs %s", desc->name ? desc->name : "", need);
    sb_result_t r = SB_OK;
    pthread_mutex_lock(&reg_mu);
    size_t n = sb_solver_count(), nm = sb_method_count();
    if (name_taken(desc->name))
        r = sb_error(ctx, SB_ERR_RANGE, "solver: a solver named '%s' is registered already", desc->name);
    else if (n == SB_SOLVERS_MAX)
        r = sb_error(ctx, SB_ERR_RANGE, "solver: %d solvers registered already, the most", SB_SOLVERS_MAX);
    else {
        solvers[n] = desc;
        if (desc->caps & SB_CAP_METHOD) methods[nm] = desc;
        atomic_store_explicit(&nsolvers, n + 1, memory_order_release);
        if (desc->caps & SB_CAP_METHOD) atomic_store_explicit(&nmethods, nm + 1, memory_order_release);
        if (method) *method = desc->caps & SB_CAP_METHOD ? (sb_method_t)nm : SB_METHOD_NONE;
    }
    pthread_mutex_unlock(&reg_mu);
    return r;
}
