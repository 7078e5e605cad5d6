/* The CDFs of the importance sampler (sampler_impl.h): built rounded to
 * float as sampler.bin holds them, searched, an entry's probability;
 * shared by the rows' tables (sampler.c) and the columns' (sampler_cols.c). */
#include <math.h>

#include "sampler_impl.h"

/* Inclusive CDF of n non-negative values (the last forced to 1), rounded
 * to float or not; uniform when they sum to 0.  Returns the sum. */
double sb_cdf_build_(const double *v, size_t n, int as_float, double *cdf) {
    double sum = 0;
    for (size_t i = 0; i < n; i++)
        sum += v[i];
    double acc = 0;
    for (size_t i = 0; i < n; i++) { /* as float, the file's values: a cell's probability is a difference */
        acc += v[i];                 /* of two entries near 1, which C and GLSL then take alike */
        cdf[i] = sum > 0 ? acc / sum : (double)(i + 1) / (double)n;
        if (as_float) cdf[i] = (float)cdf[i];
    }
    cdf[n - 1] = 1;
    return sum;
}

/* Smallest i < n with *u < cdf[i] (binary search; cdf[n - 1] > *u),
 * and *u rescaled to [0, 1) within that entry. */
size_t sb_cdf_find_(const double *cdf, size_t n, double *u) {
    size_t lo = 0, hi = n - 1;
    while (lo < hi) {
        size_t mid = (lo + hi) / 2;
        if (*u < cdf[mid])
            hi = mid;
        else
            lo = mid + 1;
    }
    double below = lo ? cdf[lo - 1] : 0, r = (*u - below) / (cdf[lo] - below);
    *u = r < 0 ? 0 : (r < 1 ? r : nextafter(1.0, 0.0));
    return lo;
}

double sb_cdf_prob_(const double *cdf, size_t i) { return cdf[i] - (i ? cdf[i - 1] : 0); }
