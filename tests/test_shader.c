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
#include "shader_check.h"

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
    /* an empty item is refused wherever it stands (twelfth outside pass:
     * "hlsl," was taken as hlsl while ",hlsl" and "hlsl,,msl" were refused) */
    CHECK(sb_shader_lang_list(ctx, "hlsl,", &m) == SB_ERR_UNKNOWN && strstr(sb_context_last_error(ctx), "''"));
    CHECK(sb_shader_lang_list(ctx, ",hlsl", &m) == SB_ERR_UNKNOWN);
    CHECK(sb_shader_lang_list(ctx, ",", &m) == SB_ERR_UNKNOWN);
    CHECK(sb_shader_lang_list(NULL, "", &m) == SB_OK && m == 1); /* the whole list empty: GLSL alone */
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

/* A check of one translated text: 0 when it passes, else a message in log. */
typedef int (*check_fn)(void *user, const char *text, int sampled, char *log, size_t logsz);

/* Every layout of specs with every form and, for form f, the sampler block
 * for 1 and 3 channels (form cos and cos2 with 3), in `lang`, through check;
 * then the vndf layout of an RGL file (its tables as the texture sb_vndf;
 * its sampler block samples the columns through the file's warp) and rv
 * (its sampler block about the view's mirror direction; not in sb_specs,
 * whose sb_coords test_wgsl.c compares with the C's to 1e-4 texels, which
 * rv's square root at the mirror direction exceeds). */
#define SB_RV_SPEC "rv:res=12"
static void each_variant(const char *lang, check_fn check, void *user) {
    for (size_t i = 0; i <= SB_NSPECS + 1; i++) {
        sb_param_t *p = i < SB_NSPECS    ? sb_param_of(sb_specs[i])
                        : i == SB_NSPECS ? sb_param_vndf()
                                         : sb_param_of(SB_RV_SPEC);
        CHECKF(p != NULL, "%s", i < SB_NSPECS ? sb_specs[i] : i == SB_NSPECS ? "vndf" : SB_RV_SPEC);
        for (int form = 0; p && form < SB_FORM_COUNT_; form++)
            for (int sampled = 0; sampled <= 3; sampled += form == SB_FORM_F ? 1 : 3) {
                if (sampled == 2) continue;
                char *s = sb_shader_text(p, (sb_form_t)form, sampled, lang), log[8192] = "";
                CHECK(s != NULL);
                int rc = s ? check(user, s, sampled, log, sizeof log) : 0;
                CHECKF(rc == 0, "%s of %s, form %d, sampler %d:\n%s", lang, sb_param_spec(p), form, sampled, log);
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
    sb_param_t *p = sb_param_of("iso:th=12,td=12,pd=6");
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
 * its list) and names them in its last line (it named sepbrdf.glsl
 * alone); an unknown language is a usage error naming it. */
SB_TEST(cli_shader_option) {
    const char *dir = sb_tmpdir("shader_cli");
    char cmd[1024], out[8192];
    snprintf(cmd, sizeof cmd, "%s factor lambert --param io -r 8 -J 1 --method nmf --shader all -o %s/set 2>/dev/null",
             SB_CLI, dir);
    CHECK(sb_run(cmd, out, sizeof out) == 0);
    CHECKF(strstr(out, "report.json and sepbrdf.glsl, sepbrdf.hlsl, sepbrdf.metal, sepbrdf.wgsl to ") != NULL, "%s",
           out);
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
    /* an empty value names no language: refused as --channels '' is (it wrote GLSL alone, exit 0) */
    snprintf(cmd, sizeof cmd, "%s factor lambert --shader '' -o %s/empty 2>&1", SB_CLI, dir);
    CHECKF(sb_run(cmd, out, sizeof out) == 1 && strstr(out, "--shader ''"), "%s", out);
    snprintf(cmd, sizeof cmd, "%s/empty", dir);
    CHECK(!sb_file_exists(cmd));
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

static const char msl_use_vndf[] =
    "float4 sb_test(texture2d_array<float> g, sampler gs, texture2d_array<float> h, sampler hs,\n"
    "               texture2d<float> v, float3 L, float3 V) {\n"
    "    sb_shader s = {g, gs, h, hs, v};\n    return float4(s.sb_brdf(normalize(L), normalize(V)), 1.0f);\n}\n";

static int check_msl(const char *text, const char *use, const char *dir, char *log, size_t logsz) {
    char cmd[1400];
    snprintf(cmd, sizeof cmd, "clang++ -std=c++14 -fsyntax-only -I %s/tests/data/metal -x c++ %s/test.metal",
             SB_SOURCE_DIR, dir);
    return write_and_run(dir, "test.metal", text, use, cmd, log, logsz);
}

static int check_msl_variant(void *dir, const char *text, int sampled, char *log, size_t logsz) {
    int vndf = strstr(text, "    texture2d<float> sb_vndf;\n") != NULL;
    return check_msl(text, sampled ? msl_use_sampled : vndf ? msl_use_vndf : msl_use, dir, log, logsz);
}

SB_TEST(msl_parses) {
    if (sb_run("command -v clang++", NULL, 0) != 0) SKIP("no clang++ (Debian: clang): MSL not checked");
    const char *dir = sb_tmpdir("shader_msl");
    each_variant("msl", check_msl_variant, (void *)dir);
    /* the check is real: GLSL fails, and so does a vector size mixed up */
    sb_param_t *p = sb_param_of(sb_specs[3]);
    char *glsl = sb_shader_text(p, SB_FORM_F, 0, "glsl"), *msl = sb_shader_text(p, SB_FORM_F, 0, "msl"), log[8192];
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

/* Compile the n modules with Chromium's WebGPU: one console line
 * "SB-WGSL k ERRORS MESSAGES" per module (chromium_page). */
static int chromium_wgsl(char *const *mods, int n, const char *dir, char *log, size_t logsz) {
    FILE *fp = sb_page_file(dir);
    if (!fp) return -1;
    fputs("<html><body><script>\nconst mods = [", fp);
    for (int i = 0; i < n; i++) {
        if (i) fputs(",\n", fp);
        sb_js_string(fp, mods[i]);
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
    return sb_chromium_page(dir, log, logsz);
}

/* Every layout, form and the sampler block in WGSL, compiled by Tint: no
 * error; and the check is real: the untranslated GLSL fails. */
typedef struct modules {
    char *text[(SB_NSPECS + 2) * 8 + 1];
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
    sb_param_t *io = sb_param_of(sb_specs[0]);
    mods[n++] = sb_shader_text(io, SB_FORM_F, 0, "glsl"); /* must fail */
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

/* Text the library did not write is answered, never crashed on: every
 * prefix of a snippet with the sampler (cut anywhere: unbalanced
 * parentheses, braces, a directive without its #endif) and random bytes,
 * in every language (under ASan in CI). */
SB_TEST(hostile_input) {
    sb_param_t *p = sb_param_of(sb_specs[4]);
    char *full = sb_shader_text(p, SB_FORM_COS, 3, "glsl");
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
