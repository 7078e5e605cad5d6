/* Private: the WGSL rewrite (shader_wgsl.c: expressions and statements;
 * shader_wgsl_module.c: the preprocessor and the module's declarations). */
#ifndef SB_SHADER_WGSL_H
#define SB_SHADER_WGSL_H

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

int sb_wg_same(const char *a, size_t n, const char *word);
/* past blanks, newlines and // comments */
const char *sb_wg_skip_ws(const char *p, const char *end);
const char *sb_wg_ident_end(const char *p, const char *end);
/* a GLSL type name -> WGSL ("" for void); NULL if the name is none */
const char *sb_wg_type_of(const char *a, size_t n);
/* the first top-level ';' at or after p, or end */
const char *sb_wg_stmt_end(const char *p, const char *end);
void sb_wg_var_add(wg_t *w, const char *name, size_t n, const char *type, size_t tn);
/* a GLSL expression [p, end) in WGSL, into w->out */
void sb_wg_expr(wg_t *w, const char *p, const char *end);
/* one GLSL statement at p in WGSL; returns after it */
const char *sb_wg_statement(wg_t *w, const char *p, const char *end);

#endif
