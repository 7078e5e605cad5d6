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
 *                 textureLoad, textureDimensions; names WGSL reserves get
 *                 a trailing '_'. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "shader_impl.h"

#define MAX_FN 64
#define MAX_PARAMS 8
#define MAX_DEFS 32

typedef struct fnsig {
    char name[48];
    int nparams;
    unsigned ptr; /* bit i: parameter i is out / inout */
    int returns_int;
} fnsig_t;

#define MAX_VARS 64

typedef struct wg {
    sb_shbuf_t out;
    fnsig_t fns[MAX_FN];
    int nfns;
    /* the function being written: its parameters, which are pointers, which the body assigns */
    char params[MAX_PARAMS][48];
    int nparams;
    unsigned ptr, assigned;
    int textures, depth;
    /* the GLSL types of the function's parameters and variables, for the
     * int arguments of float vector constructors (GLSL converts, WGSL not) */
    char vars[MAX_VARS][48], var_types[MAX_VARS][8];
    int nvars;
} wg_t;

static int same(const char *a, size_t n, const char *word) { return strlen(word) == n && strncmp(a, word, n) == 0; }

static const char *skip_ws(const char *p, const char *end) {
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

static const char *ident_end(const char *p, const char *end) {
    while (p < end && sb_sh_id(*p))
        p++;
    return p;
}

/* A GLSL type name -> WGSL; NULL if the name is none. */
static const char *type_of(const char *a, size_t n) {
    static const char *const map[][2] = {{"float", "f32"},   {"int", "i32"},     {"uint", "u32"},    {"bool", "bool"},
                                         {"vec2", "vec2f"},  {"vec3", "vec3f"},  {"vec4", "vec4f"},  {"ivec2", "vec2i"},
                                         {"ivec3", "vec3i"}, {"ivec4", "vec4i"}, {"uvec2", "vec2u"}, {"uvec3", "vec3u"},
                                         {"void", ""}};
    for (size_t k = 0; k < sizeof map / sizeof map[0]; k++)
        if (same(a, n, map[k][0])) return map[k][1];
    return NULL;
}

/* Names WGSL reserves that the GLSL may use. */
static int reserved(const char *a, size_t n) {
    static const char *const words[] = {"target", "filter", "set",     "get",  "type",   "self",   "mod",
                                        "module", "meta",   "match",   "move", "pass",   "patch",  "ref",
                                        "use",    "where",  "with",    "from", "common", "layout", "shared",
                                        "static", "final",  "precise", "std",  "enum",   "do",     "new"};
    for (size_t k = 0; k < sizeof words / sizeof words[0]; k++)
        if (same(a, n, words[k])) return 1;
    return 0;
}

static int param_index(const wg_t *w, const char *a, size_t n) {
    for (int i = 0; i < w->nparams; i++)
        if (same(a, n, w->params[i])) return i;
    return -1;
}

static const fnsig_t *fn_find(const wg_t *w, const char *a, size_t n) {
    for (int i = 0; i < w->nfns; i++)
        if (same(a, n, w->fns[i].name)) return &w->fns[i];
    return NULL;
}

static void var_add(wg_t *w, const char *name, size_t n, const char *type, size_t tn) {
    if (w->nvars == MAX_VARS) return;
    snprintf(w->vars[w->nvars], sizeof w->vars[0], "%.*s", (int)n, name);
    snprintf(w->var_types[w->nvars++], sizeof w->var_types[0], "%.*s", (int)tn, type);
}

static const char *var_type(const wg_t *w, const char *a, size_t n) {
    for (int i = w->nvars - 1; i >= 0; i--)
        if (same(a, n, w->vars[i])) return w->var_types[i];
    return NULL;
}

/* Whether [p, end) is an int expression: int literals, int variables,
 * components of ivec variables, calls of int(...) or of functions that
 * return int, with + - * / % and parentheses. */
static int int_expr(const wg_t *w, const char *p, const char *end) {
    int any = 0;
    while (p < end) {
        if (sb_sh_id0(*p)) {
            const char *b = ident_end(p, end), *o = sb_sh_skip_blanks(b, end);
            const char *ty = var_type(w, p, (size_t)(b - p));
            const fnsig_t *f = NULL;
            if (o < end && *o == '(') {
                f = fn_find(w, p, (size_t)(b - p));
                if (!(same(p, (size_t)(b - p), "int") || (f && f->returns_int))) return 0;
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

static void expr(wg_t *w, const char *p, const char *end);

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
        const char *c = sb_sh_top_comma(a, close), *x = skip_ws(a, c), *xe = ident_end(x, c);
        if (i) sb_shbuf_puts(&w->out, ", ");
        if (sig && i < MAX_PARAMS && (sig->ptr >> i & 1) && xe > x && skip_ws(xe, c) == c) {
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
            expr(w, a, c);
            sb_shbuf_puts(&w->out, ")");
        } else {
            expr(w, a, c);
        }
        a = c + 1;
    }
}

/* An identifier [a, b) followed by the call at open. */
static void call(wg_t *w, const char *a, const char *b, const char *open, const char *close) {
    size_t n = (size_t)(b - a);
    const char *first = sb_sh_top_comma(open + 1, close), *ty = type_of(a, n);
    static const char *const tex[] = {"texture", "texelFetch", "textureSize"};
    static const char *const helper[] = {"texture", "fetch", "size"};
    for (int k = 0; k < 3; k++)
        if (same(a, n, tex[k])) {
            const char *x = skip_ws(open + 1, first);
            sb_shbuf_putf(&w->out, "sb_%s_%.*s(", helper[k], (int)(ident_end(x, first) - x), x);
            if (first < close) args(w, NULL, first, close, 0);
            sb_shbuf_puts(&w->out, ")");
            return;
        }
    if (ty)
        sb_shbuf_puts(&w->out, ty);
    else if (same(a, n, "atan") && first < close)
        sb_shbuf_puts(&w->out, "atan2");
    else if (same(a, n, "inversesqrt"))
        sb_shbuf_puts(&w->out, "inverseSqrt");
    else
        put_name(w, a, n);
    sb_shbuf_puts(&w->out, "(");
    args(w, fn_find(w, a, n), open, close, ty && !strncmp(ty, "vec", 3) && ty[4] == 'f');
    sb_shbuf_puts(&w->out, ")");
}

/* A GLSL expression [p, end) in WGSL. */
static void expr(wg_t *w, const char *p, const char *end) {
    const char *colon, *q = top_ternary(p, end, &colon);
    if (q) {
        sb_shbuf_puts(&w->out, "select(");
        expr(w, colon + 1, end);
        sb_shbuf_puts(&w->out, ", ");
        expr(w, q + 1, colon);
        sb_shbuf_puts(&w->out, ", ");
        expr(w, p, q);
        sb_shbuf_puts(&w->out, ")");
        return;
    }
    while (p < end) {
        if (sb_sh_id0(*p)) {
            const char *b = ident_end(p, end), *o = sb_sh_skip_blanks(b, end);
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
                const char *ty = type_of(p, (size_t)(b - p));
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
            expr(w, p + 1, close);
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
static const char *stmt_end(const char *p, const char *end) {
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
    const char *te = ident_end(p, end), *ty = type_of(p, (size_t)(te - p));
    for (const char *d = skip_ws(te, end); d < end;) {
        const char *c = sb_sh_top_comma(d, end), *ne = ident_end(d, c), *eq = skip_ws(ne, c);
        if (d != skip_ws(te, end)) sb_shbuf_puts(&w->out, sep);
        sb_shbuf_puts(&w->out, "var ");
        put_name(w, d, (size_t)(ne - d));
        var_add(w, d, (size_t)(ne - d), p, (size_t)(te - p));
        sb_shbuf_putf(&w->out, ": %s", ty);
        if (eq < c && *eq == '=') {
            sb_shbuf_puts(&w->out, " = ");
            expr(w, skip_ws(eq + 1, c), c);
        }
        d = c < end ? skip_ws(c + 1, end) : end;
    }
}

/* An expression statement [p, end): an assignment (the target marked
 * assigned when it is a parameter), x++, or a call. */
static void simple(wg_t *w, const char *p, const char *end) {
    const char *te = ident_end(p, end);
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
    expr(w, p, end);
}

static const char *statement(wg_t *w, const char *p, const char *end);

/* A body of if / for / while, always braced. */
static const char *body(wg_t *w, const char *p, const char *end) {
    sb_shbuf_puts(&w->out, " {\n");
    w->depth++;
    p = skip_ws(p, end);
    if (p < end && *p == '{') {
        for (p = skip_ws(p + 1, end); p < end && *p != '}'; p = skip_ws(p, end))
            p = statement(w, p, end);
        p = p < end ? p + 1 : end;
    } else {
        p = statement(w, p, end);
    }
    w->depth--;
    indent(w);
    sb_shbuf_puts(&w->out, "}");
    return p;
}

/* `KW (` ... `)`: the parenthesised part's bounds. */
static const char *paren(const char *p, const char *end, const char **open) {
    *open = skip_ws(p, end);
    const char *close = *open < end && **open == '(' ? sb_sh_close_paren(*open, end) : NULL;
    return close ? close : end;
}

static const char *statement(wg_t *w, const char *p, const char *end) {
    p = skip_ws(p, end);
    const char *te = ident_end(p, end), *open, *close;
    size_t n = (size_t)(te - p);
    indent(w);
    if (same(p, n, "if")) {
        close = paren(te, end, &open);
        sb_shbuf_puts(&w->out, "if (");
        expr(w, open + 1, close);
        sb_shbuf_puts(&w->out, ")");
        p = body(w, close + 1, end);
        const char *e = skip_ws(p, end);
        if (ident_end(e, end) - e == 4 && !strncmp(e, "else", 4)) {
            const char *a = skip_ws(e + 4, end);
            if (ident_end(a, end) - a == 2 && !strncmp(a, "if", 2)) {
                sb_shbuf_puts(&w->out, " else ");
                int d = w->depth;
                w->depth = 0; /* `else if` on the same line */
                p = statement(w, a, end);
                w->depth = d;
                return p;
            }
            sb_shbuf_puts(&w->out, " else");
            p = body(w, e + 4, end);
        }
        sb_shbuf_puts(&w->out, "\n");
        return p;
    }
    if (same(p, n, "for") || same(p, n, "while")) {
        close = paren(te, end, &open);
        sb_shbuf_putf(&w->out, "%.*s (", (int)n, p);
        if (n == 3) {
            const char *s1 = stmt_end(open + 1, close), *s2 = stmt_end(s1 + 1, close);
            const char *init = skip_ws(open + 1, s1);
            if (type_of(init, (size_t)(ident_end(init, s1) - init)))
                declaration(w, init, s1, ", ");
            else
                expr(w, init, s1);
            sb_shbuf_puts(&w->out, "; ");
            expr(w, skip_ws(s1 + 1, s2), s2);
            sb_shbuf_puts(&w->out, "; ");
            expr(w, skip_ws(s2 + 1, close), close);
        } else {
            expr(w, open + 1, close);
        }
        sb_shbuf_puts(&w->out, ")");
        p = body(w, close + 1, end);
        sb_shbuf_puts(&w->out, "\n");
        return p;
    }
    const char *semi = stmt_end(p, end);
    if (same(p, n, "return")) {
        sb_shbuf_puts(&w->out, "return");
        const char *x = skip_ws(te, semi);
        if (x < semi) sb_shbuf_puts(&w->out, " ");
        expr(w, x, semi);
    } else if (type_of(p, n) && sb_sh_id0(*skip_ws(te, semi))) {
        declaration(w, p, semi, ";\n    ");
    } else {
        simple(w, p, semi);
    }
    sb_shbuf_puts(&w->out, ";\n");
    return semi < end ? semi + 1 : end;
}

/* ---- the preprocessor ---- */
typedef struct defs {
    char name[MAX_DEFS][48], value[MAX_DEFS][64];
    int n;
} defs_t;

static const char *def_value(const defs_t *d, const char *a, size_t n) {
    for (int i = 0; i < d->n; i++)
        if (same(a, n, d->name[i])) return d->value[i];
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
        const char *p = sb_sh_skip_blanks(line, end), *kw = p + 1, *ke = ident_end(kw, end);
        const char *arg = sb_sh_skip_blanks(ke, end);
        size_t kn = (size_t)(ke - kw);
        char text[256];
        snprintf(text, sizeof text, "%.*s", (int)(end - arg), arg);
        text[strcspn(text, "\r\n")] = 0;
        if (*p != '#') {
            if (active) sb_shbuf_put(code, line, (size_t)(end - line));
        } else if (same(kw, kn, "if") || same(kw, kn, "ifdef") || same(kw, kn, "ifndef")) {
            const char *t = text;
            int v = kn == 2 ? pp_expr(d, &t, 0) != 0
                            : (def_value(d, text, strcspn(text, " ")) != NULL) == same(kw, kn, "ifdef");
            if (top < 32) stack[top++] = active ? (v ? 1 : 0) : -1;
        } else if (same(kw, kn, "elif") && top) {
            const char *t = text;
            stack[top - 1] = stack[top - 1] == 0 ? (pp_expr(d, &t, 0) ? 1 : 0) : -1;
        } else if (same(kw, kn, "else") && top) {
            stack[top - 1] = stack[top - 1] == 0 ? 1 : -1;
        } else if (same(kw, kn, "endif") && top) {
            top--;
        } else if (same(kw, kn, "define") && active && d->n < MAX_DEFS) {
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
        const char *te = ident_end(c, end), *n = skip_ws(te, end), *ne = ident_end(n, end), *o = skip_ws(ne, end);
        if (!type_of(c, (size_t)(te - c)) || ne == n || o >= end || *o != '(' || w->nfns == MAX_FN) continue;
        const char *close = sb_sh_close_paren(o, end);
        if (!close) return;
        fnsig_t *f = &w->fns[w->nfns++];
        snprintf(f->name, sizeof f->name, "%.*s", (int)(ne - n), n);
        f->returns_int = same(c, (size_t)(te - c), "int");
        for (const char *a = o + 1; a < close && f->nparams < MAX_PARAMS; f->nparams++) {
            const char *cm = sb_sh_top_comma(a, close), *q = skip_ws(a, cm), *qe = ident_end(q, cm);
            if (same(q, (size_t)(qe - q), "out") || same(q, (size_t)(qe - q), "inout")) f->ptr |= 1u << f->nparams;
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

/* `const T a[N] = T[N](...);` or `const T a = v;` ([p, end) after "const"). */
static void constant(wg_t *w, const char *p, const char *end) {
    const char *t = skip_ws(p, end), *te = ident_end(t, end), *a = skip_ws(te, end), *ae = ident_end(a, end);
    const char *ty = type_of(t, (size_t)(te - t)), *br = skip_ws(ae, end), *eq = memchr(ae, '=', (size_t)(end - ae));
    const char *semi = stmt_end(ae, end);
    if (!eq) return;
    if (*br == '[') {
        const char *rb = memchr(br, ']', (size_t)(end - br)), *open = memchr(eq, '(', (size_t)(end - eq));
        const char *close = open ? sb_sh_close_paren(open, end) : NULL;
        if (!rb || !close) return;
        sb_shbuf_putf(&w->out, "var<private> %.*s: array<%s, %.*s> = array<%s, %.*s>(", (int)(ae - a), a, ty,
                      (int)(rb - br - 1), br + 1, ty, (int)(rb - br - 1), br + 1);
        expr(w, open + 1, close);
        sb_shbuf_puts(&w->out, ");\n");
        return;
    }
    sb_shbuf_putf(&w->out, "const %.*s: %s = ", (int)(ae - a), a, ty);
    expr(w, skip_ws(eq + 1, semi), semi);
    sb_shbuf_puts(&w->out, ";\n");
}

/* A function definition at p: `R name(params) { body }`; returns after it. */
static const char *function(wg_t *w, const char *p, const char *end) {
    const char *te = ident_end(p, end), *n = skip_ws(te, end), *ne = ident_end(n, end), *o = skip_ws(ne, end);
    const char *close = sb_sh_close_paren(o, end), *open = close ? skip_ws(close + 1, end) : end;
    if (!close || open >= end || *open != '{') return end;
    const char *bend = open, *rt = type_of(p, (size_t)(te - p));
    for (int depth = 0; bend < end; bend++) {
        if (*bend == '{') depth++;
        if (*bend == '}' && --depth == 0) break;
    }
    const char *types[MAX_PARAMS];
    size_t tlen[MAX_PARAMS];
    w->nparams = 0, w->ptr = 0, w->assigned = 0, w->nvars = 0;
    for (const char *a = o + 1; a < close && w->nparams < MAX_PARAMS; w->nparams++) {
        const char *cm = sb_sh_top_comma(a, close), *q = skip_ws(a, cm), *qe = ident_end(q, cm);
        if (same(q, (size_t)(qe - q), "out") || same(q, (size_t)(qe - q), "inout")) {
            w->ptr |= 1u << w->nparams;
            q = skip_ws(qe, cm), qe = ident_end(q, cm);
        }
        const char *x = skip_ws(qe, cm), *xe = ident_end(x, cm);
        types[w->nparams] = q, tlen[w->nparams] = (size_t)(qe - q);
        snprintf(w->params[w->nparams], sizeof w->params[0], "%.*s", (int)(xe - x), x);
        var_add(w, x, (size_t)(xe - x), q, (size_t)(qe - q));
        a = cm + 1;
    }
    /* the body first (it finds the parameters that must be vars), then the head */
    sb_shbuf_t head = w->out;
    w->out = (sb_shbuf_t){0};
    w->depth = 1;
    for (const char *s = skip_ws(open + 1, bend); s < bend; s = skip_ws(s, bend))
        s = statement(w, s, bend);
    sb_shbuf_t bodytext = w->out;
    w->out = head;
    sb_shbuf_putf(&w->out, "fn %.*s(", (int)(ne - n), n);
    for (int i = 0; i < w->nparams; i++) {
        const char *ty = type_of(types[i], tlen[i]);
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

static void header(wg_t *w, int sampled) {
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
    sb_shbuf_puts(&w->out,
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
    header(w, strstr(glsl, "sb_cdf") != NULL);
    preprocess(w, d, glsl, &code);
    const char *p = code.s ? code.s : "", *end = p + code.n;
    signatures(w, p, end);
    for (p = skip_ws(p, end); p < end; p = skip_ws(p, end)) {
        const char *te = ident_end(p, end);
        if (same(p, (size_t)(te - p), "uniform")) { /* uniform sampler2DArray X; */
            const char *x = skip_ws(ident_end(skip_ws(te, end), end), end), *semi = stmt_end(x, end);
            texture(w, x, (size_t)(ident_end(x, end) - x));
            p = semi + 1;
        } else if (same(p, (size_t)(te - p), "const")) {
            const char *semi = stmt_end(te, end);
            constant(w, te, semi + 1);
            p = semi + 1;
        } else if (type_of(p, (size_t)(te - p))) {
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
