/* sepbrdf batch: the factor job over many materials (folders, globs, a CSV
 * manifest), one output set per material, parallel, resumable, with a
 * summary.  Options are those of `factor` (the shared table); a manifest's
 * columns are parsed by the same table, row by row. */
#include <dirent.h>
#include <errno.h>
#include <glob.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "batch.h"

#define DEFAULT_OUT "sepbrdf-batch"
#define MAX_ITEMS 4096

#define MAX_MANIFEST (16u << 20) /* bytes of a manifest */
#define MAX_COLUMNS 64

typedef struct batch {
    batch_item_t *items;
    size_t n;
    sb_job_opts_t base;
    size_t jobs;  /* -j; 0: default_jobs */
    char **owned; /* strings the items point into (manifests' texts, paths) */
    size_t nowned;
} batch_t;

/* The options of `batch` alone (stored into its batch_t). */
static const cli_option_t batch_only[] = {
    {"-j", "--jobs", "N",
     "materials at a time, each its own process (default:\nthe cores, fewer when the matrices would not fit in\nthe "
     "available memory)",
     cli_set_size, offsetof(batch_t, jobs), 1, 64, CLI_OWN},
    {0},
};

static void help(void) {
    printf("usage: sepbrdf batch INPUT... [OPTIONS]\n"
           "\n"
           "Factor many materials as `sepbrdf factor` does, one output folder each\n"
           "(OUT/NAME, published whole), several at a time, and write OUT/summary.csv,\n"
           "OUT/summary.json and a table ranked by headline error to stdout.\n"
           "\n"
           "INPUT  a measured file or model spec; a folder (its files, except hidden ones\n"
           "       and *.md, *.txt, *.json, and *.csv but gonio tables: said on stderr); a\n"
           "       quoted glob ('data/*.binary'); a gonio table FILE.csv (its header names\n"
           "       theta_i); or a manifest FILE.csv: a header line naming `source` and any options of\n"
           "       `factor` without dashes (param, form, terms, res, method, theta-max or\n"
           "       theta_max, ...; another column is an error), then\n"
           "       one material per row (empty cell: the command line's value; a flag:\n"
           "       1 or 0, weighted 0 meaning unweighted; a relative file is found\n"
           "       beside the manifest).  Read as CSV: a cell holding a comma is quoted\n"
           "       (\"microfacet:base=gold,roughness=0.3\"),\n"
           "       a row with more cells than the header is an error.\n"
           "NAME   the file name without its extension, or the spec with other\n"
           "       characters than letters, digits, '-' and '.' as '_'; a manifest row\n"
           "       that sets param appends _PARAM, one that sets terms _JN (several\n"
           "       layouts and J of one material); a name past 80 characters (a\n"
           "       PARAM past 30) keeps its start and a hash of the whole.\n"
           "\n"
           "A material whose folder already holds a complete set of the same settings\n"
           "is reused (a batch interrupted and run again finishes the rest). A material\n"
           "that fails is reported in the summary and the others finish; the exit\n"
           "status is then 2.  OUT/summary.csv and summary.json are removed when a run\n"
           "starts and rebuilt at its end from what the folders hold (an interrupted\n"
           "run leaves none).  One batch at a time writes into OUT: a second one is\n"
           "refused (exit 2) while the first, or any of its processes, runs.\n"
           "\n"
           "On a cluster: `mpirun -np N sepbrdf-mpi batch ...` (or srun; sepbrdf-mpi is\n"
           "built where MPI is found) hands the materials to N - 1 ranks, one at a\n"
           "time, into the same OUT; rank 0 writes the summary.\n"
           "\n"
           "options:\n"
           "  -o, --out DIR        output folder (default ./" DEFAULT_OUT ")\n");
    cli_table_help(batch_only, CLI_OWN);
    cli_table_help(cli_factor_options, CLI_FACTOR);
    printf(CLI_MEASURED_HELP CLI_VERBOSITY_HELP "\n" CLI_EXIT_HELP);
}

/* c as a character of a folder's name: letters, digits, '-' and '.' (not
 * first), others '_'. */
static char name_char(char c, int first) {
    int keep =
        (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '-' || (c == '.' && !first);
    return keep ? c : '_';
}

/* s[0..n) as folder-name characters into buf; longer than keep, its first
 * keep - 9 characters and a hash of the whole (FNV-1a), so that long
 * names stay apart and fit a file system's limit. */
static void short_name(const char *s, size_t n, size_t keep, char *buf, size_t size) {
    unsigned long long h = batch_fnv1a(BATCH_FNV_START, s, n);
    size_t k = 0, take = n <= keep ? n : keep - 9;
    for (; k < take && k + 1 < size; k++)
        buf[k] = name_char(s[k], k == 0);
    buf[k] = 0;
    if (n > keep) snprintf(buf + k, size - k, "-%08llx", h & 0xffffffffull);
}

/* A folder's name from spec or file into buf: see help. */
static void item_name(const char *source, const char *suffix, char *buf, size_t size) {
    const char *base = source;
    size_t n = strlen(source);
    struct stat st;
    if (strchr(source, '/') || (stat(source, &st) == 0 && S_ISREG(st.st_mode))) {
        const char *slash = strrchr(source, '/'), *dot;
        base = slash ? slash + 1 : source;
        dot = strrchr(base, '.');
        n = dot && dot != base ? (size_t)(dot - base) : strlen(base);
    }
    short_name(base, n, 80, buf, size);
    size_t k = strlen(buf);
    if (suffix) snprintf(buf + k, size - k, "%s", suffix);
}

/* Keep s (malloc'd) until the batch ends; s, or NULL when out of memory. */
static char *own(batch_t *b, char *s) {
    char **grown = s ? realloc(b->owned, (b->nowned + 1) * sizeof *grown) : NULL;
    if (!grown) {
        free(s);
        cli_error("batch", "out of memory");
        return NULL;
    }
    b->owned = grown;
    return b->owned[b->nowned++] = s;
}

static char *own_copy(batch_t *b, const char *s) {
    char *c = malloc(strlen(s) + 1);
    return own(b, c ? strcpy(c, s) : NULL);
}

/* source and the strings of o must live as long as the batch (own). */
static int add(batch_t *b, const char *source, const sb_job_opts_t *o, const char *suffix) {
    if (b->n == MAX_ITEMS) {
        cli_error("batch", "more than %d materials", MAX_ITEMS);
        return -1;
    }
    batch_item_t *it = &b->items[b->n];
    memset(it, 0, sizeof *it);
    it->source = source;
    it->o = *o;
    item_name(source, suffix, it->name, sizeof it->name);
    for (size_t i = 0; i < b->n; i++)
        if (strcmp(b->items[i].name, it->name) == 0) {
            cli_error("batch", "'%s' and '%s' would both be written to %s/", b->items[i].source, source, it->name);
            return -1;
        }
    b->n++;
    if (batch_key(it) != 0) {
        cli_error("batch", "out of memory");
        return -1;
    }
    return 0;
}

/* The next CSV cell at *p, unquoted in place ("" in quotes: one quote; a
 * quoted cell may hold commas and line breaks); *end = 1 at the end of its
 * row, *lines += the line breaks passed.  NULL on a quote left open. */
static char *csv_cell(char **p, int *end, int *lines) {
    char *s = *p, *w = s, *cell = s;
    int quoted = *s == '"';
    for (s += quoted; *s && (quoted || (*s != ',' && *s != '\n' && *s != '\r')); s++) {
        if (quoted && *s == '"') {
            if (s[1] != '"') {
                quoted = 0;
                continue;
            }
            s++;
        }
        *lines += *s == '\n';
        *w++ = *s;
    }
    if (quoted) return NULL;
    char sep = *s;
    s += sep == '\r' && s[1] == '\n';
    *lines += *s == '\n';
    *end = sep != ',';
    *p = *s ? s + 1 : s;
    *w = 0;
    return cell;
}

/* The cells of the row at *p into cells[max] (their count; -1 when more than
 * max, -2 on an open quote); *lines counts the line breaks. */
static int csv_row(char **p, char **cells, int max, int *lines) {
    int n = 0, end = 0;
    while (!end) {
        char *c = csv_cell(p, &end, lines);
        if (!c) return -2;
        if (n == max) return -1;
        cells[n++] = c;
    }
    return n;
}

/* The folder suffix of a row's layout: _PARAM, or for a long spec (a warp
 * table) its start and a hash of the whole, so two long specs stay apart. */
static void param_suffix(const char *param, char *buf, size_t size) {
    buf[0] = '_';
    short_name(param, strlen(param), 30, buf + 1, size - 1);
}

/* The option of manifest column `col` set to `cell` in o; 0 or -1 (message
 * printed). */
static int manifest_cell(sb_job_opts_t *o, const char *file, int line, const char *col, char *cell) {
    char flag[48];
    const cli_option_t *op = NULL;
    int m = 0;
    if (strlen(col) < 40) {
        snprintf(flag, sizeof flag, "--%s", col);
        /* a flag's cell replaces the command line's (weighted 1 after
         * --unweighted is no contradiction): the flag cleared first */
        for (const cli_option_t *t = cli_factor_options; t->name; t++)
            if (!t->arg && strcmp(t->name, flag) == 0) *(int *)((char *)o + t->offset) = 0;
        char *argv[3] = {"batch", flag, cell};
        cli_args_t a = {3, 1, argv, "batch"};
        m = cli_table_opt(&a, cli_factor_options, CLI_FACTOR, o, &op);
    }
    if (m == 1 && op && !op->arg && strcmp(cell, "0") != 0 && strcmp(cell, "1") != 0) {
        cli_error("batch", "%s:%d: column '%s': '%s' for a flag, need 1 or 0", file, line, col, cell);
        return -1;
    }
    /* a flag at 0: off; a pair on one setting (weighted and unweighted,
     * stored as 1 and -1) at 0: the other of the pair, as its name says */
    if (m == 1 && op && !op->arg && strcmp(cell, "0") == 0) *(int *)((char *)o + op->offset) = -(int)op->lo;
    if (m == 1) return 0;
    cli_error("batch", "%s:%d: column '%s': %s", file, line, col, m ? "bad value" : "not an option of factor");
    return -1;
}

/* One manifest row: cells by the header's columns, through the option
 * tables; the strings stay in the manifest's text, owned by the batch. */
static int manifest_row(batch_t *b, const char *file, int line, char **cols, char **cells, int nc) {
    sb_job_opts_t o = b->base;
    const char *source = NULL, *param = NULL;
    char suffix[64] = "";
    int terms = 0; /* the row sets terms */
    for (int c = 0; c < nc; c++) {
        if (!cells[c][0]) continue;
        if (strcmp(cols[c], "source") == 0) {
            source = cells[c];
        } else if (manifest_cell(&o, file, line, cols[c], cells[c]) != 0) {
            return -1;
        } else {
            param = strcmp(cols[c], "param") == 0 ? o.param : param;
            terms |= strcmp(cols[c], "terms") == 0;
        }
    }
    if (!source) {
        cli_error("batch", "%s:%d: no source", file, line);
        return -1;
    }
    /* a relative file is found beside the manifest */
    const char *slash = strrchr(file, '/');
    size_t nd = slash ? (size_t)(slash - file) : 1;
    char *near = malloc(nd + strlen(source) + 2);
    if (!near) return -1;
    sprintf(near, "%.*s/%s", (int)nd, slash ? file : ".", source);
    if (source[0] != '/' && access(near, F_OK) == 0) {
        if (!(source = own(b, near))) return -1;
    } else {
        free(near);
    }
    if (param) param_suffix(param, suffix, sizeof suffix);
    if (terms) snprintf(suffix + strlen(suffix), sizeof suffix - strlen(suffix), "_J%zu", o.terms);
    return add(b, source, &o, suffix[0] ? suffix : NULL);
}

/* Whether column `col` names an option of factor (its name without the
 * dashes); '_' is read as '-', as the Python package writes the options
 * (theta_max), in place. */
static int manifest_column(char *col) {
    for (char *q = col; *q; q++)
        if (*q == '_') *q = '-';
    for (const cli_option_t *t = cli_factor_options; t->name; t++)
        if ((t->commands & CLI_FACTOR) && strcmp(t->name + 2, col) == 0) return 1;
    return 0;
}

/* The header's columns into cols (their count) or -1 (message printed).
 * A column that names no option of factor is an error here, not at the
 * first row whose cell is not empty (rows with it empty ran without it). */
static int manifest_header(const char *file, char **p, char **cols, int *lines) {
    int ncols = csv_row(p, cols, MAX_COLUMNS, lines), has_source = 0;
    for (int c = 0; c < ncols; c++)
        has_source |= strcmp(cols[c], "source") == 0;
    if (ncols < 0)
        cli_error("batch", "%s:1: %s", file, ncols == -2 ? "a quoted cell is never closed" : "too many columns");
    else if (!has_source)
        cli_error("batch", "%s: the header line names no 'source' column", file);
    for (int c = 0; ncols > 0 && has_source && c < ncols; c++)
        if (strcmp(cols[c], "source") != 0 && !manifest_column(cols[c])) {
            cli_error("batch",
                      "%s:1: column '%s': not an option of factor (its name without the dashes, e.g. terms, "
                      "theta-max or theta_max; `sepbrdf factor --help`)",
                      file, cols[c]);
            return -1;
        }
    return ncols > 0 && has_source ? ncols : -1;
}

/* A manifest, read as CSV is (RFC 4180: quoted cells with commas, quotes
 * and line breaks): a header, then one material per row. */
static int manifest(batch_t *b, const char *file) {
    char *text, *cols[MAX_COLUMNS], *cells[MAX_COLUMNS];
    size_t len, rows = 0;
    int e = cli_read_file(file, MAX_MANIFEST, &text, &len), lines = 0;
    if (e) {
        cli_error("batch", "%s: %s", file, cli_read_why(e));
        return EXIT_IO;
    }
    if (!own(b, text)) return EXIT_IO;
    if (memchr(text, 0, len)) {
        cli_error("batch", "%s: not a CSV manifest (it holds NUL bytes)", file);
        return EXIT_IO;
    }
    char *p = text;
    int ncols = manifest_header(file, &p, cols, &lines);
    if (ncols < 0) return EXIT_USAGE;
    while (*p) {
        int at = lines + 1, nc = csv_row(&p, cells, MAX_COLUMNS, &lines);
        if (nc == 1 && !cells[0][strspn(cells[0], " \t")]) continue; /* a blank line */
        if (nc == -2) {
            cli_error("batch", "%s:%d: a quoted cell is never closed", file, at);
            return EXIT_USAGE;
        }
        if (nc < 0 || nc > ncols) {
            cli_error("batch", "%s:%d: more cells than the header's %d columns (quote a cell holding a comma: \"a,b\")",
                      file, at, ncols);
            return EXIT_USAGE;
        }
        if (manifest_row(b, file, at, cols, cells, nc) != 0) return EXIT_USAGE;
        rows++;
    }
    if (!rows) {
        cli_error("batch", "%s: no material rows after the header line", file);
        return EXIT_USAGE;
    }
    return EXIT_OK;
}

static int skip_name(const char *name) {
    static const char *const ext[] = {".md", ".txt", ".csv", ".json"};
    size_t n = strlen(name);
    if (name[0] == '.') return 1;
    for (size_t k = 0; k < sizeof ext / sizeof ext[0]; k++)
        if (n > strlen(ext[k]) && strcmp(name + n - strlen(ext[k]), ext[k]) == 0) return 1;
    return 0;
}

/* Whether the .csv file at path is a gonio table (sepbrdf CSV, a
 * material: its header, the first line not a comment, names theta_i)
 * rather than a manifest (which names source). */
static int gonio_csv(const char *path) {
    struct stat st;
    if (stat(path, &st) != 0 || !S_ISREG(st.st_mode)) return 0; /* a FIFO is not opened (manifest() says so) */
    FILE *fp = fopen(path, "r");
    char line[1024];
    int is = 0;
    while (fp && fgets(line, sizeof line, fp))
        if (line[0] != '#' && line[strspn(line, " \t\r\n")]) {
            is = strstr(line, "theta_i") != NULL && strstr(line, "source") == NULL;
            break;
        }
    if (fp) fclose(fp);
    return is;
}

static int cmp_str(const void *a, const void *b) { return strcmp(*(char *const *)a, *(char *const *)b); }

/* One INPUT: manifest, folder, glob or source. */
static int input(batch_t *b, const char *in) {
    struct stat st;
    size_t n = strlen(in), before = b->n;
    int isdir = stat(in, &st) == 0 && S_ISDIR(st.st_mode);
    if (!isdir && n > 4 && strcmp(in + n - 4, ".csv") == 0 && access(in, F_OK) == 0 && !gonio_csv(in))
        return manifest(b, in);
    glob_t g = {0};
    int rc = EXIT_OK;
    if (isdir) {
        char *pattern = malloc(n + 3);
        if (pattern) sprintf(pattern, "%s/*", in), glob(pattern, 0, NULL, &g);
        free(pattern);
    } else if (!strpbrk(in, "*?[")) {
        return add(b, in, &b->base, NULL) ? EXIT_USAGE : EXIT_OK;
    } else if (glob(in, 0, NULL, &g) != 0) {
        cli_error("batch", "'%s' matches no file", in);
        return EXIT_IO;
    }
    if (g.gl_pathc) qsort(g.gl_pathv, g.gl_pathc, sizeof *g.gl_pathv, cmp_str);
    size_t skipped = 0;
    char names[160] = "";
    for (size_t i = 0; i < g.gl_pathc && rc == EXIT_OK; i++) {
        const char *slash = strrchr(g.gl_pathv[i], '/'), *path, *name = slash ? slash + 1 : g.gl_pathv[i];
        if (stat(g.gl_pathv[i], &st) != 0 || !S_ISREG(st.st_mode)) continue;
        if (skip_name(name) && !(name[0] != '.' && strlen(name) > 4 && !strcmp(name + strlen(name) - 4, ".csv") &&
                                 gonio_csv(g.gl_pathv[i]))) {
            if (name[0] != '.' && skipped++ < 3)
                snprintf(names + strlen(names), sizeof names - strlen(names), "%s%s", skipped > 1 ? ", " : "", name);
            continue;
        }
        if (!(path = own_copy(b, g.gl_pathv[i])) || add(b, path, &b->base, NULL)) rc = EXIT_USAGE;
    }
    globfree(&g);
    if (rc == EXIT_OK && skipped)
        cli_info(1, "batch: '%s': %zu file%s skipped (*.md, *.txt, *.json, CSV files that are no gonio table): %s%s",
                 in, skipped, skipped == 1 ? "" : "s", names, skipped > 3 ? ", ..." : "");
    if (rc == EXIT_OK && b->n == before) {
        cli_error(
            "batch",
            "'%s': no material file %s (hidden files, *.md, *.txt, *.json and CSV files that are no gonio table are "
            "skipped)",
            in, isdir ? "in this folder" : "matches");
        rc = EXIT_IO;
    }
    return rc;
}

/* Default -j: the cores, bounded by the available memory over an estimate
 * of one material's peak (three channels of the largest io-sized matrix
 * and as much again for the SVD's work). */
static size_t default_jobs(const batch_t *b) {
    long cores = sysconf(_SC_NPROCESSORS_ONLN), pages = sysconf(_SC_AVPHYS_PAGES), psz = sysconf(_SC_PAGESIZE);
    size_t jobs = cores > 0 ? (size_t)cores : 1;
    double peak = 0;
    for (size_t i = 0; i < b->n; i++) {
        double r = (double)(b->items[i].o.res ? b->items[i].o.res : 32), cells = r * r * r * r;
        if (6 * 8 * cells > peak) peak = 6 * 8 * cells;
    }
    if (pages > 0 && psz > 0 && peak > 0) {
        double fit = (double)pages * (double)psz / peak;
        if (fit < (double)jobs) jobs = fit < 1 ? 1 : (size_t)fit;
    }
    return jobs < b->n ? jobs : (b->n ? b->n : 1);
}

static int parse(int argc, char **argv, batch_t *b, const char **out, const char **inputs, size_t *ninputs) {
    cli_parser_t p = {.cmd = "batch",
                      .help = help,
                      .out_what = "folder",
                      .out = out,
                      .tables = {{batch_only, CLI_OWN, b, NULL}, {cli_factor_options, CLI_FACTOR, &b->base, NULL}},
                      .measured = &b->base.measured,
                      .what = "INPUT",
                      .args = inputs,
                      .max_args = (size_t)argc,
                      .nargs = ninputs};
    int rc = cli_parse(argc, argv, &p);
    if (rc < 0 && !*ninputs) {
        cli_error("batch", "no INPUT given (see `sepbrdf batch --help`)");
        return EXIT_USAGE;
    }
    return rc;
}

/* Rank 0 (or the one process): the items not done, run, then the summary
 * from what the folders hold; the exit code. */
static int run(batch_t *b, const char *out, int rank, int size) {
    size_t reused = 0, failed = 0;
    if (rank == 0 && batch_summary_remove(out) != EXIT_OK) return EXIT_IO;
    for (size_t i = 0; i < b->n && rank == 0; i++) /* only rank 0 hands out work */
        reused += b->items[i].skipped = batch_done(out, &b->items[i]);
    if (!b->jobs) b->jobs = default_jobs(b);
    if (size > 1)
        cli_info(1, "batch: %zu materials, %zu reused, over %d ranks", b->n, reused, size - 1);
    else
        cli_info(1, "batch: %zu materials, %zu reused, %zu at a time", b->n, reused, b->jobs);
#ifdef SEPBRDF_MPI
    batch_mpi_run(out, b->items, b->n, b->jobs, rank, size);
    if (rank != 0) return EXIT_OK; /* rank 0 writes the summary */
#else
    (void)size;
    batch_run(out, b->items, b->n, b->jobs);
#endif
    batch_reread(out, b->items, b->n); /* the summary says what the folders hold */
    for (size_t i = 0; i < b->n; i++)
        if (!b->items[i].ok) {
            failed++;
            cli_error("batch", "%s (%s): %s", b->items[i].name, b->items[i].source, b->items[i].msg);
        }
    int rc = batch_summary(out, b->items, b->n);
    if (g_verbosity >= 1) batch_table(b->items, b->n);
    return rc == EXIT_OK && failed ? EXIT_IO : rc;
}

int cmd_batch(int argc, char **argv) {
    batch_t b = {calloc(MAX_ITEMS, sizeof(batch_item_t)), 0, {0}, 0, NULL, 0};
    const char *out = DEFAULT_OUT, **inputs = calloc((size_t)argc + 1, sizeof *inputs);
    size_t ninputs = 0;
    int rc, rank = 0, size = 0, lock = -1; /* MPI: this rank, the ranks (0: MPI not started) */
    if (!b.items || !inputs) {
        cli_error("batch", "out of memory");
        rc = EXIT_IO;
        goto done;
    }
#ifdef SEPBRDF_MPI
    if (batch_mpi_begin(&rank, &size) != 0) {
        cli_error("batch", "MPI_Init failed");
        rc = EXIT_IO;
        goto done;
    }
    if (rank != 0) g_verbosity = g_verbosity > 0 ? 0 : g_verbosity; /* rank 0 reports */
#endif
    if ((rc = parse(argc, argv, &b, &out, inputs, &ninputs)) >= 0) goto done;
    rc = EXIT_OK;
    for (size_t i = 0; i < ninputs && rc == EXIT_OK; i++)
        rc = input(&b, inputs[i]);
    if (rc != EXIT_OK) goto done;
    if (mkdir(out, 0777) != 0 && errno != EEXIST) {
        cli_error("batch", "--out %s: %s", out, sb_io_why(errno));
        rc = EXIT_IO;
        goto done;
    }
    if (rank == 0 && (lock = batch_lock(out)) < 0) {
#ifdef SEPBRDF_MPI
        batch_mpi_run(out, b.items, 0, 1, rank, size); /* no work: the other ranks stop */
#endif
        rc = EXIT_IO;
        goto done;
    }
    rc = run(&b, out, rank, size);
done:
    batch_unlock(lock);
#ifdef SEPBRDF_MPI
    if (size > 0) batch_mpi_end();
#endif
    for (size_t i = 0; b.items && i < b.n; i++)
        free(b.items[i].key), free(b.items[i].fields);
    for (size_t i = 0; i < b.nowned; i++)
        free(b.owned[i]);
    free(b.owned);
    free(b.items);
    free(inputs);
    return rc;
}
