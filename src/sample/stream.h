/* Private: streamed matrices (matrix_stream.c, matrix.h). */
#ifndef SEPBRDF_SAMPLE_STREAM_H
#define SEPBRDF_SAMPLE_STREAM_H

#include "sepbrdf/matrix.h"

/* Whether a matrix on param can be streamed: rows and columns separable,
 * every cell a BRDF pair. */
int sb_matrix_streamable(const sb_param_t *param);

/* Make out (rows, cols, form, channels set) a streamed matrix of src on
 * param: the directions of its rows and columns.  Errors: SB_ERR_OVERFLOW,
 * SB_ERR_NOMEM. */
sb_result_t sb_matrix_build_streamed(sb_context_t *ctx, const sb_source_t *src, const sb_param_t *param,
                                     sb_matrix_t *out);

/* sb_matrix_build into out, and where it evaluates an isotropic source's
 * R^3 distinct values on the io grid (stored, not streamed), out2 from
 * the same evaluations in form2 (the forms differ by their weight alone:
 * the same bits as its own build); else out2 is left zeroed (rows 0). */
sb_result_t sb_matrix_build_two(sb_context_t *ctx, const sb_source_t *src, const sb_param_t *param,
                                const sb_matrix_opts_t *opts, sb_form_t form2, sb_matrix_t *out2, sb_matrix_t *out);

/* Whether every channel of m reads the same bits: streamed from a grey
 * source (SB_SOURCE_GRAY), so one channel's products serve all. */
int sb_matrix_stream_grey(const sb_matrix_t *m);

/* Cell (row, col) of channel ch of a streamed matrix. */
double sb_matrix_stream_at(const sb_matrix_t *m, int ch, size_t row, size_t col);

#endif
