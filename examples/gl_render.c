/* The sepbrdf sphere on the GPU: OSMesa core context, a full-screen pass
 * whose fragment shader repeats the scene of sepbrdf/render.h and calls
 * sb_brdf() from the shipped snippet, float framebuffer, read back. */
#define GL_GLEXT_PROTOTYPES 1
#include "gl_render.h"

#include <GL/gl.h>
#include <GL/glext.h>
#include <GL/osmesa.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct gl_sphere {
    OSMesaContext osm;
    unsigned char dummy[4 * 4 * 4]; /* OSMesa needs a colour buffer; we draw to an FBO */
    char renderer[256];
};

static int fail(char *err, size_t size, const char *fmt, ...) {
    if (err && size) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(err, size, fmt, ap);
        va_end(ap);
    }
    return -1;
}

int gl_sphere_open(gl_sphere_t **out, char *err, size_t err_size) {
    *out = NULL;
    gl_sphere_t *g = calloc(1, sizeof *g);
    if (!g) return fail(err, err_size, "out of memory");
    const int attribs[] = {OSMESA_FORMAT,
                           OSMESA_RGBA,
                           OSMESA_DEPTH_BITS,
                           0,
                           OSMESA_PROFILE,
                           OSMESA_CORE_PROFILE,
                           OSMESA_CONTEXT_MAJOR_VERSION,
                           3,
                           OSMESA_CONTEXT_MINOR_VERSION,
                           3,
                           0};
    g->osm = OSMesaCreateContextAttribs(attribs, NULL);
    if (!g->osm) {
        free(g);
        return fail(err, err_size, "OSMesa: no OpenGL 3.3 core context");
    }
    if (!OSMesaMakeCurrent(g->osm, g->dummy, GL_UNSIGNED_BYTE, 4, 4)) {
        gl_sphere_close(g);
        return fail(err, err_size, "OSMesa: cannot make the context current");
    }
    snprintf(g->renderer, sizeof g->renderer, "OpenGL %s, %s", (const char *)glGetString(GL_VERSION),
             (const char *)glGetString(GL_RENDERER));
    *out = g;
    return 0;
}

void gl_sphere_close(gl_sphere_t *g) {
    if (!g) return;
    if (g->osm) {
        OSMesaMakeCurrent(NULL, NULL, 0, 0, 0); /* releases the context's framebuffer */
        OSMesaDestroyContext(g->osm);
    }
    free(g);
}

const char *gl_sphere_renderer(const gl_sphere_t *g) { return g->renderer; }

/* Full-screen triangle strip from gl_VertexID; no vertex buffers. */
static const char *const vertex_src =
    "#version 330 core\n"
    "const vec2 corner[4] = vec2[4](vec2(-1.0, -1.0), vec2(1.0, -1.0), vec2(-1.0, 1.0), vec2(1.0, 1.0));\n"
    "void main() { gl_Position = vec4(corner[gl_VertexID], 0.0, 1.0); }\n";

/* render.h's scene: pixel centre p (gl_FragCoord counts rows from the bottom,
 * so p.y is up as on the CPU), n on the unit sphere, t = normalize(dP/dphi)
 * for the pole on +y, b = n x t, V = (0, 0, 1) in the frame. */
static const char *const fragment_main =
    "uniform float u_size;\n"
    "uniform float u_extent;\n"
    "uniform int u_nlights;\n"
    "uniform vec3 u_ldir[8];\n"
    "uniform float u_lirr[8];\n"
    "out vec4 frag;\n"
    "void main() {\n"
    "    vec2 p = (2.0 * gl_FragCoord.xy / u_size - 1.0) * u_extent;\n"
    "    float r2 = dot(p, p);\n"
    "    if (!(r2 < 1.0)) { frag = vec4(0.0); return; }\n"
    "    vec3 n = vec3(p, sqrt(1.0 - r2));\n"
    "    vec3 t = normalize(vec3(n.z, 0.0, -n.x));\n"
    "    vec3 b = cross(n, t);\n"
    "    vec3 V = vec3(t.z, b.z, n.z);\n"
    "    vec3 sum = vec3(0.0);\n"
    "    for (int i = 0; i < u_nlights; i++) {\n"
    "        vec3 L = vec3(dot(u_ldir[i], t), dot(u_ldir[i], b), dot(u_ldir[i], n));\n"
    "        if (L.z > 0.0) sum += sb_brdf(L, V) * u_lirr[i] * L.z;\n"
    "    }\n"
    "    frag = vec4(sum, 1.0);\n"
    "}\n";

static GLuint compile(GLenum type, const char *const *parts, int count, char *err, size_t err_size) {
    GLuint s = glCreateShader(type);
    glShaderSource(s, count, parts, NULL);
    glCompileShader(s);
    GLint ok = 0;
    glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        char log[2048] = "";
        glGetShaderInfoLog(s, sizeof log, NULL, log);
        fail(err, err_size, "%s shader: %s", type == GL_VERTEX_SHADER ? "vertex" : "fragment", log);
        glDeleteShader(s);
        return 0;
    }
    return s;
}

static GLuint program(const char *snippet, const char *main_src, char *err, size_t err_size) {
    const char *vs[1] = {vertex_src}, *fs[4] = {"#version 330 core\n", snippet, "\n", main_src};
    GLuint v = compile(GL_VERTEX_SHADER, vs, 1, err, err_size);
    if (!v) return 0;
    GLuint f = compile(GL_FRAGMENT_SHADER, fs, 4, err, err_size);
    if (!f) {
        glDeleteShader(v);
        return 0;
    }
    GLuint p = glCreateProgram();
    glAttachShader(p, v);
    glAttachShader(p, f);
    glLinkProgram(p);
    glDeleteShader(v);
    glDeleteShader(f);
    GLint ok = 0;
    glGetProgramiv(p, GL_LINK_STATUS, &ok);
    if (!ok) {
        char log[2048] = "";
        glGetProgramInfoLog(p, sizeof log, NULL, log);
        fail(err, err_size, "link: %s", log);
        glDeleteProgram(p);
        return 0;
    }
    return p;
}

/* One side's terms as the layers of an RGB32F array texture: texel (x, y)
 * of layer j is texel (x, y) of term j (row y of the texture is GL row y,
 * t = (y + 0.5) / h, as in param.h).  A single-channel factorisation is
 * replicated into R, G and B. */
static int upload(const sb_factors_t *f, const sb_param_t *p, int side, GLuint tex, char *err, size_t err_size) {
    size_t w, h, J = sb_factors_terms(f), C = sb_factors_channels(f);
    sb_factors_size(f, side, &w, &h);
    float *data = malloc(w * h * J * 3 * sizeof *data);
    if (!data) return fail(err, err_size, "out of memory");
    for (size_t j = 0; j < J; j++)
        for (size_t c = 0; c < 3; c++) {
            const double *t = sb_factors_tex_const(f, side, j, C == 1 ? 0 : c);
            for (size_t i = 0; i < w * h; i++)
                data[(j * w * h + i) * 3 + c] = (float)t[i];
        }
    int wrap[2];
    sb_param_wrap(p, side, wrap);
    glBindTexture(GL_TEXTURE_2D_ARRAY, tex);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTexImage3D(GL_TEXTURE_2D_ARRAY, 0, GL_RGB32F, (GLsizei)w, (GLsizei)h, (GLsizei)J, 0, GL_RGB, GL_FLOAT, data);
    free(data);
    glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_BASE_LEVEL, 0);
    glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MAX_LEVEL, 0);
    glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_WRAP_S, wrap[0] == SB_WRAP_REPEAT ? GL_REPEAT : GL_CLAMP_TO_EDGE);
    glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_WRAP_T, wrap[1] == SB_WRAP_REPEAT ? GL_REPEAT : GL_CLAMP_TO_EDGE);
    GLenum e = glGetError();
    return e == GL_NO_ERROR ? 0 : fail(err, err_size, "texture upload: GL error 0x%x", e);
}

/* An RGBA32F S x S texture as the bound framebuffer's colour. */
static int float_target(GLsizei S, GLuint *target, GLuint *fbo, char *err, size_t err_size) {
    glGenTextures(1, target);
    glBindTexture(GL_TEXTURE_2D, *target);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, S, S, 0, GL_RGBA, GL_FLOAT, NULL);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glGenFramebuffers(1, fbo);
    glBindFramebuffer(GL_FRAMEBUFFER, *fbo);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, *target, 0);
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
        return fail(err, err_size, "RGBA32F framebuffer incomplete");
    return 0;
}

/* Unbind and delete what a draw made (0 names are skipped). */
static void release(GLuint prog, GLuint vao, GLuint fbo, GLuint target, const GLuint *tex, GLsizei ntex) {
    glBindVertexArray(0);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    glUseProgram(0);
    if (vao) glDeleteVertexArrays(1, &vao);
    if (fbo) glDeleteFramebuffers(1, &fbo);
    if (target) glDeleteTextures(1, &target);
    glDeleteTextures(ntex, tex);
    glDeleteProgram(prog);
}

int gl_sphere_render(gl_sphere_t *g, const char *snippet, const sb_factors_t *f, const sb_param_t *p,
                     const sb_render_opts_t *opts, sb_image_t *out, char *err, size_t err_size) {
    memset(out, 0, sizeof *out);
    if (!OSMesaMakeCurrent(g->osm, g->dummy, GL_UNSIGNED_BYTE, 4, 4)) return fail(err, err_size, "OSMesa: not current");
    /* The scene with render.h's defaults resolved, lights normalised in double */
    sb_render_opts_t o = {0};
    if (opts) o = *opts;
    if (o.size == 0) o.size = 256;
    if (o.light_count == 0) {
        sb_light_from_angles(45, 45, 0, &o.lights[0]);
        o.light_count = 1;
    }
    if (o.light_count > 8) return fail(err, err_size, "at most 8 lights");
    GLfloat ldir[8][3], lirr[8];
    for (size_t i = 0; i < o.light_count; i++) {
        const double *d = o.lights[i].dir;
        double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        if (!(len > 0)) return fail(err, err_size, "light %zu has no direction", i + 1);
        for (int k = 0; k < 3; k++)
            ldir[i][k] = (GLfloat)(d[k] / len);
        lirr[i] = (GLfloat)(o.lights[i].irradiance > 0 ? o.lights[i].irradiance : SB_PI);
    }

    GLuint prog = program(snippet, fragment_main, err, err_size);
    if (!prog) return -1;

    int rc = -1;
    GLuint tex[2] = {0, 0}, target = 0, fbo = 0, vao = 0;
    float *pix = NULL;
    glGenTextures(2, tex);
    if (upload(f, p, SB_SIDE_G, tex[0], err, err_size) || upload(f, p, SB_SIDE_H, tex[1], err, err_size)) goto out;

    /* Float render target: linear radiance, not limited to 8 bits or [0, 1] */
    GLsizei S = (GLsizei)o.size;
    if (float_target(S, &target, &fbo, err, err_size)) goto out;

    /* Draw */
    glViewport(0, 0, S, S);
    glDisable(GL_DEPTH_TEST);
    glDisable(GL_BLEND);
    glClearColor(0, 0, 0, 0);
    glClear(GL_COLOR_BUFFER_BIT);
    glUseProgram(prog);
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_2D_ARRAY, tex[0]);
    glActiveTexture(GL_TEXTURE1);
    glBindTexture(GL_TEXTURE_2D_ARRAY, tex[1]);
    glUniform1i(glGetUniformLocation(prog, "sb_g"), 0);
    glUniform1i(glGetUniformLocation(prog, "sb_h"), 1);
    glUniform1f(glGetUniformLocation(prog, "u_size"), (GLfloat)S);
    glUniform1f(glGetUniformLocation(prog, "u_extent"), (GLfloat)SB_RENDER_EXTENT);
    glUniform1i(glGetUniformLocation(prog, "u_nlights"), (GLint)o.light_count);
    glUniform3fv(glGetUniformLocation(prog, "u_ldir"), (GLsizei)o.light_count, &ldir[0][0]);
    glUniform1fv(glGetUniformLocation(prog, "u_lirr"), (GLsizei)o.light_count, lirr);
    glGenVertexArrays(1, &vao); /* core profile: a VAO must be bound, even empty */
    glBindVertexArray(vao);
    glDrawArrays(GL_TRIANGLE_STRIP, 0, 4);

    /* Read back, rows flipped: GL row 0 is the bottom, image row 0 the top */
    pix = malloc((size_t)S * (size_t)S * 4 * sizeof *pix);
    if (!pix) {
        fail(err, err_size, "out of memory");
        goto out;
    }
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadPixels(0, 0, S, S, GL_RGBA, GL_FLOAT, pix);
    GLenum e = glGetError();
    if (e != GL_NO_ERROR) {
        fail(err, err_size, "GL error 0x%x", e);
        goto out;
    }
    if (sb_image_alloc(NULL, o.size, o.size, out) != SB_OK) {
        fail(err, err_size, "out of memory");
        goto out;
    }
    for (size_t y = 0; y < o.size; y++)
        for (size_t x = 0; x < o.size; x++) {
            const float *q = pix + ((o.size - 1 - y) * o.size + x) * 4;
            size_t i = y * o.size + x;
            for (int c = 0; c < 3; c++)
                out->rgb[3 * i + (size_t)c] = q[c];
            out->mask[i] = q[3] > 0.5f;
        }
    rc = 0;
out:
    free(pix);
    release(prog, vao, fbo, target, tex, 2);
    return rc;
}

/* ---- the sampler (sepbrdf/sampler.h) ------------------------------------ */

/* Pixel (x, y) draws with u = ((x + 1/2) / n, (y + 1/2) / n). */
static const char *const sample_main = "uniform vec3 u_V;\n"
                                       "uniform float u_n;\n"
                                       "out vec4 frag;\n"
                                       "void main() {\n"
                                       "    vec3 L;\n"
                                       "    float pdf;\n"
                                       "    bool ok = sb_sample(u_V, gl_FragCoord.xy / u_n, L, pdf);\n"
                                       "    frag = ok ? vec4(L, pdf) : vec4(0.0, 0.0, 0.0, -1.0);\n"
                                       "}\n";

/* Pixel (x, y) evaluates sb_pdf at L = texel (x, y) of u_L. */
static const char *const pdf_main = "uniform vec3 u_V;\n"
                                    "uniform highp sampler2D u_L;\n"
                                    "out vec4 frag;\n"
                                    "void main() {\n"
                                    "    vec3 L = texelFetch(u_L, ivec2(gl_FragCoord.xy), 0).xyz;\n"
                                    "    frag = vec4(sb_pdf(L, u_V), 0.0, 0.0, 1.0);\n"
                                    "}\n";

/* main_src over n x n pixels with the factors, the tables and V (and L:
 * n x n RGB32F directions as u_L, NULL: none). */
static int sampler_pass(gl_sphere_t *g, const char *snippet, const char *main_src, const sb_factors_t *f,
                        const sb_param_t *p, const gl_sampler_table_t *t, const double V[3], const float *L, size_t n,
                        float *out, char *err, size_t err_size) {
    if (!OSMesaMakeCurrent(g->osm, g->dummy, GL_UNSIGNED_BYTE, 4, 4)) return fail(err, err_size, "OSMesa: not current");
    GLuint prog = program(snippet, main_src, err, err_size);
    if (!prog) return -1;
    int rc = -1;
    GLuint tex[5] = {0, 0, 0, 0, 0}, target = 0, fbo = 0, vao = 0;
    glGenTextures(5, tex);
    if (upload(f, p, SB_SIDE_G, tex[0], err, err_size) || upload(f, p, SB_SIDE_H, tex[1], err, err_size)) goto out;
    glBindTexture(GL_TEXTURE_2D_ARRAY, tex[2]);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTexImage3D(GL_TEXTURE_2D_ARRAY, 0, GL_R32F, (GLsizei)t->width, (GLsizei)t->height, (GLsizei)t->layers, 0, GL_RED,
                 GL_FLOAT, t->data);
    glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MAX_LEVEL, 0);
    if (L) {
        glBindTexture(GL_TEXTURE_2D, tex[3]);
        glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB32F, (GLsizei)n, (GLsizei)n, 0, GL_RGB, GL_FLOAT, L);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    }
    size_t vw = 0, vh = 0;
    float *vt = NULL; /* a layout on a source's tables (vndf): vndf.exr's texture, sb_vndf */
    if (sb_param_tables(p) && sb_param_tables_texture(p, &vw, &vh, &vt) == SB_OK) {
        glBindTexture(GL_TEXTURE_2D, tex[4]);
        glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB32F, (GLsizei)vw, (GLsizei)vh, 0, GL_RGB, GL_FLOAT, vt);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
        free(vt);
    }
    if (float_target((GLsizei)n, &target, &fbo, err, err_size)) goto out;
    glViewport(0, 0, (GLsizei)n, (GLsizei)n);
    glDisable(GL_DEPTH_TEST);
    glDisable(GL_BLEND);
    glUseProgram(prog);
    if (vw) {
        glActiveTexture(GL_TEXTURE4);
        glBindTexture(GL_TEXTURE_2D, tex[4]);
        glUniform1i(glGetUniformLocation(prog, "sb_vndf"), 4);
    }
    static const char *const names[3] = {"sb_g", "sb_h", "sb_cdf"};
    for (int i = 0; i < 3; i++) {
        glActiveTexture(GL_TEXTURE0 + (GLenum)i);
        glBindTexture(GL_TEXTURE_2D_ARRAY, tex[i]);
        glUniform1i(glGetUniformLocation(prog, names[i]), i);
    }
    if (L) {
        glActiveTexture(GL_TEXTURE3);
        glBindTexture(GL_TEXTURE_2D, tex[3]);
        glUniform1i(glGetUniformLocation(prog, "u_L"), 3);
    }
    glUniform3f(glGetUniformLocation(prog, "u_V"), (GLfloat)V[0], (GLfloat)V[1], (GLfloat)V[2]);
    if (!L) glUniform1f(glGetUniformLocation(prog, "u_n"), (GLfloat)n);
    glGenVertexArrays(1, &vao);
    glBindVertexArray(vao);
    glDrawArrays(GL_TRIANGLE_STRIP, 0, 4);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadPixels(0, 0, (GLsizei)n, (GLsizei)n, GL_RGBA, GL_FLOAT, out);
    GLenum e = glGetError();
    rc = e == GL_NO_ERROR ? 0 : fail(err, err_size, "GL error 0x%x", e);
out:
    release(prog, vao, fbo, target, tex, 5);
    return rc;
}

int gl_sample_grid(gl_sphere_t *g, const char *snippet, const sb_factors_t *f, const sb_param_t *p,
                   const gl_sampler_table_t *t, const double V[3], size_t n, float *out, char *err, size_t err_size) {
    return sampler_pass(g, snippet, sample_main, f, p, t, V, NULL, n, out, err, err_size);
}

int gl_pdf_grid(gl_sphere_t *g, const char *snippet, const sb_factors_t *f, const sb_param_t *p,
                const gl_sampler_table_t *t, const double V[3], const float *L, size_t n, float *out, char *err,
                size_t err_size) {
    return sampler_pass(g, snippet, pdf_main, f, p, t, V, L, n, out, err, err_size);
}
