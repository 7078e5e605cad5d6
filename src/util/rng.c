/* The random generator (rng.h). */
#include "util/rng.h"

#include <math.h>

#include "sepbrdf/common.h"

uint64_t sb_splitmix64(uint64_t *x) {
    uint64_t z = (*x += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

void sb_rng_seed(sb_rng_t *r, uint64_t seed) {
    for (int i = 0; i < 4; i++)
        r->s[i] = sb_splitmix64(&seed);
}

static uint64_t rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }

uint64_t sb_rng_next(sb_rng_t *r) {
    uint64_t *st = r->s, x = rotl(st[1] * 5, 7) * 9, t = st[1] << 17;
    st[2] ^= st[0];
    st[3] ^= st[1];
    st[1] ^= st[2];
    st[0] ^= st[3];
    st[2] ^= t;
    st[3] = rotl(st[3], 45);
    return x;
}

double sb_unit(uint64_t x) { return (double)(x >> 11) * 0x1.0p-53; }

void sb_box_muller(uint64_t a, uint64_t b, double g[2]) {
    double u1 = ((double)(a >> 11) + 1) * 0x1.0p-53, u2 = sb_unit(b);
    double r = sqrt(-2 * log(u1)), t = 2 * SB_PI * u2;
    g[0] = r * cos(t);
    g[1] = r * sin(t);
}

void sb_rng_gauss2(sb_rng_t *r, double g[2]) {
    uint64_t a = sb_rng_next(r);
    sb_box_muller(a, sb_rng_next(r), g);
}

void sb_splitmix_gauss2(uint64_t *state, double g[2]) {
    uint64_t a = sb_splitmix64(state);
    sb_box_muller(a, sb_splitmix64(state), g);
}
