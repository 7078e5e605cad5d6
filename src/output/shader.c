/* The snippet in other shading languages: the GLSL text of sb_glsl_snippet
 * (and sb_glsl_sampler) rewritten token by token into HLSL or the Metal
 * Shading Language, so that every language runs the same coordinate code,
 * warps and sampler as the GLSL (one source of the maths: the layouts and
 * data/sepbrdf*.glsl).
 *
 * The snippet's GLSL is a small subset, and the rewrite covers exactly it:
 *   types        vecN, ivecN, uvecN, bvecN -> floatN, intN, uintN, boolN
 *   constructors a one-argument vector constructor (a splat or a
 *                conversion) -> ((floatN)(x)) (HLSL), floatN(x) (MSL)
 *   functions    atan(y, x) -> atan2; HLSL: mix -> lerp, fract -> frac;
 *                inversesqrt -> rsqrt
 *   textures     `uniform sampler2DArray X;` -> a texture and a sampler
 *                per language, and texture(X, c), texelFetch(X, p, l),
 *                textureSize(X, l) -> calls of helpers sb_texture_X(c),
 *                sb_fetch_X(p, l), sb_size_X(l) defined beside them;
 *                `uniform sampler2D X;` (a layout's tables, texelFetch
 *                only: vndf's sb_vndf) -> a 2D texture, no sampler
 *   constants    global `const T a[N] = T[N](...)` -> brace initialisers,
 *                `static const` (HLSL) or `constant` (MSL)
 *   MSL          out / inout parameters -> thread T&; the functions and
 *                textures become members of `struct sb_shader` (Metal has
 *                no global textures); float literals get an f suffix.
 * Preprocessor lines pass through (both languages have the C
 * preprocessor), but for the GL_ES precision block, which is dropped. */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sepbrdf/glsl.h"
#include "shader_impl.h"

enum { L_GLSL, L_HLSL, L_MSL, L_WGSL, L_COUNT };
static const char *const lang_names[L_COUNT] = {"glsl", "hlsl", "msl", "wgsl"};
static const char *const lang_exts[L_COUNT] = {"glsl", "hlsl", "metal", "wgsl"};

size_t sb_shader_lang_count(void) { return L_COUNT; }
const char *sb_shader_lang_name(size_t k) { return k < L_COUNT ? lang_names[k] : "?"; }
const char *sb_shader_lang_ext(size_t k) { return k < L_COUNT ? lang_exts[k] : "?"; }

int sb_shader_lang_find(const char *name) {
    for (int k = 0; name && k < L_COUNT; k++)
        if (strcmp(name, lang_names[k]) == 0) return k;
    return -1;
}

sb_result_t sb_shader_lang_list(sb_context_t *ctx, const char *list, unsigned *mask) {
    unsigned m = 1; /* GLSL, always */
    for (const char *p = list; p && *p;) {
        size_t n = strcspn(p, ",");
        char word[32];
        snprintf(word, sizeof word, "%.*s", (int)(n < sizeof word ? n : sizeof word - 1), p);
        int k = sb_shader_lang_find(word);
        if (strcmp(word, "all") == 0)
            m = (1u << L_COUNT) - 1;
        else if (k >= 0 && n < sizeof word)
            m |= 1u << k;
        else {
            char names[128] = "";
            for (size_t i = 0; i < L_COUNT; i++)
                snprintf(names + strlen(names), sizeof names - strlen(names), "%s, ", sb_shader_lang_name(i));
            return sb_error(ctx, SB_ERR_UNKNOWN, "shader language '%.*s' unknown, need %sor all", (int)n, p, names);
        }
        p += n + (p[n] == ',' && p[n + 1]); /* "hlsl,": the empty item after the comma is read too */
    }
    if (mask) *mask = m;
    return SB_OK;
}

/* ---- a growing string ---- */
void sb_shbuf_put(sb_shbuf_t *b, const char *s, size_t n) {
    if (b->oom) return;
    if (b->n + n + 1 > b->cap) {
        size_t cap = (b->n + n + 1) * 2;
        char *t = realloc(b->s, cap);
        if (!t) {
            b->oom = 1;
            return;
        }
        b->s = t;
        b->cap = cap;
    }
    memcpy(b->s + b->n, s, n);
    b->n += n;
    b->s[b->n] = 0;
}

void sb_shbuf_puts(sb_shbuf_t *b, const char *s) { sb_shbuf_put(b, s, strlen(s)); }

void sb_shbuf_putf(sb_shbuf_t *b, const char *fmt, ...) {
    char tmp[1024];
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(tmp, sizeof tmp, fmt, ap);
    va_end(ap);
    if (n > 0) sb_shbuf_put(b, tmp, (size_t)n < sizeof tmp ? (size_t)n : sizeof tmp - 1);
}

const char *sb_sh_close_paren(const char *p, const char *end) {
    int depth = 0;
    for (; p < end; p++) {
        if (*p == '(') depth++;
        if (*p == ')' && --depth == 0) return p;
    }
    return NULL;
}

const char *sb_sh_top_comma(const char *p, const char *end) {
    int depth = 0;
    for (; p < end; p++) {
        if (*p == '(' || *p == '[') depth++;
        if (*p == ')' || *p == ']') depth--;
        if (*p == ',' && depth == 0) return p;
    }
    return end;
}

const char *sb_sh_skip_blanks(const char *p, const char *end) {
    while (p < end && (*p == ' ' || *p == '\t'))
        p++;
    return p;
}

/* ---- the rewrite ---- */
typedef struct tr {
    int lang;
    sb_shbuf_t fn;      /* functions (MSL: the members of sb_shader) */
    sb_shbuf_t glob;    /* MSL: constants before the struct */
    sb_shbuf_t members; /* MSL: the texture members */
    sb_shbuf_t tables;  /* MSL: the 2D texture members, after the others */
    int textures;       /* textures declared so far: their register / binding */
} tr_t;

/* "vec3" -> "float3" etc.; NULL for another name.  *dim = N. */
static const char *vector_type(const char *id, size_t n, int *dim) {
    static const char *const glsl[] = {"vec", "ivec", "uvec", "bvec"};
    static const char *const out[] = {"float", "int", "uint", "bool"};
    static char name[4][3][8];
    for (int k = 0; k < 4; k++) {
        size_t m = strlen(glsl[k]);
        if (n == m + 1 && strncmp(id, glsl[k], m) == 0 && id[m] >= '2' && id[m] <= '4') {
            *dim = id[m] - '0';
            char *s = name[k][*dim - 2];
            snprintf(s, sizeof name[k][0], "%s%d", out[k], *dim);
            return s;
        }
    }
    return NULL;
}

static const char *rename_fn(int lang, const char *id, size_t n) {
    static const char *const map[][3] = {
        {"inversesqrt", "rsqrt", "rsqrt"}, {"mix", "lerp", "mix"}, {"fract", "frac", "fract"}};
    for (size_t k = 0; k < sizeof map / sizeof map[0]; k++)
        if (strlen(map[k][0]) == n && strncmp(id, map[k][0], n) == 0) return map[k][lang == L_HLSL ? 1 : 2];
    return NULL;
}

static void xlate(tr_t *t, const char *p, const char *end, sb_shbuf_t *out);

/* An identifier at [a, b) followed (after blanks) by `(` at call: a call
 * the languages spell differently.  Returns the position after what it
 * consumed, or NULL when the call is not special. */
static const char *xlate_call(tr_t *t, const char *a, const char *b, const char *call, const char *end,
                              sb_shbuf_t *out) {
    const char *close = sb_sh_close_paren(call, end);
    if (!close) return NULL;
    size_t n = (size_t)(b - a);
    const char *first = sb_sh_top_comma(call + 1, close);
    int dim;
    const char *vt = vector_type(a, n, &dim);
    if (vt && first == close) { /* one argument: a splat or a conversion */
        sb_shbuf_putf(out, t->lang == L_HLSL ? "((%s)(" : "%s(", vt);
        xlate(t, call + 1, close, out);
        sb_shbuf_puts(out, t->lang == L_HLSL ? "))" : ")");
        return close + 1;
    }
    if (n == 4 && strncmp(a, "atan", 4) == 0 && first != close) {
        sb_shbuf_puts(out, "atan2(");
        xlate(t, call + 1, close, out);
        sb_shbuf_puts(out, ")");
        return close + 1;
    }
    static const char *const tex[] = {"texture", "texelFetch", "textureSize"};
    static const char *const helper[] = {"texture", "fetch", "size"};
    for (int k = 0; k < 3; k++) {
        if (strlen(tex[k]) != n || strncmp(a, tex[k], n) != 0) continue;
        const char *x = call + 1;
        while (x < first && *x == ' ')
            x++;
        const char *xe = x;
        while (xe < first && sb_sh_id(*xe))
            xe++;
        sb_shbuf_putf(out, "sb_%s_%.*s(", helper[k], (int)(xe - x), x);
        if (first < close) xlate(t, sb_sh_skip_blanks(first + 1, close), close, out);
        sb_shbuf_puts(out, ")");
        return close + 1;
    }
    return NULL;
}

/* GLSL expression text [p, end) -> out in t's language. */
static void xlate(tr_t *t, const char *p, const char *end, sb_shbuf_t *out) {
    while (p < end) {
        if (p + 1 < end && p[0] == '/' && p[1] == '/') { /* a comment: verbatim to the line's end */
            const char *e = memchr(p, '\n', (size_t)(end - p));
            e = e ? e : end;
            sb_shbuf_put(out, p, (size_t)(e - p));
            p = e;
        } else if (sb_sh_id0(*p)) {
            const char *b = p;
            while (b < end && sb_sh_id(*b))
                b++;
            const char *q = b;
            while (q < end && *q == ' ')
                q++;
            const char *next = q < end && *q == '(' ? xlate_call(t, p, b, q, end, out) : NULL;
            if (next) {
                p = next;
                continue;
            }
            size_t n = (size_t)(b - p);
            int dim;
            const char *name = vector_type(p, n, &dim);
            if (!name) name = rename_fn(t->lang, p, n);
            if (t->lang == L_MSL && ((n == 3 && !strncmp(p, "out", 3)) || (n == 5 && !strncmp(p, "inout", 5)))) {
                const char *ty = q, *te = q; /* `out T name` -> `thread T& name` */
                while (te < end && sb_sh_id(*te))
                    te++;
                sb_shbuf_puts(out, "thread ");
                xlate(t, ty, te, out);
                sb_shbuf_puts(out, "&");
                p = te;
                continue;
            }
            if (name)
                sb_shbuf_puts(out, name);
            else
                sb_shbuf_put(out, p, n);
            p = b;
        } else if (sb_sh_digit(*p) || (*p == '.' && p + 1 < end && sb_sh_digit(p[1]))) {
            const char *b = p;
            int fl = 0;
            while (b < end &&
                   (sb_sh_id(*b) || *b == '.' || ((*b == '-' || *b == '+') && (b[-1] == 'e' || b[-1] == 'E')))) {
                fl |= *b == '.' || *b == 'e' || *b == 'E';
                b++;
            }
            sb_shbuf_put(out, p, (size_t)(b - p));
            if (fl && t->lang == L_MSL && b[-1] != 'f') sb_shbuf_puts(out, "f");
            p = b;
        } else {
            sb_shbuf_put(out, p, 1);
            p++;
        }
    }
}

/* `uniform sampler2DArray X;` -> the texture, its sampler and the helpers. */
static void declare_texture(tr_t *t, const char *x, size_t n) {
    int r = t->textures++;
    if (t->lang == L_HLSL) {
        sb_shbuf_putf(&t->fn, "Texture2DArray<float4> %.*s : register(t%d);\n", (int)n, x, r);
        sb_shbuf_putf(&t->fn, "SamplerState %.*s_sampler : register(s%d);\n", (int)n, x, r);
        sb_shbuf_putf(&t->fn, "float4 sb_texture_%.*s(float3 c) { return %.*s.SampleLevel(%.*s_sampler, c, 0.0); }\n",
                      (int)n, x, (int)n, x, (int)n, x);
        sb_shbuf_putf(&t->fn, "float4 sb_fetch_%.*s(int3 p, int lod) { return %.*s.Load(int4(p, lod)); }\n", (int)n, x,
                      (int)n, x);
        sb_shbuf_putf(&t->fn,
                      "int3 sb_size_%.*s(int lod) {\n    uint w, h, layers, levels;\n"
                      "    %.*s.GetDimensions(uint(lod), w, h, layers, levels);\n    return int3(w, h, layers);\n}\n",
                      (int)n, x, (int)n, x);
        return;
    }
    sb_shbuf_putf(&t->members, "    texture2d_array<float> %.*s;\n    sampler %.*s_sampler;\n", (int)n, x, (int)n, x);
    sb_shbuf_putf(&t->fn,
                  "float4 sb_texture_%.*s(float3 c) { return %.*s.sample(%.*s_sampler, c.xy, uint(c.z + 0.5f)); }\n",
                  (int)n, x, (int)n, x, (int)n, x);
    sb_shbuf_putf(&t->fn,
                  "float4 sb_fetch_%.*s(int3 p, int lod) { return %.*s.read(uint2(p.xy), uint(p.z), uint(lod)); }\n",
                  (int)n, x, (int)n, x);
    sb_shbuf_putf(&t->fn,
                  "int3 sb_size_%.*s(int lod) {\n    return int3(int(%.*s.get_width(uint(lod))), "
                  "int(%.*s.get_height(uint(lod))), int(%.*s.get_array_size()));\n}\n",
                  (int)n, x, (int)n, x, (int)n, x, (int)n, x);
}

/* `uniform sampler2D X;` (a layout's tables, read with texelFetch only:
 * vndf's sb_vndf) -> a 2D texture without a sampler and sb_fetch_X(p, l).
 * Its slot follows every array's (HLSL t3; MSL the last member), so the
 * documented bindings of sb_g, sb_h and sb_cdf stay where they are. */
static void declare_table(tr_t *t, const char *x, size_t n) {
    if (t->lang == L_HLSL) {
        sb_shbuf_putf(&t->fn, "Texture2D<float4> %.*s : register(t3);\n", (int)n, x);
        sb_shbuf_putf(&t->fn, "float4 sb_fetch_%.*s(int2 p, int lod) { return %.*s.Load(int3(p, lod)); }\n", (int)n, x,
                      (int)n, x);
        return;
    }
    sb_shbuf_putf(&t->tables, "    texture2d<float> %.*s;\n", (int)n, x);
    sb_shbuf_putf(&t->fn, "float4 sb_fetch_%.*s(int2 p, int lod) { return %.*s.read(uint2(p), uint(lod)); }\n", (int)n,
                  x, (int)n, x);
}

/* A global constant line: `const T a[N] = T[N](v, ...);` or `const T a = v;`. */
static void global_const(tr_t *t, const char *line, const char *end) {
    sb_shbuf_t *out = t->lang == L_MSL ? &t->glob : &t->fn;
    sb_shbuf_puts(out, t->lang == L_MSL ? "constant" : "static const");
    const char *p = line + 5; /* after "const" */
    const char *eq = memchr(p, '=', (size_t)(end - p));
    const char *ctor = eq ? strchr(eq, '[') : NULL, *open = ctor && ctor < end ? strchr(ctor, '(') : NULL;
    const char *close = open && open < end ? sb_sh_close_paren(open, end) : NULL;
    if (!close) {
        xlate(t, p, end, out);
        return;
    }
    xlate(t, p, eq + 1, out);
    sb_shbuf_puts(out, " {");
    xlate(t, open + 1, close, out);
    sb_shbuf_puts(out, "}");
    xlate(t, close + 1, end, out);
}

static void header(sb_shbuf_t *b, int lang, int sampled, int tables) {
    if (lang == L_HLSL) {
        sb_shbuf_puts(b,
                      "// sepbrdf.hlsl - the snippet of sepbrdf.glsl in HLSL (shader model 5.0 and later: DXC, FXC,\n"
                      "// glslang).  The same functions, with HLSL's types:\n"
                      "//     float3 sb_brdf(float3 L, float3 V);   // f_r(L, V), L and V unit, tangent frame\n");
        if (sampled)
            sb_shbuf_puts(b, "//     bool  sb_sample(float3 V, float2 u, out float3 L, out float pdf);\n"
                             "//     float sb_pdf(float3 L, float3 V);\n");
        sb_shbuf_puts(b, "// Bindings: Texture2DArray sb_g : register(t0) and SamplerState sb_g_sampler :\n"
                         "// register(s0) (layer j = g_JJ.exr, RGB), sb_h and sb_h_sampler at t1 / s1 (h_JJ.exr)");
        sb_shbuf_puts(b, sampled ? ",\n// sb_cdf at t2 (sampler.bin as an R32_FLOAT array, read with Load only).\n"
                                 : ".\n");
        if (tables)
            sb_shbuf_puts(b, "// Texture2D sb_vndf : register(t3): vndf.exr (the file's warp, NDF and sigma tables,\n"
                             "// R32G32B32A32_FLOAT or RGB float, read with Load only: no sampler).\n");
        sb_shbuf_puts(b,
                      "// Samplers: MIN_MAG_MIP_LINEAR, no mipmaps (read with SampleLevel 0); AddressU / AddressV\n"
                      "// per SB_WRAP_G_S, SB_WRAP_G_T (sb_g), SB_WRAP_H_S, SB_WRAP_H_T (sb_h): 0 = CLAMP, 1 = WRAP.\n"
                      "// Texel x of a W-wide texture has its centre at u = (x + 0.5) / W, as in GLSL.\n\n");
        return;
    }
    sb_shbuf_puts(b, "// sepbrdf.metal - the snippet of sepbrdf.glsl in the Metal Shading Language (2.0 and\n"
                     "// later).  Metal has no global textures: the functions are members of struct sb_shader,\n"
                     "// made from the textures and samplers in the order of its members, e.g.\n"
                     "//     sb_shader s = {g, g_sampler, h, h_sampler");
    sb_shbuf_puts(b, sampled ? ", cdf, cdf_sampler" : "");
    sb_shbuf_puts(b, tables ? ", vndf};\n" : "};\n");
    sb_shbuf_puts(b, "//     float3 f = s.sb_brdf(L, V);          // f_r(L, V), L and V unit, tangent frame\n");
    if (sampled)
        sb_shbuf_puts(b, "//     bool ok = s.sb_sample(V, u, L, pdf); float p = s.sb_pdf(L, V);\n"
                         "// cdf: sampler.bin as an R32Float texture2d_array (read() only; its sampler unused).\n");
    if (tables)
        sb_shbuf_puts(b,
                      "// vndf: texture2d<float> of vndf.exr (the file's warp, NDF and sigma tables; read() only).\n");
    sb_shbuf_puts(b, "// g: texture2d_array<float>, layer j = g_JJ.exr (RGB); h likewise from h_JJ.exr.\n"
                     "// Samplers: filter::linear, no mipmaps; address per SB_WRAP_G_S, SB_WRAP_G_T (g),\n"
                     "// SB_WRAP_H_S, SB_WRAP_H_T (h): 0 = clamp_to_edge, 1 = repeat.  Texel x of a W-wide\n"
                     "// texture has its centre at u = (x + 0.5) / W, as in GLSL.\n\n"
                     "#include <metal_stdlib>\nusing namespace metal;\n\n");
}

char *sb_shader_translate(const char *glsl, const char *lang) {
    int l = sb_shader_lang_find(lang);
    if (!glsl || l < 0) return NULL;
    if (l == L_GLSL) return strdup(glsl);
    if (l == L_WGSL) return sb_shader_wgsl_(glsl);
    tr_t t = {.lang = l};
    sb_shbuf_t out = {0};
    header(&out, l, strstr(glsl, "sb_cdf") != NULL, strstr(glsl, "uniform sampler2D ") != NULL);
    int depth = 0, skip = 0;
    for (const char *line = glsl; *line;) {
        const char *end = strchr(line, '\n');
        end = end ? end + 1 : line + strlen(line);
        const char *p = sb_sh_skip_blanks(line, end);
        if (*p == '#') {
            if (!strncmp(p, "#ifdef GL_ES", 12)) skip = 1;
            /* MSL: #defines before the struct (the constants there use them), conditionals
             * with the functions they enclose */
            int def = !strncmp(p, "#define", 7) || !strncmp(p, "#undef", 6);
            if (!skip) xlate(&t, line, end, l == L_MSL && def ? &t.glob : &t.fn);
            if (skip && !strncmp(p, "#endif", 6)) skip = 0;
        } else if (skip) {
        } else if (depth == 0 && !strncmp(p, "uniform sampler2DArray ", 23)) {
            const char *x = sb_sh_skip_blanks(p + 23, end), *xe = x;
            while (xe < end && sb_sh_id(*xe))
                xe++;
            declare_texture(&t, x, (size_t)(xe - x));
        } else if (depth == 0 && !strncmp(p, "uniform sampler2D ", 18)) {
            const char *x = sb_sh_skip_blanks(p + 18, end), *xe = x;
            while (xe < end && sb_sh_id(*xe))
                xe++;
            declare_table(&t, x, (size_t)(xe - x));
        } else if (depth == 0 && !strncmp(p, "const ", 6)) {
            global_const(&t, p, end);
        } else {
            xlate(&t, line, end, &t.fn);
            for (const char *c = line; c < end && !(c[0] == '/' && c[1] == '/'); c++)
                depth += *c == '{' ? 1 : *c == '}' ? -1 : 0;
        }
        line = end;
    }
    if (l == L_MSL) {
        sb_shbuf_put(&out, t.glob.s ? t.glob.s : "", t.glob.n);
        sb_shbuf_puts(&out, "\nstruct sb_shader {\n");
        sb_shbuf_put(&out, t.members.s ? t.members.s : "", t.members.n);
        sb_shbuf_put(&out, t.tables.s ? t.tables.s : "", t.tables.n);
        sb_shbuf_puts(&out, "\n");
    }
    sb_shbuf_put(&out, t.fn.s ? t.fn.s : "", t.fn.n);
    if (l == L_MSL) sb_shbuf_puts(&out, "};\n");
    int oom = out.oom || t.fn.oom || t.glob.oom || t.members.oom || t.tables.oom;
    free(t.tables.s);
    free(t.fn.s);
    free(t.glob.s);
    free(t.members.s);
    if (oom) {
        free(out.s);
        return NULL;
    }
    return out.s;
}
