/* What the shading-language tests share (tests/shader_check.h). */
#include "shader_check.h"

#include <stdlib.h>
#include <string.h>

#include "harness.h"

/* The layouts: each kind at R = 12, theta_max limited on hd, and iso and hd
 * with warp tables in their specs. */
const char *const sb_specs[SB_NSPECS] = {"io:res=12",
                                         "io-area:res=12",
                                         "hd:res=12,theta_max=1.2",
                                         "iso:th=12,td=12,pd=6",
                                         "iso:th=12,td=12,pd=6,warp_h=0.05/0.2/0.5,warp_d=0.3/0.6",
                                         "hd:res=12,warp_h=merl,warp_d=0.1/0.4/0.7",
                                         "vh:res=12",
                                         "vh:res=12,warp_h=0.05/0.2/0.5"};

sb_param_t *sb_param_of(const char *spec) {
    sb_param_kind_t k;
    sb_param_opts_t o;
    sb_param_t *p = NULL;
    if (sb_param_parse_spec(NULL, spec, &k, &o) != SB_OK || sb_param_create(NULL, k, &o, &p) != SB_OK) return NULL;
    return p;
}

/* The vndf layout of an RGL file (the orange film: its mirror peak in the
 * tables), as auto picks it there; NULL on failure. */
sb_param_t *sb_param_vndf(void) {
    sb_source_t *src = NULL;
    sb_param_kind_t k;
    sb_param_opts_t o = {0};
    sb_param_t *p = NULL;
    if (sb_measured_open(NULL, SB_MEASURED_DIR "/rgl_chm_orange_rgb.bsdf", NULL, &src, NULL) != SB_OK) return NULL;
    o.tables = sb_source_layout_tables(src);
    if (sb_param_kind_parse("vndf", &k) != SB_OK || sb_param_create(NULL, k, &o, &p) != SB_OK) p = NULL;
    sb_source_destroy(src);
    return p;
}

/* One layout, form and sampler choice as the library writes it, in
 * `lang`; glsl: the snippet alone.  NULL on failure. */
char *sb_shader_text(const sb_param_t *p, sb_form_t form, int sampled, const char *lang) {
    double scales[3] = {1, 0.5, 2};
    char *head = sb_glsl_snippet(p, form, 3, form == SB_FORM_COS ? scales : NULL);
    char *tail = sampled ? sb_glsl_sampler(p, sampled) : NULL;
    size_t n = (head ? strlen(head) : 0) + (tail ? strlen(tail) : 0) + 1;
    char *glsl = head && (tail || !sampled) ? malloc(n) : NULL;
    if (glsl) snprintf(glsl, n, "%s%s", head, tail ? tail : "");
    char *out = glsl ? sb_shader_translate(glsl, lang) : NULL;
    free(head);
    free(tail);
    free(glsl);
    return out;
}

/* A JS string literal of s. */
void sb_js_string(FILE *fp, const char *s) {
    fputc('"', fp);
    for (; *s; s++) {
        if (*s == '\n')
            fputs("\\n", fp);
        else if (*s == '"' || *s == '\\')
            fprintf(fp, "\\%c", *s);
        else if (*s == '<')
            fputs("\\x3c", fp); /* no "</script>" inside the page */
        else
            fputc(*s, fp);
    }
    fputc('"', fp);
}

/* dir/wgsl.html, open for writing (NULL on failure). */
FILE *sb_page_file(const char *dir) {
    char path[512];
    snprintf(path, sizeof path, "%s/wgsl.html", dir);
    return fopen(path, "w");
}

/* Run dir/wgsl.html (written by the caller, its script ending with
 * console.log('SB-WGSL-DONE')) in headless Chromium's WebGPU; its
 * "SB-WGSL..." console lines into log.  0 when the page ran, 77 when there
 * is no browser or no WebGPU adapter (the page logs SB-WGSL-NOADAPTER). */
int sb_chromium_page(const char *dir, char *log, size_t logsz) {
    char cmd[2048];
    if (sb_run("command -v chromium", NULL, 0) != 0) return 77;
    /* the page runs until killed: wait for its last line */
    snprintf(cmd, sizeof cmd,
             "cd %s && { timeout 300 chromium --headless=new --no-sandbox --no-first-run --disable-gpu-sandbox "
             "--enable-unsafe-webgpu --enable-unsafe-swiftshader --use-webgpu-adapter=swiftshader "
             "--user-data-dir=%s/profile --enable-logging=stderr --v=0 file://%s/wgsl.html 2> log & pid=$!; "
             "for i in $(seq 1 600); do grep -q 'SB-WGSL-DONE\\|SB-WGSL-NOADAPTER' log && break; sleep 0.5; done; "
             "kill $pid; wait $pid; grep -o 'SB-WGSL[^\"]*' log; }",
             dir, dir, dir);
    sb_run(cmd, log, logsz);
    if (strstr(log, "SB-WGSL-NOADAPTER")) return 77;
    return strstr(log, "SB-WGSL-DONE") ? 0 : -1;
}
