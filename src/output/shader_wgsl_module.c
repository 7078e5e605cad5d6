/* The WGSL rewrite's module (shader_wgsl.c has its expressions and
 * statements): the preprocessor evaluated, the functions' signatures, the
 * textures, constants and functions declared, the header. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "shader_wgsl.h"

/* ---- the preprocessor ---- */
typedef struct defs {
    char name[MAX_DEFS][48], value[MAX_DEFS][64];
    int n;
} defs_t;

static const char *def_value(const defs_t *d, const char *a, size_t n) {
    for (int i = 0; i < d->n; i++)
        if (sb_wg_same(a, n, d->name[i])) return d->value[i];
    return NULL;
}

/* An #if expression: integers, defined names (an undefined one is 0),
 * !, ==, !=, &&, || and parentheses. */
static long pp_expr(const defs_t *d, const char **p, int prec);
static long pp_unary(const defs_t *d, const char **p) {
    while (**p == ' ')
        (*p)++;
    if (**p == '!') {
        (*p)++;
        return !pp_unary(d, p);
    }
    if (**p == '(') {
        (*p)++;
        long v = pp_expr(d, p, 0);
        if (**p == ')') (*p)++;
        return v;
    }
    if (sb_sh_id0(**p)) {
        const char *b = *p;
        while (sb_sh_id(**p))
            (*p)++;
        const char *v = def_value(d, b, (size_t)(*p - b));
        return v ? strtol(v, NULL, 0) : 0;
    }
    return strtol(*p, (char **)p, 0);
}

static long pp_expr(const defs_t *d, const char **p, int prec) {
    long v = pp_unary(d, p);
    for (;;) {
        while (**p == ' ')
            (*p)++;
        static const char *const ops[] = {"||", "&&", "==", "!="};
        static const int precs[] = {1, 2, 3, 3};
        int k = -1;
        for (int i = 0; i < 4; i++)
            if (!strncmp(*p, ops[i], 2) && precs[i] > prec) k = i;
        if (k < 0) return v;
        *p += 2;
        long r = pp_expr(d, p, precs[k]);
        v = k == 0 ? (v || r) : k == 1 ? (v && r) : k == 2 ? v == r : v != r;
    }
}

/* The active lines of glsl (directives evaluated and dropped) into *code,
 * each #define as a WGSL const into w. */
static void preprocess(wg_t *w, defs_t *d, const char *glsl, sb_shbuf_t *code) {
    int stack[32], top = 0, active = 1; /* stack: 1 taken, 0 not yet, -1 done (a branch was taken) */
    for (const char *line = glsl; *line;) {
        const char *end = strchr(line, '\n');
        end = end ? end + 1 : line + strlen(line);
        const char *p = sb_sh_skip_blanks(line, end), *kw = p < end ? p + 1 : end, *ke = sb_wg_ident_end(kw, end);
        const char *arg = sb_sh_skip_blanks(ke, end);
        size_t kn = (size_t)(ke - kw);
        char text[256];
        snprintf(text, sizeof text, "%.*s", (int)(end - arg), arg);
        text[strcspn(text, "\r\n")] = 0;
        if (*p != '#') {
            if (active) sb_shbuf_put(code, line, (size_t)(end - line));
        } else if (sb_wg_same(kw, kn, "if") || sb_wg_same(kw, kn, "ifdef") || sb_wg_same(kw, kn, "ifndef")) {
            const char *t = text;
            int v = kn == 2 ? pp_expr(d, &t, 0) != 0
                            : (def_value(d, text, strcspn(text, " ")) != NULL) == sb_wg_same(kw, kn, "ifdef");
            if (top < 32) stack[top++] = active ? (v ? 1 : 0) : -1;
        } else if (sb_wg_same(kw, kn, "elif") && top) {
            const char *t = text;
            stack[top - 1] = stack[top - 1] == 0 ? (pp_expr(d, &t, 0) ? 1 : 0) : -1;
        } else if (sb_wg_same(kw, kn, "else") && top) {
            stack[top - 1] = stack[top - 1] == 0 ? 1 : -1;
        } else if (sb_wg_same(kw, kn, "endif") && top) {
            top--;
        } else if (sb_wg_same(kw, kn, "define") && active && d->n < MAX_DEFS) {
            size_t nn = strcspn(text, " ");
            const char *v = text + nn + strspn(text + nn, " ");
            snprintf(d->name[d->n], sizeof d->name[0], "%.*s", (int)nn, text);
            snprintf(d->value[d->n], sizeof d->value[0], "%s", v);
            sb_shbuf_putf(&w->out, "const %s = %s;\n", d->name[d->n], *v ? v : "1");
            d->n++;
        }
        active = 1;
        for (int i = 0; i < top; i++)
            active &= stack[i] == 1;
        line = end;
    }
}

/* ---- the module ---- */

/* Record the signature of every function of the active code. */
static void signatures(wg_t *w, const char *p, const char *end) {
    int depth = 0;
    for (const char *c = p; c < end; c++) {
        if (*c == '{') depth++;
        if (*c == '}') depth--;
        if (depth || !sb_sh_id0(*c) || (c > p && sb_sh_id(c[-1]))) continue;
        const char *te = sb_wg_ident_end(c, end), *n = sb_wg_skip_ws(te, end), *ne = sb_wg_ident_end(n, end),
                   *o = sb_wg_skip_ws(ne, end);
        if (!sb_wg_type_of(c, (size_t)(te - c)) || ne == n || o >= end || *o != '(' || w->nfns == MAX_FN) continue;
        const char *close = sb_sh_close_paren(o, end);
        if (!close) return;
        fnsig_t *f = &w->fns[w->nfns++];
        snprintf(f->name, sizeof f->name, "%.*s", (int)(ne - n), n);
        f->returns_int = sb_wg_same(c, (size_t)(te - c), "int");
        for (const char *a = o + 1; a < close && f->nparams < MAX_PARAMS; f->nparams++) {
            const char *cm = sb_sh_top_comma(a, close), *q = sb_wg_skip_ws(a, cm), *qe = sb_wg_ident_end(q, cm);
            if (sb_wg_same(q, (size_t)(qe - q), "out") || sb_wg_same(q, (size_t)(qe - q), "inout"))
                f->ptr |= 1u << f->nparams;
            a = cm + 1;
        }
        c = close;
    }
}

static void texture(wg_t *w, const char *x, size_t n) {
    int b = 2 * w->textures++;
    sb_shbuf_putf(&w->out, "@group(0) @binding(%d) var %.*s: texture_2d_array<f32>;\n", b, (int)n, x);
    sb_shbuf_putf(&w->out, "@group(0) @binding(%d) var %.*s_sampler: sampler;\n", b + 1, (int)n, x);
    sb_shbuf_putf(&w->out,
                  "fn sb_texture_%.*s(c: vec3f) -> vec4f {\n"
                  "    return textureSampleLevel(%.*s, %.*s_sampler, c.xy, i32(round(c.z)), 0.0);\n}\n",
                  (int)n, x, (int)n, x, (int)n, x);
    sb_shbuf_putf(&w->out,
                  "fn sb_fetch_%.*s(p: vec3i, lod: i32) -> vec4f { return textureLoad(%.*s, p.xy, p.z, lod); }\n",
                  (int)n, x, (int)n, x);
    sb_shbuf_putf(&w->out,
                  "fn sb_size_%.*s(lod: i32) -> vec3i {\n"
                  "    return vec3i(vec2i(textureDimensions(%.*s, lod)), i32(textureNumLayers(%.*s)));\n}\n",
                  (int)n, x, (int)n, x, (int)n, x);
}

/* `uniform sampler2D X;` (a layout's tables, texelFetch only: vndf's
 * sb_vndf) -> texture_2d<f32> at @binding(6), after every array's
 * texture and sampler (sb_cdf's at 4 and 5), with no sampler. */
static void table(wg_t *w, const char *x, size_t n) {
    sb_shbuf_putf(&w->out, "@group(0) @binding(6) var %.*s: texture_2d<f32>;\n", (int)n, x);
    sb_shbuf_putf(&w->out, "fn sb_fetch_%.*s(p: vec2i, lod: i32) -> vec4f { return textureLoad(%.*s, p, lod); }\n",
                  (int)n, x, (int)n, x);
}

/* `const T a[N] = T[N](...);` or `const T a = v;` ([p, end) after "const"). */
static void constant(wg_t *w, const char *p, const char *end) {
    const char *t = sb_wg_skip_ws(p, end), *te = sb_wg_ident_end(t, end), *a = sb_wg_skip_ws(te, end),
               *ae = sb_wg_ident_end(a, end);
    const char *ty = sb_wg_type_of(t, (size_t)(te - t)), *br = sb_wg_skip_ws(ae, end),
               *eq = memchr(ae, '=', (size_t)(end - ae));
    const char *semi = sb_wg_stmt_end(ae, end);
    if (!eq) return;
    if (*br == '[') {
        const char *rb = memchr(br, ']', (size_t)(end - br)), *open = memchr(eq, '(', (size_t)(end - eq));
        const char *close = open ? sb_sh_close_paren(open, end) : NULL;
        if (!rb || !close) return;
        sb_shbuf_putf(&w->out, "var<private> %.*s: array<%s, %.*s> = array<%s, %.*s>(", (int)(ae - a), a, ty,
                      (int)(rb - br - 1), br + 1, ty, (int)(rb - br - 1), br + 1);
        sb_wg_expr(w, open + 1, close);
        sb_shbuf_puts(&w->out, ");\n");
        return;
    }
    sb_shbuf_putf(&w->out, "const %.*s: %s = ", (int)(ae - a), a, ty);
    sb_wg_expr(w, sb_wg_skip_ws(eq + 1, semi), semi);
    sb_shbuf_puts(&w->out, ";\n");
}

/* A function definition at p: `R name(params) { body }`; returns after it. */
static const char *function(wg_t *w, const char *p, const char *end) {
    const char *te = sb_wg_ident_end(p, end), *n = sb_wg_skip_ws(te, end), *ne = sb_wg_ident_end(n, end),
               *o = sb_wg_skip_ws(ne, end);
    const char *close = sb_sh_close_paren(o, end), *open = close ? sb_wg_skip_ws(close + 1, end) : end;
    if (!close || open >= end || *open != '{') return end;
    const char *bend = open, *rt = sb_wg_type_of(p, (size_t)(te - p));
    for (int depth = 0; bend < end; bend++) {
        if (*bend == '{') depth++;
        if (*bend == '}' && --depth == 0) break;
    }
    const char *types[MAX_PARAMS];
    size_t tlen[MAX_PARAMS];
    w->nparams = 0, w->ptr = 0, w->assigned = 0, w->nvars = 0;
    for (const char *a = o + 1; a < close && w->nparams < MAX_PARAMS; w->nparams++) {
        const char *cm = sb_sh_top_comma(a, close), *q = sb_wg_skip_ws(a, cm), *qe = sb_wg_ident_end(q, cm);
        if (sb_wg_same(q, (size_t)(qe - q), "out") || sb_wg_same(q, (size_t)(qe - q), "inout")) {
            w->ptr |= 1u << w->nparams;
            q = sb_wg_skip_ws(qe, cm), qe = sb_wg_ident_end(q, cm);
        }
        const char *x = sb_wg_skip_ws(qe, cm), *xe = sb_wg_ident_end(x, cm);
        types[w->nparams] = q, tlen[w->nparams] = (size_t)(qe - q);
        snprintf(w->params[w->nparams], sizeof w->params[0], "%.*s", (int)(xe - x), x);
        sb_wg_var_add(w, x, (size_t)(xe - x), q, (size_t)(qe - q));
        a = cm + 1;
    }
    /* the body first (it finds the parameters that must be vars), then the head */
    sb_shbuf_t head = w->out;
    w->out = (sb_shbuf_t){0};
    w->depth = 1;
    for (const char *s = sb_wg_skip_ws(open + 1, bend); s < bend; s = sb_wg_skip_ws(s, bend))
        s = sb_wg_statement(w, s, bend);
    sb_shbuf_t bodytext = w->out;
    w->out = head;
    sb_shbuf_putf(&w->out, "fn %.*s(", (int)(ne - n), n);
    for (int i = 0; i < w->nparams; i++) {
        const char *ty = sb_wg_type_of(types[i], tlen[i]);
        int copy = (w->assigned >> i & 1) && !(w->ptr >> i & 1);
        sb_shbuf_putf(&w->out, "%s%s%s: ", i ? ", " : "", w->params[i], copy ? "_in" : "");
        sb_shbuf_putf(&w->out, w->ptr >> i & 1 ? "ptr<function, %s>" : "%s", ty ? ty : "f32");
    }
    sb_shbuf_putf(&w->out, ")%s%s {\n", rt && *rt ? " -> " : "", rt ? rt : "");
    for (int i = 0; i < w->nparams; i++)
        if ((w->assigned >> i & 1) && !(w->ptr >> i & 1))
            sb_shbuf_putf(&w->out, "    var %s = %s_in;\n", w->params[i], w->params[i]);
    sb_shbuf_put(&w->out, bodytext.s ? bodytext.s : "", bodytext.n);
    w->out.oom |= bodytext.oom;
    free(bodytext.s);
    sb_shbuf_puts(&w->out, "}\n");
    w->nparams = 0, w->ptr = 0;
    return bend < end ? bend + 1 : end;
}

static void header(wg_t *w, int sampled, int tables) {
    sb_shbuf_puts(&w->out,
                  "// sepbrdf.wgsl - the snippet of sepbrdf.glsl in WGSL (WebGPU).  The same functions:\n"
                  "//     fn sb_brdf(L: vec3f, V: vec3f) -> vec3f   // f_r(L, V), L and V unit, tangent frame\n");
    if (sampled)
        sb_shbuf_puts(&w->out,
                      "//     fn sb_sample(V: vec3f, u: vec2f, L: ptr<function, vec3f>, pdf: ptr<function, f32>) "
                      "-> bool\n//     fn sb_pdf(L: vec3f, V: vec3f) -> f32\n");
    sb_shbuf_puts(&w->out,
                  "// Bindings, @group(0): sb_g @binding(0) (texture_2d_array<f32>, layer j = g_JJ.exr, RGB),\n"
                  "// sb_g_sampler @binding(1); sb_h, sb_h_sampler @binding(2), @binding(3) (h_JJ.exr)");
    sb_shbuf_puts(&w->out, sampled ? ";\n// sb_cdf @binding(4) (sampler.bin as r32float, unfilterable-float; read with "
                                     "textureLoad only).\n"
                                   : ".\n");
    if (tables)
        sb_shbuf_puts(&w->out, "// sb_vndf @binding(6): vndf.exr (the file's warp, NDF and sigma tables) as a "
                               "texture_2d<f32>,\n// rgba32float, unfilterable-float: read with textureLoad only.\n");
    sb_shbuf_puts(&w->out,
                  "// Filtering float32 textures needs the device feature float32-filterable; without it\n"
                  "// upload the textures as rgba16float (exact for `sepbrdf factor --half`).\n"
                  "// Samplers: magFilter / minFilter linear, no mipmaps; addressModeU / V per SB_WRAP_G_S,\n"
                  "// SB_WRAP_G_T (sb_g), SB_WRAP_H_S, SB_WRAP_H_T (sb_h): 0 = clamp-to-edge, 1 = repeat.  Texel x\n"
                  "// of a W-wide texture has its centre at u = (x + 0.5) / W, as in GLSL.\n\n");
}

char *sb_shader_wgsl_(const char *glsl) {
    wg_t *w = calloc(1, sizeof *w);
    defs_t *d = calloc(1, sizeof *d);
    sb_shbuf_t code = {0};
    if (!w || !d) {
        free(w);
        free(d);
        return NULL;
    }
    header(w, strstr(glsl, "sb_cdf") != NULL, strstr(glsl, "uniform sampler2D ") != NULL);
    preprocess(w, d, glsl, &code);
    const char *p = code.s ? code.s : "", *end = p + code.n;
    signatures(w, p, end);
    for (p = sb_wg_skip_ws(p, end); p < end; p = sb_wg_skip_ws(p, end)) {
        const char *te = sb_wg_ident_end(p, end);
        if (sb_wg_same(p, (size_t)(te - p), "uniform")) { /* uniform sampler2DArray X; or sampler2D */
            const char *ty = sb_wg_skip_ws(te, end), *tye = sb_wg_ident_end(ty, end), *x = sb_wg_skip_ws(tye, end),
                       *semi = sb_wg_stmt_end(x, end);
            if (sb_wg_same(ty, (size_t)(tye - ty), "sampler2D"))
                table(w, x, (size_t)(sb_wg_ident_end(x, end) - x));
            else
                texture(w, x, (size_t)(sb_wg_ident_end(x, end) - x));
            p = semi < end ? semi + 1 : end;
        } else if (sb_wg_same(p, (size_t)(te - p), "const")) {
            const char *semi = sb_wg_stmt_end(te, end);
            constant(w, te, semi < end ? semi + 1 : end);
            p = semi < end ? semi + 1 : end;
        } else if (sb_wg_type_of(p, (size_t)(te - p))) {
            p = function(w, p, end);
        } else { /* what the subset does not hold: stop, and fail */
            w->out.oom = 1;
            break;
        }
    }
    free(code.s);
    free(d);
    char *out = w->out.oom || code.oom ? NULL : w->out.s;
    if (!out) free(w->out.s);
    free(w);
    return out;
}
