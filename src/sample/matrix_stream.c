/* Streamed matrices: nothing stored, cells evaluated from the source
 * whenever they are read (matrix.h, sb_matrix_t.streamed).
 *
 * On a layout whose rows and columns are separable and whose cells are all
 * BRDF pairs (io, io-area), cell (r, c) pairs the direction of row r with
 * that of column c; both lists are computed once, with the factors of the
 * form's weight a row and a column (8 N doubles, 4 MiB at io R = 256), and
 * a block of columns is then one source evaluation a cell, columns split
 * among threads.  M_c[r, c] = w(wi, wo) f_c(wi, wo) as
 * sb_matrix_build writes it; a value the source does not know (or a
 * non-finite one) reads as 0. */
#include <math.h>
#include <string.h>

#include "sample/stream.h"
#include "sepbrdf/matrix.h"
#include "util/internal.h"
#include "util/parallel.h"

int sb_matrix_streamable(const sb_param_t *param) {
    unsigned caps = sb_param_caps(param);
    return (caps & SB_CAP_SEPARABLE) && !(caps & SB_CAP_PARTIAL_DOMAIN);
}

/* The weight of the form is a product a(wi) b(wo) (f: 1, cos: cos theta_i,
 * cos2: both cosines): a(wi) = w(wi, n) / w(n, n) and b(wo) = w(n, wo)
 * with n the normal, computed once per row and column. */
sb_result_t sb_matrix_build_streamed(sb_context_t *ctx, const sb_source_t *src, const sb_param_t *param,
                                     sb_matrix_t *out) {
    size_t rows = out->rows, cols = out->cols, n;
    if (sb_size_add(rows, cols, &n) || sb_size_mul(n, 4, &n))
        return sb_error(ctx, SB_ERR_OVERFLOW, "matrix: %zu x %zu directions overflow", rows, cols);
    if (!(out->dirs = sb_alloc(ctx, n, sizeof(double), "streamed matrix directions"))) return SB_ERR_NOMEM;
    double wi[3], wo[3], *wr = out->dirs + 3 * (rows + cols), *wc = wr + rows;
    const double up[3] = {0, 0, 1}, wn = sb_form_weight(out->form, up, up);
    for (size_t r = 0; r < rows; r++) {
        sb_param_cell_dirs(param, r, 0, wi, wo);
        memcpy(out->dirs + 3 * r, wi, sizeof wi);
        wr[r] = sb_form_weight(out->form, wi, up) / wn;
    }
    for (size_t c = 0; c < cols; c++) {
        sb_param_cell_dirs(param, 0, c, wi, wo);
        memcpy(out->dirs + 3 * (rows + c), wo, sizeof wo);
        wc[c] = sb_form_weight(out->form, up, wo);
    }
    out->streamed = 1;
    out->source = src;
    out->param = param;
    out->valid_count = out->measured_count = rows * cols;
    return SB_OK;
}

/* One cell of a streamed matrix, every channel, as sb_matrix_build writes it. */
static void stream_cell(const sb_matrix_t *m, size_t r, size_t c, double rgb[3]) {
    const double *wr = m->dirs + 3 * (m->rows + m->cols), *wc = wr + m->rows;
    rgb[0] = rgb[1] = rgb[2] = 0;
    int known = sb_source_eval(m->source, m->dirs + 3 * r, m->dirs + 3 * (m->rows + c), rgb);
    double w = wr[r] * wc[c];
    for (int ch = 0; ch < 3; ch++) {
        double v = known ? rgb[ch] * w : 0.0;
        rgb[ch] = isfinite(v) ? v : 0.0;
    }
}

int sb_matrix_stream_grey(const sb_matrix_t *m) {
    return m && m->streamed && (sb_source_flags(m->source) & SB_SOURCE_GRAY);
}

double sb_matrix_stream_at(const sb_matrix_t *m, int ch, size_t row, size_t col) {
    double rgb[3];
    stream_cell(m, row, col, rgb);
    return rgb[ch];
}

typedef struct block_job {
    const sb_matrix_t *m;
    size_t c0, c1, first, ldo;
    double *const *out;
} block_job_t;

static void *stream_block(void *arg) {
    const block_job_t *j = arg;
    const sb_matrix_t *m = j->m;
    double rgb[3], *col[3];
    for (size_t c = j->c0; c < j->c1; c++) {
        for (int ch = 0; ch < 3; ch++)
            col[ch] = j->out[ch] ? j->out[ch] + (c - j->first) * j->ldo : NULL;
        for (size_t r = 0; r < m->rows; r++) {
            stream_cell(m, r, c, rgb);
            for (int ch = 0; ch < 3; ch++)
                if (col[ch]) col[ch][r] = rgb[ch];
        }
    }
    return NULL;
}

sb_result_t sb_matrix_cols(sb_context_t *ctx, const sb_matrix_t *m, size_t c0, size_t c1, double *const out[3],
                           size_t ldo, int threads) {
    if (!m || !out || c0 > c1 || c1 > m->cols || ldo < m->rows)
        return sb_error(ctx, SB_ERR_ARG, "matrix: bad column block or leading dimension");
    double *want[3];
    for (int ch = 0; ch < 3; ch++)
        want[ch] = sb_matrix_has(m, ch) ? out[ch] : NULL;
    if (!m->streamed) {
        for (int ch = 0; ch < 3; ch++)
            for (size_t c = c0; want[ch] && c < c1; c++) {
                double *dst = want[ch] + (c - c0) * ldo;
                const double *col = sb_matrix_col(m, ch, c, dst);
                if (col != dst) memcpy(dst, col, m->rows * sizeof *dst);
            }
        return SB_OK;
    }
    size_t n = c1 - c0;
    int nt = sb_threads_for(threads, n, n * m->rows, 4096);
    block_job_t jobs[SB_THREADS_MAX];
    for (int t = 0; t < nt; t++) {
        jobs[t] = (block_job_t){m, 0, 0, c0, ldo, want};
        sb_part(n, t, nt, &jobs[t].c0, &jobs[t].c1);
        jobs[t].c0 += c0;
        jobs[t].c1 += c0;
    }
    sb_parallel_run(stream_block, jobs, sizeof *jobs, nt, NULL, NULL);
    return SB_OK;
}
