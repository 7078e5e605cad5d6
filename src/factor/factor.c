/* Factors (texture pairs with sigma and metadata), the factorisation plan
 * and the reconstruction through texture lookups. */
#include "sepbrdf/factor.h"

#include <pthread.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sepbrdf/channels.h"
#include "solve/circulant.h"
#include "solve/fit.h"
#include "util/internal.h"

/* |sum(u)| below this fraction of sum|u| counts as zero for the sign rule. */
#define SB_SIGN_TIE 1e-8

/* ---- factors ----------------------------------------------------------- */

typedef struct meta {
    char *key, *value;
} meta_t;

struct sb_factors {
    size_t terms, channels;
    size_t w[2], h[2];
    double *tex[2]; /* [side]: terms * channels * w*h, term-major */
    double *sigma;  /* terms * channels */
    meta_t *meta;
    size_t nmeta;
    sb_factor_errors_t err;
};

sb_result_t sb_factors_create(sb_context_t *ctx, size_t terms, size_t channels, size_t g_w, size_t g_h, size_t h_w,
                              size_t h_h, sb_factors_t **out) {
    if (!out) return sb_error(ctx, SB_ERR_ARG, "factors: no output pointer");
    *out = NULL;
    if (terms == 0) return sb_error(ctx, SB_ERR_RANGE, "factors: need at least one term");
    if (channels != 1 && channels != 3)
        return sb_error(ctx, SB_ERR_RANGE, "factors: %zu channels, need 1 or 3", channels);
    if (!g_w || !g_h || !h_w || !h_h) return sb_error(ctx, SB_ERR_RANGE, "factors: empty texture size");
    if (terms > SIZE_MAX / 4) return sb_error(ctx, SB_ERR_OVERFLOW, "factors: %zu terms overflow", terms);
    sb_factors_t *f = calloc(1, sizeof *f);
    if (!f) return sb_error(ctx, SB_ERR_NOMEM, "factors: out of memory");
    f->terms = terms;
    f->channels = channels;
    f->w[0] = g_w;
    f->h[0] = g_h;
    f->w[1] = h_w;
    f->h[1] = h_h;
    for (int s = 0; s < 2; s++) {
        size_t n;
        if (sb_size_mul3(f->w[s], f->h[s], terms * channels, &n)) {
            sb_factors_destroy(f);
            return sb_error(ctx, SB_ERR_OVERFLOW, "factors: texture size overflows");
        }
        f->tex[s] = sb_calloc(ctx, n, sizeof(double), "factor textures");
        if (!f->tex[s]) {
            sb_factors_destroy(f);
            return SB_ERR_NOMEM;
        }
    }
    f->sigma = sb_calloc(ctx, terms * channels, sizeof(double), "factors");
    f->err.terms = terms;
    f->err.rel_rms = sb_calloc(ctx, terms * 4, sizeof(double), "factor errors");
    f->err.max_abs = sb_calloc(ctx, terms * 4, sizeof(double), "factor errors");
    if (!f->sigma || !f->err.rel_rms || !f->err.max_abs) {
        sb_factors_destroy(f);
        return SB_ERR_NOMEM;
    }
    *out = f;
    return SB_OK;
}

void sb_factors_destroy(sb_factors_t *f) {
    if (!f) return;
    free(f->tex[0]);
    free(f->tex[1]);
    free(f->sigma);
    for (size_t i = 0; i < f->nmeta; i++) {
        free(f->meta[i].key);
        free(f->meta[i].value);
    }
    free(f->meta);
    free(f->err.rel_rms);
    free(f->err.max_abs);
    free(f);
}

/* Accessors: safe values for NULL and out-of-range arguments (common.h). */
static int in_range(const sb_factors_t *f, int side, size_t term, size_t ch) {
    return f && (side == SB_SIDE_G || side == SB_SIDE_H) && term < f->terms && ch < f->channels;
}
size_t sb_factors_terms(const sb_factors_t *f) { return f ? f->terms : 0; }
size_t sb_factors_channels(const sb_factors_t *f) { return f ? f->channels : 0; }
void sb_factors_size(const sb_factors_t *f, int side, size_t *w, size_t *h) {
    int ok = in_range(f, side, 0, 0);
    if (w) *w = ok ? f->w[side] : 0;
    if (h) *h = ok ? f->h[side] : 0;
}
double *sb_factors_tex(sb_factors_t *f, int side, size_t term, size_t ch) {
    if (!in_range(f, side, term, ch)) return NULL;
    return f->tex[side] + (term * f->channels + ch) * f->w[side] * f->h[side];
}
const double *sb_factors_tex_const(const sb_factors_t *f, int side, size_t term, size_t ch) {
    if (!in_range(f, side, term, ch)) return NULL;
    return f->tex[side] + (term * f->channels + ch) * f->w[side] * f->h[side];
}
double sb_factors_sigma(const sb_factors_t *f, size_t term, size_t ch) {
    return in_range(f, SB_SIDE_G, term, ch) ? f->sigma[term * f->channels + ch] : NAN;
}
void sb_factors_set_sigma(sb_factors_t *f, size_t term, size_t ch, double s) {
    if (in_range(f, SB_SIDE_G, term, ch)) f->sigma[term * f->channels + ch] = s;
}

sb_result_t sb_factors_set_meta(sb_factors_t *f, const char *key, const char *value) {
    if (!f || !key || !value) return SB_ERR_ARG;
    for (size_t i = 0; i < f->nmeta; i++)
        if (strcmp(f->meta[i].key, key) == 0) {
            char *v = sb_strdup(value);
            if (!v) return SB_ERR_NOMEM;
            free(f->meta[i].value);
            f->meta[i].value = v;
            return SB_OK;
        }
    meta_t *m = realloc(f->meta, (f->nmeta + 1) * sizeof *m);
    if (!m) return SB_ERR_NOMEM;
    f->meta = m;
    m[f->nmeta].key = sb_strdup(key);
    m[f->nmeta].value = sb_strdup(value);
    if (!m[f->nmeta].key || !m[f->nmeta].value) {
        free(m[f->nmeta].key);
        free(m[f->nmeta].value);
        return SB_ERR_NOMEM;
    }
    f->nmeta++;
    return SB_OK;
}
const char *sb_factors_get_meta(const sb_factors_t *f, const char *key) {
    if (!f || !key) return NULL;
    for (size_t i = 0; i < f->nmeta; i++)
        if (strcmp(f->meta[i].key, key) == 0) return f->meta[i].value;
    return NULL;
}
size_t sb_factors_meta_count(const sb_factors_t *f) { return f ? f->nmeta : 0; }
void sb_factors_meta_at(const sb_factors_t *f, size_t i, const char **key, const char **value) {
    int ok = f && i < f->nmeta;
    if (key) *key = ok ? f->meta[i].key : NULL;
    if (value) *value = ok ? f->meta[i].value : NULL;
}
const sb_factor_errors_t *sb_factors_errors(const sb_factors_t *f) { return f ? &f->err : NULL; }
sb_factor_errors_t *sb_factors_errors_mut(sb_factors_t *f) { return f ? &f->err : NULL; }

double sb_factors_cell(const sb_factors_t *f, size_t terms, size_t ch, size_t row, size_t col) {
    if (!in_range(f, SB_SIDE_G, 0, ch) || row >= f->w[0] * f->h[0] || col >= f->w[1] * f->h[1]) return NAN;
    double s = 0;
    if (terms > f->terms) terms = f->terms;
    for (size_t j = 0; j < terms; j++)
        s += sb_factors_tex_const(f, 0, j, ch)[row] * sb_factors_tex_const(f, 1, j, ch)[col];
    return s;
}

/* GL texel addressing: u = s * w - 1/2, i0 = floor(u), a = u - i0; wrap is
 * applied to i0 and i0 + 1 (CLAMP_TO_EDGE clamps, REPEAT takes mod w). */
static size_t wrap_index(long i, size_t n, int mode) {
    if (mode == SB_WRAP_REPEAT) {
        long m = i % (long)n;
        return (size_t)(m < 0 ? m + (long)n : m);
    }
    if (i < 0) return 0;
    if ((size_t)i >= n) return n - 1;
    return (size_t)i;
}

double sb_factors_lookup(const sb_factors_t *f, const sb_param_t *p, int side, size_t term, size_t ch,
                         const double st[2]) {
    if (!in_range(f, side, term, ch) || !p || !st) return NAN;
    size_t w = f->w[side], h = f->h[side];
    int wrap[2];
    sb_param_wrap(p, side, wrap);
    const double *t = sb_factors_tex_const(f, side, term, ch);
    double u = st[0] * (double)w - 0.5, v = st[1] * (double)h - 0.5;
    if (!isfinite(u) || !isfinite(v)) return NAN;
    /* far outside: whole periods off (REPEAT) or any edge value (CLAMP), so
     * that the texel index fits a long */
    if (fabs(u) > 1e9) u = wrap[0] == SB_WRAP_REPEAT ? fmod(u, (double)w) : copysign(1e9, u);
    if (fabs(v) > 1e9) v = wrap[1] == SB_WRAP_REPEAT ? fmod(v, (double)h) : copysign(1e9, v);
    double fu = floor(u), fv = floor(v);
    double a = u - fu, b = v - fv;
    size_t x0 = wrap_index((long)fu, w, wrap[0]), x1 = wrap_index((long)fu + 1, w, wrap[0]);
    size_t y0 = wrap_index((long)fv, h, wrap[1]), y1 = wrap_index((long)fv + 1, h, wrap[1]);
    return (1 - b) * ((1 - a) * t[y0 * w + x0] + a * t[y0 * w + x1]) +
           b * ((1 - a) * t[y1 * w + x0] + a * t[y1 * w + x1]);
}

int sb_factors_eval(const sb_factors_t *f, const sb_param_t *p, sb_form_t form, size_t terms, const double wi[3],
                    const double wo[3], double rgb[3]) {
    double sg[2], sh[2];
    if (!rgb) return 0;
    rgb[0] = rgb[1] = rgb[2] = 0;
    if (!f || (unsigned)form >= SB_FORM_COUNT_ || !sb_param_coords(p, wi, wo, sg, sh)) return 0;
    if (terms > f->terms) terms = f->terms;
    double acc[3] = {0, 0, 0};
    for (size_t j = 0; j < terms; j++)
        for (size_t c = 0; c < f->channels; c++)
            acc[c] += sb_factors_lookup(f, p, 0, j, c, sg) * sb_factors_lookup(f, p, 1, j, c, sh);
    if (f->channels == 1) acc[1] = acc[2] = acc[0];
    /* divide back the factored form, with the lecture's grazing guard */
    double w = 1;
    if (form == SB_FORM_COS) w = fmax(wi[2], 0.001);
    if (form == SB_FORM_COS2) w = fmax(wi[2], 0.001) * fmax(wo[2], 0.001);
    for (int c = 0; c < 3; c++)
        rgb[c] = acc[c] / w;
    return 1;
}

/* ---- plan -------------------------------------------------------------- */

struct sb_plan {
    sb_context_t *ctx;
    size_t rows, cols, terms;
    sb_plan_opts_t opts;
    sb_svd_t *svd;
    sb_fit_t *fit;   /* created on the first masked execute */
    sb_circ_t *circ; /* created on the first block-circulant execute */
    double *tails;   /* block-circulant: exact squared errors of the base channel, J */
    double *s, *u, *v;
    double *x;         /* weighted copy of a channel (weighted plans only) */
    double *wr, *wc;   /* row / column weights (weighted plans only) */
    double *iwr, *iwc; /* their inverses (0 where the weight is 0) */
    double *col;       /* one residual column (per thread: threads x rows) */
    double *sbase;     /* sigma of the base channel (proportional channels) */
    int vneg;          /* p->v currently negated */
    sb_plan_stats_t stats;
    int nthreads; /* residual threads */
};

sb_result_t sb_plan_create(sb_context_t *ctx, size_t rows, size_t cols, const sb_plan_opts_t *opts, sb_plan_t **out) {
    if (!out) return sb_error(ctx, SB_ERR_ARG, "plan: no output pointer");
    *out = NULL;
    sb_plan_opts_t o = {0};
    if (opts) o = *opts;
    if (o.terms == 0) o.terms = 4;
    size_t mn = rows < cols ? rows : cols;
    if (rows == 0 || cols == 0) return sb_error(ctx, SB_ERR_ARG, "plan: empty matrix");
    if (o.terms > mn)
        return sb_error(ctx, SB_ERR_RANGE,
                        "--terms %zu exceeds the matrix rank limit %zu; lower --terms or raise --res", o.terms, mn);
    if (!(o.max_error >= 0 && o.max_error < 1))
        return sb_error(ctx, SB_ERR_RANGE, "--max-error %g out of range, need [0, 1)", o.max_error);
    sb_result_t rb = sb_blas_reserve(ctx);
    if (rb != SB_OK) return rb;
    sb_plan_t *p = calloc(1, sizeof *p);
    if (!p) return sb_error(ctx, SB_ERR_NOMEM, "plan: out of memory");
    p->ctx = ctx;
    p->rows = rows;
    p->cols = cols;
    p->terms = o.terms;
    p->opts = o;
    /* Refuse up front what cannot fit: at least one channel of the matrix
     * and its mask (held by the caller), plus the weighted copy. */
    size_t cells, need;
    if (sb_size_mul(rows, cols, &cells) || sb_size_mul(cells, 9 + (o.weighted ? 8 : 0), &need)) {
        free(p);
        return sb_error(ctx, SB_ERR_OVERFLOW, "plan: a %zu x %zu matrix overflows the address space; lower --res", rows,
                        cols);
    }
    if (need > sb_memory_limit()) {
        free(p);
        return sb_error(ctx, SB_ERR_OVERFLOW,
                        "plan: a %zu x %zu matrix needs at least %zu bytes, more than the memory limit of %zu bytes; "
                        "lower --res",
                        rows, cols, need, sb_memory_limit());
    }
    sb_result_t r = sb_svd_create(ctx, rows, cols, o.terms, &o.svd, &p->svd);
    if (r != SB_OK) {
        free(p);
        return r;
    }
    p->s = sb_alloc(ctx, o.terms, sizeof(double), "plan");
    p->u = sb_alloc(ctx, rows * o.terms, sizeof(double), "plan");
    p->v = sb_alloc(ctx, cols * o.terms, sizeof(double), "plan");
    p->nthreads = sb_thread_count(0);
    if (p->nthreads > 16) p->nthreads = 16;
    p->col = sb_alloc(ctx, rows * (size_t)p->nthreads, sizeof(double), "plan");
    p->sbase = sb_alloc(ctx, o.terms, sizeof(double), "plan");
    if (!p->s || !p->u || !p->v || !p->col || !p->sbase) {
        sb_plan_destroy(p);
        return SB_ERR_NOMEM;
    }
    if (o.weighted) {
        p->x = sb_alloc(ctx, cells, sizeof(double), "plan weighted matrix");
        p->wr = sb_alloc(ctx, rows, sizeof(double), "plan");
        p->wc = sb_alloc(ctx, cols, sizeof(double), "plan");
        p->iwr = sb_alloc(ctx, rows, sizeof(double), "plan");
        p->iwc = sb_alloc(ctx, cols, sizeof(double), "plan");
        if (!p->x || !p->wr || !p->wc || !p->iwr || !p->iwc) {
            sb_plan_destroy(p);
            return SB_ERR_NOMEM;
        }
    }
    *out = p;
    return SB_OK;
}

void sb_plan_destroy(sb_plan_t *p) {
    if (!p) return;
    sb_svd_destroy(p->svd);
    sb_fit_destroy(p->fit);
    sb_circ_destroy(p->circ);
    free(p->tails);
    free(p->s);
    free(p->u);
    free(p->v);
    free(p->x);
    free(p->wr);
    free(p->wc);
    free(p->iwr);
    free(p->iwc);
    free(p->col);
    free(p->sbase);
    free(p);
}

size_t sb_plan_terms(const sb_plan_t *p) { return p ? p->terms : 0; }
void sb_plan_stats(const sb_plan_t *p, sb_plan_stats_t *out) {
    sb_plan_stats_t none = {0, 0, 0, 0};
    if (out) *out = p ? p->stats : none;
}

/* Residual errors of every truncation J' = 1..J in one pass over the
 * columns: r = x_c - sum_{j<=J'} s_j v_j[c] u_j, accumulated over valid rows
 * (ssq per J' in the fitted, possibly weighted, norm; max |r| in native
 * units, i.e. divided by the weights).  No matrix-sized buffer is needed;
 * columns are split among threads, each with its own column buffer and
 * sums, added in a fixed order so results do not depend on timing. */
typedef struct res_job {
    const sb_plan_t *p;
    const sb_matrix_t *m;
    const double *a;
    size_t c0, c1;
    double *r, *ssq, *mx;
    double pw; /* power-of-two scale of the sums of squares (see sb_plan_execute) */
} res_job_t;

/* One term of the residual of a column without mask: r -= sv u; returns
 * sum (r pw)^2 and raises *mx to max |r| iw iwc (native units; iw NULL:
 * unweighted).  Two lanes with SSE2, which GCC does not produce itself for
 * the maximum (its NaN rules differ from maxpd; the matrix is finite). */
static double resid_step(double *r, const double *u, double sv, size_t n, const double *iw, double iwc, double pw,
                         double *mx) {
    size_t i = 0;
    double s2 = 0, m = *mx;
#if defined(__SSE2__)
    __m128d vs = _mm_set1_pd(sv), vp = _mm_set1_pd(pw), vw = _mm_set1_pd(iwc), sign = _mm_set1_pd(-0.0);
    __m128d acc = _mm_setzero_pd(), vm = _mm_set1_pd(m);
    for (; i + 2 <= n; i += 2) {
        __m128d x = _mm_sub_pd(_mm_loadu_pd(r + i), _mm_mul_pd(vs, _mm_loadu_pd(u + i)));
        _mm_storeu_pd(r + i, x);
        __m128d d = _mm_mul_pd(x, vp), a = _mm_andnot_pd(sign, x);
        acc = _mm_add_pd(acc, _mm_mul_pd(d, d));
        if (iw) a = _mm_mul_pd(a, _mm_mul_pd(_mm_loadu_pd(iw + i), vw));
        vm = _mm_max_pd(vm, a);
    }
    double t[2];
    _mm_storeu_pd(t, acc);
    s2 = t[0] + t[1];
    _mm_storeu_pd(t, vm);
    m = t[0] > t[1] ? t[0] : t[1];
#endif
    for (; i < n; i++) {
        r[i] -= sv * u[i];
        double d = r[i] * pw, a = fabs(r[i]) * (iw ? iw[i] * iwc : 1);
        s2 += d * d;
        if (a > m) m = a;
    }
    *mx = m;
    return s2;
}

static void *residual_cols(void *arg) {
    res_job_t *jb = arg;
    const sb_plan_t *p = jb->p;
    const sb_matrix_t *m = jb->m;
    size_t rows = p->rows, cols = p->cols, J = p->terms;
    const double *wr = p->opts.weighted ? p->wr : NULL, *wc = p->opts.weighted ? p->wc : NULL;
    for (size_t j = 0; j < J; j++)
        jb->ssq[j] = jb->mx[j] = 0;
    for (size_t c = jb->c0; c < jb->c1; c++) {
        double *r = jb->r;
        const double *a = jb->a;
        const unsigned char *mk = m->mask ? m->mask + c * m->ld : NULL;
        for (size_t i = 0; i < rows; i++)
            r[i] = wr ? wr[i] * a[i + c * m->ld] * wc[c] : a[i + c * m->ld];
        for (size_t j = 0; j < J; j++) {
            const double *u = p->u + j * rows;
            double sv = p->s[j] * p->v[c + j * cols], s2 = 0, mj = jb->mx[j];
            if (!mk) {
                jb->ssq[j] += resid_step(r, p->u + j * rows, sv, rows, wr ? p->iwr : NULL, wr ? p->iwc[c] : 1, jb->pw,
                                         &jb->mx[j]);
                continue;
            }
            for (size_t i = 0; i < rows; i++) {
                r[i] -= sv * u[i];
                if (mk && !mk[i]) continue;
                double d = r[i], ds = d * jb->pw; /* squares of scaled values: no under/overflow */
                s2 += ds * ds;
                double dn = fabs(wr ? d / (wr[i] * wc[c]) : d);
                if (dn > mj) mj = dn;
            }
            jb->ssq[j] += s2;
            jb->mx[j] = mj;
        }
    }
    return NULL;
}

static sb_result_t residuals(sb_plan_t *p, const sb_matrix_t *m, const double *a, double pw, double *ssq, double *mx) {
    size_t J = p->terms, cols = p->cols;
    int nt = p->nthreads;
    if ((size_t)nt > cols) nt = (int)cols;
    /* small matrices: threads cost more than they save */
    if (p->rows * cols * J < ((size_t)1 << 18)) nt = 1;
    double *acc = calloc((size_t)nt * J * 2, sizeof *acc);
    if (!acc) return sb_error(p->ctx, SB_ERR_NOMEM, "plan: out of memory");
    res_job_t jobs[16];
    pthread_t th[16];
    int started[16] = {0};
    for (int t = 0; t < nt; t++) {
        jobs[t] = (res_job_t){p,
                              m,
                              a,
                              cols * (size_t)t / (size_t)nt,
                              cols * (size_t)(t + 1) / (size_t)nt,
                              p->col + (size_t)t * p->rows,
                              acc + (size_t)t * 2 * J,
                              acc + (size_t)t * 2 * J + J,
                              pw};
        if (t > 0) started[t] = pthread_create(&th[t], NULL, residual_cols, &jobs[t]) == 0;
    }
    residual_cols(&jobs[0]);
    for (int t = 1; t < nt; t++) {
        if (started[t])
            pthread_join(th[t], NULL);
        else
            residual_cols(&jobs[t]);
    }
    for (size_t j = 0; j < J; j++) {
        ssq[j] = mx[j] = 0;
        for (int t = 0; t < nt; t++) {
            ssq[j] += jobs[t].ssq[j];
            if (jobs[t].mx[j] > mx[j]) mx[j] = jobs[t].mx[j];
        }
    }
    free(acc);
    return SB_OK;
}

sb_result_t sb_plan_execute(sb_plan_t *p, const sb_matrix_t *m, const sb_param_t *param, sb_factors_t **out) {
    if (!p) return sb_error(NULL, SB_ERR_ARG, "plan: no plan");
    sb_context_t *ctx = p->ctx;
    if (!m || !param || !out) return sb_error(ctx, SB_ERR_ARG, "plan: missing matrix, parameterisation or output");
    *out = NULL;
    if (m->ld < m->rows) return sb_error(ctx, SB_ERR_ARG, "plan: leading dimension %zu < %zu rows", m->ld, m->rows);
    if (m->rows != p->rows || m->cols != p->cols)
        return sb_error(ctx, SB_ERR_ARG, "plan: matrix is %zu x %zu, plan was made for %zu x %zu", m->rows, m->cols,
                        p->rows, p->cols);
    size_t gw, gh, hw, hh, J = p->terms, rows = p->rows, cols = p->cols;
    sb_param_texture_size(param, SB_SIDE_G, &gw, &gh);
    sb_param_texture_size(param, SB_SIDE_H, &hw, &hh);
    if (gw * gh != rows || hw * hh != cols)
        return sb_error(ctx, SB_ERR_ARG, "plan: parameterisation does not match the matrix");
    int masked = m->mask && !p->opts.zero_fill;
    memset(&p->stats, 0, sizeof p->stats);
    p->stats.masked = masked;
    p->stats.fit_converged = 1;
    if (masked && !p->fit) {
        sb_result_t r = sb_fit_create(ctx, rows, cols, J, &p->fit);
        if (r != SB_OK) return r;
    }
    if (p->opts.weighted) {
        for (size_t i = 0; i < rows; i++)
            p->wr[i] = sqrt(fmax(sb_param_row_measure(param, i), 0));
        for (size_t i = 0; i < cols; i++)
            p->wc[i] = sqrt(fmax(sb_param_col_measure(param, i), 0));
        for (size_t i = 0; i < rows; i++)
            p->iwr[i] = p->wr[i] > 0 ? 1 / p->wr[i] : 0;
        for (size_t i = 0; i < cols; i++)
            p->iwc[i] = p->wc[i] > 0 ? 1 / p->wc[i] : 0;
    }

    sb_factors_t *f;
    sb_result_t r = sb_factors_create(ctx, J, 3, gw, gh, hw, hh, &f);
    if (r != SB_OK) return r;
    sb_factor_errors_t *e = sb_factors_errors_mut(f);
    double *ssq = calloc(J * 4, sizeof(double)), *mx = calloc(J, sizeof(double));
    if (!ssq || !mx) {
        free(ssq);
        free(mx);
        sb_factors_destroy(f);
        return sb_error(ctx, SB_ERR_NOMEM, "plan: out of memory");
    }
    /* Sums of squares are taken on values multiplied by a power of two near
     * 1 / max |M| (exact), so that 1e-300 or 1e200 BRDFs keep a finite,
     * nonzero norm (they gave rel_rms 0 and a non-finite error); the ratios
     * rel_rms are unchanged by it. */
    /* Even block-circulant matrices (isotropic sources on the io grid, see
     * circulant.h) get the exact SVD from their R^3 distinct values when the
     * method is AUTO: the dense matrix is then never read beyond its first
     * block row. */
    size_t R = m->phi_period;
    const double *cw = p->opts.weighted ? p->wr : NULL;
    int circ = !m->mask && R > 0 && R * R == rows && rows == cols && p->opts.svd.method == SB_METHOD_AUTO;
    for (size_t i = 0; circ && cw && i < rows; i++)
        if (p->wr[i] != p->wr[i % R] || p->wc[i] != p->wr[i % R]) circ = 0;
    if (circ && !p->circ) {
        if (sb_circ_create(ctx, R, &p->circ) != SB_OK || !(p->tails = sb_alloc(ctx, J, sizeof(double), "plan"))) {
            sb_factors_destroy(f);
            free(ssq);
            free(mx);
            return SB_ERR_NOMEM;
        }
    }
    for (int ch = 0; circ && ch < 3; ch++)
        if (m->data[ch] && !sb_circ_is_even(p->circ, m->data[ch], m->ld, cw, 1e-9)) circ = 0;
    sb_matrix_t scan = *m; /* what the scans below read: the first block row holds every value */
    if (circ) scan.rows = R;
    /* Proportional channels (M_c = a_c M_base: grey or tinted BRDFs) are
     * factored once: the base channel first, then the others take its
     * vectors with sigma scaled by |a_c| (and h negated for a_c < 0).  The
     * check also gives the channel norms. */
    sb_channels_t chs;
    int have_chs = sb_channels_proportional(NULL, &scan, 0, &chs) == SB_OK;
    double total2 = 0, amax = 0, pw = 1;
    if (have_chs) { /* ||M_c|| bounds max |M|: no other pass */
        for (int ch = 0; ch < 3; ch++)
            if (m->data[ch] && chs.norm[ch] > amax) amax = chs.norm[ch];
    } else {
        for (int ch = 0; ch < 3; ch++)
            for (size_t c = 0; m->data[ch] && c < cols; c++) {
                const double *col = m->data[ch] + c * m->ld;
                const unsigned char *mk = m->mask ? m->mask + c * m->ld : NULL;
                for (size_t i = 0; i < scan.rows; i++) {
                    double x = fabs(col[i]);
                    if ((!mk || mk[i]) && x > amax) amax = x;
                }
            }
    }
    if (amax > 0 && isfinite(amax)) {
        int ex;
        frexp(amax, &ex); /* clamped: 2^1074 would overflow for denormal data */
        pw = ldexp(1, ex > 1020 ? -1020 : (ex < -1020 ? 1020 : -ex));
    }
    int prop = 0, order[3] = {0, 1, 2};
    if (have_chs && chs.proportional && chs.base >= 0) {
        prop = 1;
        order[0] = chs.base;
        for (int c = 0, n = 1; c < 3; c++)
            if (c != chs.base) order[n++] = c;
    }
    p->stats.proportional = prop;
    for (int oi = 0; oi < 3 && r == SB_OK; oi++) {
        int ch = order[oi];
        const double *a = m->data[ch];
        if (!a) continue;
        const double *x = a;
        size_t ldx = m->ld;
        if (p->opts.weighted && !circ) { /* X = W_r A W_c */
            for (size_t c = 0; c < cols; c++)
                for (size_t i = 0; i < rows; i++)
                    p->x[i + c * rows] = p->wr[i] * a[i + c * m->ld] * p->wc[c];
            x = p->x;
            ldx = rows;
        }
        if (prop && oi > 0) {
            /* p->s, p->u, p->v still hold the base channel's (sign-fixed) terms */
            double sc = chs.scale[ch], as = fabs(sc);
            for (size_t j = 0; j < J; j++)
                p->s[j] = p->sbase[j] * as;
            if (sc < 0 && !p->vneg) {
                for (size_t i = 0; i < cols * J; i++)
                    p->v[i] = -p->v[i];
                p->vneg = 1;
            } else if (sc >= 0 && p->vneg) {
                for (size_t i = 0; i < cols * J; i++)
                    p->v[i] = -p->v[i];
                p->vneg = 0;
            }
        } else if (circ) {
            r = sb_circ_svd(p->circ, a, m->ld, cw, J, pw, p->s, p->u, p->v, p->tails);
        } else if (masked) {
            sb_fit_opts_t fo = {p->opts.fit_max_iters, p->opts.fit_tol, p->opts.svd.seed, p->opts.max_error};
            sb_fit_info_t fi;
            r = sb_fit_execute(p->fit, x, ldx, m->mask, &fo, p->s, p->u, p->v, &fi);
            if (fi.iterations > p->stats.fit_iterations) p->stats.fit_iterations = fi.iterations;
            if (!fi.converged) p->stats.fit_converged = 0;
        } else {
            r = sb_svd_execute(p->svd, x, ldx, p->s, p->u, p->v, NULL, NULL);
        }
        if (r != SB_OK) break;
        /* sign: sum(u_j) >= 0; when the sum vanishes to rounding (common for
         * isotropic BRDFs, whose higher terms are orthogonal to constants),
         * the entry of largest magnitude is made positive instead. */
        for (size_t j = 0; j < J; j++) {
            double *u = p->u + j * rows, *v = p->v + j * cols, sum = 0, l1 = 0, big = 0;
            for (size_t i = 0; i < rows; i++) {
                double gi = p->opts.weighted && p->wr[i] > 0 ? u[i] / p->wr[i] : u[i];
                sum += gi;
                l1 += fabs(gi);
                if (fabs(gi) > fabs(big)) big = gi;
            }
            int flip = fabs(sum) > SB_SIGN_TIE * l1 ? sum < 0 : big < 0;
            if (flip && !(prop && oi > 0)) {
                for (size_t i = 0; i < rows; i++)
                    u[i] = -u[i];
                for (size_t i = 0; i < cols; i++)
                    v[i] = -v[i];
            }
        }
        if (prop && oi == 0) {
            memcpy(p->sbase, p->s, J * sizeof *p->s);
            p->vneg = 0;
        }
        /* norm of the fitted matrix on valid cells */
        double n2 = 0;
        if (circ)
            n2 = sb_circ_norm2(R, a, m->ld, cw, pw);
        else if (have_chs && !m->mask && !p->opts.weighted)
            n2 = (chs.norm[ch] * pw) * (chs.norm[ch] * pw);
        else
            for (size_t c = 0; c < cols; c++)
                for (size_t i = 0; i < rows; i++)
                    if (!m->mask || m->mask[i + c * m->ld]) n2 += (x[i + c * ldx] * pw) * (x[i + c * ldx] * pw);
        double nrm = sqrt(n2); /* scaled */
        e->norm[ch] = nrm / pw;
        total2 += n2;
        for (size_t j = 0; j < J; j++) {
            double sj = p->s[j], rt = sqrt(sj > 0 ? sj : 0);
            sb_factors_set_sigma(f, j, (size_t)ch, sj);
            double *g = sb_factors_tex(f, SB_SIDE_G, j, (size_t)ch), *h = sb_factors_tex(f, SB_SIDE_H, j, (size_t)ch);
            for (size_t i = 0; i < rows; i++) {
                double w = p->opts.weighted ? p->wr[i] : 1;
                g[i] = w > 0 ? rt * p->u[i + j * rows] / w : 0;
            }
            for (size_t i = 0; i < cols; i++) {
                double w = p->opts.weighted ? p->wc[i] : 1;
                h[i] = w > 0 ? rt * p->v[i + j * cols] / w : 0;
            }
        }
        if (circ) { /* exact tails; the max from the R^3 distinct values */
            double t = prop && oi > 0 ? chs.scale[ch] : 1;
            for (size_t j = 0; j < J; j++)
                ssq[(size_t)ch * J + j] = p->tails[j] * t * t;
            r = sb_circ_max_abs(p->circ, a, m->ld, cw, t, J, mx);
        } else {
            r = residuals(p, m, a, pw, ssq + (size_t)ch * J, mx);
        }
        if (r != SB_OK) break;
        for (size_t j = 0; j < J; j++) {
            e->rel_rms[j * 4 + ch] = nrm > 0 ? sqrt(ssq[(size_t)ch * J + j]) / nrm : 0;
            e->max_abs[j * 4 + ch] = mx[j];
            if (mx[j] > e->max_abs[j * 4 + 3]) e->max_abs[j * 4 + 3] = mx[j];
        }
    }
    if (r != SB_OK) {
        free(ssq);
        free(mx);
        sb_factors_destroy(f);
        return r;
    }
    e->norm[3] = sqrt(total2) / pw;
    for (size_t j = 0; j < J; j++) {
        double s2 = 0;
        for (int ch = 0; ch < 3; ch++)
            if (m->data[ch]) s2 += ssq[(size_t)ch * J + j];
        e->rel_rms[j * 4 + 3] = total2 > 0 ? sqrt(s2 / total2) : 0;
    }
    free(ssq);
    free(mx);
    for (size_t j = 0; j < J; j++)
        if (!isfinite(e->rel_rms[j * 4 + 3])) {
            sb_factors_destroy(f);
            return sb_error(ctx, SB_ERR_NUMERIC, "plan: non-finite error after %zu terms", j + 1);
        }
    /* stop at the error asked for */
    if (p->opts.max_error > 0) {
        size_t keep = J;
        for (size_t j = 0; j < J; j++)
            if (e->rel_rms[j * 4 + 3] <= p->opts.max_error) {
                keep = j + 1;
                break;
            }
        e->terms = keep;
        f->terms = keep; /* textures beyond `keep` stay allocated but unused */
    }
    sb_factors_set_meta(f, "param", sb_param_spec(param));
    sb_factors_set_meta(f, "form", sb_form_name(m->form));
    sb_factors_set_meta(f, "method", masked ? "masked" : circ ? "circulant" : sb_method_name(sb_svd_method(p->svd)));
    sb_factors_set_meta(f, "weighted", p->opts.weighted ? "1" : "0");
    *out = f;
    return SB_OK;
}
