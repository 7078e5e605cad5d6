/* The comparable metric: resample the reconstruction on a reference io
 * grid and integrate the error of f cos(theta_i) cos(theta_o) over solid
 * angle, so that parameterisations and forms are compared on the same work.
 *
 * For speed the bilinear footprint (4 texel indices and weights) of each
 * side is computed once per pair and shared by every term and channel;
 * sums for every J' = 1..J are accumulated in the same pass.  Rows of the
 * reference grid are split among threads. */
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"
#include "sepbrdf/factor.h"

#define MAXJ 256

typedef struct foot {
    size_t at[4];
    double w[4];
} foot_t;

static size_t wrap_i(long i, size_t n, int mode) {
    if (mode == SB_WRAP_REPEAT) {
        long m = i % (long)n;
        return (size_t)(m < 0 ? m + (long)n : m);
    }
    return i < 0 ? 0 : ((size_t)i >= n ? n - 1 : (size_t)i);
}

/* GL bilinear footprint, identical to sb_factors_lookup. */
static void footprint(size_t w, size_t h, const int wrap[2], const double st[2], foot_t *ft) {
    double u = st[0] * (double)w - 0.5, v = st[1] * (double)h - 0.5;
    double fu = floor(u), fv = floor(v), a = u - fu, b = v - fv;
    size_t x0 = wrap_i((long)fu, w, wrap[0]), x1 = wrap_i((long)fu + 1, w, wrap[0]);
    size_t y0 = wrap_i((long)fv, h, wrap[1]), y1 = wrap_i((long)fv + 1, h, wrap[1]);
    ft->at[0] = y0 * w + x0;
    ft->at[1] = y0 * w + x1;
    ft->at[2] = y1 * w + x0;
    ft->at[3] = y1 * w + x1;
    ft->w[0] = (1 - a) * (1 - b);
    ft->w[1] = a * (1 - b);
    ft->w[2] = (1 - a) * b;
    ft->w[3] = a * b;
}

typedef struct job {
    const sb_source_t *src;
    const sb_factors_t *f;
    const sb_param_t *p;
    sb_form_t form;
    size_t R, J, r0, r1, ch;
    const double **g, **h; /* [j * ch + c] */
    double num[MAXJ], den;
    size_t neg[MAXJ], known;
} job_t;

static void *run(void *arg) {
    job_t *jb = arg;
    size_t R = jb->R, N = R * R, J = jb->J, C = jb->ch;
    size_t gw, gh, hw, hh;
    int wg[2], wh[2];
    sb_factors_size(jb->f, SB_SIDE_G, &gw, &gh);
    sb_factors_size(jb->f, SB_SIDE_H, &hw, &hh);
    sb_param_wrap(jb->p, SB_SIDE_G, wg);
    sb_param_wrap(jb->p, SB_SIDE_H, wh);
    double dt = SB_PI / 2 / (double)R, dp = 2 * SB_PI / (double)R;
    for (size_t k = jb->r0; k < jb->r1; k++) {
        size_t it = k % R;
        double wi[3], wo[3], f[3], sg[2], sh[2];
        sb_dir_from_angles((it + 0.5) * dt, ((k / R) + 0.5) * dp, wi);
        double mi = dp * (cos(it * dt) - cos((it + 1) * dt));
        for (size_t l = 0; l < N; l++) {
            size_t ot = l % R;
            sb_dir_from_angles((ot + 0.5) * dt, ((l / R) + 0.5) * dp, wo);
            if (!sb_source_eval(jb->src, wi, wo, f)) continue;
            if (!isfinite(f[0] + f[1] + f[2])) continue;
            jb->known++;
            double mo = dp * (cos(ot * dt) - cos((ot + 1) * dt));
            double cc = wi[2] * wo[2], w = mi * mo * cc * cc;
            jb->den += w * (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
            double acc[3] = {0, 0, 0}, div = 1;
            int inside = sb_param_coords(jb->p, wi, wo, sg, sh);
            foot_t fg, fh;
            if (inside) {
                footprint(gw, gh, wg, sg, &fg);
                footprint(hw, hh, wh, sh, &fh);
                if (jb->form == SB_FORM_COS) div = fmax(wi[2], 0.001);
                if (jb->form == SB_FORM_COS2) div = fmax(wi[2], 0.001) * fmax(wo[2], 0.001);
            }
            for (size_t j = 0; j < J; j++) {
                if (inside)
                    for (size_t c = 0; c < C; c++) {
                        const double *g = jb->g[j * C + c], *h = jb->h[j * C + c];
                        double gv = fg.w[0] * g[fg.at[0]] + fg.w[1] * g[fg.at[1]] + fg.w[2] * g[fg.at[2]] +
                                    fg.w[3] * g[fg.at[3]];
                        double hv = fh.w[0] * h[fh.at[0]] + fh.w[1] * h[fh.at[1]] + fh.w[2] * h[fh.at[2]] +
                                    fh.w[3] * h[fh.at[3]];
                        acc[c] += gv * hv;
                    }
                double e2 = 0;
                int neg = 0;
                for (int c = 0; c < 3; c++) {
                    double rec = acc[C == 1 ? 0 : c] / div, d = rec - f[c];
                    e2 += d * d;
                    neg |= rec < 0;
                }
                jb->num[j] += w * e2;
                jb->neg[j] += (size_t)neg;
            }
        }
    }
    return NULL;
}

sb_result_t sb_metric_compute(sb_context_t *ctx, const sb_source_t *src, const sb_factors_t *f, const sb_param_t *p,
                              sb_form_t form, const sb_metric_opts_t *opts, sb_metric_t *out) {
    if (!src || !f || !p || !out) return sb_error(ctx, SB_ERR_ARG, "metric: missing argument");
    memset(out, 0, sizeof *out);
    sb_metric_opts_t o = {0};
    if (opts) o = *opts;
    if (o.res == 0) o.res = 32;
    if (o.res < 2 || o.res > 256) return sb_error(ctx, SB_ERR_RANGE, "metric: reference resolution %zu, need 2..256", o.res);
    size_t J = sb_factors_terms(f), C = sb_factors_channels(f), R = o.res, N = R * R;
    if (J > MAXJ) J = MAXJ;
    const double **g = malloc(J * C * sizeof *g), **h = malloc(J * C * sizeof *h);
    int nt = sb_thread_count(o.threads);
    if ((size_t)nt > N) nt = (int)N;
    job_t *jobs = calloc((size_t)nt, sizeof *jobs);
    pthread_t *th = calloc((size_t)nt, sizeof *th);
    if (!g || !h || !jobs || !th) {
        free(g);
        free(h);
        free(jobs);
        free(th);
        return sb_error(ctx, SB_ERR_NOMEM, "metric: out of memory");
    }
    for (size_t j = 0; j < J; j++)
        for (size_t c = 0; c < C; c++) {
            g[j * C + c] = sb_factors_tex_const(f, SB_SIDE_G, j, c);
            h[j * C + c] = sb_factors_tex_const(f, SB_SIDE_H, j, c);
        }
    int *started = calloc((size_t)nt, sizeof *started);
    for (int t = 0; t < nt; t++) {
        job_t *jb = &jobs[t];
        jb->src = src;
        jb->f = f;
        jb->p = p;
        jb->form = form;
        jb->R = R;
        jb->J = J;
        jb->ch = C;
        jb->g = g;
        jb->h = h;
        jb->r0 = N * (size_t)t / (size_t)nt;
        jb->r1 = N * (size_t)(t + 1) / (size_t)nt;
        if (t > 0 && started) started[t] = pthread_create(&th[t], NULL, run, jb) == 0;
    }
    run(&jobs[0]);
    for (int t = 1; t < nt; t++) {
        if (started && started[t]) pthread_join(th[t], NULL);
        else run(&jobs[t]);
    }
    free(started);
    double num[MAXJ] = {0}, den = 0;
    size_t neg[MAXJ] = {0}, known = 0;
    for (int t = 0; t < nt; t++) {
        for (size_t j = 0; j < J; j++) {
            num[j] += jobs[t].num[j];
            neg[j] += jobs[t].neg[j];
        }
        den += jobs[t].den;
        known += jobs[t].known;
    }
    out->terms = J;
    out->pairs = N * N;
    out->known = known;
    for (size_t j = 0; j < J; j++) {
        out->rel_l2[j] = den > 0 ? sqrt(num[j] / den) : (num[j] > 0 ? INFINITY : 0);
        out->neg_frac[j] = known ? (double)neg[j] / (double)known : 0;
    }
    /* negative texels over every texture of the kept terms */
    size_t nneg = 0, ntex = 0;
    for (int side = 0; side < 2; side++) {
        size_t w, hh;
        sb_factors_size(f, side, &w, &hh);
        for (size_t j = 0; j < J; j++)
            for (size_t c = 0; c < C; c++) {
                const double *t = sb_factors_tex_const(f, side, j, c);
                for (size_t i = 0; i < w * hh; i++) nneg += t[i] < 0;
                ntex += w * hh;
            }
    }
    out->neg_texels = ntex ? (double)nneg / (double)ntex : 0;
    free(g);
    free(h);
    free(jobs);
    free(th);
    return SB_OK;
}
