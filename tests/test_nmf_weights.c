/* The non-negative solver's cell weights toward the headline
 * (src/solve/nmf_weights.c): the headline's weight of a cell over the
 * fit's, from the stored form and the layout's cells, and the SVD terms
 * its prefixes are measured against. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"
#include "solve/nmf_gram.h"  /* not exported, in the static archive */
#include "solve/nmf_lanes.h" /* the sweeps' column loops */
#include "solve/nmf_weights.h"

static sb_param_t *iso8(void) {
    sb_param_t *p = NULL;
    sb_param_opts_t o = {0};
    o.res = 8;
    CHECK(sb_param_create(NULL, SB_PARAM_ISO, &o, &p) == SB_OK);
    return p;
}

/* ext: 1 where the cell is a BRDF pair with the light above the horizon,
 * but every seventh such cell (out of the data: weight 0); cz: cos theta_i. */
static size_t cells(const sb_param_t *p, unsigned char *ext, double *cz) {
    size_t m = sb_param_rows(p), n = sb_param_cols(p), data = 0, seen = 0;
    for (size_t c = 0; c < n; c++)
        for (size_t i = 0; i < m; i++) {
            double wi[3], wo[3];
            size_t k = i + c * m;
            int in = sb_param_cell_dirs(p, i, c, wi, wo) && wi[2] > 0;
            ext[k] = (unsigned char)(in && seen++ % 7 != 3);
            cz[k] = in ? wi[2] : 0;
            data += ext[k];
        }
    return data;
}

/* Form f: the headline measures f cos theta_i, so a cell weighs cos^2
 * theta_i (iso's cells are solid angles, no gain) over the mean, clipped
 * at the 99th percentile; form cos stores what the headline measures:
 * every data cell weighs 1. */
SB_TEST(headline_weights_follow_the_form) {
    sb_param_t *p = iso8();
    size_t m = sb_param_rows(p), n = sb_param_cols(p);
    unsigned char *ext = malloc(m * n);
    double *cz = malloc(m * n * sizeof *cz), *hw = malloc(m * n * sizeof *hw);
    size_t data = cells(p, ext, cz);
    CHECK(data > 100);
    CHECK(sb_nmf_headline_weights(p, SB_FORM_F, ext, m, n, hw, NULL) == 0);
    double sum = 0, cmax = 0, ref = -1;
    size_t k_ref = 0;
    for (size_t k = 0; k < m * n; k++) {
        sum += hw[k];
        if (!ext[k]) CHECKF(hw[k] == 0, "cell %zu out of the data weighs %g", k, hw[k]);
        if (ext[k] && cz[k] > ref && cz[k] < 0.5) ref = cz[k], k_ref = k; /* well under the clip */
        cmax = fmax(cmax, hw[k]);
    }
    CHECKF(fabs(sum / (double)data - 1) < 1e-12, "mean %g", sum / (double)data);
    size_t below = 0;
    for (size_t k = 0; k < m * n; k++) {
        if (!ext[k] || hw[k] >= cmax) continue; /* the clipped ones */
        double want = hw[k_ref] * (cz[k] * cz[k]) / (ref * ref);
        CHECKF(fabs(hw[k] - want) <= 1e-12 * want, "cell %zu: %g, cos^2 ratio says %g", k, hw[k], want);
        below++;
    }
    CHECK(below > data * 9 / 10);
    CHECK(sb_nmf_headline_weights(p, SB_FORM_COS, ext, m, n, hw, NULL) == 0);
    for (size_t k = 0; k < m * n; k++)
        CHECKF(fabs(hw[k] - (ext[k] ? 1 : 0)) < 1e-12, "form cos, cell %zu: %g", k, hw[k]);
    memset(ext, 0, m * n); /* no data cell: nothing to weigh */
    CHECK(sb_nmf_headline_weights(p, SB_FORM_F, ext, m, n, hw, NULL) == -1);
    free(ext);
    free(cz);
    free(hw);
    sb_param_destroy(p);
}

/* The unclipped weights (a fit of their own, nmf_mixes.c): cos^2 theta_i
 * over their own mean on every data cell, the clipped ones among them
 * included, and 0 out of the data; where the clipped weights are under
 * their clip the two differ by one factor, above it the unclipped are
 * larger by that factor. */
SB_TEST(headline_weights_unclipped) {
    sb_param_t *p = iso8();
    size_t m = sb_param_rows(p), n = sb_param_cols(p);
    unsigned char *ext = malloc(m * n);
    double *cz = malloc(m * n * sizeof *cz), *hw = malloc(m * n * sizeof *hw), *raw = malloc(m * n * sizeof *raw);
    size_t data = cells(p, ext, cz);
    CHECK(sb_nmf_headline_weights(p, SB_FORM_F, ext, m, n, hw, raw) == 0);
    double sum = 0, c2 = 0, hmax = 0, scale = 0;
    for (size_t k = 0; k < m * n; k++) {
        sum += raw[k];
        c2 += ext[k] ? cz[k] * cz[k] : 0;
        hmax = fmax(hmax, hw[k]);
    }
    CHECKF(fabs(sum / (double)data - 1) < 1e-12, "mean %g", sum / (double)data);
    size_t clipped = 0;
    for (size_t k = 0; k < m * n; k++) {
        double want = ext[k] ? cz[k] * cz[k] * (double)data / c2 : 0;
        CHECKF(fabs(raw[k] - want) <= 1e-12 * (want + 1), "cell %zu: %g, cos^2 over its mean says %g", k, raw[k], want);
        if (!ext[k]) continue;
        if (hw[k] < hmax) {
            if (scale == 0) scale = raw[k] / hw[k];
            CHECKF(fabs(raw[k] / hw[k] - scale) <= 1e-12 * scale, "cell %zu: ratio %g against %g", k, raw[k] / hw[k],
                   scale);
        } else
            clipped++;
    }
    CHECK(clipped >= 1 && scale > 0);
    for (size_t k = 0; k < m * n; k++)
        if (ext[k] && hw[k] >= hmax) CHECKF(raw[k] >= scale * hw[k] * (1 - 1e-12), "clipped cell %zu", k);
    free(ext);
    free(cz);
    free(hw);
    free(raw);
    sb_param_destroy(p);
}

/* The reference terms: U V^T of J = min(m, n) reproduces the matrix, and
 * the squared error of each prefix is the sum of the squared singular
 * values after it (Eckart-Young), non-increasing with J'. */
SB_TEST(svd_terms_reproduce) {
    enum { M = 5, N = 7, J = 5 };
    double x[M * N], U[M * J], V[N * J], prev = INFINITY;
    for (size_t k = 0; k < M * N; k++)
        x[k] = fabs(sin(1.7 * (double)k + 0.3)) + 0.1 * (double)(k % 3);
    CHECK(sb_nmf_svd_terms(x, M, N, J, U, V) == 0);
    for (size_t p = 1; p <= J; p++) {
        double e = 0;
        for (size_t c = 0; c < N; c++)
            for (size_t i = 0; i < M; i++) {
                double r = x[i + c * M];
                for (size_t j = 0; j < p; j++)
                    r -= U[i + j * M] * V[c + j * N];
                e += r * r;
            }
        CHECKF(e <= prev + 1e-12, "prefix %zu: %g after %g", p, e, prev);
        prev = e;
        if (p == J) CHECKF(e < 1e-20, "J = min(m, n): %g left", e);
    }
}

/* The worst prefix against the reference: 1 for the reference itself;
 * with no terms, each prefix's ratio is ||x||^2 over the reference's error
 * at it (weighted), the largest of them; cells of weight 0 do not count. */
SB_TEST(worst_ratio_against_the_reference) {
    enum { M = 6, N = 9, J = 3 };
    double x[M * N], hw[M * N], R[M * J], S[N * J], U[M * J] = {0}, V[N * J] = {0};
    for (size_t k = 0; k < M * N; k++) {
        x[k] = fabs(cos(0.9 * (double)k)) + 0.05 * (double)(k % 4);
        hw[k] = k % 5 == 2 ? 0 : 0.5 + 0.1 * (double)(k % 7);
    }
    CHECK(sb_nmf_svd_terms(x, M, N, J, R, S) == 0);
    double self = sb_nmf_worst_ratio(x, hw, M, N, J, R, S, R, S, 1e-300);
    CHECKF(fabs(self - 1) < 1e-12, "the reference against itself: %g", self);
    double xx = 0, e[J] = {0}, want = 0;
    for (size_t c = 0; c < N; c++)
        for (size_t i = 0; i < M; i++) {
            double r = x[i + c * M];
            xx += hw[i + c * M] * r * r;
            for (size_t j = 0; j < J; j++) {
                r -= R[i + j * M] * S[c + j * N];
                e[j] += hw[i + c * M] * r * r;
            }
        }
    for (size_t j = 0; j < J; j++)
        want = fmax(want, xx / e[j]);
    double none = sb_nmf_worst_ratio(x, hw, M, N, J, U, V, R, S, 1e-300);
    CHECKF(fabs(none - want) < 1e-9 * want, "no terms: %g, want %g", none, want);
    hw[7] = 0;
    x[7] += 100; /* a cell of weight 0 changes nothing */
    CHECKF(fabs(sb_nmf_worst_ratio(x, hw, M, N, J, R, S, R, S, 1e-300) - 1) < 1e-12, "weight-0 cell counted");
}

/* The terms as s_j |u_j| |v_j| (src/solve/nmf_gram.c sb_nmf_normalise):
 * unit factors, each product s_j u_j v_j^T as before, and a term with a
 * zero factor left at s_j = 0 without NaNs. */
SB_TEST(normalise_keeps_every_term) {
    enum { M = 4, N = 6, J = 3 };
    double U[M * J], V[N * J], U0[M * J], V0[N * J], sig[J];
    for (size_t k = 0; k < M * J; k++)
        U0[k] = U[k] = 0.3 + fabs(sin(1.3 * (double)k));
    for (size_t k = 0; k < N * J; k++)
        V0[k] = V[k] = k / N == 2 ? 0 : 2.5 * fabs(cos(0.7 * (double)k));
    sb_nmf_normalise(M, N, J, sig, U, V);
    for (size_t j = 0; j < J; j++) {
        double nu = 0, nv = 0;
        for (size_t i = 0; i < M; i++)
            nu += U[i + j * M] * U[i + j * M];
        for (size_t c = 0; c < N; c++)
            nv += V[c + j * N] * V[c + j * N];
        CHECKF(fabs(nu - 1) < 1e-12, "term %zu: |u|^2 = %g", j, nu);
        CHECKF(j == 2 ? nv == 0 && sig[j] == 0 : fabs(nv - 1) < 1e-12, "term %zu: |v|^2 = %g, s = %g", j, nv, sig[j]);
        for (size_t i = 0; i < M; i++)
            for (size_t c = 0; c < N; c++) {
                double was = U0[i + j * M] * V0[c + j * N], now = sig[j] * U[i + j * M] * V[c + j * N];
                CHECKF(fabs(now - was) <= 1e-12 * (1 + was), "term %zu at (%zu, %zu): %g, was %g", j, i, c, now, was);
            }
    }
}

/* The sweeps' fused column loops (src/solve/nmf_lanes.h, four lanes in
 * one vector where GCC has them) give the bits of the loops they fuse,
 * two axpy_neg then wdot, and wsq_add those of its plain four lanes, for
 * columns of every length mod 4 (the default gold's 64 rows, tails). */
SB_TEST(lanes_fused_same_bits) {
    static const size_t ms[] = {1, 3, 4, 7, 64, 65, 66, 67};
    for (size_t t = 0; t < sizeof ms / sizeof *ms; t++) {
        size_t m = ms[t];
        double e[80], r[80], e1[80], r1[80], du[80], u[80], w[80];
        for (size_t i = 0; i < m; i++) {
            e[i] = e1[i] = sin(1.3 * (double)i + 0.1) * 1e-2;
            r[i] = r1[i] = cos(0.7 * (double)i) * 3e-3;
            du[i] = sin(2.9 * (double)i) * 1e-4;
            u[i] = fabs(cos(0.37 * (double)i + 0.2));
            w[i] = i % 5 == 2 ? 1e-6 : 1 + 0.1 * (double)(i % 3);
        }
        double a = 0.731, ar = 1.913, b, d, b1, d1;
        sub2_wdot(e, r, du, a, ar, w, u, m, &b, &d);
        axpy_neg(e1, du, a, m);
        axpy_neg(r1, du, ar, m);
        wdot(w, r1, u, m, &b1, &d1);
        CHECK(b == b1 && d == d1 && !memcmp(e, e1, m * sizeof *e) && !memcmp(r, r1, m * sizeof *r));
        axpy2_neg(e, r, u, a, ar, m);
        axpy_neg(e1, u, a, m);
        axpy_neg(r1, u, ar, m);
        CHECK(!memcmp(e, e1, m * sizeof *e) && !memcmp(r, r1, m * sizeof *r));
        double f = wsq_add(w, e, u, a, m), fl[4] = {0, 0, 0, 0};
        for (size_t i = 0; i < m; i++) { /* the plain lanes: lane i % 4 but the tail's into lane 0 */
            size_t l = i < m / 4 * 4 ? i % 4 : 0;
            fl[l] += w[i] * e1[i] * e1[i];
            e1[i] += a * u[i];
        }
        CHECK(f == (fl[0] + fl[1]) + (fl[2] + fl[3]) && !memcmp(e, e1, m * sizeof *e));
    }
}
