/* Headlines of every combination of ng variants of the g textures with nh
 * variants of the h textures of one layout, in one pass over the
 * estimator's pairs (estimate.h sb_estimate_headlines): the pairs, their
 * coordinates, bilinear footprints and source values are shared, each
 * variant is looked up once per pair (ng + nh lookups for ng nh
 * combinations), and a combination costs J C products.  The texel fit's
 * candidates (every combination of the filtered axes, each side's filters
 * acting on that side alone) are ranked this way: one pass instead of one
 * per axis, a third of their time on the default layout. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "factor/estimate_impl.h"
#include "util/internal.h"

typedef struct many {
    eval_t *e; /* ng + nh: e[0..ng-1] give the g textures, e[ng..] the h ones; e[0] the coordinates */
    size_t ng, nh;
    double *num; /* per replicate: ng nh error sums, then the energy sum */
} many_t;

/* Each variant's bilinear lookup at the taps (at, fw) on side `side`: J C
 * values into out. */
static void lookup(const eval_t *e, int side, const size_t at[4], const double fw[4], double *out) {
    size_t S = e->J * e->C;
    const double *t0 = e->itex[side] + at[0] * S, *t1 = e->itex[side] + at[1] * S, *t2 = e->itex[side] + at[2] * S,
                 *t3 = e->itex[side] + at[3] * S;
    for (size_t k = 0; k < S; k++)
        out[k] = fw[0] * t0[k] + fw[1] * t1[k] + fw[2] * t2[k] + fw[3] * t3[k];
}

/* One replicate: per combination, sum over its known pairs of w
 * cos^2(theta_i) |f~_J - f|^2 (RGB), and the same of |f|^2, as
 * sb_estimate_compute's headline at J. */
static void many_unit(void *user, size_t k, int t) {
    (void)t;
    const many_t *m = user;
    const eval_t *e0 = &m->e[0];
    const sb_pairs_t *P = e0->P;
    size_t J = e0->J, C = e0->C, S = J * C, ng = m->ng, nh = m->nh, n = ng * nh;
    double *num = m->num + k * (n + 1);
    memset(num, 0, (n + 1) * sizeof *num);
    double *look = malloc((ng + nh) * S * sizeof *look); /* the lookups: g variants, then h variants */
    if (!look) {
        num[n] = NAN; /* reported as out of memory */
        return;
    }
    for (size_t i = k * P->rep; i < (k + 1) * P->rep; i++) {
        if (!P->known[i]) continue;
        const double *d = P->d + i * PD, *f = d + 7, *wi = d, *wo = d + 3;
        double q = d[6] * d[2] * d[2], f2 = (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]) * q;
        num[n] += f2;
        double sg[2], sh[2];
        int in;
        if (e0->co && e0->co_ready && i < e0->co->n) {
            const double *st = e0->co->st + 4 * i;
            sg[0] = st[0], sg[1] = st[1], sh[0] = st[2], sh[1] = st[3];
            in = e0->co->in[i];
        } else {
            in = sb_param_coords(e0->p, wi, wo, sg, sh);
            if (e0->co && !e0->co_ready && i < e0->co->cap) { /* filling: each pair by the unit that owns it */
                double *st = e0->co->st + 4 * i;
                st[0] = sg[0], st[1] = sg[1], st[2] = sh[0], st[3] = sh[1];
                e0->co->in[i] = (unsigned char)in;
            }
        }
        if (!in) { /* every combination returns 0 there */
            for (size_t s = 0; s < n; s++)
                num[s] += f2;
            continue;
        }
        size_t ag[4], ah[4];
        double fg[4], fh[4];
        est_taps(e0, SB_SIDE_G, sg, ag, fg);
        est_taps(e0, SB_SIDE_H, sh, ah, fh);
        for (size_t a = 0; a < ng; a++)
            lookup(&m->e[a], SB_SIDE_G, ag, fg, look + a * S);
        for (size_t b = 0; b < nh; b++)
            lookup(&m->e[ng + b], SB_SIDE_H, ah, fh, look + (ng + b) * S);
        double div = 1;
        div = sb_form_divisor(e0->form, wi, wo);
        double gain = sb_param_gain(e0->p, wi, wo);
        int clamp = sb_param_apply_gain(e0->p, -1, 1) == 0; /* sb_param_apply_gain (max(0, sum) unless plain), once */
        for (size_t a = 0; a < ng; a++)
            for (size_t b = 0; b < nh; b++) {
                const double *G = look + a * S, *H = look + (ng + b) * S;
                double acc[3] = {0, 0, 0};
                for (size_t j = 0; j < J; j++)
                    for (size_t c = 0, at = j * C; c < C; c++, at++)
                        acc[c] += G[at] * H[at] * e0->scale[j];
                double d2 = 0;
                for (int c = 0; c < 3; c++) {
                    double v = acc[C == 1 ? 0 : c], r = (clamp && v < 0 ? 0 : v) * gain / div - f[c];
                    d2 += r * r;
                }
                num[a * nh + b] += d2 * q;
            }
    }
    free(look);
}

sb_result_t sb_estimate_headlines(sb_context_t *ctx, const sb_pairs_t *pairs, const sb_factors_t *const *gs, size_t ng,
                                  const sb_factors_t *const *hs, size_t nh, const sb_param_t *p, sb_form_t form,
                                  double *out) {
    if (!pairs || !gs || !hs || !ng || !nh || !p || !out)
        return sb_error(ctx, SB_ERR_ARG, "headlines: missing argument");
    if ((unsigned)form >= SB_FORM_COUNT_) return sb_error(ctx, SB_ERR_ARG, "headlines: unknown form %d", (int)form);
    size_t n = ng + nh, J = sb_factors_terms(gs[0]), C = sb_factors_channels(gs[0]);
    for (size_t s = 0; s < n; s++) {
        const sb_factors_t *f = s < ng ? gs[s] : hs[s - ng];
        for (int side = 0; side < 2; side++) {
            size_t w0, h0, w1, h1;
            sb_factors_size(gs[0], side, &w0, &h0);
            sb_factors_size(f, side, &w1, &h1);
            if (w0 != w1 || h0 != h1)
                return sb_error(ctx, SB_ERR_ARG, "headlines: variant %zu's textures differ in size from the first's",
                                s);
        }
        if (sb_factors_terms(f) != J || sb_factors_channels(f) != C)
            return sb_error(ctx, SB_ERR_ARG, "headlines: variant %zu has other terms or channels than the first", s);
    }
    many_t m = {calloc(n, sizeof *m.e), ng, nh, NULL};
    double **ones = calloc(n, sizeof *ones);
    size_t ready = 0;
    sb_result_t r = m.e && ones ? SB_OK : SB_ERR_NOMEM;
    for (; r == SB_OK && ready < n; ready++) {
        m.e[ready] = (eval_t){.P = pairs, .p = p, .form = form};
        r = est_eval_setup(&m.e[ready], ready < ng ? gs[ready] : hs[ready - ng], NULL, p, &ones[ready]);
        if (r != SB_OK) break;
    }
    size_t stride = ng * nh + 1;
    if (r == SB_OK) m.num = sb_alloc(ctx, pairs->nrep * stride, sizeof *m.num, "headlines");
    if (r == SB_OK && !m.num) r = SB_ERR_NOMEM;
    if (r == SB_OK) {
        int nt = sb_thread_count(0);
        if (nt > MAXT) nt = MAXT;
        est_coords_t *co = est_coords_acquire(pairs, p, pairs->n, &m.e[0].co_ready);
        m.e[0].co = co;
        est_run_units(0, pairs->nrep, nt, many_unit, &m);
        int failed = 0;
        for (size_t k = 0; k < pairs->nrep; k++)
            failed |= isnan(m.num[k * stride + ng * nh]);
        if (co) est_coords_release(pairs, co, p, m.e[0].co_ready || failed ? 0 : pairs->n);
        for (size_t s = 0; s < ng * nh && !failed; s++) { /* replicate order: the same on any thread count */
            double a = 0, b = 0;
            for (size_t k = 0; k < pairs->nrep; k++) {
                a += m.num[k * stride + s];
                b += m.num[k * stride + ng * nh];
            }
            out[s] = b > 0 ? sqrt(a / b) : (a > 0 ? INFINITY : 0);
        }
        if (failed) r = SB_ERR_NOMEM;
    }
    for (size_t s = 0; s < ready && m.e; s++) {
        free(ones[s]);
        est_eval_free(&m.e[s]);
    }
    free(ones);
    free(m.e);
    free(m.num);
    return r == SB_OK ? SB_OK : sb_error(ctx, r, "headlines: out of memory");
}
