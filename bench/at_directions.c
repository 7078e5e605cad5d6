/* A scattered table of a source measured where another table was (issue
 * 32's paints no test has seen, bench/cv_splits.py): SOURCE evaluated at
 * every sample of DIRS (its direction pairs, in its order), values
 * x (1 + NOISE z), z ~ N(0, 1) per value, each pair dropped with
 * probability DROP; written to stdout as a sepbrdf CSV (degrees).  SOURCE
 * "=" keeps DIRS's own values.  The draws are C's rand() after
 * srand(SEED): the same glibc, the same table.
 *
 *   sepbrdf_bench_at_directions DIRS SOURCE [NOISE [SEED [DROP]]] */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sepbrdf/sepbrdf.h"

static double gauss(void) { /* Box-Muller */
    double u = (rand() + 1.0) / (RAND_MAX + 2.0), v = (rand() + 1.0) / (RAND_MAX + 2.0);
    return sqrt(-2 * log(u)) * cos(2 * 3.14159265358979323846 * v);
}

int main(int argc, char **argv) {
    if (argc < 3) {
        fprintf(stderr, "usage: %s DIRS SOURCE [NOISE [SEED [DROP]]]\n", argv[0]);
        return 2;
    }
    sb_source_t *a = NULL, *b = NULL;
    int own = strcmp(argv[2], "=") == 0;
    if (sb_source_open(NULL, argv[1], &a) != SB_OK || (!own && sb_source_open(NULL, argv[2], &b) != SB_OK)) {
        fprintf(stderr, "%s: cannot open %s or %s\n", argv[0], argv[1], argv[2]);
        sb_source_destroy(a);
        return 2;
    }
    double noise = argc > 3 ? atof(argv[3]) : 0, drop = argc > 5 ? atof(argv[5]) : 0;
    srand(argc > 4 ? (unsigned)atoi(argv[4]) : 1);
    printf("# symmetry: isotropic\ntheta_i,phi_i,theta_o,phi_o,r,g,b\n");
    for (size_t i = 0; i < sb_source_sample_count(a); i++) {
        double wi[3], wo[3], v[3], f[3];
        if (!sb_source_sample(a, i, wi, wo, v)) continue;
        if (drop > 0 && rand() < drop * RAND_MAX) continue;
        if (!own && !sb_source_eval(b, wi, wo, f)) continue;
        for (int c = 0; c < 3; c++)
            f[c] = (own ? v[c] : f[c]) * (noise > 0 ? 1 + noise * gauss() : 1);
        const double deg = 180 / 3.14159265358979323846;
        printf("%.6f,%.6f,%.6f,%.6f,%.7g,%.7g,%.7g\n", acos(wi[2]) * deg, atan2(wi[1], wi[0]) * deg, acos(wo[2]) * deg,
               atan2(wo[1], wo[0]) * deg, f[0], f[1], f[2]);
    }
    sb_source_destroy(a);
    sb_source_destroy(b);
    return 0;
}
