/* Sampling a source on a parameterisation into per-channel matrices.
 *
 * M_c[r, c] = w(wi, wo) f_c(wi, wo), column-major (ld = rows), where w is
 * the form weight (1, cos theta_i, or cos theta_i cos theta_o) and (wi, wo)
 * the centre of cell (r, c).  Columns are split among threads; each thread
 * writes only its own columns, so no locking is needed.  Progress is one
 * shared atomic count of finished columns, reported by the calling thread
 * only, so the callback needs no thread safety. */
#include "sepbrdf/matrix.h"

#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "internal.h"

static const char *const form_names[SB_FORM_COUNT_] = {"f", "cos", "cos2"};

sb_result_t sb_form_parse(const char *name, sb_form_t *out) {
    for (int k = 0; k < SB_FORM_COUNT_; k++)
        if (name && strcmp(name, form_names[k]) == 0) {
            *out = (sb_form_t)k;
            return SB_OK;
        }
    return SB_ERR_UNKNOWN;
}
const char *sb_form_name(sb_form_t f) { return (unsigned)f < SB_FORM_COUNT_ ? form_names[f] : "?"; }

double sb_form_weight(sb_form_t form, const double wi[3], const double wo[3]) {
    double ci = wi[2] > 0 ? wi[2] : 0, co = wo[2] > 0 ? wo[2] : 0;
    switch (form) {
    case SB_FORM_COS: return ci;
    case SB_FORM_COS2: return ci * co;
    default: return 1.0;
    }
}

typedef struct job {
    const sb_source_t *src;
    const sb_param_t *param;
    sb_matrix_t *m;
    size_t c0, c1;
    size_t valid, measured;
    atomic_size_t *done;        /* columns finished by all threads */
    const sb_matrix_opts_t *o;  /* progress callback: job 0 only */
} job_t;

static void *build_cols(void *arg) {
    job_t *j = arg;
    sb_matrix_t *m = j->m;
    double wi[3], wo[3], rgb[3];
    for (size_t c = j->c0; c < j->c1; c++) {
        for (size_t r = 0; r < m->rows; r++) {
            size_t at = r + c * m->ld;
            int ok = sb_param_cell_dirs(j->param, r, c, wi, wo);
            int known = 0;
            rgb[0] = rgb[1] = rgb[2] = 0;
            if (ok) {
                known = sb_source_eval(j->src, wi, wo, rgb);
                double w = sb_form_weight(m->form, wi, wo);
                for (int ch = 0; ch < 3; ch++) {
                    double v = known ? rgb[ch] * w : 0.0;
                    if (!isfinite(v)) { /* a hostile table or a model singularity */
                        v = 0.0;
                        known = 0;
                    }
                    rgb[ch] = v;
                }
            }
            for (int ch = 0; ch < 3; ch++)
                if (m->data[ch]) m->data[ch][at] = known ? rgb[ch] : 0.0;
            if (m->mask) m->mask[at] = (unsigned char)(ok && known);
            j->valid += (size_t)(ok && known);
            j->measured += (size_t)(ok && known);
        }
        size_t done = atomic_fetch_add_explicit(j->done, 1, memory_order_relaxed) + 1;
        if (j->o) j->o->progress(j->o->progress_user, (double)done / (double)m->cols);
    }
    return NULL;
}

sb_result_t sb_matrix_build(sb_context_t *ctx, const sb_source_t *src, const sb_param_t *param,
                            const sb_matrix_opts_t *opts, sb_matrix_t *out) {
    if (!src || !param || !out) return sb_error(ctx, SB_ERR_ARG, "matrix: missing source or parameterisation");
    memset(out, 0, sizeof *out);
    sb_matrix_opts_t o = {0};
    if (opts) o = *opts;
    if ((unsigned)o.form >= SB_FORM_COUNT_) return sb_error(ctx, SB_ERR_ARG, "matrix: unknown form %d", (int)o.form);
    unsigned chans = o.channels ? (o.channels & 7u) : 7u;
    if (!chans) return sb_error(ctx, SB_ERR_ARG, "matrix: empty channel mask");

    size_t rows = sb_param_rows(param), cols = sb_param_cols(param), cells;
    if (sb_size_mul(rows, cols, &cells))
        return sb_error(ctx, SB_ERR_OVERFLOW, "matrix: %zu x %zu cells overflow; lower --res", rows, cols);
    /* Refuse up front when the channels would not fit in memory. */
    size_t nch = (size_t)((chans & 1) + ((chans >> 1) & 1) + ((chans >> 2) & 1)), bytes;
    if (sb_size_mul3(cells, nch + 1, sizeof(double), &bytes) || bytes > sb_memory_limit())
        return sb_error(ctx, SB_ERR_OVERFLOW,
                        "matrix: %zu x %zu cells x %zu channels need more than %zu bytes of memory; lower --res",
                        rows, cols, nch, sb_memory_limit());

    out->rows = rows;
    out->cols = cols;
    out->ld = rows;
    out->form = o.form;
    out->channels = chans;
    for (int ch = 0; ch < 3; ch++) {
        if (!(chans & (1u << ch))) continue;
        out->data[ch] = sb_alloc(ctx, cells, sizeof(double), "matrix");
        if (!out->data[ch]) {
            sb_matrix_free(out);
            return SB_ERR_NOMEM;
        }
    }
    out->mask = sb_alloc(ctx, cells, 1, "matrix mask");
    if (!out->mask) {
        sb_matrix_free(out);
        return SB_ERR_NOMEM;
    }

    int nt = sb_thread_count(o.threads);
    if ((size_t)nt > cols) nt = (int)cols;
    if (nt < 1) nt = 1;
    job_t *jobs = calloc((size_t)nt, sizeof *jobs);
    pthread_t *th = calloc((size_t)nt, sizeof *th);
    unsigned char *joinable = calloc((size_t)nt, 1);
    if (!jobs || !th || !joinable) {
        free(jobs);
        free(th);
        free(joinable);
        sb_matrix_free(out);
        return sb_error(ctx, SB_ERR_NOMEM, "matrix: out of memory");
    }
    atomic_size_t done;
    atomic_init(&done, 0);
    for (int t = 0; t < nt; t++) {
        jobs[t] = (job_t){src, param, out, cols * (size_t)t / (size_t)nt, cols * (size_t)(t + 1) / (size_t)nt,
                          0, 0, &done, t == 0 && o.progress ? &o : NULL};
        if (t > 0 && pthread_create(&th[t], NULL, build_cols, &jobs[t]) == 0) {
            joinable[t] = 1;
            continue;
        }
        if (t > 0) build_cols(&jobs[t]); /* no thread: do it here */
    }
    build_cols(&jobs[0]);
    /* report while the other threads finish */
    while (o.progress && atomic_load(&done) < cols) {
        o.progress(o.progress_user, (double)atomic_load(&done) / (double)cols);
        struct timespec ts = {0, 50 * 1000 * 1000};
        nanosleep(&ts, NULL);
    }
    for (int t = 1; t < nt; t++)
        if (joinable[t]) pthread_join(th[t], NULL);
    free(joinable);
    if (o.progress) o.progress(o.progress_user, 1.0);
    for (int t = 0; t < nt; t++) {
        out->valid_count += jobs[t].valid;
        out->measured_count += jobs[t].measured;
    }
    free(jobs);
    free(th);
    if (out->valid_count == cells) { /* every cell valid: no mask needed */
        free(out->mask);
        out->mask = NULL;
    }
    return SB_OK;
}

void sb_matrix_free(sb_matrix_t *m) {
    if (!m) return;
    for (int ch = 0; ch < 3; ch++) free(m->data[ch]);
    free(m->mask);
    memset(m, 0, sizeof *m);
}

double sb_matrix_norm(const sb_matrix_t *m, int ch) {
    if (ch < 0 || ch > 2 || !m->data[ch]) return 0;
    const double *a = m->data[ch];
    double scale = 0, ssq = 1;
    for (size_t c = 0; c < m->cols; c++)
        for (size_t r = 0; r < m->rows; r++) {
            size_t at = r + c * m->ld;
            if (m->mask && !m->mask[at]) continue;
            double v = fabs(a[at]);
            if (v == 0) continue;
            if (scale < v) {
                ssq = 1 + ssq * (scale / v) * (scale / v);
                scale = v;
            } else {
                ssq += (v / scale) * (v / scale);
            }
        }
    return scale * sqrt(ssq);
}
