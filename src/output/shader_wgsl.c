/* The snippet in WGSL (WebGPU): the GLSL text of sb_glsl_snippet and
 * sb_glsl_sampler rewritten statement by statement.  WGSL differs from
 * the C-like languages (shader.c) in its grammar, so this rewrite parses
 * the GLSL subset the library writes:
 *   preprocessor  evaluated here (WGSL has none): #define NAME VALUE ->
 *                 `const NAME = VALUE;`, #if / #ifdef / #elif / #else
 *                 keep the active lines only
 *   declarations  `T a = x, b;` -> `var a: T' = x; var b: T';`; global
 *                 arrays -> var<private> array<T', N>; constants -> const
 *   functions     `R f(T a, out U b)` -> `fn f(a: T', b: ptr<function, U'>)
 *                 -> R'`, *b where b is used, &x where x is passed to an
 *                 out parameter; a parameter the body assigns is copied to
 *                 a var (WGSL parameters are immutable)
 *   statements    bodies of if / else / for / while always in braces
 *   expressions   c ? a : b -> select(b, a, c); types vecN, ivecN, float,
 *                 int -> vecNf, vecNi, f32, i32; atan(y, x) -> atan2;
 *                 inversesqrt -> inverseSqrt; texture / texelFetch /
 *                 textureSize -> helpers over textureSampleLevel,
 *                 textureLoad, textureDimensions (`uniform sampler2D`:
 *                 texture_2d, textureLoad only); names WGSL reserves get
 *                 a trailing '_'. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "shader_wgsl.h"

int sb_wg_same(const char *a, size_t n, const char *word) { return strlen(word) == n && strncmp(a, word, n) == 0; }

const char *sb_wg_skip_ws(const char *p, const char *end) {
    for (;;) {
        while (p < end && (*p == ' ' || *p == '\t' || *p == '\n' || *p == '\r'))
            p++;
        if (p + 1 < end && p[0] == '/' && p[1] == '/') {
            while (p < end && *p != '\n')
                p++;
            continue;
        }
        return p;
    }
}

const char *sb_wg_ident_end(const char *p, const char *end) {
    while (p < end && sb_sh_id(*p))
        p++;
    return p;
}

/* A GLSL type name -> WGSL; NULL if the name is none. */
const char *sb_wg_type_of(const char *a, size_t n) {
    static const char *const map[][2] = {{"float", "f32"},   {"int", "i32"},     {"uint", "u32"},    {"bool", "bool"},
                                         {"vec2", "vec2f"},  {"vec3", "vec3f"},  {"vec4", "vec4f"},  {"ivec2", "vec2i"},
                                         {"ivec3", "vec3i"}, {"ivec4", "vec4i"}, {"uvec2", "vec2u"}, {"uvec3", "vec3u"},
                                         {"void", ""}};
    for (size_t k = 0; k < sizeof map / sizeof map[0]; k++)
        if (sb_wg_same(a, n, map[k][0])) return map[k][1];
    return NULL;
}

/* Names WGSL reserves that the GLSL may use. */
static int reserved(const char *a, size_t n) {
    static const char *const words[] = {"target", "filter", "set",     "get",  "type",   "self",   "mod",
                                        "module", "meta",   "match",   "move", "pass",   "patch",  "ref",
                                        "use",    "where",  "with",    "from", "common", "layout", "shared",
                                        "static", "final",  "precise", "std",  "enum",   "do",     "new"};
    for (size_t k = 0; k < sizeof words / sizeof words[0]; k++)
        if (sb_wg_same(a, n, words[k])) return 1;
    return 0;
}

static int param_index(const wg_t *w, const char *a, size_t n) {
    for (int i = 0; i < w->nparams; i++)
        if (sb_wg_same(a, n, w->params[i])) return i;
    return -1;
}

static const fnsig_t *fn_find(const wg_t *w, const char *a, size_t n) {
    for (int i = 0; i < w->nfns; i++)
        if (sb_wg_same(a, n, w->fns[i].name)) return &w->fns[i];
    return NULL;
}

void sb_wg_var_add(wg_t *w, const char *name, size_t n, const char *type, size_t tn) {
    if (w->nvars == MAX_VARS) return;
    snprintf(w->vars[w->nvars], sizeof w->vars[0], "%.*s", (int)n, name);
    snprintf(w->var_types[w->nvars++], sizeof w->var_types[0], "%.*s", (int)tn, type);
}

static const char *var_type(const wg_t *w, const char *a, size_t n) {
    for (int i = w->nvars - 1; i >= 0; i--)
        if (sb_wg_same(a, n, w->vars[i])) return w->var_types[i];
    return NULL;
}

/* Whether [p, end) is an int expression: int literals, int variables,
 * components of ivec variables, calls of int(...) or of functions that
 * return int, with + - * / % and parentheses. */
static int int_expr(const wg_t *w, const char *p, const char *end) {
    int any = 0;
    while (p < end) {
        if (sb_sh_id0(*p)) {
            const char *b = sb_wg_ident_end(p, end), *o = sb_sh_skip_blanks(b, end);
            const char *ty = var_type(w, p, (size_t)(b - p));
            const fnsig_t *f = NULL;
            if (o < end && *o == '(') {
                f = fn_find(w, p, (size_t)(b - p));
                if (!(sb_wg_same(p, (size_t)(b - p), "int") || (f && f->returns_int))) return 0;
                p = sb_sh_close_paren(o, end);
                if (!p) return 0;
                p++;
            } else if (ty && !strcmp(ty, "int")) {
                p = b;
            } else if (ty && !strncmp(ty, "ivec", 4) && b + 1 < end && *b == '.' && strchr("xyzw", b[1]) &&
                       !sb_sh_id(b[2])) {
                p = b + 2;
            } else {
                return 0;
            }
            any = 1;
        } else if (sb_sh_digit(*p)) {
            const char *b = p;
            while (b < end && sb_sh_digit(*b))
                b++;
            if (b < end && (*b == '.' || *b == 'e' || sb_sh_id0(*b))) return 0;
            p = b, any = 1;
        } else if (strchr(" +-*/%()", *p)) {
            p++;
        } else {
            return 0;
        }
    }
    return any;
}

static void put_name(wg_t *w, const char *a, size_t n) {
    sb_shbuf_put(&w->out, a, n);
    if (reserved(a, n)) sb_shbuf_puts(&w->out, "_");
}

/* The top-level '?' of [p, end) and its ':', or NULL. */
static const char *top_ternary(const char *p, const char *end, const char **colon) {
    int depth = 0, nest = 0;
    const char *q = NULL;
    for (const char *c = p; c < end; c++) {
        if (*c == '(' || *c == '[') depth++;
        if (*c == ')' || *c == ']') depth--;
        if (depth) continue;
        if (*c == '?') {
            if (!q)
                q = c;
            else
                nest++;
        } else if (*c == ':' && q) {
            if (nest)
                nest--;
            else {
                *colon = c;
                return q;
            }
        }
    }
    return NULL;
}

/* A call's arguments (call at '(' .. close), with &x for x passed to an
 * out parameter of sig, and f32(x) for an int x when to_float. */
static void args(wg_t *w, const fnsig_t *sig, const char *open, const char *close, int to_float) {
    int i = 0;
    for (const char *a = open + 1; a < close; i++) {
        const char *c = sb_sh_top_comma(a, close), *x = sb_wg_skip_ws(a, c), *xe = sb_wg_ident_end(x, c);
        if (i) sb_shbuf_puts(&w->out, ", ");
        if (sig && i < MAX_PARAMS && (sig->ptr >> i & 1) && xe > x && sb_wg_skip_ws(xe, c) == c) {
            int k = param_index(w, x, (size_t)(xe - x));
            if (k >= 0 && (w->ptr >> k & 1)) { /* already a pointer */
                sb_shbuf_put(&w->out, x, (size_t)(xe - x));
            } else {
                if (k >= 0) w->assigned |= 1u << k;
                sb_shbuf_puts(&w->out, "&");
                put_name(w, x, (size_t)(xe - x));
            }
        } else if (to_float && int_expr(w, a, c)) {
            sb_shbuf_puts(&w->out, "f32(");
            sb_wg_expr(w, a, c);
            sb_shbuf_puts(&w->out, ")");
        } else {
            sb_wg_expr(w, a, c);
        }
        a = c + 1;
    }
}

/* An identifier [a, b) followed by the call at open. */
static void call(wg_t *w, const char *a, const char *b, const char *open, const char *close) {
    size_t n = (size_t)(b - a);
    const char *first = sb_sh_top_comma(open + 1, close), *ty = sb_wg_type_of(a, n);
    static const char *const tex[] = {"texture", "texelFetch", "textureSize"};
    static const char *const helper[] = {"texture", "fetch", "size"};
    for (int k = 0; k < 3; k++)
        if (sb_wg_same(a, n, tex[k])) {
            const char *x = sb_wg_skip_ws(open + 1, first);
            sb_shbuf_putf(&w->out, "sb_%s_%.*s(", helper[k], (int)(sb_wg_ident_end(x, first) - x), x);
            if (first < close) args(w, NULL, first, close, 0);
            sb_shbuf_puts(&w->out, ")");
            return;
        }
    if (ty)
        sb_shbuf_puts(&w->out, ty);
    else if (sb_wg_same(a, n, "atan") && first < close)
        sb_shbuf_puts(&w->out, "atan2");
    else if (sb_wg_same(a, n, "inversesqrt"))
        sb_shbuf_puts(&w->out, "inverseSqrt");
    else
        put_name(w, a, n);
    sb_shbuf_puts(&w->out, "(");
    args(w, fn_find(w, a, n), open, close, ty && !strncmp(ty, "vec", 3) && ty[4] == 'f');
    sb_shbuf_puts(&w->out, ")");
}

/* A GLSL expression [p, end) in WGSL. */
void sb_wg_expr(wg_t *w, const char *p, const char *end) {
    const char *colon, *q = top_ternary(p, end, &colon);
    if (q) {
        sb_shbuf_puts(&w->out, "select(");
        sb_wg_expr(w, colon + 1, end);
        sb_shbuf_puts(&w->out, ", ");
        sb_wg_expr(w, q + 1, colon);
        sb_shbuf_puts(&w->out, ", ");
        sb_wg_expr(w, p, q);
        sb_shbuf_puts(&w->out, ")");
        return;
    }
    while (p < end) {
        if (sb_sh_id0(*p)) {
            const char *b = sb_wg_ident_end(p, end), *o = sb_sh_skip_blanks(b, end);
            const char *close = o < end && *o == '(' ? sb_sh_close_paren(o, end) : NULL;
            int k = param_index(w, p, (size_t)(b - p));
            if (close) {
                call(w, p, b, o, close);
                p = close + 1;
                continue;
            }
            if (k >= 0 && (w->ptr >> k & 1)) {
                sb_shbuf_putf(&w->out, "(*%.*s)", (int)(b - p), p);
            } else {
                const char *ty = sb_wg_type_of(p, (size_t)(b - p));
                if (ty)
                    sb_shbuf_puts(&w->out, ty);
                else
                    put_name(w, p, (size_t)(b - p));
            }
            p = b;
        } else if (sb_sh_digit(*p)) {
            const char *b = p;
            while (b < end &&
                   (sb_sh_id(*b) || *b == '.' || ((*b == '-' || *b == '+') && (b[-1] == 'e' || b[-1] == 'E'))))
                b++;
            sb_shbuf_put(&w->out, p, (size_t)(b - p));
            p = b;
        } else if (*p == '(') {
            const char *close = sb_sh_close_paren(p, end);
            if (!close) close = end;
            sb_shbuf_puts(&w->out, "(");
            sb_wg_expr(w, p + 1, close);
            sb_shbuf_puts(&w->out, ")");
            p = close < end ? close + 1 : end;
        } else if (*p == '\n' || *p == '\r' || *p == '\t') {
            sb_shbuf_puts(&w->out, " ");
            while (p < end && (*p == ' ' || *p == '\n' || *p == '\r' || *p == '\t'))
                p++;
        } else {
            sb_shbuf_put(&w->out, p, 1);
            p++;
        }
    }
}

static void indent(wg_t *w) {
    for (int i = 0; i < w->depth; i++)
        sb_shbuf_puts(&w->out, "    ");
}

/* The first top-level ';' at or after p, or end. */
const char *sb_wg_stmt_end(const char *p, const char *end) {
    int depth = 0;
    for (; p < end; p++) {
        if (*p == '(') depth++;
        if (*p == ')') depth--;
        if (*p == ';' && depth == 0) return p;
    }
    return end;
}

/* `T a = x, b` ([p, end), T a type) -> var declarations, separated by `sep`. */
static void declaration(wg_t *w, const char *p, const char *end, const char *sep) {
    const char *te = sb_wg_ident_end(p, end), *ty = sb_wg_type_of(p, (size_t)(te - p));
    for (const char *d = sb_wg_skip_ws(te, end); d < end;) {
        const char *c = sb_sh_top_comma(d, end), *ne = sb_wg_ident_end(d, c), *eq = sb_wg_skip_ws(ne, c);
        if (d != sb_wg_skip_ws(te, end)) sb_shbuf_puts(&w->out, sep);
        sb_shbuf_puts(&w->out, "var ");
        put_name(w, d, (size_t)(ne - d));
        sb_wg_var_add(w, d, (size_t)(ne - d), p, (size_t)(te - p));
        sb_shbuf_putf(&w->out, ": %s", ty);
        if (eq < c && *eq == '=') {
            sb_shbuf_puts(&w->out, " = ");
            sb_wg_expr(w, sb_wg_skip_ws(eq + 1, c), c);
        }
        d = c < end ? sb_wg_skip_ws(c + 1, end) : end;
    }
}

/* An expression statement [p, end): an assignment (the target marked
 * assigned when it is a parameter), x++, or a call. */
static void simple(wg_t *w, const char *p, const char *end) {
    const char *te = sb_wg_ident_end(p, end);
    int k = param_index(w, p, (size_t)(te - p));
    int depth = 0;
    for (const char *c = p; c < end; c++) {
        if (*c == '(' || *c == '[') depth++;
        if (*c == ')' || *c == ']') depth--;
        int assign = depth == 0 && *c == '=' && c[1] != '=' && !(c > p && strchr("=!<>", c[-1]));
        if (!assign && !(depth == 0 && (*c == '+' || *c == '-') && c[1] == *c)) continue;
        if (k >= 0) w->assigned |= 1u << k;
        break;
    }
    sb_wg_expr(w, p, end);
}

/* A body of if / for / while, always braced. */
static const char *body(wg_t *w, const char *p, const char *end) {
    sb_shbuf_puts(&w->out, " {\n");
    w->depth++;
    p = sb_wg_skip_ws(p, end);
    if (p < end && *p == '{') {
        for (p = sb_wg_skip_ws(p + 1, end); p < end && *p != '}'; p = sb_wg_skip_ws(p, end))
            p = sb_wg_statement(w, p, end);
        p = p < end ? p + 1 : end;
    } else {
        p = sb_wg_statement(w, p, end);
    }
    w->depth--;
    indent(w);
    sb_shbuf_puts(&w->out, "}");
    return p;
}

/* `KW (` ... `)`: the parenthesised part's bounds. */
static const char *paren(const char *p, const char *end, const char **open) {
    *open = sb_wg_skip_ws(p, end);
    const char *close = *open < end && **open == '(' ? sb_sh_close_paren(*open, end) : NULL;
    return close ? close : end;
}

const char *sb_wg_statement(wg_t *w, const char *p, const char *end) {
    p = sb_wg_skip_ws(p, end);
    if (p >= end) return end; /* cut text: nothing left */
    const char *te = sb_wg_ident_end(p, end), *open, *close;
    size_t n = (size_t)(te - p);
    indent(w);
    if (sb_wg_same(p, n, "if")) {
        close = paren(te, end, &open);
        sb_shbuf_puts(&w->out, "if (");
        sb_wg_expr(w, open + 1, close);
        sb_shbuf_puts(&w->out, ")");
        p = body(w, close + 1, end);
        const char *e = sb_wg_skip_ws(p, end);
        if (sb_wg_ident_end(e, end) - e == 4 && !strncmp(e, "else", 4)) {
            const char *a = sb_wg_skip_ws(e + 4, end);
            if (sb_wg_ident_end(a, end) - a == 2 && !strncmp(a, "if", 2)) {
                sb_shbuf_puts(&w->out, " else ");
                int d = w->depth;
                w->depth = 0; /* `else if` on the same line */
                p = sb_wg_statement(w, a, end);
                w->depth = d;
                return p;
            }
            sb_shbuf_puts(&w->out, " else");
            p = body(w, e + 4, end);
        }
        sb_shbuf_puts(&w->out, "\n");
        return p;
    }
    if (sb_wg_same(p, n, "for") || sb_wg_same(p, n, "while")) {
        close = paren(te, end, &open);
        sb_shbuf_putf(&w->out, "%.*s (", (int)n, p);
        if (n == 3) {
            const char *s1 = sb_wg_stmt_end(open + 1, close), *s2 = sb_wg_stmt_end(s1 + 1, close);
            const char *init = sb_wg_skip_ws(open + 1, s1);
            if (sb_wg_type_of(init, (size_t)(sb_wg_ident_end(init, s1) - init)))
                declaration(w, init, s1, ", ");
            else
                sb_wg_expr(w, init, s1);
            sb_shbuf_puts(&w->out, "; ");
            sb_wg_expr(w, sb_wg_skip_ws(s1 + 1, s2), s2);
            sb_shbuf_puts(&w->out, "; ");
            sb_wg_expr(w, sb_wg_skip_ws(s2 + 1, close), close);
        } else {
            sb_wg_expr(w, open + 1, close);
        }
        sb_shbuf_puts(&w->out, ")");
        p = body(w, close + 1, end);
        sb_shbuf_puts(&w->out, "\n");
        return p;
    }
    const char *semi = sb_wg_stmt_end(p, end);
    if (sb_wg_same(p, n, "return")) {
        sb_shbuf_puts(&w->out, "return");
        const char *x = sb_wg_skip_ws(te, semi);
        if (x < semi) sb_shbuf_puts(&w->out, " ");
        sb_wg_expr(w, x, semi);
    } else if (sb_wg_type_of(p, n) && sb_sh_id0(*sb_wg_skip_ws(te, semi))) {
        declaration(w, p, semi, ";\n    ");
    } else {
        simple(w, p, semi);
    }
    sb_shbuf_puts(&w->out, ";\n");
    return semi < end ? semi + 1 : end;
}
