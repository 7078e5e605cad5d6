/* The GLSL sampler block (data/sepbrdf_sample.glsl): a header of #defines,
 * the parameterisation's sb_row_dir() and the generic sampling functions,
 * appended to the snippet when the factors are non-negative. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sb_glsl_sample_text.h"
#include "sepbrdf/glsl.h"
#include "sepbrdf/outset.h"
#include "sepbrdf/sampler.h"
#include "util/internal.h"

char *sb_glsl_sampler(const sb_param_t *p, size_t channels) {
    if (!p || (channels != 1 && channels != 3)) return NULL;
    const char *rows = sb_param_sample_glsl(p);
    if (!*rows) return NULL; /* a layout without a sampler (rv) */
    /* the layout's functions where the block's marker line is: after the
     * tables' accessors and cell searches they use, before their callers */
    const char *text = sb_glsl_sample_text_, *mark = strstr(text, "// @ROWS");
    const char *after = mark ? strchr(mark, '\n') : NULL;
    if (!after) return NULL;
    size_t cap = strlen(rows) + strlen(text) + 512;
    char *s = malloc(cap);
    if (!s) return NULL;
    snprintf(s, cap,
             "\n// ---- importance sampling (non-negative factors; sampler.bin) ----\n"
             "#define SB_SAMPLE_CH %zu\n#define SB_HALF_ROWS %d\n#define SB_COL_SAMPLE %d\n#define SB_COL_FOLD "
             "%d\n\n%.*s%s%s",
             channels, (sb_param_caps(p) & SB_CAP_HALF_ROWS) ? 1 : 0, (sb_param_caps(p) & SB_CAP_COL_SAMPLE) ? 1 : 0,
             (sb_param_caps(p) & SB_CAP_COL_FOLD) ? 1 : 0, (int)(mark - text), text, rows, after + 1);
    return s;
}

sb_result_t sb_glsl_write_sampled(sb_context_t *ctx, const char *path, const sb_param_t *p, sb_form_t form,
                                  size_t terms, const double *scales, size_t channels) {
    if (!path || !p || (channels != 1 && channels != 3))
        return sb_error(ctx, SB_ERR_ARG, "glsl: no path or parameterisation, or %zu channels", channels);
    char *head = sb_glsl_snippet(p, form, terms, scales), *tail = sb_glsl_sampler(p, channels);
    sb_result_t r = SB_OK;
    if (!head || !tail) {
        r = (unsigned)form >= SB_FORM_COUNT_ || terms == 0 || terms > SB_GLSL_MAX_TERMS
                ? sb_error(ctx, SB_ERR_ARG, "glsl: unknown form or %zu terms", terms)
                : sb_error(ctx, SB_ERR_NOMEM, "glsl: out of memory");
    } else {
        const void *parts[2] = {head, tail};
        size_t sizes[2] = {strlen(head), strlen(tail)};
        int e = sb_write_atomic(path, parts, sizes, 2);
        if (e) r = sb_error(ctx, SB_ERR_IO, "%s: cannot write: %s", path, sb_io_why(e));
    }
    free(head);
    free(tail);
    return r;
}
