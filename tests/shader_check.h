/* What the shading-language tests share (test_shader.c, test_wgsl.c, test_glsl.c): the
 * layouts they translate, the text the library writes for one of them, and
 * pages for headless Chromium's WebGPU (SwiftShader): write dir/wgsl.html,
 * run it, read its console lines "SB-WGSL...". */
#ifndef SB_SHADER_CHECK_H
#define SB_SHADER_CHECK_H

#include <stddef.h>
#include <stdio.h>

#include "sepbrdf/sepbrdf.h"

/* Each kind at R = 12, theta_max limited on hd, and iso and hd with warp
 * tables in their specs. */
#define SB_NSPECS 8
extern const char *const sb_specs[SB_NSPECS];
sb_param_t *sb_param_of(const char *spec); /* NULL on failure */
/* The vndf layout of tests/data/measured/rgl_chm_orange_rgb.bsdf (the
 * file's own tables, read by the shaders as sb_vndf); NULL on failure. */
sb_param_t *sb_param_vndf(void);
/* The snippet for p, form, 3 terms (scales 1, 0.5, 2 for form cos) and,
 * with sampled = 1 or 3 channels, the sampler block, in `lang`; NULL on
 * failure. */
char *sb_shader_text(const sb_param_t *p, sb_form_t form, int sampled, const char *lang);

/* s as a JS string literal (quotes, backslashes, newlines and '<' escaped). */
void sb_js_string(FILE *fp, const char *s);
/* dir/wgsl.html, open for writing (NULL on failure). */
FILE *sb_page_file(const char *dir);
/* Run dir/wgsl.html, whose script ends with console.log('SB-WGSL-DONE'):
 * its "SB-WGSL..." console lines into log.  0 when the page ran, 77 when
 * there is no browser or no WebGPU adapter (the page logs
 * SB-WGSL-NOADAPTER), -1 when it did not finish. */
int sb_chromium_page(const char *dir, char *log, size_t logsz);

#endif
