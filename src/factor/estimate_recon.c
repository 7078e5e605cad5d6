/* The estimator's reconstruction (estimate_impl.h): the snippet's taps of
 * a texture side (util/tex_axis.h), the pairs' coordinates under a parameterisation
 * (cached in slots of the pair set), every prefix's RGB at a pair, and the
 * evaluation state's release. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "factor/estimate_impl.h"
#include "param/serial.h"
#include "util/internal.h"
#include "util/tex_axis.h"

/* ---- evaluating a reconstruction -------------------------------------- */

void est_taps(const eval_t *e, int side, const double st[2], size_t at[4], double fw[4]) {
    sb_tex_footprint(st, e->tw[side], e->th[side], e->wrap[side], e->edge[side], at, fw);
}

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

/* Reconstructed RGB of every prefix at pair i: rec[j * 3 + c]; 0 outside. */
void est_reconstruct(const eval_t *e, size_t i, double *rec) {
    double sg[2], sh[2], fg[4], fh[4];
    size_t ag[4], ah[4], J = e->J, C = e->C;
    const double *wi = e->P->d + i * PD, *wo = wi + 3;
    est_coords_t *co = e->co;
    int in;
    if (co && e->co_ready && i < co->n) {
        const double *st = co->st + 4 * i;
        sg[0] = st[0], sg[1] = st[1], sh[0] = st[2], sh[1] = st[3];
        in = co->in[i];
    } else {
        in = sb_param_coords(e->p, wi, wo, sg, sh);
        if (co && !e->co_ready && i < co->cap) { /* filling: each pair written by the unit that owns it */
            double *st = co->st + 4 * i;
            st[0] = sg[0], st[1] = sg[1], st[2] = sh[0], st[3] = sh[1];
            co->in[i] = (unsigned char)in;
        }
    }
    if (!in) {
        memset(rec, 0, J * 3 * sizeof *rec);
        return;
    }
    est_taps(e, SB_SIDE_G, sg, ag, fg);
    est_taps(e, SB_SIDE_H, sh, ah, fh);
    double div = 1, acc[3] = {0, 0, 0};
    div = sb_form_divisor(e->form, wi, wo);
    double gain = sb_param_gain(e->p, wi, wo);         /* 1 but on SB_CAP_TABLES layouts */
    int clamp = sb_param_apply_gain(e->p, -1, 1) == 0; /* sb_param_apply_gain (max(0, sum) unless plain), once */
    size_t S = J * C; /* the interleaved texels: 8 runs of S values, not 8 J C scattered reads */
    const double *g[4], *h[4];
    for (int k = 0; k < 4; k++) {
        g[k] = e->itex[0] + ag[k] * S;
        h[k] = e->itex[1] + ah[k] * S;
    }
    /* every term and channel's product in one loop the compiler vectorises
     * (the same operations per value as one at a time, so the same bits),
     * then the prefix sums in term order */
    double t[SB_EST_MAXJ * 3];
    for (size_t at = 0; at < S; at++)
        t[at] = (fg[0] * g[0][at] + fg[1] * g[1][at] + fg[2] * g[2][at] + fg[3] * g[3][at]) *
                (fh[0] * h[0][at] + fh[1] * h[1][at] + fh[2] * h[2][at] + fh[3] * h[3][at]) * e->scs[at];
    for (size_t j = 0; j < J; j++) {
        for (size_t c = 0, at = j * C; c < C; c++, at++)
            acc[c] += t[at];
        for (int c = 0; c < 3; c++) {
            double v = acc[C == 1 ? 0 : c];
            rec[j * 3 + c] = (clamp && v < 0 ? 0 : v) * gain / div;
        }
    }
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
