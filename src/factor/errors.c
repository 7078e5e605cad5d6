/* The errors of a factorisation (errors.h), for the plan's own fit and
 * for factors that changed after it (rounded to the stored precision,
 * read back from files, edited).  One measure everywhere: on the valid
 * cells of M, for every J' = 1..J,
 *     rel_rms = ||W_r (M - sum_{j<=J'} g_j h_j^T) W_c||_F / ||W_r M W_c||_F
 * with W = diag(sqrt(cell measure)) for weighted fits and W = I otherwise,
 * and max_abs = max |M - sum g_j h_j^T| in native units. */
#include "factor/errors.h"

#include <cblas.h>
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "sample/stream.h"
#include "solve/circulant.h"
#include "solve/solver.h"
#include "util/internal.h"
#include "util/parallel.h"

/* One term of the residual of a column: r -= hv g; returns
 * sum (r wr wcp)^2 (wr NULL: 1) and raises *mx to max |r|.  Two lanes with
 * SSE2, which GCC does not produce itself for the maximum (its NaN rules
 * differ from maxpd; the matrix is finite). */
static double resid_step(double *r, const double *g, double hv, size_t n, const double *wr, double wcp, double *mx) {
    size_t i = 0;
    double s2 = 0, m = *mx;
#if defined(__SSE2__)
    __m128d vh = _mm_set1_pd(hv), vw = _mm_set1_pd(wcp), sign = _mm_set1_pd(-0.0);
    __m128d acc = _mm_setzero_pd(), vm = _mm_set1_pd(m);
    for (; i + 2 <= n; i += 2) {
        __m128d x = _mm_sub_pd(_mm_loadu_pd(r + i), _mm_mul_pd(vh, _mm_loadu_pd(g + i)));
        _mm_storeu_pd(r + i, x);
        __m128d d = _mm_mul_pd(x, vw);
        if (wr) d = _mm_mul_pd(d, _mm_loadu_pd(wr + i));
        acc = _mm_add_pd(acc, _mm_mul_pd(d, d));
        vm = _mm_max_pd(vm, _mm_andnot_pd(sign, x));
    }
    double t[2];
    _mm_storeu_pd(t, acc);
    s2 = t[0] + t[1];
    _mm_storeu_pd(t, vm);
    m = t[0] > t[1] ? t[0] : t[1];
#endif
    for (; i < n; i++) {
        r[i] -= hv * g[i];
        double d = r[i] * wcp * (wr ? wr[i] : 1), a = fabs(r[i]);
        s2 += d * d;
        if (a > m) m = a;
    }
    *mx = m;
    return s2;
}

/* The same step on the valid cells of a masked column. */
static double resid_step_masked(double *r, const double *g, double hv, size_t n, const double *wr, double wcp,
                                const unsigned char *mk, double *mx) {
    double s2 = 0, m = *mx;
    for (size_t i = 0; i < n; i++) {
        r[i] -= hv * g[i];
        if (!mk[i]) continue;
        double d = r[i] * wcp * (wr ? wr[i] : 1), a = fabs(r[i]);
        s2 += d * d;
        if (a > m) m = a;
    }
    *mx = m;
    return s2;
}

typedef struct resid_job {
    const sb_resid_t *in;
    size_t c0, c1;
    double *r, *ssq, *mx, n2; /* scratch column; sums of this job */
} resid_job_t;

static void *resid_cols(void *arg) {
    resid_job_t *jb = arg;
    const sb_resid_t *in = jb->in;
    size_t rows = in->rows, J = in->terms;
    double *r = jb->r;
    for (size_t j = 0; j < J; j++)
        jb->ssq[j] = jb->mx[j] = 0;
    jb->n2 = 0;
    for (size_t c = jb->c0; c < jb->c1; c++) {
        const double *a = in->a + c * in->ld;
        const unsigned char *mk = in->mask ? in->mask + c * in->ld : NULL;
        double wcp = (in->wc ? in->wc[c] : 1) * in->pw;
        for (size_t i = 0; i < rows; i++) {
            r[i] = a[i];
            double x = r[i] * wcp * (in->wr ? in->wr[i] : 1);
            if (!mk || mk[i]) jb->n2 += x * x;
        }
        for (size_t j = 0; j < J; j++) {
            const double *g = in->g + j * in->gstep;
            double hv = in->h[j * in->hstep + c];
            jb->ssq[j] += mk ? resid_step_masked(r, g, hv, rows, in->wr, wcp, mk, &jb->mx[j])
                             : resid_step(r, g, hv, rows, in->wr, wcp, &jb->mx[j]);
        }
    }
    return NULL;
}

size_t sb_resid_scratch(size_t rows, size_t terms, int threads) { return (rows + 2 * terms) * (size_t)threads; }

void sb_resid_channel(const sb_resid_t *in, int threads, double *scratch, double *ssq, double *mx, double *n2) {
    size_t J = in->terms;
    /* small matrices: threads cost more than they save */
    int nt = sb_threads_for(threads, in->cols, in->rows * in->cols * J, (size_t)1 << 18);
    resid_job_t jobs[SB_THREADS_MAX];
    for (int t = 0; t < nt; t++) {
        double *w = scratch + (size_t)t * (in->rows + 2 * J);
        jobs[t] = (resid_job_t){in, 0, 0, w, w + in->rows, w + in->rows + J, 0};
        sb_part(in->cols, t, nt, &jobs[t].c0, &jobs[t].c1);
    }
    sb_parallel_run(resid_cols, jobs, sizeof *jobs, nt, NULL, NULL);
    *n2 = 0;
    for (size_t j = 0; j < J; j++)
        ssq[j] = mx[j] = 0;
    for (int t = 0; t < nt; t++) { /* fixed order: deterministic */
        *n2 += jobs[t].n2;
        for (size_t j = 0; j < J; j++) {
            ssq[j] += jobs[t].ssq[j];
            if (jobs[t].mx[j] > mx[j]) mx[j] = jobs[t].mx[j];
        }
    }
}

sb_result_t sb_errors_relative(sb_context_t *ctx, size_t J, const int present[3], const double *ssq, const double *mx,
                               const double n2[3], double *rel_rms, double *max_abs) {
    double total2 = 0;
    for (int c = 0; c < 3; c++)
        if (present[c]) total2 += n2[c];
    for (size_t t = 0; t < J; t++) {
        double s2 = 0, *all = &rel_rms[sb_err_at(t, SB_CH_ALL)];
        for (size_t c = 0; c < 3; c++) {
            if (!present[c]) continue;
            double sc = ssq[c * J + t];
            rel_rms[sb_err_at(t, c)] = n2[c] > 0 ? sqrt(sc / n2[c]) : 0;
            s2 += sc;
            if (max_abs) {
                max_abs[sb_err_at(t, c)] = mx[c * J + t];
                if (mx[c * J + t] > max_abs[sb_err_at(t, SB_CH_ALL)]) max_abs[sb_err_at(t, SB_CH_ALL)] = mx[c * J + t];
            }
        }
        *all = total2 > 0 ? sqrt(s2 / total2) : 0;
        if (!isfinite(*all)) return sb_error(ctx, SB_ERR_NUMERIC, "errors: non-finite error after %zu terms", t + 1);
    }
    return SB_OK;
}

/* Weights of a parameterisation: w = sqrt(max(cell measure, 0)). */
void sb_errors_weights(const sb_param_t *p, double *wr, double *wc) {
    for (size_t i = 0; i < sb_param_rows(p); i++)
        wr[i] = sqrt(fmax(sb_param_row_measure(p, i), 0));
    for (size_t i = 0; i < sb_param_cols(p); i++)
        wc[i] = sqrt(fmax(sb_param_col_measure(p, i), 0));
}

sb_result_t sb_errors_check_fit(sb_context_t *ctx, const sb_factors_t *f, const sb_matrix_t *m,
                                const sb_param_t *weights) {
    size_t rows = m->rows, cols = m->cols, gw, gh, hw, hh;
    if (!m->structured && m->ld < rows)
        return sb_error(ctx, SB_ERR_ARG, "errors: leading dimension %zu < %zu rows", m->ld, rows);
    sb_factors_size(f, SB_SIDE_G, &gw, &gh);
    sb_factors_size(f, SB_SIDE_H, &hw, &hh);
    if (gw * gh != rows || hw * hh != cols)
        return sb_error(ctx, SB_ERR_ARG,
                        "errors: factors of %zu x %zu and %zu x %zu texels do not fit a %zu x %zu matrix", gw, gh, hw,
                        hh, rows, cols);
    if (weights && (sb_param_rows(weights) != rows || sb_param_cols(weights) != cols))
        return sb_error(ctx, SB_ERR_ARG, "errors: the weighting parameterisation does not match the matrix");
    return SB_OK;
}

static sb_result_t against_streamed(sb_context_t *ctx, const sb_factors_t *f, const sb_matrix_t *m,
                                    const sb_param_t *weights, double *rel_rms, double *max_abs);
static sb_result_t against_circulant(sb_context_t *ctx, const sb_factors_t *f, const sb_matrix_t *m,
                                     const sb_param_t *weights, double *rel_rms, double *max_abs);

sb_result_t sb_factors_errors_against(sb_context_t *ctx, const sb_factors_t *f, const sb_matrix_t *m,
                                      const sb_param_t *weights, double *rel_rms, double *max_abs) {
    if (!f || !m || !rel_rms || !max_abs) return sb_error(ctx, SB_ERR_ARG, "errors: missing argument");
    sb_result_t res = sb_errors_check_fit(ctx, f, m, weights);
    if (res != SB_OK) return res;
    /* a structured matrix (its distinct values only) is read a block of
     * columns at a time too: its dense copy took 400 MiB at R = 64 */
    if (m->structured && !m->streamed && !m->mask && m->phi_period * m->phi_period == m->rows && m->rows == m->cols) {
        res = against_circulant(ctx, f, m, weights, rel_rms, max_abs);
        if (res != SB_ERR_UNSUPPORTED) return res; /* else weights that do not keep the structure */
    }
    if (m->streamed || m->structured) return against_streamed(ctx, f, m, weights, rel_rms, max_abs);
    size_t J = sb_factors_terms(f), C = sb_factors_channels(f), rows = m->rows, cols = m->cols, n;
    memset(rel_rms, 0, J * 4 * sizeof *rel_rms);
    memset(max_abs, 0, J * 4 * sizeof *max_abs);
    int nt = sb_thread_count(0), present[3];
    if (sb_size_add(rows + cols + 6 * J, sb_resid_scratch(rows, J, nt), &n))
        return sb_error(ctx, SB_ERR_OVERFLOW, "errors: scratch size overflows");
    double *ws = sb_alloc(ctx, n, sizeof(double), "errors scratch");
    if (!ws) return SB_ERR_NOMEM;
    double *wr = ws, *wc = wr + rows, *ssq = wc + cols, *mx = ssq + 3 * J, *scratch = mx + 3 * J, n2[3] = {0, 0, 0};
    if (weights) sb_errors_weights(weights, wr, wc);
    /* Step: power-of-two scale of the largest valid |M| over all channels */
    double amax = 0;
    for (int ch = 0; ch < 3; ch++)
        for (size_t c = 0; m->data[ch] && c < cols; c++)
            for (size_t i = 0; i < rows; i++)
                if (!m->mask || m->mask[i + c * m->ld]) amax = fmax(amax, fabs(m->data[ch][i + c * m->ld]));
    /* Step: residual columns, every truncation in one pass */
    for (int ch = 0; ch < 3; ch++) {
        present[ch] = m->data[ch] != NULL;
        if (!present[ch]) continue;
        size_t fc = C == 1 ? 0 : (size_t)ch, step = C * rows;
        sb_resid_t in = {rows,
                         cols,
                         J,
                         m->data[ch],
                         m->ld,
                         m->mask,
                         weights ? wr : NULL,
                         weights ? wc : NULL,
                         sb_pow2_scale(amax),
                         sb_factors_tex_const(f, SB_SIDE_G, 0, fc),
                         sb_factors_tex_const(f, SB_SIDE_H, 0, fc),
                         step,
                         C * cols};
        sb_resid_channel(&in, nt, scratch, ssq + (size_t)ch * J, mx + (size_t)ch * J, &n2[ch]);
    }
    res = sb_errors_relative(ctx, J, present, ssq, mx, n2, rel_rms, max_abs);
    free(ws);
    return res;
}

/* The first channel of m whose residual channel ch repeats (-1 if none):
 * a grey streamed matrix (every channel the same cells) with the same
 * textures bit for bit, as the stream solver gives them. */
static int same_as_first(const sb_matrix_t *m, size_t J, const double *const g[3], const double *const h[3],
                         size_t gstep, size_t hstep, int ch) {
    int f = 0;
    while (f < ch && !(g[f] && sb_matrix_has(m, f)))
        f++;
    if (f == ch || !g[ch] || !sb_matrix_has(m, ch) || !sb_matrix_stream_grey(m)) return -1;
    for (size_t j = 0; j < J; j++)
        if (memcmp(g[f] + j * gstep, g[ch] + j * gstep, m->rows * sizeof(double)) ||
            memcmp(h[f] + j * hstep, h[ch] + j * hstep, m->cols * sizeof(double)))
            return -1;
    return f;
}

sb_result_t sb_resid_blocks(sb_context_t *ctx, const sb_matrix_t *m, size_t J, const double *const g[3],
                            const double *const h[3], size_t gstep, size_t hstep, const double *wr, const double *wc,
                            double pw, double *ssq, double *mx, double *n2) {
    size_t rows = m->rows, cols = m->cols, b = sb_solve_stream_cols(rows, cols);
    int nt = sb_thread_count(0);
    double *mem = sb_alloc(ctx, 3 * rows * b + 2 * J + sb_resid_scratch(rows, J, nt), sizeof(double), "residual"),
           *blk[3];
    if (!mem) return SB_ERR_NOMEM;
    double *bssq = mem + 3 * rows * b, *bmx = bssq + J, *scratch = bmx + J;
    memset(ssq, 0, 3 * J * sizeof *ssq);
    memset(mx, 0, 3 * J * sizeof *mx);
    int same[3];
    for (int ch = 0; ch < 3; ch++) {
        same[ch] = same_as_first(m, J, g, h, gstep, hstep, ch);
        blk[ch] = g[ch] && sb_matrix_has(m, ch) && same[ch] < 0 ? mem + (size_t)ch * rows * b : NULL;
        n2[ch] = 0;
    }
    sb_result_t r = SB_OK;
    for (size_t c0 = 0; c0 < cols && r == SB_OK; c0 += b) {
        size_t n = c0 + b < cols ? b : cols - c0;
        if (!sb_group_owns(ctx, c0 / b)) continue; /* another process of the group reads it */
        r = sb_matrix_cols(ctx, m, c0, c0 + n, blk, rows, 0);
        for (size_t ch = 0; ch < 3 && r == SB_OK; ch++) {
            if (!blk[ch]) continue;
            sb_resid_t in = {rows, n,     J,          blk[ch], rows, NULL, wr, wr ? wc + c0 : NULL,
                             pw,   g[ch], h[ch] + c0, gstep,   hstep};
            double bn2 = 0;
            sb_resid_channel(&in, nt, scratch, bssq, bmx, &bn2);
            n2[ch] += bn2; /* blocks added in order: the same bits on every run */
            for (size_t j = 0; j < J; j++) {
                ssq[ch * J + j] += bssq[j];
                mx[ch * J + j] = fmax(mx[ch * J + j], bmx[j]);
            }
        }
    }
    free(mem);
    for (int ch = 0; ch < 3; ch++)
        if (same[ch] >= 0) {
            memcpy(ssq + ch * J, ssq + same[ch] * J, J * sizeof *ssq);
            memcpy(mx + ch * J, mx + same[ch] * J, J * sizeof *mx);
            n2[ch] = n2[same[ch]];
        }
    if (r == SB_OK) r = sb_group_reduce(ctx, ssq, 3 * J, SB_REDUCE_SUM);
    if (r == SB_OK) r = sb_group_reduce(ctx, n2, 3, SB_REDUCE_SUM);
    if (r == SB_OK) r = sb_group_reduce(ctx, mx, 3 * J, SB_REDUCE_MAX);
    return r;
}

/* sb_factors_errors_against on a streamed matrix: one blocked pass,
 * scale 1 (nothing stored to scan for the largest value). */
static sb_result_t against_streamed(sb_context_t *ctx, const sb_factors_t *f, const sb_matrix_t *m,
                                    const sb_param_t *weights, double *rel_rms, double *max_abs) {
    size_t J = sb_factors_terms(f), C = sb_factors_channels(f), rows = m->rows, cols = m->cols;
    double *ws = sb_alloc(ctx, rows + cols + 6 * J, sizeof(double), "errors scratch"), n2[3];
    if (!ws) return SB_ERR_NOMEM;
    double *wr = ws, *wc = wr + rows, *ssq = wc + cols, *mx = ssq + 3 * J;
    if (weights) sb_errors_weights(weights, wr, wc);
    const double *g[3], *h[3];
    int present[3];
    for (int ch = 0; ch < 3; ch++) {
        size_t fc = C == 1 ? 0 : (size_t)ch;
        present[ch] = sb_matrix_has(m, ch);
        g[ch] = present[ch] ? sb_factors_tex_const(f, SB_SIDE_G, 0, fc) : NULL;
        h[ch] = sb_factors_tex_const(f, SB_SIDE_H, 0, fc);
    }
    sb_result_t r =
        sb_resid_blocks(ctx, m, J, g, h, C * rows, C * cols, weights ? wr : NULL, weights ? wc : NULL, 1, ssq, mx, n2);
    if (r == SB_OK) r = sb_errors_relative(ctx, J, present, ssq, mx, n2, rel_rms, max_abs);
    free(ws);
    return r;
}

/* Theta weights of a parameterisation's io cells into wt (R), 1 where
 * weights is NULL; SB_ERR_UNSUPPORTED where a row's or column's weight
 * depends on phi (not the io grid's). */
static sb_result_t circ_weights(const sb_param_t *weights, size_t R, double *w, double *wt) {
    for (size_t t = 0; t < 2 * R; t++)
        wt[t] = 1;
    if (!weights) return SB_OK;
    sb_errors_weights(weights, w, w + R * R);
    for (size_t s = 0; s < 2; s++)
        for (size_t i = 0; i < R * R; i++)
            if (w[s * R * R + i] != w[s * R * R + i % R]) return SB_ERR_UNSUPPORTED;
    memcpy(wt, w, R * sizeof *wt);
    memcpy(wt + R, w + R * R, R * sizeof *wt);
    return SB_OK;
}

/* sb_factors_errors_against on a structured (block-circulant) matrix:
 * rel_rms by Parseval over the azimuthal frequencies (sb_circ_resid, the
 * same sums as the residual pass to rounding), max_abs from
 * sb_circ_resid_max (4 of the R block rows: a lower bound where the
 * residual is not block-circulant).
 * SB_ERR_UNSUPPORTED (nothing reported) where the weights depend on phi. */
static sb_result_t against_circulant(sb_context_t *ctx, const sb_factors_t *f, const sb_matrix_t *m,
                                     const sb_param_t *weights, double *rel_rms, double *max_abs) {
    size_t J = sb_factors_terms(f), C = sb_factors_channels(f), R = m->phi_period, rows = m->rows;
    double *ws = sb_alloc(ctx, 2 * rows + 3 * R + 6 * J, sizeof(double), "errors scratch"), n2[3] = {0, 0, 0};
    if (!ws) return SB_ERR_NOMEM;
    double *wt = ws + 2 * rows, *r = wt + 2 * R, *ssq = r + R, *mx = ssq + 3 * J;
    sb_result_t res = circ_weights(weights, R, ws, wt);
    memset(ssq, 0, 6 * J * sizeof *ssq);
    int present[3], nt = sb_thread_count(0);
    for (int ch = 0; ch < 3 && res == SB_OK; ch++) {
        present[ch] = m->data[ch] != NULL;
        if (!present[ch]) continue;
        size_t fc = C == 1 ? 0 : (size_t)ch;
        int same = C == 1 ? 0 : ch; /* a grey matrix with one channel of factors: the first channel's sums */
        while (same < ch && !(m->data[same] && !memcmp(m->data[same], m->data[ch], rows * R * sizeof(double))))
            same++;
        if (same < ch) {
            memcpy(ssq + (size_t)ch * J, ssq + (size_t)same * J, J * sizeof *ssq);
            memcpy(mx + (size_t)ch * J, mx + (size_t)same * J, J * sizeof *mx);
            n2[ch] = n2[same];
            continue;
        }
        const double *g = sb_factors_tex_const(f, SB_SIDE_G, 0, fc), *h = sb_factors_tex_const(f, SB_SIDE_H, 0, fc);
        res = sb_circ_resid(ctx, R, m->data[ch], weights ? wt : NULL, weights ? wt + R : NULL, J, g, C * rows, h,
                            C * rows, nt, ssq + (size_t)ch * J, &n2[ch]);
        sb_circ_resid_max(R, m->data[ch], J, g, C * rows, h, C * rows, r, mx + (size_t)ch * J);
    }
    if (res == SB_OK) {
        memset(rel_rms, 0, J * 4 * sizeof *rel_rms);
        memset(max_abs, 0, J * 4 * sizeof *max_abs);
        res = sb_errors_relative(ctx, J, present, ssq, mx, n2, rel_rms, max_abs);
    }
    free(ws);
    return res;
}
