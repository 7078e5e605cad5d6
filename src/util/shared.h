/* Helpers the library shares with its own CLI and tests, not exported
 * (the library is built with hidden visibility; the CLI and the tests
 * link its static archive): overflow-checked sizes, the wording of file
 * errors, the JSON writer of report.json. */
#ifndef SEPBRDF_SHARED_H
#define SEPBRDF_SHARED_H

#include <stddef.h>
#include <stdio.h>

/* Overflow-checked size arithmetic: return 0 and set *out, or 1 on
 * overflow or a NULL out (then *out is left as it was). */
int sb_size_mul(size_t a, size_t b, size_t *out);
int sb_size_mul3(size_t a, size_t b, size_t c, size_t *out);
int sb_size_add(size_t a, size_t b, size_t *out);

/* Why a file operation failed, for messages: errno `err` in words, naming
 * a full disk ("disk full (no space left on device)"), a quota and the
 * file size limit plainly; strerror() otherwise.  A static string. */
const char *sb_io_why(int err);

/* The index of `name` among names[0..n) (the registries' names: forms,
 * warps, interpolations), -1 for none or a NULL name. */
int sb_name_find(const char *const *names, int n, const char *name);

/* A minimal JSON writer (report.json; the CLI's reports use it too).
 * Objects and arrays nest up to 31 deep (deeper ones are not written);
 * key NULL inside arrays and for the outermost value; value NULL is null;
 * non-finite numbers are written as null.  A NULL j, or one without fp,
 * writes nothing. */
typedef struct sb_json {
    FILE *fp;
    int depth;
    int first[32];
} sb_json_t;
void sb_json_begin_object(sb_json_t *j, const char *key);
void sb_json_end_object(sb_json_t *j);
void sb_json_begin_array(sb_json_t *j, const char *key);
void sb_json_end_array(sb_json_t *j);
void sb_json_string(sb_json_t *j, const char *key, const char *value); /* value NULL: null */
void sb_json_number(sb_json_t *j, const char *key, double value);
void sb_json_int(sb_json_t *j, const char *key, long long value);
void sb_json_bool(sb_json_t *j, const char *key, int value);

#endif
