/* sepbrdf_bench_svd: sepbrdf's dense solvers as one long-lived process,
 * so that bench/solvers.py times them against the Python peers in
 * alternation, one process pair, on the very same matrices.
 *
 *   sepbrdf_bench_svd DIR N J
 *
 * loads DIR/ioN_{r,g,b}.f64 (raw float64, column-major N x N, written by
 * `sepbrdf_bench --matrices DIR`), plans topk and randomized (block
 * Krylov, p = 10, q = 1, 2, 3: "randomized" is q = 2, the default, in
 * mixed precision, the default too) for J
 * terms, then reads method names from stdin ("topk", "randomized",
 * "randomized:q=1", "randomized:q=3", "randomized:f32": q = 2 in single
 * precision on a converted copy, "randomized:double": q = 2 with every
 * step in double (sb_svd_opts_t.mixed < 0), "quit").  For each it factors the
 * three channels and prints one line:
 *     METHOD WALL_S CPU_S REL
 * (CPU of the whole process, every BLAS thread; REL the relative error
 * sqrt(sum_c ||A_c - A_c,J||^2 / sum_c ||A_c||^2) from the identity
 * ||A||^2 - sum s_j^2, the matrices' norms computed here).  It starts
 * with the CLI's environment (src/cli/blas_env.c: OpenBLAS's idle
 * workers sleep at once), as `sepbrdf` and sepbrdf_bench do. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "sepbrdf/sepbrdf.h"

static double clock_s(clockid_t id) {
    struct timespec ts;
    clock_gettime(id, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

static double *load(const char *dir, size_t n, char c, double *norm2) {
    char path[4096];
    snprintf(path, sizeof path, "%s/io%zu_%c.f64", dir, n, c);
    FILE *fp = fopen(path, "rb");
    double *a = malloc(n * n * sizeof *a);
    size_t got = fp && a ? fread(a, sizeof *a, n * n, fp) : 0;
    if (fp) fclose(fp);
    if (got != n * n) {
        fprintf(stderr, "sepbrdf_bench_svd: %s: %zu of %zu values\n", path, got, n * n);
        free(a);
        return NULL;
    }
    *norm2 = 0;
    for (size_t i = 0; i < n * n; i++)
        *norm2 += a[i] * a[i];
    return a;
}

int main(int argc, char **argv) {
    if (argc != 4) {
        fprintf(stderr, "usage: sepbrdf_bench_svd DIR N J\n");
        return 1;
    }
    size_t n = strtoul(argv[2], NULL, 10), J = strtoul(argv[3], NULL, 10);
    double *a[3], n2[3], total = 0;
    for (int c = 0; c < 3; c++) {
        if (!(a[c] = load(argv[1], n, "rgb"[c], &n2[c]))) return 2;
        total += n2[c];
    }
    enum { NPLANS = 6 };
    static const char *const names[NPLANS] = {"topk",           "randomized",     "randomized:q=1",
                                              "randomized:q=3", "randomized:f32", "randomized:double"};
    static const int q[NPLANS] = {0, 2, 1, 3, 2, 2};
    sb_svd_t *plan[NPLANS] = {NULL};
    for (int k = 0; k < NPLANS; k++) {
        sb_svd_opts_t o = {0};
        o.method = k ? SB_METHOD_RANDOMIZED : SB_METHOD_TOPK;
        o.power_iters = q[k];
        o.single_precision = k == 4;
        o.mixed = k == 5 ? -1 : 0;
        if (sb_svd_create(NULL, n, n, J, &o, &plan[k]) != SB_OK) return 3;
    }
    double *s = malloc(J * sizeof *s), *u = malloc(n * J * sizeof *u), *v = malloc(n * J * sizeof *v);
    char line[64];
    while (s && u && v && fgets(line, sizeof line, stdin)) {
        line[strcspn(line, "\n")] = 0;
        int k = 0;
        while (k < NPLANS && strcmp(line, names[k]) != 0)
            k++;
        if (k == NPLANS) break;
        double w0 = clock_s(CLOCK_MONOTONIC), c0 = clock_s(CLOCK_PROCESS_CPUTIME_ID), resid = 0;
        for (int c = 0; c < 3; c++) {
            if (sb_svd_execute(plan[k], a[c], n, s, u, v, NULL, NULL) != SB_OK) return 3;
            double kept = 0;
            for (size_t j = 0; j < J; j++)
                kept += s[j] * s[j];
            resid += fmax(n2[c] - kept, 0);
        }
        double w1 = clock_s(CLOCK_MONOTONIC), c1 = clock_s(CLOCK_PROCESS_CPUTIME_ID);
        printf("%s %.6f %.6f %.10e\n", line, w1 - w0, c1 - c0, sqrt(resid / total));
        fflush(stdout);
    }
    for (int k = 0; k < NPLANS; k++)
        sb_svd_destroy(plan[k]);
    for (int c = 0; c < 3; c++)
        free(a[c]);
    free(s), free(u), free(v);
    return 0;
}
