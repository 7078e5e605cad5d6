/* The estimator's pairs (estimate.h): a replicate of the randomised
 * quasi-Monte Carlo set drawn through the mixture density, or through a
 * caller's draw function, and evaluated on the source (one call for a
 * batched source). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "factor/estimate_draw.h"
#include "factor/estimate_impl.h"
#include "util/internal.h"
#include "util/rng.h"

#define NCOMP 7 /* wo mixture components: uniform, cosine, four GGX lobes, grazing */
#define GRAZE (NCOMP - 1)

static const double comp_w[NCOMP] = {0.18, 0.18, 0.135, 0.135, 0.135, 0.135, 0.1};
static const double lobe_alpha[NCOMP] = {0, 0, 0.005, 0.02, 0.08, 0.3, 0};
/* wi: uniform, cosine, grazing */
static const double wi_w[3] = {0.45, 0.45, 0.1};

/* ---- drawing the pairs ------------------------------------------------ */

/* The grazing component: cos(theta) = c with density 1 / (K (c + C0)^2)
 * on [0, 1], K = 1/C0 - 1/(1 + C0) (half of its pairs within 0.17 degrees
 * of the horizon), azimuth uniform.  Where a reconstruction grows as
 * 1 / cos theta towards the horizon (a form's division, a non-reciprocal
 * source folded by a reciprocal layout), the squared error grows as
 * 1 / cos^2 and the other components, bounded there, would leave an
 * estimate of unbounded variance that misses the tail; with this one the
 * ratio stays bounded down to the guard 0.001. */
#define C0 0.003
static double graze_pdf(double c) {
    const double K = 1 / C0 - 1 / (1 + C0);
    return c >= 0 && c <= 1 ? 1 / (K * (c + C0) * (c + C0) * 2 * SB_PI) : 0;
}
static double graze_z(double u) {
    const double K = 1 / C0 - 1 / (1 + C0);
    return fmin(1, fmax(0, 1 / (1 / C0 - u * K) - C0));
}

/* GGX normal distribution D(h) for cos(theta_h) = c. */
static double ggx_d(double alpha, double c) {
    double a2 = alpha * alpha, t = (a2 - 1) * c * c + 1;
    return a2 / (SB_PI * t * t);
}

/* Mixture density of wo given wi (both unit, wo.z > 0). */
static double pdf_o(const double wi[3], const double wo[3]) {
    double p = comp_w[0] / (2 * SB_PI) + comp_w[1] * wo[2] / SB_PI + comp_w[GRAZE] * graze_pdf(wo[2]), h[3];
    for (int i = 0; i < 3; i++)
        h[i] = wi[i] + wo[i];
    double nh = sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
    if (nh <= 0) return p;
    double hz = h[2] / nh, oh = (wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2]) / nh;
    if (hz <= 0 || oh <= 0) return p;
    for (int k = 2; k < GRAZE; k++)
        p += comp_w[k] * ggx_d(lobe_alpha[k], hz) * hz / (4 * oh);
    return p;
}

/* Direction with cos(theta) = z, azimuth 2 pi u. */
void sb_estimate_dir_z(double z, double u, double w[3]) {
    double s = sqrt(fmax(0, 1 - z * z)), ph = 2 * SB_PI * u;
    w[0] = s * cos(ph);
    w[1] = s * sin(ph);
    w[2] = z;
}

double sb_estimate_draw_wo(const double wi[3], const double x[3], double wo[3]) {
    int k = 0;
    for (double acc = comp_w[0]; k < NCOMP - 1 && x[0] >= acc; acc += comp_w[++k])
        ;
    if (k == 0) {
        sb_estimate_dir_z(x[1], x[2], wo);
    } else if (k == 1) {
        sb_estimate_dir_z(sqrt(1 - x[1]), x[2], wo);
    } else if (k == GRAZE) {
        sb_estimate_dir_z(graze_z(x[1]), x[2], wo);
    } else {
        double a = lobe_alpha[k], t2 = a * a * x[1] / (1 - x[1]), h[3];
        sb_estimate_dir_z(1 / sqrt(1 + t2), x[2], h);
        double ih = wi[0] * h[0] + wi[1] * h[1] + wi[2] * h[2];
        for (int i = 0; i < 3; i++)
            wo[i] = 2 * ih * h[i] - wi[i];
    }
    return wo[2] > 0 && wi[2] > 0 ? pdf_o(wi, wo) : 0;
}

/* Mixture density of wi (unit, wi.z >= 0). */
static double pdf_i(const double wi[3]) {
    return wi_w[0] / (2 * SB_PI) + wi_w[1] * wi[2] / SB_PI + wi_w[2] * graze_pdf(wi[2]);
}

/* Map a point x of [0,1)^6 to a pair; returns its density (0: wo below the
 * horizon, no BRDF pair). */
double sb_estimate_draw_wi(const double x[3], double wi[3]) {
    sb_estimate_dir_z(x[0] < wi_w[0] ? x[1] : x[0] < wi_w[0] + wi_w[1] ? sqrt(1 - x[1]) : graze_z(x[1]), x[2], wi);
    return pdf_i(wi);
}

static double draw_pair(const double x[6], double wi[3], double wo[3]) {
    return sb_estimate_draw_wi(x, wi) * sb_estimate_draw_wo(wi, x + 3, wo);
}

double sb_estimate_draw_pair(const double x[6], double wi[3], double wo[3]) { return draw_pair(x, wi, wo); }

double sb_estimate_pair_pdf(const double wi[3], const double wo[3]) {
    return wi[2] > 0 && wo[2] > 0 ? pdf_i(wi) * pdf_o(wi, wo) : 0;
}

double sb_estimate_wi_pdf(const double wi[3]) { return wi[2] >= 0 ? pdf_i(wi) : 0; }

double sb_estimate_wo_pdf(const double wi[3], const double wo[3]) { return wi[2] > 0 && wo[2] > 0 ? pdf_o(wi, wo) : 0; }

/* A batched source (sb_source_create_batched): the drawn pairs of
 * replicate k (density in d[6]) evaluated in one call. */
static void eval_replicate(sb_pairs_t *P, size_t k) {
    size_t n = 0, *idx = malloc(P->rep * sizeof *idx);
    double *buf = malloc(P->rep * 9 * sizeof *buf);
    unsigned char *known = malloc(P->rep);
    double *wi = buf, *wo = buf ? buf + 3 * P->rep : NULL, *f = buf ? buf + 6 * P->rep : NULL;
    int have = idx && buf && known; /* else (no memory) pair by pair */
    for (size_t i = 0; i < P->rep && have; i++) {
        const double *d = P->d + (k * P->rep + i) * PD;
        if (!(d[6] > 0)) continue;
        memcpy(wi + 3 * n, d, 3 * sizeof *d);
        memcpy(wo + 3 * n, d + 3, 3 * sizeof *d);
        idx[n++] = i;
    }
    if (have) sb_source_eval_many(P->src, n, wi, wo, f, known);
    for (size_t i = 0, m = 0; i < P->rep; i++) {
        size_t at = k * P->rep + i;
        double *d = P->d + at * PD;
        int ok = have ? m < n && idx[m] == i : d[6] > 0, kn;
        if (!have)
            kn = ok && sb_source_eval(P->src, d, d + 3, d + 7) && isfinite(d[7] + d[8] + d[9]);
        else
            kn = ok && known[m] && isfinite(f[3 * m] + f[3 * m + 1] + f[3 * m + 2]);
        if (have && ok) memcpy(d + 7, f + 3 * m++, 3 * sizeof *d);
        d[6] = kn ? 1 / d[6] : 0;
        P->known[at] = (unsigned char)kn;
    }
    free(idx);
    free(buf);
    free(known);
}

/* Pairs of replicate k: the Kronecker set i alpha (alpha_d = 1/phi^(d+1),
 * phi the root of x^7 = x + 1) shifted by the replicate's random vector. */
void est_draw_replicate(sb_pairs_t *P, size_t k) {
    static const double phi6 = 1.1127756842787055;
    double alpha[6], shift[6], a = 1;
    uint64_t s = P->seed * 0x2545f4914f6cdd1dULL + k;
    int batched = sb_source_batched(P->src);
    for (int d = 0; d < 6; d++) {
        a /= phi6;
        alpha[d] = a;
        shift[d] = sb_unit(sb_splitmix64(&s));
    }
    for (size_t i = 0; i < P->rep; i++) {
        size_t at = k * P->rep + i;
        double x[6], *d = P->d + at * PD;
        for (int e = 0; e < 6; e++) {
            double v = shift[e] + (double)(i + 1) * alpha[e];
            x[e] = v - floor(v);
        }
        double pd = P->draw ? P->draw(P->draw_user, x, d, d + 3) : draw_pair(x, d, d + 3);
        if (batched) { /* evaluated below, all at once */
            d[6] = pd;
            continue;
        }
        int known = pd > 0 && sb_source_eval(P->src, d, d + 3, d + 7) && isfinite(d[7] + d[8] + d[9]);
        d[6] = known ? 1 / pd : 0;
        P->known[at] = (unsigned char)known;
    }
    if (batched) eval_replicate(P, k);
    for (size_t i = 0; i < P->rep && P->channels != 7u; i++) /* the channels not measured read as 0 */
        for (int c = 0; c < 3; c++)
            if (!(P->channels >> c & 1u)) P->d[(k * P->rep + i) * PD + 7 + (size_t)c] = 0;
}
