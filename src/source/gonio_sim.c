/* The simulated gonioreflectometer and the CSV writers: a source measured
 * at the positions of a gonioreflectometer (with optional multiplicative
 * noise), or a table's own samples, written as a sepbrdf CSV table
 * (docs/measured.md) that the readers of gonio.c read back. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "source/measured_impl.h"
#include "util/internal.h"
#include "util/rng.h"

/* Standard normal by Box-Muller, one value per call (the pair's second
 * value is kept for the next call). */
typedef struct gauss {
    uint64_t s;
    int have;
    double next;
} gauss_t;

static double gauss_next(gauss_t *g) {
    if (g->have) {
        g->have = 0;
        return g->next;
    }
    double two[2];
    sb_splitmix_gauss2(&g->s, two); /* splitmix64: small, deterministic, good enough for test noise */
    g->next = two[1];
    g->have = 1;
    return two[0];
}

/* The metadata and column lines every table written here ends its header with. */
static void csv_header(FILE *fp, const sb_source_t *src) {
    unsigned flags = sb_source_flags(src);
    fprintf(fp,
            "# units: degrees\n"
            "# symmetry: %s\n"
            "# reciprocal: %s\n"
            "theta_i,phi_i,theta_o,phi_o,r,g,b\n",
            flags & SB_SOURCE_ISOTROPIC ? "isotropic" : "anisotropic", flags & SB_SOURCE_RECIPROCAL ? "yes" : "no");
}

sb_result_t sb_measured_write_csv(sb_context_t *ctx, FILE *fp, const sb_source_t *src, size_t *rows) {
    sb_csv_write_stats_t st;
    sb_result_t r = sb_measured_write_csv_stats(ctx, fp, src, NULL, &st);
    if (rows) *rows = r == SB_OK ? st.rows : 0;
    return r;
}

sb_result_t sb_measured_write_csv_stats(sb_context_t *ctx, FILE *fp, const sb_source_t *src,
                                        const sb_write_opts_t *opts, sb_csv_write_stats_t *stats) {
    if (!fp || !src) return sb_error(ctx, SB_ERR_ARG, "csv: missing output or source");
    size_t n = sb_source_sample_count(src);
    if (n == 0) return sb_error(ctx, SB_ERR_ARG, "csv: %s has no measured samples", sb_source_description(src));
    double margin = opts && opts->horizon_deg != 0 ? opts->horizon_deg : 1;
    if (!(margin < 90)) return sb_error(ctx, SB_ERR_RANGE, "csv: horizon %g deg out of range, need < 90", margin);
    /* f of a source that stores f cos theta_i is its value over cos theta_i */
    if (!(sb_source_flags(src) & SB_SOURCE_STORES_COS) || margin < 0) margin = 0;
    double z_min = sin(margin * SB_PI / 180); /* cos theta_i at 90 deg - margin */
    sb_csv_write_stats_t st = {0, 0, 0, margin};
    fprintf(fp, "# sepbrdf table of measured samples (docs/measured.md)\n# source: %s\n", sb_source_description(src));
    if (margin > 0)
        fprintf(fp, "# left out: samples with the light within %.17g deg of the horizon (f cos theta_i stored)\n",
                margin);
    csv_header(fp, src);
    for (size_t k = 0; k < n; k++) {
        double wi[3], wo[3], f[3];
        if (!sb_source_sample(src, k, wi, wo, f)) continue;
        if (margin > 0 && wi[2] <= z_min * sqrt(wi[0] * wi[0] + wi[1] * wi[1] + wi[2] * wi[2])) {
            st.left_out++;
            st.left_out_max = fmax(st.left_out_max, fmax(f[0], fmax(f[1], f[2])));
            continue;
        }
        double a[4] = {atan2(hypot(wi[0], wi[1]), wi[2]), atan2(wi[1], wi[0]), atan2(hypot(wo[0], wo[1]), wo[2]),
                       atan2(wo[1], wo[0])};
        fprintf(fp, "%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n", a[0] * 180 / SB_PI, a[1] * 180 / SB_PI,
                a[2] * 180 / SB_PI, a[3] * 180 / SB_PI, f[0], f[1], f[2]);
        st.rows++;
    }
    if (stats) *stats = st;
    if (ferror(fp)) return sb_error(ctx, SB_ERR_IO, "csv: write error: %s", strerror(errno));
    return SB_OK;
}

sb_result_t sb_gonio_write_csv(sb_context_t *ctx, FILE *fp, const sb_source_t *src, const sb_gonio_opts_t *opts,
                               size_t *rows) {
    if (!fp || !src) return sb_error(ctx, SB_ERR_ARG, "gonio: missing output or source");
    sb_gonio_opts_t o = {0};
    if (opts) o = *opts;
    if (!o.n_theta_i && !o.n_phi_i && !o.n_theta_o && !o.n_phi_o) {
        o.n_theta_i = 18;
        o.n_phi_i = 1;
        o.n_theta_o = 18;
        o.n_phi_o = 72;
    }
    size_t nn[4] = {o.n_theta_i, o.n_phi_i, o.n_theta_o, o.n_phi_o}, total = 1;
    static const char *const nm[4] = {"N_theta_i", "N_phi_i", "N_theta_o", "N_phi_o"};
    for (int k = 0; k < 4; k++) {
        if (nn[k] < 1 || nn[k] > 4096)
            return sb_error(ctx, SB_ERR_RANGE, "gonio: %s = %zu out of range, need 1..4096", nm[k], nn[k]);
        if (sb_size_mul(total, nn[k], &total) || total > SB_MAX_ROWS)
            return sb_error(ctx, SB_ERR_OVERFLOW, "gonio: %zu x %zu x %zu x %zu positions exceed %zu rows", nn[0],
                            nn[1], nn[2], nn[3], SB_MAX_ROWS);
    }
    if (!(o.noise >= 0 && o.noise <= 10))
        return sb_error(ctx, SB_ERR_RANGE, "gonio: noise %g out of range, need 0..10", o.noise);
    gauss_t g = {o.seed ? o.seed : 1, 0, 0};
    fprintf(fp,
            "# sepbrdf gonio table (docs/measured.md)\n"
            "# source: %s\n"
            "# gonio: %zu,%zu,%zu,%zu (theta_k = (k + 1/2) 90/N deg, phi_k = k 360/N deg)\n"
            "# noise: %.17g (multiplicative gaussian, seed %llu)\n",
            sb_source_description(src), nn[0], nn[1], nn[2], nn[3], o.noise, (unsigned long long)(o.seed ? o.seed : 1));
    csv_header(fp, src);
    size_t written = 0;
    for (size_t a = 0; a < nn[0]; a++)
        for (size_t b = 0; b < nn[1]; b++)
            for (size_t c = 0; c < nn[2]; c++)
                for (size_t d = 0; d < nn[3]; d++) {
                    double ti = ((double)a + 0.5) * 90 / (double)nn[0], pi_ = (double)b * 360 / (double)nn[1];
                    double to = ((double)c + 0.5) * 90 / (double)nn[2], po = (double)d * 360 / (double)nn[3];
                    double wi[3], wo[3], v[3];
                    sb_dir_from_angles(ti * SB_PI / 180, pi_ * SB_PI / 180, wi);
                    sb_dir_from_angles(to * SB_PI / 180, po * SB_PI / 180, wo);
                    if (!sb_source_eval(src, wi, wo, v) || !isfinite(v[0]) || !isfinite(v[1]) || !isfinite(v[2]))
                        continue;
                    if (o.noise > 0)
                        for (int k = 0; k < 3; k++)
                            v[k] *= 1 + o.noise * gauss_next(&g);
                    fprintf(fp, "%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n", ti, pi_, to, po, v[0], v[1], v[2]);
                    written++;
                }
    if (rows) *rows = written;
    if (ferror(fp)) return sb_error(ctx, SB_ERR_IO, "gonio: write error: %s", strerror(errno));
    return SB_OK;
}
