/* gl_sphere: render a lit sphere with the factors in a `sepbrdf factor`
 * output folder on the GPU (Mesa offscreen), the way an application would:
 * the EXR textures become two GL_TEXTURE_2D_ARRAYs and the folder's
 * sepbrdf.glsl is pasted into a fragment shader.
 *
 *     sepbrdf factor -o out && gl_sphere out sphere.png [SIZE] [EXPOSURE]
 *
 * Tone mapping: exposure (default: 1 / the brightest channel), clamp, sRGB. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gl_render.h"

static char *read_text(const char *path) {
    FILE *fp = fopen(path, "rb");
    if (!fp) return NULL;
    fseek(fp, 0, SEEK_END);
    long n = ftell(fp);
    fseek(fp, 0, SEEK_SET);
    char *s = n >= 0 ? malloc((size_t)n + 1) : NULL;
    if (s && fread(s, 1, (size_t)n, fp) == (size_t)n) {
        s[n] = 0;
    } else {
        free(s);
        s = NULL;
    }
    fclose(fp);
    return s;
}

int main(int argc, char **argv) {
    if (argc < 3 || argc > 5) {
        fprintf(stderr, "usage: gl_sphere FACTOR-DIR OUT.png [SIZE] [EXPOSURE]\n");
        return 1;
    }
    const char *dir = argv[1], *png = argv[2];
    sb_render_opts_t opts = {0};
    opts.size = argc > 3 ? (size_t)strtoul(argv[3], NULL, 10) : 256;
    double exposure = argc > 4 ? strtod(argv[4], NULL) : 0;
    if (opts.size < 8 || opts.size > 4096) {
        fprintf(stderr, "gl_sphere: SIZE must be in 8..4096\n");
        return 1;
    }

    sb_context_t *ctx = NULL;
    sb_factors_t *f = NULL;
    sb_param_t *p = NULL;
    gl_sphere_t *g = NULL;
    sb_image_t img = {0};
    char *snippet = NULL, path[4096], err[2048];
    sb_form_t form;
    int rc = 1;
    if (sb_context_create(&ctx) != SB_OK) return 1;
    /* The factors (EXR) and the parameterisation they were made on */
    if (sb_factors_read_exr(ctx, dir, &f) != SB_OK || sb_factors_param(ctx, f, &p, &form) != SB_OK) {
        fprintf(stderr, "gl_sphere: %s\n", sb_context_last_error(ctx));
        goto out;
    }
    snprintf(path, sizeof path, "%s/sepbrdf.glsl", dir);
    if (!(snippet = read_text(path))) {
        fprintf(stderr, "gl_sphere: cannot read %s\n", path);
        goto out;
    }
    if (gl_sphere_open(&g, err, sizeof err) || gl_sphere_render(g, snippet, f, p, &opts, &img, err, sizeof err)) {
        fprintf(stderr, "gl_sphere: %s\n", err);
        goto out;
    }
    sb_tonemap_t tm = {exposure, SB_TONEMAP_CLAMP};
    if (!(tm.exposure > 0)) {
        double peak = sb_image_max(&img);
        tm.exposure = peak > 0 ? 1 / peak : 1;
    }
    if (sb_image_write_png(ctx, png, &img, &tm) != SB_OK) {
        fprintf(stderr, "gl_sphere: %s\n", sb_context_last_error(ctx));
        goto out;
    }
    printf("gl_sphere: %s, %zu terms (%s, form %s) -> %s (%zu x %zu, exposure %.4g)\n", gl_sphere_renderer(g),
           sb_factors_terms(f), sb_param_spec(p), sb_form_name(form), png, opts.size, opts.size, tm.exposure);
    rc = 0;
out:
    sb_image_free(&img);
    gl_sphere_close(g);
    free(snippet);
    sb_param_destroy(p);
    sb_factors_destroy(f);
    sb_context_destroy(ctx);
    return rc;
}
