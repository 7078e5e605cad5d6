/* The snippet in HLSL and the Metal Shading Language (glsl.h,
 * sb_shader_translate): the rewrite rules on small texts, every layout,
 * warp, form and the sampler block compiled by glslangValidator's HLSL
 * front end to SPIR-V, and the CLI's --shader files.  (Executed against
 * the CPU: tests/test_glsl.c, hlsl_matches_cpu.) */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"

static int have_validator(void) { return sb_run("command -v glslangValidator", NULL, 0) == 0; }

static char *tr(const char *glsl, const char *lang) { return sb_shader_translate(glsl, lang); }

SB_TEST(registry) {
    CHECK(sb_shader_lang_count() == 4);
    CHECK(strcmp(sb_shader_lang_name(3), "wgsl") == 0 && strcmp(sb_shader_lang_ext(3), "wgsl") == 0);
    CHECK(strcmp(sb_shader_lang_name(1), "hlsl") == 0 && strcmp(sb_shader_lang_ext(1), "hlsl") == 0);
    CHECK(strcmp(sb_shader_lang_name(2), "msl") == 0 && strcmp(sb_shader_lang_ext(2), "metal") == 0);
    CHECK(strcmp(sb_shader_lang_name(4), "?") == 0 && strcmp(sb_shader_lang_ext(99), "?") == 0);
    CHECK(sb_shader_lang_find("msl") == 2 && sb_shader_lang_find("cg") == -1 && sb_shader_lang_find(NULL) == -1);
    unsigned m = 0;
    CHECK(sb_shader_lang_list(NULL, NULL, &m) == SB_OK && m == 1);
    CHECK(sb_shader_lang_list(NULL, "hlsl", &m) == SB_OK && m == 3);
    CHECK(sb_shader_lang_list(NULL, "msl,glsl", &m) == SB_OK && m == 5);
    CHECK(sb_shader_lang_list(NULL, "all", &m) == SB_OK && m == 15);
    sb_context_t *ctx = NULL;
    CHECK(sb_context_create(&ctx) == SB_OK);
    CHECK(sb_shader_lang_list(ctx, "hlsl,spirv", &m) == SB_ERR_UNKNOWN);
    CHECK(strstr(sb_context_last_error(ctx), "'spirv'") != NULL);
    CHECK(sb_shader_lang_list(ctx, "hlslx", NULL) == SB_ERR_UNKNOWN);
    sb_context_destroy(ctx);
    CHECK(tr("x", "cg") == NULL && tr(NULL, "hlsl") == NULL);
    char *g = tr("vec3 f(vec3 a) { return a; }\n", "glsl");
    CHECK(g && strcmp(g, "vec3 f(vec3 a) { return a; }\n") == 0);
    free(g);
}

/* Each rule of shader.c on a line that needs it. */
SB_TEST(rules) {
    static const struct {
        const char *lang, *glsl, *want;
    } cases[] = {
        {"hlsl", "vec3 a = vec3(0.0);", "float3 a = ((float3)(0.0));"},
        {"msl", "vec3 a = vec3(0.0);", "float3 a = float3(0.0f);"},
        {"hlsl", "vec4 b = vec4(vec2(x), y, 1.0);", "float4 b = float4(((float2)(x)), y, 1.0);"},
        {"hlsl", "ivec2 c = ivec2(floor(st * vec2(n)));", "int2 c = ((int2)(floor(st * ((float2)(n)))));"},
        {"hlsl", "float p = atan(w.y, w.x) + atan(t);", "float p = atan2(w.y, w.x) + atan(t);"},
        {"hlsl", "float m = mix(a, b, fract(t)) * inversesqrt(d);", "float m = lerp(a, b, frac(t)) * rsqrt(d);"},
        {"msl", "float m = mix(a, b, fract(t)) * inversesqrt(d);", "float m = mix(a, b, fract(t)) * rsqrt(d);"},
        {"hlsl", "vec3 g = texture(sb_g, vec3(st.xy, float(j))).rgb;",
         "float3 g = sb_texture_sb_g(float3(st.xy, float(j))).rgb;"},
        {"hlsl", "float c = texelFetch(sb_cdf, ivec3(p, k), 0).r;", "float c = sb_fetch_sb_cdf(int3(p, k), 0).r;"},
        {"hlsl", "int n = textureSize(sb_cdf, 0).z - 1;", "int n = sb_size_sb_cdf(0).z - 1;"},
        {"msl", "bool f(vec3 V, out vec3 D, inout float u) {", "bool f(float3 V, thread float3& D, thread float& u) {"},
        {"msl", "float e = 1e-30 + 2.5e+3 + 0.5 + 7;", "float e = 1e-30f + 2.5e+3f + 0.5f + 7;"},
        {"hlsl", "x = vec2(1.0); // atan(y, x) stays as written",
         "x = ((float2)(1.0)); // atan(y, x) stays as written"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char *s = tr(cases[i].glsl, cases[i].lang);
        CHECKF(s != NULL, "%s", cases[i].glsl);
        if (!s) continue;
        CHECKF(strstr(s, cases[i].want) != NULL, "%s: %s\n  gives\n%s", cases[i].lang, cases[i].glsl, s);
        free(s);
    }
    /* global constants: brace initialisers, static const / constant */
    char *h = tr("const float k[2] = float[2](1.0, 2.0);\nconst float one = 1.0;\n", "hlsl");
    CHECK(h && strstr(h, "static const float k[2] = {1.0, 2.0};") && strstr(h, "static const float one = 1.0;"));
    free(h);
    char *m = tr("#define N 2\nconst float k[N] = float[N](1.0, 2.0);\nfloat f() { return k[0]; }\n", "msl");
    CHECK(m && strstr(m, "constant float k[N] = {1.0f, 2.0f};") && strstr(m, "struct sb_shader {"));
    CHECK(m && strstr(m, "#define N 2") < strstr(m, "constant float k") && /* before the struct */
          strstr(m, "constant float k") < strstr(m, "struct sb_shader {") &&
          strstr(m, "float f()") > strstr(m, "struct sb_shader {"));
    free(m);
    /* textures: declarations and helpers; the GL_ES precision block goes */
    h = tr("#ifdef GL_ES\nprecision highp float;\n#endif\nuniform sampler2DArray sb_g;\n", "hlsl");
    CHECK(h && !strstr(h, "precision") && strstr(h, "Texture2DArray<float4> sb_g : register(t0);") &&
          strstr(h, "SamplerState sb_g_sampler : register(s0);") && strstr(h, "float4 sb_texture_sb_g(float3 c)"));
    free(h);
    m = tr("uniform sampler2DArray sb_g;\nuniform sampler2DArray sb_h;\n", "msl");
    CHECK(m &&
          strstr(m, "    texture2d_array<float> sb_g;\n    sampler sb_g_sampler;\n    texture2d_array<float> sb_h;"));
    free(m);
}

/* One layout, form and sampler choice as the library writes it, in
 * `lang`; glsl: the snippet alone.  NULL on failure. */
static char *shader_text(const sb_param_t *p, sb_form_t form, int sampled, const char *lang) {
    double scales[3] = {1, 0.5, 2};
    char *head = sb_glsl_snippet(p, form, 3, form == SB_FORM_COS ? scales : NULL);
    char *tail = sampled ? sb_glsl_sampler(p, sampled) : NULL;
    size_t n = (head ? strlen(head) : 0) + (tail ? strlen(tail) : 0) + 1;
    char *glsl = head && (tail || !sampled) ? malloc(n) : NULL;
    if (glsl) snprintf(glsl, n, "%s%s", head, tail ? tail : "");
    char *out = glsl ? tr(glsl, lang) : NULL;
    free(head);
    free(tail);
    free(glsl);
    return out;
}

/* The layouts: each kind at R = 12, theta_max limited on hd, and iso and hd
 * with warp tables in their specs. */
static const char *const specs[] = {"io:res=12",
                                    "io-area:res=12",
                                    "hd:res=12,theta_max=1.2",
                                    "iso:th=12,td=12,pd=6",
                                    "iso:th=12,td=12,pd=6,warp_h=0.05/0.2/0.5,warp_d=0.3/0.6",
                                    "hd:res=12,warp_h=merl,warp_d=0.1/0.4/0.7"};
#define NSPECS (sizeof specs / sizeof specs[0])

static sb_param_t *param_of(const char *spec) {
    sb_param_kind_t k;
    sb_param_opts_t o;
    sb_param_t *p = NULL;
    if (sb_param_parse_spec(NULL, spec, &k, &o) != SB_OK || sb_param_create(NULL, k, &o, &p) != SB_OK) return NULL;
    return p;
}

/* A check of one translated text: 0 when it passes, else a message in log. */
typedef int (*check_fn)(void *user, const char *text, int sampled, char *log, size_t logsz);

/* Every layout of specs with every form and, for form f, the sampler block
 * for 1 and 3 channels (form cos and cos2 with 3), in `lang`, through check. */
static void each_variant(const char *lang, check_fn check, void *user) {
    for (size_t i = 0; i < NSPECS; i++) {
        sb_param_t *p = param_of(specs[i]);
        CHECKF(p != NULL, "%s", specs[i]);
        for (int form = 0; p && form < SB_FORM_COUNT_; form++)
            for (int sampled = 0; sampled <= 3; sampled += form == SB_FORM_F ? 1 : 3) {
                if (sampled == 2) continue;
                char *s = shader_text(p, (sb_form_t)form, sampled, lang), log[8192] = "";
                CHECK(s != NULL);
                int rc = s ? check(user, s, sampled, log, sizeof log) : 0;
                CHECKF(rc == 0, "%s of %s, form %d, sampler %d:\n%s", lang, specs[i], form, sampled, log);
                free(s);
            }
        sb_param_destroy(p);
    }
}

/* A pixel shader around the snippet: sb_brdf, and with the sampler block
 * sb_sample and sb_pdf, so that every function is compiled. */
static const char hlsl_main[] = "float4 main(float3 L : TEXCOORD0, float3 V : TEXCOORD1) : SV_Target {\n"
                                "    float3 f = sb_brdf(normalize(L), normalize(V));\n"
                                "#ifdef SB_SAMPLE_CH\n"
                                "    float3 Ls;\n    float pdf;\n"
                                "    if (sb_sample(normalize(V), L.xy, Ls, pdf)) f += Ls * pdf + sb_pdf(Ls, V);\n"
                                "#endif\n"
                                "    return float4(f, 1.0);\n}\n";

/* Write text and then tail into DIR/NAME and run cmd on it; 0 on success,
 * the tool's output in log. */
static int write_and_run(const char *dir, const char *name, const char *text, const char *tail, const char *cmd,
                         char *log, size_t logsz) {
    char path[512];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *fp = fopen(path, "w");
    if (!fp) return -1;
    fprintf(fp, "%s\n%s", text, tail);
    fclose(fp);
    return sb_run(cmd, log, logsz);
}

static int compile_hlsl(const char *text, const char *dir, char *log, size_t logsz) {
    char cmd[1200];
    /* -D: the HLSL front end; -V: on to SPIR-V, so that every function is
     * type-checked and lowered, not only parsed */
    snprintf(cmd, sizeof cmd, "glslangValidator -D -V -S frag -e main -o %s/test.spv %s/test.hlsl", dir, dir);
    return write_and_run(dir, "test.hlsl", text, hlsl_main, cmd, log, logsz);
}

static int check_hlsl(void *dir, const char *text, int sampled, char *log, size_t logsz) {
    if (!strstr(text, "float3 sb_brdf(float3 L, float3 V)") ||
        (sampled && !strstr(text, "bool sb_sample(float3 V, float2 u, out float3 L, out float pdf)")))
        return snprintf(log, logsz, "sb_brdf or sb_sample missing"), -1;
    return compile_hlsl(text, dir, log, logsz);
}

SB_TEST(hlsl_compiles) {
    if (!have_validator()) SKIP("glslangValidator not installed (Debian package glslang-tools)");
    each_variant("hlsl", check_hlsl, (void *)sb_tmpdir("shader"));
}

/* The check is real: GLSL that was not translated, or a snippet missing
 * its coordinate function, fails the HLSL front end. */
SB_TEST(hlsl_broken_fails) {
    if (!have_validator()) SKIP("glslangValidator not installed (Debian package glslang-tools)");
    const char *dir = sb_tmpdir("shader");
    sb_param_t *p = param_of("iso:th=12,td=12,pd=6");
    CHECK(p != NULL);
    char log[8192], *glsl = sb_glsl_snippet(p, SB_FORM_F, 2, NULL), *hlsl = tr(glsl, "hlsl");
    CHECK(compile_hlsl(hlsl, dir, log, sizeof log) == 0);
    CHECK(compile_hlsl(glsl, dir, log, sizeof log) != 0);
    char *cut = strstr(hlsl, "float4 sb_coords(");
    CHECK(cut != NULL);
    if (cut) memcpy(cut, "float4 sb_cords(", 16);
    CHECK(compile_hlsl(hlsl, dir, log, sizeof log) != 0);
    free(glsl);
    free(hlsl);
    sb_param_destroy(p);
}

/* `sepbrdf factor --shader all` writes the four files into the set (and
 * its list); an unknown language is a usage error naming it. */
SB_TEST(cli_shader_option) {
    const char *dir = sb_tmpdir("shader_cli");
    char cmd[1024], out[4096];
    snprintf(cmd, sizeof cmd, "%s factor lambert --param io -r 8 -J 1 --method nmf --shader all -q -o %s/set", SB_CLI,
             dir);
    CHECK(sb_run(cmd, out, sizeof out) == 0);
    static const char *const names[] = {"sepbrdf.glsl", "sepbrdf.hlsl", "sepbrdf.metal", "sepbrdf.wgsl"};
    for (int i = 0; i < 4; i++) {
        char path[600];
        snprintf(path, sizeof path, "%s/set/%s", dir, names[i]);
        CHECKF(sb_file_exists(path), "%s missing", names[i]);
    }
    snprintf(cmd, sizeof cmd, "grep -c 'sb_sample' %s/set/sepbrdf.hlsl %s/set/sepbrdf.metal", dir, dir);
    CHECK(sb_run(cmd, out, sizeof out) == 0); /* the sampler block too */
    snprintf(cmd, sizeof cmd, "grep -qx sepbrdf.metal %s/set/sepbrdf-set-factor.txt", dir);
    CHECK(sb_run(cmd, out, sizeof out) == 0);
    snprintf(cmd, sizeof cmd, "%s factor lambert --shader hlsl,spirv -o %s/bad 2>&1", SB_CLI, dir);
    CHECK(sb_run(cmd, out, sizeof out) == 1);
    CHECKF(strstr(out, "--shader 'hlsl,spirv': shader language 'spirv' unknown") != NULL, "%s", out);
}

/* ---- MSL: no Metal compiler on Linux; a C++ front end (clang++) against
 * a model of <metal_stdlib> (tests/data/metal/metal_stdlib: vector types
 * with swizzles, Metal's constructors, math, texture2d_array): names,
 * arities, vector sizes and members are checked. ---- */

static const char msl_use[] =
    "float4 sb_test(texture2d_array<float> g, sampler gs, texture2d_array<float> h, sampler hs, float3 L, float3 V) {\n"
    "    sb_shader s = {g, gs, h, hs};\n    return float4(s.sb_brdf(normalize(L), normalize(V)), 1.0f);\n}\n";
static const char msl_use_sampled[] =
    "float4 sb_test(texture2d_array<float> g, sampler gs, texture2d_array<float> h, sampler hs,\n"
    "               texture2d_array<float> c, sampler cs, float3 L, float3 V) {\n"
    "    sb_shader s = {g, gs, h, hs, c, cs};\n    float3 Ls;\n    float pdf;\n"
    "    float3 f = s.sb_brdf(normalize(L), normalize(V));\n"
    "    if (s.sb_sample(normalize(V), L.xy, Ls, pdf)) f += Ls * pdf + s.sb_pdf(Ls, V);\n"
    "    return float4(f, 1.0f);\n}\n";

static int check_msl(const char *text, const char *use, const char *dir, char *log, size_t logsz) {
    char cmd[1400];
    snprintf(cmd, sizeof cmd, "clang++ -std=c++14 -fsyntax-only -I %s/tests/data/metal -x c++ %s/test.metal",
             SB_SOURCE_DIR, dir);
    return write_and_run(dir, "test.metal", text, use, cmd, log, logsz);
}

static int check_msl_variant(void *dir, const char *text, int sampled, char *log, size_t logsz) {
    return check_msl(text, sampled ? msl_use_sampled : msl_use, dir, log, logsz);
}

SB_TEST(msl_parses) {
    if (sb_run("command -v clang++", NULL, 0) != 0) SKIP("no clang++ (Debian: clang): MSL not checked");
    const char *dir = sb_tmpdir("shader_msl");
    each_variant("msl", check_msl_variant, (void *)dir);
    /* the check is real: GLSL fails, and so does a vector size mixed up */
    sb_param_t *p = param_of(specs[3]);
    char *glsl = shader_text(p, SB_FORM_F, 0, "glsl"), *msl = shader_text(p, SB_FORM_F, 0, "msl"), log[8192];
    CHECK(glsl && msl && check_msl(glsl, msl_use, dir, log, sizeof log) != 0);
    char *at = msl ? strstr(msl, "float4 st = sb_coords(L, V);") : NULL;
    CHECK(at != NULL);
    if (at) memcpy(at, "float3", 6);
    CHECK(msl && check_msl(msl, msl_use, dir, log, sizeof log) != 0);
    free(glsl);
    free(msl);
    sb_param_destroy(p);
}

/* ---- WGSL through a real front end: Tint, in headless Chromium's WebGPU
 * (SwiftShader): every module's getCompilationInfo() errors. ---- */

static const char wgsl_main[] =
    "@fragment fn main(@location(0) L: vec3f, @location(1) V: vec3f) -> @location(0) vec4f {\n"
    "    var f = sb_brdf(normalize(L), normalize(V));\n"
    "    return vec4f(f, 1.0);\n}\n";
static const char wgsl_main_sampled[] =
    "@fragment fn main(@location(0) L: vec3f, @location(1) V: vec3f) -> @location(0) vec4f {\n"
    "    var f = sb_brdf(normalize(L), normalize(V));\n    var Ls: vec3f;\n    var pdf: f32;\n"
    "    if (sb_sample(normalize(V), L.xy, &Ls, &pdf)) { f += Ls * pdf + sb_pdf(Ls, V); }\n"
    "    return vec4f(f, 1.0);\n}\n";

/* A JS string literal of s. */
static void js_string(FILE *fp, const char *s) {
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

/* Run dir/wgsl.html (written by the caller, its script ending with
 * console.log('SB-WGSL-DONE')) in headless Chromium's WebGPU; its
 * "SB-WGSL..." console lines into log.  0 when the page ran, 77 when there
 * is no browser or no WebGPU adapter (the page logs SB-WGSL-NOADAPTER). */
static int chromium_page(const char *dir, char *log, size_t logsz) {
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

/* dir/wgsl.html, open for writing (NULL on failure). */
static FILE *page_file(const char *dir) {
    char path[512];
    snprintf(path, sizeof path, "%s/wgsl.html", dir);
    return fopen(path, "w");
}

/* Compile the n modules with Chromium's WebGPU: one console line
 * "SB-WGSL k ERRORS MESSAGES" per module (chromium_page). */
static int chromium_wgsl(char *const *mods, int n, const char *dir, char *log, size_t logsz) {
    FILE *fp = page_file(dir);
    if (!fp) return -1;
    fputs("<html><body><script>\nconst mods = [", fp);
    for (int i = 0; i < n; i++) {
        if (i) fputs(",\n", fp);
        js_string(fp, mods[i]);
    }
    fputs("];\n(async () => {\n  const a = navigator.gpu && await navigator.gpu.requestAdapter();\n"
          "  if (!a) { console.log('SB-WGSL-NOADAPTER'); return; }\n  const d = await a.requestDevice();\n"
          "  for (let i = 0; i < mods.length; i++) {\n"
          "    const info = await d.createShaderModule({code: mods[i]}).getCompilationInfo();\n"
          "    const e = info.messages.filter(m => m.type == 'error');\n"
          "    console.log('SB-WGSL ' + i + ' ' + e.length + ' ' + e.map(m => m.lineNum + ':' + m.linePos + ' ' + "
          "m.message).join(' | '));\n"
          "  }\n  console.log('SB-WGSL-DONE');\n})();\n</script></body></html>\n",
          fp);
    fclose(fp);
    return chromium_page(dir, log, logsz);
}

/* Every layout, form and the sampler block in WGSL, compiled by Tint: no
 * error; and the check is real: the untranslated GLSL fails. */
typedef struct modules {
    char *text[NSPECS * 8 + 1];
    int n;
} modules_t;

/* Collect the module with an entry point (compiled all at once, below). */
static int add_wgsl(void *user, const char *text, int sampled, char *log, size_t logsz) {
    modules_t *m = user;
    if (!strstr(text, "fn sb_brdf(L: vec3f, V: vec3f) -> vec3f {")) return snprintf(log, logsz, "no sb_brdf"), -1;
    size_t len = strlen(text) + sizeof wgsl_main_sampled;
    if (!(m->text[m->n] = malloc(len))) return -1;
    snprintf(m->text[m->n++], len, "%s%s", text, sampled ? wgsl_main_sampled : wgsl_main);
    return 0;
}

SB_TEST(wgsl_compiles) {
    const char *dir = sb_tmpdir("shader_wgsl");
    static modules_t m;
    char **mods = m.text;
    each_variant("wgsl", add_wgsl, &m);
    int n = m.n;
    sb_param_t *io = param_of(specs[0]);
    mods[n++] = shader_text(io, SB_FORM_F, 0, "glsl"); /* must fail */
    sb_param_destroy(io);
    static char log[1 << 16];
    int rc = chromium_wgsl(mods, n, dir, log, sizeof log);
    for (int i = 0; i < n; i++)
        free(mods[i]);
    if (rc == 77) SKIP("no chromium with WebGPU (Debian: chromium): WGSL not compiled");
    CHECKF(rc == 0, "chromium did not finish:\n%s", log);
    for (int i = 0; i < n; i++) {
        char want[64];
        snprintf(want, sizeof want, "SB-WGSL %d %s", i, i == n - 1 ? "" : "0 ");
        const char *at = strstr(log, want);
        CHECKF(at != NULL && (i < n - 1 || at[strlen(want)] != '0'), "module %d (%s): %.300s", i,
               i == n - 1 ? "GLSL, must fail" : "WGSL", at ? at : log);
    }
}

/* ---- WGSL executed: a compute shader around the WGSL snippet runs in
 * Chromium's WebGPU (SwiftShader) on random pairs and random factor
 * textures, and its sb_coords / sb_domain / sb_brdf are compared with
 * sb_param_coords / sb_factors_eval, as tests/test_glsl.c does for GLSL
 * and HLSL. ---- */

enum { WN = 256, WJ = 3 };

static const char wgsl_compute[] =
    "@group(1) @binding(0) var<storage, read> sb_pairs: array<vec4f>;\n"
    "@group(1) @binding(1) var<storage, read_write> sb_res: array<vec4f>;\n"
    "@compute @workgroup_size(64) fn main(@builtin(global_invocation_id) id: vec3u) {\n"
    "    let i = id.x;\n"
    "    if (i >= arrayLength(&sb_res) / 2u) { return; }\n"
    "    let L = normalize(sb_pairs[2u * i].xyz);\n    let V = normalize(sb_pairs[2u * i + 1u].xyz);\n"
    "    let st = sb_coords(L, V);\n    sb_res[2u * i] = st;\n"
    "    sb_res[2u * i + 1u] = vec4f(sb_brdf(L, V), select(0.0, 1.0, sb_domain(L, V, st)));\n}\n";

/* The page: every case's textures (rgba32float, linear, wrap as the layout
 * says), pairs and module; one line "SB-WGSL-OUT case pair 8 values" per
 * pair.  Float textures filtered linearly need float32-filterable. */
static const char wgsl_run_js[] =
    "(async () => {\n"
    "  const a = navigator.gpu && await navigator.gpu.requestAdapter();\n"
    "  if (!a || !a.features.has('float32-filterable')) { console.log('SB-WGSL-NOADAPTER'); return; }\n"
    "  const d = await a.requestDevice({requiredFeatures: ['float32-filterable']});\n"
    "  const mode = w => w ? 'repeat' : 'clamp-to-edge';\n"
    "  for (let c = 0; c < cases.length; c++) {\n"
    "    const k = cases[c], entries = [];\n"
    "    for (let s = 0; s < 2; s++) {\n"
    "      const t = d.createTexture({size: [k.w[s], k.h[s], k.J], format: 'rgba32float',\n"
    "                                 usage: GPUTextureUsage.TEXTURE_BINDING | GPUTextureUsage.COPY_DST});\n"
    "      d.queue.writeTexture({texture: t}, new Float32Array(k.tex[s]), {bytesPerRow: 16 * k.w[s], rowsPerImage: "
    "k.h[s]},\n"
    "                           [k.w[s], k.h[s], k.J]);\n"
    "      entries.push({binding: 2 * s, resource: t.createView({dimension: '2d-array'})});\n"
    "      entries.push({binding: 2 * s + 1, resource: d.createSampler({magFilter: 'linear', minFilter: 'linear',\n"
    "                    addressModeU: mode(k.wrap[s][0]), addressModeV: mode(k.wrap[s][1])})});\n"
    "    }\n"
    "    const m = d.createShaderModule({code: k.code});\n"
    "    const p = d.createComputePipeline({layout: 'auto', compute: {module: m, entryPoint: 'main'}});\n"
    "    const n = k.pairs.length / 8, inb = d.createBuffer({size: 32 * n, usage: GPUBufferUsage.STORAGE | "
    "GPUBufferUsage.COPY_DST});\n"
    "    d.queue.writeBuffer(inb, 0, new Float32Array(k.pairs));\n"
    "    const out = d.createBuffer({size: 32 * n, usage: GPUBufferUsage.STORAGE | GPUBufferUsage.COPY_SRC});\n"
    "    const rd = d.createBuffer({size: 32 * n, usage: GPUBufferUsage.MAP_READ | GPUBufferUsage.COPY_DST});\n"
    "    const e = d.createCommandEncoder(), pass = e.beginComputePass();\n"
    "    pass.setPipeline(p);\n"
    "    pass.setBindGroup(0, d.createBindGroup({layout: p.getBindGroupLayout(0), entries}));\n"
    "    pass.setBindGroup(1, d.createBindGroup({layout: p.getBindGroupLayout(1), entries: [\n"
    "      {binding: 0, resource: {buffer: inb}}, {binding: 1, resource: {buffer: out}}]}));\n"
    "    pass.dispatchWorkgroups(Math.ceil(n / 64));\n    pass.end();\n"
    "    e.copyBufferToBuffer(out, 0, rd, 0, 32 * n);\n    d.queue.submit([e.finish()]);\n"
    "    await rd.mapAsync(GPUMapMode.READ);\n    const r = new Float32Array(rd.getMappedRange());\n"
    "    for (let i = 0; i < n; i++) console.log('SB-WGSL-OUT ' + c + ' ' + i + ' ' + "
    "Array.from(r.slice(8 * i, 8 * i + 8)).join(' '));\n"
    "  }\n  console.log('SB-WGSL-DONE');\n})();\n";

/* Case c of the page: p's WGSL with the compute entry, random textures into
 * f (kept for the CPU), random pairs into dir (renormalised as floats). */
static void write_case(FILE *fp, const sb_param_t *p, sb_factors_t *f, double (*dirs)[2][3], unsigned long long *st) {
    char *s = shader_text(p, SB_FORM_F, 0, "wgsl");
    size_t len = (s ? strlen(s) : 0) + sizeof wgsl_compute;
    char *code = malloc(len);
    if (code) snprintf(code, len, "%s%s", s ? s : "", wgsl_compute);
    fputs("cases.push({code: ", fp);
    js_string(fp, code ? code : "");
    free(s);
    free(code);
    size_t tw[2], th[2];
    int wrap[2][2];
    for (int side = 0; side < 2; side++) {
        sb_param_texture_size(p, side, &tw[side], &th[side]);
        sb_param_wrap(p, side, wrap[side]);
    }
    fprintf(fp, ", J: %d, w: [%zu, %zu], h: [%zu, %zu], wrap: [[%d, %d], [%d, %d]], tex: [", WJ, tw[0], tw[1], th[0],
            th[1], wrap[0][0], wrap[0][1], wrap[1][0], wrap[1][1]);
    for (int side = 0; side < 2; side++) { /* layer j, row y, texel x, RGBA */
        fputs(side ? "], [" : "[", fp);
        for (size_t j = 0; j < WJ; j++)
            for (size_t i = 0; i < tw[side] * th[side]; i++)
                for (int c = 0; c < 4; c++) {
                    double v = c < 3 ? (double)(float)sb_rand01(st) : 0;
                    if (c < 3) sb_factors_tex(f, side, j, (size_t)c)[i] = v;
                    fprintf(fp, "%s%.9g", j || i || c ? "," : "", v);
                }
    }
    fputs("]], pairs: [", fp);
    for (int i = 0; i < WN; i++)
        for (int k = 0; k < 2; k++) {
            double *w = dirs[i][k], z = (i % 9 == k) ? 2 * sb_rand01(st) - 1 : 1 - sb_rand01(st);
            double ph = 2 * SB_PI * sb_rand01(st), r = sqrt(1 - z * z), n = 0;
            float v[3] = {(float)(r * cos(ph)), (float)(r * sin(ph)), (float)z};
            for (int a = 0; a < 3; a++)
                n += (double)v[a] * v[a];
            for (int a = 0; a < 3; a++)
                w[a] = v[a] / sqrt(n);
            fprintf(fp, "%s%.9g,%.9g,%.9g,0", i || k ? "," : "", v[0], v[1], v[2]);
        }
    fputs("]});\n", fp);
}

SB_TEST(wgsl_matches_cpu) {
    const char *dir = sb_tmpdir("shader_wgsl_run");
    FILE *fp = page_file(dir);
    CHECK(fp != NULL);
    if (!fp) return;
    static double dirs[NSPECS][WN][2][3];
    sb_param_t *ps[NSPECS];
    sb_factors_t *fs[NSPECS];
    unsigned long long st = 4321;
    fputs("<html><body><script>\nconst cases = [];\n", fp);
    for (size_t c = 0; c < NSPECS; c++) {
        size_t tw[2], th[2];
        ps[c] = param_of(specs[c]);
        fs[c] = NULL;
        for (int side = 0; ps[c] && side < 2; side++)
            sb_param_texture_size(ps[c], side, &tw[side], &th[side]);
        CHECK(ps[c] && sb_factors_create(NULL, WJ, 3, tw[0], th[0], tw[1], th[1], &fs[c]) == SB_OK);
        if (fs[c]) write_case(fp, ps[c], fs[c], dirs[c], &st);
    }
    fprintf(fp, "%s</script></body></html>\n", wgsl_run_js);
    fclose(fp);
    static char log[1 << 22];
    int rc = chromium_page(dir, log, sizeof log);
    if (rc == 77) {
        for (size_t c = 0; c < NSPECS; c++)
            sb_factors_destroy(fs[c]), sb_param_destroy(ps[c]);
        SKIP("no chromium with WebGPU and float32-filterable (Debian: chromium): WGSL not executed");
    }
    CHECKF(rc == 0, "chromium did not finish:\n%.2000s", log);
    /* compare, as test_glsl.c's gl_compare: texels, the domain up to the cap's rim, values */
    double worst_st = 0, worst_f = 0;
    int seen = 0, mismatch = 0, inside = 0;
    for (const char *line = strstr(log, "SB-WGSL-OUT "); line; line = strstr(line + 1, "SB-WGSL-OUT ")) {
        int c, i, used = 0;
        float o[8];
        if (sscanf(line, "SB-WGSL-OUT %d %d %f %f %f %f %f %f %f %f%n", &c, &i, &o[0], &o[1], &o[2], &o[3], &o[4],
                   &o[5], &o[6], &o[7], &used) != 10 ||
            c < 0 || c >= (int)NSPECS || i < 0 || i >= WN || !fs[c])
            continue;
        seen++;
        const sb_param_t *p = ps[c];
        const double *l = dirs[c][i][0], *v = dirs[c][i][1];
        double sg[2], sh[2], rgb[3], tmax = sb_param_theta_max(p);
        int cpu = sb_param_coords(p, l, v, sg, sh), gpu = o[7] > 0.5f;
        if (cpu != gpu) {
            double e = fmin(fmin(fabs(acos(l[2]) - tmax), fabs(acos(v[2]) - tmax)), fmin(fabs(l[2]), fabs(v[2])));
            mismatch += e > 1e-5;
            continue;
        }
        if (!cpu) continue;
        inside++;
        const double cs[4] = {sg[0], sg[1], sh[0], sh[1]};
        for (int a = 0; a < 4; a++) {
            size_t tw, th;
            int wrap[2];
            sb_param_texture_size(p, a / 2, &tw, &th);
            sb_param_wrap(p, a / 2, wrap);
            double d = fabs(cs[a] - o[a]);
            if (wrap[a % 2] == SB_WRAP_REPEAT) d = fmin(d, 1 - d);
            worst_st = fmax(worst_st, d * (double)(a % 2 ? th : tw));
        }
        sb_factors_eval(fs[c], p, SB_FORM_F, WJ, l, v, rgb);
        for (int k = 0; k < 3; k++)
            worst_f = fmax(worst_f, fabs(rgb[k] - o[4 + k]));
    }
    printf("  %d pairs (%d inside): worst |st| %.3g texels, worst |f| %.3g\n", seen, inside, worst_st, worst_f);
    CHECKF(seen == (int)NSPECS * WN, "%d of %d results came back", seen, (int)NSPECS * WN);
    CHECKF(mismatch == 0, "sb_domain differs from the CPU on %d pairs", mismatch);
    CHECKF(inside > seen / 4, "%d pairs inside", inside);
    /* float rounding: SwiftShader filters float32 textures in float32 */
    CHECKF(worst_st < 1e-4, "sb_coords differs by %g texels", worst_st);
    CHECKF(worst_f < 1e-4, "sb_brdf differs by %g", worst_f);
    for (size_t c = 0; c < NSPECS; c++)
        sb_factors_destroy(fs[c]), sb_param_destroy(ps[c]);
}

/* Text the library did not write is answered, never crashed on: every
 * prefix of a snippet with the sampler (cut anywhere: unbalanced
 * parentheses, braces, a directive without its #endif) and random bytes,
 * in every language (under ASan in CI). */
SB_TEST(hostile_input) {
    sb_param_t *p = param_of(specs[4]);
    char *full = shader_text(p, SB_FORM_COS, 3, "glsl");
    CHECK(full != NULL);
    size_t n = full ? strlen(full) : 0;
    char *cut = malloc(n + 1);
    unsigned long long st = 99;
    for (size_t len = 0; cut && len <= n; len += 1 + len / 64) {
        memcpy(cut, full, len);
        cut[len] = 0;
        for (size_t k = 1; k < sb_shader_lang_count(); k++)
            free(sb_shader_translate(cut, sb_shader_lang_name(k)));
    }
    static const char alphabet[] = "(){}[];,?:=#!<>+-*/ \n\tabcvec3float2if else for while out return const uniform";
    for (int t = 0; cut && t < 300; t++) {
        size_t len = (size_t)(sb_rand01(&st) * 200);
        for (size_t i = 0; i < len && i < n; i++)
            cut[i] = alphabet[(size_t)(sb_rand01(&st) * (sizeof alphabet - 1))];
        cut[len < n ? len : n] = 0;
        for (size_t k = 1; k < sb_shader_lang_count(); k++)
            free(sb_shader_translate(cut, sb_shader_lang_name(k)));
    }
    free(cut);
    free(full);
    sb_param_destroy(p);
}
