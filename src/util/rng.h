/* Private: the one random generator of the library.
 *
 * xoshiro256** (Blackman & Vigna 2018) seeded by splitmix64, and normal
 * pairs by Box-Muller.  Written out here so that the bits depend on the
 * seed only, not on the C library. */
#ifndef SEPBRDF_RNG_H
#define SEPBRDF_RNG_H

#include <stdint.h>

typedef struct sb_rng {
    uint64_t s[4];
} sb_rng_t;

/* One splitmix64 step: advances *state, returns 64 well-mixed bits.  Also
 * the whole generator where a single 64-bit state is enough (test noise,
 * fixed pseudo-random vectors). */
uint64_t sb_splitmix64(uint64_t *state);

void sb_rng_seed(sb_rng_t *r, uint64_t seed);
uint64_t sb_rng_next(sb_rng_t *r);

/* Uniform in [0, 1) from the top 53 bits of x. */
double sb_unit(uint64_t x);

/* Two independent N(0, 1) from two 64-bit draws a, b (Box-Muller with
 * u1 = (a >> 11 + 1) 2^-53 in (0, 1], so the log is finite, and
 * u2 = b >> 11 2^-53): g = sqrt(-2 log u1) (cos 2 pi u2, sin 2 pi u2). */
void sb_box_muller(uint64_t a, uint64_t b, double g[2]);

/* sb_box_muller of the next two draws of r. */
void sb_rng_gauss2(sb_rng_t *r, double g[2]);

/* sb_box_muller of the next two splitmix64 draws of *state. */
void sb_splitmix_gauss2(uint64_t *state, double g[2]);

#endif
