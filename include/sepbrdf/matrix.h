/* sepbrdf: sampling a source into matrices, one per colour channel.
 *
 * M_c[row, col] = form(f_r,c(wi, wo)) at the centres given by the
 * parameterisation, column-major with leading dimension ld = rows:
 * element (r, c) is data[c][r + c * ld] (a structured matrix stores less:
 * see sb_matrix_t.structured).
 *   SB_FORM_F    f_r
 *   SB_FORM_COS  f_r cos(theta_i)
 *   SB_FORM_COS2 f_r cos(theta_i) cos(theta_o)
 * Cells outside the BRDF domain or missing in a measured table are 0 in
 * `mask` (NULL = every cell valid) and hold 0 in data. */
#ifndef SEPBRDF_MATRIX_H
#define SEPBRDF_MATRIX_H

#include "common.h"
#include "param.h"
#include "source.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum sb_form { SB_FORM_F = 0, SB_FORM_COS, SB_FORM_COS2, SB_FORM_COUNT_ } sb_form_t;

/* "f", "cos", "cos2"; SB_ERR_UNKNOWN otherwise (NULL name included),
 * SB_ERR_ARG for a NULL out. */
SB_API sb_result_t sb_form_parse(const char *name, sb_form_t *out);
SB_API const char *sb_form_name(sb_form_t form);
/* The factor that turns f_r into the stored form for this pair; NaN for
 * an unknown form or a NULL direction. */
SB_API double sb_form_weight(sb_form_t form, const double wi[3], const double wo[3]);
/* What a reconstruction of the stored form is divided by to give f_r, as
 * the GLSL snippet does: cos theta raised to the grazing guard 0.001
 * (max(cos, 0.001)) per cosine of the form; 1 for SB_FORM_F. */
SB_API double sb_form_divisor(sb_form_t form, const double wi[3], const double wo[3]);

/* Progress of a long build: `fraction` of the columns done, in [0, 1]. */
typedef void (*sb_progress_fn)(void *user, double fraction);

typedef struct sb_matrix_opts {
    sb_form_t form;    /* default SB_FORM_F */
    unsigned channels; /* bit mask of channels to build (1 R, 2 G, 4 B); 0 = all */
    int threads;       /* 0 = all cores */
    /* Optional (NULL = none): called on the calling thread only, after each
     * column it builds and every ~50 ms while it waits for the other
     * threads, and once with 1 when the build is complete. */
    sb_progress_fn progress;
    void *progress_user;
    /* 1: where the matrix has a structure the library factors directly
     * (an isotropic source on the io grid, every cell valid), store only
     * its distinct values (see sb_matrix_t.structured): R^3 values a
     * channel instead of R^4.  0 (default): every cell. */
    int structured;
    /* 1: a streamed matrix (sb_matrix_t.streamed) on layouts that allow it
     * (every cell a BRDF pair, rows and columns separable: io, io-area);
     * 0 (default): streamed only where `structured` is set, the layout
     * allows it and the stored values would exceed the memory limit. */
    int stream;
    /* NULL (default): every cell.  Else rows x cols flags, column-major:
     * only cells with a flag != 0 are evaluated, the others get mask 0
     * and value 0 as cells outside the domain (a scene's unused cells,
     * scene.h); the build is then dense, never structured or streamed. */
    const unsigned char *only;
} sb_matrix_opts_t;

typedef struct sb_matrix {
    size_t rows, cols, ld;
    unsigned channels;     /* bit mask of channels present */
    double *data[3];       /* NULL for channels not built */
    unsigned char *mask;   /* rows * cols column-major, 1 = valid; NULL = all */
    size_t valid_count;    /* number of valid cells */
    size_t measured_count; /* valid cells the source reported as known */
    sb_form_t form;
    /* R > 0: the matrix is even block-circulant over the azimuth of an io
     * grid of R x R cells (an isotropic source, every cell valid): cell
     * (R i_phi + i_theta, R o_phi + o_theta) depends on the thetas and on
     * (o_phi - i_phi) mod R only, evenly.  Set by sb_matrix_build; the
     * plan then factors from the R^3 distinct values (see factor.h).  Set
     * it to 0 after editing the data by hand. */
    size_t phi_period;
    /* 1: only the distinct values are stored (opts.structured): data[c]
     * holds the first block row (phi_i = 0) of every column, R x cols with
     * ld = R = phi_period, and cell (R i_phi + i_theta, R o_phi + o_theta)
     * is data[c][i_theta + (R ((o_phi - i_phi) mod R) + o_theta) R].  Read
     * such a matrix through sb_matrix_at, sb_matrix_col or sb_matrix_mul,
     * or expand it with sb_matrix_expand. */
    int structured;
    /* 1: nothing is stored (data[] and mask NULL, `channels` says which
     * channels exist): every read evaluates the cells from `source` on
     * `param`, which must outlive the matrix; cells the source does not
     * know read as 0 (as zero-filled) and valid_count counts every cell.
     * Read it through sb_matrix_at, sb_matrix_col, sb_matrix_cols or
     * sb_matrix_mul (each product one pass over the source).  `dirs` holds
     * the row directions, then the column directions (3 doubles each), then
     * the factors of the form's weight of every row, then of every column. */
    int streamed;
    const sb_source_t *source;
    const sb_param_t *param;
    double *dirs;
} sb_matrix_t;

/* Sample `src` on `param`.  On success *out owns its buffers (sb_matrix_free).
 * Errors: SB_ERR_ARG (NULL argument, unknown form, channel bits beyond
 * 1|2|4), SB_ERR_OVERFLOW (size or memory limit), SB_ERR_NOMEM. */
SB_API sb_result_t sb_matrix_build(sb_context_t *ctx, const sb_source_t *src, const sb_param_t *param,
                                   const sb_matrix_opts_t *opts, sb_matrix_t *out);
SB_API void sb_matrix_free(sb_matrix_t *m); /* accepts NULL and zeroed structs */

/* Bytes sb_matrix_build(src, param, opts) would hold at its peak: the
 * stored values (and the table of an isotropic source on the io grid), or
 * the directions of a streamed matrix; SIZE_MAX on overflow or a NULL
 * argument.  To refuse up front what cannot fit the memory limit. */
SB_API size_t sb_matrix_bytes(const sb_source_t *src, const sb_param_t *param, const sb_matrix_opts_t *opts);

/* Cell (row, col) of channel c, dense, structured or streamed (0 for a
 * channel not built). */
SB_API double sb_matrix_at(const sb_matrix_t *m, int channel, size_t row, size_t col);

/* Column `col` of channel c (rows values): a pointer into data for a dense
 * matrix, else gathered into buf (rows doubles), which is returned; NULL
 * for a channel the matrix lacks, a column out of range, or a NULL buf
 * where one is needed. */
SB_API const double *sb_matrix_col(const sb_matrix_t *m, int channel, size_t col, double *buf);

/* Y = M_c Z for Z of k columns (cols x k, ld ldz >= cols) into Y (rows x k,
 * ld ldy >= rows): one dgemm for a dense matrix; for a structured one R
 * products with the stored R x cols block, which holds every value.
 * Errors: SB_ERR_ARG (no such channel, bad leading dimensions),
 * SB_ERR_OVERFLOW (beyond BLAS's int sizes), SB_ERR_NOMEM. */
SB_API sb_result_t sb_matrix_mul(sb_context_t *ctx, const sb_matrix_t *m, int channel, size_t k, const double *z,
                                 size_t ldz, double *y, size_t ldy);

/* Whether channel c (0..2) of m was built (stored or streamed). */
SB_API int sb_matrix_has(const sb_matrix_t *m, int channel);

/* Columns c0 .. c1 - 1 of every channel c with out[c] != NULL (a channel
 * not built is skipped) into out[c], rows x (c1 - c0) with leading
 * dimension ldo >= rows: copied from a stored matrix, evaluated from the
 * source for a streamed one (columns split among `threads` threads, 0 =
 * all cores).  Errors: SB_ERR_ARG (NULL matrix or out, c0 > c1 or c1 >
 * cols, ldo < rows). */
SB_API sb_result_t sb_matrix_cols(sb_context_t *ctx, const sb_matrix_t *m, size_t c0, size_t c1, double *const out[3],
                                  size_t ldo, int threads);

/* A dense copy of m (every cell stored, ld = rows; mask and counts kept),
 * in memory backed by huge pages where the system offers them.  Errors:
 * SB_ERR_ARG, SB_ERR_OVERFLOW (memory limit), SB_ERR_NOMEM. */
SB_API sb_result_t sb_matrix_expand(sb_context_t *ctx, const sb_matrix_t *m, sb_matrix_t *out);

#ifdef __cplusplus
}
#endif
#endif
