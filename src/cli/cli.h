/* sepbrdf CLI: shared helpers of the subcommands. */
#ifndef SEPBRDF_CLI_H
#define SEPBRDF_CLI_H

#include <stdio.h>

#include "sepbrdf/sepbrdf.h"
#include "util/shared.h" /* the library's helpers of its own programs: JSON, sizes, file errors */

/* Exit codes (documented in the README, docs/guide.md and `sepbrdf --help`). */
enum { EXIT_OK = 0, EXIT_USAGE = 1, EXIT_IO = 2, EXIT_NUMERIC = 3 };
/* The exit-code paragraph every --help ends with. */
#define CLI_EXIT_HELP                                                                                                  \
    "exit status: 0 ok, 1 usage (bad option, value or spec), 2 input/output\n"                                         \
    "(missing or malformed file, unwritable output), 3 numerical failure.\n"
/* The display options every command takes (listed in its --help). */
#define CLI_VERBOSITY_HELP                                                                                             \
    "  -q, --quiet          print nothing but errors (display level 0)\n"                                              \
    "  -v, --verbose        more detail on stderr (level 2; -vv: 3)\n"                                                 \
    "  -h, --help           this text\n"

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
/* "io, io-area, hd, iso": the parameterisations of the library's registry. */
const char *cli_param_names(void);

/* Option parsing helpers: "--opt=value" or "--opt value". */
typedef struct cli_args {
    int argc, i;
    char **argv;
    const char *cmd;
} cli_args_t;
/* If argv[i] is one of the names (NULL-terminated list), set *value (when
 * the option takes one) and advance; returns 1 if matched, 0 if not, -1 on
 * a missing value (message printed). */
/* -q/--quiet, -v/--verbose, -vv: adjust g_verbosity; 1 if arg is one. */
int cli_verbosity_opt(const char *arg);
int cli_opt(cli_args_t *a, const char *const *names, int takes_value, const char **value);
/* The one -o/--out option of every command that writes: if argv[i] is it,
 * store the value in *out and return 1; 0 if it is another option; -1 on a
 * missing or empty value (message printed; `what` is "folder" or "file"). */
int cli_out_opt(cli_args_t *a, const char *what, const char **out);
/* The options of a measured table, the same in every command that reads
 * one: --interp M, --neighbours K, --radius DEG, --white e|d65.  Returns 1
 * if argv[i] was one (stored in *mo), 0 if it is another option, -1 on a
 * bad value (message printed). */
int cli_measured_opt(cli_args_t *a, sb_measured_opts_t *mo);
/* Help lines of those options, for the commands' --help. */
#define CLI_MEASURED_HELP                                                                                              \
    "      --interp M       nearest (default for MERL), linear (MERL: trilinear;\n"                                    \
    "                       tables: local linear fit), idw, quadratic (local\n"                                        \
    "                       quadratic fit); scattered tables default to the one\n"                                     \
    "                       of lowest cross-validated error (see `info`)\n"                                            \
    "      --lobe L         scattered: auto (default), on or off: interpolate\n"                                       \
    "                       relative to a diffuse + specular lobe fitted to the\n"                                     \
    "                       samples (auto: when it lowers the cross-validated\n"                                       \
    "                       error; `info` prints the lobe)\n"                                                          \
    "      --neighbours K   scattered: k nearest samples, 1..64 (default 24; idw 4)\n"                                 \
    "      --radius DEG     scattered: farther than this from every sample is\n"                                       \
    "                       missing, in degrees of the embedding distance\n"                                           \
    "                       (default: 2.5 x the median sample spacing)\n"                                              \
    "      --white W        spectra: e (default; flat spectrum = illuminant E)\n"                                      \
    "                       or d65 (Bradford to D65: flat spectrum = RGB 1,1,1)\n"                                     \
    "      --gamut G        spectra outside the sRGB gamut (a negative channel):\n"                                    \
    "                       keep (default), clip (negatives to 0) or desaturate\n"                                     \
    "                       (luminance kept, chroma reduced into the gamut)\n"

/* Option tables: each row names an option, its value (arg NULL: a flag),
 * its help text (lines separated by '\n'), where it is stored (offset
 * from the base the caller passes) and which commands take it. */
enum { CLI_FACTOR = 1, CLI_RENDER = 2, CLI_STUDY = 4, CLI_OWN = 8 /* a command's own table */ };
typedef struct cli_option cli_option_t;
typedef int (*cli_set_fn)(const char *cmd, const cli_option_t *op, const char *value, void *dst);
struct cli_option {
    const char *short_name, *name, *arg, *help;
    cli_set_fn set; /* 0 on success; -1 after a message naming op->name */
    size_t offset;
    double lo, hi; /* range of numeric values */
    unsigned commands;
};
/* The factor group's options (factor, render, study), stored into an
 * sb_job_opts_t; terminated by a row with name NULL. */
extern const cli_option_t cli_factor_options[];
int cli_set_flag(const char *cmd, const cli_option_t *op, const char *v, void *dst);
int cli_set_size(const char *cmd, const cli_option_t *op, const char *v, void *dst);
int cli_set_double(const char *cmd, const cli_option_t *op, const char *v, void *dst);
/* If argv[i] is an option of `table` that `command` takes, parse its value
 * into base + offset and return 1 (*matched = the row, when matched is not
 * NULL); 0 if not one; -1 on a missing or bad value (message printed). */
int cli_table_opt(cli_args_t *a, const cli_option_t *table, unsigned command, void *base, const cli_option_t **matched);
/* The --help lines of the rows `command` takes (a row whose help is NULL
 * is documented in the command's own text). */
void cli_table_help(const cli_option_t *table, unsigned command);
/* A string option: the value itself (const char *). */
int cli_set_string(const char *cmd, const cli_option_t *op, const char *v, void *dst);

/* One command's parse loop, shared by the commands: -h/--help (prints
 * help()), -o/--out (when out_what is set: "folder" or "file"), the rows
 * of the tables (tried in order, each stored from its base), the options
 * of a measured table (when measured is set), -q/-v/-vv, and positional
 * arguments (`what`, e.g. "SOURCE") into args, at most max_args (one more
 * is "more than one WHAT given"), counted into *nargs when not NULL.  An
 * unknown option is named with a pointer to the command's --help. */
typedef struct cli_table_use {
    const cli_option_t *table;
    unsigned command;
    void *base;
    const char **matched; /* when not NULL: the name of the last row matched */
} cli_table_use_t;
typedef struct cli_parser {
    const char *cmd;
    void (*help)(void);
    const char *out_what;
    const char **out;
    cli_table_use_t tables[3]; /* up to the first with table NULL */
    sb_measured_opts_t *measured;
    const char *what;
    const char **args;
    size_t max_args;
    size_t *nargs;
} cli_parser_t;
/* Returns -1 to go on, else the exit code: EXIT_OK after --help,
 * EXIT_USAGE after a message. */
int cli_parse(int argc, char **argv, const cli_parser_t *p);

int cli_parse_size(const char *cmd, const char *opt, const char *s, size_t lo, size_t hi, size_t *out);
/* A byte count such as 16K, 48KiB, 1M or 3.2KB (options.c); -1 after a
 * message naming opt and the text. */
int cli_parse_bytes(const char *cmd, const char *opt, const char *v, size_t *out);
int cli_parse_double(const char *cmd, const char *opt, const char *s, double lo, double hi, double *out);
/* A comma list with no empty item (none before a first or after a last
 * comma, none between two), as every list option reads it: 0, else -1
 * after a message naming opt and the text. */
int cli_list_items(const char *cmd, const char *opt, const char *s);

/* Check, before any work, that an output set can be published in folder
 * `path` (sb_outset_check: a folder of its own, writable or creatable,
 * name not too long).  Prints "CMD: OPT PATH: why" and returns its exit
 * code (EXIT_USAGE for an empty name, EXIT_IO otherwise); EXIT_OK when
 * it can. */
int cli_check_outdir(const char *cmd, const char *opt, const char *path);
double cli_now(void);

/* Progress bar on stderr, only when stderr is a terminal and verbosity >= 1,
 * at most 10 updates per second. */
void cli_progress(const char *label, double fraction);
void cli_progress_done(void);

/* The library's JSON writer (job.h) under the CLI's short names. */
typedef sb_json_t json_t;
#define json_begin_object sb_json_begin_object
#define json_end_object sb_json_end_object
#define json_begin_array sb_json_begin_array
#define json_end_array sb_json_end_array
#define json_string sb_json_string
#define json_number sb_json_number
#define json_int sb_json_int
#define json_bool sb_json_bool

/* Open `path`.tmp-PID for writing; cli_commit renames it into place (or
 * removes it when ok == 0).  cli_commit returns 0 on success, else the
 * errno of the failure (ECANCELED when ok == 0; see sb_io_why).  The
 * temporary is guarded (cli_guard) from open to commit. */
FILE *cli_open_tmp(const char *path, char *tmp, size_t tmp_size);
int cli_commit(FILE *fp, const char *tmp, const char *path, int ok);

/* Cleanup on interruption.  cli_signals_install() catches SIGINT, SIGTERM
 * and SIGHUP (those not ignored) and ignores SIGXFSZ (so a write past the
 * file size limit fails with EFBIG and is reported).  The handler removes
 * the staging folder of the open output set (sb_outset_discard_signal_safe)
 * and every guarded file, restores the default action and re-raises the
 * signal, so the run still ends "killed by SIGTERM"; the folder keeps its
 * previous set.  It uses only unlink(), rmdir(), open() and getdents64 on
 * prebuilt names (async-signal-safe).
 * cli_guard: remove `path` if a signal ends the run (32 at a time; -1 when
 * full or longer than 4095 bytes).  cli_unguard: forget it. */
void cli_signals_install(void);
int cli_guard(const char *path);
void cli_unguard(const char *path);

/* The output set of a command (outset.h) in `dir`: cli_outset_begin locks
 * it and opens the staging folder, guarded against signals; on failure
 * prints "CMD: --out ..." and returns NULL with *rc the exit code.
 * cli_set_file puts "STAGING/name" into path (size bytes) and adds name to
 * the set; -1 on a bad or too long name.  cli_outset_end publishes the set
 * (ok != 0) or discards it, releases it and returns the exit code (message
 * printed on failure).  s may be NULL. */
sb_outset_t *cli_outset_begin(sb_context_t *ctx, const char *cmd, const char *dir, int *rc);
int cli_set_file(sb_outset_t *s, const char *name, char *path, size_t size);
int cli_outset_end(sb_context_t *ctx, const char *cmd, sb_outset_t *s, int ok);

/* Read the regular file `path` whole, at most max bytes, into a new
 * NUL-terminated buffer *text of *len bytes (the caller frees it).  A
 * device, FIFO, socket or folder is refused without reading or waiting.
 * Returns 0, an errno, CLI_READ_NOT_FILE or CLI_READ_TOO_LARGE;
 * cli_read_why(e) says why in users' words. */
enum { CLI_READ_NOT_FILE = -1, CLI_READ_TOO_LARGE = -2 };
int cli_read_file(const char *path, size_t max, char **text, size_t *len);
const char *cli_read_why(int e);

/* Subcommands */
int cmd_batch(int argc, char **argv);
int cmd_bench(int argc, char **argv);
int cmd_factor(int argc, char **argv);
int cmd_list(int argc, char **argv);
int cmd_study(int argc, char **argv);
int cmd_info(int argc, char **argv);
int cmd_sample(int argc, char **argv);
int cmd_convert(int argc, char **argv);
int cmd_render(int argc, char **argv);
int cmd_view(int argc, char **argv);

/* "source_spec" of DIR/report.json (SOURCE as given to `factor`) into
 * buf; 0 on success, -1 when absent or unreadable. */
int cli_read_source_spec(const char *dir, char *buf, size_t size);

/* Print the metadata of a factor file (an EXR written by `factor`) to out:
 * texture size, term and J, sigma_j per channel (of every term whose g file
 * sits in the same folder), parameterisation, source, form, method and
 * rel_rms per J; with json one JSON object (sigma of this term only; set,
 * may be NULL: the folder whose first texture it is, named first).
 * Returns an exit code (EXIT_IO: unreadable, not an EXR, or an EXR
 * without the sepbrdf attributes), message printed. */
int info_exr(const char *path, FILE *out, int json, const char *set);
/* Whether path is a sampler's tables (named sampler.bin, or starting with
 * "sbsampl1"); print them (sizes, layers, shares; with json one JSON
 * object; out NULL: the check alone) after checking them as the GLSL sampler
 * reads them (info_sampler.c): an exit code (EXIT_IO: damaged, the layer and
 * texel said). */
int info_is_sampler(const char *path);
int info_sampler(const char *path, FILE *out, int json);

#endif
