/* Scattered gonioreflectometer tables (Cornell .brdf, ALTA, sepbrdf CSV):
 * what the text readers share (one file per format: gonio_cornell.c,
 * gonio_alta.c, gonio_csv.c).  The samples they read become an
 * interpolated source in scattered.c; the simulated gonioreflectometer that
 * writes such tables is in gonio_sim.c. */
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "source/gonio_impl.h"
#include "util/internal.h"

sb_result_t sb_gonio_add_(sb_gonio_t *rd, const double wi[3], const double wo[3], const double f[3], int nan,
                          int negative) {
    rd->info->rows++;
    if (nan) {
        rd->info->nan_rows++;
        return SB_OK;
    }
    if (!(wi[2] > SB_HORIZON_Z && wo[2] > SB_HORIZON_Z)) {
        rd->info->horizon_rows++;
        return SB_OK;
    }
    for (int c = 0; c < 3; c++)
        if (fabs(f[c]) > FLT_MAX)
            return sb_error(rd->ctx, SB_ERR_FORMAT,
                            "%s:%zu: f_r = %g (1/sr) overflows float storage (largest %g): not a reflectance", rd->path,
                            rd->lr.line, f[c], (double)FLT_MAX);
    rd->info->negative += (size_t)(negative != 0);
    double g[3] = {f[0], f[1], f[2]};
    if (rd->info->wavelengths) rd->info->out_of_gamut += (size_t)sb_gamut_map(rd->info->gamut, g);
    return sb_samples_push_(rd->ctx, rd->path, &rd->ss, wi, wo, g, rd->info);
}

sb_result_t sb_gonio_bad_number_(sb_gonio_t *rd, const char *what, const char *field) {
    return sb_error(rd->ctx, SB_ERR_FORMAT, "%s:%zu: %s '%.40s' is not a number", rd->path, rd->lr.line, what, field);
}
sb_result_t sb_gonio_not_finite_(sb_gonio_t *rd, const char *what, const char *field) {
    return sb_error(rd->ctx, SB_ERR_FORMAT, "%s:%zu: %s '%.40s' is not finite", rd->path, rd->lr.line, what, field);
}

sb_result_t sb_gonio_angle_(sb_gonio_t *rd, const char *what, const char *s, double unit, sb_angle_kind_t kind,
                            double *out) {
    if (sb_parse_number(s, out) != 0) return sb_gonio_bad_number_(rd, what, s);
    if (!isfinite(*out)) return sb_gonio_not_finite_(rd, what, s);
    *out *= unit;
    double lo = kind == SB_ANGLE_THETA ? 0 : kind == SB_ANGLE_PHI ? -2 * SB_PI : -SB_PI;
    double hi = kind == SB_ANGLE_PHI ? 2 * SB_PI : SB_PI;
    if (!(*out >= lo - 1e-9 && *out <= hi + 1e-9))
        return sb_error(rd->ctx, SB_ERR_FORMAT, "%s:%zu: %s '%.40s' (%g deg) is outside %g..%g deg", rd->path,
                        rd->lr.line, what, s, *out * 180 / SB_PI, lo * 180 / SB_PI, hi * 180 / SB_PI);
    if (kind == SB_ANGLE_THETA && *out < 0) *out = 0;
    return SB_OK;
}

sb_result_t sb_gonio_value_(sb_gonio_t *rd, const char *what, const char *s, double *out, int *nan) {
    if (sb_parse_number(s, out) != 0) return sb_gonio_bad_number_(rd, what, s);
    if (isnan(*out))
        *nan = 1;
    else if (!isfinite(*out))
        return sb_gonio_not_finite_(rd, what, s);
    return SB_OK;
}

int sb_gonio_blank_(const char *s, char comment) {
    while (*s == ' ' || *s == '\t')
        s++;
    return *s == 0 || *s == comment;
}

/* The format-specific lines `info` prints for a scattered table. */
static void scattered_fields(sb_measured_info_t *info) {
    sb_info_field(info, "rows", (double)info->rows, "%zu (used %zu; skipped %zu: NaN %zu, at/below horizon %zu)",
                  info->rows, info->samples, info->missing, info->nan_rows, info->horizon_rows);
    sb_info_field(info, "negative", (double)info->negative, "%zu rows (kept)", info->negative);
    sb_info_field(info, "theta max", NAN, "i %.2f deg, o %.2f deg", info->theta_i_max * 180 / SB_PI,
                  info->theta_o_max * 180 / SB_PI);
    sb_info_field(info, "interp", NAN, "%s, k = %zu, radius %.3g deg (median spacing %.3g deg), %zu-D embedding",
                  sb_interp_name(info->interp), info->neighbours, info->radius * 180 / SB_PI,
                  info->spacing * 180 / SB_PI, info->dims);
    const double *cv = info->interp_cv;
    sb_info_field(info, "interp cv", cv[info->interp],
                  "%.3g %% (%s); nearest %.3g %%, linear %.3g %%, idw %.3g %%, quadratic %.3g %% (%zu held out)",
                  100 * cv[info->interp], sb_interp_name(info->interp), 100 * cv[SB_INTERP_NEAREST],
                  100 * cv[SB_INTERP_LINEAR], 100 * cv[SB_INTERP_IDW], 100 * cv[SB_INTERP_QUADRATIC],
                  info->cv_held_out);
    const sb_lobe_fit_t *L = &info->lobe;
    char f0[64];
    if (L->f0_per_channel)
        snprintf(f0, sizeof f0, "(%.2g, %.2g, %.2g)", L->f0_rgb[0], L->f0_rgb[1], L->f0_rgb[2]);
    else
        snprintf(f0, sizeof f0, "%.2g", L->f0);
    if (L->fitted)
        sb_info_field(info, "lobe", L->used,
                      "%s: diffuse%s + %s lobe, alpha %.3g, F0 %s, ks (%.3g, %.3g, %.3g); interp cv %.3g %% with, "
                      "%.3g %% without",
                      L->used ? "used" : "not used", L->diffuse_fresnel ? " x (1 - F)" : "", L->ndf, L->alpha, f0,
                      L->ks[0], L->ks[1], L->ks[2], 100 * L->cv_on, 100 * L->cv_off);
}

sb_result_t sb_gonio_open_(sb_context_t *ctx, const char *path, sb_gonio_read_fn read, const sb_measured_opts_t *o,
                           sb_source_t **out, sb_measured_info_t *info) {
    sb_result_t r;
    FILE *fp = sb_fopen_regular(ctx, path, "measured table", SB_MEASURED_MAX_FILE, &r);
    if (!fp) return r;
    sb_gonio_t rd = {ctx, path, {fp, path, 0, NULL, 0}, {NULL, 0, 0}, info};
    for (int c = 0; c < 3; c++) {
        info->value_min[c] = INFINITY;
        info->value_max[c] = -INFINITY;
    }
    info->white = o->white;
    info->gamut = o->gamut;
    int iso = 1, recip = 1;
    r = read(&rd, o, &iso, &recip);
    free(rd.lr.buf);
    fclose(fp);
    info->samples = rd.ss.n;
    info->missing = info->nan_rows + info->horizon_rows;
    for (int c = 0; c < 3; c++) {
        info->value_mean[c] = rd.ss.n ? info->value_mean[c] / (double)rd.ss.n : 0;
        if (!rd.ss.n) info->value_min[c] = info->value_max[c] = 0;
    }
    if (r == SB_OK) r = sb_table_create_(ctx, path, &rd.ss, iso, recip, o, info, out);
    free(rd.ss.s);
    if (r == SB_OK) scattered_fields(info);
    return r;
}
