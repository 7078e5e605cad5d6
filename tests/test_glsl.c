/* The GLSL snippet compiles in a real fragment shader (glslangValidator). */
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"

static int have_validator(void) { return sb_run("command -v glslangValidator", NULL, 0) == 0; }

static int compile(const char *snippet, const char *dir, char *log, size_t logsz) {
    char path[512], cmd[1024];
    snprintf(path, sizeof path, "%s/test.frag", dir);
    FILE *fp = fopen(path, "w");
    if (!fp) return -1;
    fprintf(fp,
            "#version 330 core\n%s\n"
            "in vec3 vL;\nin vec3 vV;\nout vec4 color;\n"
            "void main() { color = vec4(sb_brdf(normalize(vL), normalize(vV)), 1.0); }\n",
            snippet);
    fclose(fp);
    snprintf(cmd, sizeof cmd, "glslangValidator %s", path);
    return sb_run(cmd, log, logsz);
}

SB_TEST(snippet_compiles) {
    if (!have_validator()) SKIP("glslangValidator not installed (Debian package glslang-tools)");
    const char *dir = sb_tmpdir("glsl");
    sb_param_opts_t o = {0};
    o.res = 16;
    sb_param_t *p;
    CHECK(sb_param_create(NULL, SB_PARAM_IO, &o, &p) == SB_OK);
    for (int form = 0; form < SB_FORM_COUNT_; form++) {
        double scales[3] = {1, 0.5, 2};
        char *s = sb_glsl_snippet(p, (sb_form_t)form, 3, form == 1 ? scales : NULL);
        CHECK(s != NULL);
        CHECK(strstr(s, "#define SB_TERMS 3") != NULL);
        char log[8192];
        int rc = compile(s, dir, log, sizeof log);
        CHECKF(rc == 0, "form %d: glslangValidator failed:\n%s", form, log);
        free(s);
    }
    sb_param_destroy(p);
}

/* The check is real: a snippet missing its coordinate function fails. */
SB_TEST(broken_snippet_fails) {
    if (!have_validator()) SKIP("glslangValidator not installed (Debian package glslang-tools)");
    const char *dir = sb_tmpdir("glsl");
    char log[8192];
    const char *lib = sb_glsl_library();
    char *s = malloc(strlen(lib) + 256);
    sprintf(s, "#define SB_TERMS 2\n#define SB_FORM 0\nconst float sb_scale[2] = float[2](1.0, 1.0);\n%s", lib);
    CHECK(compile(s, dir, log, sizeof log) != 0);
    free(s);
}

SB_TEST(write_file) {
    const char *dir = sb_tmpdir("glsl");
    sb_param_t *p;
    CHECK(sb_param_create(NULL, SB_PARAM_IO, NULL, &p) == SB_OK);
    char path[512];
    snprintf(path, sizeof path, "%s/x.glsl", dir);
    CHECK(sb_glsl_write(NULL, path, p, SB_FORM_F, 4, NULL) == SB_OK);
    CHECK(sb_file_exists(path));
    snprintf(path, sizeof path, "%s/no/such/dir/x.glsl", dir);
    CHECK(sb_glsl_write(NULL, path, p, SB_FORM_F, 4, NULL) == SB_ERR_IO);
    sb_param_destroy(p);
}
