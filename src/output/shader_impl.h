/* Private: what the shading-language rewrites (shader.c: HLSL, MSL;
 * shader_wgsl.c: WGSL) share: a growing string, and scanning helpers over
 * the GLSL text. */
#ifndef SB_SHADER_IMPL_H
#define SB_SHADER_IMPL_H

#include <stddef.h>

/* A malloc'ed string that grows; oom set (and nothing more appended) when
 * an allocation failed. */
typedef struct sb_shbuf {
    char *s;
    size_t n, cap;
    int oom;
} sb_shbuf_t;
void sb_shbuf_put(sb_shbuf_t *b, const char *s, size_t n);
void sb_shbuf_puts(sb_shbuf_t *b, const char *s);
void sb_shbuf_putf(sb_shbuf_t *b, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

static inline int sb_sh_id0(char c) { return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_'; }
static inline int sb_sh_id(char c) { return sb_sh_id0(c) || (c >= '0' && c <= '9'); }
static inline int sb_sh_digit(char c) { return c >= '0' && c <= '9'; }
/* The ')' matching the '(' at p (before end), or NULL. */
const char *sb_sh_close_paren(const char *p, const char *end);
/* The first top-level ',' in (p, end), or end. */
const char *sb_sh_top_comma(const char *p, const char *end);
const char *sb_sh_skip_blanks(const char *p, const char *end);

/* The snippet text in WGSL (shader_wgsl.c); NULL on no memory. */
char *sb_shader_wgsl_(const char *glsl);

#endif
