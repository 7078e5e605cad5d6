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
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "sample/divisor.h"
#include "sample/stream.h"
#include "util/internal.h"
#include "util/parallel.h"

static const char *const form_names[SB_FORM_COUNT_] = {"f", "cos", "cos2"};

sb_result_t sb_form_parse(const char *name, sb_form_t *out) {
    if (!out) return SB_ERR_ARG;
    int k = sb_name_find(form_names, SB_FORM_COUNT_, name);
    if (k < 0) return SB_ERR_UNKNOWN;
    *out = (sb_form_t)k;
    return SB_OK;
}
const char *sb_form_name(sb_form_t f) { return (unsigned)f < SB_FORM_COUNT_ ? form_names[f] : "?"; }

double sb_form_weight(sb_form_t form, const double wi[3], const double wo[3]) {
    if (!wi || !wo || (unsigned)form >= SB_FORM_COUNT_) return NAN;
    double ci = wi[2] > 0 ? wi[2] : 0, co = wo[2] > 0 ? wo[2] : 0;
    switch (form) {
    case SB_FORM_COS:
        return ci;
    case SB_FORM_COS2:
        return ci * co;
    default:
        return 1.0;
    }
}

double sb_form_divisor(sb_form_t form, const double wi[3], const double wo[3]) {
    return sb_form_divisor_inline(form, wi, wo);
}

typedef struct job {
    const sb_source_t *src;
    const sb_param_t *param;
    sb_matrix_t *m;
    size_t c0, c1;
    size_t valid, measured;
    atomic_size_t *done;       /* columns finished by all threads */
    const sb_matrix_opts_t *o; /* progress callback: job 0 only */
    const unsigned char *only; /* opts.only: cells to evaluate, NULL = all */
} job_t;

/* A batched source (sb_source_create_batched): the pairs of column c in
 * one call, into dirs (wi of every pair, then wo: 6 rows doubles), vals (3
 * a pair) and known, in row order; build_cols then takes them in turn.  0
 * when the buffers are missing (then pair by pair). */
static int column_batch(const job_t *j, size_t c, double *dirs, double *vals, unsigned char *known) {
    const sb_matrix_t *m = j->m;
    if (!dirs || !vals || !known) return 0;
    double *wi = dirs, *wo = dirs + 3 * m->rows;
    size_t n = 0;
    for (size_t r = 0; r < m->rows; r++) {
        size_t at = r + c * m->ld;
        n += (!j->only || j->only[at]) && sb_param_cell_dirs(j->param, r, c, wi + 3 * n, wo + 3 * n);
    }
    sb_source_eval_many(j->src, n, wi, wo, vals, known);
    return 1;
}

static void *build_cols(void *arg) {
    job_t *j = arg;
    sb_matrix_t *m = j->m;
    double wi[3], wo[3], rgb[3];
    int batched = sb_source_batched(j->src);
    double *dirs = batched ? malloc(m->rows * 6 * sizeof *dirs) : NULL;
    double *vals = batched ? malloc(m->rows * 3 * sizeof *vals) : NULL;
    unsigned char *kn = batched ? malloc(m->rows) : NULL;
    for (size_t c = j->c0; c < j->c1; c++) {
        int have = batched && column_batch(j, c, dirs, vals, kn);
        size_t next = 0; /* the next pair of the batch */
        for (size_t r = 0; r < m->rows; r++) {
            size_t at = r + c * m->ld;
            int ok = (!j->only || j->only[at]) && sb_param_cell_dirs(j->param, r, c, wi, wo);
            int known = 0;
            rgb[0] = rgb[1] = rgb[2] = 0;
            if (ok && m->form == SB_FORM_COS && sb_param_cell_value(j->param, r, c, rgb)) {
                known = 1; /* the layout's table holds the entry itself */
                if (have) next++;
            } else if (ok) {
                if (have) {
                    known = kn[next];
                    memcpy(rgb, vals + 3 * next++, sizeof rgb);
                } else {
                    known = sb_source_eval(j->src, wi, wo, rgb);
                }
                /* a layout's known factor (sb_param_gain) is the shader's, not the fit's */
                double w = sb_form_weight(m->form, wi, wo), gain = sb_param_gain(j->param, wi, wo);
                w = gain == 1 ? w : gain > 0 ? w / gain : 0;
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
    free(dirs);
    free(vals);
    free(kn);
    return NULL;
}

/* Progress of a build (jobs: the job array): done columns of all jobs. */
static void report_progress(void *arg) {
    const job_t *j = arg;
    j->o->progress(j->o->progress_user, (double)atomic_load(j->done) / (double)j->m->cols);
    /* 2 ms naps, not 50: sb_parallel_run ends the loop only between calls,
     * and a 50 ms nap made a sampling of 7 ms take 55 (the default run's
     * kept iso matrix); the display itself redraws at most every 0.1 s */
    struct timespec ts = {0, 2 * 1000 * 1000};
    nanosleep(&ts, NULL);
}

/* Isotropic sources on the io grid: f depends on (theta_i, theta_o,
 * phi_o - phi_i) only, and on the grid the azimuth difference of cells
 * (i_phi, j_phi) is (j_phi - i_phi) mod R cell widths.  So only R^3 of the
 * R^4 values are distinct: evaluate them once into a table (phi_i at the
 * first cell centre), then scatter into the matrix.  R = 64: 262 144
 * evaluations instead of 16.8 million.  The table is laid out as the first
 * block row of the matrix, tab[c][it + (d R + ot) R] (the structured
 * storage of matrix.h), so a structured matrix keeps it as its data. */
typedef struct iso_job {
    const sb_source_t *src;
    const sb_param_t *param;
    sb_matrix_t *m;
    size_t R, a0, a1; /* table chunks of ISO_CHUNK theta_i, azimuth differences or matrix columns */
    double *tab[3];   /* per channel, NULL when not built */
    unsigned char *known;
    size_t step;        /* table: every step-th chunk from a0 */
    int recip;          /* table: reciprocal source, only theta_o >= theta_i */
    int even;           /* table: even source (SB_SOURCE_EVEN), only d <= R / 2 */
    const double *wi;   /* R directions theta_i (phi_i at the first cell centre) */
    const double *wo;   /* R^2 directions (theta_o, d): wo + 3 (d R + ot) */
    const double *cosi; /* cos theta of the R elevations */
    sb_form_t form;
    /* table: a second form's table from the same evaluations (NULL known2: none) */
    double *tab2[3];
    unsigned char *known2;
    sb_form_t form2;
} iso_job_t;

/* theta_i a table chunk: one cache line of doubles, so the threads write
 * whole lines of the table (theta_i runs fastest in it). */
#define ISO_CHUNK 8

static size_t iso_at(size_t R, size_t it, size_t ot, size_t d) { return it + (d * R + ot) * R; }

/* Cell `at` of a table in a form of weight w from f's values raw. */
static void iso_put(double *const tab[3], unsigned char *kn, size_t at, int known, const double raw[3], double w) {
    double rgb[3];
    for (int c = 0; c < 3; c++) {
        rgb[c] = known ? raw[c] * w : 0.0;
        if (!isfinite(rgb[c])) known = 0;
    }
    for (int c = 0; c < 3; c++)
        if (tab[c]) tab[c][at] = known ? rgb[c] : 0.0;
    kn[at] = (unsigned char)known;
}

static void iso_cell(const iso_job_t *j, size_t it, size_t ot, size_t d) {
    const double *wi = j->wi + 3 * it, *wo = j->wo + 3 * (d * j->R + ot);
    double raw[3] = {0, 0, 0};
    int known = sb_source_eval(j->src, wi, wo, raw);
    size_t at = iso_at(j->R, it, ot, d);
    iso_put(j->tab, j->known, at, known, raw, sb_form_weight(j->form, wi, wo));
    if (j->known2) iso_put(j->tab2, j->known2, at, known, raw, sb_form_weight(j->form2, wi, wo));
}

static void *iso_table(void *arg) {
    iso_job_t *j = arg;
    size_t R = j->R;
    for (size_t k = j->a0; k < j->a1; k += j->step) {
        size_t i0 = k * ISO_CHUNK, i1 = i0 + ISO_CHUNK < R ? i0 + ISO_CHUNK : R;
        for (size_t d = 0; d < (j->even ? R / 2 + 1 : R); d++)
            for (size_t ot = j->recip ? i0 : 0; ot < R; ot++)
                for (size_t it = i0, end = j->recip && ot + 1 < i1 ? ot + 1 : i1; it < end; it++)
                    iso_cell(j, it, ot, d);
    }
    return NULL;
}

/* Reciprocity: swapping wi and wo and rotating by -phi_o gives
 * f(theta_o, theta_i, -d) = f(theta_i, theta_o, d), and for an even
 * source f(theta_o, theta_i, d) (the plane d itself, evaluated); the form
 * cos is f cos(theta_i), not symmetric: move the cosine across.  Azimuth
 * differences [a0, a1); a row (d, theta_o) at a time, theta_i innermost:
 * the cells written run contiguously, those read lie in one R x R plane.
 * Cells theta_i > theta_o are written from cells theta_i < theta_o, so
 * no cell is both (the threads' ranges of d neither).  The cosines'
 * ratio is taken once for the channels of a cell, in blocks of
 * MIRROR_BLOCK (the same bits as the product written with it inline). */
#define MIRROR_BLOCK 64
static void *iso_mirror(void *arg) {
    const iso_job_t *j = arg;
    size_t R = j->R, R2 = R * R;
    int cosf = j->form == SB_FORM_COS;
    double q[MIRROR_BLOCK];
    for (size_t d = j->a0; d < j->a1; d++) {
        size_t dd = j->even ? d : (R - d) % R;
        for (size_t ot = 0; ot < R; ot++) {
            size_t row = d * R2 + ot * R, col = dd * R2 + ot; /* cell it: row + it, col + it R */
            for (size_t i0 = ot + 1; i0 < R; i0 += MIRROR_BLOCK) {
                size_t n = R - i0 < MIRROR_BLOCK ? R - i0 : MIRROR_BLOCK;
                for (size_t k = 0; cosf && k < n; k++)
                    q[k] = j->cosi[i0 + k] / j->cosi[ot];
                for (int c = 0; c < 3; c++) {
                    double *t = j->tab[c];
                    if (!t) continue;
                    if (cosf)
                        for (size_t k = 0; k < n; k++)
                            t[row + i0 + k] = t[col + (i0 + k) * R] * q[k];
                    else
                        for (size_t k = 0; k < n; k++)
                            t[row + i0 + k] = t[col + (i0 + k) * R];
                }
                for (size_t k = 0; k < n; k++)
                    j->known[row + i0 + k] = j->known[col + (i0 + k) * R];
            }
        }
    }
    return NULL;
}

/* An even source: plane d > R / 2 of the table (theta_i, theta_o at
 * azimuth difference d, R^2 values in a row) is plane R - d, for d in
 * [a0, a1): f(theta_i, theta_o, d) = f(theta_i, theta_o, -d). */
static void *iso_even(void *arg) {
    const iso_job_t *j = arg;
    size_t R = j->R, R2 = R * R;
    for (size_t d = j->a0; d < j->a1; d++) {
        if (2 * d <= R) continue;
        for (int c = 0; c < 3; c++)
            if (j->tab[c]) memcpy(j->tab[c] + d * R2, j->tab[c] + (R - d) * R2, R2 * sizeof(double));
        memcpy(j->known + d * R2, j->known + (R - d) * R2, R2);
    }
    return NULL;
}

/* Column (o_phi, o_theta) holds, for every i_phi, the R values over
 * i_theta at d = (o_phi - i_phi) mod R: one contiguous piece of the table
 * each.  The mask is written only when some value is unknown. */
static void *iso_scatter(void *arg) {
    iso_job_t *j = arg;
    sb_matrix_t *m = j->m;
    size_t R = j->R;
    for (size_t l = j->a0; l < j->a1; l++) {
        size_t ot = l % R, op = l / R;
        for (size_t ip = 0; ip < R; ip++) {
            size_t from = iso_at(R, 0, ot, (op + R - ip) % R), cell = ip * R + l * m->ld;
            for (int c = 0; c < 3; c++)
                if (m->data[c]) memcpy(m->data[c] + cell, j->tab[c] + from, R * sizeof(double));
            if (m->mask) memcpy(m->mask + cell, j->known + from, R);
        }
    }
    return NULL;
}

/* Run fn over [0, n) split among nt threads (the caller's thread
 * included): in contiguous ranges, or interleaved (t, t + nt, ...) when
 * the work per index falls with the index. */
static void run_parallel(void *(*fn)(void *), iso_job_t *jobs, int nt, size_t n, int interleave) {
    for (int t = 0; t < nt; t++) {
        jobs[t].a0 = interleave ? (size_t)t : n * (size_t)t / (size_t)nt;
        jobs[t].a1 = interleave ? n : n * (size_t)(t + 1) / (size_t)nt;
        jobs[t].step = interleave ? (size_t)nt : 1;
    }
    sb_parallel_run(fn, jobs, sizeof *jobs, nt, NULL, NULL);
}

/* Bytes of `rows` stored values per column, every channel, plus a mask of
 * mask_cells bytes; 1 on overflow. */
static int stored_bytes(const sb_matrix_t *m, size_t rows, size_t mask_cells, size_t *bytes) {
    unsigned ch = m->channels;
    size_t nch = (size_t)((ch & 1) + ((ch >> 1) & 1) + ((ch >> 2) & 1)), cells;
    return sb_size_mul(rows, m->cols, &cells) || sb_size_mul3(cells, nch, sizeof(double), bytes) ||
           sb_size_add(*bytes, mask_cells, bytes);
}

/* Refuse up front what would not fit: `rows` stored rows a column and a
 * mask of mask_cells. */
static sb_result_t check_size(sb_context_t *ctx, const sb_matrix_t *m, size_t rows, size_t mask_cells) {
    size_t bytes = 0, nch = (size_t)((m->channels & 1) + ((m->channels >> 1) & 1) + ((m->channels >> 2) & 1));
    if (stored_bytes(m, rows, mask_cells, &bytes))
        return sb_error(
            ctx, SB_ERR_OVERFLOW,
            "matrix: %zu x %zu cells x %zu channels need more than %zu bytes (overflow); lower the resolution", m->rows,
            m->cols, nch, (size_t)SIZE_MAX);
    if (bytes > sb_memory_limit())
        return sb_error(ctx, SB_ERR_OVERFLOW,
                        "matrix: %zu x %zu cells x %zu channels need %zu bytes, more than the memory limit of %zu "
                        "bytes; lower the resolution",
                        m->rows, m->cols, nch, bytes, sb_memory_limit());
    return SB_OK;
}

/* Every cell and the mask, in huge pages where offered (first touch of
 * 4 KiB pages dominated the build of large matrices).  On failure the
 * caller frees what was allocated. */
static sb_result_t alloc_dense(sb_context_t *ctx, sb_matrix_t *m) {
    sb_result_t r = check_size(ctx, m, m->rows, m->rows * m->cols);
    if (r != SB_OK) return r;
    m->ld = m->rows;
    for (int ch = 0; ch < 3; ch++)
        if ((m->channels & (1u << ch)) &&
            !(m->data[ch] = sb_alloc_large(ctx, m->rows * m->cols, sizeof(double), "matrix")))
            return SB_ERR_NOMEM;
    m->mask = sb_alloc_large(ctx, m->rows * m->cols, 1, "matrix mask");
    return m->mask ? SB_OK : SB_ERR_NOMEM;
}

/* The table's directions into dirs (3 R^2 + 3 R + R doubles): wo at
 * (theta_o, d), wi at theta_i, and cos theta of each elevation. */
static void iso_dirs(const sb_param_t *param, size_t R, double *dirs, iso_job_t *job) {
    double dt = sb_param_theta_max(param) / (double)R, dp = 2 * SB_PI / (double)R;
    double *wo = dirs, *wi = dirs + 3 * R * R, *cosi = wi + 3 * R;
    for (size_t d = 0; d < R; d++)
        for (size_t ot = 0; ot < R; ot++)
            sb_dir_from_angles((ot + 0.5) * dt, (d + 0.5) * dp, wo + 3 * (d * R + ot));
    for (size_t it = 0; it < R; it++) {
        sb_dir_from_angles((it + 0.5) * dt, 0.5 * dp, wi + 3 * it);
        cosi[it] = cos((it + 0.5) * dt);
    }
    job->wi = wi;
    job->wo = wo;
    job->cosi = cosi;
}

/* job's table (mirrored and completed) into job->m: the structured data
 * where every value is known and o asks for it, else every cell (and the
 * mask where a value is unknown); the table's channels taken or left to
 * the caller to free.  jobs: nt copies of job for the threads. */
static sb_result_t iso_output(sb_context_t *ctx, iso_job_t *job, iso_job_t *jobs, int nt, const sb_matrix_opts_t *o) {
    size_t R = job->R, n3 = R * R * R;
    sb_matrix_t *out = job->m;
    for (int t = 0; t < nt; t++)
        jobs[t] = *job;
    if (job->recip) run_parallel(iso_mirror, jobs, nt, job->even ? R / 2 + 1 : R, 0);
    if (job->even) run_parallel(iso_even, jobs, nt, R, 0);
    size_t nknown = 0;
    for (size_t i = 0; i < n3; i++)
        nknown += job->known[i];
    out->valid_count = out->measured_count = nknown * R; /* each table value fills R cells */
    out->phi_period = nknown == n3 ? R : 0;
    if (o->structured && nknown == n3) { /* the table is the data */
        out->ld = R;
        out->structured = 1;
        for (int c = 0; c < 3; c++) {
            out->data[c] = job->tab[c];
            job->tab[c] = NULL;
        }
        return SB_OK;
    }
    sb_result_t r = alloc_dense(ctx, out);
    if (r != SB_OK) return r;
    if (nknown == n3) { /* every cell valid: no mask */
        free(out->mask);
        out->mask = NULL;
    }
    run_parallel(iso_scatter, jobs, nt, out->cols, 0);
    return SB_OK;
}

/* A table's channels (n3 values each) for out's channels. */
static sb_result_t iso_alloc(sb_context_t *ctx, const sb_matrix_t *out, size_t n3, double *tab[3]) {
    for (int c = 0; c < 3; c++)
        if ((out->channels & (1u << c)) && !(tab[c] = sb_alloc_large(ctx, n3, sizeof(double), "isotropic table")))
            return SB_ERR_NOMEM;
    return SB_OK;
}

/* out (and out2, in its own form, where not NULL) from one evaluation of
 * the R^3 distinct values: the forms differ by their weight alone. */
static sb_result_t build_isotropic_io(sb_context_t *ctx, const sb_source_t *src, const sb_param_t *param,
                                      const sb_matrix_opts_t *o, sb_matrix_t *out, sb_matrix_t *out2) {
    size_t R = (size_t)llround(sqrt((double)out->rows)), n3;
    if (sb_size_mul3(R, R, R, &n3))
        return sb_error(ctx, SB_ERR_OVERFLOW, "matrix: table size overflows; lower the resolution");
    sb_result_t r = check_size(ctx, out, o->structured ? R : out->rows, o->structured ? n3 : out->rows * out->cols);
    if (r != SB_OK) return r;
    int nt = sb_thread_count(o->threads);
    if ((size_t)nt > R) nt = (int)R;
    iso_job_t job = {.src = src, .param = param, .m = out, .R = R, .step = 1, .form = out->form};
    iso_job_t jobs[SB_THREADS_MAX], job2;
    job.recip = (sb_source_flags(src) & SB_SOURCE_RECIPROCAL) != 0;
    job.even = (sb_source_flags(src) & SB_SOURCE_EVEN) != 0;
    job.known = sb_alloc(ctx, n3, 1, "isotropic table");
    job.known2 = out2 ? sb_alloc(ctx, n3, 1, "isotropic table") : NULL;
    double *dirs = sb_alloc(ctx, 3 * R * (R + 1) + R, sizeof(double), "isotropic table directions");
    r = job.known && dirs && (job.known2 || !out2) ? SB_OK : SB_ERR_NOMEM;
    if (r == SB_OK) iso_dirs(param, R, dirs, &job);
    if (r == SB_OK) r = iso_alloc(ctx, out, n3, job.tab);
    if (r == SB_OK && out2) {
        job.form2 = out2->form;
        r = iso_alloc(ctx, out2, n3, job.tab2);
    }
    if (r != SB_OK) goto done;
    for (int t = 0; t < nt; t++)
        jobs[t] = job;
    run_parallel(iso_table, jobs, nt, (R + ISO_CHUNK - 1) / ISO_CHUNK, job.recip);
    job2 = job;
    r = iso_output(ctx, &job, jobs, nt, o);
    if (r == SB_OK && out2) {
        memcpy(job2.tab, job2.tab2, sizeof job2.tab);
        job2.known = job2.known2;
        job2.known2 = NULL;
        job2.form = job2.form2;
        job2.m = out2;
        memset(job.tab2, 0, sizeof job.tab2); /* job2's now */
        job.known2 = NULL;
        r = iso_output(ctx, &job2, jobs, nt, o);
        for (int c = 0; c < 3; c++)
            free(job2.tab[c]);
        free(job2.known);
    }
done:
    for (int c = 0; c < 3; c++) {
        free(job.tab[c]);
        free(job.tab2[c]);
    }
    free(job.known);
    free(job.known2);
    free(dirs);
    return r;
}

/* Every cell evaluated, columns split among threads (see build_cols). */
static sb_result_t build_general(sb_context_t *ctx, const sb_source_t *src, const sb_param_t *param,
                                 const sb_matrix_opts_t *opts, sb_matrix_t *out) {
    sb_matrix_opts_t o = *opts;
    size_t cols = out->cols, cells = out->rows * out->cols;
    sb_result_t r = alloc_dense(ctx, out);
    if (r != SB_OK) return r;
    int nt = sb_threads_for(o.threads, cols, cols, 0);
    job_t jobs[SB_THREADS_MAX];
    atomic_size_t done;
    atomic_init(&done, 0);
    for (int t = 0; t < nt; t++) {
        jobs[t] = (job_t){src, param, out, 0, 0, 0, 0, &done, t == 0 && o.progress ? &o : NULL, o.only};
        sb_part(cols, t, nt, &jobs[t].c0, &jobs[t].c1);
    }
    /* report while the other threads finish */
    sb_parallel_run(build_cols, jobs, sizeof *jobs, nt, o.progress ? report_progress : NULL, jobs);
    if (o.progress) o.progress(o.progress_user, 1.0);
    for (int t = 0; t < nt; t++) {
        out->valid_count += jobs[t].valid;
        out->measured_count += jobs[t].measured;
    }
    if (out->valid_count == cells) { /* every cell valid: no mask needed */
        free(out->mask);
        out->mask = NULL;
    }
    return SB_OK;
}

/* Bytes of the values a stored build holds (and of the isotropic table
 * it builds them from); SIZE_MAX on overflow. */
static size_t stored_need(const sb_matrix_t *m, int iso, int structured) {
    size_t R = (size_t)llround(sqrt((double)m->rows)), n3 = 0, bytes = 0, table = 0;
    if (iso && (sb_size_mul3(R, R, R, &n3) || stored_bytes(m, R, n3, &table))) return SIZE_MAX;
    if (!(iso && structured) && stored_bytes(m, m->rows, m->rows * m->cols, &bytes)) return SIZE_MAX;
    return table > bytes ? table : bytes;
}

/* Whether the build streams: asked, or beyond the memory limit. */
static int streams(const sb_param_t *param, const sb_matrix_opts_t *o, const sb_matrix_t *m, int iso) {
    return sb_matrix_streamable(param) && (o->stream || (o->structured && stored_need(m, iso, 1) > sb_memory_limit()));
}

static int iso_layout(const sb_source_t *src, const sb_param_t *param) {
    return (sb_param_caps(param) & SB_CAP_AZIMUTH_GRID) && (sb_source_flags(src) & SB_SOURCE_ISOTROPIC);
}

size_t sb_matrix_bytes(const sb_source_t *src, const sb_param_t *param, const sb_matrix_opts_t *opts) {
    if (!src || !param) return SIZE_MAX;
    sb_matrix_opts_t o = {0};
    if (opts) o = *opts;
    sb_matrix_t m = {0};
    m.rows = sb_param_rows(param);
    m.cols = sb_param_cols(param);
    m.channels = o.channels & 7u ? o.channels & 7u : 7u;
    int iso = iso_layout(src, param);
    if (streams(param, &o, &m, iso)) return 3 * (m.rows + m.cols) * sizeof(double);
    return stored_need(&m, iso, o.structured);
}

/* out's shape, form and channels as a build of o on param sets them. */
static void matrix_shape(const sb_param_t *param, const sb_matrix_opts_t *o, sb_form_t form, sb_matrix_t *out) {
    memset(out, 0, sizeof *out);
    out->rows = sb_param_rows(param);
    out->cols = sb_param_cols(param);
    out->ld = out->rows;
    out->form = form;
    out->channels = o->channels ? o->channels : 7u;
}

sb_result_t sb_matrix_build_two(sb_context_t *ctx, const sb_source_t *src, const sb_param_t *param,
                                const sb_matrix_opts_t *opts, sb_form_t form2, sb_matrix_t *out2, sb_matrix_t *out) {
    sb_matrix_opts_t o = {0};
    if (opts) o = *opts;
    if (out2 && param) matrix_shape(param, &o, form2, out2);
    if (!out2 || !src || !param || !out || (unsigned)form2 >= SB_FORM_COUNT_ || o.only || (o.channels & ~7u) ||
        (unsigned)o.form >= SB_FORM_COUNT_ || !iso_layout(src, param) || streams(param, &o, out2, 1)) {
        if (out2) memset(out2, 0, sizeof *out2);
        return sb_matrix_build(ctx, src, param, opts, out);
    }
    matrix_shape(param, &o, o.form, out);
    sb_result_t r = build_isotropic_io(ctx, src, param, &o, out, out2);
    if (r == SB_OK && o.progress) o.progress(o.progress_user, 1.0);
    if (r != SB_OK) {
        sb_matrix_free(out);
        sb_matrix_free(out2);
    }
    return r;
}

sb_result_t sb_matrix_build(sb_context_t *ctx, const sb_source_t *src, const sb_param_t *param,
                            const sb_matrix_opts_t *opts, sb_matrix_t *out) {
    if (!src || !param || !out) return sb_error(ctx, SB_ERR_ARG, "matrix: missing source or parameterisation");
    memset(out, 0, sizeof *out);
    sb_matrix_opts_t o = {0};
    if (opts) o = *opts;
    if ((unsigned)o.form >= SB_FORM_COUNT_) return sb_error(ctx, SB_ERR_ARG, "matrix: unknown form %d", (int)o.form);
    if (o.channels & ~7u) return sb_error(ctx, SB_ERR_ARG, "matrix: channel mask %#x, need bits 1, 2, 4", o.channels);
    matrix_shape(param, &o, o.form, out);
    sb_result_t r;
    int iso = iso_layout(src, param);
    if (o.only) {
        r = build_general(ctx, src, param, &o, out);
    } else if (streams(param, &o, out, iso)) {
        r = sb_matrix_build_streamed(ctx, src, param, out);
        if (r == SB_OK && o.progress) o.progress(o.progress_user, 1.0);
    } else if (iso) {
        r = build_isotropic_io(ctx, src, param, &o, out, NULL);
        if (r == SB_OK && o.progress) o.progress(o.progress_user, 1.0);
    } else {
        r = build_general(ctx, src, param, &o, out);
    }
    if (r != SB_OK) sb_matrix_free(out);
    return r;
}

void sb_matrix_free(sb_matrix_t *m) {
    if (!m) return;
    for (int ch = 0; ch < 3; ch++)
        free(m->data[ch]);
    free(m->mask);
    free(m->dirs);
    memset(m, 0, sizeof *m);
}
