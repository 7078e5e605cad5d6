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

static sb_result_t check_fit(sb_context_t *ctx, const sb_factors_t *f, const sb_matrix_t *m,
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
    sb_result_t res = check_fit(ctx, f, m, weights);
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

/* Errors of factors `near` close to the fit `fit` (its rounding to the
 * stored precision), without a residual pass.  Per channel, in the fitted
 * (weighted) norm, with R = X - G H^T the residual of the fit, whose norm
 * the fit knows, and D = G H^T - G~ H~^T = dG H^T + G~ dH^T:
 *   ||X - G~ H~^T||^2 = ||R||^2 + 2 (<X, D> - <G H^T, D>) + ||D||^2
 *   <X, D>      = sum_b dg_b . (X h_b) + g~_b . (X dh_b)
 *   <G H^T, D>  = sum_ab (g_a . dg_b)(h_a . h_b) + (g_a . g~_b)(h_a . dh_b)
 *   ||D||^2     = sum_ab (dg_a . dg_b)(h_a . h_b) + 2 (dg_a . g~_b)(h_a . dh_b)
 *                        + (g~_a . g~_b)(dh_a . dh_b)
 * (<A B^T, C D^T> = sum_ab (a_a . c_b)(b_a . d_b)); every term is built
 * from the small differences dG, dH themselves, so nothing cancels beyond
 * eps ||X|| ||D||.  One product X [H, dH] per channel is the only read of
 * the matrix.  Where the fit's own error is large (rel_rms at J of at
 * least NEAR_DIRECT_REL, which every prefix's is too), the direct form
 *   ||X - G~ H~^T||^2 = ||X||^2 - 2 <X, G~ H~^T> + ||G~ H~^T||^2
 * loses at most eps ||X||^2 against ||R||^2 >= NEAR_DIRECT_REL^2 ||X||^2
 * (a relative 1e-13 here), and reads the matrix with J columns, X H~,
 * instead of 2 J: half of the product, which is most of this routine's
 * work (issue 36, round six).  Values are scaled by powers of two near
 * 1 / ||X|| (exact). */
#define NEAR_DIRECT_REL 0x1.0p-5
static void gram(size_t n, size_t J, const double *a, const double *b, double *out) {
    cblas_dgemm(CblasColMajor, CblasTrans, CblasNoTrans, (int)J, (int)J, (int)n, 1.0, a, (int)n, b, (int)n, 0.0, out,
                (int)J);
}

/* Workspace of sb_factors_errors_near: G~ (rows x J), H~ (cols x J), the
 * weights, the sums of squares (3 J), the Gram blocks (J x J each), Z
 * (cols x 2J), Y = M Z (rows x 2J), then G, dG (rows x J) and H, dH
 * together (cols x 2J).  In this order the direct form (which reads G~,
 * H~ and the first J columns of Z and Y only) touches the first 40 % of
 * it; where every channel takes the direct form only that part is made
 * (Y then follows Z's J columns), 1.0 MiB instead of 2.6 MiB at io R = 64:
 * on the heap's 2 MiB pages the rest took room the matrix product's
 * scratch then found above the heap's top, a huge page more to zero. */
typedef struct near_ws {
    size_t rows, cols, J;
    double *G, *Gq, *dG, *HdH, *Hq, *Z, *Y, *wr, *wc, *ssq;
    double *GdG, *HH, *GGq, *HdH2, *dGdG, *dGGq, *GqGq, *dHdH;
} near_ws_t;

static double *near_alloc(sb_context_t *ctx, near_ws_t *w, size_t rows, size_t cols, size_t J, int direct) {
    size_t nr, nc, total, k = direct ? 2 : 5;
    if (sb_size_mul(rows, k * J, &nr) || sb_size_mul(cols, k * J, &nc) || sb_size_add(nr, nc, &total) ||
        sb_size_add(total, 8 * J * J + rows + cols + 3 * J, &total)) {
        sb_error(ctx, SB_ERR_OVERFLOW, "errors: workspace size overflows");
        return NULL;
    }
    double *ws = sb_alloc(ctx, total, sizeof(double), "errors workspace");
    if (!ws) return NULL;
    *w = (near_ws_t){.rows = rows, .cols = cols, .J = J, .Gq = ws};
    w->Hq = w->Gq + rows * J;
    w->wr = w->Hq + cols * J;
    w->wc = w->wr + rows;
    w->ssq = w->wc + cols;
    double **blocks[] = {&w->GdG, &w->HH, &w->GGq, &w->HdH2, &w->dGdG, &w->dGGq, &w->GqGq, &w->dHdH};
    double *at = w->ssq + 3 * J;
    for (size_t i = 0; i < 8; i++, at += J * J) /* the Gram blocks, J x J each */
        *blocks[i] = at;
    w->Z = at;
    w->Y = w->Z + cols * (direct ? 1 : 2) * J;
    if (direct) return ws; /* G, dG, H and dH: the other form's */
    w->G = w->Y + rows * 2 * J;
    w->dG = w->G + rows * J;
    w->HdH = w->dG + rows * J;
    return ws;
}

/* Step: weighted, scaled factors and their differences (channel fc); the
 * direct form's G~ and H~ alone where direct is set. */
static void near_factors(near_ws_t *w, const sb_factors_t *fit, const sb_factors_t *near, size_t fc, double sg,
                         double sh, int direct) {
    size_t rows = w->rows, cols = w->cols, J = w->J;
    for (size_t j = 0; j < J; j++) {
        const double *g = sb_factors_tex_const(fit, SB_SIDE_G, j, fc),
                     *q = sb_factors_tex_const(near, SB_SIDE_G, j, fc);
        const double *h = sb_factors_tex_const(fit, SB_SIDE_H, j, fc),
                     *p = sb_factors_tex_const(near, SB_SIDE_H, j, fc);
        for (size_t i = 0; i < rows; i++)
            w->Gq[i + j * rows] = w->wr[i] * q[i] * sg;
        for (size_t i = 0; i < cols; i++)
            w->Hq[i + j * cols] = w->wc[i] * p[i] * sh;
        if (direct) continue;
        for (size_t i = 0; i < rows; i++) {
            w->G[i + j * rows] = w->wr[i] * g[i] * sg;
            w->dG[i + j * rows] = w->wr[i] * (g[i] - q[i]) * sg;
        }
        for (size_t i = 0; i < cols; i++) {
            w->HdH[i + j * cols] = w->wc[i] * h[i] * sh;
            w->HdH[i + (J + j) * cols] = w->wc[i] * (h[i] - p[i]) * sh;
        }
    }
}

/* Step: Y = X [H, dH] = W_r M (W_c [H, dH]) (one read of M), Gram blocks. */
static sb_result_t near_products(sb_context_t *ctx, near_ws_t *w, const sb_matrix_t *m, int ch, double sx) {
    size_t rows = w->rows, cols = w->cols, J = w->J;
    for (size_t i = 0; i < cols * 2 * J; i++)
        w->Z[i] = w->HdH[i] * w->wc[i % cols] * sx;
    sb_result_t r = sb_matrix_mul(ctx, m, ch, 2 * J, w->Z, cols, w->Y, rows); /* dense or structured */
    if (r != SB_OK) return r;
    for (size_t i = 0; i < rows * 2 * J; i++)
        w->Y[i] *= w->wr[i % rows];
    const double *dH = w->HdH + cols * J;
    gram(rows, J, w->G, w->dG, w->GdG);
    gram(rows, J, w->G, w->Gq, w->GGq);
    gram(rows, J, w->dG, w->dG, w->dGdG);
    gram(rows, J, w->dG, w->Gq, w->dGGq);
    gram(rows, J, w->Gq, w->Gq, w->GqGq);
    gram(cols, J, w->HdH, w->HdH, w->HH);
    gram(cols, J, w->HdH, dH, w->HdH2);
    gram(cols, J, dH, dH, w->dHdH);
    return SB_OK;
}

/* Step: prefix sums over J': ssq[b] = ||X - G~_b H~_b^T||^2 from the fit's
 * rel (rel_rms of the channel, stride 4) and norm nx (both scaled). */
static void near_prefix(const near_ws_t *w, const double *rel, double nx, double *ssq) {
    size_t rows = w->rows, J = w->J;
    double xd = 0, gd = 0, dd = 0;
    for (size_t b = 0; b < J; b++) {
        /* Y[:, b] = X h_b scaled by sx sh; the dG, G~ carry sg: sx sg sh = sx^2 */
        for (size_t i = 0; i < rows; i++)
            xd += w->dG[i + b * rows] * w->Y[i + b * rows] + w->Gq[i + b * rows] * w->Y[i + (J + b) * rows];
        /* pairs (a, b) with max(a, b) == b */
        for (size_t a2 = 0; a2 <= b; a2++) {
            size_t idx[2] = {a2 + b * J, b + a2 * J};
            for (int t = 0; t < (a2 != b ? 2 : 1); t++) {
                size_t ab = idx[t];
                gd += w->GdG[ab] * w->HH[ab] + w->GGq[ab] * w->HdH2[ab];
                dd += w->dGdG[ab] * w->HH[ab] + 2 * w->dGGq[ab] * w->HdH2[ab] + w->GqGq[ab] * w->dHdH[ab];
            }
        }
        double r = rel[sb_err_at(b, 0)] * nx, s2 = r * r + 2 * (xd - gd) + dd;
        ssq[b] = s2 < 0 ? 0 : s2;
    }
}

/* Step, direct form (NEAR_DIRECT_REL): Y = X H~ (J columns), the Gram
 * blocks of G~ and H~, and the prefix sums ssq[b] = ||X||^2 -
 * 2 sum_a g~_a . (X h~_a) + sum_ac (g~_a . g~_c)(h~_a . h~_c) over a, c <= b. */
static sb_result_t near_direct(sb_context_t *ctx, near_ws_t *w, const sb_matrix_t *m, int ch, double sx, double nx,
                               double *ssq) {
    size_t rows = w->rows, cols = w->cols, J = w->J;
    for (size_t i = 0; i < cols * J; i++)
        w->Z[i] = w->Hq[i] * w->wc[i % cols] * sx;
    sb_result_t r = sb_matrix_mul(ctx, m, ch, J, w->Z, cols, w->Y, rows);
    if (r != SB_OK) return r;
    for (size_t i = 0; i < rows * J; i++)
        w->Y[i] *= w->wr[i % rows];
    gram(rows, J, w->Gq, w->Gq, w->GqGq);
    gram(cols, J, w->Hq, w->Hq, w->HH);
    double xd = 0, dd = 0;
    for (size_t b = 0; b < J; b++) {
        for (size_t i = 0; i < rows; i++)
            xd += w->Gq[i + b * rows] * w->Y[i + b * rows];
        for (size_t a = 0; a <= b; a++) /* pairs (a, b) and (b, a) with max(a, b) == b */
            dd += (a != b ? 2 : 1) * w->GqGq[a + b * J] * w->HH[a + b * J];
        double s2 = nx * nx - 2 * xd + dd;
        ssq[b] = s2 < 0 ? 0 : s2;
    }
    return SB_OK;
}

sb_result_t sb_factors_errors_near(sb_context_t *ctx, const sb_factors_t *fit, const sb_factors_t *near,
                                   const sb_matrix_t *m, const sb_param_t *weights, double *rel_rms) {
    if (!fit || !near || !m || !rel_rms) return sb_error(ctx, SB_ERR_ARG, "errors: missing argument");
    if (m->mask) return sb_error(ctx, SB_ERR_ARG, "errors: a masked matrix needs the explicit residual");
    size_t J = sb_factors_terms(fit), C = sb_factors_channels(fit), rows = m->rows, cols = m->cols;
    if (check_fit(ctx, fit, m, weights) != SB_OK || check_fit(ctx, near, m, weights) != SB_OK ||
        sb_factors_terms(near) != J || sb_factors_channels(near) != C || J > INT_MAX / 2 || rows > INT_MAX ||
        cols > INT_MAX)
        return sb_error(ctx, SB_ERR_ARG, "errors: factors do not fit each other or the %zu x %zu matrix", rows, cols);
    sb_result_t rb = sb_blas_reserve(ctx);
    if (rb != SB_OK) return rb;
    const sb_factor_errors_t *fe = sb_factors_errors(fit);
    memset(rel_rms, 0, J * 4 * sizeof *rel_rms);
    /* Step: scales 2^-e ~ 1 / ||X||, split between the two sides */
    int ex = 0;
    if (fe->norm[3] > 0 && isfinite(fe->norm[3])) frexp(fe->norm[3], &ex);
    ex = ex > 1000 ? 1000 : (ex < -1000 ? -1000 : ex);
    double sx = ldexp(1, -ex), sg = ldexp(1, -(ex / 2)), sh = ldexp(1, -(ex - ex / 2));
    int direct[3], all_direct = 1;
    for (int ch = 0; ch < 3; ch++) {
        direct[ch] = fe->rel_rms[sb_err_at(J - 1, (size_t)ch)] >= NEAR_DIRECT_REL;
        all_direct &= direct[ch] || !m->data[ch];
    }
    near_ws_t w;
    double *ws = near_alloc(ctx, &w, rows, cols, J, all_direct);
    if (!ws) return sb_error(ctx, SB_ERR_NOMEM, "errors: out of memory");
    double *ssq = w.ssq, n2[3] = {0, 0, 0};
    for (size_t i = 0; i < rows + cols; i++)
        w.wr[i] = 1;
    if (weights) sb_errors_weights(weights, w.wr, w.wc);
    int present[3];
    for (int ch = 0; ch < 3; ch++) {
        present[ch] = m->data[ch] != NULL;
        if (!present[ch]) continue;
        near_factors(&w, fit, near, C == 1 ? 0 : (size_t)ch, sg, sh, direct[ch]);
        double nx = fe->norm[ch] * sx;
        n2[ch] = nx * nx;
        sb_result_t r =
            direct[ch] ? near_direct(ctx, &w, m, ch, sx, nx, ssq + (size_t)ch * J) : near_products(ctx, &w, m, ch, sx);
        if (r != SB_OK) {
            free(ws);
            return r;
        }
        if (!direct[ch]) near_prefix(&w, fe->rel_rms + ch, nx, ssq + (size_t)ch * J);
    }
    sb_result_t res = sb_errors_relative(ctx, J, present, ssq, NULL, n2, rel_rms, NULL);
    free(ws);
    return res;
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
