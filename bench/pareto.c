/* `sepbrdf bench --pareto`: run time against error as the user sees it.
 * For one source, every layout x method x R x J runs the whole factor
 * job (sample, factor, estimate, write the output set) in a forked
 * child; its CPU seconds (user + system, from getrusage, so the machine's
 * load inflates them far less than wall time) and the estimator's
 * headline error at J are one point.  A point is on the Pareto front
 * when no point costs less CPU with a headline at least as low.  Prints
 * the table, writes DIR/pareto.csv and DIR/pareto.png (pareto_png.c). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "bench.h"
#include "pareto.h"
#include "sepbrdf/sepbrdf.h"

#define MAXP 512
#define MAXL 16

typedef struct popts {
    const char *source, *out, *prog;
    char layouts[MAXL][16], methods[MAXL][16];
    size_t nlayouts, nmethods, res[MAXL], nres, terms[MAXL], nterms;
    int quiet;
} popts_t;

static void help(const char *prog) {
    printf("usage: %s --pareto [OPTIONS]\n"
           "\n"
           "CPU seconds of the whole factor job (sample, factor, estimate, write) against\n"
           "its headline error at J, for every layout, method, R and J; the points no\n"
           "other point beats on both (the Pareto front) are marked.  Each job runs in a\n"
           "forked child: its CPU time is user + system of that child (process start\n"
           "excluded), less sensitive to other processes than wall time.\n"
           "\n"
           "options:\n"
           "  --source SPEC     model spec or measured file (default: factor's default)\n"
           "  --layouts LIST    layouts, as factor's --param (default io,iso,hd)\n"
           "  --methods LIST    methods, as factor's --method (default auto,randomized,topk)\n"
           "  --res LIST        cells per axis R (default 16,32)\n"
           "  --terms LIST      terms J (default 1,2,4,8)\n"
           "  --quick           layouts io,iso, method auto, R 16, J 2,4\n"
           "  -o, --out DIR     write DIR/pareto.csv and DIR/pareto.png (default .)\n"
           "  -q, --quiet       no table on stdout\n"
           "  -h, --help        this text\n",
           prog);
}

static int split(const popts_t *o, const char *opt, const char *s, char (*out)[16], size_t *n) {
    *n = 0;
    while (*s) {
        size_t len = strcspn(s, ",");
        if (len == 0 || len >= 16 || *n == MAXL || (s[len] == ',' && !s[len + 1])) {
            fprintf(stderr, "%s --pareto: %s '%s': need a comma list of at most %d names\n", o->prog, opt, s, MAXL);
            return 1;
        }
        memcpy(out[*n], s, len);
        out[(*n)++][len] = 0;
        s += len + (s[len] == ',');
    }
    return *n == 0;
}

static int numbers(const popts_t *o, const char *opt, const char *s, size_t *out, size_t *n) {
    char names[MAXL][16];
    if (split(o, opt, s, names, n)) return 1;
    for (size_t i = 0; i < *n; i++) {
        char *end;
        unsigned long v = strtoul(names[i], &end, 10);
        if (*end || v < 1 || v > 512 || names[i][0] == '-') {
            fprintf(stderr, "%s --pareto: %s '%s': need whole numbers in 1..512\n", o->prog, opt, names[i]);
            return 1;
        }
        out[i] = v;
    }
    return 0;
}

/* 0 parsed, 1 usage error, -1 help printed. */
static int parse(int argc, char **argv, popts_t *o) {
    int r = split(o, "--layouts", "io,iso,hd", o->layouts, &o->nlayouts) ||
            split(o, "--methods", "auto,randomized,topk", o->methods, &o->nmethods) ||
            numbers(o, "--res", "16,32", o->res, &o->nres) || numbers(o, "--terms", "1,2,4,8", o->terms, &o->nterms);
    for (int i = 1; i < argc && !r; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        int takes = 1;
        if (!strcmp(a, "--pareto"))
            takes = 0;
        else if (!strcmp(a, "-h") || !strcmp(a, "--help"))
            return help(o->prog), -1;
        else if (!strcmp(a, "-q") || !strcmp(a, "--quiet"))
            o->quiet = 1, takes = 0;
        else if (!strcmp(a, "--quick")) {
            r = split(o, "--layouts", "io,iso", o->layouts, &o->nlayouts) ||
                split(o, "--methods", "auto", o->methods, &o->nmethods) ||
                numbers(o, "--res", "16", o->res, &o->nres) || numbers(o, "--terms", "2,4", o->terms, &o->nterms);
            takes = 0;
        } else if (!v) {
            fprintf(stderr, "%s --pareto: unknown option or missing value: %s\n", o->prog, a);
            return 1;
        } else if (!strcmp(a, "--source"))
            o->source = v;
        else if (!strcmp(a, "-o") || !strcmp(a, "--out"))
            o->out = v;
        else if (!strcmp(a, "--layouts"))
            r = split(o, a, v, o->layouts, &o->nlayouts);
        else if (!strcmp(a, "--methods"))
            r = split(o, a, v, o->methods, &o->nmethods);
        else if (!strcmp(a, "--res"))
            r = numbers(o, a, v, o->res, &o->nres);
        else if (!strcmp(a, "--terms"))
            r = numbers(o, a, v, o->terms, &o->nterms);
        else {
            fprintf(stderr, "%s --pareto: unknown option %s\n", o->prog, a);
            return 1;
        }
        i += takes;
    }
    for (size_t m = 0; m < o->nmethods && !r; m++) {
        sb_method_t k;
        if (sb_method_parse(o->methods[m], &k) != SB_OK) {
            fprintf(stderr, "%s --pareto: --methods: unknown method %s\n", o->prog, o->methods[m]);
            r = 1;
        }
    }
    return r;
}

/* VmHWM of this process, MiB (-1 where /proc is missing). */
static double hwm_mib(void) {
    FILE *fp = fopen("/proc/self/status", "r");
    char line[256];
    double v = -1;
    while (fp && fgets(line, sizeof line, fp))
        if (strncmp(line, "VmHWM:", 6) == 0) v = atof(line + 6) / 1024;
    if (fp) fclose(fp);
    return v;
}

static double cpu_of(const struct rusage *ru) {
    return (double)ru->ru_utime.tv_sec + ru->ru_utime.tv_usec * 1e-6 + (double)ru->ru_stime.tv_sec +
           ru->ru_stime.tv_usec * 1e-6;
}

/* The child: the whole job, its headline and method through fd. */
static void child(const popts_t *o, pareto_point_t *p, const char *dir, int fd) {
    sb_job_opts_t jo = {0};
    sb_method_t m = SB_METHOD_AUTO;
    sb_method_parse(p->method, &m);
    jo.source = o->source;
    jo.param = p->layout;
    jo.res = p->res;
    jo.terms = p->terms;
    jo.method = m;
    jo.out = dir;
    sb_job_t *job = NULL;
    if (sb_job_run(NULL, &jo, &job) == SB_OK) {
        const char *used = sb_factors_get_meta(sb_job_factors(job), "method");
        snprintf(p->used, sizeof p->used, "%s", used ? used : "?");
        p->headline = sb_job_headline(job, p->terms);
        p->ok = isfinite(p->headline) && p->headline > 0;
    }
    sb_job_destroy(job);
    p->peak_mib = hwm_mib();
    ssize_t w = write(fd, p, sizeof *p);
    _exit(w == (ssize_t)sizeof *p ? 0 : 1);
}

/* One point: fork, run, read back; its CPU from the children's usage
 * before and after it (one child at a time). */
static void run_point(const popts_t *o, pareto_point_t *p, const char *dir) {
    int fds[2];
    struct rusage ru0, ru1;
    getrusage(RUSAGE_CHILDREN, &ru0);
    fflush(NULL);
    if (pipe(fds) != 0) return;
    pid_t pid = fork();
    if (pid == 0) {
        close(fds[0]);
        child(o, p, dir, fds[1]);
    }
    close(fds[1]);
    pareto_point_t got = *p;
    int ok = pid > 0 && read(fds[0], &got, sizeof got) == (ssize_t)sizeof got;
    close(fds[0]);
    int st = 0;
    if (pid > 0 && waitpid(pid, &st, 0) == pid && ok && WIFEXITED(st) && WEXITSTATUS(st) == 0) {
        getrusage(RUSAGE_CHILDREN, &ru1);
        *p = got;
        p->cpu_s = cpu_of(&ru1) - cpu_of(&ru0);
    }
}

/* Indices of the front by rising CPU: each has a lower headline than
 * every point that costs less. */
static size_t front_of(const pareto_point_t *p, size_t n, size_t *front) {
    size_t idx[MAXP], m = 0, nf = 0;
    for (size_t i = 0; i < n; i++)
        if (p[i].ok) idx[m++] = i;
    for (size_t i = 1; i < m; i++) /* insertion sort by CPU, then headline */
        for (size_t j = i; j > 0; j--) {
            const pareto_point_t *a = &p[idx[j - 1]], *b = &p[idx[j]];
            if (a->cpu_s < b->cpu_s || (a->cpu_s == b->cpu_s && a->headline <= b->headline)) break;
            size_t t = idx[j];
            idx[j] = idx[j - 1], idx[j - 1] = t;
        }
    double best = INFINITY;
    for (size_t i = 0; i < m; i++)
        if (p[idx[i]].headline < best) best = p[idx[i]].headline, front[nf++] = idx[i];
    return nf;
}

static int on_front(size_t i, const size_t *front, size_t nf) {
    for (size_t k = 0; k < nf; k++)
        if (front[k] == i) return 1;
    return 0;
}

static int write_csv(const char *path, const pareto_point_t *p, size_t n, const size_t *front, size_t nf) {
    FILE *fp = fopen(path, "w");
    if (!fp) return 2;
    fprintf(fp, "layout,method,used,res,terms,ok,cpu_s,headline,peak_mib,front\n");
    for (size_t i = 0; i < n; i++)
        fprintf(fp, "%s,%s,%s,%zu,%zu,%d,%.4f,%.6e,%.1f,%d\n", p[i].layout, p[i].method, p[i].ok ? p[i].used : "",
                p[i].res, p[i].terms, p[i].ok, p[i].cpu_s, p[i].ok ? p[i].headline : NAN, p[i].peak_mib,
                on_front(i, front, nf));
    return fclose(fp) == 0 ? 0 : 2;
}

static void print_table(const pareto_point_t *p, size_t n, const size_t *front, size_t nf) {
    printf("%-8s %-11s %-10s %4s %3s %8s %11s %8s  %s\n", "layout", "method", "used", "R", "J", "CPU s", "headline",
           "peak MiB", "front");
    for (size_t i = 0; i < n; i++) {
        if (!p[i].ok) {
            printf("%-8s %-11s %-10s %4zu %3zu %8s %11s %8s\n", p[i].layout, p[i].method, "failed", p[i].res,
                   p[i].terms, "-", "-", "-");
            continue;
        }
        printf("%-8s %-11s %-10s %4zu %3zu %8.3f %11.4e %8.1f  %s\n", p[i].layout, p[i].method, p[i].used, p[i].res,
               p[i].terms, p[i].cpu_s, p[i].headline, p[i].peak_mib, on_front(i, front, nf) ? "*" : "");
    }
}

int sb_bench_pareto_main(int argc, char **argv, const char *prog) {
    static popts_t o;
    static pareto_point_t pts[MAXP];
    memset(&o, 0, sizeof o);
    o.prog = prog;
    o.out = ".";
    int r = parse(argc, argv, &o);
    if (r) return r < 0 ? 0 : 1;
    char who[96];
    snprintf(who, sizeof who, "%s --pareto", prog);
    if (!*o.out) {
        fprintf(stderr, "%s: --out: empty folder name\n", who);
        return 1;
    }
    if (sb_bench_out_dir(who, "--out", o.out) != 0) return 2;
    char tmp[2048], path[4200];
    snprintf(tmp, sizeof tmp, "%s/pareto-run-%ld", o.out, (long)getpid());
    size_t n = 0;
    for (size_t l = 0; l < o.nlayouts; l++)
        for (size_t m = 0; m < o.nmethods; m++)
            for (size_t ri = 0; ri < o.nres; ri++)
                for (size_t t = 0; t < o.nterms && n < MAXP; t++) {
                    pareto_point_t *p = &pts[n++];
                    memset(p, 0, sizeof *p);
                    snprintf(p->layout, sizeof p->layout, "%s", o.layouts[l]);
                    snprintf(p->method, sizeof p->method, "%s", o.methods[m]);
                    p->res = o.res[ri], p->terms = o.terms[t];
                    run_point(&o, p, tmp);
                }
    size_t front[MAXP], nf = front_of(pts, n, front);
    if (!o.quiet) print_table(pts, n, front, nf);
    snprintf(path, sizeof path, "rm -rf '%s'", tmp);
    if (system(path) != 0) fprintf(stderr, "%s --pareto: could not remove %s\n", prog, tmp);
    snprintf(path, sizeof path, "%s/pareto.csv", o.out);
    int rc = write_csv(path, pts, n, front, nf);
    snprintf(path, sizeof path, "%s/pareto.png", o.out);
    if (rc == 0) rc = pareto_plot(path, pts, n, front, nf);
    if (rc) fprintf(stderr, "%s --pareto: cannot write %s/pareto.csv or pareto.png\n", prog, o.out);
    return rc;
}
