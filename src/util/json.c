/* The minimal JSON writer (util/shared.h). */
#include <math.h>
#include <stdio.h>

#include "util/shared.h"

static void json_escape(FILE *fp, const char *s) {
    fputc('"', fp);
    for (; *s; s++) {
        unsigned char c = (unsigned char)*s;
        if (c == '"' || c == '\\')
            fprintf(fp, "\\%c", c);
        else if (c == '\n')
            fputs("\\n", fp);
        else if (c == '\t')
            fputs("\\t", fp);
        else if (c < 0x20)
            fprintf(fp, "\\u%04x", c);
        else
            fputc(c, fp);
    }
    fputc('"', fp);
}

/* Every writer takes a NULL j or a j without a FILE (nothing written) and
 * keeps depth within first[] (deeper nesting is written flat). */
#define JSON_MAX_DEPTH ((int)(sizeof((sb_json_t *)0)->first / sizeof(int)) - 1)
static int usable(const sb_json_t *j) { return j && j->fp && j->depth >= 0 && j->depth <= JSON_MAX_DEPTH; }

static void put_key(sb_json_t *j, const char *key) {
    if (j->depth > 0) {
        if (!j->first[j->depth]) fputc(',', j->fp);
        fputc('\n', j->fp);
        for (int i = 0; i < j->depth; i++)
            fputs("  ", j->fp);
    }
    j->first[j->depth] = 0;
    if (key) {
        json_escape(j->fp, key);
        fputs(": ", j->fp);
    }
}

/* Open an object or array (deeper than JSON_MAX_DEPTH: nothing). */
static void begin(sb_json_t *j, const char *key, char open) {
    if (!usable(j) || j->depth == JSON_MAX_DEPTH) return;
    put_key(j, key);
    fputc(open, j->fp);
    j->depth++;
    j->first[j->depth] = 1;
}
static void end(sb_json_t *j, char close) {
    if (!usable(j) || j->depth == 0) return;
    j->depth--;
    fputc('\n', j->fp);
    for (int i = 0; i < j->depth; i++)
        fputs("  ", j->fp);
    fputc(close, j->fp);
    if (j->depth == 0 && close == '}') fputc('\n', j->fp);
}

void sb_json_begin_object(sb_json_t *j, const char *key) { begin(j, key, '{'); }
void sb_json_end_object(sb_json_t *j) { end(j, '}'); }
void sb_json_begin_array(sb_json_t *j, const char *key) { begin(j, key, '['); }
void sb_json_end_array(sb_json_t *j) { end(j, ']'); }
void sb_json_string(sb_json_t *j, const char *key, const char *value) {
    if (!usable(j)) return;
    put_key(j, key);
    if (value)
        json_escape(j->fp, value);
    else
        fputs("null", j->fp);
}
void sb_json_number(sb_json_t *j, const char *key, double v) {
    if (!usable(j)) return;
    put_key(j, key);
    if (isfinite(v))
        fprintf(j->fp, "%.17g", v);
    else
        fputs("null", j->fp);
}
void sb_json_int(sb_json_t *j, const char *key, long long v) {
    if (!usable(j)) return;
    put_key(j, key);
    fprintf(j->fp, "%lld", v);
}
void sb_json_bool(sb_json_t *j, const char *key, int v) {
    if (!usable(j)) return;
    put_key(j, key);
    fputs(v ? "true" : "false", j->fp);
}
