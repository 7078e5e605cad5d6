/* Shared by the batch tests (test_batch.c, test_batch_manifest.c): files
 * of a batch's folder read back, and a value of report.json. */
#ifndef SB_BATCH_UTIL_H
#define SB_BATCH_UTIL_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* DIR/A[/B] whole (1 MiB at most), malloc'ed, NUL-terminated; its size in
 * *size when not NULL; NULL when unreadable. */
static inline char *slurp(const char *dir, const char *a, const char *b, size_t *size) {
    char path[16384];
    snprintf(path, sizeof path, "%s/%s%s%s", dir, a, b ? "/" : "", b ? b : "");
    FILE *fp = fopen(path, "rb");
    if (!fp) return NULL;
    char *buf = malloc(1 << 20);
    size_t n = buf ? fread(buf, 1, (1 << 20) - 1, fp) : 0;
    fclose(fp);
    if (buf) buf[n] = 0;
    if (size) *size = n;
    return buf;
}

/* The value of top-level key `key` in report.json text: a string's text
 * or a number's digits, into buf; 0 when absent. */
static inline int report_value(const char *json, const char *key, char *buf, size_t size) {
    char pat[64];
    snprintf(pat, sizeof pat, "\n  \"%s\": ", key);
    const char *at = json ? strstr(json, pat) : NULL;
    if (!at) return 0;
    at += strlen(pat);
    size_t n = *at == '"' ? strcspn(++at, "\"") : strcspn(at, ",\n");
    snprintf(buf, size, "%.*s", (int)(n < size ? n : size - 1), at);
    return 1;
}

#endif
