/* sepbrdf: an interactive viewer page for one factorisation.
 *
 * sb_viewer_write() writes one self-contained HTML file (no network, no
 * external script: plain WebGL2 and a 2D canvas) that runs the GLSL
 * snippet on a lit sphere and on a plane seen at a grazing angle, with a
 * light the mouse moves, an exposure control and a J slider, and shows
 * the original, the reconstruction and an error heat map side by side,
 * polar plots of the in-plane slice, a 3D lobe and a slice in any plane
 * for the chosen light, the sphere under a procedural sky and the
 * report's numbers.  Embedded:
 *   - the factors' texels as base64 little-endian float32 RGB, layer j =
 *     term j, texel (x, y) of layer j at ((j H + y) W + x) 3 (a
 *     single-channel factorisation replicated to RGB), values as
 *     sb_factors_read_exr returns them (the per-term scales of half output
 *     already applied; the page divides g_j by the snippet's sb_scale[j]);
 *   - the snippet text, compiled as GLSL ES 3.00 behind a
 *     "#version 300 es" line (the snippet sets its precisions for GL_ES);
 *   - with a source: a reference table, the source sampled (form f) on the
 *     factorisation's parameterisation, or on the same kind at a lower
 *     resolution so that it has at most `ref_cells` cells, as RGBA float32
 *     (alpha 1 = known cell), cell (r, c) at linear index r cols + c of a
 *     2048-wide texture; the page interpolates it multilinearly (bilinear
 *     on each side, over known cells only) through the snippet's
 *     sb_coords(), which is what the sum of all terms of a full SVD would
 *     give;
 *   - the in-plane slices: wi = (sin ti, 0, cos ti), wo = (-sin to, 0,
 *     cos to) (to > 0 on the mirror side), ti = 0, 2.5, ..., 87.5 degrees,
 *     to = -89..89 degrees, the luminance 0.2126 R + 0.7152 G + 0.0722 B of
 *     the original (NaN where a table does not know the pair) and of the
 *     reconstruction from J' = 1..J terms (sb_factors_eval).
 * Test mode: the page opened with "?test=1&size=S&el=DEG&az=DEG&J=N" renders
 * the sphere of sb_render() (render.h) with one light of irradiance pi into
 * an RGBA32F framebuffer and writes into <pre id="sb-test"> the lines
 * "status=ok" (or "status=error: why"), "renderer=...", "size=S",
 * "rec=BASE64" and, with a source, "orig=BASE64": float32 RGBA linear
 * radiance, rows from the top, alpha = coverage.  "&shape=2" lights that
 * sphere by the page's procedural sky instead (a fixed quadrature,
 * data/viewer3d.js), "&hdr=BASE64URL" by a .hdr file as if dropped on
 * the page; "&lobe=1" adds "lobe_rec=" (and "lobe_orig="), f(L, V)
 * for the light L over 48 x 48 cells in theta_o x phi_o; "&slice=1&psi=DEG"
 * adds "slice_rec=" (and "slice_orig="), f(L, V) at 256 signed theta_o in
 * the plane DEG from the plane of incidence.  tests/test_view3d.c has the
 * directions and the sky. */
#ifndef SEPBRDF_VIEWER_H
#define SEPBRDF_VIEWER_H

#include "common.h"
#include "factor.h"
#include "matrix.h"
#include "param.h"
#include "source.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SB_VIEWER_REF_CELLS (1u << 17)

typedef struct sb_viewer_opts {
    const sb_source_t *source; /* the original; NULL: the page shows the reconstruction only */
    const char *glsl;          /* snippet text to run; NULL: sb_glsl_snippet(param, form, J, NULL) */
    const char *report_json;   /* report.json text, shown as a table; NULL: none */
    size_t file_bytes;         /* size of the texture files on disk, shown; 0: unknown */
    size_t ref_cells;          /* largest reference table in cells; 0: SB_VIEWER_REF_CELLS */
} sb_viewer_opts_t;

/* Write the page to `path` (temporary "PATH.tmp-PID", then renamed).  f
 * holds the factors as read back from their files, param and form as
 * sb_factors_param() gives them; opts may be NULL.
 * Errors: SB_ERR_ARG (NULL f/param/path, sizes of f and param differ),
 * SB_ERR_NOMEM, SB_ERR_IO (cannot write), those of sb_matrix_build and
 * sb_param_create for the reference table. */
SB_API sb_result_t sb_viewer_write(sb_context_t *ctx, const char *path, const sb_factors_t *f, const sb_param_t *param,
                                   sb_form_t form, const sb_viewer_opts_t *opts);

#ifdef __cplusplus
}
#endif
#endif
