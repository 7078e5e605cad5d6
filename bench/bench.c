/* sepbrdf benchmark: time, error and memory of the factor step per method
 * (see bench.h).  Built twice: as the `sepbrdf_bench` executable (with the
 * main() at the end) and into the CLI as `sepbrdf bench` (SB_BENCH_NO_MAIN).
 *
 * Timing protocol: wall clock (CLOCK_MONOTONIC).  A configuration whose
 * factor step is short is repeated until it has run for --min-time seconds
 * (at most 5 times) and the fastest run is kept, which filters out the
 * noise of other processes on a shared machine.  FULL computes the same
 * exact triplets for every J up to the largest asked in the same time, so
 * it runs once per size at the largest J and its rows for smaller J are
 * read from the same factors (marked reused=1); TOPK's time grows with J,
 * so it runs at every J like the other methods. */
#include "bench.h"

#include <cblas.h>
#include <errno.h>
#include <lapacke.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "sb_plot_gp.h" /* sb_plot_gp_[]: bench/plot.gp, embedded by CMake */
#include "sepbrdf/sepbrdf.h"

#define MAXL 16
#define DEFAULT_MODEL "microfacet:base=gold,roughness=0.5"
#define DEFAULT_METHODS "full,topk,randomized:hmt,randomized:q=1,randomized,randomized:f32,auto"

typedef struct method_spec {
    char label[48];
    sb_svd_opts_t svd;
} method_spec_t;

typedef struct bench_opts {
    size_t sizes[MAXL], nsizes, terms[MAXL], nterms, nmethods;
    method_spec_t methods[MAXL];
    const char *model, *out, *prog, *matrices;
    sb_form_t form;
    int fork_runs, verbosity, write, baseline;
    double min_time;
} bench_opts_t;

/* What a run sends back to the parent (through a pipe when forked). */
typedef struct run_result {
    int ok, reps;
    char used[16]; /* the factors' "method": a dense method, or "circulant" for the structured SVD */
    double plan_s, factor_s, svd_s, write_s, peak_mib, base_mib;
    double rel[MAXL]; /* rel_rms for terms[i], when terms[i] <= J of the run */
    char err[200];
} run_result_t;

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

/* ---- memory: VmHWM after resetting it through clear_refs --------------- */

static double status_mib(const char *key) {
    FILE *fp = fopen("/proc/self/status", "r");
    char line[256];
    double v = -1;
    size_t n = strlen(key);
    if (!fp) return -1;
    while (fgets(line, sizeof line, fp))
        if (strncmp(line, key, n) == 0 && line[n] == ':') {
            v = atof(line + n + 1) / 1024;
            break;
        }
    fclose(fp);
    return v;
}
static int reset_peak(void) {
    FILE *fp = fopen("/proc/self/clear_refs", "w");
    if (!fp) return -1;
    int ok = fputs("5", fp) >= 0;
    return fclose(fp) == 0 && ok ? 0 : -1;
}

/* ---- options ------------------------------------------------------------ */

static void help(const char *prog) {
    printf("usage: %s [OPTIONS]\n"
           "\n"
           "Benchmark the factor step: for every size, number of terms and method,\n"
           "wall time per stage (sample, plan, factor, write), relative error, its\n"
           "excess over the Eckart-Young optimum (LAPACK dgesdd: the full method's own\n"
           "errors when it is listed, else singular values only; once per size) and\n"
           "peak memory (each run in its own process).\n"
           "\n"
           "options:\n"
           "  --sizes LIST      matrix sizes N = R*R of the io grid (default 256,1024,2304,4096)\n"
           "  -J, --terms LIST  numbers of terms J (default 1,4,8,16)\n"
           "  --methods LIST    methods, each NAME[:opt:opt...] with NAME auto|full|topk|randomized\n"
           "                    and opt q=Q (power iterations), p=P (oversampling), f32 (single\n"
           "                    precision), hmt (plain subspace iteration, no Krylov basis),\n"
           "                    block=B (default " DEFAULT_METHODS ");\n"
           "                    auto factors an isotropic model on the io grid with the exact\n"
           "                    block-circulant SVD (column `used`: circulant), the others\n"
           "                    always run on the dense matrix\n"
           "  --model SPEC      source: a model spec (see `sepbrdf list`) or a measured\n"
           "                    file (default " DEFAULT_MODEL ")\n"
           "  --form F          f (default), cos, cos2\n"
           "  --quick           sizes 256,1024, terms 4,8: a few seconds\n"
           "  --min-time S      repeat short runs until S seconds, keep the fastest (default 0.3)\n"
           "  --no-fork         run in this process (peak memory then not per run)\n"
           "  --no-write        skip writing the EXR textures\n"
           "  --no-baseline     skip the dgesdd baseline (no excess column; the baseline\n"
           "                    is most of the time of a run at N = 4096)\n"
           "  -o, --out DIR     write DIR/results.csv and DIR/results.png (gnuplot)\n"
           "  --matrices DIR    also write each sampled matrix, DIR/ioN_C.f64 (C = r, g, b:\n"
           "                    raw float64, column-major, N x N) for bench/peers.py;\n"
           "                    both folders are created if missing, before the run\n"
           "  -q, --quiet       no table on stdout\n"
           "  -v, --verbose     also gnuplot's own messages (warnings such as an empty range)\n"
           "  -h, --help        this text\n"
           "\n"
           "OpenBLAS reads OPENBLAS_NUM_THREADS and OPENBLAS_CORETYPE at start-up: set them\n"
           "in the environment to compare thread counts and kernels.\n"
           "\n"
           "exit status: 0 ok, 1 usage (bad option or value), 2 input/output, 3 numerical.\n",
           prog);
}

static int bad(const bench_opts_t *o, const char *fmt, const char *what) {
    fprintf(stderr, "%s: ", o->prog);
    fprintf(stderr, fmt, what);
    fputc('\n', stderr);
    return 1;
}

static int parse_list(const bench_opts_t *o, const char *opt, const char *s, size_t lo, size_t hi, size_t *out,
                      size_t *n) {
    *n = 0;
    while (*s) {
        char *end;
        errno = 0;
        unsigned long long v = strtoull(s, &end, 10);
        if (end == s || (*end && *end != ',') || (*end == ',' && !end[1]) || errno || v < lo || v > hi || *n == MAXL ||
            *s == '-') {
            fprintf(stderr, "%s: %s '%s': need a comma-separated list of at most %d integers in %zu..%zu\n", o->prog,
                    opt, s, MAXL, lo, hi);
            return 1;
        }
        out[(*n)++] = (size_t)v;
        s = *end ? end + 1 : end;
    }
    if (*n == 0) return bad(o, "%s: empty list", opt);
    return 0;
}

/* NAME[:q=Q][:p=P][:f32][:block=B] */
static int parse_method(const bench_opts_t *o, const char *spec, size_t len, method_spec_t *m) {
    char buf[48];
    if (len == 0 || len >= sizeof buf) return bad(o, "--methods: bad method '%s'", spec);
    memcpy(buf, spec, len);
    buf[len] = 0;
    memset(m, 0, sizeof *m);
    memcpy(m->label, buf, len + 1);
    char *save = NULL, *tok = strtok_r(buf, ":", &save);
    if (!tok || sb_method_parse(tok, &m->svd.method) != SB_OK)
        return bad(o, "--methods: unknown method in '%s' (need auto, full, topk or randomized)", m->label);
    while ((tok = strtok_r(NULL, ":", &save))) {
        int v;
        char extra;
        if (strcmp(tok, "f32") == 0)
            m->svd.single_precision = 1;
        else if (strcmp(tok, "hmt") == 0)
            m->svd.krylov = -1;
        else if (sscanf(tok, "q=%d%c", &v, &extra) == 1 && v >= 0 && v <= 20)
            m->svd.power_iters = v ? v : -1;
        else if (sscanf(tok, "p=%d%c", &v, &extra) == 1 && v >= 0 && v <= 1000)
            m->svd.oversample = v ? v : -1;
        else if (sscanf(tok, "block=%d%c", &v, &extra) == 1 && v >= 1 && v <= 100000)
            m->svd.block = (size_t)v;
        else
            return bad(o, "--methods: unknown option in '%s' (q=Q, p=P, f32, hmt, block=B)", m->label);
    }
    return 0;
}

static int parse_methods(bench_opts_t *o, const char *s) {
    o->nmethods = 0;
    while (*s) {
        const char *c = strchr(s, ',');
        size_t len = c ? (size_t)(c - s) : strlen(s);
        if (c && !c[1]) return bad(o, "--methods: an empty item after the last comma (%s)", s);
        if (o->nmethods == MAXL) return bad(o, "--methods: at most 16 methods (%s)", s);
        if (parse_method(o, s, len, &o->methods[o->nmethods++])) return 1;
        s += len + (c != NULL);
    }
    return o->nmethods ? 0 : bad(o, "--methods: empty list%s", "");
}

/* "--opt value" or "--opt=value"; 1 matched, 0 not, -1 missing value */
static int opt(int argc, char **argv, int *i, const char *a, const char *b, const char **val) {
    const char *arg = argv[*i];
    const char *names[2] = {a, b};
    for (int k = 0; k < 2; k++) {
        if (!names[k]) continue;
        size_t n = strlen(names[k]);
        if (strncmp(arg, names[k], n) != 0) continue;
        if (arg[n] == '=' && names[k][1] == '-') {
            *val = arg + n + 1;
            return 1;
        }
        if (arg[n]) continue;
        if (*i + 1 >= argc) return -1;
        *val = argv[++*i];
        return 1;
    }
    return 0;
}

static int parse(int argc, char **argv, bench_opts_t *o) {
    static const size_t sizes[] = {256, 1024, 2304, 4096}, terms[] = {1, 4, 8, 16};
    memcpy(o->sizes, sizes, sizeof sizes);
    o->nsizes = 4;
    memcpy(o->terms, terms, sizeof terms);
    o->nterms = 4;
    if (parse_methods(o, DEFAULT_METHODS)) return 1;
    for (int i = 1; i < argc; i++) {
        const char *v = NULL, *a = argv[i];
        int m;
        if (strcmp(a, "-h") == 0 || strcmp(a, "--help") == 0) {
            help(o->prog);
            return 0;
        }
        if ((m = opt(argc, argv, &i, "--sizes", NULL, &v))) {
            if (m < 0 || parse_list(o, "--sizes", v, 4, 1 << 20, o->sizes, &o->nsizes))
                return m < 0 ? bad(o, "%s needs a value", a) : 1;
            for (size_t k = 0; k < o->nsizes; k++) {
                size_t r = (size_t)llround(sqrt((double)o->sizes[k]));
                if (r * r != o->sizes[k]) return bad(o, "--sizes: %s: every N must be a square R*R (io grid)", v);
            }
        } else if ((m = opt(argc, argv, &i, "--terms", "-J", &v))) {
            if (m < 0 || parse_list(o, "--terms", v, 1, 1 << 20, o->terms, &o->nterms))
                return m < 0 ? bad(o, "%s needs a value", a) : 1;
        } else if ((m = opt(argc, argv, &i, "--methods", NULL, &v))) {
            if (m < 0 || parse_methods(o, v)) return m < 0 ? bad(o, "%s needs a value", a) : 1;
        } else if ((m = opt(argc, argv, &i, "--model", NULL, &v))) {
            if (m < 0) return bad(o, "%s needs a value", a);
            o->model = v;
        } else if ((m = opt(argc, argv, &i, "--form", NULL, &v))) {
            if (m < 0 || sb_form_parse(v, &o->form) != SB_OK) return bad(o, "--form: need f, cos or cos2%s", "");
        } else if ((m = opt(argc, argv, &i, "--min-time", NULL, &v))) {
            char *end;
            if (m < 0) return bad(o, "%s needs a value", a);
            o->min_time = strtod(v, &end);
            if (end == v || *end || !(o->min_time >= 0 && o->min_time <= 60))
                return bad(o, "--min-time '%s': need 0..60 s", v);
        } else if ((m = opt(argc, argv, &i, "-o", "--out", &v))) {
            if (m < 0) return bad(o, "%s needs a folder", a);
            if (!*v) return bad(o, "%s: empty folder name", "--out");
            o->out = v;
        } else if (strcmp(a, "--quick") == 0) {
            o->sizes[0] = 256, o->sizes[1] = 1024, o->nsizes = 2;
            o->terms[0] = 4, o->terms[1] = 8, o->nterms = 2;
        } else if ((m = opt(argc, argv, &i, "--matrices", NULL, &v))) {
            if (m < 0 || !*v) return bad(o, "%s needs a folder", a);
            o->matrices = v;
        } else if (strcmp(a, "--no-fork") == 0) {
            o->fork_runs = 0;
        } else if (strcmp(a, "--no-write") == 0) {
            o->write = 0;
        } else if (strcmp(a, "--no-baseline") == 0) {
            o->baseline = 0;
        } else if (strcmp(a, "-v") == 0 || strcmp(a, "--verbose") == 0 || strcmp(a, "-vv") == 0) {
            o->verbosity = 2; /* gnuplot's own messages too */
        } else if (strcmp(a, "-q") == 0 || strcmp(a, "--quiet") == 0) {
            o->verbosity = 0;
        } else {
            return bad(o, "unknown option or argument '%s' (see --help)", a);
        }
    }
    return -1;
}

/* ---- one run: plan, execute, write, peak memory ------------------------- */

static double write_exr(sb_context_t *ctx, const sb_factors_t *f, run_result_t *r) {
    char dir[] = "/tmp/sepbrdf-bench-XXXXXX";
    if (!mkdtemp(dir)) return -1;
    double t0 = now();
    sb_exr_opts_t eo = {0};
    sb_result_t res = sb_factors_write_exr(ctx, f, dir, &eo);
    double t = now() - t0;
    if (res != SB_OK) snprintf(r->err, sizeof r->err, "write: %s", sb_context_last_error(ctx));
    char name[64], path[128];
    for (size_t j = 0; j < sb_factors_terms(f); j++)
        for (int side = 0; side < 2; side++) {
            sb_exr_name(side, j, name, sizeof name);
            snprintf(path, sizeof path, "%s/%s", dir, name);
            remove(path);
        }
    rmdir(dir);
    return res == SB_OK ? t : -1;
}

static void run_one(const bench_opts_t *o, const sb_matrix_t *m, const sb_param_t *param, size_t J,
                    const method_spec_t *spec, int time_svd, run_result_t *r) {
    memset(r, 0, sizeof *r);
    r->svd_s = r->write_s = -1;
    int have_peak = reset_peak() == 0;
    r->base_mib = status_mib("VmRSS");
    sb_context_t *ctx = NULL;
    sb_plan_t *plan = NULL;
    sb_factors_t *f = NULL;
    if (sb_context_create(&ctx) != SB_OK) {
        snprintf(r->err, sizeof r->err, "out of memory");
        return;
    }
    sb_plan_opts_t po = {0};
    po.terms = J;
    po.svd = spec->svd;
    double t0 = now();
    sb_result_t res = sb_plan_create(ctx, m->rows, m->cols, &po, &plan);
    r->plan_s = now() - t0;
    /* the factor step; short ones repeated, the fastest kept */
    double spent = 0;
    r->factor_s = INFINITY;
    while (res == SB_OK && (r->reps == 0 || (spent < o->min_time && r->reps < 5))) {
        sb_factors_destroy(f);
        f = NULL;
        t0 = now();
        res = sb_plan_execute(plan, m, param, &f);
        double t = now() - t0;
        spent += t;
        if (t < r->factor_s) r->factor_s = t;
        r->reps++;
    }
    if (res != SB_OK) {
        snprintf(r->err, sizeof r->err, "%s", sb_context_last_error(ctx));
        goto done;
    }
    snprintf(r->used, sizeof r->used, "%s", sb_factors_get_meta(f, "method"));
    /* the structured SVD never runs a dense method: no "SVD alone" figure */
    if (strcmp(r->used, "circulant") == 0) time_svd = 0;
    const sb_factor_errors_t *e = sb_factors_errors(f);
    for (size_t i = 0; i < o->nterms; i++)
        if (o->terms[i] <= J) r->rel[i] = e->rel_rms[(o->terms[i] - 1) * 4 + 3];
    if (o->write) r->write_s = write_exr(ctx, f, r);
    r->peak_mib = have_peak ? status_mib("VmHWM") : -1;
    sb_factors_destroy(f);
    f = NULL;
    sb_plan_destroy(plan);
    plan = NULL;
    /* the SVD alone, every channel, so factor_s - svd_s is the rest of the
     * factor step (residual errors, textures) */
    if (time_svd) {
        sb_svd_t *svd;
        size_t N = m->rows;
        double *s = malloc(J * sizeof *s), *U = malloc(N * J * sizeof *U), *V = malloc(N * J * sizeof *V);
        if (s && U && V && sb_svd_create(ctx, N, m->cols, J, &spec->svd, &svd) == SB_OK) {
            double best = INFINITY, spent2 = 0;
            for (int rep = 0; rep < 5 && (rep == 0 || spent2 < o->min_time); rep++) {
                t0 = now();
                for (int c = 0; c < 3; c++)
                    if (m->data[c]) sb_svd_execute(svd, m->data[c], m->ld, s, U, V, NULL, NULL);
                double t = now() - t0;
                spent2 += t;
                if (t < best) best = t;
            }
            r->svd_s = best;
            sb_svd_destroy(svd);
        }
        free(s);
        free(U);
        free(V);
    }
    r->ok = 1;
done:
    sb_factors_destroy(f);
    sb_plan_destroy(plan);
    sb_context_destroy(ctx);
}

/* Run in a child process so that its peak memory is its own. */
static void run_forked(const bench_opts_t *o, const sb_matrix_t *m, const sb_param_t *param, size_t J,
                       const method_spec_t *spec, int time_svd, run_result_t *r) {
    int fd[2];
    if (!o->fork_runs || pipe(fd) != 0) {
        run_one(o, m, param, J, spec, time_svd, r);
        return;
    }
    fflush(NULL);
    pid_t pid = fork();
    if (pid < 0) {
        close(fd[0]);
        close(fd[1]);
        run_one(o, m, param, J, spec, time_svd, r);
        return;
    }
    if (pid == 0) {
        close(fd[0]);
        run_one(o, m, param, J, spec, time_svd, r);
        ssize_t w = write(fd[1], r, sizeof *r);
        _exit(w == (ssize_t)sizeof *r ? 0 : 1);
    }
    close(fd[1]);
    memset(r, 0, sizeof *r);
    size_t got = 0;
    while (got < sizeof *r) {
        ssize_t n = read(fd[0], (char *)r + got, sizeof *r - got);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) break;
        got += (size_t)n;
    }
    close(fd[0]);
    int st = 0;
    waitpid(pid, &st, 0);
    if (got != sizeof *r) {
        memset(r, 0, sizeof *r);
        snprintf(r->err, sizeof r->err, "run died (%s %d)", WIFSIGNALED(st) ? "signal" : "status",
                 WIFSIGNALED(st) ? WTERMSIG(st) : WEXITSTATUS(st));
    }
}

/* ---- driver ------------------------------------------------------------- */

/* DIR/ioN_C.f64: channel C (r, g, b) of the N x N matrix, raw float64
 * column-major, native byte order: the peers (bench/peers.py) factor the
 * very same numbers.  0 on success. */
static int write_matrices(const bench_opts_t *o, const sb_matrix_t *m) {
    for (int c = 0; c < 3; c++) {
        char path[4200];
        snprintf(path, sizeof path, "%s/io%zu_%c.f64", o->matrices, m->rows, "rgb"[c]);
        FILE *fp = m->data[c] ? fopen(path, "wb") : NULL;
        int ok = fp != NULL;
        for (size_t j = 0; ok && j < m->cols; j++)
            ok = fwrite(m->data[c] + j * m->ld, sizeof(double), m->rows, fp) == m->rows;
        if (fp && fclose(fp) != 0) ok = 0;
        if (!ok) return -1;
    }
    return 0;
}

/* Singular values of every channel (dgesdd, values only): the baseline. */
static int baseline(const sb_matrix_t *m, double **sig) {
    size_t N = m->rows, n = m->cols, d = N < n ? N : n;
    double *a = malloc(N * n * sizeof *a);
    if (!a) return -1;
    for (int c = 0; c < 3; c++) {
        sig[c] = NULL;
        if (!m->data[c]) continue;
        sig[c] = malloc(d * sizeof(double));
        for (size_t j = 0; j < n; j++)
            memcpy(a + j * N, m->data[c] + j * m->ld, N * sizeof *a);
        if (!sig[c] || LAPACKE_dgesdd(LAPACK_COL_MAJOR, 'N', (lapack_int)N, (lapack_int)n, a, (lapack_int)N, sig[c],
                                      NULL, 1, NULL, 1) != 0) {
            free(a);
            return -1;
        }
    }
    free(a);
    return 0;
}

static void csv_header(FILE *fp) {
    fprintf(fp, "n,res,terms,method,used,precision,q,p,sample_s,plan_s,factor_s,svd_s,write_s,total_s,rel_err,"
                "opt_err,excess,peak_mib,extra_mib,reused,reps\n");
}

static void plot(const bench_opts_t *o, const char *csv) {
    char png[4200];
    snprintf(png, sizeof png, "%s/results.png", o->out);
    if (strchr(o->out, '\'') || strchr(o->out, '"')) {
        fprintf(stderr, "%s: not plotting: quotes in the folder name\n", o->prog);
        return;
    }
    if (system("command -v gnuplot >/dev/null 2>&1") != 0) {
        if (o->verbosity) fprintf(stderr, "%s: gnuplot not found, no plot\n", o->prog);
        return;
    }
    /* the paths go through gnuplot's stdin, not through the shell */
    FILE *gp = popen(o->verbosity >= 2 ? "gnuplot" : "gnuplot 2>/dev/null", "w"); /* "empty y range": not ours */
    if (!gp) return;
    size_t J = 0; /* the left panel's J: 8 when run, else the largest (a J not run plots nothing: gnuplot fails) */
    for (size_t i = 0; i < o->nterms; i++)
        if (J != 8 && (o->terms[i] == 8 || o->terms[i] > J)) J = o->terms[i];
    fprintf(gp, "csv = '%s'\nout = '%s'\nJ = %zu\nnobase = %d\n", csv, png, J, !o->baseline);
    fputs(sb_plot_gp_, gp);
    if (pclose(gp) != 0)
        fprintf(stderr, "%s: gnuplot failed, no plot%s\n", o->prog,
                o->verbosity >= 2 ? "" : " (-v shows its messages)");
    else if (o->verbosity)
        fprintf(stderr, "%s: wrote %s\n", o->prog, png);
}

void (*sb_bench_tmp_hook)(const char *path, int on);

int sb_bench_out_dir(const char *prog, const char *opt, const char *dir) {
    char buf[4200];
    struct stat st;
    int e = 0, n = snprintf(buf, sizeof buf, "%s", dir);
    if (n < 0 || (size_t)n >= sizeof buf) e = ENAMETOOLONG;
    for (char *p = buf + 1; !e; p++) { /* mkdir -p */
        if (*p != '/' && *p) continue;
        char c = *p;
        *p = 0;
        if (mkdir(buf, 0777) != 0 && errno != EEXIST) e = errno;
        *p = c;
        if (!c) break;
    }
    if (!e && (stat(dir, &st) != 0 || !S_ISDIR(st.st_mode))) {
        fprintf(stderr, "%s: %s %s: exists and is not a folder\n", prog, opt, dir);
        return 2;
    }
    if (e) fprintf(stderr, "%s: %s %s: cannot create the folder: %s\n", prog, opt, dir, strerror(e));
    return e ? 2 : 0;
}

/* The source, opened once before any output: one that cannot be read is an
 * input error (exit 2, as every command; no folder made), an unknown spec a
 * usage one (1).  It printed the table's header and left an empty --out
 * folder, exit 1. */
static int check_model(const bench_opts_t *o) {
    sb_context_t *ctx = NULL;
    sb_source_t *src = NULL;
    sb_context_create(&ctx);
    sb_result_t r = sb_source_open(ctx, o->model, &src);
    if (r != SB_OK) fprintf(stderr, "%s: %s\n", o->prog, sb_context_last_error(ctx));
    sb_source_destroy(src);
    sb_context_destroy(ctx);
    return r == SB_OK ? 0 : r == SB_ERR_IO || r == SB_ERR_FORMAT || r == SB_ERR_UNSUPPORTED ? 2 : 1;
}

static int run_sizes(bench_opts_t *o);

/* The folders of --matrices and --out, made before anything is written
 * (a --matrices that cannot be one was found after the sampling, with an
 * empty --out folder left); those this run made go again if it fails
 * while they are empty. */
static int run_all(bench_opts_t *o) {
    struct stat st;
    int bad = check_model(o), made_m = o->matrices && stat(o->matrices, &st) != 0,
        made_o = o->out && stat(o->out, &st) != 0;
    if (bad) return bad;
    if (o->matrices && sb_bench_out_dir(o->prog, "--matrices", o->matrices) != 0) return 2;
    int rc = o->out && sb_bench_out_dir(o->prog, "--out", o->out) != 0 ? 2 : run_sizes(o);
    if (rc != 0 && made_o) rmdir(o->out);
    if (rc != 0 && made_m) rmdir(o->matrices);
    return rc;
}

/* The table over --sizes and --terms (results.csv written whole). */
static int run_sizes(bench_opts_t *o) {
    FILE *csv = NULL;
    char csv_path[4200], tmp_path[4300];
    if (o->out) {
        snprintf(csv_path, sizeof csv_path, "%s/results.csv", o->out);
        snprintf(tmp_path, sizeof tmp_path, "%s.tmp-%ld", csv_path, (long)getpid());
        if (sb_bench_tmp_hook) sb_bench_tmp_hook(tmp_path, 1); /* before it exists */
        if (!(csv = fopen(tmp_path, "w"))) {
            if (sb_bench_tmp_hook) sb_bench_tmp_hook(tmp_path, 0);
            fprintf(stderr, "%s: %s: cannot write\n", o->prog, csv_path);
            return 2;
        }
        csv_header(csv);
    }
    char load[64] = "?";
    FILE *la = fopen("/proc/loadavg", "r");
    if (la) {
        if (!fgets(load, sizeof load, la)) strcpy(load, "?");
        load[strcspn(load, "\n")] = 0;
        fclose(la);
    }
    if (o->verbosity) {
        printf("# %s; %d BLAS threads; load average %s\n", openblas_get_config(), openblas_get_num_threads(), load);
        printf("# model %s, form %s, io grid; times in seconds, memory in MiB\n", o->model, sb_form_name(o->form));
        printf("%6s %3s %-22s %-10s %8s %8s %8s %8s %8s %10s %9s %7s %6s\n", "N", "J", "method", "used", "sample",
               "plan", "factor", "svd", "write", "rel_err", "excess", "peak", "extra");
    }
    size_t jmax = 0;
    for (size_t i = 0; i < o->nterms; i++)
        if (o->terms[i] > jmax) jmax = o->terms[i];
    int rc = 0;
    for (size_t si = 0; si < o->nsizes && rc == 0; si++) {
        size_t N = o->sizes[si], R = (size_t)llround(sqrt((double)N));
        sb_context_t *ctx = NULL;
        sb_source_t *src = NULL;
        sb_param_t *param = NULL;
        sb_matrix_t m = {0};
        double *sig[3] = {NULL, NULL, NULL};
        sb_param_opts_t po = {0};
        po.res = R;
        sb_matrix_opts_t mo = {0};
        mo.form = o->form;
        sb_context_create(&ctx);
        double t0 = now();
        if (sb_source_open(ctx, o->model, &src) != SB_OK || sb_param_create(ctx, SB_PARAM_IO, &po, &param) != SB_OK ||
            sb_matrix_build(ctx, src, param, &mo, &m) != SB_OK) {
            fprintf(stderr, "%s: %s\n", o->prog, sb_context_last_error(ctx));
            rc = 1;
            goto next;
        }
        double sample_s = now() - t0;
        if (o->matrices && write_matrices(o, &m) != 0) {
            fprintf(stderr, "%s: --matrices %s: cannot write: %s\n", o->prog, o->matrices, strerror(errno));
            rc = 2;
            goto next;
        }
        /* The optimum: when FULL (double) is among the methods, its own
         * errors are the Eckart-Young ones (dgesdd; the factor tests hold
         * them to 1e-9 of an independent dgesvd), so it runs first and
         * serves as the baseline; otherwise dgesdd values only. */
        size_t jm = jmax < N ? jmax : N, full_idx = o->nmethods;
        for (size_t mi = o->nmethods; mi-- > 0;)
            if (o->methods[mi].svd.method == SB_METHOD_FULL && !o->methods[mi].svd.single_precision) full_idx = mi;
        run_result_t full_res;
        double opt_rel[MAXL];
        t0 = now();
        if (o->baseline && full_idx < o->nmethods) {
            run_forked(o, &m, param, jm, &o->methods[full_idx], N <= 1024, &full_res);
            if (!full_res.ok) {
                fprintf(stderr, "%s: N %zu: baseline (full) failed: %s\n", o->prog, N, full_res.err);
                rc = 3;
                goto next;
            }
            memcpy(opt_rel, full_res.rel, sizeof opt_rel);
        } else if (o->baseline) {
            if (baseline(&m, sig) != 0) {
                fprintf(stderr, "%s: baseline dgesdd failed at N = %zu\n", o->prog, N);
                rc = 3;
                goto next;
            }
            double norm2 = 0;
            for (int c = 0; c < 3; c++)
                for (size_t j = 0; sig[c] && j < N; j++)
                    norm2 += sig[c][j] * sig[c][j];
            for (size_t ti = 0; ti < o->nterms; ti++) {
                double opt2 = 0;
                for (int c = 0; c < 3; c++)
                    for (size_t j = o->terms[ti]; sig[c] && j < N; j++)
                        opt2 += sig[c][j] * sig[c][j];
                opt_rel[ti] = norm2 > 0 ? sqrt(opt2 / norm2) : 0;
            }
        }
        if (o->verbosity)
            printf("# N = %zu (R = %zu): sample %.3f s, baseline %s %.2f s\n", N, R, sample_s,
                   !o->baseline             ? "none"
                   : full_idx < o->nmethods ? "= the full method (dgesdd, 3 channels, with its factor step)"
                                            : "dgesdd values only (3 channels)",
                   now() - t0);
        for (size_t mi = 0; mi < o->nmethods; mi++) {
            const method_spec_t *spec = &o->methods[mi];
            /* exact methods: one run at the largest J serves every J */
            sb_method_t used_max = sb_svd_auto_method(N, N, jm, &spec->svd);
            /* FULL's time does not depend on J; TOPK's does (its Krylov basis has J + 10 columns), so it
             * runs at every J that the peers are compared at */
            int once = spec->svd.method != SB_METHOD_AUTO && used_max == SB_METHOD_FULL;
            for (size_t i = 0; i < o->nterms && once; i++)
                if (o->terms[i] <= N && sb_svd_auto_method(N, N, o->terms[i], &spec->svd) != used_max) once = 0;
            run_result_t shared;
            if (mi == full_idx && o->baseline)
                shared = full_res;
            else if (once)
                run_forked(o, &m, param, jm, spec, N <= 1024 || spec->svd.method != SB_METHOD_FULL, &shared);
            for (size_t ti = 0; ti < o->nterms; ti++) {
                size_t J = o->terms[ti];
                if (J > N) continue;
                run_result_t r;
                if (once)
                    r = shared;
                else
                    run_forked(o, &m, param, J, spec, 1, &r);
                if (!r.ok) {
                    fprintf(stderr, "%s: N %zu J %zu %s: %s\n", o->prog, N, J, spec->label, r.err);
                    continue;
                }
                double opt = o->baseline ? opt_rel[ti] : NAN, rel = r.rel[ti];
                double excess = opt > 0 ? (rel - opt) / opt : rel - opt;
                double total = sample_s + r.plan_s + r.factor_s + (r.write_s > 0 ? r.write_s : 0);
                int reused = once && J != jm;
                int q = spec->svd.power_iters > 0 ? spec->svd.power_iters : spec->svd.power_iters < 0 ? 0 : 2;
                int p = spec->svd.oversample > 0 ? spec->svd.oversample : spec->svd.oversample < 0 ? 0 : 10;
                const char *used = r.used;
                if (o->verbosity) {
                    char svd[16] = "-", wr[16] = "-", peak[16] = "-", extra[16] = "-", exc[16] = "-";
                    if (isfinite(excess)) snprintf(exc, sizeof exc, "%.2e", excess); /* no baseline: "-", not nan */
                    if (r.svd_s >= 0) snprintf(svd, sizeof svd, "%.4f", r.svd_s);
                    if (r.write_s >= 0) snprintf(wr, sizeof wr, "%.4f", r.write_s);
                    if (r.peak_mib >= 0) snprintf(peak, sizeof peak, "%.0f", r.peak_mib);
                    if (r.peak_mib >= 0 && r.base_mib >= 0)
                        snprintf(extra, sizeof extra, "%.0f", r.peak_mib - r.base_mib);
                    printf("%6zu %3zu %-22s %-10s %8.3f %8.4f %8.4f %8s %8s %10.4e %9s %7s %6s%s\n", N, J, spec->label,
                           used, sample_s, r.plan_s, r.factor_s, svd, wr, rel, exc, peak, extra,
                           reused ? "  (reused)" : "");
                }
                if (csv)
                    fprintf(
                        csv,
                        "%zu,%zu,%zu,%s,%s,%s,%d,%d,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.10e,%.10e,%.4e,%.1f,%.1f,%d,%d\n",
                        N, R, J, spec->label, used, spec->svd.single_precision ? "single" : "double", q, p, sample_s,
                        r.plan_s, r.factor_s, r.svd_s, r.write_s, total, rel, opt, excess, r.peak_mib,
                        r.peak_mib - r.base_mib, reused, r.reps);
                fflush(stdout);
            }
        }
    next:
        for (int c = 0; c < 3; c++)
            free(sig[c]);
        sb_matrix_free(&m);
        sb_param_destroy(param);
        sb_source_destroy(src);
        sb_context_destroy(ctx);
    }
    if (csv) {
        int ok = fclose(csv) == 0 && rc == 0, moved = ok && rename(tmp_path, csv_path) == 0;
        if (!moved) remove(tmp_path);
        if (sb_bench_tmp_hook) sb_bench_tmp_hook(tmp_path, 0);
        if (moved) {
            if (o->verbosity) fprintf(stderr, "%s: wrote %s\n", o->prog, csv_path);
            plot(o, csv_path);
        } else {
            if (rc == 0) {
                fprintf(stderr, "%s: %s: cannot write\n", o->prog, csv_path);
                rc = 2;
            }
        }
    }
    return rc;
}

int sb_bench_main(int argc, char **argv, const char *prog) {
    bench_opts_t o;
    memset(&o, 0, sizeof o);
    o.prog = prog;
    o.model = DEFAULT_MODEL;
    o.fork_runs = 1;
    o.write = 1;
    o.baseline = 1;
    o.verbosity = 1;
    o.min_time = 0.3;
    int rc = parse(argc, argv, &o);
    if (rc >= 0) return rc;
    return run_all(&o);
}

#ifndef SB_BENCH_NO_MAIN
#include "env_plan.h" /* src/cli: the CLI's environment, set before OpenBLAS starts */
int main(int argc, char **argv) {
    sb_cli_malloc_env_restore();
    return sb_bench_main(argc, argv, "sepbrdf_bench");
}
#endif
