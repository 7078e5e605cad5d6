/* The GLSL snippet compiles in a real fragment shader (glslangValidator). */
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"
#include "shader_check.h"

static int have_validator(void) { return sb_run("command -v glslangValidator", NULL, 0) == 0; }

/* The profiles the snippet supports: desktop GLSL 3.30 core and 4.50 core,
 * and GLSL ES 3.00 (WebGL2, GLES 3), which converts no int to float and
 * needs precision qualifiers (the snippet declares them under GL_ES). */
static const char *const profiles[] = {"#version 330 core", "#version 450 core", "#version 300 es"};
#define NPROFILES (sizeof profiles / sizeof profiles[0])

static int compile_as(const char *version, const char *snippet, const char *dir, char *log, size_t logsz) {
    char path[512], cmd[1024];
    snprintf(path, sizeof path, "%s/test.frag", dir);
    FILE *fp = fopen(path, "w");
    if (!fp) return -1;
    fprintf(fp,
            "%s\n%s\n"
            "in vec3 vL;\nin vec3 vV;\nout vec4 color;\n"
            "void main() { color = vec4(sb_brdf(normalize(vL), normalize(vV)), 1.0); }\n",
            version, snippet);
    fclose(fp);
    snprintf(cmd, sizeof cmd, "glslangValidator %s", path);
    return sb_run(cmd, log, logsz);
}

/* Layouts with warps (param.h): iso with both axes measured on GGX
 * roughness 0.1 (tables of 64 segments), hd with MERL's theta_h and a
 * measured theta_d; theta_max as given. */
static sb_param_t *warped_param(int which, size_t res, double theta_max) {
    sb_source_t *src = NULL;
    sb_param_opts_t o = {0};
    o.res = res;
    o.theta_max = theta_max;
    sb_warp_measure_opts_t wo = {0};
    wo.theta_max = theta_max;
    sb_param_t *p = NULL;
    if (sb_source_open(NULL, "cook-torrance:roughness=0.1", &src) != SB_OK) return NULL;
    if (which == 0 && sb_warp_measure(NULL, src, SB_AXIS_THETA_H, &wo, &o.warp[SB_AXIS_THETA_H]) != SB_OK) o.res = 0;
    if (which == 1) o.warp[SB_AXIS_THETA_H].kind = SB_WARP_MERL;
    if (sb_warp_measure(NULL, src, SB_AXIS_THETA_D, &wo, &o.warp[SB_AXIS_THETA_D]) != SB_OK) o.res = 0;
    sb_source_destroy(src);
    if (!o.res || sb_param_create(NULL, which ? SB_PARAM_HD : SB_PARAM_ISO, &o, &p) != SB_OK) return NULL;
    return p;
}

/* rv (param_rv.c): a kind numbered by name, after the numbered ones. */
static sb_param_kind_t rv_kind(void) {
    sb_param_kind_t k = SB_PARAM_NONE;
    CHECK(sb_param_kind_parse("rv", &k) == SB_OK);
    return k;
}

static int compile(const char *snippet, const char *dir, char *log, size_t logsz) {
    return compile_as(profiles[0], snippet, dir, log, logsz);
}

/* Every parameterisation's sb_coords()/sb_domain() (rv too) with every form, also
 * with a limited theta_max, and with warp tables (iso, hd), in every
 * profile; scales with integral values (1, 2) and fractional ones, as
 * --half writes them. */
SB_TEST(snippet_compiles) {
    if (!have_validator()) SKIP("glslangValidator not installed (Debian package glslang-tools)");
    const char *dir = sb_tmpdir("glsl");
    for (int kind = 0; kind < SB_TEST_KINDS + 3; kind++) {
        sb_param_opts_t o = {0};
        o.res = 16;
        o.theta_max = kind == SB_PARAM_HD ? 1.0 : 0;
        sb_param_t *p = NULL;
        if (kind == SB_TEST_KINDS + 2) /* rv, numbered by name */
            CHECK(sb_param_create(NULL, rv_kind(), &o, &p) == SB_OK);
        else if (kind >= SB_TEST_KINDS)
            CHECK((p = warped_param(kind - SB_TEST_KINDS, 16, kind == SB_TEST_KINDS ? 0 : 1.0)) != NULL);
        else
            CHECK(sb_param_create(NULL, (sb_param_kind_t)kind, &o, &p) == SB_OK);
        if (!p) continue;
        for (int form = 0; form < SB_FORM_COUNT_; form++) {
            double scales[3] = {1, 0.5, 2};
            char *s = sb_glsl_snippet(p, (sb_form_t)form, 3, form == 1 ? scales : NULL);
            CHECK(s != NULL);
            CHECK(strstr(s, "#define SB_TERMS 3") != NULL);
            CHECK(strstr(s, sb_param_spec(p)) != NULL);
            for (size_t v = 0; v < NPROFILES; v++) {
                char log[8192];
                int rc = compile_as(profiles[v], s, dir, log, sizeof log);
                CHECKF(rc == 0, "%s form %d, %s: glslangValidator failed:\n%s", sb_param_spec(p), form, profiles[v],
                       log);
            }
            free(s);
        }
        sb_param_destroy(p);
    }
}

/* The ES check is real: the integer literals the snippet once wrote in
 * float[N](1, 1) fail GLSL ES 3.00 (and pass 3.30 core, which converts). */
SB_TEST(es_rejects_int_literals) {
    if (!have_validator()) SKIP("glslangValidator not installed (Debian package glslang-tools)");
    const char *dir = sb_tmpdir("glsl");
    const char *bad = "precision highp float;\nconst float k[2] = float[2](1, 1);\n"
                      "vec3 sb_brdf(vec3 L, vec3 V) { return L * k[0] + V * k[1]; }\n";
    char log[8192];
    CHECK(compile_as(profiles[0], bad, dir, log, sizeof log) == 0);
    CHECK(compile_as(profiles[2], bad, dir, log, sizeof log) != 0);
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

/* ---- the snippet computes what the CPU computes ------------------------ */

/* Runs the real snippet in an OpenGL 3.3 core context (EGL, Mesa's
 * surfaceless platform: llvmpipe needs no display or GPU) on random pairs
 * and random factor textures, and compares sb_coords()/sb_domain()/
 * sb_brdf() with sb_param_coords()/sb_factors_eval().  libEGL is opened at
 * run time, so nothing links against GL; without it the case skips. */
#if defined(__has_include)
#if __has_include(<EGL/egl.h>) && __has_include(<EGL/eglext.h>) && __has_include(<GL/glcorearb.h>)
#define SB_HAVE_GL_HEADERS 1
#endif
#endif

#ifdef SB_HAVE_GL_HEADERS
#define EGL_NO_X11 1
#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <GL/glcorearb.h>
#include <dlfcn.h>

#define GL_FUNCS(X)                                                                                                    \
    X(PFNGLCREATESHADERPROC, glCreateShader)                                                                           \
    X(PFNGLSHADERSOURCEPROC, glShaderSource)                                                                           \
    X(PFNGLCOMPILESHADERPROC, glCompileShader)                                                                         \
    X(PFNGLGETSHADERIVPROC, glGetShaderiv)                                                                             \
    X(PFNGLGETSHADERINFOLOGPROC, glGetShaderInfoLog)                                                                   \
    X(PFNGLDELETESHADERPROC, glDeleteShader)                                                                           \
    X(PFNGLCREATEPROGRAMPROC, glCreateProgram)                                                                         \
    X(PFNGLATTACHSHADERPROC, glAttachShader)                                                                           \
    X(PFNGLLINKPROGRAMPROC, glLinkProgram)                                                                             \
    X(PFNGLGETPROGRAMIVPROC, glGetProgramiv)                                                                           \
    X(PFNGLUSEPROGRAMPROC, glUseProgram)                                                                               \
    X(PFNGLDELETEPROGRAMPROC, glDeleteProgram)                                                                         \
    X(PFNGLGETUNIFORMLOCATIONPROC, glGetUniformLocation)                                                               \
    X(PFNGLUNIFORM1IPROC, glUniform1i)                                                                                 \
    X(PFNGLGENTEXTURESPROC, glGenTextures)                                                                             \
    X(PFNGLDELETETEXTURESPROC, glDeleteTextures)                                                                       \
    X(PFNGLBINDTEXTUREPROC, glBindTexture)                                                                             \
    X(PFNGLACTIVETEXTUREPROC, glActiveTexture)                                                                         \
    X(PFNGLTEXIMAGE2DPROC, glTexImage2D)                                                                               \
    X(PFNGLTEXIMAGE3DPROC, glTexImage3D)                                                                               \
    X(PFNGLTEXPARAMETERIPROC, glTexParameteri)                                                                         \
    X(PFNGLGENFRAMEBUFFERSPROC, glGenFramebuffers)                                                                     \
    X(PFNGLDELETEFRAMEBUFFERSPROC, glDeleteFramebuffers)                                                               \
    X(PFNGLBINDFRAMEBUFFERPROC, glBindFramebuffer)                                                                     \
    X(PFNGLFRAMEBUFFERTEXTURE2DPROC, glFramebufferTexture2D)                                                           \
    X(PFNGLCHECKFRAMEBUFFERSTATUSPROC, glCheckFramebufferStatus)                                                       \
    X(PFNGLDRAWBUFFERSPROC, glDrawBuffers)                                                                             \
    X(PFNGLREADBUFFERPROC, glReadBuffer)                                                                               \
    X(PFNGLREADPIXELSPROC, glReadPixels)                                                                               \
    X(PFNGLGENVERTEXARRAYSPROC, glGenVertexArrays)                                                                     \
    X(PFNGLDELETEVERTEXARRAYSPROC, glDeleteVertexArrays)                                                               \
    X(PFNGLBINDVERTEXARRAYPROC, glBindVertexArray)                                                                     \
    X(PFNGLVIEWPORTPROC, glViewport)                                                                                   \
    X(PFNGLDRAWARRAYSPROC, glDrawArrays)
#define GL_DECLARE(type, name) static type p_##name;
GL_FUNCS(GL_DECLARE)

/* Open an EGL display and a current GL 3.3 core context; NULL or a reason. */
static const char *gl_open(void) {
    void *lib = dlopen("libEGL.so.1", RTLD_NOW | RTLD_LOCAL);
    if (!lib) return "libEGL.so.1 not found";
    PFNEGLGETPROCADDRESSPROC gpa;
    *(void **)&gpa = dlsym(lib, "eglGetProcAddress");
    if (!gpa) return "eglGetProcAddress missing";
#define EGL_LOAD(type, name)                                                                                           \
    type name;                                                                                                         \
    *(void **)&name = (void *)gpa(#name);                                                                              \
    if (!name) return #name " missing";
    EGL_LOAD(PFNEGLGETPLATFORMDISPLAYEXTPROC, eglGetPlatformDisplayEXT)
    EGL_LOAD(PFNEGLINITIALIZEPROC, eglInitialize)
    EGL_LOAD(PFNEGLBINDAPIPROC, eglBindAPI)
    EGL_LOAD(PFNEGLCREATECONTEXTPROC, eglCreateContext)
    EGL_LOAD(PFNEGLMAKECURRENTPROC, eglMakeCurrent)
    EGLDisplay dpy = eglGetPlatformDisplayEXT(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, NULL);
    if (dpy == EGL_NO_DISPLAY || !eglInitialize(dpy, NULL, NULL)) return "no surfaceless EGL display";
    if (!eglBindAPI(EGL_OPENGL_API)) return "EGL has no desktop OpenGL";
    const EGLint attr[] = {
        EGL_CONTEXT_MAJOR_VERSION,           3,       EGL_CONTEXT_MINOR_VERSION, 3, EGL_CONTEXT_OPENGL_PROFILE_MASK,
        EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
    EGLContext c = eglCreateContext(dpy, EGL_NO_CONFIG_KHR, EGL_NO_CONTEXT, attr);
    if (c == EGL_NO_CONTEXT || !eglMakeCurrent(dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, c))
        return "no GL 3.3 core context without a surface";
#define GL_LOAD(type, name)                                                                                            \
    *(void **)&p_##name = (void *)gpa(#name);                                                                          \
    if (!p_##name) return #name " missing";
    GL_FUNCS(GL_LOAD)
    return NULL;
}

static GLuint gl_shader(GLenum type, const char *src) {
    GLuint s = p_glCreateShader(type);
    p_glShaderSource(s, 1, &src, NULL);
    p_glCompileShader(s);
    GLint ok;
    p_glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        char log[4096];
        p_glGetShaderInfoLog(s, sizeof log, NULL, log);
        CHECKF(0, "shader: %s", log);
    }
    return s;
}

static double glsl_rand_dir(unsigned long long *st, double w[3], int below) {
    double z = below ? 2 * sb_rand01(st) - 1 : 1 - sb_rand01(st), ph = 2 * SB_PI * sb_rand01(st);
    double r = sqrt(1 - z * z);
    w[0] = r * cos(ph), w[1] = r * sin(ph), w[2] = z;
    return z;
}

enum { GW = 64, GH = 64, GN = GW * GH, GJ = 2 };

/* Every occurrence of `from` in the malloc'ed *s replaced by `to`. */
static void replace_all(char **s, const char *from, const char *to) {
    for (char *at; *s && (at = strstr(*s, from)) != NULL;) {
        size_t head = (size_t)(at - *s), n = strlen(*s) - strlen(from) + strlen(to) + 1;
        char *t = malloc(n);
        if (t) snprintf(t, n, "%.*s%s%s", (int)head, *s, to, at + strlen(from));
        free(*s);
        *s = t;
    }
}

/* gl_compare's fragment shader: texelFetch the pair, write sb_coords and
 * (sb_brdf, sb_domain). */
static char *glsl_shader(const sb_param_t *p) {
    char *snip = sb_glsl_snippet(p, SB_FORM_F, GJ, NULL);
    size_t len = strlen(snip) + 1024;
    char *fs = malloc(len);
    if (fs)
        snprintf(fs, len,
                 "#version 330 core\n%s\nuniform sampler2D inL;\nuniform sampler2D inV;\n"
                 "layout(location = 0) out vec4 o0;\nlayout(location = 1) out vec4 o1;\n"
                 "void main() {\n    ivec2 q = ivec2(gl_FragCoord.xy);\n"
                 "    vec3 L = normalize(texelFetch(inL, q, 0).xyz), V = normalize(texelFetch(inV, q, 0).xyz);\n"
                 "    vec4 st = sb_coords(L, V);\n    o0 = st;\n"
                 "    o1 = vec4(sb_brdf(L, V), sb_domain(L, V, st) ? 1.0 : 0.0);\n}\n",
                 snip);
    free(snip);
    return fs;
}

/* gl_compare's fragment shader through the HLSL snippet: the same main in
 * HLSL, compiled by glslangValidator's HLSL front end to SPIR-V, turned into
 * GLSL 3.30 by spirv-cross, its textures renamed as gl_compare binds them.
 * NULL (after a failed check) if a tool fails. */
static char *hlsl_shader(const sb_param_t *p) {
    const char *dir = sb_tmpdir("glsl_hlsl");
    char *glsl = sb_glsl_snippet(p, SB_FORM_F, GJ, NULL), *hlsl = sb_shader_translate(glsl, "hlsl"), path[512];
    char cmd[1600], log[8192];
    free(glsl);
    snprintf(path, sizeof path, "%s/cmp.hlsl", dir);
    FILE *fp = hlsl ? fopen(path, "w") : NULL;
    CHECK(fp != NULL);
    if (!fp) return NULL;
    fprintf(fp,
            "%s\nTexture2D<float4> inL : register(t3);\nTexture2D<float4> inV : register(t4);\n"
            "struct sb_out { float4 o0 : SV_Target0; float4 o1 : SV_Target1; };\n"
            "sb_out main(float4 pos : SV_Position) {\n    int2 q = int2(pos.xy);\n"
            "    float3 L = normalize(inL.Load(int3(q, 0)).xyz), V = normalize(inV.Load(int3(q, 0)).xyz);\n"
            "    float4 st = sb_coords(L, V);\n    sb_out o;\n    o.o0 = st;\n"
            "    o.o1 = float4(sb_brdf(L, V), sb_domain(L, V, st) ? 1.0 : 0.0);\n    return o;\n}\n",
            hlsl);
    fclose(fp);
    free(hlsl);
    snprintf(cmd, sizeof cmd,
             "glslangValidator -D -V -S frag -e main -o %s/cmp.spv %s && "
             "spirv-cross --version 330 --no-es %s/cmp.spv --output %s/cmp.frag",
             dir, path, dir, dir);
    int rc = sb_run(cmd, log, sizeof log);
    CHECKF(rc == 0, "%s: HLSL -> SPIR-V -> GLSL failed:\n%s", sb_param_spec(p), log);
    snprintf(path, sizeof path, "%s/cmp.frag", dir);
    fp = rc == 0 ? fopen(path, "rb") : NULL;
    if (!fp) return NULL;
    char *text = calloc(1, 1 << 20);
    if (text) fread(text, 1, (1 << 20) - 1, fp);
    fclose(fp);
    static const char *const names[][2] = {{"SPIRV_Cross_Combinedsb_gsb_g_sampler", "sb_g"},
                                           {"SPIRV_Cross_Combinedsb_hsb_h_sampler", "sb_h"},
                                           {"SPIRV_Cross_CombinedinLSPIRV_Cross_DummySampler", "inL"},
                                           {"SPIRV_Cross_CombinedinVSPIRV_Cross_DummySampler", "inV"}};
    for (int i = 0; i < 4; i++) {
        CHECKF(text && strstr(text, names[i][0]), "%s: no %s in spirv-cross's GLSL", sb_param_spec(p), names[i][0]);
        replace_all(&text, names[i][0], names[i][1]);
    }
    /* vndf's tables (Load on a Texture2D, no sampler): combined with a dummy */
    replace_all(&text, "SPIRV_Cross_Combinedsb_vndfSPIRV_Cross_DummySampler", "sb_vndf");
    /* GetDimensions (textureSize: sb_texture_h with SB_EDGE_H_S) reads a
     * texture without its sampler: spirv-cross combines it with a dummy */
    for (int s = 0; s < 2 && text; s++) {
        char dummy[96], decl[128];
        snprintf(dummy, sizeof dummy, "SPIRV_Cross_Combined%sSPIRV_Cross_DummySampler", s ? "sb_h" : "sb_g");
        snprintf(decl, sizeof decl, "uniform sampler2DArray %s;", dummy);
        replace_all(&text, decl, "");
        replace_all(&text, dummy, s ? "sb_h" : "sb_g");
    }
    return text;
}

/* A layout's tables (vndf: sb_vndf, vndf.exr's texels) on texture unit 4,
 * nearest (read with texelFetch only); 0 when it has none. */
static GLuint gl_tables(const sb_param_t *p, GLuint prog) {
    size_t w, h;
    float *rgb = NULL;
    if (sb_param_tables_texture(p, &w, &h, &rgb) != SB_OK) return 0;
    GLuint t;
    p_glGenTextures(1, &t);
    p_glActiveTexture(GL_TEXTURE4);
    p_glBindTexture(GL_TEXTURE_2D, t);
    p_glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB32F, (GLsizei)w, (GLsizei)h, 0, GL_RGB, GL_FLOAT, rgb);
    p_glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    p_glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    p_glUniform1i(p_glGetUniformLocation(prog, "sb_vndf"), 4);
    p_glActiveTexture(GL_TEXTURE5); /* unit 4 keeps it while the outputs are bound */
    free(rgb);
    return t;
}

/* One parameterisation: render, read back, compare; through the HLSL
 * snippet (hlsl_shader) when hlsl is set.  Returns what the shader wrote
 * (2 GN vec4s: sb_coords, then sb_brdf and sb_domain; malloc'ed, NULL when
 * it did not run) and the pairs (dirs, GN x 2 x 3, when not NULL). */
static float *gl_compare(sb_param_t *p, int hlsl, double (**dirs)[2][3]) {
    char *fs = hlsl ? hlsl_shader(p) : glsl_shader(p);
    if (!fs) return NULL;
    size_t tw[2], th[2];
    int wrap[2][2];
    for (int s = 0; s < 2; s++) {
        sb_param_texture_size(p, s, &tw[s], &th[s]);
        sb_param_wrap(p, s, wrap[s]);
    }
    sb_factors_t *f;
    CHECK(sb_factors_create(NULL, GJ, 3, tw[0], th[0], tw[1], th[1], &f) == SB_OK);
    unsigned long long st = 1234;
    float *tex = malloc((tw[0] * th[0] + tw[1] * th[1]) * GJ * 3 * sizeof *tex);
    float *in = malloc(2 * GN * 4 * sizeof *in), *out = malloc(2 * GN * 4 * sizeof *out);
    double(*dir)[2][3] = malloc(GN * sizeof *dir);
    /* random pairs, some below the horizon; the CPU gets the float-rounded,
     * renormalised directions the shader sees */
    for (int i = 0; i < GN; i++)
        for (int k = 0; k < 2; k++) {
            double *w = dir[i][k], n = 0;
            glsl_rand_dir(&st, w, i % 9 == k);
            for (int a = 0; a < 3; a++)
                n += (double)(float)w[a] * (float)w[a];
            for (int a = 0; a < 3; a++) {
                in[(k * GN + i) * 4 + a] = (float)w[a];
                w[a] = (float)w[a] / sqrt(n);
            }
            in[(k * GN + i) * 4 + 3] = 0;
        }
    const char *vs =
        "#version 330 core\nvoid main() {\n"
        "    gl_Position = vec4(float((gl_VertexID & 1) * 4 - 1), float((gl_VertexID >> 1) * 4 - 1), 0, 1);\n}\n";
    GLuint prog = p_glCreateProgram(), sv = gl_shader(GL_VERTEX_SHADER, vs), sf = gl_shader(GL_FRAGMENT_SHADER, fs);
    p_glAttachShader(prog, sv);
    p_glAttachShader(prog, sf);
    p_glLinkProgram(prog);
    GLint ok;
    p_glGetProgramiv(prog, GL_LINK_STATUS, &ok);
    CHECK(ok);
    p_glUseProgram(prog);
    GLuint t[6], fbo, vao;
    p_glGenTextures(6, t);
    for (int k = 0; k < 2; k++) { /* inputs: nearest, fetched by texel */
        p_glActiveTexture(GL_TEXTURE0 + k);
        p_glBindTexture(GL_TEXTURE_2D, t[k]);
        p_glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, GW, GH, 0, GL_RGBA, GL_FLOAT, in + k * GN * 4);
        p_glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
        p_glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
        p_glUniform1i(p_glGetUniformLocation(prog, k ? "inV" : "inL"), k);
    }
    for (int s = 0; s < 2; s++) { /* factors: random, layer j = term j, sampler state as documented */
        size_t n = tw[s] * th[s];
        for (size_t j = 0; j < GJ; j++)
            for (int c = 0; c < 3; c++) {
                double *x = sb_factors_tex(f, s, j, c);
                for (size_t i = 0; i < n; i++)
                    tex[(j * n + i) * 3 + c] = (float)(x[i] = sb_rand01(&st));
            }
        p_glActiveTexture(GL_TEXTURE2 + s);
        p_glBindTexture(GL_TEXTURE_2D_ARRAY, t[2 + s]);
        p_glTexImage3D(GL_TEXTURE_2D_ARRAY, 0, GL_RGB32F, (GLsizei)tw[s], (GLsizei)th[s], GJ, 0, GL_RGB, GL_FLOAT, tex);
        p_glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
        p_glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
        p_glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_WRAP_S, wrap[s][0] ? GL_REPEAT : GL_CLAMP_TO_EDGE);
        p_glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_WRAP_T, wrap[s][1] ? GL_REPEAT : GL_CLAMP_TO_EDGE);
        p_glUniform1i(p_glGetUniformLocation(prog, s ? "sb_h" : "sb_g"), 2 + s);
    }
    GLuint tables = gl_tables(p, prog);
    p_glGenFramebuffers(1, &fbo);
    p_glBindFramebuffer(GL_FRAMEBUFFER, fbo);
    for (int k = 0; k < 2; k++) {
        p_glBindTexture(GL_TEXTURE_2D, t[4 + k]);
        p_glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, GW, GH, 0, GL_RGBA, GL_FLOAT, NULL);
        p_glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0 + k, GL_TEXTURE_2D, t[4 + k], 0);
    }
    const GLenum bufs[2] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1};
    p_glDrawBuffers(2, bufs);
    CHECK(p_glCheckFramebufferStatus(GL_FRAMEBUFFER) == GL_FRAMEBUFFER_COMPLETE);
    p_glGenVertexArrays(1, &vao);
    p_glBindVertexArray(vao);
    p_glViewport(0, 0, GW, GH);
    p_glDrawArrays(GL_TRIANGLES, 0, 3);
    for (int k = 0; k < 2; k++) {
        p_glReadBuffer(GL_COLOR_ATTACHMENT0 + k);
        p_glReadPixels(0, 0, GW, GH, GL_RGBA, GL_FLOAT, out + k * GN * 4);
    }
    /* compare: coordinates in texels (modulo the width on REPEAT axes),
     * values with float textures and filtering (8-bit filter weights on
     * some GPUs: 1e-2; relative above 1, where a gain (vndf's NDF / 4
     * sigma) scales the sum), the domain up to pairs on the cap's rim */
    double worst_st = 0, worst_f = 0, tmax = sb_param_theta_max(p);
    int mismatch = 0, inside = 0;
    for (int i = 0; i < GN; i++) {
        const double *l = dir[i][0], *v = dir[i][1];
        double sg[2], sh[2], rgb[3];
        int cpu = sb_param_coords(p, l, v, sg, sh), gpu = out[(GN + i) * 4 + 3] > 0.5;
        if (cpu != gpu) {
            double e = fmin(fmin(fabs(acos(l[2]) - tmax), fabs(acos(v[2]) - tmax)), fmin(fabs(l[2]), fabs(v[2])));
            if (e > 1e-5) mismatch++;
            continue;
        }
        if (!cpu) continue;
        inside++;
        const double c[4] = {sg[0], sg[1], sh[0], sh[1]};
        for (int a = 0; a < 4; a++) {
            int s = a / 2;
            double n = (double)(a % 2 ? th[s] : tw[s]), d = fabs(c[a] - out[i * 4 + a]);
            if (wrap[s][a % 2] == SB_WRAP_REPEAT) d = fmin(d, 1 - d);
            worst_st = fmax(worst_st, d * n);
        }
        sb_factors_eval(f, p, SB_FORM_F, GJ, l, v, rgb);
        for (int k = 0; k < 3; k++)
            worst_f = fmax(worst_f, fabs(rgb[k] - out[(GN + i) * 4 + k]) / fmax(1, fabs(rgb[k])));
    }
    CHECKF(mismatch == 0, "%s: sb_domain differs from the CPU on %d pairs", sb_param_spec(p), mismatch);
    CHECKF(inside > GN / 4, "%s: %d pairs inside", sb_param_spec(p), inside);
    CHECKF(worst_st < 1e-3, "%s: sb_coords differs by %g texels", sb_param_spec(p), worst_st);
    CHECKF(worst_f < 1e-2, "%s: sb_brdf differs by %g", sb_param_spec(p), worst_f);
    if (sb_param_caps(p) & SB_CAP_TABLES)
        printf("  %s %s: %d pairs, sb_coords within %.2g texels, sb_brdf %.2g of the CPU's\n", sb_param_spec(p),
               hlsl ? "HLSL" : "GLSL", inside, worst_st, worst_f);
    p_glDeleteVertexArrays(1, &vao);
    p_glDeleteFramebuffers(1, &fbo);
    p_glDeleteTextures(6, t);
    if (tables) p_glDeleteTextures(1, &tables);
    p_glDeleteProgram(prog);
    p_glDeleteShader(sv);
    p_glDeleteShader(sf);
    free(fs);
    if (dirs)
        *dirs = dir;
    else
        free(dir);
    free(in);
    free(tex);
    sb_factors_destroy(f);
    return out;
}

/* gl_compare on every layout (rv too), with a limited theta_max, and with warp tables. */
static void compare_all(int hlsl) {
    for (int kind = 0; kind < SB_TEST_KINDS + 3; kind++)
        for (int limited = 0; limited < 2; limited++) {
            sb_param_opts_t o = {0};
            o.res = 12;
            o.theta_max = limited ? 1.3 : 0;
            sb_param_t *p = NULL;
            if (kind == SB_TEST_KINDS + 2) /* rv */
                CHECK(sb_param_create(NULL, rv_kind(), &o, &p) == SB_OK);
            else if (kind >= SB_TEST_KINDS) /* warp tables */
                CHECK((p = warped_param(kind - SB_TEST_KINDS, 12, o.theta_max)) != NULL);
            else
                CHECK(sb_param_create(NULL, (sb_param_kind_t)kind, &o, &p) == SB_OK);
            if (!p) continue;
            free(gl_compare(p, hlsl, NULL));
            sb_param_destroy(p);
        }
}
#endif

SB_TEST(snippet_matches_cpu) {
#ifndef SB_HAVE_GL_HEADERS
    SKIP("EGL / GL headers not available at build time");
#else
    const char *why = gl_open();
    if (why) SKIP(why);
    compare_all(0);
#endif
}

/* The HLSL snippet (sb_shader_translate) executed: compiled by
 * glslangValidator's HLSL front end to SPIR-V, made GLSL again by
 * spirv-cross (a compiler's own lowering: SPIR-V's control flow, constants
 * folded in float) and run as snippet_matches_cpu runs the GLSL one, on
 * every layout, limited theta_max and warp tables: the same coordinates
 * (< 1e-3 texels), domain and values. */
SB_TEST(hlsl_matches_cpu) {
#ifndef SB_HAVE_GL_HEADERS
    SKIP("EGL / GL headers not available at build time");
#else
    if (!have_validator()) SKIP("glslangValidator not installed (Debian package glslang-tools)");
    if (sb_run("command -v spirv-cross", NULL, 0) != 0) SKIP("spirv-cross not installed (Debian package spirv-cross)");
    const char *why = gl_open();
    if (why) SKIP(why);
    compare_all(1);
#endif
}

#ifdef SB_HAVE_GL_HEADERS
/* The largest difference of two runs' outputs over the pairs both take:
 * coordinates in texels (st[0]) and values relative to max(1, |value|)
 * (st[1]); the number of such pairs. */
static int gl_outputs_differ(const sb_param_t *p, const float *a, const float *b, double st[2]) {
    size_t tw[2], th[2];
    int n = 0;
    st[0] = st[1] = 0;
    for (int s = 0; s < 2; s++)
        sb_param_texture_size(p, s, &tw[s], &th[s]);
    for (int i = 0; i < GN; i++) {
        if ((a[(GN + i) * 4 + 3] > 0.5) != (b[(GN + i) * 4 + 3] > 0.5)) return -1;
        if (!(a[(GN + i) * 4 + 3] > 0.5)) continue;
        n++;
        for (int c = 0; c < 4; c++) {
            double texels = (double)(c % 2 ? th[c / 2] : tw[c / 2]);
            st[0] = fmax(st[0], fabs((double)a[i * 4 + c] - b[i * 4 + c]) * texels);
        }
        for (int c = 0; c < 3; c++) {
            double x = a[(GN + i) * 4 + c], y = b[(GN + i) * 4 + c];
            st[1] = fmax(st[1], fabs(x - y) / fmax(1, fabs(x)));
        }
    }
    return n;
}
#endif

/* The vndf layout (an RGL file's own grid; its GLSL reads the file's warp,
 * NDF and sigma from the texture sb_vndf): its GLSL and its HLSL (through
 * SPIR-V and spirv-cross) run on 4096 random pairs with random factor
 * textures agree with the CPU (sb_param_coords within 1e-3 texels,
 * 6.6e-5 measured on llvmpipe; with GLSL's asin and atan for the
 * elevations and azimuths they were 0.02 texels apart at grazing views;
 * sb_factors_eval within the driver's filtering, 1e-2, 1.2e-5 measured),
 * and with each other to float rounding (the same texels filtered alike:
 * 1.7e-5 texels and 4e-6 measured, checked at 1e-3 and 1e-4). */
SB_TEST(vndf_matches_cpu) {
#ifndef SB_HAVE_GL_HEADERS
    SKIP("EGL / GL headers not available at build time");
#else
    const char *why = gl_open();
    if (why) SKIP(why);
    sb_param_t *p = sb_param_vndf();
    CHECK(p != NULL);
    if (!p) return;
    float *g = gl_compare(p, 0, NULL), *h = NULL;
    int tools = have_validator() && sb_run("command -v spirv-cross", NULL, 0) == 0;
    if (tools) h = gl_compare(p, 1, NULL);
    CHECK(g != NULL && (!tools || h != NULL));
    if (g && h) {
        double d[2];
        int n = gl_outputs_differ(p, g, h, d);
        CHECKF(n > GN / 8, "GLSL and HLSL: %d pairs inside both, or the domains differ (-1)", n);
        CHECKF(d[0] < 1e-3 && d[1] < 1e-4, "GLSL and HLSL differ: %g texels, values %g", d[0], d[1]);
        printf("  vndf GLSL vs HLSL: %d pairs, sb_coords within %.2g texels, sb_brdf %.2g\n", n, d[0], d[1]);
    }
    free(g);
    free(h);
    sb_param_destroy(p);
    if (!tools) SKIP("glslangValidator or spirv-cross not installed: the HLSL not run");
#endif
}
