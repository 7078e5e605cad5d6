/* sepbrdf CLI: shared helpers of the subcommands. */
#ifndef SEPBRDF_CLI_H
#define SEPBRDF_CLI_H

#include <stdio.h>

#include "sepbrdf/sepbrdf.h"

/* Exit codes (documented in the README and `sepbrdf --help`). */
enum { EXIT_OK = 0, EXIT_USAGE = 1, EXIT_IO = 2, EXIT_NUMERIC = 3 };

/* Display level: 0 quiet (-q), 1 normal, 2 verbose (-v), 3 debug (-vv). */
extern int g_verbosity;
extern const char *g_prog;

/* Diagnostics to stderr: "sepbrdf CMD: message". */
void cli_error(const char *cmd, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
void cli_info(int level, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
/* Exit code for a library result. */
int cli_exit_code(sb_result_t r);
/* Report a failed library call with the context's detail; returns the exit code. */
int cli_fail(const char *cmd, sb_context_t *ctx, sb_result_t r);

/* Option parsing helpers: "--opt=value" or "--opt value". */
typedef struct cli_args {
    int argc, i;
    char **argv;
    const char *cmd;
} cli_args_t;
/* If argv[i] is one of the names (NULL-terminated list), set *value (when
 * the option takes one) and advance; returns 1 if matched, 0 if not, -1 on
 * a missing value (message printed). */
int cli_opt(cli_args_t *a, const char *const *names, int takes_value, const char **value);
int cli_parse_size(const char *cmd, const char *opt, const char *s, size_t lo, size_t hi, size_t *out);
int cli_parse_double(const char *cmd, const char *opt, const char *s, double lo, double hi, double *out);

/* mkdir -p; 0 on success. */
int cli_mkdirs(const char *path);
double cli_now(void);

/* Progress bar on stderr, only when stderr is a terminal and verbosity >= 1,
 * at most 10 updates per second. */
void cli_progress(const char *label, double fraction);
void cli_progress_done(void);

/* Minimal JSON writer. */
typedef struct json {
    FILE *fp;
    int depth;
    int first[32];
} json_t;
void json_begin_object(json_t *j, const char *key);
void json_end_object(json_t *j);
void json_begin_array(json_t *j, const char *key);
void json_end_array(json_t *j);
void json_string(json_t *j, const char *key, const char *value);
void json_number(json_t *j, const char *key, double value);
void json_int(json_t *j, const char *key, long long value);
void json_bool(json_t *j, const char *key, int value);

/* Open `path`.tmp-PID for writing; cli_commit renames it into place (or
 * removes it when ok == 0).  Return 0 on success. */
FILE *cli_open_tmp(const char *path, char *tmp, size_t tmp_size);
int cli_commit(FILE *fp, const char *tmp, const char *path, int ok);

/* Subcommands */
int cmd_bench(int argc, char **argv);
int cmd_factor(int argc, char **argv);
int cmd_list(int argc, char **argv);

#endif
