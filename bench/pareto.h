/* `sepbrdf bench --pareto`: CPU seconds of the whole factor job against
 * its headline error, over layouts, methods, R and J for one source
 * (pareto.c), the front marked; table, CSV and PNG (pareto_png.c). */
#ifndef SEPBRDF_BENCH_PARETO_H
#define SEPBRDF_BENCH_PARETO_H

#include <stddef.h>

typedef struct pareto_point {
    char layout[16], method[16], used[16]; /* asked for; the factors' method */
    size_t res, terms;
    int ok;          /* the job ran */
    double cpu_s;    /* user + system seconds of the child that ran the job (and wrote the set) */
    double headline; /* the estimator's headline error at J */
    double peak_mib; /* its peak resident memory */
} pareto_point_t;

/* argv as `sepbrdf bench --pareto --help` prints; exit status 0, 1 usage, 2 I/O. */
int sb_bench_pareto_main(int argc, char **argv, const char *prog);

/* The plot of the n points, the front's indices (by rising CPU) joined;
 * 0 written, 2 not. */
int pareto_plot(const char *path, const pareto_point_t *p, size_t n, const size_t *front, size_t nfront);

#endif
