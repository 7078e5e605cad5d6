/* The estimator's reconstruction (estimate_impl.h, where the taps and
 * every prefix's RGB at a pair are inline): the pairs' coordinates under a
 * parameterisation (cached in slots of the pair set) and the evaluation
 * state's release. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "factor/estimate_impl.h"
#include "param/serial.h"
#include "util/internal.h"

/* ---- coordinates of the pairs under a layout --------------------------- */

/* A slot to fill: an empty one, else the least recently used one nobody
 * reads; NULL when all are read.  Under P->mu. */
static est_coords_t *coords_victim(sb_pairs_t *P) {
    est_coords_t *v = NULL;
    for (int s = 0; s < EST_COORD_SLOTS; s++) {
        est_coords_t *c = &P->coords[s];
        if (c->users) continue;
        if (!c->serial) return c;
        if (!v || c->used < v->used) v = c;
    }
    return v;
}

est_coords_t *est_coords_acquire(const sb_pairs_t *cP, const sb_param_t *p, size_t need, int *ready) {
    sb_pairs_t *P = (sb_pairs_t *)cP; /* the slots are a memo: the pairs themselves stay as they are */
    unsigned long serial = sb_param_serial_(p);
    *ready = 0;
    if (!P || !serial || !need) return NULL;
    pthread_mutex_lock(&P->mu);
    est_coords_t *co = NULL;
    for (int s = 0; s < EST_COORD_SLOTS && !co; s++)
        if (P->coords[s].serial == serial && P->coords[s].n >= need) co = &P->coords[s];
    *ready = co != NULL;
    if (!co && (co = coords_victim(P)) != NULL) co->serial = 0; /* being filled: nobody else finds it */
    if (co) co->users++, co->used = ++P->tick;
    pthread_mutex_unlock(&P->mu);
    if (!co || *ready) return co;
    if (co->cap < need) {
        free(co->st), free(co->in);
        co->st = sb_alloc_large(NULL, need, 4 * sizeof *co->st, "estimator coordinates");
        co->in = malloc(need);
        co->cap = co->st && co->in ? need : 0;
    }
    co->n = 0;
    if (co->cap) return co;
    est_coords_release(P, co, p, 0);
    return NULL;
}

void est_coords_release(const sb_pairs_t *cP, est_coords_t *co, const sb_param_t *p, size_t filled) {
    if (!cP || !co) return;
    sb_pairs_t *P = (sb_pairs_t *)cP;
    pthread_mutex_lock(&P->mu);
    if (filled) {
        co->n = filled;
        co->serial = sb_param_serial_(p);
    }
    co->users--;
    pthread_mutex_unlock(&P->mu);
}

void est_eval_free(eval_t *e) {
    free(e->tex[0]);
    free(e->tex[1]);
    free(e->itex[0]);
    free(e->itex[1]);
    free(e->num);
    free(e->den);
    free(e->neg);
    free(e->meas);
    free(e->de);
    free(e->dew);
    free(e->hist);
    free(e->maxr);
    free(e->maxv);
    est_bands_free(e);
}
