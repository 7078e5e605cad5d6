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

typedef struct batch {
    batch_item_t *items;
    size_t n;
    sb_job_opts_t base;
    size_t jobs; /* -j; 0: default_jobs */
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
           "       and *.md, *.txt, *.csv, *.json); a quoted glob ('data/*.binary'); or a\n"
           "       manifest FILE.csv: a header line naming `source` and any options of\n"
           "       `factor` without dashes (param, form, terms, res, method, ...), then\n"
           "       one material per row (empty cell: the command line's value; a flag:\n"
           "       1 or 0; a relative file is found beside the manifest).\n"
           "NAME   the file name without its extension, or the spec with other\n"
           "       characters than letters, digits, '-' and '.' as '_'; a manifest row\n"
           "       that sets param appends _PARAM, one that sets terms _JN (several\n"
           "       layouts and J of one material).\n"
           "\n"
           "A material whose folder already holds a complete set of the same settings\n"
           "is reused (a batch interrupted and run again finishes the rest). A material\n"
           "that fails is reported in the summary and the others finish; the exit\n"
           "status is then 2.\n"
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
    size_t k = 0;
    for (size_t i = 0; i < n && k + 1 < size; i++, k++) {
        char c = base[i];
        int keep = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '-' ||
                   (c == '.' && k > 0);
        buf[k] = keep ? c : '_';
    }
    buf[k] = 0;
    if (suffix) snprintf(buf + k, size - k, "%s", suffix);
}

static int add(batch_t *b, const char *source, const sb_job_opts_t *o, const char *suffix) {
    if (b->n == MAX_ITEMS) {
        cli_error("batch", "more than %d materials", MAX_ITEMS);
        return -1;
    }
    batch_item_t *it = &b->items[b->n];
    memset(it, 0, sizeof *it);
    snprintf(it->source, sizeof it->source, "%.1023s", source);
    it->o = *o;
    /* the row's strings live in the item, the table stored pointers */
    if (o->param) snprintf(it->param, sizeof it->param, "%s", o->param), it->o.param = it->param;
    if (o->form) snprintf(it->form, sizeof it->form, "%s", o->form), it->o.form = it->form;
    item_name(source, suffix, it->name, sizeof it->name);
    for (size_t i = 0; i < b->n; i++)
        if (strcmp(b->items[i].name, it->name) == 0) {
            cli_error("batch", "'%s' and '%s' would both be written to %s/", b->items[i].source, source, it->name);
            return -1;
        }
    batch_key(it);
    b->n++;
    return 0;
}

/* Next CSV field of *p (quotes allowed) into buf; 1 while the line goes on. */
static int csv_next(const char **p, char *buf, size_t size) {
    const char *s = *p;
    size_t k = 0;
    int quoted = *s == '"';
    for (s += quoted; *s && (quoted || (*s != ',' && *s != '\n' && *s != '\r')); s++) {
        if (quoted && *s == '"') {
            if (s[1] != '"') {
                quoted = 0;
                continue;
            }
            s++;
        }
        if (k + 1 < size) buf[k++] = *s;
    }
    buf[k] = 0;
    *p = *s == ',' ? s + 1 : s;
    return *s == ',';
}

/* One manifest row: cells by the header's columns, through the option tables. */
static int manifest_row(batch_t *b, const char *file, int line, char cols[][32], int ncols, const char *row) {
    sb_job_opts_t o = b->base;
    char cells[32][1000], flag[40], source[1000] = "", suffix[64] = "";
    const char *param = NULL;
    int terms = 0; /* the row sets terms */
    int nc = 0;
    for (int more = 1; more && nc < ncols; nc++)
        more = csv_next(&row, cells[nc], sizeof cells[nc]);
    for (int c = 0; c < nc; c++) {
        if (!cells[c][0]) continue;
        if (strcmp(cols[c], "source") == 0) {
            snprintf(source, sizeof source, "%.999s", cells[c]);
            continue;
        }
        snprintf(flag, sizeof flag, "--%.31s", cols[c]);
        char *argv[3] = {"batch", flag, cells[c]};
        cli_args_t a = {3, 1, argv, "batch"};
        const cli_option_t *op = NULL;
        int m = cli_table_opt(&a, cli_factor_options, CLI_FACTOR, &o, &op);
        if (m == 1 && op && !op->arg && strcmp(cells[c], "0") == 0) *(int *)((char *)&o + op->offset) = 0;
        if (m != 1) {
            cli_error("batch", "%s:%d: column '%s': %s", file, line, cols[c], m ? "bad value" : "not an option");
            return -1;
        }
        if (strcmp(cols[c], "param") == 0) param = o.param;
        terms |= strcmp(cols[c], "terms") == 0;
    }
    if (!source[0]) {
        cli_error("batch", "%s:%d: no source", file, line);
        return -1;
    }
    /* a relative file is found beside the manifest */
    const char *slash = strrchr(file, '/');
    char near[2200];
    snprintf(near, sizeof near, "%.*s/%s", slash ? (int)(slash - file) : 1, slash ? file : ".", source);
    if (param) snprintf(suffix, sizeof suffix, "_%.30s", param);
    if (terms) snprintf(suffix + strlen(suffix), sizeof suffix - strlen(suffix), "_J%zu", o.terms);
    return add(b, source[0] != '/' && access(near, F_OK) == 0 ? near : source, &o, suffix[0] ? suffix : NULL);
}

static int manifest(batch_t *b, const char *file) {
    FILE *fp = fopen(file, "r");
    if (!fp) {
        cli_error("batch", "%s: %s", file, strerror(errno));
        return EXIT_IO;
    }
    char line[8192], cols[32][32];
    int ncols = 0, ln = 0, rc = EXIT_OK, has_source = 0;
    while (rc == EXIT_OK && fgets(line, sizeof line, fp)) {
        ln++;
        const char *p = line;
        if (ln == 1) {
            for (int more = 1; more && ncols < 32; ncols++) {
                more = csv_next(&p, cols[ncols], sizeof cols[ncols]);
                has_source |= strcmp(cols[ncols], "source") == 0;
            }
            if (!has_source) {
                cli_error("batch", "%s: the header line names no 'source' column", file);
                rc = EXIT_USAGE;
            }
        } else if (line[strspn(line, " \t\r\n")] && manifest_row(b, file, ln, cols, ncols, p) != 0) {
            rc = EXIT_USAGE;
        }
    }
    fclose(fp);
    return rc;
}

static int skip_name(const char *name) {
    static const char *const ext[] = {".md", ".txt", ".csv", ".json"};
    size_t n = strlen(name);
    if (name[0] == '.') return 1;
    for (size_t k = 0; k < sizeof ext / sizeof ext[0]; k++)
        if (n > strlen(ext[k]) && strcmp(name + n - strlen(ext[k]), ext[k]) == 0) return 1;
    return 0;
}

static int cmp_str(const void *a, const void *b) { return strcmp(*(char *const *)a, *(char *const *)b); }

/* One INPUT: manifest, folder, glob or source. */
static int input(batch_t *b, const char *in) {
    struct stat st;
    size_t n = strlen(in);
    int isdir = stat(in, &st) == 0 && S_ISDIR(st.st_mode);
    if (!isdir && n > 4 && strcmp(in + n - 4, ".csv") == 0 && access(in, F_OK) == 0) return manifest(b, in);
    glob_t g = {0};
    int rc = EXIT_OK;
    if (isdir) {
        char pattern[4200];
        snprintf(pattern, sizeof pattern, "%s/*", in);
        glob(pattern, 0, NULL, &g);
    } else if (strpbrk(in, "*?[") && glob(in, 0, NULL, &g) != 0) {
        cli_error("batch", "'%s' matches no file", in);
        return EXIT_IO;
    }
    if (!g.gl_pathc) {
        rc = isdir ? EXIT_OK : add(b, in, &b->base, NULL) ? EXIT_USAGE : EXIT_OK;
        globfree(&g);
        return rc;
    }
    qsort(g.gl_pathv, g.gl_pathc, sizeof *g.gl_pathv, cmp_str);
    for (size_t i = 0; i < g.gl_pathc && rc == EXIT_OK; i++) {
        const char *slash = strrchr(g.gl_pathv[i], '/');
        if (stat(g.gl_pathv[i], &st) != 0 || !S_ISREG(st.st_mode) || skip_name(slash ? slash + 1 : g.gl_pathv[i]))
            continue;
        if (add(b, g.gl_pathv[i], &b->base, NULL)) rc = EXIT_USAGE;
    }
    globfree(&g);
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

int cmd_batch(int argc, char **argv) {
    batch_t b = {calloc(MAX_ITEMS, sizeof(batch_item_t)), 0, {0}, 0};
    const char *out = DEFAULT_OUT, **inputs = calloc((size_t)argc + 1, sizeof *inputs);
    size_t ninputs = 0;
    int rc, rank = 0, size = 0; /* MPI: this rank, the ranks (0: MPI not started) */
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
    size_t reused = 0;
    for (size_t i = 0; i < b.n && rank == 0; i++) /* only rank 0 hands out work */
        reused += b.items[i].skipped = batch_done(out, &b.items[i]);
    if (!b.jobs) b.jobs = default_jobs(&b);
    if (size > 1)
        cli_info(1, "batch: %zu materials, %zu reused, over %d ranks", b.n, reused, size - 1);
    else
        cli_info(1, "batch: %zu materials, %zu reused, %zu at a time", b.n, reused, b.jobs);
#ifdef SEPBRDF_MPI
    batch_mpi_run(out, b.items, b.n, b.jobs, rank, size);
    if (rank != 0) goto done; /* rank 0 writes the summary */
#else
    batch_run(out, b.items, b.n, b.jobs);
#endif
    size_t failed = 0;
    for (size_t i = 0; i < b.n; i++)
        if (!b.items[i].ok) {
            failed++;
            cli_error("batch", "%s (%s): %s", b.items[i].name, b.items[i].source, b.items[i].msg);
        }
    rc = batch_summary(out, b.items, b.n);
    if (g_verbosity >= 1) batch_table(b.items, b.n);
    if (rc == EXIT_OK && failed) rc = EXIT_IO;
done:
#ifdef SEPBRDF_MPI
    if (size > 0) batch_mpi_end();
#endif
    free(b.items);
    free(inputs);
    return rc;
}
