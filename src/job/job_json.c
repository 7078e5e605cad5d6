/* The minimal JSON writer of job.h. */
#include <math.h>
#include <stdio.h>

#include "sepbrdf/job.h"

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

void sb_json_begin_object(sb_json_t *j, const char *key) {
    put_key(j, key);
    fputc('{', j->fp);
    j->depth++;
    j->first[j->depth] = 1;
}
void sb_json_end_object(sb_json_t *j) {
    j->depth--;
    fputc('\n', j->fp);
    for (int i = 0; i < j->depth; i++)
        fputs("  ", j->fp);
    fputc('}', j->fp);
    if (j->depth == 0) fputc('\n', j->fp);
}
void sb_json_begin_array(sb_json_t *j, const char *key) {
    put_key(j, key);
    fputc('[', j->fp);
    j->depth++;
    j->first[j->depth] = 1;
}
void sb_json_end_array(sb_json_t *j) {
    j->depth--;
    fputc('\n', j->fp);
    for (int i = 0; i < j->depth; i++)
        fputs("  ", j->fp);
    fputc(']', j->fp);
}
void sb_json_string(sb_json_t *j, const char *key, const char *value) {
    put_key(j, key);
    if (value)
        json_escape(j->fp, value);
    else
        fputs("null", j->fp);
}
void sb_json_number(sb_json_t *j, const char *key, double v) {
    put_key(j, key);
    if (isfinite(v))
        fprintf(j->fp, "%.17g", v);
    else
        fputs("null", j->fp);
}
void sb_json_int(sb_json_t *j, const char *key, long long v) {
    put_key(j, key);
    fprintf(j->fp, "%lld", v);
}
void sb_json_bool(sb_json_t *j, const char *key, int v) {
    put_key(j, key);
    fputs(v ? "true" : "false", j->fp);
}
